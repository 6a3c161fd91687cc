#!/usr/bin/env python3
"""Calls out of the SIMD batch kernels: what a kernel calls instead of inlining, counted from
the machine code (not timed).

    python3 bench/kernel_calls.py                       # target/release/liblacquer.so
    python3 bench/kernel_calls.py target/release/examples/kernel_profile

A closure or a plain function called from lane-generic code is compiled without the batch
kernel's `#[target_feature]`; where the (very large) kernel does not inline it, every SIMD
intrinsic inside it becomes a call of its own (session 39: the metal base's bounce series ran
the paint's AVX-512 eval at 98 ns per element instead of 14). This lists, per kernel
(`…KernelVisitor>::visit::{avx2,avx512}_{eval_pdf,sample}`), the functions it calls, and
exits 1 if any of them is a SIMD intrinsic (`core::core_arch::x86::…`) or calls one: the
kernels' own helpers must be inlined or run through `Lanes::outlined`. Known calls that were
measured and kept are listed without the mark (the list in `main`).
Needs objdump (binutils).
"""

import collections
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KERNEL = re.compile(r"KernelVisitor>::visit::(avx2|avx512)(_eval_pdf|_sample)?$")


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release", "liblacquer.so")
    if not os.path.exists(binary):
        sys.exit(f"{binary} is missing: cargo build --release -p lacquer-capi")
    dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", "-C", binary],
                         capture_output=True, text=True, check=True).stdout
    # Position-independent code calls many functions through the GOT (`call *slot(%rip)`):
    # the slot's relative relocation holds the function's address.
    relocs = subprocess.run(["objdump", "-R", binary], capture_output=True, text=True).stdout
    slot_target = {int(a, 16): int(t, 16) for a, t in
                   re.findall(r"^([0-9a-f]+)\s+R_X86_64_RELATIVE\s+\*ABS\*\+0x([0-9a-f]+)", relocs, re.M)}
    slot_symbol = {int(a, 16): n for a, n in
                   re.findall(r"^([0-9a-f]+)\s+R_X86_64_(?:GLOB_DAT|JUMP_SLOT|64)\s+(\S+)", relocs, re.M)}
    starts = {int(a, 16): n for a, n in re.findall(r"^([0-9a-f]+) <(.*)>:$", dis, re.M)}
    calls = collections.defaultdict(collections.Counter)  # caller -> callee -> count
    current = None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if m:
            current = m.group(1)
            continue
        if not current:
            continue
        m = re.search(r"\bcall\s+[0-9a-f]+ <(.*)>", line)
        if m:
            calls[current][m.group(1)] += 1
            continue
        m = re.search(r"\bcall\s+\*0x[0-9a-f]+\(%rip\)\s+# ([0-9a-f]+)", line)
        if m:
            slot = int(m.group(1), 16)
            target = slot_target.get(slot)
            name = starts.get(target) if target is not None else slot_symbol.get(slot)
            calls[current][name or f"(through the GOT slot {hex(slot)})"] += 1
    kernels = [f for f in calls if KERNEL.search(f)]
    if not kernels and not any(KERNEL.search(f) for f in re.findall(r"^[0-9a-f]+ <(.*)>:$", dis, re.M)):
        sys.exit(f"no batch kernels in {binary}")
    intrinsic = lambda f: "core::core_arch::x86::" in f
    # Measured and kept (docs/speed.md, "Session 39"): the anisotropic energy-compensation
    # tables' per-lane scalar lookup (by design), the AVX-512 64-entry table lookup's `pick`
    # and `Rgb`'s operator closures (written out, the paints' kernels were 2-11 % slower: the
    # calls sit on rare paths and keep their registers out of the kernel's allocation), and
    # the batch report's status bookkeeping (once per lane group, outside the model).
    # `Rgb`'s `Add` closure joined them in session 43 (3 calls in the per-element paint's AVX-512
    # sampler, right after 3 of the kept `Mul<T>` ones: the same `a * s + b`, once the batch
    # loops' prefetching moved the inliner's budget); `lq_sample_varying` of `gold_flake_8`
    # with per-element parameters took 78.9 / 82.0 ns per element with and without it (the
    # first library loaded was the faster in both orders): the rare path again.
    known = ("Compensation::loss_lanes::{{closure}}", "lookup_pairs_f32_::{{closure}}",
             "as core::ops::arith::Mul>::mul::{{closure}}", "as core::ops::arith::Mul<T>>::mul::{{closure}}",
             "as core::ops::arith::Add>::add::{{closure}}", "BatchReport::record")
    bad = 0
    for k in sorted(set(re.findall(r"^[0-9a-f]+ <(.*)>:$", dis, re.M))):
        if not KERNEL.search(k):
            continue
        name = KERNEL.search(k).group(0).split("::")[-1]
        print(f"{name}:")
        if not calls.get(k):
            print("    (no calls)")
        for callee, n in calls.get(k, {}).most_common():
            inner = sum(c for f, c in calls.get(callee, {}).items() if intrinsic(f))
            flag = intrinsic(callee) or inner > 0
            allowed = flag and any(k in callee for k in known)
            bad += flag and not allowed
            note = f" (calls {inner} SIMD intrinsics out of line{'; known, kept' if allowed else ''})" if inner else ""
            print(f"  {'  ' if allowed or not flag else '!!'} {n:5d} × {callee[:150]}{note}")
    if bad:
        sys.exit(f"{bad} callee(s) of the batch kernels run SIMD intrinsics out of line (marked !!)")
    print("no SIMD intrinsic runs out of line from the batch kernels but the known ones")


if __name__ == "__main__":
    main()
