//! Ashikhmin & Shirley (2000), the anisotropic Phong BRDF with its own coupled diffuse term,
//!
//! ```text
//! f(k1, k2) = ρs + ρd
//! ρs = √((nu+1)(nv+1))/(8π) · (n·h)^{nu cos²φh + nv sin²φh} / ((h·k) max(n·k1, n·k2)) · F(h·k)
//! ρd = 28 Rd/(23π) · (1 − Rs) · (1 − (1 − n·k1/2)⁵) · (1 − (1 − n·k2/2)⁵)
//! F(c) = Rs + (1 − Rs)(1 − c)⁵     (Schlick)
//! ```
//!
//! with `h` the half vector, φh its azimuth from the tangent x, and `h·k = h·k1 = h·k2`
//! (`= |k1 + k2|/2` for unit directions). The exponent is the paper's
//! `(nu (h·u)² + nv (h·v)²)/(1 − (h·n)²)`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | substrate (diffuse) reflectance Rd |
//! | `specular` | colour | 0.05 | [0, 1] | specular reflectance at normal incidence Rs (Schlick's F0) |
//! | `nu` | scalar | 100 | [0, 10⁴] | Phong-like exponent along the tangent x |
//! | `nv` | scalar | 100 | [0, 10⁴] | Phong-like exponent along the bitangent y |
//!
//! Physics: reciprocal. Energy conserving (claimed, and checked): the specular term is
//! `p_h(h) F / (4 (h·k) max(n·k1, n·k2))` with `p_h` the paper's normalised half-vector density
//! (below), so with `dωi = 4 (h·k) dωh` its albedo is `∫ p_h F cos θi / max(cos θi, cos θo) dωh`
//! ≤ 1 for F ≤ 1. The total is linear in Rs; at Rs = 1 it is that bound, at Rs = 0 it is
//! `∫ p_h (1 − h·k)⁵ cosθi/max dωh + Rd (1 − (1 − cosθo/2)⁵)` (the diffuse albedo, in closed
//! form: `2π ∫₀¹ (1 − (1 − μ/2)⁵) μ dμ = 23π/28`), which the paper designed to stay below 1
//! and which quadrature and the furnace confirm over the exponent range, anisotropic corners
//! included (at most 0.969 for Rd = 1, at normal incidence). The Fresnel factor in the
//! diffuse term is what allows Rd = 1 with any Rs; the thesis's plain Lambertian variant is
//! [`super::ashikhmin_shirley_lambert`]. `(h·k) max(n·k1, n·k2)` is clamped below at 10⁻³⁰.
//!
//! Sampling (the paper's section 5): the half vector's azimuth in the first quadrant is
//! `φh = atan(√((nu+1)/(nv+1)) tan(π ξ1/2))` (ξ1 remapped from a quarter of `u[1]`, mirrored into
//! the other three quadrants), its polar angle `cos θh = (1 − ξ2)^{1/(nu cos²φh + nv sin²φh + 1)}`;
//! this draws `h` with density `p_h(h) = √((nu+1)(nv+1))/(2π) (n·h)^{nu cos²φh + nv sin²φh}`,
//! and `wi` (`wo` mirrored about `h`) with `p_h/(4 h·k)`. The diffuse term is sampled
//! cosine-weighted; `u[0]` picks between them in proportion to `(1 − R̄s) R̄d` and the
//! Schlick reflectance at `wo` (channel means). The pdf is the mixture.
//!
//! Reference: M. Ashikhmin, P. Shirley, "An anisotropic Phong BRDF model", Journal of Graphics
//! Tools 5(2), 2000, 25–32.

use super::phong::{mean, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::{reflect, spherical_direction, versine_z};
use crate::fresnel::schlick_rgb;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cos_pow_versine, cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe};

/// Parameters of both Ashikhmin-Shirley models (`diffuse` is Rd here, kd in the Lambertian variant).
pub(crate) const fn params(diffuse_doc: &'static str) -> [ParamSpec; 4] {
    [
        ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, diffuse_doc),
        ParamSpec::color("specular", [0.05; 3], 0.0, 1.0, "specular reflectance at normal incidence Rs (Schlick's F0)"),
        ParamSpec::scalar("nu", 100.0, 0.0, MAX_EXPONENT, "", "Phong-like exponent along the tangent x"),
        ParamSpec::scalar("nv", 100.0, 0.0, MAX_EXPONENT, "", "Phong-like exponent along the bitangent y"),
    ]
}

const PARAMS: &[ParamSpec] = &params("substrate (diffuse) reflectance Rd");

