//! The clearcoat: a dielectric interface of index `η` over the basecoat, smooth (a mirror
//! delta lobe) or GGX-rough, with Beer-Lambert absorption across its thickness.
//!
//! Light crossing the coat refracts at the macro normal (Snell); the rough coat's transmission
//! is approximated by that refraction with the energy `1 − E_top(μ) − ΔR(μ)` its reflection
//! leaves (Weidlich & Wilkie 2007), so that top reflection and transmission together conserve
//! energy. `ΔR` is the rough interface's multiple-scattering reflection ([`MultipleScattering`],
//! issue 17 item 3): the share of the energy Walter's single-scattering GGX loses to masking
//! that a lossless interface reflects.
//!
//! ## Transmission blur (issue 17, item 3)
//! A rough coat also spreads the light it lets through: a facet tilted by a small angle `δ`
//! turns the refracted direction by `k δ`, with (Snell on the facet, differentiated at `δ = 0`)
//!
//! `k(μ') = 1 − μ / (η μ')`,  `μ = √(1 − η²(1 − μ'²))` the outside cosine of the inside one
//!
//! (`k = 1 − 1/η` at normal incidence, → 1 at the critical angle; `k = 1` under total internal
//! reflection, its continuation; `k = 0` for `η = 1`). The coat's facet slopes have the
//! variance `c α_c²/2` per axis (`c` = [`ggx_slope_variance`], the Beckmann equivalent of the
//! GGX `α_c`, calibrated); a lobe of the base
//! reflects about a normal that bisects the two blurred inside directions, so its own slope
//! variance `α_b²/2` grows by `c (k_i² + k_o²) α_c²/8`. Around a specular lobe's peak the light
//! leaves near the mirror direction, whose cosine is `μo'`: the blur a lobe seen from `wo'`
//! gets is `α_eff²(μo') = α_b² + 2c α_c² q(μo')`, `q = k²/4` ([`TransmissionBlur::one_sided`]).
//! That is a proper GGX (Beckmann for the flakes) lobe for each `wo`, normalised as the base's
//! own, but not symmetric. The layered model uses
//!
//! `f_blur(wi', wo') = min(f_{α_eff(μi')}(wi', wo'), f_{α_eff(μo')}(wi', wo'))`
//!
//! — symmetric (each one-sided lobe is a microfacet BRDF of fixed α, symmetric in its two
//! directions, and the min swaps them), and for fixed `wo'` below the normalised lobe
//! `f_{α_eff(μo')}`, so its albedo is at most that lobe's (energy conservation holds for the
//! base as it does without blur). At the peak (`μi' = μo'`) the two agree. This is in the spirit
//! of Belcour 2018 (the interface's variance added to the lobe's, scaled by the η and cosine
//! factors of the refraction), made symmetric so that the
//! layered BRDF stays reciprocal. The blur vanishes as `α_c → 0` (a smooth coat has none).

use crate::frame::HalfPair;
use crate::fresnel;
use crate::lanes::{self, keep, Lanes, Mask};
use crate::math::Vec3;
use crate::microfacet::{DistributionKind, MaskingKind, Microfacet};
use crate::real::Real;
use crate::sampling::cosine_hemisphere_pdf;
use crate::table::MuTable;

/// Number of `μ` nodes of the coat's albedo table.
const ALBEDO_NODES: usize = 64;
/// Low-discrepancy samples per node of the albedo table.
const ALBEDO_SAMPLES: usize = 1024;

/// The slope variance per axis of the coat's GGX facets in units of `α_c²/2` (Beckmann's),
/// `c(α_c) = 1.7 + 3 exp(−α_c/0.08)`: GGX slopes (a Student-t of 2 degrees of freedom) have no
/// finite variance, so the equivalent is calibrated, as Belcour 2018 maps GGX roughness to a
/// variance empirically. A constant `c` cannot serve every roughness: the heavier the coat's
/// tails, the less of them the blurred lobe should take. Calibrated on a sharp metal base
/// (α 0.05) under coats of α 0.03–0.3 at θo 0°/40°/75° against the lossless reference
/// (`docs/paint-validation.md` §8, 200 000 walks): the lobe-shape error is smallest near
/// c ≈ 3.5 (α 0.03, the largest scanned), 2.3–2.8 (α 0.1), 2.0 (α 0.2, where more blur also
/// darkens the grazing albedo) and 1.75 (α 0.3); this form gives 3.76, 2.56, 1.95, 1.77.
/// (Sessions 10–22 used the constant 1.75, the best single value for α 0.1–0.3 at
/// θo 0°/40°.)
#[inline(always)]
#[must_use]
pub fn ggx_slope_variance<L: Lanes>(alpha: L) -> L {
    L::c(1.7) + L::c(3.0) * lanes::exp(alpha * L::c(-1.0 / 0.08))
}

/// The transmission blur of a rough coat of index `ior` and GGX roughness `alpha` (see the
/// module docs): the variance it adds to a base lobe's `α²` for the inside cosines of the two
/// directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransmissionBlur {
    /// Coat index of refraction η.
    pub ior: f64,
    /// The coat's GGX `α_c`.
    pub alpha: f64,
    /// `2 c(α_c) α_c²` ([`ggx_slope_variance`]), derived from `alpha` once
    /// ([`TransmissionBlur::new`], the only way to make one).
    variance: f64,
}

impl TransmissionBlur {
    /// The blur of a coat of index `ior` and GGX roughness `alpha`.
    #[must_use]
    pub fn new(ior: f64, alpha: f64) -> Self {
        Self { ior, alpha, variance: 2.0 * ggx_slope_variance(alpha) * alpha * alpha }
    }

    /// `q(μ') = k(μ')²/4` for an inside direction with cosine `mu_in` (see the module docs).
    #[inline(always)]
    #[must_use]
    pub fn spread<L: Lanes>(ior: f64, mu_in: L) -> L {
        let eta = L::c(ior);
        let mu_in = lanes::max(mu_in, L::c(1e-6));
        // Outside cosine; 0 under total internal reflection (then k = 1).
        let mu_out = lanes::sqrt_fast(lanes::max(L::c(1.0) - eta * eta * (L::c(1.0) - mu_in * mu_in), L::c(0.0)));
        let k = L::c(1.0) - lanes::div_fast(mu_out, eta * mu_in);
        k * k * L::c(0.25)
    }

