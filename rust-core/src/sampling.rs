//! Warps from the unit square to directions, with their densities (solid angle).

use crate::frame::{basis_around, from_basis};
use crate::math::Vec3;
use crate::real::Real;

/// Largest `f32`/`f64` value below one: uniform numbers are clamped to it.
#[inline(always)]
#[must_use]
pub fn one_minus_epsilon<T: Real>() -> T {
    T::one() - T::epsilon() * T::of(0.5)
}

/// Maps the unit square to the unit disk, preserving area and stratification (Shirley-Chiu).
#[inline]
#[must_use]
pub fn concentric_disk<T: Real>(u1: T, u2: T) -> (T, T) {
    let two = T::of(2.0);
    let ox = two * u1 - T::one();
    let oy = two * u2 - T::one();
    if ox == T::zero() && oy == T::zero() {
        return (T::zero(), T::zero());
    }
    let quarter_pi = T::FRAC_PI_4();
    let (r, theta) =
        if ox.abs() > oy.abs() { (ox, quarter_pi * (oy / ox)) } else { (oy, T::FRAC_PI_2() - quarter_pi * (ox / oy)) };
    (r * theta.cos(), r * theta.sin())
}

/// Cosine-weighted hemisphere around z (Malley's method).
#[inline]
#[must_use]
pub fn cosine_hemisphere<T: Real>(u1: T, u2: T) -> Vec3<T> {
    let (x, y) = concentric_disk(u1, u2);
    let z = (T::one() - x * x - y * y).safe_sqrt();
    Vec3::new(x, y, z)
}

/// Density of [`cosine_hemisphere`]: `cos θ / π` above the surface, 0 below.
#[inline]
#[must_use]
pub fn cosine_hemisphere_pdf<T: Real>(cos_theta: T) -> T {
    if cos_theta > T::zero() {
        cos_theta * T::inv_pi()
    } else {
        T::zero()
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
