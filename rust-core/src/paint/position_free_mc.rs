//! Position-free Monte Carlo reference for the coated paint's layer stack: an unbiased,
//! stochastic evaluation of the **same** stack the analytic model approximates, used to
//! measure the analytic model's approximations (`examples/layer_validation.rs`,
//! `docs/paint-validation.md`).
//!
//! ## The stack
//! - top: the clearcoat surface, a smooth or GGX-rough dielectric with real microfacet
//!   reflection **and** transmission ([`RoughDielectric`], Walter et al. 2007);
//! - a homogeneous, non-scattering slab of the coat's thickness and absorption
//!   (Beer-Lambert: a crossing along inside direction `w` transmits `exp(−σ_a d/|cos θ|)`);
//! - bottom: the [`Basecoat`] BRDF, evaluated in the binder (inside directions).
//!
//! ## The estimator
//! Guo, Hašan & Zhao 2018 ("Position-free Monte Carlo simulation for arbitrary layered
//! BSDFs") write the layered BSDF as a path integral over directions and depths only: for
//! laterally infinite, homogeneous layers the horizontal position of a vertex never matters,
//! so a path is a sequence of interface events, each a product of BSDF values in solid-angle
//! measure. Without scattering in the slab every vertex sits on one of the two interfaces and
//! the state of a walk is (interface, direction, throughput). This is the unidirectional
//! estimator with next-event estimation of their §5, in the form pbrt-v4's
//! `LayeredBxDF::f` uses:
//!
//! 1. sample a transmission through the top for `wo` (the camera side) and, independently,
//!    one for `wi` (the light side: a direction `d` into the slab with density `p_T(d | wi)`);
//! 2. walk: cross the slab (`β ← β τ(w)`); at the basecoat add the light-side connection
//!    `β f_b(−d, −w) |cos d| τ(d) f_T(wi → d) / p_T(d | wi)`, then sample the basecoat; along
//!    the sampled direction `u` add the exit `β τ(u) f_T(wi → −u)` (rough top only); at the
//!    top, continue with a sampled internal reflection;
//! 3. Russian roulette after 3 events once `max β < 0.25` (pbrt-v4's rule), a depth cap.
//!
//! The two ways of reaching `wi` (light-side direction `d` vs basecoat-sampled `u = −d`) are
//! combined with the power heuristic on the **same** variable, the inside direction: the
//! basecoat density `p_b(−d | −w)` against `p_T(d | wi)`. (pbrt-v4 weights the
//! basecoat-sampled strategy against the density of sampling `wi` from `−u`, a different
//! measure, so its weights need not sum to one; this implementation keeps them consistent,
//! and a test checks that the MIS estimator agrees with the basecoat-sampling-only one.)
//! With a smooth top only the light-side connection exists and it is exact (weight 1).
//!
//! Values are for radiance transport: the top's transmission carries `1/η²` leaving the coat
//! and `η²` entering it, so an entering-and-leaving path is free of `η`, as it must be.
//!
//! [`reference_albedo`] follows a path analogue (pbrt-v4's `LayeredBxDF::Sample_f`): the top
//! reflects or transmits by its own sampler, and the throughput of a path that leaves the
//! stack is the albedo estimate.
//!
//! ## Cost
//! A reference evaluation needs hundreds to thousands of walks for 1 % noise, each several
//! basecoat evaluations: 10⁴–10⁶ times the analytic model (measured per configuration in
//! `docs/paint-validation.md`).

use super::basecoat::Basecoat;
use super::coat::Coat;
use super::coated_paint::CoatedPaint;
use super::rough_dielectric::{Lobes, RoughDielectric};
use crate::math::{Rgb, Vec3};
use crate::rng::Pcg32;
use crate::sampling::power_heuristic;

/// Interface events before a walk is cut (Russian roulette ends almost all walks long before).
pub const DEFAULT_MAX_DEPTH: usize = 1000;

/// A Monte Carlo estimate per channel with its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Sample mean.
    pub value: Rgb<f64>,
    /// Standard error of the mean (sample standard deviation / √walks).
    pub std_error: Rgb<f64>,
    /// Number of walks.
    pub walks: usize,
}