    /// `2 c α_c² q(μ')`: what the blur adds to the `α²` of a base lobe seen from an inside
    /// direction with cosine `mu_in` (both crossings at that cosine: the lobe's peak; `c` is
    /// [`ggx_slope_variance`]).
    #[inline(always)]
    #[must_use]
    pub fn one_sided<L: Lanes>(&self, mu_in: L) -> L {
        L::c(self.variance) * Self::spread(self.ior, mu_in)
    }

    /// [`TransmissionBlur::one_sided`] for a coat of index `ior` and roughness `alpha` per lane
    /// (the per-element path, [`super::varying`]).
    #[inline(always)]
    #[must_use]
    pub fn one_sided_at<L: Lanes>(ior: f64, alpha: L, mu_in: L) -> L {
        L::c(2.0) * ggx_slope_variance(alpha) * (alpha * alpha) * Self::spread(ior, mu_in)
    }
}

/// A dielectric coat.
#[derive(Clone, Debug)]
pub struct Coat {
    /// Relative index of refraction coat/air (1 means no interface).
    pub ior: f64,
    /// GGX roughness α of the top surface (0 = smooth).
    pub roughness: f64,
    /// Absorption coefficient per channel, 1/mm.
    pub absorption_per_mm: [f64; 3],
    /// Thickness in mm.
    pub thickness_mm: f64,
    /// `E_top(μ)`: directional albedo of the top reflection (rough coats only).
    albedo: Option<MuTable>,
    /// The interface's multiple-scattering reflection (rough coats only; see
    /// [`MultipleScattering`]).
    ms: Option<MultipleScattering>,
    /// `g(μ)`, the crossing factor of the light that crosses the coat twice (rough coats
    /// only; see [`Coat::crossing`]).
    crossing: Option<MuTable>,
    /// `E_top(μ)`, `ΔR(μ)` and `g(μ)` as the three channels of one table (rough coats only):
    /// [`Coat::at`] reads all three with one index computation.
    factors: Option<MuTable>,
    /// The ratio `sin θ'/sin θ` of the first metal bounce's inside direction to its outside
    /// direction `θ` per outside cosine (rough coats only; [`Coat::mean_refract_in`]).
    mean_refraction: Option<MuTable>,
}

/// The inside direction of `w` whose tangent-plane part is `ratio` times `w`'s (the same
/// azimuth, `sin θ' = ratio · sin θ`).
#[inline(always)]
#[must_use]
pub(crate) fn inside_with_ratio<T: Lanes>(w: Vec3<T>, ratio: T) -> Vec3<T> {
    let sin2 = lanes::max(T::c(1.0) - w.z * w.z, T::c(0.0));
    let z = lanes::sqrt_fast(lanes::max(T::c(1.0) - sin2 * ratio * ratio, T::c(1e-6)));
    Vec3::new(w.x * ratio, w.y * ratio, z)
}

/// The share of the rough interface's mean refraction shift that the metal base's first
/// bounce and its bounce series take ([`Coat::mean_refract_in`]): `sin θ' = sin θ/η + β (s̄ −
/// sin θ/η)`, `s̄` the tangent-plane mean of the transmitted directions. Calibrated on the
/// lossless reference (metal base α 0.05 under coats of α 0.01–0.3, θo 0°/40°/75°, 400 000
/// walks; §8 of docs/paint-validation.md, ninth pass): with the series at the same map the
/// worst whole-lobe shapes over the 15 cells were 5.4 / 4.5 / 4.8 / 6.6 / 8.9 % for β 0.4 /
/// 0.5 / 0.6 / 0.8 / 1 (with the series at the macro refraction, session 37: 6.7 % at β 0.6);
/// β = 1 darkens the first bounce by up to 15 % against the walk's.
pub const MEAN_REFRACTION_SHARE: f64 = 0.5;

/// The share of the rough interface's mean refraction shift that the flakes' lobe takes
/// ([`Coat::flake_refract_in`]), in place of a share of the transmission blur (which the
/// flakes no longer take). The flakes' Beckmann lobe (α ≈ 0.2) is broad next to the coat's
/// blur; what the rough interface changes for it is where light crosses: at the mean
/// refraction the lobe's outside solid angle shrinks (`J`, [`Coat::mean_refract_out`]), most
/// at normal view, where the blurred model's first bounce was too bright. Calibrated against
/// the lossless reference (Al flakes 8 % under coats of α 0.1–0.3, θo 0°/40°/75°;
/// docs/paint-validation.md §8, tenth pass). The scan (a throwaway build with the shares from
/// the environment, the layer tables as before; largest albedo error over the 15 cells):
/// 1.92 / 1.82 / 2.05 % for shares 0.1 / 0.15 / 0.2 without blur (1 600 000 walks); share
/// 0.15 with the flakes' blur share 0 / 0.1 / 0.25: 1.90 / 2.22 / 2.64 %, shares 0.5 and 1
/// without blur: 3.99 / 5.80 % (400 000 walks); session 23's blur share 0.25 at the macro
/// refraction: 2.09 %. Kept, with `A1` and `M` following the map: 1.79 ± 0.20 % (α 0.3, θo
/// 75°; 1 600 000 walks), and the body lobe at θo 75°, α 0.3: 11.0 % (was 16.8 %).
pub const FLAKE_MEAN_REFRACTION_SHARE: f64 = 0.15;

/// `sin θ'/sin θ` of the flakes' map ([`Coat::flake_refract_in`]) from the metal's
/// ([`Coat::mean_refract_in`], share [`MEAN_REFRACTION_SHARE`]) for a coat of index `ior`:
/// both maps are the macro refraction plus their share of the same shift, so the flakes' is
/// `1/η + (β_f/β)(r − 1/η)` (below the metal's where that is above the macro refraction,
/// so within the metal map's range).
#[inline(always)]
#[must_use]
pub(crate) fn flake_ratio_from_mean<T: Lanes>(ior: f64, mean_ratio: T) -> T {
    let macro_ratio = T::c(1.0 / ior);
    macro_ratio + (mean_ratio - macro_ratio) * T::c(FLAKE_MEAN_REFRACTION_SHARE / MEAN_REFRACTION_SHARE)
}

