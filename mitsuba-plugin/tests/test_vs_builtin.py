"""Same directions, same parameters: Lacquer's models through the plugin against Mitsuba's own
BSDFs (scalar_rgb). eval (which includes the cosine in both) and pdf must agree to 1e-4
relative, except where a model differs by design; each such test says how and why.

Lacquer's `rough_conductor` and `rough_plastic` follow Mitsuba's `roughconductor` and
`roughplastic` conventions (rust-core/src/models/rough_conductor.rs, rough_plastic.rs); the
tests skip with a reason while those models are not registered on the branch.
"""

import json
import math

import pytest

import drjit as dr
import mitsuba as mi

from conftest import load_lacquer
from directions import pairs, rel_err

# Gold, the RGB constants of lacquer's fresnel::METALS["Au"]; passed as explicit eta/k to
# both sides (Mitsuba's material="Au" reduces its spectral data to RGB differently).
AU_ETA = [0.143119, 0.374957, 1.44248]
AU_K = [3.98316, 2.38572, 1.60322]
TOL = 1e-4


def compare(ours, ref, expected_ratio=None, tol=TOL, tol_pdf=None, floor_rel=1e-6):
    """Max relative error of eval and pdf over the direction pairs; `expected_ratio(v, l)`
    returns (eval ratio, pdf ratio) ours/ref predicted by a documented design difference."""
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    rows = []
    for v, l in pairs():
        si.wi = mi.Vector3f(v)
        wo = mi.Vector3f(l)
        fa, fb = ours.eval(ctx, si, wo), ref.eval(ctx, si, wo)
        pa, pb = ours.pdf(ctx, si, wo), ref.pdf(ctx, si, wo)
        rows.append((v, l, [fa[i] for i in range(3)], [fb[i] for i in range(3)], float(pa), float(pb)))
    fmax = max(max(r[3]) for r in rows)
    pmax = max(r[5] for r in rows)
    worst_f = worst_p = 0.0
    for v, l, fa, fb, pa, pb in rows:
        rf, rp = expected_ratio(v, l) if expected_ratio else (1.0, 1.0)
        for a, b in zip(fa, fb):
            worst_f = max(worst_f, rel_err(a, b * rf, floor_rel * fmax))
        worst_p = max(worst_p, rel_err(pa, pb * rp, floor_rel * pmax))
    assert worst_f <= tol, f"eval differs: max relative error {worst_f:.3g} > {tol}"
    tol_pdf = tol if tol_pdf is None else tol_pdf
    assert worst_p <= tol_pdf, f"pdf differs: max relative error {worst_p:.3g} > {tol_pdf}"
    return worst_f, worst_p


def test_lambert_vs_diffuse(scalar_rgb):
    ours = load_lacquer({"model": "lambert", "albedo": [0.2, 0.5, 0.8]})
    ref = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.5, 0.8]}})
    compare(ours, ref)


@pytest.mark.parametrize("alpha_u,alpha_v", [(0.3, 0.3), (0.08, 0.08), (0.1, 0.4)])
def test_ggx_rough_conductor_gold_vs_roughconductor(scalar_rgb, alpha_u, alpha_v):
    ours = load_lacquer({"model": "rough_conductor", "distribution": "ggx", "alpha_u": alpha_u,
                         "alpha_v": alpha_v, "eta": AU_ETA, "k": AU_K})
    ref = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha_u": alpha_u,
                        "alpha_v": alpha_v, "eta": {"type": "rgb", "value": AU_ETA},
                        "k": {"type": "rgb", "value": AU_K}})
    compare(ours, ref)


def beckmann_g1_exact(w, m, au, av):
    """Smith G1 of Beckmann with the exact Lambda (what Lacquer uses)."""
    if (w[0] * m[0] + w[1] * m[1] + w[2] * m[2]) * w[2] <= 0:
        return 0.0
    t2 = ((au * w[0]) ** 2 + (av * w[1]) ** 2) / w[2] ** 2
    if t2 == 0:
        return 1.0
    a = 1.0 / math.sqrt(t2)
    lam = (math.erf(a) - 1.0) / 2.0 + math.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))
    return 1.0 / (1.0 + lam)


def beckmann_g1_mitsuba(w, m, au, av):
    """Mitsuba 3's rational approximation of the same G1 (microfacet.h, <= 0.35 % error)."""
    if (w[0] * m[0] + w[1] * m[1] + w[2] * m[2]) * w[2] <= 0:
        return 0.0
    t2 = ((au * w[0]) ** 2 + (av * w[1]) ** 2) / w[2] ** 2
    if t2 == 0:
        return 1.0
    a = 1.0 / math.sqrt(t2)
    if a >= 1.6:
        return 1.0
    return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)


