#!/usr/bin/env bash
# Rebuilds the SPIR-V module the library embeds, host/kernels/kdray.spv, and the record of the
# sources it came from (host/kernels/kdray.spv.sources), by compiling shader-crate/ (over
# shared/) with rust-gpu and the nightly it pins. Run it after editing anything under shared/ or
# shader-crate/, and commit both files; tests/kernels.rs fails until then.
#
# --check: build, compare with the committed files and write nothing (CI); exit status 1 when
# they differ. The output does not depend on the machine or the checkout's path.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --kernels
cd shader-crate/builder
# cargo run puts the code generator's dylib (rustc_codegen_spirv) on the library path.
exec cargo run --release --locked --target-dir ../../target -- "$@"
