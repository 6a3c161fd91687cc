//! The specular bounce series of a metallic base under a coat (issue 17, item 3).
//!
//! Light that the metal base reflects up and the coat reflects back down (partial and total
//! internal reflection) meets the base again near the base's mirror direction: a mirror-like
//! base keeps it near `μ'` round trip after round trip, so it leaves in a widened specular
//! lobe, not diffusely. The coated paint's multiple-scatter lobe `M` (diffuse) therefore keeps
//! only what the pigment and the flakes send back down (`R − R_spec`, split per sample in the
//! layer tables), and the metal's share `R_spec(μ)` leaves through
//!
//! `S(wi, wo) = T(μi) T(μo)/η² · τ(wi') τ(wo') · m · D̃G̃(wi', wo') / (4 μi' μo') ·
//!   [F0 √(w₁(μi) w₁(μo)) + (1 − F0)(1 − wi'·h)⁵ √(w₀(μi) w₀(μo))]`
//!
//! per channel, with `D̃G̃` the metal base's GGX lobe (height-correlated Smith) widened by
//! `α_b² + α_c²` (one more base bounce and one reflection off the coat's rough underside,
//! whose facets tilt the direction as the base's do) on top of the coat's transmission blur
//! (the smaller of the lobes seen from `wo'` and `wi'`, as the single-scatter term), `m` the
//! metal's weight and `F0` its Schlick reflectance. Schlick's `F = F0 + (1 − F0)(1 − c)⁵` is
//! split into its two components, each with its own weight table: `w₁` for the `F0 = 1` part,
//! `w₀` for the `(1 − c)⁵` part. So `S` is linear in `F0` and in `m` (the per-element tables
//! of [`super::varying`] combine it as they combine the base's own lobes), symmetric in
//! `(wi, wo)` (reciprocal), and non-negative.
//!
//! **The weights** (per coat, built by [`SpecSeries::build`], 48 μ nodes, 2048 points each):
//! for each component `F` ∈ {1, (1 − c)⁵} of a unit metal (`m = 1`) under the coat,
//! `R_F(μ)` is what the coat reflects back down after the first base bounce (the layer
//! tables' `U − A1` of that component) and `A_F(μ)` the albedo of the widened term with unit
//! weights; `w_F = σ_F R_F/A_F`. With the weights `√(w(μi) w(μo))` the term's albedo
//! `S_F(μ)` is only close to `R_F(μ)`, so `σ_F = min_μ R_F/S_F` (over the table nodes)
//! makes `S_F ≤ R_F` at every node, with equality at the tightest one. (Until issue 17's
//! third pass `σ_F` was also capped at 1; the fixed-point rounds fix the shape of `S_F/R_F`
//! but not its scale — a uniform error flips between `c` and `1/c` from round to round — so
//! the cap left the series' albedo 8–10 % below `R_F` at every node for coat α 0.1–0.3.)
//! Since the paint's `S` is `m(F0 S₁ + (1 − F0) S₀)` and its `R_spec` is
//! `m(F0 R₁ + (1 − F0) R₀)`, `S ≤ R_spec` for every `F0` in [0, 1] and weight `m`, and the albedo `E_top + ΔR + A1 + S + M ≤ E_top + ΔR + A1 + R_spec + R_rest =
//! E_top + ΔR + U ≤ 1` (up to the tables' linear interpolation between nodes).
//!
//! **Later bounces**: a grey metal absorbs `1 − F0` at each later bounce; the lobe carries
//! `F0^n` per channel with `n` the effective number of later metal bounces per node
//! (`later_bounces`: walks under the coat whose interface lets out what the lossless rough
//! interface does, [`Coat::escape_from_inside`], also beyond the critical angle).
//!
//! **Assumptions**: the later bounces' Fresnel is `F0` (Schlick's normal value, exact for
//! `F0` = 1 and matched at `F0` = 0.9 by `n`); the lobe of
//! all later orders is one GGX lobe widened by one round trip (the second order, which
//! dominates when the coat reflects little); the weights are computed without the coat's
//! absorption (which scales `S` through `τ(wi') τ(wo')` at evaluation); the weight of a pair of
//! directions is the geometric mean of the two directions' weights (the symmetric choice;
//! exact for a mirror base, where `μi = μo`).
//!
//! The term is present only with a metallic base under a coat with an interface: a pigment or
//! flake paint is the previous model bit for bit.

