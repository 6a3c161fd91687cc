//! Poulin-Fournier (1990): anisotropic reflection from a surface covered with parallel
//! cylinders, raised from (bumps) or cut into (grooves) a flat base, with self-shadowing and
//! masking, integrated numerically over the cylinders' cross-section.
//!
//! In the plane across the cylinders (radius 1; all lengths in radii) one period of the
//! profile is an arc of normals `n(θ) = (sin θ, cos θ)`, `θ ∈ [−θm, θm]`, `cos θm = 1 − h`,
//! followed by a flat of length `d`; the period is `P = 2 sin θm + d`. The macroscopic BRDF
//! is the average of a local BRDF over the lit and visible part of the profile,
//!
//! ```text
//! f(wi, wo) = 1/(P cos θi cos θo) · ∫_profile f_loc(wi, wo; n) (n·wi)₊ (n·wo)₊ V_i V_o ds
//! ```
//!
//! (radiance balance over one period: lit micro-area `(n·wi) V_i ds`, seen micro-area
//! `(n·wo) V_o ds`). `V_i`, `V_o` are exact for the extruded profile: a ray leaving a point
//! is blocked when it meets a neighbouring cylinder (bumps: the disk of a neighbour, tested
//! for the two neighbours on the ray's side), or when it leaves its own groove below the rim
//! (grooves: the exit point of the chord has height `1 − h − cos(θ + 2β)`, β the elevation of
//! the projected ray). Directions enter only through their projection on the plane across
//! the cylinders; the component along the axis does not change visibility.
//!
//! The local reflector is Lambert plus the normalised reciprocal Phong lobe
//! `f_loc = kd/π + ks (n+2)/(2π) max(0, r·wi)^n`, `r` the mirror of `wo` about the local
//! normal (Lewis 1994); Poulin and Fournier shade the cylinders with Phong's lobe, whose
//! original form is neither reciprocal nor energy conserving. With `kd + ks ≤ 1` the model is
//! reciprocal and conserves energy: the lit micro-area projects exactly onto the macro-area,
//! and each lit element reflects at most what it receives.
//!
//! Integration (the paper's first technique, "sampling the surface of the cylinders"): the
//! arc is cut at every visibility breakpoint (closed forms for the tangent and forward-
//! boundary conditions; each piece is classified at its midpoint by the exact predicate),
//! and each lit-and-visible piece is integrated by 24-point Gauss-Legendre in a sinh-mapped
//! variable centred on the Phong peak `θ* = (π − βi − βo)/2` with the peak's width
//! `√((C + B)/(4nB))`, so sharp lobes are resolved. The flat contributes its lit-and-visible
//! length in closed form. Geometry constants and the sampling nodes depend only on the
//! parameters and are computed once, at build time.
//!
//! | parameter | kind | default | range | unit | meaning |
//! |---|---|---|---|---|---|
//! | `height` | scalar | 0.6 | [0, 1] | radii | height `h` of the cylinders above (bumps) or depth below (grooves) the base |
//! | `spacing` | scalar | 0.5 | [0, 4] | radii | flat gap `d` between neighbouring cylinders |
//! | `profile` | choice | bumps | bumps, grooves | | cylinders added to or subtracted from the base |
//! | `direction` | scalar | 0 | [0, 180] | degrees | angle of the cylinder axis from the tangent x |
//! | `diffuse` | colour | 0.2 | [0, 1] | | Lambertian reflectance `kd` of the cylinder material |
//! | `specular` | colour | 0.6 | [0, 1] | | Phong reflectance `ks` (kd + ks ≤ 1 per channel) |
//! | `exponent` | scalar | 40 | [1, 1000] | | Phong exponent `n` of the local lobe |
//!
//! Sampling (a proxy with an exact density): the profile is discretised once into facets
//! (arc nodes spaced finely enough for the Phong lobe, plus the flat); for `wo` a facet is
//! picked in proportion to its visible projected length `(n_k·wo)₊ V_o Δs_k`, then either the
//! cosine lobe about `n_k` or the Phong lobe about the mirror of `wo` (probabilities from
//! kd and ks), with 10 % of a macro cosine lobe as a defensive component. `pdf` is that finite
//! mixture. References: P. Poulin, A. Fournier, "A model for anisotropic reflection",
//! SIGGRAPH 1990; R. R. Lewis, "Making shaders more physically plausible", 1994.

