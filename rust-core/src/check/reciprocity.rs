//! Reciprocity: `f(wi, wo) = f(wo, wi)` on random and adversarial direction pairs (f64).

use super::{direction, random_direction, CheckConfig};
use crate::frame::mirror_z;
use crate::material::Material;
use crate::math::Vec3;
use crate::rng::Pcg32;
use serde::Serialize;

/// Result of the reciprocity check.
#[derive(Clone, Debug, Serialize)]
pub struct ReciprocityReport {
    /// Pairs evaluated.
    pub pairs: usize,
    /// Largest relative error over channels and pairs (floor 1e-10 /sr).
    pub max_relative_error: f64,
    /// The pair where it occurred, `[wi, wo]`.
    pub worst_pair: [[f64; 3]; 2],
}

fn rel_err(a: f64, b: f64) -> f64 {
    let d = (a - b).abs();
    if d == 0.0 {
        return 0.0;
    }
    d / a.abs().max(b.abs()).max(1e-10)
}

/// Measures the largest reciprocity error.
#[must_use]
pub fn reciprocity(m: &Material, cfg: &CheckConfig) -> ReciprocityReport {
    let mut rng = Pcg32::new(cfg.seed, 0x2ec1);
    let mut pairs: Vec<(Vec3<f64>, Vec3<f64>)> = Vec::with_capacity(cfg.reciprocity_pairs + 256);
    for _ in 0..cfg.reciprocity_pairs {
        pairs.push((random_direction(&mut rng), random_direction(&mut rng)));
    }
    // Adversarial pairs: mirror configurations, near-mirror, grazing, identical, normal.
    for &c in &[1.0, 0.9, 0.5, 0.1, 1e-2, 1e-4] {
        for &phi in &[0.0, 0.4, std::f64::consts::FRAC_PI_2, 2.8] {
            let w = direction(c, phi);
            pairs.push((w, w));
            pairs.push((w, mirror_z(w)));
            pairs.push((w, direction(c * 0.999, phi + std::f64::consts::PI + 1e-3)));
            pairs.push((w, direction(1e-3, phi + 1.0)));
            pairs.push((w, Vec3::new(0.0, 0.0, 1.0)));
        }
    }
    let mut worst = 0.0;
    let mut worst_pair = [[0.0; 3]; 2];
    for (a, b) in pairs.iter().copied() {
        let f_ab = m.eval(a, b);
        let f_ba = m.eval(b, a);
        for c in 0..3 {
            let e = rel_err(f_ab[c], f_ba[c]);
            if e > worst || e.is_nan() {
                worst = if e.is_nan() { f64::INFINITY } else { e };
                worst_pair = [[a.x, a.y, a.z], [b.x, b.y, b.z]];
            }
        }
    }
    ReciprocityReport { pairs: pairs.len(), max_relative_error: worst, worst_pair }
}
