//! The interface every reflectance model implements, and what a model claims about itself.

use crate::error::Error;
use crate::lanes::{self, Lanes, Mask};
use crate::math::{Rgb, Vec3};
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use serde::Serialize;

/// One importance sample of a BRDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample<T> {
    /// Sampled direction toward the light (away from the surface).
    pub wi: Vec3<T>,
    /// `f_r(wi, wo) · cos θi / pdf`, the Monte Carlo weight.
    pub weight: Rgb<T>,
    /// Solid-angle density of `wi` (for a delta lobe: the discrete probability of the lobe).
    pub pdf: T,
    /// True when `wi` comes from a Dirac delta lobe (no density; `pdf` is the lobe probability).
    pub delta: bool,
}

impl<T: Real> BsdfSample<T> {
    /// A sample from a smooth lobe, given the BRDF value and the density at `wi`.
    /// Returns `None` when the density is zero or not finite, or the weight is not finite.
    #[inline]
    #[must_use]
    pub fn from_eval(wi: Vec3<T>, f: Rgb<T>, pdf: T) -> Option<Self> {
        if !(pdf > T::zero()) || !pdf.is_finite() {
            return None;
        }
        let weight = f * (wi.z / pdf);
        if !weight.is_finite() {
            return None;
        }
        Some(Self { wi, weight, pdf, delta: false })
    }
}

/// Importance samples of a BRDF in lanes ([`BsdfSample`] per lane, with a validity mask
/// instead of `Option`).
#[derive(Clone, Copy, Debug)]
pub struct LaneSample<L: Lanes> {
    /// Sampled directions toward the light.
    pub wi: Vec3<L>,
    /// `f_r · cos θi / pdf`.
    pub weight: Rgb<L>,
    /// Solid-angle densities (for a delta lobe: the lobe probability).
    pub pdf: L,
    /// Lanes that hold a sample (elsewhere the other fields are meaningless).
    pub valid: L::Mask,
    /// Lanes whose sample comes from a Dirac delta lobe.
    pub delta: L::Mask,
}

impl<L: Lanes> LaneSample<L> {
    /// Samples from a smooth lobe, given the BRDF value and the density at `wi`: valid where
    /// `valid` is set, the density is positive and finite, and the weight is finite (the
    /// lane form of [`BsdfSample::from_eval`]).
    #[inline(always)]
    #[must_use]
    pub fn from_eval(wi: Vec3<L>, f: Rgb<L>, pdf: L, valid: L::Mask) -> Self {
        let weight = f * (wi.z / pdf);
        let finite_weight = lanes::is_finite(weight.r) & lanes::is_finite(weight.g) & lanes::is_finite(weight.b);
        let valid = valid & lanes::gt(pdf, L::c(0.0)) & lanes::is_finite(pdf) & finite_weight;
        Self { wi, weight, pdf, valid, delta: L::Mask::splat(false) }
    }
}

impl<T: Real> LaneSample<T> {
    /// The one-lane sample as the scalar API returns it.
    #[inline(always)]
    #[must_use]
    pub fn into_option(self) -> Option<BsdfSample<T>> {
        self.valid.then_some(BsdfSample { wi: self.wi, weight: self.weight, pdf: self.pdf, delta: self.delta })
    }
}

/// Which AVX2 batch kernels of a lane model run on two interleaved lane groups
/// ([`LaneBxdf::PAIRED`], [`crate::lanes::pair::X2`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Paired {
    /// The value / density kernel (`eval`, `pdf`, both).
    pub eval_pdf: bool,
    /// The sampling kernel.
    pub sample: bool,
}

impl Paired {
    /// No paired kernel: one lane group at a time.
    pub const NONE: Self = Self { eval_pdf: false, sample: false };
    /// Only the sampling kernel.
    pub const SAMPLE: Self = Self { eval_pdf: false, sample: true };
    /// Every kernel.
    pub const ALL: Self = Self { eval_pdf: true, sample: true };
}

