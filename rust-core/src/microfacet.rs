//! Microfacet distributions (Beckmann, GGX/Trowbridge-Reitz; isotropic and anisotropic),
//! Smith masking (separable and height-correlated), the V-groove masking of Cook-Torrance,
//! and sampling of the full and the visible normal distribution.
//!
//! References: Walter et al. 2007 (GGX, Smith G1); Heitz 2014 ("Understanding the
//! masking-shadowing function", Λ and the height-correlated G); Heitz & d'Eon 2014 (visible
//! normal sampling); Dupuy & Benyoub 2023 (spherical-cap VNDF sampling for GGX);
//! Cook & Torrance 1981 / Blinn 1977 (V-groove G).
//!
//! Roughness is the slope-space `α` (Beckmann: RMS slope·√2⁻¹ convention of Walter et al.;
//! α_x along the tangent, α_y along the bitangent).

use crate::frame::{cos2_theta, cos_theta, half_vector_masked};
use crate::lanes::{self, eq, gt, keep, le, lt, select, sqr, Lanes, Mask};
use crate::math::Vec3;
use crate::real::Real;

/// The shape of the microfacet normal distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DistributionKind {
    /// Beckmann-Spizzichino (Gaussian slopes).
    Beckmann,
    /// Trowbridge-Reitz, a.k.a. GGX (Student-t slopes with heavy tails).
    Ggx,
}

/// How masking and shadowing are combined into the bidirectional G.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MaskingKind {
    /// `G1(wi)·G1(wo)` (Walter et al. 2007; Mitsuba's default).
    Separable,
    /// `1/(1 + Λ(wi) + Λ(wo))` (Heitz 2014; pbrt-v4's choice).
    HeightCorrelated,
    /// The V-groove (V-cavity) masking of Torrance-Sparrow / Cook-Torrance, [`g_vgroove`];
    /// independent of the distribution's shape.
    VGroove,
}

impl DistributionKind {
    /// The JSON name of a distribution (`"beckmann"`, `"ggx"`), as used by choice parameters.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "beckmann" => Some(Self::Beckmann),
            "ggx" => Some(Self::Ggx),
            _ => None,
        }
    }
}

impl MaskingKind {
    /// The JSON name of a masking combination (`"smith_separable"`,
    /// `"smith_height_correlated"`, `"vgroove"`), as used by choice parameters.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "smith_separable" => Some(Self::Separable),
            "smith_height_correlated" => Some(Self::HeightCorrelated),
            "vgroove" => Some(Self::VGroove),
            _ => None,
        }
    }
}

/// A microfacet distribution with its roughness, instantiated in the working precision.
#[derive(Clone, Copy, Debug)]
pub struct Microfacet<T> {
    /// Distribution shape.
    pub kind: DistributionKind,
    /// Roughness along the tangent (x).
    pub alpha_x: T,
    /// Roughness along the bitangent (y).
    pub alpha_y: T,
    /// `1/α_x` and `1/α_y`, so that `D` multiplies instead of dividing per evaluation.
    inv_alpha: (T, T),
}

impl<T: Lanes> Microfacet<T> {
    /// Builds a distribution; roughness values are taken as given (validated by the caller).
    #[inline(always)]
    #[must_use]
    pub fn new(kind: DistributionKind, alpha_x: T, alpha_y: T) -> Self {
        let one = T::c(1.0);
        Self { kind, alpha_x, alpha_y, inv_alpha: (one / alpha_x, one / alpha_y) }
    }

    /// [`Microfacet::new`] for roughness values that are the same in every lane (a material
    /// parameter): the reciprocals are taken once in f64, so kernels that build the
    /// distribution per batch of lanes do no division for them.
    #[inline(always)]
    #[must_use]
    pub fn uniform(kind: DistributionKind, alpha_x: f64, alpha_y: f64) -> Self {
        Self {
            kind,
            alpha_x: T::c(alpha_x),
            alpha_y: T::c(alpha_y),
            inv_alpha: (T::c(1.0 / alpha_x), T::c(1.0 / alpha_y)),
        }
    }

    /// Normal distribution `D(m)` (1/sr, projected-area normalised: ∫ D(m) cos θm dm = 1).
    #[inline(always)]
    #[must_use]
    pub fn d(&self, m: Vec3<T>) -> T {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let sx = m.x * self.inv_alpha.0;
        let sy = m.y * self.inv_alpha.1;
        let z2 = m.z * m.z;
        let pi = T::c(std::f64::consts::PI);
        let d = match self.kind {
            DistributionKind::Ggx => lanes::div_fast(T::c(1.0), self.ggx_d_denominator(m)),
            DistributionKind::Beckmann => {
                let e = lanes::div_fast(sx * sx + sy * sy, z2);
                lanes::div_fast(lanes::exp(-e), pi * ax * ay * z2 * z2)
            }
        };
        keep(gt(m.z, T::c(0.0)), d)
    }

    /// Smith's auxiliary function `Λ(w)`; infinite at or below the horizon.
    #[inline(always)]
    #[must_use]
    pub fn lambda(&self, w: Vec3<T>) -> T {
        let a2_sin2 = sqr(self.alpha_x * w.x) + sqr(self.alpha_y * w.y);
        let l = match self.kind {
            DistributionKind::Ggx => {
                // (√(1 + α²tan²θ) − 1)/2 written without cancellation.
                let t = lanes::div_fast(a2_sin2, cos2_theta(w));
                lanes::div_fast(t, T::c(2.0) * (T::c(1.0) + lanes::sqrt_fast(T::c(1.0) + t)))
            }
            DistributionKind::Beckmann => beckmann_lambda(w.z, a2_sin2),
        };
        let l = select(eq(a2_sin2, T::c(0.0)), T::c(0.0), l);
        select(le(w.z, T::c(0.0)), T::c(f64::INFINITY), l)
    }

