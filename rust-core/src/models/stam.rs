//! Stam (1999) diffraction shader: the Kirchhoff integral for a metallic surface with a
//! periodic (grating, e.g. the tracks of a compact disc) or random height profile, summed
//! over the visible spectrum into RGB.
//!
//! With `v_xy = (wi + wo)_xy` written `(u, v)` in the frame of the grating vector, `w = cos θi
//! + cos θo` and `k = 2π/λ`, Stam's result is
//!
//! ```text
//! f(wi, wo) = F(θℓ) · G/w² · Φ_λ(u, v; w),   G = (1 + wi·wo)² / (cos θi cos θo)
//! Φ_λ = k² ⟨|P(ku, kv)|²⟩ / (4π² A),         P = Fourier transform of e^{ikw h(x, y)}
//! ```
//!
//! `G` is the geometric ("gain") factor of the Kirchhoff tangent-plane approximation
//! (Beckmann & Spizzichino); it is 1 in the specular configuration and grows away from it,
//! which is where the colourful, strongly anisotropic off-specular lobes get their strength.
//! By Parseval `∫ Φ_λ du dv = 1` for every profile and wavelength (`|e^{ikwh}| = 1`), so a flat
//! profile gives a mirror of reflectance `F`. The light is coherent over a finite patch: a
//! Gaussian window `exp(−(x² + y²)/2ℓ²)` on the field (`ℓ` = `coherence`) turns each Dirac
//! order into a normalised Gaussian of standard deviation `s(λ) = λ/(2√2 π ℓ)` in `u` and `v`.
//!
//! * `binary` (compact-disc pits/lands, step `H`, duty `f`, period `a`): orders at `u = nλ/a`
//!   with efficiency `|c₀|² = 1 − 2f(1−f)(1 − cos φ)`, `|c_n|² = 4 sin²(φ/2) sin²(πnf)/(π²n²)`,
//!   `φ = k w H` (the Fourier coefficients of a two-level phase grating).
//! * `sine` (`h = (H/2) sin(2πx/a)`): `|c_n|² = J_n²(k w H/2)` (Jacobi-Anger).
//! * `random` (Gaussian heights of RMS σ with Gaussian correlation lengths `Tx`, `Ty`, Stam's
//!   anisotropic extension of He et al.): `Φ = Σ_{m≥0} e^{−g} g^m/m! · N(u; 2m/(k²Tx²) + s²)
//!   N(v; 2m/(k²Ty²) + s²)`, `g = k²σ²w²` (the coherent term `m = 0` is the mirror; summed
//!   over the Poisson window holding all but 10⁻¹² of the mass).
//!
//! RGB is the spectral sum: `Φ_λ` is integrated against the CIE 1931 colour-matching functions
//! ([`crate::paint::thin_film::cie_xyz`]) over 360-830 nm, converted to linear Rec.709 and
//! normalised so a wavelength-independent Φ is grey; negative (out-of-gamut, spectral)
//! channels are clipped to 0. The integral runs over `t = 1/λ`, in which every order's
//! factor `N(u − nλ/a; s²) N(v; s²)` is an exact Gaussian (centre `t_c = nu/(a(u² + v²))`,
//! deviation `1/(2√2πℓ √(u² + v²))`): each diffracted order is integrated by Simpson's rule
//! over ±7 deviations of that Gaussian (node spacing ≤ half a deviation and ≤ 0.02 µm⁻¹ in
//! `t`, i.e. ≤ 4 nm where the colour-matching functions are narrowest), the zeroth
//! order over the whole range (96 intervals), and the random profile on 12 wavelengths with
//! hat-function weights. The sine grating's Bessel functions come from a table built with the
//! model (cubic Hermite with exact derivatives, error below 1e-10). `F` is the
//! polarisation-averaged conductor reflectance of each channel (the RGB reduction of the
//! complex index) at `cos θℓ = |wi + wo|/2`.
//!
//! | parameter | kind | default | range | unit | meaning |
//! |---|---|---|---|---|---|
//! | `profile` | choice | binary | binary, sine, random | | height profile |
//! | `pitch` | scalar | 1.6 | [0.3, 5] | µm | grating period `a` (binary, sine) |
//! | `depth` | scalar | 0.11 | [0, 1] | µm | step height (binary) or peak-to-valley height (sine) `H` |
//! | `duty` | scalar | 0.35 | [0.05, 0.95] | | fraction of the period at the raised level (binary) |
//! | `roughness` | scalar | 0.08 | [0, 0.25] | µm | RMS height σ (random) |
//! | `correlation_x` | scalar | 1 | [0.2, 10] | µm | correlation length `Tx` along the grating vector (random) |
//! | `correlation_y` | scalar | 4 | [0.2, 10] | µm | correlation length `Ty` across it (random) |
//! | `coherence` | scalar | 3 | [2, 50] | µm | coherence length `ℓ` of the illumination on the surface |
//! | `direction` | scalar | 0 | [0, 180] | degrees | angle of the grating vector (across the tracks) from the tangent x |
//! | `eta` | colour | Al | [0.01, 10] | | real part of the complex index |
//! | `k` | colour | Al | [0, 20] | | extinction coefficient |
//!
//! Physics: reciprocal (`u, v, w` and `G` are symmetric in wi, wo). **Not** claimed energy
//! conserving: `G/w²` exceeds 1 off the specular direction (Kirchhoff's approximation), and
//! clipping out-of-gamut channels adds light; `lacquer check` reports the measured albedo.
//!
//! Sampling (a proxy with an exact density), in the `(u, v)` plane where
//! `f cos θi dωi = F G/w² Φ du dv`: gratings — order `n` with probability ∝ its
//! luminance-weighted efficiency at `w = 2 cos θo` (tabulated over `w` at build time), then
//! `u = nλ/a + s·z₁`, `v = s·z₂` with λ uniform on 380-780 nm and `s` one of `s(450 nm)`,
//! `s(750 nm)` (floored at 0.03 and 0.045: the proxy need not be as sharp as very coherent
//! lines); random — the Poisson mixture of the random profile at 450, 550 and 650 nm;
//! plus 10 % of cosine-weighted directions. `pdf` is that mixture (times `cos θi`).
//!
//! References: J. Stam, "Diffraction shaders", SIGGRAPH 1999; P. Beckmann, A. Spizzichino,
//! *The scattering of electromagnetic waves from rough surfaces*, 1963.

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::fresnel::conductor;
use crate::math::{Rgb, Vec3};
use crate::models::htsg::GaussMixture;
use crate::models::Model;
use crate::paint::thin_film::{cie_xyz, xyz_to_rgb};
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe};
use std::f64::consts::PI;
use std::sync::OnceLock;

