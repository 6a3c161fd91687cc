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
//! `α_b² (1 + n) + α_c²` at each direction ([`series_widening`]: the later metal bounces, `n`
//! per direction from the walks below, and one reflection off the coat's rough underside,
//! whose facets tilt the direction as the base's do) on top of the coat's transmission blur
//! (the smaller of the lobes seen from `wo'` and `wi'`, as the single-scatter term), `m` the
//! metal's weight and `F0` its Schlick reflectance. Schlick's `F = F0 + (1 − F0)(1 − c)⁵` is
//! split into its two components, each with its own weight table: `w₁` for the `F0 = 1` part,
//! `w₀` for the `(1 − c)⁵` part. So `S` is linear in `F0` and in `m` (the per-element tables
//! of [`super::varying`] combine it as they combine the base's own lobes), symmetric in
//! `(wi, wo)` (reciprocal), and non-negative. Under a rough coat `wi'`, `wo'` are the coat's
//! mean refracted directions ([`Coat::mean_refract_in`], as for the metal's first bounce: the
//! light of the last bounce leaves through the rough interface's tilted facets as the first
//! bounce's enters; session 39), the blur and the weights still looked up at the macro
//! refraction's and the outside cosines; otherwise the macro refraction.
//!
//! **The target** (per coat, built by [`SpecSeries::build`], 48 μ nodes): for each component
//! `F` ∈ {1, (1 − c)⁵} of a unit metal (`m = 1`) under the coat, `R_F(μ)` is what the series
//! must return: walks with the physics of the position-free reference (`reference_walks`:
//! the lossless multiple-scattering rough interface, the metal's own GGX lobe, 4096 walks at
//! every other node, four times as many for the first bounce, smoothed over neighbouring
//! walked nodes and interpolated between) give the light that leaves after the first metal bounce (`first`) and after two or
//! more (`later`, a white metal after the first); the single-scatter layer term lets out
//! `A1_F(μ)` of the first bounce (2048 points of the blurred base, out with `T`; under a rough
//! coat at the mean refracted directions, out with `T/(η² J)`, `Coat::mean_refract_out`), so
//! `R_F = first + later − A1_F`, at most `T − A1_F`. The series thus carries what the rough
//! interface reflects back down and lets out later, and what the layer term's crossing at the
//! macro normal misses of the first bounce (or gives too much of: then `R_F` is less than
//! `later`). Until session 35 `R_F` was what the layer tables send back down (`U − A1`), which
//! the blurred pair's `min` had already thinned by up to 22 % at grazing view (§8 of
//! docs/paint-validation.md, fifth pass).
//!
//! **The weights**: `A_F(μ)` is the albedo of the widened term with unit weights (drawn at
//! the node's inside direction; under a rough coat what the term sends along an inside
//! direction leaves with `T/(η² J)` at the outside cosine of [`Coat::mean_refract_out`], the
//! change of variables of the first bounce's `A1_F`, otherwise with `T`) and
//! `w_F = σ_F R_F/A_F`. With the weights `√(w(μi) w(μo))` the term's albedo `S_F(μ)` is only
//! close to `R_F(μ)`: fixed-point rounds `w ← w (R/S)²` settle the shape of `S_F/R_F`, and
//! `σ_F` is the least-squares fit of `S_F` to `R_F` over the nodes, at most
//! `min_μ (T − A1_F)/S_F`. So `A1_F + S_F ≤ T` at every node; the paint's `A1 + S` of the
//! metal is linear in `F0` and in the metal weight `m`, so it stays below `m T` for every `F0`
//! in [0, 1], the other components' `A1 + M` below their share of `U`, and the albedo
//! `E_top + ΔR + A1 + S + M ≤ E_top + ΔR + T = 1` (up to the tables' linear interpolation
//! between nodes).
//!
//! **Later bounces**: a grey metal absorbs `1 − F0` at each later bounce; the lobe carries
//! `F0^n` per channel with `n` the effective number of later metal bounces per node (from the
//! same walks: `E[0.9^N] = E[1] 0.9^n` over the later light, with the first bounce's light that
//! `A1` misses counted with no later bounce).
//!
//! **Assumptions**: the later bounces' Fresnel is `F0` (Schlick's normal value, exact for
//! `F0` = 1 and matched at `F0` = 0.9 by `n`); the lobe of
//! all later orders is one GGX lobe, as wide as the metal lobe after its later bounces (the
//! slope variances of successive reflections add; each direction's own `n`, the pair's lobe
//! the smaller of the two, as the blur's) and one reflection off the coat's underside (the
//! coat's `α_c²` once: once per bounce over-widens it for α_c ≥ 0.2, §8 of
//! docs/paint-validation.md, seventh pass); until session 36 it was widened by one round
//! trip at every direction (`α_b² + α_c²`), too narrow where the light is trapped beyond the
//! critical angle for several bounces (grazing view); the weights are computed without the coat's
//! absorption (which scales `S` through `τ(wi') τ(wo')` at evaluation); the weight of a pair of
//! directions is the geometric mean of the two directions' weights (the symmetric choice;
//! exact for a mirror base, where `μi = μo`).
//!
//! The term is present only with a metallic base under a coat with an interface: a pigment or
//! flake paint is the previous model bit for bit.

