//! The flake layer inside the basecoat: mirror-like platelets covering a fraction of the area,
//! their normals spread around the coat normal by a Beckmann distribution, reflecting with a
//! conductor's Fresnel (metallic flakes) or a thin film's Airy reflectance (pearlescent flakes).
//!
//! As a BRDF (in the binder, directions refracted into the coat) a flake population of
//! projected area coverage `c` gives `c · R(wi·h) D(h) G2(wi, wo) / (4 cos θi cos θo)`: the
//! microfacet form with the flakes' normal distribution, height-correlated Smith masking for
//! mutual occlusion at grazing angles, and albedo at most `c`.

use crate::bxdf::BsdfSample;
use crate::frame::half_vector_masked;
use crate::fresnel;
use crate::lanes::{self, keep, Lanes};
use crate::math::{Rgb, Vec3};
use crate::microfacet::{reflection_jacobian, DistributionKind, MaskingKind, Microfacet};
use crate::real::Real;
use crate::table::MuTable;

/// Flake populations sharing one orientation distribution.
#[derive(Clone, Debug)]
pub struct FlakeLayer {
    /// Beckmann α of the flake normals (`tan` of the RMS tilt).
    pub alpha: f64,
    /// Area coverage of metallic flakes, 0..1.
    pub metallic_coverage: f64,
    /// Metallic flake IOR relative to the binder (real part) per channel.
    pub metal_eta: [f64; 3],
    /// Metallic flake extinction relative to the binder per channel.
    pub metal_k: [f64; 3],
    /// Area coverage of pearlescent flakes, 0..1.
    pub pearl_coverage: f64,
    /// Thin-film reflectance of pearlescent flakes over `cos θ` on the flake.
    pub pearl_reflectance: Option<MuTable>,
}

impl FlakeLayer {
    #[inline(always)]
    fn microfacet<T: Lanes>(&self) -> Microfacet<T> {
        let a = T::c(self.alpha);
        Microfacet::new(DistributionKind::Beckmann, a, a)
    }

    /// The Beckmann distribution with `added` (per lane) added to `α²`: the flakes seen through
    /// a rough coat ([`super::coat::TransmissionBlur`]).
    #[inline(always)]
    #[must_use]
    pub fn blurred<T: Lanes>(&self, added: T) -> Microfacet<T> {
        let a = lanes::sqrt(T::c(self.alpha * self.alpha) + added);
        Microfacet::new(DistributionKind::Beckmann, a, a)
    }

    /// Reflectance of the metallic population at incidence `cos` on a flake.
    #[inline(always)]
    #[must_use]
    pub fn metal_reflectance<T: Lanes>(&self, cos: T) -> Rgb<T> {
        fresnel::conductor_rgb(cos, Rgb::from_array(self.metal_eta), Rgb::from_array(self.metal_k))
    }

    /// Reflectance of the pearlescent population at incidence `cos` on a flake.
    #[inline(always)]
    #[must_use]
    pub fn pearl_reflectance<T: Lanes>(&self, cos: T) -> Rgb<T> {
        match &self.pearl_reflectance {
            Some(t) => {
                let [r, g, b] = t.eval_lanes(cos);
                Rgb::new(r, g, b)
            }
            None => Rgb::zero(),
        }
    }

    /// Coverage-weighted reflectance of all flakes at incidence `cos`, with per-population
    /// multipliers (1 for the smooth lobe; the sparkle ratios otherwise).
    #[inline(always)]
    #[must_use]
    pub fn reflectance<T: Lanes>(&self, cos: T, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        let mut r = Rgb::zero();
        if self.metallic_coverage > 0.0 {
            r += self.metal_reflectance(cos) * (T::c(self.metallic_coverage) * metal_scale);
        }
        if self.pearl_coverage > 0.0 {
            r += self.pearl_reflectance(cos) * (T::c(self.pearl_coverage) * pearl_scale);
        }
        r
    }

