//! Fresnel reflectance: exact dielectric, exact conductor with a complex index of
//! refraction, Schlick's approximation, and measured metal constants.
//!
//! All functions take the cosine between the direction and the (micro)normal and return
//! the unpolarised reflectance (the mean of the s and p terms).

use crate::lanes::{self, Lanes};
use crate::math::Rgb;
use crate::poly_fit::{MuFit32, SqrtMuFit8};
use crate::real::Real;
use std::sync::Arc;

/// Unpolarised Fresnel reflectance of a dielectric interface.
///
/// `cos_i` is the cosine of the incident angle on the side the light comes from;
/// `eta` = n_transmitted / n_incident. Returns 1 under total internal reflection.
/// A negative `cos_i` means the light arrives from the other side (eta is inverted).
#[inline(always)]
#[must_use]
pub fn dielectric<T: Lanes>(cos_i: T, eta: T) -> T {
    let one = T::c(1.0);
    let inside = lanes::lt(cos_i, T::c(0.0));
    // Exact divisions and root, not the fast estimates: at grazing incidence layered models
    // use 1 − F, which is O(cos θ) and would inherit the estimates' 2-ulp error of F as a
    // relative error of 2 ulp / cos θ (1 % at cos θ = 1e-6 in `principled`'s coat).
    // One division per lane: `1/η` and `1/η²` divide the caller's `eta`, which in the SIMD
    // kernels is one value for every lane (the compiler divides it once, as a scalar), and
    // `r_s = a/b`, `r_p = c/d` share `1/(b d)`. Without total internal reflection
    // `cos_t ≥ √ulp`, so `b d ≥ η cos_t²` stays far from underflow.
    let eta2 = eta * eta;
    let (inv_eta, inv_eta2) = (one / eta, one / eta2);
    let eta = lanes::select(inside, inv_eta, eta);
    let cos_i = lanes::min(lanes::abs(cos_i), one);
    let sin2_t = (one - cos_i * cos_i) * lanes::select(inside, eta2, inv_eta2);
    let tir = lanes::ge(sin2_t, one);
    let cos_t = lanes::safe_sqrt(one - sin2_t);
    let (a, b) = (cos_i - eta * cos_t, cos_i + eta * cos_t);
    let (c, d) = (eta * cos_i - cos_t, eta * cos_i + cos_t);
    let inv_bd = one / (b * d);
    let (r_s, r_p) = (a * d * inv_bd, c * b * inv_bd);
    lanes::select(tir, one, T::c(0.5) * (r_s * r_s + r_p * r_p))
}

/// `1 − F` of [`dielectric`] (the transmitted share) without the cancellation of `1 − F`
/// at grazing incidence, where `F → 1`: `1 − r_s² = 4ηc c_t/b²` and `1 − r_p² = 4ηc c_t/d²`
/// (`b = c + η c_t`, `d = ηc + c_t`), so `T = 2ηc c_t (b² + d²)/(b d)²`, sums and products of
/// positive terms. In f32 `1 − F` has the relative error `ulp(1)/T` (2.4e-4 at cos θ = 1e-4);
/// this form keeps a few ulps relative at every angle. 0 under total internal reflection;
/// `cos_i` and `eta` as in [`dielectric`].
#[inline(always)]
#[must_use]
pub fn dielectric_transmittance<T: Lanes>(cos_i: T, eta: T) -> T {
    let one = T::c(1.0);
    let inside = lanes::lt(cos_i, T::c(0.0));
    let eta2 = eta * eta;
    let (inv_eta, inv_eta2) = (one / eta, one / eta2);
    let eta = lanes::select(inside, inv_eta, eta);
    let cos_i = lanes::min(lanes::abs(cos_i), one);
    let sin2_t = (one - cos_i * cos_i) * lanes::select(inside, eta2, inv_eta2);
    let tir = lanes::ge(sin2_t, one);
    let cos_t = lanes::safe_sqrt(one - sin2_t);
    let (b, d) = (cos_i + eta * cos_t, eta * cos_i + cos_t);
    let inv_bd = one / (b * d);
    let t = T::c(2.0) * eta * cos_i * cos_t * (b * b + d * d) * (inv_bd * inv_bd);
    lanes::select(tir, T::c(0.0), t)
}

