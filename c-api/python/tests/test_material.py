"""The Python package over the installed wheel: the CONTRACT API and its behaviour."""

import json
import math
import os
import pickle
import threading
from pathlib import Path

import numpy as np
import pytest

import lacquer

PI = math.pi


def test_abi_and_library_location():
    assert lacquer.abi_version >> 16 == 0 and lacquer.abi_version & 0xFFFF >= 1
    assert lacquer.__version__.count(".") == 2
    if not os.environ.get("LACQUER_LIBRARY"):
        # The wheel carries the library: it is loaded from the package folder.
        assert Path(lacquer.library_path).parent == Path(lacquer.__file__).parent


def test_material_from_preset_dict_json_and_material():
    a = lacquer.Material("white_lambert")
    b = lacquer.Material({"model": "lambert", "albedo": 1.0})
    c = lacquer.Material('{"model": "lambert", "albedo": [1, 1, 1]}')
    d = lacquer.Material(a)
    e = lacquer.Material.preset("white_lambert")
    f = lacquer.Material.from_json('{"preset": "white_lambert"}')
    assert {m.to_json() for m in (a, b, c, d, e, f)} == {a.to_json()}
    assert a.model == "lambert"
    assert a.to_dict()["albedo"] == [1.0, 1.0, 1.0]
    assert "lambert" in repr(a)
    assert pickle.loads(pickle.dumps(a)).to_json() == a.to_json()


def test_lambert_closed_forms():
    m = lacquer.Material({"model": "lambert", "albedo": [0.8, 0.5, 0.25]})
    wi = np.array([[0.0, 0.6, 0.8], [0.0, 0.0, 1.0], [0.3, 0.4, -0.866]])
    wo = np.array([[0.0, 0.0, 1.0]] * 3)
    f = m.eval(wi, wo)
    assert f.shape == (3, 3) and f.dtype == np.float64
    np.testing.assert_allclose(f[:2], np.array([[0.8, 0.5, 0.25]] * 2) / PI, rtol=0, atol=1e-15)
    assert (f[2] == 0).all()  # below the horizon
    p = m.pdf(wi, wo)
    np.testing.assert_allclose(p, [0.8 / PI, 1 / PI, 0.0], atol=1e-15)
    f2, p2 = m.eval_pdf(wi, wo)
    assert (f2 == f).all() and (p2 == p).all()


def test_dtypes_shapes_and_broadcasting():
    m = lacquer.Material("white_lambert")
    wi32 = np.array([[0, 0.6, 0.8]], np.float32)
    wo32 = np.array([[0, 0, 1]], np.float32)
    assert m.eval(wi32, wo32).dtype == np.float32
    assert m.eval(wi32, wo32.astype(np.float64)).dtype == np.float64
    # One direction: shape (3,) -> (3,) and a scalar pdf.
    assert m.eval([0, 0.6, 0.8], [0, 0, 1]).shape == (3,)
    assert m.pdf([0, 0.6, 0.8], [0, 0, 1]).shape == ()
    # One wo against many wi; 2-D grids of directions.
    wi = np.tile([0.0, 0.6, 0.8], (5, 4, 1))
    assert m.eval(wi, [0, 0, 1]).shape == (5, 4, 3)
    assert m.pdf(wi, [0, 0, 1]).shape == (5, 4)
    # Empty batch.
    assert m.eval(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0, 3)
    # Integer input is accepted (converted to float64).
    assert m.eval([0, 0, 1], [0, 0, 1]).dtype == np.float64


def test_sampling_is_consistent_with_pdf_and_eval():
    rng = np.random.default_rng(1)
    m = lacquer.Material({"model": "lambert", "albedo": [0.9, 0.4, 0.1]})
    wo = np.tile([0.3, -0.2, 0.9], (2000, 1))
    s = m.sample(wo, rng.random((2000, 3)))
    assert s.wi.shape == (2000, 3) and s.pdf.shape == (2000,) and s.flags.dtype == np.uint32
    assert (s.flags == 0).all() and (s.pdf > 0).all()
    np.testing.assert_allclose(s.pdf, m.pdf(s.wi, wo), rtol=1e-12)
    np.testing.assert_allclose(s.weight, m.eval(s.wi, wo) * s.wi[:, 2:] / s.pdf[:, None], rtol=1e-12)
    np.testing.assert_allclose(s.weight, np.tile([0.9, 0.4, 0.1], (2000, 1)), rtol=1e-12)
    # Below the horizon: a failed sample, not an error.
    f = m.sample([0, 0, -1], [0.5, 0.5, 0.5])
    assert f.pdf == 0 and f.flags == lacquer.LQ_SAMPLE_FAILED and (f.weight == 0).all()


@pytest.mark.parametrize("info", lacquer.models(), ids=lambda m: m["name"])
def test_every_model_through_python(info):
    rng = np.random.default_rng(7)
    m = lacquer.Material({"model": info["name"]})
    n = 4000
    wo = rng.normal(size=(n, 3))
    wo[:, 2] = np.abs(wo[:, 2]) + 0.05
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    s = m.sample(wo, rng.random((n, 3)))
    ok = s.pdf > 0
    assert np.isfinite(s.weight).all() and (s.weight >= 0).all()
    smooth = ok & ((s.flags & lacquer.LQ_SAMPLE_DELTA) == 0)
    f, p = m.eval_pdf(s.wi[smooth], wo[smooth])
    np.testing.assert_allclose(s.pdf[smooth], p, rtol=1e-6)
    assert np.isfinite(f).all() and (f >= 0).all()
    # f32 and f64 paths agree to the precision the checks demand.
    f32 = m.eval(s.wi[smooth].astype(np.float32), wo[smooth].astype(np.float32))
    np.testing.assert_allclose(f32, f, rtol=2e-3, atol=1e-4 * max(f.max(), 1e-30))


