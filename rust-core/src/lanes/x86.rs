//! x86-64 SIMD lanes: [`F32x8`] (AVX2 + FMA) and [`F32x16`] (AVX-512F).
//!
//! # Safety contract
//! These types wrap registers whose instructions the baseline x86-64 target does not have.
//! Their operations are `#[inline(always)]` and call the intrinsics directly, so they must
//! only run inside a function compiled with the matching `#[target_feature]` and entered after
//! `is_x86_feature_detected!` confirmed the CPU has it. [`crate::batch`] is the only place
//! that creates them and it does exactly that ([`crate::batch::SimdLevel`]); the types are
//! public for documentation and benchmarks, and every constructor is reachable only through
//! the [`Lanes`] trait inside such a kernel.

use super::{poly, Lanes, Mask};
use std::arch::x86_64::*;
use std::fmt;
use std::ops::{Add, AddAssign, BitAnd, BitOr, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign};

/// Eight `f32` lanes in an AVX register.
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x8(__m256);

/// Eight lane masks (all-ones or all-zero bits per lane).
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct M32x8(__m256);

/// Sixteen `f32` lanes in an AVX-512 register.
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x16(__m512);

/// Sixteen lane masks (one bit per lane, AVX-512 `k` register).
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct M16(u16);

macro_rules! lane_debug {
    ($t:ty) => {
        impl fmt::Debug for $t {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                let v: Vec<f32> = (0..<$t as Lanes>::WIDTH).map(|i| self.lane(i)).collect();
                write!(f, "{}{:?}", stringify!($t), v)
            }
        }
    };
}
lane_debug!(F32x8);
lane_debug!(F32x16);

impl fmt::Debug for M32x8 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v: Vec<bool> = (0..8).map(|i| self.lane(i)).collect();
        write!(f, "M32x8{v:?}")
    }
}

// SAFETY (every `unsafe` block in this file): see the module's safety contract — these run
// only inside kernels compiled for, and entered after detecting, AVX2+FMA (F32x8, M32x8) or
// AVX-512F (F32x16, M16). Loads and stores go through arrays of the exact width.

macro_rules! binops {
    ($t:ident, $add:ident, $sub:ident, $mul:ident, $div:ident) => {
        impl Add for $t {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                Self(unsafe { $add(self.0, o.0) })
            }
        }
        impl Sub for $t {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                Self(unsafe { $sub(self.0, o.0) })
            }
        }
        impl Mul for $t {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                Self(unsafe { $mul(self.0, o.0) })
            }
        }
        impl Div for $t {
            type Output = Self;
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                Self(unsafe { $div(self.0, o.0) })
            }
        }
        impl Neg for $t {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                self.flip_sign()
            }
        }
        impl AddAssign for $t {
            #[inline(always)]
            fn add_assign(&mut self, o: Self) {
                *self = *self + o;
            }
        }
        impl SubAssign for $t {
            #[inline(always)]
            fn sub_assign(&mut self, o: Self) {
                *self = *self - o;
            }
        }
        impl MulAssign for $t {
            #[inline(always)]
            fn mul_assign(&mut self, o: Self) {
                *self = *self * o;
            }
        }
        impl DivAssign for $t {
            #[inline(always)]
            fn div_assign(&mut self, o: Self) {
                *self = *self / o;
            }
        }
    };
}
binops!(F32x8, _mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps, _mm256_div_ps);
binops!(F32x16, _mm512_add_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_div_ps);

impl F32x8 {
    #[inline(always)]
    fn flip_sign(self) -> Self {
        Self(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
    }
    /// Loads eight consecutive values.
    #[inline(always)]
    pub fn load(s: &[f32; 8]) -> Self {
        Self(unsafe { _mm256_loadu_ps(s.as_ptr()) })
    }
    /// Stores eight consecutive values.
    #[inline(always)]
    pub fn store(self, s: &mut [f32; 8]) {
        unsafe { _mm256_storeu_ps(s.as_mut_ptr(), self.0) }
    }
}

impl F32x16 {
    #[inline(always)]
    fn flip_sign(self) -> Self {
        Self(unsafe { _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(self.0), _mm512_set1_epi32(i32::MIN))) })
    }
    /// Loads sixteen consecutive values.
    #[inline(always)]
    pub fn load(s: &[f32; 16]) -> Self {
        Self(unsafe { _mm512_loadu_ps(s.as_ptr()) })
    }
    /// Stores sixteen consecutive values.
    #[inline(always)]
    pub fn store(self, s: &mut [f32; 16]) {
        unsafe { _mm512_storeu_ps(s.as_mut_ptr(), self.0) }
    }
}

impl BitAnd for M32x8 {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        Self(unsafe { _mm256_and_ps(self.0, o.0) })
    }
}
impl BitOr for M32x8 {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        Self(unsafe { _mm256_or_ps(self.0, o.0) })
    }
}
impl Not for M32x8 {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Self(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
    }
}
impl Mask for M32x8 {
    const WIDTH: usize = 8;
    #[inline(always)]
    fn splat(b: bool) -> Self {
        Self(unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(if b { -1 } else { 0 })) })
    }
    #[inline(always)]
    fn any(self) -> bool {
        unsafe { _mm256_movemask_ps(self.0) != 0 }
    }
    #[inline(always)]
    fn all(self) -> bool {
        unsafe { _mm256_movemask_ps(self.0) == 0xff }
    }
    #[inline(always)]
    fn lane(self, i: usize) -> bool {
        unsafe { (_mm256_movemask_ps(self.0) >> i) & 1 != 0 }
    }
}

