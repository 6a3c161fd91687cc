//! Neumann–Neumann–Szirmay-Kalos (1999): the "metallic" Ward model, whose
//! `1/√(cosθi cosθo)` is replaced by `1/max(cosθi, cosθo)`,
//!
//! ```text
//! f(wi, wo) = ρd/π + ρs · exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy max(cosθi, cosθo))
//! ```
//!
//! The thesis the project started from (its "Neumann" Ward variant) gives the isotropic
//! lobe `exp(−tan²θh/α²)/(4πα² max(cosθi, cosθo))`; the anisotropic exponent of Ward's
//! eq. 5 is carried over unchanged (the energy bound below does not depend on it). In
//! microfacet terms the `max` is Neumann's geometry factor
//! `G/(4 cosθi cosθo) = 1/(4 max(cosθi, cosθo))`, which also keeps the highlight from
//! vanishing at grazing ("metallic" look).
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance ρd |
//! | `specular` | colour | 0.2 | [0, 1] | specular reflectance ρs (ρd + ρs ≤ 1 per channel) |
//! | `alpha_x` | scalar | 0.1 | [0.01, 1] | lobe width along the tangent x (Ward's slope deviation) |
//! | `alpha_y` | scalar | 0.1 | [0.01, 1] | lobe width along the bitangent y (Ward's slope deviation) |
//!
//! Physics: reciprocal (the `max` is symmetric) and energy conserving: since
//! `cosθi/max(cosθi, cosθo) ≤ 1` and `dωi = 4 (wo·h) dωh`, the specular albedo is at most
//! `ρs ∫ D(h) cosθh · cos³θh (wo·h) dωh ≤ ρs` (`D` the Beckmann distribution, normalised),
//! so ρd + ρs ≤ 1 bounds the total.
//!
//! Sampling: Ward's half-vector formulas with Walter's exact density, mixed with a cosine
//! lobe by the reflectances (shared with the family, see [`super::ward`]).
//!
//! Reference: L. Neumann, A. Neumann, L. Szirmay-Kalos, "Compact metallic reflectance
//! models", Computer Graphics Forum 18(3) (Eurographics 1999), 161–172.

use super::ward::{WardLobes, CHECK_PARAMS, PARAMS};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::Params;
use crate::real::Real;

shared_lobe_model! {
    /// Ward's BRDF with Neumann's `max(cosθi, cosθo)` normalisation.
    pub struct WardNeumann as WardNeumann {
        /// Reflectances and roughness.
        lobes: WardLobes
    }
    info: {
        name: "ward_neumann",
        summary: "Ward gloss with Neumann's 1/max(cosθi, cosθo) normalisation, + Lambert",
        reference: "L. Neumann, A. Neumann, L. Szirmay-Kalos, Compact metallic reflectance \
                    models, Computer Graphics Forum 18(3) 1999",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
        check_params: CHECK_PARAMS,
    }
    build: |p| WardLobes::from_params(p)?;
    eval: |_this, l, wi, wo| l.value(wi + wo, T::of(4.0) * T::PI() * l.alpha_xy::<T>() * wi.z.max(wo.z));
    sampling: lobe_sampling!(lobes);
}

#[cfg(test)]
mod tests {
    use super::super::ward::testing::{albedo_by_h_quadrature, normal_albedo};
    use super::*;
    use crate::check::{check_model, CheckConfig};
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use std::f64::consts::PI;

    fn neumann(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "ward_neumann", {json}}}"#)).unwrap()
    }

    /// The paper's isotropic form `ρs e^{−tan²θh/α²}/(4πα² max(cosθi, cosθo))`.
    #[test]
    fn isotropic_case_is_papers_form() {
        let alpha: f64 = 0.15;
        let m = neumann(r#""diffuse": 0.0, "specular": 0.9, "alpha_x": 0.15, "alpha_y": 0.15"#);
        for (wi, wo) in [
            (spherical_direction(0.6f64, 0.8, 0.3), spherical_direction(0.5, 0.75f64.sqrt(), 3.2)),
            (spherical_direction(0.95f64, 0.0975f64.sqrt(), 0.0), spherical_direction(0.9, 0.19f64.sqrt(), 3.0)),
        ] {
            let h = (wi + wo).normalize();
            let t2 = h.z.acos().tan().powi(2);
            let expect =
                0.9 * (-t2 / (alpha * alpha)).exp() / (4.0 * PI * alpha * alpha * wi.z.max(wo.z));
            let f = m.eval(wi, wo).r;
            assert!((f - expect).abs() <= 1e-12 * expect, "{f} vs {expect}");
        }
    }

    /// Normal incidence (`max = 1`): `ρs ∫₀¹ e^{−t/α²}/α² (1 − t)(1 + t)^{−3} dt`
    /// (t = tan²θh), ≤ ρs and → ρs as α → 0.
    #[test]
    fn normal_incidence_albedo_matches_derivation() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        for alpha in [0.05, 0.2, 0.6] {
            let m = neumann(&format!(
                r#""diffuse": 0.0, "specular": 0.8, "alpha_x": {alpha}, "alpha_y": {alpha}"#
            ));
            let golden = 0.8 * normal_albedo(alpha, |t| (1.0 - t) * (1.0 + t).powi(-3));
            let a = albedo_by_h_quadrature(&m, n, alpha, alpha);
            assert!((a[0] - golden).abs() < 1e-4, "α={alpha}: {} vs {golden}", a[0]);
        }
        let golden = normal_albedo(0.01, |t| (1.0 - t) * (1.0 + t).powi(-3));
        assert!((golden - 1.0).abs() < 5e-4, "{golden}");
    }

    /// Small-α limit at oblique incidence: `max(ci, co) → co`, so like the original Ward
    /// lobe the albedo tends to `ρs cosθo` (first-order corrections in α from the `max`).
    #[test]
    fn small_alpha_albedo_tends_to_rho_s_cos_theta_o() {
        let m = neumann(r#""diffuse": 0.0, "specular": 0.6, "alpha_x": 0.01, "alpha_y": 0.01"#);
        for c in [0.9f64, 0.5, 0.3] {
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.4);
            let a = albedo_by_h_quadrature(&m, wo, 0.01, 0.01)[0];
            assert!(a <= 0.6 * c && a > 0.6 * c * 0.97, "cos={c}: {a}");
        }
    }

    /// The bound `albedo ≤ ρs` holds at grazing, rough and anisotropic.
    #[test]
    fn albedo_stays_below_rho_s_at_grazing() {
        for (ax, ay) in [(1.0f64, 1.0f64), (0.3, 0.3), (0.05, 1.0)] {
            let m = neumann(&format!(
                r#""diffuse": 0.0, "specular": 1.0, "alpha_x": {ax}, "alpha_y": {ay}"#
            ));
            for c in [1e-2f64, 1e-4] {
                let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.5);
                let a = albedo_by_h_quadrature(&m, wo, ax, ay)[0];
                assert!(a <= 1.0, "αx={ax} αy={ay} cos={c}: {a}");
            }
        }
    }

    #[test]
    fn passes_quick_checks() {
        let r = check_model(&INFO, &CheckConfig::quick());
        assert!(r.passed, "{:#?}", r.summary);
    }
}