use super::basecoat::{Basecoat, MetalBase};
use super::coat::Coat;
use super::flakes::FlakeSampler;
use super::rough_dielectric::RoughDielectric;
use crate::frame::half_vector_masked;
use crate::lanes::{self, keep, Lanes, Outlined};
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
    /// `reference_walks`).
    pub weights: MuTable,
    /// `[S₁, S₀, 0]`: the term's albedo per unit metal weight, per component (for the lobe
    /// selection).
    pub albedo: MuTable,
    /// The metal base's `α_b²` (GGX).
    pub metal_alpha2: f64,
    /// The coat's `α_c²` (GGX).
    pub coat_alpha2: f64,
    /// True when the lobe is evaluated at the coat's mean refracted directions
    /// ([`Coat::mean_refract_in`], a rough coat), as the metal's first bounce is.
    pub at_mean_refraction: bool,
}

/// What the series adds to the metal lobe's `α²` at a direction whose light takes `n` later
/// metal bounces (the weight tables' third column): `α_b² (1 + n) + α_c²` — each later
/// reflection off the metal adds its slope variance, one reflection off the coat's rough
/// underside adds the coat's. `n` is the absorption-weighted count (`E[F0^N] = F0^n`), below
/// the mean count by Jensen's inequality: the `1 +` makes up for it (measured, module doc).
#[inline(always)]
pub(crate) fn series_widening<L: Lanes>(metal_alpha2: L, coat_alpha2: L, n: L) -> L {
    metal_alpha2 * (L::c(1.0) + n) + coat_alpha2
}

/// The widened lobe `m D̃G̃/(4 μi' μo') · [F0 W₁ + (1 − F0)(1 − wi'·h)⁵ W₀] · g(F0, r̄)` per
/// channel, directions inside the coat; `added` what is added to the metal's `α²` seen from
/// `wi'`, `wo'` (the transmission blur plus [`series_widening`]); `w1`, `w0` the pair's
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
    let f = Rgb::new(
        (f0.r * w.0 + (one - f0.r) * s5) * k * escape_share(f0.r, n_eff),
        (f0.g * w.0 + (one - f0.g) * s5) * k * escape_share(f0.g, n_eff),
        (f0.b * w.0 + (one - f0.b) * s5) * k * escape_share(f0.b, n_eff),
    );
    Rgb::select(defined & lanes::gt(dg, L::c(0.0)), f, Rgb::zero())
}

/// [`series_lobe`]'s arguments, for [`Lanes::outlined`] (the paint's kernels run the series
/// out of line: only metal-base paints have it).
pub(crate) struct SeriesLobe<'a, L: Lanes> {
    /// The metal base.
    pub metal: &'a MetalBase,
    /// Its `F0` per channel.
    pub f0: Rgb<L>,
    /// Its weight.
    pub weight: L,
    /// What is added to the metal's `α²` seen from `wi'`, `wo'`.
    pub added: (L, L),
    /// The inside direction toward the light (`wi'`).
    pub wi: Vec3<L>,
    /// The inside direction toward the viewer (`wo'`).
    pub wo: Vec3<L>,
    /// The pair's weights `√(w(μi) w(μo))`.
    pub w: (L, L),
    /// The pair's effective number of later metal bounces.
    pub n_eff: Option<L>,
}

impl<L: Lanes> Outlined for SeriesLobe<'_, L> {
    type Output = Rgb<L>;
    #[inline(always)]
    fn run(self) -> Rgb<L> {
        series_lobe(self.metal, self.f0, self.weight, self.added, self.wi, self.wo, self.w, self.n_eff)
    }
}

