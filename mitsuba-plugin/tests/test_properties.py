"""Typed properties, mi.traverse / parameters_changed, and flags from the core (issue 14 items
2, 4, 5; issue 16 item 7): the plugin takes every parameter of every model as a Mitsuba
property of its kind, exposes the scalar and colour ones to mi.traverse, rebuilds the
material on edits (keeping the previous one when an edit is invalid), and sets Mitsuba's
component flags from lq_material_lobes.

The parameter lists these tests compare against come from the core through the ctypes
package (`lacquer.models()`, i.e. lq_models_json), a route independent of the plugin's
lq_model_param queries."""

import json
import re

import numpy as np
import pytest

import drjit as dr
import mitsuba as mi

from conftest import eval_pdf_pairs, lacquer_dict


def canonical(bsdf):
    """The canonical material JSON the plugin built (from its to_string)."""
    m = re.search(r"material = (\{.*\}),\n", str(bsdf))
    assert m, str(bsdf)
    return json.loads(m.group(1))


def evals(bsdf, n=48):
    """f·cos and pdf on a fixed set of direction pairs (scalar variant)."""
    return eval_pdf_pairs(bsdf, n)


def test_typed_properties_equal_material_json(scalar_rgb):
    """<string model>, <float>, <rgb>, <string> choice and <boolean> give exactly the
    material that the same JSON gives (colours exactly representable in float32: a
    ScalarColor3f holds float32)."""
    typed = mi.load_dict({"type": "lacquer", "model": "coated_paint", "flake_density": 5.0,
                          "base_color": mi.ScalarColor3f(0.125, 0.25, 0.375), "flake_material": "Au",
                          "sparkle": False, "coat_roughness": 0.05})
    ref = mi.load_dict(lacquer_dict({"model": "coated_paint", "flake_density": 5, "base_color": [0.125, 0.25, 0.375],
                                     "flake_material": "Au", "sparkle": False, "coat_roughness": 0.05}))
    assert canonical(typed) == canonical(ref)
    assert np.array_equal(evals(typed), evals(ref))


def test_typed_properties_from_xml(scalar_rgb):
    paint = mi.load_string("""<bsdf version="3.0.0" type="lacquer">
        <string name="model" value="coated_paint"/>
        <float name="flake_density" value="5"/>
        <rgb name="base_color" value="0.1, 0.2, 0.3"/>
        <string name="flake_material" value="Au"/>
        <boolean name="sparkle" value="false"/>
        <float name="surface_scale_mm" value="250"/>
      </bsdf>""")
    c = canonical(paint)
    assert c["model"] == "coated_paint" and c["flake_density"] == 5 and c["flake_material"] == "Au"
    assert c["base_color"] == pytest.approx([0.1, 0.2, 0.3]) and c["sparkle"] is False
    assert c["surface_scale_mm"] == 250
    assert "flake_density" in mi.traverse(paint).keys()


def test_preset_with_overrides(scalar_rgb):
    base = canonical(mi.load_dict(lacquer_dict("gold_flake_8")))
    over = canonical(mi.load_dict({"type": "lacquer", "preset": "gold_flake_8", "coat_roughness": 0.12,
                                   "flake_density": 3.5}))
    assert over["coat_roughness"] == 0.12 and over["flake_density"] == 3.5
    base.update(coat_roughness=0.12, flake_density=3.5)
    assert over == base
    # The JSON form takes overrides too.
    j = canonical(mi.load_dict({"type": "lacquer", "material": '{"model": "lambert", "albedo": 0.3}',
                                "albedo": mi.ScalarColor3f(0.5, 0.25, 0.125)}))
    assert j["albedo"] == [0.5, 0.25, 0.125]


@pytest.mark.parametrize("props, words", [
    ({"flake_densty": 5.0}, ["flake_densty", "flake_density", "coat_roughness"]),  # unknown: lists the names
    ({"flake_density": -1.0}, ["flake_density", "-1", "[0, "]),                    # out of range: the range
    ({"base_color": (0.2, 1.5, 0.2)}, ["base_color", "1.5", "[0, 1] per component"]),
    ({"flake_material": "Pt"}, ["flake_material", "Pt", "one of Al", "Au"]),
    ({"flake_density": "five"}, ["flake_density", "wrong type", "<float>"]),
    ({"sparkle": 1.0}, ["sparkle", "<boolean>"]),
])
def test_bad_properties_name_parameter_and_range(scalar_rgb, props, words):
    props = {k: mi.ScalarColor3f(*v) if isinstance(v, tuple) else v for k, v in props.items()}
    with pytest.raises(RuntimeError) as e:
        mi.load_dict({"type": "lacquer", "model": "coated_paint", **props})
    for w in words:
        assert w in str(e.value), (w, str(e.value))


