//! Importance sampling of a tabulated isotropic BRDF with tabulated marginal and conditional
//! distributions.
//!
//! For each of `N_OUT + 1` outgoing polar angles `θo` (nodes uniform over `[0, π/2]`, `φo = 0`)
//! the density `q(θi, φ) = f̄(wi, wo) cos θi sin θi` (`f̄` the mean of the three channels, `φ`
//! the azimuth of `wi` relative to `wo`) is tabulated on a grid of `(N_THETA + 1) × N_PHI`
//! nodes and interpolated *bilinearly* (periodic in `φ`). Sampling inverts the piecewise-linear
//! marginal in `θi` and then the piecewise-linear conditional in `φ` at the sampled `θi`
//! (blended row CDFs, one quadratic solve each), in the manner of the piecewise-linear 2D
//! distributions of Mitsuba 3 (`Marginal2D`) and pbrt-v4 (`PiecewiseLinear2D`).
//! The density in solid angle is `q / (∫q · sin θi)`; because `q` is continuous, so is the pdf.
//! Between two `θo` nodes the sampler is the mixture of the two node distributions with
//! linear weights (`u[0]` picks the node), and `pdf` returns that mixture.
//!
//! A floor of `1e-3` × the node's mean value is added to `f̄` so every direction where the
//! table may be non-zero keeps a positive density.

use super::parameterization::{polar, spherical, HALF_PI};
use crate::math::Vec3;
use std::f64::consts::PI;

/// Intervals in `θo`.
pub const N_OUT: usize = 30;
/// Intervals in `θi`.
pub const N_THETA: usize = 90;
/// Intervals (and nodes) in the relative azimuth `φ ∈ [0, 2π)`.
pub const N_PHI: usize = 180;

const D_OUT: f64 = HALF_PI / N_OUT as f64;
const D_THETA: f64 = HALF_PI / N_THETA as f64;
const D_PHI: f64 = 2.0 * PI / N_PHI as f64;
const ROW: usize = N_PHI + 1;

/// The tabulated distributions of one `θo` node.
#[derive(Clone)]
struct Slice {
    /// `q` at `(θ node k, φ node j)`: `k·N_PHI + j`.
    q: Vec<f64>,
    /// Row CDFs `R_k(φ_j)`, `j = 0..=N_PHI`: `k·ROW + j`.
    row_cdf: Vec<f64>,
    /// Marginal CDF over `θ` nodes `k = 0..=N_THETA`.
    marginal_cdf: Vec<f64>,
    /// `m_k = ∫ q(θ_k, φ) dφ`.
    marginal: Vec<f64>,
}

/// Samples `(θ, φ)` offsets inside an interval whose density is linear from `a` to `b`:
/// returns the fraction `t ∈ [0, 1]` with `a t + (b − a) t²/2 = r` (`r` in units of the
/// interval width).
#[inline]
fn invert_linear(a: f64, b: f64, r: f64) -> f64 {
    let disc = (a * a + 2.0 * (b - a) * r).max(0.0);
    let den = a + disc.sqrt();
    if den > 0.0 {
        (2.0 * r / den).clamp(0.0, 1.0)
    } else {
        0.5
    }
}

