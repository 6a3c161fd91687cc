"""The plugin as a Mitsuba user meets it: loading (dict and XML), errors, the convention
mapping (directions, cosine, sample weight, delta lobes), spectral and JIT variants, the tint
texture and the sparkle footprint."""

import gc
import json
import logging
import math

import numpy as np
import pytest

import drjit as dr
import mitsuba as mi

import lacquer_mitsuba
from conftest import lacquer_dict, load_lacquer
from directions import hemisphere_grid, pairs


def test_register_finds_the_native_plugin(scalar_rgb):
    assert lacquer_mitsuba.register() == "native"
    assert any(str(p) == lacquer_mitsuba.plugin_dir() for p in mi.file_resolver())
    # registering twice does not add the folder twice
    lacquer_mitsuba.register()
    assert sum(str(p) == lacquer_mitsuba.plugin_dir() for p in mi.file_resolver()) == 1


def test_load_from_xml_and_dict(scalar_rgb):
    xml = """<bsdf version="3.0.0" type="lacquer">
                 <string name="material" value='{"model": "lambert", "albedo": 0.25}'/>
             </bsdf>"""
    a = mi.load_string(xml)
    b = mi.load_dict({"type": "lacquer", "material": json.dumps({"model": "lambert", "albedo": 0.25})})
    c = mi.load_string('<bsdf version="3.0.0" type="lacquer"><string name="preset" value="gold_flake_8"/></bsdf>')
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0, 0, 1)
    wo = mi.Vector3f(0.6, 0, 0.8)
    assert dr.allclose(a.eval(ctx, si, wo), b.eval(ctx, si, wo))
    assert dr.allclose(a.eval(ctx, si, wo), 0.25 / math.pi * 0.8)
    assert '"model":"coated_paint"' in str(c)


def test_whole_scene_from_xml(scalar_rgb):
    scene = mi.load_string("""<scene version="3.0.0">
        <integrator type="path"/>
        <sensor type="perspective">
            <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
            <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        </sensor>
        <shape type="sphere"><bsdf type="lacquer"><string name="preset" value="pearl_blue"/></bsdf></shape>
        <emitter type="constant"/>
    </scene>""")
    img = np.array(mi.render(scene))
    assert np.isfinite(img).all() and img.mean() > 0.01


@pytest.mark.parametrize("props,message", [
    ({}, "exactly one of"),
    ({"material": '{"model": "lambert"}', "preset": "gold_flake_8"}, "exactly one of"),
    ({"material": '{"model": "lambert", "albedo": 1.5}'}, "albedo"),
    ({"material": '{"model": "lambert", "albdo": 0.5}'}, "albdo"),
    ({"material": "{not json"}, "LQ_ERR_INVALID_JSON"),
    ({"preset": "no_such_paint"}, "no_such_paint"),
])
def test_errors_name_the_problem(scalar_rgb, props, message):
    with pytest.raises(RuntimeError, match=message):
        mi.load_dict({"type": "lacquer", **props})


def test_conventions_against_the_c_abi(scalar_rgb, lacquer_py):
    """Mitsuba's si.wi is Lacquer's wo, Mitsuba's wo Lacquer's wi, Mitsuba's eval includes the
    cosine of its wo, sample's value is f cos / pdf. Checked on a non-reciprocal model
    (original Phong), where swapping the directions would show."""
    material = {"model": "phong", "diffuse": 0.2, "specular": 0.6, "exponent": 20}
    ours = load_lacquer(material)
    ref = lacquer_py.Material(material)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    asym = 0.0
    for v, l in pairs():
        si.wi = mi.Vector3f(v)
        f = np.array(ours.eval(ctx, si, mi.Vector3f(l)))
        p = float(ours.pdf(ctx, si, mi.Vector3f(l)))
        expect = ref.eval(np.array(l), np.array(v)) * l[2]
        assert np.allclose(f, expect, rtol=1e-6, atol=1e-9)
        assert math.isclose(p, float(ref.pdf(np.array(l), np.array(v))), rel_tol=1e-6, abs_tol=1e-9)
        asym = max(asym, float(np.max(np.abs(ref.eval(np.array(l), np.array(v)) - ref.eval(np.array(v), np.array(l))))))
    assert asym > 1e-3, "the model should be non-reciprocal for this test to mean anything"
    rng = np.random.default_rng(3)
    for v in hemisphere_grid():
        u = rng.random(3)
        si.wi = mi.Vector3f(v)
        bs, w = ours.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
        s = ref.sample(np.array(v), u)
        if s.pdf == 0:
            assert float(bs.pdf) == 0 and np.all(np.array(w) == 0)
            continue
        assert np.allclose(np.array(bs.wo), s.wi, atol=1e-6)
        assert math.isclose(float(bs.pdf), float(s.pdf), rel_tol=1e-6)
        assert np.allclose(np.array(w), s.weight, rtol=1e-6)
        # the core reports a diffuse and a glossy lobe (lq_material_lobes); a sample does not
        # say which one it came from, so it carries both bits
        assert int(bs.sampled_type) == int(mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection)