/// Cosine of the refracted direction for a dielectric (positive), or `None` under total
/// internal reflection. `eta` as in [`dielectric`].
#[inline]
#[must_use]
pub fn refracted_cos<T: Real>(cos_i: T, eta: T) -> Option<T> {
    let (cos_t, refracts) = refracted_cos_masked(cos_i, eta);
    refracts.then_some(cos_t)
}

/// [`refracted_cos`] per lane: the cosine and where it exists (no total internal reflection).
#[inline(always)]
#[must_use]
pub fn refracted_cos_masked<T: Lanes>(cos_i: T, eta: T) -> (T, T::Mask) {
    let one = T::c(1.0);
    let sin2_t = lanes::max(one - cos_i * cos_i, T::c(0.0)) / (eta * eta);
    (lanes::safe_sqrt(one - sin2_t), lanes::lt(sin2_t, one))
}

/// Normal-incidence reflectance `((η−1)/(η+1))²` of a dielectric.
#[inline(always)]
#[must_use]
pub fn dielectric_f0<T: Lanes>(eta: T) -> T {
    lanes::sqr((eta - T::c(1.0)) / (eta + T::c(1.0)))
}

/// Schlick's approximation `F0 + (1 − F0)(1 − cos)^5`.
#[inline(always)]
#[must_use]
pub fn schlick<T: Lanes>(cos_i: T, f0: T) -> T {
    let one = T::c(1.0);
    let m = lanes::max(one - lanes::clamp(cos_i, T::c(0.0), one), T::c(0.0));
    let m2 = m * m;
    f0 + (one - f0) * m2 * m2 * m
}

/// Schlick's approximation per channel.
#[inline(always)]
#[must_use]
pub fn schlick_rgb<T: Lanes>(cos_i: T, f0: Rgb<T>) -> Rgb<T> {
    // Written out, not `f0.map(..)`: the closure was not inlined into the AVX-512 kernel.
    Rgb::new(schlick(cos_i, f0.r), schlick(cos_i, f0.g), schlick(cos_i, f0.b))
}

/// The index of refraction whose normal-incidence reflectance is `f0` (the inverse of
/// [`dielectric_f0`]), with `f0` clamped to `[0, 0.99]`.
#[inline]
#[must_use]
pub fn ior_from_f0(f0: f64) -> f64 {
    let r = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + r) / (1.0 - r)
}

/// The F82-tint conductor model (Kutz et al., "Novel aspects of the Adobe Standard Material",
/// 2021; as in Blender's Cycles and OpenPBR): Schlick's curve minus a term `b·cos·(1 − cos)⁶`
/// that bends it near 82°, clamped to `[0, 1]`:
/// `F(cos) = F0 + (1 − F0)(1 − cos)⁵ − b·cos·(1 − cos)⁶`. See [`f82_tint_b`] for `b`.
#[inline(always)]
#[must_use]
pub fn f82<T: Lanes>(cos_i: T, f0: T, b: T) -> T {
    let one = T::c(1.0);
    let s = lanes::clamp(one - cos_i, T::c(0.0), one);
    let s5 = lanes::sqr(lanes::sqr(s)) * s;
    lanes::clamp(f0 + (one - f0) * s5 - b * cos_i * s5 * s, T::c(0.0), one)
}

/// The `b` of [`f82`] for which the curve at `cos θ = 1/7` (≈ 82°) is Schlick's value there
/// times `tint`: `b = S(1/7)·(1 − tint)·7/(6/7)⁶` with `S` Schlick's curve. `tint = 1` gives
/// `b = 0` (plain Schlick).
#[inline]
#[must_use]
pub fn f82_tint_b(f0: f64, tint: f64) -> f64 {
    let f = 6.0 / 7.0;
    let f5 = f * f * f * f * f;
    let schlick = f0 + (1.0 - f0) * f5;
    schlick * 7.0 / (f5 * f) * (1.0 - tint)
}