    /// Masking of a single direction by microfacets with normal `m` (0 on back-facing facets).
    #[inline(always)]
    #[must_use]
    pub fn g1(&self, w: Vec3<T>, m: Vec3<T>) -> T {
        let front = gt(w.dot(m) * cos_theta(w), T::c(0.0));
        let g1 = match self.kind {
            // 1/(1 + Λ) = 2/(1 + √(1 + α²tan²θ)) = 2 cos θ/(cos θ + √(cos²θ + α²sin²θ)): one
            // division, no cancellation; 0 at and below the horizon.
            DistributionKind::Ggx => {
                let z = w.z;
                let a2_sin2 = sqr(self.alpha_x * w.x) + sqr(self.alpha_y * w.y);
                keep(gt(z, T::c(0.0)), lanes::div_fast(T::c(2.0) * z, z + lanes::sqrt(z * z + a2_sin2)))
            }
            DistributionKind::Beckmann => T::c(1.0) / (T::c(1.0) + self.lambda(w)),
        };
        keep(front, g1)
    }

    /// Bidirectional masking-shadowing for the chosen combination.
    #[inline(always)]
    #[must_use]
    pub fn g(&self, wi: Vec3<T>, wo: Vec3<T>, m: Vec3<T>, masking: MaskingKind) -> T {
        let front = gt(wi.dot(m), T::c(0.0)) & gt(wo.dot(m), T::c(0.0));
        let g = match masking {
            MaskingKind::Separable => self.g1(wi, m) * self.g1(wo, m),
            MaskingKind::HeightCorrelated => {
                // Λ is +∞ below the horizon, where the fast reciprocal is unspecified: 0 there,
                // as the division gives.
                let den = T::c(1.0) + self.lambda(wi) + self.lambda(wo);
                keep(!eq(den, T::c(f64::INFINITY)), lanes::div_fast(T::c(1.0), den))
            }
            MaskingKind::VGroove => g_vgroove(wi, wo, m),
        };
        keep(front, g)
    }

    /// The reflection lobe's `D(m) G(wi, wo, m) / (4 cos θi cos θo)`, and where `G > 0`.
    ///
    /// For GGX the `4 cos θi cos θo` cancels against `G` (Heitz 2014's visibility form): with
    /// `S(w) = √(cos²θ + α²sin²θ)`, separable masking gives `1/((cos θi + S(wi))(cos θo + S(wo)))`
    /// and height-correlated masking `1/(2 (cos θo S(wi) + cos θi S(wo)))`, so `D` and `G`
    /// together take one division instead of four. Other distributions and masking
    /// combinations evaluate `D G` and divide. Zero where `D` or `G` is.
    #[inline(always)]
    #[must_use]
    pub fn reflection_dg(&self, wi: Vec3<T>, wo: Vec3<T>, m: Vec3<T>, masking: MaskingKind) -> (T, T::Mask) {
        let (dg, positive, _) = self.reflection_dg_pdf(wi, wo, m, masking);
        (dg, positive)
    }

    /// [`Self::reflection_dg`] and, at the same pair, the density of visible-normal reflection
    /// sampling `G1(wo) D(m) / (4 cos θo)` ([`Self::reflection_pdf`] with `visible`, `m` the
    /// half vector; 0 unless `cos θo > 0` and `wo·m > 0`). For GGX the two share `D(m)`'s
    /// denominator and the masking root of `wo`: `G1(wo) = 2 cos θo/(cos θo + S(wo))`, so the
    /// density is `1/(2 π αx αy t² (cos θo + S(wo)))`: one more division where the separate
    /// density takes `D`, `G1` and two divisions.
    #[inline(always)]
    #[must_use]
    pub fn reflection_dg_pdf(&self, wi: Vec3<T>, wo: Vec3<T>, m: Vec3<T>, masking: MaskingKind) -> (T, T::Mask, T) {
        let zero = T::c(0.0);
        let om = wo.dot(m);
        let sampled = gt(wo.z, zero) & gt(om, zero);
        if self.kind == DistributionKind::Ggx && masking != MaskingKind::VGroove {
            let (zi, zo) = (wi.z, wo.z);
            let seen = gt(zi, zero) & gt(zo, zero) & gt(wi.dot(m), zero) & gt(om, zero);
            // Not a closure: closures are not inlined into the `#[target_feature]` kernels.
            let (si, so) = (self.ggx_root(wi), self.ggx_root(wo));
            let visibility_denominator = match masking {
                MaskingKind::Separable => (zi + si) * (zo + so),
                _ => T::c(2.0) * (zo * si + zi * so),
            };
            let d_denominator = self.ggx_d_denominator(m);
            let value = lanes::div_fast(T::c(1.0), d_denominator * visibility_denominator);
            let pdf = lanes::div_fast(T::c(1.0), d_denominator * (T::c(2.0) * (zo + so)));
            let upper = gt(m.z, zero);
            return (keep(seen & upper, value), seen, keep(sampled & upper, pdf));
        }
        let (d, g) = (self.d(m), self.g(wi, wo, m, masking));
        let pdf = keep(sampled, lanes::div_fast(self.g1(wo, m) * d, T::c(4.0) * wo.z));
        (lanes::div_fast(d * g, T::c(4.0) * wi.z * wo.z), gt(g, zero), pdf)
    }

    /// `1/D(m)` of GGX for an upper-hemisphere `m`: `π αx αy t²`, `t = (mx/αx)² + (my/αy)² + mz²`.
    #[inline(always)]
    fn ggx_d_denominator(&self, m: Vec3<T>) -> T {
        let (sx, sy) = (m.x * self.inv_alpha.0, m.y * self.inv_alpha.1);
        let t = sx * sx + sy * sy + m.z * m.z;
        T::c(std::f64::consts::PI) * self.alpha_x * self.alpha_y * t * t
    }

    /// `√(cos²θ + α²sin²θ)` of `w` with the anisotropic `α` (GGX's masking root).
    #[inline(always)]
    fn ggx_root(&self, w: Vec3<T>) -> T {
        lanes::sqrt(w.z * w.z + sqr(self.alpha_x * w.x) + sqr(self.alpha_y * w.y))
    }

