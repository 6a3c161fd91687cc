//! A dielectric interface, smooth or GGX-rough, with microfacet reflection **and** transmission
//! (Walter, Marschner, Li & Torrance 2007, "Microfacet models for refraction through rough
//! surfaces"): the clearcoat's top surface as the position-free Monte Carlo reference sees it.
//!
//! The interface separates the outside (`z > 0`, index 1) from the coat (`z < 0`, relative
//! index `η`). Directions point away from the interface on their own side, so a transmitted
//! pair has `wi.z · wo.z < 0`. Values are for **radiance** transport: `eval(wi, wo)` is the
//! BSDF for light arriving along `wi` and leaving along `wo` (the viewer side).
//!
//! | field | meaning |
//! |---|---|
//! | `eta` | index inside / index outside (1 = no interface: pure pass-through) |
//! | `alpha` | GGX α of the microsurface; 0 = smooth (delta lobes) |
//!
//! ## Formulas (Walter et al. 2007, eqs. 16, 17, 20, 21; height-correlated Smith G)
//! With `η_i`, `η_o` the indices on the sides of `wi` and `wo` and `η_p = η_i/η_o`:
//! - half vector `h ∝ η_p wi + wo`, turned to `h.z > 0` (for reflection `η_p = 1`);
//!   pairs with `(wi·h) wi.z ≤ 0` or `(wo·h) wo.z ≤ 0` see the back of the microfacet: 0;
//! - reflection `f_r = F(wo·h) D(h) G / (4 |cos θi| |cos θo|)`;
//! - transmission `f_t = (1 − F) D G |wi·h| |wo·h| / (|cos θi| |cos θo| (η_p wi·h + wo·h)²)`,
//!   which is Walter's `η_o² (…)/(η_i wi·h + η_o wo·h)²` divided through by `η_o²`. It obeys
//!   the generalised reciprocity `f_t(wi, wo)/η_o² = f_t(wo, wi)/η_i²`;
//! - `G = 1/(1 + Λ(wi) + Λ(wo))` with `Λ` taken on the mirrored direction `(x, y, |z|)`.
//!
//! ## Sampling
//! A visible normal `h` is drawn for `wo` (seen from its own side: for `wo` inside, the
//! normals visible from `−wo`), then reflection is chosen with probability `F(wo·h)` and
//! transmission with `1 − F` (or one of them only, see [`Lobes`]). Densities: reflection
//! `D_wo(h)/(4|wo·h|)`, transmission `D_wo(h) |wi·h| η_p² / (η_p wi·h + wo·h)²` (Walter's
//! eq. 17), each times its choice probability. A smooth interface (α = 0, or η = 1) has delta
//! lobes: `sample` returns the mirror or the Snell direction with the discrete probability as
//! `pdf`, and `eval`/`pdf` are 0.

use crate::fresnel;
use crate::math::Vec3;
use crate::microfacet::{DistributionKind, Microfacet};
use crate::real::Real;

/// Which lobes a sampling call may choose (pbrt-v4's `BxDFReflTransFlags`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobes {
    /// Reflection and transmission, chosen by the Fresnel weight.
    All,
    /// Reflection only (its density is not scaled by a choice probability).
    Reflection,
    /// Transmission only.
    Transmission,
}

impl Lobes {
    #[inline]
    fn reflection(self) -> bool {
        self != Lobes::Transmission
    }
    #[inline]
    fn transmission(self) -> bool {
        self != Lobes::Reflection
    }
}

/// One sample of the interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterfaceSample<T> {
    /// The sampled direction (light side), pointing away from the interface.
    pub wi: Vec3<T>,
    /// BSDF value for radiance from `wi` to `wo`; for a delta lobe its coefficient `/|cos θi|`.
    pub f: T,
    /// Solid-angle density, or the discrete probability of a delta lobe.
    pub pdf: T,
    /// `f |cos θi| / pdf`.
    pub weight: T,
    /// True for the smooth interface's delta lobes.
    pub delta: bool,
}

/// A dielectric interface between the outside (`z > 0`) and a coat of relative index `eta`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughDielectric {
    /// Index inside / index outside.
    pub eta: f64,
    /// GGX α (0 = smooth).
    pub alpha: f64,
}