use super::basecoat::{Basecoat, MetalBase};
use super::coat::Coat;
use super::flakes::FlakeSampler;
use crate::frame::half_vector_masked;
use crate::lanes::{self, keep, Lanes};
use crate::math::{Rgb, Vec3};
use crate::microfacet::MaskingKind;
use crate::rng::Pcg32;
use crate::sampling::hammersley3;
use crate::table::MuTable;

/// μ nodes of the weight tables (as the layer tables').
pub(crate) const NODES: usize = 48;
/// Points behind each node.
const SAMPLES: usize = 2048;

/// The weight tables of the specular bounce series for one coat and one metal roughness.
#[derive(Clone, Debug)]
pub struct SpecSeries {
    /// `[w₁, w₀, n]` per outside `μ` node (`n` the effective number of later metal bounces,
    /// `later_bounces`).
    pub weights: MuTable,
    /// `[S₁, S₀, 0]`: the term's albedo per unit metal weight, per component (for the lobe
    /// selection).
    pub albedo: MuTable,
    /// What the series adds to the metal lobe's `α²`: `α_b² + α_c²`.
    pub extra: f64,
}

/// The widened lobe `m D̃G̃/(4 μi' μo') · [F0 W₁ + (1 − F0)(1 − wi'·h)⁵ W₀] · g(F0, r̄)` per
/// channel, directions inside the coat; `added` what is added to the metal's `α²` seen from
/// `wi'`, `wo'` (the transmission blur plus [`SpecSeries::extra`]); `w1`, `w0` the pair's
/// weights `√(w(μi) w(μo))`; `n_eff` the pair's mean `(n(μi) + n(μo))/2` of the effective
/// number of later metal bounces, or None for `g = 1` (the table build); `g = F0^n_eff` per
/// channel, the share of the light sent back down that a metal of albedo ≈ `F0` lets escape.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn series_lobe<L: Lanes>(
    metal: &MetalBase,
    f0: Rgb<L>,
    weight: L,
    added: (L, L),
    wi: Vec3<L>,
    wo: Vec3<L>,
    w: (L, L),
    n_eff: Option<L>,
) -> Rgb<L> {
    let (h, defined) = half_vector_masked(wi, wo);
    let (mi, mo) = (metal.blurred(added.0), metal.blurred(added.1));
    let dg = lanes::min(
        mo.d(h) * mo.g(wi, wo, h, MaskingKind::HeightCorrelated),
        mi.d(h) * mi.g(wi, wo, h, MaskingKind::HeightCorrelated),
    );
    let one = L::c(1.0);
    let m = lanes::max(one - lanes::clamp(wi.dot(h), L::c(0.0), one), L::c(0.0));
    let m2 = m * m;
    let s5 = m2 * m2 * m * w.1;
    let k = weight * dg / (L::c(4.0) * wi.z * wo.z);
    // F^n: exp(n ln F), 0 for F = 0.
    let g = |f: L| match n_eff {
        None => one,
        Some(n) => keep(lanes::gt(f, L::c(0.0)), lanes::exp(n * lanes::ln(lanes::max(f, L::c(1e-30))))),
    };
    let f = Rgb::new(
        (f0.r * w.0 + (one - f0.r) * s5) * k * g(f0.r),
        (f0.g * w.0 + (one - f0.g) * s5) * k * g(f0.g),
        (f0.b * w.0 + (one - f0.b) * s5) * k * g(f0.b),
    );
    Rgb::select(defined & lanes::gt(dg, L::c(0.0)), f, Rgb::zero())
}

/// Rounds of the weights' fixed-point iteration `w ← w (R/S)²` ([`SpecSeries::build`]).
const ROUNDS: usize = 4;

