//! Neumann, Neumann & Szirmay-Kalos (1999), the "stretched" Blinn-Phong model: the Blinn lobe
//! divided by `max(cos θi, cos θo)`,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · (n+2)/(8π) · cosⁿθh / max(cos θi, cos θo),   h = (wi + wo)/|wi + wo|
//! ```
//!
//! The thesis the project started from quotes the lobe with the factor `(n+2)/(2π)`; with that
//! factor the albedo reaches about 4 ks for sharp lobes (the `(n+2)/(2π)` normalises the
//! half-vector distribution, and `dωi = 4 (wo·h) dωh`). The paper itself was not available to
//! this implementation. The factor used here, `(n+2)/(8π)`, is the one that makes the model the
//! microfacet BRDF `D G / (4 cos θi cos θo)` with the normalised Blinn distribution
//! `D = (n+2)/(2π) cosⁿθh` (`∫ D cos θh dωh = 1`) and Neumann's geometry term
//! `G = cos θi cos θo / max(cos θi, cos θo)` — the form in which the paper's `max` is widely
//! used (e.g. as the "Neumann" visibility `1/(4 max(n·l, n·v))` of real-time engines).
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular reflectance ks (kd + ks ≤ 1 per channel) |
//! | `exponent` | scalar | 100 | [0, 10⁴] | Blinn exponent n on `cos θh` |
//!
//! Physics: reciprocal. Energy conserving for kd + ks ≤ 1, which is enforced: with
//! `dωi = 4 (wo·h) dωh` the specular albedo is `ks ∫ D(h) (wo·h) cos θi / max(cos θi, cos θo) dωh
//! ≤ ks ∫ D(h) max(0, wo·h) dωh ≤ ks ∫ D cos θh dωh = ks`, the last step by the rearrangement
//! inequality on the sphere (both factors are non-decreasing functions of the angle to their
//! axis, z and wo). At normal incidence the albedo is `ks (n+2)/(8π) · 8π [2/(n+4) − 1/(n+2) −
//! 2^{−n/2}/(2(n+4)) + 2^{−n/2}/(2(n+2))]` (→ ks as n → ∞); for sharp lobes at oblique `wo`
//! it tends to `ks cos θo`, like the modified Phong model. `max(cos θi, cos θo)` is clamped
//! below at 10⁻³⁰.
//!
//! Sampling: as [`super::blinn_phong`] — the half vector from `(n+1)/(2π) cosⁿθh`, `wi`
//! mirrored about it, or a cosine lobe, chosen by the channel means of kd and ks.
//!
//! Reference: L. Neumann, A. Neumann, L. Szirmay-Kalos, "Compact metallic reflectance
//! models", Computer Graphics Forum 18(3) (Eurographics 1999), 161–172.

use super::blinn_phong::HalfLobe;
use super::phong::{stretch, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance kd"),
    ParamSpec::color("specular", [0.3; 3], 0.0, 1.0, "specular reflectance ks (kd + ks ≤ 1 per channel)"),
    ParamSpec::scalar("exponent", 100.0, 0.0, MAX_EXPONENT, "", "Blinn exponent n on cos θh"),
];

shared_lobe_model! {
    /// The stretched Blinn-Phong BRDF.
    pub struct NeumannStretchBlinnPhong as NeumannStretchBlinnPhong {
        /// Parameters and sampler.
        lobe: HalfLobe
    }
    info: {
        name: "neumann_stretch_blinn_phong",
        summary: "Neumann et al. 1999 stretched Blinn-Phong: kd/π + ks (n+2)/(8π) cosⁿθh / max(cosθi, cosθo)",
        reference: "L. Neumann, A. Neumann, L. Szirmay-Kalos, Compact metallic reflectance models, \
                    Computer Graphics Forum 18(3) 1999",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
        check_params: &[
            r#"{"diffuse": 0.0, "specular": 1.0, "exponent": 1.0}"#,
            r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.3, 0.5, 0.8], "exponent": 1000.0}"#,
            r#"{"diffuse": 0.2, "specular": 0.8, "exponent": 20.0}"#,
        ],
    }
    build: |p| HalfLobe::bounded_from_params(p)?;
    eval: |_this, l, wi, wo| {
        let norm = (T::of(l.exponent) + T::of(2.0)) * T::inv_pi() / T::of(8.0);
        l.diffuse_value() + l.specular_power(wi, wo) * (norm / stretch(wi, wo))
    };
    sampling: lobe_sampling!(lobe);
}

#[cfg(test)]
mod tests {
    use super::super::blinn_phong::testing::normal_incidence_integral;
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::{mirror_z, spherical_direction};
    use crate::material::Material;
    use std::f64::consts::PI;

    fn stretch(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "neumann_stretch_blinn_phong", {json}}}"#)).unwrap()
    }

    /// The value written out from θh and the two cosines.
    #[test]
    fn value_is_the_stretched_formula() {
        let m = stretch(r#""diffuse": 0.1, "specular": 0.6, "exponent": 25"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.4);
        let wi = spherical_direction(0.8f64, 0.6, 3.3);
        let h = (wi + wo).normalize();
        let expect = 0.1 / PI + 0.6 * 27.0 / (8.0 * PI) * h.z.powi(25) / 0.8;
        assert!((m.eval(wi, wo).r - expect).abs() < 1e-13 * expect);
        assert!((m.eval(wo, wi).r - expect).abs() < 1e-13 * expect);
    }

    /// Normal incidence (`max = 1`): `ks (n+2)/(8π) × the Blinn integral`, below ks, → ks.
    #[test]
    fn normal_incidence_albedo_matches_closed_form() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for n in [0.0, 10.0, 3000.0] {
            let m = stretch(&format!(r#""diffuse": 0.0, "specular": 1.0, "exponent": {n}"#));
            let golden = (n + 2.0) / (8.0 * PI) * normal_incidence_integral(n);
            let a = albedo_around(&m, z, z)[0];
            assert!((a - golden).abs() < 2e-4 && golden < 1.0, "n = {n}: {a} vs {golden}");
        }
        assert!((3002.0 / (8.0 * PI) * normal_incidence_integral(3000.0) - 1.0).abs() < 2e-3);
    }

    /// The bound `albedo ≤ ks` at grazing and rough, where the lobe is widest.
    #[test]
    fn albedo_stays_below_ks() {
        for n in [0.0, 1.0, 5.0] {
            let m = stretch(&format!(r#""diffuse": 0.0, "specular": 1.0, "exponent": {n}"#));
            for c in [0.9f64, 0.5, 0.1, 0.01] {
                let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.2);
                let a = albedo_around(&m, wo, mirror_z(wo))[0];
                assert!(a < 1.0, "n = {n}, cos θo = {c}: {a}");
            }
        }
    }

    #[test]
    fn rejects_diffuse_plus_specular_above_one() {
        let e = Material::from_json(r#"{"model": "neumann_stretch_blinn_phong", "diffuse": 0.9, "specular": 0.2}"#)
            .unwrap_err();
        assert!(e.to_string().contains("specular"), "{e}");
    }
}
