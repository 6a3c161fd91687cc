//! Lanes: the number type the SIMD-capable models are written against.
//!
//! A model written once against [`Lanes`] gives every precision from one source:
//! - `f64` — the reference path (one lane, `Mask = bool`, `std` maths),
//! - `f32` — the scalar fast path (one lane),
//! - [`F32x8`](x86::F32x8) (AVX2 + FMA) and [`F32x16`](x86::F32x16) (AVX-512) — eight or
//!   sixteen `f32` lanes per operation, used by the batch kernels in [`crate::batch`].
//!
//! Every [`Real`] is a one-lane [`Lanes`] (blanket implementation), so lane-generic code is
//! callable from the scalar models unchanged. Branches become masked selects, as in Dr.Jit or
//! ISPC code: compute both sides, keep one with [`select`]; a lane's result never depends on
//! another lane. Where an algorithm is inherently scalar (a Newton iteration with data-dependent
//! exits), lane code calls the scalar routine per lane with [`Lanes::map_lanes`].
//!
//! Write lane code with the free functions of this module (`sqrt(x)`, `max(a, b)`,
//! `select(m, a, b)`, `lt(a, b)` …): they read like the formulas and never collide with
//! `num_traits::Float` methods in files that also hold scalar code.

use crate::real::Real;
use std::fmt::Debug;
use std::ops::{Add, AddAssign, BitAnd, BitOr, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign};

// The polynomials serve the SIMD types, which exist on x86-64 only for now.
pub mod pair;
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
mod poly;
#[cfg(target_arch = "x86_64")]
pub mod x86;

/// A per-lane truth value: `bool` for one lane, a bit mask for SIMD lanes.
pub trait Mask:
    Copy + Debug + Send + Sync + 'static + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self>
{
    /// Number of lanes.
    const WIDTH: usize;
    /// The same value in every lane.
    fn splat(b: bool) -> Self;
    /// True when any lane is set.
    fn any(self) -> bool;
    /// True when every lane is set.
    fn all(self) -> bool;
    /// Lane `i`.
    fn lane(self, i: usize) -> bool;
}

impl Mask for bool {
    const WIDTH: usize = 1;
    #[inline(always)]
    fn splat(b: bool) -> Self {
        b
    }
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> bool {
        self
    }
}

/// The widest lane type ([`pair::X2`] of 16 AVX-512 lanes): the size of the stack buffers
/// that hold one lane group element by element (short tails, per-lane fallbacks).
pub const MAX_WIDTH: usize = 32;

