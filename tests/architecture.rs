//! The layering rules of docs/architecture.md, checked on the source tree: a change that makes
//! a lower host layer name a higher one (runtime < kernels < tracer < integrator < commands),
//! `shared` or the shader crate use the host, or an integrator use wgpu, fails here.
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file below `dir` with its text.
fn sources(dir: &str) -> Vec<(PathBuf, String)> {
    fn walk(p: &Path, out: &mut Vec<(PathBuf, String)>) {
        let mut entries: Vec<_> = std::fs::read_dir(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).flatten().collect();
        entries.sort_by_key(|e| e.path());
        for e in entries {
            let path = e.path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                out.push((path, text));
            }
        }
    }
    let mut out = Vec::new();
    let p = root().join(dir);
    if p.is_dir() {
        walk(&p, &mut out);
    } else {
        out.push((p.clone(), std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))));
    }
    out
}

/// Lines of code (comments dropped) of `dir` that contain `word` as a word of its own (not the
/// tail of a longer name: `spirv_std::` is not `std::`).
fn uses(dir: &str, word: &str) -> Vec<String> {
    let mut hits = Vec::new();
    let starts_word = |code: &str, at: usize| !code[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_');
    for (path, text) in sources(dir) {
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if code.match_indices(word).any(|(at, _)| starts_word(code, at)) {
                hits.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
            }
        }
    }
    hits
}

#[test]
fn shared_is_no_std_and_independent_of_the_host() {
    let lib = std::fs::read_to_string(root().join("shared/src/lib.rs")).unwrap();
    assert!(lib.contains("#![no_std]"));
    for word in ["std::", "kdray::", "extern crate std", "wgpu"] {
        let hits = uses("shared/src", word);
        assert!(hits.is_empty(), "shared/ must not use {word}:\n{}", hits.join("\n"));
    }
    let manifest = std::fs::read_to_string(root().join("shared/Cargo.toml")).unwrap();
    assert!(!manifest.contains("kdray ="), "shared/ must not depend on the host");
}

#[test]
fn the_shader_crate_never_uses_the_host() {
    let manifest = std::fs::read_to_string(root().join("shader-crate/Cargo.toml")).unwrap();
    let deps = manifest.split("[dependencies]").nth(1).unwrap_or("");
    for line in deps.lines().take_while(|l| !l.starts_with('[')) {
        let name = line.split('=').next().unwrap_or("").trim();
        assert!(
            name.is_empty() || ["spirv-std", "kdray-shared", "glam", "bytemuck"].contains(&name),
            "shader-crate depends on {name}"
        );
    }
    for word in ["kdray::", "wgpu"] {
        let hits = uses("shader-crate/src", word);
        assert!(hits.is_empty(), "shader-crate must not use {word}:\n{}", hits.join("\n"));
    }
}

/// The host's layers, lowest first: a layer may use the ones below it, never one above.
const LAYERS: [(&str, &[&str]); 5] = [
    ("runtime", &["host/src/runtime", "host/src/gpu"]),
    ("kernels", &["host/src/kernels.rs"]),
    ("tracer", &["host/src/tracer.rs", "host/src/accel.rs", "host/src/sort.rs"]),
    ("integrator", &["host/src/integrator"]),
    ("commands", &["host/src/bin/kdray"]),
];

/// How code names each layer.
fn names(layer: &str) -> &'static [&'static str] {
    match layer {
        "runtime" => &["crate::runtime", "crate::gpu"],
        "kernels" => &["crate::kernels"],
        "tracer" => &["crate::tracer", "crate::accel", "crate::Tracer", "crate::Accel", "crate::sort"],
        "integrator" => &["crate::integrator", "integrator::"],
        _ => &["crate::bench", "crate::cli"],
    }
}

/// The library never uses what only the command line needs (feature `cli`): a user with
/// `default-features = false` compiles none of it, and errors are `kdray::Error`.
#[test]
fn the_library_holds_no_command_line_dependency() {
    for (path, text) in sources("host/src") {
        if path.components().any(|c| c.as_os_str() == "bin") {
            continue;
        }
        for word in ["clap", "indicatif", "plotters", "anyhow"] {
            for (n, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                assert!(!code.contains(word), "{}:{}: the library uses {word}: {}", path.display(), n + 1, line.trim());
            }
        }
    }
    let manifest = std::fs::read_to_string(root().join("host/Cargo.toml")).unwrap();
    for dep in ["clap", "indicatif", "plotters", "anyhow"] {
        let line = manifest.lines().find(|l| l.starts_with(&format!("{dep} ="))).unwrap_or_else(|| panic!("{dep} not in host/Cargo.toml"));
        assert!(line.contains("optional = true"), "{dep} must be optional (feature cli): {line}");
    }
}

#[test]
fn layers_only_use_the_layers_below() {
    for (i, (layer, dirs)) in LAYERS.iter().enumerate() {
        for (above, _) in &LAYERS[i + 1..] {
            for dir in *dirs {
                for word in names(above) {
                    let hits = uses(dir, word);
                    assert!(hits.is_empty(), "the {layer} layer ({dir}) uses the {above} layer above it:\n{}", hits.join("\n"));
                }
            }
        }
    }
}

#[test]
fn integrators_tracer_and_kernel_declarations_hold_no_wgpu() {
    for dir in ["host/src/integrator", "host/src/tracer.rs", "host/src/kernels.rs", "host/src/accel.rs"] {
        let hits = uses(dir, "wgpu");
        assert!(hits.is_empty(), "{dir} must not use wgpu:\n{}", hits.join("\n"));
    }
}

#[test]
fn queries_and_statistics_do_not_import_the_kd_tree() {
    for file in ["shared/src/query.rs", "shared/src/stats.rs", "shared/src/brute.rs", "shared/src/kernel.rs"] {
        let hits = uses(file, "kdtree");
        assert!(hits.is_empty(), "{file} must not import the kd-tree:\n{}", hits.join("\n"));
    }
}