/// Exact unpolarised reflectance of a conductor with complex IOR `eta + i·k`
/// (relative to the outside medium), for `cos_i` in `[0, 1]`.
///
/// The closed real form of the Fresnel equations (as in pbrt-v3 and Mitsuba 3): with
/// `t = η² − k² − sin²θ`, `a² + b² = √(t² + 4η²k²)` and `a² = (a² + b² + t)/2`,
/// `R_s = (a²+b² + cos²θ − 2a cos θ)/(a²+b² + cos²θ + 2a cos θ)` and
/// `R_p = R_s (a²+b² cos²θ + sin⁴θ − 2a cos θ sin²θ)/(a²+b² cos²θ + sin⁴θ + 2a cos θ sin²θ)`.
/// Since `R_p = R_s (term3 − term4)/(term3 + term4)`, the mean is `R_s term3/(term3 + term4)`.
/// One square root pair per channel instead of complex arithmetic; `a²` is taken as
/// `2η²k²/(a²+b² − t)` when `t < 0`, which avoids the cancellation of `a²+b² + t` for metals
/// (`k ≫ η`; in f32 it would cost ~3e-5 relative on gold).
///
/// At `η = 1, k = 0` (an index-matched interface: nothing reflects) the result is exactly 0.
/// The formula gives 0 there only up to rounding: `t = 1 − sin²θ` is `cos²θ` with an absolute
/// error of 1e-16, so `a²+b² + cos²θ − 2a cos θ` cancels to residues of either sign (F ≈ −1e-17
/// and non-reciprocal once a microfacet lobe multiplies it by `D G / (4 cos θi cos θo)`), and
/// at `cos θ = 0` it is 0/0 (NaN in f32 at grazing half vectors). `lacquer numerics`' index-matched
/// sets found it in every model that uses this function (docs/numerics.md).
#[inline(always)]
#[must_use]
pub fn conductor<T: Lanes>(cos_i: T, eta: T, k: T) -> T {
    let matched = lanes::eq(eta, T::c(1.0)) & lanes::eq(k, T::c(0.0));
    lanes::select(matched, T::c(0.0), conductor_formula(cos_i, eta, k))
}

/// [`conductor`] without the index-matched case.
#[inline(always)]
fn conductor_formula<T: Lanes>(cos_i: T, eta: T, k: T) -> T {
    let one = T::c(1.0);
    let c = lanes::clamp(cos_i, T::c(0.0), one);
    let c2 = c * c;
    let s2 = one - c2;
    let (eta2, k2) = (eta * eta, k * k);
    let t = eta2 - k2 - s2;
    let four_eta2_k2 = T::c(4.0) * eta2 * k2;
    let a2_plus_b2 = lanes::sqrt(t * t + four_eta2_k2);
    let a2 = lanes::select(
        lanes::ge(t, T::c(0.0)),
        T::c(0.5) * (a2_plus_b2 + t),
        lanes::div_fast(T::c(0.5) * four_eta2_k2, a2_plus_b2 - t),
    );
    let a = lanes::safe_sqrt(a2);
    let term1 = a2_plus_b2 + c2;
    let term2 = T::c(2.0) * c * a;
    let term3 = a2_plus_b2 * c2 + s2 * s2;
    let term4 = term2 * s2;
    // (R_s + R_p)/2 = R_s · term3/(term3 + term4): one division instead of two.
    lanes::div_fast((term1 - term2) * term3, (term1 + term2) * (term3 + term4))
}

/// [`conductor`] per RGB channel.
#[inline(always)]
#[must_use]
pub fn conductor_rgb<T: Lanes>(cos_i: T, eta: Rgb<T>, k: Rgb<T>) -> Rgb<T> {
    Rgb::new(conductor(cos_i, eta.r, k.r), conductor(cos_i, eta.g, k.g), conductor(cos_i, eta.b, k.b))
}

/// The conductor Fresnel of one material (`η + i·k` per RGB channel) as models hold it: the
/// exact [`conductor_rgb`], and for SIMD lanes its measured piecewise-polynomial fits
/// ([`crate::poly_fit`]): AVX-512 lanes 32 quintic pieces in `μ` (6 permutes and 5 FMAs per
/// channel), AVX2 lanes 8 pieces of degree 7 in `√μ` (8 permutes and 7 FMAs per channel, one
/// square root for the three) — instead of 2 square roots and 2 divisions per channel. The
/// f64 reference and scalar f32 paths always take the exact formula; a material whose fit
/// misses [`crate::poly_fit::FIT_TOLERANCE`] (an index-matched or nearly matched interface)
/// takes it on those lanes too.
#[derive(Clone, Debug)]
pub struct ConductorFresnel {
    /// Real part of the IOR per channel.
    pub eta: [f64; 3],
    /// Imaginary part of the IOR per channel.
    pub k: [f64; 3],
    fit: Option<Arc<MuFit32>>,
    fit8: Option<Arc<SqrtMuFit8>>,
}