/// A model written against [`Lanes`]: one source for the f64 reference, the scalar f32 path
/// and the SIMD batch kernels. Its [`Bxdf`] implementation forwards to these methods with a
/// one-lane type. Directions are unit and finite; lanes below the horizon may return anything
/// finite or not (the dispatcher masks them), but never affect other lanes.
pub trait LaneBxdf {
    /// [`Bxdf::eval`] per lane.
    fn eval_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> Rgb<L>;
    /// [`Bxdf::pdf`] per lane.
    fn pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> L;
    /// [`Bxdf::sample`] per lane.
    fn sample_lanes<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3]) -> LaneSample<L>;
    /// [`LaneBxdf::eval_lanes`] with per-lane multipliers of the spatially varying lobes,
    /// `scale = [metallic flakes, pearlescent flakes]` (the sparkle's `n / (N p)`, see
    /// `Model::sparkle_scales`); models without such lobes ignore them.
    #[inline(always)]
    fn eval_scaled_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, scale: [L; 2]) -> Rgb<L> {
        let _ = scale;
        self.eval_lanes(wi, wo)
    }
    /// [`LaneBxdf::eval_scaled_lanes`] restricted to the lobes of the lobe mask `lobes`
    /// ([`crate::lobes::bits`]: `DIFFUSE`, `GLOSSY`, `COAT`). Models that cannot separate
    /// their lobes keep this default (the full value): `Material::select_lobes` lets a mask
    /// reach them only when it enables all of their lobes. With every selectable lobe
    /// (`bits::SELECTABLE`) it must give `eval_scaled_lanes` bit for bit (the batch kernels
    /// call it for both).
    #[inline(always)]
    fn eval_lobes_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, scale: [L; 2], lobes: u32) -> Rgb<L> {
        let _ = lobes;
        self.eval_scaled_lanes(wi, wo, scale)
    }
    /// The density of [`LaneBxdf::sample_lobes_lanes`] (see [`LaneBxdf::eval_lobes_lanes`]).
    #[inline(always)]
    fn pdf_lobes_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, lobes: u32) -> L {
        let _ = lobes;
        self.pdf_lanes(wi, wo)
    }
    /// A sample among the lobes `lobes` enables, their selection renormalised (see
    /// [`LaneBxdf::eval_lobes_lanes`]).
    #[inline(always)]
    fn sample_lobes_lanes<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3], lobes: u32) -> LaneSample<L> {
        let _ = lobes;
        self.sample_lanes(wo, u)
    }
    /// True when [`LaneBxdf::eval_pdf_lanes`] shares work between the value and the density
    /// (the batch calls that want both then call it instead of the two methods).
    const SHARES_EVAL_PDF: bool = false;
    /// True for a model whose lane code is small (tens of instructions per element): its
    /// SIMD batch kernels run the full lane groups of a plain call in a loop of their own
    /// (`batch::eval_pdf_full_groups`), whose saved per-group work is a measurable share of
    /// such a model's time, for a second copy of its lane code per kernel. The large models
    /// (paint, `principled`) keep one loop: for them the copy costs compile minutes and the
    /// loop's work is noise (docs/reliability.md, "CI duration: session 27 went over the limit").
    const SMALL: bool = false;
    /// Which of this model's SIMD batch kernels (AVX2 and AVX-512) run two lane groups
    /// interleaved ([`crate::lanes::pair::X2`]): worth it where a kernel is bound by one
    /// group's dependency chain and the gain was measured; each paired kernel is a second,
    /// larger copy of the model's lane code to compile per instruction set (docs/speed.md,
    /// sessions 30 and 31).
    const PAIRED: Paired = Paired::NONE;
    /// [`LaneBxdf::eval_lanes`] and [`LaneBxdf::pdf_lanes`] together: the same results.
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> (Rgb<L>, L) {
        (self.eval_lanes(wi, wo), self.pdf_lanes(wi, wo))
    }
}

/// Implements [`Bxdf`] for a [`LaneBxdf`] model by calling its lane methods with a one-lane
/// type: the scalar f32/f64 paths are the lane code itself.
#[macro_export]
macro_rules! bxdf_from_lanes {
    ($ty:ty) => {
        impl $crate::bxdf::Bxdf for $ty {
            #[inline]
            fn eval<T: $crate::real::Real>(
                &self,
                wi: $crate::math::Vec3<T>,
                wo: $crate::math::Vec3<T>,
            ) -> $crate::math::Rgb<T> {
                $crate::bxdf::LaneBxdf::eval_lanes(self, wi, wo)
            }

            #[inline]
            fn pdf<T: $crate::real::Real>(&self, wi: $crate::math::Vec3<T>, wo: $crate::math::Vec3<T>) -> T {
                $crate::bxdf::LaneBxdf::pdf_lanes(self, wi, wo)
            }

            #[inline]
            fn sample<T: $crate::real::Real>(
                &self,
                wo: $crate::math::Vec3<T>,
                u: [T; 3],
            ) -> Option<$crate::bxdf::BsdfSample<T>> {
                $crate::bxdf::LaneBxdf::sample_lanes(self, wo, u).into_option()
            }
        }
    };
}

/// Runs a scalar colour function of a direction pair on each lane: the bridge from lane code
/// to parts that exist only in scalar form (tabulated compensation lobes, Newton iterations).
#[inline(always)]
pub fn per_lane_rgb<L: Lanes>(
    wi: Vec3<L>,
    wo: Vec3<L>,
    f: impl Fn(Vec3<L::Elem>, Vec3<L::Elem>) -> Rgb<L::Elem>,
) -> Rgb<L> {
    use crate::lanes::MAX_WIDTH;
    assert!(L::WIDTH <= MAX_WIDTH, "lane type wider than {MAX_WIDTH}");
    let mut out = [Rgb::<L::Elem>::zero(); MAX_WIDTH];
    for (i, o) in out.iter_mut().enumerate().take(L::WIDTH) {
        *o = f(lane_of(wi, i), lane_of(wo, i));
    }
    Rgb::new(L::from_fn(|i| out[i].r), L::from_fn(|i| out[i].g), L::from_fn(|i| out[i].b))
}

