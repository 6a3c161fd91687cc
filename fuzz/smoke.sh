#!/usr/bin/env bash
# Smoke run of the four fuzz targets (docs/reliability.md): each target runs for
# LACQUER_FUZZ_SECONDS (default 10 s, so ~40 s of fuzzing in total) from its committed corpus
# (fuzz/corpus/<target>, read only: new inputs go to a temporary directory), with hangs
# (-timeout) and allocation blow-ups (-rss_limit_mb, -malloc_limit_mb) counted as failures.
# The targets run side by side, LACQUER_FUZZ_JOBS at a time (default: the number of cores).
# Any crash, hang or leak fails the script; libFuzzer's reproducer is printed.
#
# Needs the nightly toolchain and cargo-fuzz. No silent skip: it installs cargo-fuzz (crates.io,
# pinned) when absent, and fails if the nightly toolchain cannot be had.
#
# `--build-only` installs what is missing and builds the instrumented targets, then stops:
# scripts/test.sh runs it in the background beside the single-threaded steps before this one
# (the ASan build of the core is one codegen unit, so it keeps one core busy for minutes), and
# the later full run finds the build done. The build is at opt-level 1 (below).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here"
build_only=0
for a in "$@"; do
  case "$a" in
    --build-only) build_only=1 ;;
    *) echo "fuzz/smoke.sh: unknown option $a" >&2; exit 2 ;;
  esac
done
seconds="${LACQUER_FUZZ_SECONDS:-10}"
# Longest corpus replay first, so that side by side (below) the short ones fill in at the end.
targets=(capi_calls material_json render_scene merl_table)

if ! rustup run nightly rustc --version >/dev/null 2>&1; then
  echo "fuzz/smoke.sh: the nightly toolchain is missing; installing it (rustup toolchain install nightly)"
  rustup toolchain install nightly --profile minimal \
    || { echo "fuzz/smoke.sh: no nightly toolchain: cargo-fuzz needs it (this is a failure, not a skip)" >&2; exit 1; }
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz/smoke.sh: installing cargo-fuzz"
  cargo install cargo-fuzz --version 0.13.2 --locked \
    || { echo "fuzz/smoke.sh: cannot install cargo-fuzz (this is a failure, not a skip)" >&2; exit 1; }
fi
cargo fuzz --version

# A target directory of its own (instrumented builds never mix with the workspace's, nor with
# the full-speed builds of long runs, docs/reliability.md: their RUSTFLAGS differ).
export CARGO_TARGET_DIR="${LACQUER_FUZZ_TARGET_DIR:-$here/target/smoke}"
# The smoke build at opt-level 1 (LACQUER_FUZZ_OPT_LEVEL; cargo-fuzz puts RUSTFLAGS after its
# own flags and the profile's opt-level 3, so this one wins; a caller's RUSTFLAGS still come
# last). cargo-fuzz builds the core in one codegen unit under ASan and coverage instrumentation:
# built side by side from one fresh clone, opt-level 1 took 19 min 12 s and opt-level 3 24 min
# 12 s (its last 5 minutes alone), and the smoke run's executions hardly change (the replay of
# the committed corpora is ASan's and the allocator's time, not the kernels'; docs/reliability.md,
# "CI duration: session 32"). Long runs (docs/reliability.md) build at the profile's opt-level 3
# in fuzz/target.
opt_level="${LACQUER_FUZZ_OPT_LEVEL:-1}"
case "$opt_level" in
  0|1|2|3|s|z) ;;
  *) echo "fuzz/smoke.sh: LACQUER_FUZZ_OPT_LEVEL must be 0-3, s or z, got '$opt_level'" >&2; exit 2 ;;
