//! Fast Phong (Bishop & Weimer 1986): the modified Phong BRDF with the power `cosⁿα` read from a
//! table and linearly interpolated instead of computed,
//!
//! ```text
//! f(wi, wo) = kd/π + ks · N_L · L(cos α),     cos α = max(0, wi · mirror(wo))
//! ```
//!
//! `L` is the linear interpolation of `c_k = (k/(m−1))ⁿ` at `m` evenly spaced nodes over
//! `cos α ∈ [0, 1]` (`m` = `table_size`). Bishop & Weimer evaluate `n·h` incrementally per pixel
//! and replace the exponentiation by "one memory reference"; this model keeps that table lookup
//! (with linear interpolation between entries) and the modified-Phong lobe around it.
//!
//! `N_L = 1 / (2π ∫₀¹ L(μ) μ dμ)` is the normalisation of the *tabulated* lobe (computed exactly
//! for the interpolant), so the specular albedo at normal incidence is exactly ks, as in the
//! modified model; it equals `(n+2)/(2π)` up to the table error. For a convex `μⁿ` (n ≥ 1) the
//! chords lie above the curve, so `L ≥ μⁿ` and `N_L ≤ (n+2)/(2π)`. A table much coarser than
//! the lobe (`m ≪ √n`) flattens it into a wider, dimmer linear ramp over the last interval.
//! The interpolation error for several n and m is measured in the tests
//! (`table_error_report`, run with `--nocapture` to print it).
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance kd |
//! | `specular` | colour | 0.3 | [0, 1] | specular reflectance ks (kd + ks ≤ 1 per channel) |
//! | `exponent` | scalar | 30 | [0, 10⁴] | Phong exponent n (shininess) |
//! | `table_size` | integer | 256 | [2, 65536] | entries m of the `cosⁿ` table over `cos α ∈ [0, 1]` |
//!
//! Physics: reciprocal (`cos α` is symmetric in wi and wo). Energy conserving when kd + ks ≤ 1,
//! which is enforced: `L` is non-decreasing (the node values are), so by the rearrangement
//! inequality on the sphere the lobe's albedo is largest at normal incidence, where it is ks by
//! the choice of `N_L` (the argument of [`super::modified_phong`]).
//!
//! Sampling: exactly the tabulated lobe. With probability k̄s/(k̄d + k̄s) `cos α` is drawn
//! from the piecewise-linear density `L(μ)/∫L` ([`crate::sampling::PiecewiseLinear`]) and the
//! azimuth uniformly around the mirror direction (solid-angle density `L(cos α)/(2π ∫L)`),
//! otherwise a cosine-weighted direction; the pdf is the mixture. The table is stored and
//! indexed by the versine `1 − cos α` (same nodes, reverse order) so that f32 keeps the
//! precision of narrow lobes near their peak.
//!
//! References: G. Bishop, D. M. Weimer, "Fast Phong shading", SIGGRAPH 1986 (Computer Graphics
//! 20(4), 103–106); the lobe and its normalisation as in [`super::modified_phong`].

use super::phong::{check_sum_at_most_one, mean, two_lobe_weights, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::{basis_around, from_basis, mirror_z, spherical_direction, versine_between};
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe, PiecewiseLinear};

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance kd"),
    ParamSpec::color("specular", [0.3; 3], 0.0, 1.0, "specular reflectance ks (kd + ks ≤ 1 per channel)"),
    ParamSpec::scalar("exponent", 30.0, 0.0, MAX_EXPONENT, "", "Phong exponent n (shininess)"),
    ParamSpec::integer("table_size", 256, 2, 65536, "entries m of the cosⁿ table over cos α ∈ [0, 1]"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "fast_phong",
    summary: "Bishop & Weimer 1986 fast Phong: modified Phong with cosⁿα from an interpolated table",
    reference: "G. Bishop, D. M. Weimer, Fast Phong shading, SIGGRAPH 1986, Computer Graphics 20(4) 103-106",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: &[
        r#"{"diffuse": 0.0, "specular": 1.0, "exponent": 2.0, "table_size": 8}"#,
        r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.3, 0.5, 0.8], "exponent": 200.0, "table_size": 1024}"#,
        r#"{"diffuse": 0.1, "specular": 0.9, "exponent": 1000.0, "table_size": 32}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    let diffuse = p.color("diffuse");
    let specular = p.color("specular");
    check_sum_at_most_one(diffuse, specular, "so that the albedo stays at most 1")?;
    let exponent = p.scalar("exponent");
    let size = usize::try_from(p.integer("table_size")).unwrap_or(2).max(2);
    let table = versine_table(exponent, size).ok_or_else(|| Error::Invalid {
        param: "table_size".into(),
        reason: "the cosⁿ table has no positive entry".into(),
    })?;
    // ∫₀¹ L(μ) μ dμ with μ = 1 − v.
    let moment = table.integral() - table.first_moment();
    let norm = 1.0 / (2.0 * std::f64::consts::PI * moment);
    Ok(Model::FastPhong(FastPhong { diffuse, specular, exponent, norm, table }))
}

