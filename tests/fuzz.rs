//! The scene readers under mutation fuzzing with a fixed budget: seed files (`scenes/` and the
//! corpus in `tests/fuzz/`) are mutated by a deterministic generator — bytes replaced, ranges
//! deleted or repeated, tokens from the formats' vocabulary and hostile numbers inserted,
//! lines cut — and every mutant is loaded with `kdray::scene::load`. Each must load or fail with
//! one error line, never panic, and finish quickly. A mutant that breaks one of these is written
//! to `target/fuzz-failures/` so it can be added to the corpus once fixed.
use kdray::scene;
use kdray_shared::rng::Rng;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Mutants per seed file.
const MUTANTS: u32 = 3000;
/// Longest a load may take (a hang shows as a load far past this).
const SLOW: Duration = Duration::from_secs(10);

/// Words and numbers the readers give meaning to, and values that break naive parsers.
const VOCABULARY: &[&str] = &[
    "v", "vt", "vn", "f", "o", "g", "s", "usemtl", "mtllib", "newmtl", "Kd", "Ks", "Ke", "Ni", "d", "illum", "[camera]",
    "[[mesh]]", "[[light]]", "[materials.x]", "file", "builtin", "material", "scale", "translate", "point", "intensity",
    "direction", "cone", "falloff_start", "corner", "edge1", "edge2", "emission", "diffuse", "glass", "mirror", "ior", "eye",
    "look_at", "up", "fov_y", "=", "[", "]", "\"", "/", "//", "#", "\n", " ", "\t", "0", "-0", "1", "-1", "3", "-4", "0.5",
    "1e38", "-1e38", "1e39", "3.4e38", "1e-45", "nan", "NaN", "inf", "-inf", "4294967295", "4294967296", "-2147483648",
    "99999999999999999999", "0x10", "1.5.5", "--1", "true", "false", "\u{0}", "\u{feff}", "é", "\r\n",
];

/// A mutant of `seed`: one to four edits drawn from `rng`.
fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    let edits = 1 + rng.next_u32() % 4;
    for _ in 0..edits {
        let at = if b.is_empty() { 0 } else { (rng.next_u32() as usize) % (b.len() + 1) };
        match rng.next_u32() % 7 {
            // A byte replaced by any byte.
            0 if at < b.len() => b[at] = rng.next_u32() as u8,
            // A range deleted.
            1 => {
                let n = (1 + rng.next_u32() % 24) as usize;
                b.drain(at..(at + n).min(b.len()));
            }
            // A range repeated in place.
            2 => {
                let n = (1 + rng.next_u32() % 64) as usize;
                let piece: Vec<u8> = b[at..(at + n).min(b.len())].to_vec();
                let times = 1 + rng.next_u32() % 8;
                for _ in 0..times {
                    b.splice(at..at, piece.iter().copied());
                }
            }
            // The file cut short.
            3 => b.truncate(at),
            // A digit changed (numbers stay numbers, with other values).
            4 => {
                if let Some(k) = (at..b.len()).find(|&k| b[k].is_ascii_digit()) {
                    b[k] = b'0' + (rng.next_u32() % 10) as u8;
                }
            }
            // A token inserted.
            _ => {
                let word = VOCABULARY[(rng.next_u32() as usize) % VOCABULARY.len()];
                b.splice(at..at, word.bytes());
            }
        }
    }
    b
}

/// The seed files: each is mutated while the files it refers to stay beside it unchanged.
fn seeds() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    ["scenes/room.obj", "scenes/room.mtl", "scenes/room.toml", "scenes/ball.obj", "scenes/cornell-mirror.toml", "scenes/cornell.mtl", "tests/fuzz/polygons.obj", "tests/fuzz/polygons.mtl", "tests/fuzz/lights.toml"]
        .iter()
        .map(|p| root.join(p))
        .collect()
}

/// Copies the seed's folder (the files a scene refers to) into a fresh working folder.
fn workspace(seed: &Path, n: usize) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdray-fuzz-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for e in std::fs::read_dir(seed.parent().unwrap()).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() && matches!(p.extension().and_then(|x| x.to_str()), Some("obj" | "mtl" | "toml")) {
            std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
    }
    dir
}

/// The scene to load for a mutated file: the file itself, or for a material library the OBJ
/// file that uses it.
fn scene_for(mutated: &Path) -> PathBuf {
    match mutated.extension().and_then(|x| x.to_str()) {
        Some("mtl") => mutated.with_extension("obj"),
        _ => mutated.to_path_buf(),
    }
}

#[test]
fn mutated_scene_files_load_or_fail_with_one_error_line() {
    let mut failures = Vec::new();
    let (mut loaded, mut refused) = (0, 0);
    let mut slowest = (Duration::ZERO, String::new());
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/fuzz-failures");
    for (n, seed) in seeds().iter().enumerate() {
        let original = std::fs::read(seed).unwrap_or_else(|e| panic!("{}: {e}", seed.display()));
        let dir = workspace(seed, n);
        let target = dir.join(seed.file_name().unwrap());
        let spec = scene_for(&target).to_string_lossy().into_owned();
        for m in 0..MUTANTS {
            let mut rng = Rng::new(0xF022 + n as u32, m);
            let bytes = mutate(&original, &mut rng);
            std::fs::write(&target, &bytes).unwrap();
            let start = Instant::now();
            let result = std::panic::catch_unwind(|| scene::load(&spec));
            let took = start.elapsed();
            let what = format!("{} mutant {m}", seed.file_name().unwrap().to_string_lossy());
            if took > slowest.0 {
                slowest = (took, what.clone());
            }
            let problem = match &result {
                Err(_) => Some("panicked".to_string()),
                Ok(Err(e)) if e.to_string().contains('\n') => Some(format!("a multi-line error: {e}")),
                Ok(Err(e)) if e.to_string().trim().is_empty() => Some("an empty error".to_string()),
                _ if took > SLOW => Some(format!("took {took:?}")),
                _ => None,
            };
            match result {
                Ok(Ok(_)) => loaded += 1,
                Ok(Err(_)) => refused += 1,
                Err(_) => {}
            }
            if let Some(p) = problem {
                std::fs::create_dir_all(&keep).unwrap();
                let name = format!("{}-{m}.{}", seed.file_stem().unwrap().to_string_lossy(), seed.extension().unwrap().to_string_lossy());
                std::fs::write(keep.join(&name), &bytes).unwrap();
                failures.push(format!("{what}: {p} (kept as target/fuzz-failures/{name})"));
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
    eprintln!("{loaded} mutants loaded, {refused} refused with an error, slowest {:?} ({})", slowest.0, slowest.1);
    assert!(failures.is_empty(), "{} of {} mutants misbehaved:\n{}", failures.len(), MUTANTS as usize * seeds().len(), failures.join("\n"));
    // The generator must exercise both outcomes, or the test proves nothing.
    assert!(loaded > 100 && refused > 100, "{loaded} loaded, {refused} refused");
}

#[test]
fn a_material_library_that_is_not_utf8_is_still_checked() {
    // Found by the fuzzer: tobj reads an MTL file's lines up to the first byte that is not
    // UTF-8 and panicked on a colour with two numbers before it; the check reads it lossily.
    let dir = std::env::temp_dir().join(format!("kdray-fuzz-utf8-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    std::fs::write(dir.join("m.mtl"), b"newmtl a\nKd 0.78 0.09\n\xb1\n").unwrap();
    let e = scene::load(&dir.join("m.obj").to_string_lossy()).unwrap_err();
    assert!(e.to_string().contains("needs 3 numbers") && !e.to_string().contains('\n'), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
