//! Modified Phong (Lewis 1994; Lafortune & Willems 1994): the reciprocal, energy-conserving
//! Phong BRDF,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · (n+2)/(2π) · cosⁿα,     cos α = max(0, wi · mirror(wo))
//! ```
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular reflectance ks (kd + ks ≤ 1 per channel) |
//! | `exponent` | scalar | 30 | [0, 10⁴] | Phong exponent n (shininess) |
//!
//! Physics: reciprocal (`wi · mirror(wo) = wo · mirror(wi)`). Energy conserving when
//! kd + ks ≤ 1, which is enforced: at normal incidence the specular albedo is exactly
//! `ks (n+2)/(2π) ∫ cosⁿθ cos θ dω = ks`, and at any other `wo` it is smaller — the integral
//! `∫ F(wi·a) G(wi·z) dωi` of two non-decreasing functions of the angle to two axes is largest
//! when the axes coincide (the Hardy–Littlewood rearrangement inequality on the sphere), here
//! `F = cosⁿ` around `a = mirror(wo)` and `G = max(0, cos θi)`.
//!
//! Sampling: as [`super::phong`] — a cosine lobe or a power-cosine lobe around the mirror
//! direction, chosen by the channel means of kd and ks; the specular weight is
//! `ks (n+2)/(n+1) cos θi` over the selection probability.
//!
//! References: R. R. Lewis, "Making shaders more physically plausible", Computer Graphics
//! Forum 13(2), 1994; E. P. Lafortune, Y. D. Willems, "Using the modified Phong reflectance
//! model for physically based rendering", KU Leuven CW 197, 1994.

use super::phong::{MirrorLobe, CHECK_PARAMS, PARAMS};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::Params;
use crate::real::Real;

shared_lobe_model! {
    /// The modified (reciprocal, normalised) Phong BRDF.
    pub struct ModifiedPhong as ModifiedPhong {
        /// Parameters and sampler.
        lobe: MirrorLobe
    }
    info: {
        name: "modified_phong",
        summary: "Modified Phong (Lewis; Lafortune & Willems 1994): kd/π + ks (n+2)/(2π) cosⁿα",
        reference: "R. R. Lewis, Making shaders more physically plausible, Computer Graphics Forum \
                    13(2) 1994; E. P. Lafortune, Y. D. Willems, Using the modified Phong reflectance \
                    model for physically based rendering, KU Leuven CW 197 (1994)",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
        check_params: CHECK_PARAMS,
    }
    build: |p| MirrorLobe::bounded_from_params(p)?;
    eval: |_this, l, wi, wo| l.diffuse_value() + l.normalised_lobe(wi, wo);
    sampling: lobe_sampling!(lobe);
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::{mirror_z, spherical_direction};
    use crate::material::Material;
    use std::f64::consts::PI;

    fn modified(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "modified_phong", {json}}}"#)).unwrap()
    }

    /// At normal incidence `α = θi`, so the albedo is `kd + ks (n+2)/(2π) · 2π ∫₀¹ μⁿ μ dμ`
    /// = `kd + ks` exactly, for every n.
    #[test]
    fn normal_incidence_albedo_is_kd_plus_ks() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for n in [0.0, 1.0, 7.5, 100.0, 3000.0] {
            let m = modified(&format!(r#""diffuse": 0.25, "specular": 0.6, "exponent": {n}"#));
            let a = albedo_around(&m, z, z)[0];
            assert!((a - 0.85).abs() < 2e-4, "n = {n}: {a}");
        }
    }

    /// Off normal incidence the albedo is below kd + ks (rearrangement). For a lobe wholly
    /// above the horizon it is exactly `ks cos θo`: `cos θi = wi·z` is linear in `wi`, and the
    /// mean of `wi` under the density `(n+1)/(2π) cosⁿα` is `(n+1)/(n+2)` times its axis, so
    /// `∫ cosⁿα cos θi dωi = 2π/(n+1) · (n+1)/(n+2) · cos θo`.
    #[test]
    fn oblique_albedo_is_below_ks_and_tends_to_ks_cos_theta_o() {
        let m = modified(r#""diffuse": 0.0, "specular": 1.0, "exponent": 5000"#);
        for c in [0.9f64, 0.5, 0.2] {
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 1.2);
            let a = albedo_around(&m, wo, mirror_z(wo))[0];
            assert!(a < 1.0 && (a - c).abs() < 2e-4, "cos θo = {c}: {a}");
        }
        let m = modified(r#""diffuse": 0.0, "specular": 1.0, "exponent": 0.0"#);
        for c in [0.7f64, 0.1] {
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.3);
            assert!(albedo_around(&m, wo, mirror_z(wo))[0] < 1.0);
        }
    }

    /// The value written out from α, and reciprocity at a generic pair.
    #[test]
    fn value_is_lewis_formula_and_reciprocal() {
        let m = modified(r#""diffuse": [0.1, 0.2, 0.3], "specular": 0.4, "exponent": 9"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.4);
        let wi = spherical_direction(0.5f64, 0.75f64.sqrt(), 3.3);
        let alpha = wi.dot(mirror_z(wo)).acos();
        let expect = 0.3 / PI + 0.4 * 11.0 / (2.0 * PI) * alpha.cos().powi(9);
        assert!((m.eval(wi, wo).b - expect).abs() < 1e-13 * expect);
        assert!((m.eval(wi, wo).b - m.eval(wo, wi).b).abs() < 1e-15);
    }

    #[test]
    fn rejects_diffuse_plus_specular_above_one() {
        let e = Material::from_json(r#"{"model": "modified_phong", "diffuse": 0.8, "specular": [0.1, 0.3, 0.1]}"#)
            .unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("specular") && msg.contains("channel 1"), "{msg}");
        assert!(Material::from_json(r#"{"model": "modified_phong", "diffuse": 0.7, "specular": 0.3}"#).is_ok());
    }
}
