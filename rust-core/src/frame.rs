//! The local shading frame: z is the normal, x the tangent (anisotropy axis), y = z × x.
//!
//! Both directions point away from the surface. These helpers are the only place where
//! spherical coordinates are derived from a direction.

use crate::lanes::{self, Lanes, Mask};
use crate::math::Vec3;
use crate::real::Real;

/// `cos θ` of a direction: its z component.
#[inline(always)]
#[must_use]
pub fn cos_theta<T: Lanes>(w: Vec3<T>) -> T {
    w.z
}

/// `cos² θ`.
#[inline(always)]
#[must_use]
pub fn cos2_theta<T: Lanes>(w: Vec3<T>) -> T {
    w.z * w.z
}

/// `sin² θ`, never negative.
#[inline(always)]
#[must_use]
pub fn sin2_theta<T: Lanes>(w: Vec3<T>) -> T {
    lanes::max(w.x * w.x + w.y * w.y, T::c(0.0))
}

/// `sin θ`.
#[inline(always)]
#[must_use]
pub fn sin_theta<T: Real>(w: Vec3<T>) -> T {
    sin2_theta(w).sqrt()
}

/// `tan² θ` (infinite at the horizon).
#[inline(always)]
#[must_use]
pub fn tan2_theta<T: Real>(w: Vec3<T>) -> T {
    sin2_theta(w) / cos2_theta(w)
}

/// `cos φ`, taken as 1 at the pole where φ is undefined.
#[inline(always)]
#[must_use]
pub fn cos_phi<T: Real>(w: Vec3<T>) -> T {
    let s = sin_theta(w);
    if s == T::zero() {
        T::one()
    } else {
        (w.x / s).clamp_to(-T::one(), T::one())
    }
}

/// `sin φ`, taken as 0 at the pole.
#[inline(always)]
#[must_use]
pub fn sin_phi<T: Real>(w: Vec3<T>) -> T {
    let s = sin_theta(w);
    if s == T::zero() {
        T::zero()
    } else {
        (w.y / s).clamp_to(-T::one(), T::one())
    }
}

/// True when both directions lie above the surface, `cos θ > HORIZON_COS` (the only case a
/// one-sided opaque BRDF is non-zero).
#[inline(always)]
#[must_use]
pub fn both_above<T: Real>(wi: Vec3<T>, wo: Vec3<T>) -> bool {
    above(wi.z) && above(wo.z)
}

/// Smallest `cos θ` of a direction counted as above the surface: directions closer to the
/// horizon (`cos θ ≤ 1e-8`, every denormal included) get `f = 0`, `pdf = 0` and no sample, in
/// the scalar paths and the batch kernels, f32 and f64 alike. Their contribution `f cos θ` is
/// nil (a direction within 1e-8 rad of the horizon), while the models' `1/cos θ` factors
/// overflow there and products of grazing cosines underflow in f32 (cos θ = 1e-12 gives
/// cos⁴ = 1e-48 → 0). Found twice: by the `material_json` fuzz target (NaN/±Inf at
/// cos θ ≤ 1e-12 in rough_conductor, rough_plastic, cook_torrance, torrance_sparrow,
/// cook_torrance_1981, stam, principled; docs/reliability.md) and by `lacquer numerics` (NaN and
/// Inf of nine models at cos θ = 1e-310 in f64 and 1e-40 in f32; docs/numerics.md). Grazing
/// angles down to cos θ = 1e-7 (the hard-case grid) still evaluate normally.
pub const HORIZON_COS: f64 = 1e-8;

/// True when `cos θ` is above [`HORIZON_COS`] (false for NaN).
#[inline(always)]
#[must_use]
pub fn above<T: Real>(cos_theta: T) -> bool {
    cos_theta > T::of(HORIZON_COS)
}

/// Mirror reflection of `w` about the normal `n` (both pointing away from the surface).
#[inline(always)]
#[must_use]
pub fn reflect<T: Lanes>(w: Vec3<T>, n: Vec3<T>) -> Vec3<T> {
    n * (T::c(2.0) * w.dot(n)) - w
}

