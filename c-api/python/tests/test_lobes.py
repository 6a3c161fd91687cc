"""Lobe selection (ABI 0.7) through the Python package: the groups of a paint, the parts
adding up to the whole, sampling one group, and bad masks."""

import numpy as np
import pytest

import lacquer


def _dirs(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_lobe_parts_of_paints():
    flakes = lacquer.Material("gold_flake_8")
    assert flakes.lobe_parts() == [
        (lacquer.LOBE_DIFFUSE, lacquer.LOBE_DIFFUSE),
        (lacquer.LOBE_GLOSSY, lacquer.LOBE_GLOSSY),
        (lacquer.LOBE_COAT, lacquer.LOBE_GLOSSY),
    ]
    assert flakes.lobes() & lacquer.LOBE_COAT
    smooth = lacquer.Material({"model": "coated_paint", "coat_roughness": 0, "flake_density": 0})
    assert smooth.lobe_parts() == [(lacquer.LOBE_DIFFUSE, lacquer.LOBE_DIFFUSE), (lacquer.LOBE_COAT, lacquer.LOBE_DELTA)]
    assert lacquer.Material({"model": "lambert"}).lobe_parts() == [(lacquer.LOBE_DIFFUSE, lacquer.LOBE_DIFFUSE)]


def test_parts_sum_to_the_full_eval_and_full_mask_is_plain():
    """f32 parts against the plain call: summed in another order, asserted 1e-5 relative
    (the core's own test measures 2.4e-7); the full mask is the plain call bit for bit."""
    m = lacquer.Material("gold_flake_8")
    wi, wo = _dirs(500, 1), _dirs(500, 2)
    f, p = m.eval_pdf(wi.astype(np.float32), wo.astype(np.float32))
    total = sum(m.eval_pdf_lobes(wi, wo, l)[0] for l in (lacquer.LOBE_DIFFUSE, lacquer.LOBE_GLOSSY, lacquer.LOBE_COAT))
    assert np.allclose(total, f, rtol=1e-5, atol=1e-7)
    f_all, p_all = m.eval_pdf_lobes(wi, wo, lacquer.LOBES_SELECTABLE)
    assert np.array_equal(f_all, f) and np.array_equal(p_all, p)


def test_sampling_one_group_returns_its_lobe():
    m = lacquer.Material({"model": "coated_paint", "coat_roughness": 0, "flake_density": 5})
    wo = _dirs(256, 3)
    u = np.random.default_rng(4).random((256, 3))
    coat = m.sample_lobes(wo, u, lacquer.LOBE_COAT)
    assert np.all(coat.flags == lacquer.LQ_SAMPLE_DELTA)  # the smooth coat alone: the mirror
    glossy = m.sample_lobes(wo, u, lacquer.LOBE_GLOSSY)
    ok = glossy.flags == 0
    # Flake samples that do not escape the coat (total internal reflection) fail: 161 of 256
    # succeed on these directions (measured).
    assert ok.sum() > 100 and not np.any(glossy.flags & lacquer.LQ_SAMPLE_DELTA)
    f, p = m.eval_pdf_lobes(glossy.wi[ok], wo[ok], lacquer.LOBE_GLOSSY)
    assert np.allclose(p, glossy.pdf[ok], rtol=1e-4)
    assert np.allclose(f * glossy.wi[ok][:, 2:3] / p[:, None], glossy.weight[ok], rtol=1e-4, atol=1e-7)


def test_bad_masks_raise():
    m = lacquer.Material("gold_flake_8")
    with pytest.raises(lacquer.InvalidArgumentError, match="lobe mask"):
        m.eval_pdf_lobes(_dirs(2, 1), _dirs(2, 2), lacquer.LOBE_DELTA)
    ct = lacquer.Material({"model": "cook_torrance"})
    with pytest.raises(lacquer.InvalidArgumentError, match="all or none"):
        ct.sample_lobes(_dirs(2, 1), np.full((2, 3), 0.5), lacquer.LOBE_DIFFUSE)
    f, p = m.eval_pdf_lobes(_dirs(3, 1), _dirs(3, 2), 0)
    assert not f.any() and not p.any()
