//! The two parameterisations of an isotropic BRDF that tables use, and conversions between
//! them and direction pairs.
//!
//! - **Standard** `(θin, θout, φdiff)`: the polar angles of `wi` and `wo` and the difference
//!   of their azimuths, folded to `[0, π]` (an isotropic BRDF with bilateral symmetry depends
//!   on `|φi − φo|` only). The thesis bins its camera measurements this way (90 × 90 × 180).
//! - **Rusinkiewicz** `(θh, φh, θd, φd)` (Rusinkiewicz 1998, "A New Change of Variables for
//!   Efficient BRDF Representation"): the half vector `h = (wi + wo)/|wi + wo|` in spherical
//!   coordinates, and the *difference* vector `d`, which is `wi` expressed in a frame where `h`
//!   is the pole: `d = rot_y(−θh) · rot_z(−φh) · wi`. Isotropy removes `φh`; reciprocity
//!   (swapping `wi` and `wo` turns `d` into `(−dx, −dy, dz)`) makes a table π-periodic in `φd`.
//!   MERL tables (Matusik et al. 2003) use this one.
//!
//! All angles are radians; all functions work in `f64`. The conversions are written to be
//! exactly symmetric in `wi` and `wo` (the half vector is a commutative sum, and `d` is formed
//! from the difference of the two rotated directions), so a table lookup through them is
//! reciprocal to rounding.

use crate::math::Vec3;
use std::f64::consts::{FRAC_PI_2, PI};

/// Rusinkiewicz half/difference angles of a direction pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiff {
    /// Polar angle of the half vector, `[0, π/2]`.
    pub theta_h: f64,
    /// Azimuth of the half vector, `(−π, π]`.
    pub phi_h: f64,
    /// Polar angle of the difference vector (angle between `wi` and `h`), `[0, π/2]`.
    pub theta_d: f64,
    /// Azimuth of the difference vector, `(−π, π]`.
    pub phi_d: f64,
}

/// Standard angles of a direction pair (isotropic, bilaterally symmetric BRDF).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StandardAngles {
    /// Polar angle of `wi`.
    pub theta_in: f64,
    /// Polar angle of `wo`.
    pub theta_out: f64,
    /// `|φi − φo|` folded to `[0, π]`.
    pub phi_diff: f64,
}

/// Polar angle of a unit vector, accurate near the pole (no `acos`).
#[inline]
#[must_use]
pub fn polar(w: Vec3<f64>) -> f64 {
    (w.x * w.x + w.y * w.y).sqrt().atan2(w.z)
}

#[inline]
fn rot_z(v: Vec3<f64>, cos: f64, sin: f64) -> Vec3<f64> {
    Vec3::new(v.x * cos - v.y * sin, v.x * sin + v.y * cos, v.z)
}

#[inline]
fn rot_y(v: Vec3<f64>, cos: f64, sin: f64) -> Vec3<f64> {
    Vec3::new(v.x * cos + v.z * sin, v.y, -v.x * sin + v.z * cos)
}

/// Direction from polar angle and azimuth.
#[inline]
#[must_use]
pub fn spherical(theta: f64, phi: f64) -> Vec3<f64> {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new(st * cp, st * sp, ct)
}

/// Half/difference angles of `(wi, wo)` (unit vectors). Swapping `wi` and `wo` gives the same
/// `θh, φh, θd` and `φd ± π`.
#[must_use]
pub fn to_half_diff(wi: Vec3<f64>, wo: Vec3<f64>) -> HalfDiff {
    let sum = wi + wo;
    let len = sum.length();
    let h = if len > 1e-300 && len.is_finite() { sum / len } else { Vec3::new(0.0, 0.0, 1.0) };
    let sin_h = (h.x * h.x + h.y * h.y).sqrt();
    let theta_h = sin_h.atan2(h.z);
    let phi_h = if sin_h > 0.0 { h.y.atan2(h.x) } else { 0.0 };
    let (sp, cp) = if sin_h > 0.0 { (h.y / sin_h, h.x / sin_h) } else { (0.0, 1.0) };
    let (st, ct) = (sin_h, h.z);
    // rot_y(−θh) · rot_z(−φh) applied to both directions.
    let to_h = |w: Vec3<f64>| rot_y(rot_z(w, cp, -sp), ct, -st);
    let (a, b) = (to_h(wi), to_h(wo));
    // In the h frame b = (−dx, −dy, dz) exactly in real arithmetic; averaging makes the result
    // exactly antisymmetric (x, y) and symmetric (z) under the swap.
    let (dx, dy, dz) = (0.5 * (a.x - b.x), 0.5 * (a.y - b.y), 0.5 * (a.z + b.z));
    let sin_d = (dx * dx + dy * dy).sqrt();
    HalfDiff { theta_h, phi_h, theta_d: sin_d.atan2(dz), phi_d: if sin_d > 0.0 { dy.atan2(dx) } else { 0.0 } }
}