/// The coat's factors at one outside cosine `μ`, per lane ([`Coat::at`]).
#[derive(Clone, Copy, Debug)]
pub struct CoatAt<T> {
    /// Energy the top surface reflects: [`Coat::reflectance`].
    pub reflectance: T,
    /// Energy that enters the coat: [`Coat::transmittance`] (a smooth coat's without the
    /// cancellation of `1 − F` at grazing incidence, [`fresnel::dielectric_transmittance`]).
    pub entering: T,
    /// The multiple-scattering reflection `ΔR(μ)`: [`Coat::ms_albedo`] (0 for a smooth coat).
    pub ms: T,
    /// The crossing factor `g(μ)`: [`Coat::crossing`].
    pub crossing: T,
}

impl<T: Lanes> CoatAt<T> {
    /// Energy that enters the coat: [`Coat::transmittance`] (`max(1 − reflectance − ΔR, 0)`
    /// for a rough coat).
    #[inline(always)]
    #[must_use]
    pub fn transmittance(&self) -> T {
        self.entering
    }
}

/// The rough coat's multiple-scattering reflection (issue 17, item 3): the energy Walter's
/// single-scattering GGX interface loses to masking, `L(μ) = 1 − E_r(μ) − E_t(μ)`, is in a
/// lossless (Heitz et al. 2016) interface partly reflected and partly transmitted. The
/// reflected share `κ` is [`ms_reflected_share`] (fitted to the multiple-scattering walk); the
/// reflection leaves through the separable Kulla-Conty-style lobe
///
/// `f_ms(wi, wo) = ΔR(μi) ΔR(μo) / (π ΔR̄)`,  `ΔR(μ) = κ L(μ)`, `ΔR̄ = 2∫ΔR μ dμ`,
///
/// whose albedo is exactly `ΔR(μo)` (symmetric, hence reciprocal); the coat lets through
/// `1 − E_top(μ) − ΔR(μ)` (energy conserving: `E_top + ΔR ≤ E_r + E_t + L = 1`). As α → 0
/// the loss `L` and with it the term vanish; a smooth coat has none.
#[derive(Clone, Debug)]
pub struct MultipleScattering {
    /// `ΔR(μ)` (the same value in the three channels).
    pub albedo: MuTable,
    /// `1/(π ΔR̄)` (0 when `ΔR̄ = 0`).
    pub norm: f64,
    /// The reflected share `κ` of the single-scattering loss.
    pub kappa: f64,
}

/// The forward concentration `r` of the multiple-scattering reflection's azimuthal factor
/// [`ms_azimuthal`]: its wrapped-Cauchy parameter is `ρ = r √(sin θi sin θo)`. Fitted at η 1.5
/// to the lossless walk's reflections after more than one event (θo 60°/75°/85°, α 0.1–0.3,
/// 2 · 10⁶ walks per direction, 12 × 6 equal-solid-angle bins): the walk sends 74–93 % of
/// them into the 30° of azimuth around the mirror plane's forward side at θo 75° (a uniform
/// azimuth gives 17 %); with `r` 0.95 and the square root the lobe-shape error of that
/// reflection alone drops from 86–91 % (the separable lobe) to 15–20 % at θo 75°
/// (`docs/paint-validation.md` §8); `r` 0.95 rather than the scan's 0.96–0.98 keeps the
/// factor's peak `(1 + r)/(1 − r)` at 39.
pub const MS_FORWARD_CONCENTRATION: f64 = 0.95;

/// The azimuthal factor of the coat's multiple-scattering reflection (issue 17 item 3): a
/// wrapped Cauchy distribution of the azimuth difference `Δφ` centred on the forward direction
/// (`Δφ = π`, where light reflected twice on a rough surface goes),
///
/// `A(wi, wo) = (1 − ρ²) / (1 + ρ² + 2ρ cos Δφ)`,  `ρ = r √(sin θi sin θo)`
///
/// (`r` = [`MS_FORWARD_CONCENTRATION`]). Its mean over `Δφ` is exactly 1 for every `ρ` in
/// [0, 1), so multiplying the separable lobe by it keeps that lobe's albedo `ΔR(μo)` exactly
/// (energy conservation unchanged); it is symmetric in `wi` and `wo` (reciprocity unchanged);
/// it is positive and at most `(1 + r)/(1 − r)`; at normal incidence (`ρ = 0`) it is 1.
///
/// Written without cancellation: near its peak (both directions grazing, `Δφ ≈ π`)
/// `1 + ρ² + 2ρ cos Δφ` is a difference of numbers near 2 that leaves `(1 − ρ)²` ≈ 0.0025, so
/// the direct form lost ~600× the working precision (f32: `A` 1.3e-4 off the f64 value at
/// grazing forward pairs; the paint's f32 batch path 1.8e-5 off its f64 reference, session
/// 22). With `s = sin θi sin θo`, the denominator is `(1 − ρ)² + 2ρ (1 + cos Δφ)` and
/// - `1 − ρ = U/Q`, `U = (1 − r) Q + r (1 − s²)`, `Q = (1 + s)(1 + √s)` (from
///   `1 − √s = (1 − s²)/Q`), `1 − s² = cos²θi + cos²θo − cos²θi cos²θo` (unit directions);
/// - `s (1 + cos Δφ) = s + h` with `h = hi·ho` the horizontal parts' dot product, and where
///   `h < 0` (the cancelling side) `s + h = c²/(s − h)` with `c = hi × ho` (Lagrange:
///   `s² − h² = c²`),
///
/// so `A = U (1 + ρ) Q V √s / (U² V √s + 2 r q Q²)` with `q = c²`, `V = s − h` where `h < 0`
/// and `q = s + h`, `V = 1` elsewhere: sums of positive terms and one division (the direct
/// form near the normal, where `ρ ≤ 1e-6` leaves it nothing to cancel).
#[inline(always)]
#[must_use]
pub fn ms_azimuthal<L: Lanes>(wi: Vec3<L>, wo: Vec3<L>) -> L {
    let (one, zero) = (L::c(1.0), L::c(0.0));
    let r = MS_FORWARD_CONCENTRATION;
    let (si2, so2) = (wi.x * wi.x + wi.y * wi.y, wo.x * wo.x + wo.y * wo.y);
    let s = lanes::sqrt(si2 * so2);
    let root_s = lanes::sqrt_fast(s);
    let rho = L::c(r) * root_s;
    // 1 − s² = cos²θi + cos²θo − cos²θi cos²θo: symmetric, and the subtracted product is at
    // most either square, so nothing cancels.
    let (ci2, co2) = (wi.z * wi.z, wo.z * wo.z);
    let one_minus_s2 = lanes::max((ci2 + co2) - ci2 * co2, zero);
    let q_big = (one + s) * (one + root_s);
    let u = L::c(1.0 - r) * q_big + L::c(r) * one_minus_s2;
    let h = wi.x * wo.x + wi.y * wo.y;
    let c = wi.x * wo.y - wi.y * wo.x;
    let opposed = lanes::lt(h, zero);
    let q = lanes::select(opposed, c * c, s + h);
    let v = lanes::select(opposed, s - h, one);
    let v_root_s = v * root_s;
    // Near the normal (s ≤ 1e-12, so ρ ≤ 1e-6) the quotient's terms shrink like s^1.5 (0/0 at
    // s = 0) while the direct form has nothing to cancel: `(1 − ρ²)/(1 + ρ² + 2 r h/√s)`.
    let away = lanes::gt(s, L::c(1e-12));
    let numerator_away = u * (one + rho) * q_big * v_root_s;
    let denominator_away = u * u * v_root_s + L::c(2.0 * r) * q * q_big * q_big;
    if away.all() {
        // No lane near the normal (the common case): the direct form is not needed.
        return lanes::div_fast(numerator_away, denominator_away);
    }
    let inv_root_s = lanes::rsqrt_fast(lanes::max(s, L::c(f64::from(f32::MIN_POSITIVE))));
    let numerator = lanes::select(away, numerator_away, one - rho * rho);
    let denominator = lanes::select(away, denominator_away, one + rho * rho + L::c(2.0 * r) * h * inv_root_s);
    lanes::div_fast(numerator, denominator)
}