    /// Smith masking of a direction on either side of the surface (e.g. a refracted direction
    /// below it): `1/(1 + Λ(w'))` with `w'` mirrored to the upper side, and 0 when `w` sees the
    /// back of the microfacet (`(w·m)·cos θw ≤ 0`).
    #[inline(always)]
    #[must_use]
    pub fn g1_either_side(&self, w: Vec3<T>, m: Vec3<T>) -> T {
        let front = gt(w.dot(m) * cos_theta(w), T::c(0.0));
        keep(front, T::c(1.0) / (T::c(1.0) + self.lambda(Vec3::new(w.x, w.y, lanes::abs(w.z)))))
    }

    /// Density of visible normals seen from `w`: `G1(w) max(0, w·m) D(m) / cos θw`.
    #[inline(always)]
    #[must_use]
    pub fn visible_d(&self, w: Vec3<T>, m: Vec3<T>) -> T {
        let wm = w.dot(m);
        let visible = gt(w.z, T::c(0.0)) & gt(wm, T::c(0.0));
        keep(visible, lanes::div_fast(self.g1(w, m) * wm * self.d(m), w.z))
    }

    /// Samples a microfacet normal. With `visible` the density is [`Self::visible_d`]
    /// (requires `w.z > 0`), otherwise `D(m) cos θm`.
    #[inline(always)]
    #[must_use]
    pub fn sample_m(&self, w: Vec3<T>, u1: T, u2: T, visible: bool) -> Vec3<T> {
        match (visible, self.kind) {
            (true, DistributionKind::Ggx) => self.sample_visible_ggx(w, u1, u2),
            (true, DistributionKind::Beckmann) => {
                sample_visible_beckmann(self.alpha_x, self.alpha_y, w, u1, u2, T::Mask::splat(true))
            }
            (false, _) => self.per_lane(w, u1, u2, |mf, _, u1, u2| mf.sample_full(u1, u2)),
        }
    }

    /// Runs a scalar sampler on each lane.
    #[inline(always)]
    fn per_lane(
        &self,
        w: Vec3<T>,
        u1: T,
        u2: T,
        f: impl Fn(&Microfacet<T::Elem>, Vec3<T::Elem>, T::Elem, T::Elem) -> Vec3<T::Elem>,
    ) -> Vec3<T> {
        use crate::lanes::MAX_WIDTH;
        assert!(T::WIDTH <= MAX_WIDTH, "lane type wider than {MAX_WIDTH}");
        let mut out = [Vec3::<T::Elem>::zero(); MAX_WIDTH];
        for (i, o) in out.iter_mut().enumerate().take(T::WIDTH) {
            let mf = Microfacet::new(self.kind, self.alpha_x.lane(i), self.alpha_y.lane(i));
            *o = f(&mf, Vec3::new(w.x.lane(i), w.y.lane(i), w.z.lane(i)), u1.lane(i), u2.lane(i));
        }
        Vec3::new(T::from_fn(|i| out[i].x), T::from_fn(|i| out[i].y), T::from_fn(|i| out[i].z))
    }

    /// Density of [`Self::sample_m`] with the same `visible` flag.
    #[inline(always)]
    #[must_use]
    pub fn pdf_m(&self, w: Vec3<T>, m: Vec3<T>, visible: bool) -> T {
        if visible {
            self.visible_d(w, m)
        } else {
            self.d(m) * lanes::max(m.z, T::c(0.0))
        }
    }

    /// [`Self::sample_reflection`] per lane: the direction and where it is valid (above the
    /// horizon and finite).
    #[inline(always)]
    #[must_use]
    pub fn sample_reflection_masked(&self, wo: Vec3<T>, u1: T, u2: T, visible: bool) -> (Vec3<T>, T::Mask) {
        let m = self.sample_m(wo, u1, u2, visible);
        let wi = crate::frame::reflect(wo, m);
        (wi, gt(wi.z, T::c(0.0)) & wi.finite_mask())
    }

    /// Solid-angle density of [`Self::sample_reflection`] at `wi` for `wo` (both above the
    /// surface): `pdf_m(h) / (4 wo·h)` with `h` the half vector, written without the
    /// cancelling `wo·h` for visible normals (`G1(wo) D(h) / (4 cos θo)`).
    #[inline(always)]
    #[must_use]
    pub fn reflection_pdf(&self, wi: Vec3<T>, wo: Vec3<T>, visible: bool) -> T {
        let (h, defined) = half_vector_masked(wi, wo);
        let oh = wo.dot(h);
        let ok = defined & gt(oh, T::c(0.0)) & gt(wo.z, T::c(0.0));
        let pdf = if visible {
            self.visible_reflection_pdf(wo, h)
        } else {
            self.d(h) * lanes::max(h.z, T::c(0.0)) / (T::c(4.0) * oh)
        };
        keep(ok, pdf)
    }

    /// Solid-angle density of the direction that `wo` reflects to on a visible normal `m`
    /// drawn by [`Self::sample_m`]: `G1(wo) D(m) / (4 cos θo)` (0 where `m` faces down). For
    /// GGX in closed form, `1/(2π αx αy t² (cos θo + √(cos²θo + α²sin²θo)))`: one division
    /// and one root instead of three divisions. The caller masks `wo` below the surface and
    /// `wo·m ≤ 0`.
    #[inline(always)]
    #[must_use]
    pub fn visible_reflection_pdf(&self, wo: Vec3<T>, m: Vec3<T>) -> T {
        match self.kind {
            // The density of `reflection_dg_pdf`, the same expression.
            DistributionKind::Ggx => self.ggx_visible_reflection_pdf(wo.z, self.ggx_root(wo), m),
            DistributionKind::Beckmann => lanes::div_fast(self.g1(wo, m) * self.d(m), T::c(4.0) * wo.z),
        }
    }

