//! He-Torrance-Sillion-Greenberg (1991): the physical-optics reflectance model, with its
//! specular, directional-diffuse and uniform-diffuse terms,
//!
//! ```text
//! f = f_sp + f_dd + a/π
//! f_sp = F(θo) · e^{−g_sp} · S(θi) S(θo) · δ(wi − mirror(wo)) / cos θi         (a Dirac lobe)
//! f_dd = F(θℓ) · S(θi) S(θo) · (1 + wi·wo)² / (cos θi cos θo w²) · Φ(v_xy)
//! Φ    = (k²τ²/4π) · Σ_{m≥1} e^{−g} g^m / (m!·m) · exp(−k²τ² |v_xy|² / 4m)
//! ```
//!
//! with `k = 2π/λ`, `w = cos θi + cos θo`, `v_xy = (wi + wo)_xy` (the tangential part of the
//! scattering vector in units of `k`), `g = (k σ w)²` the roughness phase variance, `σ` the
//! *effective* roughness and `cos θℓ = |wi + wo|/2` the cosine of the local incidence angle
//! at which the polarisation-averaged conductor Fresnel reflectance `F` is evaluated
//! ([`crate::fresnel::conductor`], exact for a complex index `η + iκ`; `κ = 0` is a dielectric).
//! This is the paper's eq. 78 written with `G = (v·v/v_z)²` (eq. 76: for unpolarised light and
//! the polarisation-averaged `|F|²` the two polarisation brackets cancel `|k̂r × k̂i|⁴`, so only
//! `(v·v/v_z)²` remains) and `D`'s prefactor `π²τ²/(4λ²)` folded into `k²τ²/4π`.
//! Each term of the series is a normalised Gaussian in `v_xy`, so with `F = S = 1` and the
//! geometric factor at its specular value 1, `e^{−g}` (specular) plus the `m ≥ 1` terms
//! integrate to exactly 1 over the projected hemisphere (Parseval; Stam 1999 derives the same
//! series from the Kirchhoff integral).
//!
//! * Effective roughness (eqs. 80-83): `σ = σ₀/√(1 + z₀²/σ₀²)` with
//!   `√(π/2)·z₀ = (σ₀/4)(K_i + K_o)·exp(−z₀²/2σ₀²)` and `K = tan θ · erfc(τ cot θ / 2σ₀)`,
//!   solved for `x = z₀/σ₀` (`x e^{x²/2} = (K_i + K_o)/√(8π)`) by a safeguarded Newton
//!   iteration in log form.
//! * Shadowing (eqs. 23-25, Smith 1967): `S(θ) = (1 − ½ erfc(a)) / (1 + Λ(a))`,
//!   `a = τ cot θ / 2σ₀`, `Λ = ½ (e^{−a²}/(√π a) − erfc(a))`. The printed eq. 25 omits the
//!   `e^{−a²}`; the errata of Holzschuch & Pacanowski and Westin's reference code restore
//!   it, and it is Smith's Λ for Gaussian slopes of RMS `√2 σ₀/τ` (Beckmann `α = 2σ₀/τ`).
//! * `v_xy` in the exponent carries the wave number (`v = k(k̂r − k̂i)`, as in Westin's code);
//!   with `|v̂_xy|` alone the exponent would not be dimensionless.
//! * Uniform diffuse: `a(λ)` is taken as a parameter (the paper's `a(λ)` is a fitted
//!   subsurface albedo, not derived).
//!
//! Wavelength per RGB channel: the dominant wavelengths of the Rec.709 primaries,
//! λ = 611, 549, 464 nm ([`LAMBDA_RGB_UM`]). The roughness and correlation length are in µm.
//!
//! ## The series and its truncation
//! The terms `t_m = e^{−g} g^m/(m!·m) · e^{−A/m}` (`A = k²τ²|v_xy|²/4`) are unimodal in `m`:
//! their ratio `r(m) = t_{m+1}/t_m = g·m/(m+1)² · e^{A/(m(m+1))}` decreases with `m`.
//! [`series`] finds the peak, sums outward, and stops on each side when the geometric bound
//! `t_M r(M)/(1 − r(M))` (upper tail) or `t_L q/(1 − q)`, `q = 1/r(L−1)` (lower tail) falls
//! below `ε/2` of the partial sum: the relative truncation error is at most `ε`
//! (`series_tolerance`), rigorously. The number of terms grows like `√(g · ln 1/ε)`; the
//! cost-versus-error table is in `docs/seed-models.md`. Everything runs in f64 (the terms need
//! `ln Γ` and an exponent range f32 lacks); the f32 path converts its inputs and rounds the
//! result.
//!
//! | parameter | kind | default | range | unit | meaning |
//! |---|---|---|---|---|---|
//! | `sigma0` | scalar | 0.18 | [0, 1] | µm | RMS height σ₀ of the Gaussian surface |
//! | `tau` | scalar | 3 | [0.2, 20] | µm | autocorrelation length τ |
//! | `eta` | colour | Al (1.657, 0.880, 0.521) | [0.01, 10] | | real part of the complex IOR |
//! | `k` | colour | Al (9.224, 6.270, 4.837) | [0, 20] | | extinction coefficient (0: dielectric) |
//! | `diffuse` | colour | 0 | [0, 1] | | uniform-diffuse albedo a(λ) |
//! | `series_tolerance` | scalar | 1e-4 | [1e-10, 0.1] | | bound on the relative truncation error of Σ_m |
//!
//! Physics: reciprocal (every factor is symmetric in wi, wo). **Not** claimed energy
//! conserving: Kirchhoff's tangent-plane approximation and the geometric factor (which exceeds
//! 1 away from the specular direction) do not guarantee it; `lacquer check` reports the
//! measured albedo.
//!
//! Sampling: one of five lobes is chosen in proportion to an estimate of its albedo for this
//! `wo`: the specular Dirac lobe (`F e^{−g} S²`), the directional-diffuse lobe of each channel
//! (`F S² (1 − e^{−g})`, `g` at the specular configuration), and the uniform diffuse (`a`,
//! cosine-distributed). A channel's directional-diffuse lobe is sampled in the plane of
//! `v_xy = (wi + wo)_xy`, where `f_dd cos θi dωi = F S G/w² · Φ d²v_xy`: with `g_o` the phase
//! variance of the specular configuration, `m` is drawn from the zero-truncated Poisson(`g_o`)
//! (exactly for `g_o ≤ 30`, by 7-point Gauss-Hermite nodes on its normal limit above) and
//! `v_xy` from the Gaussian of term `m` (variance `2m/(k²τ²)` per axis); then
//! `wi_xy = v_xy − wo_xy`. The density is `q(v_xy) cos θi` with `q` that same finite mixture,
//! so `pdf` reports exactly what `sample` draws. It equals the series when `g = g_o`, i.e. at
//! and near the specular direction.
//!
//! References: X. D. He, K. E. Torrance, F. X. Sillion, D. P. Greenberg, "A comprehensive
//! physical model for light reflection", SIGGRAPH 1991; B. G. Smith, "Geometrical shadowing
//! of a random rough surface", IEEE TAP 1967; N. Holzschuch, R. Pacanowski, errata to He et
//! al.; S. H. Westin, reference implementation of the He model (Cornell); J. Stam,
//! "Diffraction shaders", SIGGRAPH 1999 (the same series from the Kirchhoff integral).

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::fresnel::conductor;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe};
use std::f64::consts::PI;

