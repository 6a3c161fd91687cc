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
    let (sin_r, cos_r) = sin_cos_quarter_f32(r);
    // Quadrant q mod 4: 0 → (s, c), 1 → (c, −s), 2 → (−s, −c), 3 → (−c, s).
    let qm = q - (q * L::c(0.25)).floor_() * L::c(4.0);
    let odd = L::c(0.5).lt_(qm) & qm.lt_(L::c(1.5)) | L::c(2.5).lt_(qm);
    let (s0, c0) = (select(odd, cos_r, sin_r), select(odd, sin_r, cos_r));
    let sin_neg = L::c(1.5).lt_(qm);
    let cos_neg = L::c(0.5).lt_(qm) & qm.lt_(L::c(2.5));
    (select(sin_neg, -s0, s0), select(cos_neg, -c0, c0))
}

/// `(sin r, cos r)` for f32 lanes with |r| ≤ π/4 (no range reduction): the polynomials of
/// [`sin_cos_f32`].
#[inline(always)]
pub(crate) fn sin_cos_quarter_f32<L: Lanes>(r: L) -> (L, L) {
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
    (sin_r, cos_r)
}

/// `erfc(x)` for f32 lanes: `erfc(|x|) = t·e^{−x²}·e^{P(t)}`, `t = 1/(1 + |x|/2)`, with the
/// degree-9 Chebyshev-fitted `P` of Numerical Recipes (`erfcc`, fractional error < 1.2e-7 in
/// exact arithmetic), and `erfc(−x) = 2 − erfc(x)`. `e^{−x²}` is taken apart from `e^{P}`
/// with `x²` split exactly by an FMA, so large arguments lose no accuracy to the rounding
/// of `x²`. Measured against f64 `libm::erfc` (test `erfc_f32_error` in `lanes::x86`).
/// Underflows to 0 beyond |x| ≈ 9.2; NaN stays NaN.
#[inline(always)]
pub(crate) fn erfc_f32<L: Lanes>(x: L) -> L {
    gauss_erfc_f32(x).1
}

/// `(e^{−x²}, erfc(x))` for f32 lanes: [`erfc_f32`] and the Gaussian it contains, so a caller
/// that needs both (Beckmann's Smith `Λ`) pays for two `exp`s, not three. `e^{−x²} = e^{−hi}
/// e^{−lo}` with `x² = hi + lo` exactly (`|lo| ≤ ulp(hi)/2`), `e^{−lo}` taken as `1 − lo`
/// (relative error below `lo²/2 < 1e-12` where `e^{−x²}` is a normal f32): within 2 ulp of
/// the Gaussian, closer than `exp_f32(−x·x)`, which drops `lo`.
#[inline(always)]
pub(crate) fn gauss_erfc_f32<L: Lanes>(x: L) -> (L, L) {
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
    let gauss_hi = exp_f32(-hi);
    let r = t * gauss_hi * exp_f32(p - lo);
    let erfc = select(x.lt_(L::c(0.0)), L::c(2.0) - r, r);
    (gauss_hi.mul_add_(-lo, gauss_hi), erfc)
}

/// `ln x` for f32 lanes (Cephes `logf`): `x = m 2^e` with `m ∈ [√½, √2)`, a degree-9
/// polynomial for `ln(1 + (m − 1))`, then `e ln 2` in two parts. Positive normal `x` only
/// (the callers' arguments); measured against f64 (test `ln_erfinv_f32_error` below).
#[inline(always)]
pub(crate) fn ln_f32<L: Lanes>(x: L) -> L {
    let (m, e) = x.frexp_();
    let small = m.lt_(L::c(std::f64::consts::FRAC_1_SQRT_2));
    let e = select(small, e - L::c(1.0), e);
    let r = select(small, m + m, m) - L::c(1.0);
    let z = r * r;
    let mut p = L::c(7.037_683_629_2e-2);
    p = p.mul_add_(r, L::c(-1.151_461_031_0e-1));
    p = p.mul_add_(r, L::c(1.167_699_874_0e-1));
    p = p.mul_add_(r, L::c(-1.242_014_084_6e-1));
    p = p.mul_add_(r, L::c(1.424_932_278_7e-1));
    p = p.mul_add_(r, L::c(-1.666_805_766_5e-1));
    p = p.mul_add_(r, L::c(2.000_071_476_5e-1));
    p = p.mul_add_(r, L::c(-2.499_999_399_3e-1));
    p = p.mul_add_(r, L::c(3.333_333_117_4e-1));
    let mut y = p * r * z;
    y = e.mul_add_(L::c(-2.121_944_4e-4), y);
    y = z.mul_add_(L::c(-0.5), y);
    let y = r + y;
    e.mul_add_(L::c(0.693_359_375), y)
}