use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe, power_cosine_around, power_cosine_pdf};
use std::f64::consts::PI;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::scalar(
        "height",
        0.6,
        0.0,
        1.0,
        "radii",
        "height of the cylinders above (bumps) or depth below (grooves) the base",
    ),
    ParamSpec::scalar("spacing", 0.5, 0.0, 4.0, "radii", "flat gap between neighbouring cylinders"),
    ParamSpec::choice(
        "profile",
        "bumps",
        &["bumps", "grooves"],
        "cylinders added to (bumps) or subtracted from (grooves) the base",
    ),
    ParamSpec::scalar("direction", 0.0, 0.0, 180.0, "degrees", "angle of the cylinder axis from the tangent x"),
    ParamSpec::color("diffuse", [0.2; 3], 0.0, 1.0, "Lambertian reflectance kd of the cylinder material"),
    ParamSpec::color("specular", [0.6; 3], 0.0, 1.0, "Phong reflectance ks of the cylinders (kd + ks ≤ 1)"),
    ParamSpec::scalar("exponent", 40.0, 1.0, 1000.0, "", "Phong exponent n of the local lobe"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "poulin_fournier",
    summary: "Poulin-Fournier 1990 anisotropic reflection from parallel cylinders (self-shadowing, masking)",
    reference: "P. Poulin, A. Fournier, A model for anisotropic reflection, SIGGRAPH 1990; local lobe: \
                R. R. Lewis, Making shaders more physically plausible, 1994",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: &[
        r#"{"height": 1.0, "spacing": 0.0, "diffuse": 0.0, "specular": 1.0, "exponent": 20}"#,
        r#"{"height": 0.4, "spacing": 1.5, "profile": "grooves", "direction": 30, "diffuse": [0.5, 0.3, 0.1], "specular": 0.3, "exponent": 8}"#,
        r#"{"height": 0.9, "spacing": 0.2, "diffuse": 0.1, "specular": [0.9, 0.6, 0.3], "exponent": 100, "direction": 90}"#,
    ],
    build,
};

fn build(p: &Params) -> Result<Model, Error> {
    let diffuse = p.color("diffuse");
    let specular = p.color("specular");
    for c in 0..3 {
        if diffuse[c] + specular[c] > 1.0 + 1e-9 {
            return Err(Error::Invalid {
                param: "specular".into(),
                reason: format!(
                    "diffuse + specular must not exceed 1 in any channel (channel {c}: {} + {})",
                    diffuse[c], specular[c]
                ),
            });
        }
    }
    Ok(Model::PoulinFournier(PoulinFournier::new(
        p.scalar("height"),
        p.scalar("spacing"),
        p.choice("profile") == "grooves",
        p.scalar("direction"),
        diffuse,
        specular,
        p.scalar("exponent"),
    )))
}

/// 24-point Gauss-Legendre nodes on [−1, 1] (positive half; symmetric).
#[allow(clippy::excessive_precision)] // the published 17-digit values
const GL24: [(f64, f64); 12] = [
    (0.064_056_892_862_605_63, 0.127_938_195_346_752_16),
    (0.191_118_867_473_616_3, 0.125_837_456_346_828_3),
    (0.315_042_679_696_163_4, 0.121_670_472_927_803_4),
    (0.433_793_507_626_045_1, 0.115_505_668_053_725_6),
    (0.545_421_471_388_839_5, 0.107_444_270_115_965_6),
    (0.648_093_651_936_975_6, 0.097_618_652_104_113_89),
    (0.740_124_191_578_554_4, 0.086_190_161_531_953_28),
    (0.820_001_985_973_902_9, 0.073_346_481_411_080_31),
    (0.886_415_527_004_401_1, 0.059_298_584_915_436_78),
    (0.938_274_552_002_732_8, 0.044_277_438_817_419_81),
    (0.974_728_555_971_309_5, 0.028_531_388_628_933_66),
    (0.995_187_219_997_021_4, 0.012_341_229_799_987_2),
];

