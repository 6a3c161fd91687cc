"""The Blender extension, end to end, in headless bpy from PyPI.

This file runs in the tests venv (numpy 2, OpenImageIO 3; scripts/python-env.sh). It starts the
bpy venv's python (scripts/blender-env.sh: bpy 4.5 LTS, numpy 1.26) on
blender-addon/scripts/scenes.py, which installs the built extension zip into a temporary
BLENDER_USER_RESOURCES, enables it, assigns presets with its operator and renders each scene
with Cycles and with LACQUER into EXRs; the checks below read them with OpenImageIO.

Inputs (blender-addon/test.sh sets them): LACQUER_BLENDER_ZIP (the zip from build.sh) and
LACQUER_BLENDER_VENV (the bpy venv). LACQUER_BLENDER_SIZE / _SPP override 128 / 32.
Figures are printed (pytest -s) and written to figures.json in the render folder.
"""

from __future__ import annotations

import glob
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

HERE = Path(__file__).resolve().parent
SCENES = HERE.parent / "scripts" / "scenes.py"
SIZE = int(os.environ.get("LACQUER_BLENDER_SIZE", "128"))
SPP = int(os.environ.get("LACQUER_BLENDER_SPP", "32"))

#: Cycles (node group, fitted by the core) against LACQUER (the exact model), gold_flake_8 on a
#: sphere. "mean": the node group with Sparkle 0, the mean lobe the core fits — per region of a 3×3
#: grid, the largest relative difference of the mean luminance and of any channel (stable: both
#: images are smooth). "sparkle": Sparkle 1, the per-cell flakes artists render with — their narrow
#: lobes reflecting a small light make Cycles' region means heavy-tailed at test sample counts
#: (a region's ratio moves by ±20 % between 32, 64 and 256 spp), so it is checked on the whole
#: sphere's mean (which moves by 3 %). Measured figures: blender-addon/README.md.
#: The renders are seeded, so the figures repeat: 15 runs kept in /tmp (2026-12-01, several
#: revisions of the extension) gave per region 9.54–9.56 % / 19.92–20.16 % (bpy 4.5.15 / 5.0.1:
#: Cycles' own sampling differs between the versions, a stand-in for a seed change) and on the
#: sphere with per-cell flakes 7.84 % / 16.6 % (4.5.15) and 3.94 % / 6.34 % (5.0.1). REGION_TOL
#: was 12 % / 30 %: now the measured worst plus 1 point in luminance and 2 points in a channel
#: (ten times the spread between the bpy versions). SPHERE_TOL stays: the sparkle variant's
#: sphere mean moves by 3 points between 32, 64 and 256 spp (above), and 7.84 + 3 ≈ 11 < 12 %;
#: its blue channel differs by 10 points between the versions (16.6 vs 6.3 %), more than the
#: 8-point margin of 25 % over 16.6 %, so that margin is not tightened.
REGION_TOL = (0.105, 0.22)
SPHERE_TOL = (0.12, 0.25)
#: Light and world conversions with an exact material on both sides (Diffuse BSDF = Lambert).
LIGHTS_TOL = 0.01

FIGURES: dict = {}


def _bpy_python() -> str:
    venv = os.environ.get("LACQUER_BLENDER_VENV")
    if not venv:
        pytest.skip("LACQUER_BLENDER_VENV not set (run blender-addon/test.sh)")
    return str(Path(venv) / "bin" / "python")


def _zip() -> str:
    z = os.environ.get("LACQUER_BLENDER_ZIP")
    if not z or not os.path.isfile(z):
        pytest.skip("LACQUER_BLENDER_ZIP not set (run blender-addon/test.sh)")
    return z


def _run(args, resources, timeout=900):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(resources))
    p = subprocess.run([_bpy_python(), str(SCENES), *args], env=env, capture_output=True, text=True,
                       timeout=timeout)
    if p.returncode != 0:
        raise AssertionError(f"scenes.py failed ({p.returncode}):\n{p.stdout[-4000:]}\n{p.stderr[-4000:]}")
    return p.stdout


@pytest.fixture(scope="session")
def renders():
    out = Path(tempfile.mkdtemp(prefix="lacquer-blender-test-"))
    log = _run(["--zip", _zip(), "--out", str(out), "--size", str(SIZE), "--spp", str(SPP),
                "--scenes", "compare,density,lights,instances,principled,flakescale,lod", "--blend", "--eevee"],
               out / "user-resources")
    report = json.loads((out / "report.json").read_text())
    yield {"dir": out, "report": report, "log": log}
    (out / "figures.json").write_text(json.dumps(FIGURES, indent=1))
    print(f"\nBlender extension figures: {out / 'figures.json'}")