impl ConductorFresnel {
    /// The Fresnel of `η + i·k`, with its fits where they are within tolerance.
    #[must_use]
    pub fn new(eta: [f64; 3], k: [f64; 3]) -> Self {
        let exact = |mu: f64| [0, 1, 2].map(|c| conductor(mu, eta[c], k[c]));
        let fit = MuFit32::new(exact).map(Arc::new);
        let fit8 = SqrtMuFit8::new(exact).map(Arc::new);
        Self { eta, k, fit, fit8 }
    }

    /// The same material without the fits: every path evaluates the exact formula (for
    /// measuring what the fits save and cost).
    #[must_use]
    pub fn exact_only(&self) -> Self {
        Self { fit: None, fit8: None, ..self.clone() }
    }

    /// The AVX-512 fit's measured largest relative error, or `None` when the exact formula
    /// is used.
    #[must_use]
    pub fn fit_error(&self) -> Option<f64> {
        self.fit.as_ref().map(|f| f.max_relative_error())
    }

    /// The AVX2 fit's measured largest relative error, or `None` when the exact formula is
    /// used.
    #[must_use]
    pub fn fit8_error(&self) -> Option<f64> {
        self.fit8.as_ref().map(|f| f.max_relative_error())
    }

    /// Reflectance per channel at incidence `cos_i` (clamped to `[0, 1]`).
    #[inline(always)]
    #[must_use]
    pub fn eval<L: Lanes>(&self, cos_i: L) -> Rgb<L> {
        if L::REGISTER_LOOKUP {
            if let Some(fit) = &self.fit {
                return fit.eval_lanes(cos_i);
            }
        } else if L::PERMUTE8 {
            if let Some(fit) = &self.fit8 {
                return fit.eval_lanes(cos_i);
            }
        }
        conductor_rgb(cos_i, Rgb::from_array(self.eta), Rgb::from_array(self.k))
    }
}

/// A measured metal: complex IOR per RGB channel, relative to air.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metal {
    /// Name as accepted in material JSON (`"Au"`).
    pub name: &'static str,
    /// Real part of the IOR per channel.
    pub eta: [f64; 3],
    /// Imaginary part (extinction) per channel.
    pub k: [f64; 3],
}

/// Measured metals: the widely used RGB reduction of the spectral n, k tables that pbrt and
/// Mitsuba ship (Palik / Weaver data). Mitsuba's own RGB reduction differs slightly; the
/// Mitsuba comparison tests pass n, k explicitly so both sides use the same numbers.
pub const METALS: &[Metal] = &[
    Metal { name: "Au", eta: [0.143119, 0.374957, 1.44248], k: [3.98316, 2.38572, 1.60322] },
    Metal { name: "Ag", eta: [0.155265, 0.116723, 0.138342], k: [4.82835, 3.12225, 2.14696] },
    Metal { name: "Al", eta: [1.65746, 0.880369, 0.521229], k: [9.22387, 6.26952, 4.837] },
    Metal { name: "Cu", eta: [0.200438, 0.924033, 1.10221], k: [3.91295, 2.45285, 2.14219] },
];

/// Looks up a metal by name (case-sensitive chemical symbol).
#[must_use]
pub fn metal(name: &str) -> Option<&'static Metal> {
    METALS.iter().find(|m| m.name == name)
}