/// Wavelength (µm) of each RGB channel: the dominant wavelengths of the Rec.709 primaries.
pub const LAMBDA_RGB_UM: [f64; 3] = [0.611, 0.549, 0.464];

const AL_ETA: [f64; 3] = [1.65746, 0.880369, 0.521229];
const AL_K: [f64; 3] = [9.22387, 6.26952, 4.837];

const PARAMS: &[ParamSpec] = &[
    ParamSpec::scalar("sigma0", 0.18, 0.0, 1.0, "µm", "RMS height σ₀ of the Gaussian surface"),
    ParamSpec::scalar("tau", 3.0, 0.2, 20.0, "µm", "autocorrelation length τ of the surface heights"),
    ParamSpec::color("eta", AL_ETA, 0.01, 10.0, "real part η of the complex refractive index (default aluminium)"),
    ParamSpec::color("k", AL_K, 0.0, 20.0, "extinction coefficient κ of the complex index (0: dielectric)"),
    ParamSpec::color("diffuse", [0.0; 3], 0.0, 1.0, "uniform-diffuse albedo a(λ)"),
    ParamSpec::scalar(
        "series_tolerance",
        1e-4,
        1e-10,
        0.1,
        "",
        "bound on the relative truncation error of the directional-diffuse series",
    ),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "htsg",
    summary: "He-Torrance-Sillion-Greenberg 1991 physical optics: specular + directional diffuse + uniform diffuse",
    reference: "X. D. He, K. E. Torrance, F. X. Sillion, D. P. Greenberg, A comprehensive physical model for \
                light reflection, SIGGRAPH 1991 (shadowing with the errata's exponential factor)",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
    check_params: &[
        r#"{"sigma0": 0.05, "tau": 1.0}"#,
        r#"{"sigma0": 0.5, "tau": 5.0, "eta": 1.5, "k": 0.0, "diffuse": [0.6, 0.4, 0.2]}"#,
        r#"{"sigma0": 0.02, "tau": 0.6, "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14], "diffuse": 0.1}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    Ok(Model::Htsg(Htsg {
        sigma0: p.scalar("sigma0"),
        tau: p.scalar("tau"),
        eta: p.color("eta"),
        k: p.color("k"),
        diffuse: p.color("diffuse"),
        tolerance: p.scalar("series_tolerance"),
        lambda_um: LAMBDA_RGB_UM,
    }))
}

/// The HTSG BRDF. Lengths in µm.
#[derive(Clone, Debug)]
pub struct Htsg {
    /// RMS roughness σ₀.
    pub sigma0: f64,
    /// Autocorrelation length τ.
    pub tau: f64,
    /// Real part of the complex IOR per channel.
    pub eta: [f64; 3],
    /// Extinction coefficient per channel.
    pub k: [f64; 3],
    /// Uniform-diffuse albedo per channel.
    pub diffuse: [f64; 3],
    /// Relative truncation bound of the series.
    pub tolerance: f64,
    /// Wavelength (µm) of each channel: [`LAMBDA_RGB_UM`] for RGB; the spectral path
    /// ([`crate::spectral`]) builds the model with three sampled wavelengths instead.
    pub lambda_um: [f64; 3],
}