/// Parallel-cylinder BRDF with its cached geometry and sampling facets.
#[derive(Clone, Debug)]
pub struct PoulinFournier {
    /// Cylinder height (bumps) or groove depth, in radii.
    pub height: f64,
    /// Flat gap between cylinders, in radii.
    pub spacing: f64,
    /// Grooves instead of bumps.
    pub grooves: bool,
    /// Unit vector along the cylinder axis (tangent plane).
    axis: [f64; 2],
    /// Lambertian reflectance per channel.
    pub diffuse: [f64; 3],
    /// Phong reflectance per channel.
    pub specular: [f64; 3],
    /// Phong exponent.
    pub exponent: f64,
    /// Half-angle of the arc θm.
    theta_m: f64,
    /// Half-width of the arc's footprint sin θm.
    foot: f64,
    /// Period 2 sin θm + d.
    period: f64,
    /// Sampling facets on the arc.
    facets: Vec<Facet>,
}

/// A direction projected on the plane across the cylinders: `(p, z)` components, the length
/// of the projection, its elevation β ∈ (0, π), and `cos 2β`, `sin 2β`.
#[derive(Clone, Copy, Debug)]
struct Projected {
    ux: f64,
    uz: f64,
    len: f64,
    beta: f64,
    cos2b: f64,
    sin2b: f64,
}

/// A sampling facet of the arc: normal angle, arc length, `sin θ`, `cos θ` and the 3-D normal.
#[derive(Clone, Copy, Debug)]
struct Facet {
    dt: f64,
    sin: f64,
    cos: f64,
    normal: Vec3<f64>,
}

impl PoulinFournier {
    /// Builds the model and caches what depends only on the parameters.
    #[must_use]
    pub fn new(
        height: f64,
        spacing: f64,
        grooves: bool,
        direction_deg: f64,
        diffuse: [f64; 3],
        specular: [f64; 3],
        exponent: f64,
    ) -> Self {
        let theta_m = (1.0 - height).clamp(-1.0, 1.0).acos();
        let foot = theta_m.sin();
        let a = direction_deg.to_radians();
        // Facet spacing Δθ = 1/(4√n): a facet rotation by Δθ turns the mirror direction by
        // 2Δθ, half the Phong lobe's angular width 1/√n (at most 256 facets).
        let k = if theta_m > 0.0 {
            (8.0 * theta_m * exponent.max(1.0).sqrt()).ceil().clamp(8.0, 256.0) as usize
        } else {
            0
        };
        let axis = [a.cos(), a.sin()];
        let facets = (0..k)
            .map(|i| {
                let dt = 2.0 * theta_m / k as f64;
                let (sin, cos) = (-theta_m + (i as f64 + 0.5) * dt).sin_cos();
                Facet { dt, sin, cos, normal: Vec3::new(-axis[1] * sin, axis[0] * sin, cos) }
            })
            .collect();
        Self {
            height,
            spacing,
            grooves,
            axis,
            diffuse,
            specular,
            exponent,
            theta_m,
            foot,
            period: 2.0 * foot + spacing,
            facets,
        }
    }

    /// True when the cylinders have vanished (a flat surface).
    #[inline]
    fn flat(&self) -> bool {
        !(self.height > 1e-9)
    }

    /// Component of a tangent-plane vector across the cylinders.
    #[inline]
    fn across(&self, w: Vec3<f64>) -> f64 {
        -self.axis[1] * w.x + self.axis[0] * w.y
    }

    /// The 3-D normal of the arc at angle θ.
    #[inline]
    fn normal(&self, theta: f64) -> Vec3<f64> {
        let (s, c) = theta.sin_cos();
        Vec3::new(-self.axis[1] * s, self.axis[0] * s, c)
    }

    fn project(&self, w: Vec3<f64>) -> Projected {
        let x = self.across(w);
        let len = (x * x + w.z * w.z).sqrt();
        let (ux, uz) = (x / len, w.z / len);
        // cos 2β = ux² − uz², sin 2β = 2 ux uz.
        Projected { ux, uz, len, beta: w.z.atan2(x), cos2b: ux * ux - uz * uz, sin2b: 2.0 * ux * uz }
    }