/// `erfinv(y)` for f32 lanes on `(−1, 1)`: Giles (2010), "Approximating the erfinv function"
/// (the single-precision branch pair, `w = −ln(1 − y²)` below or above 5). Measured against
/// f64 (test `ln_erfinv_f32_error` below).
#[inline(always)]
pub(crate) fn erfinv_f32<L: Lanes>(y: L) -> L {
    let w = -((L::c(1.0) - y) * (L::c(1.0) + y)).ln_();
    let central = w.lt_(L::c(5.0));
    let a = w - L::c(2.5);
    let mut p = L::c(2.810_226_36e-08);
    p = p.mul_add_(a, L::c(3.432_739_39e-07));
    p = p.mul_add_(a, L::c(-3.523_387_7e-06));
    p = p.mul_add_(a, L::c(-4.391_506_54e-06));
    p = p.mul_add_(a, L::c(0.000_218_580_87));
    p = p.mul_add_(a, L::c(-0.001_253_725_03));
    p = p.mul_add_(a, L::c(-0.004_177_681_64));
    p = p.mul_add_(a, L::c(0.246_640_727));
    p = p.mul_add_(a, L::c(1.501_409_41));
    let b = w.sqrt_() - L::c(3.0);
    let mut q = L::c(-0.000_200_214_257);
    q = q.mul_add_(b, L::c(0.000_100_950_558));
    q = q.mul_add_(b, L::c(0.001_349_343_22));
    q = q.mul_add_(b, L::c(-0.003_673_428_44));
    q = q.mul_add_(b, L::c(0.005_739_507_73));
    q = q.mul_add_(b, L::c(-0.007_622_461_3));
    q = q.mul_add_(b, L::c(0.009_438_870_47));
    q = q.mul_add_(b, L::c(1.001_674_06));
    q = q.mul_add_(b, L::c(2.832_976_82));
    select(central, p, q) * y
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
        if !crate::lanes::x86::avx2_or_allowed_skip("erfc_f32_error") {
            return;
        }
        // SAFETY: the features were detected above.
        let (rel, at, abs) = unsafe { erfc_errors() };
        eprintln!("erfc_f32: max relative error {rel:.3e} (at x = {at}), max absolute {abs:.3e}");
        assert!(rel < 1e-6 && abs < 3e-7, "{rel} at {at}, abs {abs}");
    }

    /// Largest relative error of `gauss_erfc_f32`'s Gaussian in AVX2 lanes against f64
    /// `exp(−x²)` on [−9.3, 9.3] (where `e^{−x²}` is a normal f32), the `x` there, and whether
    /// its `erfc` is `erfc_f32`'s bit for bit.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn gauss_errors() -> (f64, f64, bool) {
        let (mut rel, mut at, mut same) = (0.0f64, 0.0, true);
        let n = 200_000;
        for k in (0..n).step_by(8) {
            let xs: [f32; 8] = std::array::from_fn(|j| -9.3 + 18.6 * (k + j) as f32 / n as f32);
            let (mut gauss, mut erfc, mut alone) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
            let (g, e) = gauss_erfc_f32(F32x8::load(&xs));
            g.store(&mut gauss);
            e.store(&mut erfc);
            erfc_f32(F32x8::load(&xs)).store(&mut alone);
            for j in 0..8 {
                let x = f64::from(xs[j]);
                let want = (-x * x).exp();
                let e = (f64::from(gauss[j]) - want).abs() / want;
                if e > rel {
                    (rel, at) = (e, x);
                }
                same &= erfc[j].to_bits() == alone[j].to_bits();
            }
        }
        (rel, at, same)
    }

    #[test]
    fn gauss_erfc_f32_gives_the_gaussian_within_two_ulp_and_the_same_erfc() {
        if !crate::lanes::x86::avx2_or_allowed_skip("gauss_erfc_f32") {
            return;
        }
        // SAFETY: the features were detected above.
        let (rel, at, same) = unsafe { gauss_errors() };
        eprintln!("gauss_erfc_f32: Gaussian max relative error {rel:.3e} (at x = {at})");
        // 2 ulp of f32 at the bottom of a binade: 2 × 2⁻²³ = 2.4e-7 (measured: 1.17e-7 at
        // x = 3.81; `exp_f32(−x·x)`, which drops the low part of x², is off by up to x²·2⁻²⁴).
        assert!(rel < 2.4e-7, "{rel} at {at}");
        assert!(same, "erfc from gauss_erfc_f32 differs from erfc_f32");
    }

    /// Largest errors of `ln_f32` (relative, on [1e-30, 1e30]) and `erfinv_f32` (relative to
    /// the f64 `special::erfinv`, on (−1, 1) down to 1 − y = 2⁻²³) in AVX2 and AVX-512 lanes.
    fn ln_erfinv_errors<L: Lanes<Elem = f32>>() -> (f64, f64) {
        let (mut ln_err, mut erfinv_err) = (0.0f64, 0.0f64);
        let w = L::WIDTH;
        let n = 100_000;
        for k in (0..n).step_by(w) {
            let xs: Vec<f32> = (0..w).map(|j| 10f32.powf(-30.0 + 60.0 * (k + j) as f32 / n as f32)).collect();
            let l = L::from_fn(|j| xs[j]).ln_();
            for (j, &x) in xs.iter().enumerate() {
                let want = f64::from(x).ln();
                ln_err = ln_err.max((f64::from(l.lane(j)) - want).abs() / want.abs().max(1.0));
            }
            // y over (−1, 1), denser towards ±1: y = ±(1 − 2^−s), s ∈ (0, 23].
            let ys: Vec<f32> = (0..w)
                .map(|j| {
                    let t = (k + j) as f32 / n as f32;
                    let y = 1.0 - (-23.0 * (2.0 * t - 1.0).abs()).exp2();
                    if t < 0.5 {
                        -y
                    } else {
                        y
                    }
                })
                .collect();
            let e = L::from_fn(|j| ys[j]).erfinv_();
            for (j, &y) in ys.iter().enumerate() {
                let want = crate::special::erfinv(f64::from(y));
                if want != 0.0 {
                    erfinv_err = erfinv_err.max((f64::from(e.lane(j)) - want).abs() / want.abs());
                }
            }
        }
        (ln_err, erfinv_err)
    }

    #[target_feature(enable = "avx2,fma")]
    fn ln_erfinv_avx2() -> (f64, f64) {
        ln_erfinv_errors::<F32x8>()
    }

    #[target_feature(enable = "avx512f")]
    fn ln_erfinv_avx512() -> (f64, f64) {
        ln_erfinv_errors::<super::super::x86::F32x16>()
    }

    /// Measured: ln ≤ 7.5e-8 (relative to max(|ln x|, 1)); erfinv ≤ 2.5e-7 relative. Bounds:
    /// 2.4e-7 (2 ulp) and 1e-6.
    #[test]
    fn ln_erfinv_f32_error() {
        let mut results = Vec::new();
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            // SAFETY: the features were detected above.
            results.push(("avx2", unsafe { ln_erfinv_avx2() }));
        }
        if is_x86_feature_detected!("avx512f") {
            // SAFETY: the feature was detected above.
            results.push(("avx512", unsafe { ln_erfinv_avx512() }));
        }
        assert!(!results.is_empty(), "no SIMD level to test on this CPU");
        for (level, (ln_err, erfinv_err)) in results {
            eprintln!("{level}: ln max error {ln_err:.3e}, erfinv max relative error {erfinv_err:.3e}");
            assert!(ln_err <= 2.4e-7, "{level} ln: {ln_err:e}");
            assert!(erfinv_err <= 1e-6, "{level} erfinv: {erfinv_err:e}");
        }
    }
}
