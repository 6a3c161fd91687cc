#!/usr/bin/env python3
"""Render time of two-frame shading (docs/render.md, "coat_normal"): a 2 m plane of 64×64
vertices in gold_flake_8 under the studio environment and a sphere light, 256² at 32 spp, with
no orange peel, orange peel on the mesh (one frame: the whole paint tilts) and the same orange
peel on the coat (`coat_normal`: two frames). Usage:

    python3 scripts/coat_normal_speed.py [path/to/lacquer]   (default target/release/lacquer)
"""
import json
import os
import re
import subprocess
import sys
import tempfile


def scenes():
    n = 64
    pos, tri = [], []
    for j in range(n):
        for i in range(n):
            pos.append([-1 + 2 * i / (n - 1), 0, -1 + 2 * j / (n - 1)])
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            tri += [[a, a + n, a + 1], [a + 1, a + n, a + n + 1]]
    peel = {"amplitude_um": 30, "wavelength_mm": 50, "coords": pos}
    for where in ("none", "mesh", "coat"):
        mesh = {"positions": pos, "triangles": tri, "normals": [[0, 1, 0]] * len(pos)}
        if where == "mesh":
            mesh["orange_peel"] = peel
        if where == "coat":
            mesh["coat_normal"] = {"follows_normal": True, "orange_peel": peel}
        yield where, {"camera": {"position": [0, 1.5, 2.5], "look_at": [0, 0, 0], "fov_deg": 40},
                      "materials": {"paint": {"preset": "gold_flake_8"}}, "meshes": {"p": mesh},
                      "objects": [{"type": "mesh", "mesh": "p", "material": "paint"}],
                      "lights": [{"type": "environment", "map": "studio", "scale": 1},
                                 {"type": "sphere", "center": [-2, 3, 2], "radius": 0.3, "radiance": 100}]}


def main():
    exe = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.environ.get("CARGO_TARGET_DIR", "target"),
                                                             "release", "lacquer")
    with tempfile.TemporaryDirectory() as d:
        for where, scene in scenes():
            path = os.path.join(d, f"{where}.json")
            with open(path, "w") as f:
                json.dump(scene, f)
            out = subprocess.run([exe, "render", "--scene", path, "--width", "256", "--height", "256", "--spp", "32",
                                  "-o", os.path.join(d, f"{where}.exr")], capture_output=True, text=True, check=True)
            m = re.search(r"render ([0-9.]+ s, [0-9.]+ M paths/s)", out.stdout + out.stderr)
            print(f"orange peel {where:4}: {m.group(1) if m else out.stdout.strip()}")


if __name__ == "__main__":
    main()