/// Largest `i` with `cdf[i] ≤ x` (clamped to `[0, len − 2]`).
#[inline]
fn find_interval(len: usize, x: f64, cdf: impl Fn(usize) -> f64) -> usize {
    let (mut lo, mut hi) = (0usize, len - 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if cdf(mid) <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

impl Slice {
    fn build(theta_o: f64, f: &impl Fn(Vec3<f64>, Vec3<f64>) -> f64) -> Self {
        let wo = spherical(theta_o, 0.0);
        let mut fbar = vec![0.0; (N_THETA + 1) * N_PHI];
        for k in 0..=N_THETA {
            let theta = k as f64 * D_THETA;
            for j in 0..N_PHI {
                let wi = spherical(theta, j as f64 * D_PHI);
                let v = if wi.z > 0.0 { f(wi, wo) } else { 0.0 };
                fbar[k * N_PHI + j] = if v.is_finite() && v > 0.0 { v } else { 0.0 };
            }
        }
        let mean = fbar.iter().sum::<f64>() / fbar.len() as f64;
        let floor = 1e-3 * mean + 1e-12;
        let mut q = vec![0.0; fbar.len()];
        for k in 0..=N_THETA {
            let theta = k as f64 * D_THETA;
            // Exact zeros at the pole and the horizon keep the pdf continuous and finite.
            let jac = if k == 0 || k == N_THETA { 0.0 } else { theta.cos() * theta.sin() };
            for j in 0..N_PHI {
                q[k * N_PHI + j] = (fbar[k * N_PHI + j] + floor) * jac;
            }
        }
        let mut row_cdf = vec![0.0; (N_THETA + 1) * ROW];
        let mut marginal = vec![0.0; N_THETA + 1];
        for k in 0..=N_THETA {
            let mut acc = 0.0;
            for j in 0..N_PHI {
                let (a, b) = (q[k * N_PHI + j], q[k * N_PHI + (j + 1) % N_PHI]);
                acc += 0.5 * D_PHI * (a + b);
                row_cdf[k * ROW + j + 1] = acc;
            }
            marginal[k] = acc;
        }
        let mut marginal_cdf = vec![0.0; N_THETA + 1];
        for k in 0..N_THETA {
            marginal_cdf[k + 1] = marginal_cdf[k] + 0.5 * D_THETA * (marginal[k] + marginal[k + 1]);
        }
        Self { q, row_cdf, marginal_cdf, marginal }
    }

    fn total(&self) -> f64 {
        self.marginal_cdf[N_THETA]
    }

    /// `(θ, φ)` from two uniform numbers.
    fn sample(&self, u1: f64, u2: f64) -> (f64, f64) {
        let r = u1 * self.total();
        let k = find_interval(N_THETA + 1, r, |i| self.marginal_cdf[i]);
        let t = invert_linear(self.marginal[k], self.marginal[k + 1], (r - self.marginal_cdf[k]) / D_THETA);
        let theta = (k as f64 + t) * D_THETA;
        let blend = |j: usize| (1.0 - t) * self.row_cdf[k * ROW + j] + t * self.row_cdf[(k + 1) * ROW + j];
        let row_total = blend(N_PHI);
        if !(row_total > 0.0) {
            return (theta, u2 * 2.0 * PI);
        }
        let r2 = u2 * row_total;
        let j = find_interval(ROW, r2, blend);
        let g = |jj: usize| {
            let jj = jj % N_PHI;
            (1.0 - t) * self.q[k * N_PHI + jj] + t * self.q[(k + 1) * N_PHI + jj]
        };
        let s = invert_linear(g(j), g(j + 1), (r2 - blend(j)) / D_PHI);
        (theta, (j as f64 + s) * D_PHI)
    }

    /// Solid-angle density at `(θ, φ)`.
    fn pdf(&self, theta: f64, phi: f64) -> f64 {
        let total = self.total();
        if !(total > 0.0) {
            return 0.0;
        }
        let x = (theta / D_THETA).clamp(0.0, N_THETA as f64);
        let k = (x as usize).min(N_THETA - 1);
        let t = x - k as f64;
        let y = (phi / D_PHI).clamp(0.0, N_PHI as f64);
        let j = (y as usize).min(N_PHI - 1);
        let s = y - j as f64;
        let row = |kk: usize| (1.0 - s) * self.q[kk * N_PHI + j] + s * self.q[kk * N_PHI + (j + 1) % N_PHI];
        if k == 0 {
            // Row 0 is zero: q = t·q1(φ) with t = θ/Δθ, and q / sin θ = q1(φ)/Δθ · θ/sin θ.
            let ratio = if theta < 1e-4 { 1.0 + theta * theta / 6.0 } else { theta / theta.sin() };
            return row(1) / D_THETA * ratio / total;
        }
        ((1.0 - t) * row(k) + t * row(k + 1)) / (theta.sin() * total)
    }
}

/// Tabulated sampler of an isotropic BRDF.
#[derive(Clone)]
pub struct TabulatedSampler {
    slices: Vec<Slice>,
}

impl std::fmt::Debug for TabulatedSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TabulatedSampler {{ {} θo nodes × {}×{} }}", N_OUT + 1, N_THETA + 1, N_PHI)
    }
}

/// The outgoing node pair and the weight of the upper one for `wo`.
#[inline]
fn out_nodes(wo: Vec3<f64>) -> (usize, f64) {
    let x = (polar(wo) / D_OUT).clamp(0.0, N_OUT as f64);
    let n = (x as usize).min(N_OUT - 1);
    (n, x - n as f64)
}

