#!/usr/bin/env python3
"""Instructions per element of one batch kernel, counted exactly (not timed).

    python3 bench/instruction_mix.py gold_flake_8 eval                 # by mnemonic
    python3 bench/instruction_mix.py gold_flake_8 eval --by function   # by the crate function
    python3 bench/instruction_mix.py '<material JSON>' pdf --by line --only vcvtsd2ss,vdivps

Times on a shared 2-core host move by 10-30 % from run to run, so a change of a few per cent
in a kernel cannot be seen in one timing; the number of instructions it executes per element
can. This runs `kernel_profile` (build it first: `cargo build --release -p lacquer --example
kernel_profile`) under valgrind's callgrind, counting only inside the batch kernel
(`KernelVisitor::visit::avx2`), and reports instructions per element: in total, by mnemonic,
or attributed to the innermost function (or source line) of this crate that the instruction
was inlined from (`addr2line -i`; the lane types' own code is attributed to their caller).

`--by function` and `--by line` need the core's line tables, which the release profile leaves
out (Cargo.toml: `[profile.release.package.lacquer] debug = 0`, for the CI's memory): build
the example with `cargo build --release -p lacquer --example kernel_profile --config
'profile.release.package.lacquer.debug=1'` (the tool stops with this hint when the binary
has none).

valgrind has no AVX-512, so the count is the AVX2 path's (`LACQUER_SIMD=avx2`; the AVX-512
kernels come from the same source, with 16 lanes, register-permute lookups instead of gathers
and the conductor Fresnel fit). Needs valgrind, objdump and addr2line (binutils).
"""

import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KERNEL = "*KernelVisitor*visit::avx2*"


