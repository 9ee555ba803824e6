#!/usr/bin/env bash
# Sets up (Vulkan/lavapipe if missing) and renders the default scene, the Cornell
# box, to cornell.png on the best GPU (or the CPU when there is none). Extra arguments go to
# `kdray render`, e.g. `--device cpu --size 1024 --compare`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo run --release -p kdray -- render --scene cornell --out cornell.png "$@"