/// Result of [`series`]: the sum and the number of terms it took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeriesSum {
    /// `Σ_{m≥1} e^{−g} g^m/(m!·m) · e^{−A/m}` (truncated).
    pub sum: f64,
    /// Terms evaluated.
    pub terms: usize,
}

/// `ln r(m) = ln(t_{m+1}/t_m)` of the HTSG series.
#[inline]
fn ln_ratio(ln_g: f64, a: f64, m: f64) -> f64 {
    ln_g + m.ln() - 2.0 * (m + 1.0).ln() + a / (m * (m + 1.0))
}

/// `Σ_{m≥1} e^{−g} g^m/(m!·m) · e^{−A/m}` with a relative truncation error of at most `eps`
/// (see the module docs for the bound). Terms are summed outward from the largest one.
#[must_use]
pub fn series(g: f64, a: f64, eps: f64) -> SeriesSum {
    if !(g > 0.0) || !g.is_finite() || !a.is_finite() {
        return SeriesSum { sum: 0.0, terms: 0 };
    }
    let a = a.max(0.0);
    let ln_g = g.ln();
    // The peak: the first m with r(m) < 1 (r decreases in m).
    let peak = if ln_ratio(ln_g, a, 1.0) < 0.0 {
        1.0
    } else {
        let mut hi = 2.0f64;
        while ln_ratio(ln_g, a, hi) >= 0.0 {
            hi *= 2.0;
        }
        let mut lo = hi / 2.0; // r(lo) ≥ 1
        while hi - lo > 1.0 {
            let mid = (0.5 * (lo + hi)).floor();
            if ln_ratio(ln_g, a, mid) < 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    };
    let ln_peak = peak * ln_g - g - libm::lgamma(peak + 1.0) - peak.ln() - a / peak;
    let half = 0.5 * eps;
    // Terms relative to the peak term.
    let mut total = 1.0f64;
    let mut terms = 1usize;
    // Upward.
    let (mut m, mut rel) = (peak, 1.0f64);
    loop {
        let r = ln_ratio(ln_g, a, m).exp();
        if r < 1.0 && rel * r / (1.0 - r) <= half * total {
            break;
        }
        rel *= r;
        m += 1.0;
        total += rel;
        terms += 1;
        if rel == 0.0 {
            break;
        }
    }
    // Downward.
    let (mut m, mut rel) = (peak, 1.0f64);
    while m > 1.0 {
        let q = (-ln_ratio(ln_g, a, m - 1.0)).exp();
        if q < 1.0 && rel * q / (1.0 - q) <= half * total {
            break;
        }
        rel *= q;
        m -= 1.0;
        total += rel;
        terms += 1;
        if rel == 0.0 {
            break;
        }
    }
    SeriesSum { sum: ln_peak.exp() * total, terms }
}

/// Largest number of components of a sampling mixture.
pub(crate) const MAX_COMPONENTS: usize = 96;

/// A finite mixture of isotropic 2-D Gaussians centred at the origin: weights summing to one
/// and per-axis variances. Sampling and density agree exactly.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GaussMixture {
    pub n: usize,
    pub weight: [f64; MAX_COMPONENTS],
    pub var: [f64; MAX_COMPONENTS],
}

/// Seven-point Gauss-Hermite nodes and weights (weight function e^{−x²}; weights sum to √π).
const GH7: [(f64, f64); 7] = [
    (-2.651_961_356_835_233, 9.717_812_450_995_192e-4),
    (-1.673_551_628_767_471, 5.451_558_281_912_703e-2),
    (-0.816_287_882_858_964_7, 0.425_607_252_610_127_8),
    (0.0, 0.810_264_617_556_807_3),
    (0.816_287_882_858_964_7, 0.425_607_252_610_127_8),
    (1.673_551_628_767_471, 5.451_558_281_912_703e-2),
    (2.651_961_356_835_233, 9.717_812_450_995_192e-4),
];

