#!/usr/bin/env python3
"""ns per lane of BSDF.eval and BSDF.sample in llvm_ad_rgb or llvm_ad_spectral (--variant): the
lacquer plugin against Mitsuba's built-in BSDF for the same material (GGX gold alpha 0.2:
roughconductor; Lambert: diffuse), on
the same evaluated arrays of N lanes (default 1e6). A call is timed from the method call to its
outputs being evaluated (dr.eval + dr.sync_thread); the inputs are evaluated beforehand. The
first call of each configuration (kernel compilation) is not timed; the minimum over --repeat
calls is reported. In llvm_ad_spectral each lane has four random wavelengths in 360-830 nm, and
two paints without a built-in are added: a pearl paint (spectral physics: lq_eval_spectral /
lq_sample_spectral at the lanes' wavelengths) and a paint without pearl (the RGB batched path,
upsampled per lane); in llvm_ad_rgb the same two paints run the RGB path.

Run (after mitsuba-plugin/build.sh; needs DRJIT_LIBLLVM_PATH, see test.sh):
    .venv-mitsuba/bin/python mitsuba-plugin/bench/bsdf_lanes.py [--lanes 1000000 --repeat 10]
        [--variant llvm_ad_spectral] [--paints]   (--paints: add the two paints)
        [--core]   (llvm_ad_spectral: also time the C ABI's lq_eval_spectral on the same arrays,
                    one call on the calling thread, through liblacquer.so: $LACQUER_LIBRARY)
Prints a Markdown table; --json PATH also writes the figures.
"""

import argparse
import json
import os
import time

import drjit as dr
import mitsuba as mi
import numpy as np

AU_ETA = [0.143119, 0.374957, 1.44248]
AU_K = [3.98316, 2.38572, 1.60322]
MATERIALS = {
    "ggx_gold": ({"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2,
                  "eta": AU_ETA, "k": AU_K},
                 {"type": "roughconductor", "distribution": "ggx", "alpha": 0.2,
                  "eta": {"type": "rgb", "value": AU_ETA}, "k": {"type": "rgb", "value": AU_K}}),
    "lambert": ({"model": "lambert", "albedo": [0.7, 0.5, 0.3]},
                {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.5, 0.3]}}),
}
#: Paints without a built-in counterpart (--paints).
PAINTS = {
    "pearl_paint": ({"model": "coated_paint", "pearl_density": 30, "pearl_film_nm": 300, "flake_density": 3,
                     "coat_roughness": 0.1}, None),
    "paint_no_pearl": ({"model": "coated_paint", "base_color": [0.5, 0.1, 0.05], "flake_density": 5,
                        "coat_roughness": 0.1}, None),
}


def hemisphere(rng, n):
    """Directions on the upper hemisphere, uniform in solid angle."""
    z = rng.random(n, dtype=np.float32)
    phi = rng.random(n, dtype=np.float32) * np.float32(2 * np.pi)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return mi.Vector3f(mi.Float(r * np.cos(phi)), mi.Float(r * np.sin(phi)), mi.Float(z))


