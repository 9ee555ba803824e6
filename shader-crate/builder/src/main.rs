//! Compiles `shader-crate/` to SPIR-V with rust-gpu (the nightly pinned in
//! `shader-crate/rust-toolchain.toml`) and writes the module the library embeds,
//! `host/kernels/kdray.spv`, with the record of the sources it came from
//! (`host/kernels/kdray.spv.sources`). The library itself then builds on stable Rust.
//!
//! `--check`: build, compare with the committed files, write nothing; exit status 1 when they
//! differ (CI runs this; the build is deterministic and does not depend on the checkout's path).
mod sources;

use spirv_builder::{Capability, SpirvBuilder, SpirvMetadata};
use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let check = match std::env::args().nth(1).as_deref() {
        None => false,
        Some("--check") => true,
        Some(other) => {
            eprintln!("error: unknown argument `{other}` (usage: kdray-kernel-builder [--check])");
            return ExitCode::from(2);
        }
    };
    match run(check) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(check: bool) -> Result<bool, String> {
    let builder = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shader = builder.parent().ok_or("no shader-crate folder")?;
    let root = shader.parent().ok_or("no repository root")?;
    let mut b = SpirvBuilder::new(shader, "spirv-unknown-vulkan1.2");
    // Keep the names of variables: the host matches its kernels' buffers to bindings by name.
    b.spirv_metadata = SpirvMetadata::NameVariables;
    // Subgroup arithmetic and ballots (Vulkan 1.1: every device lists what it supports).
    b.capabilities.extend([Capability::GroupNonUniform, Capability::GroupNonUniformArithmetic, Capability::GroupNonUniformBallot]);
    let result = b.build().map_err(|e| format!("the shader crate failed to compile to SPIR-V: {e}"))?;
    let built = result.module.unwrap_single();
    let module = std::fs::read(built).map_err(|e| format!("{}: {e}", built.display()))?;
    let record = sources::record(root, &module).map_err(|e| format!("reading the sources: {e}"))?;
    let outputs = [(sources::MODULE, module.as_slice()), (sources::RECORD, record.as_bytes())];
    if check {
        let mut same = true;
        for (path, bytes) in outputs {
            let committed = std::fs::read(root.join(path)).unwrap_or_default();
            if committed != bytes {
                eprintln!("error: {path} differs from what the sources compile to: run `{}` and commit it", sources::REBUILD);
                same = false;
            }
        }
        if same {
            println!("{} and {} match the sources ({} bytes)", sources::MODULE, sources::RECORD, module.len());
        }
        return Ok(same);
    }
    for (path, bytes) in outputs {
        let p = root.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).map_err(|e| format!("{}: {e}", p.display()))?;
        std::fs::write(&p, bytes).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    println!("wrote {} ({} bytes) and {}", sources::MODULE, module.len(), sources::RECORD);
    Ok(true)
}