/// Parameter sets the checks run for both models besides the defaults: rough isotropic,
/// anisotropic and coloured, a metal.
pub(crate) const CHECK_PARAMS: &[&str] = &[
    r#"{"diffuse": 1.0, "specular": 0.0, "nu": 1.0, "nv": 1.0}"#,
    r#"{"diffuse": [0.6, 0.3, 0.1], "specular": [0.05, 0.1, 0.2], "nu": 10.0, "nv": 1000.0}"#,
    r#"{"diffuse": 0.0, "specular": [0.95, 0.64, 0.54], "nu": 300.0, "nv": 30.0}"#,
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "ashikhmin_shirley",
    summary: "Ashikhmin & Shirley 2000 anisotropic Phong with Schlick Fresnel and its coupled diffuse term",
    reference: "M. Ashikhmin, P. Shirley, An anisotropic Phong BRDF model, Journal of Graphics Tools 5(2) 2000",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: CHECK_PARAMS,
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    Ok(Model::AshikhminShirley(AshikhminShirley { lobe: AsLobe::from_params(p) }))
}

/// Smallest `(h·k) max(n·k1, n·k2)` and `|k1 + k2|` divided by: keeps values finite in f32.
#[inline]
fn denominator_floor<T: Real>() -> T {
    T::of(1e-30)
}

/// The Ashikhmin-Shirley specular lobe, its half-vector sampler, and the diffuse colour.
#[derive(Clone, Debug)]
pub struct AsLobe {
    /// Rd (coupled model) or kd (Lambertian variant) per channel.
    pub diffuse: [f64; 3],
    /// Rs per channel.
    pub specular: [f64; 3],
    /// Exponent along x.
    pub nu: f64,
    /// Exponent along y.
    pub nv: f64,
}

impl AsLobe {
    /// Reads the parameters.
    pub(crate) fn from_params(p: &Params) -> Self {
        Self { diffuse: p.color("diffuse"), specular: p.color("specular"), nu: p.scalar("nu"), nv: p.scalar("nv") }
    }

    /// The half-vector density `√((nu+1)(nv+1))/(2π) (n·h)^{nu cos²φh + nv sin²φh}` from the
    /// unnormalised half vector `s = k1 + k2`.
    #[inline]
    fn half_density<T: Real>(&self, s: Vec3<T>) -> T {
        let (nu, nv) = (T::of(self.nu), T::of(self.nv));
        let r2 = s.x * s.x + s.y * s.y;
        let e = if r2 > T::zero() { (nu * s.x * s.x + nv * s.y * s.y) / r2 } else { nu };
        let norm = T::of(((self.nu + 1.0) * (self.nv + 1.0)).sqrt()) * T::inv_pi() * T::of(0.5);
        norm * cos_pow_versine(versine_z(s), e)
    }

