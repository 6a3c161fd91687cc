//! The basecoat as seen from inside the clearcoat: diffuse pigment, an optional rough metallic
//! base, and the flake layer. Directions are in the binder (refracted into the coat), z up.
//!
//! `f_b = ρ/π · (1 − c + c_p T_p(μi) T_p(μo)) + (1 − c)·m·f_metal + f_flakes`, where `c` is the
//! total flake coverage, `c_p` the pearlescent part, `T_p = 1 − R_film` the light a pearl flake
//! lets through to the pigment, and `m` the metallic weight of the base. Every term is
//! symmetric in (wi, wo), and the weights sum to at most one, so `f_b` is reciprocal and
//! energy-conserving when each lobe is.

use super::coat::TransmissionBlur;
use super::flakes::{FlakeLayer, FlakeSampler};
use super::pick3;
use crate::bxdf::BsdfSample;
use crate::frame::HalfPair;
use crate::fresnel;
use crate::lanes::{self, keep, Lanes, Mask};
use crate::math::{Rgb, Vec3};
use crate::microfacet::{reflection_jacobian, DistributionKind, MaskingKind, Microfacet};
use crate::models::eon::Eon;
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::table::MuTable;

/// A GGX metallic base with Schlick Fresnel.
#[derive(Clone, Debug)]
pub struct MetalBase {
    /// GGX α.
    pub alpha: f64,
    /// Normal-incidence reflectance per channel.
    pub f0: [f64; 3],
    /// Weight `(1 − c)·m`.
    pub weight: f64,
}

impl MetalBase {
    #[inline(always)]
    pub(crate) fn microfacet<T: Lanes>(&self) -> Microfacet<T> {
        Microfacet::uniform(DistributionKind::Ggx, self.alpha, self.alpha)
    }

    /// The GGX distribution with `added` (per lane) added to `α²`: the base seen through a
    /// rough coat ([`TransmissionBlur`]).
    #[inline(always)]
    pub(crate) fn blurred<T: Lanes>(&self, added: T) -> Microfacet<T> {
        let a = lanes::sqrt_fast(T::c(self.alpha * self.alpha) + added);
        Microfacet::new(DistributionKind::Ggx, a, a)
    }

    /// The lobe `F D G / (4 cos θi cos θo)` with the distribution `mf`, Schlick's `f0` and the
    /// weight `weight` (the per-element path passes its own); under a rough coat with `other`
    /// the smaller of the two lobes' `D G` (the blurred lobes seen from `wo` and from `wi`,
    /// [`TransmissionBlur`]).
    #[inline(always)]
    pub(crate) fn eval_with<T: Lanes>(
        &self,
        mf: &Microfacet<T>,
        other: Option<&Microfacet<T>>,
        f0: Rgb<T>,
        weight: T,
        wi: Vec3<T>,
        wo: Vec3<T>,
    ) -> Rgb<T> {
        self.eval_with_h(mf, other, f0, weight, &HalfPair::new(wi, wo))
    }

    /// [`MetalBase::eval_with`] of a pair whose half vector is known.
    #[inline(always)]
    pub(crate) fn eval_with_h<T: Lanes>(
        &self,
        mf: &Microfacet<T>,
        other: Option<&Microfacet<T>>,
        f0: Rgb<T>,
        weight: T,
        pair: &HalfPair<T>,
    ) -> Rgb<T> {
        let HalfPair { wi, wo, h, defined } = *pair;
        let (f, ok) = match other {
            None => {
                let (dg, g_positive) = mf.reflection_dg(wi, wo, h, MaskingKind::HeightCorrelated);
                (fresnel::schlick_rgb(wi.dot(h), f0) * (weight * dg), g_positive)
            }
            Some(b) => {
                let g = mf.g(wi, wo, h, MaskingKind::HeightCorrelated);
                let dg = lanes::min(mf.d(h) * g, b.d(h) * b.g(wi, wo, h, MaskingKind::HeightCorrelated));
                (
                    fresnel::schlick_rgb(wi.dot(h), f0) * lanes::div_fast(weight * dg, T::c(4.0) * wi.z * wo.z),
                    lanes::gt(dg, T::c(0.0)),
                )
            }
        };
        Rgb::select(defined & ok, f, Rgb::zero())
    }