    /// Is the ray from profile point `(px, pz)` along `u` blocked by a bump (disk) centred at
    /// `(cx, h − 1)`?
    #[inline]
    fn hits_disk(&self, px: f64, pz: f64, cx: f64, u: &Projected) -> bool {
        let cz = self.height - 1.0;
        let (dx, dz) = (px - cx, pz - cz);
        let dist = (dx * u.uz - dz * u.ux).abs();
        let forward = -(dx * u.ux + dz * u.uz);
        dist < 1.0 && forward > 0.0
    }

    /// Is the arc point at normal angle θ shadowed (or masked) along `u`?
    fn arc_blocked(&self, theta: f64, u: &Projected) -> bool {
        let (s, c) = theta.sin_cos();
        self.arc_blocked_sc(s, c, u)
    }

    /// [`Self::arc_blocked`] from `sin θ` and `cos θ`.
    fn arc_blocked_sc(&self, sin: f64, cos: f64, u: &Projected) -> bool {
        if self.grooves {
            // cos(θ + 2β) > 1 − h.
            return cos * u.cos2b - sin * u.sin2b > 1.0 - self.height;
        }
        let (px, pz) = (sin, self.height - 1.0 + cos);
        let side = if u.ux >= 0.0 { 1.0 } else { -1.0 };
        self.hits_disk(px, pz, side * self.period, u) || self.hits_disk(px, pz, 2.0 * side * self.period, u)
    }

    /// Is the flat point at `x ∈ [foot, foot + d]` shadowed (or masked) along `u`?
    fn flat_blocked(&self, x: f64, u: &Projected) -> bool {
        if self.grooves {
            return false;
        }
        let p = self.period;
        let (a, b) = if u.ux >= 0.0 { (p, 2.0 * p) } else { (0.0, -p) };
        self.hits_disk(x, 0.0, a, u) || self.hits_disk(x, 0.0, b, u)
    }

    /// Candidate breakpoints of the visibility along `u` on the arc (angles θ).
    fn arc_breaks(&self, u: &Projected, out: &mut Vec<f64>) {
        let mut push = |t: f64| {
            // Bring into (−π, π].
            let t = (t + PI).rem_euclid(2.0 * PI) - PI;
            if t > -self.theta_m && t < self.theta_m {
                out.push(t);
            }
        };
        // Facing boundary: sin(θ + β) = 0.
        push(-u.beta);
        push(PI - u.beta);
        if self.grooves {
            push(-2.0 * u.beta + self.theta_m);
            push(-2.0 * u.beta - self.theta_m);
            return;
        }
        let side = if u.ux >= 0.0 { 1.0 } else { -1.0 };
        for k in [1.0, 2.0] {
            let kp = side * k * self.period;
            // Tangency: cos(θ + β) = −kP u_z ∓ 1.
            for sgn in [-1.0, 1.0] {
                let c = -kp * u.uz + sgn;
                if c.abs() <= 1.0 {
                    let a = c.acos();
                    push(a - u.beta);
                    push(-a - u.beta);
                }
            }
            // Forward boundary: sin(θ + β) = kP u_x.
            let s = kp * u.ux;
            if s.abs() <= 1.0 {
                let a = s.asin();
                push(a - u.beta);
                push(PI - a - u.beta);
            }
        }
    }

    /// Candidate breakpoints on the flat (positions x).
    fn flat_breaks(&self, u: &Projected, out: &mut Vec<f64>) {
        if self.grooves {
            return;
        }
        let p = self.period;
        let (lo, hi) = (self.foot, self.foot + self.spacing);
        let mut push = |x: f64| {
            if x > lo && x < hi {
                out.push(x);
            }
        };
        for k in [-1.0, 0.0, 1.0, 2.0] {
            let kp = k * p;
            for sgn in [-1.0, 1.0] {
                push(kp + ((1.0 - self.height) * u.ux + sgn) / u.uz);
            }
            if u.ux != 0.0 {
                push(kp + (self.height - 1.0) * u.uz / u.ux);
            }
        }
    }

