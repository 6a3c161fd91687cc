//! Small vector and colour types, generic over [`Real`].

use crate::lanes::{self, Lanes};
use crate::real::Real;
use serde::Serialize;
use std::ops::{Add, AddAssign, Div, Index, Mul, MulAssign, Neg, Sub};

/// A 3-vector (directions in the local shading frame, positions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Vec3<T> {
    /// Tangent component.
    pub x: T,
    /// Bitangent component.
    pub y: T,
    /// Normal component.
    pub z: T,
}

impl<T: Lanes> Vec3<T> {
    /// Builds a vector from its components.
    #[inline(always)]
    #[must_use]
    pub fn new(x: T, y: T, z: T) -> Self {
        Self { x, y, z }
    }
    /// Builds a vector from `f64` components (rounded to the lane precision).
    #[inline(always)]
    #[must_use]
    pub fn from_f64(x: f64, y: f64, z: f64) -> Self {
        Self::new(T::c(x), T::c(y), T::c(z))
    }
    /// The zero vector.
    #[inline(always)]
    #[must_use]
    pub fn zero() -> Self {
        Self::new(T::c(0.0), T::c(0.0), T::c(0.0))
    }
    /// Dot product.
    #[inline(always)]
    #[must_use]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// Cross product.
    #[inline(always)]
    #[must_use]
    pub fn cross(self, o: Self) -> Self {
        Self::new(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }
    /// Squared length.
    #[inline(always)]
    #[must_use]
    pub fn length_squared(self) -> T {
        self.dot(self)
    }
    /// Length.
    #[inline(always)]
    #[must_use]
    pub fn length(self) -> T {
        lanes::sqrt(self.length_squared())
    }
    /// Unit vector in the same direction (NaN for the zero vector).
    #[inline(always)]
    #[must_use]
    pub fn normalize(self) -> Self {
        self * lanes::rsqrt_fast(self.length_squared())
    }
    /// Per lane: every component is finite.
    #[inline(always)]
    #[must_use]
    pub fn finite_mask(self) -> T::Mask {
        lanes::is_finite(self.x) & lanes::is_finite(self.y) & lanes::is_finite(self.z)
    }
    /// Component-wise fused `self * s + o`.
    #[inline(always)]
    #[must_use]
    pub fn scale_add(self, s: T, o: Self) -> Self {
        Self::new(self.x * s + o.x, self.y * s + o.y, self.z * s + o.z)
    }
    /// Picks `a` or `b` per lane.
    #[inline(always)]
    #[must_use]
    pub fn select(m: T::Mask, a: Self, b: Self) -> Self {
        Self::new(lanes::select(m, a.x, b.x), lanes::select(m, a.y, b.y), lanes::select(m, a.z, b.z))
    }
}

impl<T: Real> Vec3<T> {
    /// Converts to another precision.
    #[inline(always)]
    #[must_use]
    pub fn cast<U: Real>(self) -> Vec3<U> {
        Vec3::new(U::of(self.x.f64()), U::of(self.y.f64()), U::of(self.z.f64()))
    }
    /// True when every component is finite.
    #[inline(always)]
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl<T: Lanes> Add for Vec3<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<T: Lanes> Sub for Vec3<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<T: Lanes> Neg for Vec3<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<T: Lanes> Mul<T> for Vec3<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: T) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<T: Lanes> Div<T> for Vec3<T> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: T) -> Self {
        Self::new(self.x / s, self.y / s, self.z / s)
    }
}

/// A linear RGB triple (Rec.709 primaries): BRDF values, albedos, reflectances.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Rgb<T> {
    /// Red.
    pub r: T,
    /// Green.
    pub g: T,
    /// Blue.
    pub b: T,
}

