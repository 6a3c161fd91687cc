"""Tables sampled from Mitsuba 3's own BSDFs, an independent source, are read and fitted by
`lacquer fit`.

Mitsuba 3.9.1 (`scalar_rgb`) evaluates `roughplastic` and `roughconductor` at every node of
the MERL grid (built here with numpy from the format's definition, not with Lacquer's code);
the values are written as a MERL `.binary` file. Then:

- `lacquer check --material '{"model": "measured", "file": ...}'` loads it (the real loader) and
  the measured model passes its claims on it;
- `lacquer fit` fits the matching Lacquer model (`rough_plastic`, `rough_conductor`, written to
  Mitsuba's formulas) and recovers Mitsuba's parameters (η, k, α, reflectances) to the
  tolerances stated at the tests, and always fits `ward`; a NaN, Inf or negative value from
  Mitsuba at a valid node fails the test.

Environment: `pip install -r tests/requirements.txt` (mitsuba==3.9.1, numpy, pytest). The
Lacquer binary is `$LACQUER_BIN`, else `$CARGO_TARGET_DIR/release/lacquer` or
`target/release/lacquer`, built with `cargo build --release -p lacquer-cli` when missing.

Run as a script to write a table for demos: `python tests/test_fit_mitsuba.py OUT.binary
roughplastic|roughconductor`.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
N_TH, N_TD, N_PD = 90, 90, 180

# Mitsuba BSDFs sampled by the tests, and the Lacquer fit spec that matches each one.
PLASTIC = {
    "type": "roughplastic",
    "distribution": "ggx",
    "alpha": 0.12,
    "int_ior": 1.5,
    "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.15, 0.05]},
}
PLASTIC_FIT = {"model": "rough_plastic", "distribution": "ggx", "ext_ior": 1.000277, "nonlinear": False}
CONDUCTOR_ETA = [0.2, 0.9, 1.1]
CONDUCTOR_K = [3.9, 2.4, 2.2]
CONDUCTOR = {
    "type": "roughconductor",
    "distribution": "ggx",
    "alpha": 0.15,
    "eta": {"type": "rgb", "value": CONDUCTOR_ETA},
    "k": {"type": "rgb", "value": CONDUCTOR_K},
}
CONDUCTOR_FIT = {"model": "rough_conductor", "distribution": "ggx", "material": "none"}


def merl_node_directions():
    """(wi, wo, valid) of every MERL node, arrays of shape (90, 90, 180, 3), from the format's
    definition: θh = (i/90)² π/2, θd = j/90 π/2, φd = k/180 π, φh = 0; wi is the difference
    vector d rotated by θh about y, wo the rotation of (−dx, −dy, dz)."""
    th = (np.arange(N_TH) / N_TH) ** 2 * (math.pi / 2)
    td = np.arange(N_TD) / N_TD * (math.pi / 2)
    pd = np.arange(N_PD) / N_PD * math.pi
    th, td, pd = np.meshgrid(th, td, pd, indexing="ij")
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], axis=-1)

    def rot_y(v, t):
        c, s = np.cos(t), np.sin(t)
        return np.stack([v[..., 0] * c + v[..., 2] * s, v[..., 1], -v[..., 0] * s + v[..., 2] * c], axis=-1)

    wi = rot_y(d, th)
    wo = rot_y(d * np.array([-1.0, -1.0, 1.0]), th)
    valid = (wi[..., 2] > 1e-6) & (wo[..., 2] > 1e-6)
    return wi, wo, valid


def sample_mitsuba(bsdf_dict):
    """RGB BRDF (1/sr, no cosine) of a Mitsuba BSDF at every MERL node; −1 where the node has
    no valid direction pair. A NaN, infinite or negative value from Mitsuba at a valid node is
    an error (it used to be written as 0, a fake measurement the fit then tried to follow)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    bsdf = mi.load_dict(bsdf_dict)
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    wi, wo, valid = merl_node_directions()
    out = -np.ones(wi.shape)
    idx = np.argwhere(valid)
    for a, b, c in idx:
        i, o = wi[a, b, c], wo[a, b, c]
        # Mitsuba: si.wi points to the viewer (our wo), its wo to the light (our wi), and
        # eval includes the cosine of its wo.
        si.wi = mi.Vector3f(o[0], o[1], o[2])
        v = bsdf.eval(ctx, si, mi.Vector3f(i[0], i[1], i[2]))
        out[a, b, c] = np.array([v[0], v[1], v[2]]) / i[2]
    reject_invalid(out, valid)
    return out


