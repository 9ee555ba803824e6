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
    if let Err(e) = kdray::runtime::cpu::check_cpu() {
        eprintln!("error: {e}");
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
