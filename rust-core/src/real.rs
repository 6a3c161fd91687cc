//! The floating-point type every model is generic over.
//!
//! Each model is written once against [`Real`] and instantiated twice: `f64` is the
//! reference path, `f32` the fast path. The checks measure the distance between the two.

use num_traits::{Float, FloatConst};
use std::fmt::{Debug, Display};
use std::ops::{AddAssign, DivAssign, MulAssign, SubAssign};

/// A floating-point scalar (`f32` or `f64`) with the few conversions models need.
pub trait Real:
    Float + FloatConst + AddAssign + SubAssign + MulAssign + DivAssign + Debug + Display + Default + Send + Sync + 'static
{
    /// Converts an `f64` constant or parameter to this type (rounding for `f32`).
    fn of(x: f64) -> Self;
    /// Widens this value to `f64`.
    fn f64(self) -> f64;
    /// `1/π`.
    #[inline]
    fn inv_pi() -> Self {
        Self::FRAC_1_PI()
    }
    /// `sqrt(max(x, 0))`: a square root that tolerates rounding below zero.
    #[inline]
    fn safe_sqrt(self) -> Self {
        self.max(Self::zero()).sqrt()
    }
    /// Clamps to `[lo, hi]`; NaN stays NaN.
    #[inline]
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        if self < lo {
            lo
        } else if self > hi {
            hi
        } else {
            self
        }
    }
    /// `acos` of the argument clamped to `[-1, 1]`.
    #[inline]
    fn safe_acos(self) -> Self {
        self.clamp_to(-Self::one(), Self::one()).acos()
    }
    /// `x * x`.
    #[inline]
    fn sqr(self) -> Self {
        self * self
    }
}

impl Real for f32 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn f64(self) -> f64 {
        self as f64
    }
}

impl Real for f64 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn f64(self) -> f64 {
        self
    }
}