def test_spatial_inputs_are_accepted():
    m = lacquer.Material("white_lambert")
    wi = np.array([[0, 0.6, 0.8]] * 4, np.float32)
    wo = np.array([[0, 0, 1]] * 4, np.float32)
    uv = np.random.default_rng(0).random((4, 2))
    duv = np.full((4, 4), 1e-3)
    f = m.eval(wi, wo, uv=uv, duv=duv)
    assert f.dtype == np.float32 and (f == m.eval(wi, wo)).all()
    assert (m.pdf(wi, wo, uv=uv) == m.pdf(wi, wo)).all()
    s = m.sample(wo, np.full((4, 3), 0.3), uv=uv, duv=duv)
    assert (s.pdf == m.sample(wo, np.full((4, 3), 0.3, np.float32)).pdf).all()


def test_one_material_from_eight_threads():
    rng = np.random.default_rng(3)
    m = lacquer.Material({"model": "lambert", "albedo": [0.7, 0.6, 0.5]})
    wi = rng.normal(size=(200_000, 3))
    wo = rng.normal(size=(200_000, 3))
    reference = m.eval(wi, wo)
    results = [None] * 8

    def work(k):
        results[k] = m.eval(wi, wo)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        assert r.tobytes() == reference.tobytes()


def test_catalogue_and_checks():
    names = [m["name"] for m in lacquer.models()]
    assert "lambert" in names
    for m in lacquer.models():
        assert set(m["claims"]) == {"reciprocal", "energy_conserving", "sampled"}
        for p in m["params"]:
            assert {"name", "kind", "default", "min", "max", "unit", "doc"} <= set(p)
    presets = lacquer.presets()
    assert "white_lambert" in [p["name"] for p in presets]
    for p in presets:
        assert lacquer.Material(p["name"]).to_dict() == p["material"]
    r = lacquer.Material({"model": "lambert", "albedo": 0.9}).check("quick")
    assert r.passed and {v["check"] for v in r.report["verdicts"]} >= {"reciprocity", "energy", "chi2"}
    r = lacquer.check_model("lambert")
    assert r.passed and r.report["model"] == "lambert"


def test_per_element_errors_carry_the_result():
    m = lacquer.Material("white_lambert")
    wi = np.array([[0, 0, 1], [np.nan, 0, 1], [0, 0, 1]])
    wo = np.array([[0, 0, 1]] * 3)
    with pytest.raises(lacquer.InvalidDirectionError) as e:
        m.eval(wi, wo)
    assert "1 of 3 elements" in str(e.value) and "element 1" in str(e.value)
    assert e.value.status == 6 and e.value.status_name == "LQ_ERR_INVALID_DIRECTION"
    f = e.value.result
    assert (f[1] == 0).all() and abs(f[0, 0] - 1 / PI) < 1e-15
    f2 = m.eval(wi, wo, strict=False)
    assert (f2 == f).all()


def test_library_env_override(tmp_path):
    import shutil
    import subprocess
    import sys

    code = "import lacquer; print(lacquer.library_path)"
    env = dict(os.environ, LACQUER_LIBRARY=str(tmp_path / "missing.so"))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert r.returncode != 0 and "LACQUER_LIBRARY" in r.stderr
    copy = tmp_path / "liblacquer-copy.so"
    shutil.copy(lacquer.library_path, copy)
    env["LACQUER_LIBRARY"] = str(copy)
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(copy)


def test_incompatible_abi_is_refused_at_import():
    import subprocess
    import sys

    # A library whose lq_abi_version() reports ABI 1.0: the import must fail, not misbehave.
    code = """
import ctypes
real_cdll = ctypes.CDLL
fake_version = ctypes.CFUNCTYPE(ctypes.c_uint32)(lambda: 1 << 16)
class FakeLib:
    def __init__(self, path, *a, **k):
        self._lib = real_cdll(path, *a, **k)
    def __getattr__(self, name):
        return fake_version if name == "lq_abi_version" else getattr(self._lib, name)
ctypes.CDLL = FakeLib
try:
    import lacquer
except ImportError as e:
    print("refused:", e)
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "refused:" in r.stdout and "ABI 1.0" in r.stdout, r.stdout


def test_lobes_and_diffuse_reflectance():
    """lq_material_lobes / lq_material_diffuse_reflectance through the package."""
    paint = lacquer.Material({"model": "coated_paint", "coat_roughness": 0, "base_color": [0.2, 0.3, 0.4]})
    lobes = paint.lobes()
    assert lobes & lacquer.LOBE_DIFFUSE and lobes & lacquer.LOBE_DELTA and lobes & lacquer.LOBE_GLOSSY
    assert not lobes & lacquer.LOBE_ANISOTROPIC
    assert np.allclose(paint.diffuse_reflectance(), [0.2, 0.3, 0.4], rtol=1e-6)
    conductor = lacquer.Material({"model": "rough_conductor", "alpha_u": 0.1, "alpha_v": 0.3})
    assert conductor.lobes() & lacquer.LOBE_ANISOTROPIC
    assert np.all(conductor.diffuse_reflectance() == 0)
    assert lacquer.Material({"model": "phong"}).lobes() & lacquer.LOBE_NON_RECIPROCAL