impl Estimate {
    /// Relative standard error of one walk in luminance (`σ/mean`): `(σ_rel/ε)²` walks give
    /// relative noise `ε`.
    #[must_use]
    pub fn relative_std_dev(&self) -> f64 {
        let y = self.value.luminance();
        if y > 0.0 {
            self.std_error.luminance() * (self.walks as f64).sqrt() / y
        } else {
            0.0
        }
    }
}

/// Accumulates per-walk RGB values into a mean and a standard error.
#[derive(Default)]
struct Accumulator {
    sum: [f64; 3],
    sum2: [f64; 3],
    n: usize,
}

impl Accumulator {
    fn add(&mut self, v: Rgb<f64>) {
        for c in 0..3 {
            self.sum[c] += v[c];
            self.sum2[c] += v[c] * v[c];
        }
        self.n += 1;
    }

    fn finish(&self) -> Estimate {
        let n = self.n.max(1) as f64;
        let mean = self.sum.map(|s| s / n);
        let se = [0, 1, 2].map(|c| {
            let var = (self.sum2[c] / n - mean[c] * mean[c]).max(0.0) * n / (n - 1.0).max(1.0);
            (var / n).sqrt()
        });
        Estimate { value: Rgb::from_array(mean), std_error: Rgb::from_array(se), walks: self.n }
    }
}

/// How an analogue walk left the stack.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkExit {
    /// The path's throughput.
    pub weight: Rgb<f64>,
    /// The exit direction (outside, pointing away from the surface).
    pub direction: Vec3<f64>,
    /// False for light the top reflected at once; true for light that crossed the coat.
    pub entered: bool,
    /// How many times the path scattered off the basecoat (0 for the top reflection).
    pub base_bounces: u32,
}

/// The bin of direction `d` (upper hemisphere) in a lobe histogram around azimuth `phi_o`.
#[must_use]
pub fn lobe_bin(d: Vec3<f64>, phi_o: f64, n_mu: usize, n_phi: usize) -> usize {
    let i = ((d.z * n_mu as f64) as usize).min(n_mu - 1);
    let mut dphi = (d.y.atan2(d.x) - phi_o).abs();
    if dphi > std::f64::consts::PI {
        dphi = std::f64::consts::TAU - dphi;
    }
    let j = ((dphi / std::f64::consts::PI * n_phi as f64) as usize).min(n_phi - 1);
    i * n_phi + j
}

/// A reflected lobe binned over equal solid angles (see [`PositionFreeMc::albedo_lobe`]).
#[derive(Clone, Debug)]
pub struct LobeHistogram {
    /// `∫ f cos dω` over each bin per channel (row-major: `cos θ` bin, then azimuth bin).
    pub value: Vec<[f64; 3]>,
    /// Standard error of each bin's value.
    pub std_error: Vec<[f64; 3]>,
    /// Bins over `cos θ`.
    pub n_mu: usize,
    /// Bins over the folded azimuth difference `[0, π]`.
    pub n_phi: usize,
}

impl LobeHistogram {
    /// Means and standard errors from per-bin sums of `n` independent samples.
    #[must_use]
    pub fn from_sums(sum: &[[f64; 3]], sum2: &[[f64; 3]], n: usize, n_mu: usize, n_phi: usize) -> Self {
        let nf = n.max(1) as f64;
        let value = sum.iter().map(|s| s.map(|x| x / nf)).collect();
        let std_error = sum
            .iter()
            .zip(sum2)
            .map(|(s, q)| [0, 1, 2].map(|c| ((q[c] / nf - (s[c] / nf).powi(2)).max(0.0) / (nf - 1.0).max(1.0)).sqrt()))
            .collect();
        Self { value, std_error, n_mu, n_phi }
    }

    /// The directional albedo (sum over bins) per channel.
    #[must_use]
    pub fn albedo(&self) -> [f64; 3] {
        let mut a = [0.0; 3];
        for v in &self.value {
            for c in 0..3 {
                a[c] += v[c];
            }
        }
        a
    }