impl GaussMixture {
    /// The terms `m ≥ 1` (or `m ≥ 0` with `from_zero`) of a Poisson(`g`), renormalised, with
    /// per-axis variance `var_per_m · m + var0`: exact terms for `g ≤ 30`, 7-point
    /// Gauss-Hermite nodes on the normal limit above (where the `m = 0` mass is below 1e-13).
    /// `None` when there is no mass (`g = 0` without `from_zero`).
    pub(crate) fn poisson(g: f64, var_per_m: f64, var0: f64, from_zero: bool) -> Option<Self> {
        let mut mix = Self { n: 0, weight: [0.0; MAX_COMPONENTS], var: [0.0; MAX_COMPONENTS] };
        if !(g > 1e-300) || !g.is_finite() {
            if !from_zero {
                return None;
            }
            mix.weight[0] = 1.0;
            mix.var[0] = var0;
            mix.n = 1;
            return Some(mix);
        }
        if g <= 30.0 {
            // p_m ∝ g^m/m!, by recurrence (p₀ = 1/g relative to p₁ = 1).
            let first = usize::from(!from_zero);
            let mut p = if from_zero { 1.0 / g } else { 1.0 };
            let mut best = 0.0f64;
            for m in first..first + MAX_COMPONENTS {
                if m > first {
                    p *= g / m as f64;
                }
                best = best.max(p);
                if m as f64 > g && p < 1e-13 * best {
                    break;
                }
                mix.weight[mix.n] = p;
                mix.var[mix.n] = var_per_m * m as f64 + var0;
                mix.n += 1;
            }
        } else {
            let sd = (2.0 * g).sqrt();
            for (x, w) in GH7 {
                mix.weight[mix.n] = w;
                mix.var[mix.n] = var_per_m * (g + sd * x).max(1.0) + var0;
                mix.n += 1;
            }
        }
        let total: f64 = mix.weight[..mix.n].iter().sum();
        for w in &mut mix.weight[..mix.n] {
            *w /= total;
        }
        Some(mix)
    }

    /// Density at a point at squared distance `r2` from the origin.
    pub(crate) fn density(&self, r2: f64) -> f64 {
        let mut d = 0.0;
        for j in 0..self.n {
            let v = self.var[j];
            d += self.weight[j] * (-0.5 * r2 / v).exp() / (2.0 * PI * v);
        }
        d
    }

    /// Picks a component with `u` and draws a point from it with `(u1, u2)` (Box-Muller).
    pub(crate) fn sample(&self, u: f64, u1: f64, u2: f64) -> (f64, f64) {
        let (j, _) = pick_lobe(&self.weight[..self.n], u).unwrap_or((0, 0.0));
        let r = (self.var[j] * -2.0 * (1.0 - u1).max(1e-300).ln()).sqrt();
        let phi = 2.0 * PI * u2;
        (r * phi.cos(), r * phi.sin())
    }
}

