#!/usr/bin/env bash
# Runs every test of the project. `.ci/run` calls exactly this; it must pass on a fresh
# machine, so it installs what it needs itself.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never

step() { printf '\n==== %s\n' "$*"; }

step "toolchain components"
command -v cargo >/dev/null || { echo "cargo not found: install Rust (rustup) first" >&2; exit 1; }
if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
  rustup component add rustfmt clippy
fi

step "format"
cargo fmt --all -- --check

step "clippy"
cargo clippy --workspace --all-targets -- -D warnings

step "Rust tests (unit, property, chi-square, golden, every model through the checks)"
cargo test --workspace

step "lacquer check --all (standard configuration, release build)"
cargo run --release -q -p lacquer-cli -- check --all

step "Python cross-language tests: EXR read back with OpenImageIO, fits of Mitsuba-sampled tables (pytest)"
cargo build --release -q -p lacquer-cli
venv="$(bash scripts/python-env.sh)"
"$venv/bin/python" -m pytest -q tests/test_render_exr.py tests/test_fit_mitsuba.py

export LACQUER_VENV="$venv"  # the Mitsuba plugin's tests share the pinned test venv
for extra in c-api/test.sh mitsuba-plugin/test.sh blender-addon/test.sh; do
  if [ -f "$extra" ]; then
    step "$extra"
    bash "$extra"
  fi
done