    /// The flake lobe `R(wi·h) D(h) G2 / (4 cos θi cos θo)` with per-population multipliers.
    #[inline(always)]
    #[must_use]
    pub fn eval_scaled<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        self.eval_scaled_with(&self.microfacet::<T>(), None, wi, wo, metal_scale, pearl_scale)
    }

    /// [`FlakeLayer::eval_scaled`] with the normal distribution `mf`, or under a rough coat
    /// with `other` the smaller of the two lobes' `D G` (the blurred lobes seen from `wo` and
    /// from `wi`, [`super::coat::TransmissionBlur`]).
    #[inline(always)]
    #[must_use]
    pub fn eval_scaled_with<T: Lanes>(
        &self,
        mf: &Microfacet<T>,
        other: Option<&Microfacet<T>>,
        wi: Vec3<T>,
        wo: Vec3<T>,
        metal_scale: T,
        pearl_scale: T,
    ) -> Rgb<T> {
        let (h, defined) = half_vector_masked(wi, wo);
        let g = mf.g(wi, wo, h, MaskingKind::HeightCorrelated);
        let d = mf.d(h);
        let (dg, ok) = match other {
            None => (d * g, lanes::gt(g, T::c(0.0))),
            Some(b) => {
                let dg = lanes::min(d * g, b.d(h) * b.g(wi, wo, h, MaskingKind::HeightCorrelated));
                (dg, lanes::gt(dg, T::c(0.0)))
            }
        };
        let f = self.reflectance(wi.dot(h), metal_scale, pearl_scale) * (dg / (T::c(4.0) * wi.z * wo.z));
        Rgb::select(defined & ok, f, Rgb::zero())
    }

    /// The mean (footprint → ∞) flake lobe.
    #[inline(always)]
    #[must_use]
    pub fn eval<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        self.eval_scaled(wi, wo, T::c(1.0), T::c(1.0))
    }

    /// Density of [`FlakeLayer::sample`]: visible flake normals seen from `wo`, reflected.
    #[inline(always)]
    #[must_use]
    pub fn pdf<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        Self::pdf_with(&self.microfacet::<T>(), wi, wo)
    }

    /// Density of sampling `wi` by the visible normals of `mf` seen from `wo`, reflected.
    #[inline(always)]
    #[must_use]
    pub fn pdf_with<T: Lanes>(mf: &Microfacet<T>, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let (h, defined) = half_vector_masked(wi, wo);
        keep(defined, mf.visible_d(wo, h) * reflection_jacobian(wo, h))
    }

    /// Samples a visible flake normal and reflects `wo` about it (may fall below the surface).
    #[inline]
    #[must_use]
    pub fn sample_direction<T: Real>(&self, wo: Vec3<T>, u1: T, u2: T) -> Vec3<T> {
        self.sample_direction_masked(wo, u1, u2, true)
    }

    /// [`FlakeLayer::sample_direction`] on the lanes set in `active` (the others get an
    /// unspecified direction and cost nothing extra: the Beckmann visible-normal inversion
    /// iterates until the active lanes converge).
    #[inline(always)]
    #[must_use]
    pub fn sample_direction_masked<T: Lanes>(&self, wo: Vec3<T>, u1: T, u2: T, active: T::Mask) -> Vec3<T> {
        Self::sample_direction_with(self.microfacet::<T>(), wo, u1, u2, active)
    }

    /// [`FlakeLayer::sample_direction_masked`] with the Beckmann distribution `mf`.
    #[inline(always)]
    #[must_use]
    pub fn sample_direction_with<T: Lanes>(mf: Microfacet<T>, wo: Vec3<T>, u1: T, u2: T, active: T::Mask) -> Vec3<T> {
        let (ax, ay) = (mf.alpha_x, mf.alpha_y);
        crate::frame::reflect(wo, crate::microfacet::sample_visible_beckmann(ax, ay, wo, u1, u2, active))
    }

    /// A sample of the mean flake lobe alone.
    #[must_use]
    pub fn sample<T: Real>(&self, wo: Vec3<T>, u1: T, u2: T) -> Option<BsdfSample<T>> {
        let wi = self.sample_direction(wo, u1, u2);
        if wi.z <= T::zero() {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }

    /// Mean reflectance at normal incidence (a lobe-selection weight).
    #[must_use]
    pub fn normal_reflectance(&self) -> f64 {
        self.reflectance(1.0f64, 1.0, 1.0).average()
    }
}
