//! Neumann, Neumann & Szirmay-Kalos (1999), the "stretched" (metallic) Phong model: the
//! normalised Phong lobe divided by `max(cos θi, cos θo)`,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · (n+2)/(2π) · cosⁿα / max(cos θi, cos θo),   cos α = max(0, wi · mirror(wo))
//! ```
//!
//! The form is the one the thesis the project started from quotes from the paper (its
//! "stretch Phong"); the paper itself was not available to this implementation, so the
//! energy statement below is derived and measured here rather than quoted. The `max` keeps the
//! specular albedo near ks at all angles for sharp lobes (the "metallic" look), where the
//! modified Phong albedo falls like `ks cos θo`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular reflectance ks (kd + ks ≤ 1 per channel) |
//! | `exponent` | scalar | 30 | [2, 10⁴] | Phong exponent n (shininess) |
//!
//! Physics: reciprocal (the `max` is symmetric). Energy: at normal incidence the `max` is 1 and
//! the specular albedo is exactly ks; for n ≥ 1.5 that is the largest albedo over all `wo`
//! (measured by quadrature on a fine grid of n and θo, see the tests), so kd + ks ≤ 1, which
//! is enforced, bounds the total. Below n ≈ 1.4 the albedo rises slightly above ks just off
//! normal incidence (1.086 ks at n = 0 for cos θo = 0.7, 1.0003 ks at n = 1), hence the range
//! starts at 2. For a sharp lobe the albedo is about `ks (1 − tan θo/√(2πn))`: it tends to ks
//! at every angle as n → ∞ (the mirror limit). `max(cos θi, cos θo)` is clamped below at 10⁻³⁰.
//!
//! Sampling: as [`super::phong`] (cosine lobe or power-cosine lobe around the mirror
//! direction, chosen by the channel means of kd and ks); the specular weight is
//! `ks (n+2)/(n+1) · cos θi / max(cos θi, cos θo) ≤ ks (n+2)/(n+1)` over the selection
//! probability.
//!
//! Reference: L. Neumann, A. Neumann, L. Szirmay-Kalos, "Compact metallic reflectance
//! models", Computer Graphics Forum 18(3) (Eurographics 1999), 161–172.

use super::phong::{stretch, MirrorLobe, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance kd"),
    ParamSpec::color("specular", [0.3; 3], 0.0, 1.0, "specular reflectance ks (kd + ks ≤ 1 per channel)"),
    ParamSpec::scalar("exponent", 30.0, 2.0, MAX_EXPONENT, "", "Phong exponent n (shininess)"),
];

