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

for extra in c-api/test.sh mitsuba-plugin/test.sh; do
  if [ -f "$extra" ]; then
    step "$extra"
    bash "$extra"
  fi
done