impl SpecSeries {
    /// The weight tables for a metal base of GGX roughness `metal_alpha` under `coat` (None
    /// for a coat without an interface: nothing is reflected back down).
    #[must_use]
    pub fn build(coat: &Coat, metal_alpha: f64) -> Option<Self> {
        if !coat.has_interface() {
            return None;
        }
        let blur = coat.transmission_blur();
        let extra = metal_alpha * metal_alpha + coat.roughness * coat.roughness;
        let points: Vec<[f64; 3]> = (0..SAMPLES).map(|k| hammersley3(k, SAMPLES)).collect();
        let escape = |v: Vec3<f64>| coat.refract_out(v).map_or(0.0, |o| coat.transmittance(o.z));
        let mu_out = |v: Vec3<f64>| coat.refract_out(v).map_or(0.0, |o| o.z);
        let nodes: Vec<(f64, Vec3<f64>)> = (0..NODES)
            .map(|k| {
                let mu = (k as f64 / (NODES - 1) as f64).max(1e-4);
                (mu, coat.refract_in(Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu)))
            })
            .collect();
        let added = |mu_in: f64| blur.map_or(0.0, |b| b.one_sided(mu_in)) + extra;
        let mut weights = [vec![0.0; NODES], vec![0.0; NODES]];
        let mut albedo = [vec![0.0; NODES], vec![0.0; NODES]];
        let mut n_eff = vec![0.0; NODES];
        for (c, f0) in [1.0, 0.0].into_iter().enumerate() {
            let metal = MetalBase { alpha: metal_alpha, f0: [f0; 3], weight: 1.0 };
            let base = Basecoat::new([0.0; 3], 0.0, 0.0, None, Some(metal.clone()), None).with_blur(blur);
            // R_F(μ): what the coat sends back down after the first base bounce.
            // The nodes are independent (each sums its own samples in order, `later_bounces`
            // seeds its own generator): they run on up to `batch::thread_count()` threads.
            let r: Vec<f64> = crate::parallel::map_indices(NODES, |k| {
                let (mu, w_in) = nodes[k];
                let t = coat.transmittance(mu);
                let mut r = 0.0;
                for u in &points {
                    if let Some(b) = base.sample_by(w_in, *u, FlakeSampler::Visible) {
                        r += t * b.weight[0] * (1.0 - escape(b.wi)) / SAMPLES as f64;
                    }
                }
                r
            });
            if c == 0 {
                let inside_escape = coat.inside_escape_table();
                n_eff = crate::parallel::map_indices(NODES, |k| later_bounces(&base, coat, &inside_escape, nodes[k].1));
            }
            // The term's albedo per node with the weights `w` (node values, interpolated in μ).
            // The lobe is linear in its pair weight `√(w(μi) w(μo))` (`n_eff` None), so each
            // node's samples of the widened lobe are drawn and evaluated once, at unit weight:
            // per sample `f₁ cos θi / pdf · escape` and the exit's `μ`; the fixed-point rounds
            // below only reweight them.
            let unit_samples: Vec<Vec<(f64, f64)>> = crate::parallel::map_indices(NODES, |k| {
                let (mu, w_in) = nodes[k];
                if coat.transmittance(mu) <= 0.0 {
                    return Vec::new();
                }
                let wide = metal.blurred::<f64>(added(w_in.z));
                points
                    .iter()
                    .filter_map(|u| {
                        let wi = MetalBase::sample_direction_with(&wide, w_in, u[1], u[2]);
                        let pdf = MetalBase::pdf_with(&wide, wi, w_in);
                        if wi.z <= 0.0 || !(pdf > 0.0) {
                            return None;
                        }
                        let added = (added(wi.z), added(w_in.z));
                        let f = series_lobe(&metal, Rgb::splat(f0), 1.0, added, wi, w_in, (1.0, 1.0), None);
                        Some((mu_out(wi), f.r * wi.z / pdf * escape(wi)))
                    })
                    .collect()
            });
            let albedo_with = |w: &[f64]| -> Vec<f64> {
                let table = MuTable::from_values(w.iter().map(|&x| [x, 0.0, 0.0]).collect());
                let at = |mu: f64| table.eval::<f64>(mu)[0];
                nodes
                    .iter()
                    .zip(&unit_samples)
                    .enumerate()
                    .map(|(k, (&(mu, _), samples))| {
                        let t = coat.transmittance(mu);
                        if t <= 0.0 || w[k] <= 0.0 {
                            return 0.0;
                        }
                        let out: f64 = samples.iter().map(|&(mu_exit, unit)| (at(mu_exit) * w[k]).sqrt() * unit).sum();
                        t * out / SAMPLES as f64
                    })
                    .collect()
            };
            // Unit weights first (w = R/A), then w ← w (R/S)²: the pair weight √(w(μi) w(μo))
            // moves the albedo at μo about as √w(μo). A uniform factor moves it as w, so the
            // rounds settle the shape of S/R only; σ below sets the scale.
            let a = albedo_with(&vec![1.0; NODES]);
            let mut w: Vec<f64> = r.iter().zip(&a).map(|(&r, &a)| if a > 1e-12 { r / a } else { 0.0 }).collect();
            for _ in 0..ROUNDS {
                let s = albedo_with(&w);
                for k in 0..NODES {
                    if s[k] > 1e-12 {
                        w[k] *= (r[k] / s[k]).powi(2).min(16.0);
                    }
                }
            }
            let s = albedo_with(&w);
            let sigma =
                r.iter().zip(&s).filter(|(_, &s)| s > 0.0).fold(f64::INFINITY, |acc, (&r, &s)| acc.min(r / s)).max(0.0);
            weights[c] = w.iter().map(|w| sigma * w).collect();
            albedo[c] = s.iter().map(|s| sigma * s).collect();
        }
        let table = |t: &[Vec<f64>; 2], third: &[f64]| {
            MuTable::from_values((0..NODES).map(|k| [t[0][k], t[1][k], third[k]]).collect())
        };
        Some(Self { weights: table(&weights, &n_eff), albedo: table(&albedo, &[0.0; NODES]), extra })
    }
}