/// The table of `μⁿ` at `μ_k = k/(m−1)`, stored by the versine `v = 1 − μ` (node `j` holds
/// `(1 − j/(m−1))ⁿ`, the same nodes in reverse order): near the peak `v` is small and keeps
/// its precision in f32, where `1 − v` would round it away.
fn versine_table(exponent: f64, size: usize) -> Option<PiecewiseLinear> {
    PiecewiseLinear::new((0..size).map(|j| (1.0 - j as f64 / (size - 1) as f64).powf(exponent)).collect())
}

/// The modified Phong BRDF with a tabulated power.
#[derive(Clone, Debug)]
pub struct FastPhong {
    /// Diffuse reflectance kd per channel.
    pub diffuse: [f64; 3],
    /// Specular reflectance ks per channel.
    pub specular: [f64; 3],
    /// Phong exponent n the table was built for.
    pub exponent: f64,
    /// `N_L = 1/(2π ∫ L(μ) μ dμ)`.
    pub norm: f64,
    /// `L` as a function of the versine `v = 1 − cos α` (node `j` at `v = j/(m−1)`); also the
    /// sampling density of `v`.
    pub table: PiecewiseLinear,
}

impl FastPhong {
    /// `1 − cos α`, α the angle to the mirror direction.
    #[inline]
    fn versine<T: Real>(wi: Vec3<T>, wo: Vec3<T>) -> T {
        versine_between(wi, mirror_z(wo))
    }

    #[inline]
    fn lobe_weights<T: Real>(&self) -> [T; 2] {
        two_lobe_weights(mean(self.diffuse), mean(self.specular))
    }
}

