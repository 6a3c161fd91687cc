//! Kulla-Conty multiple-scattering energy compensation for microfacet reflection.
//!
//! A single-scattering microfacet BRDF loses the energy of light that bounces more than once
//! between microfacets: even with `F = 1` its directional albedo
//! `E(wo) = ∫ f_ss(wi, wo) cos θi dωi` is below one, increasingly so for rough surfaces.
//! Kulla & Conty (2017) add a lobe
//!
//! ```text
//! f_ms(wi, wo) = (1 − E(wi)) (1 − E(wo)) / (π (1 − E_avg)),   E_avg = (1/π) ∫ E(w) cos θ dω
//! ```
//!
//! whose albedo is exactly `1 − E(wo)`, so `f_ss + f_ms` has albedo 1 with `F = 1`; it is
//! symmetric in `wi, wo` (reciprocal). With a Fresnel term the lobe is scaled by the colour
//!
//! ```text
//! F_ms = F_avg² E_avg / (1 − F_avg (1 − E_avg)),   F_avg = 2 ∫₀¹ F(μ) μ dμ
//! ```
//!
//! (the sum of the geometric series of further bounces, each losing `F_avg`), which keeps the
//! total albedo at most one because `F_ms ≤ 1` whenever `F_avg ≤ 1`.
//!
//! ## The table
//! [`AlbedoTable`] holds `1 − E` for one distribution, roughness and masking, computed by the
//! library itself at construction (no baked data):
//! - 48 nodes in `cos θo`, uniform in `ln(1 + μ/ε)` with `ε = α_min/2` (dense near grazing,
//!   where `E` changes on the scale `μ ~ α`); for anisotropic roughness, 17 azimuths on
//!   `[0, π/2]` uniform in `ln(α(φ) + c)` (`α(φ)` the projected roughness, `c` a hundredth
//!   of the larger `α`: `E` depends on the azimuth mostly through `α(φ)`, which changes fast
//!   near the smooth axis of a strongly anisotropic surface). `E` has the symmetries
//!   `φ → −φ`, `φ → π − φ` of the distribution;
//! - at each node `E(wo)` is computed by [`directional_albedo`]: a Gauss-Legendre product rule
//!   over the microfacet slopes, split along every kink of the integrand, which is known in
//!   closed form (accurate to ~3e-5, isotropic V-groove ~2e-4; checked in the tests against an
//!   adaptive reference and a product rule over the visible-normal sampler's unit square);
//! - lookups interpolate `1 − E` with a monotone cubic in `μ` (it never leaves the range of
//!   the nodes, so `1 − E` stays in `[0, 1]`) and linearly in the azimuth coordinate;
//!   `1 − E_avg` is the integral of that interpolant (Gauss-Legendre per cell, ~1e-10), so the
//!   albedo of `f_ms` is `1 − E_table(wo)` and the furnace error of `f_ss + f_ms` is only the
//!   interpolation error of `E`: below 5e-4 isotropic, about 1e-3 between azimuth rows for
//!   anisotropy ratios up to 1000 (tests).
//!
//! Storing `1 − E` rather than `E` keeps the f32 path free of cancellation when `E ≈ 1`.
//!
//! Cost (release build, measured on the shared development machine): an isotropic table
//! takes 3–7 ms (V-groove masking 5–20 ms), an anisotropic one 250–300 ms (17 rows, and more
//! breakpoints per node); the rule needs no visible-normal sampling (which for Beckmann
//! inverts a CDF numerically). Tables are cached by their exact parameters
//! ([`AlbedoTable::cached`]), so materials sharing a roughness share one table.
//!
//! ## Fresnel-weighted tables
//! [`AlbedoTable::weighted`] (and its cached form [`AlbedoTable::cached_weighted`]) tabulate,
//! on the same nodes and with the same interpolation, `1 − E_w(wo)` for the single-scattering
//! albedo `E_w(wo) = ∫ w(wo·m) G(wi, wo, m)/G1(wo, m) D_wo(m) dm` weighted by a Fresnel-like
//! function `w(cos) ∈ [0, 1]` of the angle on the microfacet ([`directional_albedo_weighted`]):
//! the exact directional albedo of a microfacet lobe with that Fresnel curve, as layered models
//! (the `principled` model's albedo-scaled layers) need it.
//!
//! ## Integrals over visible normals
//! [`visible_normal_integral`] is the general rule behind [`directional_albedo`]: any
//! `∫ D_w(m) f(m) dm` over all visible normals or over those whose mirror stays above the
//! horizon, with kinks given as conics in slope space ([`SlopeConic`]: the mirror's horizon,
//! the critical angle of total internal reflection) or located numerically. `rough_plastic`
//! uses it for the transmittance and internal reflectance of its rough interface.
//!
//! Reference: C. Kulla and A. Conty, "Revisiting Physically Based Shading at Imageworks",
//! SIGGRAPH 2017 course *Physically Based Shading in Theory and Practice*.

use crate::frame::reflect;
use crate::lanes::{self, Lanes};
use crate::math::Vec3;
use crate::microfacet::{DistributionKind, MaskingKind, Microfacet};
use crate::quadrature::gauss_legendre;
use crate::real::Real;
use std::sync::{Arc, Mutex, OnceLock};

/// Number of nodes in `cos θ`.
const N_MU: usize = 48;
/// Number of azimuth nodes on `[0, π/2]` for anisotropic roughness.
const N_PHI_ANISO: usize = 17;
/// Gauss-Legendre orders per piece of the albedo integral (outer `t₁`, inner `t₂`).
const OUTER_ORDER: usize = 16;
const INNER_ORDER: usize = 24;
/// `μ` used for the node at `μ = 0` (the grazing limit).
const MU_MIN: f64 = 1e-6;

/// `1 − E(wo)` tabulated over `(cos θo, φo)` for one microfacet configuration, with its
/// cosine-weighted hemispherical average.
#[derive(Clone, Debug)]
pub struct AlbedoTable {
    kind: DistributionKind,
    masking: MaskingKind,
    alpha_x: f64,
    alpha_y: f64,
    /// Per azimuth row, the scale of the node spacing near grazing:
    /// `s = ln(1 + μ/ε) / ln(1 + 1/ε)`.
    eps: Vec<f64>,
    /// Per azimuth row, `1 / ln(1 + 1/ε)`.
    inv_log_span: Vec<f64>,
    n_phi: usize,
    /// `1 − E` at node `(k, j)` stored at `k·N_MU + j` (`k` azimuth, `j` in `s`).
    loss: Vec<f64>,
    /// Monotone-cubic (Fritsch-Carlson) slopes `d(1 − E)/ds` at the nodes, same layout.
    slope: Vec<f64>,
    /// Row 0 of `loss` and `slope` rounded to f32 and padded for [`Lanes::lookup_f32_`] (the
    /// isotropic lane lookups of [`AlbedoTable::loss_at_lanes`]).
    lane_loss: Vec<f32>,
    /// See `lane_loss`.
    lane_slope: Vec<f32>,
    /// Row 0's f32 `loss` and `slope` at node `j` and `j + 1` as the rows of
    /// [`Lanes::lookup_rows3_f32_`] (SIMD lanes without register lookups: AVX2).
    lane_rows: Vec<[f32; 8]>,
    /// `1 − E_avg`, the integral of the interpolated table.
    loss_avg: f64,
    /// The Fresnel-like weight of a shared weighted table ([`AlbedoTable::cached_weighted`]);
    /// `None` for the plain table and for uncached weighted tables.
    weight: Option<WeightKey>,
}

/// One request of [`AlbedoTable::cached_set`]: the key of a weight (`None`: the plain table)
/// and the weight function.
pub type TableRequest<'a> = (Option<WeightKey>, &'a dyn Fn(f64) -> f64);

/// Names a weight function `w(cos)` of [`AlbedoTable::cached_weighted`] so that tables of the
/// same function are shared: a label chosen by the caller and up to four parameters (compared
/// bit for bit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WeightKey {
    /// What the function is (e.g. `"dielectric"`), unique per formula.
    pub name: &'static str,
    /// Its parameters as `f64::to_bits` (e.g. the index of refraction), unused ones 0.
    pub params: [u64; 4],
}

impl WeightKey {
    /// A key for `name` with up to four real parameters (further ones are ignored).
    #[must_use]
    pub fn new(name: &'static str, params: &[f64]) -> Self {
        let mut bits = [0u64; 4];
        for (b, p) in bits.iter_mut().zip(params) {
            *b = p.to_bits();
        }
        Self { name, params: bits }
    }
}

/// Directional albedo `E(wo)` of the single-scattering microfacet BRDF with `F = 1`,
/// `D G / (4 cos θi cos θo)`: the visible-normal integral of `G(wi, wo, m)/G1(wo, m)` over the
/// normals whose mirror `wi` lies above the horizon ([`visible_normal_integral`]).
#[must_use]
pub fn directional_albedo(mf: &Microfacet<f64>, masking: MaskingKind, wo: Vec3<f64>) -> f64 {
    directional_albedo_weighted(mf, masking, wo, &|_| 1.0)
}

/// Directional albedo of the single-scattering microfacet BRDF with the Fresnel-like factor
/// `weight(wo·m)`, `w D G / (4 cos θi cos θo)`: [`directional_albedo`] with the integrand
/// multiplied by `weight` (a smooth function of the angle on the microfacet for the rule to stay
/// accurate; kinks of `weight` are not resolved).
#[must_use]
pub fn directional_albedo_weighted(
    mf: &Microfacet<f64>,
    masking: MaskingKind,
    wo: Vec3<f64>,
    weight: &dyn Fn(f64) -> f64,
) -> f64 {
    directional_albedo_weights(mf, masking, wo, [weight])[0]
}