    /// `ρs(k1, k2)`, the specular term.
    #[inline]
    pub(crate) fn specular_value<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let s = wi + wo;
        let len = s.length();
        if !(len > T::zero()) || !(s.z > T::zero()) {
            return Rgb::zero();
        }
        // h·k = |s|/2, so p_h F / (4 (h·k) max) = p_h F / (2 |s| max).
        let denom = (T::of(2.0) * len * wi.z.max(wo.z)).max(denominator_floor());
        let fresnel = schlick_rgb(T::of(0.5) * len, Rgb::from_array(self.specular));
        fresnel * (self.half_density(s) / denom)
    }

    /// Density of the half-vector sampler in `wi`: `p_h / (4 h·k) = p_h / (2 |wi + wo|)`.
    #[inline]
    pub(crate) fn specular_pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let s = wi + wo;
        let len = s.length();
        if !(len > T::zero()) || !(s.z > T::zero()) {
            return T::zero();
        }
        self.half_density(s) / (T::of(2.0) * len).max(denominator_floor())
    }

    /// The paper's half-vector sampler (eqs. for φh and cos θh), first quadrant mirrored into
    /// all four by `u1`.
    #[inline]
    pub(crate) fn sample_half<T: Real>(&self, u1: T, u2: T) -> Vec3<T> {
        let x = (u1 * T::of(4.0)).clamp_to(T::zero(), T::of(4.0));
        let quadrant = x.floor().min(T::of(3.0));
        let t = (x - quadrant).clamp_to(T::zero(), T::one());
        let ratio = T::of(((self.nu + 1.0) / (self.nv + 1.0)).sqrt());
        let phi0 = (ratio * (T::FRAC_PI_2() * t).tan()).atan();
        let pi = T::PI();
        let phi = match quadrant.to_u8().unwrap_or(0) {
            0 => phi0,
            1 => pi - phi0,
            2 => pi + phi0,
            _ => T::of(2.0) * pi - phi0,
        };
        let (cos_phi, sin_phi) = (phi.cos(), phi.sin());
        let e = T::of(self.nu) * cos_phi * cos_phi + T::of(self.nv) * sin_phi * sin_phi;
        let one_minus = (T::one() - u2).max(T::min_positive_value());
        let cos_t = (one_minus.ln() / (e + T::one())).exp();
        let sin_t = (T::one() - cos_t * cos_t).safe_sqrt();
        spherical_direction(sin_t, cos_t, phi)
    }

    /// Selection weights `[diffuse, specular]` for `wo`: the given diffuse weight and the
    /// Schlick reflectance at `wo` (channel means), or an even split when both vanish.
    #[inline]
    pub(crate) fn lobe_weights<T: Real>(&self, diffuse_weight: f64, wo: Vec3<T>) -> [T; 2] {
        let d = T::of(diffuse_weight);
        let s = schlick_rgb(wo.z, Rgb::from_array(self.specular)).average();
        let total = d + s;
        if total > T::zero() {
            [d / total, s / total]
        } else {
            [T::of(0.5), T::of(0.5)]
        }
    }

    /// Mixture density for the selection weights `w`.
    #[inline]
    pub(crate) fn pdf<T: Real>(&self, w: [T; 2], wi: Vec3<T>, wo: Vec3<T>) -> T {
        w[0] * cosine_hemisphere_pdf(wi.z) + w[1] * self.specular_pdf(wi, wo)
    }

    /// Draws `wi` for the selection weights `w`; `None` below the horizon.
    #[inline]
    pub(crate) fn sample_direction<T: Real>(&self, w: [T; 2], wo: Vec3<T>, u: [T; 3]) -> Option<Vec3<T>> {
        let (lobe, _) = pick_lobe(&w, u[0])?;
        let wi = if lobe == 0 { cosine_hemisphere(u[1], u[2]) } else { reflect(wo, self.sample_half(u[1], u[2])) };
        (wi.z > T::zero() && wi.is_finite()).then_some(wi)
    }
}

/// `1 − (1 − μ/2)⁵`, the paper's diffuse angular factor.
#[inline]
fn diffuse_factor<T: Real>(mu: T) -> T {
    let m = T::one() - T::of(0.5) * mu.clamp_to(T::zero(), T::one());
    let m2 = m * m;
    T::one() - m2 * m2 * m
}

/// The Ashikhmin-Shirley BRDF with its coupled diffuse term.
#[derive(Clone, Debug)]
pub struct AshikhminShirley {
    /// Parameters and sampler.
    pub lobe: AsLobe,
}

impl AshikhminShirley {
    /// `ρd = 28 Rd/(23π) (1 − Rs)(1 − (1 − cos θi/2)⁵)(1 − (1 − cos θo/2)⁵)`.
    #[inline]
    pub fn diffuse_value<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let rd = Rgb::from_array(self.lobe.diffuse);
        let one_minus_rs = Rgb::from_array(self.lobe.specular).map(|r| T::one() - r);
        let k = T::of(28.0 / 23.0) * T::inv_pi() * diffuse_factor(wi.z) * diffuse_factor(wo.z);
        rd * one_minus_rs * k
    }

    #[inline]
    fn weights<T: Real>(&self, wo: Vec3<T>) -> [T; 2] {
        self.lobe.lobe_weights(mean(self.lobe.diffuse) * (1.0 - mean(self.lobe.specular)), wo)
    }
}

impl Bxdf for AshikhminShirley {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        self.diffuse_value(wi, wo) + self.lobe.specular_value(wi, wo)
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.lobe.pdf(self.weights(wo), wi, wo)
    }

    #[inline]
    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wi = self.lobe.sample_direction(self.weights(wo), wo, u)?;
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