/// Samples the shape of the multiple-scattering reflection for `wo`: `cos θi` from the cosine
/// lobe (`sin² θi = u1`), then the azimuth difference from the wrapped Cauchy of
/// [`ms_azimuthal`] by its closed-form inverse, `Δφ = π + 2 atan(((1 − ρ)/(1 + ρ)) tan(π(u2 − ½)))`
/// (`ρ` depends on `θi`, drawn first). Density [`ms_pdf`] `= A(wi, wo) cos θi / π`, so the
/// lobe `ΔR(μi) ΔR(μo) A / (π ΔR̄)` is sampled up to its `ΔR` factors (weights bounded by
/// `ΔR`'s range, not by `A`'s peak of 39 as with the cosine lobe alone).
#[inline(always)]
#[must_use]
pub fn ms_sample<L: Lanes>(wo: Vec3<L>, u1: L, u2: L) -> Vec3<L> {
    let one = L::c(1.0);
    let sin_i = lanes::safe_sqrt(u1);
    let mu_i = lanes::safe_sqrt(one - u1);
    let sin_o = lanes::sqrt(wo.x * wo.x + wo.y * wo.y);
    let rho = L::c(MS_FORWARD_CONCENTRATION) * lanes::sqrt(sin_i * sin_o);
    let k = (one - rho) / (one + rho);
    // Δ = 2 atan(k tan x) without tan/atan: with t = k sin x / cos x, cos Δ = (1 − t²)/(1 + t²)
    // and sin Δ = 2t/(1 + t²); the denominator c² + k²s² > 0 for k > 0 (ρ ≤ r < 1).
    let (s, c) = lanes::sin_cos(L::c(std::f64::consts::PI) * (u2 - L::c(0.5)));
    let ks = k * s;
    let inv = one / (c * c + ks * ks);
    let (cos_d, sin_d) = ((c * c - ks * ks) * inv, L::c(2.0) * ks * c * inv);
    // wo's azimuth (any for wo along the normal, where ρ = 0 and the azimuth is uniform).
    let has_azimuth = lanes::gt(sin_o, L::c(1e-12));
    let inv_o = one / lanes::max(sin_o, L::c(1e-12));
    let (cos_o, sin_o_phi) = (lanes::select(has_azimuth, wo.x * inv_o, one), wo.y * inv_o);
    let sin_o_phi = lanes::select(has_azimuth, sin_o_phi, L::c(0.0));
    // φi = φo + π + Δ.
    let cos_i = -(cos_o * cos_d - sin_o_phi * sin_d);
    let sin_i_phi = -(sin_o_phi * cos_d + cos_o * sin_d);
    Vec3::new(sin_i * cos_i, sin_i * sin_i_phi, mu_i)
}

/// Density of [`ms_sample`]: `A(wi, wo) cos θi / π` above the surface, 0 below.
#[inline(always)]
#[must_use]
pub fn ms_pdf<L: Lanes>(wi: Vec3<L>, wo: Vec3<L>) -> L {
    cosine_hemisphere_pdf(wi.z) * ms_azimuthal(wi, wo)
}

/// The share `κ` of the single-scattering loss that the lossless rough interface reflects, for
/// cosine-distributed incidence: `κ(α) = 0.42 exp(−5.2 α) · α²/(α² + 0.02²)`, fitted to the multiple-scattering
/// walk ([`super::rough_dielectric::RoughDielectric::sample_multiple`]) at η 1.5 (400 000 walks
/// per direction: `κ` 0.25 at α 0.1, 0.148 at 0.2, 0.088 at 0.3; per direction it runs
/// 0.12–0.31, 0.10–0.16 and 0.05–0.09; 0.12–0.53 at α 0.03, 0.02–0.06 at 0.5). A smooth
/// function of α (estimating `κ` per coat with walks made the α-grid tables noisy in α); not
/// measured for other indices. Energy conservation and reciprocity hold for any `κ` in [0, 1].
/// The factor `α²/(α² + 0.02²)` (0.96 at α 0.1) fades the term out for nearly smooth coats:
/// there the loss `L(μ)` sits at the table's grazing node alone (α 0.001: `L` ≈ 0.02 at μ → 0,
/// ≈ 0 elsewhere), so the separable lobe's shape `ΔR(μ)/ΔR̄` would be a spike of 10⁴ with
/// negligible energy (a firefly in rendering rather than a correction).
#[must_use]
pub fn ms_reflected_share(alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    (0.42 * (-5.2 * alpha).exp() * a2 / (a2 + 0.02 * 0.02)).clamp(0.0, 1.0)
}

/// The share of the single-scattering loss that the lossless rough interface lets out for
/// light arriving from inside with cosine `mu_inside` (the rest it reflects back down):
/// `0.03 + 0.15 μ'²`, fitted to the multiple-scattering walk at η 1.5, α 0.1–0.3 (200 000
/// walks per direction, μ' 0.3–1: shares 0.04–0.18; test
/// `coat::tests::escape_from_inside_matches_the_lossless_walk`). **Not measured for other
/// indices.**
#[must_use]
pub fn inside_escape_share(mu_inside: f64) -> f64 {
    0.03 + 0.15 * mu_inside * mu_inside
}