    /// Rec.709 luminance of each bin.
    #[must_use]
    pub fn luminance(&self) -> Vec<f64> {
        self.value.iter().map(|v| Rgb::from_array(*v).luminance()).collect()
    }
}

/// The layer stack of a [`CoatedPaint`] as the reference sees it.
#[derive(Clone, Debug)]
pub struct PositionFreeMc<'a> {
    top: RoughDielectric,
    coat: &'a Coat,
    base: Basecoat,
    /// Interface events before a walk is cut.
    pub max_depth: usize,
    /// Light-side connections (next-event estimation) on; off leaves only basecoat sampling
    /// (rough tops only: a smooth top can only be reached by the connection).
    pub light_sampling: bool,
    /// The analogue walks ([`PositionFreeMc::albedo`], [`PositionFreeMc::albedo_lobe`]) cross
    /// a rough top by Heitz et al.'s multiple-scattering random walk on the microsurface
    /// ([`RoughDielectric::sample_multiple`], lossless) instead of Walter's single-scattering
    /// lobes (which lose what the microsurface masks). On by default; [`PositionFreeMc::eval`]
    /// (next-event estimation needs the interface's BSDF value) always uses Walter's lobes.
    pub multiple_scattering: bool,
}

impl<'a> PositionFreeMc<'a> {
    /// The stack of `paint`: its coat (index, roughness, thickness, absorption) and basecoat.
    #[must_use]
    pub fn new(paint: &'a CoatedPaint) -> Self {
        let coat = paint.coat();
        Self {
            top: RoughDielectric { eta: coat.ior, alpha: coat.roughness },
            coat,
            // The physical basecoat: the walks cross the rough interface themselves (the
            // analytic model's transmission blur stands in for that).
            base: paint.basecoat().clone().with_blur(None),
            max_depth: DEFAULT_MAX_DEPTH,
            light_sampling: true,
            multiple_scattering: true,
        }
    }

    /// The top interface.
    #[must_use]
    pub fn top(&self) -> &RoughDielectric {
        &self.top
    }

    /// Beer-Lambert transmittance of one crossing along inside direction `w`.
    #[inline]
    fn tau(&self, w: Vec3<f64>) -> Rgb<f64> {
        Rgb::from_array(self.coat.attenuation(w.z.abs()))
    }

    /// Reflection at the top surface (exact; 0 off the mirror direction for a smooth coat).
    #[must_use]
    pub fn top_reflection(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
        self.top.eval(wi, wo)
    }

    /// One walk's estimate of the light that crosses the top and returns (everything but the
    /// top reflection).
    pub fn body_walk(&self, wi: Vec3<f64>, wo: Vec3<f64>, rng: &mut Pcg32) -> Rgb<f64> {
        let mut f = Rgb::zero();
        let top = &self.top;
        let eta2 = self.top.eta * self.top.eta;
        // Camera side: enter the coat.
        let Some(enter) = top.sample(wo, rng.uniform3(), Lobes::Transmission) else { return f };
        // Light side: a direction d into the coat for wi, with f_T(wi → d) (radiance entering:
        // the reverse value times η², by generalised reciprocity) and its density.
        let light = top.sample(wi, rng.uniform3(), Lobes::Transmission).map(|s| (s.wi, s.f * eta2, s.pdf, s.delta));
        let use_light = self.light_sampling || top.is_smooth();
        let mut beta = Rgb::splat(enter.weight);
        let mut w = enter.wi;
        let mut at_bottom = false;
        for depth in 0..self.max_depth {
            let m = beta.max_channel();
            if depth > 3 && m < 0.25 {
                let q = (1.0 - m).max(0.0);
                if rng.uniform() < q {
                    break;
                }
                beta = beta / (1.0 - q);
            }
            beta = beta * self.tau(w);
            at_bottom = !at_bottom;
            if !at_bottom {
                // Internal reflection at the top (transmission toward wi is the connections').
                let Some(s) = top.sample(-w, rng.uniform3(), Lobes::Reflection) else { break };
                beta *= s.weight;
                w = s.wi;
                continue;
            }
            let wo_b = -w;
            if let (true, Some((d, f_light, p_light, delta))) = (use_light, light) {
                let wl = -d;
                let fb = self.base.eval(wl, wo_b);
                if !fb.is_black() && p_light > 0.0 {
                    let weight = if delta || !self.light_sampling {
                        1.0
                    } else {
                        power_heuristic(p_light, self.base.pdf(wl, wo_b))
                    };
                    f += beta * fb * self.tau(d) * (wl.z * f_light * weight / p_light);
                }
            }
            let Some(bs) = self.base.sample(wo_b, rng.uniform3()) else { break };
            beta = beta * bs.weight;
            w = bs.wi;
            if !top.is_smooth() {
                let f_exit = top.eval(wi, -w);
                if f_exit > 0.0 {
                    let weight = if self.light_sampling {
                        power_heuristic(bs.pdf, top.pdf(-w, wi, Lobes::Transmission))
                    } else {
                        1.0
                    };
                    f += beta * self.tau(w) * (f_exit * weight);
                }
            }
        }
        f
    }

