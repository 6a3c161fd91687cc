#!/usr/bin/env bash
# Builds the Mitsuba plugin (build.sh) and runs its pytest suite. What CI runs (from
# scripts/test.sh); works on a fresh Debian machine as root: installs libllvm19 for the
# llvm_ad_rgb variant (Dr.Jit aborts with Debian's default LLVM 15; fails without it) and
# OpenImageIO (pip). No test may skip (LACQUER_ALLOW_SKIP=1 allows it outside CI).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${LACQUER_VENV:-$repo/.venv-mitsuba}"
target="${CARGO_TARGET_DIR:-$repo/target}"
export LACQUER_VENV="$venv"

bash "$here/build.sh"

printf '\n==== mitsuba-plugin: test prerequisites\n'
# Without libLLVM the llvm_ad_rgb tests (every chi-square test) cannot run: that fails the
# suite, it is not a skip (LACQUER_ALLOW_SKIP=1 lets the tests skip on a developer machine,
# never with CI=true).
llvm=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
  if [ ! -f "$llvm" ]; then
    if [ "$(id -u)" = 0 ]; then sudo_=""; else sudo_="sudo"; fi
    echo "installing libllvm19 (apt-get) for Dr.Jit's LLVM backend"
    $sudo_ apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq libllvm19 >/dev/null ||
      echo "mitsuba-plugin/test.sh: apt-get install libllvm19 failed" >&2
  fi
  [ -f "$llvm" ] && export DRJIT_LIBLLVM_PATH="$llvm"
fi
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ] || [ ! -f "$DRJIT_LIBLLVM_PATH" ]; then
  echo "mitsuba-plugin/test.sh: no libLLVM for Dr.Jit (DRJIT_LIBLLVM_PATH='${DRJIT_LIBLLVM_PATH:-}'," \
    "$llvm missing): the llvm_ad_rgb tests cannot run" >&2
  if [ "${LACQUER_ALLOW_SKIP:-}" = 1 ] && [ "${CI:-}" != true ]; then
    echo "LACQUER_ALLOW_SKIP=1: continuing, the llvm tests will skip" >&2
  else
    exit 1
  fi
fi
echo "DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-<none>}"
"$venv/bin/python" -c "import OpenImageIO" 2>/dev/null ||
  "$venv/bin/python" -m pip install -q --disable-pip-version-check "OpenImageIO==3.2.2.0"
# The CLI (for the `lacquer render` comparison) and liblacquer.so (for the ctypes package).
(cd "$repo" && cargo build --release -q -p lacquer-cli -p lacquer-capi)
export LACQUER_LIBRARY="${LACQUER_LIBRARY:-$target/release/liblacquer.so}"
export LACQUER_BIN="${LACQUER_BIN:-$target/release/lacquer}"

printf '\n==== mitsuba-plugin: pytest\n'
cd "$here/tests"
# -rs lists every skip; the lacquer_no_skip plugin makes a skip a failure (scripts/pytest/).
export PYTHONPATH="$repo/scripts/pytest${PYTHONPATH:+:$PYTHONPATH}"
"$venv/bin/python" -m pytest -q -rsx -p lacquer_no_skip -p no:cacheprovider "$@"