/// One or more floating-point lanes with masked selection: what SIMD models are generic over.
pub trait Lanes:
    Copy
    + Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// Per-lane truth values.
    type Mask: Mask;
    /// The scalar type of one lane (`f32` or `f64`).
    type Elem: Real;
    /// Number of lanes.
    const WIDTH: usize;
    /// Whether [`Lanes::lookup_f32_`] on a 32-entry table is a register permute (AVX-512: one
    /// `vpermt2ps`) rather than a memory gather or per-lane loads. Kernels use the 32-piece
    /// fits ([`crate::poly_fit::MuFit32`]) in place of exact formulas only where this holds.
    const REGISTER_LOOKUP: bool = false;
    /// Whether [`Lanes::lookup8_f32_`] is one register permute (AVX2: `vpermps`). Kernels use
    /// the 8-piece fits ([`crate::poly_fit::SqrtMuFit8`]) only where this holds.
    const PERMUTE8: bool = false;

    /// `x` in every lane.
    fn splat(x: Self::Elem) -> Self;
    /// Builds lanes from a function of the lane index.
    fn from_fn(f: impl FnMut(usize) -> Self::Elem) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> Self::Elem;
    /// Loads `WIDTH` consecutive values.
    ///
    /// # Safety
    /// `p` points to `WIDTH` readable values.
    unsafe fn load_ptr(p: *const Self::Elem) -> Self;
    /// Stores `WIDTH` consecutive values.
    ///
    /// # Safety
    /// `p` points to `WIDTH` writable values.
    unsafe fn store_ptr(self, p: *mut Self::Elem);
    /// Loads `WIDTH` interleaved 3-vectors (`3·WIDTH` consecutive values `x0 y0 z0 x1 …`)
    /// as their three components. SIMD lanes load three contiguous registers and
    /// deinterleave them with permutes; the default reads lane by lane.
    ///
    /// # Safety
    /// `p` points to `3·WIDTH` readable values.
    #[inline(always)]
    unsafe fn load_xyz_ptr(p: *const Self::Elem) -> [Self; 3] {
        // SAFETY: the caller guarantees 3·WIDTH readable values.
        [0, 1, 2].map(|k| Self::from_fn(|i| unsafe { *p.add(3 * i + k) }))
    }
    /// Stores three components as `WIDTH` interleaved 3-vectors (`3·WIDTH` consecutive values),
    /// the inverse of [`Lanes::load_xyz_ptr`].
    ///
    /// # Safety
    /// `p` points to `3·WIDTH` writable values.
    #[inline(always)]
    unsafe fn store_xyz_ptr(v: [Self; 3], p: *mut Self::Elem) {
        for i in 0..Self::WIDTH {
            for (k, c) in v.iter().enumerate() {
                // SAFETY: the caller guarantees 3·WIDTH writable values.
                unsafe { *p.add(3 * i + k) = c.lane(i) };
            }
        }
    }
    /// Square root (exact, correctly rounded).
    fn sqrt_(self) -> Self;
    /// Absolute value.
    fn abs_(self) -> Self;
    /// Lane-wise minimum.
    fn min_(self, o: Self) -> Self;
    /// Lane-wise maximum.
    fn max_(self, o: Self) -> Self;
    /// `self · a + b`, fused where the hardware has FMA.
    fn mul_add_(self, a: Self, b: Self) -> Self;
    /// Largest integer not above each lane.
    fn floor_(self) -> Self;
    /// `self · 2^k` for integral `k` (as a float) in `[-126, 127]`.
    fn ldexp_(self, k: Self) -> Self;
    /// `(m, e)` with `self = m · 2^e`, `m ∈ [0.5, 1)` and integral `e` (as a float), for
    /// positive normal numbers (others unspecified).
    fn frexp_(self) -> (Self, Self);
    /// `|self|` with the sign of `sign`.
    fn copysign_(self, sign: Self) -> Self;
    /// `self < o`.
    fn lt_(self, o: Self) -> Self::Mask;
    /// `self <= o`.
    fn le_(self, o: Self) -> Self::Mask;
    /// `self == o`.
    fn eq_(self, o: Self) -> Self::Mask;
    /// `m ? a : b` per lane.
    fn select_(m: Self::Mask, a: Self, b: Self) -> Self;
    /// `self / o` where the divider limits throughput: exact for one lane; for SIMD lanes the
    /// hardware reciprocal estimate refined by one Newton step (≤ 2 ulp for finite, non-zero
    /// `o`; unspecified for `o = 0` or ±∞ — use it only where such lanes are masked out).
    fn div_fast_(self, o: Self) -> Self;
    /// `1/√self` likewise: exact for one lane, estimate + one Newton step (≤ 2 ulp) for SIMD
    /// lanes, unspecified for 0 and ±∞.
    fn rsqrt_fast_(self) -> Self;
    /// `√self` where the square-root unit limits throughput: exact for one lane; for SIMD
    /// lanes `x · r` with `r` the reciprocal-square-root estimate refined by one Newton step
    /// (≤ 2 ulp), exactly 0 for `self = 0`, for finite `self ≥ 0` (unspecified otherwise).
    fn sqrt_fast_(self) -> Self;
    /// `e^x`.
    fn exp_(self) -> Self;
    /// `(sin x, cos x)` for moderate arguments (|x| ≤ 10⁴).
    fn sin_cos_(self) -> (Self, Self);
    /// `(sin x, cos x)` for |x| ≤ π/4 (unspecified beyond): SIMD lanes skip the range
    /// reduction of [`Lanes::sin_cos_`]; one lane takes `sin_cos_`.
    #[inline(always)]
    fn sin_cos_quarter_(self) -> (Self, Self) {
        self.sin_cos_()
    }
    /// `table[i]` per lane for lanes `idx` holding integral values; indices are clamped to
    /// the table (NaN reads entry 0). `table.len()` must be a multiple of 16 and at least 32
    /// (pad with the last entry). SIMD lanes use register permutes for tables of up to 64
    /// entries with AVX-512 and the hardware gather otherwise.
    #[inline(always)]
    fn lookup_f32_(table: &[f32], idx: Self) -> Self {
        let last = (table.len() - 1) as f64;
        Self::from_fn(|i| {
            let j = idx.lane(i).f64();
            let j = if j > 0.0 { j.min(last) } else { 0.0 };
            Self::Elem::of(f64::from(table[j as usize]))
        })
    }
    /// `table[i]` per lane of an 8-entry table (at least 8 entries; the first 8 are read) for
    /// lanes `idx` holding integral values in `[0, 7]`; NaN reads entry 0, other indices read
    /// some entry of the 8. AVX2 lanes use one `vpermps`.
    #[inline(always)]
    fn lookup8_f32_(table: &[f32], idx: Self) -> Self {
        let table = &table[..8];
        Self::from_fn(|i| {
            let j = idx.lane(i).f64();
            let j = if j > 0.0 { j.min(7.0) } else { 0.0 };
            Self::Elem::of(f64::from(table[j as usize]))
        })
    }
    /// `(table[i], table[i + 1])` per lane for each of `tables`, for lanes `idx` holding
    /// integral values in `[0, len − 2]` (clamped to it; NaN reads entries 0 and 1): the two
    /// neighbours a linear interpolation needs. The tables are of one length, a multiple of
    /// 16 and at least 32, as for [`Lanes::lookup_f32_`], whose values these are (with
    /// tables of different lengths the shortest bounds the index). SIMD
    /// lanes convert the index and pick the lookup for the table size once for all the
    /// tables and load each table's registers once for both neighbours.
    #[inline(always)]
    fn lookup_pairs_f32_<const N: usize>(tables: [&[f32]; N], idx: Self) -> [(Self, Self); N] {
        let last = (tables.iter().fold(usize::MAX, |m, t| m.min(t.len())) - 2) as f64;
        let j = Self::from_fn(|i| {
            let j = idx.lane(i).f64();
            Self::Elem::of(if j > 0.0 { j.min(last) } else { 0.0 })
        });
        let next = j + Self::c(1.0);
        let mut out = [(j, j); N];
        for (o, t) in out.iter_mut().zip(tables.iter()) {
            *o = (Self::lookup_f32_(t, j), Self::lookup_f32_(t, next));
        }
        out
    }
    /// Both neighbours of three channels from rows: `rows[j]` holds the channels' values at
    /// node `j` in its first four entries (the fourth unused) and at node `j + 1` in its last
    /// four; returns `[(c0[j], c0[j + 1]), (c1[j], c1[j + 1]), (c2[j], c2[j + 1])]` per lane
    /// for lanes `idx` holding integral values, clamped to `[0, rows.len() − 1]` (NaN reads
    /// row 0). SIMD lanes without register lookups load one row per lane and transpose: on
    /// AVX2 8 loads and 20 shuffles (8 unpacks, 6 in-lane shuffles, 6 lane permutes) in place
    /// of 6 gathers (3× faster measured on AMD Zen 3).
    #[inline(always)]
    fn lookup_rows3_f32_(rows: &[[f32; 8]], idx: Self) -> [(Self, Self); 3] {
        assert!(!rows.is_empty(), "lookup rows need at least one row");
        let last = (rows.len() - 1) as f64;
        let row = |i: usize| {
            let j = idx.lane(i).f64();
            &rows[if j > 0.0 { j.min(last) } else { 0.0 } as usize]
        };
        [0, 1, 2].map(|c| {
            (
                Self::from_fn(|i| Self::Elem::of(f64::from(row(i)[c]))),
                Self::from_fn(|i| Self::Elem::of(f64::from(row(i)[4 + c]))),
            )
        })
    }
    /// The complementary error function `1 − erf(x)`: the f32 polynomial of
    /// [`poly::erfc_f32`] for SIMD lanes; the scalar types keep [`crate::special::erfc`].
    #[inline(always)]
    fn erfc_(self) -> Self {
        poly::erfc_f32(self)
    }
    /// `(e^{−x²}, erfc(x))` together: SIMD lanes share the Gaussian inside the f32 `erfc`
    /// polynomial ([`poly::gauss_erfc_f32`], one `exp` fewer than taking them apart); the
    /// scalar types keep `exp(−x·x)` and [`crate::special::erfc`].
    #[inline(always)]
    fn gauss_erfc_(self) -> (Self, Self) {
        poly::gauss_erfc_f32(self)
    }

    /// The natural logarithm: the f32 polynomial of [`poly::ln_f32`] for SIMD lanes (positive
    /// normal arguments); the scalar types keep `std`.
    #[inline(always)]
    fn ln_(self) -> Self {
        poly::ln_f32(self)
    }
    /// The inverse error function on `(−1, 1)`: Giles' single-precision approximation
    /// ([`poly::erfinv_f32`]) for SIMD lanes; the scalar types keep [`crate::special::erfinv`].
    #[inline(always)]
    fn erfinv_(self) -> Self {
        poly::erfinv_f32(self)
    }

    /// An `f64` constant or parameter in every lane (rounded to the lane precision).
    #[inline(always)]
    fn c(x: f64) -> Self {
        Self::splat(Self::Elem::of(x))
    }
    /// Runs `work` in a function of its own, out of line, compiled with this lane type's
    /// target features (the SIMD types; the scalar ones run it in place). For a large term
    /// that few materials have, inside a kernel that every material of the model shares:
    /// inlined, its code crowds the kernel's register allocation for the materials that never
    /// run it. A closure or an `#[inline(never)]` function would not do: either is compiled
    /// without the kernel's target features, so its SIMD intrinsics become calls (session 39:
    /// the metal base's bounce series ran the paint's AVX-512 eval at 98 ns per element as a
    /// closure). [`Outlined::run`] is `#[inline(always)]`, so it is inlined into the
    /// feature-enabled function.
    #[inline(always)]
    fn outlined<W: Outlined>(work: W) -> W::Output {
        work.run()
    }
    /// Applies a scalar function to each lane (for inherently scalar algorithms).
    #[inline(always)]
    fn map_lanes(self, mut f: impl FnMut(Self::Elem) -> Self::Elem) -> Self {
        Self::from_fn(|i| f(self.lane(i)))
    }
}