    /// A visible normal `m` drawn for `wo` ([`Self::sample_m`] with `visible`) and the density
    /// of the direction `wo` reflects to about it ([`Self::visible_reflection_pdf`]). For GGX
    /// the sampler's stretched direction `(αx wx, αy wy, wz)` has the length
    /// `√(cos²θo + α²sin²θo)` that the density's masking term needs: one reciprocal square
    /// root serves both (the separate calls take it twice, once as a square root).
    #[inline(always)]
    #[must_use]
    pub fn sample_visible_with_pdf(&self, wo: Vec3<T>, u1: T, u2: T) -> (Vec3<T>, T) {
        if self.kind == DistributionKind::Ggx {
            let (m, root) = self.sample_visible_ggx_with_root(wo, u1, u2);
            return (m, self.ggx_visible_reflection_pdf(wo.z, root, m));
        }
        let m = self.sample_m(wo, u1, u2, true);
        (m, self.visible_reflection_pdf(wo, m))
    }

    /// GGX's visible-normal reflection density from the masking root `S(wo)` of `wo`
    /// ([`Self::visible_reflection_pdf`]).
    #[inline(always)]
    fn ggx_visible_reflection_pdf(&self, cos_o: T, root: T, m: Vec3<T>) -> T {
        keep(gt(m.z, T::c(0.0)), lanes::div_fast(T::c(1.0), self.ggx_d_denominator(m) * (T::c(2.0) * (cos_o + root))))
    }

    /// GGX visible normals by the spherical-cap method (Dupuy & Benyoub 2023).
    #[inline(always)]
    fn sample_visible_ggx(&self, w: Vec3<T>, u1: T, u2: T) -> Vec3<T> {
        self.sample_visible_ggx_with_root(w, u1, u2).0
    }

    /// [`Self::sample_visible_ggx`] and the length `S(w)` of the stretched direction (GGX's
    /// masking root, [`Self::ggx_root`]).
    #[inline(always)]
    fn sample_visible_ggx_with_root(&self, w: Vec3<T>, u1: T, u2: T) -> (Vec3<T>, T) {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let stretched = Vec3::new(ax * w.x, ay * w.y, w.z);
        let length_squared = stretched.length_squared();
        let inverse_length = lanes::rsqrt_fast(length_squared);
        let ws = stretched * inverse_length;
        let phi = T::c(std::f64::consts::TAU) * u1;
        let z = (T::c(1.0) - u2) * (T::c(1.0) + ws.z) - ws.z;
        let sin_t = lanes::safe_sqrt(T::c(1.0) - z * z);
        let (sin_phi, cos_phi) = lanes::sin_cos(phi);
        let cap = Vec3::new(sin_t * cos_phi, sin_t * sin_phi, z);
        let h = cap + ws;
        let m = Vec3::new(ax * h.x, ay * h.y, lanes::max(h.z, T::c(0.0))).normalize();
        (m, length_squared * inverse_length)
    }
}

/// Beckmann visible normals, per lane: the stretched configuration's visible slope
/// distribution is `p(x̃) ∝ max(0, cot θ − x̃)·e^{−x̃²}` along the azimuth of `w` and Gaussian
/// across it (Heitz & d'Eon 2014). Its CDF is inverted by [`beckmann_visible_slope`]. Lanes
/// outside `active` get an unspecified direction and do not hold up the iteration.
#[inline(always)]
pub(crate) fn sample_visible_beckmann<T: Lanes>(ax: T, ay: T, w: Vec3<T>, u1: T, u2: T, active: T::Mask) -> Vec3<T> {
    let ws = Vec3::new(ax * w.x, ay * w.y, w.z).normalize();
    let sin_t = lanes::sqrt(ws.x * ws.x + ws.y * ws.y);
    let tilted = gt(sin_t, T::c(1e-12));
    let safe_sin = select(tilted, sin_t, T::c(1.0));
    let (cos_phi, sin_phi) = (select(tilted, ws.x / safe_sin, T::c(1.0)), select(tilted, ws.y / safe_sin, T::c(0.0)));
    // u in [1e-12, 1 − 1e-12], or the largest float below one when that rounds to one (f32).
    let eps = <T::Elem as num_traits::Float>::epsilon().f64();
    let (lo, hi) = (T::c(1e-12), T::c(1.0 - (0.5 * eps).max(1e-12)));
    let (u1, u2) = (lanes::clamp(u1, lo, hi), lanes::clamp(u2, lo, hi));
    let normal_incidence = lt(sin_t, T::c(1e-9));
    let slope_x = select(
        normal_incidence,
        lanes::erfinv(T::c(2.0) * u1 - T::c(1.0)),
        beckmann_visible_slope(ws.z / safe_sin, u1, active & !normal_incidence),
    );
    let slope_y = lanes::erfinv(T::c(2.0) * u2 - T::c(1.0));
    // Rotate back to the azimuth of w, then unstretch the slopes.
    let sx = cos_phi * slope_x - sin_phi * slope_y;
    let sy = sin_phi * slope_x + cos_phi * slope_y;
    Vec3::new(-ax * sx, -ay * sy, T::c(1.0)).normalize()
}

