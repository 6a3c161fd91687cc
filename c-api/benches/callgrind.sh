#!/usr/bin/env bash
# Instructions per element of the C ABI against the Rust API (eval and sample, f32, Lambert),
# for n = 1 and n = 10^6, counted by callgrind: unlike wall time, the counts do not depend on
# what else the machine is doing. Needs valgrind; builds the release library and the bench.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
cd "$root"
cargo build --release -p lacquer-capi --quiet
bench="$(cargo bench -p lacquer-capi --bench overhead --no-run --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*overhead[^"]*\)".*/\1/p' | tail -1)"
[ -x "$bench" ] || { echo "bench binary not found" >&2; exit 1; }
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
printf '%-8s %-11s %12s %12s %10s\n' n call rust_api c_abi overhead
for n in 1 1000000; do
    LACQUER_OVERHEAD_COUNT=$n valgrind --tool=callgrind --callgrind-out-file="$out/cg.$n" \
        --toggle-collect='overhead::count_*' "$bench" >/dev/null 2>&1
    elements=$(( n == 1 ? 100000 : n ))
    for v in eval sample; do
        get() { callgrind_annotate --inclusive=yes "$out/cg.$n" 2>/dev/null |
            awk -v f="overhead::count_$1_$v " 'index($0, f) && !done { gsub(",", "", $1); print $1; done = 1 }'; }
        r="$(get rust)"; c="$(get capi)"
        awk -v n="$n" -v v="$v" -v r="$r" -v c="$c" -v e="$elements" \
            'BEGIN { printf "%-8s %-11s %12.1f %12.1f %+10.1f  instructions/element\n", n, v, r/e, c/e, (c-r)/e }'
        if [ "$n" = 1 ]; then # the one-element functions lq_eval_one / lq_sample_one
            o="$(get capi_one)"
            awk -v v="${v}_one" -v r="$r" -v c="$o" -v e="$elements" \
                'BEGIN { printf "%-8s %-11s %12.1f %12.1f %+10.1f  instructions/element\n", 1, v, r/e, c/e, (c-r)/e }'
        fi
    done
done
