//! Warps from the unit square to directions, with their densities (solid angle).

use crate::frame::{basis_around, from_basis};
use crate::lanes::{self, Lanes};
use crate::math::Vec3;
use crate::real::Real;

/// Largest `f32`/`f64` value below one: uniform numbers are clamped to it.
#[inline(always)]
#[must_use]
pub fn one_minus_epsilon<T: Real>() -> T {
    T::one() - T::epsilon() * T::of(0.5)
}

/// Maps the unit square to the unit disk, preserving area and stratification (Shirley-Chiu).
#[inline(always)]
#[must_use]
pub fn concentric_disk<T: Lanes>(u1: T, u2: T) -> (T, T) {
    let two = T::c(2.0);
    let ox = two * u1 - T::c(1.0);
    let oy = two * u2 - T::c(1.0);
    let wide = lanes::gt(lanes::abs(ox), lanes::abs(oy));
    // The radius is the larger coordinate, the angle `φ = π/4 · smaller/larger` from its axis
    // (|φ| ≤ π/4): θ = φ where |ox| > |oy|, else θ = π/2 − φ, whose sine and cosine are φ's
    // swapped. One division, and sin/cos without range reduction.
    let (r, other) = (lanes::select(wide, ox, oy), lanes::select(wide, oy, ox));
    let (sin_phi, cos_phi) = lanes::sin_cos_quarter(T::c(std::f64::consts::FRAC_PI_4) * (other / r));
    let (cos_t, sin_t) = (lanes::select(wide, cos_phi, sin_phi), lanes::select(wide, sin_phi, cos_phi));
    let centre = lanes::eq(ox, T::c(0.0)) & lanes::eq(oy, T::c(0.0));
    (lanes::keep(!centre, r * cos_t), lanes::keep(!centre, r * sin_t))
}

/// Inverse of [`concentric_disk`]: the point of the unit square that maps to `(x, y)` on the
/// unit disk. Equal-area like the forward map, so a uniform grid on the square is a grid of
/// equal-area, nearly square cells on the disk.
#[inline]
#[must_use]
pub fn concentric_disk_inverse<T: Real>(x: T, y: T) -> (T, T) {
    let r = (x * x + y * y).sqrt();
    if !(r > T::zero()) {
        return (T::of(0.5), T::of(0.5));
    }
    let four_over_pi = T::of(4.0) * T::FRAC_1_PI();
    // Forward: |a| ≥ |b| gives (a cos θ, a sin θ) with θ = π/4 · b/a ∈ [−π/4, π/4], so
    // |x| ≥ |y| and sign(x) = sign(a); otherwise θ = π/2 − π/4 · a/b and sign(y) = sign(b).
    let (a, b) = if x.abs() >= y.abs() {
        let a = if x < T::zero() { -r } else { r };
        (a, a * (y / x).atan() * four_over_pi)
    } else {
        let b = if y < T::zero() { -r } else { r };
        (b * (x / y).atan() * four_over_pi, b)
    };
    let half = T::of(0.5);
    ((a + T::one()) * half, (b + T::one()) * half)
}

/// Cosine-weighted hemisphere around z (Malley's method).
#[inline(always)]
#[must_use]
pub fn cosine_hemisphere<T: Lanes>(u1: T, u2: T) -> Vec3<T> {
    let (x, y) = concentric_disk(u1, u2);
    let z = lanes::safe_sqrt(T::c(1.0) - x * x - y * y);
    Vec3::new(x, y, z)
}

/// Density of [`cosine_hemisphere`]: `cos θ / π` above the surface, 0 below.
#[inline(always)]
#[must_use]
pub fn cosine_hemisphere_pdf<T: Lanes>(cos_theta: T) -> T {
    lanes::keep(lanes::gt(cos_theta, T::c(0.0)), cos_theta * T::c(std::f64::consts::FRAC_1_PI))
}

