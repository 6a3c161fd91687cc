//! Oren-Nayar (1994), the "qualitative" model: the simplified form the paper derives by
//! dropping the `C3` and inter-reflection terms and the `(2β/π)³` correction,
//!
//! ```text
//! f = ρ/π · (A + B · max(0, cos(φi − φo)) · sin α · tan β)
//! A = 1 − 0.5 σ²/(σ² + 0.33),   B = 0.45 σ²/(σ² + 0.09)
//! ```
//!
//! with `α = max(θi, θo)` and `β = min(θi, θo)`. At `σ = 0`, `A = 1` and `B = 0`: Lambert.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `albedo` | colour | 0.5 | [0, 1] | facet albedo ρ |
//! | `sigma` | scalar | 0.3 | [0, π/2] rad | standard deviation of the facet slope angle |
//!
//! Properties (measured by `lacquer check`): reciprocal (symmetric in the two directions);
//! *not* energy conserving. At grazing viewing the albedo tends to `ρ(A + B/2)` (the `B` term
//! integrates to `sin α · ∫max(0, cos Δφ) dφ · ∫ sin²θ dθ / π = B/2`), which exceeds `ρ` for
//! `0 < σ ≲ 0.35` rad, most near σ = 0.2 (1.0155 ρ; measured 1.0155 at cos θo = 0.001), so
//! the claim is `false`.
//! It is non-negative for every `σ` (unlike the full model, whose range is limited).
//!
//! Sampling: cosine-weighted hemisphere.
//!
//! Reference: M. Oren and S. K. Nayar, "Generalization of Lambert's Reflectance Model",
//! SIGGRAPH 1994, pp. 239-246 (the qualitative model, section 4.4, eq. 30).

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::oren_nayar::{angles, Facets};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("albedo", [0.5; 3], 0.0, 1.0, "facet albedo ρ"),
    ParamSpec::scalar(
        "sigma",
        0.3,
        0.0,
        std::f64::consts::FRAC_PI_2,
        "rad",
        "standard deviation of the facet slope angle (Gaussian)",
    ),
];

shared_lobe_model! {
    /// The qualitative Oren-Nayar BRDF.
    pub struct OrenNayarQualitative as OrenNayarQualitative {
        /// Facet albedo and roughness.
        facets: Facets
    }
    info: {
        name: "oren_nayar_qualitative",
        summary: "Oren-Nayar 1994 rough diffuse, qualitative model A + B max(0, cos Δφ) sin α tan β",
        reference: "M. Oren, S. K. Nayar, Generalization of Lambert's Reflectance Model, SIGGRAPH 1994",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
        check_params: &[
            r#"{"albedo": 1.0, "sigma": 0.2}"#,
            r#"{"albedo": [0.9, 0.4, 0.1], "sigma": 1.2}"#,
        ],
    }
    build: |p| Facets::from_params(p);
    eval: |this, l, wi, wo| Rgb::from_array(l.albedo) * (this.factor(wi, wo) * T::inv_pi());
    sampling: cosine_sampling!();
}

impl OrenNayarQualitative {
    /// `A + B max(0, cos Δφ) sin α tan β`.
    #[inline]
    fn factor<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let s2 = T::of(self.facets.sigma * self.facets.sigma);
        let a = T::one() - T::of(0.5) * s2 / (s2 + T::of(0.33));
        let b = T::of(0.45) * s2 / (s2 + T::of(0.09));
        let (sin_a, _, sin_b, cos_b, cos_dphi) = angles(wi, wo);
        let tan_b = sin_b / cos_b.max(T::min_positive_value());
        a + b * cos_dphi.max(T::zero()) * sin_a * tan_b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{check_model, furnace::albedo, CheckConfig};
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use crate::rng::Pcg32;

    fn dir(theta: f64, phi: f64) -> Vec3<f64> {
        spherical_direction(theta.sin(), theta.cos(), phi)
    }

    #[test]
    fn zero_roughness_is_lambert() {
        let m = OrenNayarQualitative {
            facets: Facets { albedo: [0.3; 3], sigma: 0.0 },
        };
        let mut rng = Pcg32::new(5, 5);
        for _ in 0..1000 {
            let wi = cosine_hemisphere(rng.uniform(), rng.uniform());
            let wo = cosine_hemisphere(rng.uniform(), rng.uniform());
            assert_eq!(m.eval(wi, wo).r, 0.3 * std::f64::consts::FRAC_1_PI);
        }
    }

    /// Hand-evaluated: θi = 50°, θo = 20°, Δφ = 40°: f = ρ/π (A + B cos 40° sin 50° tan 20°).
    #[test]
    fn off_plane_value() {
        let (rho, sigma) = (0.5, 0.35);
        let s2 = sigma * sigma;
        let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
        let b = 0.45 * s2 / (s2 + 0.09);
        let r = f64::to_radians;
        let want = rho / std::f64::consts::PI * (a + b * r(40.0).cos() * r(50.0).sin() * r(20.0).tan());
        let m = OrenNayarQualitative {
            facets: Facets { albedo: [rho; 3], sigma },
        };
        let f = m.eval(dir(r(50.0), 1.0), dir(r(20.0), 1.0 - r(40.0)));
        assert!((f.r - want).abs() < 1e-14, "{} vs {want}", f.r);
        // Back-scattering half: the B term is clipped to zero.
        let back = m.eval(dir(r(50.0), 0.0), dir(r(20.0), std::f64::consts::PI));
        assert!((back.r - rho * a / std::f64::consts::PI).abs() < 1e-15);
    }

    /// Albedo at normal viewing is exactly ρA (β = 0).
    #[test]
    fn albedo_at_normal_viewing_is_rho_a() {
        let (rho, sigma) = (0.8, 0.6);
        let s2 = sigma * sigma;
        let want = rho * (1.0 - 0.5 * s2 / (s2 + 0.33));
        let m = Material::from_json(&format!(
            r#"{{"model": "oren_nayar_qualitative", "albedo": {rho}, "sigma": {sigma}}}"#
        ))
        .unwrap();
        let (a, _) = albedo(&m, Vec3::new(0.0, 0.0, 1.0), 20_000, &mut Pcg32::new(2, 2));
        assert!((a[0] - want).abs() < 2e-3, "{} vs {want}", a[0]);
    }

    #[test]
    fn passes_its_claims() {
        let report = check_model(&INFO, &CheckConfig::quick());
        assert!(report.passed, "{:?}", report.summary);
    }
}
