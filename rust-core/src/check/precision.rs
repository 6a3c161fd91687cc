//! The f32 fast path against the f64 reference on random direction pairs.

use super::{random_direction, CheckConfig};
use crate::material::Material;
use crate::math::{Rgb, Vec3};
use crate::rng::Pcg32;
use serde::Serialize;

/// Result of the precision comparison.
#[derive(Clone, Debug, Serialize)]
pub struct PrecisionReport {
    /// Pairs compared.
    pub pairs: usize,
    /// Largest relative error of f32 eval/pdf against f64, with a floor of 1e-4 × the
    /// largest f64 value seen (so values far below the lobe's peak do not dominate).
    pub max_relative_error: f64,
    /// Mean relative error of eval.
    pub mean_relative_error: f64,
}

/// eval and pdf of one pair in f64 and in f32 (widened).
///
/// Not inlined on purpose: with the model's `match` inlined into the loop above, the optimiser
/// hoisted loop-invariant code of *other* models' arms into the loop preheader (loop
/// unswitching) and branched on the enum's unused bytes, which hold whatever the stack held when
/// `Material::from_params` built the value. The results never depended on it, but valgrind
/// reported "conditional jump depends on uninitialised value" (origin: a stack allocation in
/// `Material::from_params`), attributed to the `Vec::with_capacity` line of the preheader. With
/// one dispatch per call there is no loop around the `match` to hoist out of (the cause was
/// the same as in the batch kernels, fixed there by `Model::visit_kernel`).
#[inline(never)]
fn both_paths(m: &Material, wi: Vec3<f32>, wo: Vec3<f32>) -> (Rgb<f64>, Rgb<f64>, f64, f64) {
    let f64v = m.eval(wi.cast::<f64>(), wo.cast::<f64>());
    let f32v = m.eval(wi, wo).cast::<f64>();
    let p64 = m.pdf(wi.cast::<f64>(), wo.cast::<f64>());
    let p32 = m.pdf(wi, wo) as f64;
    (f64v, f32v, p64, p32)
}

/// Compares the f32 and f64 paths.
#[must_use]
pub fn precision(m: &Material, cfg: &CheckConfig) -> PrecisionReport {
    let mut rng = Pcg32::new(cfg.seed, 0x3232);
    let n = 4000;
    let mut rows = Vec::with_capacity(n);
    let mut peak = 0.0f64;
    let mut peak_pdf = 0.0f64;
    for _ in 0..n {
        // Directions are rounded to f32 first, so both paths see the same input.
        let wi = random_direction(&mut rng).cast::<f32>();
        let wo = random_direction(&mut rng).cast::<f32>();
        let (f64v, f32v, p64, p32) = both_paths(m, wi, wo);
        peak = peak.max(f64v.max_channel());
        peak_pdf = peak_pdf.max(p64);
        rows.push((f64v, f32v, p64, p32));
    }
    let floor = (1e-4 * peak).max(1e-12);
    let floor_pdf = (1e-4 * peak_pdf).max(1e-12);
    let (mut max_err, mut sum_err) = (0.0f64, 0.0f64);
    for (a, b, pa, pb) in rows {
        let mut e = 0.0f64;
        for c in 0..3 {
            let d = (a[c] - b[c]).abs() / a[c].abs().max(floor);
            e = e.max(if d.is_nan() { f64::INFINITY } else { d });
        }
        sum_err += e;
        let ep = (pa - pb).abs() / pa.abs().max(floor_pdf);
        max_err = max_err.max(e).max(if ep.is_nan() { f64::INFINITY } else { ep });
    }
    PrecisionReport { pairs: n, max_relative_error: max_err, mean_relative_error: sum_err / n as f64 }
}