def callgrind_counts(binary, material, op, n, reps):
    """Executed instructions per address of `binary` inside the AVX2 batch kernel."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        env = dict(os.environ, LACQUER_SIMD="avx2")
        cmd = ["valgrind", "--tool=callgrind", "--dump-instr=yes", f"--toggle-collect={KERNEL}",
               f"--callgrind-out-file={out}", binary, material, op, str(n), str(reps)]
        run = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"valgrind failed ({run.returncode}):\n{run.stderr[-2000:]}")
        lines = open(out).read().splitlines()
    names, counts = {}, collections.Counter()
    current, last, after_call = None, 0, False
    base = os.path.basename(binary)
    for line in lines:
        m = re.match(r"c?ob=\((\d+)\)\s*(.*)", line)
        if m:
            if m.group(2):
                names[m.group(1)] = m.group(2)
            if line.startswith("ob="):
                current = names.get(m.group(1))
            continue
        if line.startswith("calls="):
            after_call = True  # the next cost line is the call's inclusive cost
            continue
        m = re.match(r"^(0x[0-9a-f]+|[+-]\d+|\*)\s+\S+\s+(\d+)$", line)
        if not m:
            continue
        pos = m.group(1)
        last = int(pos, 16) if pos.startswith("0x") else last if pos == "*" else last + int(pos)
        if after_call:
            after_call = False
            continue
        if current and os.path.basename(current) == base:
            counts[last] += int(m.group(2))
    if not counts:
        sys.exit(f"no instructions counted inside {KERNEL}: is {binary} a kernel_profile build?")
    return counts


def mnemonics(binary, addresses):
    lo, hi = min(addresses), max(addresses)
    dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", f"--start-address={lo}",
                          f"--stop-address={hi + 16}", binary], capture_output=True, text=True).stdout
    out = {}
    for line in dis.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(\S+)", line)
        if m:
            out[int(m.group(1), 16)] = m.group(2)
    return out


CHAIN_DEPTH = 4


def attribution(binary, addresses, by):
    """The innermost function (or file:line) of this crate each address was inlined from; with
    `by == "chain"` that function and the crate functions it was inlined into, each with the line
    of the call, up to `CHAIN_DEPTH` deep (which of several calls of one function costs)."""
    addresses = list(addresses)
    out = {}
    for start in range(0, len(addresses), 2000):
        chunk = addresses[start:start + 2000]
        text = subprocess.run(["addr2line", "-a", "-i", "-f", "-C", "-e", binary] + [hex(a) for a in chunk],
                              capture_output=True, text=True).stdout.splitlines()
        frames, current = {}, None
        for line in text:
            if re.fullmatch(r"0x[0-9a-f]+", line):
                current = int(line, 16)
                frames[current] = []
            elif current is not None:
                frames[current].append(line)
        for a, fr in frames.items():
            crate = [(fn, loc) for fn, loc in zip(fr[0::2], fr[1::2])
                     if "/rust-core/src/" in loc and not re.search(r"/lanes/|/real\.rs|/math\.rs", loc)]
            if not crate:
                out[a] = "?"
            elif by == "line":
                out[a] = re.sub(r".*/rust-core/src/", "", crate[0][1]).split(" ")[0]
            elif by == "chain":
                out[a] = " < ".join(f"{short_name(fn)} ({re.sub(r'.*/rust-core/src/', '', loc).split(' ')[0]})"
                                    for fn, loc in crate[:CHAIN_DEPTH])
            else:
                out[a] = re.sub(r"<[^<>]*>", "", re.sub(r"<[^<>]*>", "", crate[0][0]))
    return out


def short_name(fn):
    """`Type::method` of a demangled path (generic arguments and the crate's modules dropped)."""
    parts = re.sub(r"<[^<>]*>", "", re.sub(r"<[^<>]*>", "", fn)).split("::")
    return "::".join(parts[-2:]) if len(parts) > 1 and parts[-2][:1].isupper() else parts[-1]


def tally_by_label(binary, weights, by):
    """`weights` ({address: count or share}) summed by `attribution`'s label; stops with the
    build command when the binary has no line tables for the core."""
    labels = attribution(binary, weights, by)
    if weights and all(label == "?" for label in labels.values()):
        sys.exit(f"{binary} has no line tables for the core (release builds leave them out): "
                 "cargo build --release -p lacquer --example kernel_profile "
                 "--config 'profile.release.package.lacquer.debug=1'")
    tally = collections.Counter()
    for a, w in weights.items():
        tally[labels.get(a, "?")] += w
    return tally


def kernel_profile_parser(doc, n, reps, by):
    """The arguments this tool and `perf_profile.py` share: the material, the operation, the
    call size and count, the attribution (`by`: the choices, the first the default) and the
    `kernel_profile` binary."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("material", help="preset name or material JSON")
    ap.add_argument("op", choices=["eval", "pdf", "eval_pdf", "sample"])
    ap.add_argument("--n", type=int, default=n, help=f"elements per call (default {n})")
    ap.add_argument("--reps", type=int, default=reps, help=f"calls (default {reps})")
    ap.add_argument("--by", choices=by, default=by[0])
    ap.add_argument("--top", type=int, default=30)
    ap.add_argument("--binary", default=os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")),
                                                     "release", "examples", "kernel_profile"))
    return ap


def require_binary(binary):
    """Stops with the build command when `kernel_profile` is missing."""
    if not os.path.exists(binary):
        sys.exit(f"{binary} is missing: cargo build --release -p lacquer --example kernel_profile "
                 "--config 'profile.release.package.lacquer.debug=1'")


def main():
    ap = kernel_profile_parser(__doc__, 8192, 4, ["mnemonic", "function", "line", "chain"])
    ap.add_argument("--only", help="comma-separated mnemonics to count (with --by function|line|chain)")
    args = ap.parse_args()
    require_binary(args.binary)
    counts = callgrind_counts(args.binary, args.material, args.op, args.n, args.reps)
    elements = args.n * args.reps
    total = sum(counts.values())
    mn = mnemonics(args.binary, counts)
    print(f"{args.material} {args.op}, AVX2 path: {total / elements:.1f} instructions per element "
          f"({total} in {elements} elements)")
    if args.by == "mnemonic":
        tally = collections.Counter()
        for a, c in counts.items():
            tally[mn.get(a, "?")] += c
    else:
        only = set(args.only.split(",")) if args.only else None
        chosen = {a: c for a, c in counts.items() if only is None or mn.get(a) in only}
        tally = tally_by_label(args.binary, chosen, args.by)
    for label, c in tally.most_common(args.top):
        print(f"{c / elements:8.2f}  {100 * c / total:5.1f} %  {label}")


if __name__ == "__main__":
    main()