def reject_invalid(out, valid):
    """Raises ValueError when a valid node holds a NaN, infinite or negative value."""
    bad = (~np.isfinite(out) | (out < 0)).any(axis=-1) & valid
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"Mitsuba returned {int(bad.sum())} invalid (NaN, Inf or negative) values at valid "
                         f"MERL nodes, first at (θh, θd, φd) index {first}: {out[first]}")


def write_merl(path, rgb):
    """Writes a MERL .binary file: int32 90 90 180, then red, green, blue planes of f64
    (value / channel scale; invalid entries −1)."""
    planes = []
    for c in range(3):
        v = rgb[..., c]
        planes.append(np.where(v >= 0, v / SCALE[c], -1.0).astype("<f8").ravel())
    with open(path, "wb") as f:
        f.write(np.array([N_TH, N_TD, N_PD], dtype="<i4").tobytes())
        for p in planes:
            f.write(p.tobytes())


def lacquer_bin():
    env = os.environ.get("LACQUER_BIN")
    if env:
        return env
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    exe = target / "release" / "lacquer"
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "lacquer-cli"], cwd=ROOT, check=True)
    return str(exe)


def lacquer(*args):
    r = subprocess.run([lacquer_bin(), *args], capture_output=True, text=True)
    return r


def registered_models():
    r = lacquer("models", "--json")
    assert r.returncode == 0, r.stderr
    return {m["name"] for m in json.loads(r.stdout)}


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    pytest.importorskip("mitsuba")
    d = tmp_path_factory.mktemp("merl")
    out = {}
    for name, bsdf in [("roughplastic", PLASTIC), ("roughconductor", CONDUCTOR)]:
        path = d / f"{name}.binary"
        write_merl(path, sample_mitsuba(bsdf))
        out[name] = path
    return out


def test_node_directions_follow_the_format():
    wi, wo, valid = merl_node_directions()
    # Node (0, j, k): θh = 0, so wi and wo are mirror images about the normal at angle θd.
    j = 30
    assert np.allclose(wi[0, j, 0], [math.sin(j / 90 * math.pi / 2), 0, math.cos(j / 90 * math.pi / 2)])
    assert np.allclose(wo[0, j, 0] * [-1, -1, 1], wi[0, j, 0])
    # The half vector of every valid node is at θh from the normal.
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    th = (np.arange(N_TH) / N_TH) ** 2 * (math.pi / 2)
    assert np.allclose(np.arccos(np.clip(h[..., 2], -1, 1))[valid], np.broadcast_to(th[:, None, None], valid.shape)[valid], atol=1e-6)
    assert 0.7 < valid.mean() < 0.8


def test_invalid_mitsuba_values_fail():
    valid = np.array([[True, True, False]])
    reject_invalid(np.array([[[0.1, 0.2, 0.3], [0.0, 0.0, 0.0], [-1.0, -1.0, -1.0]]]), valid)
    for bad in (np.nan, np.inf, -1e-9):
        out = np.array([[[0.1, 0.2, 0.3], [0.0, bad, 0.0], [-1.0, -1.0, -1.0]]])
        with pytest.raises(ValueError, match="invalid"):
            reject_invalid(out, valid)


def test_loader_reads_mitsuba_tables_and_the_measured_model_passes(tables):
    for path in tables.values():
        material = json.dumps({"model": "measured", "file": str(path)})
        r = lacquer("check", "--material", material, "--quick", "--json")
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr
        report = json.loads(r.stdout)
        assert all(v["status"] != "fail" for v in report["verdicts"])


def fit(path, *args):
    r = lacquer("fit", "--table", str(path), "--json", *args)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)["fits"]


def test_ward_fits_mitsuba_tables_better_than_lambert(tables):
    # Ward's Gaussian lobe cannot follow GGX tails and Fresnel at grazing angles, so its SNR
    # stays low; it must still beat a constant (SNR > 0) and the Lambert fit.
    for path in tables.values():
        lam, ward = fit(path, "--model", "lambert,ward", "--points", "6000")
        assert ward["metrics"]["snr_weighted_db"] > max(0.0, lam["metrics"]["snr_weighted_db"]), (lam, ward)
        assert math.isfinite(ward["metrics"]["snr_db_mean"]) and ward["metrics"]["ngan"] < lam["metrics"]["ngan"]


