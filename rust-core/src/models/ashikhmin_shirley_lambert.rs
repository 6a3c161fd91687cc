//! The Ashikhmin-Shirley specular lobe over a plain Lambertian term, the variant the thesis
//! the project started from fits to measured paint (it keeps the diffuse term Lambertian for
//! every model it compares):
//!
//! ```text
//! f(k1, k2) = kd/π + √((nu+1)(nv+1))/(8π) · (n·h)^{nu cos²φh + nv sin²φh} / ((h·k) max(n·k1, n·k2)) · F(h·k)
//! F(c) = Rs + (1 − Rs)(1 − c)⁵
//! ```
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | Lambertian reflectance kd |
//! | `specular` | colour | 0.05 | [0, 1] | specular reflectance at normal incidence Rs (Schlick's F0) |
//! | `nu` | scalar | 100 | [0, 10⁴] | Phong-like exponent along the tangent x |
//! | `nv` | scalar | 100 | [0, 10⁴] | Phong-like exponent along the bitangent y |
//!
//! Physics: reciprocal. **Not** energy conserving, and claimed so: the Lambertian term does
//! not give way to the Fresnel-weighted specular term, so the albedo reaches
//! `kd + ∫ p_h F cos θi/max dωh`, and at grazing `wo` the Fresnel factor drives the specular
//! albedo toward 1 (for a sharp lobe it tends to `F(cos θo)`): kd + that exceeds 1 for any
//! kd > 0 near grazing, whatever Rs. The coupled diffuse term of the paper
//! ([`super::ashikhmin_shirley`]) exists to prevent exactly this. `lacquer check` reports the
//! measured maximum; no constraint is imposed (the thesis fits kd and Rs freely).
//!
//! Sampling: the paper's half-vector sampler for the specular lobe and a cosine-weighted
//! direction for the Lambertian term, chosen in proportion to k̄d and the Schlick reflectance
//! at `wo` (see [`super::ashikhmin_shirley`]).
//!
//! References: M. Ashikhmin, P. Shirley, "An anisotropic Phong BRDF model", Journal of Graphics
//! Tools 5(2), 2000; the Lambertian pairing as used in the source thesis ("Microstructure-based
//! Modeling of Coated Surfaces", fitting chapter).

use super::ashikhmin_shirley::{params, AsLobe, CHECK_PARAMS};
use super::phong::mean;
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;

const PARAMS: &[ParamSpec] = &params("Lambertian reflectance kd");

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "ashikhmin_shirley_lambert",
    summary: "Ashikhmin & Shirley 2000 anisotropic specular lobe + plain Lambert (the thesis's variant)",
    reference: "M. Ashikhmin, P. Shirley, An anisotropic Phong BRDF model, Journal of Graphics Tools 5(2) 2000",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
    check_params: CHECK_PARAMS,
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    Ok(Model::AshikhminShirleyLambert(AshikhminShirleyLambert { lobe: AsLobe::from_params(p) }))
}

/// The Ashikhmin-Shirley specular lobe over a Lambertian term.
#[derive(Clone, Debug)]
pub struct AshikhminShirleyLambert {
    /// Parameters and sampler (`diffuse` is kd).
    pub lobe: AsLobe,
}

impl AshikhminShirleyLambert {
    #[inline]
    fn weights<T: Real>(&self, wo: Vec3<T>) -> [T; 2] {
        self.lobe.lobe_weights(mean(self.lobe.diffuse), wo)
    }
}

impl Bxdf for AshikhminShirleyLambert {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        Rgb::from_array(self.lobe.diffuse) * T::inv_pi() + self.lobe.specular_value(wi, wo)
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.lobe.pdf(self.weights(wo), wi, wo)
    }

    #[inline]
    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wi = self.lobe.sample_direction(self.weights(wo), wo, u)?;
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::super::ashikhmin_shirley::testing::normal_incidence_specular_albedo;
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::{mirror_z, spherical_direction};
    use crate::material::Material;
    use std::f64::consts::PI;

    fn asl(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "ashikhmin_shirley_lambert", {json}}}"#)).unwrap()
    }

    /// The same specular lobe as the coupled model, with kd/π instead of the coupled term.
    #[test]
    fn specular_lobe_matches_coupled_model() {
        let a = asl(r#""diffuse": 0.3, "specular": 0.4, "nu": 50, "nv": 7"#);
        let b = Material::from_json(
            r#"{"model": "ashikhmin_shirley", "diffuse": 0.0, "specular": 0.4, "nu": 50, "nv": 7}"#,
        )
        .unwrap();
        let d = |c: f64, p: f64| spherical_direction((1.0 - c * c).sqrt(), c, p);
        for (wi, wo) in [(d(0.7, 0.3), d(0.8, 3.5)), (d(0.2, 1.0), d(0.9, 4.1))] {
            let expect = 0.3 / PI + b.eval(wi, wo).r;
            assert!((a.eval(wi, wo).r - expect).abs() < 1e-14 * expect);
        }
    }

    /// At normal incidence with Rs = 1 the albedo is kd + the closed-form specular albedo.
    #[test]
    fn normal_incidence_albedo_is_kd_plus_specular() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        let m = asl(r#""diffuse": 0.4, "specular": 1.0, "nu": 30, "nv": 30"#);
        let golden = 0.4 + normal_incidence_specular_albedo(30.0);
        assert!((albedo_around(&m, z, z)[0] - golden).abs() < 2e-4);
    }

    /// Not energy conserving: near grazing the Fresnel factor makes the specular albedo large
    /// even for Rs = 0.04 (F(0.02) ≈ 0.91 before the horizon's cut), so kd = 0.5 pushes the
    /// total above 1.
    #[test]
    fn grazing_albedo_exceeds_one() {
        let m = asl(r#""diffuse": 0.5, "specular": 0.04, "nu": 5000, "nv": 5000"#);
        let c: f64 = 0.02;
        let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.0);
        let a = albedo_around(&m, wo, mirror_z(wo))[0];
        assert!(a > 1.03, "{a}");
    }
}
