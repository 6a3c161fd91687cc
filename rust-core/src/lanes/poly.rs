//! Polynomial `exp` and `sin`/`cos` in `f32` lanes, written once against [`Lanes`] so every
//! SIMD type gets them (the scalar types use `std`). Errors against `f64`, measured by the
//! tests in `lanes::x86`: `exp` ≤ 2 ulp, `sin`/`cos` ≤ 2e-7 absolute on |x| ≤ 100.

use super::{select, Lanes};

/// `e^x` for f32 lanes (Cephes `expf`): `x = k ln 2 + r`, |r| ≤ ln 2 / 2, a degree-7
/// polynomial for `e^r`, then `2^k`. Underflows to 0 below −87.3, overflows to +∞ above 88.7.
#[inline(always)]
pub(crate) fn exp_f32<L: Lanes>(x: L) -> L {
    let hi = L::c(88.722_84);
    let lo = L::c(-87.336_55);
    let xc = x.max_(lo).min_(hi);
    let k = xc.mul_add_(L::c(std::f64::consts::LOG2_E), L::c(0.5)).floor_();
    // Cody-Waite: ln 2 split so that k·C1 is exact.
    let r = k.mul_add_(L::c(-0.693_359_375), xc);
    let r = k.mul_add_(L::c(2.121_944_4e-4), r);
    let mut p = L::c(1.987_569_15e-4);
    p = p.mul_add_(r, L::c(1.398_199_95e-3));
    p = p.mul_add_(r, L::c(8.333_451_9e-3));
    p = p.mul_add_(r, L::c(4.166_579_6e-2));
    p = p.mul_add_(r, L::c(1.666_666_55e-1));
    p = p.mul_add_(r, L::c(5.000_000_12e-1));
    let y = (p * r).mul_add_(r, r) + L::c(1.0);
    let y = y.ldexp_(k);
    let y = select(x.lt_(lo), L::c(0.0), y);
    let y = select(hi.lt_(x), L::c(f64::INFINITY), y);
    // NaN stays NaN (every comparison above is false for it; the clamps are not).
    select(x.eq_(x), y, x)
}

/// `(sin x, cos x)` for f32 lanes: `x = q π/2 + r` (three-part Cody-Waite), minimax-grade
/// Taylor polynomials on |r| ≤ π/4, then the quadrant's swap and signs.
#[inline(always)]
pub(crate) fn sin_cos_f32<L: Lanes>(x: L) -> (L, L) {
    let q = x.mul_add_(L::c(std::f64::consts::FRAC_2_PI), L::c(0.5)).floor_();
    let r = q.mul_add_(L::c(-1.570_312_5), x);
    let r = q.mul_add_(L::c(-4.837_512_97e-4), r);
    let r = q.mul_add_(L::c(-7.549_789_95e-8), r);
    let r2 = r * r;
    // sin r = r (1 − r²/6 + r⁴/120 − r⁶/5040 + r⁸/362880), cos r to r¹⁰.
    let mut s = L::c(2.755_731_9e-6);
    s = s.mul_add_(r2, L::c(-1.984_127e-4));
    s = s.mul_add_(r2, L::c(8.333_333_3e-3));
    s = s.mul_add_(r2, L::c(-1.666_666_7e-1));
    let sin_r = (s * r2).mul_add_(r, r);
    let mut c = L::c(-2.755_731_9e-7);
    c = c.mul_add_(r2, L::c(2.480_158_7e-5));
    c = c.mul_add_(r2, L::c(-1.388_888_9e-3));
    c = c.mul_add_(r2, L::c(4.166_666_6e-2));
    c = c.mul_add_(r2, L::c(-0.5));
    let cos_r = c.mul_add_(r2, L::c(1.0));
    // Quadrant q mod 4: 0 → (s, c), 1 → (c, −s), 2 → (−s, −c), 3 → (−c, s).
    let qm = q - (q * L::c(0.25)).floor_() * L::c(4.0);
    let odd = L::c(0.5).lt_(qm) & qm.lt_(L::c(1.5)) | L::c(2.5).lt_(qm);
    let (s0, c0) = (select(odd, cos_r, sin_r), select(odd, sin_r, cos_r));
    let sin_neg = L::c(1.5).lt_(qm);
    let cos_neg = L::c(0.5).lt_(qm) & qm.lt_(L::c(2.5));
    (select(sin_neg, -s0, s0), select(cos_neg, -c0, c0))
}