const AL_ETA: [f64; 3] = [1.65746, 0.880369, 0.521229];
const AL_K: [f64; 3] = [9.22387, 6.26952, 4.837];

const PARAMS: &[ParamSpec] = &[
    ParamSpec::choice("profile", "binary", &["binary", "sine", "random"], "height profile of the surface"),
    ParamSpec::scalar("pitch", 1.6, 0.3, 5.0, "µm", "grating period a (binary, sine)"),
    ParamSpec::scalar("depth", 0.11, 0.0, 1.0, "µm", "step height (binary) or peak-to-valley height (sine)"),
    ParamSpec::scalar("duty", 0.35, 0.05, 0.95, "", "fraction of the period at the raised level (binary)"),
    ParamSpec::scalar("roughness", 0.08, 0.0, 0.25, "µm", "RMS height σ (random)"),
    ParamSpec::scalar("correlation_x", 1.0, 0.2, 10.0, "µm", "correlation length along the grating vector (random)"),
    ParamSpec::scalar("correlation_y", 4.0, 0.2, 10.0, "µm", "correlation length across the grating vector (random)"),
    ParamSpec::scalar("coherence", 3.0, 2.0, 50.0, "µm", "coherence length ℓ of the illumination on the surface"),
    ParamSpec::scalar(
        "direction",
        0.0,
        0.0,
        180.0,
        "degrees",
        "angle of the grating vector (across the tracks) from the tangent x",
    ),
    ParamSpec::color("eta", AL_ETA, 0.01, 10.0, "real part η of the complex refractive index (default aluminium)"),
    ParamSpec::color("k", AL_K, 0.0, 20.0, "extinction coefficient κ of the complex index"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "stam",
    summary: "Stam 1999 diffraction shader: Kirchhoff integral of a grating (CD) or random profile, spectral sum to RGB",
    reference: "J. Stam, Diffraction shaders, SIGGRAPH 1999",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: false, sampled: true },
    check_params: &[
        r#"{"profile": "sine", "pitch": 1.0, "depth": 0.3, "coherence": 2.0, "direction": 45}"#,
        r#"{"profile": "random", "roughness": 0.08, "correlation_x": 1.0, "correlation_y": 4.0}"#,
        r#"{"pitch": 4.0, "depth": 0.3, "duty": 0.5, "coherence": 2.0, "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    let profile = match p.choice("profile") {
        "binary" => Profile::Binary { duty: p.scalar("duty") },
        "sine" => Profile::Sine,
        _ => Profile::Random {
            sigma: p.scalar("roughness"),
            tx: p.scalar("correlation_x"),
            ty: p.scalar("correlation_y"),
        },
    };
    Ok(Model::Stam(Stam::new(
        profile,
        p.scalar("pitch"),
        p.scalar("depth"),
        p.scalar("coherence"),
        p.scalar("direction"),
        p.color("eta"),
        p.color("k"),
    )))
}

/// The surface height profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Profile {
    /// Two-level (pits and lands) grating with the given duty cycle.
    Binary {
        /// Fraction of the period at the raised level.
        duty: f64,
    },
    /// Sinusoidal grating.
    Sine,
    /// Gaussian random heights with Gaussian correlation.
    Random {
        /// RMS height (µm).
        sigma: f64,
        /// Correlation length along the grating vector (µm).
        tx: f64,
        /// Correlation length across it (µm).
        ty: f64,
    },
}

/// Spectral range of the RGB integration (µm).
const LAMBDA_LO: f64 = 0.360;
const LAMBDA_HI: f64 = 0.830;
/// Wavelength range of the sampling proxy (µm).
const SAMPLE_LO: f64 = 0.380;
const SAMPLE_HI: f64 = 0.780;

/// `ω_c(λ)` on a 1 nm grid from 360 nm: linear Rec.709 per unit Φ, normalised so that a
/// wavelength-independent Φ integrates to grey (Σ ω_c · 1 nm = 1).
fn rgb_weights() -> &'static [[f64; 3]] {
    static TABLE: OnceLock<Vec<[f64; 3]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = ((LAMBDA_HI - LAMBDA_LO) * 1000.0).round() as usize + 1;
        let raw: Vec<[f64; 3]> = (0..n).map(|i| xyz_to_rgb(cie_xyz(360.0 + i as f64))).collect();
        let mut white = [0.0; 3];
        for (i, r) in raw.iter().enumerate() {
            let w = if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
            for c in 0..3 {
                white[c] += w * r[c] * 1e-3;
            }
        }
        raw.iter().map(|r| [0, 1, 2].map(|c| r[c] / white[c])).collect()
    })
}

