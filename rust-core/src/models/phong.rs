//! Phong (1975), the original form as the lecture slides give it: a Lambertian term plus a
//! normalised cosine lobe around the mirror direction, **divided by `cos θi`**,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · (n+2)/(2π) · cosⁿα / cos θi,     cos α = max(0, wi · mirror(wo))
//! ```
//!
//! (`mirror(wo) = (−wo.x, −wo.y, wo.z)`.) Phong defined the *reflected intensity*
//! `ks cosⁿα`; read as a BRDF that is the lobe over `cos θi`. The `(n+2)/(2π)` factor
//! normalises the lobe `cosⁿα · cos θi` of the *modified* model, not this one.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular coefficient ks |
//! | `exponent` | scalar | 30 | [0, 10⁴] | Phong exponent n (shininess) |
//!
//! Physics: **not reciprocal** (the `1/cos θi` is not symmetric) and **not energy
//! conserving**: the specular albedo is `ks (n+2)/(2π) ∫ cosⁿα dωi`, i.e. `ks (n+2)/(n+1)`
//! for a lobe wholly above the horizon — above `ks` — and no constraint on kd + ks would bound
//! it by one. `lacquer check` reports both measured figures. `cos θi` is clamped below at
//! 10⁻³⁰ so that f stays finite (in f32 too) at the horizon.
//!
//! Sampling: with probability k̄d/(k̄d + k̄s) (channel means) a cosine-weighted direction,
//! otherwise a power-cosine lobe `(n+1)/(2π) cosⁿα` around the mirror direction (Lafortune &
//! Willems 1994); the pdf is the mixture. Since `f cos θi` is then exactly a power-cosine
//! lobe, the specular weight is the constant `ks (n+2)/(n+1)` divided by its selection
//! probability. Directions below the horizon are failed samples.
//!
//! This module also holds what the reflection-vector Phong family shares (parameters, the
//! lobe, the sampler): [`super::modified_phong`] and [`super::neumann_stretch_phong`] differ
//! only in the factor after the lobe.
//!
//! References: B. T. Phong, "Illumination for computer generated pictures", CACM 18(6), 1975;
//! E. P. Lafortune, Y. D. Willems, "Using the modified Phong reflectance model for physically
//! based rendering", KU Leuven CW 197, 1994 (the normalisation and the sampler).

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::{mirror_z, versine_between};
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use std::marker::PhantomData;
use crate::sampling::{
    cos_pow_versine, cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe, power_cosine_around,
    power_cosine_pdf_versine,
};

/// The largest exponent of the family: the hard-case grid tries it.
pub(crate) const MAX_EXPONENT: f64 = 1e4;

/// Parameters of `phong` and `modified_phong`.
pub(crate) const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance kd"),
    ParamSpec::color("specular", [0.3; 3], 0.0, 1.0, "specular coefficient ks"),
    ParamSpec::scalar("exponent", 30.0, 0.0, MAX_EXPONENT, "", "Phong exponent n (shininess)"),
];

/// Parameter sets the checks run for the Phong family besides the defaults: rough, coloured
/// and fairly sharp. (Sharper lobes, up to n = 10⁴, are covered by the hard cases.)
pub(crate) const CHECK_PARAMS: &[&str] = &[
    r#"{"diffuse": 0.0, "specular": 1.0, "exponent": 2.0}"#,
    r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.3, 0.5, 0.8], "exponent": 200.0}"#,
    r#"{"diffuse": 0.9, "specular": 0.1, "exponent": 0.5}"#,
];

shared_lobe_model! {
    /// The original (non-reciprocal) Phong BRDF.
    pub struct Phong as Phong {
        /// Parameters and sampler.
        lobe: MirrorLobe
    }
    info: {
        name: "phong",
        summary: "Original Phong 1975: kd/π + ks (n+2)/(2π) cosⁿα / cosθi (not reciprocal, not energy conserving)",
        reference: "B. T. Phong, Illumination for computer generated pictures, CACM 18(6) 1975; \
                    E. P. Lafortune, Y. D. Willems, Using the modified Phong reflectance model for \
                    physically based rendering, KU Leuven CW 197 (1994)",
        params: PARAMS,
        claims: Claims { reciprocal: false, energy_conserving: false, sampled: true },
        check_params: CHECK_PARAMS,
    }
    build: |p| MirrorLobe::from_params(p);
    eval: |_this, l, wi, wo| l.diffuse_value() + l.normalised_lobe(wi, wo) / wi.z.max(cos_floor());
    sampling: lobe_sampling!(lobe);
}

