#!/usr/bin/env python3
"""Render time of the lacquer plugin against Mitsuba's built-in BSDF for the same material, in
scalar_rgb and in llvm_ad_rgb wavefront mode (the built-in also in Mitsuba's default symbolic
mode, for reference). Scene of tests/test_render.py (sphere, floor, environment, point light).

Run (after mitsuba-plugin/build.sh; llvm needs DRJIT_LIBLLVM_PATH):
    .venv-mitsuba/bin/python mitsuba-plugin/bench/render_ratio.py [--size 256 --spp 64 --repeat 3]
Writes mitsuba-plugin/bench/render_ratio.json and prints a Markdown table.
"""

import argparse
import json
import os
import pathlib
import sys
import time

import drjit as dr
import mitsuba as mi

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

AU_ETA = [0.143119, 0.374957, 1.44248]
AU_K = [3.98316, 2.38572, 1.60322]
MATERIALS = {
    "lambert": ({"model": "lambert", "albedo": [0.7, 0.5, 0.3]},
                {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.5, 0.3]}}),
    "ggx_gold": ({"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2,
                  "eta": AU_ETA, "k": AU_K},
                 {"type": "roughconductor", "distribution": "ggx", "alpha": 0.2,
                  "eta": {"type": "rgb", "value": AU_ETA}, "k": {"type": "rgb", "value": AU_K}}),
}


def timed_render(scene, spp):
    t = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=0)
    dr.eval(img)
    dr.sync_thread()
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    import test_render as tr
    import lacquer_mitsuba

    tr.W, tr.H = args.size, args.size * 3 // 4
    results = []
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        try:
            mi.set_variant(variant)
        except Exception as e:  # noqa: BLE001
            print(f"skip {variant}: {e}")
            continue
        lacquer_mitsuba.register(fallback=False)
        for name, (ours, builtin) in MATERIALS.items():
            builtin_scene = tr.mitsuba_scene(builtin, spp=args.spp)
            sym = None
            if variant.startswith("llvm"):
                # Before any lacquer BSDF exists: symbolic calls trace every registered BSDF
                # instance of the variant, and a traced lacquer object adds its (zero) branch.
                timed_render(builtin_scene, args.spp)
                sym = min(timed_render(builtin_scene, args.spp) for _ in range(args.repeat))
            try:
                plugin_scene = tr.mitsuba_scene(tr.lacquer_dict(ours), spp=args.spp)
            except RuntimeError as e:
                print(f"skip {name}: {str(e).splitlines()[-1][:120]}")
                continue
            modes = [("wavefront", True)] if variant.startswith("llvm") else [("", False)]
            for mode, wave in modes:
                times = {"plugin": [], "builtin": []}
                for _ in range(args.repeat + (1 if wave else 0)):  # llvm: first run compiles kernels
                    for key, scene in (("plugin", plugin_scene), ("builtin", builtin_scene)):
                        if wave:
                            with lacquer_mitsuba.wavefront():
                                times[key].append(timed_render(scene, args.spp))
                        else:
                            times[key].append(timed_render(scene, args.spp))
                if wave:
                    times = {k: v[1:] for k, v in times.items()}
                row = {"variant": variant, "mode": mode or "scalar", "material": name,
                       "plugin_s": min(times["plugin"]), "builtin_s": min(times["builtin"])}
                if sym is not None:  # the built-in in Mitsuba's default (symbolic, megakernel) mode
                    row["builtin_symbolic_s"] = sym
                row["ratio"] = row["plugin_s"] / row["builtin_s"]
                results.append(row)
                print(row, flush=True)
            del plugin_scene
            import gc
            gc.collect()

    out = {"size": [args.size, args.size * 3 // 4], "spp": args.spp, "repeat": args.repeat,
           "threads": dr.thread_count(), "load_average_after": os.getloadavg(), "mitsuba": mi.__version__,
           "results": results}
    (HERE / "render_ratio.json").write_text(json.dumps(out, indent=2))
    print("| variant | material | plugin (s) | built-in (s) | ratio | built-in, symbolic (s) |")
    print("|---|---|---|---|---|---|")
    for r in results:
        sym = f"{r['builtin_symbolic_s']:.2f}" if "builtin_symbolic_s" in r else ""
        print(f"| {r['variant']} {r['mode']} | {r['material']} | {r['plugin_s']:.2f} | {r['builtin_s']:.2f} | "
              f"{r['ratio']:.2f} | {sym} |")


if __name__ == "__main__":
    main()