def test_sample_weight_is_eval_over_pdf(scalar_rgb):
    bsdf = load_lacquer("gold_flake_8")
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    rng = np.random.default_rng(1)
    n = 0
    for v in hemisphere_grid():
        si.wi = mi.Vector3f(v)
        for _ in range(8):
            u = rng.random(3)
            bs, w = bsdf.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
            if float(bs.pdf) == 0:
                continue
            f, p = bsdf.eval_pdf(ctx, si, bs.wo)
            assert math.isclose(float(p), float(bs.pdf), rel_tol=1e-4)
            assert np.allclose(np.array(w), np.array(f) / float(p), rtol=1e-4, atol=1e-7)
            n += 1
    assert n > 100


def test_flags_and_delta_lobe(scalar_rgb):
    lam = load_lacquer({"model": "lambert"})
    assert lam.flags() & int(mi.BSDFFlags.DiffuseReflection)
    assert lam.component_count() == 1
    glossy = load_lacquer("gold_flake_8")
    assert glossy.flags() & int(mi.BSDFFlags.GlossyReflection)
    assert not glossy.flags() & int(mi.BSDFFlags.Delta)
    needs_differentials = 0x20000  # BSDFFlags::NeedsDifferentials (not exposed in Python)
    assert glossy.flags() & needs_differentials  # sparkle on: uv partials wanted
    no_fp = mi.load_dict({**lacquer_dict("gold_flake_8"), "footprint": False})
    assert not no_fp.flags() & needs_differentials

    # A mirror-smooth clearcoat is a Dirac lobe: component 1, pdf = its selection probability.
    smooth = load_lacquer({"model": "coated_paint", "coat_roughness": 0, "flake_density": 0})
    assert smooth.component_count() == 2
    assert smooth.flags() & int(mi.BSDFFlags.DeltaReflection)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = dr.normalize(mi.Vector3f(0.8, 0.1, 0.2))
    deltas = 0
    for i in range(64):
        bs, w = smooth.sample(ctx, si, (i + 0.5) / 64, mi.Point2f(0.3, 0.6))
        if int(bs.sampled_type) == int(mi.BSDFFlags.DeltaReflection):
            deltas += 1
            assert int(bs.sampled_component) == 1
            assert dr.allclose(bs.wo, mi.Vector3f(-si.wi.x, -si.wi.y, si.wi.z), atol=1e-5)
            assert 0 < float(bs.pdf) <= 1
            # eval and pdf never include the Dirac lobe
            assert float(smooth.pdf(ctx, si, bs.wo)) < 1e3
    assert deltas > 0
    # Selecting only the smooth component: delta samples come back as failures.
    ctx_glossy = mi.BSDFContext(mi.TransportMode.Radiance, int(mi.BSDFFlags.GlossyReflection))
    for i in range(64):
        bs, w = smooth.sample(ctx_glossy, si, (i + 0.5) / 64, mi.Point2f(0.3, 0.6))
        assert int(bs.sampled_type) != int(mi.BSDFFlags.DeltaReflection) or np.all(np.array(w) == 0)


def test_tint_texture_scales_f_not_pdf(scalar_rgb):
    tex = np.zeros((2, 2, 3), dtype=np.float32)
    tex[..., 0], tex[..., 1], tex[..., 2] = 0.25, 0.5, 1.0
    tinted = mi.load_dict({**lacquer_dict({"model": "ward", "alpha_x": 0.2, "alpha_y": 0.2}),
                           "tint": {"type": "bitmap", "bitmap": mi.Bitmap(tex), "raw": True,
                                    "filter_type": "nearest"}})
    plain = load_lacquer({"model": "ward", "alpha_x": 0.2, "alpha_y": 0.2})
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.uv = mi.Point2f(0.3, 0.7)
    si.wi = dr.normalize(mi.Vector3f(0.2, 0.1, 0.9))
    wo = dr.normalize(mi.Vector3f(-0.25, -0.1, 0.9))
    ft, fp = np.array(tinted.eval(ctx, si, wo)), np.array(plain.eval(ctx, si, wo))
    assert np.allclose(ft, fp * [0.25, 0.5, 1.0], rtol=1e-5)
    assert float(tinted.pdf(ctx, si, wo)) == float(plain.pdf(ctx, si, wo))
    assert any("tint" in k for k in mi.traverse(tinted).keys())