/// `ω_c(λ)` (per µm) by linear interpolation; zero outside 360-830 nm.
#[inline]
fn omega(lambda: f64) -> [f64; 3] {
    let t = rgb_weights();
    let x = (lambda - LAMBDA_LO) * 1000.0;
    if !(x >= 0.0) || x > (t.len() - 1) as f64 {
        return [0.0; 3];
    }
    let i = (x as usize).min(t.len() - 2);
    let f = x - i as f64;
    [0, 1, 2].map(|c| t[i][c] + (t[i + 1][c] - t[i][c]) * f)
}

/// Nodes and RGB weights for integrating a function of λ that is piecewise linear between
/// `n` evenly spaced nodes over 360-830 nm (`∫ ω_c(λ) Σ_j φ_j hat_j(λ) dλ = Σ_j W_jc φ_j`).
fn hat_weights(n: usize) -> Vec<(f64, [f64; 3])> {
    let t = rgb_weights();
    let h = (LAMBDA_HI - LAMBDA_LO) / (n - 1) as f64;
    let mut out: Vec<(f64, [f64; 3])> = (0..n).map(|j| (LAMBDA_LO + j as f64 * h, [0.0; 3])).collect();
    for (i, w) in t.iter().enumerate() {
        let l = LAMBDA_LO + i as f64 * 1e-3;
        let q = if i == 0 || i == t.len() - 1 { 0.5e-3 } else { 1e-3 };
        let x = ((l - LAMBDA_LO) / h).min((n - 1) as f64);
        let j = (x as usize).min(n - 2);
        let f = x - j as f64;
        for (c, wc) in w.iter().enumerate() {
            out[j].1[c] += (1.0 - f) * wc * q;
            out[j + 1].1[c] += f * wc * q;
        }
    }
    out
}

fn random_nodes() -> &'static [(f64, [f64; 3])] {
    static T: OnceLock<Vec<(f64, [f64; 3])>> = OnceLock::new();
    T.get_or_init(|| hat_weights(12))
}

/// Normal density with variance `var`.
#[inline]
fn normal(x: f64, var: f64) -> f64 {
    (-0.5 * x * x / var).exp() / (2.0 * PI * var).sqrt()
}

/// Standard normal CDF.
#[inline]
fn norm_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

/// Nodes of the `w` table of order efficiencies (the sampling proxy).
const W_NODES: usize = 65;
/// Intervals of the Bessel-function table of the sine grating.
const BESSEL_NODES: usize = 2048;
/// Smallest standard deviation of the proxy's Gaussians in `u` and `v`.
const PROXY_MIN_SPREAD: f64 = 0.03;

/// The diffraction shader with its cached order-efficiency table.
#[derive(Clone, Debug)]
pub struct Stam {
    /// Height profile.
    pub profile: Profile,
    /// Grating period (µm).
    pub pitch: f64,
    /// Step or peak-to-valley height (µm).
    pub depth: f64,
    /// Coherence length (µm).
    pub coherence: f64,
    /// Unit grating vector in the tangent plane.
    dir: [f64; 2],
    /// Real part of the complex IOR per channel.
    pub eta: [f64; 3],
    /// Extinction coefficient per channel.
    pub k: [f64; 3],
    /// Highest order the proxy samples.
    nmax: i32,
    /// Highest order any direction can reach: `2a/λ_min`.
    reach: usize,
    /// Binary grating: `sin²(πnf)/(π²n²)` for `n = 0..=reach` (entry 0 unused).
    binary_factor: Vec<f64>,
    /// Sine grating: `J_n(x)` for `n = 0..=reach + 1` on `BESSEL_NODES + 1` nodes of `x`.
    bessel: Vec<f64>,
    /// Node spacing of the Bessel table.
    bessel_dx: f64,
    /// Luminance-weighted efficiency of orders −nmax..=nmax at `w = 2i/(W_NODES−1)`.
    efficiency: Vec<Vec<f64>>,
    /// Σ over the orders of `efficiency` at each `w` node.
    efficiency_total: Vec<f64>,
}

impl Stam {
    /// Builds the model and tabulates what depends only on the parameters.
    #[must_use]
    pub fn new(
        profile: Profile,
        pitch: f64,
        depth: f64,
        coherence: f64,
        direction_deg: f64,
        eta: [f64; 3],
        k: [f64; 3],
    ) -> Self {
        let a = direction_deg.to_radians();
        let mut m = Self {
            profile,
            pitch,
            depth,
            coherence,
            dir: [a.cos(), a.sin()],
            eta,
            k,
            nmax: 0,
            reach: (2.0 * pitch / LAMBDA_LO).ceil() as usize + 1,
            binary_factor: Vec::new(),
            bessel: Vec::new(),
            bessel_dx: 1.0,
            efficiency: Vec::new(),
            efficiency_total: Vec::new(),
        };
        match profile {
            Profile::Binary { duty } => {
                m.binary_factor = (0..=m.reach)
                    .map(|n| {
                        let nf = n as f64;
                        if n == 0 {
                            0.0
                        } else {
                            (PI * nf * duty).sin().powi(2) / (PI * PI * nf * nf)
                        }
                    })
                    .collect();
            }
            Profile::Sine => {
                // x = k w H/2 ≤ (2π/λ_min)·2·H/2.
                let x_max = 2.0 * PI / LAMBDA_LO * depth + 1e-9;
                m.bessel_dx = x_max / BESSEL_NODES as f64;
                m.bessel = (0..=m.reach + 1)
                    .flat_map(|n| (0..=BESSEL_NODES).map(move |i| (n, i)))
                    .map(|(n, i)| libm::jn(n as i32, i as f64 * m.bessel_dx))
                    .collect();
            }
            Profile::Random { .. } => {}
        }
        if !matches!(profile, Profile::Random { .. }) {
            m.nmax = (2.2 * pitch / SAMPLE_LO).floor() as i32;
            let lums: Vec<(f64, f64)> =
                (0..=40).map(|i| SAMPLE_LO + (SAMPLE_HI - SAMPLE_LO) * i as f64 / 40.0).map(|l| (l, cie_xyz(l * 1e3)[1])).collect();
            let ysum: f64 = lums.iter().map(|p| p.1).sum();
            m.efficiency = (0..W_NODES)
                .map(|i| {
                    let w = 2.0 * i as f64 / (W_NODES - 1) as f64;
                    (-m.nmax..=m.nmax)
                        .map(|n| lums.iter().map(|&(l, y)| y * m.efficiency_of(n, l, w)).sum::<f64>() / ysum)
                        .collect()
                })
                .collect();
            m.efficiency_total = m.efficiency.iter().map(|row| row.iter().sum()).collect();
        }
        m
    }