/// Inverts the CDF of the visible slope `x̃` for `cot θ = cot` at probability `u`, on the lanes
/// in `active`: `CDF(x̃) = cot·erfc(−x̃)/2 + e^{−x̃²}/(2√π)` up to `min(cot, 8)`, by Newton steps
/// safeguarded with bisection inside a shrinking bracket, from `erfinv(2u − 1)` (the slope at
/// normal incidence). A lane stops when the CDF matches to 4.5 ulp (f64) or 32 ulp (f32) or
/// its bracket closes to that width; the loop stops when all active lanes have (≤ 100 steps;
/// measured on `gold_flake_8` with uniform `u`: 2.8 steps per 16-lane call, the slowest lane).
#[inline(always)]
fn beckmann_visible_slope<T: Lanes>(cot: T, u: T, active: T::Mask) -> T {
    let inv_sqrt_pi = T::c(0.5 * std::f64::consts::FRAC_2_SQRT_PI);
    let half = T::c(0.5);
    // Stopping tolerance: 4.5 ulp in f64; in f32 32 ulp (3.8e-6), above the ≈ 6 ulp noise of
    // the polynomial erfc/exp, which a tighter tolerance would chase for extra steps.
    let ulp = <T::Elem as num_traits::Float>::epsilon().f64();
    let eps = T::c(if ulp < 1e-10 { 4.5 * ulp } else { 32.0 * ulp });
    let hi0 = lanes::min(cot, T::c(8.0));
    let cdf_hi = half * cot * lanes::erfc(-hi0) + half * inv_sqrt_pi * lanes::exp(-hi0 * hi0);
    let target = u * cdf_hi;
    let tolerance = eps * lanes::max(target, T::c(1e-300));
    let (mut lo, mut hi) = (T::c(-8.0), hi0);
    let mut x = lanes::clamp(lanes::erfinv(T::c(2.0) * u - T::c(1.0)), lo, hi);
    let mut done = !active;
    for _ in 0..100 {
        let gauss = lanes::exp(-x * x);
        let value = half * cot * lanes::erfc(-x) + half * inv_sqrt_pi * gauss - target;
        done = done | le(lanes::abs(value), tolerance);
        if done.all() {
            break;
        }
        let above = gt(value, T::c(0.0));
        hi = select(above & !done, x, hi);
        lo = select(!above & !done, x, lo);
        let deriv = (cot - x) * inv_sqrt_pi * gauss;
        let newton = x - value / deriv;
        let inside = gt(deriv, T::c(0.0)) & gt(newton, lo) & lt(newton, hi);
        x = select(done, x, select(inside, newton, half * (lo + hi)));
        done = done | lt(hi - lo, eps * lanes::max(lanes::abs(x), T::c(1.0)));
        if done.all() {
            break;
        }
    }
    x
}

/// Beckmann's Λ from `cos θ` and `α² sin² θ` (> 0): with `a = 1/(α tan θ)`,
/// `Λ = (e^{−a²}/(a√π) − erfc(a))/2` (0 beyond `a = 26`). `erfc` is `special::erfc` in the
/// scalar paths and the f32 polynomial in SIMD lanes ([`lanes::erfc`]).
///
/// When every lane has `a` ≥ [`beckmann_lambda_negligible_from`] (Λ below a quarter of the
/// precision's epsilon: 1 + Λi + Λo rounds to 1) it returns 0 without the `exp` and `erfc`:
/// every use of Beckmann's Λ in the crate is `1 + Λ` or `1 + Λi + Λo` (`g1`, `g`,
/// `g1_either_side`; the raw Λ in `paint::rough_dielectric` and `paint::coat` is GGX's), which
/// then come out bit for bit as with the full formula. Flakes seen through a coat are the common case: `gold_flake_8`'s flakes
/// (α = tan 12°) under η 1.5 have `a` ≥ 5.3 for every refracted direction.
#[inline(always)]
fn beckmann_lambda<T: Lanes>(cos_theta: T, a2_sin2: T) -> T {
    // At a2_sin2 = 0 (normal incidence) `a` is huge instead of ∞: Λ is 0 either way.
    let a2_sin2 = lanes::max(a2_sin2, T::c(f64::from(f32::MIN_POSITIVE)));
    // `a ≥ a0` is `cos θ > 0` and `cos²θ ≥ a0² α²sin²θ`: tested on the squares, the common
    // case (every lane past the threshold) needs neither the division nor the root. Where
    // the rounded test and the rounded `a` disagree, `a` is within an ulp or two of `a0`,
    // where the full formula's Λ is below a quarter of epsilon too: the same `1 + Λ`.
    let a0 = beckmann_lambda_negligible_from::<T::Elem>();
    if (gt(cos_theta, T::c(0.0)) & gt(cos_theta * cos_theta, T::c(a0 * a0) * a2_sin2)).all() {
        return T::c(0.0);
    }
    beckmann_lambda_of_a(lanes::div_fast(cos_theta, lanes::sqrt_fast(a2_sin2)))
}

/// Beckmann's Λ from `a = 1/(α tan θ)` (> 0) by the full formula (no shortcut).
#[inline(always)]
fn beckmann_lambda_of_a<T: Lanes>(a: T) -> T {
    let inv_sqrt_pi = T::c(0.5 * std::f64::consts::FRAC_2_SQRT_PI);
    // The Gaussian and erfc together: SIMD lanes take both from one polynomial (one `exp` fewer).
    let (gauss, erfc) = lanes::gauss_erfc(a);
    let l = lanes::max(lanes::div_fast(gauss * inv_sqrt_pi, a) - erfc, T::c(0.0)) * T::c(0.5);
    keep(le(a, T::c(26.0)), l)
}

/// The `a = 1/(α tan θ)` from which Beckmann's Λ is below a quarter of `E`'s epsilon (so that
/// `1 + Λi + Λo` rounds to 1): 3.5 for `f32` (Λ(3.5) = 1.41e-8 < 2⁻²³/4 = 2.98e-8) and 5.8 for
/// `f64` (Λ(5.8) = 1.70e-18 < 2⁻⁵²/4 = 5.55e-17); Λ decreases with `a`. Values from mpmath at
/// 50 digits; test `beckmann_lambda_is_negligible_from_its_threshold`.
#[inline(always)]
fn beckmann_lambda_negligible_from<E: Real>() -> f64 {
    if <E as num_traits::Float>::epsilon().f64() > 1e-10 {
        3.5
    } else {
        5.8
    }
}