def test_footprint_reaches_sparkle(scalar_rgb):
    """With ray differentials, uv and the footprint go to the C ABI's _spatial functions; a
    sparkle paint then varies from place to place at a small footprint, and its average over
    places is the mean lobe (what eval gives without a footprint)."""
    bsdf = load_lacquer("gold_flake_8")
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = dr.normalize(mi.Vector3f(0.1, 0.0, 1.0))
    wo = dr.normalize(mi.Vector3f(-0.1, 0.02, 1.0))
    mean_lobe = np.array(bsdf.eval(ctx, si, wo))
    values = []
    rng = np.random.default_rng(7)
    for _ in range(1000):
        si.uv = mi.Point2f(*rng.random(2))
        si.duv_dx = mi.Vector2f(1e-3, 0)  # 100 um at the paint's default 100 mm per uv unit
        si.duv_dy = mi.Vector2f(0, 1e-3)
        values.append(np.array(bsdf.eval(ctx, si, wo)))
    values = np.array(values)
    # The C ABI's lq_*_spatial functions pass uv/footprint to the core's eval_at: the values
    # must vary from place to place (this used to be an xfail, which would now hide a regression).
    assert not np.allclose(values, mean_lobe, rtol=1e-6), "uv/footprint did not reach the core's eval_at"
    assert np.isfinite(values).all() and (values >= 0).all()
    assert values.std(axis=0).max() > 0
    # The spatial mean is the mean lobe. Measured (issue 16; this seed 7 and seeds 8-11):
    # relative deviation -0.71 % here (at most 0.72 %), relative standard error of the mean of
    # 1000 places 0.26-0.46 %; rtol 2 % is about 4 standard errors above that (was 50 %).
    assert np.allclose(values.mean(axis=0), mean_lobe, rtol=0.02)


def test_scalar_spectral_grey_is_exact_and_colours_are_close(scalar_spectral):
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0, 0, 1)
    si.wavelengths = mi.Spectrum([420, 510, 580, 650])
    wo = mi.Vector3f(0, 0.6, 0.8)
    grey = load_lacquer({"model": "lambert", "albedo": 0.5})
    assert dr.allclose(grey.eval(ctx, si, wo), 0.5 / math.pi * 0.8, rtol=1e-5)
    red = load_lacquer({"model": "lambert", "albedo": [0.8, 0.1, 0.1]})
    v = np.array(red.eval(ctx, si, wo)) / 0.8 * math.pi
    assert v[3] > 0.6 and v[0] < 0.3  # reflects long wavelengths, not short ones
    bs, w = red.sample(ctx, si, 0.5, mi.Point2f(0.3, 0.3))
    assert np.allclose(np.array(w), v, rtol=1e-4)


# ---- JIT (llvm_ad_rgb): the batched path ---------------------------------------------------