    /// Coherence broadening `s(λ)` (standard deviation in `u` and `v`).
    #[inline]
    fn spread(&self, lambda: f64) -> f64 {
        lambda / (2.0 * std::f64::consts::SQRT_2 * PI * self.coherence)
    }

    /// `J_n(x)` from the table by cubic Hermite interpolation, with the exact derivative
    /// `J_n' = (J_{n−1} − J_{n+1})/2` (`J_0' = −J_1`); `libm::jn` outside the table.
    fn bessel(&self, n: usize, x: f64) -> f64 {
        let stride = BESSEL_NODES + 1;
        if n + 1 >= self.bessel.len() / stride || !(x >= 0.0) || x > BESSEL_NODES as f64 * self.bessel_dx {
            return libm::jn(n as i32, x);
        }
        let h = self.bessel_dx;
        let pos = x / h;
        let i = (pos as usize).min(BESSEL_NODES - 1);
        let t = pos - i as f64;
        let at = |n: usize, i: usize| self.bessel[n * stride + i];
        let deriv = |i: usize| {
            if n == 0 {
                -at(1, i)
            } else {
                0.5 * (at(n - 1, i) - at(n + 1, i))
            }
        };
        let (y0, y1, d0, d1) = (at(n, i), at(n, i + 1), deriv(i), deriv(i + 1));
        let (t2, t3) = (t * t, t * t * t);
        (2.0 * t3 - 3.0 * t2 + 1.0) * y0 + (t3 - 2.0 * t2 + t) * h * d0 + (-2.0 * t3 + 3.0 * t2) * y1 + (t3 - t2) * h * d1
    }