    /// One crossing or reflection at the top for light arriving along `w` (its own side):
    /// the direction it leaves along and the walk's weight.
    fn top_scatter(&self, w: Vec3<f64>, rng: &mut Pcg32) -> Option<(Vec3<f64>, f64)> {
        if self.multiple_scattering && !self.top.is_smooth() {
            self.top.sample_multiple(w, rng).map(|(d, _)| (d, 1.0))
        } else {
            self.top.sample(w, rng.uniform3(), Lobes::All).map(|s| (s.wi, s.weight))
        }
    }

    /// One analogue walk from `wo`: the throughput of the path when it leaves the stack.
    pub fn albedo_walk(&self, wo: Vec3<f64>, rng: &mut Pcg32) -> Rgb<f64> {
        self.albedo_walk_exit(wo, rng).map_or(Rgb::zero(), |e| e.weight)
    }

    /// One analogue walk from `wo`: how the path leaves the stack (`None` when it is absorbed,
    /// ended by Russian roulette or cut).
    pub fn albedo_walk_exit(&self, wo: Vec3<f64>, rng: &mut Pcg32) -> Option<WalkExit> {
        let (d, weight) = self.top_scatter(wo, rng)?;
        let mut beta = Rgb::splat(weight);
        if d.z > 0.0 {
            return Some(WalkExit { weight: beta, direction: d, entered: false, base_bounces: 0 });
        }
        let mut w = d;
        let mut at_bottom = false;
        let mut base_bounces = 0;
        for depth in 0..self.max_depth {
            let m = beta.max_channel();
            if depth > 3 && m < 0.25 {
                let q = (1.0 - m).max(0.0);
                if rng.uniform() < q {
                    break;
                }
                beta = beta / (1.0 - q);
            }
            beta = beta * self.tau(w);
            at_bottom = !at_bottom;
            if at_bottom {
                let bs = self.base.sample(-w, rng.uniform3())?;
                beta = beta * bs.weight;
                w = bs.wi;
                base_bounces += 1;
            } else {
                let (d, weight) = self.top_scatter(-w, rng)?;
                beta *= weight;
                w = d;
                if w.z > 0.0 {
                    return Some(WalkExit { weight: beta, direction: w, entered: true, base_bounces });
                }
            }
        }
        None
    }