shared_lobe_model! {
    /// The stretched Phong BRDF.
    pub struct NeumannStretchPhong as NeumannStretchPhong {
        /// Parameters and sampler.
        lobe: MirrorLobe
    }
    info: {
        name: "neumann_stretch_phong",
        summary: "Neumann et al. 1999 stretched (metallic) Phong: kd/π + ks (n+2)/(2π) cosⁿα / max(cosθi, cosθo)",
        reference: "L. Neumann, A. Neumann, L. Szirmay-Kalos, Compact metallic reflectance models, \
                    Computer Graphics Forum 18(3) 1999",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
        check_params: &[
            r#"{"diffuse": 0.0, "specular": 1.0, "exponent": 2.0}"#,
            r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.3, 0.5, 0.8], "exponent": 200.0}"#,
            r#"{"diffuse": 0.2, "specular": 0.8, "exponent": 8.0}"#,
        ],
    }
    build: |p| MirrorLobe::bounded_from_params(p)?;
    eval: |_this, l, wi, wo| l.diffuse_value() + l.normalised_lobe(wi, wo) / stretch(wi, wo);
    sampling: lobe_sampling!(lobe);
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::{mirror_z, spherical_direction};
    use crate::material::Material;
    use std::f64::consts::PI;

    fn stretch(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "neumann_stretch_phong", {json}}}"#)).unwrap()
    }

    fn specular_albedo(n: f64, cos_o: f64) -> f64 {
        let m = stretch(&format!(r#""diffuse": 0.0, "specular": 1.0, "exponent": {n}"#));
        let wo = spherical_direction((1.0 - cos_o * cos_o).sqrt(), cos_o, 0.9);
        albedo_around(&m, wo, mirror_z(wo))[0]
    }

    /// The value written out from α and the two cosines.
    #[test]
    fn value_is_the_stretched_formula() {
        let m = stretch(r#""diffuse": 0.1, "specular": 0.5, "exponent": 6"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.4);
        let wi = spherical_direction(0.8f64, 0.6, 3.0);
        let alpha = wi.dot(mirror_z(wo)).acos();
        let expect = 0.1 / PI + 0.5 * 8.0 / (2.0 * PI) * alpha.cos().powi(6) / 0.8;
        assert!((m.eval(wi, wo).r - expect).abs() < 1e-13 * expect);
        assert!((m.eval(wo, wi).r - expect).abs() < 1e-13 * expect);
    }

    /// At normal incidence `max(cos θi, 1) = 1`: the albedo is `kd + ks` exactly (as for the
    /// modified model, `ks (n+2)/(2π) · 2π/(n+2)`).
    #[test]
    fn normal_incidence_albedo_is_kd_plus_ks() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for n in [2.0, 30.0, 2000.0] {
            let m = stretch(&format!(r#""diffuse": 0.3, "specular": 0.7, "exponent": {n}"#));
            let a = albedo_around(&m, z, z)[0];
            assert!((a - 1.0).abs() < 2e-4, "n = {n}: {a}");
        }
    }

    /// The energy claim: no `wo` has a larger albedo than normal incidence (ks), from n = 2 up.
    #[test]
    fn albedo_never_exceeds_ks() {
        for n in [2.0, 3.0, 10.0, 100.0] {
            for c in [0.999, 0.99, 0.95, 0.8, 0.5, 0.2, 0.02] {
                let a = specular_albedo(n, c);
                assert!(a <= 1.0 + 2e-5, "n = {n}, cos θo = {c}: {a}");
            }
        }
    }

    /// Sharp lobes: `cos θi / max(cos θi, cos θo) = min(1, 1 + δ)` with δ ≈ −tan θo γ cos ψ
    /// (γ the angle to the mirror direction), so the albedo is `1 − tan θo E[γ] E|cos ψ|/2`
    /// with `E[γ] = √(π/(2n))` and `E|cos ψ| = 2/π`: `1 − tan θo/√(2πn)`, → 1 as n → ∞.
    #[test]
    fn sharp_lobe_albedo_tends_to_ks_at_every_angle() {
        let n = 5000.0;
        for c in [0.8f64, 0.5] {
            let tan = (1.0 - c * c).sqrt() / c;
            let expect = 1.0 - tan / (2.0 * PI * n).sqrt();
            let a = specular_albedo(n, c);
            assert!((a - expect).abs() < 1e-3, "cos θo = {c}: {a} vs {expect}");
        }
    }

    /// Why the range starts at 2: with n = 0 the albedo exceeds ks off normal incidence.
    #[test]
    fn small_exponents_would_break_the_bound() {
        let m = Material::from_json(r#"{"model": "modified_phong", "diffuse": 0.0, "specular": 1.0, "exponent": 0}"#)
            .unwrap();
        // The n = 0 stretched lobe is 1/(π max(cos θi, cos θo)) over the hemisphere around
        // mirror(wo); integrate it directly at cos θo = 0.7 (the modified model supplies the
        // indicator of that hemisphere as π·f).
        let c: f64 = 0.7;
        let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.0);
        let (nt, np) = (2000, 2000);
        let mut a = 0.0;
        for i in 0..nt {
            let ci = (i as f64 + 0.5) / nt as f64;
            for j in 0..np {
                let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                let wi = spherical_direction((1.0 - ci * ci).sqrt(), ci, phi);
                let inside = m.eval(wi, wo).r * PI;
                a += inside / (PI * ci.max(c)) * ci * (2.0 * PI) / (nt * np) as f64;
            }
        }
        assert!(a > 1.08, "{a}");
        let e = Material::from_json(r#"{"model": "neumann_stretch_phong", "exponent": 1}"#).unwrap_err();
        assert!(e.to_string().contains("exponent"), "{e}");
    }
}