def test_exactly_one_source(scalar_rgb):
    with pytest.raises(RuntimeError, match="exactly one of"):
        mi.load_dict({"type": "lacquer", "model": "lambert", "preset": "gold_flake_8"})
    with pytest.raises(RuntimeError, match="unknown model"):
        mi.load_dict({"type": "lacquer", "model": "no_such_model"})


def test_every_scalar_and_colour_parameter_in_traverse(scalar_rgb, lacquer_py):
    """For every model whose defaults build: mi.traverse shows exactly its scalar, integer and
    colour parameters (names as `lacquer models` gives them), with their values."""
    checked = 0
    for info in lacquer_py.models():
        try:
            bsdf = mi.load_dict({"type": "lacquer", "model": info["name"]})
        except RuntimeError as e:
            # only the measured model has no buildable defaults (it needs a table file)
            assert info["name"] == "measured", (info["name"], str(e))
            continue
        params = mi.traverse(bsdf)
        want = {p["name"] for p in info["params"] if p["kind"] in ("scalar", "color", "integer")}
        assert set(params.keys()) == want, info["name"]
        c = canonical(bsdf)
        for k in want:
            got = np.array(params[k], dtype=float).ravel()
            exp = np.array(c[k], dtype=float).ravel()
            assert np.allclose(got, exp if exp.size == got.size else np.full(got.size, exp[0]), rtol=1e-6), k
        checked += 1
    assert checked >= 20


def scene_dict(bsdf):
    return {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, -3, 2.5], target=[0, 0, 0], up=[0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 24, "height": 24, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 8}},
        "plane": {"type": "rectangle", "bsdf": bsdf},
        "light": {"type": "point", "position": [1.0, -1.0, 2.0], "intensity": {"type": "rgb", "value": 8.0}},
    }


def render(scene):
    return np.array(mi.render(scene, seed=3))


def test_traverse_edit_flake_density_changes_render(scalar_rgb):
    scene = mi.load_dict(scene_dict({"type": "lacquer", "model": "coated_paint", "flake_density": 0.0,
                                     "sparkle": False, "coat_roughness": 0.2}))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("flake_density"))
    before = render(scene)
    params[key] = 40.0
    params.update()
    after = render(scene)
    assert canonical(next(s for s in scene.shapes()).bsdf())["flake_density"] == 40
    # flakes add a metallic glossy lobe under the coat: the image changes (measured mean
    # |Δ| = 1.5e-2 against an image mean of 2.4e-2; below 1e-3 would mean no rebuild)
    assert np.mean(np.abs(after - before)) > 1e-3
    params[key] = 0.0
    params.update()
    assert np.array_equal(render(scene), before)  # same seed, same material: bit-identical


def test_traverse_colour_edit(scalar_rgb):
    bsdf = mi.load_dict({"type": "lacquer", "model": "lambert"})
    params = mi.traverse(bsdf)
    params["albedo"] = mi.Color3f(0.1, 0.2, 0.4)
    params.update()
    assert canonical(bsdf)["albedo"] == pytest.approx([0.1, 0.2, 0.4])
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0, 0, 1)
    f = np.array(bsdf.eval(ctx, si, mi.Vector3f(0, 0, 1)))
    assert np.allclose(f, np.array([0.1, 0.2, 0.4]) / np.pi, rtol=1e-6)


@pytest.mark.parametrize("value, words", [(-3.0, ["flake_density", "-3", "[0, "]), (float("nan"), ["flake_density"])])
def test_bad_traverse_edit_keeps_previous_material(scalar_rgb, value, words):
    """Issue 16 item 7: a bad value through traverse raises an error naming the parameter
    (and its range), and the previous valid material and values stay in place."""
    scene = mi.load_dict(scene_dict({"type": "lacquer", "model": "coated_paint", "flake_density": 6.0,
                                     "sparkle": False, "coat_roughness": 0.2}))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("flake_density"))
    before = render(scene)
    params[key] = value
    with pytest.raises(RuntimeError) as e:
        params.update()
    for w in words:
        assert w in str(e.value), (w, str(e.value))
    assert "previous material is kept" in str(e.value)
    assert float(params[key]) == 6.0
    assert canonical(next(s for s in scene.shapes()).bsdf())["flake_density"] == 6
    assert np.array_equal(render(scene), before)
    params[key] = 7.0  # and a later valid edit still works
    params.update()
    assert canonical(next(s for s in scene.shapes()).bsdf())["flake_density"] == 7


