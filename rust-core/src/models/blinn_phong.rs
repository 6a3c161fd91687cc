//! Blinn-Phong (Blinn 1977) with the usual BRDF normalisation: a Lambertian term plus a power of
//! the cosine of the half vector,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · (n+8)/(8π) · cosⁿθh,     h = (wi + wo)/|wi + wo|
//! ```
//!
//! (The source slides write `h = (l + v)/2` — it must be normalised — and `(n+2)/(2π)`, which
//! normalises the half-vector *distribution* `∫ cosⁿθh cos θh dωh`, not the BRDF: as a BRDF that
//! factor gives an albedo of about 4 ks for sharp lobes.) `(n+8)/(8π)` is the approximate BRDF
//! normalisation derived in Akenine-Möller & Haines, *Real-Time Rendering* (2nd ed. 2002, §6.7);
//! it is exact for n = 0 (then `f = (kd + ks)/π`).
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular coefficient ks |
//! | `exponent` | scalar | 100 | [0, 10⁴] | Blinn exponent n on `cos θh` (about 4× a Phong exponent for the same highlight) |
//!
//! Physics: reciprocal (h is symmetric). **Not** energy conserving, and claimed so: at normal
//! incidence (`θi = 2θh`, `dωi = 4 cos θh dωh`) the specular albedo is, in closed form,
//!
//! ```text
//! ks (n+8) [2/(n+4) − 1/(n+2) − 2^{−n/2}/(2(n+4)) + 2^{−n/2}/(2(n+2))]
//! ```
//!
//! which exceeds ks for every n > 0 — by up to 7.5 % (1.0748 ks at n = 10, 1.018 ks at n = 100);
//! in quadrature scans (n from 0 to 100) it is also the largest albedo over `wo`, which falls
//! toward grazing. `lacquer check` reports the measured figure; no constraint on kd + ks is
//! imposed.
//!
//! Sampling: with probability k̄s/(k̄d + k̄s) (channel means) the half vector is drawn from
//! `(n+1)/(2π) cosⁿθh` around the normal and `wi` is `wo` mirrored about it (solid-angle
//! density `(n+1)/(2π) cosⁿθh / (4 wo·h)`); otherwise a cosine-weighted direction. The pdf is
//! the mixture; mirrored directions below the horizon are failed samples.
//!
//! This module also holds the half-vector lobe shared with
//! [`super::neumann_stretch_blinn_phong`].
//!
//! References: J. F. Blinn, "Models of light reflection for computer synthesized pictures",
//! SIGGRAPH 1977; T. Akenine-Möller, E. Haines, *Real-Time Rendering*, 2nd ed., 2002 (the
//! (n+8)/(8π) normalisation).

use super::phong::{PhongLobe, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::{reflect, versine_z};
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{
    cos_pow_versine, cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe, power_cosine_around,
    power_cosine_pdf_versine,
};

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance kd"),
    ParamSpec::color("specular", [0.3; 3], 0.0, 1.0, "specular coefficient ks"),
    ParamSpec::scalar(
        "exponent",
        100.0,
        0.0,
        MAX_EXPONENT,
        "",
        "Blinn exponent n on cos θh (about 4× a Phong exponent for the same highlight)",
    ),
];

shared_lobe_model! {
    /// The normalised Blinn-Phong BRDF.
    pub struct BlinnPhong as BlinnPhong {
        /// Parameters and sampler.
        lobe: HalfLobe
    }
    info: {
        name: "blinn_phong",
        summary: "Blinn-Phong 1977 with the (n+8)/(8π) normalisation: kd/π + ks (n+8)/(8π) cosⁿθh",
        reference: "J. F. Blinn, Models of light reflection for computer synthesized pictures, SIGGRAPH 1977; \
                    T. Akenine-Möller, E. Haines, Real-Time Rendering 2nd ed. (2002)",
        params: PARAMS,
        claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
        check_params: &[
            r#"{"diffuse": 0.0, "specular": 1.0, "exponent": 10.0}"#,
            r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.3, 0.5, 0.8], "exponent": 1000.0}"#,
            r#"{"diffuse": 0.2, "specular": 0.8, "exponent": 1.0}"#,
        ],
    }
    build: |p| HalfLobe::from_params(p);
    eval: |_this, l, wi, wo| {
        let norm = (T::of(l.exponent) + T::of(8.0)) * T::inv_pi() / T::of(8.0);
        l.diffuse_value() + l.specular_power(wi, wo) * norm
    };
    sampling: lobe_sampling!(lobe);
}

/// The lobe around the normal in the half vector (Blinn's `cosⁿθh`).
#[derive(Clone, Copy, Debug)]
pub struct Half;

/// A half-vector (Blinn) lobe over a Lambertian term.
pub type HalfLobe = PhongLobe<Half>;

/// Smallest `|wi + wo|` the Jacobian `1/(4 wo·h) = 1/(2|wi + wo|)` divides by.
#[inline]
fn sum_floor<T: Real>() -> T {
    T::of(1e-30)
}