/// `θi` and `φi − φo` (in `[0, 2π)`) of `wi` relative to `wo`.
#[inline]
fn relative(wi: Vec3<f64>, wo: Vec3<f64>) -> (f64, f64) {
    let phi_o = if wo.x == 0.0 && wo.y == 0.0 { 0.0 } else { wo.y.atan2(wo.x) };
    let phi_i = if wi.x == 0.0 && wi.y == 0.0 { 0.0 } else { wi.y.atan2(wi.x) };
    (polar(wi), super::parameterization::wrap(phi_i - phi_o, 2.0 * PI))
}

impl TabulatedSampler {
    /// Tabulates the distributions of `f` (an isotropic BRDF; its mean channel value is used).
    #[must_use]
    pub fn build(f: impl Fn(Vec3<f64>, Vec3<f64>) -> f64 + Sync) -> Self {
        let slices = super::parallel_rows(N_OUT + 1, |n| Slice::build(n as f64 * D_OUT, &f));
        Self { slices }
    }

    /// Samples `wi` for `wo` (above the surface) from three uniform numbers.
    #[must_use]
    pub fn sample(&self, wo: Vec3<f64>, u: [f64; 3]) -> Vec3<f64> {
        let (n, w) = out_nodes(wo);
        let slice = if u[0] < 1.0 - w { &self.slices[n] } else { &self.slices[n + 1] };
        let (theta, phi) = slice.sample(u[1], u[2]);
        let phi_o = if wo.x == 0.0 && wo.y == 0.0 { 0.0 } else { wo.y.atan2(wo.x) };
        spherical(theta, phi + phi_o)
    }

    /// Solid-angle density of [`TabulatedSampler::sample`] choosing `wi` for `wo`.
    #[must_use]
    pub fn pdf(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
        let (n, w) = out_nodes(wo);
        let (theta, phi) = relative(wi, wo);
        let mut p = 0.0;
        if w < 1.0 {
            p += (1.0 - w) * self.slices[n].pdf(theta, phi);
        }
        if w > 0.0 {
            p += w * self.slices[n + 1].pdf(theta, phi);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn invert_linear_by_hand() {
        // Constant density: t = r/a.
        assert!((invert_linear(2.0, 2.0, 0.5) - 0.25).abs() < 1e-15);
        // Density rising from 0 to 2: CDF t², so r = 0.25 gives t = 0.5.
        assert!((invert_linear(0.0, 2.0, 0.25) - 0.5).abs() < 1e-15);
        // Falling from 2 to 0: CDF 2t − t², r = 0.75 gives t = 0.5.
        assert!((invert_linear(2.0, 0.0, 0.75) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn lambert_is_sampled_near_cosine_and_pdf_integrates_to_one() {
        let s = TabulatedSampler::build(|_, _| 1.0 / PI);
        let wo = spherical(0.5, 0.3);
        // ∫ pdf dω by midpoint rule.
        let (nt, np) = (400, 400);
        let mut integral = 0.0;
        for a in 0..nt {
            let mu = (a as f64 + 0.5) / nt as f64;
            for b in 0..np {
                let phi = (b as f64 + 0.5) / np as f64 * 2.0 * PI;
                integral += s.pdf(spherical(mu.acos(), phi), wo) / (nt * np) as f64 * 2.0 * PI;
            }
        }
        assert!((integral - 1.0).abs() < 2e-3, "∫pdf = {integral}");
        // The pdf is close to cos θ/π for a Lambertian table (the floor and the bilinear
        // interpolation of cos θ sin θ change it slightly).
        for theta in [0.05, 0.4, 1.0, 1.4] {
            let p = s.pdf(spherical(theta, 1.0), wo);
            assert!((p / (theta.cos() / PI) - 1.0).abs() < 0.01, "θ {theta}: {p}");
        }
        // Samples land where the pdf says: mean cos θ of a cosine lobe is 2/3.
        let mut rng = Pcg32::new(1, 1);
        let n = 200_000;
        let mean: f64 = (0..n).map(|_| s.sample(wo, rng.uniform3()).z).sum::<f64>() / n as f64;
        assert!((mean - 2.0 / 3.0).abs() < 5e-3, "{mean}");
    }
}
