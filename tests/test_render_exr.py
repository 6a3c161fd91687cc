"""`lacquer render` end to end: run the binary, read its OpenEXR output back with OpenImageIO.

Run: venv="$(bash scripts/python-env.sh)" && "$venv/bin/python" -m pytest tests/test_render_exr.py
The binary comes from $LACQUER_BIN, else $CARGO_TARGET_DIR/release/lacquer, else
target/release/lacquer (build it with `cargo build --release -p lacquer-cli`).
Images are tiny so that the whole file runs in a few seconds.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import OpenImageIO as oiio
import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent


def lacquer_bin() -> pathlib.Path:
    candidates = []
    if os.environ.get("LACQUER_BIN"):
        candidates.append(pathlib.Path(os.environ["LACQUER_BIN"]))
    if os.environ.get("CARGO_TARGET_DIR"):
        candidates.append(pathlib.Path(os.environ["CARGO_TARGET_DIR"]) / "release" / "lacquer")
    candidates.append(ROOT / "target" / "release" / "lacquer")
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    pytest.fail(
        "lacquer binary not found (tried %s); run `cargo build --release -p lacquer-cli` or set LACQUER_BIN"
        % ", ".join(map(str, candidates))
    )


def run_render(tmp_path, *args, expect_ok=True):
    cmd = [str(lacquer_bin()), "render", "--quiet", "--json", *map(str, args)]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    if expect_ok:
        assert proc.returncode == 0, f"{cmd} failed:\n{proc.stderr}"
        return json.loads(proc.stdout)
    return proc


def read_exr(path):
    """Returns (spec, {channel name: 2-D float array})."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
    finally:
        inp.close()
    assert pixels is not None
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
    return spec, {name: pixels[:, :, i] for i, name in enumerate(spec.channelnames)}


AOV_CHANNELS = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z"}


def test_main_job_exr(tmp_path):
    """The README's first command, small: channels, size, finite non-negative values, metadata."""
    report = run_render(tmp_path, "--preset", "gold_flake_8", "-o", "paint.exr", "--png", "paint.png",
                        "--width", 64, "--height", 48, "--spp", 8)
    spec, ch = read_exr(tmp_path / "paint.exr")
    assert (spec.width, spec.height) == (64, 48)
    assert set(spec.channelnames) == AOV_CHANNELS
    assert spec.format == oiio.HALF  # default precision
    for name, data in ch.items():
        assert np.isfinite(data).all(), name
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    assert (rgb >= 0).all()
    assert ((ch["A"] >= 0) & (ch["A"] <= 1)).all()
    # The sphere and floor fill the frame; the sky shows above the horizon only.
    assert 0.5 < ch["A"].mean() <= 1.0
    # Gold paint: red > green > blue on average, in a plausible exposure range.
    mean = rgb.reshape(-1, 3).mean(axis=0)
    assert 0.05 < mean.mean() < 3.0, mean
    assert mean[0] > mean[1] > mean[2], mean
    # The JSON report's mean is the float image's mean; the EXR holds halves (3 digits).
    np.testing.assert_allclose(mean, report["mean_rgb"], rtol=2e-3)
    # Albedo is a directional albedo: within [0, 1] up to sampling noise at 8 spp.
    albedo = np.stack([ch["albedo.R"], ch["albedo.G"], ch["albedo.B"]], axis=-1)
    assert (albedo >= 0).all() and albedo.mean() < 1.0
    # Normals are unit vectors where geometry was hit in every sample.
    n = np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], axis=-1)
    covered = ch["A"] == 1.0
    lengths = np.linalg.norm(n[covered], axis=-1)
    np.testing.assert_allclose(lengths[lengths > 0.99], 1.0, atol=2e-3)
    assert (lengths > 0.99).mean() > 0.9
    # Render metadata travels with the file.
    assert spec.getattribute("lacquer:spp") == "8"
    assert "gold_flake_8" in spec.getattribute("lacquer:render")
    assert report["paths"] == 64 * 48 * 8 and report["invalid_paths"] == 0
    # The preview PNG has the same size.
    png = oiio.ImageInput.open(str(tmp_path / "paint.png"))
    assert png is not None and (png.spec().width, png.spec().height) == (64, 48)
    png.close()


