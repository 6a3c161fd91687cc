#!/usr/bin/env bash
# Builds the Mitsuba plugin (build.sh) and runs its pytest suite. What CI runs (from
# scripts/test.sh); works on a fresh Debian machine as root: installs libllvm19 for the
# llvm_ad_rgb variant (Dr.Jit aborts with Debian's default LLVM 15) and OpenImageIO (pip).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${LACQUER_VENV:-$repo/.venv-mitsuba}"
target="${CARGO_TARGET_DIR:-$repo/target}"
export LACQUER_VENV="$venv"

bash "$here/build.sh"

printf '\n==== mitsuba-plugin: test prerequisites\n'
llvm=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
  if [ ! -f "$llvm" ] && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq libllvm19 >/dev/null
  fi
  [ -f "$llvm" ] && export DRJIT_LIBLLVM_PATH="$llvm"
fi
echo "DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-<none: llvm tests skip>}"
"$venv/bin/python" -c "import OpenImageIO" 2>/dev/null ||
  "$venv/bin/python" -m pip install -q --disable-pip-version-check "OpenImageIO==3.2.2.0"
# The CLI (for the `lacquer render` comparison) and liblacquer.so (for the ctypes package).
(cd "$repo" && cargo build --release -q -p lacquer-cli -p lacquer-capi)
export LACQUER_LIBRARY="${LACQUER_LIBRARY:-$target/release/liblacquer.so}"
export LACQUER_BIN="${LACQUER_BIN:-$target/release/lacquer}"

printf '\n==== mitsuba-plugin: pytest\n'
cd "$here/tests"
"$venv/bin/python" -m pytest -q -rsx -p no:cacheprovider "$@"