impl<T: Real> Microfacet<T> {
    /// Radial CDF of the projected-area distribution `D(m) cos θm`: the fraction of projected
    /// microfacet area whose normals lie inside the (stretched) slope ellipse through `m`, i.e.
    /// `1 − e^{−e}` (Beckmann) or `e/(1 + e)` (GGX) with `e = (m_x/(α_x m_z))² + (m_y/(α_y m_z))²`.
    /// It inverts the radial part of the full-distribution sampler: the normal that
    /// [`Self::sample_m`] (with `visible = false`) draws from `(u1, u2)` has `radial_cdf = u1`.
    /// Exact 1 at and below the horizon.
    #[inline]
    #[must_use]
    pub fn radial_cdf(&self, m: Vec3<T>) -> T {
        if !(m.z > T::zero()) {
            return T::one();
        }
        let e = (m.x / (self.alpha_x * m.z)).sqr() + (m.y / (self.alpha_y * m.z)).sqr();
        if !e.is_finite() {
            return T::one();
        }
        match self.kind {
            DistributionKind::Beckmann => -(-e).exp_m1(),
            DistributionKind::Ggx => e / (T::one() + e),
        }
    }

    /// Samples a reflected direction: `wi` is the mirror of `wo` about a normal drawn by
    /// [`Self::sample_m`]; `None` when `wi` falls at or below the horizon (the density of
    /// [`Self::reflection_pdf`] then integrates to less than one over the upper hemisphere).
    #[inline]
    #[must_use]
    pub fn sample_reflection(&self, wo: Vec3<T>, u1: T, u2: T, visible: bool) -> Option<Vec3<T>> {
        let (wi, valid) = self.sample_reflection_masked(wo, u1, u2, visible);
        valid.then_some(wi)
    }

    /// Density of the diffuse + specular mixture of the Cook-Torrance-style models: with
    /// probability `ps` reflection off a visible normal ([`Self::reflection_pdf`]), else the
    /// cosine lobe.
    #[inline]
    #[must_use]
    pub fn mixed_with_cosine_pdf(&self, ps: T, wi: Vec3<T>, wo: Vec3<T>) -> T {
        ps * self.reflection_pdf(wi, wo, true) + (T::one() - ps) * crate::sampling::cosine_hemisphere_pdf(wi.z)
    }

    /// Samples the mixture of [`Self::mixed_with_cosine_pdf`]: `u[0] < ps` picks the visible-
    /// normal reflection ([`Self::sample_reflection`]), otherwise the cosine lobe.
    #[inline]
    #[must_use]
    pub fn sample_mixed_with_cosine(&self, ps: T, wo: Vec3<T>, u: [T; 3]) -> Option<Vec3<T>> {
        if u[0] < ps {
            self.sample_reflection(wo, u[1], u[2], true)
        } else {
            Some(crate::sampling::cosine_hemisphere(u[1], u[2]))
        }
    }

    /// Samples `D(m) cos θm` by inverting its CDF (anisotropic φ as in Walter et al. 2007).
    fn sample_full(&self, u1: T, u2: T) -> Vec3<T> {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let two_pi = T::of(2.0) * T::PI();
        // Azimuth of the stretched ellipse, then the per-azimuth roughness.
        let mut phi = (ay / ax * (two_pi * u2).tan()).atan();
        if u2 > T::of(0.25) && u2 <= T::of(0.75) {
            phi += T::PI();
        } else if u2 > T::of(0.75) {
            phi += two_pi;
        }
        let (sin_phi, cos_phi) = phi.sin_cos();
        let inv_a2 = (cos_phi / ax).sqr() + (sin_phi / ay).sqr();
        let tan2 = match self.kind {
            DistributionKind::Ggx => u1 / ((T::one() - u1).max(T::epsilon()) * inv_a2),
            DistributionKind::Beckmann => -(T::one() - u1).max(T::min_positive_value()).ln() / inv_a2,
        };
        let cos_t = T::one() / (T::one() + tan2).sqrt();
        let sin_t = (T::one() - cos_t * cos_t).safe_sqrt();
        Vec3::new(sin_t * cos_phi, sin_t * sin_phi, cos_t)
    }
}

/// The V-groove masking-shadowing of Torrance-Sparrow / Cook-Torrance:
/// `min(1, 2(n·h)(n·wo)/(wo·h), 2(n·h)(n·wi)/(wo·h))`.
#[inline(always)]
#[must_use]
pub fn g_vgroove<T: Lanes>(wi: Vec3<T>, wo: Vec3<T>, h: Vec3<T>) -> T {
    let oh = wo.dot(h);
    let front = gt(oh, T::c(0.0)) & gt(wi.dot(h), T::c(0.0));
    let two_nh = T::c(2.0) * h.z;
    let g = lanes::min(lanes::min(T::c(1.0), two_nh * wo.z / oh), two_nh * wi.z / oh);
    keep(front, lanes::max(g, T::c(0.0)))
}

