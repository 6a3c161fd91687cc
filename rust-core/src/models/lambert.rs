//! Lambert: ideal diffuse reflection, `f = ρ/π`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `albedo` | colour | 0.5 | [0, 1] | hemispherical reflectance ρ |
//!
//! Sampling: cosine-weighted hemisphere, so the weight is exactly ρ.
//! Reference: J. H. Lambert, *Photometria*, 1760.

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

const PARAMS: &[ParamSpec] = &[ParamSpec::color("albedo", [0.5; 3], 0.0, 1.0, "hemispherical reflectance ρ")];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "lambert",
    summary: "Ideal diffuse reflection f = ρ/π",
    reference: "J. H. Lambert, Photometria (1760)",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: &[r#"{"albedo": 1.0}"#, r#"{"albedo": [0.9, 0.2, 0.05]}"#],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    Ok(Model::Lambert(Lambert { albedo: p.color("albedo") }))
}

/// Ideal diffuse BRDF.
#[derive(Clone, Debug)]
pub struct Lambert {
    /// Hemispherical reflectance per channel.
    pub albedo: [f64; 3],
}

impl Bxdf for Lambert {
    #[inline]
    fn eval<T: Real>(&self, _wi: Vec3<T>, _wo: Vec3<T>) -> Rgb<T> {
        Rgb::from_array(self.albedo) * T::inv_pi()
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, _wo: Vec3<T>) -> T {
        cosine_hemisphere_pdf(wi.z)
    }

    #[inline]
    fn sample<T: Real>(&self, _wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wi = cosine_hemisphere(u[1], u[2]);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (pdf > T::zero()).then(|| BsdfSample { wi, weight: Rgb::from_array(self.albedo), pdf, delta: false })
    }
}
