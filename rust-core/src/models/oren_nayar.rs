//! Oren-Nayar (1994), the full model: a rough diffuse surface made of Lambertian V-grooves
//! whose slope angles have a Gaussian distribution of standard deviation `σ`, with
//! shadowing, masking, foreshortening and two-bounce inter-reflection.
//!
//! With `α = max(θi, θo)`, `β = min(θi, θo)` and `Δφ = φi − φo` (paper, eqs. 27-30):
//!
//! ```text
//! f = ρ/π [C1 + cos Δφ · C2 · tan β + (1 − |cos Δφ|) · C3 · tan((α + β)/2)]      (direct)
//!   + 0.17 ρ²/π · σ²/(σ² + 0.13) · [1 − cos Δφ · (2β/π)²]                      (inter-reflection)
//! C1 = 1 − 0.5 σ²/(σ² + 0.33)
//! C2 = 0.45 σ²/(σ² + 0.09) · sin α                 if cos Δφ ≥ 0
//!    = 0.45 σ²/(σ² + 0.09) · (sin α − (2β/π)³)     otherwise
//! C3 = 0.125 σ²/(σ² + 0.09) · (4αβ/π²)²
//! ```
//!
//! At `σ = 0` every term but `C1 = 1` vanishes: exactly Lambert, `ρ/π`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `albedo` | colour | 0.5 | [0, 1] | facet albedo ρ |
//! | `sigma` | scalar | 0.3 | [0, 0.65] rad | standard deviation of the facet slope angle |
//!
//! The range of `σ` stops at 0.65 rad (37°): the paper's functional approximation turns
//! negative above σ ≈ 0.664 rad when both directions are grazing and opposite in azimuth
//! (`C1 + cos Δφ · C2 · tan β` with `cos Δφ = −1`, `β → π/2`), which no BRDF may do. The
//! paper's measured samples (plaster, sand, cloth) lie well inside.
//!
//! Properties (measured by `lacquer check`, see the tests): the model is reciprocal (`α`, `β`
//! and `cos Δφ` are symmetric in the two directions). It is *not* energy conserving: the
//! retro-reflective `C2` term and the inter-reflection term push the albedo above one near
//! grazing for bright, moderately rough surfaces — measured with ρ = 1: 1.004 at σ = 0.05,
//! 1.051 at σ = 0.3 (the maximum), 1.027 at σ = 0.5, below one from σ ≈ 0.62, all at
//! cos θo = 0.001 — so the claim is `false` and the checker reports the measured maximum.
//!
//! Sampling: cosine-weighted hemisphere (the model is a perturbed Lambertian lobe).
//!
//! Reference: M. Oren and S. K. Nayar, "Generalization of Lambert's Reflectance Model",
//! SIGGRAPH 1994, pp. 239-246 (eqs. 27-30 and the inter-reflection term, section 5).

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
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
        0.65,
        "rad",
        "standard deviation of the facet slope angle (Gaussian)",
    ),
];

shared_lobe_model! {
    /// The full Oren-Nayar BRDF.
    pub struct OrenNayar as OrenNayar {
        /// Facet albedo and roughness.
        facets: Facets
    }
    info: {
        name: "oren_nayar",
        summary: "Oren-Nayar 1994 rough diffuse, full model (C1, C2, C3 and inter-reflection)",
        reference: "M. Oren, S. K. Nayar, Generalization of Lambert's Reflectance Model, SIGGRAPH 1994",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
        check_params: &[
            r#"{"albedo": 1.0, "sigma": 0.3}"#,
            r#"{"albedo": [0.9, 0.4, 0.1], "sigma": 0.65}"#,
        ],
    }
    build: |p| Facets::from_params(p);
    eval: |this, l, wi, wo| {
        let (direct, inter) = this.brackets(wi, wo);
        let rho = Rgb::from_array(l.albedo);
        (rho * direct + rho * rho * inter) * T::inv_pi()
    };
    sampling: cosine_sampling!();
}

/// The parameters of both Oren-Nayar models.
#[derive(Clone, Debug)]
pub struct Facets {
    /// Facet albedo ρ per channel.
    pub albedo: [f64; 3],
    /// Standard deviation of the facet slope angle, radians.
    pub sigma: f64,
}

impl Facets {
    /// Reads `albedo` and `sigma`.
    pub(crate) fn from_params(p: &Params) -> Self {
        Self { albedo: p.color("albedo"), sigma: p.scalar("sigma") }
    }
}

