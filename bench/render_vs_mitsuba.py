#!/usr/bin/env python3
"""Render time and samples/s: `lacquer render` against Mitsuba 3's `path` integrator on the
same scene: a rough (GGX) gold conductor sphere on a diffuse floor, under a constant
environment and a point light; same camera, resolution, samples per pixel, path depth, box
pixel filter, thread count.

Setup (once):  python3 -m venv .venv-bench &&
               .venv-bench/bin/pip install mitsuba==3.9.1 numpy==2.4.6
Build:         cargo build --release -p lacquer-cli
Run:           .venv-bench/bin/python bench/render_vs_mitsuba.py [--spp 64 --size 256 --repeat 3]

The material on the lacquer side is `rough_conductor` (GGX, separable Smith masking, exact
conductor Fresnel with gold's RGB n, k), the model written to Mitsuba's `roughconductor`
conventions; Mitsuba's gold constants come from its own spectral data reduced to RGB, so the
images differ slightly (the script prints the mean difference). Depths:
lacquer's max_depth counts scattering events, Mitsuba's counts path segments, so Mitsuba gets
max_depth + 1.

Writes bench/results/render_vs_mitsuba.json and prints a Markdown table.
"""

import argparse
import json
import os
import pathlib
import platform
import subprocess
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent

# Gold (lacquer's fresnel::METALS Au, RGB): normal-incidence reflectance ((n-1)^2+k^2)/((n+1)^2+k^2).
AU_ETA = np.array([0.143119, 0.374957, 1.44248])
AU_K = np.array([3.98316, 2.38572, 1.60322])
AU_F0 = ((AU_ETA - 1) ** 2 + AU_K**2) / ((AU_ETA + 1) ** 2 + AU_K**2)

CAMERA = {"position": [0.0, 1.6, 5.5], "look_at": [0.0, 0.9, 0.0], "fov_deg": 30.0}
POINT = {"position": [-4.0, 6.0, 5.0], "intensity": 60.0}
ENV_RADIANCE = 0.6
FLOOR_ALBEDO = 0.18


def lacquer_bin():
    for c in [os.environ.get("LACQUER_BIN"),
              os.environ.get("CARGO_TARGET_DIR") and os.path.join(os.environ["CARGO_TARGET_DIR"], "release", "lacquer"),
              str(ROOT / "target" / "release" / "lacquer")]:
        if c and os.path.isfile(c):
            return c
    raise SystemExit("lacquer binary not found: cargo build --release -p lacquer-cli (or set LACQUER_BIN)")


def lacquer_scene(alpha):
    material = {"model": "rough_conductor", "distribution": "ggx", "alpha_u": alpha, "alpha_v": alpha,
                "material": "Au"}
    return {
        "camera": CAMERA,
        "materials": {"metal": material, "floor": {"model": "lambert", "albedo": FLOOR_ALBEDO}},
        "objects": [
            {"type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "metal"},
            {"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "size": [40, 40], "material": "floor"},
        ],
        "lights": [
            {"type": "environment", "radiance": ENV_RADIANCE},
            {"type": "point", "position": POINT["position"], "intensity": POINT["intensity"]},
        ],
    }


def mitsuba_scene(mi, alpha, size, spp, max_depth):
    T = mi.ScalarTransform4f
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth + 1},
        "sensor": {
            "type": "perspective", "fov": CAMERA["fov_deg"], "fov_axis": "y",
            "to_world": T().look_at(origin=CAMERA["position"], target=CAMERA["look_at"], up=[0, 1, 0]),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
        },
        "sphere": {"type": "sphere", "center": [0, 1, 0], "radius": 1.0,
                   "bsdf": {"type": "roughconductor", "distribution": "ggx", "alpha": alpha, "material": "Au"}},
        "floor": {"type": "rectangle",
                  "to_world": T().rotate(axis=[1, 0, 0], angle=-90).scale([20, 20, 1]),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": FLOOR_ALBEDO}}},
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": ENV_RADIANCE}},
        "light": {"type": "point", "position": POINT["position"],
                  "intensity": {"type": "rgb", "value": POINT["intensity"]}},
    })


def run_lacquer(args, workdir):
    scene_path = workdir / "scene.json"
    scene_path.write_text(json.dumps(lacquer_scene(args.alpha)))
    out = workdir / "lacquer.exr"
    cmd = [lacquer_bin(), "render", "--scene", str(scene_path), "--width", str(args.size), "--height",
           str(args.size), "--spp", str(args.spp), "--max-depth", str(args.max_depth), "--threads",
           str(args.threads), "--no-aovs", "--no-sparkle", "--precision", "float", "--json", "-o", str(out)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    report = json.loads(proc.stdout)
    return {"render_s": report["render_seconds"], "wall_s": wall, "mean_rgb": report["mean_rgb"]}


def run_mitsuba(mi, dr, args):
    t0 = time.perf_counter()
    scene = mitsuba_scene(mi, args.alpha, args.size, args.spp, args.max_depth)
    t1 = time.perf_counter()
    img = mi.render(scene, spp=args.spp, seed=0)
    arr = np.array(img)
    t2 = time.perf_counter()
    return {"render_s": t2 - t1, "wall_s": t2 - t0, "mean_rgb": arr.reshape(-1, 3).mean(axis=0).tolist()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--alpha", type=float, default=0.2)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--repeat", type=int, default=3, help="runs per renderer (alternating); the best counts")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench" / "results" / "render_vs_mitsuba.json")
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    dr.set_thread_count(args.threads)

    runs = {"lacquer": [], "mitsuba": []}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            runs["lacquer"].append(run_lacquer(args, pathlib.Path(tmp)))
            runs["mitsuba"].append(run_mitsuba(mi, dr, args))

    samples = args.size * args.size * args.spp
    load = os.getloadavg()
    result = {"size": args.size, "spp": args.spp, "max_depth": args.max_depth, "alpha": args.alpha,
              "threads": args.threads, "samples": samples, "load_average_after": load,
              "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.system()}",
              "mitsuba": mi.__version__, "runs": runs, "summary": {}}
    for name, rs in runs.items():
        best = min(rs, key=lambda r: r["render_s"])
        result["summary"][name] = {"render_s": best["render_s"], "wall_s": min(r["wall_s"] for r in rs),
                                   "samples_per_s": samples / best["render_s"], "mean_rgb": best["mean_rgb"]}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))

    print(f"{args.size}x{args.size}, {args.spp} spp, max depth {args.max_depth}, GGX alpha {args.alpha}, "
          f"{args.threads} threads, best of {args.repeat}; load average after: {load[0]:.2f}")
    print("| renderer | render time (s) | wall incl. startup (s) | samples/s | mean RGB |")
    print("|---|---|---|---|---|")
    for name, label in (("lacquer", "lacquer render"), ("mitsuba", f"Mitsuba {mi.__version__} scalar_rgb path")):
        s = result["summary"][name]
        mean = ", ".join(f"{v:.4f}" for v in s["mean_rgb"])
        print(f"| {label} | {s['render_s']:.2f} | {s['wall_s']:.2f} | {s['samples_per_s'] / 1e6:.2f} M | {mean} |")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