/// `(x, y, |z|)`: the direction mirrored to the upper side (Λ is even in `z`).
#[inline]
fn upper<T: Real>(w: Vec3<T>) -> Vec3<T> {
    Vec3::new(w.x, w.y, w.z.abs())
}

impl RoughDielectric {
    /// True when the interface has delta lobes only (α = 0, or η = 1: nothing to scatter).
    #[inline]
    #[must_use]
    pub fn is_smooth(&self) -> bool {
        self.alpha == 0.0 || self.eta == 1.0
    }

    #[inline]
    fn microfacet<T: Real>(&self) -> Microfacet<T> {
        let a = T::of(self.alpha);
        Microfacet::new(DistributionKind::Ggx, a, a)
    }

    /// `η_p = η_i/η_o` for the pair (1 for reflection).
    #[inline]
    fn eta_p<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let eta = T::of(self.eta);
        if wi.z * wo.z > T::zero() {
            T::one()
        } else if wo.z > T::zero() {
            eta
        } else {
            T::one() / eta
        }
    }

    /// The generalised half vector (upper side), or `None` when undefined or back-facing.
    #[inline]
    fn half<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, eta_p: T) -> Option<Vec3<T>> {
        let h = wi * eta_p + wo;
        let len2 = h.length_squared();
        if !(len2 > T::zero()) || !len2.is_finite() {
            return None;
        }
        let mut h = h / len2.sqrt();
        if h.z < T::zero() {
            h = -h;
        }
        if wi.dot(h) * wi.z <= T::zero() || wo.dot(h) * wo.z <= T::zero() {
            return None;
        }
        Some(h)
    }

    /// The BSDF for radiance from `wi` to `wo` (reflection or transmission), without cosine.
    #[must_use]
    pub fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        if self.is_smooth() || wi.z == T::zero() || wo.z == T::zero() {
            return T::zero();
        }
        let eta_p = self.eta_p(wi, wo);
        let Some(h) = self.half(wi, wo, eta_p) else { return T::zero() };
        let mf = self.microfacet::<T>();
        let g = T::one() / (T::one() + mf.lambda(upper(wi)) + mf.lambda(upper(wo)));
        let d = mf.d(h);
        let f = fresnel::dielectric(wo.dot(h), T::of(self.eta));
        let cos = (wi.z * wo.z).abs();
        if wi.z * wo.z > T::zero() {
            f * d * g / (T::of(4.0) * cos)
        } else {
            let s = eta_p * wi.dot(h) + wo.dot(h);
            (T::one() - f) * d * g * (wi.dot(h) * wo.dot(h)).abs() / (cos * s * s)
        }
    }

    /// Density with which [`RoughDielectric::sample`] for `wo` and `lobes` returns `wi`.
    #[must_use]
    pub fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, lobes: Lobes) -> T {
        if self.is_smooth() || wi.z == T::zero() || wo.z == T::zero() {
            return T::zero();
        }
        let reflect = wi.z * wo.z > T::zero();
        if (reflect && !lobes.reflection()) || (!reflect && !lobes.transmission()) {
            return T::zero();
        }
        let eta_p = self.eta_p(wi, wo);
        let Some(h) = self.half(wi, wo, eta_p) else { return T::zero() };
        let r = fresnel::dielectric(wo.dot(h), T::of(self.eta));
        let pr = if lobes.reflection() { r } else { T::zero() };
        let pt = if lobes.transmission() { T::one() - r } else { T::zero() };
        if !(pr + pt > T::zero()) {
            return T::zero();
        }
        let visible = self.microfacet::<T>().visible_d(upper_side(wo), h);
        if reflect {
            visible / (T::of(4.0) * wo.dot(h).abs()) * pr / (pr + pt)
        } else {
            let s = eta_p * wi.dot(h) + wo.dot(h);
            visible * wi.dot(h).abs() * eta_p * eta_p / (s * s) * pt / (pr + pt)
        }
    }

    /// Samples the light-side direction for `wo` from `u` (`u[0]` picks the lobe).
    #[must_use]
    pub fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3], lobes: Lobes) -> Option<InterfaceSample<T>> {
        if wo.z == T::zero() {
            return None;
        }
        let eta = T::of(self.eta);
        // Index ratio transmitted/incident for light crossing from wo's side.
        let eta_t = if wo.z > T::zero() { eta } else { T::one() / eta };
        if self.is_smooth() {
            let r = fresnel::dielectric(wo.z, eta);
            let pr = if lobes.reflection() { r } else { T::zero() };
            let pt = if lobes.transmission() { T::one() - r } else { T::zero() };
            if !(pr + pt > T::zero()) {
                return None;
            }
            if u[0] < pr / (pr + pt) {
                let wi = crate::frame::mirror_z(wo);
                let pdf = pr / (pr + pt);
                return Some(InterfaceSample { wi, f: r / wi.z.abs(), pdf, weight: r / pdf, delta: true });
            }
            let n = Vec3::new(T::zero(), T::zero(), T::one().copysign(wo.z));
            let wi = crate::frame::refract(wo, n, eta_t)?;
            let pdf = pt / (pr + pt);
            // Radiance from wi to wo: the coefficient (1 − F)/η_p² with η_p = η_i/η_o = eta_t.
            let coefficient = (T::one() - r) / (eta_t * eta_t);
            return Some(InterfaceSample {
                wi,
                f: coefficient / wi.z.abs(),
                pdf,
                weight: coefficient / pdf,
                delta: true,
            });
        }
        let h = self.microfacet::<T>().sample_m(upper_side(wo), u[1], u[2], true);
        let r = fresnel::dielectric(wo.dot(h), eta);
        let pr = if lobes.reflection() { r } else { T::zero() };
        let pt = if lobes.transmission() { T::one() - r } else { T::zero() };
        if !(pr + pt > T::zero()) {
            return None;
        }
        let wi = if u[0] < pr / (pr + pt) {
            let wi = crate::frame::reflect(wo, h);
            if wi.z * wo.z <= T::zero() {
                return None;
            }
            wi
        } else {
            let n = if wo.dot(h) > T::zero() { h } else { -h };
            let wi = crate::frame::refract(wo, n, eta_t)?;
            if wi.z * wo.z >= T::zero() {
                return None;
            }
            wi
        };
        let (f, pdf) = (self.eval(wi, wo), self.pdf(wi, wo, lobes));
        if !(pdf > T::zero()) || !pdf.is_finite() {
            return None;
        }
        let weight = f * wi.z.abs() / pdf;
        weight.is_finite().then_some(InterfaceSample { wi, f, pdf, weight, delta: false })
    }
}