impl<T: Lanes> Rgb<T> {
    /// Builds a colour from its channels.
    #[inline(always)]
    #[must_use]
    pub fn new(r: T, g: T, b: T) -> Self {
        Self { r, g, b }
    }
    /// A grey with all three channels equal.
    #[inline(always)]
    #[must_use]
    pub fn splat(v: T) -> Self {
        Self::new(v, v, v)
    }
    /// Black.
    #[inline(always)]
    #[must_use]
    pub fn zero() -> Self {
        Self::splat(T::c(0.0))
    }
    /// Builds a colour from `[f64; 3]` (rounded to the lane precision).
    #[inline(always)]
    #[must_use]
    pub fn from_array(c: [f64; 3]) -> Self {
        Self::new(T::c(c[0]), T::c(c[1]), T::c(c[2]))
    }
    /// The channels as an array.
    #[inline(always)]
    #[must_use]
    pub fn to_array(self) -> [T; 3] {
        [self.r, self.g, self.b]
    }
    /// Applies `f` to each channel.
    #[inline(always)]
    #[must_use]
    pub fn map(self, f: impl Fn(T) -> T) -> Self {
        Self::new(f(self.r), f(self.g), f(self.b))
    }
    /// Combines two colours channel by channel.
    #[inline(always)]
    #[must_use]
    pub fn zip(self, o: Self, f: impl Fn(T, T) -> T) -> Self {
        Self::new(f(self.r, o.r), f(self.g, o.g), f(self.b, o.b))
    }
    /// Picks `a` or `b` per lane.
    #[inline(always)]
    #[must_use]
    pub fn select(m: T::Mask, a: Self, b: Self) -> Self {
        Self::new(lanes::select(m, a.r, b.r), lanes::select(m, a.g, b.g), lanes::select(m, a.b, b.b))
    }
}

impl<T: Real> Rgb<T> {
    /// Converts to another precision.
    #[inline(always)]
    #[must_use]
    pub fn cast<U: Real>(self) -> Rgb<U> {
        Rgb::new(U::of(self.r.f64()), U::of(self.g.f64()), U::of(self.b.f64()))
    }
    /// Largest channel.
    #[inline(always)]
    #[must_use]
    pub fn max_channel(self) -> T {
        self.r.max(self.g).max(self.b)
    }
    /// Smallest channel.
    #[inline(always)]
    #[must_use]
    pub fn min_channel(self) -> T {
        self.r.min(self.g).min(self.b)
    }
    /// Mean of the three channels.
    #[inline(always)]
    #[must_use]
    pub fn average(self) -> T {
        (self.r + self.g + self.b) / T::of(3.0)
    }
    /// Rec.709 luminance.
    #[inline(always)]
    #[must_use]
    pub fn luminance(self) -> T {
        T::of(0.2126) * self.r + T::of(0.7152) * self.g + T::of(0.0722) * self.b
    }
    /// True when all channels are exactly zero.
    #[inline(always)]
    #[must_use]
    pub fn is_black(self) -> bool {
        self.r == T::zero() && self.g == T::zero() && self.b == T::zero()
    }
    /// True when all channels are finite.
    #[inline(always)]
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.r.is_finite() && self.g.is_finite() && self.b.is_finite()
    }
}

impl<T: Lanes> Add for Rgb<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
}
impl<T: Lanes> AddAssign for Rgb<T> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<T: Lanes> Sub for Rgb<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
}
impl<T: Lanes> Mul for Rgb<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.zip(o, |a, b| a * b)
    }
}
impl<T: Lanes> Mul<T> for Rgb<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: T) -> Self {
        self.map(|a| a * s)
    }
}
impl<T: Lanes> MulAssign<T> for Rgb<T> {
    #[inline(always)]
    fn mul_assign(&mut self, s: T) {
        *self = *self * s;
    }
}
impl<T: Lanes> Div<T> for Rgb<T> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: T) -> Self {
        self.map(|a| a / s)
    }
}
impl<T> Index<usize> for Rgb<T> {
    type Output = T;
    #[inline(always)]
    fn index(&self, i: usize) -> &T {
        match i {
            0 => &self.r,
            1 => &self.g,
            _ => &self.b,
        }
    }
}
