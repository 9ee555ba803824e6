#!/usr/bin/env bash
# Sets up (Vulkan/lavapipe and Open MPI if missing) and runs every test on stable Rust, the GPU ones
# included: with KDRAY_REQUIRE_GPU=1 a test that finds no GPU adapter fails instead of
# skipping. Also: the shader crate's entry points as plain functions on the host, the library's
# examples, the doc tests, and a crate outside the workspace that depends on kdray as a user's
# would (tests/downstream), and the Python package (scripts/python.sh: pip install ./python into
# a virtual environment, pytest, the example against trimesh). The kernels are the committed
# SPIR-V (host/kernels/); tests/kernels.rs checks it still matches its sources. CI also rebuilds
# it (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --mpi
export KDRAY_REQUIRE_GPU=1
# Mesa probes Wayland during adapter enumeration; without this libwayland prints errors.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-${TMPDIR:-/tmp}}"
# With the `mpi` feature: tests/mpi.rs runs `render --mpi` under mpirun (as root too, in CI).
# One feature set for the workspace's builds below (tests, examples), so the library compiles once.
features=(--features kdray/mpi)
cargo test --release --workspace "${features[@]}" "$@"
cargo test --release --manifest-path shader-crate/Cargo.toml --target-dir target/shader-host "$@"
# The API documentation builds without a warning (every public item documented).
RUSTDOCFLAGS="-D warnings" cargo doc --release --no-deps -p kdray -p kdray-shared
# The examples, small.
cargo run --release "${features[@]}" --example trace_arrays
cargo run --release "${features[@]}" --example render_obj -- scenes/room.obj target/examples-room-obj.png 64 16
cargo run --release "${features[@]}" --example render_toml -- scenes/room.toml target/examples-room-toml.png 64 4
# A user's crate on stable Rust, without the command line's dependencies.
cargo run --release --locked --manifest-path tests/downstream/Cargo.toml --target-dir target
# The Python package: pip install ./python into a virtual environment, its pytest suite (on the
# GPU too: KDRAY_REQUIRE_GPU is set) and its example against trimesh.
bash scripts/python.sh
