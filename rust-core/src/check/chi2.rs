//! χ² goodness of fit of `sample` against `pdf`, in the manner of Mitsuba's and pbrt's
//! sampler tests: draw many samples, histogram them in equal-solid-angle `(cos θ, φ)` cells,
//! integrate `pdf` over every cell by adaptive Simpson quadrature, pool sparse cells, and
//! compare. Failed samples (and samples of delta lobes) go to an "outside" bin whose
//! expected count is `N (1 − ∫ pdf)`, so a sampler that loses mass the pdf claims is caught.

use super::{direction, CheckConfig};
use crate::bxdf::{BsdfSample, SurfacePoint};
use crate::material::Material;
use crate::math::{Rgb, Vec3};
use crate::rng::Pcg32;
use serde::Serialize;
use std::f64::consts::PI;

/// One χ² test (one outgoing direction).
#[derive(Clone, Debug, Serialize)]
pub struct Chi2Case {
    /// `cos θo`.
    pub cos_theta: f64,
    /// `φo`.
    pub phi: f64,
    /// Samples drawn.
    pub samples: usize,
    /// χ² statistic after pooling.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Upper-tail probability of the statistic.
    pub p_value: f64,
    /// `∫ pdf dωi` over the upper hemisphere.
    pub pdf_integral: f64,
    /// Fraction of samples that failed (or came from a delta lobe).
    pub outside_fraction: f64,
    /// Largest relative gap between `sample`'s pdf/weight and `pdf`/`eval·cos/pdf`.
    pub sample_consistency: f64,
    /// Why the test failed outright, if it did.
    pub note: String,
}

/// Absolute error budget of a cell's expected count: far below the Poisson noise of any cell
/// the test keeps (cells expecting fewer than 5 samples are pooled), and it spares the
/// integrator from resolving the far tails of sharp lobes to 2e-4 relative.
const CELL_COUNT_TOLERANCE: f64 = 1e-3;

fn simpson(f: &impl Fn(f64, f64) -> f64, x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let (xm, ym) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let w = [1.0, 4.0, 1.0];
    let xs = [x0, xm, x1];
    let ys = [y0, ym, y1];
    let mut s = 0.0;
    for (i, &x) in xs.iter().enumerate() {
        for (j, &y) in ys.iter().enumerate() {
            s += w[i] * w[j] * f(x, y);
        }
    }
    s * (x1 - x0) * (y1 - y0) / 36.0
}

/// Adaptive Simpson on a rectangle: a part is accepted when its refinement changes it by at
/// most 2e-4 relative or `abs_tol` absolute (split evenly among the four sub-parts).
#[allow(clippy::too_many_arguments)]
fn adaptive(
    f: &impl Fn(f64, f64) -> f64,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    whole: f64,
    depth: u32,
    abs_tol: f64,
) -> f64 {
    let (xm, ym) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let parts = [(x0, xm, y0, ym), (xm, x1, y0, ym), (x0, xm, ym, y1), (xm, x1, ym, y1)];
    let vals = parts.map(|(a, b, c, d)| simpson(f, a, b, c, d));
    let sum: f64 = vals.iter().sum();
    if depth == 0 || (sum - whole).abs() <= 2e-4 * sum.abs() + abs_tol {
        return sum + (sum - whole) / 15.0;
    }
    parts.iter().zip(vals).map(|(&(a, b, c, d), v)| adaptive(f, a, b, c, d, v, depth - 1, 0.25 * abs_tol)).sum()
}

/// Integral of `pdf(·, wo)` over the cell `[μ0, μ1] × [φ0, φ1]` (`dω = dμ dφ`), to 2e-4
/// relative or `abs_tol` absolute (a probability).
fn cell_integral(m: &Material, wo: crate::Vec3<f64>, mu: (f64, f64), phi: (f64, f64), abs_tol: f64) -> f64 {
    let f = |u: f64, p: f64| m.pdf(direction(u, p), wo);
    let whole = simpson(&f, mu.0, mu.1, phi.0, phi.1);
    adaptive(&f, mu.0, mu.1, phi.0, phi.1, whole, 7, abs_tol).max(0.0)
}

fn rel_gap(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(floor)
}

/// Runs one χ² test per configured outgoing direction.
#[must_use]
pub fn chi2_test(m: &Material, cfg: &CheckConfig) -> Vec<Chi2Case> {
    (0..cfg.chi2_directions.len()).map(|k| chi2_direction(m, cfg, k)).collect()
}

/// The χ² test of the `k`-th configured outgoing direction alone: the same numbers as the
/// `k`-th case of [`chi2_test`] (its random stream starts where the serial run's would), so
/// directions can run on different threads.
#[must_use]
pub fn chi2_direction(m: &Material, cfg: &CheckConfig, k: usize) -> Chi2Case {
    chi2_case(m, cfg, k, |wo, u| m.sample(wo, u), |wi, wo| m.eval(wi, wo))
}