def test_white_furnace_cli(tmp_path):
    """A lossless Lambert sphere in a uniform environment of radiance 1 renders to 1 everywhere
    (background pixels exactly, sphere pixels within Monte Carlo noise)."""
    run_render(tmp_path, "--preset", "white_lambert", "--env", "uniform:1", "--no-floor", "--no-key-light",
               "--width", 32, "--height", 32, "--spp", 64, "--precision", "float", "--no-aovs", "-o", "f.exr")
    spec, ch = read_exr(tmp_path / "f.exr")
    assert spec.format == oiio.FLOAT
    assert set(spec.channelnames) == {"R", "G", "B", "A"}
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    background = ch["A"] == 0
    sphere = ch["A"] == 1
    assert sphere.sum() > 100 and background.sum() > 100
    np.testing.assert_allclose(rgb[background], 1.0, atol=1e-6)
    # Per-sample standard deviation is ~0.4 here: 64 spp → σ_pixel ≈ 0.05, σ_mean ≈ 0.003.
    assert abs(rgb[sphere].mean() - 1.0) < 0.01
    assert np.abs(rgb[sphere] - 1.0).max() < 0.3


def test_direct_point_light_closed_form(tmp_path):
    """The thesis' local illumination L = f_r · I/r² · cos θi through a JSON scene: a Lambert
    (albedo ρ) sphere's top point under a point light straight above it renders ρ/π · I/h²."""
    scene = {
        "camera": {"position": [0, 1.02, 0.0001], "look_at": [0, 0, 0], "fov_deg": 0.5},
        "materials": {"paint": {"model": "lambert", "albedo": 0.6}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "paint"}],
        "lights": [{"type": "point", "position": [0, 3, 0], "intensity": 8}],
    }
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    run_render(tmp_path, "--scene", "scene.json", "--direct", "--width", 4, "--height", 4, "--spp", 4,
               "--precision", "float", "--no-aovs", "-o", "p.exr")
    _, ch = read_exr(tmp_path / "p.exr")
    expected = 0.6 / np.pi * 8 / 2.0**2
    # The 0.5° view covers ±0.0045 around the pole: cos θ and r² change by < 1e-4.
    np.testing.assert_allclose(ch["G"], expected, rtol=3e-4)


def test_sheet(tmp_path):
    """The thesis density sheet: 2 rows × 5 cells, all finite; flakes change the cells."""
    report = run_render(tmp_path, "--sheet", "thesis-density", "--cell", 32, "--spp", 4, "-o", "sheet.exr",
                        "--png", "sheet.png")
    spec, ch = read_exr(tmp_path / "sheet.exr")
    gap, band = 6, 7 + 12
    assert (spec.width, spec.height) == (5 * 32 + 6 * gap, 2 * (32 + band) + gap)
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    assert np.isfinite(rgb).all() and (rgb >= 0).all()
    assert len(report["what"]["presets"]) == 10

    def cell(r, c):
        y0, x0 = gap + r * (32 + band), gap + c * (32 + gap)
        return rgb[y0:y0 + 32, x0:x0 + 32]

    # Every cell is rendered (not left black) and gold differs from silver.
    for r in range(2):
        for c in range(5):
            assert cell(r, c).mean() > 0.02
    assert cell(0, 0)[..., 2].mean() < cell(1, 0)[..., 2].mean()  # gold has less blue


def test_deterministic_per_seed(tmp_path):
    args = ["--preset", "silver_flake_5", "--width", 24, "--height", 16, "--spp", 4, "--precision", "float"]
    run_render(tmp_path, *args, "--seed", 3, "-o", "a.exr")
    run_render(tmp_path, *args, "--seed", 3, "--threads", 1, "-o", "b.exr")
    run_render(tmp_path, *args, "--seed", 4, "-o", "c.exr")
    a, b, c = (read_exr(tmp_path / f)[1]["R"] for f in ("a.exr", "b.exr", "c.exr"))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_errors_name_the_problem(tmp_path):
    proc = run_render(tmp_path, "--preset", "no_such_paint", "-o", "x.exr", expect_ok=False)
    assert proc.returncode != 0 and "no_such_paint" in proc.stderr
    proc = run_render(tmp_path, "--sheet", "nope", "-o", "x.exr", expect_ok=False)
    assert proc.returncode != 0 and "thesis-density" in proc.stderr
    assert not (tmp_path / "x.exr").exists()


def test_mesh_in_builtin_scene(tmp_path):
    """--mesh puts an OBJ (here a cube made of quads) in the built-in scene instead of the sphere."""
    v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    obj = "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join("f %d %d %d %d\n" % f for f in faces)
    (tmp_path / "cube.obj").write_text(obj)
    run_render(tmp_path, "--preset", "solid_red", "--mesh", "cube.obj", "--no-floor", "--width", 32, "--height", 32,
               "--spp", 4, "-o", "cube.exr")
    _, ch = read_exr(tmp_path / "cube.exr")
    covered = ch["A"] == 1.0
    assert 50 < covered.sum() < 32 * 32  # the cube fills part of the frame
    # Solid red paint: red dominates on the cube.
    assert ch["R"][covered].mean() > ch["G"][covered].mean()