/// Solves `x e^{x²/2} = f0` for `x ≥ 0` (safeguarded Newton on `ln x + x²/2 = ln f0`).
fn solve_z0(f0: f64) -> f64 {
    if !(f0 > 0.0) {
        return 0.0;
    }
    let target = f0.ln();
    let h = |x: f64| x.ln() + 0.5 * x * x - target;
    let (mut lo, mut hi) = (0.0f64, 1.0f64.max((2.0 * target.max(0.0)).sqrt() + 1.0));
    let mut x = if f0 < 1.0 { f0 } else { (2.0 * target).sqrt().max(0.5) };
    for _ in 0..100 {
        let v = h(x);
        if v > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let step = v / (1.0 / x + x);
        if step.abs() <= 1e-15 * x {
            return x - step;
        }
        let next = x - step;
        x = if next > lo && next < hi { next } else { 0.5 * (lo + hi) };
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    x
}

/// `tan θ` and `cot θ` from `cos θ` (finite for `cos θ` in (0, 1]; `tan` is 0 at the pole).
#[inline]
fn tan_cot(c: f64) -> (f64, f64) {
    let s = (1.0 - c * c).max(0.0).sqrt();
    (s / c, if s > 0.0 { c / s } else { f64::INFINITY })
}

impl Htsg {
    /// Smooth surface (σ₀ = 0): a Fresnel mirror plus the uniform diffuse.
    #[inline]
    fn smooth(&self) -> bool {
        !(self.sigma0 > 0.0)
    }

    /// Effective roughness σ for the pair of directions (eqs. 80-83).
    #[must_use]
    pub fn effective_sigma(&self, ci: f64, co: f64) -> f64 {
        if self.smooth() {
            return 0.0;
        }
        let kk = |c: f64| {
            let (tan, cot) = tan_cot(c);
            if tan == 0.0 {
                0.0
            } else {
                tan * libm::erfc(self.tau * cot / (2.0 * self.sigma0))
            }
        };
        let x = solve_z0((kk(ci) + kk(co)) / (8.0 * PI).sqrt());
        self.sigma0 / (1.0 + x * x).sqrt()
    }

    /// Shadowing of one direction `S(θ)` (eqs. 23-25 with the errata's `e^{−a²}`).
    #[must_use]
    pub fn shadowing(&self, c: f64) -> f64 {
        if self.smooth() {
            return 1.0;
        }
        let (_, cot) = tan_cot(c);
        let a = self.tau * cot / (2.0 * self.sigma0);
        if !(a < 26.0) {
            return 1.0;
        }
        let erfc = libm::erfc(a);
        let lambda = (0.5 * ((-a * a).exp() / (PI.sqrt() * a) - erfc)).max(0.0);
        (1.0 - 0.5 * erfc) / (1.0 + lambda)
    }

    /// Wave number `k = 2π/λ` of channel `c` (1/µm).
    #[inline]
    fn wave_number(&self, c: usize) -> f64 {
        2.0 * PI / self.lambda_um[c]
    }

    /// Phase variance `g` of the specular configuration for `cos θo`, per channel.
    fn specular_g(&self, co: f64) -> [f64; 3] {
        let sigma = self.effective_sigma(co, co);
        [0, 1, 2].map(|c| (self.wave_number(c) * sigma * 2.0 * co).powi(2))
    }

    /// Reflectance of the specular Dirac lobe for `cos θo` (per channel).
    #[must_use]
    pub fn specular_reflectance(&self, co: f64) -> [f64; 3] {
        let g = self.specular_g(co);
        let s = self.shadowing(co).powi(2);
        [0, 1, 2].map(|c| conductor(co, self.eta[c], self.k[c]) * (-g[c]).exp() * s)
    }

    /// The directional-diffuse term per channel, and the series terms it took.
    #[must_use]
    pub fn directional_diffuse(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> ([f64; 3], usize) {
        if self.smooth() || !(wi.z > 0.0) || !(wo.z > 0.0) {
            return ([0.0; 3], 0);
        }
        let (ci, co) = (wi.z.min(1.0), wo.z.min(1.0));
        let w = ci + co;
        let dot = wi.dot(wo).clamp(-1.0, 1.0);
        let geo = (1.0 + dot).powi(2) / (ci * co * w * w);
        let shadow = self.shadowing(ci) * self.shadowing(co);
        let cos_local = (0.5 * (1.0 + dot)).max(0.0).sqrt();
        let v2 = (wi.x + wo.x).powi(2) + (wi.y + wo.y).powi(2);
        let sigma = self.effective_sigma(ci, co);
        let mut out = [0.0; 3];
        let mut terms = 0;
        for (c, o) in out.iter_mut().enumerate() {
            let k = self.wave_number(c);
            let kt2 = (k * self.tau).powi(2);
            let g = (k * sigma * w).powi(2);
            let s = series(g, 0.25 * kt2 * v2, self.tolerance);
            terms += s.terms;
            let phi = kt2 / (4.0 * PI) * s.sum;
            *o = conductor(cos_local, self.eta[c], self.k[c]) * shadow * geo * phi;
        }
        (out, terms)
    }

    /// Full (non-delta) BRDF in f64.
    fn eval64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> [f64; 3] {
        // Renormalised in f64 so the f32 path sees the same directions as the f64 path.
        let (dd, _) = self.directional_diffuse(wi.normalize(), wo.normalize());
        [0, 1, 2].map(|c| dd[c] + self.diffuse[c] / PI)
    }

    /// Lobe-selection weights for `wo`: specular, directional diffuse R, G, B, uniform diffuse;
    /// and the specular-configuration `g` per channel.
    fn selection(&self, co: f64) -> ([f64; 5], [f64; 3]) {
        let g = self.specular_g(co);
        let s = self.shadowing(co).powi(2);
        let f = [0, 1, 2].map(|c| conductor(co, self.eta[c], self.k[c]) * s);
        let sp = (0..3).map(|c| f[c] * (-g[c]).exp()).sum::<f64>() / 3.0;
        let dd = [0, 1, 2].map(|c| f[c] * -(-g[c]).exp_m1() / 3.0);
        let diff = self.diffuse.iter().sum::<f64>() / 3.0;
        ([sp, dd[0], dd[1], dd[2], diff], g)
    }

    /// The sampling mixture of channel `c`'s directional-diffuse lobe in the `v_xy` plane.
    fn dd_mixture(&self, c: usize, g_o: f64) -> Option<GaussMixture> {
        let k = self.wave_number(c);
        GaussMixture::poisson(g_o, 2.0 / (k * self.tau).powi(2), 0.0, false)
    }

    fn pdf64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
        let (wi, wo) = (wi.normalize(), wo.normalize());
        if !(wi.z > 0.0) || !(wo.z > 0.0) {
            return 0.0;
        }
        let (sel, g) = self.selection(wo.z.min(1.0));
        let total: f64 = sel.iter().sum();
        if !(total > 0.0) {
            return 0.0;
        }
        let r2 = (wi.x + wo.x).powi(2) + (wi.y + wo.y).powi(2);
        let mut pdf = sel[4] / total * cosine_hemisphere_pdf(wi.z);
        for c in 0..3 {
            if sel[1 + c] > 0.0 {
                if let Some(mix) = self.dd_mixture(c, g[c]) {
                    pdf += sel[1 + c] / total * mix.density(r2) * wi.z;
                }
            }
        }
        pdf
    }
}

/// The Cook-Torrance-style Beckmann microfacet lobe closest to HTSG's directional diffuse
/// term (see [`Htsg::beckmann_fit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeckmannFit {
    /// Fitted Beckmann roughness α.
    pub alpha: f64,
    /// Fitted scale of the lobe (1 when HTSG's energy is matched exactly).
    pub scale: f64,
    /// Relative RMS residual `√(Σ(cos θi Δf)²/Σ(cos θi f)²)` over the fitting grid.
    pub rel_rms: f64,
}