impl Coat {
    /// Builds a coat; rough coats tabulate their reflection albedo.
    #[must_use]
    pub fn new(ior: f64, roughness: f64, thickness_um: f64, absorption_per_mm: [f64; 3]) -> Self {
        let mut coat = Self {
            ior,
            roughness,
            absorption_per_mm,
            thickness_mm: thickness_um * 1e-3,
            albedo: None,
            ms: None,
            crossing: None,
            factors: None,
            mean_refraction: None,
        };
        if !coat.is_smooth() && coat.has_interface() {
            let (albedo, loss) = coat.tabulate_albedo();
            let ms = coat.build_multiple_scattering(&loss);
            let top: Vec<(f64, f64)> =
                albedo.values().iter().zip(ms.albedo.values()).map(|(r, m)| (r[0], m[0])).collect();
            coat.albedo = Some(albedo);
            coat.ms = Some(ms);
            // `g` from `E_top` and `ΔR` (set above).
            let crossing = coat.tabulate_crossing();
            let factors = top.iter().zip(crossing.values()).map(|(&(r, m), g)| [r, m, g[0]]).collect();
            coat.factors = Some(MuTable::from_values(factors));
            coat.crossing = Some(crossing);
            coat.mean_refraction = Some(coat.tabulate_mean_refraction(MEAN_REFRACTION_SHARE));
        }
        coat
    }