    /// The reflected lobe for `wo` as a histogram: `walks` analogue walks, each adding its
    /// throughput to the bin of its exit direction. Bin `(i, j)` holds `∫ f(wi, wo) cos θi dωi`
    /// over `cos θi ∈ [i/n_mu, (i+1)/n_mu)`, `|φi − φo| ∈ [jπ/n_phi, (j+1)π/n_phi)` (both
    /// azimuth sides folded: all bins have the same solid angle, `2π/(n_mu n_phi)`), estimated
    /// per channel with the standard error per bin. Needs no BSDF value of the top, so it is
    /// exact also with the multiple-scattering interface.
    #[must_use]
    pub fn albedo_lobe(&self, wo: Vec3<f64>, walks: usize, seed: u64, n_mu: usize, n_phi: usize) -> LobeHistogram {
        let bins = n_mu * n_phi;
        let (mut sum, mut sum2) = (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
        let mut rng = Pcg32::new(seed, 0x0b1d_10be);
        let phi_o = wo.y.atan2(wo.x);
        for _ in 0..walks {
            let Some(exit) = self.albedo_walk_exit(wo, &mut rng) else { continue };
            let b = lobe_bin(exit.direction, phi_o, n_mu, n_phi);
            for c in 0..3 {
                sum[b][c] += exit.weight[c];
                sum2[b][c] += exit.weight[c] * exit.weight[c];
            }
        }
        LobeHistogram::from_sums(&sum, &sum2, walks, n_mu, n_phi)
    }
    /// The layered BRDF `f(wi, wo)`: exact top reflection plus the mean of `walks` walks.
    #[must_use]
    pub fn eval(&self, wi: Vec3<f64>, wo: Vec3<f64>, walks: usize, seed: u64) -> Estimate {
        let mut acc = Accumulator::default();
        if wi.z > 0.0 && wo.z > 0.0 {
            let mut rng = Pcg32::new(seed, 0x1a7e_04ed);
            for _ in 0..walks {
                acc.add(self.body_walk(wi, wo, &mut rng));
            }
        }
        let mut e = acc.finish();
        if wi.z > 0.0 && wo.z > 0.0 {
            e.value += Rgb::splat(self.top_reflection(wi, wo));
        }
        e
    }

    /// The directional albedo `∫ f(wi, wo) cos θi dωi` (top reflection included).
    #[must_use]
    pub fn albedo(&self, wo: Vec3<f64>, walks: usize, seed: u64) -> Estimate {
        let mut acc = Accumulator::default();
        if wo.z > 0.0 {
            let mut rng = Pcg32::new(seed, 0x00a1_b3d0);
            for _ in 0..walks {
                acc.add(self.albedo_walk(wo, &mut rng));
            }
        }
        acc.finish()
    }
}

/// Reference value of the paint's BRDF at `(wi, wo)` from `samples` walks: `(f, standard error)`.
#[must_use]
pub fn reference_eval(
    paint: &CoatedPaint,
    wi: Vec3<f64>,
    wo: Vec3<f64>,
    samples: usize,
    seed: u64,
) -> (Rgb<f64>, Rgb<f64>) {
    let e = PositionFreeMc::new(paint).eval(wi, wo, samples, seed);
    (e.value, e.std_error)
}

/// Reference directional albedo of the paint for `wo` from `samples` walks: `(albedo, standard error)`.
#[must_use]
pub fn reference_albedo(paint: &CoatedPaint, wo: Vec3<f64>, samples: usize, seed: u64) -> (Rgb<f64>, Rgb<f64>) {
    let e = PositionFreeMc::new(paint).albedo(wo, samples, seed);
    (e.value, e.std_error)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::spherical_direction;
    use crate::fresnel;
    use crate::models::Model;
    use crate::Bxdf;
    use crate::Material;
    use std::f64::consts::PI;

    fn paint(json: &str) -> CoatedPaint {
        match Material::from_json(json).unwrap().model() {
            Model::CoatedPaint(p) => p.clone(),
            _ => unreachable!(),
        }
    }

    fn dir(theta_deg: f64, phi: f64) -> Vec3<f64> {
        let t = theta_deg.to_radians();
        spherical_direction(t.sin(), t.cos(), phi)
    }

    /// `r̄_i = ∫ F_inside(μ) 2μ dμ`, the coat's internal diffuse reflectance: 1 up to the
    /// critical cosine `μc = √(1 − 1/η²)`, Simpson's rule on the smooth rest.
    fn internal_diffuse_reflectance(eta: f64) -> f64 {
        let mu_c = (1.0 - 1.0 / (eta * eta)).sqrt();
        let n = 20_000;
        let h = (1.0 - mu_c) / n as f64;
        let g = |mu: f64| fresnel::dielectric(mu, 1.0 / eta) * 2.0 * mu;
        let mut s = g(mu_c) + g(1.0);
        for k in 1..n {
            s += g(mu_c + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        mu_c * mu_c + s * h / 3.0
    }

    /// A smooth coat over a Lambertian base (no absorption) has a closed form, derived by
    /// summing the bounces between the base and the coat's underside (each bounce returns the
    /// fraction `ρ r̄_i` of the light to the base, and a Lambertian base forgets directions):
    /// `f = (1 − F(μi))(1 − F(μo)) ρ / (π η² (1 − ρ r̄_i))` off the mirror direction, and the
    /// albedo is `F(μo) + (1 − F(μo)) ρ (1 − r̄_i)/(1 − ρ r̄_i)` (using `1 − r̄_e = η²(1 − r̄_i)`).
    #[test]
    fn smooth_coat_over_lambert_matches_closed_form() {
        let rho = [0.2, 0.5, 0.9];
        let eta = 1.5;
        let p = paint(
            r#"{"model": "coated_paint", "coat_ior": 1.5, "coat_roughness": 0, "flake_density": 0, "base_color": [0.2, 0.5, 0.9]}"#,
        );
        let ri = internal_diffuse_reflectance(eta);
        let mc = PositionFreeMc::new(&p);
        for (k, (ti, to)) in [(0.0, 0.0), (30.0, 60.0), (75.0, 10.0), (85.0, 45.0)].iter().enumerate() {
            let (wi, wo) = (dir(*ti, 0.3), dir(*to, 2.5));
            let e = mc.eval(wi, wo, 20_000, k as u64);
            let (fi, fo) = (fresnel::dielectric(wi.z, eta), fresnel::dielectric(wo.z, eta));
            for (c, r) in rho.iter().enumerate() {
                let expect = (1.0 - fi) * (1.0 - fo) * r / (PI * eta * eta * (1.0 - r * ri));
                let tol = 4.0 * e.std_error[c] + 2e-4 * expect;
                assert!((e.value[c] - expect).abs() < tol, "θ {ti}/{to} ch {c}: {} vs {expect} ± {tol}", e.value[c]);
            }
        }
        for (k, to) in [0.0, 45.0, 80.0].iter().enumerate() {
            let wo = dir(*to, 1.0);
            let e = mc.albedo(wo, 200_000, 100 + k as u64);
            let fo = fresnel::dielectric(wo.z, eta);
            for (c, r) in rho.iter().enumerate() {
                let expect = fo + (1.0 - fo) * r * (1.0 - ri) / (1.0 - r * ri);
                let tol = 4.0 * e.std_error[c] + 1e-4;
                assert!((e.value[c] - expect).abs() < tol, "θo {to} ch {c}: {} vs {expect} ± {tol}", e.value[c]);
            }
        }
    }

    /// The walks' basecoat bounce counts against the same closed form split by order: the light
    /// that leaves after exactly `k` bounces off a Lambertian base under a smooth coat is
    /// `(1 − F(μo)) ρᵏ r̄_iᵏ⁻¹ (1 − r̄_i)` (each bounce sends `ρ`, of which the coat's underside
    /// returns `r̄_i`); the top reflection counts 0 bounces and has not entered.
    #[test]
    fn walk_exits_count_the_basecoat_bounces() {
        let rho: [f64; 3] = [0.2, 0.5, 0.9];
        let eta = 1.5;
        let p = paint(
            r#"{"model": "coated_paint", "coat_ior": 1.5, "coat_roughness": 0, "flake_density": 0, "base_color": [0.2, 0.5, 0.9]}"#,
        );
        let ri = internal_diffuse_reflectance(eta);
        let mc = PositionFreeMc::new(&p);
        let walks = 200_000;
        for (seed, to) in [0.0, 60.0].iter().enumerate() {
            let wo = dir(*to, 0.4);
            let mut rng = Pcg32::new(seed as u64, 99);
            let (mut sum, mut sum2) = ([[0.0; 3]; 4], [[0.0; 3]; 4]);
            for _ in 0..walks {
                let Some(exit) = mc.albedo_walk_exit(wo, &mut rng) else { continue };
                assert_eq!(exit.entered, exit.base_bounces > 0, "{exit:?}");
                let k = (exit.base_bounces as usize).min(3);
                for c in 0..3 {
                    sum[k][c] += exit.weight[c];
                    sum2[k][c] += exit.weight[c] * exit.weight[c];
                }
            }
            let fo = fresnel::dielectric(wo.z, eta);
            for k in 1..3 {
                for (c, r) in rho.iter().enumerate() {
                    let expect = (1.0 - fo) * r.powi(k as i32) * ri.powi(k as i32 - 1) * (1.0 - ri);
                    let n = walks as f64;
                    let mean = sum[k][c] / n;
                    let se = ((sum2[k][c] / n - mean * mean).max(0.0) / n).sqrt();
                    let tol = 4.0 * se + 1e-4;
                    assert!((mean - expect).abs() < tol, "θo {to} k {k} ch {c}: {mean} vs {expect} ± {tol}");
                }
            }
        }
    }

    /// A lossless smooth stack (white Lambert, clear coat) reflects everything: every analogue
    /// walk leaves with throughput exactly 1.
    #[test]
    fn lossless_smooth_stack_has_unit_albedo() {
        let p = paint(r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 0, "base_color": 1.0}"#);
        let mc = PositionFreeMc::new(&p);
        for to in [0.0, 60.0, 89.0] {
            let e = mc.albedo(dir(to, 0.0), 5_000, 7);
            for c in 0..3 {
                assert!((e.value[c] - 1.0).abs() < 1e-12, "{to}: {:?}", e.value);
            }
        }
    }

    /// With a rough top the two strategies (light-side connection and basecoat sampling)
    /// are combined by MIS; the estimate must agree with basecoat sampling alone (unbiased
    /// either way), within the combined noise.
    #[test]
    fn mis_agrees_with_basecoat_sampling_alone() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.3, "flake_density": 8, "base_color": [0.6, 0.3, 0.1], "coat_absorption": [1, 2, 4]}"#,
        );
        let mis = PositionFreeMc::new(&p);
        let plain = PositionFreeMc { light_sampling: false, ..mis.clone() };
        for (k, (ti, to, phi)) in [(20.0, 20.0, PI), (50.0, 10.0, 0.0), (70.0, 70.0, PI)].iter().enumerate() {
            let (wi, wo) = (dir(*ti, *phi), dir(*to, 0.0));
            let a = mis.eval(wi, wo, 40_000, k as u64);
            let b = plain.eval(wi, wo, 160_000, 50 + k as u64);
            for c in 0..3 {
                let tol = 4.5 * (a.std_error[c].powi(2) + b.std_error[c].powi(2)).sqrt();
                assert!(
                    (a.value[c] - b.value[c]).abs() < tol,
                    "{ti}/{to} ch {c}: MIS {} vs plain {} (tol {tol})",
                    a.value[c],
                    b.value[c]
                );
            }
        }
    }