impl Htsg {
    /// Least-squares fit of `s · F(h·wi) D(h; α) G₂(wi, wo; α)/(4 cos θi cos θo)` (Beckmann
    /// `D`, separable Smith `G₂`, this model's Fresnel; what a Cook-Torrance renderer would use)
    /// to the directional-diffuse term of channel `c`, with the cosine-weighted residual of the
    /// thesis' fits. `wo` at θo = 0°, 15°, …, 75°; `wi` on a 24 × 48 grid in (cos θi, φi).
    /// `α` by golden-section search in `ln α` after a coarse scan, `s` in closed form.
    #[must_use]
    pub fn beckmann_fit(&self, c: usize) -> BeckmannFit {
        use crate::microfacet::{DistributionKind, MaskingKind, Microfacet};
        let mut pairs = Vec::new();
        for io in 0..6 {
            let t = (io as f64 * 15.0).to_radians();
            let wo = Vec3::new(t.sin(), 0.0, t.cos());
            for i in 0..24 {
                let ci = (i as f64 + 0.5) / 24.0;
                let si = (1.0 - ci * ci).sqrt();
                for j in 0..48 {
                    let p = 2.0 * PI * (j as f64 + 0.5) / 48.0;
                    let wi = Vec3::new(si * p.cos(), si * p.sin(), ci);
                    let target = self.directional_diffuse(wi, wo).0[c] * ci;
                    pairs.push((wi, wo, target));
                }
            }
        }
        let basis = |alpha: f64, wi: Vec3<f64>, wo: Vec3<f64>| {
            let mf = Microfacet::new(DistributionKind::Beckmann, alpha, alpha);
            let h = (wi + wo).normalize();
            let f = conductor(h.dot(wi), self.eta[c], self.k[c]);
            f * mf.d(h) * mf.g(wi, wo, h, MaskingKind::Separable) / (4.0 * wo.z)
        };
        let solve = |alpha: f64| {
            let (mut tb, mut bb, mut tt) = (0.0, 0.0, 0.0);
            for &(wi, wo, t) in &pairs {
                let b = basis(alpha, wi, wo);
                tb += t * b;
                bb += b * b;
                tt += t * t;
            }
            let s = if bb > 0.0 { tb / bb } else { 0.0 };
            let err = (tt - 2.0 * s * tb + s * s * bb).max(0.0);
            (err, s, tt)
        };
        let (lo, hi) = (0.003f64.ln(), 2.0f64.ln());
        let mut best = (f64::INFINITY, lo);
        for i in 0..=40 {
            let x = lo + (hi - lo) * i as f64 / 40.0;
            let e = solve(x.exp()).0;
            if e < best.0 {
                best = (e, x);
            }
        }
        let step = (hi - lo) / 40.0;
        let (mut a, mut b) = (best.1 - step, best.1 + step);
        let phi = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..40 {
            let (x1, x2) = (b - phi * (b - a), a + phi * (b - a));
            if solve(x1.exp()).0 < solve(x2.exp()).0 {
                b = x2;
            } else {
                a = x1;
            }
        }
        let alpha = (0.5 * (a + b)).exp();
        let (err, scale, tt) = solve(alpha);
        BeckmannFit { alpha, scale, rel_rms: if tt > 0.0 { (err / tt).sqrt() } else { 0.0 } }
    }
}