    /// `sin θ'/sin θ` per outside cosine for [`Coat::mean_refract_in`]: the single-scattering
    /// GGX transmission's directions (visible normals seen from the outside direction,
    /// weighted by `1 − F`, 48 × 48 midpoint quadrature per node) averaged in the tangent
    /// plane, `s̄`, and `sin θ' = sin θ/η + share · (s̄ − sin θ/η)`. The ratio, not `sin θ'`
    /// itself, is tabulated: it is smooth at the normal (`1/η` there), where `sin θ'` has an
    /// infinite slope in `μ` that linear interpolation would bend.
    fn tabulate_mean_refraction(&self, share: f64) -> MuTable {
        let mf = Microfacet::<f64>::uniform(DistributionKind::Ggx, self.roughness, self.roughness);
        let n = 48;
        MuTable::build(ALBEDO_NODES, |mu| {
            let mu = mu.max(1e-4);
            let s = (1.0 - mu * mu).max(0.0).sqrt();
            if s < 1e-6 {
                return [1.0 / self.ior; 3];
            }
            let w = Vec3::new(s, 0.0, mu);
            let (mut sx, mut sw) = (0.0, 0.0);
            for i in 0..n {
                for j in 0..n {
                    let m = mf.sample_m(w, (i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64, true);
                    let c = w.dot(m);
                    let Some(t) = crate::frame::refract(w, m, self.ior).filter(|t| c > 0.0 && t.z < 0.0) else {
                        continue;
                    };
                    let weight = 1.0 - fresnel::dielectric(c, self.ior);
                    sx -= t.x * weight;
                    sw += weight;
                }
            }
            let macro_s = s / self.ior;
            let mean = if sw > 0.0 { (sx / sw).clamp(0.0, 0.999) } else { macro_s };
            [(macro_s + share * (mean - macro_s)).clamp(0.0, 0.999) / s; 3]
        })
    }

    /// The inside direction at which the metal base's first bounce sees light from (or sends
    /// it to) the outside direction `w` through a rough interface: the mean of the refracted
    /// directions rather than the refraction at the macro normal ([`Coat::refract_in`], which
    /// a smooth coat keeps). Light from grazing directions reaches the base mostly through
    /// facets tilted toward it, beyond the macro critical angle: at θ 75° the single-scattering
    /// transmission's mean is at 43° / 47° / 51° for α 0.1 / 0.2 / 0.3 against 40° at the
    /// macro normal (taken with the share [`MEAN_REFRACTION_SHARE`]). The same map for both
    /// directions keeps the lobe reciprocal; its energy: [`Coat::mean_refract_out`].
    #[inline(always)]
    #[must_use]
    pub fn mean_refract_in<T: Lanes>(&self, w: Vec3<T>) -> Vec3<T> {
        match &self.mean_refraction {
            None => self.refract_in(w),
            Some(t) => inside_with_ratio(w, t.eval_lanes(w.z)[0]),
        }
    }

    /// The inside direction at which the flakes' lobe sees light from (or sends it to) the
    /// outside direction `w` through a rough interface: the macro refraction moved by the share
    /// [`FLAKE_MEAN_REFRACTION_SHARE`] toward the mean refracted direction (as
    /// [`Coat::mean_refract_in`] with its own share); [`Coat::refract_in`] for a smooth coat.
    /// The same map for both directions keeps the lobe reciprocal.
    #[inline(always)]
    #[must_use]
    pub fn flake_refract_in<T: Lanes>(&self, w: Vec3<T>) -> Vec3<T> {
        match &self.mean_refraction {
            None => self.refract_in(w),
            Some(t) => inside_with_ratio(w, flake_ratio_from_mean(self.ior, t.eval_lanes(w.z)[0])),
        }
    }

    /// `sin θ'/sin θ` of [`Coat::mean_refract_in`] at the outside cosine `mu` (f64; None
    /// without the map): the per-element α grid's tables ([`super::varying`]).
    #[must_use]
    pub fn mean_refraction_ratio(&self, mu: f64) -> Option<f64> {
        self.mean_refraction.as_ref().map(|t| t.eval::<f64>(mu)[0])
    }

    /// True when the coat maps the metal's first bounce to the mean refracted directions
    /// (a rough coat with an interface).
    #[inline]
    #[must_use]
    pub fn has_mean_refraction(&self) -> bool {
        self.mean_refraction.is_some()
    }

    /// The outside cosine `μ` whose [`Coat::mean_refract_in`] direction has the inside cosine
    /// `mu_in` (None beyond the map's range: no outside direction, or a coat without the
    /// map), and `J = d sin²θ'/d sin²θ` there. Light that a first bounce sends along the
    /// inside direction leaves with the share `T(μ)/(η² J)` (`J = 1/η²` at the macro normal:
    /// `T`), so `A1(μo) = T(μo) ∫ f_m(u, w'_o) T(μ(u))/(η² J(μ(u))) cos θu dωu` for the lobe
    /// `T(μi) T(μo)/η² f_m(w'_i, w'_o)`; `J` grows toward grazing (the map's range there is
    /// wide), so the light sent beyond the macro critical angle mostly stays in.
    #[must_use]
    pub fn mean_refract_out(&self, mu_in: f64) -> Option<(f64, f64)> {
        let t = self.mean_refraction.as_ref()?;
        // `sin θ'(μ)` falls from its grazing value to 0 at the normal: bisection on μ, then
        // `J` by a central difference.
        let s_in = (1.0 - mu_in * mu_in).max(0.0).sqrt();
        let f = |mu: f64| t.eval::<f64>(mu)[0] * (1.0 - mu * mu).max(0.0).sqrt();
        if s_in > f(0.0) {
            return None;
        }
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(mid) > s_in {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let mu = 0.5 * (lo + hi);
        let h = 2e-3;
        let (a, b) = ((mu - h).max(0.0), (mu + h).min(1.0));
        let s2 = |m: f64| 1.0 - m * m;
        let j = (f(a).powi(2) - f(b).powi(2)) / (s2(a) - s2(b));
        Some((mu, j))
    }

    /// [`Coat::reflectance`], [`Coat::ms_albedo`] and [`Coat::crossing`] at `mu`, with one
    /// table lookup for a rough coat (the same table values, so the same results as the three
    /// calls).
    #[inline(always)]
    #[must_use]
    pub fn at<T: Lanes>(&self, mu: T) -> CoatAt<T> {
        match &self.factors {
            Some(t) => {
                let [reflectance, ms, crossing] = t.eval_lanes(mu);
                let entering = lanes::max(T::c(1.0) - reflectance - ms, T::c(0.0));
                CoatAt { reflectance, entering, ms, crossing }
            }
            None => {
                let entering = self.transmittance(mu);
                CoatAt { reflectance: self.reflectance(mu), entering, ms: T::c(0.0), crossing: entering }
            }
        }
    }

    /// True for a mirror-smooth top surface.
    #[inline]
    #[must_use]
    pub fn is_smooth(&self) -> bool {
        self.roughness == 0.0
    }

    /// False for `ior = 1`: no index step, so no top reflection. The Fresnel formula gives 0
    /// there only up to rounding (its `1 − sin²θt` cancels at grazing angles, leaving residues of
    /// 1e-16 relative that the rough lobe's `D G / (4 cos θi cos θo)` amplified to non-reciprocal
    /// values up to 1e-9 /sr; docs/numerics.md), so the coat answers exactly 0 instead.
    #[inline]
    #[must_use]
    pub fn has_interface(&self) -> bool {
        self.ior != 1.0
    }

    /// The blur the coat's rough transmission gives the base's specular lobes (None for a
    /// smooth coat or `ior = 1`, which do not blur).
    #[must_use]
    pub fn transmission_blur(&self) -> Option<TransmissionBlur> {
        (!self.is_smooth() && self.has_interface()).then_some(TransmissionBlur::new(self.ior, self.roughness))
    }

    /// True when the coat absorbs.
    #[inline]
    #[must_use]
    pub fn absorbs(&self) -> bool {
        self.thickness_mm > 0.0 && self.absorption_per_mm.iter().any(|&a| a > 0.0)
    }

    #[inline(always)]
    fn microfacet<T: Lanes>(&self) -> Microfacet<T> {
        Microfacet::uniform(DistributionKind::Ggx, self.roughness, self.roughness)
    }

    /// Energy the top surface reflects for incidence `μ`: `F(μ)` (smooth) or `E_top(μ)`.
    #[inline(always)]
    #[must_use]
    pub fn reflectance<T: Lanes>(&self, mu: T) -> T {
        match &self.albedo {
            _ if !self.has_interface() => T::c(0.0),
            None => fresnel::dielectric(mu, T::c(self.ior)),
            Some(t) => t.eval_lanes(mu)[0],
        }
    }

    /// `ΔR(μ)`: energy the interface's multiple scattering reflects for incidence `μ` (0 for
    /// a smooth coat; [`MultipleScattering`]).
    #[inline(always)]
    #[must_use]
    pub fn ms_albedo<T: Lanes>(&self, mu: T) -> T {
        match &self.ms {
            Some(m) => m.albedo.eval_lanes(mu)[0],
            None => T::c(0.0),
        }
    }

    /// The multiple-scattering reflection of the rough coat, if any.
    #[must_use]
    pub fn multiple_scattering(&self) -> Option<&MultipleScattering> {
        self.ms.as_ref()
    }

    /// The multiple-scattering reflection lobe `ΔR(μi) ΔR(μo) A(wi, wo) / (π ΔR̄)` (0 for a
    /// smooth coat; `A` the azimuthal factor [`ms_azimuthal`]).
    #[inline(always)]
    #[must_use]
    pub fn ms_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        match &self.ms {
            Some(m) => self.ms_lobe(m.albedo.eval_lanes(wi.z)[0], m.albedo.eval_lanes(wo.z)[0], ms_azimuthal(wi, wo)),
            None => T::c(0.0),
        }
    }

    /// [`Coat::ms_eval`] from its factors `ΔR(μi)`, `ΔR(μo)` and `A(wi, wo)` (0 for a smooth coat).
    #[inline(always)]
    #[must_use]
    pub fn ms_lobe<T: Lanes>(&self, ms_i: T, ms_o: T, azimuthal: T) -> T {
        match &self.ms {
            Some(m) => ms_i * ms_o * T::c(m.norm) * azimuthal,
            None => T::c(0.0),
        }
    }

    /// The whole top reflection: the single-scattering lobe [`Coat::reflection_eval`] plus the
    /// multiple-scattering lobe [`Coat::ms_eval`].
    #[inline(always)]
    #[must_use]
    pub fn top_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        if self.ms.is_none() {
            return self.reflection_eval(wi, wo);
        }
        self.reflection_eval(wi, wo) + self.ms_eval(wi, wo)
    }

    /// Energy that enters the coat from direction `μ`: `1 − reflectance − ΔR` (the
    /// multiple-scattering reflection [`Coat::ms_albedo`] is 0 for a smooth coat).
    #[inline(always)]
    #[must_use]
    pub fn transmittance<T: Lanes>(&self, mu: T) -> T {
        if self.albedo.is_none() {
            // A smooth interface: `1 − F` without its cancellation at grazing incidence.
            return if self.has_interface() {
                fresnel::dielectric_transmittance(mu, T::c(self.ior))
            } else {
                T::c(1.0)
            };
        }
        if self.ms.is_none() {
            return lanes::max(T::c(1.0) - self.reflectance(mu), T::c(0.0));
        }
        lanes::max(T::c(1.0) - self.reflectance(mu) - self.ms_albedo(mu), T::c(0.0))
    }

