#!/usr/bin/env python3
"""Lacquer's batch calls (C ABI, through ctypes) timed with warm caches and after an eviction.

    python3 bench/cold_calls.py                                  # GGX conductor, the default library
    python3 bench/cold_calls.py --material gold_flake_8 --op eval --op sample
    python3 bench/cold_calls.py --library /tmp/old/liblacquer.so # another build, for an A/B

`bench/vs_mitsuba.py` alternates Lacquer's calls with Mitsuba's, whose arrays push Lacquer's
out of the last-level cache, so its Lacquer times are times from memory; a loop of calls
alone finds its arrays in cache. This runs each call `--reps` times in a loop of its own
("warm") and then with `--evict-mb` MiB of other memory written before each call ("cold"),
pinned to `--cpu`, and prints the min and median ns per element of each, next to numpy's
`add` of the same direction arrays (reads 6 and writes 3 floats per element: the memory
floor of `vs_mitsuba.py`). Inputs as in `vs_mitsuba.py` (10⁶ cosine-distributed pairs).

Runs in the venv of scripts/python-env.sh (numpy; it re-executes itself there), with
$LACQUER_LIBRARY or target/release/liblacquer.so unless --library is given.
"""

import argparse
import json
import os
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
import vs_mitsuba  # noqa: E402  (its ctypes binding and inputs; Mitsuba is imported only by its main)

GGX = {"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2,
       "eta": vs_mitsuba.AU_ETA, "k": vs_mitsuba.AU_K}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--library", help="liblacquer.so (default $LACQUER_LIBRARY, else target/release)")
    ap.add_argument("--material", default=None,
                    help="preset name or material JSON (default: the GGX conductor of vs_mitsuba.py)")
    ap.add_argument("--op", action="append", choices=["eval", "pdf", "sample", "eval_soa", "pdf_soa"],
                    help="calls to time (repeatable; default eval, pdf, sample, eval_soa)")
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--cpu", type=int, default=0)
    ap.add_argument("--evict-mb", type=int, default=300, help="memory written before each cold call (MiB)")
    args = ap.parse_args()
    try:
        import numpy as np
    except ImportError:
        proc = vs_mitsuba.subprocess.run(["bash", str(ROOT / "scripts" / "python-env.sh")], check=True,
                                         stdout=vs_mitsuba.subprocess.PIPE, text=True)
        python = os.path.join(proc.stdout.strip().splitlines()[-1], "bin", "python")
        os.execv(python, [python, os.path.abspath(__file__), *sys.argv[1:]])

    library = args.library or os.environ.get("LACQUER_LIBRARY") or str(ROOT / "target" / "release" / "liblacquer.so")
    if not os.path.isfile(library):
        sys.exit(f"{library} does not exist: cargo build --release -p lacquer-capi -p lacquer-cli")
    os.sched_setaffinity(0, {args.cpu})
    lq = vs_mitsuba.Lacquer(library)
    lq.set_threads(1)
    n = args.n
    inp = vs_mitsuba.make_inputs(np, n, 1)
    spec = args.material
    spec = GGX if spec is None else (json.loads(spec) if spec.lstrip().startswith("{") else {"preset": spec})
    m = lq.material(spec)
    f32 = np.float32
    f, pdf = np.zeros((n, 3), f32), np.zeros(n, f32)
    s_wi, s_w, s_pdf = np.zeros((n, 3), f32), np.zeros((n, 3), f32), np.zeros(n, f32)
    f_soa = [np.zeros(n, f32) for _ in range(3)]
    p, L = vs_mitsuba.ptr, lq.lib
    wi_soa, wo_soa = [p(a) for a in inp["wi_soa"]], [p(a) for a in inp["wo_soa"]]
    calls = {
        "eval": lambda: L.lq_eval(m, n, p(inp["wi"]), p(inp["wo"]), p(f)),
        "pdf": lambda: L.lq_pdf(m, n, p(inp["wi"]), p(inp["wo"]), p(pdf)),
        "sample": lambda: L.lq_sample(m, n, p(inp["wo"]), p(inp["u"]), p(s_wi), p(s_w), p(s_pdf)),
        "eval_soa": lambda: L.lq_eval_soa(m, n, *wi_soa, *wo_soa, None, *[p(a) for a in f_soa]),
        "pdf_soa": lambda: L.lq_pdf_soa(m, n, *wi_soa, *wo_soa, None, p(pdf)),
    }
    floor_out = np.empty_like(inp["wi"])
    calls["numpy add (floor)"] = lambda: np.add(inp["wi"], inp["wo"], out=floor_out)
    source, junk = np.ones(args.evict_mb << 18, f32), np.empty(args.evict_mb << 18, f32)

    print(f"{library} ({lq.version}), {json.dumps(spec)}, n = {n}, cpu {args.cpu}, "
          f"min / median of {args.reps} calls, ns per element")
    for name in (args.op or ["eval", "pdf", "sample", "eval_soa"]) + ["numpy add (floor)"]:
        call, cells = calls[name], []
        for cold in (False, True):
            call()
            call()
            times = []
            for _ in range(args.reps):
                if cold:
                    np.copyto(junk, source)
                time.sleep(0.03)
                t0 = time.perf_counter_ns()
                status = call()
                times.append(time.perf_counter_ns() - t0)
                if name != "numpy add (floor)":
                    lq.check(status, name)
            times.sort()
            cells.append(f"{'cold' if cold else 'warm'} {times[0] / n:.2f} / {times[len(times) // 2] / n:.2f}")
        print(f"  {name:18s} {'   '.join(cells)}")


if __name__ == "__main__":
    main()
