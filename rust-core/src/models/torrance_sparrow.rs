//! Torrance-Sparrow (1967) in the form pbrt gives it (`MicrofacetReflection`): mirror
//! microfacets with a symmetric V-groove masking, Fresnel-weighted, plus the paper's
//! optional Lambertian component:
//!
//! ```text
//! f = R · F(wo·h) · D(h) · G(wi, wo, h) / (4 (n·wi)(n·wo)) + ρd/π
//! ```
//!
//! Exactly which form: the `1/(4 (n·wi)(n·wo))` factor is the Jacobian of the half-vector
//! map (Torrance & Sparrow's `dω' = dω/(4 cos ψ)` combined with the projected facet area),
//! with `D` normalised to `∫ D cos θm dω = 1` as pbrt does. The facet distribution is
//! - `gaussian` — the paper's own: Gaussian in the facet *angle*, `D ∝ exp(−θm²/α²)`
//!   (their `b·e^{−c²α²}` with `c = 1/α`), normalised numerically at construction;
//! - `beckmann` (default) — Beckmann's Gaussian-slope distribution
//!   `exp(−tan²θm/α²)/(π α² cos⁴θm)`, which pbrt uses and which agrees with the Gaussian in
//!   angle for small `θm`.
//!
//! `G` is the paper's V-groove shadowing/masking `min(1, 2(n·h)(n·wo)/(wo·h),
//! 2(n·h)(n·wi)/(wo·h))` by default; pbrt-v3/v4's Smith forms are available for Beckmann
//! (Smith's `Λ` needs the slope distribution, so they are rejected for `gaussian`). `F` is the
//! exact Fresnel reflectance of the (complex) index `η + i·k`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `distribution` | choice | `beckmann` | `beckmann`, `gaussian` | facet distribution |
//! | `alpha` | scalar | 0.2 | [0.001, 1] | Beckmann α, or the Gaussian's angular width (rad) |
//! | `masking` | choice | `vgroove` | `vgroove`, `smith_separable`, `smith_height_correlated` | `G` (Smith only with `beckmann`) |
//! | `eta` | colour | 1.5 | [0.01, 10] | real part of the relative index of refraction |
//! | `k` | colour | 0 | [0, 10] | extinction coefficient (0 for a dielectric) |
//! | `specular` | colour | 1 | [0, 1] | scale `R` of the specular term (pbrt's `R`) |
//! | `diffuse` | colour | 0 | [0, 1] | Lambertian reflectance ρd; `specular + diffuse ≤ 1` per channel |
//!
//! Claims: reciprocal (`wo·h = wi·h`, `G` symmetric); energy conserving: the specular albedo
//! is at most `R` (single scattering with `F ≤ 1`) and the diffuse one `ρd`, and their sum is
//! limited to one per channel.
//!
//! Sampling: Beckmann visible normals (also as the proposal for the `gaussian` shape) and the
//! cosine lobe, chosen in proportion to `R̄·F̄(cos θo)` and `ρ̄d`; the pdf is the mixture.
//!
//! References: K. E. Torrance and E. M. Sparrow, "Theory for Off-Specular Reflection From
//! Roughened Surfaces", JOSA 57(9), 1105-1114, 1967; M. Pharr, W. Jakob, G. Humphreys,
//! *Physically Based Rendering*, 3rd ed., section 8.4.4.

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::half_vector;
use crate::fresnel::conductor_rgb;
use crate::math::{Rgb, Vec3};
use crate::microfacet::{DistributionKind, MaskingKind, Microfacet};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::quadrature::gauss_legendre_on;
use crate::real::Real;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::choice(
        "distribution",
        "beckmann",
        &["beckmann", "gaussian"],
        "facet distribution: Beckmann slopes, or the paper's Gaussian in facet angle",
    ),
    ParamSpec::scalar(
        "alpha",
        0.2,
        0.001,
        1.0,
        "",
        "Beckmann roughness α, or the Gaussian's angular width in radians",
    ),
    ParamSpec::choice(
        "masking",
        "vgroove",
        &["vgroove", "smith_separable", "smith_height_correlated"],
        "masking-shadowing G (Smith forms need the beckmann distribution)",
    ),
    ParamSpec::color("eta", [1.5; 3], 0.01, 10.0, "real part of the relative IOR"),
    ParamSpec::color("k", [0.0; 3], 0.0, 10.0, "extinction coefficient (0: dielectric)"),
    ParamSpec::color("specular", [1.0; 3], 0.0, 1.0, "scale R of the specular term"),
    ParamSpec::color(
        "diffuse",
        [0.0; 3],
        0.0,
        1.0,
        "Lambertian reflectance ρd (specular + diffuse ≤ 1)",
    ),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "torrance_sparrow",
    summary: "Torrance-Sparrow 1967 as in pbrt: R F D G / (4 cos cos), V-groove G, + ρd/π",
    reference: "K. E. Torrance, E. M. Sparrow, Theory for Off-Specular Reflection From Roughened Surfaces, JOSA 1967",
    params: PARAMS,
    claims: Claims {
        reciprocal: true,
        energy_conserving: true,
        sampled: true,
    },
    check_params: &[
        r#"{"distribution": "gaussian", "alpha": 0.5, "eta": 0.05, "k": 8.0}"#,
        r#"{"alpha": 0.8, "masking": "smith_height_correlated", "eta": 0.05, "k": 8.0}"#,
        r#"{"alpha": 0.1, "specular": 0.3, "diffuse": [0.7, 0.4, 0.1]}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    let gaussian = p.choice("distribution") == "gaussian";
    let masking =
        MaskingKind::from_name(p.choice("masking")).expect("choices are validated against the spec");
    if gaussian && masking != MaskingKind::VGroove {
        return Err(Error::Invalid {
            param: "masking".into(),
            reason: "Smith masking needs the Beckmann slope distribution; use \"vgroove\" with \
                     the gaussian distribution"
                .into(),
        });
    }
    let (specular, diffuse) = (p.color("specular"), p.color("diffuse"));
    if (0..3).any(|c| specular[c] + diffuse[c] > 1.0 + 1e-12) {
        return Err(Error::Invalid {
            param: "diffuse".into(),
            reason: format!(
                "specular + diffuse must not exceed 1 in any channel, got {specular:?} + {diffuse:?}"
            ),
        });
    }
    let alpha = p.scalar("alpha");
    Ok(Model::TorranceSparrow(TorranceSparrow {
        gaussian_norm: gaussian.then(|| 1.0 / gaussian_projected_area(alpha)),
        alpha,
        masking,
        eta: p.color("eta"),
        k: p.color("k"),
        specular,
        diffuse,
    }))
}