    /// Lit-and-visible length of the flat.
    fn flat_length(&self, ui: &Projected, uo: &Projected) -> f64 {
        if !(self.spacing > 0.0) {
            return 0.0;
        }
        let (lo, hi) = (self.foot, self.foot + self.spacing);
        let mut cuts = vec![lo, hi];
        self.flat_breaks(ui, &mut cuts);
        self.flat_breaks(uo, &mut cuts);
        cuts.sort_by(f64::total_cmp);
        let mut len = 0.0;
        for w in cuts.windows(2) {
            let mid = 0.5 * (w[0] + w[1]);
            if w[1] > w[0] && !self.flat_blocked(mid, ui) && !self.flat_blocked(mid, uo) {
                len += w[1] - w[0];
            }
        }
        len
    }

    /// Local BRDF for the facet normal `n` (per channel), times `(n·wi)(n·wo)`.
    #[inline]
    fn local(&self, n: Vec3<f64>, wi: Vec3<f64>, wo: Vec3<f64>, dot_io: f64) -> [f64; 3] {
        let (ni, no) = (n.dot(wi), n.dot(wo));
        if !(ni > 0.0) || !(no > 0.0) {
            return [0.0; 3];
        }
        let rdot = 2.0 * ni * no - dot_io;
        let lobe = if rdot > 0.0 { (self.exponent + 2.0) / (2.0 * PI) * rdot.powf(self.exponent) } else { 0.0 };
        let g = ni * no;
        [0, 1, 2].map(|c| (self.diffuse[c] / PI + self.specular[c] * lobe) * g)
    }

    /// The BRDF in f64.
    fn eval64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> [f64; 3] {
        // Renormalised in f64 so the f32 path sees the same directions as the f64 path.
        let (wi, wo) = (wi.normalize(), wo.normalize());
        let (ci, co) = (wi.z, wo.z);
        if !(ci > 0.0) || !(co > 0.0) {
            return [0.0; 3];
        }
        let dot_io = wi.dot(wo);
        let z = Vec3::new(0.0, 0.0, 1.0);
        if self.flat() {
            let l = self.local(z, wi, wo, dot_io);
            return l.map(|v| v / (ci * co));
        }
        let (ui, uo) = (self.project(wi), self.project(wo));
        let mut acc = [0.0; 3];
        // Flat part.
        let flat = self.flat_length(&ui, &uo);
        if flat > 0.0 {
            let l = self.local(z, wi, wo, dot_io);
            for c in 0..3 {
                acc[c] += l[c] * flat;
            }
        }
        // Arc: pieces between breakpoints, classified at their midpoints.
        let mut cuts = Vec::with_capacity(24);
        cuts.push(-self.theta_m);
        cuts.push(self.theta_m);
        self.arc_breaks(&ui, &mut cuts);
        self.arc_breaks(&uo, &mut cuts);
        let peak = 0.5 * (PI - ui.beta - uo.beta);
        // Peak width of (C + B cos 2ψ)^n, B = Li Lo, C + B = Li Lo (1 + cos Δβ) − wi·wo.
        let b = ui.len * uo.len;
        let cb = b * (1.0 + (ui.beta - uo.beta).cos()) - dot_io;
        let width = if b > 0.0 && cb > 0.0 {
            (cb / (4.0 * self.exponent * b)).sqrt().clamp(1e-5, 1.0)
        } else {
            1.0
        };
        if peak > -self.theta_m && peak < self.theta_m {
            cuts.push(peak);
        }
        cuts.sort_by(f64::total_cmp);
        for w in cuts.windows(2) {
            let (a, bnd) = (w[0], w[1]);
            if !(bnd > a) {
                continue;
            }
            let mid = 0.5 * (a + bnd);
            let n = self.normal(mid);
            if !(n.dot(wi) > 0.0) || !(n.dot(wo) > 0.0) || self.arc_blocked(mid, &ui) || self.arc_blocked(mid, &uo) {
                continue;
            }
            // θ = peak + width·sinh(t).
            let (ta, tb) = (((a - peak) / width).asinh(), ((bnd - peak) / width).asinh());
            let (tm, th) = (0.5 * (ta + tb), 0.5 * (tb - ta));
            for &(x, wgt) in &GL24 {
                for t in [tm - th * x, tm + th * x] {
                    let theta = peak + width * t.sinh();
                    let jac = width * t.cosh() * th * wgt;
                    let l = self.local(self.normal(theta), wi, wo, dot_io);
                    for c in 0..3 {
                        acc[c] += l[c] * jac;
                    }
                }
            }
        }
        let norm = 1.0 / (self.period * ci * co);
        acc.map(|v| (v * norm).max(0.0))
    }