/// Mirror direction of `w` about the geometric normal z.
#[inline(always)]
#[must_use]
pub fn mirror_z<T: Lanes>(w: Vec3<T>) -> Vec3<T> {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Refraction of `w` (pointing away from the surface on the incident side) through an
/// interface with normal `n` on the same side as `w` (`w·n > 0`), for `eta` = n_transmitted /
/// n_incident. Returns the transmitted direction (pointing away on the other side), or `None`
/// under total internal reflection.
#[inline]
#[must_use]
pub fn refract<T: Real>(w: Vec3<T>, n: Vec3<T>, eta: T) -> Option<Vec3<T>> {
    let cos_i = w.dot(n);
    let sin2_t = (T::one() - cos_i * cos_i).max(T::zero()) / (eta * eta);
    if sin2_t >= T::one() {
        return None;
    }
    let cos_t = (T::one() - sin2_t).sqrt();
    Some(n * (cos_i / eta - cos_t) - w / eta)
}

/// The unit half vector `(wi + wo)/|wi + wo|`, or `None` when it is undefined
/// (`wi = -wo`, or a non-finite sum).
#[inline(always)]
#[must_use]
pub fn half_vector<T: Real>(wi: Vec3<T>, wo: Vec3<T>) -> Option<Vec3<T>> {
    let (h, defined) = half_vector_masked(wi, wo);
    defined.then_some(h)
}

/// [`half_vector`] per lane: the half vector and where it is defined (elsewhere its lanes
/// hold garbage that the caller masks out).
#[inline(always)]
#[must_use]
pub fn half_vector_masked<T: Lanes>(wi: Vec3<T>, wo: Vec3<T>) -> (Vec3<T>, T::Mask) {
    let h = wi + wo;
    let len2 = h.length_squared();
    let defined = lanes::gt(len2, T::c(0.0)) & lanes::is_finite(len2);
    (h * lanes::rsqrt_fast(len2), defined)
}

/// Two directions and their half vector, per lane: what a microfacet lobe's value and its
/// density share, computed once when a caller needs both (sampling: the value and the density
/// at the drawn direction).
#[derive(Clone, Copy, Debug)]
pub struct HalfPair<T: Lanes> {
    /// The incident direction.
    pub wi: Vec3<T>,
    /// The outgoing direction.
    pub wo: Vec3<T>,
    /// The unit half vector ([`half_vector_masked`]; meaningless where not `defined`).
    pub h: Vec3<T>,
    /// Where the half vector exists: `wi + wo` non-zero and finite.
    pub defined: T::Mask,
}

impl<T: Lanes> HalfPair<T> {
    /// `wi`, `wo` and their half vector.
    #[inline(always)]
    #[must_use]
    pub fn new(wi: Vec3<T>, wo: Vec3<T>) -> Self {
        let (h, defined) = half_vector_masked(wi, wo);
        Self { wi, wo, h, defined }
    }

    /// `wi` and `wo` without their half vector, for lobes that read only the two directions
    /// (a diffuse lobe): `h` is the normal and `defined` false in every lane, so a lobe that
    /// reads it anyway gets nothing rather than a wrong value.
    #[inline(always)]
    #[must_use]
    pub fn without_half(wi: Vec3<T>, wo: Vec3<T>) -> Self {
        Self { wi, wo, h: Vec3::from_f64(0.0, 0.0, 1.0), defined: T::Mask::splat(false) }
    }
}

/// Builds a unit direction from spherical coordinates.
#[inline]
#[must_use]
pub fn spherical_direction<T: Real>(sin_theta: T, cos_theta: T, phi: T) -> Vec3<T> {
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// An orthonormal basis around a unit vector `n` (Duff et al. 2017, branchless).
#[inline]
#[must_use]
pub fn basis_around<T: Real>(n: Vec3<T>) -> (Vec3<T>, Vec3<T>) {
    let sign = if n.z >= T::zero() { T::one() } else { -T::one() };
    let a = -T::one() / (sign + n.z);
    let b = n.x * n.y * a;
    let s = Vec3::new(T::one() + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (s, t)
}

/// Expresses a direction given in the frame `(s, t, n)` in that frame's parent.
#[inline]
#[must_use]
pub fn from_basis<T: Real>(v: Vec3<T>, s: Vec3<T>, t: Vec3<T>, n: Vec3<T>) -> Vec3<T> {
    s * v.x + t * v.y + n * v.z
}

/// `1 − cos γ` for the angle γ between two unit vectors, computed as `|a − b|²/2`: accurate
/// (relative to itself) when the vectors are nearly parallel, where `1 − a·b` cancels. Narrow
/// lobes `cosⁿγ` with n up to 10⁴ need this in f32.
#[inline]
#[must_use]
pub fn versine_between<T: Real>(a: Vec3<T>, b: Vec3<T>) -> T {
    T::of(0.5) * (a - b).length_squared()
}

/// `1 − cos θ` of a non-zero vector `v` (θ its angle to the normal z), without cancellation
/// near the pole: `(x² + y²) / (|v| (|v| + z))` for `z ≥ 0`, `1 − z/|v|` below. Zero for the
/// zero vector.
#[inline]
#[must_use]
pub fn versine_z<T: Real>(v: Vec3<T>) -> T {
    let len = v.length();
    if !(len > T::zero()) {
        return T::zero();
    }
    if v.z >= T::zero() {
        (v.x * v.x + v.y * v.y) / (len * (len + v.z))
    } else {
        T::one() - v.z / len
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versines_match_one_minus_cos_and_stay_accurate_near_zero() {
        let a = Vec3::new(0.36f64, 0.48, 0.8);
        let b = Vec3::new(0.0f64, 0.6, 0.8);
        assert!((versine_between(a, b) - (1.0 - a.dot(b))).abs() < 1e-15);
        let v = Vec3::new(0.3f64, -0.4, 1.2);
        assert!((versine_z(v) - (1.0 - 1.2 / 1.3)).abs() < 1e-15);
        assert!((versine_z(Vec3::new(0.3f64, 0.4, -1.2)) - (1.0 + 1.2 / 1.3)).abs() < 1e-15);
        assert_eq!(versine_z(Vec3::<f64>::zero()), 0.0);
        // Angle 1e-5 rad: 1 − cos = 5e-11, lost to cancellation in f32 (1 − cos rounds to 0).
        let t = 1e-5f64;
        let (p, q) = (Vec3::new(0.0f32, 0.0, 1.0), Vec3::new(t.sin() as f32, 0.0, t.cos() as f32));
        let exact = 1.0 - t.cos();
        assert!((versine_between(p, q) as f64 - exact).abs() < 1e-5 * exact);
        assert!((versine_z(q) as f64 - exact).abs() < 1e-5 * exact);
        assert_eq!(1.0 - p.dot(q), 0.0);
    }

    /// Snell's law `sin θi = η sin θt`, the transmitted direction in the plane of incidence on
    /// the far side, unit length; total internal reflection past the critical angle.
    #[test]
    fn refract_obeys_snell() {
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        let (si, eta) = (0.6f64, 1.5);
        let w = Vec3::new(si * 0.6, si * 0.8, (1.0 - si * si).sqrt());
        let t = refract(w, n, eta).unwrap();
        assert!((t.length() - 1.0).abs() < 1e-14);
        assert!(t.z < 0.0);
        assert!((sin_theta(t) * eta - si).abs() < 1e-14);
        // Same azimuth plane, on the opposite side of the normal.
        assert!((t.x / t.y - w.x / w.y).abs() < 1e-12 && t.x * w.x < 0.0);
        // From glass (η = 1/1.5) at sin θ = 0.7 > 1/1.5: total internal reflection.
        let w = Vec3::new(0.7f64, 0.0, (1.0f64 - 0.49).sqrt());
        assert!(refract(w, n, 1.0 / 1.5).is_none());
    }
}