/// [`directional_albedo_weighted`] for several weights at once, over the same quadrature
/// nodes: about the cost of one (the geometry — normals, masking — is shared).
#[must_use]
pub fn directional_albedo_weights<const N: usize>(
    mf: &Microfacet<f64>,
    masking: MaskingKind,
    wo: Vec3<f64>,
    weights: [&dyn Fn(f64) -> f64; N],
) -> [f64; N] {
    let mut conics = Vec::new();
    let vgroove = masking == MaskingKind::VGroove;
    if vgroove {
        // 2 (n·m)(n·wo) = wo·m is the line s·wo_xy = −cos θo in slope space.
        conics.push(SlopeConic { m: [[0.0; 2]; 2], b: [0.5 * wo.x, 0.5 * wo.y], c: wo.z, singular: false });
    }
    // The other V-groove branch switch, 2 (n·m)(n·wi) = wo·m, is not a conic: located
    // numerically along each line.
    let kink = |m: Vec3<f64>| {
        let wi = reflect(wo, m);
        2.0 * m.z * wi.z - wo.dot(m)
    };
    visible_normal_integral(
        mf,
        wo,
        NormalDomain::MirrorAboveHorizon,
        &conics,
        if vgroove { Some(&kink) } else { None },
        |m| {
            let wi = reflect(wo, m);
            let g1o = mf.g1(wo, m);
            if wi.z > 0.0 && g1o > 0.0 {
                let g = mf.g(wi, wo, m, masking) / g1o;
                let cos = wo.dot(m).clamp(0.0, 1.0);
                weights.map(|w| g * w(cos))
            } else {
                [0.0; N]
            }
        },
    )
}

/// A conic `sᵀ M s + 2 b·s + c = 0` in microfacet-slope space (the normal
/// `m ∝ (−s_x, −s_y, 1)`), along which an integrand over normals has a kink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlopeConic {
    /// The quadratic form `M` (symmetric).
    pub m: [[f64; 2]; 2],
    /// The linear term `b`.
    pub b: [f64; 2],
    /// The constant `c`.
    pub c: f64,
    /// Whether the integrand behaves like a square root across the conic (e.g. the Fresnel
    /// term at the critical angle), which the rule then resolves by a change of variable.
    pub singular: bool,
}

impl SlopeConic {
    /// Where the mirror of `w` about `m` reaches the horizon: `|s|² + 2 s·w_xy/w_z − 1 = 0`
    /// (the mirror is above the horizon inside this ellipse).
    #[must_use]
    pub fn mirror_horizon(w: Vec3<f64>) -> Self {
        Self { m: [[1.0, 0.0], [0.0, 1.0]], b: [w.x / w.z, w.y / w.z], c: -1.0, singular: false }
    }

    /// Where `w·m = cos`: `(w_z − s·w_xy)² = cos² (1 + |s|²)`; marked singular, as meant for
    /// the critical angle of total internal reflection, where the Fresnel term has a
    /// square-root edge.
    #[must_use]
    pub fn critical_angle(w: Vec3<f64>, cos: f64) -> Self {
        let c2 = cos * cos;
        Self {
            m: [[w.x * w.x - c2, w.x * w.y], [w.x * w.y, w.y * w.y - c2]],
            b: [-w.z * w.x, -w.z * w.y],
            c: w.z * w.z - c2,
            singular: true,
        }
    }
}

/// The normals an integral runs over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalDomain {
    /// Every visible normal.
    All,
    /// The visible normals whose mirror of `w` lies above the horizon (reflection).
    MirrorAboveHorizon,
}

/// The conic in the rotated stretched slope coordinates `t` (`s = L t`) of one integral:
/// `N₁₁ t₁² + 2 N₁₂ t₁ t₂ + N₂₂ t₂² + 2 q₁ t₁ + 2 q₂ t₂ + c = 0`.
#[derive(Clone, Copy, Debug)]
struct TConic {
    n: [[f64; 2]; 2],
    q: [f64; 2],
    c: f64,
    singular: bool,
}

impl TConic {
    fn new(k: &SlopeConic, l: [[f64; 2]; 2]) -> Self {
        // N = Lᵀ M L, q = Lᵀ b.
        let ml = |i: usize, j: usize| k.m[i][0] * l[0][j] + k.m[i][1] * l[1][j];
        let n = [
            [l[0][0] * ml(0, 0) + l[1][0] * ml(1, 0), l[0][0] * ml(0, 1) + l[1][0] * ml(1, 1)],
            [l[0][1] * ml(0, 0) + l[1][1] * ml(1, 0), l[0][1] * ml(0, 1) + l[1][1] * ml(1, 1)],
        ];
        let q = [l[0][0] * k.b[0] + l[1][0] * k.b[1], l[0][1] * k.b[0] + l[1][1] * k.b[1]];
        Self { n, q, c: k.c, singular: k.singular }
    }

    /// Is this conic a line of constant `t₁` (a straight line, `M = 0`, orthogonal to `t₂`)?
    fn is_t1_line(&self) -> bool {
        self.n == [[0.0; 2]; 2] && self.q[1].abs() <= 1e-12 * self.q[0].abs()
    }

    /// Roots in `t₂` along the line of constant `t₁`, sorted.
    fn line_roots(&self, t1: f64) -> Vec<f64> {
        if self.is_t1_line() {
            return Vec::new();
        }
        let a = self.n[1][1];
        let b = 2.0 * (self.n[0][1] * t1 + self.q[1]);
        let c = self.n[0][0] * t1 * t1 + 2.0 * self.q[0] * t1 + self.c;
        quadratic_roots(a, b, c)
    }

    /// The `t₁` where lines of constant `t₁` touch the conic (its extent in `t₁`); for a
    /// line of constant `t₁`, that line.
    fn extent(&self) -> Vec<f64> {
        if self.is_t1_line() {
            return quadratic_roots(self.n[0][0], 2.0 * self.q[0], self.c);
        }
        let (n, q) = (self.n, self.q);
        quadratic_roots(
            n[0][1] * n[0][1] - n[0][0] * n[1][1],
            2.0 * (n[0][1] * q[1] - n[1][1] * q[0]),
            q[1] * q[1] - n[1][1] * self.c,
        )
    }

    /// The `t₁` where the conic meets the line `t₂ = const`.
    fn crossings(&self, t2: f64) -> Vec<f64> {
        quadratic_roots(
            self.n[0][0],
            2.0 * (self.n[0][1] * t2 + self.q[0]),
            self.n[1][1] * t2 * t2 + 2.0 * self.q[1] * t2 + self.c,
        )
    }
}

/// Real roots of `a x² + b x + c = 0` (a linear equation when `a = 0`), sorted.
fn quadratic_roots(a: f64, b: f64, c: f64) -> Vec<f64> {
    let scale = a.abs().max(b.abs()).max(c.abs());
    if !(scale > 0.0) || !scale.is_finite() {
        return Vec::new();
    }
    if a.abs() <= 1e-14 * scale {
        return if b != 0.0 { vec![-c / b] } else { Vec::new() };
    }
    let disc = b * b - 4.0 * a * c;
    if !(disc >= 0.0) {
        return Vec::new();
    }
    let q = -0.5 * (b + disc.sqrt().copysign(b));
    let mut r = if q != 0.0 { vec![q / a, c / q] } else { vec![0.0] };
    r.retain(|x| x.is_finite());
    r.sort_by(f64::total_cmp);
    r
}

/// Where the slope density carries no mass: a "far" bound for unbounded ranges.
const FAR: f64 = 1e8;

/// A value an integral over normals accumulates: a number, or several integrals over the same
/// nodes at once (an array) — hardly dearer than one, since the geometry (normals, masking)
/// is shared.
pub trait Integrand: Copy {
    /// The additive identity.
    fn zero() -> Self;
    /// Sum.
    #[must_use]
    fn add(self, o: Self) -> Self;
    /// Product with a number.
    #[must_use]
    fn scale(self, s: f64) -> Self;
}

