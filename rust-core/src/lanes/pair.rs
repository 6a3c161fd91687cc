//! [`X2`]: two lane groups processed as one, every operation issued for both halves back to back.
//!
//! Some small lane models' SIMD kernels are latency-bound: one AVX2 group of the GGX sampler
//! executes ~376 instructions whose dependency chain (`llvm-mca -mcpu=znver3` of the loop:
//! 227 cycles per group against a resource bound of 92) keeps the out-of-order window from
//! reaching the next group. Two independent groups interleaved instruction by instruction (as
//! ISPC's double-pumped targets do) let the core overlap the two chains. The halves never
//! interact: lane `i < L::WIDTH` is lane `i` of the first half, the rest the second's.
//!
//! A model chooses which of its AVX2 kernels run on `X2<F32x8>`
//! ([`crate::bxdf::LaneBxdf::PAIRED`]): each paired kernel is a second, twice as long copy of
//! its lane code to compile, so only the kernels whose gain was measured are paired.

use super::{poly, Lanes, Mask};
use std::ops::{Add, AddAssign, BitAnd, BitOr, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign};

/// Two lane groups of `L` as one lane type of `2 · L::WIDTH` lanes.
#[derive(Clone, Copy, Debug)]
pub struct X2<L>(pub L, pub L);

/// The mask of [`X2`]: one mask per half.
#[derive(Clone, Copy, Debug)]
pub struct X2Mask<M>(pub M, pub M);

impl<M: Mask> BitAnd for X2Mask<M> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        Self(self.0 & o.0, self.1 & o.1)
    }
}

impl<M: Mask> BitOr for X2Mask<M> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        Self(self.0 | o.0, self.1 | o.1)
    }
}

impl<M: Mask> Not for X2Mask<M> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Self(!self.0, !self.1)
    }
}

impl<M: Mask> Mask for X2Mask<M> {
    const WIDTH: usize = 2 * M::WIDTH;
    #[inline(always)]
    fn splat(b: bool) -> Self {
        Self(M::splat(b), M::splat(b))
    }
    #[inline(always)]
    fn any(self) -> bool {
        (self.0 | self.1).any()
    }
    #[inline(always)]
    fn all(self) -> bool {
        (self.0 & self.1).all()
    }
    #[inline(always)]
    fn lane(self, i: usize) -> bool {
        if i < M::WIDTH {
            self.0.lane(i)
        } else {
            self.1.lane(i - M::WIDTH)
        }
    }
}

macro_rules! binop {
    ($tr:ident, $f:ident, $atr:ident, $af:ident) => {
        impl<L: Lanes> $tr for X2<L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                Self(self.0.$f(o.0), self.1.$f(o.1))
            }
        }
        impl<L: Lanes> $atr for X2<L> {
            #[inline(always)]
            fn $af(&mut self, o: Self) {
                self.0.$af(o.0);
                self.1.$af(o.1);
            }
        }
    };
}
binop!(Add, add, AddAssign, add_assign);
binop!(Sub, sub, SubAssign, sub_assign);
binop!(Mul, mul, MulAssign, mul_assign);
binop!(Div, div, DivAssign, div_assign);

impl<L: Lanes> Neg for X2<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self(-self.0, -self.1)
    }
}

/// Splits `idx`'s lanes for a per-half call.
macro_rules! halves {
    ($s:expr, $m:ident $(, $a:expr)*) => {
        X2($s.0.$m($($a.0),*), $s.1.$m($($a.1),*))
    };
}

impl<L: Lanes> Lanes for X2<L> {
    type Mask = X2Mask<L::Mask>;
    type Elem = L::Elem;
    const WIDTH: usize = 2 * L::WIDTH;
    const REGISTER_LOOKUP: bool = L::REGISTER_LOOKUP;
    const PERMUTE8: bool = L::PERMUTE8;

