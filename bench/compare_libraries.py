#!/usr/bin/env python3
"""Are two builds of liblacquer.so bit-identical on the batch calls? For speed work that must
not change a value (a refactoring, a skipped computation, a cheaper test).

    python3 bench/compare_libraries.py OLD/liblacquer.so NEW/liblacquer.so
    python3 bench/compare_libraries.py OLD.so NEW.so --simd avx2 --n 50000

Evaluates `lq_eval`, `lq_pdf` and `lq_sample` (interleaved f32) of both libraries on the same
random inputs for a set of materials (the paint presets and variants that reach the optional
lobes: pigment only, metal base, rough and smooth coats; Beckmann models), at each SIMD level
(`LACQUER_SIMD`: scalar, avx2, avx512 where the CPU has it; one subprocess per level, since a
library reads the variable once), and compares the outputs bit for bit. Inputs include lanes
below the horizon, near the normal, at grazing angles and mirror pairs. Prints the arrays that
differ (count and largest relative difference) and exits 1 if any does. Needs numpy.
"""

import argparse
import ctypes
import json
import os
import subprocess
import sys

import numpy as np

MATERIALS = [{"preset": p} for p in ("solid_red", "solid_black", "gold_flake_8", "silver_flake_8", "pearl_white")] + [
    {"model": "coated_paint", "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "coat_roughness": 0.3},
    {"model": "coated_paint", "flake_density": 8, "coat_roughness": 0.2},
    {"model": "coated_paint", "coat_roughness": 0.0},
    {"model": "rough_conductor", "distribution": "beckmann", "alpha_u": 0.3, "alpha_v": 0.1},
    {"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2},
    {"model": "cook_torrance", "distribution": "beckmann", "alpha": 0.2},
    {"model": "rough_plastic", "distribution": "beckmann", "alpha": 0.2},
    {"model": "principled", "base_color": [0.8, 0.3, 0.2], "roughness": 0.5, "metallic": 0.5, "coat_weight": 0.5},
]


def inputs(n, seed=7):
    rng = np.random.default_rng(seed)

    def directions():
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1)[:, None]
        v[:, 2] = np.where(rng.random(n) < 0.95, np.abs(v[:, 2]), v[:, 2])  # 5 % below
        k = n // 20
        v[:k] = [1e-4, 2e-4, 1.0]  # near the normal
        v[k:2 * k, 2] = 1e-3  # grazing
        v[: 2 * k] /= np.linalg.norm(v[: 2 * k], axis=1)[:, None]
        return v.astype(np.float32)

    wi, wo = directions(), directions()
    wo[: n // 40] = wi[: n // 40] * np.array([-1, -1, 1], np.float32)  # mirror pairs
    return wi, wo, rng.random((n, 3)).astype(np.float32)


def outputs(path, n):
    """Every material's eval, pdf and sample outputs of the library at `path`."""
    lib = ctypes.CDLL(path)
    P, N = ctypes.c_void_p, ctypes.c_size_t
    lib.lq_material_from_json.argtypes = [ctypes.c_char_p, ctypes.POINTER(P)]
    lib.lq_material_free.argtypes = [P]
    lib.lq_last_error.restype = ctypes.c_char_p
    for name, k in (("lq_eval", 5), ("lq_pdf", 5), ("lq_sample", 7)):
        getattr(lib, name).argtypes = [P, N] + [P] * (k - 2)
        getattr(lib, name).restype = ctypes.c_int32
    wi, wo, u = inputs(n)
    ptr = lambda a: ctypes.c_void_p(a.ctypes.data)  # noqa: E731
    out = {}
    for i, spec in enumerate(MATERIALS):
        m = P()
        if lib.lq_material_from_json(json.dumps(spec).encode(), ctypes.byref(m)) != 0:
            sys.exit(f"{path}: {spec}: {lib.lq_last_error().decode()}")
        f, p = np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
        swi, sw, sp = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
        # Status codes are compared too: a call that reports bad input must do so in both.
        status = [lib.lq_eval(m, n, ptr(wi), ptr(wo), ptr(f)), lib.lq_pdf(m, n, ptr(wi), ptr(wo), ptr(p)),
                  lib.lq_sample(m, n, ptr(wo), ptr(u), ptr(swi), ptr(sw), ptr(sp))]
        lib.lq_material_free(m)
        tag = json.dumps(spec)
        out.update({f"{tag} eval": f, f"{tag} pdf": p, f"{tag} sample wi": swi, f"{tag} sample weight": sw,
                    f"{tag} sample pdf": sp, f"{tag} status": np.array(status, np.int32)})
    return out


def compare_at_level(old, new, n):
    a, b = outputs(old, n), outputs(new, n)
    differing = 0
    for key in a:
        same = a[key].view(np.uint32) == b[key].view(np.uint32)
        if not same.all():
            x, y = a[key].astype(np.float64), b[key].astype(np.float64)
            with np.errstate(invalid="ignore", divide="ignore"):
                rel = np.abs(x - y) / np.maximum(np.abs(x), 1e-30)
            print(f"  {key}: {(~same).sum()} of {same.size} differ, largest relative difference "
                  f"{np.nanmax(np.where(same, 0.0, rel)):.3g}")
            differing += 1
    return differing


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--n", type=int, default=200_000, help="direction pairs per material (default 2e5)")
    ap.add_argument("--simd", help="one level only (scalar, avx2, avx512); default: every level the CPU has")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    for path in (args.old, args.new):
        if not os.path.isfile(path):
            sys.exit(f"no such library: {path}")
    if args.child:
        sys.exit(1 if compare_at_level(args.old, args.new, args.n) else 0)
    levels = [args.simd] if args.simd else ["scalar"] + [
        lvl for lvl, flag in (("avx2", "avx2"), ("avx512", "avx512f"))
        if flag in open("/proc/cpuinfo").read().split()]
    failed = []
    for level in levels:
        print(f"LACQUER_SIMD={level}: {len(MATERIALS)} materials x {args.n} pairs, eval / pdf / sample")
        env = dict(os.environ, LACQUER_SIMD=level)
        rc = subprocess.run([sys.executable, __file__, args.old, args.new, "--n", str(args.n), "--child"], env=env).returncode
        print(f"  {'bit-identical' if rc == 0 else 'DIFFERENT'}")
        if rc != 0:
            failed.append(level)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