    /// Sampling mixture for `wo`: facet probabilities (arc facets, then the flat) and the
    /// diffuse/specular split. Returns `None` when nothing is visible.
    fn facet_weights(&self, wo: Vec3<f64>) -> (Vec<f64>, f64) {
        let mut w = Vec::with_capacity(self.facets.len() + 1);
        let p_spec = {
            let (d, s) = (self.diffuse.iter().sum::<f64>(), self.specular.iter().sum::<f64>());
            if d + s > 0.0 {
                s / (d + s)
            } else {
                0.5
            }
        };
        if self.flat() {
            w.push(1.0);
            return (w, p_spec);
        }
        let uo = self.project(wo);
        for f in &self.facets {
            let no = f.normal.dot(wo);
            w.push(if no > 0.0 && !self.arc_blocked_sc(f.sin, f.cos, &uo) { no * f.dt } else { 0.0 });
        }
        let flat = if self.spacing > 0.0 { self.flat_length(&uo, &uo) } else { 0.0 };
        w.push(flat * wo.z);
        (w, p_spec)
    }

    /// Normal of facet `k` (the last index is the flat).
    #[inline]
    fn facet_normal(&self, k: usize) -> Vec3<f64> {
        if k < self.facets.len() && !self.flat() {
            self.facets[k].normal
        } else {
            Vec3::new(0.0, 0.0, 1.0)
        }
    }

    /// Probability of the defensive macro cosine lobe.
    const DEFENSIVE: f64 = 0.1;

    fn pdf64(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
        let (wi, wo) = (wi.normalize(), wo.normalize());
        if !(wi.z > 0.0) || !(wo.z > 0.0) {
            return 0.0;
        }
        let (w, p_spec) = self.facet_weights(wo);
        let total: f64 = w.iter().sum();
        let mut pdf = Self::DEFENSIVE * cosine_hemisphere_pdf(wi.z);
        if total > 0.0 {
            let mut mix = 0.0;
            for (k, &wk) in w.iter().enumerate() {
                if wk > 0.0 {
                    let n = self.facet_normal(k);
                    let r = n * (2.0 * n.dot(wo)) - wo;
                    let lobe = (1.0 - p_spec) * cosine_hemisphere_pdf(n.dot(wi))
                        + p_spec * power_cosine_pdf(self.exponent, r.dot(wi));
                    mix += wk * lobe;
                }
            }
            pdf += (1.0 - Self::DEFENSIVE) * mix / total;
        } else {
            pdf = cosine_hemisphere_pdf(wi.z);
        }
        pdf
    }

    fn sample64(&self, wo: Vec3<f64>, u: [f64; 3]) -> Option<Vec3<f64>> {
        let wo = wo.normalize();
        let (w, p_spec) = self.facet_weights(wo);
        let total: f64 = w.iter().sum();
        let (lobe, u0) = if total > 0.0 {
            pick_lobe(&[Self::DEFENSIVE, 1.0 - Self::DEFENSIVE], u[0])?
        } else {
            (0, u[0])
        };
        if lobe == 0 {
            return Some(cosine_hemisphere(u[1], u[2]));
        }
        let (k, u0) = pick_lobe(&w, u0)?;
        let n = self.facet_normal(k);
        if u0 < p_spec {
            let r = n * (2.0 * n.dot(wo)) - wo;
            Some(power_cosine_around(r, self.exponent, u[1], u[2]))
        } else {
            let (s, t) = crate::frame::basis_around(n);
            Some(crate::frame::from_basis(cosine_hemisphere(u[1], u[2]), s, t, n))
        }
    }
}