/// The χ² tests of [`Material::sample_at`] at one surface point against [`Material::pdf`]
/// (the density does not depend on the position); the consistency figure compares the
/// weights with [`Material::eval_at`].
#[must_use]
pub fn chi2_test_at(m: &Material, cfg: &CheckConfig, at: &SurfacePoint) -> Vec<Chi2Case> {
    (0..cfg.chi2_directions.len())
        .map(|k| chi2_case(m, cfg, k, |wo, u| m.sample_at(wo, u, at), |wi, wo| m.eval_at(wi, wo, at)))
        .collect()
}

/// Outputs of [`Pcg32::next_u32`] one χ² sample uses (`uniform3`: three 53-bit numbers).
const DRAWS_PER_SAMPLE: u64 = 6;

fn chi2_case(
    m: &Material,
    cfg: &CheckConfig,
    k: usize,
    sample: impl Fn(Vec3<f64>, [f64; 3]) -> Option<BsdfSample<f64>>,
    eval: impl Fn(Vec3<f64>, Vec3<f64>) -> Rgb<f64>,
) -> Chi2Case {
    let (nt, np) = (cfg.chi2_theta_bins, cfg.chi2_phi_bins);
    // One stream for all directions, in order: direction k starts after k·N samples.
    let mut rng = Pcg32::new(cfg.seed, 0xc412);
    rng.advance(DRAWS_PER_SAMPLE * (k * cfg.chi2_samples) as u64);
    let (cos_o, phi_o) = cfg.chi2_directions[k];
    let wo = direction(cos_o, phi_o);
    let n = cfg.chi2_samples;
    let mut observed = vec![0.0f64; nt * np];
    let mut outside = 0.0;
    let mut consistency = 0.0f64;
    for _ in 0..n {
        let Some(s) = sample(wo, rng.uniform3()) else {
            outside += 1.0;
            continue;
        };
        if s.delta {
            outside += 1.0;
            continue;
        }
        let pdf = m.pdf(s.wi, wo);
        consistency = consistency.max(rel_gap(s.pdf, pdf, 1e-12));
        let f = eval(s.wi, wo);
        for c in 0..3 {
            let expect = f[c] * s.wi.z / s.pdf;
            consistency = consistency.max(rel_gap(s.weight[c], expect, 1e-9));
        }
        let mu = s.wi.z.clamp(0.0, 1.0);
        let mut phi = s.wi.y.atan2(s.wi.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let i = ((mu * nt as f64) as usize).min(nt - 1);
        let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
        observed[i * np + j] += 1.0;
    }
    let mut expected = vec![0.0f64; nt * np];
    for i in 0..nt {
        for j in 0..np {
            let mu = (i as f64 / nt as f64, (i + 1) as f64 / nt as f64);
            let ph = (2.0 * PI * j as f64 / np as f64, 2.0 * PI * (j + 1) as f64 / np as f64);
            expected[i * np + j] = n as f64 * cell_integral(m, wo, mu, ph, CELL_COUNT_TOLERANCE / n as f64);
        }
    }
    let total_expected: f64 = expected.iter().sum();
    let pdf_integral = total_expected / n as f64;
    let mut note = String::new();
    // Cells where the pdf integrates to zero but samples land: an outright failure.
    let impossible = observed.iter().zip(&expected).filter(|(o, e)| **o > 0.0 && **e == 0.0).count();
    if impossible > 0 {
        note = format!("{impossible} cells received samples where the pdf integrates to zero");
    }
    let mut bins: Vec<(f64, f64)> =
        observed.iter().copied().zip(expected.iter().copied()).filter(|(_, e)| *e > 0.0).collect();
    bins.push((outside, (n as f64 - total_expected).max(0.0)));
    bins.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (o, e) in bins {
        if e < 5.0 {
            pool_o += o;
            pool_e += e;
            if pool_e >= 5.0 {
                chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                dof += 1;
                pool_o = 0.0;
                pool_e = 0.0;
            }
        } else {
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof += 1;
    } else if pool_o > 0.0 {
        note = format!("{pool_o} samples in cells with no expected mass");
    }
    let dof = dof.saturating_sub(1).max(1);
    let p_value = if note.is_empty() { super::stats::chi2_sf(chi2, dof as f64) } else { 0.0 };
    Chi2Case {
        cos_theta: cos_o,
        phi: phi_o,
        samples: n,
        chi2,
        dof,
        p_value,
        pdf_integral,
        outside_fraction: outside / n as f64,
        sample_consistency: consistency,
        note,
    }
}