def timed(fn, repeat):
    fn()  # compiles the kernels
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lanes", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--json", default=None)
    ap.add_argument("--variant", default="llvm_ad_rgb", choices=["llvm_ad_rgb", "llvm_ad_spectral"])
    ap.add_argument("--paints", action="store_true")
    ap.add_argument("--core", action="store_true")
    args = ap.parse_args()

    mi.set_variant(args.variant)
    import lacquer_mitsuba
    lacquer_mitsuba.register(fallback=False)

    n = args.lanes
    rng = np.random.default_rng(1)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = hemisphere(rng, n)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    if args.variant == "llvm_ad_spectral":
        si.wavelengths = mi.Spectrum(*[mi.Float(rng.uniform(360, 830, n).astype(np.float32)) for _ in range(4)])
    wo = hemisphere(rng, n)
    s1 = mi.Float(rng.random(n, dtype=np.float32))
    s2 = mi.Point2f(mi.Float(rng.random(n, dtype=np.float32)), mi.Float(rng.random(n, dtype=np.float32)))
    active = mi.Bool(True)
    dr.eval(si, wo, s1, s2)
    dr.sync_thread()
    ctx = mi.BSDFContext()

    rows = []
    materials = dict(MATERIALS, **(PAINTS if args.paints else {}))
    for name, (ours, builtin) in materials.items():
        bsdfs = {"lacquer": mi.load_dict({"type": "lacquer", "material": json.dumps(ours)})}
        if builtin:
            bsdfs["built-in"] = mi.load_dict(builtin)
        row = {"material": name}
        for key, bsdf in bsdfs.items():
            def ev(b=bsdf):
                v = b.eval(ctx, si, wo, active)
                dr.eval(v)
                dr.sync_thread()

            def sa(b=bsdf):
                bs, w = b.sample(ctx, si, s1, s2, active)
                dr.eval(bs.wo, bs.pdf, bs.sampled_type, bs.sampled_component, w)
                dr.sync_thread()

            row[f"{key} eval"] = timed(ev, args.repeat) / n * 1e9
            row[f"{key} sample"] = timed(sa, args.repeat) / n * 1e9
        rows.append(row)
        print(row, flush=True)

    if args.core and args.variant == "llvm_ad_spectral":
        # The plugin's spectral path against the core's own call on the same inputs: what the
        # packing of lanes into interleaved arrays costs on top (docs/mitsuba.md, Spectral).
        import ctypes

        lib = ctypes.CDLL(os.environ["LACQUER_LIBRARY"])
        m = ctypes.c_void_p()
        assert lib.lq_material_from_json(json.dumps(PAINTS["pearl_paint"][0]).encode(), ctypes.byref(m)) == 0
        a = np.ascontiguousarray(np.array(wo, dtype=np.float32).T)
        b = np.ascontiguousarray(np.array(si.wi, dtype=np.float32).T)
        lam = np.ascontiguousarray(np.array(si.wavelengths, dtype=np.float32).T)
        f = np.zeros((n, 4), np.float32)
        ptr = [x.ctypes.data_as(ctypes.c_void_p) for x in (a, b, lam, f)]
        lib.lq_eval_spectral.argtypes = [ctypes.c_void_p, ctypes.c_size_t] + [ctypes.c_void_p] * 6
        core = timed(lambda: lib.lq_eval_spectral(m, n, ptr[0], ptr[1], None, None, ptr[2], ptr[3]),
                     args.repeat) / n * 1e9
        lib.lq_material_free(m)
        rows.append({"material": "pearl_paint: lq_eval_spectral, 1 thread", "lacquer eval": core,
                     "lacquer sample": 0.0})
        print(rows[-1], flush=True)

    print(f"\n{args.variant}, {n} lanes, {dr.thread_count()} Dr.Jit threads, min of {args.repeat}; "
          f"load average after: {os.getloadavg()[0]:.1f}")
    print("| material | eval: lacquer | eval: built-in | ratio | sample: lacquer | sample: built-in | ratio |")
    print("|---|---|---|---|---|---|---|")

    def cell(v):
        return f"{v:.1f}" if v else "-"

    for r in rows:
        e, s_, b_e, b_s = r["lacquer eval"], r["lacquer sample"], r.get("built-in eval"), r.get("built-in sample")
        print(f"| {r['material']} | {cell(e)} | {cell(b_e)} | {f'{e / b_e:.2f}' if b_e else '-'} | "
              f"{cell(s_)} | {cell(b_s)} | {f'{s_ / b_s:.2f}' if b_s else '-'} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"variant": args.variant, "lanes": n, "repeat": args.repeat, "threads": dr.thread_count(),
                       "load_average_after": os.getloadavg(), "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