/// `F^n = exp(n ln F)` per lane (0 for `F` = 0), or 1 without `n` ([`series_lobe`]'s `g`).
/// A function, not a closure: a closure in a lane-generic function is compiled as its own
/// function without the batch kernel's `#[target_feature]`, so its SIMD intrinsics become
/// calls when it is not inlined (session 39: this closure, called three times, ran the
/// metal-base paint's AVX-512 eval at 98 ns per element).
#[inline(always)]
fn escape_share<L: Lanes>(f: L, n_eff: Option<L>) -> L {
    match n_eff {
        None => L::c(1.0),
        Some(n) => keep(lanes::gt(f, L::c(0.0)), lanes::exp(n * lanes::ln(lanes::max(f, L::c(1e-30))))),
    }
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
        let (metal_alpha2, coat_alpha2) = (metal_alpha * metal_alpha, coat.roughness * coat.roughness);
        let points: Vec<[f64; 3]> = (0..SAMPLES).map(|k| hammersley3(k, SAMPLES)).collect();
        let at_mean_refraction = coat.has_mean_refraction();
        let eta2 = coat.ior * coat.ior;
        let macro_in = |m: f64| coat.refract_in(Vec3::new((1.0 - m * m).max(0.0).sqrt(), 0.0, m));
        // Where light the lobe sends along the inside direction `v` leaves: its outside cosine,
        // the share that leaves, and the macro refraction's inside cosine there (at which the
        // transmission blur is evaluated). At the mean refraction the share is `T/(η² J)`
        // (`Coat::mean_refract_out`), at the macro normal `T`.
        let exit = |v: Vec3<f64>| -> Option<(f64, f64, f64)> {
            if at_mean_refraction {
                let (mu, j) = coat.mean_refract_out(v.z).filter(|&(_, j)| v.z > 0.0 && j > 0.0)?;
                Some((mu, coat.transmittance(mu) / (eta2 * j), macro_in(mu).z))
            } else {
                coat.refract_out(v).map(|o| (o.z, coat.transmittance(o.z), v.z))
            }
        };
        let nodes: Vec<(f64, Vec3<f64>)> = (0..NODES)
            .map(|k| {
                let mu = (k as f64 / (NODES - 1) as f64).max(1e-4);
                let outside = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                (mu, if at_mean_refraction { coat.mean_refract_in(outside) } else { coat.refract_in(outside) })
            })
            .collect();
        let mut weights = [vec![0.0; NODES], vec![0.0; NODES]];
        let mut albedo = [vec![0.0; NODES], vec![0.0; NODES]];
        let mut n_eff = vec![0.0; NODES];
        // The walks behind the target (both components on the same paths), at every
        // `WALK_STRIDE`-th node and interpolated linearly in μ between them.
        let inside_escape = coat.inside_escape_table();
        let walked_nodes: Vec<usize> = (0..NODES).step_by(WALK_STRIDE).chain([NODES - 1]).collect();
        let walked_at: Vec<Walked> = crate::parallel::map_indices(walked_nodes.len(), |j| {
            reference_walks(coat, metal_alpha, &inside_escape, nodes[walked_nodes[j]].0)
        });
        // The walks' noise, smoothed over neighbouring walked nodes ([1, 2, 1]/4; the last
        // node, μ = 1, with its neighbour as (2, 1)/3; the first, μ ≈ 0, as walked): the
        // per-element α grid interpolates the tables of neighbouring coats, whose walks' noise
        // differs (`tests/integration/varying.rs`, `alpha_interpolation_error_against_fixed_alpha_tables`).
        let last = walked_at.len() - 1;
        let walked_at: Vec<Walked> = (0..=last)
            .map(|j| match j {
                0 => walked_at[0],
                j if j == last => walked_at[last].lerp(&walked_at[last - 1], 1.0 / 3.0),
                j => walked_at[j - 1].lerp(&walked_at[j + 1], 0.5).lerp(&walked_at[j], 0.5),
            })
            .collect();
        let walked: Vec<Walked> = (0..NODES)
            .map(|k| {
                let j = walked_nodes.iter().rposition(|&n| n <= k).expect("node 0 is walked");
                if walked_nodes[j] == k {
                    return walked_at[j];
                }
                let (k0, k1) = (walked_nodes[j], walked_nodes[j + 1]);
                walked_at[j].lerp(&walked_at[j + 1], (k - k0) as f64 / (k1 - k0) as f64)
            })
            .collect();
        for (c, f0) in [1.0, 0.0].into_iter().enumerate() {
            let metal = MetalBase { alpha: metal_alpha, f0: [f0; 3], weight: 1.0 };
            let base = Basecoat::new([0.0; 3], 0.0, 0.0, None, Some(metal.clone()), None).with_blur(blur);
            // A1_F(μ): what the single-scatter layer term lets out of the first bounce (the
            // layer tables' `A1` of this component: the blurred base, out with `T`).
            // The nodes are independent (each sums its own samples in order, the walks seed
            // their own generators): they run on up to `batch::thread_count()` threads.
            let a1: Vec<f64> = crate::parallel::map_indices(NODES, |k| {
                let (mu, w_in) = nodes[k];
                let t = coat.transmittance(mu);
                let mut a1 = 0.0;
                if coat.has_mean_refraction() {
                    return first_bounce_albedo(coat, &metal, mu, &points, false)[0];
                }
                for u in &points {
                    if let Some(b) = base.sample_by(w_in, *u, FlakeSampler::Visible) {
                        a1 += t * b.weight[0] * coat.refract_out(b.wi).map_or(0.0, |o| coat.transmittance(o.z))
                            / SAMPLES as f64;
                    }
                }
                a1
            });
            // R_F(μ): what the series returns, from walks with the reference's physics: the
            // light that leaves after two or more bounces, plus what `A1` misses of the first
            // bounce's light (or less what it adds), at most what `A1` leaves of the light that
            // entered (`T − A1`: the energy bound).
            let cap: Vec<f64> = (0..NODES).map(|k| (coat.transmittance(nodes[k].0) - a1[k]).max(0.0)).collect();
            let r: Vec<f64> =
                (0..NODES).map(|k| (walked[k].later[c] + walked[k].first[c] - a1[k]).clamp(0.0, cap[k])).collect();
            if c == 0 {
                // The series carries the later light (`n_later` later bounces) and, where `A1`
                // misses some of the first bounce, that light (no later bounce).
                n_eff = (0..NODES)
                    .map(|k| {
                        let Walked { first: [first, _], later: [later, _], n_later } = walked[k];
                        let missed = (first - a1[k]).max(0.0);
                        if missed > 0.0 && later > 0.0 {
                            ((missed + later * F_REF.powf(n_later)) / (missed + later)).ln() / F_REF.ln()
                        } else {
                            n_later
                        }
                    })
                    .collect();
            }
            // What the lobe adds to the metal's α² seen from an inside direction: the
            // transmission blur and the widening for that direction's later bounces.
            let n_table = MuTable::from_values(n_eff.iter().map(|&n| [n, 0.0, 0.0]).collect());
            let added = |mu_out: f64, macro_cos: f64| {
                let n = n_table.eval::<f64>(mu_out)[0];
                blur.map_or(0.0, |b| b.one_sided(macro_cos)) + series_widening(metal_alpha2, coat_alpha2, n)
            };
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
                let added_o = added(mu, macro_in(mu).z);
                let wide = metal.blurred::<f64>(added_o);
                points
                    .iter()
                    .filter_map(|u| {
                        let wi = MetalBase::sample_direction_with(&wide, w_in, u[1], u[2]);
                        let pdf = MetalBase::pdf_with(&wide, wi, w_in);
                        if wi.z <= 0.0 || !(pdf > 0.0) {
                            return None;
                        }
                        let (mu_exit, escape, macro_cos) = exit(wi)?;
                        let added = (added(mu_exit, macro_cos), added_o);
                        let f = series_lobe(&metal, Rgb::splat(f0), 1.0, added, wi, w_in, (1.0, 1.0), None);
                        Some((mu_exit, f.r * wi.z / pdf * escape))
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
            // The scale: the least-squares fit of S_F to R_F over the nodes (the walks' noise
            // stays in R_F, so a bound by R_F at every node would follow its lowest dip), at most
            // what keeps S_F ≤ T − A1_F at every node (energy conservation).
            let s = albedo_with(&w);
            let (rs, ss) = r.iter().zip(&s).fold((0.0, 0.0), |(rs, ss), (&r, &s)| (rs + r * s, ss + s * s));
            let fit = if ss > 0.0 { rs / ss } else { 0.0 };
            let bound =
                cap.iter().zip(&s).filter(|(_, &s)| s > 0.0).fold(f64::INFINITY, |acc, (&c, &s)| acc.min(c / s));
            let sigma = fit.min(bound).max(0.0);
            weights[c] = w.iter().map(|w| sigma * w).collect();
            albedo[c] = s.iter().map(|s| sigma * s).collect();
        }
        let table = |t: &[Vec<f64>; 2], third: &[f64]| {
            MuTable::from_values((0..NODES).map(|k| [t[0][k], t[1][k], third[k]]).collect())
        };
        Some(Self {
            weights: table(&weights, &n_eff),
            albedo: table(&albedo, &[0.0; NODES]),
            metal_alpha2,
            coat_alpha2,
            at_mean_refraction,
        })
    }
}

/// Walks per node of `reference_walks`.
const WALKS: usize = 4096;
/// Of the walks for the first bounce's light, every `FIRST_BOUNCE_FACTOR`-th goes on to the later
/// bounces: the target is `first + later − A1`, a small difference where `first` and `A1` are
/// large (near the normal), so `first` takes more walks (they are cheap: two events each), and
/// the per-element α grid's interpolation between coats sees less of the walks' noise
/// (`tests/integration/varying.rs`, `alpha_interpolation_error_against_fixed_alpha_tables`).
const FIRST_BOUNCE_FACTOR: usize = 4;
/// `reference_walks` runs at every `WALK_STRIDE`-th μ node (and the last); the nodes between
/// interpolate (the walks' results are smooth in μ, their cost is the table's build time).
const WALK_STRIDE: usize = 2;
/// Largest number of round trips a walk of `reference_walks` follows.
const MAX_ROUNDS: usize = 48;
/// The metal albedo at which the effective number of later bounces matches `E[F^N]`.
const F_REF: f64 = 0.9;

/// What `reference_walks` measures per unit of light incident from outside, per Schlick
/// component `F` ∈ {1, (1 − c)⁵} of the first bounce.
#[derive(Clone, Copy, Debug)]
struct Walked {
    /// The light that leaves after the first metal bounce.
    first: [f64; 2],
    /// The light that leaves after two or more metal bounces (a white metal after the first).
    later: [f64; 2],
    /// The effective number `n` of later metal bounces of `later[0]`: `E[F_ref^N] = E[1]
    /// F_ref^n` (`N` the bounces after the first, `F_ref` = 0.9), so `F^n` is exact for `F` = 1
    /// and 0.9.
    n_later: f64,
}

impl Walked {
    /// `self + (other − self) t`, per field.
    fn lerp(&self, other: &Self, t: f64) -> Self {
        let mix = |a: f64, b: f64| a + (b - a) * t;
        Self {
            first: [0, 1].map(|c| mix(self.first[c], other.first[c])),
            later: [0, 1].map(|c| mix(self.later[c], other.later[c])),
            n_later: mix(self.n_later, other.n_later),
        }
    }
}

/// The albedo per channel of a metal base's first bounce under a rough coat with the mean
/// refraction ([`Coat::mean_refract_in`]) for the outside cosine `mu`: the metal's lobe
/// (blurred as the paint evaluates it: at the macro refraction's cosines) drawn at the mean
/// inside direction with `points`, each sample let out with `T(μ)/(η² J(μ))` at its outside
/// cosine ([`Coat::mean_refract_out`]), times `T(mu)`; with `absorb` the coat's attenuation
/// at both crossings (the macro cosines, as the paint applies it). 0 without the map.
pub(crate) fn first_bounce_albedo(
    coat: &Coat,
    metal: &MetalBase,
    mu: f64,
    points: &[[f64; 3]],
    absorb: bool,
) -> [f64; 3] {
    let Some(blur) = coat.transmission_blur().filter(|_| coat.has_mean_refraction()) else { return [0.0; 3] };
    let macro_in = |m: f64| coat.refract_in(Vec3::new((1.0 - m * m).max(0.0).sqrt(), 0.0, m));
    let w_in = macro_in(mu);
    let w_mean = coat.mean_refract_in(Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu));
    let lobe_o = metal.blurred::<f64>(blur.one_sided(w_in.z));
    let eta2 = coat.ior * coat.ior;
    let entering = coat.transmittance(mu);
    let a_o = if absorb { coat.attenuation(w_in.z) } else { [1.0; 3] };
    let mut sum = [0.0; 3];
    for u in points {
        let v = MetalBase::sample_direction_with(&lobe_o, w_mean, u[0], u[1]);
        let pdf = MetalBase::pdf_with(&lobe_o, v, w_mean);
        let Some((mu_v, jacobian)) = coat.mean_refract_out(v.z).filter(|&(_, j)| v.z > 0.0 && pdf > 0.0 && j > 0.0)
        else {
            continue;
        };
        let v_in = macro_in(mu_v);
        let lobe_i = metal.blurred(blur.one_sided(v_in.z));
        let f = metal.eval_with(&lobe_o, Some(&lobe_i), Rgb::from_array(metal.f0), metal.weight, v, w_mean);
        let a_v = if absorb { coat.attenuation(v_in.z) } else { [1.0; 3] };
        let out = v.z / pdf * coat.transmittance(mu_v) / (eta2 * jacobian);
        for c in 0..3 {
            sum[c] += f[c] * out * a_v[c];
        }
    }
    [0, 1, 2].map(|c| entering * a_o[c] * sum[c] / points.len() as f64)
}