/// `2π ∫₀^{π/2} exp(−θ²/α²) cos θ sin θ dθ`, the projected area of the unnormalised
/// Gaussian-in-angle distribution (64-point Gauss-Legendre over the range where the
/// exponential is above 1e-28).
fn gaussian_projected_area(alpha: f64) -> f64 {
    let top = (8.0 * alpha).min(std::f64::consts::FRAC_PI_2);
    let (x, w) = gauss_legendre_on(64, 0.0, top);
    2.0 * std::f64::consts::PI
        * x.iter()
            .zip(&w)
            .map(|(t, w)| w * (-(t / alpha).powi(2)).exp() * t.cos() * t.sin())
            .sum::<f64>()
}

/// The Torrance-Sparrow BRDF.
#[derive(Clone, Debug)]
pub struct TorranceSparrow {
    /// `1/N` of the Gaussian-in-angle distribution, or `None` for Beckmann.
    pub gaussian_norm: Option<f64>,
    /// Roughness (Beckmann α, or the Gaussian's angular width).
    pub alpha: f64,
    /// Masking-shadowing.
    pub masking: MaskingKind,
    /// Real part of the IOR per channel.
    pub eta: [f64; 3],
    /// Extinction coefficient per channel.
    pub k: [f64; 3],
    /// Scale of the specular term.
    pub specular: [f64; 3],
    /// Lambertian reflectance.
    pub diffuse: [f64; 3],
}

impl TorranceSparrow {
    /// The Beckmann distribution (the model's `D` for `beckmann`, the sampler for both).
    fn beckmann<T: Real>(&self) -> Microfacet<T> {
        let a = T::of(self.alpha);
        Microfacet::new(DistributionKind::Beckmann, a, a)
    }

    /// The facet distribution `D(h)`.
    fn d<T: Real>(&self, h: Vec3<T>) -> T {
        match self.gaussian_norm {
            None => self.beckmann::<T>().d(h),
            Some(norm) => {
                let theta = (h.x * h.x + h.y * h.y).sqrt().atan2(h.z);
                (-(theta / T::of(self.alpha)).sqr()).exp() * T::of(norm)
            }
        }
    }

    /// Selection probability of the specular lobe for this `wo`.
    fn specular_probability<T: Real>(&self, wo: Vec3<T>) -> T {
        let f = conductor_rgb(wo.z, Rgb::from_array(self.eta), Rgb::from_array(self.k));
        let ws = (Rgb::from_array(self.specular) * f).average();
        let wd = Rgb::<T>::from_array(self.diffuse).average();
        if ws + wd > T::zero() {
            ws / (ws + wd)
        } else {
            T::one()
        }
    }
}