impl Bxdf for PoulinFournier {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        Rgb::from_array(self.eval64(wi.cast(), wo.cast()))
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        T::of(self.pdf64(wi.cast(), wo.cast()))
    }

    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wi: Vec3<T> = self.sample64(wo.cast(), u.map(|v| v.f64()))?.cast();
        if !(wi.z > T::zero()) {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn dir(c: f64, phi: f64) -> Vec3<f64> {
        let s = (1.0 - c * c).max(0.0).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), c)
    }

    fn pf(h: f64, d: f64, grooves: bool, kd: f64, ks: f64, n: f64) -> PoulinFournier {
        PoulinFournier::new(h, d, grooves, 0.0, [kd; 3], [ks; 3], n)
    }

    /// Height of the profile at `x` (one period centred on a cylinder, repeated).
    fn profile_height(m: &PoulinFournier, x: f64) -> f64 {
        let p = m.period;
        let xr = x - p * (x / p).round();
        if xr.abs() >= m.foot {
            return 0.0;
        }
        let chord = (1.0 - xr * xr).sqrt();
        if m.grooves {
            1.0 - m.height - chord
        } else {
            m.height - 1.0 + chord
        }
    }

    /// Is the ray from (x, z) along u blocked? By marching over the height field.
    fn marched_blocked(m: &PoulinFournier, x: f64, z: f64, u: &Projected) -> bool {
        let step = 2e-4;
        let top = if m.grooves { 0.0 } else { m.height };
        let mut t = step;
        while z + t * u.uz <= top + 1e-9 {
            let (px, pz) = (x + t * u.ux, z + t * u.uz);
            if pz < profile_height(m, px) - 1e-9 {
                return true;
            }
            t += step;
        }
        false
    }

    /// The closed-form visibility predicates agree with ray marching over the profile.
    #[test]
    fn visibility_matches_ray_marching() {
        let mut rng = Pcg32::new(3, 9);
        let mut checked = 0;
        for &(h, d, grooves) in &[(1.0, 0.0, false), (0.6, 0.5, false), (0.2, 0.1, false), (0.7, 0.3, true), (1.0, 0.0, true)] {
            let m = pf(h, d, grooves, 0.5, 0.5, 10.0);
            for _ in 0..400 {
                let w = dir(0.1 + 0.9 * rng.uniform(), 2.0 * PI * rng.uniform());
                let u = m.project(w);
                // A point on the arc (facing the ray) or on the flat.
                if rng.uniform() < 0.7 {
                    let theta = m.theta_m * (2.0 * rng.uniform() - 1.0);
                    if (theta + u.beta).sin() <= 0.01 {
                        continue;
                    }
                    let (px, pz) = if grooves {
                        (-theta.sin(), 1.0 - h - theta.cos())
                    } else {
                        (theta.sin(), h - 1.0 + theta.cos())
                    };
                    let want = marched_blocked(&m, px, pz, &u);
                    let got = m.arc_blocked(theta, &u);
                    // Skip points within marching resolution of the shadow boundary.
                    let near = (-3..=3).any(|j| m.arc_blocked(theta + j as f64 * 2e-3, &u) != got);
                    if !near {
                        assert_eq!(got, want, "h {h} d {d} grooves {grooves} θ {theta} u {u:?}");
                        checked += 1;
                    }
                } else if d > 0.0 {
                    let x = m.foot + d * rng.uniform();
                    let want = marched_blocked(&m, x, 0.0, &u);
                    let got = m.flat_blocked(x, &u);
                    let near = (-3..=3).any(|j| m.flat_blocked(x + j as f64 * 2e-3, &u) != got);
                    if !near {
                        assert_eq!(got, want, "flat h {h} d {d} x {x} u {u:?}");
                        checked += 1;
                    }
                }
            }
        }
        println!("Poulin-Fournier visibility: {checked} points agree with ray marching");
        assert!(checked > 1000);
    }

    /// h = 0: the cylinders vanish and the model is its local BRDF on a flat surface.
    #[test]
    fn flat_limit_is_the_local_brdf() {
        let m = pf(0.0, 0.5, false, 0.3, 0.5, 20.0);
        let (wi, wo) = (dir(0.7, 0.2), dir(0.8, 3.0));
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        let want = 0.3 / PI + 0.5 * 22.0 / (2.0 * PI) * r.dot(wi).powf(20.0);
        let f = m.eval64(wi, wo);
        assert!((f[0] - want).abs() < 1e-14 * want);
    }

    /// Touching half-cylinders (h = 1, d = 0), Lambertian, seen and lit along the normal:
    /// no shadowing for vertical rays, so f = (1/P)∫ (kd/π) cos²θ dθ = kd/4 (P = 2).
    /// The same for touching half-grooves.
    #[test]
    fn half_cylinders_at_normal_incidence() {
        let z = dir(1.0, 0.0);
        for grooves in [false, true] {
            let m = pf(1.0, 0.0, grooves, 0.8, 0.0, 1.0);
            let f = m.eval64(z, z);
            assert!((f[0] - 0.2).abs() < 1e-12, "grooves {grooves}: {}", f[0]);
        }
    }

    /// The breakpoint-and-Gauss-Legendre integral matches a brute-force midpoint sum over
    /// the profile (2·10⁵ points) to 1e-4, sharp lobes included.
    #[test]
    fn integration_matches_brute_force() {
        let mut rng = Pcg32::new(11, 2);
        let mut worst = 0.0f64;
        for &(h, d, grooves, n) in &[(1.0, 0.0, false, 20.0), (0.6, 0.5, false, 300.0), (0.8, 0.2, true, 1000.0), (0.3, 2.0, false, 5.0)] {
            let m = pf(h, d, grooves, 0.2, 0.8, n);
            for _ in 0..30 {
                let wo = dir(rng.uniform().max(0.05), 2.0 * PI * rng.uniform());
                // Half of the pairs near the highlight.
                let wi = if rng.uniform() < 0.5 {
                    dir(rng.uniform().max(0.05), 2.0 * PI * rng.uniform())
                } else {
                    let t = m.theta_m * (2.0 * rng.uniform() - 1.0);
                    let nn = m.normal(t);
                    let r = nn * (2.0 * nn.dot(wo)) - wo;
                    if r.z <= 0.05 {
                        continue;
                    }
                    r
                };
                let (ui, uo) = (m.project(wi), m.project(wo));
                let steps = 200_000;
                let dt = 2.0 * m.theta_m / steps as f64;
                let mut s = 0.0;
                for j in 0..steps {
                    let t = -m.theta_m + (j as f64 + 0.5) * dt;
                    if m.arc_blocked(t, &ui) || m.arc_blocked(t, &uo) {
                        continue;
                    }
                    s += m.local(m.normal(t), wi, wo, wi.dot(wo))[0] * dt;
                }
                let dx = d / steps as f64;
                let z = Vec3::new(0.0, 0.0, 1.0);
                let lz = m.local(z, wi, wo, wi.dot(wo))[0];
                for j in 0..steps {
                    let x = m.foot + (j as f64 + 0.5) * dx;
                    if !m.flat_blocked(x, &ui) && !m.flat_blocked(x, &uo) {
                        s += lz * dx;
                    }
                }
                let want = s / (m.period * wi.z * wo.z);
                let got = m.eval64(wi, wo)[0];
                let err = (got - want).abs() / want.max(1e-3);
                worst = worst.max(err);
            }
        }
        println!("Poulin-Fournier quadrature vs brute force: worst relative error {worst:.2e}");
        assert!(worst < 1e-4, "worst relative error {worst}");
    }

    /// Anisotropy: with the axis along x the highlight spreads across x, not along it.
    #[test]
    fn highlight_is_stretched_across_the_cylinders() {
        let m = pf(1.0, 0.0, false, 0.0, 1.0, 200.0);
        let wo = dir(0.8, 0.0);
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        let tilt = |axis: usize| {
            let mut w = r;
            if axis == 0 {
                w.x += 0.3;
            } else {
                w.y += 0.3;
            }
            w.normalize()
        };
        // Cylinders along x: normals tilt in y, so moving wi in y stays bright.
        let along = m.eval64(tilt(1), wo)[0];
        let across = m.eval64(tilt(0), wo)[0];
        assert!(along > 100.0 * across, "{along} vs {across}");
    }
}