# Measured on this machine (release build, 2026-12-01; `python tests/test_fit_mitsuba.py T.binary
# roughplastic` then `lacquer fit --table T.binary --spec ...`): both fits recover Mitsuba's
# parameters to 1e-5 or better, at SNR 100–126 dB. The tolerances below sit 10–50x above those
# figures (the optimiser's stopping point moves with the SIMD level and the thread split), far
# below the old ones (SNR > 30 dB, α ± 0.01, η and k never checked).


def test_rough_plastic_fits_mitsuba_roughplastic(tables):
    assert "rough_plastic" in registered_models()
    [f] = fit(tables["roughplastic"], "--spec", json.dumps(PLASTIC_FIT), "--points", "6000", "--budget", "120")
    m = f["metrics"]
    # measured: weighted SNR 99.7 dB, mean 110.9 dB
    assert m["snr_weighted_db"] > 90.0 and m["snr_db_mean"] > 100.0, f
    params = dict(f["parameters"])
    # measured errors: α 2.4e-7, int_ior 3.0e-6, diffuse ≤ 1.7e-5, specular ≤ 6.1e-6
    assert abs(params["alpha"] - PLASTIC["alpha"]) < 1e-5, params
    assert abs(params["int_ior"] - PLASTIC["int_ior"]) < 1e-4, params
    for c, want in enumerate(PLASTIC["diffuse_reflectance"]["value"]):
        assert abs(params[f"diffuse_reflectance[{c}]"] - want) < 2e-4, params
        assert abs(params[f"specular_reflectance[{c}]"] - 1.0) < 1e-4, params


def test_rough_conductor_fits_mitsuba_roughconductor(tables):
    assert "rough_conductor" in registered_models()
    [f] = fit(tables["roughconductor"], "--spec", json.dumps(CONDUCTOR_FIT), "--points", "6000", "--budget", "120")
    m = f["metrics"]
    # measured: weighted SNR 126.0 dB, mean 119.7 dB
    assert m["snr_weighted_db"] > 110.0 and m["snr_db_mean"] > 105.0, f
    params = dict(f["parameters"])
    # measured errors: α 6e-9, η ≤ 6.4e-7, k ≤ 2.3e-6, specular ≤ 1.6e-7
    assert abs(params["alpha_u"] - 0.15) < 1e-5 and abs(params["alpha_v"] - 0.15) < 1e-5, params
    for c in range(3):
        assert abs(params[f"eta[{c}]"] - CONDUCTOR_ETA[c]) < 1e-4, params
        assert abs(params[f"k[{c}]"] - CONDUCTOR_K[c]) < 1e-4, params
        assert abs(params[f"specular_reflectance[{c}]"] - 1.0) < 1e-4, params


def test_stop_snr_ends_the_fit_once_good_enough(tables):
    # `--stop-snr DB` stops each start and refinement once its subset's weighted error is DB
    # below the spread of its values: the report says "target", the fit takes fewer iterations
    # than the one that runs until it stops improving, and the whole-table figures sit near the
    # asked 40 dB rather than at the exact fit's 120 dB.
    args = ("--spec", json.dumps(CONDUCTOR_FIT), "--points", "6000", "--budget", "120")
    [full] = fit(tables["roughconductor"], *args)
    [good] = fit(tables["roughconductor"], *args, "--stop-snr", "40")
    assert full["stop"] != "target" and good["stop"] == "target", (full["stop"], good["stop"])
    assert good["total_iterations"] < full["total_iterations"], (good, full)
    w = good["metrics"]["snr_weighted_db"]
    # measured (session 46): weighted SNR 42.4 dB in 136 iterations; the full fit 126.0 dB in
    # 205 (stop "step"). The unweighted mean SNR is lower (30.2 dB): the stop is on the
    # solid-angle-weighted objective the fit minimises.
    assert 35.0 < w < full["metrics"]["snr_weighted_db"] - 20.0, (good, full)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[2] not in ("roughplastic", "roughconductor"):
        sys.exit("usage: test_fit_mitsuba.py OUT.binary roughplastic|roughconductor")
    write_merl(sys.argv[1], sample_mitsuba(PLASTIC if sys.argv[2] == "roughplastic" else CONDUCTOR))
    print(f"wrote {sys.argv[1]}")
