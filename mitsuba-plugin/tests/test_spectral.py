"""scalar_spectral: materials with spectral physics (the pearl paint's thin film, HTSG; the
core's LQ_LOBE_SPECTRAL) are evaluated by the core at the ray's wavelengths
(lq_eval_spectral / lq_sample_spectral). Integrated against Mitsuba's own CIE 1931 matching
functions, the spectral path must agree with the plugin's RGB path; a scene with a pearl
paint renders in scalar_spectral."""

import json

import numpy as np
import pytest

import mitsuba as mi

import lacquer_mitsuba
from conftest import load_lacquer, set_variant

PEARL = {"model": "coated_paint", "pearl_density": 30, "pearl_film_nm": 300, "flake_density": 3,
         "coat_roughness": 0.1}
# Direction pairs (Mitsuba's si.wi = toward the viewer, wo = toward the light), off the coat's
# highlight and on it.
PAIRS = [((0.3, 0.1, 0.9487), (0.5, 0.2, 0.8426)), ((0.6, 0.0, 0.8), (-0.2, 0.3, 0.9327)),
         ((0.0, 0.0, 1.0), (0.7, 0.0, 0.7141))]
LAMBDA = np.arange(360.0, 831.0, 2.0)  # nm, Mitsuba's visible range


def normalise(v):
    v = np.array(v, dtype=float)
    return v / np.linalg.norm(v)


_LOADED = {}


def cached(material):
    """The plugin object of a material in the current variant, made once per test session: a
    spectral material builds its wavelength bank on the first spectral call (4.5 s for the
    pearl paint on the loaded CI machine), so each is built once."""
    key = (mi.variant(), json.dumps(material, sort_keys=True))
    if key not in _LOADED:
        _LOADED[key] = load_lacquer(material)
    return _LOADED[key]


def spectral_values(material, wi, wo):
    """f·cos at every LAMBDA from the plugin in scalar_spectral (4 wavelengths per call)."""
    bsdf = cached(material)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    out = []
    for k in range(0, len(LAMBDA), 4):
        ls = list(LAMBDA[k:k + 4]) + [LAMBDA[-1]] * (4 - len(LAMBDA[k:k + 4]))
        si.wavelengths = mi.Spectrum(ls)
        out.extend(np.array(bsdf.eval(ctx, si, mi.Vector3f(*wo)))[: len(LAMBDA[k:k + 4])])
    return np.array(out)


def to_rgb(values):
    """Linear sRGB of a spectrum with Mitsuba's CIE 1931 tables (mi.cie1931_xyz) and its XYZ
    to sRGB matrix, normalised so a flat spectrum is (1, 1, 1), as Lacquer's RGB is."""
    cmf = np.array([np.array(mi.cie1931_xyz(float(l))) for l in LAMBDA])  # (n, 3)
    m = np.array([[3.240479, -1.537150, -0.498535], [-0.969256, 1.875991, 0.041556],
                  [0.055648, -0.204043, 1.057311]])
    rgb = m @ (cmf * values[:, None]).sum(axis=0)
    white = m @ cmf.sum(axis=0)
    return rgb / white


def rgb_values(material, wi, wo):
    bsdf = cached(material)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    return np.array(bsdf.eval(ctx, si, mi.Vector3f(*wo)))


@pytest.mark.parametrize("material,tol", [
    # measured 4.31e-2 (worst channel over the three pairs, relative to the largest channel;
    # 2.94e-2 before the basecoat mean-albedo fix changed this flaked paint's ρ̄ and with it the
    # layering's 1/(1 − ρ̄ r) term): the paint's nonlinearity in the film reflectance and 5 nm
    # node interpolation inside the core (its own test: 3.3e-2, was 2.0e-2, with its matching
    # functions), plus Mitsuba's tabulated CIE 1931 against the core's analytic fit
    (PEARL, 0.06),
    # measured 0.123: HTSG's RGB path evaluates one dominant wavelength per channel, the
    # spectral path the whole spectrum (the core's test: 0.113)
    ({"model": "htsg"}, 0.15),
])
def test_spectral_path_integrates_to_the_rgb_path(material, tol):
    set_variant("scalar_spectral")
    spec = [spectral_values(material, normalise(wi), normalise(wo)) for wi, wo in PAIRS]
    set_variant("scalar_rgb")
    worst = 0.0
    for (wi, wo), s in zip(PAIRS, spec):
        rgb = rgb_values(material, normalise(wi), normalise(wo))
        got = to_rgb(s)
        worst = max(worst, np.abs(got - rgb).max() / np.abs(rgb).max())
    print(f"{material}: spectral integral vs RGB path {worst:.3e}")
    assert worst < tol