/// The direction pair `(wi, wo)` of half/difference angles (the inverse of [`to_half_diff`]).
/// Either direction may lie below the horizon for large `θh + θd`.
#[must_use]
pub fn from_half_diff(hd: &HalfDiff) -> (Vec3<f64>, Vec3<f64>) {
    let d = spherical(hd.theta_d, hd.phi_d);
    let back = |v: Vec3<f64>| {
        let (st, ct) = hd.theta_h.sin_cos();
        let (sp, cp) = hd.phi_h.sin_cos();
        rot_z(rot_y(v, ct, st), cp, sp)
    };
    (back(d), back(Vec3::new(-d.x, -d.y, d.z)))
}

/// Standard angles of `(wi, wo)`; symmetric in the pair except for `θin ↔ θout`.
#[must_use]
pub fn to_standard(wi: Vec3<f64>, wo: Vec3<f64>) -> StandardAngles {
    let cross = wi.x * wo.y - wi.y * wo.x;
    let dot = wi.x * wo.x + wi.y * wo.y;
    let phi_diff = if cross == 0.0 && dot == 0.0 { 0.0 } else { cross.abs().atan2(dot) };
    StandardAngles { theta_in: polar(wi), theta_out: polar(wo), phi_diff }
}

/// A direction pair with the given standard angles: `wo` at azimuth 0, `wi` at `φdiff`.
#[must_use]
pub fn from_standard(s: &StandardAngles) -> (Vec3<f64>, Vec3<f64>) {
    (spherical(s.theta_in, s.phi_diff), spherical(s.theta_out, 0.0))
}

/// Half/difference angles from standard angles (through the direction pair).
#[must_use]
pub fn standard_to_half_diff(s: &StandardAngles) -> HalfDiff {
    let (wi, wo) = from_standard(s);
    to_half_diff(wi, wo)
}

/// Standard angles from half/difference angles (through the direction pair); `None` when a
/// direction is below the horizon.
#[must_use]
pub fn half_diff_to_standard(hd: &HalfDiff) -> Option<StandardAngles> {
    let (wi, wo) = from_half_diff(hd);
    (wi.z > 0.0 && wo.z > 0.0).then(|| to_standard(wi, wo))
}

/// Wraps an angle to `[0, period)`.
#[inline]
#[must_use]
pub fn wrap(x: f64, period: f64) -> f64 {
    let r = x.rem_euclid(period);
    if r >= period {
        0.0
    } else {
        r
    }
}

