//! Polynomial `exp` and `sin`/`cos` in `f32` lanes, written once against [`Lanes`] so every
//! SIMD type gets them (the scalar types use `std`). Errors against `f64`, measured by the
//! tests in `lanes::x86`: `exp` ≤ 2 ulp, `sin`/`cos` ≤ 2e-7 absolute on |x| ≤ 100, `erfc`
//! (test `erfc_f32_error` there) see [`erfc_f32`].

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

/// `erfc(x)` for f32 lanes: `erfc(|x|) = t·e^{−x²}·e^{P(t)}`, `t = 1/(1 + |x|/2)`, with the
/// degree-9 Chebyshev-fitted `P` of Numerical Recipes (`erfcc`, fractional error < 1.2e-7 in
/// exact arithmetic), and `erfc(−x) = 2 − erfc(x)`. `e^{−x²}` is taken apart from `e^{P}`
/// with `x²` split exactly by an FMA, so large arguments lose no accuracy to the rounding
/// of `x²`. Measured against f64 `libm::erfc` (test `erfc_f32_error` in `lanes::x86`).
/// Underflows to 0 beyond |x| ≈ 9.2; NaN stays NaN.
#[inline(always)]
pub(crate) fn erfc_f32<L: Lanes>(x: L) -> L {
    let z = x.abs_();
    let t = L::c(1.0) / z.mul_add_(L::c(0.5), L::c(1.0));
    let mut p = L::c(0.170_872_77);
    p = p.mul_add_(t, L::c(-0.822_152_23));
    p = p.mul_add_(t, L::c(1.488_515_87));
    p = p.mul_add_(t, L::c(-1.135_203_98));
    p = p.mul_add_(t, L::c(0.278_868_07));
    p = p.mul_add_(t, L::c(-0.186_288_06));
    p = p.mul_add_(t, L::c(0.096_784_18));
    p = p.mul_add_(t, L::c(0.374_091_96));
    p = p.mul_add_(t, L::c(1.000_023_68));
    p = p.mul_add_(t, L::c(-1.265_512_23));
    // x² = hi + lo exactly (lo from the FMA): e^{−x²} = e^{−hi} e^{−lo}, lo folded into P.
    let hi = z * z;
    let lo = z.mul_add_(z, -hi);
    let r = t * exp_f32(-hi) * exp_f32(p - lo);
    select(x.lt_(L::c(0.0)), L::c(2.0) - r, r)
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::x86::F32x8;
    use super::*;

    /// Largest relative error of `erfc_f32` in AVX2 lanes against f64 `libm::erfc` on
    /// [−4, 9] (where erfc ≥ 1e-37, a normal f32), and the largest absolute error.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn erfc_errors() -> (f64, f64, f64) {
        let (mut rel, mut at, mut abs) = (0.0f64, 0.0, 0.0f64);
        let n = 200_000;
        for k in (0..n).step_by(8) {
            let xs: [f32; 8] = std::array::from_fn(|j| -4.0 + 13.0 * (k + j) as f32 / n as f32);
            let mut out = [0.0f32; 8];
            erfc_f32(F32x8::load(&xs)).store(&mut out);
            for j in 0..8 {
                let want = libm::erfc(f64::from(xs[j]));
                let e = (f64::from(out[j]) - want).abs() / want;
                if e > rel {
                    (rel, at) = (e, f64::from(xs[j]));
                }
                abs = abs.max((f64::from(out[j]) - want).abs());
            }
        }
        (rel, at, abs)
    }

    #[test]
    fn erfc_f32_error() {
        if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")) {
            return;
        }
        // SAFETY: the features were detected above.
        let (rel, at, abs) = unsafe { erfc_errors() };
        eprintln!("erfc_f32: max relative error {rel:.3e} (at x = {at}), max absolute {abs:.3e}");
        assert!(rel < 1e-6 && abs < 3e-7, "{rel} at {at}, abs {abs}");
    }
}