def test_llvm_batched_equals_scalar(llvm_rgb):
    material = "gold_flake_8"
    bsdf = load_lacquer(material)
    grid = pairs()
    si = dr.zeros(mi.SurfaceInteraction3f, len(grid))
    si.wi = mi.Vector3f(*[list(c) for c in zip(*[v for v, _ in grid])])
    wo = mi.Vector3f(*[list(c) for c in zip(*[l for _, l in grid])])
    ctx = mi.BSDFContext()
    f, p = bsdf.eval_pdf(ctx, si, wo)
    f_only, p_only = bsdf.eval(ctx, si, wo), bsdf.pdf(ctx, si, wo)
    u = np.random.default_rng(5).random((3, len(grid))).astype(np.float32)
    bs, w = bsdf.sample(ctx, si, mi.Float(u[0]), mi.Point2f(u[1], u[2]))
    F, P = np.array(f).T, np.array(p)  # (3, n) -> (n, 3)
    assert np.array_equal(F, np.array(f_only).T) and np.array_equal(P, np.array(p_only))
    BS_WO, BS_PDF, W = np.array(bs.wo).T, np.array(bs.pdf), np.array(w).T

    mi.set_variant("scalar_rgb")
    ref = load_lacquer(material)
    ctx, s = mi.BSDFContext(), mi.SurfaceInteraction3f()
    for i, (v, l) in enumerate(grid):
        s.wi = mi.Vector3f(v)
        fr, pr = ref.eval_pdf(ctx, s, mi.Vector3f(l))
        assert np.allclose(F[i], np.array(fr), rtol=1e-6, atol=1e-9)
        assert math.isclose(P[i], float(pr), rel_tol=1e-6, abs_tol=1e-9)
        bsr, wr = ref.sample(ctx, s, float(u[0, i]), mi.Point2f(float(u[1, i]), float(u[2, i])))
        # Sampling: the batched path runs the SIMD lane sampler, whose Beckmann flake sampler
        # uses f32 polynomial erfc/erfinv where the scalar path calls libm (rust-core
        # tests/integration/batch.rs holds the two to 1e-3). Measured here: ≤ 1e-6 except pair 7
        # (u = 0.045, 0.0063, 0.999: the sampler's tail), pdf 8.2e-5 relative, wo 3.0e-5, weight
        # 4.2e-5; LACQUER_SIMD=scalar gives the scalar values exactly. Tolerances 2e-4 / 1e-4.
        assert math.isclose(BS_PDF[i], float(bsr.pdf), rel_tol=2e-4, abs_tol=1e-9)
        if float(bsr.pdf) > 0:
            assert np.allclose(BS_WO[i], np.array(bsr.wo), atol=1e-4)
            assert np.allclose(W[i], np.array(wr), rtol=2e-4, atol=1e-9)


def small_scene(bsdf, spp=4):
    return mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at([0, -4, 1.5], [0, 0, 0], [0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 24, "height": 16},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "sphere": {"type": "sphere", "bsdf": bsdf},
        "light": {"type": "constant"},
    })


DIFFUSE = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.3, 0.5, 0.7]}}


def same_render(a, b):
    """Two llvm renders of one scene with one seed. Not compared bit for bit: with two or more
    live BSDFs (a real virtual call) Dr.Jit's renders vary in the last bits between runs, with
    no lacquer involved: a diffuse scene with a live `roughconductor` differed in 1 of 40
    llvm_ad_spectral renders by 4.8e-7 (values up to 1.48, a few ulp); with live lacquer
    objects 1 of 30 llvm_ad_rgb renders differed (129 of 384 pixels), and the bit-for-bit
    check failed about 1 run in 4 in llvm_ad_spectral (the shared 2-core machine). 1e-5
    relative is far below any real difference (a lacquer object that was not zero where
    unused would change whole pixels)."""
    return np.allclose(a, b, rtol=1e-5, atol=1e-6)
SYMBOLIC_WARNING = "is being traced inside a symbolic Dr.Jit loop or call"


@pytest.mark.parametrize("jit", ["llvm_rgb", "llvm_spectral"])
def test_llvm_symbolic_render_of_another_scene_unchanged_by_a_live_lacquer_object(request, jit, capfd):
    """A symbolic virtual call traces every live BSDF of the variant: a lacquer object that the
    rendered scene does not use returns zero there (never selected), so the render is the one
    made without it (up to the film's atomic-add order, see same_render), and the object warns once (not per render) naming the fix."""
    request.getfixturevalue(jit)  # llvm_ad_rgb, llvm_ad_spectral: the same rules
    assert dr.flag(dr.JitFlag.SymbolicLoops) and dr.flag(dr.JitFlag.SymbolicCalls)  # Mitsuba's default
    gc.collect()  # no lacquer object of an earlier test alive for the reference
    ref = np.array(mi.render(small_scene(DIFFUSE), seed=5))
    live = mi.load_dict(lacquer_dict({"model": "lambert", "albedo": 0.8}))
    live.set_id("live_unused_lacquer")  # to count its warnings apart from other live objects'
    capfd.readouterr()
    img = np.array(mi.render(small_scene(DIFFUSE), seed=5))
    mi.render(small_scene(DIFFUSE), seed=6)  # traced again: no second warning
    out = capfd.readouterr()
    log = out.out + out.err
    assert same_render(img, ref), np.abs(img - ref).max()
    assert img.mean() > 0.1  # a real render, not an empty one
    assert log.count('"live_unused_lacquer" (model lambert) ' + SYMBOLIC_WARNING) == 1, log
    assert "lacquer_mitsuba.render" in log and "SymbolicCalls, False" in log, log
    del live


