#!/usr/bin/env python3
"""Two or more builds of one batch kernel timed side by side, alternated, on one pinned CPU.

    cp target/release/examples/kernel_profile /tmp/kp-old      # before the change
    cargo build --release -p lacquer --example kernel_profile  # after it
    python3 bench/kernel_ab.py /tmp/kp-old target/release/examples/kernel_profile \\
        --material gold_flake_8 --material solid_red --op eval --op sample

On a shared host a kernel's time moves 10–30 % from run to run, and the load changes over
minutes, so two builds timed one after the other can differ by more than a change's effect.
This runs each build's `kernel_profile <material> <op> <n> <reps>` in turn, `--rounds` times
(ABAB…), pinned to `--cpu`, and prints every run's CPU ns per element of the kernel thread and
each build's minimum: the figures docs/speed.md quotes as "alternated". For a change that must
not alter any value, `bench/compare_libraries.py` compares two libraries bit for bit; for
instruction counts, `bench/instruction_mix.py`.
"""

import argparse
import os
import re
import subprocess
import sys


def ns_per_element(binary, material, op, n, reps, cpu, layout, caches):
    """The CPU ns per element of `kernel_profile`'s kernel thread (wall ns for cold caches); exits
    with its output when it fails."""
    run = subprocess.run(["taskset", "-c", str(cpu), binary, material, op, str(n), str(reps), "1", layout, caches],
                         capture_output=True, text=True)
    # Warm runs: the kernel thread's CPU time; cold ones print wall time only (kernel_profile).
    m = re.search(r"([0-9.]+) ns/element of this thread", run.stdout + run.stderr) or \
        re.search(r"([0-9.]+) ns/element wall", run.stdout + run.stderr)
    if run.returncode != 0 or not m:
        sys.exit(f"{binary} {material} {op} failed ({run.returncode}):\n{(run.stdout + run.stderr)[-1500:]}")
    return float(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("binaries", nargs="+", help="kernel_profile builds to compare (two or more)")
    ap.add_argument("--material", action="append", help="preset name or material JSON (repeatable; "
                                                         "default gold_flake_8)")
    ap.add_argument("--op", action="append", choices=["eval", "pdf", "eval_pdf", "sample"],
                    help="operation (repeatable; default eval, pdf, sample)")
    ap.add_argument("--n", type=int, default=65536, help="elements per call (default 65536)")
    ap.add_argument("--reps", type=int, default=200, help="calls per run (default 200)")
    ap.add_argument("--rounds", type=int, default=3, help="alternations (default 3)")
    ap.add_argument("--cpu", type=int, default=1, help="the CPU to pin to (default 1)")
    ap.add_argument("--layout", choices=["soa", "xyz"], default="soa", help="array layout (default soa)")
    ap.add_argument("--caches", choices=["warm", "cold"], default="warm",
                    help="cold: 256 MiB of other memory written before each call (kernel_profile's `cold`)")
    args = ap.parse_args()
    if len(args.binaries) < 2:
        sys.exit("give two or more kernel_profile builds")
    for b in args.binaries:
        if not os.access(b, os.X_OK):
            sys.exit(f"{b} is not an executable kernel_profile build")
    base = [os.path.basename(b) for b in args.binaries]
    names = base if len(set(base)) == len(base) else args.binaries
    print(f"CPU ns per element of the kernel thread (cold: wall ns), cpu {args.cpu}, n = {args.n}, {args.reps} calls per run, "
          f"{args.rounds} alternated rounds, {args.layout} layout, {args.caches} caches; min per build")
    for material in args.material or ["gold_flake_8"]:
        for op in args.op or ["eval", "pdf", "sample"]:
            runs = [[] for _ in args.binaries]
            for _ in range(args.rounds):
                for k, b in enumerate(args.binaries):
                    runs[k].append(ns_per_element(b, material, op, args.n, args.reps, args.cpu, args.layout, args.caches))
            cells = "  ".join(f"{name}: min {min(r):.2f} ({', '.join(f'{v:.2f}' for v in r)})"
                              for name, r in zip(names, runs))
            label = material if len(material) <= 40 else material[:37] + "..."
            print(f"{label} {op}: {cells}")


if __name__ == "__main__":
    main()