/// The angles and azimuth term shared by both Oren-Nayar models, from the two directions:
/// `(sin α, cos α, sin β, cos β, cos Δφ)` with `α = max θ`, `β = min θ`. `cos Δφ` is taken as
/// zero when either direction is at the pole (every term it multiplies vanishes there).
#[inline]
pub(crate) fn angles<T: Real>(wi: Vec3<T>, wo: Vec3<T>) -> (T, T, T, T, T) {
    let si = (wi.x * wi.x + wi.y * wi.y).sqrt();
    let so = (wo.x * wo.x + wo.y * wo.y).sqrt();
    let denom = si * so;
    let cos_dphi = if denom > T::zero() {
        ((wi.x * wo.x + wi.y * wo.y) / denom).clamp_to(-T::one(), T::one())
    } else {
        T::zero()
    };
    // α belongs to the direction closer to the horizon (smaller cos θ).
    if wi.z < wo.z {
        (si, wi.z, so, wo.z, cos_dphi)
    } else {
        (so, wo.z, si, wi.z, cos_dphi)
    }
}

impl OrenNayar {
    /// The direct (`L1`) bracket and the inter-reflection (`L2`) bracket, both without `ρ/π`.
    #[inline]
    fn brackets<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> (T, T) {
        let s2 = T::of(self.facets.sigma * self.facets.sigma);
        let (sin_a, cos_a, sin_b, cos_b, cos_dphi) = angles(wi, wo);
        // Angles from atan2 of (sin, cos): accurate near the pole in f32, unlike acos.
        let alpha = sin_a.atan2(cos_a);
        let beta = sin_b.atan2(cos_b);
        let two_beta_pi = T::of(2.0) * beta * T::inv_pi();
        let c1 = T::one() - T::of(0.5) * s2 / (s2 + T::of(0.33));
        let r = s2 / (s2 + T::of(0.09));
        let c2 = if cos_dphi >= T::zero() {
            T::of(0.45) * r * sin_a
        } else {
            // sin α − (2β/π)³ without cancellation: both terms approach 1 when both
            // directions graze, and their f32 rounding, multiplied by tan β ≈ 1/cos β, turned
            // f negative (`lacquer numerics`: −0.014 at cos θ ≈ 3e-7, σ = 0.65). Written as
            // (1 − t)(1 + t + t²) − cos²α/(1 + sin α), t = 2β/π, 1 − t = (2/π)·atan2(cos β, sin β).
            let one_minus_t = T::of(2.0) * T::inv_pi() * cos_b.atan2(sin_b);
            let t = two_beta_pi;
            T::of(0.45) * r * (one_minus_t * (T::one() + t + t * t) - cos_a * cos_a / (T::one() + sin_a))
        };
        let k = T::of(4.0) * alpha * beta * T::inv_pi() * T::inv_pi();
        let c3 = T::of(0.125) * r * k * k;
        let tan_b = sin_b / cos_b.max(T::min_positive_value());
        // tan((α + β)/2) by the half-angle formula (sin α + sin β)/(cos α + cos β).
        let tan_half = (sin_a + sin_b) / (cos_a + cos_b).max(T::min_positive_value());
        let direct = c1 + cos_dphi * c2 * tan_b + (T::one() - cos_dphi.abs()) * c3 * tan_half;
        let inter = T::of(0.17) * s2 / (s2 + T::of(0.13))
            * (T::one() - cos_dphi * two_beta_pi * two_beta_pi);
        (direct, inter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{check_model, furnace::albedo, CheckConfig};
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use crate::rng::Pcg32;

    fn on(rho: f64, sigma: f64) -> OrenNayar {
        OrenNayar {
            facets: Facets { albedo: [rho; 3], sigma },
        }
    }

    fn dir(theta: f64, phi: f64) -> Vec3<f64> {
        spherical_direction(theta.sin(), theta.cos(), phi)
    }

    /// σ = 0 is Lambert exactly, for every pair of directions.
    #[test]
    fn zero_roughness_is_lambert() {
        let m = on(0.7, 0.0);
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..1000 {
            let wi = cosine_hemisphere(rng.uniform(), rng.uniform());
            let wo = cosine_hemisphere(rng.uniform(), rng.uniform());
            let f = m.eval(wi, wo);
            assert_eq!(f.r, 0.7 * std::f64::consts::FRAC_1_PI);
        }
    }

    /// Hand-evaluated value: wi = wo = normal gives α = β = 0, so
    /// f = ρ C1/π + 0.17 ρ² σ²/(σ² + 0.13)/π.
    #[test]
    fn normal_incidence_value() {
        let (rho, sigma) = (0.8, 0.5);
        let s2 = sigma * sigma;
        let c1 = 1.0 - 0.5 * s2 / (s2 + 0.33);
        let want = (rho * c1 + 0.17 * rho * rho * s2 / (s2 + 0.13)) / std::f64::consts::PI;
        let z = Vec3::new(0.0, 0.0, 1.0);
        assert!((on(rho, sigma).eval(z, z).r - want).abs() < 1e-15);
    }

    /// Hand-evaluated value away from the normal: θi = 60°, θo = 30°, same azimuth.
    /// α = 60°, β = 30°, cos Δφ = 1: C2 = 0.45 r sin 60°, the C3 term vanishes and the
    /// inter-reflection bracket is 1 − (2β/π)² = 1 − 1/9.
    #[test]
    fn in_plane_value() {
        let (rho, sigma) = (0.6, 0.4);
        let s2 = sigma * sigma;
        let c1 = 1.0 - 0.5 * s2 / (s2 + 0.33);
        let c2 = 0.45 * s2 / (s2 + 0.09) * (60f64).to_radians().sin();
        let direct = c1 + c2 * (30f64).to_radians().tan();
        let inter = 0.17 * s2 / (s2 + 0.13) * (1.0 - 1.0 / 9.0);
        let want = (rho * direct + rho * rho * inter) / std::f64::consts::PI;
        let f = on(rho, sigma).eval(dir(60f64.to_radians(), 0.3), dir(30f64.to_radians(), 0.3));
        assert!((f.r - want).abs() < 1e-14, "{} vs {want}", f.r);
    }

    /// Albedo at normal viewing: β = 0 removes the C2, C3 and (2β/π)² terms, so the albedo is
    /// ρ C1 + 0.17 ρ² σ²/(σ² + 0.13) exactly.
    #[test]
    fn albedo_at_normal_viewing() {
        let (rho, sigma) = (0.9, 0.5);
        let s2 = sigma * sigma;
        let want = rho * (1.0 - 0.5 * s2 / (s2 + 0.33)) + 0.17 * rho * rho * s2 / (s2 + 0.13);
        let m = Material::from_json(&format!(
            r#"{{"model": "oren_nayar", "albedo": {rho}, "sigma": {sigma}}}"#
        ))
        .unwrap();
        let (a, _) = albedo(&m, Vec3::new(0.0, 0.0, 1.0), 20_000, &mut Pcg32::new(1, 1));
        assert!((a[0] - want).abs() < 2e-3, "{} vs {want}", a[0]);
    }

    /// The direct bracket stays positive over the whole σ range, even for opposite grazing
    /// directions (where it is smallest), in both precisions.
    #[test]
    fn direct_term_is_positive_at_the_largest_sigma() {
        let m = on(1.0, 0.65);
        for &e in &[1e-7f64, 1e-5, 1e-3, 1e-2, 0.1] {
            for &e2 in &[1e-7f64, 1e-5, 1e-3, 0.1] {
                let wi = dir(std::f64::consts::FRAC_PI_2 - e, 0.0);
                let wo = dir(std::f64::consts::FRAC_PI_2 - e2, std::f64::consts::PI);
                assert!(m.brackets(wi, wo).0 > 0.0, "{e} {e2}");
                assert!(m.brackets(wi.cast::<f32>(), wo.cast()).0 > 0.0, "{e} {e2}");
            }
        }
    }

    /// Regression (`lacquer numerics`): opposite grazing directions at cos θ ≈ 3e-7 and
    /// σ = 0.65 gave f = −0.014 in f32 (cancellation in sin α − (2β/π)³). Now f32 agrees with
    /// f64 to 1e-2 relative (measured 1.8e-3 on the ρ = 0.4 channel, 5.65e-3 on ρ = 0.1, below
    /// 5e-3 on ρ = 0.9: the f32 rounding of the inputs themselves at cos θ ≈ 3e-7, amplified
    /// by tan β ≈ 3.5e6; before the fix the error was 200 %).
    #[test]
    fn f32_opposite_grazing_is_positive_and_accurate() {
        let m = Material::from_json(r#"{"model": "oren_nayar", "albedo": [0.9, 0.4, 0.1], "sigma": 0.65}"#)
            .expect("a valid material");
        let wi = Vec3::new(-0.3158024318524749, -0.9488249701794228, 2.832937313247381e-7);
        let wo = Vec3::new(0.31583461343446767, 0.9488142584071027, 2.83284123037668e-7);
        let f64v = m.eval(wi, wo);
        let f32v = m.eval(wi.cast::<f32>(), wo.cast::<f32>());
        for c in 0..3 {
            assert!(f32v[c] >= 0.0, "channel {c}: {}", f32v[c]);
            let rel = (f64::from(f32v[c]) - f64v[c]).abs() / f64v[c];
            assert!(rel < 1e-2, "channel {c}: f32 {} vs f64 {} ({rel:.2e})", f32v[c], f64v[c]);
        }
    }

    #[test]
    fn passes_its_claims() {
        let report = check_model(&INFO, &CheckConfig::quick());
        assert!(report.passed, "{:?}", report.summary);
    }
}