def read_exr(path) -> np.ndarray:
    buf = oiio.ImageBuf(str(path))
    assert not buf.has_error, buf.geterror()
    px = buf.get_pixels(oiio.FLOAT)
    assert px.ndim == 3 and px.shape[2] == 4, px.shape
    return px


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def test_zip_is_a_valid_extension(renders):
    """The manifest and layout pass Blender's own validator, and the zip installs and enables."""
    cli = glob.glob(str(Path(_bpy_python()).parent.parent / "lib" / "python3*" / "site-packages" / "bpy" / "*" /
                        "scripts" / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"))
    assert cli, "blender_ext.py not found in the bpy package"
    p = subprocess.run([_bpy_python(), cli[0], "validate", _zip()], capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    assert renders["report"]["install_seconds"] < 60


def test_unregisters_cleanly(renders):
    """Disabling removes the engine, operators and properties (and bpy then exits: no hang)."""
    assert renders["report"]["engine_registered"] is True
    assert all(renders["report"]["unregistered"].values()), renders["report"]["unregistered"]


def _region_means(img, mask, grid=3, min_pixels=40):
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    out = {}
    for i in range(grid):
        for j in range(grid):
            sl = (slice(y0 + (y1 - y0) * i // grid, y0 + (y1 - y0) * (i + 1) // grid),
                  slice(x0 + (x1 - x0) * j // grid, x0 + (x1 - x0) * (j + 1) // grid))
            m = mask[sl]
            if m.sum() >= min_pixels:
                out[(i, j)] = img[sl][m][:, :3].mean(axis=0)
    return out


def _compare(renders, variant):
    d = renders["dir"]
    cyc = read_exr(d / ("compare_cycles_mean.exr" if variant == "mean" else "compare_cycles.exr"))
    lq = read_exr(d / "compare_lacquer.exr")
    mask = (cyc[..., 3] > 0.999) & (lq[..., 3] > 0.999)
    assert mask.sum() > 0.1 * mask.size
    rc, rl = _region_means(cyc, mask), _region_means(lq, mask)
    assert len(rc) >= 7
    rows = []
    worst_lum = worst_ch = 0.0
    for k in rc:
        c, l_ = rc[k].astype(np.float64), rl[k].astype(np.float64)
        dl = float(abs(luminance(c) - luminance(l_)) / luminance(l_))
        dc = float(np.max(np.abs(c - l_) / np.maximum(l_, 1e-3)))
        worst_lum, worst_ch = max(worst_lum, dl), max(worst_ch, dc)
        rows.append({"region": list(k), "cycles": [round(float(x), 4) for x in c],
                     "lacquer": [round(float(x), 4) for x in l_],
                     "rel_luminance": round(dl, 4), "rel_channel_max": round(dc, 4)})
    c, l_ = cyc[mask][:, :3].astype(np.float64).mean(axis=0), lq[mask][:, :3].astype(np.float64).mean(axis=0)
    sphere = {"cycles": [round(float(x), 4) for x in c], "lacquer": [round(float(x), 4) for x in l_],
              "rel_luminance": round(float(abs(luminance(c) - luminance(l_)) / luminance(l_)), 4),
              "rel_channel_max": round(float(np.max(np.abs(c - l_) / l_)), 4)}
    FIGURES[f"compare_{variant}"] = {"regions": rows, "worst_rel_luminance": round(worst_lum, 4),
                                     "worst_rel_channel": round(worst_ch, 4), "sphere": sphere,
                                     "fit": renders["report"]["materials"].get("gold_flake_8")}
    print(f"\nCycles ({variant}) vs LACQUER, gold_flake_8, per region (row, col): "
          "rel. luminance / worst channel")
    for r in rows:
        print(f"  {r['region']}: C {r['cycles']} L {r['lacquer']}  {r['rel_luminance']:.3f} / "
              f"{r['rel_channel_max']:.3f}")
    print(f"  whole sphere: C {sphere['cycles']} L {sphere['lacquer']}  {sphere['rel_luminance']:.3f} / "
          f"{sphere['rel_channel_max']:.3f}")
    return FIGURES[f"compare_{variant}"]


def test_cycles_mean_lobe_and_lacquer_agree_per_region(renders):
    """gold_flake_8 on a sphere: the fitted node group's mean lobe (Sparkle 0) in Cycles against
    the exact model in LACQUER, region by region."""
    f = _compare(renders, "mean")
    assert f["worst_rel_luminance"] <= REGION_TOL[0], f
    assert f["worst_rel_channel"] <= REGION_TOL[1], f


def test_cycles_sparkle_and_lacquer_agree_on_the_sphere(renders):
    """gold_flake_8 on a sphere with per-cell flakes (Sparkle 1, as artists render it): the whole
    sphere's mean colour in Cycles against LACQUER."""
    f = _compare(renders, "sparkle")
    assert f["sphere"]["rel_luminance"] <= SPHERE_TOL[0], f
    assert f["sphere"]["rel_channel_max"] <= SPHERE_TOL[1], f


def test_panels_draw_every_parameter(renders):
    """The Material and Render panels and the preset menu draw (into a recording layout): every
    paint parameter the core lists is on the panel, and every menu and operator they name exists."""
    ui = renders["report"]["ui"]
    for name in ("flake_density", "flake_size", "flake_orientation_deg", "coat_ior", "pearl_film",
                 "base_color", "samples", "max_depth"):
        assert name in ui["ui_props"], ui
    assert "surface_scale_mm" not in ui["ui_props"]  # set by the engine, not the artist
    assert ui["ui_items"] > 40


def test_editing_a_parameter_refits_the_node_group(renders):
    """gold_flake_8 edited to 2 % flakes: the fitted Flake Coverage drops, the preset is marked
    modified; applying the preset again restores both."""
    a = renders["report"]["auto_update"]
    assert a["coverage_after_edit"] < 0.5 * a["coverage_before"], a
    assert a["modified"] is True and a["modified_after_reapply"] is False, a
    assert abs(a["coverage_restored"] - a["coverage_before"]) < 1e-6, a


def test_eevee_renders_the_node_group(renders):
    """EEVEE (software GL when headless) renders the same node group close to Cycles."""
    d = renders["dir"]
    if "eevee_error" in renders["report"]:
        pytest.skip(f"EEVEE cannot render here: {renders['report']['eevee_error']}")
    cyc, ee = read_exr(d / "compare_cycles.exr"), read_exr(d / "compare_eevee.exr")
    mask = (cyc[..., 3] > 0.999) & (ee[..., 3] > 0.999)
    mc, me = cyc[mask][:, :3].mean(axis=0), ee[mask][:, :3].mean(axis=0)
    rel = float(np.max(np.abs(me - mc) / mc))
    FIGURES["eevee"] = {"cycles": mc.round(4).tolist(), "eevee": me.round(4).tolist(), "rel": round(rel, 4)}
    assert rel < 0.15, FIGURES["eevee"]


def _sparkle_variance(img):
    """Variance of luminance around its 9×9 local mean (away from the border)."""
    lum = luminance(img[..., :3].astype(np.float64))
    r, k = 4, 9
    c = np.pad(np.cumsum(np.cumsum(np.pad(lum, r, mode="edge"), 0), 1), ((1, 0), (1, 0)))
    local = (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)
    return float((lum - local)[8:-8, 8:-8].var()), float(lum.mean())


def test_more_flakes_more_sparkle(renders):
    """Flake density 0 → 2 → 8 %: sparkle variance grows in both renderers (and is ~0 without flakes)."""
    d = renders["dir"]
    figures = {}
    for engine in ("cycles", "lacquer"):
        v = {p: _sparkle_variance(read_exr(d / f"density_gold_flake_{p}_{engine}.exr")) for p in (0, 2, 8)}
        figures[engine] = {f"{p} %": {"variance": round(v[p][0], 6), "mean_luminance": round(v[p][1], 4)}
                           for p in v}
        assert v[0][0] < 0.05 * v[2][0], (engine, v)
        assert v[8][0] > 2.0 * v[2][0], (engine, v)
        assert v[8][1] > v[2][1] > v[0][1], (engine, v)  # flakes add light where they face the sun
    FIGURES["density"] = figures
    print("\nSparkle variance (luminance around its 9×9 mean) for 0 / 2 / 8 % flakes:")
    for engine, f in figures.items():
        print(f"  {engine}: " + ", ".join(f"{k}: {x['variance']:.4g} (mean {x['mean_luminance']:.3f})"
                                          for k, x in f.items()))


LOD_DISTANCES = (0.1, 4.0)


def test_sparkle_level_of_detail_follows_the_pixel_footprint(renders):
    """gold_flake_8 on a plate seen from 0.1 m (a pixel covers ~1.6 flake cells) and 4 m (~2500):
    Cycles' glint variance with the level of detail on and off against LACQUER's. Near, the LOD
    leaves the cells alone (identical image); far, it fades them into the mean lobe, cutting the
    sampling noise the cells leave at 32 spp."""
    d = renders["dir"]
    fig = {}
    for dist in LOD_DISTANCES:
        on = _sparkle_variance(read_exr(d / f"lod_{dist}_on_cycles.exr"))
        off = _sparkle_variance(read_exr(d / f"lod_{dist}_off_cycles.exr"))
        lq = _sparkle_variance(read_exr(d / f"lod_{dist}_on_lacquer.exr"))
        fig[f"{dist} m"] = {"cycles_lod": on[0], "cycles_no_lod": off[0], "lacquer": lq[0],
                            "mean_lum": {"cycles_lod": on[1], "cycles_no_lod": off[1], "lacquer": lq[1]},
                            "inputs": renders["report"]["lod"][f"lod_{dist}_on"]}
    FIGURES["sparkle_lod"] = fig
    print("\nSparkle variance (luminance around its 9×9 mean), Cycles LOD / no LOD / LACQUER:")
    for k, f in fig.items():
        print(f"  {k}: {f['cycles_lod']:.4g} / {f['cycles_no_lod']:.4g} / {f['lacquer']:.4g}  "
              f"(means {f['mean_lum']})")
    near, far = fig[f"{LOD_DISTANCES[0]} m"], fig[f"{LOD_DISTANCES[1]} m"]
    assert near["inputs"]["Pixel Angle"] > 0 and near["inputs"]["Sparkle Samples"] == SPP, near
    assert abs(near["cycles_lod"] / near["cycles_no_lod"] - 1.0) < 1e-3, near  # w = 1: the same cells
    assert far["cycles_lod"] < 0.5 * far["cycles_no_lod"], far


LIGHT_CASES = ("point", "point_radius", "spot", "sun", "area", "area_disk", "area_ellipse", "world_color",
               "world_hdri")


@pytest.mark.parametrize("case", LIGHT_CASES)
def test_lights_and_world_match_cycles(renders, case):
    """A Diffuse BSDF plate (exact on both sides) under each light type: image means agree."""
    d = renders["dir"]
    cyc, lq = read_exr(d / f"lights_{case}_cycles.exr"), read_exr(d / f"lights_{case}_lacquer.exr")
    mc, ml = cyc[..., :3].mean(axis=(0, 1)), lq[..., :3].mean(axis=(0, 1))
    rel = float(np.max(np.abs(ml - mc) / np.maximum(mc, 1e-4)))
    FIGURES.setdefault("lights", {})[case] = {"cycles": mc.round(5).tolist(), "lacquer": ml.round(5).tolist(),
                                              "rel": round(rel, 5)}
    assert mc.min() > 1e-3, mc
    assert rel <= LIGHTS_TOL, (case, mc, ml)


def test_instances_transforms_and_material_slots(renders):
    """Collection instances (rotated, non-uniform scale), a two-material beveled cube and its
    linked duplicate: the same pixels are covered and the image means agree."""
    d = renders["dir"]
    cyc, lq = read_exr(d / "instances_cycles.exr"), read_exr(d / "instances_lacquer.exr")
    a, b = cyc[..., 3] > 0.5, lq[..., 3] > 0.5
    iou = float((a & b).sum() / (a | b).sum())
    mc, ml = cyc[..., :3].mean(axis=(0, 1)), lq[..., :3].mean(axis=(0, 1))
    rel = float(np.max(np.abs(ml - mc) / mc))
    FIGURES["instances"] = {"coverage_iou": round(iou, 5), "cycles": mc.round(5).tolist(),
                            "lacquer": ml.round(5).tolist(), "rel": round(rel, 5)}
    assert iou > 0.995, FIGURES["instances"]
    assert rel < LIGHTS_TOL, FIGURES["instances"]


#: The flake-scale scene (scripts/scenes.py: scene_flakescale), mirrored here: Unit Scales, then
#: (name, world centre x, world width) of each plate; ortho camera 10 units wide over SIZE pixels.
FLAKESCALE_UNITS = (1.0, 0.5)
FLAKESCALE_PLATES = (("fbx_child", -3.75, 2.0), ("plain", -1.25, 2.0), ("instance_half", 1.25, 2.0),
                     ("instance_quarter", 3.5, 1.0))
#: Metres of flake-cell coordinate per world Blender unit must be the Unit Scale on every plate,
#: in Cycles (fitted to the rendered coordinate, 32 spp: measured within 4.3e-4 relative on bpy
#: 4.5.15 and 3.0e-4 on 5.0.1, worst on the smallest plate — the pixel samples' jitter) and in
#: LACQUER's export (exact up to float32: measured within 2.3e-8). Before the fix, the
#: FBX child had 100×, the instances 2× and 4× the plain plate's in Cycles, and neither
#: engine followed the Unit Scale: any tolerance below 2× tells them apart.
FLAKESCALE_TOL = 1e-3


def _cycles_metres_per_unit(img, x, width):
    """The rendered coordinate P (3 channels) on one plate fitted as P = a + b·col + c·row: the
    singular values of [b c] per world unit (10/SIZE units per pixel); the fit's residual."""
    units_per_px = 10.0 / img.shape[1]
    lo = (x - width / 2 + 5.0) / units_per_px + 1.0  # one pixel in from the plate's edges
    hi = (x + width / 2 + 5.0) / units_per_px - 2.0
    rows, cols = np.nonzero(img[..., 3] > 0.999)
    keep = (cols >= lo) & (cols <= hi)
    rows, cols = rows[keep], cols[keep]
    assert len(rows) > 50, (x, len(rows))
    a = np.stack([np.ones(len(rows)), cols, rows], axis=1).astype(np.float64)
    p = img[rows, cols, :3].astype(np.float64)
    coef, *_ = np.linalg.lstsq(a, p, rcond=None)
    resid = float(np.abs(a @ coef - p).max())
    sv = np.linalg.svd(coef[1:].T, compute_uv=False) / units_per_px
    return float(sv.min()), float(sv.max()), resid


def test_flake_scale_is_world_and_unit_scale_in_both_engines(renders):
    """Flake cells per world unit are the same on a plate under a 0.01 FBX-like root, a plain
    plate, and two collection instances of one mesh scaled 0.5 and 0.25 — in Cycles (the node
    group's cell coordinate, rendered) and in LACQUER (its exported sparkle uv) — and follow the
    scene's Unit Scale, so that a flake's physical size in metres never changes."""
    d = renders["dir"]
    figures = {}
    for unit in FLAKESCALE_UNITS:
        name = f"flakescale_{unit}"
        img = read_exr(d / f"{name}_cycles_coord.exr")
        lq = renders["report"]["flakescale"][name]
        for plate, x, width in FLAKESCALE_PLATES:
            c_min, c_max, resid = _cycles_metres_per_unit(img, x, width)
            l_min, l_max = lq[plate]["metres_per_unit_min"], lq[plate]["metres_per_unit_max"]
            figures[f"{unit} {plate}"] = {"cycles": [round(c_min, 7), round(c_max, 7)],
                                          "lacquer": [round(l_min, 7), round(l_max, 7)], "fit_residual": resid}
    FIGURES["flake_scale"] = figures
    print("\nFlake-cell metres per world unit (min/max singular value), Cycles | LACQUER:")
    for k, f in figures.items():
        print(f"  unit {k}: {f['cycles']} | {f['lacquer']}")
    for k, f in figures.items():
        unit = float(k.split()[0])
        # Identical on every plate and in both engines: the Unit Scale (metres per Blender unit),
        # i.e. a flake of Flake Size µm covers Flake Size/unit µm-units whatever the parenting.
        for v in (*f["cycles"], *f["lacquer"]):
            assert abs(v / unit - 1.0) <= FLAKESCALE_TOL, (k, f)


def test_principled_materials_are_approximated_with_a_message(renders):
    """A plain Principled BSDF material renders in LACQUER through the `principled` model (or
    Lambert when the library lacks it), and the engine says so."""
    log = renders["log"]
    assert 'material "Principled red coat"' in log
    d = renders["dir"]
    cyc, lq = read_exr(d / "principled_cycles.exr"), read_exr(d / "principled_lacquer.exr")
    mask = (cyc[..., 3] > 0.999) & (lq[..., 3] > 0.999)
    mc, ml = cyc[mask][:, :3].mean(axis=0), lq[mask][:, :3].mean(axis=0)
    rel = float(abs(luminance(mc) - luminance(ml)) / luminance(mc))
    FIGURES["principled"] = {"cycles": mc.round(4).tolist(), "lacquer": ml.round(4).tolist(), "rel_luminance": rel,
                             "approximated_by": "principled" if "`principled` model from" in log else "lambert"}
    if "`principled` model from" in log:
        assert rel < 0.05, FIGURES["principled"]


def test_farm_renders_the_blend_without_the_extension(renders):
    """The saved .blend renders in a bpy with nothing installed (a farm node), identically."""
    d = renders["dir"]
    farm = d / "farm"
    _run(["--render-blend", str(d / "compare.blend"), "--out", str(farm)], farm / "empty-user-resources")
    rep = json.loads((farm / "report_farm.json").read_text())
    assert rep["addon_enabled"] is False
    a, b = read_exr(farm / "compare_farm_cycles.exr"), read_exr(d / "compare_cycles.exr")
    diff = float(np.abs(a - b).mean() / max(b[..., :3].mean(), 1e-6))
    FIGURES["farm_rel_mean_abs_diff"] = diff
    assert diff < 1e-3, diff


@pytest.fixture(scope="session")
def smokes():
    """The engine and editing smokes (scripts/scenes.py engine_smoke, editing_smoke) in their own
    bpy session, 64² renders."""
    out = Path(tempfile.mkdtemp(prefix="lacquer-blender-smokes-"))
    log = _run(["--zip", _zip(), "--out", str(out), "--size", "64", "--scenes", "engine,artist,assets,editing"],
               out / "user-resources")
    report = json.loads((out / "report.json").read_text())
    FIGURES["smoke_seconds"] = {k: round(report[k]["smoke_seconds"], 2) for k in ("engine", "artist", "assets", "editing")}
    return {"dir": out, "report": report, "log": log}


def test_lacquer_renders_progressively_with_denoising_passes(smokes):
    """A 16-spp LACQUER render shows its image in rounds (update_result after 1, 1, 2, 4, 4, 4
    spp) and fills Denoising Albedo and Denoising Normal, read back through the compositor
    (Render Layers → output): albedo in [0, 1] on the sphere, normals unit and facing the camera."""
    r = smokes["report"]["engine"]["passes_render"]
    assert r["rounds"] > 1 and r["spp"] == r["target"] == 16 and not r["cancelled"], r
    assert r["passes"] == ["Combined", "Denoising Albedo", "Denoising Normal"], r
    d = smokes["dir"]
    alpha = read_exr(d / "engine_combined.exr")[..., 3]
    hit = alpha > 0.999
    albedo, normal = read_exr(d / "engine_albedo.exr")[..., :3], read_exr(d / "engine_normal.exr")[..., :3]
    assert hit.sum() > 100
    a = albedo[hit]
    assert np.isfinite(a).all() and a.min() >= 0.0 and 0.05 < a.mean() <= 1.0, a.mean(axis=0)
    assert (alpha == 0.0).sum() > 100 and albedo[alpha == 0.0].max() == 0.0  # nothing where no surface is seen
    n = normal[hit]
    lengths = np.linalg.norm(n, axis=1)
    # The core normalises the pixel's mean first-hit normal: unit up to float rounding
    # (measured 6e-8 on bpy 4.5.15 and 5.0.1).
    assert np.abs(lengths - 1.0).max() < 1e-5, lengths.min()
    # The camera looks along +y (Blender's z-up): visible normals face it (n_y < 0).
    assert (n[:, 1] < 0.05).mean() > 0.99
    FIGURES["engine_passes"] = {"rounds": r["rounds"], "albedo_mean": a.mean(axis=0).round(4).tolist(),
                                "normal_length_dev": float(np.abs(lengths - 1.0).max()),
                                "seconds": round(r["seconds"], 3)}


def test_diffuse_and_glossy_color_passes(smokes):
    """With the view layer's Diffuse Color / Glossy Color on, LACQUER declares and fills DiffCol
    and GlossCol (the first hit's diffuse and glossy lobe groups' directional albedo), read back
    through the compositor: non-zero on the sphere, a solid paint's Glossy Color grey (its
    clearcoat's reflection alone), the metallic paint's coloured (gold flakes), and in a
    one-bounce render in the uniform 0.5 world (lamp hidden) Combined = 0.5 (Diffuse + Glossy)
    on the sphere. Off by default (the other tests' passes are Combined and the Denoising ones)."""
    d = smokes["dir"]
    lp = smokes["report"]["engine"]["lobe_passes"]
    fig = {}
    for preset in ("gold_flake_8", "solid_red"):
        assert lp[preset]["passes"] == ["Combined", "Denoising Albedo", "Denoising Normal", "DiffCol", "GlossCol"], lp
        comb = read_exr(d / f"engine_{preset}_lobes_combined.exr")
        dif = read_exr(d / f"engine_{preset}_DiffCol.exr")[..., :3].astype(np.float64)
        glo = read_exr(d / f"engine_{preset}_GlossCol.exr")[..., :3].astype(np.float64)
        # The sphere's pixels (non-zero colour passes) away from its silhouette, where Combined
        # also holds the world seen past the edge: the mask eroded by one pixel.
        seen = (dif.sum(-1) + glo.sum(-1)) > 0
        hit = seen.copy()
        hit[1:-1, 1:-1] &= seen[:-2, 1:-1] & seen[2:, 1:-1] & seen[1:-1, :-2] & seen[1:-1, 2:]
        hit[[0, -1], :] = False
        hit[:, [0, -1]] = False
        assert hit.sum() > 100, hit.sum()
        c = comb[..., :3][hit].astype(np.float64).mean(0)
        s = 0.5 * (dif[hit].mean(0) + glo[hit].mean(0))
        fig[preset] = {"combined": c.round(4).tolist(), "half_diffuse_plus_glossy": s.round(4).tolist(),
                       "diffuse": dif[hit].mean(0).round(4).tolist(), "glossy": glo[hit].mean(0).round(4).tolist()}
    FIGURES["lobe_passes"] = fig
    print(f"\nDiffuse/Glossy Color: {fig}")
    # Measured (bpy 4.5.15, 64², 16 spp): Combined vs 0.5 (D + G) within 1.7 % per channel (the
    # render crate's test: 0.9 %; Combined is higher by ~0.001 everywhere); tolerance 3 %.
    # Glossy Color: solid_red 0.074 grey (the coat), gold_flake_8 0.119 grey (the coat and the
    # aluminium flakes); Diffuse Color of solid_red (0.229, 0.008, 0.008).
    for preset, f in fig.items():
        for k in range(3):
            assert abs(f["combined"][k] - f["half_diffuse_plus_glossy"][k]) < 0.03 * f["combined"][k], (preset, f)
        assert min(f["diffuse"]) >= 0.0 and max(f["glossy"]) > 0.01, (preset, f)
    g = fig["solid_red"]["glossy"]
    assert max(g) - min(g) < 0.02 * max(g) and 0.02 < max(g) < 0.3, fig  # the coat's grey Fresnel
    dr = fig["solid_red"]["diffuse"]
    assert dr[0] > 2 * dr[2], fig  # the red pigment
    # The flakes add glossy reflectance to the coat's (aluminium: grey too).
    assert min(fig["gold_flake_8"]["glossy"]) > 1.3 * max(g), fig


def test_compositor_denoise_node_works_on_lacquer_passes(smokes):
    """The Render Layers node offers LACQUER's passes; Render Layers → Denoise (Image, Normal,
    Albedo) → output renders pixels (sparkle off: flake glints are detail, not noise): finite,
    the same mean as the noisy 4-spp image, and much closer to a 256-spp reference."""
    rep = smokes["report"]["engine"]
    assert "Denoising Albedo" in rep["rl_outputs"] and "Denoising Normal" in rep["rl_outputs"], rep["rl_outputs"]
    d = smokes["dir"]
    noisy, den = read_exr(d / "engine_noisy.exr"), read_exr(d / "engine_denoised.exr")
    mask = noisy[..., 3] > 0.999
    assert np.isfinite(den).all()
    mn, md = noisy[mask][:, :3].mean(axis=0), den[mask][:, :3].mean(axis=0)
    ref = read_exr(d / "engine_reference.exr")

    def rmse(img):
        # On the display's range (Standard view clips at 1): the highlight's fireflies, which
        # no denoiser removes at 4 spp, would otherwise be the whole error.
        c = np.clip(img[mask][:, :3], 0.0, 1.0) - np.clip(ref[mask][:, :3], 0.0, 1.0)
        return float(np.sqrt((c ** 2).mean()))

    FIGURES["denoise"] = {"noisy_mean": mn.round(4).tolist(), "denoised_mean": md.round(4).tolist(),
                          "rmse_noisy": rmse(noisy), "rmse_denoised": rmse(den)}
    print(f"\nDenoise node on LACQUER 4 spp: RMSE vs 256 spp {rmse(noisy):.4f} → {rmse(den):.4f}")
    assert md.min() > 0.0
    # Measured (bpy 4.5.15 and 5.0.1): means within 0.9 % (blue); a denoiser moves the mean little.
    assert np.abs(md - mn).max() / mn.max() < 0.05, FIGURES["denoise"]
    # Measured on bpy 5.0.1: 0.067 → 0.029 (ratio 0.43).
    assert rmse(den) < 0.7 * rmse(noisy), FIGURES["denoise"]


def test_esc_cancels_a_lacquer_render_promptly(smokes):
    """test_break answering True: a 4096-spp render stops after its first 1-sample round (whose
    image it keeps), well within the 0.5 s an artist would call prompt."""
    c = smokes["report"]["engine"]["cancel"]
    FIGURES["cancel"] = c
    assert c["cancelled"] and c["spp"] <= 1 and c["target"] == 4096, c
    assert c["seconds"] < 0.5, c


def test_viewport_renders_low_resolution_first_then_refines(smokes):
    """The Rendered viewport's worker: a quarter-resolution 1-spp image first, then the full
    region in rounds up to the viewport samples; the buffer view_draw uploads is finite and lit.
    (Headless bpy has no GPU context: the texture upload and draw itself are not tested here.)"""
    v = smokes["report"]["engine"]["viewport"]
    FIGURES["viewport"] = v
    assert v["error"] is None and v["done"], v
    h = v["history"]
    assert h[0][:2] == [16, 12] and h[0][2] == 1, h
    assert h[-1] == [64, 48, 8], h
    assert len([x for x in h if x[:2] == [64, 48]]) > 1, h  # progressive at full size
    assert v["final_shape"] == [48, 64, 4] and v["buffer_len"] == 48 * 64 * 4
    assert v["buffer_finite"] and v["buffer_mean"] > 0.01, v
    assert v["stop_seconds"] < 0.5, v
    cams = smokes["report"]["engine"]["viewport_camera"]
    for k in ("position", "look_at", "up"):
        assert np.allclose(cams["viewport"][k], cams["render"][k], atol=1e-5), cams
    assert abs(cams["viewport"]["fov_deg"] - cams["render"]["fov_deg"]) < 1e-3, cams


def test_refit_runs_off_the_main_thread_and_applies_on_completion(smokes):
    """An edit returns before the fit is done; the fit runs on the "lacquer-refit" thread; the
    timer applies the result (the coverage the core fits for the new density). Applying a
    preset fits on the worker thread too."""
    a = smokes["report"]["editing"]["async"]
    FIGURES["async_refit"] = a
    assert a["finished"] and a["refit"]["thread"] == "lacquer-refit" != a["main_thread"], a
    assert a["coverage_right_after"] == a["coverage_before"], a  # not applied synchronously
    assert a["edit_seconds"] < 0.5 * a["refit"]["seconds"] or a["edit_seconds"] < 0.01, a
    assert abs(a["coverage_applied"] - a["coverage_expected"]) < 1e-6, a
    p = smokes["report"]["editing"]["async_preset"]
    FIGURES["async_preset"] = p
    assert p["finished"] and p["refit"]["thread"] == "lacquer-refit", p
    assert abs(p["coverage"] - p["expected"]) < 1e-6, p


def test_keyframed_paint_parameters_refit_on_frame_change(smokes):
    """flake_density keyed 8 % at frame 1 and 2.5 % at frame 11: at frames 1, 11 and 6 the node
    group's Flake Coverage is the core's fit of the animated density; flake_size keyed the same
    way reaches the core and the node group."""
    frames = smokes["report"]["editing"]["frames"]
    assert abs(frames["1"]["density"] - 8.0) < 1e-5 and abs(frames["11"]["density"] - 2.5) < 1e-5, frames
    assert 2.5 < frames["6"]["density"] < 8.0, frames
    for f in frames.values():
        assert abs(f["coverage"] - f["expected"]) < 1e-6, frames
    # flake_size (a length: scene units over stored metres) keyed 15 µm / 25 µm: the core and
    # the node group get the animated value (20 µm at frame 6, the Bézier's midpoint).
    assert [frames[k]["flake_size_um"] for k in ("1", "11")] == [15.0, 25.0], frames
    assert abs(frames["6"]["flake_size_um"] - 20.0) < 1e-3, frames  # float32 key interpolation
    assert all(abs(f["node_flake_size"] - f["flake_size_um"]) < 1e-5 for f in frames.values()), frames


def test_bad_edits_keep_the_previous_paint(smokes):
    """Invalid JSON, an out-of-range value, an unknown parameter, another model, and a value the
    refit refuses: each reports an error and keeps the previous valid paint in the settings, the
    node group and what LACQUER renders; a valid JSON edit then applies."""
    bad = smokes["report"]["editing"]["bad_edits"]
    FIGURES["bad_edits"] = bad
    for label in ("invalid_json", "out_of_range", "unknown_parameter", "wrong_model", "refused_by_refit"):
        b = bad[label]
        assert b["kept_settings"] and b["kept_node"] and b["kept_lacquer"], (label, b)
    assert "invalid JSON" in bad["invalid_json"]["message"], bad
    assert "kept its paint" in bad["out_of_range"]["message"], bad
    assert bad["refused_by_refit"]["message"].startswith("rejected:") and "kept the previous paint" in \
        bad["refused_by_refit"]["message"], bad
    v = bad["valid_json"]
    assert v["result"] == "{'FINISHED'}" and abs(v["density"] - 5.0) < 1e-6, v
    assert abs(v["coverage"] - v["expected"]) < 1e-6, v


def test_load_post_upgrades_old_node_groups(smokes):
    """A file saved with an older node group version (and a clobbered input) is upgraded when
    opened: the group is rebuilt at this version and the material refitted."""
    lp = smokes["report"]["editing"]["load_post"]
    assert lp["upgrade"]["upgraded"] and lp["upgrade"]["refit"] >= 1, lp
    assert lp["upgrade"]["upgraded"][0].endswith(f"-> {lp['version_after']}"), lp
    assert not lp["upgrade"]["linked"], lp
    assert abs(lp["coverage_after"] - lp["coverage_expected"]) < 1e-6, lp


def test_linked_node_groups_are_left_untouched(smokes):
    """A material and its old node group linked from a library file: opening the file that links
    them leaves the group at its version, says so, and makes no local copy."""
    li = smokes["report"]["editing"]["linked"]
    assert li["library"] and li["library"].endswith("paint_library.blend"), li
    assert li["upgrade"]["linked"] and "left untouched" in li["upgrade"]["linked"][0], li
    assert not li["upgrade"]["upgraded"], li
    assert "Lacquer Coated Paint" not in li["local_groups"], li
    lp = smokes["report"]["editing"]["load_post"]
    assert li["version_after"] == lp["version_after"] - 1, (li, lp)


def _normals(path, alpha_from):
    n = read_exr(path)[..., :3].astype(np.float64)
    mask = read_exr(alpha_from)[..., 3] > 0.999
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return n / np.maximum(length, 1e-12), mask & (length[..., 0] > 0.5)


def _normals_against_cycles_and_plain(d, name):
    """The artist scene ``name``'s shading normals (LACQUER's Denoising Normal, Cycles' Normal
    pass): per pixel where both engines see the plate (at least half the image), the angle in
    degrees between LACQUER and Cycles and between LACQUER and the plain plate's LACQUER normal
    (the tilt). Returns ``(angle, tilt, mask)``."""
    lq_n, m1 = _normals(d / f"artist_{name}_lacquer_normal.exr", d / f"artist_{name}_lacquer.exr")
    cy_n, m2 = _normals(d / f"artist_{name}_cycles_normal.exr", d / f"artist_{name}_cycles.exr")
    plain_n, _ = _normals(d / "artist_plain_lacquer_normal.exr", d / "artist_plain_lacquer.exr")
    mask = m1 & m2
    assert mask.sum() > 0.5 * mask.size

    def degrees(a, b):
        return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))[mask]

    return degrees(lq_n, cy_n), degrees(lq_n, plain_n), mask


def test_normal_map_on_the_normal_input_renders_in_both_engines(smokes):
    """An Image Texture → Normal Map (tangent space) on the Lacquer node's Normal input: LACQUER
    exports it and its image changes; its shading normals (Denoising Normal) equal Cycles'
    (Normal pass, Sparkle 0 so every closure has the paint's normal) pixel by pixel."""
    a = smokes["report"]["artist"]
    d = smokes["dir"]
    assert a["normal_map_exported"], a
    ang, tilt, mask = _normals_against_cycles_and_plain(d, "normalmap")
    lq, plain = read_exr(d / "artist_normalmap_lacquer.exr"), read_exr(d / "artist_plain_lacquer.exr")
    change = float(np.abs(luminance(lq[..., :3]) - luminance(plain[..., :3]))[mask].mean()
                   / luminance(plain[..., :3])[mask].mean())
    FIGURES["normal_map"] = {"angle_lacquer_vs_cycles_deg_mean": float(ang.mean()),
                             "angle_deg_p99": float(np.percentile(ang, 99)),
                             "tilt_deg_max": float(tilt.max()), "lacquer_image_change": change}
    print(f"\nNormal map: LACQUER vs Cycles shading normal {ang.mean():.3f}° mean, "
          f"{np.percentile(ang, 99):.3f}° p99; tilt up to {tilt.max():.1f}°; image change {change:.3f}")
    # The map tilts normals by up to 0.4 rad = 22.9° (a pixel averages part of a stripe).
    assert tilt.max() > 15.0, FIGURES["normal_map"]
    assert change > 0.05, FIGURES["normal_map"]
    assert ang.mean() < 1.0 and np.percentile(ang, 99) < 3.0, FIGURES["normal_map"]


def test_coat_normal_map_tilts_only_the_coat_in_both_engines(smokes):
    """The normal map of test_normal_map_on_the_normal_input_renders_in_both_engines on the Lacquer
    node's Coat Normal instead: LACQUER exports it as the coat's own normal (two frames; no map on
    the base) and its shading normal (Denoising Normal: the base's) stays the plain plate's. The
    image differs from the one with the map on Normal (flakes and pigment no longer tilt), and
    it differs from it the way Cycles' (the node group's Principled Coat Normal) does: the
    per-pixel maps of both changes (Coat Normal vs plain, Coat Normal vs Normal) correlate
    between the engines. (The tilted coat's stripes catch the sun here, so the Coat Normal image
    changes about as much as the Normal one in both engines.)"""
    a = smokes["report"]["artist"]
    d = smokes["dir"]
    assert a["coat_normal_exported"] == [["follows_normal", "normal_map"]], a
    assert not a["coat_normal_base_map"], a
    _, tilt, mask = _normals_against_cycles_and_plain(d, "coatnormal")

    def lum(engine, tag):
        return luminance(read_exr(d / f"artist_{tag}_{engine}.exr")[..., :3])[mask].astype(np.float64)

    fig = {"base_tilt_deg_max": float(tilt.max())}
    maps = {}
    for engine in ("lacquer", "cycles"):
        plain, coat, whole = (lum(engine, t) for t in ("plain", "coatnormal", "normalmap"))
        maps[engine] = (coat - plain, coat - whole)
        fig[engine] = {"coat_vs_plain": float(np.abs(coat - plain).mean() / plain.mean()),
                       "coat_vs_normal_input": float(np.abs(coat - whole).mean() / plain.mean()),
                       "normal_input_vs_plain": float(np.abs(whole - plain).mean() / plain.mean())}
    fig["correlation_coat_vs_plain"] = float(np.corrcoef(maps["lacquer"][0], maps["cycles"][0])[0, 1])
    fig["correlation_coat_vs_normal_input"] = float(np.corrcoef(maps["lacquer"][1], maps["cycles"][1])[0, 1])
    FIGURES["coat_normal"] = fig
    print(f"\nCoat Normal map: {fig}")
    # Measured on bpy 4.5.15 (64², 16 spp): base tilt 0.0°; LACQUER's Coat Normal image differs
    # from its Normal image by 16.8 % of the plain mean per pixel (Cycles 13.1 %; the one-frame
    # paint before this test gave 0: the map tilted the whole paint); change-map correlations
    # between the engines 0.959 (vs plain) and 0.986 (vs Normal).
    assert tilt.max() < 0.5, fig  # the base normal is untouched (LACQUER's normal pass)
    assert fig["lacquer"]["coat_vs_normal_input"] > 0.08, fig
    assert 0.5 < fig["lacquer"]["coat_vs_normal_input"] / fig["cycles"]["coat_vs_normal_input"] < 2.0, fig
    assert fig["correlation_coat_vs_plain"] > 0.9 and fig["correlation_coat_vs_normal_input"] > 0.9, fig


def _half_means(path, cols):
    """Mean RGB and luminance of an EXR over pixel columns ``cols`` (every row)."""
    px = read_exr(path)[:, cols, :3].reshape(-1, 3).astype(np.float64)
    rgb = px.mean(0)
    return rgb, float(luminance(rgb))


def test_image_texture_on_base_color_renders_in_both_engines(smokes):
    """A two-colour Image Texture on the Lacquer node's Base Color (scenes.py _texture_smoke): in
    LACQUER each half equals the untextured paint of that colour, in Cycles too (the node group
    maps the texel through the core's base colour map), and the engines agree per half; the export binds the image
    and a link LACQUER cannot follow is named in the report."""
    t = smokes["report"]["artist"]["texture"]
    d = smokes["dir"]
    ex = t["exported"]
    assert ex["textures"] and ex["textures"]["base_color"]["image"] in ex["images"], ex
    assert ex["texture_uvs"], ex
    assert any("Base Color comes from ShaderNodeRGB" in m for m in t["unfollowed_link_messages"]), t
    # The image on Flake Density (%) and Coat Roughness (Principled's √α) exports Cycles' colour →
    # float conversion (Rec.709 luminance) and its square (the paint's coat is rough: 0.02).
    sc = t["scalars"]
    grey = [float(np.dot(c, (0.2126, 0.7152, 0.0722))) for c in ((0.70, 0.12, 0.05), (0.06, 0.22, 0.60))]
    assert sc["keys"] == ["coat_roughness", "flake_density"], sc
    assert np.allclose(sc["flake_density"], [grey[0], grey[1], grey[1]], rtol=1e-5), (sc, grey)
    assert np.allclose(sc["coat_roughness"], [grey[0] ** 2, grey[1] ** 2, grey[1] ** 2], rtol=1e-5), (sc, grey)
    # 64² plate, u = 0.25 + 0.5 (x + ½)/64 across the frame; the image's halves blend (bilinear)
    # for u in [0.47, 0.53] = columns 28..36: compare columns 0..24 and 40..64.
    halves = (slice(0, 24), slice(40, 64))
    fig = {}
    for engine in ("lacquer", "cycles"):
        for k, cols in enumerate(halves):
            tex, lt = _half_means(d / f"texture_halves_{engine}.exr", cols)
            plain, lp = _half_means(d / f"texture_plain{k}_{engine}.exr", cols)
            fig[f"{engine}_half{k}"] = {"luminance": abs(lt / lp - 1.0),
                                        "channel": float(np.max(np.abs(tex / plain - 1.0)))}
    for k, cols in enumerate(halves):
        # Cycles against LACQUER, textured and untextured (the node group's own fit error).
        for tag, name in (("halves", "texture_halves"), ("plain", f"texture_plain{k}")):
            _, lq = _half_means(d / f"{name}_lacquer.exr", cols)
            _, cy = _half_means(d / f"{name}_cycles.exr", cols)
            fig[f"engines_{tag}{k}"] = abs(cy / lq - 1.0)
    c0, _ = _half_means(d / "texture_plain0_lacquer.exr", halves[0])
    c1, _ = _half_means(d / "texture_plain1_lacquer.exr", halves[0])
    fig["colours_differ"] = float(np.max(np.abs(c0 / c1 - 1.0)))
    FIGURES["texture_base_color"] = fig
    print(f"\nBase Color texture: {json.dumps(fig)}")
    # The two colours render differently (so the comparisons can fail): measured 3.0 in red.
    assert fig["colours_differ"] > 0.5, fig
    for k in range(2):
        # LACQUER: the per-element path against the material built with the half's colour; the
        # per-component tables and the material's own differ by up to 2.6 % in f (docs/speed.md).
        # Measured (bpy 4.5.15 and 5.0.1) 0.17 % / 0.08 % in a channel; tolerance 4 % (that bound).
        assert fig[f"lacquer_half{k}"]["channel"] < 0.04, fig
        # Cycles: the node group maps the texel through the core's base colour map (node group
        # version 7: per channel the pigment the fitted group needs, nodegroup.py), so each half
        # renders as the paint refitted with that base colour. Measured (4.5.15 / 5.0.1) luminance
        # 0.014 % / 0.015 %, worst channel 0.024 % / 0.48 % (the blue of the blue half; it was
        # 12 % / 38 % when version 6 scaled the fitted pigment linearly). Tolerances 0.2 % and 1 %.
        assert fig[f"cycles_half{k}"]["luminance"] < 0.002, fig
        assert fig[f"cycles_half{k}"]["channel"] < 0.01, fig
        # Between the engines, the textured halves differ as the untextured paints do (the node
        # group's fit at this view, 17–20 % in luminance): measured 0.06 and 0.03 points apart
        # (4.5.15; 5.0.1 the same to 0.01 point); tolerance 0.5 points.
        assert abs(fig[f"engines_halves{k}"] - fig[f"engines_plain{k}"]) < 0.005, fig


def test_bump_node_on_the_normal_input_renders_in_both_engines(smokes):
    """An Image Texture (heights) → Bump → the Lacquer node's Normal: LACQUER exports the height
    image, strength and distance; its shading normals (Denoising Normal) follow Cycles' (Normal
    pass, Sparkle 0) pixel by pixel, and the bump tilts them."""
    a = smokes["report"]["artist"]
    d = smokes["dir"]
    assert a["bump_exported"], a["bump_messages"]
    ang, tilt, mask = _normals_against_cycles_and_plain(d, "bump")
    FIGURES["bump"] = {"angle_lacquer_vs_cycles_deg_mean": float(ang.mean()),
                       "angle_deg_p99": float(np.percentile(ang, 99)), "tilt_deg_max": float(tilt.max())}
    print(f"\nBump: LACQUER vs Cycles shading normal {ang.mean():.3f}° mean, "
          f"{np.percentile(ang, 99):.3f}° p99; tilt up to {tilt.max():.1f}°")
    # The heights tilt normals by up to atan(0.314) = 17.4° (measured 17.3°).
    assert tilt.max() > 10.0, FIGURES["bump"]
    # Measured (bpy 4.5.15) 0.072° mean, 0.40° p99 (Cycles differentiates the height over a
    # pixel's footprint, LACQUER the bilinear interpolant); tolerances as the normal map's.
    assert ang.mean() < 1.0 and np.percentile(ang, 99) < 3.0, FIGURES["bump"]


def test_orange_peel_tilts_the_coat_in_both_engines(smokes):
    """Orange peel (50 µm RMS at 8 mm) on the plate: LACQUER exports it as the coat's own normal
    (following Normal), so the paint's shading normal (Denoising Normal: the base's) stays the
    plain plate's, as in Cycles where only the Coat Normal tilts; both engines' images change.
    (The tilt itself against the height field's predicted RMS slope: the render crate's
    perturb::tests::orange_peel_* and desc tests.)"""
    a = smokes["report"]["artist"]
    d = smokes["dir"]
    assert a["peel_node_inputs"] == [50.0, 8.0], a
    assert a["peel_exported"] and all(
        p["amplitude_um"] == 50.0 and p["wavelength_mm"] == 8.0 and p["follows_normal"]
        and "orange_peel" not in p["base_keys"] for p in a["peel_exported"]), a
    peel_n, mask = _normals(d / "artist_peel_lacquer_normal.exr", d / "artist_peel_lacquer.exr")
    plain_n, _ = _normals(d / "artist_plain_lacquer_normal.exr", d / "artist_plain_lacquer.exr")
    tilt = np.degrees(np.arccos(np.clip((peel_n * plain_n).sum(-1), -1, 1)))[mask]
    changes = {}
    for engine in ("lacquer", "cycles"):
        on, off = read_exr(d / f"artist_peel_{engine}.exr"), read_exr(d / f"artist_plain_{engine}.exr")
        changes[engine] = float(np.abs(luminance(on[..., :3]) - luminance(off[..., :3]))[mask].mean()
                                / luminance(off[..., :3])[mask].mean())
    FIGURES["orange_peel"] = {"base_tilt_deg_max": float(tilt.max()), "image_change": changes}
    print(f"\nOrange peel: base normal tilt up to {tilt.max():.3f}°; image change {changes}")
    assert tilt.max() < 0.5, FIGURES["orange_peel"]
    # Measured (bpy 4.5.15): base tilt 0.000°; image change LACQUER 0.50 %, Cycles 0.57 % of the
    # mean luminance per pixel (in both engines only the coat tilts and this view sees no coat
    # highlight; with the one-frame paint LACQUER changed by 2.5 %).
    assert changes["lacquer"] > 0.002 and changes["cycles"] > 0.002, FIGURES["orange_peel"]
    assert 0.5 < changes["lacquer"] / changes["cycles"] < 2.0, FIGURES["orange_peel"]


def test_flake_scale_units_and_fit_text(smokes):
    """Flake Scale 2 reaches the node group and LACQUER (sparkle surface scale 1000/2 mm);
    the flake orientation is an angle property (degrees in the core's JSON); the fit error is
    sentences, not raw keys."""
    a = smokes["report"]["artist"]
    assert a["flake_scale"] == {"node": 2.0, "surface_scale_mm": 500.0}, a
    assert a["angle"]["subtype"] == "ANGLE" and a["angle"]["unit"] == "ROTATION", a
    assert abs(a["angle"]["json_deg"] - a["angle"]["preset_deg"]) < 1e-3, a
    assert a["fit_text"] and not any("_rms" in line or "snr_db" in line for line in a["fit_text"]), a
    assert a["fit_text"][0].startswith("Match to the exact paint:"), a


def test_lengths_use_blender_units_and_reach_the_core_unchanged(smokes):
    """Flake and pearl size, pearl film, coat thickness, orange peel and its wavelength are
    Blender lengths (DISTANCE / LENGTH) without the old µm/nm names; set under metric (adaptive,
    µm), imperial and centimetre (Unit Scale 0.01) units they reach the core's JSON, the LACQUER
    export and the node group in µm / nm / mm exactly (the float32 the panel passes rounds to
    the typed decimal), and the scene's unit system shows them."""
    r = smokes["report"]["artist"]["lengths"]
    print("\nLengths shown: " + ", ".join(f"{k}: {v['shown']}" for k, v in r["systems"].items()))
    assert all(v == ["DISTANCE", "LENGTH"] for v in r["subtypes"].values()), r["subtypes"]
    assert r["old_names_gone"] == [], r
    assert set(r["systems"]) == {"METRIC/ADAPTIVE", "METRIC/MICROMETERS", "IMPERIAL/ADAPTIVE", "METRIC/CENTIMETERS"}, r
    for system, v in r["systems"].items():
        assert v["json"] == v["expected"] and v["export"] == v["expected"], (system, v)
        assert v["node_flake_size"] == 23.0 and v["node_orange_peel"] == [0.75, 4.5], (system, v)
    assert r["systems"]["METRIC/ADAPTIVE"]["shown"] == "23 µm", r
    # Unit Scale 0.01 (a scene in centimetres): the panel still shows 23 µm and the core gets 23.
    assert r["systems"]["METRIC/CENTIMETERS"]["shown"] == "23 µm", r
    assert "µm" not in r["systems"]["IMPERIAL/ADAPTIVE"]["shown"], r  # feet / thou
    # A file saved with the old properties (flake_size_um = 25 µm, orange peel 0.75 µm at
    # 4.5 mm) is migrated on load: metric values, old keys dropped, the core sees 25 µm.
    m = smokes["report"]["editing"]["lengths_migrated"]
    # The property reads float32: relative half-ulp 6e-8 (measured 2.5e-8, 3.5e-8, 4.3e-8);
    # tolerance 1e-7.
    for key, metres in (("flake_size_m", 25e-6), ("orange_peel_m", 0.75e-6), ("orange_peel_wavelength_m", 4.5e-3)):
        assert abs(m[key] / metres - 1.0) < 1e-7, m
    assert m["json_flake_size_um"] == 25.0 and m["old_keys_left"] == [], m
    assert m["node"] == {"Flake Size": 25.0, "Orange Peel": 0.75, "Orange Peel Wavelength": 4.5}, m


def test_asset_library_loads_and_an_asset_is_a_working_paint(smokes):
    """The bundled library is registered ("Lacquer Paints"), holds one material per core preset
    in the four catalogues with a preview rendered by the core, and an appended asset on an
    object is a Lacquer paint: the preset's parameters, the current node group with its fit,
    LACQUER renders it as coated_paint."""
    a = smokes["report"]["assets"]
    FIGURES["assets"] = {k: {kk: v[kk] for kk in ("lacquer_mean", "preview_mean", "catalog")}
                         for k, v in a["applied"].items()}
    assert a["library"]["registered"] and a["library"]["name"] == "Lacquer Paints", a["library"]
    assert a["asset_materials"] == a["preset_labels"], (a["asset_materials"], a["preset_labels"])
    assert a["catalogs"] == ["Lacquer/Thesis series", "Lacquer/Solid", "Lacquer/Metallic", "Lacquer/Pearlescent"]
    # Every preset's menu preview loaded (96² core thumbnails); headless bpy makes no UI icons
    # (icon_id 0, checked only with a UI).
    assert all(v == [96, 96] for v in a["previews"].values()), a["previews"]
    assert a["background"] or all(i > 0 for i in a["icon_ids"]), a["icon_ids"]
    for name, r in a["applied"].items():
        assert r["enabled"] and r["preset"] == name and r["params_match"], (name, r)
        assert r["group"] == "Lacquer Coated Paint" and r["group_version"] == r["expected_group_version"], (name, r)
        assert r["fit_inputs"] and abs(r["coverage"] - r["expected_coverage"]) < 1e-6, (name, r)
        assert r["catalog"] == r["expected_catalog"], (name, r)
        assert r["models"] == ["coated_paint"], (name, r)
        assert r["lacquer_mean"] > 1e-3 and r["preview_size"] == [96, 96] and r["preview_mean"] > 0.02, (name, r)
    assert a["applied"]["gold_flake_8"]["catalog"] == "Lacquer/Thesis series"
    assert a["applied"]["pearl_blue"]["catalog"] == "Lacquer/Pearlescent"
    assert a["applied"]["solid_red"]["catalog"] == "Lacquer/Solid"
    assert a["local_groups"] == ["Lacquer Coated Paint"], a["local_groups"]  # no duplicate group left


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q", "-s"]))