/// Rejects `diffuse + specular > 1` in any channel (with a little slack for rounding), naming
/// the parameter `specular`. Shared by the energy-conserving members of the Phong families.
pub(crate) fn check_sum_at_most_one(diffuse: [f64; 3], specular: [f64; 3], what: &str) -> Result<(), Error> {
    for c in 0..3 {
        if diffuse[c] + specular[c] > 1.0 + 1e-9 {
            return Err(Error::Invalid {
                param: "specular".into(),
                reason: format!(
                    "diffuse + specular must not exceed 1 in any channel, {what} \
                     (channel {c}: {} + {} = {})",
                    diffuse[c],
                    specular[c],
                    diffuse[c] + specular[c]
                ),
            });
        }
    }
    Ok(())
}

/// Channel mean of a colour.
#[inline]
pub(crate) fn mean(c: [f64; 3]) -> f64 {
    (c[0] + c[1] + c[2]) / 3.0
}

/// Selection probabilities `[diffuse, specular]` from two non-negative weights, or an even
/// split when both vanish (so sampling stays defined for a black material).
#[inline]
pub(crate) fn two_lobe_weights<T: Real>(d: f64, s: f64) -> [T; 2] {
    if d + s > 0.0 {
        [T::of(d / (d + s)), T::of(s / (d + s))]
    } else {
        [T::of(0.5), T::of(0.5)]
    }
}

/// A Phong-family lobe over a Lambertian term: the parameters kd, ks, n, what both lobe shapes
/// compute from them, and (per shape, see [`MirrorLobe`] and
/// [`super::blinn_phong::HalfLobe`]) the lobe and its sampler.
#[derive(Clone, Debug)]
pub struct PhongLobe<S> {
    /// Diffuse reflectance kd per channel.
    pub diffuse: [f64; 3],
    /// Specular coefficient ks per channel.
    pub specular: [f64; 3],
    /// Phong (or Blinn) exponent n.
    pub exponent: f64,
    shape: PhantomData<S>,
}

/// The lobe around the mirror direction (Phong's `cosⁿα`).
#[derive(Clone, Copy, Debug)]
pub struct Mirror;

/// A reflection-vector Phong lobe over a Lambertian term.
pub type MirrorLobe = PhongLobe<Mirror>;

impl<S> PhongLobe<S> {
    /// Reads the family's parameters (no cross-checks).
    pub(crate) fn from_params(p: &Params) -> Self {
        Self {
            diffuse: p.color("diffuse"),
            specular: p.color("specular"),
            exponent: p.scalar("exponent"),
            shape: PhantomData,
        }
    }

    /// [`PhongLobe::from_params`] with kd + ks ≤ 1 enforced ([`check_sum_at_most_one`]): the
    /// energy-conserving members.
    pub(crate) fn bounded_from_params(p: &Params) -> Result<Self, Error> {
        let lobe = Self::from_params(p);
        check_sum_at_most_one(lobe.diffuse, lobe.specular, "so that the albedo stays at most 1")?;
        Ok(lobe)
    }

    /// `kd/π`.
    #[inline]
    pub(crate) fn diffuse_value<T: Real>(&self) -> Rgb<T> {
        Rgb::from_array(self.diffuse) * T::inv_pi()
    }

    /// Selection probabilities `[diffuse, specular]` of the samplers: the channel means.
    #[inline]
    pub(crate) fn lobe_weights<T: Real>(&self) -> [T; 2] {
        two_lobe_weights(mean(self.diffuse), mean(self.specular))
    }
}

impl MirrorLobe {
    /// `ks (n+2)/(2π) cosⁿα`: the modified-Phong specular value.
    #[inline]
    pub(crate) fn normalised_lobe<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let n = T::of(self.exponent);
        let lobe = cos_pow_versine(versine_between(wi, mirror_z(wo)), n);
        Rgb::from_array(self.specular) * ((n + T::of(2.0)) * T::inv_pi() * T::of(0.5) * lobe)
    }

    /// The mixture density `P_d cos θi/π + P_s (n+1)/(2π) cosⁿα`.
    #[inline]
    pub(crate) fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let [pd, ps] = self.lobe_weights::<T>();
        let spec = power_cosine_pdf_versine(T::of(self.exponent), versine_between(wi, mirror_z(wo)));
        pd * cosine_hemisphere_pdf(wi.z) + ps * spec
    }

    /// Draws `wi`: `u[0]` picks the lobe, `u[1]`, `u[2]` the direction; `None` below the horizon.
    #[inline]
    pub(crate) fn sample_direction<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<Vec3<T>> {
        let (lobe, _) = pick_lobe(&self.lobe_weights::<T>(), u[0])?;
        let wi = if lobe == 0 {
            cosine_hemisphere(u[1], u[2])
        } else {
            power_cosine_around(mirror_z(wo), T::of(self.exponent), u[1], u[2])
        };
        (wi.z > T::zero() && wi.is_finite()).then_some(wi)
    }
}

/// Smallest `cos θ` a `1/cos θ` factor of the family divides by: keeps f finite in f32.
#[inline]
pub(crate) fn cos_floor<T: Real>() -> T {
    T::of(1e-30)
}