/// `WALKS` walks (`FIRST_BOUNCE_FACTOR` times as many for the first bounce) of the position-free reference's physics (`super::position_free_mc`) for the
/// outside direction of cosine `mu`: in through the coat's interface by the lossless
/// multiple-scattering rough dielectric (`RoughDielectric::sample_multiple`), a first bounce on
/// a white metal (GGX of `metal_alpha`, not blurred: the walk crosses the rough interface
/// itself; the `(1 − c)⁵` component weighs the same paths by Schlick's factor), then up to the
/// interface, which lets out `T_out` (`Coat::escape_from_inside`, tabulated in
/// `inside_escape`; the expected share, for less noise) and reflects the rest down in a
/// direction drawn from the interface; later bounces on a white metal until the interface lets
/// the light out. No absorption in the coat (the term applies it per direction).
fn reference_walks(coat: &Coat, metal_alpha: f64, inside_escape: &MuTable, mu: f64) -> Walked {
    let top = RoughDielectric { eta: coat.ior, alpha: coat.roughness };
    let white = Basecoat::new(
        [0.0; 3],
        0.0,
        0.0,
        None,
        Some(MetalBase { alpha: metal_alpha, f0: [1.0; 3], weight: 1.0 }),
        None,
    );
    let t_out = |v: Vec3<f64>| inside_escape.eval::<f64>(v.z.clamp(0.0, 1.0))[0];
    let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut rng = Pcg32::new(0xfa17_4f01, (mu * 1e6) as u64);
    let (mut first, mut later, mut later_ref) = ([0.0; 2], [0.0; 2], 0.0);
    for walk in 0..WALKS * FIRST_BOUNCE_FACTOR {
        let Some((d, _)) = top.sample_multiple(wo, &mut rng) else { continue };
        if d.z >= 0.0 {
            continue; // reflected by the coat
        }
        let Some(b) = white.sample_by(-d, rng.uniform3(), FlakeSampler::Visible) else { continue };
        // Schlick's `(1 − c)⁵` with `c` = wi·h of the first bounce.
        let h = (b.wi - d).normalize();
        let m = (1.0 - b.wi.dot(h).clamp(0.0, 1.0)).max(0.0);
        let schlick = [1.0, m * m * m * m * m];
        let escape = t_out(b.wi);
        for c in 0..2 {
            first[c] += b.weight[0] * schlick[c] * escape;
        }
        let mut weight = b.weight[0] * (1.0 - escape);
        if walk % FIRST_BOUNCE_FACTOR != 0 || !(weight > 1e-12) {
            continue;
        }
        // The direction the interface reflects down, given that it reflects (drawn again until
        // it does: the reflected share is `1 − T_out` > 1e-12 here).
        let mut down = None;
        for _ in 0..64 {
            if let Some((d, _)) = top.sample_multiple(-b.wi, &mut rng) {
                if d.z < 0.0 {
                    down = Some(d);
                    break;
                }
            }
        }
        let Some(mut d) = down else { continue };
        let mut f = 1.0;
        for _ in 0..MAX_ROUNDS {
            let Some(b) = white.sample_by(-d, rng.uniform3(), FlakeSampler::Visible) else { break };
            weight *= b.weight[0];
            f *= F_REF;
            let Some((e, _)) = top.sample_multiple(-b.wi, &mut rng) else { break };
            if e.z > 0.0 {
                for c in 0..2 {
                    later[c] += weight * schlick[c];
                }
                later_ref += weight * f;
                break;
            }
            d = e;
        }
    }
    let n_later = if later[0] > 1e-12 && later_ref > 1e-12 { (later_ref / later[0]).ln() / F_REF.ln() } else { 1.0 };
    let per_walk = 1.0 / WALKS as f64;
    let per_first = per_walk / FIRST_BOUNCE_FACTOR as f64;
    Walked { first: first.map(|x| x * per_first), later: later.map(|x| x * per_walk), n_later }
}
