//! Cook-Torrance (1981) exactly as published: a Lambertian diffuse term plus a specular
//! microfacet term with the *un-normalised* Beckmann distribution and the V-groove
//! masking-shadowing, divided by `π (n·l)(n·v)`:
//!
//! ```text
//! f = kd · ρd/π + ks · F(v·h) · D(h) · G / (π (n·l)(n·v))
//! D = exp(−tan²α / m²) / (m² cos⁴α)                (α the angle between h and n; no 1/π)
//! G = min(1, 2(n·h)(n·v)/(v·h), 2(n·h)(n·l)/(v·h))
//! ```
//!
//! `F` is the exact Fresnel reflectance of the (complex) index `η + i·k` (the paper writes the
//! dielectric form with `g² = η² + c² − 1`; with `k = 0` the two coincide). The paper also
//! allows a weighted sum of several slopes `m_j`; this model uses one.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `kd` | scalar | 0.5 | [0, 1] | diffuse weight `d` (the paper has `d + s = 1`) |
//! | `albedo` | colour | 0.5 | [0, 1] | diffuse reflectance ρd |
//! | `ks` | scalar | 0.5 | [0, 1] | specular weight `s`; `kd + ks ≤ 1` is required |
//! | `roughness` | scalar | 0.3 | [0.001, 1] | RMS facet slope `m` |
//! | `eta` | colour | 1.5 | [0.01, 10] | real part of the relative index of refraction |
//! | `k` | colour | 0 | [0, 10] | extinction coefficient (0 for a dielectric) |
//!
//! This is the form the seeds README warns about: relative to the modern normalised form
//! (`cook_torrance`, `D/π` and `4 (n·l)(n·v)`) the specular term is exactly four times
//! brighter, so it is *not* energy conserving: `lacquer check` measures specular albedos far
//! above one (claim `false`, reported). It is reciprocal: `v·h = l·h` and `G` is symmetric.
//!
//! Sampling: Beckmann visible normals (`α = m`) reflected about `wo`, and the cosine lobe,
//! chosen with `u[0]` in proportion to `4·ks·F̄(cos θo)` (this form's specular albedo is about
//! four times the Fresnel reflectance) and `kd·ρ̄d`; the pdf is the mixture.
//!
//! Reference: R. L. Cook and K. E. Torrance, "A Reflectance Model for Computer Graphics",
//! Computer Graphics (SIGGRAPH '81) 15(3), 307-316, 1981.