/// Neumann et al.'s "stretch" `max(cos θi, cos θo)` (floored at [`cos_floor`]), which the
/// stretched variants divide their specular lobe by.
#[inline]
pub(crate) fn stretch<T: Real>(wi: Vec3<T>, wo: Vec3<T>) -> T {
    wi.z.max(wo.z).max(cos_floor())
}

#[cfg(test)]
pub(crate) mod testing {
    use crate::material::Material;
    use crate::math::Vec3;

    /// Directional albedo `∫ f(wi, wo) cos θi dωi` by quadrature in polar coordinates around a
    /// unit `axis` (where the lobe peaks): `wi = (sin γ cos ψ) s + (sin γ sin ψ) t + cos γ axis`,
    /// with `cos γ = 1 − v` and `v` warped as `v = 2 w^k` so that sharp lobes are resolved.
    pub fn albedo_around(m: &Material, wo: Vec3<f64>, axis: Vec3<f64>) -> [f64; 3] {
        let (s, t) = crate::frame::basis_around(axis);
        let (nw, npsi, k) = (4000, 720, 4.0);
        let dpsi = 2.0 * std::f64::consts::PI / npsi as f64;
        let mut sum = [0.0; 3];
        for i in 0..nw {
            let w = (i as f64 + 0.5) / nw as f64;
            let v = 2.0 * w.powf(k);
            let dv = 2.0 * k * w.powf(k - 1.0) / nw as f64;
            let c = 1.0 - v;
            let sg = (1.0 - c * c).max(0.0).sqrt();
            for j in 0..npsi {
                let psi = (j as f64 + 0.5) * dpsi;
                let wi = s * (sg * psi.cos()) + t * (sg * psi.sin()) + axis * c;
                if wi.z <= 0.0 {
                    continue;
                }
                let f = m.eval(wi, wo);
                for (acc, fc) in sum.iter_mut().zip([f.r, f.g, f.b]) {
                    *acc += fc * wi.z * dv * dpsi;
                }
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::testing::albedo_around;
    use super::*;
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use std::f64::consts::PI;

    fn phong(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "phong", {json}}}"#)).unwrap()
    }

    /// The slides' formula, written out from the angle α.
    #[test]
    fn value_is_the_slides_formula() {
        let m = phong(r#""diffuse": 0.2, "specular": 0.7, "exponent": 12"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.4);
        let wi = spherical_direction(0.5f64, 0.75f64.sqrt(), 3.3);
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        let alpha = wi.dot(r).acos();
        let expect = 0.2 / PI + 0.7 * 14.0 / (2.0 * PI) * alpha.cos().powi(12) / wi.z;
        let f = m.eval(wi, wo).g;
        assert!((f - expect).abs() < 1e-13 * expect, "{f} vs {expect}");
    }

    /// Specular albedo of a lobe wholly above the horizon: `ks (n+2)/(2π) · 2π/(n+1)`
    /// = `ks (n+2)/(n+1)`, whatever wo — more than ks: not energy conserving.
    #[test]
    fn specular_albedo_is_ks_n_plus_2_over_n_plus_1() {
        let m = phong(r#""diffuse": 0.0, "specular": 1.0, "exponent": 400"#);
        for c in [1.0f64, 0.8, 0.5] {
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.7);
            let a = albedo_around(&m, wo, mirror_z(wo))[0];
            assert!((a - 402.0 / 401.0).abs() < 1e-4, "cos θo = {c}: {a}");
        }
        // At n = 1 the excess is 3/2.
        let m = phong(r#""diffuse": 0.0, "specular": 1.0, "exponent": 1"#);
        let z = Vec3::new(0.0, 0.0, 1.0);
        assert!((albedo_around(&m, z, z)[0] - 1.5).abs() < 1e-4);
    }

    /// Not reciprocal: swapping the directions scales the lobe by cos θi / cos θo.
    #[test]
    fn swapping_directions_scales_by_cosine_ratio() {
        let m = phong(r#""diffuse": 0.0, "specular": 0.5, "exponent": 8"#);
        let wo = spherical_direction(0.6f64, 0.8, 0.0);
        let wi = spherical_direction(0.8f64, 0.6, 3.0);
        let (a, b) = (m.eval(wi, wo).r, m.eval(wo, wi).r);
        assert!((a / b - wo.z / wi.z).abs() < 1e-12, "{a} {b}");
    }

    /// Finite at the horizon and for n = 10⁴ in f32 (the clamp and the versine form).
    #[test]
    fn finite_at_horizon_and_max_exponent() {
        let m = phong(r#""exponent": 10000"#);
        let wo = spherical_direction(1.0f32, 1e-7, 0.0);
        let wi = spherical_direction(1.0f32, 1e-7, std::f32::consts::PI);
        let f = m.eval(wi, wo);
        assert!(f.is_finite() && f.r > 0.0, "{f:?}");
        let p: f32 = m.pdf(wi, wo);
        assert!(p.is_finite() && p > 0.0);
    }
}
