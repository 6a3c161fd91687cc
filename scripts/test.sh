#!/usr/bin/env bash
# Runs every test of the project. `.ci/run` calls exactly this; it must pass on a fresh
# machine, so it installs what it needs itself. Each step prints how long it took, and the run
# ends with a table of step durations (also printed when a step fails).
#
# No silent skips: a missing sub-suite fails the run, every pytest run reports its skips (-rs),
# and the `lacquer_no_skip` pytest plugin (scripts/pytest/) turns a skipped test into a failure.
# LACQUER_ALLOW_SKIP=1 lets tests skip on a developer machine; CI (CI=true) ignores it.
#
# Durations are bounded by the cheaper `ci` profile of `lacquer check` (docs/checks.md: what it
# still detects); the full standard run is `cargo run --release -p lacquer-cli -- check --all`.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never

# pytest everywhere (here and in the sub-suites): the skip summary and the no-skip plugin.
export PYTHONPATH="$PWD/scripts/pytest${PYTHONPATH:+:$PYTHONPATH}"
export PYTEST_ADDOPTS="-rs -p lacquer_no_skip${PYTEST_ADDOPTS:+ $PYTEST_ADDOPTS}"
if [ "${CI:-}" = true ] && [ -n "${LACQUER_ALLOW_SKIP:-}" ]; then
  echo "LACQUER_ALLOW_SKIP is ignored in CI (CI=true): a skipped test fails the run"
  unset LACQUER_ALLOW_SKIP
fi

step_names=() step_secs=()
step_name="" step_start=$SECONDS run_start=$SECONDS
end_step() {
  if [ -n "$step_name" ]; then
    local s=$((SECONDS - step_start))
    step_names+=("$step_name") step_secs+=("$s")
    printf '==== (%d s) %s\n' "$s" "$step_name"
  fi
}
step() {
  end_step
  step_name="$*" step_start=$SECONDS
  printf '\n==== %s\n' "$*"
}
kill_tree() { # kill_tree PID: a background job and everything it started
  local child
  for child in $(pgrep -P "$1" 2>/dev/null); do kill_tree "$child"; done
  kill "$1" 2>/dev/null || true
}
summary() {
  local rc=$? i
  # A step failed before the fuzz step waited for its background build: stop the build.
  if [ -n "${fuzz_build_pid:-}" ] && kill -0 "$fuzz_build_pid" 2>/dev/null; then
    kill_tree "$fuzz_build_pid"
  fi
  end_step
  step_name=""
  printf '\n==== step durations (%s)\n' "$([ "$rc" = 0 ] && echo "all passed" || echo "FAILED, exit $rc")"
  for i in "${!step_names[@]}"; do
    printf '%6d s  %s\n' "${step_secs[$i]}" "${step_names[$i]}"
  done
  printf '%6d s  total\n' "$((SECONDS - run_start))"
}
trap summary EXIT

step "toolchain components"
command -v cargo >/dev/null || { echo "cargo not found: install Rust (rustup) first" >&2; exit 1; }
if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
  rustup component add rustfmt clippy
fi

step "format"
cargo fmt --all -- --check

step "clippy"
cargo clippy --workspace --all-targets -- -D warnings

# Includes the c-api crate's Rust tests (so c-api/test.sh below runs with --skip-rust). Skips
# the two tests of rust-core/tests/integration/all_models.rs that run every model and preset through the
# checks in the quick configuration, and the models' own `passes_its_claims` /
# `passes_quick_checks` unit tests (each is `check_model(&INFO, &CheckConfig::quick())`, 21 % of
# the unit tests' time): the next step checks the same materials with at least as many samples,
# pairs and directions (a test, ci_profile_covers_the_quick_configuration, keeps that true), so
# running both would only repeat work. A plain `cargo test` still runs them all.
#
# Release build: the tests run the code as it ships (opt-level 3, the SIMD code users get), and
# every later step (lacquer check, the C ABI library, the Mitsuba plugin, the Blender wheel)
# reuses the same compiled crates instead of building them a second time at another profile.
# Debug assertions and integer-overflow checks are off here (the crate has four debug_assert!s);
# a plain `cargo test` keeps them for development. Examples are not built (clippy above
# type-checks them), and the doc tests run on their own line.
step "Rust tests (unit, property, chi-square, golden; every model through the checks is the next step)"
cargo test --workspace --release --lib --bins --tests -- --skip every_model_passes_its_claims --skip every_preset_passes_its_claims \
  --skip tests::passes_its_claims --skip tests::passes_quick_checks
cargo test --workspace --release --doc