/// Golden values and quadratures shared with the Lambertian variant's tests.
#[cfg(test)]
pub(crate) mod testing {
    /// Specular albedo at normal incidence with F ≡ 1 (Rs = 1), isotropic exponent n, by hand:
    /// `∫ p_h cos θi dωh` with `cos θi = 2c² − 1` (`c = cos θh ≥ 1/√2`):
    /// `(n+1) ∫ cⁿ (2c² − 1) dc = (n+1) [2 (1 − 2^{−(n+3)/2})/(n+3) − (1 − 2^{−(n+1)/2})/(n+1)]`.
    pub fn normal_incidence_specular_albedo(n: f64) -> f64 {
        (n + 1.0) * (2.0 * (1.0 - 2f64.powf(-(n + 3.0) / 2.0)) / (n + 3.0) - (1.0 - 2f64.powf(-(n + 1.0) / 2.0)) / (n + 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::testing::normal_incidence_specular_albedo;
    use super::*;
    use crate::check::furnace::albedo;
    use crate::frame::mirror_z;
    use crate::material::Material;
    use crate::rng::Pcg32;
    use std::f64::consts::PI;

    fn asm(json: &str) -> Material {
        Material::from_json(&format!(r#"{{"model": "ashikhmin_shirley", {json}}}"#)).unwrap()
    }

    fn dir(c: f64, phi: f64) -> Vec3<f64> {
        spherical_direction((1.0 - c * c).sqrt(), c, phi)
    }

    /// The paper's formula, written out from θh, φh and the angles.
    #[test]
    fn value_is_the_papers_formula() {
        let (nu, nv, rd, rs) = (40.0f64, 400.0f64, 0.6f64, 0.2f64);
        let m = asm(r#""diffuse": 0.6, "specular": 0.2, "nu": 40, "nv": 400"#);
        for (wi, wo) in [(dir(0.7, 0.3), dir(0.8, 3.5)), (dir(0.3, 1.0), dir(0.95, 4.0)), (dir(0.5, 2.0), dir(0.5, 5.0))] {
            let h = (wi + wo).normalize();
            let (theta_h, phi_h) = (h.z.acos(), h.y.atan2(h.x));
            let e = nu * phi_h.cos().powi(2) + nv * phi_h.sin().powi(2);
            let hk = h.dot(wi);
            let fresnel = rs + (1.0 - rs) * (1.0 - hk).powi(5);
            let spec = ((nu + 1.0) * (nv + 1.0)).sqrt() / (8.0 * PI) * theta_h.cos().powf(e)
                / (hk * wi.z.max(wo.z))
                * fresnel;
            let diff = 28.0 * rd / (23.0 * PI)
                * (1.0 - rs)
                * (1.0 - (1.0 - wi.z / 2.0).powi(5))
                * (1.0 - (1.0 - wo.z / 2.0).powi(5));
            let f = m.eval(wi, wo).r;
            assert!((f - spec - diff).abs() < 1e-12 * (spec + diff), "{f} vs {}", spec + diff);
            assert!((m.eval(wo, wi).r - f).abs() < 1e-13 * f);
        }
    }

    /// Diffuse albedo, by hand: `2π ∫₀¹ (1 − (1 − μ/2)⁵) μ dμ = 23π/28`, so
    /// `∫ ρd cos θi dωi = Rd (1 − Rs)(1 − (1 − cos θo/2)⁵)`.
    #[test]
    fn diffuse_albedo_closed_form() {
        let Model::AshikhminShirley(m) = asm(r#""diffuse": 0.8, "specular": 0.25"#).model().clone() else { panic!() };
        for c in [1.0f64, 0.6, 0.1] {
            let wo = dir(c, 0.0);
            let n = 4000;
            let a: f64 = (0..n)
                .map(|i| {
                    let mu = (i as f64 + 0.5) / n as f64;
                    m.diffuse_value(dir(mu, 1.0), wo).g * mu * 2.0 * PI / n as f64
                })
                .sum();
            let golden = 0.8 * 0.75 * (1.0 - (1.0 - c / 2.0).powi(5));
            assert!((a - golden).abs() < 1e-7, "cos θo = {c}: {a} vs {golden}");
        }
    }

    /// With Rs = 1 (F ≡ 1, no diffuse) the normal-incidence albedo is the closed form above.
    /// A sharp lobe tends to 1 at every angle (the `max` keeps the metal bright at grazing):
    /// with `h = z + (tx, ty)`, `tx, ty ~ N(0, 1/n)`, the mirrored `cos θi ≈ cos θo + 2 wo.x tx`,
    /// so `cos θi / max(cos θi, cos θo) = min(1, 1 + 2 tan θo tx)` and the albedo is
    /// `1 − tan θo E|tx| = 1 − tan θo √(2/(πn))`.
    #[test]
    fn metal_albedo_closed_form_and_mirror_limit() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        for n in [0.0, 5.0, 100.0] {
            let m = asm(&format!(r#""diffuse": 0.0, "specular": 1.0, "nu": {n}, "nv": {n}"#));
            let golden = normal_incidence_specular_albedo(n);
            let a = albedo_around(&m, z, z)[0];
            assert!((a - golden).abs() < 2e-4, "n = {n}: {a} vs {golden}");
        }
        assert!((normal_incidence_specular_albedo(0.0) - 0.13807).abs() < 1e-5);
        let m = asm(r#""diffuse": 0.0, "specular": 1.0, "nu": 8000, "nv": 8000"#);
        for c in [0.9f64, 0.5, 0.2] {
            let wo = dir(c, 0.4);
            let a = albedo_around(&m, wo, mirror_z(wo))[0];
            let tan = (1.0 - c * c).sqrt() / c;
            let expect = 1.0 - tan * (2.0 / (PI * 8000.0)).sqrt();
            assert!(a < 1.0 && (a - expect).abs() < 1e-3, "cos θo = {c}: {a} vs {expect}");
        }
    }

    /// The half-vector density integrates to one over the hemisphere, anisotropic included.
    #[test]
    fn half_vector_density_is_normalised() {
        for (nu, nv) in [(0.0, 0.0), (10.0, 1000.0), (500.0, 3.0)] {
            let lobe = AsLobe { diffuse: [0.0; 3], specular: [0.0; 3], nu, nv };
            // Warp cos θh = 1 − 2^{-?}: integrate in v = 1 − cos θh with v = w⁴.
            let (nw, nphi) = (3000, 1440);
            let mut total = 0.0;
            for i in 0..nw {
                let w = (i as f64 + 0.5) / nw as f64;
                let v = w.powi(4);
                let dv = 4.0 * w.powi(3) / nw as f64;
                for j in 0..nphi {
                    let phi = 2.0 * PI * (j as f64 + 0.5) / nphi as f64;
                    let h = dir(1.0 - v, phi);
                    total += lobe.half_density(h) * dv * 2.0 * PI / nphi as f64;
                }
            }
            assert!((total - 1.0).abs() < 2e-3, "nu={nu} nv={nv}: {total}");
        }
    }

    /// `sample` follows the paper's formulas for φh and cos θh and reports `p_h/(4 h·k)`.
    #[test]
    fn sampling_follows_the_papers_equations() {
        let (nu, nv) = (20.0f64, 200.0f64);
        let m = asm(r#""diffuse": 0.0, "specular": 0.5, "nu": 20, "nv": 200"#);
        let wo = dir(0.8, 0.3);
        for (xi1, xi2, quadrant) in [(0.3f64, 0.4f64, 0usize), (0.7, 0.2, 1), (0.1, 0.9, 2), (0.5, 0.5, 3)] {
            let phi0 = (((nu + 1.0) / (nv + 1.0)).sqrt() * (PI * xi1 / 2.0).tan()).atan();
            let phi = [phi0, PI - phi0, PI + phi0, 2.0 * PI - phi0][quadrant];
            let e = nu * phi.cos().powi(2) + nv * phi.sin().powi(2);
            let cos_t = (1.0 - xi2).powf(1.0 / (e + 1.0));
            let h = dir(cos_t, phi);
            let wi = h * (2.0 * wo.dot(h)) - wo;
            let s = m.sample(wo, [0.99, (quadrant as f64 + xi1) / 4.0, xi2]).expect("above the horizon");
            assert!((s.wi - wi).length() < 1e-9, "{:?} vs {wi:?}", s.wi);
            let p_h = ((nu + 1.0) * (nv + 1.0)).sqrt() / (2.0 * PI) * cos_t.powf(e);
            let expect = p_h / (4.0 * wo.dot(h));
            assert!((s.pdf - expect).abs() < 1e-9 * expect, "{} vs {expect}", s.pdf);
        }
    }

    /// The energy claim at its worst: Rs = 0 (diffuse strongest) and Rs = 1, rough and
    /// extreme anisotropy, the furnace over wo (MIS estimator of the checks).
    #[test]
    fn albedo_at_most_one_at_the_corners() {
        let mut rng = Pcg32::new(7, 11);
        for (nu, nv) in [(0.0, 0.0), (0.0, 10000.0), (10000.0, 0.0), (1.0, 100.0), (10000.0, 10000.0)] {
            for rs in [0.0, 1.0] {
                let m = asm(&format!(r#""diffuse": 1.0, "specular": {rs}, "nu": {nu}, "nv": {nv}"#));
                for c in [1.0, 0.7, 0.3, 0.05] {
                    for phi in [0.0, 0.8] {
                        let (a, se) = albedo(&m, dir(c, phi), 20_000, &mut rng);
                        assert!(a[0] - 3.0 * se <= 1.0, "nu={nu} nv={nv} Rs={rs} cos={c}: {a:?} ± {se}");
                    }
                }
            }
        }
    }
}