/// `π/2`, the range of every polar angle.
pub const HALF_PI: f64 = FRAC_PI_2;
/// `π`, the period of `φd` in a reciprocal table.
pub const PHI_D_PERIOD: f64 = PI;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn random_dir(rng: &mut Pcg32) -> Vec3<f64> {
        let z = rng.uniform().max(1e-9);
        let phi = 2.0 * PI * rng.uniform();
        let s = (1.0 - z * z).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    }

    fn close(a: Vec3<f64>, b: Vec3<f64>, tol: f64) -> bool {
        (a - b).length() <= tol
    }

    #[test]
    fn half_diff_round_trip() {
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..10_000 {
            let (wi, wo) = (random_dir(&mut rng), random_dir(&mut rng));
            let hd = to_half_diff(wi, wo);
            let (a, b) = from_half_diff(&hd);
            assert!(close(a, wi, 1e-12) && close(b, wo, 1e-12), "{wi:?} {wo:?} -> {hd:?} -> {a:?} {b:?}");
            assert!(hd.theta_h >= 0.0 && hd.theta_h <= HALF_PI + 1e-15);
            assert!(hd.theta_d >= 0.0 && hd.theta_d <= HALF_PI + 1e-15);
        }
    }

    #[test]
    fn half_diff_by_hand() {
        // Mirror pair in the xz plane: h is the normal, θd is the incidence angle, and d points
        // along wi's azimuth.
        let t = 0.6f64;
        let wi = Vec3::new(t.sin(), 0.0, t.cos());
        let wo = Vec3::new(-t.sin(), 0.0, t.cos());
        let hd = to_half_diff(wi, wo);
        assert!(hd.theta_h.abs() < 1e-15 && (hd.theta_d - t).abs() < 1e-15 && hd.phi_d.abs() < 1e-15);
        // wi = wo: θd = 0, h = wi.
        let hd = to_half_diff(wi, wi);
        assert!((hd.theta_h - t).abs() < 1e-15 && hd.theta_d.abs() < 1e-15);
        // wi = normal, wo at 90° in the yz plane: h at 45° toward y, d at 45° in the h frame.
        let hd = to_half_diff(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 0.0));
        assert!((hd.theta_h - PI / 4.0).abs() < 1e-15 && (hd.phi_h - PI / 2.0).abs() < 1e-15);
        assert!((hd.theta_d - PI / 4.0).abs() < 1e-15);
    }

    #[test]
    fn swap_shifts_phi_d_by_pi() {
        let mut rng = Pcg32::new(3, 4);
        for _ in 0..10_000 {
            let (wi, wo) = (random_dir(&mut rng), random_dir(&mut rng));
            let (a, b) = (to_half_diff(wi, wo), to_half_diff(wo, wi));
            assert_eq!(a.theta_h, b.theta_h);
            assert_eq!(a.theta_d, b.theta_d);
            let gap = wrap(a.phi_d - b.phi_d, 2.0 * PI);
            assert!((gap - PI).abs() < 1e-12 || a.theta_d < 1e-12, "{a:?} {b:?}");
        }
    }

    #[test]
    fn standard_round_trip_and_conversions() {
        let mut rng = Pcg32::new(5, 6);
        for _ in 0..10_000 {
            let (wi, wo) = (random_dir(&mut rng), random_dir(&mut rng));
            let s = to_standard(wi, wo);
            let (a, b) = from_standard(&s);
            let s2 = to_standard(a, b);
            assert!((s.theta_in - s2.theta_in).abs() < 1e-12 && (s.theta_out - s2.theta_out).abs() < 1e-12);
            assert!((s.phi_diff - s2.phi_diff).abs() < 1e-9);
            // Through half/difference and back: the same standard angles.
            let hd = standard_to_half_diff(&s);
            let s3 = half_diff_to_standard(&hd).unwrap();
            assert!((s.theta_in - s3.theta_in).abs() < 1e-9 && (s.theta_out - s3.theta_out).abs() < 1e-9);
            assert!((s.phi_diff - s3.phi_diff).abs() < 1e-7, "{s:?} {s3:?}");
            // The half/difference angles do not depend on the frame's azimuth.
            let hd0 = to_half_diff(wi, wo);
            assert!((hd.theta_h - hd0.theta_h).abs() < 1e-9 && (hd.theta_d - hd0.theta_d).abs() < 1e-9);
        }
        // By hand: normal incidence, wo at 30°, azimuths 90° apart.
        let s = to_standard(Vec3::new(0.0, 0.0, 1.0), spherical(0.5, 1.0));
        assert!(s.theta_in.abs() < 1e-15 && (s.theta_out - 0.5).abs() < 1e-15 && s.phi_diff == 0.0);
        let s = to_standard(spherical(0.3, 0.2), spherical(0.5, 0.2 + PI / 2.0));
        assert!((s.phi_diff - PI / 2.0).abs() < 1e-14);
    }
}