use super::cook_torrance::check_kd_plus_ks;
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::fresnel::conductor_rgb;
use crate::frame::half_vector;
use crate::math::{Rgb, Vec3};
use crate::microfacet::{g_vgroove, DistributionKind, Microfacet};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::scalar("kd", 0.5, 0.0, 1.0, "", "diffuse weight d (kd + ks ≤ 1)"),
    ParamSpec::color("albedo", [0.5; 3], 0.0, 1.0, "diffuse reflectance ρd"),
    ParamSpec::scalar("ks", 0.5, 0.0, 1.0, "", "specular weight s (kd + ks ≤ 1)"),
    ParamSpec::scalar("roughness", 0.3, 0.001, 1.0, "", "RMS facet slope m (Beckmann)"),
    ParamSpec::color("eta", [1.5; 3], 0.01, 10.0, "real part of the relative IOR"),
    ParamSpec::color("k", [0.0; 3], 0.0, 10.0, "extinction coefficient (0: dielectric)"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "cook_torrance_1981",
    summary: "Cook-Torrance 1981 as published: un-normalised Beckmann D, V-groove G, /π(n·l)(n·v)",
    reference: "R. L. Cook, K. E. Torrance, A Reflectance Model for Computer Graphics, SIGGRAPH 1981",
    params: PARAMS,
    claims: Claims {
        reciprocal: true,
        energy_conserving: false,
        sampled: true,
    },
    check_params: &[
        r#"{"kd": 0.0, "ks": 1.0, "roughness": 0.5, "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]}"#,
        r#"{"kd": 0.7, "albedo": [0.8, 0.3, 0.1], "ks": 0.3, "roughness": 0.15}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    let (kd, ks) = (p.scalar("kd"), p.scalar("ks"));
    check_kd_plus_ks(kd, ks, " (the paper's d + s = 1)")?;
    Ok(Model::CookTorrance1981(CookTorrance1981 {
        kd,
        albedo: p.color("albedo"),
        ks,
        roughness: p.scalar("roughness"),
        eta: p.color("eta"),
        k: p.color("k"),
    }))
}

/// The 1981 Cook-Torrance BRDF.
#[derive(Clone, Debug)]
pub struct CookTorrance1981 {
    /// Diffuse weight.
    pub kd: f64,
    /// Diffuse reflectance per channel.
    pub albedo: [f64; 3],
    /// Specular weight.
    pub ks: f64,
    /// RMS facet slope `m`.
    pub roughness: f64,
    /// Real part of the IOR per channel.
    pub eta: [f64; 3],
    /// Extinction coefficient per channel.
    pub k: [f64; 3],
}

impl CookTorrance1981 {
    fn beckmann<T: Real>(&self) -> Microfacet<T> {
        let m = T::of(self.roughness);
        Microfacet::new(DistributionKind::Beckmann, m, m)
    }

    /// Selection probability of the specular lobe for this `wo`.
    fn specular_probability<T: Real>(&self, wo: Vec3<T>) -> T {
        let f = conductor_rgb(wo.z, Rgb::from_array(self.eta), Rgb::from_array(self.k));
        let ws = T::of(4.0 * self.ks) * f.average();
        let wd = T::of(self.kd) * Rgb::<T>::from_array(self.albedo).average();
        // Both weights zero: the BRDF is zero; the cosine lobe is sampled.
        if ws + wd > T::zero() {
            ws / (ws + wd)
        } else {
            T::zero()
        }
    }
}

impl Bxdf for CookTorrance1981 {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let diffuse = Rgb::from_array(self.albedo) * (T::of(self.kd) * T::inv_pi());
        let Some(h) = half_vector(wi, wo) else {
            return diffuse;
        };
        // The paper's D is the normalised Beckmann D times π; with the 1/π of the
        // denominator the two factors of π cancel.
        let d = self.beckmann::<T>().d(h);
        let g = g_vgroove(wi, wo, h);
        let f = conductor_rgb(wo.dot(h), Rgb::from_array(self.eta), Rgb::from_array(self.k));
        diffuse + f * (T::of(self.ks) * d * g / (wi.z * wo.z))
    }

    beckmann_mixture_sampling!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::cosine_hemisphere;
    use crate::check::{check_model, CheckConfig};
    use crate::frame::spherical_direction;
    use crate::rng::Pcg32;

    fn model(kd: f64, ks: f64, m: f64, eta: f64, k: f64) -> CookTorrance1981 {
        CookTorrance1981 {
            kd,
            albedo: [0.4, 0.5, 0.6],
            ks,
            roughness: m,
            eta: [eta; 3],
            k: [k; 3],
        }
    }

    /// At wi = wo = n: h = n, D = 1/m², G = 1, F = F0 = ((η−1)² + k²)/((η+1)² + k²), so
    /// f = kd ρd/π + ks F0/(π m²).
    #[test]
    fn normal_incidence_value() {
        let (kd, ks, m, eta, k) = (0.3, 0.7, 0.25, 0.2, 3.9);
        let f0 = ((eta - 1.0f64).powi(2) + k * k) / ((eta + 1.0f64).powi(2) + k * k);
        let z = Vec3::new(0.0, 0.0, 1.0);
        let f = model(kd, ks, m, eta, k).eval(z, z);
        let want = kd * 0.4 / std::f64::consts::PI + ks * f0 / (std::f64::consts::PI * m * m);
        assert!((f.r - want).abs() < 1e-12 * want, "{} vs {want}", f.r);
    }

    /// Hand-evaluated off-specular value with a dielectric: wi and wo at 40° on either side
    /// of the normal in one plane, so h = n, D = 1/m², v·h = cos 40°, and
    /// G = min(1, 2 cos 40°·... / cos 40°) = 1; F from the paper's dielectric formula.
    #[test]
    fn mirror_configuration_value() {
        let (m, eta) = (0.3f64, 1.5f64);
        let t = 40f64.to_radians();
        let wi = spherical_direction(t.sin(), t.cos(), 0.0);
        let wo = spherical_direction(t.sin(), t.cos(), std::f64::consts::PI);
        // Cook-Torrance's form: c = v·h, g² = η² + c² − 1.
        let c = t.cos();
        let g = (eta * eta + c * c - 1.0).sqrt();
        let fr = 0.5 * (g - c).powi(2) / (g + c).powi(2)
            * (1.0 + (c * (g + c) - 1.0).powi(2) / (c * (g - c) + 1.0).powi(2));
        let want = fr / (std::f64::consts::PI * m * m) / (c * c);
        let f = model(0.0, 1.0, m, eta, 0.0).eval(wi, wo);
        assert!((f.r - want).abs() < 1e-12 * want, "{} vs {want}", f.r);
    }

    /// The published specular term is exactly four times the modern normalised one
    /// (D/π and 4(n·l)(n·v)) with the same D shape, G and F.
    #[test]
    fn specular_term_is_four_times_the_normalised_form() {
        let m = model(0.0, 1.0, 0.35, 1.7, 0.5);
        let mf = Microfacet::new(DistributionKind::Beckmann, 0.35f64, 0.35);
        let mut rng = Pcg32::new(8, 1);
        for _ in 0..500 {
            let wi = cosine_hemisphere(rng.uniform(), rng.uniform());
            let wo = cosine_hemisphere(rng.uniform(), rng.uniform());
            let h = (wi + wo).normalize();
            let f = conductor_rgb(wo.dot(h), Rgb::splat(1.7), Rgb::splat(0.5));
            let modern = f.r * mf.d(h) * g_vgroove(wi, wo, h) / (4.0 * wi.z * wo.z);
            let got = m.eval(wi, wo).r;
            assert!((got - 4.0 * modern).abs() <= 1e-12 * got.max(1e-300));
        }
    }

    #[test]
    fn rejects_weights_above_one() {
        let e = crate::Material::from_json(r#"{"model": "cook_torrance_1981", "kd": 0.8, "ks": 0.5}"#)
            .unwrap_err();
        assert!(e.to_string().contains("ks"), "{e}");
    }

    #[test]
    fn passes_its_claims() {
        let report = check_model(&INFO, &CheckConfig::quick());
        assert!(report.passed, "{:?}", report.summary);
    }
}