impl Bxdf for TorranceSparrow {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let diffuse = Rgb::from_array(self.diffuse) * T::inv_pi();
        let Some(h) = half_vector(wi, wo) else {
            return diffuse;
        };
        let g = self.beckmann::<T>().g(wi, wo, h, self.masking);
        let fr = conductor_rgb(wo.dot(h), Rgb::from_array(self.eta), Rgb::from_array(self.k));
        let spec = Rgb::from_array(self.specular) * fr;
        diffuse + spec * (self.d(h) * g / (T::of(4.0) * wi.z * wo.z))
    }

    beckmann_mixture_sampling!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{check_model, furnace::albedo, CheckConfig};
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use crate::rng::Pcg32;

    fn mat(json: &str) -> Material {
        Material::from_json(json).unwrap()
    }

    /// The numerically normalised Gaussian-in-angle D has unit projected area (checked by an
    /// independent midpoint rule over the hemisphere).
    #[test]
    fn gaussian_distribution_is_normalised() {
        for &a in &[0.01, 0.2, 0.7, 1.0] {
            let m = TorranceSparrow {
                gaussian_norm: Some(1.0 / gaussian_projected_area(a)),
                alpha: a,
                masking: MaskingKind::VGroove,
                eta: [1.5; 3],
                k: [0.0; 3],
                specular: [1.0; 3],
                diffuse: [0.0; 3],
            };
            let n = 200_000;
            let top = (10.0 * a).min(std::f64::consts::FRAC_PI_2);
            let mut s = 0.0;
            for i in 0..n {
                let t = (i as f64 + 0.5) / n as f64 * top;
                let h = spherical_direction(t.sin(), t.cos(), 0.3);
                s += m.d(h) * t.cos() * t.sin() * top / n as f64;
            }
            let area = 2.0 * std::f64::consts::PI * s;
            assert!((area - 1.0).abs() < 1e-6, "α={a}: {area}");
        }
    }

    /// For small angles the paper's Gaussian in angle and Beckmann's Gaussian in slope agree
    /// (tan θ ≈ θ, cos θ ≈ 1), both tending to e^{−θ²/α²}/(π α²).
    #[test]
    fn gaussian_matches_beckmann_for_small_roughness() {
        let a = 0.01f64;
        let g = mat(&format!(r#"{{"model": "torrance_sparrow", "distribution": "gaussian", "alpha": {a}}}"#));
        let b = mat(&format!(r#"{{"model": "torrance_sparrow", "alpha": {a}}}"#));
        for &t in &[0.0f64, 0.005, 0.01, 0.02] {
            let wi = spherical_direction(t.sin(), t.cos(), 0.0);
            let wo = spherical_direction(t.sin(), t.cos(), std::f64::consts::PI);
            let (fg, fb) = (g.eval(wi, wo).r, b.eval(wi, wo).r);
            assert!((fg / fb - 1.0).abs() < 1e-3, "θ={t}: {fg} vs {fb}");
        }
    }

    /// Normal incidence: f(n, n) = R F0 D(n)/4 + ρd/π with D(n) = 1/(π α²) (Beckmann).
    #[test]
    fn normal_incidence_value() {
        let m = mat(r#"{"model": "torrance_sparrow", "alpha": 0.3, "specular": 0.6, "diffuse": 0.2}"#);
        let z = Vec3::new(0.0, 0.0, 1.0);
        let want = 0.6 * 0.04 / (4.0 * std::f64::consts::PI * 0.09) + 0.2 / std::f64::consts::PI;
        assert!((m.eval(z, z).r - want).abs() < 1e-14);
    }

    /// Roughness → 0: a mirror of albedo F(θo) (Fresnel from the textbook amplitudes).
    #[test]
    fn smooth_limit_is_a_fresnel_mirror() {
        let m = mat(r#"{"model": "torrance_sparrow", "alpha": 0.001}"#);
        for &c in &[1.0f64, 0.5] {
            let sin_t = (1.0 - c * c).sqrt() / 1.5;
            let ct = (1.0 - sin_t * sin_t).sqrt();
            let rs = (c - 1.5 * ct) / (c + 1.5 * ct);
            let rp = (1.5 * c - ct) / (1.5 * c + ct);
            let want = 0.5 * (rs * rs + rp * rp);
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.0);
            let (a, _) = albedo(&m, wo, 20_000, &mut Pcg32::new(6, 6));
            assert!((a[0] - want).abs() < 0.02 * want, "{c}: {} vs {want}", a[0]);
        }
    }

    #[test]
    fn rejects_smith_with_the_gaussian_and_too_much_energy() {
        let e = Material::from_json(
            r#"{"model": "torrance_sparrow", "distribution": "gaussian", "masking": "smith_separable"}"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("masking"), "{e}");
        let e = Material::from_json(r#"{"model": "torrance_sparrow", "diffuse": 0.5}"#).unwrap_err();
        assert!(e.to_string().contains("diffuse"), "{e}");
    }

    #[test]
    fn passes_its_claims() {
        let report = check_model(&INFO, &CheckConfig::quick());
        assert!(report.passed, "{:?}", report.summary);
    }
}
