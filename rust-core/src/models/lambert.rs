//! Lambert: ideal diffuse reflection, `f = ρ/π`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `albedo` | colour | 0.5 | [0, 1] | hemispherical reflectance ρ |
//!
//! Sampling: cosine-weighted hemisphere, so the weight is exactly ρ.
//! Reference: J. H. Lambert, *Photometria*, 1760.

use crate::bxdf::{Claims, LaneBxdf, LaneSample, ModelInfo};
use crate::lanes::{self, Lanes, Mask};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
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

impl LaneBxdf for Lambert {
    const SMALL: bool = true;
    #[inline(always)]
    fn eval_lanes<L: Lanes>(&self, _wi: Vec3<L>, _wo: Vec3<L>) -> Rgb<L> {
        Rgb::from_array(self.albedo) * L::c(std::f64::consts::FRAC_1_PI)
    }

    #[inline(always)]
    fn pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, _wo: Vec3<L>) -> L {
        cosine_hemisphere_pdf(wi.z)
    }

    #[inline(always)]
    fn sample_lanes<L: Lanes>(&self, _wo: Vec3<L>, u: [L; 3]) -> LaneSample<L> {
        let wi = cosine_hemisphere(u[1], u[2]);
        let pdf = cosine_hemisphere_pdf(wi.z);
        LaneSample {
            wi,
            weight: Rgb::from_array(self.albedo),
            pdf,
            valid: lanes::gt(pdf, L::c(0.0)),
            delta: L::Mask::splat(false),
        }
    }
}

crate::bxdf_from_lanes!(Lambert);
