#!/usr/bin/env bash
# Installs what building and running kdray needs, skipping what is already there: a Vulkan
# loader plus Mesa's lavapipe CPU driver when the machine has no Vulkan driver at all, and a
# TrueType font for the benchmark plots (DejaVu) when there is none. The library builds on
# stable Rust (the toolchain rustup already has).
#
# --kernels: also the nightly that rust-gpu pins (shader-crate/rust-toolchain.toml) with its
# components, needed only to rebuild the committed SPIR-V (scripts/kernels.sh).
# --python: also Python 3 (3.9 or later) with its venv module, for the Python package (python/,
# scripts/python.sh).
# --mpi: also Open MPI (mpirun, its headers) and libclang, for the `mpi` feature (render --mpi;
# scripts/test.sh builds and tests it).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v rustup >/dev/null && ! command -v cargo >/dev/null; then
  echo "error: no Rust toolchain found: install Rust from rustup.rs first" >&2
  exit 1
fi
if [ "${1:-}" = "--kernels" ]; then
  if ! command -v rustup >/dev/null; then
    echo "error: rebuilding the kernels needs rustup (for the pinned nightly): install Rust from rustup.rs" >&2
    exit 1
  fi
  toolchain=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' shader-crate/rust-toolchain.toml)
  if ! rustup toolchain list | grep -q "^${toolchain}"; then
    echo "setup: installing Rust ${toolchain} (rust-src, rustc-dev, llvm-tools) for rust-gpu"
    rustup toolchain install "${toolchain}" --profile minimal --component rust-src,rustc-dev,llvm-tools
  fi
  installed=$(rustup component list --toolchain "${toolchain}" --installed)
  for c in rust-src rustc-dev llvm-tools; do
    if ! grep -q "^${c}" <<<"${installed}"; then
      rustup component add --toolchain "${toolchain}" "${c}"
    fi
  done
fi

have_loader() { ldconfig -p 2>/dev/null | grep -c 'libvulkan\.so\.1' >/dev/null; }
have_driver() {
  local f
  for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json /usr/local/share/vulkan/icd.d/*.json; do
    [ -e "$f" ] && return 0
  done
  return 1
}
packages=()
if ! have_loader || ! have_driver; then
  echo "setup: no Vulkan driver found: installing the Vulkan loader and Mesa's lavapipe"
  packages+=(libvulkan1 mesa-vulkan-drivers)
fi
# Whether any of the paths (globs expanded) exists. (`ls a b` fails when any one is missing:
# with it these checks reinstalled what was there.)
any_exists() {
  local f
  for f in "$@"; do
    [ -e "$f" ] && return 0
  done
  return 1
}
if [ -z "${KDRAY_PLOT_FONT:-}" ] && ! any_exists /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf /usr/share/fonts/TTF/DejaVuSans.ttf /usr/share/fonts/dejavu/DejaVuSans.ttf; then
  echo "setup: no DejaVu font found: installing fonts-dejavu-core (benchmark plots)"
  packages+=(fonts-dejavu-core)
fi
if [ "${1:-}" = "--python" ] && ! python3 -c 'import sys, venv, ensurepip; sys.exit(sys.version_info < (3, 9))' 2>/dev/null; then
  echo "setup: no Python 3.9+ with venv found: installing python3 and python3-venv (the Python package)"
  packages+=(python3 python3-venv)
fi
if [ "${1:-}" = "--mpi" ]; then
  if ! command -v mpirun >/dev/null || ! command -v mpicc >/dev/null; then
    echo "setup: no Open MPI found: installing openmpi-bin and libopenmpi-dev (render --mpi)"
    packages+=(openmpi-bin libopenmpi-dev)
  fi
  # libclang itself (libclang.so*, libclang-N*.so*), not libclang-cpp, which bindgen cannot use
  # and which a machine with LLVM may have alone (CI failed so on a fresh machine, 2026-12-06),
  # and clang's own headers (stddef.h), which bindgen needs for mpi.h and a runtime-only
  # libclang lacks.
  if ! any_exists /usr/lib/llvm-*/lib/libclang.so* /usr/lib/llvm-*/lib/libclang-[0-9]*.so* /usr/lib/x86_64-linux-gnu/libclang.so* \
    /usr/lib/x86_64-linux-gnu/libclang-[0-9]*.so* || ! any_exists /usr/lib/llvm-*/lib/clang/*/include/stddef.h; then
    echo "setup: no libclang with clang's headers found: installing libclang-dev (the mpi crate's bindings)"
    packages+=(libclang-dev)
  fi
fi
if [ ${#packages[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
fi