@pytest.mark.parametrize("alpha_u,alpha_v", [(0.3, 0.3), (0.15, 0.5)])
def test_beckmann_rough_conductor_vs_roughconductor(scalar_rgb, alpha_u, alpha_v):
    """Differs by design: Lacquer uses Smith's exact Beckmann Lambda (erf), Mitsuba a rational
    approximation of G1 (up to 0.35 % per G1). The test predicts the ratio ours/Mitsuba from
    the two G1 formulas (eval: G1(wi) G1(wo); pdf with visible normals: G1(viewer)) and requires
    agreement with that ratio to 1e-4; everything else (D, Fresnel, Jacobian) must match."""
    ours = load_lacquer({"model": "rough_conductor", "distribution": "beckmann", "alpha_u": alpha_u,
                         "alpha_v": alpha_v, "eta": AU_ETA, "k": AU_K})
    ref = mi.load_dict({"type": "roughconductor", "distribution": "beckmann", "alpha_u": alpha_u,
                        "alpha_v": alpha_v, "eta": {"type": "rgb", "value": AU_ETA},
                        "k": {"type": "rgb", "value": AU_K}})

    def ratio(v, l):
        h = [v[i] + l[i] for i in range(3)]
        n = math.sqrt(sum(x * x for x in h))
        h = [x / n for x in h]
        gv_e, gl_e = beckmann_g1_exact(v, h, alpha_u, alpha_v), beckmann_g1_exact(l, h, alpha_u, alpha_v)
        gv_m, gl_m = beckmann_g1_mitsuba(v, h, alpha_u, alpha_v), beckmann_g1_mitsuba(l, h, alpha_u, alpha_v)
        re = (gv_e * gl_e) / (gv_m * gl_m) if gv_m * gl_m > 0 else 1.0
        rp = gv_e / gv_m if gv_m > 0 else 1.0
        return re, rp

    compare(ours, ref, expected_ratio=ratio)


def test_beckmann_rough_conductor_all_normals_pdf(scalar_rgb):
    """With sample_visible = false the pdf is D(h) cos(theta_h) / (4 wo.h): no G1 in it, so it
    must match Mitsuba's to 1e-4 even for Beckmann (eval still carries the G1 ratio)."""
    ours = load_lacquer({"model": "rough_conductor", "distribution": "beckmann", "alpha_u": 0.25,
                         "alpha_v": 0.25, "eta": AU_ETA, "k": AU_K, "sample_visible": False})
    ref = mi.load_dict({"type": "roughconductor", "distribution": "beckmann", "alpha": 0.25,
                        "sample_visible": False, "eta": {"type": "rgb", "value": AU_ETA},
                        "k": {"type": "rgb", "value": AU_K}})

    def ratio(v, l):
        h = [v[i] + l[i] for i in range(3)]
        n = math.sqrt(sum(x * x for x in h))
        h = [x / n for x in h]
        e = beckmann_g1_exact(v, h, 0.25, 0.25) * beckmann_g1_exact(l, h, 0.25, 0.25)
        m = beckmann_g1_mitsuba(v, h, 0.25, 0.25) * beckmann_g1_mitsuba(l, h, 0.25, 0.25)
        return (e / m if m > 0 else 1.0), 1.0

    compare(ours, ref, expected_ratio=ratio)


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
def test_rough_plastic_specular_only_vs_roughplastic(scalar_rgb, distribution):
    """diffuse_reflectance = 0 leaves the specular coating alone (both select it with
    probability 1): eval and pdf must match to 1e-4 for GGX; for Beckmann the G1 of the two
    differ by design (see the conductor test) and the ratio is predicted the same way."""
    alpha = 0.2
    ours = load_lacquer({"model": "rough_plastic", "distribution": distribution, "alpha": alpha,
                         "int_ior": 1.5, "ext_ior": 1.0, "diffuse_reflectance": 0.0})
    ref = mi.load_dict({"type": "roughplastic", "distribution": distribution, "alpha": alpha,
                        "int_ior": 1.5, "ext_ior": 1.0,
                        "diffuse_reflectance": {"type": "rgb", "value": 0.0}})
    ratio = None
    if distribution == "beckmann":
        def ratio(v, l):
            h = [v[i] + l[i] for i in range(3)]
            n = math.sqrt(sum(x * x for x in h))
            h = [x / n for x in h]
            gv_e, gl_e = beckmann_g1_exact(v, h, alpha, alpha), beckmann_g1_exact(l, h, alpha, alpha)
            gv_m, gl_m = beckmann_g1_mitsuba(v, h, alpha, alpha), beckmann_g1_mitsuba(l, h, alpha, alpha)
            return (gv_e * gl_e) / (gv_m * gl_m), gv_e / gv_m
    compare(ours, ref, expected_ratio=ratio)


def test_rough_plastic_ggx_vs_roughplastic(scalar_rgb):
    """The full model (specular coating + diffuse substrate), GGX. Differs by design in the
    substrate term: Mitsuba integrates the coating's transmittance T(mu) and internal diffuse
    reflectance F_dr with a 32x32 Gauss-Legendre rule in single precision, Lacquer to ~1e-6
    (rough_plastic.rs). T enters eval (measured gap 4e-4 relative: tolerance 1e-3) and the
    lobe-selection probability p_spec ~ (1 - T(mu)) of pdf, where the same absolute error of T
    is amplified by 1/(1 - T) ~ 25 near normal incidence (1 - T ~ 0.04): measured 3.2e-3,
    tolerance 5e-3. The specular-only test above holds the rest of the model to 1e-4."""
    ours = load_lacquer({"model": "rough_plastic", "distribution": "ggx", "alpha": 0.2,
                         "int_ior": 1.5, "ext_ior": 1.0, "diffuse_reflectance": [0.2, 0.4, 0.7]})
    ref = mi.load_dict({"type": "roughplastic", "distribution": "ggx", "alpha": 0.2,
                        "int_ior": 1.5, "ext_ior": 1.0,
                        "diffuse_reflectance": {"type": "rgb", "value": [0.2, 0.4, 0.7]}})
    compare(ours, ref, tol=1e-3, tol_pdf=5e-3)
