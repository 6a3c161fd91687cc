"""Speed controls through the C ABI: thread count, SIMD level, the error-budget choice."""

import numpy as np
import pytest

import lacquer


def _pairs(n, seed=3):
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(2, n, 3)).astype(np.float32)
    w[..., 2] = np.abs(w[..., 2]) + 0.05
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    return w[0], w[1]


def test_simd_level_is_one_of_the_known_levels():
    assert lacquer.simd_level() in {"avx512", "avx2", "scalar"}


def test_thread_count_does_not_change_values():
    """A batch large enough to be split over threads gives bit-identical values with 1 and
    with all threads (the kernels compute each element the same way on any thread)."""
    m = lacquer.Material({"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2})
    wi, wo = _pairs(100_000)
    try:
        lacquer.set_thread_count(1)
        one = m.eval(wi, wo)
        lacquer.set_thread_count(0)
        all_ = m.eval(wi, wo)
    finally:
        lacquer.set_thread_count(0)
    assert one.view(np.uint32).tolist() == all_.view(np.uint32).tolist()
    with pytest.raises(ValueError):
        lacquer.set_thread_count(-1)


def test_choose_configuration_respects_the_tolerance():
    """A loose tolerance lets the chooser drop a lobe the material barely needs; the picked
    configuration's measured error is within the tolerance, and a zero tolerance keeps the
    f64 reference (error 0 by definition)."""
    paint = {"preset": "gold_flake_2"}
    loose = lacquer.choose_configuration(paint, 0.5, n=4096)
    assert loose["picked"]["error"]["max"] <= 0.5
    assert loose["picked"]["path"] != "f64"
    assert len(loose["candidates"]) >= 3
    strict = lacquer.choose_configuration(paint, 0.0, n=4096)
    assert strict["picked"]["path"] == "f64" and strict["picked"]["error"]["max"] == 0.0
    with pytest.raises(lacquer.InvalidArgumentError):
        lacquer.choose_configuration(paint, float("nan"))