impl Bxdf for Htsg {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        Rgb::from_array(self.eval64(wi.cast(), wo.cast()))
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        T::of(self.pdf64(wi.cast(), wo.cast()))
    }

    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wo64: Vec3<f64> = wo.cast::<f64>().normalize();
        let co = wo64.z.min(1.0);
        let (sel, g) = self.selection(co);
        let (lobe, u0) = pick_lobe(&sel, u[0].f64())?;
        let (u1, u2) = (u[1].f64(), u[2].f64());
        let wi: Vec3<f64> = match lobe {
            0 => {
                let total: f64 = sel.iter().sum();
                let p = sel[0] / total;
                let rho = self.specular_reflectance(co);
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                return (p > 0.0).then(|| BsdfSample {
                    wi,
                    weight: Rgb::from_array(rho.map(|r| r / p)),
                    pdf: T::of(p),
                    delta: true,
                });
            }
            1..=3 => {
                let mix = self.dd_mixture(lobe - 1, g[lobe - 1])?;
                let (vx, vy) = mix.sample(u0, u1, u2);
                let (x, y) = (vx - wo64.x, vy - wo64.y);
                let z2 = 1.0 - x * x - y * y;
                if !(z2 > 0.0) {
                    return None;
                }
                Vec3::new(x, y, z2.sqrt())
            }
            _ => cosine_hemisphere(u1, u2),
        };
        let wi: Vec3<T> = wi.cast();
        if !(wi.z > T::zero()) {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::furnace::albedo;
    use crate::microfacet::{DistributionKind, Microfacet};
    use crate::rng::Pcg32;
    use crate::Material;

    fn dir(c: f64, phi: f64) -> Vec3<f64> {
        let s = (1.0 - c * c).max(0.0).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), c)
    }

    fn model(sigma0: f64, tau: f64) -> Htsg {
        Htsg { sigma0, tau, eta: AL_ETA, k: AL_K, diffuse: [0.0; 3], tolerance: 1e-10, lambda_um: LAMBDA_RGB_UM }
    }

    /// Brute-force sum of the series to convergence, term by term in log form.
    fn series_brute(g: f64, a: f64) -> f64 {
        let mut s = 0.0;
        let top = (g + 40.0 * g.sqrt() + 200.0 + (2.0 * a).sqrt() * 4.0) as usize;
        for m in 1..=top {
            let m = m as f64;
            s += (m * g.ln() - g - libm::lgamma(m + 1.0) - m.ln() - a / m).exp();
        }
        s
    }

    /// The adaptive truncation meets its bound against a brute-force sum over a wide range
    /// of g and A (including A far off the lobe, where the peak moves to large m).
    #[test]
    fn series_meets_its_error_bound() {
        for &g in &[1e-6, 0.01, 0.5, 3.0, 30.0, 300.0, 3000.0] {
            for &a in &[0.0, 0.1, 5.0, 80.0, 2000.0] {
                let exact = series_brute(g, a);
                for &eps in &[1e-2, 1e-4, 1e-8] {
                    let s = series(g, a, eps);
                    let err = (exact - s.sum) / exact;
                    assert!(err >= -1e-12 && err <= eps, "g {g} A {a} eps {eps}: rel err {err:e}");
                }
            }
        }
    }

    /// Each term of the series is a normalised Gaussian in v_xy with mass e^{−g} g^m/m!:
    /// the Φ integral over the plane is 1 − e^{−g} (Parseval), checked by quadrature.
    #[test]
    fn series_integrates_to_one_minus_exp_minus_g() {
        let (k, tau) = (2.0 * PI / 0.55, 1.5);
        let kt2 = (k * tau) * (k * tau);
        for &g in &[0.2, 4.0, 60.0] {
            // ∫ Φ d²v = 2π ∫ Φ(r) r dr, Φ = kt2/(4π) series(g, kt2 r²/4).
            let (n, rmax) = (40_000, 6.0);
            let h = rmax / n as f64;
            let mut s = 0.0;
            for i in 0..n {
                let r = (i as f64 + 0.5) * h;
                s += kt2 / (4.0 * PI) * series(g, 0.25 * kt2 * r * r, 1e-12).sum * 2.0 * PI * r * h;
            }
            let want = -(-g).exp_m1();
            assert!((s - want).abs() < 1e-5, "g {g}: {s} vs {want}");
        }
    }

    /// σ₀ → 0: no directional diffuse, and the specular lobe is the Fresnel mirror
    /// (conductor reflectance at normal incidence in closed form).
    #[test]
    fn smooth_limit_is_a_fresnel_mirror() {
        let m = model(0.0, 3.0);
        let wo = dir(1.0, 0.0);
        let rho = m.specular_reflectance(1.0);
        for c in 0..3 {
            let (n, k) = (AL_ETA[c], AL_K[c]);
            let f0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
            assert!((rho[c] - f0).abs() < 1e-12);
        }
        assert_eq!(m.directional_diffuse(dir(0.8, 1.0), wo).0, [0.0; 3]);
        // Tiny σ₀: e^{−g} → 1, the directional diffuse vanishes like g.
        let m = model(1e-5, 3.0);
        let r = m.specular_reflectance(0.7);
        let r0 = model(0.0, 3.0).specular_reflectance(0.7);
        for c in 0..3 {
            assert!((r[c] / r0[c] - 1.0).abs() < 1e-6);
        }
        let s = m.sample(wo, [0.0, 0.5, 0.5]).unwrap();
        assert!(s.delta && (s.wi.z - 1.0).abs() < 1e-15);
    }

    /// Shadowing is Smith's G1 for Beckmann slopes with α = 2σ₀/τ, times the visible-height
    /// factor 1 − ½ erfc(a) (independent Λ from `microfacet`).
    #[test]
    fn shadowing_is_smith_for_beckmann() {
        let m = model(0.4, 2.0);
        let mf = Microfacet::new(DistributionKind::Beckmann, 0.4, 0.4);
        for &c in &[0.99, 0.7, 0.3, 0.05] {
            let w = dir(c, 0.3);
            let a = c / (0.4 * (1.0 - c * c).sqrt());
            let want = (1.0 - 0.5 * libm::erfc(a)) / (1.0 + mf.lambda(w));
            assert!((m.shadowing(c) - want).abs() < 1e-12, "cos {c}");
        }
    }

    /// The effective roughness solves eq. 81 (checked by substitution) and falls toward
    /// grazing, where the surface is seen "smoother" (the paper's Fig. 5 trend).
    #[test]
    fn effective_roughness_solves_its_equation() {
        let m = model(0.5, 2.0);
        let mut last = f64::INFINITY;
        for &c in &[1.0, 0.8, 0.5, 0.2, 0.05, 1e-4] {
            let s = m.effective_sigma(c, c);
            let z0 = m.sigma0 * ((m.sigma0 / s).powi(2) - 1.0).max(0.0).sqrt();
            let kk = |c: f64| {
                let (t, ct) = tan_cot(c);
                if t == 0.0 {
                    0.0
                } else {
                    t * libm::erfc(m.tau * ct / (2.0 * m.sigma0))
                }
            };
            let lhs = (PI / 2.0).sqrt() * z0;
            let rhs = m.sigma0 / 4.0 * (kk(c) + kk(c)) * (-z0 * z0 / (2.0 * m.sigma0 * m.sigma0)).exp();
            // z₀ recovered from σ is ill-conditioned when z₀ ≪ σ₀: compare to 1e-6.
            assert!((lhs - rhs).abs() <= 1e-6 * rhs.max(1e-300), "cos {c}: {lhs} vs {rhs}");
            assert!(s <= last + 1e-15);
            last = s;
        }
        assert!((m.effective_sigma(1.0, 1.0) - 0.5).abs() < 1e-15);
    }

    /// σ₀/λ ≫ 1: the directional diffuse becomes the Beckmann microfacet BRDF
    /// F S D(h) / (4 cos θi cos θo) with α = 2σ/τ (σ the effective roughness); the relative
    /// error of the series' rough limit is O(1/g).
    #[test]
    fn rough_limit_is_beckmann_microfacet() {
        let m = model(2.0, 10.0); // g ≈ 700-3000 per channel, α ≈ 0.4
        let mut worst = 0.0f64;
        for &(ci, pi, co, po) in &[(0.9, 0.0, 0.8, 3.0), (0.7, 0.5, 0.7, 3.5), (0.5, 0.0, 0.95, 2.0), (0.6, 1.0, 0.4, 4.0)] {
            let (wi, wo) = (dir(ci, pi), dir(co, po));
            let sigma = m.effective_sigma(ci, co);
            let alpha = 2.0 * sigma / m.tau;
            let mf = Microfacet::new(DistributionKind::Beckmann, alpha, alpha);
            let h = (wi + wo).normalize();
            let s = m.shadowing(ci) * m.shadowing(co);
            let (dd, _) = m.directional_diffuse(wi, wo);
            for c in 0..3 {
                let f = conductor(h.dot(wi), AL_ETA[c], AL_K[c]);
                let want = f * s * mf.d(h) / (4.0 * ci * co);
                let rel = (dd[c] / want - 1.0).abs();
                worst = worst.max(rel);
            }
        }
        println!("HTSG rough limit: worst relative gap to the Beckmann microfacet BRDF {worst:.2e}");
        assert!(worst < 0.02, "worst relative gap to Beckmann: {worst}");
    }

    /// Kirchhoff energy: at normal incidence with a narrow lobe the specular reflectance plus
    /// the directional-diffuse albedo equals F(0)·S² (up to the geometric factor's spread),
    /// i.e. the series carries exactly the energy the specular lobe loses.
    #[test]
    fn specular_plus_directional_diffuse_keeps_the_fresnel_energy() {
        let m = Htsg { sigma0: 0.08, tau: 4.0, eta: [1.5; 3], k: [0.0; 3], diffuse: [0.0; 3], tolerance: 1e-8, lambda_um: LAMBDA_RGB_UM };
        let mat = Material::from_params(
            &INFO,
            Params::parse(
                "htsg",
                PARAMS,
                &serde_json::from_str(r#"{"sigma0": 0.08, "tau": 4.0, "eta": 1.5, "k": 0.0, "series_tolerance": 1e-8}"#)
                    .unwrap(),
            )
            .unwrap(),
        )
        .unwrap();
        let wo = dir(1.0, 0.0);
        let (a, se) = albedo(&mat, wo, 200_000, &mut Pcg32::new(1, 2));
        let f0 = 0.04;
        println!("HTSG normal-incidence albedo (sp + dd), η = 1.5: {a:?} ± {se:.1e}, F(0) = {f0}");
        for (c, ac) in a.iter().enumerate() {
            // Fresnel varies by < 1e-3 over the lobe; S = 1 at normal incidence.
            assert!((ac - f0).abs() < 2e-3 * f0 + 4.0 * se, "channel {c}: {ac} vs {f0}");
        }
        assert!(m.specular_reflectance(1.0)[0] < f0);
    }

    /// The sampling mixture reports the density it draws (the χ² check tests this too).
    #[test]
    fn sampled_pdf_matches_pdf() {
        let m = model(0.2, 2.0);
        let mut rng = Pcg32::new(5, 6);
        for _ in 0..2000 {
            let wo = dir(rng.uniform().max(1e-3), 6.0 * rng.uniform());
            if let Some(s) = m.sample(wo, rng.uniform3()) {
                if !s.delta {
                    let p = m.pdf(s.wi, wo);
                    assert!((s.pdf - p).abs() <= 1e-12 * p);
                }
            }
        }
    }

    /// HTSG against the Beckmann (Cook-Torrance) lobe fitted to it: for σ₀/λ ≫ 1 the fit is
    /// close (the series' Beckmann limit, α near 2σ/τ); for a smooth surface (g ≈ 1) the
    /// Poisson mixture of diffraction lobes is not a Beckmann lobe and the fit is poor.
    #[test]
    fn cook_torrance_fit_to_htsg() {
        let rough = model(1.0, 8.0).beckmann_fit(1);
        assert!(rough.rel_rms < 0.15, "{rough:?}");
        assert!((rough.alpha / 0.25 - 1.0).abs() < 0.25, "{rough:?}");
        let smooth = model(0.03, 1.0).beckmann_fit(1);
        println!("Beckmann fit to HTSG: rough {rough:?}, smooth {smooth:?}");
        assert!(smooth.rel_rms > 2.0 * rough.rel_rms, "{smooth:?} vs {rough:?}");
    }
}