/// Work for [`Lanes::outlined`]: its inputs as fields, `run` marked `#[inline(always)]`.
pub trait Outlined {
    /// What `run` returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// Every scalar [`Real`] is one lane: the reference (`f64`) and scalar fast (`f32`) paths.
impl<T: Real> Lanes for T {
    type Mask = bool;
    type Elem = T;
    const WIDTH: usize = 1;

    #[inline(always)]
    fn splat(x: T) -> Self {
        x
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> T) -> Self {
        f(0)
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> T {
        self
    }
    #[inline(always)]
    unsafe fn load_ptr(p: *const T) -> Self {
        // SAFETY: the caller guarantees one readable value.
        unsafe { p.read() }
    }
    #[inline(always)]
    unsafe fn store_ptr(self, p: *mut T) {
        // SAFETY: the caller guarantees one writable value.
        unsafe { p.write(self) }
    }
    #[inline(always)]
    fn sqrt_(self) -> Self {
        num_traits::Float::sqrt(self)
    }
    #[inline(always)]
    fn abs_(self) -> Self {
        num_traits::Float::abs(self)
    }
    #[inline(always)]
    fn min_(self, o: Self) -> Self {
        num_traits::Float::min(self, o)
    }
    #[inline(always)]
    fn max_(self, o: Self) -> Self {
        num_traits::Float::max(self, o)
    }
    #[inline(always)]
    fn mul_add_(self, a: Self, b: Self) -> Self {
        // Not `Float::mul_add`: without hardware FMA it is a slow library call.
        self * a + b
    }
    #[inline(always)]
    fn floor_(self) -> Self {
        num_traits::Float::floor(self)
    }
    #[inline(always)]
    fn ldexp_(self, k: Self) -> Self {
        self * num_traits::Float::powi(T::of(2.0), k.f64() as i32)
    }
    #[inline(always)]
    fn frexp_(self) -> (Self, Self) {
        let (m, e) = libm::frexp(self.f64());
        (T::of(m), T::of(f64::from(e)))
    }
    #[inline(always)]
    fn copysign_(self, sign: Self) -> Self {
        num_traits::Float::copysign(self, sign)
    }
    #[inline(always)]
    fn lt_(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn le_(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn eq_(self, o: Self) -> bool {
        self == o
    }
    #[inline(always)]
    fn select_(m: bool, a: Self, b: Self) -> Self {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn div_fast_(self, o: Self) -> Self {
        self / o
    }
    #[inline(always)]
    fn rsqrt_fast_(self) -> Self {
        T::one() / num_traits::Float::sqrt(self)
    }
    #[inline(always)]
    fn sqrt_fast_(self) -> Self {
        num_traits::Float::sqrt(self)
    }
    #[inline(always)]
    fn exp_(self) -> Self {
        num_traits::Float::exp(self)
    }
    #[inline(always)]
    fn sin_cos_(self) -> (Self, Self) {
        num_traits::Float::sin_cos(self)
    }
    #[inline(always)]
    fn erfc_(self) -> Self {
        crate::special::erfc(self)
    }
    #[inline(always)]
    fn gauss_erfc_(self) -> (Self, Self) {
        (num_traits::Float::exp(-self * self), crate::special::erfc(self))
    }
    #[inline(always)]
    fn ln_(self) -> Self {
        num_traits::Float::ln(self)
    }
    #[inline(always)]
    fn erfinv_(self) -> Self {
        T::of(crate::special::erfinv(self.f64()))
    }
}

/// Square root.
#[inline(always)]
pub fn sqrt<L: Lanes>(x: L) -> L {
    x.sqrt_()
}
/// `sqrt(max(x, 0))`: tolerates rounding below zero.
#[inline(always)]
pub fn safe_sqrt<L: Lanes>(x: L) -> L {
    x.max_(L::c(0.0)).sqrt_()
}
/// Absolute value.
#[inline(always)]
pub fn abs<L: Lanes>(x: L) -> L {
    x.abs_()
}
/// Lane-wise minimum.
#[inline(always)]
pub fn min<L: Lanes>(a: L, b: L) -> L {
    a.min_(b)
}
/// Lane-wise maximum.
#[inline(always)]
pub fn max<L: Lanes>(a: L, b: L) -> L {
    a.max_(b)
}
/// Clamps to `[lo, hi]`.
#[inline(always)]
pub fn clamp<L: Lanes>(x: L, lo: L, hi: L) -> L {
    x.max_(lo).min_(hi)
}
/// `a · b + c` (fused where the hardware has FMA).
#[inline(always)]
pub fn mul_add<L: Lanes>(a: L, b: L, c: L) -> L {
    a.mul_add_(b, c)
}
/// `x · x`.
#[inline(always)]
pub fn sqr<L: Lanes>(x: L) -> L {
    x * x
}
/// `a / b` through the fast reciprocal on SIMD lanes (exact in one lane); see
/// [`Lanes::div_fast_`] for the error and the inputs it excludes.
#[inline(always)]
pub fn div_fast<L: Lanes>(a: L, b: L) -> L {
    a.div_fast_(b)
}
/// `1/√x` through the fast estimate on SIMD lanes (exact in one lane).
#[inline(always)]
pub fn rsqrt_fast<L: Lanes>(x: L) -> L {
    x.rsqrt_fast_()
}
/// `√x` through the fast estimate on SIMD lanes (exact in one lane), for finite `x ≥ 0`.
#[inline(always)]
pub fn sqrt_fast<L: Lanes>(x: L) -> L {
    x.sqrt_fast_()
}
/// `e^x`.
#[inline(always)]
pub fn exp<L: Lanes>(x: L) -> L {
    x.exp_()
}
/// `(sin x, cos x)`.
#[inline(always)]
pub fn sin_cos<L: Lanes>(x: L) -> (L, L) {
    x.sin_cos_()
}
/// `(sin x, cos x)` for |x| ≤ π/4 ([`Lanes::sin_cos_quarter_`]).
#[inline(always)]
pub fn sin_cos_quarter<L: Lanes>(x: L) -> (L, L) {
    x.sin_cos_quarter_()
}
/// `erfc(x) = 1 − erf(x)`.
#[inline(always)]
pub fn erfc<L: Lanes>(x: L) -> L {
    x.erfc_()
}
/// `(e^{−x²}, erfc(x))` together ([`Lanes::gauss_erfc_`]).
#[inline(always)]
pub fn gauss_erfc<L: Lanes>(x: L) -> (L, L) {
    x.gauss_erfc_()
}
/// The natural logarithm (positive normal arguments in SIMD lanes).
#[inline(always)]
pub fn ln<L: Lanes>(x: L) -> L {
    x.ln_()
}
/// The inverse error function on `(−1, 1)`.
#[inline(always)]
pub fn erfinv<L: Lanes>(x: L) -> L {
    x.erfinv_()
}
/// `|x|` with the sign of `sign`.
#[inline(always)]
pub fn copysign<L: Lanes>(x: L, sign: L) -> L {
    x.copysign_(sign)
}
/// `m ? a : b` per lane.
#[inline(always)]
pub fn select<L: Lanes>(m: L::Mask, a: L, b: L) -> L {
    L::select_(m, a, b)
}
/// `a < b` per lane (false for NaN).
#[inline(always)]
pub fn lt<L: Lanes>(a: L, b: L) -> L::Mask {
    a.lt_(b)
}
/// `a <= b` per lane (false for NaN).
#[inline(always)]
pub fn le<L: Lanes>(a: L, b: L) -> L::Mask {
    a.le_(b)
}
/// `a > b` per lane (false for NaN).
#[inline(always)]
pub fn gt<L: Lanes>(a: L, b: L) -> L::Mask {
    b.lt_(a)
}
/// `a >= b` per lane (false for NaN).
#[inline(always)]
pub fn ge<L: Lanes>(a: L, b: L) -> L::Mask {
    b.le_(a)
}
/// `a == b` per lane.
#[inline(always)]
pub fn eq<L: Lanes>(a: L, b: L) -> L::Mask {
    a.eq_(b)
}
/// True per lane when `x` is finite (false for NaN and ±∞).
#[inline(always)]
pub fn is_finite<L: Lanes>(x: L) -> L::Mask {
    x.abs_().le_(L::splat(<L::Elem as num_traits::Float>::max_value()))
}
/// `x` where `m` is set, zero elsewhere.
#[inline(always)]
pub fn keep<L: Lanes>(m: L::Mask, x: L) -> L {
    L::select_(m, x, L::c(0.0))
}
