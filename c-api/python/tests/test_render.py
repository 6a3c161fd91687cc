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
