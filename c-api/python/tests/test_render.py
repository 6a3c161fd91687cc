"""lacquer.render: the reference renderer through the C ABI."""
import numpy as np
import pytest

import lacquer


def test_render_returns_a_finite_image_and_reports_progress():
    seen = []
    out = lacquer.render({"preset": "white_lambert", "width": 12, "height": 8, "spp": 2}, progress=lambda f: seen.append(f) or True)
    rgba = out["rgba"]
    assert rgba.shape == (8, 12, 4) and rgba.dtype == np.float32
    assert np.isfinite(rgba).all() and (rgba >= 0).all()
    assert out["albedo"].shape == (8, 12, 3)
    assert seen and 0.0 <= min(seen) and max(seen) <= 1.0


def test_render_cancel_and_errors():
    with pytest.raises(lacquer.CancelledError):
        # Progress is polled every 100 ms: the job must run longer than that to be cancelled.
        lacquer.render({"preset": "gold_flake_0", "width": 64, "height": 64, "spp": 4096}, progress=lambda f: False)
    with pytest.raises(lacquer.InvalidArgumentError, match="no_such"):
        lacquer.render({"preset": "no_such_preset"})
    with pytest.raises(lacquer.InvalidArgumentError):
        lacquer.render('{"spp": 0}')


def test_render_session_rounds_end_at_the_one_shot_image():
    job = {"preset": "gold_flake_8", "width": 16, "height": 12, "spp": 6}
    once = lacquer.render(job)
    s = lacquer.RenderSession(job)
    assert (s.samples, s.target) == (0, 6)
    assert s.advance(2) == 2
    partial = s.image()
    assert partial["rgba"].shape == (12, 16, 4) and np.isfinite(partial["rgba"]).all()
    assert not np.array_equal(partial["rgba"], once["rgba"])
    assert s.advance(10) == 4 and s.samples == 6
    done = s.image()
    for k in ("rgba", "albedo", "normal"):
        assert np.array_equal(done[k], once[k]), k
    s.close()
    with pytest.raises(ValueError):
        s.advance(1)
    with pytest.raises(lacquer.InvalidArgumentError, match="no_such"):
        lacquer.RenderSession({"preset": "no_such_preset"})
    big = lacquer.RenderSession({"preset": "gold_flake_0", "width": 64, "height": 64, "spp": 4096})
    with pytest.raises(lacquer.CancelledError):
        big.advance(4096, progress=lambda f: False)
    assert big.samples == 0


def test_render_diffuse_and_glossy_color_layers():
    """``"lobe_aovs": True`` adds Diffuse Color and Glossy Color (ABI 0.8); off by default. A
    Lambert's diffuse colour is its albedo (every sample weight is exactly 0.5), its glossy
    colour zero."""
    plain = lacquer.render({"preset": "white_lambert", "width": 6, "height": 4, "spp": 2, "floor": False})
    assert plain["diffuse_color"] is None and plain["glossy_color"] is None
    out = lacquer.render({"material": {"model": "lambert", "albedo": 0.5}, "width": 6, "height": 4, "spp": 2,
                          "floor": False, "lobe_aovs": True})
    d, g = out["diffuse_color"], out["glossy_color"]
    assert d.shape == g.shape == (4, 6, 3)
    hit = out["rgba"][..., 3] == 1.0
    assert hit.any() and np.allclose(d[hit], 0.5, atol=1e-6) and (g == 0).all()