    /// The factor `g(μ)` of each crossing of the light that enters the coat from outside
    /// direction `μ`, meets the flakes once and leaves (the single-scatter layer term, with
    /// `g(μi) g(μo)`; the diffuse pigment keeps `T(μi) T(μo)`: its light spreads over the
    /// whole inside hemisphere, where the cosine-weighted escape through any interface is
    /// `T`'s, by reciprocity; so does the metal base, see docs/paint-validation.md §8). A smooth coat's is [`Coat::transmittance`] `T(μ)`: in and out by the
    /// same Fresnel factor. A rough interface lets less out from inside than it lets in near
    /// the normal — its facets tilted beyond the critical angle reflect the light back down —
    /// so the light that crosses twice is `T(μi) T_out(μo')` (`T_out` the interface's
    /// transmittance from inside at the refracted `μo'`, [`Coat::escape_from_inside`]).
    /// Reciprocity asks for a symmetric product: `g(μ) = min(√(T(μ) T_out(μ')), T(μ))`, exact
    /// when both directions are the same, and never above `T(μ)`, so the layer term's albedo
    /// stays below the energy that entered (what it does not let out goes to the multiple-scatter
    /// lobe through the layer tables). Tabulated on the albedo table's nodes.
    #[inline(always)]
    #[must_use]
    pub fn crossing<T: Lanes>(&self, mu: T) -> T {
        match &self.crossing {
            Some(t) => t.eval_lanes(mu)[0],
            None => self.transmittance(mu),
        }
    }

    /// True when [`Coat::crossing`] differs from [`Coat::transmittance`] (a rough coat).
    #[inline(always)]
    #[must_use]
    pub fn has_crossing(&self) -> bool {
        self.crossing.is_some()
    }

    /// The crossing factor [`Coat::crossing`] of the light that leaves along inside direction
    /// `w` (pointing up), 0 under total internal reflection.
    #[must_use]
    pub fn escape(&self, w: Vec3<f64>) -> f64 {
        self.refract_out(w).map_or(0.0, |o| self.crossing(o.z))
    }

    /// `T_out(μ')`: the energy the lossless rough interface lets out for light arriving from
    /// inside with cosine `mu_inside`: Walter's single-scattering transmission (the estimator
    /// of [`Coat::tabulate_albedo`] with the relative index `1/η`) plus the share
    /// [`inside_escape_share`] of the single-scattering loss that the multiple-scattering walk
    /// lets out.
    #[must_use]
    pub fn escape_from_inside(&self, mu_inside: f64) -> f64 {
        if self.is_smooth() || !self.has_interface() {
            let w = Vec3::new((1.0 - mu_inside * mu_inside).max(0.0).sqrt(), 0.0, mu_inside);
            return self.refract_out(w).map_or(0.0, |o| self.transmittance(o.z));
        }
        let (r, t) = self.single_scattering_albedos(mu_inside, 1.0 / self.ior);
        t + inside_escape_share(mu_inside) * (1.0 - r - t).max(0.0)
    }

    /// [`Coat::escape_from_inside`] tabulated over the inside cosine `μ'` ∈ [0, 1] (64 nodes,
    /// linear in between; for a smooth coat the macro-normal refraction's `T`, which has a kink
    /// at the critical angle that the table rounds off between two nodes).
    #[must_use]
    pub fn inside_escape_table(&self) -> MuTable {
        MuTable::build(ALBEDO_NODES, |mu_inside| [self.escape_from_inside(mu_inside); 3])
    }