# The fuzz step's instrumented build (ASan, the core in one codegen unit, at opt-level 1 since
# session 32: at least a fifth faster than opt-level 3; 20–25 minutes beside the other steps)
# runs in the background from here on, at a lower priority, beside every step up to the
# fuzz step; the fuzz step waits for it and fails with its log if it failed. Not earlier: beside
# the test step's two release compiles of the core it ran the machine out of memory (session
# 28: rustc killed, 24 GiB). Started after the check step (sessions 14–27), it finished 20
# minutes after the last other step in session 27 and pushed the run over 60 minutes
# (docs/reliability.md, "CI duration: session 28").
[ -f fuzz/smoke.sh ] || { echo "sub-suite fuzz/smoke.sh is missing: a missing suite fails CI" >&2; exit 1; }
fuzz_build_log="$(mktemp "${TMPDIR:-/tmp}/lacquer-fuzz-build.XXXXXX")"
nice -n 5 bash fuzz/smoke.sh --build-only >"$fuzz_build_log" 2>&1 &
fuzz_build_pid=$!

# The `ci` profile: the standard configuration, with fewer samples for the three slow
# physical-optics models (their statistical power is stated in rust-core/src/check/mod.rs and
# docs/checks.md). The full standard run: `lacquer check --all` (docs/checks.md).
step "lacquer check --all --profile ci (release build)"
cargo run --release -q -p lacquer-cli -- check --all --profile ci

# Smoke runs of the speed tooling (the full runs are documented commands, not CI steps):
# lacquer bench on a lane model and a scalar one, the speed-vs-error report and the side-by-side
# comparison with Mitsuba 3 at n = 1e5 (docs/speed.md).

step "speed tooling smoke: lacquer bench --quick, bench --report --quick, bench --max-error"
cargo run --release -q -p lacquer-cli -- bench --quick --model rough_conductor >/dev/null
cargo run --release -q -p lacquer-cli -- bench --report --quick >/dev/null
cargo run --release -q -p lacquer-cli -- bench --quick --preset solid_red --max-error 1e-3

step "Python cross-language tests: EXR read back with OpenImageIO, fits of Mitsuba-sampled tables (pytest)"
cargo build --release -q -p lacquer-cli
venv="$(bash scripts/python-env.sh)"
"$venv/bin/python" -m pytest -q -rs -p lacquer_no_skip tests/test_render_exr.py tests/test_fit_mitsuba.py

export LACQUER_VENV="$venv"  # the Mitsuba plugin's tests share the pinned test venv
for extra in c-api/test.sh mitsuba-plugin/test.sh blender-addon/test.sh fuzz/smoke.sh; do
  [ -f "$extra" ] || { echo "sub-suite $extra is missing: a missing suite fails CI" >&2; exit 1; }
done
step "bench/vs_mitsuba.py --quick (Lacquer C ABI vs Mitsuba 3 built-ins, smoke)"
python3 bench/vs_mitsuba.py --quick >/dev/null

# The SIMD batch kernels of the shipped library must not call SIMD intrinsics out of line (a
# closure or helper compiled without the kernel's `#[target_feature]`: session 39 found one that
# made every metal-base paint 4-7x slower). Reads the machine code, about 15 s; x86-64 only
# (the kernels it checks are the AVX2/AVX-512 ones).
step "bench/kernel_calls.py (no SIMD intrinsic called out of line from the batch kernels)"
if [ "$(uname -m)" = x86_64 ]; then
  # With the CLI, as everywhere here: lacquer-capi alone resolves fewer dependency features and
  # rebuilds the core (450 s in session 40's first CI run with it); with it, only a link.
  cargo build --release -q -p lacquer-capi -p lacquer-cli
  python3 bench/kernel_calls.py
else
  echo "not run on $(uname -m): the AVX2/AVX-512 kernels it checks exist on x86-64 only"
fi

step "c-api/test.sh --skip-rust (its Rust tests ran in cargo test --workspace)"
bash c-api/test.sh --skip-rust
step "mitsuba-plugin/test.sh"
bash mitsuba-plugin/test.sh
step "blender-addon/test.sh"
bash blender-addon/test.sh
# Fuzzing smoke run (docs/reliability.md): the four cargo-fuzz targets, 10 s each from their
# committed corpora; installs cargo-fuzz when absent and fails without the nightly toolchain.
# Last, so that its background build has every mostly single-threaded step above to run beside
# (docs/reliability.md, "CI duration, fifth pass").
step "fuzz/smoke.sh (cargo-fuzz: material JSON, MERL tables, render jobs, C ABI call sequences; 4 x 10 s)"
fuzz_build_rc=0
wait "$fuzz_build_pid" || fuzz_build_rc=$?
cat "$fuzz_build_log"
rm -f "$fuzz_build_log"
fuzz_build_pid=""
[ "$fuzz_build_rc" = 0 ] || { echo "fuzz/smoke.sh --build-only failed (exit $fuzz_build_rc)" >&2; exit 1; }
bash fuzz/smoke.sh
