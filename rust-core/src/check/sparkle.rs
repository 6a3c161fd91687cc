//! Checks of the spatially varying path (`eval_at`, `sample_at`) of models that sparkle:
//! reciprocity of `eval_at` on random surface points and footprints, and the consistency of
//! `sample_at`'s pdf and weight with `pdf` and `eval_at`. Degenerate footprints are part of
//! the hard cases ([`super::hard_cases`]).

use super::{direction, random_direction, CheckConfig};
use crate::bxdf::SurfacePoint;
use crate::frame::mirror_z;
use crate::material::Material;
use crate::math::Vec3;
use crate::rng::Pcg32;
use serde::Serialize;

/// Result of the sparkle checks on one material.
#[derive(Clone, Debug, Serialize)]
pub struct SparkleReport {
    /// `(wi, wo, surface point)` triples evaluated both ways.
    pub pairs: usize,
    /// Largest relative error `|f_at(wi, wo) − f_at(wo, wi)| / max(|f|, 1e-10)`.
    pub reciprocity_max_relative_error: f64,
    /// Where it occurred.
    pub worst_case: String,
    /// `sample_at` calls compared with `pdf` and `eval_at`.
    pub samples: usize,
    /// Largest relative gap between `sample_at`'s pdf/weight and `pdf`/`eval_at · cos/pdf`.
    pub sample_consistency: f64,
    /// Fraction of random evaluations where `eval_at` differed from `eval` (how much the
    /// spatial path is exercised; 0 would mean the check tested nothing).
    pub varied_fraction: f64,
}

/// A random surface point: uv in `[−50, 50]²` and a sheared footprint whose two edges have
/// log-uniform lengths in `[1e-7, 1e-1]` uv units and random directions.
#[must_use]
pub fn random_surface_point(rng: &mut Pcg32) -> SurfacePoint {
    let edge = |rng: &mut Pcg32| {
        let len = 10f64.powf(rng.range(-7.0, -1.0));
        let phi = rng.range(0.0, 2.0 * std::f64::consts::PI);
        [len * phi.cos(), len * phi.sin()]
    };
    let duv_dx = edge(rng);
    let duv_dy = edge(rng);
    SurfacePoint { uv: [rng.range(-50.0, 50.0), rng.range(-50.0, 50.0)], duv_dx, duv_dy }
}

/// Degenerate and extreme surface points for the hard cases.
#[must_use]
pub fn extreme_surface_points() -> Vec<SurfacePoint> {
    let at = |uv: [f64; 2], dx: [f64; 2], dy: [f64; 2]| SurfacePoint { uv, duv_dx: dx, duv_dy: dy };
    vec![
        at([0.0, 0.0], [0.0, 0.0], [0.0, 0.0]),
        at([0.25, 0.75], [1e-4, 0.0], [0.0, 1e-4]),
        at([-3.5, 2.0], [1e-300, 0.0], [0.0, 1e-300]),
        at([0.5, 0.5], [1e300, 0.0], [0.0, 1e300]),
        at([1e300, -1e300], [1e-3, 2e-3], [2e-3, 4e-3]),
        at([-7.25, -1e6], [-1e-3, 5e-4], [3e-4, -2e-3]),
        at([0.125, 0.0625], [f64::MAX, f64::MAX], [f64::MAX, -f64::MAX]),
    ]
}

fn rel_err(a: f64, b: f64) -> f64 {
    let d = (a - b).abs();
    if d == 0.0 {
        return 0.0;
    }
    if d.is_nan() {
        return f64::INFINITY;
    }
    d / a.abs().max(b.abs()).max(1e-10)
}

/// Runs the sparkle checks, or `None` for a material without spatial variation.
#[must_use]
pub fn sparkle(m: &Material, cfg: &CheckConfig) -> Option<SparkleReport> {
    if !m.spatially_varying() {
        return None;
    }
    let mut rng = Pcg32::new(cfg.seed, 0x5a4c);
    let mut triples: Vec<(Vec3<f64>, Vec3<f64>, SurfacePoint)> = Vec::new();
    for _ in 0..cfg.reciprocity_pairs {
        let (a, b) = (random_direction(&mut rng), random_direction(&mut rng));
        triples.push((a, b, random_surface_point(&mut rng)));
    }
    // Near-mirror pairs, where the flake lobes (and their glints) peak.
    for &c in &[1.0, 0.9, 0.5, 0.1, 1e-2] {
        for &phi in &[0.0, 0.4, std::f64::consts::FRAC_PI_2, 2.8] {
            let w = direction(c, phi);
            for _ in 0..16 {
                let jitter = direction(c * rng.range(0.95, 1.0), phi + std::f64::consts::PI + rng.range(-0.05, 0.05));
                triples.push((w, mirror_z(w), random_surface_point(&mut rng)));
                triples.push((w, jitter, random_surface_point(&mut rng)));
            }
        }
    }
    let (mut worst, mut worst_case, mut varied) = (0.0f64, String::new(), 0usize);
    for (a, b, at) in &triples {
        let f_ab = m.eval_at(*a, *b, at);
        let f_ba = m.eval_at(*b, *a, at);
        if f_ab != m.eval(*a, *b) {
            varied += 1;
        }
        for c in 0..3 {
            let e = rel_err(f_ab[c], f_ba[c]);
            if e > worst {
                worst = e;
                worst_case = format!("wi {a:?} wo {b:?} at {at:?}");
            }
        }
    }
    let samples = cfg.reciprocity_pairs;
    let mut consistency = 0.0f64;
    for _ in 0..samples {
        let wo = random_direction(&mut rng);
        let at = random_surface_point(&mut rng);
        let Some(s) = m.sample_at(wo, rng.uniform3(), &at) else { continue };
        if s.delta {
            continue;
        }
        consistency = consistency.max(rel_err(s.pdf, m.pdf(s.wi, wo)));
        let f = m.eval_at(s.wi, wo, &at);
        for c in 0..3 {
            let expect = f[c] * s.wi.z / s.pdf;
            let gap = (s.weight[c] - expect).abs() / s.weight[c].abs().max(expect.abs()).max(1e-9);
            consistency = consistency.max(if gap.is_nan() { f64::INFINITY } else { gap });
        }
    }
    Some(SparkleReport {
        pairs: triples.len(),
        reciprocity_max_relative_error: worst,
        worst_case,
        samples,
        sample_consistency: consistency,
        varied_fraction: varied as f64 / triples.len() as f64,
    })
}