/// Lane `i` of a vector of lanes.
#[inline(always)]
#[must_use]
pub fn lane_of<L: Lanes>(w: Vec3<L>, i: usize) -> Vec3<L::Elem> {
    Vec3::new(w.x.lane(i), w.y.lane(i), w.z.lane(i))
}

/// A surface position and its pixel footprint in uv space, for spatially varying effects
/// (sparkle). The footprint is the parallelogram spanned by the uv derivatives along the
/// screen axes (ray differentials).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SurfacePoint {
    /// Texture coordinates of the shading point.
    pub uv: [f64; 2],
    /// ∂uv/∂x along the screen x axis.
    pub duv_dx: [f64; 2],
    /// ∂uv/∂y along the screen y axis.
    pub duv_dy: [f64; 2],
}

impl SurfacePoint {
    /// Area of the footprint parallelogram in uv units² (0 for a degenerate footprint).
    #[inline]
    #[must_use]
    pub fn footprint_area(&self) -> f64 {
        (self.duv_dx[0] * self.duv_dy[1] - self.duv_dx[1] * self.duv_dy[0]).abs()
    }

    /// True when every component is finite.
    #[inline]
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.uv.iter().chain(&self.duv_dx).chain(&self.duv_dy).all(|v| v.is_finite())
    }
}

/// A reflectance model: the BRDF, its sampler and the sampler's density, side by side.
///
/// The caller (see [`crate::models::Model`]) guarantees unit, finite directions. Methods must
/// still return zero (never NaN) for directions at or below the horizon.
pub trait Bxdf {
    /// `f_r(wi, wo)` in 1/sr, without the cosine.
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T>;
    /// Solid-angle density with which [`Bxdf::sample`] returns `wi` for this `wo`.
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T;
    /// Samples `wi` for `wo` from three uniform numbers (first one picks a lobe).
    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>>;

    /// `f_r` at a surface point with a footprint (sparkle). Models without spatial variation
    /// return the mean BRDF [`Bxdf::eval`].
    #[inline]
    fn eval_at<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, _at: &SurfacePoint) -> Rgb<T> {
        self.eval(wi, wo)
    }

    /// A sample at a surface point. Spatially varying models sample their mean lobe, so the
    /// density is [`Bxdf::pdf`] everywhere and only the weight changes.
    #[inline]
    fn sample_at<T: Real>(&self, wo: Vec3<T>, u: [T; 3], _at: &SurfacePoint) -> Option<BsdfSample<T>> {
        self.sample(wo, u)
    }

    /// True when [`Bxdf::eval_at`] can differ from [`Bxdf::eval`] (the checks then also test
    /// the spatially varying path).
    #[inline]
    fn spatially_varying(&self) -> bool {
        false
    }
}

/// What a model claims; `lacquer check` verifies each claim and reports the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Claims {
    /// `f(wi, wo) = f(wo, wi)` for all directions.
    pub reciprocal: bool,
    /// Directional albedo `∫ f cos θi dωi ≤ 1` for every `wo` and every valid parameter set.
    pub energy_conserving: bool,
    /// `sample` draws from exactly the density `pdf` reports (χ² test applies).
    pub sampled: bool,
}

/// A registered model: its name, documentation, parameters, claims and constructor.
#[derive(Clone, Copy)]
pub struct ModelInfo {
    /// Name used in material JSON (`"model": "..."`).
    pub name: &'static str,
    /// One-line description.
    pub summary: &'static str,
    /// The paper the formula comes from.
    pub reference: &'static str,
    /// Parameter specifications.
    pub params: &'static [ParamSpec],
    /// What the model claims.
    pub claims: Claims,
    /// Extra parameter sets (JSON objects without `"model"`) the checks run besides the
    /// defaults, chosen to cover the model's regimes (rough/smooth, anisotropic, ...).
    pub check_params: &'static [&'static str],
    /// Builds the model from validated parameters (cross-parameter checks happen here).
    pub build: fn(&Params) -> Result<crate::models::Model, Error>,
}

impl ModelInfo {
    /// The entry as `lacquer models --json` and the C ABI list it: name, summary, reference,
    /// claims and parameters (default, range, unit, meaning).
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "name": self.name,
            "summary": self.summary,
            "reference": self.reference,
            "claims": self.claims,
            "params": self.params,
        })
    }
}

impl std::fmt::Debug for ModelInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModelInfo").field("name", &self.name).finish_non_exhaustive()
    }
}
