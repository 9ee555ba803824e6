#!/usr/bin/env bash
# The Python package (python/): sets up (as scripts/setup.sh --python), installs it the way a
# user does, `pip install ./python` (maturin builds an abi3 wheel from the Rust crate there),
# into a virtual environment (KDRAY_PYTHON_ENV, default target/python-env) with pytest, trimesh
# and, where a wheel exists, embreex; then runs its tests (python/tests: against the `kdray`
# binary's answers, so build that first: scripts/test.sh does) and its example against trimesh.
# Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --python
env="${KDRAY_PYTHON_ENV:-target/python-env}"
if [ ! -x "$env/bin/pip" ]; then
  python3 -m venv "$env"
fi
"$env/bin/pip" install -q --upgrade pip
"$env/bin/pip" install -q numpy pytest trimesh rtree
"$env/bin/pip" install -q embreex 2>/dev/null || echo "python: no embreex wheel here: trimesh's own intersector in the example"
# The workspace's target folder: the Rust dependencies the tests built are reused.
start=$SECONDS
CARGO_TARGET_DIR="$PWD/target" "$env/bin/pip" install ./python
echo "python: the wheel built and installed in $((SECONDS - start)) s"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-${TMPDIR:-/tmp}}"
KDRAY_BIN="$PWD/target/release/kdray" KDRAY_REQUIRE_BIN=1 "$env/bin/pytest" -q python/tests "$@"
"$env/bin/python" python/examples/compare_trimesh.py --rays 65536 --trimesh-rays 2048 --reps 1 --require-agreement 99.99