    #[inline(always)]
    pub(crate) fn pdf<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        Self::pdf_with(&self.microfacet::<T>(), wi, wo)
    }

    /// Density of sampling `wi` by the visible normals of `mf` seen from `wo`.
    #[inline(always)]
    pub(crate) fn pdf_with<T: Lanes>(mf: &Microfacet<T>, wi: Vec3<T>, wo: Vec3<T>) -> T {
        Self::pdf_with_h(mf, &HalfPair::new(wi, wo))
    }

    /// [`MetalBase::pdf_with`] of a pair whose half vector is known.
    #[inline(always)]
    pub(crate) fn pdf_with_h<T: Lanes>(mf: &Microfacet<T>, pair: &HalfPair<T>) -> T {
        keep(pair.defined, mf.visible_d(pair.wo, pair.h) * reflection_jacobian(pair.wo, pair.h))
    }

    #[inline(always)]
    pub(crate) fn sample_direction<T: Lanes>(&self, wo: Vec3<T>, u1: T, u2: T) -> Vec3<T> {
        Self::sample_direction_with(&self.microfacet::<T>(), wo, u1, u2)
    }

    /// Reflects `wo` about a visible normal of `mf`.
    #[inline(always)]
    pub(crate) fn sample_direction_with<T: Lanes>(mf: &Microfacet<T>, wo: Vec3<T>, u1: T, u2: T) -> Vec3<T> {
        crate::frame::reflect(wo, mf.sample_m(wo, u1, u2, true))
    }
}

/// Which of the basecoat's lobes a call includes: the pigment (diffuse) and/or the glossy
/// lobes (metallic base, metallic and pearlescent flakes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BaseParts {
    /// The pigment (Lambert or EON, also seen through pearl flakes).
    pub pigment: bool,
    /// The metallic base and the flakes.
    pub glossy: bool,
}

impl BaseParts {
    /// Every lobe.
    pub const ALL: Self = Self { pigment: true, glossy: true };
}

/// What the basecoat's value and its density share at one pair of inside directions, per
/// lane ([`Basecoat::pair`]): the half vector, the transmission blur at both directions (the
/// metal base's), and the flakes' `D(h)` (the value's and the projected-area density's).
#[derive(Clone, Copy, Debug)]
pub struct BasePair<T: Lanes> {
    /// The directions and their half vector.
    pub half: HalfPair<T>,
    /// The blur's added `α²` at `wi` and at `wo` (None without the blur).
    added: Option<(T, T)>,
    /// `D(h)` of the flakes' distribution (0 without flakes, or where the caller asked for
    /// the directions alone, [`Basecoat::pair_at`]; the flakes take no transmission blur,
    /// [`super::coat::FLAKE_MEAN_REFRACTION_SHARE`]).
    flake_d: T,
}

/// The basecoat.
#[derive(Clone, Debug)]
pub struct Basecoat {
    /// Pigment albedo ρ.
    pub pigment: [f64; 3],
    /// Area not covered by flakes times the non-metallic weight: `(1 − c)(1 − m)`.
    pub pigment_weight: f64,
    /// Pearl coverage `c_p` (pigment seen through pearl flakes).
    pub pearl_coverage: f64,
    /// `T_p(μ) = 1 − R_film(μ)` of pearl flakes (None without pearl flakes).
    pub pearl_transmission: Option<MuTable>,
    /// Optional metallic base.
    pub metal: Option<MetalBase>,
    /// Optional flakes.
    pub flakes: Option<FlakeLayer>,
    /// The pigment's rough-diffuse lobe: EON (energy-preserving Oren-Nayar, albedo ρ) in place
    /// of Lambert's `ρ/π` (None: Lambert). Set by [`Basecoat::with_rough_pigment`].
    pub rough_pigment: Option<Eon>,
    /// The rough coat's blur of the metal base's lobe (the flakes take none): None for the basecoat
    /// as it is (under a smooth coat; the reference's walks). Set by [`Basecoat::with_blur`].
    pub blur: Option<TransmissionBlur>,
    /// Lobe-selection weights: pigment, metal, flakes.
    selection: [f64; 3],
}