/// The textbook dielectric Fresnel reflectance (Snell, then `r_s`, `r_p` with a division
/// each), in f64: the independent reference the tests of [`dielectric`] and of the models
/// built on it compare with. `cos_i < 0` is the other side (index `1/η`); 1 under total
/// internal reflection.
#[cfg(test)]
pub(crate) fn dielectric_textbook(cos_i: f64, eta: f64) -> f64 {
    let eta = if cos_i < 0.0 { 1.0 / eta } else { eta };
    let c = cos_i.abs().min(1.0);
    let sin2_t = (1.0 - c * c) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - sin2_t).sqrt();
    let rs = (c - eta * ct) / (c + eta * ct);
    let rp = (eta * c - ct) / (eta * c + ct);
    0.5 * (rs * rs + rp * rp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_normal_incidence_matches_closed_form() {
        // ((1.5 − 1)/(1.5 + 1))² = 0.04 exactly.
        assert!((dielectric(1.0f64, 1.5) - 0.04).abs() < 1e-15);
        assert!((dielectric_f0(1.5f64) - 0.04).abs() < 1e-15);
    }

    #[test]
    fn dielectric_is_one_at_grazing_and_under_tir() {
        assert!((dielectric(0.0f64, 1.5) - 1.0).abs() < 1e-12);
        // From inside glass (cos < 0 means the other side) beyond the critical angle.
        assert_eq!(dielectric(-0.1f64, 1.5), 1.0);
    }

    #[test]
    fn dielectric_brewster_angle_zeroes_p_polarisation() {
        // At Brewster's angle tan θ = η, r_p = 0 so F = r_s²/2; r_s² = cos²(2θ)... check via
        // the closed form r_s = (cos i − η cos t)/(cos i + η cos t) independently.
        let eta: f64 = 1.5;
        let theta = eta.atan();
        let (ci, si) = (theta.cos(), theta.sin());
        let ct = (1.0 - (si / eta).powi(2)).sqrt();
        let rs = (ci - eta * ct) / (ci + eta * ct);
        assert!((dielectric(ci, eta) - 0.5 * rs * rs).abs() < 1e-14);
    }

    /// `dielectric` divides once per lane (reciprocals of `η` and `η²`, and `1/(b d)` shared
    /// by `r_s` and `r_p`; session 32). Against the textbook form away from the critical angle
    /// (`sin²θt ≤ 0.99`; nearer, both forms are as ill-conditioned as `cos θt` is), the error
    /// relative to `max(F, 0.01)` (`F` is 2.5e-9 at η 1.0001, where the plain relative error
    /// measures the cancellation in `cos θi − η cos θt` of both forms alike): f64 measured
    /// 4.9e-15 (asserted 1e-13); scalar f32 against the f64 textbook value at the rounded
    /// inputs 2.3e-6 (asserted 1e-5; the textbook form in f32: 2.9e-6, numpy replay).
    #[test]
    fn dielectric_with_one_division_matches_the_textbook_form() {
        let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
        for &eta in &[1.0001, 1.33, 1.5, 2.5, 1.0 / 1.5] {
            for k in 0..=4000 {
                let c = -1.0 + 2.0 * f64::from(k) / 4000.0;
                let e = if c < 0.0 { 1.0 / eta } else { eta };
                if (1.0 - c * c) / (e * e) > 0.99 {
                    continue;
                }
                let want = dielectric_textbook(c, eta);
                worst64 = worst64.max((dielectric(c, eta) - want).abs() / want.max(0.01));
                // f32 inputs: the reference at the rounded inputs.
                let (c32, eta32) = (c as f32, eta as f32);
                let want32 = dielectric_textbook(f64::from(c32), f64::from(eta32));
                worst32 = worst32.max((f64::from(dielectric(c32, eta32)) - want32).abs() / want32.max(0.01));
            }
        }
        println!("dielectric vs textbook: f64 {worst64:.2e}, f32 {worst32:.2e} (relative to max(F, 0.01))");
        assert!(worst64 < 1e-13, "f64 {worst64:e}");
        assert!(worst32 < 1e-5, "f32 {worst32:e}");
    }

    /// Hecht's transmitted power `T = ½ (η c_t/c)(t_s² + t_p²)` from the amplitude
    /// transmission coefficients `t_s = 2c/(c + η c_t)`, `t_p = 2c/(ηc + c_t)` (f64, no
    /// cancellation): the independent reference for [`dielectric_transmittance`].
    fn transmittance_hecht(cos_i: f64, eta: f64) -> f64 {
        let eta = if cos_i < 0.0 { 1.0 / eta } else { eta };
        let c = cos_i.abs().min(1.0);
        let sin2_t = (1.0 - c * c) / (eta * eta);
        if sin2_t >= 1.0 || c == 0.0 {
            return 0.0;
        }
        let ct = (1.0 - sin2_t).sqrt();
        let (ts, tp) = (2.0 * c / (c + eta * ct), 2.0 * c / (eta * c + ct));
        0.5 * (eta * ct / c) * (ts * ts + tp * tp)
    }

    /// `dielectric_transmittance` is `1 − F` without the cancellation at grazing incidence:
    /// against Hecht's form for cos θ from 1e-7 to 1, both sides, four indices (away from the
    /// critical angle, as above): f64 within 1e-13 relative (measured 8.6e-16), f32 within 2e-6
    /// relative of the f64 reference at the rounded inputs (measured 4.3e-7), where `1 − F` in
    /// f32 is 2.4e-4 off at cos θ = 1e-4 (asserted > 1e-4: the old form fails the bound), and
    /// `F + T = 1` in f64 within 1e-15.
    #[test]
    fn dielectric_transmittance_keeps_its_precision_at_grazing_incidence() {
        let (mut worst64, mut worst32, mut worst_sum) = (0.0f64, 0.0f64, 0.0f64);
        for &eta in &[1.0001, 1.33, 1.5, 2.5] {
            for side in [1.0, -1.0] {
                for k in 0..=700 {
                    let c = side * 10f64.powf(-7.0 + 7.0 * f64::from(k) / 700.0);
                    let e = if c < 0.0 { 1.0 / eta } else { eta };
                    if (1.0 - c * c) / (e * e) > 0.99 {
                        continue;
                    }
                    let want = transmittance_hecht(c, eta);
                    worst64 = worst64.max((dielectric_transmittance(c, eta) - want).abs() / want);
                    worst_sum = worst_sum.max((dielectric_transmittance(c, eta) + dielectric(c, eta) - 1.0).abs());
                    let (c32, eta32) = (c as f32, eta as f32);
                    let want32 = transmittance_hecht(f64::from(c32), f64::from(eta32));
                    worst32 = worst32.max((f64::from(dielectric_transmittance(c32, eta32)) - want32).abs() / want32);
                }
            }
        }
        let c = 1e-4f32;
        let want = transmittance_hecht(f64::from(c), f64::from(1.5f32));
        let one_minus_f = (f64::from(1.0 - dielectric(c, 1.5f32)) - want).abs() / want;
        println!(
            "dielectric_transmittance vs Hecht: f64 {worst64:.2e}, f32 {worst32:.2e}; F + T - 1 {worst_sum:.1e}; 1 - F in f32 at cos 1e-4: {one_minus_f:.2e}"
        );
        assert!(worst64 < 1e-13, "f64 {worst64:e}");
        assert!(worst32 < 2e-6, "f32 {worst32:e}");
        assert!(worst_sum < 1e-15, "F + T - 1: {worst_sum:e}");
        assert!(one_minus_f > 1e-4, "1 - F in f32 at cos 1e-4: {one_minus_f:e}");
        assert_eq!(dielectric_transmittance(-0.1f64, 1.5), 0.0, "total internal reflection");
        assert_eq!(dielectric_transmittance(0.0f64, 1.5), 0.0);
    }

    #[test]
    fn conductor_normal_incidence_matches_closed_form() {
        // F0 = ((η−1)² + k²)/((η+1)² + k²).
        for m in METALS {
            for c in 0..3 {
                let (n, k) = (m.eta[c], m.k[c]);
                let f0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
                assert!((conductor(1.0, n, k) - f0).abs() < 1e-12, "{}", m.name);
            }
        }
    }

    /// The closed real form against the complex Fresnel amplitudes computed independently
    /// (complex arithmetic written out here, Born & Wolf's r_s, r_p with complex cos θt), for
    /// metals, dielectrics and in between, at 2001 angles: agreement to 1e-13 absolute in f64
    /// (measured 4e-16), and the f32 version within 2e-6 relative of it (measured 4e-7 on gold,
    /// where the cancellation-free a² matters).
    #[test]
    fn conductor_closed_form_matches_complex_amplitudes() {
        #[derive(Clone, Copy)]
        struct C(f64, f64);
        let mul = |a: C, b: C| C(a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
        let div = |a: C, b: C| {
            let d = b.0 * b.0 + b.1 * b.1;
            C((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
        };
        let sqrt = |a: C| {
            let r = (a.0 * a.0 + a.1 * a.1).sqrt();
            let re = (0.5 * (r + a.0)).sqrt();
            let im = (0.5 * (r - a.0)).max(0.0).sqrt().copysign(a.1);
            C(re, im)
        };
        let reference = |c: f64, eta: f64, k: f64| {
            let n = C(eta, k);
            let s2 = 1.0 - c * c;
            let ct = sqrt(C(1.0 - div(C(s2, 0.0), mul(n, n)).0, -div(C(s2, 0.0), mul(n, n)).1));
            let nct = mul(n, ct);
            let rs = div(C(c - nct.0, -nct.1), C(c + nct.0, nct.1));
            let nc = C(n.0 * c, n.1 * c);
            let rp = div(C(nc.0 - ct.0, nc.1 - ct.1), C(nc.0 + ct.0, nc.1 + ct.1));
            0.5 * (rs.0 * rs.0 + rs.1 * rs.1 + rp.0 * rp.0 + rp.1 * rp.1)
        };
        let mut worst32 = 0.0f64;
        for (eta, k) in [(0.143, 3.983), (0.155, 4.828), (1.657, 9.224), (0.2, 0.5), (1.5, 0.0), (2.0, 1.0), (0.5, 0.0)]
        {
            for i in 0..=2000 {
                let c = i as f64 / 2000.0;
                let want = reference(c, eta, k);
                let got = conductor(c, eta, k);
                assert!((got - want).abs() < 1e-13, "η {eta} k {k} cos {c}: {got} vs {want}");
                if k > 0.0 {
                    let got32 = f64::from(conductor(c as f32, eta as f32, k as f32));
                    worst32 = worst32.max((got32 - want).abs() / want);
                }
            }
        }
        assert!(worst32 < 2e-6, "f32 closed form: {worst32:e}");
    }

    #[test]
    fn conductor_with_zero_k_is_the_dielectric() {
        for i in 0..=20 {
            let c = i as f64 / 20.0;
            assert!((conductor(c, 1.7, 0.0) - dielectric(c, 1.7)).abs() < 1e-12);
        }
    }

    #[test]
    fn ior_from_f0_inverts_the_normal_incidence_reflectance() {
        // F0 = 0.04 is glass of index 1.5 exactly.
        assert!((ior_from_f0(0.04) - 1.5).abs() < 1e-12);
        assert_eq!(ior_from_f0(0.0), 1.0);
    }

    #[test]
    fn f82_hits_f0_at_normal_incidence_and_the_tinted_schlick_value_at_82_degrees() {
        for (f0, tint) in [(0.9, 0.5), (0.2, 0.0), (0.6, 1.0), (0.95, 0.8)] {
            let b = f82_tint_b(f0, tint);
            assert!((f82(1.0f64, f0, b) - f0).abs() < 1e-15);
            // At cos = 1/7: Schlick's F0 + (1 − F0)(6/7)⁵, times the tint.
            let schlick = f0 + (1.0 - f0) * (6.0f64 / 7.0).powi(5);
            assert!((f82(1.0f64 / 7.0, f0, b) - schlick * tint).abs() < 1e-12, "{f0} {tint}");
            // Grazing: 1 whatever the tint (the correction vanishes with cos).
            assert!((f82(0.0f64, f0, b) - 1.0).abs() < 1e-15);
        }
        assert_eq!(f82_tint_b(0.5, 1.0), 0.0);
    }

    #[test]
    fn schlick_endpoints() {
        assert_eq!(schlick(1.0f64, 0.04), 0.04);
        assert_eq!(schlick(0.0f64, 0.04), 1.0);
    }

    /// η = 1, k = 0 reflects nothing: exactly 0 at every angle, in f64 and f32 (the formula
    /// gave ±1e-17 residues and 0/0 at cos θ = 0), and indices next to it are untouched.
    #[test]
    fn index_matched_conductor_is_exactly_zero() {
        for i in 0..=1000 {
            let c = f64::from(i) / 1000.0;
            assert_eq!(conductor(c, 1.0, 0.0), 0.0, "cos {c}");
            assert_eq!(conductor(c as f32, 1.0, 0.0), 0.0, "cos {c} (f32)");
            for (eta, k) in [(1.0 + 1e-6, 0.0), (1.0, 1e-6), (1.5, 0.0)] {
                assert_eq!(conductor(c, eta, k).to_bits(), conductor_formula(c, eta, k).to_bits());
            }
        }
        assert_eq!(conductor(1e-30f32, 1.0, 0.0), 0.0);
    }

    /// The fitted conductor Fresnel against the exact formula in f64, per channel, for the
    /// measured metals in air and in a binder of index 1.5 (the paint's flakes), at 4097
    /// cosines including both ends: every lane type agrees with f64 to 1e-6 relative (the
    /// fit's tolerance), and each fit alone is within 3e-7 (measured 3.0e-8 … 6.4e-8 for the
    /// 8-piece fit, 3.1e-8 … 1.5e-7 for the 32-piece one). Measured end to end: the fitted
    /// AVX-512 lanes 1.8e-7 (session 22's Intel host), the fitted AVX2 lanes 1.6e-7, while the
    /// exact formula in scalar f32 gives 4.2e-7 (before the AVX2 fit, AVX2 lanes ran it: 4.5e-7):
    /// the fits are the more accurate f32 paths. Index-matched interfaces keep the exact formula.
    #[test]
    fn fitted_conductor_fresnel_matches_the_exact_formula() {
        /// Each measured metal in air and relative to a binder of index 1.5.
        fn materials() -> Vec<([f64; 3], [f64; 3])> {
            METALS.iter().flat_map(|m| [(m.eta, m.k), (m.eta.map(|n| n / 1.5), m.k.map(|k| k / 1.5))]).collect()
        }
        fn check<L: Lanes>() -> f64 {
            let mut worst = 0.0f64;
            for (eta, k) in materials() {
                let fresnel = ConductorFresnel::new(eta, k);
                let fit_error = fresnel.fit_error().expect("a measured metal has a fit");
                let fit8_error = fresnel.fit8_error().expect("a measured metal has an 8-piece fit");
                eprintln!("eta {eta:.3?} k {k:.3?}: fit errors {fit_error:.2e} (32 pieces), {fit8_error:.2e} (8)");
                assert!(fit_error < 3e-7, "fit error {fit_error} for eta {eta:?}, k {k:?}");
                assert!(fit8_error < 3e-7, "8-piece fit error {fit8_error} for eta {eta:?}, k {k:?}");
                for j in 0..=4096 / L::WIDTH {
                    let mu = L::from_fn(|i| L::Elem::of(((j * L::WIDTH + i) as f64 / 4096.0).min(1.0)));
                    let f = fresnel.eval(mu);
                    for i in 0..L::WIDTH {
                        let m = mu.lane(i).f64();
                        for (c, got) in [f.r, f.g, f.b].into_iter().enumerate() {
                            let exact = conductor(m, eta[c], k[c]);
                            worst = worst.max((got.lane(i).f64() - exact).abs() / exact);
                        }
                    }
                }
            }
            worst
        }
        // One lane: the exact formula (f64 bit-identical to `conductor`).
        let (worst_f64, worst_f32) = (check::<f64>(), check::<f32>());
        eprintln!("one lane: f64 {worst_f64:.2e}, f32 {worst_f32:.2e}");
        assert!(worst_f64 < 1e-14);
        assert!(worst_f32 < 1e-6);
        #[cfg(target_arch = "x86_64")]
        {
            fn simd<L: Lanes>() {
                let worst = check::<L>();
                eprintln!("{} lanes: {worst:.2e}", L::WIDTH);
                assert!(worst < 1e-6, "{} lanes: {worst}", L::WIDTH);
            }
            crate::lanes::x86::check_each_simd_type!(simd);
        }
        let matched = ConductorFresnel::new([1.0; 3], [0.0; 3]);
        assert!(matched.fit_error().is_none() && matched.fit8_error().is_none(), "index-matched");
    }
}