impl Integrand for f64 {
    #[inline]
    fn zero() -> Self {
        0.0
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn scale(self, s: f64) -> Self {
        self * s
    }
}

impl<const N: usize> Integrand for [f64; N] {
    #[inline]
    fn zero() -> Self {
        [0.0; N]
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        std::array::from_fn(|i| self[i] + o[i])
    }
    #[inline]
    fn scale(self, s: f64) -> Self {
        self.map(|v| v * s)
    }
}

/// `∫ D_w(m) f(m) dm` over the visible normals of `w` (`D_w = G1(w, m) max(0, w·m) D(m)/cos θw`,
/// Heitz & d'Eon 2014), restricted to `domain`, by a product Gauss-Legendre rule split along
/// every kink of the integrand.
///
/// Written over the stretched microfacet slopes `t` (isotropic density `P(t)`: `e^{−|t|²}/π`
/// for Beckmann, `1/(π(1 + |t|²)²)` for GGX), with `t₁` along the stretched projection of `w`
/// (length `ρ`), the integral is
///
/// ```text
/// ∫ P(t) max(0, 1 − t₁ ρ / cos θw) G1(w, m) f(m) dt
/// ```
///
/// The back-facing cut is the line `t₁ = cos θw / ρ`. The kinks the caller knows are conics in
/// slope space (`conics`: the mirror's horizon, the critical angle of total internal
/// reflection, ...), met by each line of constant `t₁` at roots solved in closed form; the
/// outer rule breaks where a conic is tangent to those lines and, for anisotropic roughness,
/// where conics cross the peak of the density (a tilted conic's chord ends sweep across it
/// quickly). `numeric_kink`, if given, marks further kinks by its sign changes, located by a
/// scan and bisection along each line. The rule is graded toward the ends of the outer range
/// (masking drops to zero in a thin layer near the horizon). Slopes are mapped by
/// `t = σ v/(1 − v²)` so the rule sees GGX's heavy tails; Beckmann is cut at |t| = 6.5.
/// Accuracy: ~3e-5 absolute for the albedo integrals of the tests.
#[must_use]
pub fn visible_normal_integral<I: Integrand>(
    mf: &Microfacet<f64>,
    w: Vec3<f64>,
    domain: NormalDomain,
    conics: &[SlopeConic],
    numeric_kink: Option<&dyn Fn(Vec3<f64>) -> f64>,
    f: impl Fn(Vec3<f64>) -> I,
) -> I {
    let (xo, wo_gl) = gauss_legendre(OUTER_ORDER);
    let (xi, wi_gl) = gauss_legendre(INNER_ORDER);
    let (ax, ay) = (mf.alpha_x, mf.alpha_y);
    let (vx, vy) = (ax * w.x, ay * w.y);
    let rho = (vx * vx + vy * vy).sqrt();
    let (e1x, e1y) = if rho > 0.0 { (vx / rho, vy / rho) } else { (1.0, 0.0) };
    let cz = w.z;
    // s = L t: t₁ along e1, t₂ along e1 turned by 90°, then stretched by (α_x, α_y).
    let l = [[ax * e1x, -ax * e1y], [ay * e1y, ay * e1x]];
    let normal = |t1: f64, t2: f64| {
        let tx = t1 * e1x - t2 * e1y;
        let ty = t1 * e1y + t2 * e1x;
        Vec3::new(-ax * tx, -ay * ty, 1.0).normalize()
    };
    let horizon = TConic::new(&SlopeConic::mirror_horizon(w), l);
    let extra: Vec<TConic> = conics.iter().map(|k| TConic::new(k, l)).collect();
    // Outer range in t₁.
    let facing_cut = if rho > 0.0 { cz / rho } else { FAR };
    let (lo, hi) = match domain {
        NormalDomain::All => (-FAR, facing_cut.min(FAR)),
        NormalDomain::MirrorAboveHorizon => {
            let e = horizon.extent();
            if e.len() < 2 {
                return I::zero();
            }
            (e[0], e[e.len() - 1].min(facing_cut))
        }
    };
    if !(hi > lo) {
        return I::zero();
    }
    let mut outer = graded(lo, hi);
    let inside = |r: f64| r > lo && r < hi;
    for k in &extra {
        for r in k.extent() {
            outer.push(r);
            if k.singular {
                // The singular region opens like a square root past the tangency.
                outer.extend([r - 0.1, r - 0.01, r + 0.01, r + 0.1]);
            }
        }
    }
    outer.retain(|&r| r == lo || r == hi || inside(r));
    if ax != ay {
        let lines: &[f64] = match mf.kind {
            DistributionKind::Beckmann => &[0.0, 1.5, -1.5, 4.0, -4.0],
            DistributionKind::Ggx => &[0.0, 1.5, -1.5, 4.0, -4.0, 12.0, -12.0],
        };
        let domain_conic = (domain == NormalDomain::MirrorAboveHorizon).then_some(&horizon);
        for k in extra.iter().chain(domain_conic) {
            for &t2 in lines {
                outer.extend(k.crossings(t2).into_iter().filter(|&r| inside(r)));
            }
        }
    }
    outer.sort_by(f64::total_cmp);
    outer.dedup();
    let density = |tt: f64| match mf.kind {
        DistributionKind::Beckmann => (-tt).exp() * std::f64::consts::FRAC_1_PI,
        DistributionKind::Ggx => std::f64::consts::FRAC_1_PI / ((1.0 + tt) * (1.0 + tt)),
    };
    let value = |t1: f64, t2: f64| -> I {
        let facing = 1.0 - t1 * rho / cz;
        if !(facing > 0.0) {
            return I::zero();
        }
        let m = normal(t1, t2);
        let g1 = mf.g1(w, m);
        if !(g1 > 0.0) {
            return I::zero();
        }
        f(m).scale(density(t1 * t1 + t2 * t2) * facing * g1)
    };
    // Width of the slope density along t₂ at a given t₁ (GGX's heavy tails widen it).
    let width = |t1: f64| match mf.kind {
        DistributionKind::Beckmann => 1.0,
        DistributionKind::Ggx => (1.0 + t1 * t1).sqrt(),
    };
    let line = |t1: f64| -> I {
        let (r1, r2) = match domain {
            NormalDomain::All => (-FAR, FAR),
            NormalDomain::MirrorAboveHorizon => {
                let r = horizon.line_roots(t1);
                if r.len() < 2 {
                    return I::zero();
                }
                (r[0], r[r.len() - 1])
            }
        };
        // Breakpoints, each flagged when the integrand has a square-root edge there.
        let mut pieces: Vec<(f64, bool)> = vec![(r1, false), (r2, false)];
        for k in &extra {
            pieces.extend(k.line_roots(t1).into_iter().filter(|&r| r > r1 && r < r2).map(|r| (r, k.singular)));
        }
        if let Some(kink) = numeric_kink {
            // Scan uniformly in the mapped coordinate v (t = σ v/(1 − v²)), which spreads the
            // points where the density has its mass.
            const SCAN: usize = 48;
            let sigma = width(t1);
            let to_v = |t: f64| {
                let t = t / sigma;
                if t == 0.0 {
                    0.0
                } else {
                    2.0 * t / (1.0 + (1.0 + 4.0 * t * t).sqrt())
                }
            };
            let (v1, v2) = (to_v(r1), to_v(r2));
            let at = |i: usize| {
                let v = v1 + (v2 - v1) * i as f64 / SCAN as f64;
                (sigma * v / (1.0 - v * v)).clamp(r1, r2)
            };
            for i in 0..SCAN {
                let (mut u0, mut u1) = (at(i), at(i + 1));
                let f0 = kink(normal(t1, u0)) > 0.0;
                if f0 != (kink(normal(t1, u1)) > 0.0) {
                    for _ in 0..60 {
                        let mid = 0.5 * (u0 + u1);
                        if (kink(normal(t1, mid)) > 0.0) == f0 {
                            u0 = mid;
                        } else {
                            u1 = mid;
                        }
                    }
                    let root = 0.5 * (u0 + u1);
                    pieces.push((root, false));
                    // Masking often drops to zero in a thin layer at such a kink (a direction
                    // reaching the horizon): grade geometrically on both sides.
                    for d in [1e-3, 1e-2, 1e-1] {
                        for r in [root - d * sigma, root + d * sigma] {
                            if r > r1 && r < r2 {
                                pieces.push((r, false));
                            }
                        }
                    }
                }
            }
        }
        pieces.sort_by(|a, b| a.0.total_cmp(&b.0));
        let f_line = |t2: f64| value(t1, t2);
        pieces
            .windows(2)
            .map(|p| {
                let ((mut a, sa), (mut b, sb)) = (p[0], p[1]);
                if !(b > a) {
                    return I::zero();
                }
                let mut sum = I::zero();
                // Square-root edges: the substitution t = edge ± δu² makes them smooth.
                let delta = (0.5 * (b - a)).min(width(t1));
                if sa {
                    sum = sum.add(sqrt_edge(&xi, &wi_gl, a, delta, &f_line));
                    a += delta;
                }
                if sb {
                    sum = sum.add(sqrt_edge(&xi, &wi_gl, b, -delta, &f_line));
                    b -= delta;
                }
                sum.add(piece(mf.kind, &xi, &wi_gl, a, b, width(t1), f_line))
            })
            .fold(I::zero(), I::add)
    };
    outer.windows(2).map(|p| piece(mf.kind, &xo, &wo_gl, p[0], p[1], 1.0, line)).fold(I::zero(), I::add)
}

/// Breakpoints of `[a, b]` (in stretched-slope units) graded toward both ends: masking
/// drops from one to zero in a layer about one unit thick where `wi` approaches the horizon,
/// and the pieces (0.1, 1 and 10 units, and a tenth of the length, from each end) resolve
/// it. Returns the sorted breakpoints including `a` and `b`.
fn graded(a: f64, b: f64) -> Vec<f64> {
    if !(b > a) {
        return vec![a, b];
    }
    let l = b - a;
    let mut v = vec![a, b];
    for d in [0.1, 1.0, 10.0, 0.1 * l] {
        if 2.0 * d < l {
            v.push(a + d);
            v.push(b - d);
        }
    }
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

/// `∫ f` over `[edge, edge + delta]` (or `[edge + delta, edge]` for `delta < 0`) for an
/// integrand with a square-root edge at `edge`: Gauss-Legendre in `u` with
/// `t = edge + delta·u²`.
fn sqrt_edge<I: Integrand>(x: &[f64], w: &[f64], edge: f64, delta: f64, f: &impl Fn(f64) -> I) -> I {
    x.iter()
        .zip(w)
        .map(|(xi, wi)| {
            let u = 0.5 * (xi + 1.0);
            f(edge + delta * u * u).scale(0.5 * wi * 2.0 * u)
        })
        .fold(I::zero(), I::add)
        .scale(delta.abs())
}

/// Beckmann slopes beyond this many stretched units carry no mass (`e^{−42}`).
const BECKMANN_RANGE: f64 = 6.5;

/// `∫_a^b f(t) dt` over one smooth piece in stretched-slope units: for Beckmann, plain
/// Gauss-Legendre on the part within [`BECKMANN_RANGE`], split at ±2; for GGX (heavy tails)
/// the mapped rule of [`mapped_gl`] with width `sigma`.
fn piece<I: Integrand>(
    kind: DistributionKind,
    x: &[f64],
    w: &[f64],
    a: f64,
    b: f64,
    sigma: f64,
    f: impl Fn(f64) -> I,
) -> I {
    match kind {
        DistributionKind::Beckmann => {
            // The Gaussian's support, split at ±2 so each part is nearly polynomial.
            let (a, b) = (a.max(-BECKMANN_RANGE), b.min(BECKMANN_RANGE));
            let mut cuts = vec![a];
            cuts.extend([-2.0, 2.0].into_iter().filter(|&c| c > a && c < b));
            cuts.push(b);
            cuts.windows(2)
                .filter(|p| p[1] > p[0])
                .map(|p| {
                    let (half, mid) = (0.5 * (p[1] - p[0]), 0.5 * (p[0] + p[1]));
                    x.iter().zip(w).map(|(xi, wi)| f(mid + half * xi).scale(*wi)).fold(I::zero(), I::add).scale(half)
                })
                .fold(I::zero(), I::add)
        }
        DistributionKind::Ggx => mapped_gl(x, w, a, b, sigma, f),
    }
}

/// `∫_a^b f(t) dt` by Gauss-Legendre in `v` with `t = σ v/(1 − v²)` (which spreads the
/// nodes over long slope ranges while keeping them dense within `σ` of `t = 0`).
fn mapped_gl<I: Integrand>(x: &[f64], w: &[f64], a: f64, b: f64, sigma: f64, f: impl Fn(f64) -> I) -> I {
    if !(b > a) {
        return I::zero();
    }
    let inv = |t: f64| {
        let t = t / sigma;
        if t == 0.0 {
            0.0
        } else {
            2.0 * t / (1.0 + (1.0 + 4.0 * t * t).sqrt())
        }
    };
    let (va, vb) = (inv(a), inv(b));
    let (half, mid) = (0.5 * (vb - va), 0.5 * (va + vb));
    let mut s = I::zero();
    for (xi, wi) in x.iter().zip(w) {
        let v = mid + half * xi;
        let d = 1.0 - v * v;
        s = s.add(f(sigma * v / d).scale(wi * (1.0 + v * v) / (d * d)));
    }
    s.scale(half * sigma)
}

impl AlbedoTable {
    /// Computes the table for a distribution, roughness and masking (see the module docs for
    /// the cost; prefer [`AlbedoTable::cached`]).
    #[must_use]
    pub fn new(kind: DistributionKind, masking: MaskingKind, alpha_x: f64, alpha_y: f64) -> Self {
        Self::weighted(kind, masking, alpha_x, alpha_y, &|_| 1.0)
    }

    /// The table of `1 − E_w` for a Fresnel-like weight `w(cos) ∈ [0, 1]` of the angle on the
    /// microfacet (see the module docs); [`AlbedoTable::new`] is the weight 1. Costs as much
    /// as the plain table; prefer [`AlbedoTable::cached_weighted`] for shared weights.
    #[must_use]
    pub fn weighted(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        weight: &dyn Fn(f64) -> f64,
    ) -> Self {
        Self::weighted_set(kind, masking, alpha_x, alpha_y, &[weight]).remove(0)
    }

    /// [`AlbedoTable::weighted`] for several weights, computed together (four per quadrature
    /// pass, each pass about the cost of one table).
    #[must_use]
    pub fn weighted_set(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        weights: &[&dyn Fn(f64) -> f64],
    ) -> Vec<Self> {
        let mf = Microfacet::new(kind, alpha_x, alpha_y);
        let n_phi = if alpha_x == alpha_y { 1 } else { N_PHI_ANISO };
        let mut losses = vec![vec![0.0; n_phi * N_MU]; weights.len()];
        let (mut eps, mut inv_log_span) = (Vec::new(), Vec::new());
        let zero = |_: f64| 0.0;
        for k in 0..n_phi {
            let phi = azimuth_node(alpha_x, alpha_y, k, n_phi);
            // E varies on the scale μ ~ α(φ) near grazing (α(φ) the projected roughness of
            // this row): space the nodes logarithmically there.
            let a_phi = (alpha_x * phi.cos()).hypot(alpha_y * phi.sin());
            let e = (0.5 * a_phi).clamp(1e-4, 1.0);
            eps.push(e);
            inv_log_span.push(1.0 / (1.0 + 1.0 / e).ln());
            for j in 0..N_MU {
                let s = j as f64 / (N_MU - 1) as f64;
                let mu = mu_of_s(e, s).clamp(MU_MIN, 1.0);
                let sin = (1.0 - mu * mu).max(0.0).sqrt();
                let wo = Vec3::new(sin * phi.cos(), sin * phi.sin(), mu);
                for (chunk, first) in weights.chunks(4).zip((0..).step_by(4)) {
                    let at = |i: usize| chunk.get(i).copied().unwrap_or(&zero);
                    // The narrowest array that holds the chunk.
                    let e: Vec<f64> = match chunk.len() {
                        1 => directional_albedo_weights(&mf, masking, wo, [at(0)]).to_vec(),
                        2 => directional_albedo_weights(&mf, masking, wo, [at(0), at(1)]).to_vec(),
                        _ => directional_albedo_weights(&mf, masking, wo, [at(0), at(1), at(2), at(3)]).to_vec(),
                    };
                    for (i, e) in e.iter().take(chunk.len()).enumerate() {
                        losses[first + i][k * N_MU + j] = (1.0 - e).clamp(0.0, 1.0);
                    }
                }
            }
        }
        losses
            .into_iter()
            .map(|loss| {
                let mut slope = vec![0.0; n_phi * N_MU];
                for k in 0..n_phi {
                    let row = &loss[k * N_MU..(k + 1) * N_MU];
                    monotone_slopes(row, 1.0 / (N_MU - 1) as f64, &mut slope[k * N_MU..(k + 1) * N_MU]);
                }
                let mut table = Self {
                    kind,
                    masking,
                    alpha_x,
                    alpha_y,
                    eps: eps.clone(),
                    inv_log_span: inv_log_span.clone(),
                    n_phi,
                    lane_loss: padded_f32(&loss[..N_MU]),
                    lane_slope: padded_f32(&slope[..N_MU]),
                    lane_rows: neighbour_rows(&loss[..N_MU], &slope[..N_MU]),
                    loss,
                    slope,
                    loss_avg: 0.0,
                    weight: None,
                };
                table.loss_avg = table.integrate_loss();
                table
            })
            .collect()
    }

    /// A shared table for these exact parameters, computed once per process (a small cache
    /// of the most recently used tables).
    #[must_use]
    pub fn cached(kind: DistributionKind, masking: MaskingKind, alpha_x: f64, alpha_y: f64) -> Arc<Self> {
        Self::cached_with(kind, masking, alpha_x, alpha_y, None, &|_| 1.0)
    }

    /// A shared weighted table ([`AlbedoTable::weighted`]) for these exact parameters and the
    /// weight named by `key`; `weight` must be the same function whenever the key is.
    #[must_use]
    pub fn cached_weighted(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        key: WeightKey,
        weight: &dyn Fn(f64) -> f64,
    ) -> Arc<Self> {
        Self::cached_with(kind, masking, alpha_x, alpha_y, Some(key), weight)
    }

    fn cached_with(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        key: Option<WeightKey>,
        weight: &dyn Fn(f64) -> f64,
    ) -> Arc<Self> {
        Self::cached_set(kind, masking, alpha_x, alpha_y, &[(key, weight)]).remove(0)
    }

    /// Shared tables for several weights at once: `(None, _)` asks for the plain table (the
    /// weight is then ignored), `(Some(key), weight)` for [`AlbedoTable::cached_weighted`].
    /// The missing ones are computed together ([`AlbedoTable::weighted_set`]).
    #[must_use]
    pub fn cached_set(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        requests: &[TableRequest<'_>],
    ) -> Vec<Arc<Self>> {
        type Cache = Mutex<Vec<Arc<AlbedoTable>>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        const CAPACITY: usize = 256;
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        let same = |t: &AlbedoTable, key: Option<WeightKey>| {
            t.kind == kind
                && t.masking == masking
                && t.alpha_x.to_bits() == alpha_x.to_bits()
                && t.alpha_y.to_bits() == alpha_y.to_bits()
                && t.weight == key
        };
        let mut found: Vec<Option<Arc<Self>>> = vec![None; requests.len()];
        if let Ok(c) = cache.lock() {
            for (slot, (key, _)) in found.iter_mut().zip(requests) {
                *slot = c.iter().find(|t| same(t, *key)).map(Arc::clone);
            }
        }
        let missing: Vec<usize> = (0..requests.len()).filter(|&i| found[i].is_none()).collect();
        if !missing.is_empty() {
            // Computed outside the lock so other threads are not held up.
            let one = |_: f64| 1.0;
            let weights: Vec<&dyn Fn(f64) -> f64> =
                missing.iter().map(|&i| if requests[i].0.is_some() { requests[i].1 } else { &one }).collect();
            let tables = Self::weighted_set(kind, masking, alpha_x, alpha_y, &weights);
            let mut c = cache.lock().ok();
            for (&i, mut table) in missing.iter().zip(tables) {
                table.weight = requests[i].0;
                let table = Arc::new(table);
                if let Some(c) = c.as_mut() {
                    if !c.iter().any(|t| same(t, table.weight)) {
                        if c.len() >= CAPACITY {
                            c.remove(0);
                        }
                        c.push(Arc::clone(&table));
                    }
                }
                found[i] = Some(table);
            }
        }
        found.into_iter().map(|t| t.expect("every request is found or computed")).collect()
    }

    /// `1 − E_avg`: the energy the single-scattering lobe loses on average.
    #[must_use]
    pub fn loss_avg(&self) -> f64 {
        self.loss_avg
    }

    /// `E_avg = (1/π) ∫ E(w) cos θ dω` of the tabulated (interpolated) albedo.
    #[must_use]
    pub fn e_avg(&self) -> f64 {
        1.0 - self.loss_avg
    }

    /// Row `k` (an azimuth node) of the table at `cos θ = μ`.
    #[inline]
    fn row<T: Real>(&self, k: usize, mu: T) -> T {
        let s = (mu / T::of(self.eps[k])).ln_1p() * T::of(self.inv_log_span[k]);
        let (j, f) = split(s * T::of((N_MU - 1) as f64), N_MU);
        let i = k * N_MU + j;
        let h = T::of(1.0 / (N_MU - 1) as f64);
        let (y0, y1) = (T::of(self.loss[i]), T::of(self.loss[i + 1]));
        let (d0, d1) = (T::of(self.slope[i]) * h, T::of(self.slope[i + 1]) * h);
        // Cubic Hermite basis.
        let f2 = f * f;
        let f3 = f2 * f;
        let two = T::of(2.0);
        let three = T::of(3.0);
        let h00 = two * f3 - three * f2 + T::one();
        let h10 = f3 - two * f2 + f;
        let h01 = three * f2 - two * f3;
        let h11 = f3 - f2;
        (h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1).clamp_to(T::zero(), T::one())
    }

    /// `1 − E(w)` interpolated from the table, for `w` above the surface.
    #[inline]
    #[must_use]
    pub fn loss<T: Real>(&self, w: Vec3<T>) -> T {
        let mu = w.z.clamp_to(T::zero(), T::one());
        if self.n_phi == 1 {
            return self.row(0, mu);
        }
        // Azimuth coordinate: ln(α(φ) + c) between its values on the two axes (see
        // `azimuth_node`).
        let r2 = w.x * w.x + w.y * w.y;
        let (ax, ay) = (T::of(self.alpha_x), T::of(self.alpha_y));
        let a = if r2 > T::zero() { ((ax * ax * w.x * w.x + ay * ay * w.y * w.y) / r2).sqrt() } else { ax };
        let c = T::of(azimuth_offset(self.alpha_x, self.alpha_y));
        let q = ((a + c) / (ax + c)).ln() / ((ay + c) / (ax + c)).ln();
        let p = q * T::of((self.n_phi - 1) as f64);
        let (k, fp) = split(p, self.n_phi);
        let (a, b) = (self.row(k, mu), self.row(k + 1, mu));
        a + (b - a) * fp
    }

    /// True when `self` and `o` are isotropic tables on the same `μ` nodes (tables of the same
    /// roughness): a cell found with [`AlbedoTable::cell_lanes`] of one serves the other.
    #[must_use]
    pub fn same_cells(&self, o: &Self) -> bool {
        self.n_phi == 1 && o.n_phi == 1 && self.eps == o.eps && self.inv_log_span == o.inv_log_span
    }

    /// The cell of `cos θ = μ` in an isotropic table, per lane: the node index (as a float)
    /// and the fraction in the cell, as [`AlbedoTable::loss`] finds them (one per roughness
    /// and call, shared by every table on the same nodes).
    #[inline(always)]
    #[must_use]
    pub fn cell_lanes<L: Lanes>(&self, mu: L) -> (L, L) {
        debug_assert_eq!(self.n_phi, 1, "cell_lanes needs an isotropic table");
        let mu = lanes::clamp(mu, L::c(0.0), L::c(1.0));
        let (eps, span) = (L::Elem::of(self.eps[0]), L::Elem::of(self.inv_log_span[0]));
        let s = ln_1p_lanes(mu / L::splat(eps)) * L::splat(span);
        let x = lanes::clamp(s * L::c((N_MU - 1) as f64), L::c(0.0), L::c((N_MU - 1) as f64));
        let j = lanes::min(x.floor_(), L::c((N_MU - 2) as f64));
        (j, x - j)
    }

    /// `1 − E` of an isotropic table at a cell of [`AlbedoTable::cell_lanes`] (of this table
    /// or one with [`AlbedoTable::same_cells`]): the node values read per lane (register permutes
    /// with AVX-512, one row per lane with AVX2), the cubic
    /// Hermite interpolation in lanes, as [`AlbedoTable::loss`].
    #[inline(always)]
    #[must_use]
    pub fn loss_at_lanes<L: Lanes>(&self, (j, f): (L, L)) -> L {
        let h = L::c(1.0 / (N_MU - 1) as f64);
        let (y0, y1, d0, d1) = if L::WIDTH == 1 {
            // One lane (the scalar paths, f64 among them): the nodes at full precision.
            let i = (j.lane(0).f64() as usize).min(N_MU - 2);
            let at = |v: &[f64], i: usize| L::splat(L::Elem::of(v[i]));
            (at(&self.loss, i), at(&self.loss, i + 1), at(&self.slope, i) * h, at(&self.slope, i + 1) * h)
        } else {
            // `cell_lanes` keeps `j` in [0, N_MU − 2]; the lookups clamp (NaN reads nodes 0, 1),
            // and their f32 nodes are the values the lanes held before (f64 rounded to f32).
            let [(y0, y1), (d0, d1)] = if L::REGISTER_LOOKUP {
                L::lookup_pairs_f32_([self.lane_loss.as_slice(), self.lane_slope.as_slice()], j)
            } else {
                // One row per lane instead of four gathers (same f32 values).
                let [loss, slope, _] = L::lookup_rows3_f32_(&self.lane_rows, j);
                [loss, slope]
            };
            (y0, y1, d0 * h, d1 * h)
        };
        // Cubic Hermite basis.
        let f2 = f * f;
        let f3 = f2 * f;
        let two = L::c(2.0);
        let three = L::c(3.0);
        let h00 = two * f3 - three * f2 + L::c(1.0);
        let h10 = f3 - two * f2 + f;
        let h01 = three * f2 - two * f3;
        let h11 = f3 - f2;
        lanes::clamp(h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1, L::c(0.0), L::c(1.0))
    }

    /// `E(w)` interpolated from the table.
    #[inline]
    #[must_use]
    pub fn e<T: Real>(&self, w: Vec3<T>) -> T {
        T::one() - self.loss(w)
    }

    /// The compensation lobe with `F = 1`: `(1 − E(wi))(1 − E(wo)) / (π (1 − E_avg))`
    /// (zero when the single-scattering lobe loses no energy).
    #[inline]
    #[must_use]
    pub fn f_ms<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        if !(self.loss_avg > 1e-9) {
            return T::zero();
        }
        self.loss(wi) * self.loss(wo) * T::inv_pi() / T::of(self.loss_avg)
    }

    /// `(1/π) ∫ (1 − E_table(w)) cos θ dω` of the interpolant, by Gauss-Legendre per table
    /// cell (8 points in `s` and in the stretched azimuth): accurate to ~1e-10.
    fn integrate_loss(&self) -> f64 {
        let (x, w) = gauss_legendre(8);
        let ds = 1.0 / (N_MU - 1) as f64;
        // Radially, the cells of the finest row: μ = ε (e^{s L} − 1), L = ln(1 + 1/ε),
        // dμ = ε L e^{s L} ds.
        let eps = self.eps.iter().copied().fold(1.0, f64::min);
        let l = (1.0 + 1.0 / eps).ln();
        let radial = |phi: f64| -> f64 {
            let mut sum = 0.0;
            for j in 0..N_MU - 1 {
                for (xi, wi) in x.iter().zip(&w) {
                    let s = (j as f64 + 0.5 + 0.5 * xi) * ds;
                    let mu = eps * ((s * l).exp() - 1.0);
                    let dmu = eps * l * (s * l).exp();
                    let sin = (1.0 - mu * mu).max(0.0).sqrt();
                    let v = self.loss(Vec3::new(sin * phi.cos(), sin * phi.sin(), mu));
                    sum += 0.5 * ds * wi * v * mu * dmu;
                }
            }
            sum
        };
        if self.n_phi == 1 {
            // (1/π)·2π ∫ L μ dμ.
            return 2.0 * radial(0.0);
        }
        // ∫ over φ ∈ [0, π/2], cell by cell between the azimuth nodes.
        let (xp, wp) = gauss_legendre(8);
        let mut sum = 0.0;
        for k in 0..self.n_phi - 1 {
            let p0 = azimuth_node(self.alpha_x, self.alpha_y, k, self.n_phi);
            let p1 = azimuth_node(self.alpha_x, self.alpha_y, k + 1, self.n_phi);
            for (xi, wi) in xp.iter().zip(&wp) {
                let phi = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * xi;
                sum += 0.5 * (p1 - p0) * wi * radial(phi);
            }
        }
        // Four quadrants, divided by π.
        4.0 * sum / std::f64::consts::PI
    }
}

/// `values` rounded to f32, padded with the last value to a multiple of 16 (at least 32)
/// entries, as [`Lanes::lookup_f32_`] needs.
fn padded_f32(values: &[f64]) -> Vec<f32> {
    let mut v: Vec<f32> = values.iter().map(|&x| x as f32).collect();
    let last = *v.last().expect("a table row has nodes");
    v.resize(values.len().next_multiple_of(16).max(32), last);
    v
}

/// Rows `[loss_j, slope_j, 0, 0, loss_{j+1}, slope_{j+1}, 0, 0]` (f32) for
/// [`Lanes::lookup_rows3_f32_`].
fn neighbour_rows(loss: &[f64], slope: &[f64]) -> Vec<[f32; 8]> {
    (0..loss.len() - 1)
        .map(|j| {
            let (l, d) = (|i: usize| loss[i] as f32, |i: usize| slope[i] as f32);
            [l(j), d(j), 0.0, 0.0, l(j + 1), d(j + 1), 0.0, 0.0]
        })
        .collect()
}

/// `μ` at the table coordinate `s ∈ [0, 1]` of a row with spacing scale `ε`.
fn mu_of_s(eps: f64, s: f64) -> f64 {
    eps * (s * (1.0 + 1.0 / eps).ln()).exp_m1()
}

/// Fritsch-Carlson slopes of a monotone piecewise-cubic interpolant through `y` (uniform
/// spacing `h`): the interpolant never leaves the range of neighbouring nodes.
fn monotone_slopes(y: &[f64], h: f64, d: &mut [f64]) {
    let n = y.len();
    let delta: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h).collect();
    d[0] = delta[0];
    d[n - 1] = delta[n - 2];
    for i in 1..n - 1 {
        d[i] = if delta[i - 1] * delta[i] <= 0.0 {
            0.0
        } else {
            // Harmonic mean (Fritsch-Butland), which satisfies the monotonicity bound.
            2.0 * delta[i - 1] * delta[i] / (delta[i - 1] + delta[i])
        };
    }
    for i in [0, n - 1] {
        let di = delta[i.min(n - 2)];
        if d[i] * di <= 0.0 {
            d[i] = 0.0;
        }
    }
}

/// Azimuth `φ ∈ [0, π/2]` of node `k` of `n`. `E` depends on the azimuth mostly through the
/// projected roughness `α(φ) = (α_x² cos²φ + α_y² sin²φ)^½`, so the nodes are uniform in
/// `ln(α(φ) + c)` with `c` a tenth of the larger roughness: dense where `α(φ)` changes fast
/// (near the smooth axis of a strongly anisotropic surface), yet not wasted on tiny `α`.
fn azimuth_node(alpha_x: f64, alpha_y: f64, k: usize, n: usize) -> f64 {
    if n == 1 {
        return 0.0;
    }
    let f = k as f64 / (n - 1) as f64;
    let c = azimuth_offset(alpha_x, alpha_y);
    let a = (alpha_x + c) * ((alpha_y + c) / (alpha_x + c)).powf(f) - c;
    let (ax2, ay2) = (alpha_x * alpha_x, alpha_y * alpha_y);
    ((a * a - ax2) / (ay2 - ax2)).clamp(0.0, 1.0).sqrt().asin()
}

/// The offset `c` of the azimuth coordinate `ln(α(φ) + c)`.
fn azimuth_offset(alpha_x: f64, alpha_y: f64) -> f64 {
    0.01 * alpha_x.max(alpha_y)
}

/// `ln(1 + x)` for `x ∈ [0, 2¹⁵)`, per lane: `std` for one lane (so the scalar paths are those
/// of [`AlbedoTable::loss`] bit for bit), otherwise `u = 1 + x = 2^e·m` with `m ∈ [√½, √2)`
/// found by a branch-free binary search on the exponent, `ln m = 2 atanh((m − 1)/(m + 1))` by
/// its series to the 11th power (truncation < 1e-10), and the rounding of `1 + x` corrected by
/// the factor `x/(u − 1)`. About 1 ulp in f32; only the table coordinate uses it.
#[inline(always)]
fn ln_1p_lanes<L: Lanes>(x: L) -> L {
    if L::WIDTH == 1 {
        return x.map_lanes(num_traits::Float::ln_1p);
    }
    let one = L::c(1.0);
    let u = x + one;
    let mut m = u;
    let mut e = L::c(0.0);
    for k in [8, 4, 2, 1] {
        let big = lanes::ge(m, L::c(f64::from(1u32 << k)));
        m = lanes::select(big, m * L::c(1.0 / f64::from(1u32 << k)), m);
        e += lanes::keep(big, L::c(f64::from(k)));
    }
    let big = lanes::gt(m, L::c(std::f64::consts::SQRT_2));
    m = lanes::select(big, m * L::c(0.5), m);
    e += lanes::keep(big, one);
    let z = (m - one) / (m + one);
    let w = z * z;
    let mut p = L::c(1.0 / 11.0);
    for c in [1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0] {
        p = p.mul_add_(w, L::c(c));
    }
    // e·ln 2 in two parts (Cody-Waite) so that e·C1 is exact.
    let ln_u = e.mul_add_(L::c(0.693_359_375), e.mul_add_(L::c(-2.121_944_400_546_905_8e-4), L::c(2.0) * z * p));
    lanes::select(lanes::eq(u, one), x, ln_u * (x / (u - one)))
}

/// Splits a table coordinate `x ∈ [0, n−1]` into a cell index and a fraction.
#[inline]
fn split<T: Real>(x: T, n: usize) -> (usize, T) {
    let x = x.clamp_to(T::zero(), T::of((n - 1) as f64));
    let i = x.floor().to_usize().unwrap_or(0).min(n - 2);
    (i, x - T::of(i as f64))
}

/// The compensation lobe of one microfacet model: the albedo table and the Fresnel colour
/// `F_ms` per channel, ready to evaluate `F_ms · f_ms(wi, wo)`.
#[derive(Clone, Debug)]
pub struct Compensation {
    /// `1 − E` for the model's distribution, roughness and masking (shared, cached).
    pub table: Arc<AlbedoTable>,
    /// `F_avg² E_avg / (1 − F_avg (1 − E_avg))` per channel.
    pub f_ms: [f64; 3],
}

impl Compensation {
    /// Builds the lobe for a distribution, roughness and masking, with the Fresnel curve
    /// `fresnel(channel, cos θ)` averaged per channel.
    #[must_use]
    pub fn new(
        kind: DistributionKind,
        masking: MaskingKind,
        alpha_x: f64,
        alpha_y: f64,
        fresnel: impl Fn(usize, f64) -> f64,
    ) -> Self {
        let table = AlbedoTable::cached(kind, masking, alpha_x, alpha_y);
        let f_ms = std::array::from_fn(|c| ms_fresnel_factor(fresnel_average(|mu| fresnel(c, mu)), table.e_avg()));
        Self { table, f_ms }
    }