impl Basecoat {
    /// Assembles a basecoat and its lobe-selection weights (estimated lobe albedos).
    #[must_use]
    pub fn new(
        pigment: [f64; 3],
        pigment_weight: f64,
        pearl_coverage: f64,
        pearl_transmission: Option<MuTable>,
        metal: Option<MetalBase>,
        flakes: Option<FlakeLayer>,
    ) -> Self {
        let mean = |c: [f64; 3]| (c[0] + c[1] + c[2]) / 3.0;
        let t_p = pearl_transmission.as_ref().map_or(0.0, |t| mean(t.eval::<f64>(1.0)).powi(2));
        let w_pigment = mean(pigment) * (pigment_weight + pearl_coverage * t_p);
        let w_metal = metal.as_ref().map_or(0.0, |m| m.weight * mean(m.f0).max(0.04));
        let w_flakes = flakes.as_ref().map_or(0.0, |f| f.normal_reflectance());
        // Never let a present lobe go unsampled: floor each at 2 % of the total.
        let total = (w_pigment + w_metal + w_flakes).max(1e-12);
        let floor = |w: f64, present: bool| if present { w.max(0.02 * total) } else { 0.0 };
        let selection = [
            floor(w_pigment, pigment_weight > 0.0 || pearl_coverage > 0.0),
            floor(w_metal, metal.is_some()),
            floor(w_flakes, flakes.is_some()),
        ];
        Self {
            pigment,
            pigment_weight,
            pearl_coverage,
            pearl_transmission,
            metal,
            flakes,
            rough_pigment: None,
            blur: None,
            selection,
        }
    }

    /// The same basecoat with the pigment scattering by EON of roughness `r` (0–1) instead of
    /// Lambert (issue 17, item 5). The pigment is still sampled by its cosine lobe (the pdf is
    /// the same, so sampling stays consistent; EON's lobe is within a few tens of percent of a
    /// cosine, so the variance stays bounded).
    #[must_use]
    pub fn with_rough_pigment(mut self, r: f64) -> Self {
        self.rough_pigment = Some(Eon::new(self.pigment, r));
        self
    }

    /// The same basecoat seen through a coat with transmission blur `blur` (None: as it is).
    /// The pigment is unchanged (a diffuse lobe stays diffuse); the metal base's lobe is
    /// blurred as [`TransmissionBlur`] describes. The flakes' broad lobe takes no blur: under a
    /// rough coat the paint evaluates it at a share of the mean refraction instead
    /// ([`super::coat::FLAKE_MEAN_REFRACTION_SHARE`]).
    #[must_use]
    pub fn with_blur(mut self, blur: Option<TransmissionBlur>) -> Self {
        self.blur = blur;
        self
    }