/// `w` or `−w`, whichever points up: the side from which `w`'s visible normals are seen.
#[inline]
fn upper_side<T: Real>(w: Vec3<T>) -> Vec3<T> {
    if w.z < T::zero() {
        -w
    } else {
        w
    }
}

/// Scattering events on the microsurface after which [`RoughDielectric::sample_multiple`] gives
/// up (the walk's energy is then lost; at α ≤ 0.5 walks end after a handful of events).
pub const MAX_MICROSURFACE_EVENTS: usize = 256;

impl RoughDielectric {
    /// Heitz's signed `Λ`: `Λ(w)` for a direction going up, `−1 − Λ(w)` going down.
    #[inline]
    fn lambda_signed(&self, w: Vec3<f64>) -> f64 {
        let l = self.microfacet::<f64>().lambda(upper(w));
        if w.z > 0.0 {
            l
        } else {
            -1.0 - l
        }
    }

    /// The next height of a ray travelling along `w` from height `h` over a microsurface of
    /// uniform heights on [−1, 1] (`C1(h) = (h + 1)/2`), or `None` when it leaves upward
    /// (Heitz et al. 2016, `Microsurface::height`).
    fn next_height(&self, w: Vec3<f64>, h: f64, u: f64) -> Option<f64> {
        let c1 = |h: f64| ((h + 1.0) * 0.5).clamp(0.0, 1.0);
        let inv_c1 = |u: f64| (2.0 * u - 1.0).clamp(-1.0, 1.0);
        if w.z > 0.9999 {
            return None;
        }
        if w.z < -0.9999 {
            return Some(inv_c1(u * c1(h)));
        }
        if w.z.abs() < 1e-4 {
            return Some(h);
        }
        let lambda = self.lambda_signed(w);
        if w.z > 0.0 {
            // Probability of leaving without another intersection: G1 = C1(h)^Λ.
            let g1 = c1(h).powf(lambda);
            if u > 1.0 - g1 {
                return None;
            }
        }
        Some(inv_c1(c1(h) / (1.0 - u).powf(1.0 / lambda)))
    }

