#!/usr/bin/env bash
# Sets up (toolchain, Vulkan/lavapipe if missing) and runs every test, the GPU ones included:
# with KDRAY_REQUIRE_GPU=1 a test that finds no GPU adapter fails instead of skipping. The
# shader crate's entry points are also built for the host and tested as plain functions.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export KDRAY_REQUIRE_GPU=1
# Mesa probes Wayland during adapter enumeration; without this libwayland prints errors.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-${TMPDIR:-/tmp}}"
cargo test --release --workspace "$@"
cargo test --release --manifest-path shader-crate/Cargo.toml --target-dir shader-crate/target/host "$@"