    /// Diffraction efficiency `|c_n|²` of a grating at wavelength λ (µm) and `w`.
    #[must_use]
    pub fn efficiency_of(&self, n: i32, lambda: f64, w: f64) -> f64 {
        let phase = 2.0 * PI / lambda * w * self.depth;
        match self.profile {
            Profile::Binary { duty } => {
                let na = n.unsigned_abs() as usize;
                if n == 0 {
                    1.0 - 2.0 * duty * (1.0 - duty) * (1.0 - phase.cos())
                } else if na < self.binary_factor.len() {
                    4.0 * (0.5 * phase).sin().powi(2) * self.binary_factor[na]
                } else {
                    let nf = n as f64;
                    4.0 * (0.5 * phase).sin().powi(2) * (PI * nf * duty).sin().powi(2) / (PI * PI * nf * nf)
                }
            }
            Profile::Sine => self.bessel(n.unsigned_abs() as usize, 0.5 * phase).powi(2),
            Profile::Random { .. } => {
                if n == 0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// `(u, v)`: the tangential scattering vector `(wi + wo)_xy` in the grating frame.
    #[inline]
    fn uv(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> (f64, f64) {
        let (x, y) = (wi.x + wo.x, wi.y + wo.y);
        (self.dir[0] * x + self.dir[1] * y, -self.dir[1] * x + self.dir[0] * y)
    }

    /// `Φ_λ(u, v; w)` of the random profile at one wavelength.
    #[allow(clippy::too_many_arguments)]
    fn random_phi(&self, lambda: f64, u: f64, v: f64, w: f64, sigma: f64, tx: f64, ty: f64) -> f64 {
        let k = 2.0 * PI / lambda;
        let s2 = self.spread(lambda).powi(2);
        let (ax, ay) = (2.0 / (k * tx).powi(2), 2.0 / (k * ty).powi(2));
        let term = |m: f64| {
            let (vx, vy) = (ax * m + s2, ay * m + s2);
            (-0.5 * (u * u / vx + v * v / vy)).exp() / (2.0 * PI * (vx * vy).sqrt())
        };
        let g = (k * sigma * w).powi(2);
        if !(g > 1e-300) {
            return term(0.0);
        }
        // The Poisson window mode ± 7.2√g (+3) holds all but ~1e-12 of the mass.
        let half = 7.2 * g.sqrt() + 3.0;
        let m0 = (g - half).max(0.0).floor();
        let m1 = (g + half).ceil();
        let mut p = (m0 * g.ln() - g - libm::lgamma(m0 + 1.0)).exp();
        let mut sum = 0.0;
        let mut m = m0;
        while m <= m1 {
            sum += p * term(m);
            m += 1.0;
            p *= g / m;
        }
        sum
    }

    /// `∫ ω_c(λ) Φ_λ dλ` per channel (before clipping), for `(u, v, w)`.
    #[must_use]
    pub fn spectral_phi(&self, u: f64, v: f64, w: f64) -> [f64; 3] {
        let mut out = [0.0; 3];
        if let Profile::Random { sigma, tx, ty } = self.profile {
            for &(l, wt) in random_nodes() {
                let phi = self.random_phi(l, u, v, w, sigma, tx, ty);
                for c in 0..3 {
                    out[c] += wt[c] * phi;
                }
            }
            return out;
        }
        // Integrate over t = 1/λ; κ = 2√2πℓ so that 1/s(λ) = κ t.
        let kappa = 2.0 * std::f64::consts::SQRT_2 * PI * self.coherence;
        let r2 = u * u + v * v;
        let (t_lo, t_hi) = (1.0 / LAMBDA_HI, 1.0 / LAMBDA_LO);
        let order = |n: i32, a: f64, b: f64, intervals: usize, out: &mut [f64; 3]| {
            let nf = n as f64;
            let h = (b - a) / intervals as f64;
            for i in 0..=intervals {
                let t = a + i as f64 * h;
                let e = 0.5 * kappa * kappa * ((u * t - nf / self.pitch).powi(2) + (v * t).powi(2));
                if e > 700.0 {
                    continue;
                }
                let simpson = if i == 0 || i == intervals {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                let l = 1.0 / t;
                let phi = simpson * h / 3.0 * self.efficiency_of(n, l, w) * (-e).exp();
                let om = omega(l);
                for c in 0..3 {
                    out[c] += om[c] * phi;
                }
            }
        };
        // Zeroth order: a Gaussian in t centred at 0, over the whole range.
        if 0.5 * kappa * kappa * r2 * t_lo * t_lo < 36.0 {
            order(0, t_lo, t_hi, 96, &mut out);
        }
        // Orders n ≠ 0: Gaussian in t centred at n u/(a r²) with deviation 1/(κ √r²).
        if u.abs() > 1e-12 {
            let sd = 1.0 / (kappa * r2.sqrt());
            let span = 7.0 * sd;
            let scale = self.pitch * r2 / u.abs();
            let (lo_n, mut hi_n) = (((t_lo - span) * scale).ceil().max(1.0), ((t_hi + span) * scale).floor());
            // The exponent never falls below its value at the centre, ½κ²(n/a)²v²/r²: orders
            // for which that exceeds the nodes' cut-off (700) contribute exactly nothing, and
            // without this bound a tiny |u| would visit ~1/|u| of them.
            if v != 0.0 {
                hi_n = hi_n.min((1400.0f64.sqrt() * self.pitch * r2.sqrt() / (kappa * v.abs())).floor());
            }
            let mut na = lo_n;
            while na <= hi_n {
                let n = if u > 0.0 { na } else { -na } as i32;
                let centre = na / scale;
                let (a, b) = ((centre - span).max(t_lo), (centre + span).min(t_hi));
                if b > a {
                    // Spacing ≤ sd/2 and dt ≤ 0.02 µm⁻¹ (dλ = λ² dt: ≤ 4 nm where the
                    // colour-matching functions are narrowest, 430-530 nm; ≤ 14 nm at 830 nm).
                    let dt = (0.5 * sd).min(0.02);
                    // (The −1e-6 keeps the unclipped window, exactly 28 spacings wide, off a
                    // knife edge between 28 and 30 intervals.)
                    let intervals = (((b - a) / dt - 1e-6).ceil() as usize).clamp(16, 400).next_multiple_of(2);
                    order(n, a, b, intervals, &mut out);
                }
                na += 1.0;
            }
        }
        out.map(|x| x * kappa * kappa / (2.0 * PI))
    }

    fn eval64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> [f64; 3] {
        // Renormalised in f64 so the f32 path (whose inputs pass the front end's f32 unit
        // test unchanged) sees the same directions as the f64 path: the lines are sharp.
        let (wi, wo) = (wi.normalize(), wo.normalize());
        let (ci, co) = (wi.z.min(1.0), wo.z.min(1.0));
        if !(ci > 0.0) || !(co > 0.0) {
            return [0.0; 3];
        }
        let w = ci + co;
        let dot = wi.dot(wo).clamp(-1.0, 1.0);
        let geo = (1.0 + dot).powi(2) / (ci * co * w * w);
        let cos_local = (0.5 * (1.0 + dot)).max(0.0).sqrt();
        let (u, v) = self.uv(wi, wo);
        let phi = self.spectral_phi(u, v, w);
        [0, 1, 2].map(|c| {
            let val = conductor(cos_local, self.eta[c], self.k[c]) * geo * phi[c].max(0.0);
            if val.is_finite() {
                val
            } else {
                0.0
            }
        })
    }

    /// The two spreads of the grating proxy: `s(450 nm)` and `s(750 nm)`, at least
    /// `PROXY_MIN_SPREAD` (very coherent light gives lines far sharper than any sampler needs).
    fn proxy_widths(&self) -> [f64; 2] {
        [self.spread(0.45).max(PROXY_MIN_SPREAD), self.spread(0.75).max(1.5 * PROXY_MIN_SPREAD)]
    }

    /// Interpolation position in the `w` table.
    #[inline]
    fn w_slot(w: f64) -> (usize, f64) {
        let x = (w.clamp(0.0, 2.0) * 0.5 * (W_NODES - 1) as f64).min((W_NODES - 1) as f64);
        let i = (x as usize).min(W_NODES - 2);
        (i, x - i as f64)
    }

    /// Proxy weight of the order with table index `idx` (order `idx − nmax`) at slot `(i, f)`.
    #[inline]
    fn order_weight(&self, idx: usize, (i, f): (usize, f64)) -> f64 {
        let (p, q) = (self.efficiency[i][idx], self.efficiency[i + 1][idx]);
        p + (q - p) * f
    }

    /// Order probabilities of the proxy for `w` (orders −nmax..=nmax), unnormalised.
    fn order_weights(&self, w: f64) -> Vec<f64> {
        let slot = Self::w_slot(w);
        (0..self.efficiency[0].len()).map(|idx| self.order_weight(idx, slot)).collect()
    }

    /// Σ of [`Self::order_weights`] (interpolation commutes with the sum).
    fn order_total(&self, w: f64) -> f64 {
        let (i, f) = Self::w_slot(w);
        let (p, q) = (self.efficiency_total[i], self.efficiency_total[i + 1]);
        p + (q - p) * f
    }

    /// The random profile's proxy: Poisson mixtures at 450, 550 and 650 nm (anisotropic).
    fn random_mixtures(&self, w: f64) -> Vec<(GaussMixture, f64, f64, f64)> {
        let Profile::Random { sigma, tx, ty } = self.profile else { return Vec::new() };
        [0.45, 0.55, 0.65]
            .iter()
            .map(|&l| {
                let k = 2.0 * PI / l;
                let s2 = self.spread(l).max(PROXY_MIN_SPREAD).powi(2);
                let g = (k * sigma * w).powi(2);
                // Unit per-m variance; the axes scale it (anisotropic) and add s² below.
                let mix = GaussMixture::poisson(g, 1.0, 0.0, true).expect("a mixture from m = 0 always exists");
                (mix, 2.0 / (k * tx).powi(2), 2.0 / (k * ty).powi(2), s2)
            })
            .collect()
    }

    /// Proxy density in the `(u, v)` plane for `w_o = 2 cos θo`.
    fn proxy_density(&self, u: f64, v: f64, w_o: f64) -> f64 {
        if matches!(self.profile, Profile::Random { .. }) {
            let mut d = 0.0;
            for (mix, ax, ay, s2) in self.random_mixtures(w_o) {
                for j in 0..mix.n {
                    let m = mix.var[j];
                    d += mix.weight[j] * normal(u, ax * m + s2) * normal(v, ay * m + s2);
                }
            }
            return d / 3.0;
        }
        let total = self.order_total(w_o);
        if !(total > 0.0) {
            return 0.0;
        }
        let slot = Self::w_slot(w_o);
        let widths = self.proxy_widths();
        // Orders whose band [nλ₀/a, nλ₁/a] (± 9 spreads) can contain u.
        let reach = 9.0 * widths[1];
        let (lo, hi) = ((u - reach) * self.pitch, (u + reach) * self.pitch);
        let (n_lo, n_hi) = ((lo / SAMPLE_HI).min(lo / SAMPLE_LO).floor(), (hi / SAMPLE_LO).max(hi / SAMPLE_HI).ceil());
        let (n_lo, n_hi) = (n_lo.max(-self.nmax as f64) as i32, n_hi.min(self.nmax as f64) as i32);
        let mut d = 0.0;
        for n in n_lo..=n_hi {
            let wn = self.order_weight((n + self.nmax) as usize, slot);
            if wn <= 0.0 {
                continue;
            }
            let (x0, x1) = {
                let (a, b) = (n as f64 * SAMPLE_LO / self.pitch, n as f64 * SAMPLE_HI / self.pitch);
                (a.min(b), a.max(b))
            };
            if u < x0 - 9.0 * widths[1] || u > x1 + 9.0 * widths[1] {
                continue;
            }
            let mut comp = 0.0;
            for &s in &widths {
                let ud = if n == 0 {
                    normal(u, s * s)
                } else {
                    (norm_cdf((u - x0) / s) - norm_cdf((u - x1) / s)) / (x1 - x0)
                };
                comp += 0.5 * ud * normal(v, s * s);
            }
            d += wn / total * comp;
        }
        d
    }

    /// Draws `(u, v)` from the proxy for `w_o`.
    fn proxy_sample(&self, w_o: f64, u0: f64, u1: f64, u2: f64) -> Option<(f64, f64)> {
        // Box-Muller pair from (u1, u2).
        let r = (-2.0 * (1.0 - u1).max(1e-300).ln()).sqrt();
        let (z1, z2) = (r * (2.0 * PI * u2).cos(), r * (2.0 * PI * u2).sin());
        if matches!(self.profile, Profile::Random { .. }) {
            let mixes = self.random_mixtures(w_o);
            let (which, u0) = pick_lobe(&[1.0, 1.0, 1.0], u0)?;
            let (mix, ax, ay, s2) = &mixes[which];
            let (j, _) = pick_lobe(&mix.weight[..mix.n], u0)?;
            let m = mix.var[j];
            return Some((z1 * (ax * m + s2).sqrt(), z2 * (ay * m + s2).sqrt()));
        }
        let weights = self.order_weights(w_o);
        let (idx, u0) = pick_lobe(&weights, u0)?;
        let n = idx as i32 - self.nmax;
        let (width, u0) = pick_lobe(&[1.0, 1.0], u0)?;
        let s = self.proxy_widths()[width];
        let centre = if n == 0 { 0.0 } else { n as f64 * (SAMPLE_LO + (SAMPLE_HI - SAMPLE_LO) * u0) / self.pitch };
        Some((centre + s * z1, s * z2))
    }

    /// Probability of the defensive cosine lobe.
    const DEFENSIVE: f64 = 0.1;

    fn pdf64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
        let (wi, wo) = (wi.normalize(), wo.normalize());
        if !(wi.z > 0.0) || !(wo.z > 0.0) {
            return 0.0;
        }
        let (u, v) = self.uv(wi, wo);
        let q = self.proxy_density(u, v, 2.0 * wo.z.min(1.0));
        Self::DEFENSIVE * cosine_hemisphere_pdf(wi.z) + (1.0 - Self::DEFENSIVE) * q * wi.z
    }

    fn sample64(&self, wo: Vec3<f64>, u: [f64; 3]) -> Option<Vec3<f64>> {
        let wo = wo.normalize();
        let (lobe, u0) = pick_lobe(&[Self::DEFENSIVE, 1.0 - Self::DEFENSIVE], u[0])?;
        if lobe == 0 {
            return Some(cosine_hemisphere(u[1], u[2]));
        }
        let (pu, pv) = self.proxy_sample(2.0 * wo.z.min(1.0), u0, u[1], u[2])?;
        // Back to the tangent frame, then wi_xy = v_xy − wo_xy.
        let x = self.dir[0] * pu - self.dir[1] * pv - wo.x;
        let y = self.dir[1] * pu + self.dir[0] * pv - wo.y;
        let z2 = 1.0 - x * x - y * y;
        (z2 > 0.0).then(|| Vec3::new(x, y, z2.sqrt()))
    }
}

impl Bxdf for Stam {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        Rgb::from_array(self.eval64(wi.cast(), wo.cast()))
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        T::of(self.pdf64(wi.cast(), wo.cast()))
    }

    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wi: Vec3<T> = self.sample64(wo.cast(), u.map(|x| x.f64()))?.cast();
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
    use crate::rng::Pcg32;
    use crate::Material;

    fn dir(c: f64, phi: f64) -> Vec3<f64> {
        let s = (1.0 - c * c).max(0.0).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), c)
    }

    fn grating(profile: Profile, depth: f64, coherence: f64) -> Stam {
        Stam::new(profile, 1.6, depth, coherence, 0.0, AL_ETA, AL_K)
    }

    /// |c_n|² of a phase profile by direct quadrature of its Fourier coefficient.
    fn efficiency_by_quadrature(h: impl Fn(f64) -> f64, n: i32, phase_per_height: f64) -> f64 {
        let steps = 20_000;
        let (mut re, mut im) = (0.0, 0.0);
        for j in 0..steps {
            let x = (j as f64 + 0.5) / steps as f64;
            let arg = phase_per_height * h(x) - 2.0 * PI * n as f64 * x;
            re += arg.cos() / steps as f64;
            im += arg.sin() / steps as f64;
        }
        re * re + im * im
    }

    /// The closed-form efficiencies equal the Fourier coefficients of e^{ikwh} computed by
    /// quadrature, and sum to one over the orders (Parseval).
    #[test]
    fn efficiencies_match_fourier_coefficients() {
        let (lambda, w) = (0.55, 1.7);
        for (profile, depth) in [(Profile::Binary { duty: 0.35 }, 0.11), (Profile::Binary { duty: 0.5 }, 0.4), (Profile::Sine, 0.3)] {
            let m = Stam::new(profile, 1.6, depth, 3.0, 0.0, AL_ETA, AL_K);
            let k = 2.0 * PI / lambda;
            let h = |x: f64| match profile {
                Profile::Binary { duty } => {
                    if x < duty {
                        depth
                    } else {
                        0.0
                    }
                }
                _ => 0.5 * depth * (2.0 * PI * x).sin(),
            };
            let mut total = 0.0;
            for n in -4000..=4000 {
                let e = m.efficiency_of(n, lambda, w);
                total += e;
                if n.abs() <= 6 {
                    let q = efficiency_by_quadrature(h, n, k * w);
                    assert!((e - q).abs() < 1e-6, "{profile:?} n {n}: {e} vs {q}");
                }
            }
            println!("Stam {profile:?}: Σ|c_n|² = {total:.6}");
            assert!((total - 1.0).abs() < 1e-3, "{profile:?}: Σ|c_n|² = {total}");
        }
    }

    /// A wavelength-independent Φ integrates to grey: the RGB weights (1 nm table and the hat
    /// weights) sum to one per channel.
    #[test]
    fn flat_spectrum_is_grey() {
        for nodes in [hat_weights(95).as_slice(), random_nodes()] {
            for c in 0..3 {
                let s: f64 = nodes.iter().map(|n| n.1[c]).sum();
                assert!((s - 1.0).abs() < 1e-9, "{s}");
            }
        }
    }

    /// Flat profile (depth 0): no diffraction. All light is in the zeroth order, whose
    /// albedo at normal incidence is the Fresnel reflectance of each channel (Parseval), and
    /// nothing reaches the first-order direction u = λ/a.
    #[test]
    fn flat_profile_does_not_diffract() {
        let m = grating(Profile::Binary { duty: 0.35 }, 0.0, 8.0);
        let z = dir(1.0, 0.0);
        for u in [0.3f64, 0.34, 0.4, 0.45] {
            let wi = Vec3::new(u, 0.0, (1.0 - u * u).sqrt());
            assert!(m.eval64(wi, z).iter().all(|&f| f < 1e-100), "{:?}", m.eval64(wi, z));
        }
        let mat = Material::from_json(r#"{"model": "stam", "depth": 0.0, "coherence": 8.0}"#).unwrap();
        let (a, se) = albedo(&mat, z, 100_000, &mut Pcg32::new(4, 4));
        println!("Stam flat profile albedo at normal incidence {a:?} ± {se:.1e}");
        for c in 0..3 {
            let f0 = conductor(1.0, AL_ETA[c], AL_K[c]);
            // G/w² departs from 1 by O(s²) over the narrow lobe.
            assert!((a[c] - f0).abs() < 2e-3 + 4.0 * se, "channel {c}: {} vs {f0}", a[c]);
        }
    }

    /// The grating equation and the colour it brings: at normal incidence the first order
    /// of each channel peaks at u = λ/a for the channel's wavelengths (red beyond green beyond
    /// blue).
    #[test]
    fn first_order_follows_the_grating_equation() {
        let m = grating(Profile::Binary { duty: 0.5 }, 0.15, 20.0);
        let z = dir(1.0, 0.0);
        let mut best = [(0.0, 0.0); 3];
        for i in 0..=2000 {
            let u = 0.2 + 0.3 * i as f64 / 2000.0;
            let wi = Vec3::new(u, 0.0, (1.0 - u * u).sqrt());
            let f = m.eval64(wi, z);
            for c in 0..3 {
                if f[c] > best[c].1 {
                    best[c] = (u, f[c]);
                }
            }
        }
        let lam: Vec<f64> = best.iter().map(|b| b.0 * 1.6).collect();
        println!("Stam first-order peaks at λ = a·u: R {:.3} µm, G {:.3} µm, B {:.3} µm", lam[0], lam[1], lam[2]);
        assert!(lam[0] > 0.59 && lam[0] < 0.66, "red peak at λ = {}", lam[0]);
        assert!(lam[1] > 0.51 && lam[1] < 0.56, "green peak at λ = {}", lam[1]);
        assert!(lam[2] > 0.43 && lam[2] < 0.48, "blue peak at λ = {}", lam[2]);
    }

    /// The random profile with Tx = Ty = τ and unlimited coherence is He et al.'s directional
    /// diffuse series (Stam 1999 §5): compare with the HTSG implementation.
    #[test]
    fn random_profile_is_the_htsg_series() {
        let (sigma, tau, lambda, w) = (0.1, 2.0, 0.55, 1.6);
        let m = Stam::new(Profile::Random { sigma, tx: tau, ty: tau }, 1.6, 0.0, 1e7, 0.0, AL_ETA, AL_K);
        let k = 2.0 * PI / lambda;
        let g = (k * sigma * w).powi(2);
        for (u, v) in [(0.05, 0.0), (0.1, 0.2), (0.3, -0.1)] {
            let stam = m.random_phi(lambda, u, v, w, sigma, tau, tau);
            let r2 = u * u + v * v;
            let kt2 = (k * tau).powi(2);
            let htsg = kt2 / (4.0 * PI) * crate::models::htsg::series(g, 0.25 * kt2 * r2, 1e-12).sum;
            assert!((stam / htsg - 1.0).abs() < 1e-9, "({u}, {v}): {stam} vs {htsg}");
        }
    }

    /// The spectral integral over t = 1/λ agrees with a brute-force 0.05 nm sum over λ.
    #[test]
    fn spectral_integral_matches_brute_force() {
        for m in [
            grating(Profile::Binary { duty: 0.35 }, 0.11, 3.0),
            grating(Profile::Sine, 0.3, 1.5),
            Stam::new(Profile::Binary { duty: 0.5 }, 5.0, 0.3, 10.0, 0.0, AL_ETA, AL_K),
        ] {
            for (u, v, w) in [(0.0, 0.0, 2.0), (0.3, 0.01, 1.8), (-0.7, 0.0, 1.2), (1.2, -0.02, 1.9), (0.02, 0.01, 0.5)] {
                let got = m.spectral_phi(u, v, w);
                let mut want = [0.0; 3];
                let dl = 5e-5;
                let mut l = LAMBDA_LO;
                while l < LAMBDA_HI {
                    let lm = l + 0.5 * dl;
                    let s2 = m.spread(lm).powi(2);
                    let mut phi = 0.0;
                    let reach = (2.5 * m.pitch / LAMBDA_LO) as i32;
                    for n in -reach..=reach {
                        let e = m.efficiency_of(n, lm, w);
                        if e > 0.0 {
                            phi += e * normal(u - n as f64 * lm / m.pitch, s2) * normal(v, s2);
                        }
                    }
                    let om = omega(lm);
                    for c in 0..3 {
                        want[c] += om[c] * phi * dl;
                    }
                    l += dl;
                }
                let scale = want.iter().fold(0.0f64, |a, b| a.max(b.abs())).max(1e-6);
                let err = (0..3).map(|c| (got[c] - want[c]).abs() / scale).fold(0.0, f64::max);
                println!("Stam spectral quadrature at ({u}, {v}, {w}): error {err:.1e} of the largest channel");
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 2e-3 * scale, "({u}, {v}, {w}) c {c}: {got:?} vs {want:?}");
                }
            }
        }
    }