    /// `F_ms · f_ms(wi, wo)`.
    #[inline]
    #[must_use]
    pub fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> crate::math::Rgb<T> {
        crate::math::Rgb::from_array(self.f_ms) * self.table.f_ms(wi, wo)
    }

    /// The lobe's albedo at `wo`, `F̄_ms (1 − E(wo))` (for lobe selection).
    #[inline]
    #[must_use]
    pub fn albedo<T: Real>(&self, wo: Vec3<T>) -> T {
        crate::math::Rgb::<T>::from_array(self.f_ms).average() * self.table.loss(wo)
    }

    /// `1 − E(w)` per lane: isotropic tables interpolated in lanes
    /// ([`AlbedoTable::cell_lanes`], [`AlbedoTable::loss_at_lanes`]), anisotropic ones (and
    /// the one-lane paths) through [`AlbedoTable::loss`] one lane at a time.
    #[inline(always)]
    #[must_use]
    pub fn loss_lanes<L: Lanes>(&self, w: Vec3<L>) -> L {
        let t = &self.table;
        if L::WIDTH == 1 || t.n_phi != 1 {
            return L::from_fn(|i| t.loss(crate::bxdf::lane_of(w, i)));
        }
        t.loss_at_lanes(t.cell_lanes(w.z))
    }