    /// Diffuse pigment term `f_p(wi, wo) (w + c_p T_p(μi) T_p(μo))`, `f_p = ρ/π` (Lambert) or
    /// EON with albedo ρ.
    #[inline(always)]
    fn pigment_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let rho = match &self.rough_pigment {
            None => Rgb::from_array(self.pigment) * T::c(std::f64::consts::FRAC_1_PI),
            Some(eon) => eon.eval_lanes(wi, wo),
        };
        match &self.pearl_transmission {
            None => rho * T::c(self.pigment_weight),
            Some(t) => {
                let (a, b) = (t.eval_lanes(wi.z), t.eval_lanes(wo.z));
                let cp = T::c(self.pearl_coverage);
                let w = T::c(self.pigment_weight);
                Rgb::new(rho.r * (w + cp * a[0] * b[0]), rho.g * (w + cp * a[1] * b[1]), rho.b * (w + cp * a[2] * b[2]))
            }
        }
    }

    /// `f_b(wi, wo)` with flake multipliers (1, 1 for the mean lobe).
    #[inline(always)]
    #[must_use]
    pub fn eval_scaled<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        self.eval_parts(wi, wo, metal_scale, pearl_scale, BaseParts::ALL)
    }

    /// [`Basecoat::eval_scaled`] restricted to `parts` (the pigment and/or the glossy lobes:
    /// metal base and flakes). With [`BaseParts::ALL`] the same arithmetic as the full sum.
    #[inline(always)]
    #[must_use]
    pub fn eval_parts<T: Lanes>(
        &self,
        wi: Vec3<T>,
        wo: Vec3<T>,
        metal_scale: T,
        pearl_scale: T,
        parts: BaseParts,
    ) -> Rgb<T> {
        self.eval_pair(&self.pair(wi, wo), metal_scale, pearl_scale, parts)
    }

    /// The transmission blur's added `α²` for an inside direction with cosine `mu_in`
    /// ([`TransmissionBlur::one_sided`]; None without the blur, or without a metal base for
    /// it to widen: a pigment or flake basecoat does not pay for it).
    #[inline(always)]
    #[must_use]
    pub fn blur_added<T: Lanes>(&self, mu_in: T) -> Option<T> {
        self.blur.filter(|_| self.metal.is_some()).map(|b| b.one_sided(mu_in))
    }

    /// What the value and the density share at `wi`, `wo` ([`BasePair`]).
    #[inline(always)]
    #[must_use]
    pub fn pair<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> BasePair<T> {
        self.pair_at(wi, wo, self.blur_added(wo.z), true)
    }

    /// [`Basecoat::pair`] with the blur at `wo` already known: `added_o` must be
    /// [`Basecoat::blur_added`]`(wo.z)` (the sampler computes it too). `glossy_read` false
    /// gives the directions alone, as for a pigment-only basecoat, to a caller that reads
    /// no glossy lobe at this pair: the paint's value under a rough coat, which reads its
    /// flakes at their own pair ([`super::coat::Coat::flake_refract_in`]) and has no metal
    /// base. There the half vector and the flakes' `D` cost 9 % of `gold_flake_8`'s AVX-512
    /// eval for nothing (session 41).
    #[inline(always)]
    #[must_use]
    pub(crate) fn pair_at<T: Lanes>(
        &self,
        wi: Vec3<T>,
        wo: Vec3<T>,
        added_o: Option<T>,
        glossy_read: bool,
    ) -> BasePair<T> {
        if !self.has_glossy() || !glossy_read {
            // The pigment alone reads the two directions, not their half vector nor the blur.
            return BasePair { half: HalfPair::without_half(wi, wo), added: None, flake_d: T::c(0.0) };
        }
        let half = HalfPair::new(wi, wo);
        let added = match (&self.blur, added_o) {
            (Some(b), Some(o)) => Some((b.one_sided(wi.z), o)),
            _ => None,
        };
        let flake_d = match &self.flakes {
            None => T::c(0.0),
            Some(f) => f.microfacet::<T>().d(half.h),
        };
        BasePair { half, added, flake_d }
    }

    /// [`Basecoat::eval_parts`] at a [`BasePair`].
    #[inline(always)]
    #[must_use]
    pub fn eval_pair<T: Lanes>(&self, p: &BasePair<T>, metal_scale: T, pearl_scale: T, parts: BaseParts) -> Rgb<T> {
        let mut f = if parts.pigment { self.pigment_eval(p.half.wi, p.half.wo) } else { Rgb::zero() };
        if !parts.glossy {
            return f;
        }
        if self.metal.is_some() {
            f += self.metal_eval_pair(p);
        }
        if self.flakes.is_some() {
            f += self.flakes_eval_pair(p, metal_scale, pearl_scale);
        }
        f
    }

    /// The flakes' lobe alone (0 without flakes), with the flake populations scaled by `metal_scale` and `pearl_scale`.
    #[inline(always)]
    #[must_use]
    pub fn flakes_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        self.flakes_eval_pair(&self.pair(wi, wo), metal_scale, pearl_scale)
    }

    /// [`Basecoat::flakes_eval`] at a [`BasePair`].
    #[inline(always)]
    #[must_use]
    pub fn flakes_eval_pair<T: Lanes>(&self, p: &BasePair<T>, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        let Some(fl) = &self.flakes else { return Rgb::zero() };
        fl.eval_scaled_h(&fl.microfacet::<T>(), p.flake_d, &p.half, metal_scale, pearl_scale)
    }

    /// The metallic base's lobe alone (0 without one), blurred as in [`Basecoat::eval_parts`].
    #[inline(always)]
    #[must_use]
    pub fn metal_eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        self.metal_eval_pair(&self.pair(wi, wo))
    }

    /// [`Basecoat::metal_eval`] at a [`BasePair`].
    #[inline(always)]
    #[must_use]
    pub fn metal_eval_pair<T: Lanes>(&self, p: &BasePair<T>) -> Rgb<T> {
        let Some(m) = &self.metal else { return Rgb::zero() };
        let (f0, weight) = (Rgb::from_array(m.f0), T::c(m.weight));
        match p.added {
            None => m.eval_with_h(&m.microfacet::<T>(), None, f0, weight, &p.half),
            Some((ai, ao)) => m.eval_with_h(&m.blurred(ao), Some(&m.blurred(ai)), f0, weight, &p.half),
        }
    }

    /// The lobe-selection weights `[pigment, metal, flakes]` restricted to `parts` (the
    /// disabled ones zero).
    #[inline(always)]
    #[must_use]
    pub fn selection_of(&self, parts: BaseParts) -> [f64; 3] {
        let [a, b, c] = self.selection;
        [if parts.pigment { a } else { 0.0 }, if parts.glossy { b } else { 0.0 }, if parts.glossy { c } else { 0.0 }]
    }

    /// The share of the lobe-selection weight that `parts` enable (1 for [`BaseParts::ALL`]).
    #[must_use]
    pub fn selection_share(&self, parts: BaseParts) -> f64 {
        let total: f64 = self.selection.iter().sum();
        if !(total > 0.0) {
            return 0.0;
        }
        self.selection_of(parts).iter().sum::<f64>() / total
    }

    /// Whether the basecoat has a glossy lobe (a metallic base or flakes).
    #[must_use]
    pub fn has_glossy(&self) -> bool {
        self.metal.is_some() || self.flakes.is_some()
    }

    /// `f_b(wi, wo)`, the mean basecoat BRDF.
    #[inline(always)]
    #[must_use]
    pub fn eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        self.eval_scaled(wi, wo, T::c(1.0), T::c(1.0))
    }

    /// Mixture density of [`Basecoat::sample_direction`].
    #[inline(always)]
    #[must_use]
    pub fn pdf<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.pdf_parts(wi, wo, BaseParts::ALL)
    }

    /// The density of [`Basecoat::sample_direction_parts`]: the mixture of the lobes `parts`
    /// enable, renormalised to them.
    #[inline(always)]
    #[must_use]
    pub fn pdf_parts<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, parts: BaseParts) -> T {
        self.pdf_parts_by(wi, wo, parts, FlakeSampler::Projected)
    }

    /// [`Basecoat::pdf_parts`] with the flakes sampled by `sampler` (the density of
    /// [`Basecoat::sample_direction_parts_by`]).
    #[inline(always)]
    #[must_use]
    pub fn pdf_parts_by<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, parts: BaseParts, sampler: FlakeSampler) -> T {
        self.pdf_pair_by(&self.pair(wi, wo), parts, sampler)
    }

    /// [`Basecoat::pdf_parts`] at a [`BasePair`].
    #[inline(always)]
    #[must_use]
    pub fn pdf_pair<T: Lanes>(&self, p: &BasePair<T>, parts: BaseParts) -> T {
        self.pdf_pair_by(p, parts, FlakeSampler::Projected)
    }

    /// [`Basecoat::pdf_parts_by`] at a [`BasePair`].
    #[inline(always)]
    #[must_use]
    fn pdf_pair_by<T: Lanes>(&self, pair: &BasePair<T>, parts: BaseParts, sampler: FlakeSampler) -> T {
        let sel = self.selection_of(parts);
        let [a, b, c] = sel.map(T::c);
        if !(sel.iter().sum::<f64>() > 0.0) {
            return T::c(0.0);
        }
        let total = a + b + c;
        let half = &pair.half;
        let mut p = a * cosine_hemisphere_pdf(half.wi.z);
        if let Some(m) = self.metal.as_ref().filter(|_| parts.glossy) {
            let mf = match pair.added {
                None => m.microfacet::<T>(),
                Some((_, o)) => m.blurred(o),
            };
            p += b * MetalBase::pdf_with_h(&mf, half);
        }
        if let Some(f) = self.flakes.as_ref().filter(|_| parts.glossy) {
            p += c * match sampler {
                FlakeSampler::Projected => FlakeLayer::projected_pdf_h(pair.flake_d, half),
                FlakeSampler::Visible => FlakeLayer::visible_pdf_h(&f.microfacet::<T>(), half),
            };
        }
        lanes::div_fast(p, total)
    }

    /// Picks a lobe with `u0` and samples a direction from it (may be below the surface).
    #[inline]
    #[must_use]
    pub fn sample_direction<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<Vec3<T>> {
        let (wi, valid) = self.sample_direction_masked(wo, u, true);
        valid.then_some(wi)
    }

    /// [`Basecoat::sample_direction`] per lane: the direction and where a lobe was picked.
    /// `active` marks the lanes whose result is used: the flake sampler, which runs one lane
    /// at a time, skips the others.
    #[inline(always)]
    #[must_use]
    pub fn sample_direction_masked<T: Lanes>(&self, wo: Vec3<T>, u: [T; 3], active: T::Mask) -> (Vec3<T>, T::Mask) {
        self.sample_direction_parts(wo, u, active, BaseParts::ALL)
    }

    /// [`Basecoat::sample_direction_masked`] choosing among the lobes `parts` enable only.
    #[inline(always)]
    #[must_use]
    pub fn sample_direction_parts<T: Lanes>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        active: T::Mask,
        parts: BaseParts,
    ) -> (Vec3<T>, T::Mask) {
        self.sample_direction_parts_by(wo, u, active, parts, FlakeSampler::Projected)
    }

    /// [`Basecoat::sample_direction_parts`] with the flakes sampled by `sampler` (density
    /// [`Basecoat::pdf_parts_by`]).
    #[inline(always)]
    #[must_use]
    pub fn sample_direction_parts_by<T: Lanes>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        active: T::Mask,
        parts: BaseParts,
        sampler: FlakeSampler,
    ) -> (Vec3<T>, T::Mask) {
        self.sample_direction_at(wo, u, active, parts, sampler, self.blur_added(wo.z), None)
    }

    /// [`Basecoat::sample_direction_parts_by`] with the blur at `wo` already known: `added`
    /// must be [`Basecoat::blur_added`]`(wo.z)`; `cosine`, if given, must be
    /// `cosine_hemisphere(u[1], u[2])` (a caller that draws it for a lobe of its own passes it
    /// on rather than drawing it twice).
    #[inline(always)]
    #[must_use]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn sample_direction_at<T: Lanes>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        active: T::Mask,
        parts: BaseParts,
        sampler: FlakeSampler,
        added: Option<T>,
        cosine: Option<Vec3<T>>,
    ) -> (Vec3<T>, T::Mask) {
        let pick = pick3(self.selection_of(parts).map(T::c), u[0]);
        // Each lobe's sampler runs only when an active lane chose it (one lane: only the
        // chosen one, so the scalar paths pay for one sampler, not three).
        let [pigment, metal, flake] = [pick.lobe[0] & active, pick.lobe[1] & active, pick.lobe[2] & active];
        let mut wi = Vec3::from_f64(0.0, 0.0, 1.0);
        if pigment.any() {
            let w = match cosine {
                Some(w) => w,
                None => cosine_hemisphere(u[1], u[2]),
            };
            wi = Vec3::select(pigment, w, wi);
        }
        if let Some(m) = self.metal.as_ref().filter(|_| metal.any()) {
            let w = match added {
                None => m.sample_direction(wo, u[1], u[2]),
                Some(a) => MetalBase::sample_direction_with(&m.blurred(a), wo, u[1], u[2]),
            };
            wi = Vec3::select(metal, w, wi);
        }
        if let Some(f) = self.flakes.as_ref().filter(|_| flake.any()) {
            // The flakes take no transmission blur ([`super::coat::FLAKE_MEAN_REFRACTION_SHARE`]).
            let w = FlakeLayer::sample_direction_by(f.microfacet::<T>(), wo, u[1], u[2], flake, sampler);
            wi = Vec3::select(flake, w, wi);
        }
        (wi, pick.valid)
    }

    /// A full sample of the basecoat alone (weight `f_b cos/pdf` with the mixture pdf).
    #[must_use]
    pub fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        self.sample_by(wo, u, FlakeSampler::Projected)
    }

    /// [`Basecoat::sample`] with the flakes sampled by `sampler` (the weight uses the matching
    /// density [`Basecoat::pdf_parts_by`]). The layer-table builds use
    /// [`FlakeSampler::Visible`]: lower-variance estimates than the render-time
    /// [`FlakeSampler::Projected`] (docs/speed.md).
    #[must_use]
    pub fn sample_by<T: Real>(&self, wo: Vec3<T>, u: [T; 3], sampler: FlakeSampler) -> Option<BsdfSample<T>> {
        let (wi, valid) = self.sample_direction_parts_by(wo, u, true, BaseParts::ALL, sampler);
        if !valid || wi.z <= T::zero() {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf_parts_by(wi, wo, BaseParts::ALL, sampler))
    }
}
