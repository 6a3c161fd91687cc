"""scalar_spectral: materials with spectral physics (the pearl paint's thin film, HTSG; the
core's LQ_LOBE_SPECTRAL) are evaluated by the core at the ray's wavelengths
(lq_eval_spectral / lq_sample_spectral). Integrated against Mitsuba's own CIE 1931 matching
functions, the spectral path must agree with the plugin's RGB path; a scene with a pearl
paint renders in scalar_spectral."""

import json

import numpy as np
import pytest

import mitsuba as mi

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
