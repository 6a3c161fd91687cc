//! White furnace: the directional albedo `ρ(wo) = ∫ f(wi, wo) cos θi dωi` for a grid of `wo`.
//!
//! Two-sided: the bounds are the mean ± [`BOUND_SIGMAS`] standard errors, measured from
//! [`REPLICAS`] independent randomisations (not from an iid formula, which quasi-random points
//! do not obey). An energy-conserving model fails when an albedo is significantly above one;
//! a lossless configuration ([`LOSSLESS`]) fails when one is significantly below
//! [`LOSSLESS_MIN_ALBEDO`].
//!
//! Estimated with one sample from the model's own sampler and one cosine-weighted sample per
//! iteration, combined with the balance heuristic: unbiased even where the model's sampler
//! misses part of the lobe, and low-variance where it is good.

use super::{direction, CheckConfig};
use crate::material::Material;
use crate::rng::Pcg32;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use serde::Serialize;

/// Configurations that absorb nothing, `(model, parameters)`: their albedo must reach
/// [`LOSSLESS_MIN_ALBEDO`] at every checked direction (`lacquer check` adds them to their
/// model's materials, origin `lossless`).
pub const LOSSLESS: &[(&str, &str)] = &[
    ("lambert", r#"{"albedo": 1.0}"#),
    ("oren_nayar", r#"{"albedo": 1.0, "sigma": 0.0}"#),
    ("oren_nayar_qualitative", r#"{"albedo": 1.0, "sigma": 0.0}"#),
    // A perfect conductor (η = 0, k = 1: F = 1 at every angle) with Kulla-Conty compensation.
    ("rough_conductor", r#"{"distribution": "ggx", "alpha_u": 0.3, "alpha_v": 0.3, "multiple_scattering": true}"#),
    // White pigment under a clear coat, no flakes: the coat's and the base's losses are nil.
    ("coated_paint", r#"{"base_color": 1.0, "flake_density": 0, "coat_roughness": 0}"#),
    ("coated_paint", r#"{"base_color": 1.0, "flake_density": 0, "coat_roughness": 0.1}"#),
];

/// Smallest albedo (upper bound, mean + 4σ) a [`LOSSLESS`] configuration may show.
pub const LOSSLESS_MIN_ALBEDO: f64 = 0.99;

/// Albedo at one outgoing direction.
#[derive(Clone, Debug, Serialize)]
pub struct AlbedoPoint {
    /// `cos θo`.
    pub cos_theta: f64,
    /// `φo`.
    pub phi: f64,
    /// Albedo per channel.
    pub albedo: [f64; 3],
    /// Standard error of the largest channel, from the spread of [`REPLICAS`] independent
    /// randomisations.
    pub std_error: f64,
}

/// Result of the furnace test.
#[derive(Clone, Debug, Serialize)]
pub struct FurnaceReport {
    /// Per outgoing direction.
    pub points: Vec<AlbedoPoint>,
    /// Largest albedo (any channel).
    pub max_albedo: f64,
    /// Smallest albedo (any channel).
    pub min_albedo: f64,
    /// Largest `mean − 4σ` over directions and channels (the energy verdict: an
    /// energy-conserving model fails when it lies above 1 + tolerance).
    pub max_lower_bound: f64,
    /// Smallest `mean + 4σ` over directions and channels (the lossless verdict: a lossless
    /// configuration fails when it lies below [`LOSSLESS_MIN_ALBEDO`]).
    pub min_upper_bound: f64,
}

/// Estimates the directional albedo at one `wo`. The uniform numbers are a randomly shifted
/// Halton-Hammersley set (Cranley-Patterson rotation): unbiased, and far less noisy than
/// independent samples. The standard error is computed as if the samples were independent,
/// which overstates it.
#[must_use]
pub fn albedo(m: &Material, wo: crate::Vec3<f64>, samples: usize, rng: &mut Pcg32) -> ([f64; 3], f64) {
    let mut sum = [0.0; 3];
    let mut sum2 = 0.0;
    let n = samples.max(1);
    let shift1 = rng.uniform3();
    let shift2 = rng.uniform3();
    let rotate = |p: [f64; 3], s: [f64; 3]| [0, 1, 2].map(|i| (p[i] + s[i]).fract());
    for k in 0..n {
        let point = crate::sampling::hammersley3(k, n);
        let mut est = [0.0; 3];
        // Strategy 1: the model's sampler.
        let u = rotate(point, shift1);
        if let Some(s) = m.sample(wo, u) {
            if s.delta {
                for (c, e) in est.iter_mut().enumerate() {
                    *e += s.weight[c];
                }
            } else {
                let f = m.eval(s.wi, wo);
                let denom = s.pdf + cosine_hemisphere_pdf(s.wi.z);
                for (c, e) in est.iter_mut().enumerate() {
                    *e += f[c] * s.wi.z / denom;
                }
            }
        }
        // Strategy 2: cosine-weighted hemisphere.
        let v = rotate(point, shift2);
        let wi = cosine_hemisphere(v[1], v[2]);
        if wi.z > 0.0 {
            let f = m.eval(wi, wo);
            let denom = m.pdf(wi, wo) + cosine_hemisphere_pdf(wi.z);
            for (c, e) in est.iter_mut().enumerate() {
                *e += f[c] * wi.z / denom;
            }
        }
        for c in 0..3 {
            sum[c] += est[c];
        }
        let mx = est[0].max(est[1]).max(est[2]);
        sum2 += mx * mx;
    }
    let mean = sum.map(|s| s / n as f64);
    let mmax = mean[0].max(mean[1]).max(mean[2]);
    let var = (sum2 / n as f64 - mmax * mmax).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// Independent randomisations of the furnace estimate: each is its own pair of random shifts
/// of a Hammersley set of `samples / REPLICAS` points, so the replica means are independent
/// and identically distributed and their spread is an honest standard error.
pub const REPLICAS: usize = 16;

/// The bound factor on the replica standard error: Student's t with `REPLICAS − 1` = 15
/// degrees of freedom exceeds 4.0 with probability 5.5e-4 (one-sided), about the normal 3.3σ.
pub const BOUND_SIGMAS: f64 = 4.0;

/// The directional albedo at `wo` from [`REPLICAS`] independently shifted quasi-random sets
/// of `samples / REPLICAS` points each: the mean and, per channel, the standard error of the
/// mean from the spread of the replica means.
#[must_use]
pub fn albedo_replicas(m: &Material, wo: crate::Vec3<f64>, samples: usize, rng: &mut Pcg32) -> ([f64; 3], [f64; 3]) {
    let per = (samples / REPLICAS).max(1);
    let means: Vec<[f64; 3]> = (0..REPLICAS).map(|_| albedo(m, wo, per, rng).0).collect();
    let r = REPLICAS as f64;
    let mean = [0, 1, 2].map(|c| means.iter().map(|a| a[c]).sum::<f64>() / r);
    let se = [0, 1, 2].map(|c| {
        let var = means.iter().map(|a| (a[c] - mean[c]).powi(2)).sum::<f64>() / (r - 1.0);
        (var / r).sqrt()
    });
    (mean, se)
}

/// Runs the furnace over the configured `wo` grid ([`albedo_replicas`] at every direction).
#[must_use]
pub fn furnace(m: &Material, cfg: &CheckConfig) -> FurnaceReport {
    let mut rng = Pcg32::new(cfg.seed, 0xf0e4);
    let mut points = Vec::new();
    let (mut max_albedo, mut min_albedo) = (0.0f64, f64::INFINITY);
    let (mut max_lower, mut min_upper) = (f64::NEG_INFINITY, f64::INFINITY);
    for &c in &cfg.furnace_cos {
        for &phi in &cfg.furnace_phi {
            let wo = direction(c, phi);
            let (a, se) = albedo_replicas(m, wo, cfg.furnace_samples, &mut rng);
            let (mut hi, mut lo, mut hi_se) = (f64::NEG_INFINITY, f64::INFINITY, 0.0);
            for ch in 0..3 {
                max_lower = max_lower.max(a[ch] - BOUND_SIGMAS * se[ch]);
                min_upper = min_upper.min(a[ch] + BOUND_SIGMAS * se[ch]);
                if a[ch] > hi {
                    hi = a[ch];
                    hi_se = se[ch];
                }
                lo = lo.min(a[ch]);
            }
            max_albedo = max_albedo.max(hi);
            min_albedo = min_albedo.min(lo);
            points.push(AlbedoPoint { cos_theta: c, phi, albedo: a, std_error: hi_se });
        }
    }
    FurnaceReport { points, max_albedo, min_albedo, max_lower_bound: max_lower, min_upper_bound: min_upper }
}