impl HalfLobe {
    /// `ks cosⁿθh` (zero when the half vector is undefined).
    #[inline]
    pub(crate) fn specular_power<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let lobe = cos_pow_versine(versine_z(wi + wo), T::of(self.exponent));
        Rgb::from_array(self.specular) * lobe
    }

    /// The mixture density `P_d cos θi/π + P_s (n+1)/(2π) cosⁿθh / (4 wo·h)`, with
    /// `4 wo·h = 2 |wi + wo|` for unit directions.
    #[inline]
    pub(crate) fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let [pd, ps] = self.lobe_weights::<T>();
        let s = wi + wo;
        let len = s.length();
        let mut p = pd * cosine_hemisphere_pdf(wi.z);
        if len > T::zero() && s.z > T::zero() {
            let ph = power_cosine_pdf_versine(T::of(self.exponent), versine_z(s));
            p += ps * ph / (T::of(2.0) * len.max(sum_floor()));
        }
        p
    }

    /// Draws `wi`: `u[0]` picks the lobe, `u[1]`, `u[2]` the direction (or the half vector);
    /// `None` below the horizon.
    #[inline]
    pub(crate) fn sample_direction<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<Vec3<T>> {
        let (lobe, _) = pick_lobe(&self.lobe_weights::<T>(), u[0])?;
        let wi = if lobe == 0 {
            cosine_hemisphere(u[1], u[2])
        } else {
            let z = Vec3::new(T::zero(), T::zero(), T::one());
            reflect(wo, power_cosine_around(z, T::of(self.exponent), u[1], u[2]))
        };
        (wi.z > T::zero() && wi.is_finite()).then_some(wi)
    }
}

/// Golden values shared with the stretched variant's tests.
#[cfg(test)]
pub(crate) mod testing {
    /// `∫ cosⁿθh cos θi dωi` at normal incidence, by hand: with `θi = 2θh`,
    /// `dωi = 4 cos θh dωh` and `cos θi = 2c² − 1` (`c = cos θh ≥ 1/√2` above the horizon),
    /// `8π ∫ (2c^{n+3} − c^{n+1}) dc = 8π [2/(n+4) − 1/(n+2) − 2^{−n/2}/(2(n+4)) + 2^{−n/2}/(2(n+2))]`.
    pub fn normal_incidence_integral(n: f64) -> f64 {
        let q = 2f64.powf(-n / 2.0);
        8.0 * std::f64::consts::PI * (2.0 / (n + 4.0) - 1.0 / (n + 2.0) - q / (2.0 * (n + 4.0)) + q / (2.0 * (n + 2.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::testing::normal_incidence_integral;
    use super::*;
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use std::f64::consts::PI;

    fn blinn(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "blinn_phong", {json}}}"#)).unwrap()
    }

    /// n = 0: the value is the constant `(kd + ks)/π` everywhere, so the albedo is kd + ks.
    #[test]
    fn exponent_zero_is_constant() {
        let m = blinn(r#""diffuse": 0.2, "specular": 0.7, "exponent": 0"#);
        for (wi, wo) in [
            (spherical_direction(0.6f64, 0.8, 0.4), spherical_direction(0.9f64, 0.19f64.sqrt(), 2.0)),
            (spherical_direction(1.0f64, 1e-6, 0.0), spherical_direction(1.0f64, 1e-6, PI)),
        ] {
            assert!((m.eval(wi.normalize(), wo.normalize()).r - 0.9 / PI).abs() < 1e-15);
        }
    }

    /// The value from the normalised half vector (not (wi+wo)/2).
    #[test]
    fn value_uses_normalised_half_vector() {
        let m = blinn(r#""diffuse": 0.0, "specular": 0.5, "exponent": 40"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.4);
        let wi = spherical_direction(0.7f64, 0.51f64.sqrt(), 3.0);
        let h = (wi + wo) / (wi + wo).length();
        let expect = 0.5 * 48.0 / (8.0 * PI) * h.z.powi(40);
        assert!((m.eval(wi, wo).r - expect).abs() < 1e-13 * expect);
    }

    /// Normal-incidence albedo against the closed form; above ks for n > 0 (1.0748 at n = 10).
    #[test]
    fn normal_incidence_albedo_matches_closed_form_and_exceeds_ks() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for n in [1.0, 10.0, 100.0, 2000.0] {
            let m = blinn(&format!(r#""diffuse": 0.0, "specular": 1.0, "exponent": {n}"#));
            let golden = (n + 8.0) / (8.0 * PI) * normal_incidence_integral(n);
            let a = albedo_around(&m, z, z)[0];
            assert!((a - golden).abs() < 2e-4, "n = {n}: {a} vs {golden}");
            assert!(golden > 1.0, "n = {n}: {golden}");
        }
        let g10 = 18.0 / (8.0 * PI) * normal_incidence_integral(10.0);
        assert!((g10 - 1.0748).abs() < 1e-4, "{g10}");
    }

    /// The sampler's half-vector density `(n+1)/(2π) cosⁿθh` becomes `/(4 wo·h)` in wi.
    #[test]
    fn sample_density_is_half_vector_density_over_jacobian() {
        let m = blinn(r#""diffuse": 0.0, "specular": 1.0, "exponent": 30"#);
        let wo = spherical_direction(0.5f64, 0.75f64.sqrt(), 0.3);
        for u in [[0.5, 0.2, 0.7], [0.5, 0.9, 0.1], [0.5, 0.6, 0.5]] {
            let s = m.sample(wo, u).unwrap();
            let h = (s.wi + wo).normalize();
            let expect = 31.0 / (2.0 * PI) * h.z.powi(30) / (4.0 * wo.dot(h));
            assert!((s.pdf - expect).abs() < 1e-10 * expect, "{} vs {expect}", s.pdf);
            // cos θh = u^(1/(n+1)).
            assert!((h.z - u[1].powf(1.0 / 31.0)).abs() < 1e-12);
        }
    }
}