/// Uniform direction on the upper hemisphere.
#[inline]
#[must_use]
pub fn uniform_hemisphere<T: Real>(u1: T, u2: T) -> Vec3<T> {
    let z = u1;
    let r = (T::one() - z * z).safe_sqrt();
    let phi = T::of(2.0) * T::PI() * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_hemisphere`]: `1 / 2π`.
#[inline]
#[must_use]
pub fn uniform_hemisphere_pdf<T: Real>() -> T {
    T::one() / (T::of(2.0) * T::PI())
}

/// Direction with density `(n + 1)/(2π) · cosⁿ α` around the unit `axis`, α the angle to
/// the axis (the Phong lobe, Lafortune & Willems 1994). Directions may fall below the surface.
#[inline]
#[must_use]
pub fn power_cosine_around<T: Real>(axis: Vec3<T>, exponent: T, u1: T, u2: T) -> Vec3<T> {
    // cos α = u^(1/(n+1)) computed via exp/log so huge exponents stay accurate.
    let cos_a = (u1.max(T::min_positive_value()).ln() / (exponent + T::one())).exp();
    let sin_a = (T::one() - cos_a * cos_a).safe_sqrt();
    let phi = T::of(2.0) * T::PI() * u2;
    let local = Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a);
    let (s, t) = basis_around(axis);
    from_basis(local, s, t, axis)
}

/// Density of [`power_cosine_around`] for a direction with `cos α` to the axis.
#[inline]
#[must_use]
pub fn power_cosine_pdf<T: Real>(exponent: T, cos_alpha: T) -> T {
    if cos_alpha <= T::zero() {
        return T::zero();
    }
    (exponent + T::one()) * T::inv_pi() * T::of(0.5) * cos_alpha.powf(exponent)
}

/// `cosⁿ α` from the versine `v = 1 − cos α` (see [`crate::frame::versine_between`]):
/// `exp(n·ln(1 − v))`, exact to a few ulps of `v` even for n = 10⁴ in f32, where `powf` of a
/// rounded cosine is off by `n·ε`. Zero when `cos α ≤ 0` (`v ≥ 1`), one when `n = 0` and
/// `cos α > 0`; never above one.
#[inline]
#[must_use]
pub fn cos_pow_versine<T: Real>(versine: T, exponent: T) -> T {
    if !(versine < T::one()) {
        return T::zero();
    }
    if exponent == T::zero() {
        return T::one();
    }
    (exponent * (-versine.max(T::zero())).ln_1p()).exp()
}

/// Density of [`power_cosine_around`] for a direction whose angle α to the axis has the
/// versine `v = 1 − cos α`: `(n + 1)/(2π) · cosⁿ α` via [`cos_pow_versine`].
#[inline]
#[must_use]
pub fn power_cosine_pdf_versine<T: Real>(exponent: T, versine: T) -> T {
    (exponent + T::one()) * T::inv_pi() * T::of(0.5) * cos_pow_versine(versine, exponent)
}

/// Balance heuristic weight of strategy `a` against strategy `b` (one sample each).
#[inline]
#[must_use]
pub fn balance_heuristic<T: Real>(pdf_a: T, pdf_b: T) -> T {
    let s = pdf_a + pdf_b;
    if s > T::zero() {
        pdf_a / s
    } else {
        T::zero()
    }
}

/// Power heuristic (β = 2) weight of strategy `a` against strategy `b` (one sample each).
#[inline]
#[must_use]
pub fn power_heuristic<T: Real>(pdf_a: T, pdf_b: T) -> T {
    if !(pdf_a > T::zero()) {
        return T::zero();
    }
    // Written as a ratio so that neither tiny nor huge densities under- or overflow.
    let r = pdf_b.max(T::zero()) / pdf_a;
    if r.is_nan() {
        return T::of(0.5); // both infinite
    }
    T::one() / (T::one() + r * r)
}

/// Chooses one of several lobes from their selection weights using `u`; returns the index
/// and `u` rescaled to `[0, 1)` for reuse. Weights need not be normalised.
#[inline]
#[must_use]
pub fn pick_lobe<T: Real>(weights: &[T], u: T) -> Option<(usize, T)> {
    let total = weights.iter().fold(T::zero(), |a, &w| a + w);
    if !(total > T::zero()) {
        return None;
    }
    let target = u * total;
    let mut acc = T::zero();
    for (i, &w) in weights.iter().enumerate() {
        if w > T::zero() && (target < acc + w || i + 1 == weights.len()) {
            let remapped = ((target - acc) / w).clamp_to(T::zero(), one_minus_epsilon());
            return Some((i, remapped));
        }
        acc += w;
    }
    // Rounding left `target` past the last positive weight.
    let last = weights.iter().rposition(|&w| w > T::zero())?;
    Some((last, one_minus_epsilon()))
}

/// Point `k` of an `n`-point 3-D Halton-Hammersley set: `[(k + ½)/n, Φ₂(k), Φ₃(k)]`. Used by
/// precomputed tables and the furnace check: stratified in every dimension, so an integrand
/// with a kink (e.g. a critical angle) is not aliased.
#[inline]
#[must_use]
pub fn hammersley3(k: usize, n: usize) -> [f64; 3] {
    let mut base3 = 0.0;
    let mut inv = 1.0 / 3.0;
    let mut i = k;
    while i > 0 {
        base3 += (i % 3) as f64 * inv;
        i /= 3;
        inv /= 3.0;
    }
    [(k as f64 + 0.5) / n as f64, radical_inverse(k as u32), base3]
}

/// Base-2 radical inverse (van der Corput) of `i`: a deterministic low-discrepancy jitter used
/// by the material's precomputed tables.
#[inline]
#[must_use]
pub fn radical_inverse(i: u32) -> f64 {
    i.reverse_bits() as f64 * (1.0 / 4_294_967_296.0)
}

/// A 1-D density on `[0, 1]` proportional to the linear interpolation of non-negative values at
/// evenly spaced nodes `x_k = k/(n−1)`, sampled exactly (per segment, the inverse of a quadratic
/// CDF). Used for tabulated lobes (Bishop & Weimer's fast Phong).
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseLinear {
    values: Vec<f64>,
    /// `cdf[k]` = unnormalised integral over `[0, x_k]`; `cdf[0] = 0`.
    cdf: Vec<f64>,
}

impl PiecewiseLinear {
    /// A distribution from node values; `None` unless there are at least two values, all finite
    /// and non-negative, with a positive integral.
    #[must_use]
    pub fn new(values: Vec<f64>) -> Option<Self> {
        if values.len() < 2 || values.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return None;
        }
        let h = 1.0 / (values.len() - 1) as f64;
        let mut cdf = Vec::with_capacity(values.len());
        let mut acc = 0.0;
        cdf.push(0.0);
        for w in values.windows(2) {
            acc += 0.5 * h * (w[0] + w[1]);
            cdf.push(acc);
        }
        (acc > 0.0).then_some(Self { values, cdf })
    }

    /// Node values.
    #[must_use]
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// `∫₀¹ L(x) dx` of the interpolant `L`.
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.cdf[self.cdf.len() - 1]
    }

    /// `∫₀¹ L(x) x dx`, exactly for the piecewise-linear interpolant.
    #[must_use]
    pub fn first_moment(&self) -> f64 {
        let h = 1.0 / (self.values.len() - 1) as f64;
        self.values
            .windows(2)
            .enumerate()
            .map(|(k, w)| {
                let (x0, x1) = (k as f64 * h, (k + 1) as f64 * h);
                h * (w[0] * (2.0 * x0 + x1) + w[1] * (x0 + 2.0 * x1)) / 6.0
            })
            .sum()
    }

    /// The interpolant `L(x)`; zero outside `[0, 1]`.
    #[inline]
    #[must_use]
    pub fn eval<T: Real>(&self, x: T) -> T {
        if !(x >= T::zero() && x <= T::one()) {
            return T::zero();
        }
        let last = self.values.len() - 1;
        let pos = x * T::of(last as f64);
        let k = pos.floor().to_usize().unwrap_or(0).min(last - 1);
        let t = pos - T::of(k as f64);
        let (a, b) = (T::of(self.values[k]), T::of(self.values[k + 1]));
        (a + (b - a) * t).max(T::zero())
    }

    /// Density of [`Self::sample`]: `L(x) / ∫L`.
    #[inline]
    #[must_use]
    pub fn pdf<T: Real>(&self, x: T) -> T {
        self.eval(x) / T::of(self.integral())
    }

    /// Draws `x ∈ [0, 1]` with density [`Self::pdf`] from a uniform `u ∈ [0, 1)`.
    #[inline]
    #[must_use]
    pub fn sample<T: Real>(&self, u: T) -> T {
        let last = self.values.len() - 1;
        let target = u.clamp_to(T::zero(), one_minus_epsilon()) * T::of(self.integral());
        // Segment k with cdf[k] ≤ target < cdf[k + 1], skipping empty segments.
        let k = self.cdf.partition_point(|&c| T::of(c) <= target).clamp(1, last) - 1;
        let h = T::of(1.0 / last as f64);
        let (a, b) = (T::of(self.values[k]), T::of(self.values[k + 1]));
        // Area r/h on the unit segment: a t + (b − a) t²/2 = r/h; the stable root of the quadratic.
        let r = ((target - T::of(self.cdf[k])) / h).max(T::zero());
        let disc = (a * a + T::of(2.0) * (b - a) * r).max(T::zero());
        let denom = a + disc.sqrt();
        let t = if denom > T::zero() { (T::of(2.0) * r / denom).clamp_to(T::zero(), T::one()) } else { T::zero() };
        ((T::of(k as f64) + t) * h).clamp_to(T::zero(), T::one())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse concentric map undoes the forward map everywhere on the square, including
    /// the diagonals and the edges where the forward map switches branches.
    #[test]
    fn concentric_disk_inverse_round_trips() {
        let n = 41;
        for i in 0..=n {
            for j in 0..=n {
                let (u1, u2) = (i as f64 / n as f64, j as f64 / n as f64);
                let (x, y) = concentric_disk(u1, u2);
                assert!(x * x + y * y <= 1.0 + 1e-12);
                let (v1, v2) = concentric_disk_inverse(x, y);
                assert!((v1 - u1).abs() < 1e-12 && (v2 - u2).abs() < 1e-12, "({u1}, {u2}) -> ({v1}, {v2})");
            }
        }
        assert_eq!(concentric_disk_inverse(0.0f64, 0.0), (0.5, 0.5));
    }

    #[test]
    fn cos_pow_versine_matches_powf_and_handles_edges() {
        for (c, n) in [(0.9f64, 3.0f64), (0.5, 0.5), (0.999, 1000.0), (0.2, 0.0)] {
            let got = cos_pow_versine(1.0 - c, n);
            assert!((got - c.powf(n)).abs() <= 1e-12 * c.powf(n).max(1e-300), "{c} {n}: {got}");
        }
        assert_eq!(cos_pow_versine(1.0f64, 0.0), 0.0);
        assert_eq!(cos_pow_versine(1.5f64, 2.0), 0.0);
        assert_eq!(cos_pow_versine(0.0f32, 1e4), 1.0);
        // f32 with n = 10⁴ at an angle of 0.01 rad: cos¹⁰⁰⁰⁰ = e^{−0.5}·(1 + O(1e−5)).
        let v = 1.0 - 0.01f64.cos();
        let exact = (1e4 * (1.0 - v).ln()).exp();
        let got = cos_pow_versine(v as f32, 1e4f32) as f64;
        assert!((got - exact).abs() < 1e-5 * exact, "{got} vs {exact}");
        // Density normalisation: ∫ (n+1)/(2π) cosⁿα dω over the cap = 1 (midpoint rule in cos α).
        let n = 7.0;
        let m = 20_000;
        let s: f64 = (0..m)
            .map(|i| {
                let c = (i as f64 + 0.5) / m as f64;
                power_cosine_pdf_versine(n, 1.0 - c) * 2.0 * std::f64::consts::PI / m as f64
            })
            .sum();
        assert!((s - 1.0).abs() < 1e-6, "{s}");
    }

    #[test]
    fn piecewise_linear_moments_and_sampling() {
        // L(x) = x on one segment: ∫ = 1/2, ∫ x L = 1/3; samples x = √u.
        let d = PiecewiseLinear::new(vec![0.0, 1.0]).unwrap();
        assert!((d.integral() - 0.5).abs() < 1e-15 && (d.first_moment() - 1.0 / 3.0).abs() < 1e-15);
        for u in [0.0f64, 0.1, 0.49, 0.81, 0.999] {
            assert!((d.sample(u) - u.sqrt()).abs() < 1e-12, "{u}");
        }
        // A table with empty segments: samples never fall where L = 0; CDF matches.
        let d = PiecewiseLinear::new(vec![0.0, 0.0, 2.0, 1.0, 0.0, 0.0]).unwrap();
        let total = d.integral();
        for i in 0..1000 {
            let u = (i as f64 + 0.5) / 1000.0;
            let x: f64 = d.sample(u);
            assert!(d.eval(x) > 0.0 || x == 0.2 || x == 0.8, "{x}");
            // CDF at x by integrating the interpolant numerically.
            let m = 4000;
            let cdf: f64 = (0..m).map(|j| d.eval((j as f64 + 0.5) / m as f64 * x) * x / m as f64).sum();
            assert!((cdf / total - u).abs() < 1e-5, "u={u} x={x} cdf={}", cdf / total);
        }
        assert!(PiecewiseLinear::new(vec![0.0, 0.0]).is_none());
        assert!(PiecewiseLinear::new(vec![1.0]).is_none());
        assert!(PiecewiseLinear::new(vec![1.0, -1.0]).is_none());
        // f32 agrees with f64.
        let d = PiecewiseLinear::new((0..256).map(|k| (k as f64 / 255.0).powi(40)).collect()).unwrap();
        for u in [0.01f64, 0.3, 0.77, 0.9999] {
            let (a, b) = (d.sample(u), d.sample(u as f32) as f64);
            assert!((a - b).abs() < 1e-5, "{a} {b}");
        }
    }

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0f64, 3.0), (0.2, 0.0), (5e-200, 7e-200), (1e200, 1.0)] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((s - 1.0).abs() < 1e-12, "{a} {b}: {s}");
        }
        assert_eq!(power_heuristic(1.0f64, 3.0), 0.1);
        assert_eq!(power_heuristic(0.0f64, 0.0), 0.0);
    }
}
