//! Which files the kernels are compiled from, and how they are fingerprinted.
//!
//! One source for both sides: the builder (`shader-crate/builder`, nightly) records every file
//! with its hash beside the module it writes, and the library's test (`tests/kernels.rs`, stable
//! Rust, `#[path]`-included) recomputes them, so a module that no longer matches its sources —
//! a kernel edited without rebuilding — fails the tests instead of shipping.
use std::io;
use std::path::Path;

/// The module the library embeds and its record, relative to the repository root.
pub const MODULE: &str = "host/kernels/kdray.spv";
/// The record of what [`MODULE`] was built from.
pub const RECORD: &str = "host/kernels/kdray.spv.sources";
/// The command that rebuilds both.
pub const REBUILD: &str = "bash scripts/kernels.sh";

/// Every file whose content can change the module, relative to the repository root, with `/`
/// separators, sorted: the shared crate, the shader crate, the toolchain and lock files that pin
/// the compiler, the builder itself, and the workspace manifest the shared crate inherits from.
pub fn source_files(root: &Path) -> io::Result<Vec<String>> {
    let mut out = Vec::new();
    for f in [
        "Cargo.toml",
        "shared/Cargo.toml",
        "shader-crate/Cargo.toml",
        "shader-crate/Cargo.lock",
        "shader-crate/rust-toolchain.toml",
        "shader-crate/builder/Cargo.toml",
        "shader-crate/builder/Cargo.lock",
    ] {
        if root.join(f).is_file() {
            out.push(f.to_string());
        }
    }
    for dir in ["shared/src", "shader-crate/src", "shader-crate/builder/src"] {
        rust_files(root, dir, &mut out)?;
    }
    out.sort();
    Ok(out)
}

fn rust_files(root: &Path, dir: &str, out: &mut Vec<String>) -> io::Result<()> {
    for entry in std::fs::read_dir(root.join(dir))? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let rel = format!("{dir}/{name}");
        if entry.file_type()?.is_dir() {
            rust_files(root, &rel, out)?;
        } else if name.ends_with(".rs") {
            out.push(rel);
        }
    }
    Ok(())
}

/// FNV-1a (64 bit) of a file's bytes with carriage returns dropped, so a checkout with CRLF
/// line ends fingerprints like one with LF. A check for staleness, not a defence against
/// tampering.
pub fn fingerprint(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes.iter().filter(|&&b| b != b'\r') {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The record for the sources under `root` and the module's bytes: a comment, the module's
/// fingerprint, then one `fingerprint  path` line per source file.
pub fn record(root: &Path, module: &[u8]) -> io::Result<String> {
    let mut s = format!(
        "# {MODULE} was compiled from these files (FNV-1a 64, CR dropped) by `{REBUILD}`.\n\
         # tests/kernels.rs fails when they no longer match: rerun that command after editing them.\n\
         {:016x}  {MODULE}\n",
        fingerprint(module)
    );
    for f in source_files(root)? {
        let bytes = std::fs::read(root.join(&f))?;
        s.push_str(&format!("{:016x}  {f}\n", fingerprint(&bytes)));
    }
    Ok(s)
}