    /// GGX visible normal for the direction `w` (pointing away from the microsurface, **any**
    /// side of the mean plane: Heitz 2018's projected-disk warp keeps only the visible part of the
    /// hemisphere also for `w.z < 0`, as the walk needs after a reflection upward).
    fn sample_visible_normal(&self, w: Vec3<f64>, u1: f64, u2: f64) -> Vec3<f64> {
        let a = self.alpha;
        let vh = Vec3::new(a * w.x, a * w.y, w.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) * (1.0 / len2.sqrt()) } else { Vec3::new(1.0, 0.0, 0.0) };
        let t2 = vh.cross(t1);
        let r = u1.sqrt();
        let phi = std::f64::consts::TAU * u2;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-12)).normalize()
    }

    /// A direction from the **multiple-scattering** rough dielectric (Heitz, Hanika, d'Eon &
    /// Dachsbacher 2016, "Multiple-scattering microfacet BSDFs with the Smith model", §5): the
    /// light arrives along `wo` (pointing away from the interface on its own side) and walks the
    /// microsurface — next height from the Smith height model, a visible microfacet, Fresnel
    /// picks reflection or refraction — until it leaves upward or downward. Every event keeps
    /// the energy, so the walk's weight is 1 for light (flux): what Walter's single-scattering
    /// lobes lose to masking is here scattered again. The direction returned points away from
    /// the interface on the side the light leaves to; `None` only for a walk cut after
    /// [`MAX_MICROSURFACE_EVENTS`] events. A smooth interface samples its delta lobes by Fresnel.
    pub fn sample_multiple(&self, wo: Vec3<f64>, rng: &mut crate::rng::Pcg32) -> Option<(Vec3<f64>, usize)> {
        if wo.z == 0.0 {
            return None;
        }
        if self.is_smooth() {
            let s = self.sample(wo, rng.uniform3(), Lobes::All)?;
            return Some((s.wi, 1));
        }
        let mut outside = wo.z > 0.0;
        let mut wr = -wo; // the travel direction
        let start = 1.0 + 0.998; // above every height (Heitz: 1 + C1⁻¹(0.999))
        let mut hr = if outside { start } else { -start };
        for events in 0..MAX_MICROSURFACE_EVENTS {
            // Inside the coat the walk runs in the point-mirrored frame (heights and directions
            // negated), where the microsurface has the same statistics seen from above.
            let u = rng.uniform();
            let next = if outside { self.next_height(wr, hr, u) } else { self.next_height(-wr, -hr, u).map(|h| -h) };
            let Some(h) = next else { return Some((wr, events)) };
            hr = h;
            // Phase function: a visible microfacet for wi = −wr, reflect or refract by Fresnel.
            let wi = -wr;
            let (u1, u2, u3) = (rng.uniform(), rng.uniform(), rng.uniform());
            let wm =
                if outside { self.sample_visible_normal(wi, u1, u2) } else { -self.sample_visible_normal(-wi, u1, u2) };
            let eta = if outside { self.eta } else { 1.0 / self.eta };
            let cos_i = wi.dot(wm);
            let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
            let f = fresnel::dielectric(cos_i.abs(), eta);
            if u3 < f || sin2_t >= 1.0 {
                wr = wm * (2.0 * cos_i) - wi;
            } else {
                let cos_t = -(1.0 - sin2_t).sqrt();
                wr = (wm * (cos_i / eta + cos_t) - wi * (1.0 / eta)).normalize();
                outside = !outside;
            }
            if !(wr.z.is_finite() && hr.is_finite()) {
                return None;
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::stats::chi2_sf;
    use crate::frame::spherical_direction;
    use crate::paint::coat::Coat;
    use crate::rng::Pcg32;
    use std::f64::consts::PI;

    fn dir(cos: f64, phi: f64) -> Vec3<f64> {
        spherical_direction((1.0 - cos * cos).max(0.0).sqrt(), cos, phi)
    }

    /// The reflection lobe is the clearcoat's own GGX reflection (same D, G, F).
    #[test]
    fn reflection_is_the_coats_reflection() {
        let (eta, alpha) = (1.5, 0.2);
        let top = RoughDielectric { eta, alpha };
        let coat = Coat::new(eta, alpha, 40.0, [0.0; 3]);
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..200 {
            let wi = dir(rng.range(0.01, 1.0), rng.range(0.0, 2.0 * PI));
            let wo = dir(rng.range(0.01, 1.0), rng.range(0.0, 2.0 * PI));
            let (a, b) = (top.eval(wi, wo), coat.reflection_eval(wi, wo));
            assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-300), "{a} vs {b}");
            let (p, q) = (top.pdf(wi, wo, Lobes::Reflection), coat.reflection_pdf(wi, wo));
            assert!((p - q).abs() <= 1e-12 * q.max(1e-300), "{p} vs {q}");
        }
    }

    /// Walter's transmission term carries `η_o²`, so `f(wi, wo)/η_o² = f(wo, wi)/η_i²`.
    #[test]
    fn transmission_obeys_generalised_reciprocity() {
        let top = RoughDielectric { eta: 1.6, alpha: 0.3 };
        let mut rng = Pcg32::new(3, 4);
        let mut tested = 0;
        for _ in 0..500 {
            let outside = dir(rng.range(0.01, 1.0), rng.range(0.0, 2.0 * PI));
            let inside = -dir(rng.range(0.01, 1.0), rng.range(0.0, 2.0 * PI));
            let into = top.eval(outside, inside); // light from outside, seen inside: η_o = η
            let out = top.eval(inside, outside); // light from inside, seen outside: η_o = 1
            if into > 0.0 {
                tested += 1;
                assert!((into / (1.6 * 1.6) - out).abs() <= 1e-10 * out, "{into} {out}");
            } else {
                assert_eq!(out, 0.0);
            }
        }
        assert!(tested > 100, "{tested}");
    }

    /// Nearly smooth interface at normal incidence: reflection albedo `F0 = ((η−1)/(η+1))²`;
    /// radiance transmission `(1 − F0)/η²` entering, `(1 − F0) η²` leaving (radiance scales
    /// with η²). Past the critical angle from inside everything is reflected.
    #[test]
    fn near_smooth_albedos_match_fresnel() {
        let eta = 1.5f64;
        let f0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        let top = RoughDielectric { eta, alpha: 0.01 };
        let mut rng = Pcg32::new(5, 6);
        let n = 100_000;
        let estimate = |wo: Vec3<f64>, rng: &mut Pcg32| {
            let (mut r, mut t) = (0.0, 0.0);
            for _ in 0..n {
                if let Some(s) = top.sample(wo, rng.uniform3(), Lobes::All) {
                    if s.wi.z * wo.z > 0.0 {
                        r += s.weight;
                    } else {
                        t += s.weight;
                    }
                }
            }
            (r / n as f64, t / n as f64)
        };
        let (r, t) = estimate(Vec3::new(0.0, 0.0, 1.0), &mut rng);
        assert!((r - f0).abs() < 1e-3 && (t - (1.0 - f0) / (eta * eta)).abs() < 1e-3, "{r} {t}");
        let (r, t) = estimate(Vec3::new(0.0, 0.0, -1.0), &mut rng);
        assert!((r - f0).abs() < 1e-3 && (t - (1.0 - f0) * eta * eta).abs() < 3e-3, "{r} {t}");
        let (r, t) = estimate(-dir(0.3, 0.4), &mut rng);
        assert!((r - 1.0).abs() < 2e-3 && t < 1e-3, "{r} {t}");
        // The smooth interface gives the same numbers exactly.
        let smooth = RoughDielectric { eta, alpha: 0.0 };
        let s = smooth.sample(Vec3::new(0.0, 0.0, 1.0), [0.99, 0.5, 0.5], Lobes::Transmission).unwrap();
        assert!(s.delta && (s.weight - (1.0 - f0) / (eta * eta)).abs() < 1e-15);
    }

    /// χ² test of `sample` against `pdf` over the whole sphere (both lobes), from outside and
    /// from inside; the mass the sampler loses must match `1 − ∫ pdf`.
    #[test]
    fn sampler_matches_pdf_chi2() {
        for (alpha, wo) in [(0.3, dir(0.7, 0.3)), (0.5, -dir(0.8, 1.0)), (0.2, dir(0.25, 2.0)), (0.4, -dir(0.5, 0.0))] {
            let top = RoughDielectric { eta: 1.5, alpha };
            let (nt, np) = (24, 48);
            let n = 400_000;
            let mut counts = vec![0.0; nt * np];
            let mut rng = Pcg32::new(11, 12);
            let mut failed = 0.0;
            for _ in 0..n {
                match top.sample(wo, rng.uniform3(), Lobes::All) {
                    Some(s) => {
                        let (f, p) = (top.eval(s.wi, wo), top.pdf(s.wi, wo, Lobes::All));
                        assert!((s.pdf - p).abs() <= 1e-9 * p && (s.f - f).abs() <= 1e-9 * f.max(1e-300));
                        let i = (((s.wi.z + 1.0) * 0.5 * nt as f64) as usize).min(nt - 1);
                        let phi = s.wi.y.atan2(s.wi.x).rem_euclid(2.0 * PI);
                        let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
                        counts[i * np + j] += 1.0;
                    }
                    None => failed += 1.0,
                }
            }
            // Expected counts: midpoint quadrature of pdf in (cos θ, φ) inside each cell.
            let sub = 12;
            let mut expected = vec![0.0; nt * np];
            let mut integral = 0.0;
            for i in 0..nt {
                for j in 0..np {
                    let mut s = 0.0;
                    for a in 0..sub {
                        for b in 0..sub {
                            let c = -1.0 + 2.0 * (i as f64 + (a as f64 + 0.5) / sub as f64) / nt as f64;
                            let phi = 2.0 * PI * (j as f64 + (b as f64 + 0.5) / sub as f64) / np as f64;
                            s += top.pdf(dir(c, phi), wo, Lobes::All);
                        }
                    }
                    let cell = s / (sub * sub) as f64 * (2.0 / nt as f64) * (2.0 * PI / np as f64);
                    integral += cell;
                    expected[i * np + j] = cell * n as f64;
                }
            }
            // Pool cells with fewer than 20 expected samples into one bin, plus the failures.
            let (mut chi2, mut dof) = (0.0, 0usize);
            let (mut pool_obs, mut pool_exp) = (failed, (1.0 - integral).max(0.0) * n as f64);
            for (o, e) in counts.iter().zip(&expected) {
                if *e < 20.0 {
                    pool_obs += o;
                    pool_exp += e;
                } else {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            if pool_exp > 5.0 {
                chi2 += (pool_obs - pool_exp) * (pool_obs - pool_exp) / pool_exp;
                dof += 1;
            }
            let p = chi2_sf(chi2, (dof - 1) as f64);
            assert!(
                p > 1e-3,
                "α {alpha} wo {wo:?}: χ² {chi2} dof {dof} p {p}; ∫pdf {integral}, failed {}",
                failed / n as f64
            );
        }
    }

    /// Everything stays finite and non-negative at grazing and degenerate pairs.
    #[test]
    fn degenerate_directions_are_finite() {
        let top = RoughDielectric { eta: 1.5, alpha: 0.001 };
        let g = dir(1e-7, 0.0);
        let cases = [(g, g), (g, -g), (g, crate::frame::mirror_z(g)), (-g, g), (Vec3::new(0.0, 0.0, 1.0), -g)];
        for (a, b) in cases {
            for (wi, wo) in [(a, b), (b, a)] {
                let f = top.eval(wi, wo);
                let p = top.pdf(wi, wo, Lobes::All);
                assert!(f.is_finite() && f >= 0.0 && p.is_finite() && p >= 0.0, "{wi:?} {wo:?}: {f} {p}");
                if let Some(s) = top.sample(wo, [0.5, 0.5, 0.5], Lobes::All) {
                    assert!(s.weight.is_finite() && s.weight >= 0.0);
                }
            }
        }
    }
    /// Issue 17, item 3: the multiple-scattering walk (Heitz et al. 2016) keeps every walk's
    /// energy (no walk lost: 0 of 60 000 per direction at α 0.3), and its **first** event
    /// is the Smith single-scattering interface with uniform heights: a walk that leaves
    /// after one reflection does so with probability `E[F (1 + Λo)/(1 + Λo + Λr)]` (Walter's
    /// reflection with height-correlated G), after one refraction with
    /// `E[(1 − F)(1 + Λo) B(1 + Λo, 1 + Λt)]` (the Beta function of Heitz 2014 §5 for
    /// transmission; 48-point Gauss-Legendre per half, error ≲ 4e-4 against a noise of 2e-3),
    /// expectations over 20 000 visible normals of the crate's own sampler (the walk has its
    /// own). Asserted within 4.5 σ of both estimates' noise (measured ≤ 1.6 σ); a sign error
    /// in Λ or a wrong mirrored frame moves these probabilities by tens of σ. The single-scattering interface loses 1–24 % at α 0.3 (the energy
    /// table of `docs/paint-validation.md`); the walk loses nothing.
    #[test]
    fn multiple_scattering_walk_is_lossless_and_starts_as_smith_single_scattering() {
        use crate::quadrature::gauss_legendre_on;
        let top = RoughDielectric { eta: 1.5, alpha: 0.3 };
        let mf = top.microfacet::<f64>();
        let lambda = |w: Vec3<f64>| mf.lambda(upper(w));
        // ∫0^1 c^a (1 − c)^b dc, split at 1/2 (endpoint kinks).
        let beta_fn = |a: f64, b: f64| {
            let mut t = 0.0;
            for (lo, hi) in [(0.0, 0.5), (0.5, 1.0)] {
                let (x, w) = gauss_legendre_on(48, lo, hi);
                t += x.iter().zip(&w).map(|(c, w)| w * c.powf(a) * (1.0 - c).powf(b)).sum::<f64>();
            }
            t
        };
        let (n, n_expect) = (60_000, 20_000);
        for (mu, outside) in [(1.0, true), (0.5, true), (0.2, true), (0.9, false), (0.5, false)] {
            let wo = if outside { dir(mu, 0.3) } else { -dir(mu, 0.3) };
            let lo = lambda(wo);
            // Expectation over visible normals.
            let mut rng = Pcg32::new(11, 12);
            let (mut er, mut er2, mut et, mut et2) = (0.0, 0.0, 0.0, 0.0);
            let eta_t = if outside { 1.5 } else { 1.0 / 1.5 };
            for _ in 0..n_expect {
                let h = mf.sample_m(upper_side(wo), rng.uniform(), rng.uniform(), true);
                let m = if wo.dot(h) > 0.0 { h } else { -h };
                let f = fresnel::dielectric(wo.dot(m), eta_t);
                let r = crate::frame::reflect(wo, m);
                let vr = if r.z * wo.z > 0.0 { f * (1.0 + lo) / (1.0 + lo + lambda(r)) } else { 0.0 };
                let vt = match crate::frame::refract(wo, m, eta_t) {
                    Some(t) if t.z * wo.z < 0.0 => (1.0 - f) * (1.0 + lo) * beta_fn(lo, lambda(t)),
                    _ => 0.0,
                };
                er += vr;
                er2 += vr * vr;
                et += vt;
                et2 += vt * vt;
            }
            let ne = n_expect as f64;
            let (er, et) = (er / ne, et / ne);
            let (ser, set) = (((er2 / ne - er * er) / ne).sqrt(), ((et2 / ne - et * et) / ne).sqrt());
            let nf = n as f64;
            // The walk.
            let mut rng = Pcg32::new(13, 14);
            let (mut once_r, mut once_t, mut lost, mut events) = (0usize, 0usize, 0usize, 0usize);
            for _ in 0..n {
                match top.sample_multiple(wo, &mut rng) {
                    None => lost += 1,
                    Some((d, k)) => {
                        events += k;
                        if k == 1 {
                            if d.z * wo.z > 0.0 {
                                once_r += 1;
                            } else {
                                once_t += 1;
                            }
                        }
                    }
                }
            }
            let (pr, pt) = (once_r as f64 / nf, once_t as f64 / nf);
            let sr = (pr * (1.0 - pr) / nf + ser * ser).sqrt();
            let st = (pt * (1.0 - pt) / nf + set * set).sqrt();
            eprintln!(
                "μ {mu} {}: one reflection {pr:.5} vs {er:.5} ({:.1} σ), one refraction {pt:.5} vs {et:.5} ({:.1} σ), single scattering keeps {:.4}, mean events {:.3}, lost {lost}",
                if outside { "outside" } else { "inside" },
                (pr - er) / sr,
                (pt - et) / st,
                er + et,
                events as f64 / nf
            );
            assert_eq!(lost, 0);
            assert!((pr - er).abs() < 4.5 * sr, "μ {mu}: {pr} vs {er}");
            assert!((pt - et).abs() < 4.5 * st, "μ {mu}: {pt} vs {et}");
        }
    }
}
