#!/usr/bin/env python3
"""Render time of a textured coated paint against the same paint untextured (issue 14 item 3):
the textured parameters go through the core's per-element calls (lq_eval_pdf_varying /
lq_sample_varying), the untextured paint through the plain ones. Scene of
tests/test_textures.py (a plane under a point light and a constant environment), `path`
integrator (max_depth 3), in scalar_rgb and llvm_ad_rgb (wavefront mode).

Run (after mitsuba-plugin/build.sh; llvm needs DRJIT_LIBLLVM_PATH):
    .venv-mitsuba/bin/python mitsuba-plugin/bench/texture_cost.py [--size 128 --spp 16 --repeat 3]
Writes mitsuba-plugin/bench/texture_cost.json and prints a Markdown table (best of --repeat).
"""

import argparse
import json
import pathlib
import sys
import time

import drjit as dr
import mitsuba as mi

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

# A metallic paint (flakes, mean lobe); the textures are 2x2 raw bitmaps (two values per half).
PAINT = {"type": "lacquer", "model": "coated_paint", "flake_density": 5.0, "sparkle": False,
         "coat_roughness": 0.05, "base_color": 0.5}


def timed(scene, spp, wavefront):
    import lacquer_mitsuba

    t = time.perf_counter()
    if wavefront:
        with lacquer_mitsuba.wavefront():
            img = mi.render(scene, spp=spp, seed=0)
            dr.eval(img)
            dr.sync_thread()
    else:
        img = mi.render(scene, spp=spp, seed=0)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    import lacquer_mitsuba
    import test_textures as tt

    tt.W = args.size
    rows = []
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        mi.set_variant(variant)
        lacquer_mitsuba.register(fallback=False)
        cases = {
            "untextured": PAINT,
            "base_color": {**PAINT, "base_color": tt.bitmap([0.8, 0.1, 0.1], [0.1, 0.2, 0.7])},
            "base_color + flake_density": {**PAINT, "base_color": tt.bitmap([0.8, 0.1, 0.1], [0.1, 0.2, 0.7]),
                                           "flake_density": tt.bitmap(2.0, 8.0)},
            "all three": {**PAINT, "base_color": tt.bitmap([0.8, 0.1, 0.1], [0.1, 0.2, 0.7]),
                          "flake_density": tt.bitmap(2.0, 8.0), "coat_roughness": tt.bitmap(0.02, 0.2)},
        }
        base = None
        for name, bsdf in cases.items():
            d = tt.scene_dict(bsdf)
            d["integrator"] = {"type": "path", "max_depth": 3}
            scene = mi.load_dict(d)
            timed(scene, 1, variant.startswith("llvm"))  # warm-up (JIT compile, tables)
            best = min(timed(scene, args.spp, variant.startswith("llvm")) for _ in range(args.repeat))
            base = base or best
            rows.append({"variant": variant, "textured": name, "seconds": round(best, 4),
                         "ratio": round(best / base, 2)})
            print(rows[-1], flush=True)
    out = {"size": args.size, "spp": args.spp, "repeat": args.repeat, "mitsuba": mi.__version__, "rows": rows}
    (HERE / "texture_cost.json").write_text(json.dumps(out, indent=1) + "\n")
    print(f"\n{args.size}x{args.size}, {args.spp} spp, path max_depth 3, best of {args.repeat}\n")
    print("| variant | textured | seconds | ratio to untextured |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r['variant']} | {r['textured']} | {r['seconds']} | {r['ratio']:.2f} |")


if __name__ == "__main__":
    main()