impl BitAnd for M16 {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        Self(self.0 & o.0)
    }
}
impl BitOr for M16 {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        Self(self.0 | o.0)
    }
}
impl Not for M16 {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Self(!self.0)
    }
}
impl Mask for M16 {
    const WIDTH: usize = 16;
    #[inline(always)]
    fn splat(b: bool) -> Self {
        Self(if b { u16::MAX } else { 0 })
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0 != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0 == u16::MAX
    }
    #[inline(always)]
    fn lane(self, i: usize) -> bool {
        (self.0 >> i) & 1 != 0
    }
}

/// The longest table the lookups read: its last index, `2^24 − 1`, and every smaller one are
/// exact in f32, so the clamps keep every read in bounds.
const MAX_LOOKUP_LEN: usize = 1 << 24;

impl Lanes for F32x8 {
    type Mask = M32x8;
    type Elem = f32;
    const WIDTH: usize = 8;

    #[inline(always)]
    fn outlined<W: super::Outlined>(work: W) -> W::Output {
        #[target_feature(enable = "avx2,fma")]
        #[inline(never)]
        unsafe fn call<W: super::Outlined>(work: W) -> W::Output {
            work.run()
        }
        // SAFETY: F32x8 values exist only where AVX2 and FMA are (module contract).
        unsafe { call(work) }
    }
    const PERMUTE8: bool = true;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self(unsafe { _mm256_set1_ps(x) })
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        let mut a = [0.0f32; 8];
        for (i, v) in a.iter_mut().enumerate() {
            *v = f(i);
        }
        Self::load(&a)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        let mut a = [0.0f32; 8];
        self.store(&mut a);
        a[i]
    }
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        Self(unsafe { _mm256_loadu_ps(p) })
    }
    #[inline(always)]
    unsafe fn store_ptr(self, p: *mut f32) {
        unsafe { _mm256_storeu_ps(p, self.0) }
    }
    #[inline(always)]
    unsafe fn load_xyz_ptr(p: *const f32) -> [Self; 3] {
        // Three loads a = x0 y0 z0 x1 y1 z1 x2 y2, b = z2 x3 … x5, c = y5 z5 … z7; two blends
        // put each component's eight values in one register (in a fixed order), one permute
        // sorts them.
        unsafe {
            let (a, b, c) = (_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8)), _mm256_loadu_ps(p.add(16)));
            let x = _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(a, b), c);
            let y = _mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x24>(a, b), c);
            let z = _mm256_blend_ps::<0x92>(_mm256_blend_ps::<0x49>(a, b), c);
            [
                Self(_mm256_permutevar8x32_ps(x, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5))),
                Self(_mm256_permutevar8x32_ps(y, _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6))),
                Self(_mm256_permutevar8x32_ps(z, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7))),
            ]
        }
    }
    #[inline(always)]
    unsafe fn store_xyz_ptr(v: [Self; 3], p: *mut f32) {
        // The inverse of `load_xyz_ptr`: permute each component into its blend order, blend.
        unsafe {
            let x = _mm256_permutevar8x32_ps(v[0].0, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
            let y = _mm256_permutevar8x32_ps(v[1].0, _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2));
            let z = _mm256_permutevar8x32_ps(v[2].0, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
            _mm256_storeu_ps(p, _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(x, y), z));
            _mm256_storeu_ps(p.add(8), _mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x24>(x, y), z));
            _mm256_storeu_ps(p.add(16), _mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x92>(x, z), y));
        }
    }
    #[inline(always)]
    fn sqrt_(self) -> Self {
        Self(unsafe { _mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn abs_(self) -> Self {
        Self(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
    }
    #[inline(always)]
    fn min_(self, o: Self) -> Self {
        Self(unsafe { _mm256_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn max_(self, o: Self) -> Self {
        Self(unsafe { _mm256_max_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn mul_add_(self, a: Self, b: Self) -> Self {
        Self(unsafe { _mm256_fmadd_ps(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn floor_(self) -> Self {
        Self(unsafe { _mm256_floor_ps(self.0) })
    }
    #[inline(always)]
    fn ldexp_(self, k: Self) -> Self {
        // 2^k built from its exponent bits, in two halves so k = ±127..128 stays in range.
        unsafe {
            let k1 = _mm256_floor_ps(_mm256_mul_ps(k.0, _mm256_set1_ps(0.5)));
            let k2 = _mm256_sub_ps(k.0, k1);
            let bias = _mm256_set1_epi32(127);
            let p1 = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(_mm256_cvtps_epi32(k1), bias)));
            let p2 = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(_mm256_cvtps_epi32(k2), bias)));
            Self(_mm256_mul_ps(_mm256_mul_ps(self.0, p1), p2))
        }
    }
    #[inline(always)]
    fn frexp_(self) -> (Self, Self) {
        // SAFETY: AVX2 per the module contract. Exponent and mantissa from the bits.
        unsafe {
            let bits = _mm256_castps_si256(self.0);
            let e = _mm256_sub_epi32(
                _mm256_and_si256(_mm256_srli_epi32::<23>(bits), _mm256_set1_epi32(0xff)),
                _mm256_set1_epi32(126),
            );
            let m = _mm256_or_si256(
                _mm256_and_si256(bits, _mm256_set1_epi32(0x807f_ffff_u32 as i32)),
                _mm256_set1_epi32(0x3f00_0000),
            );
            (Self(_mm256_castsi256_ps(m)), Self(_mm256_cvtepi32_ps(e)))
        }
    }
    #[inline(always)]
    fn copysign_(self, sign: Self) -> Self {
        unsafe {
            let m = _mm256_set1_ps(-0.0);
            Self(_mm256_or_ps(_mm256_andnot_ps(m, self.0), _mm256_and_ps(m, sign.0)))
        }
    }
    #[inline(always)]
    fn lt_(self, o: Self) -> M32x8 {
        M32x8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn le_(self, o: Self) -> M32x8 {
        M32x8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn eq_(self, o: Self) -> M32x8 {
        M32x8(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn select_(m: M32x8, a: Self, b: Self) -> Self {
        Self(unsafe { _mm256_blendv_ps(b.0, a.0, m.0) })
    }
    #[inline(always)]
    fn div_fast_(self, o: Self) -> Self {
        // 12-bit estimate, one Newton step: r' = r + r(1 − o r).
        unsafe {
            let r = _mm256_rcp_ps(o.0);
            let e = _mm256_fnmadd_ps(o.0, r, _mm256_set1_ps(1.0));
            let r = _mm256_fmadd_ps(r, e, r);
            Self(_mm256_mul_ps(self.0, r))
        }
    }
    #[inline(always)]
    fn rsqrt_fast_(self) -> Self {
        // 12-bit estimate, one Newton step: r' = r (1.5 − x r²/2).
        unsafe {
            let r = _mm256_rsqrt_ps(self.0);
            let h = _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5), self.0), _mm256_mul_ps(r, r));
            Self(_mm256_mul_ps(r, _mm256_sub_ps(_mm256_set1_ps(1.5), h)))
        }
    }
    #[inline(always)]
    fn sqrt_fast_(self) -> Self {
        // √x = x · (1/√x): the estimate of 1/√x (of the smallest normal for x = 0, so the
        // product is 0, not 0 · ∞), one Newton step folded into the product:
        // s = x r, √x ≈ s (1.5 − s r / 2).
        unsafe {
            let r = _mm256_rsqrt_ps(_mm256_max_ps(self.0, _mm256_set1_ps(f32::MIN_POSITIVE)));
            let s = _mm256_mul_ps(self.0, r);
            let h = _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5), s), r);
            Self(_mm256_mul_ps(s, _mm256_sub_ps(_mm256_set1_ps(1.5), h)))
        }
    }
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
        assert!((1..=MAX_LOOKUP_LEN).contains(&table.len()), "lookup tables hold 1 to 2^24 entries");
        // Exact in f32: len − 1 < 2^24.
        let last = (table.len() - 1) as f32;
        // max(NaN, 0) = 0 (the second operand), so every index is in bounds.
        let j = idx.max_(Self::splat(0.0)).min_(Self::splat(last));
        // SAFETY: indices clamped to [0, len − 1] above; AVX2 per the module contract.
        unsafe { Self(_mm256_i32gather_ps::<4>(table.as_ptr(), _mm256_cvttps_epi32(j.0))) }
    }
    #[inline(always)]
    fn lookup8_f32_(table: &[f32], idx: Self) -> Self {
        let table: &[f32; 8] = table[..8].try_into().expect("eight entries");
        // `vpermps` reads index bits 0–2 only, so every lane reads one of the eight entries;
        // NaN converts to 0x8000_0000, entry 0.
        // SAFETY: eight values at `table`; AVX2 per the module contract.
        unsafe { Self(_mm256_permutevar8x32_ps(_mm256_loadu_ps(table.as_ptr()), _mm256_cvttps_epi32(idx.0))) }
    }
    #[inline(always)]
    fn lookup_pairs_f32_<const N: usize>(tables: [&[f32]; N], idx: Self) -> [(Self, Self); N] {
        // The shortest table bounds the index (the tables are meant to be of one length), so
        // every read below is in bounds whatever the caller passes.
        let len = tables.iter().fold(usize::MAX, |m, t| m.min(t.len()));
        assert!((2..=MAX_LOOKUP_LEN).contains(&len), "lookup tables hold 2 to 2^24 entries");
        // max(NaN, 0) = 0 (the second operand), so every index and its successor are in bounds.
        let j = idx.max_(Self::splat(0.0)).min_(Self::splat((len - 2) as f32));
        let mut out = [(j, j); N];
        // SAFETY: j in [0, len − 2] and every table holds at least len entries, so j and j + 1
        // index every table; AVX2 per the module contract.
        unsafe {
            let j = _mm256_cvttps_epi32(j.0);
            let next = _mm256_add_epi32(j, _mm256_set1_epi32(1));
            for (o, t) in out.iter_mut().zip(tables.iter()) {
                let p = t.as_ptr();
                *o = (Self(_mm256_i32gather_ps::<4>(p, j)), Self(_mm256_i32gather_ps::<4>(p, next)));
            }
        }
        out
    }

    #[inline(always)]
    fn lookup_rows3_f32_(rows: &[[f32; 8]], idx: Self) -> [(Self, Self); 3] {
        assert!((1..=MAX_LOOKUP_LEN).contains(&rows.len()), "lookup rows hold 1 to 2^24 rows");
        // max(NaN, 0) = 0 (the second operand), so every row index is in bounds.
        let j = idx.max_(Self::splat(0.0)).min_(Self::splat((rows.len() - 1) as f32));
        let mut k = [0i32; 8];
        // SAFETY: every k[l] is in [0, rows.len() − 1] (clamped above; rows.len() − 1 < 2^24
        // is exact in f32, so the clamp and the conversion are exact), so each load reads one
        // whole row; AVX2 per the module contract.
        unsafe {
            _mm256_storeu_si256(k.as_mut_ptr().cast(), _mm256_cvttps_epi32(j.0));
            let p = rows.as_ptr().cast::<f32>();
            let r = |l: usize| _mm256_loadu_ps(p.add(8 * k[l] as usize));
            let (r0, r1, r2, r3, r4, r5, r6, r7) = (r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7));
            // An 8 × 8 transpose of the rows, keeping the six columns in use: per 128-bit
            // half, unpack pairs of rows, then gather each channel's four lanes …
            let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
            let (t2, t3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
            let (t4, t5) = (_mm256_unpacklo_ps(r4, r5), _mm256_unpackhi_ps(r4, r5));
            let (t6, t7) = (_mm256_unpacklo_ps(r6, r7), _mm256_unpackhi_ps(r6, r7));
            let low = [
                _mm256_shuffle_ps::<0x44>(t0, t2),
                _mm256_shuffle_ps::<0xEE>(t0, t2),
                _mm256_shuffle_ps::<0x44>(t1, t3),
            ];
            let high = [
                _mm256_shuffle_ps::<0x44>(t4, t6),
                _mm256_shuffle_ps::<0xEE>(t4, t6),
                _mm256_shuffle_ps::<0x44>(t5, t7),
            ];
            // … and join lanes 0–3 with lanes 4–7: low halves are node j, high halves node j + 1.
            let mut out = [(j, j); 3];
            for ((o, &a), &b) in out.iter_mut().zip(low.iter()).zip(high.iter()) {
                *o = (Self(_mm256_permute2f128_ps::<0x20>(a, b)), Self(_mm256_permute2f128_ps::<0x31>(a, b)));
            }
            out
        }
    }
}

impl Lanes for F32x16 {
    type Mask = M16;
    type Elem = f32;
    const WIDTH: usize = 16;
    const REGISTER_LOOKUP: bool = true;

    #[inline(always)]
    fn outlined<W: super::Outlined>(work: W) -> W::Output {
        #[target_feature(enable = "avx512f")]
        #[inline(never)]
        unsafe fn call<W: super::Outlined>(work: W) -> W::Output {
            work.run()
        }
        // SAFETY: F32x16 values exist only where AVX-512F is (module contract).
        unsafe { call(work) }
    }

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self(unsafe { _mm512_set1_ps(x) })
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        let mut a = [0.0f32; 16];
        for (i, v) in a.iter_mut().enumerate() {
            *v = f(i);
        }
        Self::load(&a)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        let mut a = [0.0f32; 16];
        self.store(&mut a);
        a[i]
    }
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        Self(unsafe { _mm512_loadu_ps(p) })
    }
    #[inline(always)]
    unsafe fn store_ptr(self, p: *mut f32) {
        unsafe { _mm512_storeu_ps(p, self.0) }
    }
    #[inline(always)]
    unsafe fn load_xyz_ptr(p: *const f32) -> [Self; 3] {
        // Three loads (48 values); per component one two-source permute takes its values
        // from the first two registers, a second one the rest from the third. (Measured
        // faster here than the AVX2 scheme of two masked blends and one permute: 0.48 vs
        // 0.60 ns per lambert eval.) No closures: they would not inherit the kernel's target
        // features, and the intrinsics in them would become calls.
        unsafe {
            let (a, b, c) = (_mm512_loadu_ps(p), _mm512_loadu_ps(p.add(16)), _mm512_loadu_ps(p.add(32)));
            let t = &DEINTERLEAVE;
            let x = _mm512_permutex2var_ps(a, _mm512_loadu_epi32(t[0][0].as_ptr()), b);
            let y = _mm512_permutex2var_ps(a, _mm512_loadu_epi32(t[1][0].as_ptr()), b);
            let z = _mm512_permutex2var_ps(a, _mm512_loadu_epi32(t[2][0].as_ptr()), b);
            [
                Self(_mm512_permutex2var_ps(x, _mm512_loadu_epi32(t[0][1].as_ptr()), c)),
                Self(_mm512_permutex2var_ps(y, _mm512_loadu_epi32(t[1][1].as_ptr()), c)),
                Self(_mm512_permutex2var_ps(z, _mm512_loadu_epi32(t[2][1].as_ptr()), c)),
            ]
        }
    }
    #[inline(always)]
    unsafe fn store_xyz_ptr(v: [Self; 3], p: *mut f32) {
        // Per output register: x and y values by one two-source permute, z by a second.
        unsafe {
            let t = &INTERLEAVE;
            let [x, y, z] = [v[0].0, v[1].0, v[2].0];
            let a = _mm512_permutex2var_ps(x, _mm512_loadu_epi32(t[0][0].as_ptr()), y);
            let b = _mm512_permutex2var_ps(x, _mm512_loadu_epi32(t[1][0].as_ptr()), y);
            let c = _mm512_permutex2var_ps(x, _mm512_loadu_epi32(t[2][0].as_ptr()), y);
            _mm512_storeu_ps(p, _mm512_permutex2var_ps(a, _mm512_loadu_epi32(t[0][1].as_ptr()), z));
            _mm512_storeu_ps(p.add(16), _mm512_permutex2var_ps(b, _mm512_loadu_epi32(t[1][1].as_ptr()), z));
            _mm512_storeu_ps(p.add(32), _mm512_permutex2var_ps(c, _mm512_loadu_epi32(t[2][1].as_ptr()), z));
        }
    }
    #[inline(always)]
    fn sqrt_(self) -> Self {
        Self(unsafe { _mm512_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn abs_(self) -> Self {
        Self(unsafe { _mm512_abs_ps(self.0) })
    }
    #[inline(always)]
    fn min_(self, o: Self) -> Self {
        Self(unsafe { _mm512_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn max_(self, o: Self) -> Self {
        Self(unsafe { _mm512_max_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn mul_add_(self, a: Self, b: Self) -> Self {
        Self(unsafe { _mm512_fmadd_ps(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn floor_(self) -> Self {
        Self(unsafe { _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(self.0) })
    }
    #[inline(always)]
    fn ldexp_(self, k: Self) -> Self {
        Self(unsafe { _mm512_scalef_ps(self.0, k.0) })
    }
    #[inline(always)]
    fn frexp_(self) -> (Self, Self) {
        // SAFETY: AVX-512F per the module contract. getmant normalises to [0.5, 1) and getexp
        // gives floor(log2) for the [1, 2) convention, hence the + 1.
        unsafe {
            let m = _mm512_getmant_ps::<_MM_MANT_NORM_P5_1, _MM_MANT_SIGN_SRC>(self.0);
            let e = _mm512_add_ps(_mm512_getexp_ps(self.0), _mm512_set1_ps(1.0));
            (Self(m), Self(e))
        }
    }
    #[inline(always)]
    fn copysign_(self, sign: Self) -> Self {
        unsafe {
            let m = _mm512_set1_epi32(i32::MIN);
            let a = _mm512_andnot_si512(m, _mm512_castps_si512(self.0));
            let s = _mm512_and_si512(m, _mm512_castps_si512(sign.0));
            Self(_mm512_castsi512_ps(_mm512_or_si512(a, s)))
        }
    }
    #[inline(always)]
    fn lt_(self, o: Self) -> M16 {
        M16(unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn le_(self, o: Self) -> M16 {
        M16(unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn eq_(self, o: Self) -> M16 {
        M16(unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn select_(m: M16, a: Self, b: Self) -> Self {
        Self(unsafe { _mm512_mask_blend_ps(m.0, b.0, a.0) })
    }
    #[inline(always)]
    fn div_fast_(self, o: Self) -> Self {
        // 14-bit estimate, one Newton step.
        unsafe {
            let r = _mm512_rcp14_ps(o.0);
            let e = _mm512_fnmadd_ps(o.0, r, _mm512_set1_ps(1.0));
            let r = _mm512_fmadd_ps(r, e, r);
            Self(_mm512_mul_ps(self.0, r))
        }
    }
    #[inline(always)]
    fn rsqrt_fast_(self) -> Self {
        unsafe {
            let r = _mm512_rsqrt14_ps(self.0);
            let h = _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5), self.0), _mm512_mul_ps(r, r));
            Self(_mm512_mul_ps(r, _mm512_sub_ps(_mm512_set1_ps(1.5), h)))
        }
    }
    #[inline(always)]
    fn sqrt_fast_(self) -> Self {
        // As for F32x8, with the 14-bit estimate.
        unsafe {
            let r = _mm512_rsqrt14_ps(_mm512_max_ps(self.0, _mm512_set1_ps(f32::MIN_POSITIVE)));
            let s = _mm512_mul_ps(self.0, r);
            let h = _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5), s), r);
            Self(_mm512_mul_ps(s, _mm512_sub_ps(_mm512_set1_ps(1.5), h)))
        }
    }
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
        assert!((1..=MAX_LOOKUP_LEN).contains(&table.len()), "lookup tables hold 1 to 2^24 entries");
        debug_assert!(
            table.len() >= 32 && table.len().is_multiple_of(16),
            "lookup tables are padded to 16k ≥ 32 entries"
        );
        let last = (table.len() - 1) as f32;
        // max(NaN, 0) = 0 (the second operand), so every index is in bounds.
        let j = idx.max_(Self::splat(0.0)).min_(Self::splat(last));
        let p = table.as_ptr();
        // SAFETY: indices clamped to [0, len − 1] above, and the table holds a multiple of 16
        // entries, so every 16-wide load is in bounds; AVX-512F per the module contract.
        unsafe {
            let j = _mm512_cvttps_epi32(j.0);
            match table.len() {
                // Two registers hold the table: one two-source permute (index bits 0–4).
                32 => Self(_mm512_permutex2var_ps(_mm512_loadu_ps(p), j, _mm512_loadu_ps(p.add(16)))),
                // Four registers: a permute per half, then bit 5 of the index picks the half.
                48 | 64 => {
                    let low = _mm512_permutex2var_ps(_mm512_loadu_ps(p), j, _mm512_loadu_ps(p.add(16)));
                    let high_b = if table.len() == 64 { p.add(48) } else { p.add(32) };
                    let high = _mm512_permutex2var_ps(_mm512_loadu_ps(p.add(32)), j, _mm512_loadu_ps(high_b));
                    Self(_mm512_mask_blend_ps(_mm512_test_epi32_mask(j, _mm512_set1_epi32(32)), low, high))
                }
                _ => Self(_mm512_i32gather_ps::<4>(j, p)),
            }
        }
    }
    #[inline(always)]
    fn lookup_pairs_f32_<const N: usize>(tables: [&[f32]; N], idx: Self) -> [(Self, Self); N] {
        // The shortest table bounds the index and picks the lookup (the tables are meant to be
        // of one length), so every read below is in bounds whatever the caller passes.
        let len = tables.iter().fold(usize::MAX, |m, t| m.min(t.len()));
        assert!((2..=MAX_LOOKUP_LEN).contains(&len), "lookup tables hold 2 to 2^24 entries");
        debug_assert!(len >= 32 && len.is_multiple_of(16), "tables padded to 16k ≥ 32 entries");
        // max(NaN, 0) = 0 (the second operand), so every index and its successor are in bounds.
        let j = idx.max_(Self::splat(0.0)).min_(Self::splat((len - 2) as f32));
        let mut out = [(j, j); N];
        // SAFETY: j in [0, len − 2] and every table holds at least len entries, so j and j + 1
        // index every table, and the register loads read entries below 32, 48 or 64 only when
        // len is that; AVX-512F per the module contract.
        unsafe {
            let j = _mm512_cvttps_epi32(j.0);
            let next = _mm512_add_epi32(j, _mm512_set1_epi32(1));
            let load = |p: *const f32, k: usize| _mm512_loadu_ps(p.add(16 * k));
            // Bit 5 of each index: the entry is in the upper part of a 48- or 64-entry table.
            let hi_j = _mm512_test_epi32_mask(j, _mm512_set1_epi32(32));
            let hi_next = _mm512_test_epi32_mask(next, _mm512_set1_epi32(32));
            match len {
                // Two registers: one two-source permute per neighbour.
                32 => {
                    for (o, t) in out.iter_mut().zip(tables.iter()) {
                        let (r0, r1) = (load(t.as_ptr(), 0), load(t.as_ptr(), 1));
                        *o = (Self(_mm512_permutex2var_ps(r0, j, r1)), Self(_mm512_permutex2var_ps(r0, next, r1)));
                    }
                }
                // Three registers: entries 0–31 by a two-source permute, then entries 32–47
                // merged over it by a one-source permute (index bits 0–3) where bit 5 is set.
                48 => {
                    for (o, t) in out.iter_mut().zip(tables.iter()) {
                        let p = t.as_ptr();
                        let (r0, r1, r2) = (load(p, 0), load(p, 1), load(p, 2));
                        let a = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(r0, j, r1), hi_j, j, r2);
                        let b = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(r0, next, r1), hi_next, next, r2);
                        *o = (Self(a), Self(b));
                    }
                }
                // Four registers: a two-source permute per half, bit 5 of the index picks it.
                64 => {
                    for (o, t) in out.iter_mut().zip(tables.iter()) {
                        let p = t.as_ptr();
                        let (r0, r1, r2, r3) = (load(p, 0), load(p, 1), load(p, 2), load(p, 3));
                        // A closure, compiled without the kernel's target features and called
                        // out of line from the paint's AVX-512 eval: written out, the paints'
                        // eval was 8–11 % slower (session 39, `kernel_profile`; the calls keep
                        // this rare path's registers out of the kernel's allocation).
                        let pick = |k, i| {
                            _mm512_mask_blend_ps(
                                k,
                                _mm512_permutex2var_ps(r0, i, r1),
                                _mm512_permutex2var_ps(r2, i, r3),
                            )
                        };
                        *o = (Self(pick(hi_j, j)), Self(pick(hi_next, next)));
                    }
                }
                _ => {
                    for (o, t) in out.iter_mut().zip(tables.iter()) {
                        let p = t.as_ptr();
                        *o = (Self(_mm512_i32gather_ps::<4>(j, p)), Self(_mm512_i32gather_ps::<4>(next, p)));
                    }
                }
            }
        }
        out
    }
}

/// `_mm512_permutex2var_ps` indices that deinterleave 16 3-vectors held in three registers
/// `a b c` (48 values): component `k` is `perm(perm(a, [k][0], b), [k][1], c)`.
const DEINTERLEAVE: [[[i32; 16]; 2]; 3] = {
    let mut t = [[[0i32; 16]; 2]; 3];
    let mut k = 0;
    while k < 3 {
        let mut j = 0;
        while j < 16 {
            let pos = 3 * j + k; // where element j's component k sits in a b c
            if pos < 32 {
                t[k][0][j] = pos as i32;
                t[k][1][j] = j as i32;
            } else {
                t[k][1][j] = (16 + pos - 32) as i32;
            }
            j += 1;
        }
        k += 1;
    }
    t
};

/// The inverse of [`DEINTERLEAVE`]: output register `q` (values `16q … 16q + 15` of the
/// interleaved array) is `perm(perm(x, [q][0], y), [q][1], z)`.
const INTERLEAVE: [[[i32; 16]; 2]; 3] = {
    let mut t = [[[0i32; 16]; 2]; 3];
    let mut q = 0;
    while q < 3 {
        let mut j = 0;
        while j < 16 {
            let pos = 16 * q + j;
            let (comp, elem) = (pos % 3, (pos / 3) as i32);
            match comp {
                0 => t[q][0][j] = elem,
                1 => t[q][0][j] = 16 + elem,
                _ => {}
            }
            t[q][1][j] = if comp == 2 { 16 + elem } else { j as i32 };
            j += 1;
        }
        q += 1;
    }
    t
};

/// For a unit test of AVX2 lanes: true when the CPU has AVX2 + FMA. Without them the test
/// fails, as any skip does in this project, unless `LACQUER_ALLOW_SKIP=1` outside CI (`CI`
/// unset), where this says so and returns false.
#[cfg(test)]
pub(crate) fn avx2_or_allowed_skip(test: &str) -> bool {
    if crate::batch::SimdLevel::Avx2.supported() {
        return true;
    }
    let ci = matches!(std::env::var("CI").as_deref(), Ok("true" | "1"));
    let allowed = std::env::var("LACQUER_ALLOW_SKIP").as_deref() == Ok("1") && !ci;
    assert!(
        allowed,
        "{test}: this CPU has no AVX2 + FMA (a skip is a failure; LACQUER_ALLOW_SKIP=1 allows it outside CI)"
    );
    eprintln!("{test}: skipped, this CPU has no AVX2 + FMA");
    false
}

/// Test helper: calls the generic function `$check::<L>()` for every SIMD lane type this CPU
/// has ([`F32x8`] with AVX2 + FMA, required as [`avx2_or_allowed_skip`] says; [`F32x16`] with
/// AVX-512F, where the CPU has it), each inside a function compiled with that target feature.
#[cfg(test)]
macro_rules! check_each_simd_type {
    ($check:ident) => {{
        #[target_feature(enable = "avx2,fma")]
        fn avx2() {
            $check::<$crate::lanes::x86::F32x8>();
            // The pair the small models' AVX2 kernels run on.
            $check::<$crate::lanes::pair::X2<$crate::lanes::x86::F32x8>>();
        }
        #[target_feature(enable = "avx512f")]
        fn avx512() {
            $check::<$crate::lanes::x86::F32x16>();
            // The pair the small models' AVX-512 kernels run on.
            $check::<$crate::lanes::pair::X2<$crate::lanes::x86::F32x16>>();
        }
        if $crate::lanes::x86::avx2_or_allowed_skip(stringify!($check)) {
            // SAFETY: the CPU has AVX2 and FMA (checked above).
            unsafe { avx2() };
        }
        if $crate::batch::SimdLevel::Avx512.supported() {
            // SAFETY: the CPU has AVX-512F (checked above).
            unsafe { avx512() };
        }
    }};
}
#[cfg(test)]
pub(crate) use check_each_simd_type;

#[cfg(test)]
mod tests {
    use super::*;

    /// The interleaved loads and stores against the lane-by-lane definition: every
    /// component of every element lands in its lane, and storing gives the array back.
    #[test]
    fn interleaved_load_store_round_trip() {
        fn check<L: Lanes<Elem = f32>>() {
            let w = L::WIDTH;
            let src: Vec<f32> = (0..3 * w).map(|i| i as f32 * 1.5 - 7.0).collect();
            // SAFETY: src holds 3·WIDTH values.
            let v = unsafe { L::load_xyz_ptr(src.as_ptr()) };
            for (k, c) in v.iter().enumerate() {
                for i in 0..w {
                    assert_eq!(c.lane(i), src[3 * i + k], "component {k}, lane {i} of {w}");
                }
            }
            let mut dst = vec![f32::NAN; 3 * w + 1];
            // SAFETY: dst holds more than 3·WIDTH values.
            unsafe { L::store_xyz_ptr(v, dst.as_mut_ptr()) };
            assert_eq!(dst[..3 * w], src[..], "width {w}");
            assert!(dst[3 * w].is_nan(), "wrote past 3·WIDTH");
        }
        check::<f32>();
        check_each_simd_type!(check);
    }

    /// Largest error of the lane `exp` and `sin`/`cos` polynomials against f64 `std`, in every
    /// SIMD type this CPU has. Measured: exp ≤ 1.9 ulp relative (bounds: 2 ulp = 2.4e-7);
    /// sin/cos ≤ 1.8e-7 absolute on |x| ≤ 100 (bound 2.5e-7; 2^-22).
    #[test]
    fn polynomials_match_f64() {
        fn check<L: Lanes<Elem = f32>>() {
            let mut worst_exp = 0.0f64;
            let mut worst_trig = 0.0f64;
            let mut worst_quarter = 0.0f64;
            let w = L::WIDTH;
            for k in 0..20_000 {
                let xs: Vec<f32> = (0..w).map(|j| -87.0 + 175.0 * ((k * w + j) as f32 / (20_000 * w) as f32)).collect();
                let e = L::from_fn(|j| xs[j]).exp_();
                for (j, &x) in xs.iter().enumerate() {
                    let want = f64::from(x).exp();
                    worst_exp = worst_exp.max((f64::from(e.lane(j)) - want).abs() / want);
                }
                let ts: Vec<f32> =
                    (0..w).map(|j| -100.0 + 200.0 * ((k * w + j) as f32 / (20_000 * w) as f32)).collect();
                let (s, c) = L::from_fn(|j| ts[j]).sin_cos_();
                for (j, &t) in ts.iter().enumerate() {
                    worst_trig = worst_trig.max((f64::from(s.lane(j)) - f64::from(t).sin()).abs());
                    worst_trig = worst_trig.max((f64::from(c.lane(j)) - f64::from(t).cos()).abs());
                }
                // The quarter-range form (no reduction) on |x| ≤ π/4, both ends included.
                let qs: Vec<f32> = (0..w)
                    .map(|j| {
                        std::f32::consts::FRAC_PI_4 * (-1.0 + 2.0 * ((k * w + j) as f32 / (20_000 * w - 1) as f32))
                    })
                    .collect();
                let (s, c) = L::from_fn(|j| qs[j]).sin_cos_quarter_();
                for (j, &t) in qs.iter().enumerate() {
                    worst_quarter = worst_quarter.max((f64::from(s.lane(j)) - f64::from(t).sin()).abs());
                    worst_quarter = worst_quarter.max((f64::from(c.lane(j)) - f64::from(t).cos()).abs());
                }
            }
            eprintln!("{} lanes: sin/cos {worst_trig:.2e}, quarter range {worst_quarter:.2e}", L::WIDTH);
            assert!(worst_quarter <= 2.5e-7, "sin/cos on |x| ≤ π/4: {worst_quarter:e}");
            assert!(worst_exp <= 2.4e-7, "exp: {worst_exp:e}");
            assert!(worst_trig <= 2.5e-7, "sin/cos: {worst_trig:e}");
            // Edges: underflow to 0, overflow to ∞, NaN stays NaN.
            let e = L::from_fn(|j| [-100.0, 100.0, f32::NAN, 0.0][j % 4]).exp_();
            assert_eq!((e.lane(0), e.lane(1), e.lane(3)), (0.0, f32::INFINITY, 1.0));
            assert!(e.lane(2).is_nan());
        }
        check_each_simd_type!(check);
    }

    /// The fast division, reciprocal square root and square root (estimate + one Newton
    /// step) against f64 over 2^-40 … 2^40, in ulps of the f32 result (1 ulp = 2^-23 relative
    /// at the bottom of a binade): the ≤ 2 ulp the doc comments promise. Measured (session
    /// 20, Intel Xeon): avx2 (12-bit estimates) div 1.30, rsqrt 1.84, sqrt 1.74 ulp; avx512
    /// (14-bit) div 0.98, rsqrt 1.16, sqrt 1.23 ulp. `sqrt_fast` of 0 is exactly 0.
    #[test]
    fn fast_division_and_roots_are_within_two_ulp() {
        fn check<L: Lanes<Elem = f32>>() {
            let w = L::WIDTH;
            let n = 40_000;
            let (mut div, mut rsqrt, mut sqrt) = (0.0f64, 0.0f64, 0.0f64);
            let ulps = |got: f32, want: f64| (f64::from(got) - want).abs() / (want.abs() * f64::from(f32::EPSILON));
            for k in 0..n {
                let xs: Vec<f32> =
                    (0..w).map(|j| (((k * w + j) as f64 / (n * w) as f64) * 80.0 - 40.0).exp2() as f32).collect();
                let ys: Vec<f32> = xs.iter().map(|&x| 1.0 + (x * 7.77).fract()).collect();
                let (x, y) = (L::from_fn(|j| xs[j]), L::from_fn(|j| ys[j]));
                let (d, r, s) = (y.div_fast_(x), x.rsqrt_fast_(), x.sqrt_fast_());
                for j in 0..w {
                    let (xf, yf) = (f64::from(xs[j]), f64::from(ys[j]));
                    div = div.max(ulps(d.lane(j), yf / xf));
                    rsqrt = rsqrt.max(ulps(r.lane(j), 1.0 / xf.sqrt()));
                    sqrt = sqrt.max(ulps(s.lane(j), xf.sqrt()));
                }
            }
            eprintln!("width {w}: div {div:.3}, rsqrt {rsqrt:.3}, sqrt {sqrt:.3} ulp");
            assert!(div <= 2.0 && rsqrt <= 2.0 && sqrt <= 2.0, "width {w}: div {div}, rsqrt {rsqrt}, sqrt {sqrt} ulp");
            assert_eq!(L::c(0.0).sqrt_fast_().lane(0), 0.0);
        }
        check_each_simd_type!(check);
    }

    /// The row lookups against indexing the rows directly: every row, indices below 0 and
    /// beyond the last row (clamped), and NaN (row 0).
    #[test]
    fn lookup_rows_read_both_neighbours_of_three_channels() {
        fn check<L: Lanes<Elem = f32>>() {
            for len in [1usize, 2, 63, 80] {
                let rows: Vec<[f32; 8]> =
                    (0..len).map(|j| std::array::from_fn(|e| (j * j) as f32 * 0.25 + e as f32 * 100.0 - 3.0)).collect();
                let mut indices: Vec<f32> = (0..len).map(|i| i as f32).collect();
                indices.extend([-5.0, -1.0, len as f32, (len + 9) as f32, 1e9, f32::NAN]);
                for group in indices.chunks(L::WIDTH) {
                    let idx = L::from_fn(|i| group.get(i).copied().unwrap_or(0.0));
                    let got = L::lookup_rows3_f32_(&rows, idx);
                    for (lane, &x) in group.iter().enumerate() {
                        let j = if x.is_nan() { 0 } else { x.clamp(0.0, (len - 1) as f32) as usize };
                        for (c, (a, b)) in got.iter().enumerate() {
                            assert_eq!(
                                (a.lane(lane), b.lane(lane)),
                                (rows[j][c], rows[j][4 + c]),
                                "width {}, {len} rows, index {x}, channel {c}",
                                L::WIDTH
                            );
                        }
                    }
                }
            }
        }
        check::<f32>();
        check_each_simd_type!(check);
    }

    /// The neighbour lookups of every table size (two, three and four registers, and the
    /// gather beyond) against indexing the tables directly: every in-range index, indices
    /// below 0 and beyond `len − 2` (clamped), and NaN (entries 0 and 1); tables of different
    /// lengths are read within the shortest.
    #[test]
    fn lookup_pairs_read_both_neighbours_of_every_table_size() {
        fn check<L: Lanes<Elem = f32>>() {
            for len in [32usize, 48, 64, 80] {
                let tables: [Vec<f32>; 2] =
                    [0, 1].map(|k| (0..len).map(|i| (i * i + 7 * k) as f32 * 0.25 - 3.0).collect());
                let mut indices: Vec<f32> = (0..len as i32 - 1).map(|i| i as f32).collect();
                indices.extend([-5.0, -1.0, (len - 1) as f32, (len + 9) as f32, 1e9, f32::NAN]);
                for group in indices.chunks(L::WIDTH) {
                    let idx = L::from_fn(|i| group.get(i).copied().unwrap_or(0.0));
                    let got = L::lookup_pairs_f32_([tables[0].as_slice(), tables[1].as_slice()], idx);
                    for (lane, &x) in group.iter().enumerate() {
                        let j = if x.is_nan() { 0 } else { x.clamp(0.0, (len - 2) as f32) as usize };
                        for (t, (a, b)) in got.iter().enumerate() {
                            let want = (tables[t][j], tables[t][j + 1]);
                            assert_eq!(
                                (a.lane(lane), b.lane(lane)),
                                want,
                                "width {}, len {len}, index {x}, table {t}",
                                L::WIDTH
                            );
                        }
                    }
                }
            }
            // Tables of different lengths (not how the crate calls it): the shortest bounds
            // the index, and nothing is read beyond it.
            let long: Vec<f32> = (0..64).map(|i| i as f32).collect();
            let short: Vec<f32> = (0..48).map(|i| -(i as f32)).collect();
            let got = L::lookup_pairs_f32_([long.as_slice(), short.as_slice()], L::splat(100.0));
            let lane0 = (got[0].0.lane(0), got[0].1.lane(0), got[1].0.lane(0), got[1].1.lane(0));
            assert_eq!(lane0, (46.0, 47.0, -46.0, -47.0), "width {}", L::WIDTH);
        }
        check::<f32>();
        check_each_simd_type!(check);
    }
}
