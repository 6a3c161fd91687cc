"""lacquer.fit_node_group: the Blender node group fitted to a coated paint, through the C ABI."""

import math

import pytest

import lacquer

SOCKETS = {
    "Pigment Color",
    "Flake Color",
    "Flake Coverage",
    "Flake Roughness",
    "Flake Spread",
    "Flake Size",
    "Pearl Coverage",
    "Pearl Color",
    "Pearl Film Thickness",
    "Pearl Film IOR",
    "Pearl Spread",
    "Coat Weight",
    "Coat Roughness",
    "Coat IOR",
    "Coat Tint",
    "Sparkle",
}
ERRORS = {"albedo_rms", "albedo_max", "brdf_rel_rms", "brdf_cos_rms", "snr_db", "seconds"}


def _check_result(r):
    assert set(r["inputs"]) == SOCKETS
    assert set(r["error"]) == ERRORS
    for name in ("Pigment Color", "Flake Color", "Pearl Color", "Coat Tint"):
        c = r["inputs"][name]
        assert len(c) == 3 and all(0.0 <= v <= 1.0 for v in c)
    assert all(math.isfinite(v) for v in r["error"].values())
    assert r["inputs"]["Flake Coverage"] + r["inputs"]["Pearl Coverage"] <= 1.0
    # The base colour map (what a textured Base Color becomes in the node group).
    m = r["base_color_map"]
    assert m["base_color"] == [k / 8 for k in range(9)]
    assert len(m["ratio"]) == 9 and all(len(q) == 3 and all(math.isfinite(v) for v in q) for q in m["ratio"])


def test_preset_name_dict_json_and_material_agree():
    by_name = lacquer.fit_node_group("gold_flake_5")
    _check_result(by_name)
    # Copied from the paint, not fitted.
    assert by_name["inputs"]["Flake Size"] == 25.0
    assert by_name["inputs"]["Coat IOR"] == 1.5
    assert by_name["inputs"]["Coat Roughness"] == pytest.approx(math.sqrt(0.02))
    material = lacquer.Material("gold_flake_5")
    for spec in ({"preset": "gold_flake_5"}, material.to_dict(), material.to_json(), material):
        r = lacquer.fit_node_group(spec)
        assert r["inputs"] == by_name["inputs"]


def test_fit_is_close_to_a_solid_paint():
    r = lacquer.fit_node_group({"model": "coated_paint", "base_color": [0.4, 0.1, 0.05], "flake_density": 0})
    _check_result(r)
    assert r["inputs"]["Flake Coverage"] == 0.0 and r["inputs"]["Pearl Coverage"] == 0.0
    assert r["error"]["albedo_max"] < 0.02
    assert r["error"]["snr_db"] > 20.0


def test_bad_input_raises_the_documented_errors():
    with pytest.raises(lacquer.InvalidMaterialError, match="coated_paint"):
        lacquer.fit_node_group({"model": "lambert"})
    with pytest.raises(lacquer.UnknownNameError, match="no_such_preset"):
        lacquer.fit_node_group("no_such_preset")
    with pytest.raises(lacquer.InvalidJSONError):
        lacquer.fit_node_group("{not json")
    with pytest.raises(lacquer.InvalidMaterialError, match="flake_density"):
        lacquer.fit_node_group({"model": "coated_paint", "flake_density": 300})
    with pytest.raises(TypeError):
        lacquer.fit_node_group(42)