    /// The reference's albedo equals the integral of its own BRDF (rough top, flakes,
    /// absorption): the analogue walk and the connection walk estimate the same thing.
    #[test]
    fn albedo_walk_matches_integrated_eval() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.3, "flake_density": 5, "coat_absorption": [3, 1, 0]}"#,
        );
        let mut mc = PositionFreeMc::new(&p);
        // The connection walk (`body_walk`) crosses the rough top with the single-scattering
        // interface, so the analogue walk must use that interface too for the two to estimate
        // the same thing (the multiple-scattering walk has its own gate:
        // `lossless_rough_stack_has_unit_albedo`). With the default walk the two differ by
        // the energy the single-scattering interface loses: 0.2135 vs 0.2352 in channel 0.
        mc.multiple_scattering = false;
        let wo = dir(40.0, 0.0);
        // ∫ f cos dωi by cosine-weighted sampling of wi (one walk per direction).
        let mut rng = Pcg32::new(9, 9);
        let n = 200_000;
        let mut acc = Accumulator::default();
        for k in 0..n {
            let u = crate::sampling::hammersley3(k, n);
            let wi = crate::sampling::cosine_hemisphere(u[1], u[2]);
            let f = mc.body_walk(wi, wo, &mut rng) + Rgb::splat(mc.top_reflection(wi, wo));
            acc.add(f * PI);
        }
        let integrated = acc.finish();
        let walked = mc.albedo(wo, 200_000, 3);
        for c in 0..3 {
            let tol = 4.0 * (integrated.std_error[c].powi(2) + walked.std_error[c].powi(2)).sqrt();
            assert!(
                (integrated.value[c] - walked.value[c]).abs() < tol,
                "ch {c}: {} vs {} (tol {tol})",
                integrated.value[c],
                walked.value[c]
            );
        }
    }

    /// The analytic model against the reference where its approximations vanish: a smooth coat
    /// over a Lambertian base (solid paint) and the lossless white stack. The analytic model is
    /// exact there up to its tables; stated tolerance: 0.2 % of the value + 4σ of the reference.
    #[test]
    fn analytic_model_matches_reference_where_it_is_exact() {
        let configs = [
            r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 0}"#,
            r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 0, "base_color": 1.0}"#,
        ];
        let (mut worst_rel, mut worst_sigma) = (0.0f64, 0.0f64);
        for json in configs {
            let p = paint(json);
            let mc = PositionFreeMc::new(&p);
            for (k, (ti, to, phi)) in
                [(0.0, 0.0, 0.0), (30.0, 60.0, PI), (60.0, 20.0, 1.0), (80.0, 45.0, 0.0)].iter().enumerate()
            {
                let (wi, wo) = (dir(*ti, *phi), dir(*to, 0.0));
                let r = mc.eval(wi, wo, 4_000, k as u64);
                let a = p.eval(wi, wo);
                for c in 0..3 {
                    worst_rel = worst_rel.max((a[c] - r.value[c]).abs() / r.value[c]);
                    worst_sigma = worst_sigma.max((a[c] - r.value[c]).abs() / r.std_error[c]);
                    // Measured: worst gap 2.75σ of the reference (2.15 % relative: the noise of
                    // 4 000 walks), so no bias term is needed beyond the tables' 0.2 %; was 1 % + 4σ.
                    let tol = 0.002 * r.value[c] + 4.0 * r.std_error[c];
                    assert!(
                        (a[c] - r.value[c]).abs() < tol,
                        "{json} θ {ti}/{to} ch {c}: analytic {} vs reference {} ± {tol}",
                        a[c],
                        r.value[c]
                    );
                }
            }
        }
        eprintln!("analytic vs position-free MC: worst relative gap {worst_rel:.2e}, worst gap / σ {worst_sigma:.2}");
    }
    /// Issue 17, item 3, the gate: a lossless stack (clear coat over a white Lambert base) under
    /// a **rough** coat reflects everything. With the multiple-scattering interface every walk
    /// leaves with weight 1, so the albedo is 1 up to the walks cut at the depth cap (asserted
    /// 1e-3; measured 1.0000 with 4 000 walks at α 0.1 and 0.3, θo 0°, 60°, 85°); with Walter's
    /// single-scattering interface (the reference before) the same stack keeps 0.925 (α 0.1)
    /// and 0.703 (α 0.3) at normal incidence (asserted < 0.9 at α 0.3, so this test fails on
    /// the old reference).
    #[test]
    fn lossless_rough_stack_has_unit_albedo() {
        for alpha in [0.1, 0.3] {
            let p = paint(&format!(
                r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 0, "base_color": 1.0}}"#
            ));
            let mut mc = PositionFreeMc::new(&p);
            for to in [0.0, 60.0, 85.0] {
                let e = mc.albedo(dir(to, 0.0), 4_000, 9);
                eprintln!("α {alpha} θo {to}: albedo {:.5} ± {:.5}", e.value.g, e.std_error.g);
                assert!((e.value.g - 1.0).abs() < 1e-3, "α {alpha} θo {to}: {:?}", e.value);
            }
            mc.multiple_scattering = false;
            let single = mc.albedo(dir(0.0, 0.0), 4_000, 9).value.g;
            eprintln!("α {alpha}: single-scattering interface {single:.4}");
            if alpha == 0.3 {
                assert!(single < 0.9, "{single}");
            }
            mc.multiple_scattering = true;
        }
    }
}
