"""Builds the extension's bundled asset library: one Lacquer material per core preset, marked
as an asset, in catalogues (Solid / Metallic / Pearlescent / Thesis series), with a thumbnail
rendered by the core (`lacquer render`, the built-in shader ball; cached).

Run by blender-addon/build.sh with a bpy python (headless) on a first zip without assets:

    BLENDER_USER_RESOURCES=$(mktemp -d) python build_assets.py --zip ZIP --lacquer-cli PATH \
        --out DIR --thumbs CACHE_DIR [--size 96 --spp 16]

Writes DIR/lacquer_paints.blend, DIR/blender_assets.cats.txt and DIR/thumbs/<preset>.png.
Thumbnails are cached in CACHE_DIR by a hash of the preset's material JSON and the render
settings (delete the folder to re-render them after a change of the renderer).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys

import bpy

ADDON = "bl_ext.user_default.lacquer"


def thumbnail(cli: str, material: dict, cache: str, size: int, spp: int) -> str:
    """The PNG of the core's shader ball for ``material`` (rendered once per JSON and settings)."""
    key = hashlib.sha256(json.dumps([material, size, spp], sort_keys=True).encode()).hexdigest()[:20]
    png = os.path.join(cache, f"{key}.png")
    if not os.path.exists(png):
        exr = os.path.join(cache, f"{key}.exr")
        subprocess.run([cli, "render", "--material", json.dumps(material), "-o", exr, "--png", png,
                        "--width", str(size), "--height", str(size), "--spp", str(spp)],
                       check=True, stdout=subprocess.DEVNULL)
        os.remove(exr)
    return png


def set_preview(idb, png: str) -> None:
    """The data-block's preview (what the Asset Browser shows) from a PNG."""
    img = bpy.data.images.load(png)
    w, h = img.size
    px = [0.0] * (w * h * 4)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    idb.preview_ensure()
    idb.preview.image_size = (w, h)
    idb.preview.image_pixels_float.foreach_set(px)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--zip", required=True)
    ap.add_argument("--lacquer-cli", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--thumbs", required=True)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=16)
    a = ap.parse_args(argv)
    if not os.environ.get("BLENDER_USER_RESOURCES"):
        raise SystemExit("set BLENDER_USER_RESOURCES to a temporary folder (before bpy starts)")
    r = bpy.ops.extensions.package_install_files(filepath=os.path.abspath(a.zip), repo="user_default",
                                                 enable_on_install=True)
    if r != {"FINISHED"} or ADDON not in bpy.context.preferences.addons:
        raise SystemExit(f"installing {a.zip} failed: {r}")
    catalog = sys.modules[f"{ADDON}.catalog"]
    operators = sys.modules[f"{ADDON}.operators"]
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras):
        for item in list(coll):
            coll.remove(item)
    os.makedirs(a.thumbs, exist_ok=True)
    out = os.path.abspath(a.out)
    os.makedirs(os.path.join(out, "thumbs"), exist_ok=True)
    with open(os.path.join(out, "blender_assets.cats.txt"), "w") as f:
        f.write("# Lacquer paints: asset catalogues (built by blender-addon/scripts/build_assets.py)\nVERSION 1\n\n")
        for path in catalog.ASSET_CATALOGS:
            f.write(f"{catalog.catalog_uuid(path)}:{path}:{path.replace('/', '-')}\n")
    for name, label, desc, material in catalog.presets():
        mat = bpy.data.materials.new(label)
        operators.apply_preset(mat, name)
        mat.asset_mark()
        mat.asset_data.catalog_id = catalog.catalog_uuid(catalog.asset_catalog(name))
        mat.asset_data.description = f"{desc} (lacquer preset `{name}`)".strip()
        mat.asset_data.tags.new("lacquer")
        mat.asset_data.tags.new(name)
        png = thumbnail(a.lacquer_cli, material, a.thumbs, a.size, a.spp)
        shutil.copyfile(png, os.path.join(out, "thumbs", f"{name}.png"))
        set_preview(mat, png)
        mat.use_fake_user = True
        print(f"asset {name}: {label} [{catalog.asset_catalog(name)}]", flush=True)
    path = os.path.join(out, "lacquer_paints.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, copy=True)
    bpy.ops.preferences.addon_disable(module=ADDON)
    print(path)


if __name__ == "__main__":
    main(sys.argv[1:])
