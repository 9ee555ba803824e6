//! The committed SPIR-V module (`host/kernels/kdray.spv`) must be what its sources compile to.
//! The builder (`scripts/kernels.sh`, nightly) records every source file's fingerprint beside
//! the module; this test, on whatever toolchain builds the library, recomputes them with the
//! same code, so a kernel edited without rebuilding fails here. (CI also rebuilds the module and
//! compares bytes.)
#[path = "../shader-crate/builder/src/sources.rs"]
#[allow(dead_code)] // `record` is the builder's
mod sources;

use std::collections::BTreeMap;
use std::path::Path;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap()
}

fn parse(record: &str) -> BTreeMap<String, u64> {
    record
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (h, p) = l.split_once("  ").unwrap_or_else(|| panic!("malformed line in {}: {l:?}", sources::RECORD));
            (p.to_string(), u64::from_str_radix(h, 16).unwrap_or_else(|_| panic!("malformed hash in {}: {l:?}", sources::RECORD)))
        })
        .collect()
}

#[test]
fn committed_module_matches_its_sources() {
    let root = root();
    let record = std::fs::read_to_string(root.join(sources::RECORD)).expect("the record of the kernels' sources");
    let recorded = parse(&record);
    let module = std::fs::read(root.join(sources::MODULE)).expect("the committed SPIR-V module");
    let mut problems = Vec::new();
    match recorded.get(sources::MODULE) {
        Some(&h) if h == sources::fingerprint(&module) => {}
        _ => problems.push(format!("{} is not the module the record was written for", sources::MODULE)),
    }
    let now = sources::source_files(root).expect("listing the kernels' sources");
    for f in &now {
        let h = sources::fingerprint(&std::fs::read(root.join(f)).unwrap());
        match recorded.get(f) {
            None => problems.push(format!("{f} is new")),
            Some(&r) if r != h => problems.push(format!("{f} changed")),
            _ => {}
        }
    }
    for f in recorded.keys().filter(|f| f.as_str() != sources::MODULE && !now.contains(f)) {
        problems.push(format!("{f} is gone"));
    }
    assert!(
        problems.is_empty(),
        "the committed kernels are stale ({}): run `{}` and commit {} and {}",
        problems.join("; "),
        sources::REBUILD,
        sources::MODULE,
        sources::RECORD
    );
}

/// The check can fail: a one-byte edit of any source is seen.
#[test]
fn fingerprint_sees_an_edit() {
    let root = root();
    let files = sources::source_files(root).unwrap();
    assert!(files.iter().any(|f| f == "shared/src/photon.rs") && files.iter().any(|f| f == "shader-crate/src/lib.rs"), "{files:?}");
    let bytes = std::fs::read(root.join("shared/src/photon.rs")).unwrap();
    let mut edited = bytes.clone();
    let i = edited.len() / 2;
    edited[i] ^= 1;
    assert_ne!(sources::fingerprint(&bytes), sources::fingerprint(&edited));
    let crlf: Vec<u8> = bytes.iter().flat_map(|&b| if b == b'\n' { vec![b'\r', b'\n'] } else { vec![b] }).collect();
    assert_eq!(sources::fingerprint(&bytes), sources::fingerprint(&crlf), "CRLF checkouts fingerprint alike");
}

/// Every entry point's bindings are numbered 0, 1, 2, … without a gap: with a gap (an unused
/// parameter that rust-gpu drops, e.g. bindings 0, 1, 3, 4, 5) lavapipe 22.3 ran the BVH kernel
/// without writing its output, silently.
#[test]
fn every_entry_points_bindings_are_contiguous() {
    let m = kdray::runtime::module::module_info().unwrap();
    let mut gaps = Vec::new();
    for e in &m.entry_points {
        let mut b: Vec<u32> = e.bindings.iter().map(|b| b.binding).collect();
        b.sort();
        if b.iter().enumerate().any(|(i, &n)| n != i as u32) {
            gaps.push(format!("{}: {b:?}", e.name));
        }
    }
    assert!(gaps.is_empty(), "entry points with gaps in their bindings:\n{}", gaps.join("\n"));
}
