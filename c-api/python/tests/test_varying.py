"""Per-element paint parameters through the package (ABI 0.6): Material.eval_pdf_varying /
Material.sample_varying over lq_eval_pdf_varying / lq_sample_varying, against materials built
with each element's parameters."""

import numpy as np
import pytest

import lacquer

# A pigment-only rough paint: the per-element calls equal a material built with the
# element's parameters to 3e-14 in f64 (rust-core/tests/integration/varying.rs).
BASE = {"model": "coated_paint", "flake_density": 0.0, "sparkle": False, "coat_roughness": 0.1}


def directions(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.1
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)


def test_eval_pdf_varying_equals_per_element_materials():
    n = 6
    wi, wo = directions(n, 1), directions(n, 2)
    colours = np.random.default_rng(3).random((n, 3)).astype(np.float32)
    m = lacquer.Material(BASE)
    f, pdf = m.eval_pdf_varying(wi, wo, base_color=colours)
    assert f.shape == (n, 3) and pdf.shape == (n,) and f.dtype == np.float32
    for i in range(n):
        mi = lacquer.Material({**BASE, "base_color": [float(c) for c in colours[i]]})
        fi, pi = mi.eval_pdf(wi[i : i + 1], wo[i : i + 1])
        # float32 kernels on both sides: measured 6.8e-8 (f) and 0 (pdf) relative
        np.testing.assert_allclose(f[i], fi[0], rtol=1e-5)
        np.testing.assert_allclose(pdf[i], pi[0], rtol=1e-5)
    # the same colour for every element broadcasts
    f1, _ = m.eval_pdf_varying(wi, wo, base_color=colours[0])
    np.testing.assert_allclose(f1[0], f[0], rtol=1e-6)


def test_sample_varying_equals_per_element_materials():
    n = 64
    wo = directions(n, 4)
    u = np.random.default_rng(5).random((n, 3)).astype(np.float32)
    colour = np.array([0.7, 0.3, 0.1], np.float32)
    m = lacquer.Material(BASE)
    s = m.sample_varying(wo, u, base_color=colour)
    r = lacquer.Material({**BASE, "base_color": [0.7, 0.3, 0.1]}).sample(wo, u)
    ok = r.pdf > 0
    assert ok.sum() > n // 2
    # measured: wi identical, pdf 1.5e-7 and weight 2.3e-7 relative
    np.testing.assert_allclose(s.wi[ok], r.wi[ok], atol=1e-5)
    np.testing.assert_allclose(s.pdf[ok], r.pdf[ok], rtol=1e-4)
    np.testing.assert_allclose(s.weight[ok], r.weight[ok], rtol=1e-4, atol=1e-7)
    np.testing.assert_array_equal(s.flags, r.flags)


def test_varying_invalid_element_and_wrong_model():
    wi, wo = directions(3, 6), directions(3, 7)
    m = lacquer.Material(BASE)
    with pytest.raises(lacquer.InvalidElementError, match="base_color") as e:
        m.eval_pdf_varying(wi, wo, base_color=[[0.5, 0.5, 0.5], [1.5, 0.2, 0.2], [0.2, 0.2, 0.2]])
    f, pdf = e.value.result
    assert np.all(f[1] == 0) and pdf[1] == 0 and np.all(f[[0, 2]] > 0)
    s = m.sample_varying(wo, np.full((3, 3), 0.4), flake_density=[1.0, np.nan, 2.0], strict=False)
    assert s.flags[1] & 2 and s.pdf[1] == 0 and s.pdf[0] > 0
    with pytest.raises(lacquer.InvalidArgumentError, match="coated_paint"):
        lacquer.Material({"model": "lambert"}).eval_pdf_varying(wi, wo, base_color=[0.5, 0.5, 0.5])
    with pytest.raises(lacquer.InvalidArgumentError, match="base_color"):
        m.eval_pdf_varying(wi, wo, base_color=[0.5, 0.5])
