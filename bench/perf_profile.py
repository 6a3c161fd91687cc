#!/usr/bin/env python3
"""Where one batch kernel's time goes on this CPU's own SIMD level (AVX-512 here), sampled.

    python3 bench/perf_profile.py gold_flake_8 eval                 # by the crate function
    python3 bench/perf_profile.py gold_flake_8 sample --by line
    python3 bench/perf_profile.py gold_flake_8 sample --by chain    # which call of a function costs
    python3 bench/perf_profile.py '<material JSON>' eval --binary /tmp/kernel_profile-old

`bench/instruction_mix.py` counts instructions exactly, but under valgrind, which has no
AVX-512: it sees the AVX2 kernels only. This runs `kernel_profile` (build it with line tables:
`cargo build --release -p lacquer --example kernel_profile --config
'profile.release.package.lacquer.debug=1'`) pinned to one CPU under `perf record -e
cpu-clock` (a software clock: virtual machines often have no hardware counters), takes the
samples inside the hottest symbol (the batch kernel, `KernelVisitor::visit::avx512_*`, when
the CPU has AVX-512) from `perf annotate`, and attributes each sampled instruction to the
innermost function (or source line) of this crate it was inlined from, as
`instruction_mix.py` does.

Read the shares as approximate: an out-of-order core charges a stall to the instructions
that wait for a slow result, not to the one they wait for, so a division's or a table
load's cost shows partly on the instructions after it. What the samples do show reliably is
work that should not be there at all (session 41 found a `D` the value never reads: 10 % of
`gold_flake_8`'s eval). Times move 10–30 % from run to run on a shared host; compare two
builds with alternated `kernel_profile` runs (docs/speed.md), not with this.
Needs perf, addr2line (binutils) and taskset.
"""

import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from instruction_mix import kernel_profile_parser, require_binary, tally_by_label  # noqa: E402


def run_perf(binary, material, op, n, reps, cpu, out):
    """Records `kernel_profile` under perf; returns its own ns/element line."""
    cmd = ["taskset", "-c", str(cpu), "perf", "record", "-q", "-e", "cpu-clock", "-F", "20000", "-o", out,
           binary, material, op, str(n), str(reps)]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"perf record failed ({run.returncode}):\n{run.stderr[-2000:]}")
    timing = [line for line in (run.stdout + run.stderr).splitlines() if "ns/element" in line]
    return timing[0] if timing else ""


def hottest_symbol(data):
    """The symbol with the most samples and its share of all samples."""
    rep = subprocess.run(["perf", "report", "-i", data, "--stdio", "--sort", "sym"], capture_output=True, text=True)
    for line in rep.stdout.splitlines():
        m = re.match(r"\s*([0-9.]+)%\s+\[\.\]\s+(.*\S)", line)
        if m:
            return m.group(2), float(m.group(1))
    sys.exit(f"no samples in user code:\n{rep.stderr[-2000:]}")


def sampled_addresses(data, symbol):
    """{address: percent of the symbol's samples} from perf annotate."""
    ann = subprocess.run(["perf", "annotate", "-i", data, "--stdio", "--no-source", "-s", symbol],
                         capture_output=True, text=True).stdout
    out = {}
    for line in ann.splitlines():
        m = re.match(r"\s*([0-9.]+)\s+:\s+([0-9a-f]+):", line)
        if m and float(m.group(1)) > 0:
            out[int(m.group(2), 16)] = float(m.group(1))
    if not out:
        sys.exit(f"perf annotate gave no sampled instructions for {symbol}")
    return out


def main():
    # 65536 elements × 600 calls: about 30 000 samples.
    ap = kernel_profile_parser(__doc__, 65536, 600, ["function", "line", "chain"])
    ap.add_argument("--cpu", type=int, default=1, help="the CPU to pin to (default 1)")
    args = ap.parse_args()
    require_binary(args.binary)
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "perf.data")
        timing = run_perf(args.binary, args.material, args.op, args.n, args.reps, args.cpu, data)
        symbol, share = hottest_symbol(data)
        shares = sampled_addresses(data, symbol)
    tally = tally_by_label(args.binary, shares, args.by)
    print(f"{args.material}: {timing.strip()}")
    print(f"hottest symbol ({share:.1f} % of the samples): {symbol}")
    what = {"function": "function", "line": "source line",
            "chain": "function and the crate functions it was inlined into (innermost first)"}[args.by]
    print(f"percent of that symbol's samples, by the innermost crate {what} (approximate: see --help)")
    for label, pct in tally.most_common(args.top):
        print(f"{pct:6.2f} %  {label}")


if __name__ == "__main__":
    main()