esac
export RUSTFLAGS="-Copt-level=$opt_level${RUSTFLAGS:+ $RUSTFLAGS}"
# Only the batch kernels this machine runs (LACQUER_FUZZ_SIMD_KERNELS: avx512, avx2 or all;
# default: this CPU's best instruction set, the one the library's dispatch picks here). The
# smoke run never executes the other set's kernels, and leaving them out shortens the build,
# the CI run's longest pole (`--cfg lacquer_simd_kernels`, `SimdLevel::compiled`;
# docs/reliability.md, "CI duration: session 45"). Long runs build every kernel.
kernels="${LACQUER_FUZZ_SIMD_KERNELS:-}"
if [ -z "$kernels" ]; then
  kernels=all
  if [ "$(uname -m)" = x86_64 ] && [ -r /proc/cpuinfo ]; then
    cpu_flags="$(grep -m1 '^flags' /proc/cpuinfo || true)"
    if grep -qw avx512f <<<"$cpu_flags"; then
      kernels=avx512
    elif grep -qw avx2 <<<"$cpu_flags" && grep -qw fma <<<"$cpu_flags"; then
      kernels=avx2
    fi
  fi
fi
case "$kernels" in
  all) ;;
  avx2|avx512) RUSTFLAGS="$RUSTFLAGS --cfg lacquer_simd_kernels=\"$kernels\"" ;;
  *) echo "fuzz/smoke.sh: LACQUER_FUZZ_SIMD_KERNELS must be avx512, avx2 or all, got '$kernels'" >&2; exit 2 ;;
esac
echo "fuzz: batch kernels built: $kernels (and the scalar path); RUSTFLAGS=$RUSTFLAGS"
# One known false leak report (a rayon worker's thread-local teardown racing the leak check):
# suppressed by its innermost glibc frame only, see fuzz/lsan.supp.
export LSAN_OPTIONS="suppressions=$here/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
cargo +nightly fuzz build
if [ "$build_only" = 1 ]; then
  echo "fuzz: ${#targets[@]} targets built"
  exit 0
fi
work="$(mktemp -d "${TMPDIR:-/tmp}/lacquer-fuzz-smoke.XXXXXX")"
trap 'rm -rf "$work"' EXIT
# The targets run side by side, LACQUER_FUZZ_JOBS at a time (default: the number of cores):
# each is one libFuzzer process on one core (no -jobs: libFuzzer would fork and log to files),
# and most of a target's time is the replay of its committed corpus under ASan, so on two cores
# two at a time halves the step (docs/reliability.md, "CI duration, eighth pass").
jobs="${LACQUER_FUZZ_JOBS:-$(nproc 2>/dev/null || echo 1)}"
[ "$jobs" -ge 1 ] 2>/dev/null || { echo "fuzz/smoke.sh: LACQUER_FUZZ_JOBS must be a positive integer, got '$jobs'" >&2; exit 2; }
run_target() { # run_target T: fuzz target T for $seconds; its exit status goes to $work/T.rc
  local t="$1" rc=0
  mkdir -p "$work/$t" "$work/$t-artifacts"
  # The first corpus directory (writable) is the temporary one.
  cargo +nightly fuzz run "$t" "$work/$t" "corpus/$t" -- \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$work/$t-artifacts/" >"$work/$t.log" 2>&1 || rc=$?
  echo "$rc" >"$work/$t.rc"
}
running=0
for t in "${targets[@]}"; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n || true  # one target finished (its status is in its .rc file)
    running=$((running - 1))
  fi
  echo "=== fuzz $t: $seconds s"
  run_target "$t" &
  running=$((running + 1))
done
wait
failed=0
for t in "${targets[@]}"; do
  echo "=== fuzz $t"
  rc="$(cat "$work/$t.rc" 2>/dev/null || echo 'no status')"
  grep -E '^(Done [0-9]+ runs|stat::number_of_executed_units|stat::peak_rss_mb)' "$work/$t.log" || true
  runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/$t.log" | tail -1)"
  if [ "$rc" != 0 ] || [ -z "$runs" ] || [ "$runs" = 0 ]; then
    tail -40 "$work/$t.log" >&2
    echo "fuzz/smoke.sh: $t failed (exit $rc, ${runs:-no} executions)" >&2
    mkdir -p "$here/artifacts/$t"
    cp "$work/$t-artifacts"/* "$here/artifacts/$t/" 2>/dev/null || true
    echo "reproduce: cargo +nightly fuzz run $t fuzz/artifacts/$t/<file>" >&2
    failed=$((failed + 1))
  fi
done
[ "$failed" = 0 ] || { echo "fuzz: $((${#targets[@]} - failed)) passed, $failed failed" >&2; exit 1; }
echo "fuzz: ${#targets[@]} passed, 0 failed"