    /// The rough top reflection `F(wo·h) D(h) G(wi, wo) / (4 cos θi cos θo)` (0 when smooth).
    #[inline(always)]
    #[must_use]
    pub fn reflection_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.reflection_eval_h(&HalfPair::new(wi, wo))
    }

    /// [`Coat::reflection_eval`] of a pair whose half vector is known.
    #[inline(always)]
    #[must_use]
    pub fn reflection_eval_h<T: Lanes>(&self, pair: &HalfPair<T>) -> T {
        self.reflection_eval_pdf_h(pair).0
    }

    /// Density of [`Coat::reflection_sample`] (visible-normal sampling).
    #[inline(always)]
    #[must_use]
    pub fn reflection_pdf<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.reflection_pdf_h(&HalfPair::new(wi, wo))
    }

    /// [`Coat::reflection_pdf`] of a pair whose half vector is known.
    #[inline(always)]
    #[must_use]
    pub fn reflection_pdf_h<T: Lanes>(&self, pair: &HalfPair<T>) -> T {
        self.reflection_eval_pdf_h(pair).1
    }

    /// [`Coat::reflection_eval_h`] and [`Coat::reflection_pdf_h`] together: they share the
    /// distribution's value and the masking root of `wo` ([`Microfacet::reflection_dg_pdf`]).
    #[inline(always)]
    #[must_use]
    pub fn reflection_eval_pdf_h<T: Lanes>(&self, pair: &HalfPair<T>) -> (T, T) {
        if self.is_smooth() {
            return (T::c(0.0), T::c(0.0));
        }
        let HalfPair { wi, wo, h, defined } = *pair;
        let (dg, g_positive, pdf) = self.microfacet::<T>().reflection_dg_pdf(wi, wo, h, MaskingKind::HeightCorrelated);
        let value = if self.has_interface() {
            keep(defined & g_positive, fresnel::dielectric(wo.dot(h), T::c(self.ior)) * dg)
        } else {
            T::c(0.0)
        };
        (value, keep(defined, pdf))
    }

    /// Samples the top reflection: the mirror direction when smooth, else a GGX visible normal.
    #[inline(always)]
    #[must_use]
    pub fn reflection_sample<T: Lanes>(&self, wo: Vec3<T>, u1: T, u2: T) -> Vec3<T> {
        if self.is_smooth() {
            return crate::frame::mirror_z(wo);
        }
        let h = self.microfacet::<T>().sample_m(wo, u1, u2, true);
        crate::frame::reflect(wo, h)
    }

    /// Direction inside the coat (pointing up, away from the base) of light that crossed the
    /// top surface along outside direction `w`.
    #[inline(always)]
    #[must_use]
    pub fn refract_in<T: Lanes>(&self, w: Vec3<T>) -> Vec3<T> {
        let eta = T::c(self.ior);
        // cos²θ' = (η² − 1 + cos²θ)/η², written from z so it stays exact at η = 1 and grazing.
        let tiny = T::splat(<T::Elem as num_traits::Float>::min_positive_value());
        // 1/η taken once in f64: the lanes multiply instead of dividing.
        let inv_eta = T::c(1.0 / self.ior);
        let z = lanes::max(lanes::sqrt_fast(lanes::max(eta * eta - T::c(1.0) + w.z * w.z, T::c(0.0))) * inv_eta, tiny);
        Vec3::new(w.x * inv_eta, w.y * inv_eta, z)
    }

    /// Outside direction of light leaving the coat along inside direction `w`, or `None` under
    /// total internal reflection.
    #[inline]
    #[must_use]
    pub fn refract_out<T: Real>(&self, w: Vec3<T>) -> Option<Vec3<T>> {
        let (v, ok) = self.refract_out_masked(w);
        ok.then_some(v)
    }

    /// [`Coat::refract_out`] per lane: the direction and where it exists (no total internal
    /// reflection; elsewhere the direction's z is 0).
    #[inline(always)]
    #[must_use]
    pub fn refract_out_masked<T: Lanes>(&self, w: Vec3<T>) -> (Vec3<T>, T::Mask) {
        let eta = T::c(self.ior);
        // cos²θ = 1 − η²(1 − cos²θ') = 1 − η² sin²θ'.
        let c2 = T::c(1.0) - eta * eta * (T::c(1.0) - w.z * w.z);
        (Vec3::new(w.x * eta, w.y * eta, lanes::safe_sqrt(c2)), lanes::gt(c2, T::c(0.0)))
    }

    /// `dω_inside / dω_outside = cos θ / (η² cos θ')` for an outside direction with cosine
    /// `mu_out` and its refracted inside cosine `mu_in`.
    #[inline(always)]
    #[must_use]
    pub fn solid_angle_ratio<T: Lanes>(&self, mu_out: T, mu_in: T) -> T {
        lanes::div_fast(mu_out, T::c(self.ior * self.ior) * mu_in)
    }

    /// Beer-Lambert transmittance of one crossing along an inside direction with cosine `mu_in`.
    #[inline(always)]
    #[must_use]
    pub fn attenuation<T: Lanes>(&self, mu_in: T) -> [T; 3] {
        if !self.absorbs() {
            return [T::c(1.0); 3];
        }
        let path = T::c(self.thickness_mm) / lanes::max(mu_in, T::c(1e-6));
        let [a, b, c] = self.absorption_per_mm;
        [lanes::exp(-(T::c(a) * path)), lanes::exp(-(T::c(b) * path)), lanes::exp(-(T::c(c) * path))]
    }

    /// Walter's single-scattering reflection and transmission albedos `(E_r, E_t)` of the
    /// interface for light arriving with cosine `mu` on a side where the relative index
    /// (far side / this side) is `eta`, by stratified visible-normal samples: `E_r` with the
    /// estimator `F(wo·h) G2/G1(wo)` (low variance, no bias), `E_t` the transmission's albedo
    /// with `G2 = 1/(1 + Λo + Λt)` (estimator `(1 − F)(1 + Λo)/(1 + Λo + Λt)`).
    fn single_scattering_albedos(&self, mu: f64, eta: f64) -> (f64, f64) {
        let mf = self.microfacet::<f64>();
        let mu = mu.max(1e-4);
        let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let n = ALBEDO_SAMPLES;
        let lo = mf.lambda(wo);
        let (mut sum, mut through) = (0.0, 0.0);
        for k in 0..n {
            let [_, u1, u2] = crate::paint::hammersley3(k, n);
            let h = mf.sample_m(wo, u1, u2, true);
            let f = fresnel::dielectric(wo.dot(h), eta);
            if let Some(t) = crate::frame::refract(wo, h, eta) {
                if t.z < 0.0 {
                    let lt = mf.lambda(Vec3::new(t.x, t.y, -t.z));
                    through += (1.0 - f) * (1.0 + lo) / (1.0 + lo + lt);
                }
            }
            let wi = crate::frame::reflect(wo, h);
            if wi.z <= 0.0 {
                continue;
            }
            let g1 = mf.g1(wo, h);
            if g1 > 0.0 {
                sum += f * mf.g(wi, wo, h, MaskingKind::HeightCorrelated) / g1;
            }
        }
        (sum / n as f64, through / n as f64)
    }

    /// Tabulates `E_top(μ) = ∫ F D G / (4 cos θo) dωi` and with the same samples the
    /// single-scattering loss `L(μ) = 1 − E_r(μ) − E_t(μ)`
    /// ([`Coat::single_scattering_albedos`] from outside).
    fn tabulate_albedo(&self) -> (MuTable, MuTable) {
        let mut loss = Vec::with_capacity(ALBEDO_NODES);
        let albedo = MuTable::build(ALBEDO_NODES, |mu| {
            let (r, t) = self.single_scattering_albedos(mu, self.ior);
            loss.push([(1.0 - r - t).max(0.0); 3]);
            [r; 3]
        });
        (albedo, MuTable::from_values(loss))
    }

    /// Tabulates [`Coat::crossing`] on the albedo table's nodes (after `E_top` and `ΔR`).
    fn tabulate_crossing(&self) -> MuTable {
        MuTable::build(ALBEDO_NODES, |mu| {
            let t_in = self.transmittance(mu);
            let mu_inside = self.refract_in(Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)).z;
            let t_out = self.escape_from_inside(mu_inside);
            [(t_in * t_out).sqrt().min(t_in); 3]
        })
    }

    /// The multiple-scattering reflection for the single-scattering loss `loss` (`L(μ)`):
    /// `ΔR = κ L` with `κ` = [`ms_reflected_share`] of the coat's α.
    fn build_multiple_scattering(&self, loss: &MuTable) -> MultipleScattering {
        let kappa = ms_reflected_share(self.roughness);
        let albedo = MuTable::from_values(loss.values().iter().map(|l| [kappa * l[0]; 3]).collect());
        let avg = albedo.cosine_average()[0];
        let norm = if avg > 1e-12 { 1.0 / (std::f64::consts::PI * avg) } else { 0.0 };
        MultipleScattering { albedo, norm, kappa }
    }
}