/// Jacobian of the reflection half-vector map: `dω_h/dω_i = 1/(4 |wo·h|)`.
#[inline(always)]
#[must_use]
pub fn reflection_jacobian<T: Lanes>(wo: Vec3<T>, h: Vec3<T>) -> T {
    let oh = lanes::abs(wo.dot(h));
    keep(gt(oh, T::c(0.0)), lanes::div_fast(T::c(1.0), T::c(4.0) * oh))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::spherical_direction;
    use crate::rng::Pcg32;

    fn dists() -> Vec<Microfacet<f64>> {
        let mut v = Vec::new();
        for kind in [DistributionKind::Beckmann, DistributionKind::Ggx] {
            for (ax, ay) in [(0.1, 0.1), (0.5, 0.5), (0.05, 0.4), (1.0, 0.3)] {
                v.push(Microfacet::new(kind, ax, ay));
            }
        }
        v
    }

    /// ∫ D(m) cos θm dω = 1, by quadrature in (cos θ, φ) with the substitution tan θ = α·s.
    #[test]
    fn projected_area_of_d_is_one() {
        for mf in dists() {
            let (nt, np) = (4000, 256);
            let mut sum = 0.0;
            for i in 0..nt {
                // θ on [0, π/2) with midpoint rule in a warped variable concentrating near 0.
                let t = (i as f64 + 0.5) / nt as f64;
                let theta = t * t * std::f64::consts::FRAC_PI_2;
                let dtheta = 2.0 * t / nt as f64 * std::f64::consts::FRAC_PI_2;
                for j in 0..np {
                    let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                    let m = spherical_direction(theta.sin(), theta.cos(), phi);
                    sum += mf.d(m) * m.z * theta.sin() * dtheta * (2.0 * std::f64::consts::PI / np as f64);
                }
            }
            assert!((sum - 1.0).abs() < 2e-3, "{mf:?}: {sum}");
        }
    }

    /// The visible normal density integrates to one (Heitz 2014, eq. 18): checks Λ and G1.
    #[test]
    fn visible_normals_integrate_to_one() {
        let mut rng = Pcg32::new(7, 1);
        for mf in dists() {
            for &cos_w in &[0.95, 0.5, 0.1] {
                let w = spherical_direction((1.0f64 - cos_w * cos_w).sqrt(), cos_w, 0.7);
                // Importance-sample D(m) cos θm (exact) and average D_w(m)/(D cos θm).
                let n = 200_000;
                let mut s = 0.0;
                for _ in 0..n {
                    let m = mf.sample_m(w, rng.uniform(), rng.uniform(), false);
                    let p = mf.pdf_m(w, m, false);
                    if p > 0.0 {
                        s += mf.visible_d(w, m) / p;
                    }
                }
                let mean = s / n as f64;
                assert!((mean - 1.0).abs() < 0.02, "{mf:?} cos {cos_w}: {mean}");
            }
        }
    }

    /// `radial_cdf` inverts the full-distribution sampler's radial coordinate.
    #[test]
    fn radial_cdf_inverts_the_full_sampler() {
        for mf in dists() {
            for &u1 in &[1e-6, 0.01, 0.3, 0.5, 0.9, 0.999] {
                for &u2 in &[0.03, 0.3, 0.6, 0.95] {
                    let m = mf.sample_m(Vec3::new(0.0, 0.0, 1.0), u1, u2, false);
                    let c = mf.radial_cdf(m);
                    assert!((c - u1).abs() < 1e-9 * (1.0 + 1.0 / (1.0 - u1)), "{mf:?} u1 {u1} u2 {u2}: {c}");
                }
            }
        }
    }

    #[test]
    fn ggx_lambda_matches_closed_form() {
        // Isotropic GGX: Λ = (−1 + √(1 + α² tan²θ))/2.
        let mf = Microfacet::new(DistributionKind::Ggx, 0.3f64, 0.3);
        let w = spherical_direction(0.6f64, 0.8, 1.1);
        let expect = (-1.0 + (1.0 + 0.09 * (0.36 / 0.64f64)).sqrt()) / 2.0;
        assert!((mf.lambda(w) - expect).abs() < 1e-15);
    }

    /// The shortcut of `beckmann_lambda` (0 when every lane's `a` is past the threshold) gives
    /// `G1` and the height-correlated `G2` bit for bit as the full formula, in f64, f32 and
    /// every SIMD type this CPU has, for `a` from the threshold to 40; and the threshold's Λ
    /// (mpmath, 50 digits: Λ(3.5) = 1.4124e-8, Λ(5.8) = 1.702e-18) is what the full formula
    /// computes there and below a quarter of the precision's epsilon.
    #[test]
    fn beckmann_lambda_is_negligible_from_its_threshold() {
        fn check<L: Lanes>() {
            let a0 = beckmann_lambda_negligible_from::<L::Elem>();
            let eps = <L::Elem as num_traits::Float>::epsilon().f64();
            let golden = if eps > 1e-10 { 1.4124e-8 } else { 1.702e-18 };
            assert!(golden < eps / 4.0, "threshold {a0}: Λ {golden} ≥ ε/4");
            let full = beckmann_lambda_of_a(L::c(a0)).lane(0).f64();
            assert!((full - golden).abs() < 1e-3 * golden + 1e-3 * eps, "Λ({a0}) = {full}, mpmath {golden}");
            let alpha = 0.2;
            let mf = Microfacet::new(DistributionKind::Beckmann, L::c(alpha), L::c(alpha));
            let up = Vec3::new(L::c(0.0), L::c(0.0), L::c(1.0));
            for k in 0..2000 {
                // a = 1/(α tan θ) from a0 to 40, lane j a little further on.
                let a = |j: usize| a0 + (40.0 - a0) * ((k * L::WIDTH + j) as f64 / (2000 * L::WIDTH) as f64).powi(2);
                let w = |shift: f64| {
                    let tan = L::from_fn(|j| L::Elem::of(1.0 / (alpha * (a(j) + shift))));
                    let cos = L::c(1.0) / lanes::sqrt(L::c(1.0) + tan * tan);
                    Vec3::new(tan * cos, L::c(0.0), cos)
                };
                let (wi, wo) = (w(0.0), w(0.5));
                let lambda_full = |v: Vec3<L>| beckmann_lambda_of_a(v.z / lanes::sqrt(sqr(L::c(alpha) * v.x)));
                let g1_full = L::c(1.0) / (L::c(1.0) + lambda_full(wi));
                let g2_full = L::c(1.0) / (L::c(1.0) + lambda_full(wi) + lambda_full(wo));
                let g1 = mf.g1(wi, up);
                let g2 = L::c(1.0) / (L::c(1.0) + mf.lambda(wi) + mf.lambda(wo));
                for j in 0..L::WIDTH {
                    let bits = |x: L| x.lane(j).f64().to_bits();
                    assert_eq!(bits(g1), bits(g1_full), "G1 at a = {}: {:?}", a(j), g1.lane(j));
                    assert_eq!(bits(g2), bits(g2_full), "G2 at a = {}: {:?}", a(j), g2.lane(j));
                }
            }
        }
        check::<f64>();
        check::<f32>();
        #[cfg(target_arch = "x86_64")]
        crate::lanes::x86::check_each_simd_type!(check);
    }

    #[test]
    fn g1_either_side_mirrors_below_the_surface() {
        let mf = Microfacet::new(DistributionKind::Beckmann, 0.4f64, 0.2);
        let w = spherical_direction(0.6f64, 0.8, 0.3);
        let below = Vec3::new(w.x, w.y, -w.z);
        let m = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(mf.g1_either_side(w, m), mf.g1(w, m));
        // A refracted direction below the surface sees the facet from behind (w·m < 0).
        assert_eq!(mf.g1_either_side(below, m), mf.g1(w, m));
        assert_eq!(mf.g1_either_side(below, -m), 0.0);
    }

    /// `sample_reflection` draws from exactly `reflection_pdf`: a histogram over cosθi of many
    /// samples against the integrated density (the lost mass below the horizon included).
    /// The cancelled GGX form of `D G / (4 cos θi cos θo)` against the plain product and
    /// division in f64, anisotropic and both Smith combinations, over random directions
    /// including some below the horizon (both must give 0 there). Measured: ≤ 4e-16 relative.
    #[test]
    fn ggx_reflection_dg_matches_the_plain_product() {
        let mut rng = Pcg32::new(5, 11);
        for (ax, ay) in [(0.2, 0.2), (0.05, 0.6), (1.0, 0.001)] {
            let mf = Microfacet::new(DistributionKind::Ggx, ax, ay);
            for masking in [MaskingKind::Separable, MaskingKind::HeightCorrelated] {
                let mut worst = 0.0f64;
                for _ in 0..20_000 {
                    let mut w = || {
                        let z = 2.0 * rng.uniform() - 0.9;
                        spherical_direction((1.0 - z * z).sqrt(), z, 6.3 * rng.uniform())
                    };
                    let (wi, wo) = (w(), w());
                    let (h, defined) = half_vector_masked(wi, wo);
                    if !defined {
                        continue;
                    }
                    let g = mf.g(wi, wo, h, masking);
                    let plain = if g > 0.0 { mf.d(h) * g / (4.0 * wi.z * wo.z) } else { 0.0 };
                    let (fast, g_positive) = mf.reflection_dg(wi, wo, h, masking);
                    assert_eq!(g_positive, g > 0.0, "{wi:?} {wo:?}");
                    if plain == 0.0 {
                        assert_eq!(fast, 0.0, "{wi:?} {wo:?}");
                    } else {
                        worst = worst.max((fast - plain).abs() / plain);
                    }
                }
                assert!(worst < 1e-14, "α ({ax}, {ay}) {masking:?}: {worst:e}");
            }
        }
    }

    /// `sample_visible_with_pdf` draws the normal `sample_m` draws and gives the density
    /// `visible_reflection_pdf` gives at it; for GGX its masking root comes from the sampler's
    /// reciprocal root (`len² · (1/√len²)`, two roundings against one in f64).
    #[test]
    fn sample_with_pdf_matches_the_separate_calls() {
        // The density's relative difference is rounding only: 6.7e-16 at most over 4·10⁵
        // directions for the two GGX cases, replaying the same f64 operations in numpy.
        const TOL: f64 = 1e-13;
        let mut rng = Pcg32::new(11, 4);
        for mf in [
            Microfacet::new(DistributionKind::Ggx, 0.2f64, 0.2),
            Microfacet::new(DistributionKind::Ggx, 0.05, 0.7),
            Microfacet::new(DistributionKind::Beckmann, 0.3, 0.6),
        ] {
            for _ in 0..2000 {
                let mu = rng.uniform().max(1e-3);
                let wo = spherical_direction((1.0 - mu * mu).sqrt(), mu, 6.3 * rng.uniform());
                let (u1, u2) = (rng.uniform(), rng.uniform());
                let (m, pdf) = mf.sample_visible_with_pdf(wo, u1, u2);
                let want_m = mf.sample_m(wo, u1, u2, true);
                assert_eq!((m.x, m.y, m.z), (want_m.x, want_m.y, want_m.z), "{mf:?}");
                let want = mf.visible_reflection_pdf(wo, m);
                assert!(want > 0.0 && (pdf - want).abs() <= TOL * want, "{mf:?}: {pdf} vs {want}");
            }
        }
    }

    #[test]
    fn reflection_sampling_matches_its_density() {
        let mut rng = Pcg32::new(3, 9);
        for mf in [
            Microfacet::new(DistributionKind::Ggx, 0.4f64, 0.4),
            Microfacet::new(DistributionKind::Beckmann, 0.3f64, 0.6),
        ] {
            for visible in [true, false] {
                let wo = spherical_direction(0.6f64, 0.8, 0.4);
                let n = 200_000;
                let bins = 8;
                let mut hist = vec![0.0; bins];
                for _ in 0..n {
                    if let Some(wi) = mf.sample_reflection(wo, rng.uniform(), rng.uniform(), visible) {
                        hist[((wi.z * bins as f64) as usize).min(bins - 1)] += 1.0 / n as f64;
                    }
                }
                // Integrate the density over each cosθ band (midpoint rule, fine grid).
                for (b, h) in hist.iter().enumerate() {
                    let (nm, np) = (100, 200);
                    let mut mass = 0.0;
                    for i in 0..nm {
                        let mu = (b as f64 + (i as f64 + 0.5) / nm as f64) / bins as f64;
                        for j in 0..np {
                            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                            let wi = spherical_direction((1.0 - mu * mu).sqrt(), mu, phi);
                            mass += mf.reflection_pdf(wi, wo, visible);
                        }
                    }
                    mass *= (1.0 / bins as f64 / nm as f64) * (2.0 * std::f64::consts::PI / np as f64);
                    assert!((mass - h).abs() < 5e-3, "{mf:?} visible={visible} band {b}: {mass} vs {h}");
                }
            }
        }
    }

    #[test]
    fn names_parse() {
        assert_eq!(DistributionKind::from_name("ggx"), Some(DistributionKind::Ggx));
        assert_eq!(MaskingKind::from_name("vgroove"), Some(MaskingKind::VGroove));
        assert_eq!(MaskingKind::from_name("smith"), None);
    }

    #[test]
    fn vgroove_is_one_at_normal_incidence() {
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        assert_eq!(g_vgroove(n, n, n), 1.0);
    }
}