    /// The proxy reports the density it samples (the χ² check tests this statistically).
    #[test]
    fn sampled_pdf_matches_pdf() {
        let mut rng = Pcg32::new(8, 1);
        for m in [grating(Profile::Binary { duty: 0.35 }, 0.11, 3.0), Stam::new(Profile::Random { sigma: 0.1, tx: 1.0, ty: 3.0 }, 1.6, 0.0, 3.0, 30.0, AL_ETA, AL_K)] {
            for _ in 0..2000 {
                let wo = dir(rng.uniform().max(1e-3), 6.0 * rng.uniform());
                if let Some(s) = m.sample(wo, rng.uniform3()) {
                    let p = m.pdf(s.wi, wo);
                    assert!((s.pdf - p).abs() <= 1e-12 * p);
                }
            }
        }
    }

    /// The sine grating's Bessel table reproduces `libm::jn` to 1e-10.
    #[test]
    fn bessel_table_is_accurate() {
        let m = grating(Profile::Sine, 0.7, 3.0);
        let mut rng = Pcg32::new(2, 2);
        for _ in 0..20_000 {
            let n = (rng.uniform() * m.reach as f64) as usize;
            let x = rng.uniform() * 2.0 * PI / LAMBDA_LO * 0.7;
            let (a, b) = (m.bessel(n, x), libm::jn(n as i32, x));
            assert!((a - b).abs() < 1e-10, "J_{n}({x}): {a} vs {b}");
        }
    }
}
