//! The `kdray` command line: render, benchmark suites, exports and plots over the library.
mod bench;
mod cli;

use clap::Parser;

fn main() {
    // Mesa's Vulkan drivers probe Wayland while enumerating adapters, and libwayland prints an
    // "error:" line when XDG_RUNTIME_DIR is unset (headless machines, CI). Give it a harmless
    // value before any thread exists.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    // Built for FMA (the repository's .cargo/config.toml): one line, not an illegal instruction
    // (best effort: the compiler may use AVX anywhere in such a build, but nothing before this
    // has floating-point work to put it in).
    #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
    if !cpu_runs_fma() {
        eprintln!("error: this kdray was built for x86-64 CPUs with FMA and this one has none; rebuild it with RUSTFLAGS=\"-C target-feature=-fma\"");
        std::process::exit(1);
    }
    let cli = cli::Cli::parse();
    if let Some(p) = std::env::var_os(kdray::runtime::module::SPIRV_OVERRIDE) {
        eprintln!("note: GPU kernels from {} ({}), not the built-in module", p.to_string_lossy(), kdray::runtime::module::SPIRV_OVERRIDE);
    }
    if let Err(e) = cli::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Whether this CPU and its OS run FMA (and the AVX state it needs), asked of CPUID itself:
/// `is_x86_feature_detected!` answers `true` without asking in a build that targets the feature.
#[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
fn cpu_runs_fma() -> bool {
    use std::arch::x86_64::{__cpuid, _xgetbv};
    // SAFETY: every x86-64 CPU has CPUID; XGETBV is run only where CPUID says the OS enabled it
    // (OSXSAVE).
    unsafe {
        let c = __cpuid(1).ecx;
        let (fma, osxsave, avx) = (c & (1 << 12) != 0, c & (1 << 27) != 0, c & (1 << 28) != 0);
        fma && avx && osxsave && _xgetbv(0) & 6 == 6
    }
}