@pytest.mark.parametrize("jit", ["llvm_rgb", "llvm_spectral"])
def test_llvm_lacquer_scene_symbolic(request, jit, capfd, caplog):
    """A scene that uses lacquer: lacquer_mitsuba.render in Mitsuba's default (symbolic) flags
    switches to wavefront mode, says so, and gives the wavefront render (see same_render); plain
    mi.render in symbolic mode renders the lacquer surface black and warns (not silently)."""
    request.getfixturevalue(jit)
    scene = small_scene(lacquer_dict({"model": "lambert", "albedo": 0.8}))
    scene.shapes()[0].bsdf().set_id("used_lacquer")
    assert lacquer_mitsuba.uses_lacquer(scene) and not lacquer_mitsuba.uses_lacquer(small_scene(DIFFUSE))
    with caplog.at_level(logging.INFO, logger="lacquer_mitsuba"):
        img = np.array(lacquer_mitsuba.render(scene, seed=3))
    assert "rendering in wavefront mode" in caplog.text
    assert dr.flag(dr.JitFlag.SymbolicLoops) and dr.flag(dr.JitFlag.SymbolicCalls)  # restored
    with lacquer_mitsuba.wavefront():
        wave = np.array(mi.render(scene, seed=3))
    assert same_render(img, wave), np.abs(img - wave).max()
    # The sphere fills the film's centre: lambert 0.8 under a white environment.
    assert 0.6 < img[6:10, 10:14].mean() < 1.0
    capfd.readouterr()
    black = np.array(mi.render(scene, seed=3))
    out = capfd.readouterr()
    assert (black[6:10, 10:14] == 0).all()
    assert (out.out + out.err).count('"used_lacquer" (model lambert) ' + SYMBOLIC_WARNING) == 1


def test_uses_lacquer_finds_nested_bsdfs(scalar_rgb):
    """uses_lacquer walks what `traverse` reports: BSDFs nested in blendbsdf / mask / twosided,
    shapes inside a shape group reached through an instance; a scene without lacquer is False."""
    lq, diffuse = lacquer_dict("white_lambert"), {"type": "diffuse"}
    assert lacquer_mitsuba.uses_lacquer(mi.load_dict({"type": "blendbsdf", "weight": 0.5, "a": diffuse, "b": lq}))
    assert lacquer_mitsuba.uses_lacquer(mi.load_dict({"type": "mask", "opacity": 0.5, "b": {"type": "twosided", "n": lq}}))
    assert not lacquer_mitsuba.uses_lacquer(mi.load_dict({"type": "blendbsdf", "weight": 0.5, "a": diffuse, "b": diffuse}))

    def instanced(bsdf):
        return mi.load_dict({"type": "scene", "g": {"type": "shapegroup", "s": {"type": "sphere", "bsdf": bsdf}},
                             "i": {"type": "instance", "shapegroup": {"type": "ref", "id": "g"}}})

    assert lacquer_mitsuba.uses_lacquer(instanced(lq)) and not lacquer_mitsuba.uses_lacquer(instanced(diffuse))
    # Scalar variants have no symbolic mode: render() is mi.render. Not compared bit for bit: a
    # multi-threaded scalar render adds the image blocks' overlapping filter borders in thread
    # order, so two mi.render calls with one seed can differ in the last bits (it failed once in
    # CI that way, while passing locally); 1e-5 relative is far below any real difference.
    scene = small_scene(lq, spp=1)
    a, b = np.array(lacquer_mitsuba.render(scene, seed=1)), np.array(mi.render(scene, seed=1))
    assert np.allclose(a, b, rtol=1e-5, atol=1e-6), np.abs(a - b).max()


def test_llvm_wavefront_render(llvm_rgb):
    with lacquer_mitsuba.wavefront():
        img = np.array(mi.render(small_scene(lacquer_dict({"model": "lambert", "albedo": 0.8})), seed=3))
        ref = np.array(mi.render(small_scene({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.8}}), seed=3))
    assert dr.flag(dr.JitFlag.SymbolicLoops)  # restored
    assert np.isfinite(img).all()
    assert abs(img.mean() - ref.mean()) < 0.05 * ref.mean()