impl Bxdf for FastPhong {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let lobe = self.table.eval(Self::versine(wi, wo)) * T::of(self.norm);
        Rgb::from_array(self.diffuse) * T::inv_pi() + Rgb::from_array(self.specular) * lobe
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let [pd, ps] = self.lobe_weights::<T>();
        let spec = self.table.pdf(Self::versine(wi, wo)) * T::inv_pi() * T::of(0.5);
        pd * cosine_hemisphere_pdf(wi.z) + ps * spec
    }

    #[inline]
    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let (lobe, _) = pick_lobe(&self.lobe_weights::<T>(), u[0])?;
        let wi = if lobe == 0 {
            cosine_hemisphere(u[1], u[2])
        } else {
            let v = self.table.sample(u[1]);
            let sin = (v * (T::of(2.0) - v)).safe_sqrt();
            let local = spherical_direction(sin, T::one() - v, T::of(2.0) * T::PI() * u[2]);
            let axis = mirror_z(wo);
            let (s, t) = basis_around(axis);
            from_basis(local, s, t, axis)
        };
        if !(wi.z > T::zero()) {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::spherical_direction;
    use crate::material::Material;
    use std::f64::consts::PI;

    fn fast(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "fast_phong", {json}}}"#)).unwrap()
    }


    /// Max absolute and relative error of the interpolated `μⁿ` (relative where `μⁿ ≥ 10⁻³`,
    /// the visible part of the lobe), and `N_L / ((n+2)/(2π))`.
    fn table_errors(n: f64, m: usize) -> (f64, f64, f64) {
        let t = versine_table(n, m).unwrap();
        let (mut abs, mut rel) = (0.0f64, 0.0f64);
        let samples = 200_000;
        for i in 0..=samples {
            let mu = i as f64 / samples as f64;
            let exact = mu.powf(n);
            let e = (t.eval(1.0 - mu) - exact).abs();
            abs = abs.max(e);
            if exact >= 1e-3 {
                rel = rel.max(e / exact);
            }
        }
        (abs, rel, 1.0 / (2.0 * PI * (t.integral() - t.first_moment())) / ((n + 2.0) / (2.0 * PI)))
    }

    /// The table error against the exact power, for several exponents and table sizes. Linear
    /// interpolation of `μⁿ` with spacing `h = 1/(m−1)` errs by at most `h² n(n−1)/8` (the
    /// second derivative is at most `n(n−1)`); the coarse tables of sharp lobes hit the
    /// other bound, 1 (both values in [0, 1]).
    #[test]
    fn table_error_report() {
        eprintln!("fast_phong table error against μⁿ (rel. where μⁿ ≥ 1e-3; N_L / ((n+2)/2π)):");
        eprintln!("{:>8} {:>6} {:>12} {:>12} {:>10}", "n", "m", "max abs", "max rel", "norm ratio");
        for n in [10.0, 100.0, 1000.0, 10000.0] {
            for m in [64usize, 256, 1024, 4096] {
                let (abs, rel, ratio) = table_errors(n, m);
                eprintln!("{n:>8} {m:>6} {abs:>12.3e} {rel:>12.3e} {ratio:>10.4}");
                let h = 1.0 / (m - 1) as f64;
                assert!(abs <= (h * h * n * (n - 1.0) / 8.0).min(1.0) * (1.0 + 1e-9) + 1e-15, "n={n} m={m}");
                assert!(ratio <= 1.0 + 1e-12, "chords above a convex curve make N_L ≤ (n+2)/(2π)");
            }
        }
        // Fine tables converge: n = 100, m = 4096: h²n(n−1)/8 = 7.4e-5.
        let (abs, _, ratio) = table_errors(100.0, 4096);
        assert!(abs < 7.4e-5 && (ratio - 1.0).abs() < 1e-4, "{abs} {ratio}");
    }

    /// At the table nodes the lobe is exact, and with the normalisation `N_L` it equals the
    /// modified Phong value up to `N_L / ((n+2)/(2π))`.
    #[test]
    fn exact_at_nodes() {
        let m = fast(r#""diffuse": 0.0, "specular": 1.0, "exponent": 20, "table_size": 11"#);
        let modified = Material::from_json(r#"{"model": "modified_phong", "diffuse": 0.0, "specular": 1.0, "exponent": 20}"#)
            .unwrap();
        let Model::FastPhong(fp) = m.model() else { panic!() };
        let ratio = fp.norm / (22.0 / (2.0 * PI));
        let wo = spherical_direction(0.6f64, 0.8, 0.2);
        let axis = mirror_z(wo);
        let (s, t) = basis_around(axis);
        for k in [6, 8, 9, 10] {
            let c = k as f64 / 10.0;
            let wi = from_basis(spherical_direction((1.0 - c * c).sqrt(), c, 2.0), s, t, axis);
            let (a, b) = (m.eval(wi, wo).r, modified.eval(wi, wo).r * ratio);
            assert!((a - b).abs() < 1e-9 * b, "cos α = {c}: {a} vs {b}");
        }
    }

    /// Normal-incidence albedo is kd + ks exactly, however coarse the table.
    #[test]
    fn normal_incidence_albedo_is_kd_plus_ks() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for (n, size) in [(30.0, 256), (1000.0, 16), (2.0, 2), (0.0, 5)] {
            let m = fast(&format!(r#""diffuse": 0.2, "specular": 0.8, "exponent": {n}, "table_size": {size}"#));
            let a = albedo_around(&m, z, z)[0];
            assert!((a - 1.0).abs() < 3e-4, "n = {n}, m = {size}: {a}");
        }
    }

    /// Sampled `cos α` follows the table: one-segment table (m = 2, n ≥ 1) is the linear lobe
    /// `L(μ) = μ`, whose CDF in `v = 1 − μ` is `1 − μ²`: drawn as `μ = √(1 − u)`.
    #[test]
    fn sampling_follows_the_table() {
        let m = fast(r#""diffuse": 0.0, "specular": 1.0, "exponent": 5, "table_size": 2"#);
        let wo = Vec3::new(0.0f64, 0.0, 1.0);
        for u in [0.1f64, 0.5, 0.9] {
            let s = m.sample(wo, [0.5, u, 0.3]).unwrap();
            let mu = (1.0 - u).sqrt();
            assert!((s.wi.z - mu).abs() < 1e-12, "{u}: {:?}", s.wi);
            // Density: L(μ)/(2π ∫L) = μ/π.
            assert!((s.pdf - mu / PI).abs() < 1e-12);
        }
    }
}