def test_traverse_in_llvm(llvm_rgb):
    bsdf = mi.load_dict({"type": "lacquer", "model": "lambert", "albedo": 0.5})
    params = mi.traverse(bsdf)
    params["albedo"] = mi.Color3f(0.25, 0.5, 0.75)
    params.update()
    ctx, si = mi.BSDFContext(), dr.zeros(mi.SurfaceInteraction3f)
    si.wi = mi.Vector3f(0, 0, 1)
    f = np.array(bsdf.eval(ctx, si, mi.Vector3f(0, 0, 1))).ravel()
    assert np.allclose(f, np.array([0.25, 0.5, 0.75]) / np.pi, rtol=1e-6)
    params["albedo"] = mi.Color3f(2.0, 0.5, 0.5)
    with pytest.raises(RuntimeError, match="albedo"):
        params.update()
    assert np.allclose(np.array(params["albedo"]).ravel(), [0.25, 0.5, 0.75])


F = mi.BSDFFlags


def test_flags_from_core(scalar_rgb):
    def flags(d):
        return int(mi.load_dict({"type": "lacquer", **d}).flags())
    lam = flags({"model": "lambert"})
    assert lam & int(F.DiffuseReflection) and not lam & int(F.GlossyReflection) and not lam & int(F.Delta)
    # a coated paint with flakes: diffuse pigment + glossy flakes/coat, both reported
    paint = flags({"model": "coated_paint", "flake_density": 5.0, "coat_roughness": 0.1})
    assert paint & int(F.DiffuseReflection) and paint & int(F.GlossyReflection) and not paint & int(F.Delta)
    assert paint & int(F.SpatiallyVarying)  # sparkle
    aniso = flags({"model": "rough_conductor", "alpha_u": 0.1, "alpha_v": 0.4})
    assert aniso & int(F.Anisotropic) and aniso & int(F.GlossyReflection) and not aniso & int(F.DiffuseReflection)
    assert not flags({"model": "rough_conductor", "alpha_u": 0.2, "alpha_v": 0.2}) & int(F.Anisotropic)
    # non-reciprocal models (phong, principled) are NonSymmetric; reciprocal ones are not
    assert flags({"model": "phong"}) & int(F.NonSymmetric)
    assert flags({"model": "principled"}) & int(F.NonSymmetric)
    assert not flags({"model": "ward"}) & int(F.NonSymmetric)


def test_eval_diffuse_reflectance_is_pigment(scalar_rgb):
    """The albedo AOV shows the pigment (base_color), not the clearcoat highlight."""
    bsdf = mi.load_dict({"type": "lacquer", "model": "coated_paint", "base_color": mi.ScalarColor3f(0.2, 0.3, 0.4),
                         "coat_roughness": 0.0})
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0, 0, 1)
    assert np.allclose(np.array(bsdf.eval_diffuse_reflectance(si)), [0.2, 0.3, 0.4], rtol=1e-6)
    metal = mi.load_dict({"type": "lacquer", "model": "rough_conductor"})
    assert np.all(np.array(metal.eval_diffuse_reflectance(si)) == 0)


def test_generated_properties_table_is_current():
    """docs/mitsuba-properties.md is what tools/properties_table.py prints from the core's
    model list today (regenerate it with the command in its first lines)."""
    import os
    import subprocess
    import sys

    from conftest import REPO, lacquer_cli

    binary = lacquer_cli()
    assert binary, "the lacquer CLI is needed (test.sh builds it)"
    out = subprocess.run([sys.executable, str(REPO / "mitsuba-plugin/tools/properties_table.py"), binary],
                         check=True, capture_output=True, text=True, env=dict(os.environ)).stdout
    assert out == (REPO / "docs/mitsuba-properties.md").read_text(), \
        "docs/mitsuba-properties.md is stale: python3 mitsuba-plugin/tools/properties_table.py > docs/mitsuba-properties.md"