def test_pearl_spectrum_is_not_an_upsampled_rgb():
    """The thin film's fringes reach Mitsuba: within one RGB band (600-720 nm) the pearl
    paint's value changes, and a non-spectral paint of the same colour takes the RGB route."""
    set_variant("scalar_spectral")
    wi, wo = normalise(PAIRS[1][0]), normalise(PAIRS[1][1])
    v = spectral_values({"model": "coated_paint", "pearl_density": 40, "pearl_film_nm": 600}, wi, wo)
    band = v[(LAMBDA >= 600) & (LAMBDA <= 720)]
    assert band.max() / band.min() > 1.05
    # sample() weights are f·cos/pdf at the same wavelengths.
    bsdf = cached(PEARL)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    si.wavelengths = mi.Spectrum([450, 520, 610, 700])
    checked = 0
    for k in range(32):
        u = ((k + 0.5) / 32, (k * 7 % 32 + 0.3) / 32, (k * 13 % 32 + 0.6) / 32)
        bs, w = bsdf.sample(ctx, si, u[0], mi.Point2f(u[1], u[2]))
        if not bs.pdf > 0:
            continue
        f = np.array(bsdf.eval(ctx, si, bs.wo))
        assert np.allclose(np.array(w), f / bs.pdf, rtol=1e-4, atol=1e-7)
        checked += 1
    assert checked > 16


def test_pearl_paint_renders_in_scalar_spectral():
    set_variant("scalar_spectral")
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 32, "height": 24},
                   "sampler": {"type": "independent", "sample_count": 8}},
        "ball": {"type": "sphere", "bsdf": {"type": "lacquer", "model": "coated_paint",
                                            "pearl_density": 30.0, "pearl_film_nm": 300.0}},
        "env": {"type": "constant"},
    })
    img = np.array(mi.render(scene))
    assert np.isfinite(img).all() and img.mean() > 0.01
    centre = img[8:16, 12:20, :3].mean(axis=(0, 1))
    assert (centre > 0).all()


# ---- llvm_ad_spectral: the batched path at each lane's four wavelengths ---------------------
# The pearl paint (spectral physics) goes through lq_eval_spectral / lq_sample_spectral, a
# non-spectral paint through the RGB batched calls upsampled per lane with Mitsuba's sRGB model,
# as in scalar_spectral. The materials are the cached ones above: a pearl paint builds its
# wavelength bank once per object and variant (about 4.5 s each on the loaded CI machine).

PAINT = {"model": "coated_paint", "base_color": [0.5, 0.1, 0.05], "flake_density": 5, "coat_roughness": 0.1}


def batch_inputs(n, seed):
    rng = np.random.default_rng(seed)

    def dirs():
        v = rng.normal(size=(n, 3))
        v[:, 2] = np.abs(v[:, 2]) + 0.1
        return (v / np.linalg.norm(v, axis=1)[:, None]).astype(np.float32)

    return dirs(), dirs(), rng.uniform(360, 830, size=(n, 4)).astype(np.float32), rng.random((n, 3)).astype(np.float32)


@pytest.mark.parametrize("material,name", [(PEARL, "pearl"), (PAINT, "paint")])
def test_llvm_spectral_equals_scalar_spectral(llvm_spectral, material, name):
    """Per element: eval, pdf and sample of the batched llvm_ad_spectral path (64 lanes,
    random directions, wavelengths and u) against scalar_spectral's one-element calls."""
    import drjit as dr

    n = 64
    wi, wo, lam, u = batch_inputs(n, 3)
    bsdf = cached(material)
    ctx, si = mi.BSDFContext(), dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi, si.wavelengths = mi.Vector3f(wi.T), mi.Spectrum(lam.T)
    f, p = bsdf.eval_pdf(ctx, si, mi.Vector3f(wo.T))
    bs, w = bsdf.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(u[:, 1:].T))
    got = [np.array(f).T, np.array(p), np.array(w).T, np.array(bs.wo).T, np.array(bs.pdf)]
    set_variant("scalar_spectral")
    ref = cached(material)
    ctx, s = mi.BSDFContext(), mi.SurfaceInteraction3f()
    want = [[], [], [], [], []]
    for i in range(n):
        s.wi, s.wavelengths = mi.Vector3f(wi[i]), mi.Spectrum(lam[i])
        fr, pr = ref.eval_pdf(ctx, s, mi.Vector3f(wo[i]))
        bsr, wr = ref.sample(ctx, s, float(u[i, 0]), mi.Point2f(u[i, 1], u[i, 2]))
        for k, v in enumerate([fr, pr, wr, bsr.wo, bsr.pdf]):
            want[k].append(np.array(v))
    err = [float(np.abs(g - np.array(r)).max() / max(np.abs(np.array(r)).max(), 1e-30)) for g, r in zip(got, want)]
    print(f"{name}: llvm_ad_spectral vs scalar_spectral, relative to the largest value "
          f"(f, pdf, weight, wo, sample pdf): {', '.join(f'{e:.2e}' for e in err)}")
    assert min(np.array(want[0]).max(), np.array(want[2]).max()) > 0.05  # real values, not zeros
    # eval and pdf, measured: pearl 0 f (the same lq_eval_spectral call), 9.2e-8 pdf
    # (lq_pdf_soa's SIMD lanes vs lq_pdf_one); paint 3.1e-7 f, 2.2e-8 pdf (the SIMD RGB kernels
    # vs the one-element calls, then the same upsampling). Tolerance 2e-6.
    assert max(err[0], err[1]) < 2e-6, err
    # sample: pearl 0 (the same lq_sample_spectral call); paint 2.6e-4 weight, 2.7e-5 wo: the
    # batched RGB path runs the SIMD lane sampler, whose flake sampler uses f32 polynomial
    # erfc/erfinv where the one-element call uses libm (test_llvm_batched_equals_scalar,
    # rust-core tests/integration/batch.rs: 1e-3). Tolerance 1e-3 (pearl: 1e-6).
    assert max(err[2:]) < (1e-6 if name == "pearl" else 1e-3), err