    /// [`Compensation::eval`] per lane.
    #[inline(always)]
    #[must_use]
    pub fn eval_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> crate::math::Rgb<L> {
        let loss_avg = self.table.loss_avg;
        if !(loss_avg > 1e-9) {
            return crate::math::Rgb::splat(L::c(0.0));
        }
        let f = self.loss_lanes(wi) * self.loss_lanes(wo) * L::c(std::f64::consts::FRAC_1_PI) / L::c(loss_avg);
        crate::math::Rgb::from_array(self.f_ms) * f
    }

    /// [`Compensation::albedo`] per lane.
    #[inline(always)]
    #[must_use]
    pub fn albedo_lanes<L: Lanes>(&self, wo: Vec3<L>) -> L {
        let [r, g, b] = self.f_ms.map(L::c);
        // Rgb::average, as `albedo` computes it.
        (r + g + b) / L::c(3.0) * self.loss_lanes(wo)
    }
}

/// The cosine-weighted average `F_avg = 2 ∫₀¹ F(μ) μ dμ` of a Fresnel curve (64-point
/// Gauss-Legendre).
#[must_use]
pub fn fresnel_average(f: impl Fn(f64) -> f64) -> f64 {
    let (x, w) = gauss_legendre(64);
    x.iter()
        .zip(&w)
        .map(|(x, w)| {
            let mu = 0.5 * (x + 1.0);
            0.5 * w * 2.0 * f(mu) * mu
        })
        .sum()
}

/// The colour of the compensation lobe, `F_avg² E_avg / (1 − F_avg (1 − E_avg))`.
#[must_use]
pub fn ms_fresnel_factor(f_avg: f64, e_avg: f64) -> f64 {
    let d = 1.0 - f_avg * (1.0 - e_avg);
    if d > 0.0 {
        (f_avg * f_avg * e_avg / d).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// An independent (slow) reference for the tests: nested adaptive Gauss-Kronrod over the
/// stretched slopes without the closed-form breakpoints.
#[cfg(test)]
mod reference {
    use super::*;

    /// `E(wo)` by nested globally adaptive Gauss-Kronrod (7/15) integration of the same slope
    /// integral as [`directional_albedo`], without its closed-form breakpoints (slow; the
    /// kinks are found by adaptivity). Cross-checked during development against a 512×512
    /// product rule over the visible-normal sampler's unit square (agreement ~1e-7).
    pub(super) fn directional_albedo_adaptive(
        mf: &Microfacet<f64>,
        masking: MaskingKind,
        wo: Vec3<f64>,
        tol: f64,
    ) -> f64 {
        let (ax, ay) = (mf.alpha_x, mf.alpha_y);
        let (vx, vy) = (ax * wo.x, ay * wo.y);
        let rho = (vx * vx + vy * vy).sqrt();
        let (e1x, e1y) = if rho > 0.0 { (vx / rho, vy / rho) } else { (1.0, 0.0) };
        let density = |t2: f64| match mf.kind {
            DistributionKind::Beckmann => (-t2).exp() * std::f64::consts::FRAC_1_PI,
            DistributionKind::Ggx => std::f64::consts::FRAC_1_PI / ((1.0 + t2) * (1.0 + t2)),
        };
        // t = v/(1 − v²) and its derivative.
        let map = |v: f64| {
            let d = 1.0 - v * v;
            (v / d, (1.0 + v * v) / (d * d))
        };
        let integrand = |v1: f64, v2: f64| -> f64 {
            let ((t1, j1), (t2, j2)) = (map(v1), map(v2));
            let facing = 1.0 - t1 * rho / wo.z;
            if !(facing > 0.0) {
                return 0.0;
            }
            let tx = t1 * e1x - t2 * e1y;
            let ty = t1 * e1y + t2 * e1x;
            let m = Vec3::new(-ax * tx, -ay * ty, 1.0).normalize();
            let wi = reflect(wo, m);
            if !(wi.z > 0.0) || !m.is_finite() {
                return 0.0;
            }
            density(t1 * t1 + t2 * t2) * facing * mf.g(wi, wo, m, masking) * j1 * j2
        };
        // Upper limit of v1 from t1 < cos θo / ρ.
        let v1_max = if rho > 0.0 {
            let t = wo.z / rho;
            2.0 * t / (1.0 + (1.0 + 4.0 * t * t).sqrt())
        } else {
            1.0
        };
        adaptive_gk15(&|v1| adaptive_gk15(&|v2| integrand(v1, v2), -1.0, 1.0, tol), -1.0, v1_max, tol)
    }

    /// Kronrod 15-point nodes (non-negative half) and weights, with the embedded Gauss 7-point
    /// weights (QUADPACK `qk15`).
    const XGK: [f64; 8] = [
        0.991_455_371_120_812_6,
        0.949_107_912_342_758_5,
        0.864_864_423_359_769_1,
        0.741_531_185_599_394_4,
        0.586_087_235_467_691_1,
        0.405_845_151_377_397_2,
        0.207_784_955_007_898_5,
        0.0,
    ];
    const WGK: [f64; 8] = [
        0.022_935_322_010_529_22,
        0.063_092_092_629_978_55,
        0.104_790_010_322_250_2,
        0.140_653_259_715_525_9,
        0.169_004_726_639_267_9,
        0.190_350_578_064_785_4,
        0.204_432_940_075_298_9,
        0.209_482_141_084_728_8,
    ];
    const WG: [f64; 4] =
        [0.129_484_966_168_869_7, 0.279_705_391_489_276_7, 0.381_830_050_505_118_9, 0.417_959_183_673_469_4];

    /// One Gauss-Kronrod 7/15 panel: the Kronrod estimate and QUADPACK's error estimate
    /// (`resasc · min(1, (200 |K − G| / resasc)^1.5)`, much less pessimistic than `|K − G|` for
    /// smooth integrands).
    fn gk15(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64) {
        let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
        let mut fv = [0.0; 15];
        fv[7] = f(c);
        for j in 0..7 {
            fv[j] = f(c - h * XGK[j]);
            fv[14 - j] = f(c + h * XGK[j]);
        }
        let weight = |i: usize| if i <= 7 { WGK[i] } else { WGK[14 - i] };
        let mut k = 0.0;
        for (i, v) in fv.iter().enumerate() {
            k += weight(i) * v;
        }
        let mut g = WG[3] * fv[7];
        for j in (1..7).step_by(2) {
            g += WG[j / 2] * (fv[j] + fv[14 - j]);
        }
        let mean = 0.5 * k;
        let resasc: f64 = fv.iter().enumerate().map(|(i, v)| weight(i) * (v - mean).abs()).sum::<f64>() * h;
        let diff = ((k - g) * h).abs();
        let err = if resasc > 0.0 && diff > 0.0 { resasc * (200.0 * diff / resasc).powf(1.5).min(1.0) } else { diff };
        (k * h, err)
    }

    /// Globally adaptive Gauss-Kronrod integration of `f` over `[a, b]`: the panel with the
    /// largest error estimate is halved until the estimates sum to at most `tol` (or 100 panels).
    fn adaptive_gk15(f: &impl Fn(f64) -> f64, a: f64, b: f64, tol: f64) -> f64 {
        if !(b > a) {
            return 0.0;
        }
        let mut panels: Vec<(f64, f64, f64, f64)> = Vec::with_capacity(32);
        let q = 0.5 * (b - a);
        for i in 0..2 {
            let (lo, hi) = (a + q * i as f64, a + q * (i + 1) as f64);
            let (v, e) = gk15(f, lo, hi);
            panels.push((lo, hi, v, e));
        }
        while panels.len() < 100 {
            let err: f64 = panels.iter().map(|p| p.3).sum();
            if err <= tol {
                break;
            }
            let (i, _) =
                panels.iter().enumerate().max_by(|x, y| x.1 .3.total_cmp(&y.1 .3)).expect("panels are never empty");
            let (lo, hi, _, _) = panels.swap_remove(i);
            let mid = 0.5 * (lo + hi);
            let (v1, e1) = gk15(f, lo, mid);
            let (v2, e2) = gk15(f, mid, hi);
            panels.push((lo, mid, v1, e1));
            panels.push((mid, hi, v2, e2));
        }
        panels.iter().map(|p| p.2).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::reference::directional_albedo_adaptive;
    use super::*;

    /// The lane `ln(1 + x)` of the table coordinate in AVX2 lanes against `std` in f64, over
    /// the range the tables use (`μ/ε ≤ 10⁴`).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lane_ln_1p_matches_std() {
        use crate::lanes::x86::F32x8;
        #[target_feature(enable = "avx2,fma")]
        unsafe fn run(x: f32) -> f32 {
            ln_1p_lanes(F32x8::splat(x)).lane(3)
        }
        if !crate::lanes::x86::avx2_or_allowed_skip("lane_ln_1p_matches_std") {
            return;
        }
        let mut worst = 0.0f64;
        for k in 0..40_000 {
            let x = if k < 20_000 { f64::from(k) * 5e-5 } else { 10f64.powf(f64::from(k - 20_000) * 4e-4 - 4.0) };
            let x = x.min(1e4) as f32;
            // SAFETY: AVX2 and FMA were detected above.
            let got = unsafe { run(x) };
            let want = f64::from(x).ln_1p();
            worst = worst.max((f64::from(got) - want).abs() / want.max(1e-30));
        }
        assert!(worst < 5e-7, "{worst}");
    }
    use crate::frame::spherical_direction;
    use crate::rng::Pcg32;
    use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

    fn dir(mu: f64, phi: f64) -> Vec3<f64> {
        spherical_direction((1.0 - mu * mu).max(0.0).sqrt(), mu, phi)
    }

    /// Directional albedo of `f_ss + f_ms` with F = 1, estimated independently of the table
    /// by Monte Carlo with the visible-normal sampler and cosine sampling (balance heuristic).
    fn furnace(t: &AlbedoTable, mf: &Microfacet<f64>, wo: Vec3<f64>, n: usize) -> f64 {
        let mut rng = Pcg32::new(11, 5);
        let f = |wi: Vec3<f64>| -> f64 {
            let h = (wi + wo).normalize();
            let ss = mf.d(h) * mf.g(wi, wo, h, t.masking) / (4.0 * wi.z * wo.z);
            ss + t.f_ms(wi, wo)
        };
        let pdf_spec = |wi: Vec3<f64>| -> f64 {
            let h = (wi + wo).normalize();
            mf.visible_d(wo, h) / (4.0 * wo.dot(h))
        };
        let mut sum = 0.0;
        for _ in 0..n {
            let m = mf.sample_m(wo, rng.uniform(), rng.uniform(), true);
            let wi = reflect(wo, m);
            if wi.z > 0.0 {
                sum += f(wi) * wi.z / (pdf_spec(wi) + cosine_hemisphere_pdf(wi.z));
            }
            let wi = cosine_hemisphere(rng.uniform(), rng.uniform());
            if wi.z > 0.0 {
                sum += f(wi) * wi.z / (pdf_spec(wi) + cosine_hemisphere_pdf(wi.z));
            }
        }
        sum / n as f64
    }

    /// The whole point: with F = 1 and the compensation on, the furnace albedo is 1.
    #[test]
    fn furnace_with_compensation_is_one() {
        for kind in [DistributionKind::Ggx, DistributionKind::Beckmann] {
            for masking in [MaskingKind::Separable, MaskingKind::HeightCorrelated] {
                for &(ax, ay) in &[(0.001, 0.001), (0.05, 0.05), (0.3, 0.3), (0.7, 0.7), (1.0, 1.0), (0.1, 0.6)] {
                    let t = AlbedoTable::new(kind, masking, ax, ay);
                    let mf = Microfacet::new(kind, ax, ay);
                    for &mu in &[1.0, 0.7, 0.3, 0.1, 0.02] {
                        for &phi in &[0.0, 0.9] {
                            let a = furnace(&t, &mf, dir(mu, phi), 40_000);
                            assert!((a - 1.0).abs() < 1e-2, "{kind:?} {masking:?} α=({ax},{ay}) μ={mu} φ={phi}: {a}");
                        }
                    }
                }
            }
        }
    }

    /// The visible normal distribution is normalised: ∫ D_w(m) dm = 1 (Heitz 2014, eq. 18).
    #[test]
    fn visible_normals_integrate_to_one() {
        for kind in [DistributionKind::Ggx, DistributionKind::Beckmann] {
            for &(ax, ay) in &[(0.01, 0.01), (0.3, 0.3), (1.0, 1.0), (0.05, 0.7)] {
                let mf = Microfacet::new(kind, ax, ay);
                for &(mu, phi) in &[(1.0, 0.0), (0.5, 0.3), (0.05, 2.0), (0.001, 1.0)] {
                    let v = visible_normal_integral(&mf, dir(mu, phi), NormalDomain::All, &[], None, |_| 1.0);
                    assert!((v - 1.0).abs() < 1e-5, "{kind:?} ({ax},{ay}) μ={mu}: {v}");
                }
            }
        }
    }

    /// Golden value derived by hand: GGX with α = 1 has `D = 1/π`, and at normal incidence
    /// `G1(wi) = 2μ/(1 + μ)`, so `E = (1/4π) ∫ G1 dω = 1 − ln 2` (both maskings, as Λ(wo) = 0).
    #[test]
    fn ggx_alpha_one_normal_incidence_is_one_minus_ln2() {
        let mf = Microfacet::new(DistributionKind::Ggx, 1.0, 1.0);
        let z = Vec3::new(0.0, 0.0, 1.0);
        for masking in [MaskingKind::Separable, MaskingKind::HeightCorrelated] {
            let e = directional_albedo(&mf, masking, z);
            assert!((e - (1.0 - std::f64::consts::LN_2)).abs() < 1e-6, "{e}");
        }
    }

    /// The fast rule agrees with the adaptive reference, including the V-groove masking
    /// (isotropic, and anisotropic along an axis; off-axis anisotropic cases are checked
    /// against a product rule over the visible-normal sampler below).
    #[test]
    fn quadrature_matches_the_adaptive_reference() {
        for kind in [DistributionKind::Ggx, DistributionKind::Beckmann] {
            for masking in [MaskingKind::Separable, MaskingKind::HeightCorrelated, MaskingKind::VGroove] {
                for &(ax, ay, phi) in &[
                    (0.01, 0.01, 0.7),
                    (0.1, 0.1, 0.7),
                    (1.0, 1.0, 0.7),
                    (0.05, 0.5, 0.0),
                    (0.05, 0.5, std::f64::consts::FRAC_PI_2),
                ] {
                    if masking == MaskingKind::VGroove && ax != ay {
                        // The models use V-groove masking with isotropic roughness only.
                        continue;
                    }
                    let mf = Microfacet::new(kind, ax, ay);
                    for &mu in &[0.9, 0.3, 0.02, 0.002] {
                        let wo = dir(mu, phi);
                        let fast = directional_albedo(&mf, masking, wo);
                        let slow = directional_albedo_adaptive(&mf, masking, wo, 1e-8);
                        // The V-groove's second kink is located numerically: less accurate.
                        let tol = if masking == MaskingKind::VGroove { 3e-4 } else { 5e-5 };
                        assert!(
                            (fast - slow).abs() < tol,
                            "{kind:?} {masking:?} α=({ax},{ay}) μ={mu}: {fast} vs {slow}"
                        );
                    }
                }
            }
        }
    }

    /// Off-axis anisotropic: against a 400×400 Gauss-Legendre rule over the unit square of
    /// the visible-normal sampler (an independent parametrisation of the same integral).
    #[test]
    fn anisotropic_quadrature_matches_a_visible_normal_product_rule() {
        let mf = Microfacet::new(DistributionKind::Ggx, 0.05, 0.5);
        let (x, w) = gauss_legendre(400);
        for &(mu, phi) in &[(0.9, 0.7), (0.5, 0.7), (0.3, 2.0)] {
            let wo = dir(mu, phi);
            let mut reference = 0.0;
            for (a, wa) in x.iter().zip(&w) {
                for (b, wb) in x.iter().zip(&w) {
                    let m = mf.sample_m(wo, 0.5 * (a + 1.0), 0.5 * (b + 1.0), true);
                    let wi = reflect(wo, m);
                    if wi.z > 0.0 {
                        let g = mf.g(wi, wo, m, MaskingKind::Separable) / mf.g1(wo, m);
                        reference += 0.25 * wa * wb * g;
                    }
                }
            }
            let fast = directional_albedo(&mf, MaskingKind::Separable, wo);
            assert!((fast - reference).abs() < 3e-4, "μ={mu} φ={phi}: {fast} vs {reference}");
        }
    }

    /// The interpolated table reproduces the node integral between its nodes.
    #[test]
    fn interpolation_error_is_small() {
        let cases: &[(f64, f64, f64)] = &[
            (0.001, 0.001, 1e-3),
            (0.01, 0.01, 1e-3),
            (0.2, 0.2, 1e-3),
            (1.0, 1.0, 1e-3),
            (0.01, 0.3, 2e-3),
            (1.0, 0.001, 2e-3),
        ];
        for kind in [DistributionKind::Ggx, DistributionKind::Beckmann] {
            for &(ax, ay, limit) in cases {
                let t = AlbedoTable::new(kind, MaskingKind::Separable, ax, ay);
                let mf = Microfacet::new(kind, ax, ay);
                let mut worst: f64 = 0.0;
                for &mu in &[0.97, 0.55, 0.12, 0.05, 0.011, 0.003] {
                    for &phi in &[0.1, 0.7, 1.4, 4.0] {
                        let wo = dir(mu, phi);
                        let exact = directional_albedo(&mf, MaskingKind::Separable, wo);
                        worst = worst.max((t.e(wo) - exact).abs());
                    }
                }
                assert!(worst < limit, "{kind:?} α=({ax},{ay}): {worst}");
            }
        }
    }

    /// E(μ) → 1 as α → 0 (a smooth mirror loses nothing), and E < 1 for rough surfaces.
    #[test]
    fn albedo_tends_to_one_for_smooth_surfaces() {
        for kind in [DistributionKind::Ggx, DistributionKind::Beckmann] {
            let smooth = AlbedoTable::new(kind, MaskingKind::Separable, 1e-3, 1e-3);
            for &mu in &[1.0f64, 0.5, 0.1] {
                assert!((smooth.e(dir(mu, 0.0)) - 1.0).abs() < 1e-3);
            }
            assert!(smooth.e_avg() > 0.99);
            let rough = AlbedoTable::new(kind, MaskingKind::Separable, 1.0, 1.0);
            assert!(rough.e_avg() < 0.9, "{}", rough.e_avg());
        }
    }

    /// The lobe is symmetric in its arguments (reciprocity), in both precisions.
    /// Weighted tables: a constant weight scales the albedo (linearity of the integral), and
    /// for a nearly smooth surface the Fresnel-weighted albedo is the Fresnel reflectance at
    /// the viewing angle (the mirror limit; 4 % for glass at normal incidence).
    #[test]
    fn weighted_tables_scale_and_reach_the_mirror_limit() {
        let plain = AlbedoTable::new(DistributionKind::Ggx, MaskingKind::HeightCorrelated, 0.4, 0.4);
        let half = AlbedoTable::weighted(DistributionKind::Ggx, MaskingKind::HeightCorrelated, 0.4, 0.4, &|_| 0.5);
        for mu in [1.0, 0.6, 0.2, 0.03] {
            let w = dir(mu, 0.0);
            assert!((half.e(w) - 0.5 * plain.e(w)).abs() < 1e-12, "μ {mu}");
        }
        let key = WeightKey::new("test_dielectric", &[1.5]);
        let smooth =
            AlbedoTable::cached_weighted(DistributionKind::Ggx, MaskingKind::HeightCorrelated, 2e-3, 2e-3, key, &|c| {
                crate::fresnel::dielectric(c, 1.5)
            });
        assert!((smooth.e(dir(1.0, 0.0)) - 0.04).abs() < 1e-4, "{}", smooth.e(dir(1.0, 0.0)));
        let mu: f64 = 0.5;
        assert!((smooth.e(dir(mu, 0.0)) - crate::fresnel::dielectric(mu, 1.5)).abs() < 1e-3);
        // The same key returns the same shared table.
        let again = AlbedoTable::cached_weighted(
            DistributionKind::Ggx,
            MaskingKind::HeightCorrelated,
            2e-3,
            2e-3,
            key,
            &|_| 0.0,
        );
        assert!(Arc::ptr_eq(&smooth, &again));
    }

    #[test]
    fn compensation_lobe_is_reciprocal() {
        let t = AlbedoTable::new(DistributionKind::Ggx, MaskingKind::Separable, 0.2, 0.7);
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..1000 {
            let a = cosine_hemisphere(rng.uniform(), rng.uniform());
            let b = cosine_hemisphere(rng.uniform(), rng.uniform());
            assert_eq!(t.f_ms(a, b), t.f_ms(b, a));
            assert_eq!(t.f_ms(a.cast::<f32>(), b.cast()), t.f_ms(b.cast::<f32>(), a.cast()));
        }
    }

    #[test]
    fn fresnel_factor_is_one_for_a_perfect_mirror_and_bounded() {
        assert!((fresnel_average(|_| 1.0) - 1.0).abs() < 1e-14);
        // 2∫ μ·μ dμ = 2/3.
        assert!((fresnel_average(|mu| mu) - 2.0 / 3.0).abs() < 1e-14);
        assert!((ms_fresnel_factor(1.0, 0.7) - 1.0).abs() < 1e-15);
        for &f in &[0.0, 0.3, 0.9] {
            for &e in &[0.2, 0.9] {
                let m = ms_fresnel_factor(f, e);
                assert!((0.0..=1.0).contains(&m));
            }
        }
    }
}