    #[inline(always)]
    fn splat(x: L::Elem) -> Self {
        Self(L::splat(x), L::splat(x))
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> L::Elem) -> Self {
        let a = L::from_fn(&mut f);
        let b = L::from_fn(|i| f(i + L::WIDTH));
        Self(a, b)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> L::Elem {
        if i < L::WIDTH {
            self.0.lane(i)
        } else {
            self.1.lane(i - L::WIDTH)
        }
    }
    #[inline(always)]
    unsafe fn load_ptr(p: *const L::Elem) -> Self {
        // SAFETY: the caller guarantees 2·L::WIDTH readable values.
        unsafe { Self(L::load_ptr(p), L::load_ptr(p.add(L::WIDTH))) }
    }
    #[inline(always)]
    unsafe fn store_ptr(self, p: *mut L::Elem) {
        // SAFETY: the caller guarantees 2·L::WIDTH writable values.
        unsafe {
            self.0.store_ptr(p);
            self.1.store_ptr(p.add(L::WIDTH));
        }
    }
    #[inline(always)]
    unsafe fn load_xyz_ptr(p: *const L::Elem) -> [Self; 3] {
        // SAFETY: the caller guarantees 3·2·L::WIDTH readable values.
        let ([ax, ay, az], [bx, by, bz]) = unsafe { (L::load_xyz_ptr(p), L::load_xyz_ptr(p.add(3 * L::WIDTH))) };
        [Self(ax, bx), Self(ay, by), Self(az, bz)]
    }
    #[inline(always)]
    unsafe fn store_xyz_ptr(v: [Self; 3], p: *mut L::Elem) {
        // SAFETY: the caller guarantees 3·2·L::WIDTH writable values.
        unsafe {
            L::store_xyz_ptr([v[0].0, v[1].0, v[2].0], p);
            L::store_xyz_ptr([v[0].1, v[1].1, v[2].1], p.add(3 * L::WIDTH));
        }
    }
    #[inline(always)]
    fn sqrt_(self) -> Self {
        halves!(self, sqrt_)
    }
    #[inline(always)]
    fn abs_(self) -> Self {
        halves!(self, abs_)
    }
    #[inline(always)]
    fn min_(self, o: Self) -> Self {
        halves!(self, min_, o)
    }
    #[inline(always)]
    fn max_(self, o: Self) -> Self {
        halves!(self, max_, o)
    }
    #[inline(always)]
    fn mul_add_(self, a: Self, b: Self) -> Self {
        halves!(self, mul_add_, a, b)
    }
    #[inline(always)]
    fn floor_(self) -> Self {
        halves!(self, floor_)
    }
    #[inline(always)]
    fn ldexp_(self, k: Self) -> Self {
        halves!(self, ldexp_, k)
    }
    #[inline(always)]
    fn frexp_(self) -> (Self, Self) {
        let ((m0, e0), (m1, e1)) = (self.0.frexp_(), self.1.frexp_());
        (Self(m0, m1), Self(e0, e1))
    }
    #[inline(always)]
    fn copysign_(self, sign: Self) -> Self {
        halves!(self, copysign_, sign)
    }
    #[inline(always)]
    fn lt_(self, o: Self) -> Self::Mask {
        X2Mask(self.0.lt_(o.0), self.1.lt_(o.1))
    }
    #[inline(always)]
    fn le_(self, o: Self) -> Self::Mask {
        X2Mask(self.0.le_(o.0), self.1.le_(o.1))
    }
    #[inline(always)]
    fn eq_(self, o: Self) -> Self::Mask {
        X2Mask(self.0.eq_(o.0), self.1.eq_(o.1))
    }
    #[inline(always)]
    fn select_(m: Self::Mask, a: Self, b: Self) -> Self {
        Self(L::select_(m.0, a.0, b.0), L::select_(m.1, a.1, b.1))
    }
    #[inline(always)]
    fn div_fast_(self, o: Self) -> Self {
        halves!(self, div_fast_, o)
    }
    #[inline(always)]
    fn rsqrt_fast_(self) -> Self {
        halves!(self, rsqrt_fast_)
    }
    #[inline(always)]
    fn sqrt_fast_(self) -> Self {
        halves!(self, sqrt_fast_)
    }
    // The polynomials run on the pair, so their instructions interleave too.
    #[inline(always)]
    fn exp_(self) -> Self {
        poly::exp_f32(self)
    }
    #[inline(always)]
    fn sin_cos_(self) -> (Self, Self) {
        poly::sin_cos_f32(self)
    }
    #[inline(always)]
    fn sin_cos_quarter_(self) -> (Self, Self) {
        poly::sin_cos_quarter_f32(self)
    }
    #[inline(always)]
    fn lookup_f32_(table: &[f32], idx: Self) -> Self {
        Self(L::lookup_f32_(table, idx.0), L::lookup_f32_(table, idx.1))
    }
    #[inline(always)]
    fn lookup8_f32_(table: &[f32], idx: Self) -> Self {
        Self(L::lookup8_f32_(table, idx.0), L::lookup8_f32_(table, idx.1))
    }
    #[inline(always)]
    fn lookup_pairs_f32_<const N: usize>(tables: [&[f32]; N], idx: Self) -> [(Self, Self); N] {
        let (a, b) = (L::lookup_pairs_f32_(tables, idx.0), L::lookup_pairs_f32_(tables, idx.1));
        std::array::from_fn(|k| (Self(a[k].0, b[k].0), Self(a[k].1, b[k].1)))
    }
    #[inline(always)]
    fn lookup_rows3_f32_(rows: &[[f32; 8]], idx: Self) -> [(Self, Self); 3] {
        let (a, b) = (L::lookup_rows3_f32_(rows, idx.0), L::lookup_rows3_f32_(rows, idx.1));
        std::array::from_fn(|k| (Self(a[k].0, b[k].0), Self(a[k].1, b[k].1)))
    }
}