def test_llvm_spectral_path_integrates_to_the_rgb_path(llvm_spectral):
    """test_spectral_path_integrates_to_the_rgb_path for the pearl paint through the batched
    llvm_ad_spectral path: one call per direction pair, 59 lanes x 4 wavelengths = LAMBDA."""
    import drjit as dr

    bsdf = cached(PEARL)
    lanes = len(LAMBDA) // 4
    spec = []
    for wi, wo in PAIRS:
        si = dr.zeros(mi.SurfaceInteraction3f, lanes)
        si.wi = mi.Vector3f(*[np.full(lanes, c, dtype=np.float32) for c in normalise(wi)])
        si.wavelengths = mi.Spectrum(LAMBDA.reshape(lanes, 4).T.astype(np.float32))
        v = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*[np.full(lanes, c, dtype=np.float32) for c in normalise(wo)]))
        spec.append(np.array(v).T.reshape(-1))  # lane-major: LAMBDA's order
    set_variant("scalar_rgb")
    worst = 0.0
    for (wi, wo), s in zip(PAIRS, spec):
        rgb = rgb_values(PEARL, normalise(wi), normalise(wo))
        worst = max(worst, np.abs(to_rgb(s) - rgb).max() / np.abs(rgb).max())
    print(f"llvm_ad_spectral pearl: spectral integral vs RGB path {worst:.3e}")
    # measured 4.31e-2, as in scalar_spectral (the same core calls): tolerance 0.06, see above
    assert worst < 0.06


def spectral_scene(pearl, paint, spp):
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, -4, 1.5], target=[0, 0, 0], up=[0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 64, "height": 48, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "ball": {"type": "sphere", "bsdf": pearl},
        "floor": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, -1]).scale(4),
                  "bsdf": paint},
        "env": {"type": "constant"},
    }


def test_llvm_spectral_render_equals_scalar_spectral(llvm_spectral):
    """A pearl sphere (spectral physics) on a non-spectral paint floor, rendered in
    llvm_ad_spectral (wavefront, lacquer_mitsuba.render) and in scalar_spectral with the same
    spp: the images agree within noise (imgstats: image mean within 5 sigma, at most 3 % of
    8x8 blocks beyond 4 sigma, none beyond 8)."""
    from imgstats import assert_within_noise, compare

    spp = 16
    img = np.array(lacquer_mitsuba.render(mi.load_dict(spectral_scene(cached(PEARL), cached(PAINT), spp)), seed=1))
    set_variant("scalar_spectral")
    ref = np.array(mi.render(mi.load_dict(spectral_scene(cached(PEARL), cached(PAINT), spp)), seed=2))
    stats = compare(img[:, :, :3], ref[:, :, :3])
    print("llvm_ad_spectral vs scalar_spectral render:", stats)
    assert ref[:, :, :3].mean() > 0.05 and np.isfinite(img).all()
    # Measured (seeds 1 / 2, 64x48, 16 spp): z_mean 0.54, 1 of 48 blocks beyond 4 sigma (2.1 %),
    # max block z 4.1; two renders of one variant with different seeds scatter alike (z_mean
    # up to 1.7, max block z up to 4.0; a box pixel filter keeps pixels independent: with the
    # default Gaussian the block statistic flagged up to 12 % of blocks between two seeds of
    # one variant). At 128 spp the largest block difference falls from 9 % to 3 % (noise, no
    # bias). Exact equality is not expected: the samplers differ between variants, and the
    # core's SIMD flake tables differ from its one-element path by up to 2.6 % in f
    # (docs/speed.md), below this noise.
    assert_within_noise(stats)
    # channel means, measured at most 0.5 % apart: tolerance 2 %
    a, b = img[:, :, :3].mean(axis=(0, 1)), ref[:, :, :3].mean(axis=(0, 1))
    print("channel means, relative difference:", np.abs(a - b) / b)
    assert (np.abs(a - b) / b).max() < 0.02, (a, b)