/// Walks per node of [`later_bounces`].
const WALKS: usize = 1024;
/// Largest number of round trips a walk of [`later_bounces`] follows.
const MAX_ROUNDS: usize = 48;
/// The metal albedo at which [`later_bounces`] matches `E[F^N]`.
const F_REF: f64 = 0.9;

/// The effective number `n` of later metal bounces of the light the coat sends back down
/// after the first bounce from the inside direction `w_in`: walks of a white metal (`base`,
/// F0 = 1) under `coat` (mirrored at the mean plane; the coat's roughness enters through the
/// base's blur) give the escaping energy `E[1]` and `E[F_ref^N]` (`N` the metal bounces after
/// the return, `F_ref` = 0.9), and `n = ln(E[F_ref^N]/E[1]) / ln F_ref`, so `F^n` is exact for
/// `F` = 1 and 0.9. Light that total internal reflection keeps near the base's mirror
/// direction meets the metal many times (`n` large): a grey metal absorbs it.
///
/// The walk starts from what the layer tables count as sent back down (`1 − escape` of the
/// macro-normal refraction, `escape`), but a rough interface lets more out than that, also
/// beyond the critical angle (`inside_escape`: [`Coat::escape_from_inside`], 0.18–0.44 at
/// μ' 0.70–0.74 for α 0.1–0.3, where the macro refraction gives 0): the share
/// `(T_out − escape)/(1 − escape)` of the returned light leaves at once, with no later metal
/// bounce, and every later return escapes with `T_out`. For a smooth coat `T_out` is `escape`
/// and the walk is the macro-refraction one.
fn later_bounces(base: &Basecoat, coat: &Coat, inside_escape: &MuTable, w_in: Vec3<f64>) -> f64 {
    let escape = |v: Vec3<f64>| coat.refract_out(v).map_or(0.0, |o| coat.transmittance(o.z));
    let t_out = |v: Vec3<f64>| inside_escape.eval::<f64>(v.z.clamp(0.0, 1.0))[0];
    let mut rng = Pcg32::new(0x5bec_5e1e5, (w_in.z * 1e6) as u64);
    let (mut e1, mut eref) = (0.0, 0.0);
    for _ in 0..WALKS {
        let Some(first) = base.sample_by(w_in, rng.uniform3(), FlakeSampler::Visible) else { continue };
        let macro_escape = escape(first.wi);
        let mut weight = first.weight[0] * (1.0 - macro_escape);
        if macro_escape < 1.0 {
            let at_once = ((t_out(first.wi) - macro_escape) / (1.0 - macro_escape)).clamp(0.0, 1.0);
            e1 += weight * at_once;
            eref += weight * at_once;
            weight *= 1.0 - at_once;
        }
        let mut v = first.wi;
        let mut f = 1.0;
        for _ in 0..MAX_ROUNDS {
            if !(weight > 1e-9) {
                break;
            }
            // Reflected down by the coat: the base sees it coming from the mirrored direction.
            let from = Vec3::new(-v.x, -v.y, v.z);
            let Some(b) = base.sample_by(from, rng.uniform3(), FlakeSampler::Visible) else { break };
            weight *= b.weight[0];
            f *= F_REF;
            v = b.wi;
            let esc = t_out(v);
            e1 += weight * esc;
            eref += weight * esc * f;
            weight *= 1.0 - esc;
        }
    }
    if e1 > 1e-12 && eref > 1e-12 {
        (eref / e1).ln() / F_REF.ln()
    } else {
        1.0
    }
}
