//! Coated paint whose `base_color`, `flake_density` and `coat_roughness` vary per element
//! (textures), evaluated without rebuilding the material's tables per element.
//!
//! ## Why this is cheap and (nearly) exact
//! The basecoat BRDF is linear in the pigment colour `ρ` and in the coverages:
//! `f_b = ρ(1−c−c_p)(1−m)·f_pig + ρ c_p·f_pig,pearl + (1−c−c_p)m·[ρ f_metal,F0=1 + (1−ρ) f_metal,F0=0]
//! + c·f_flake,unit + f_pearl-flakes` (Schlick is linear in `F0`). The layer tables `A1(μ)` and
//! `U(μ) − A1(μ)` of [`super::coated_paint`] and the basecoat's mean albedo `ρ̄` are integrals
//! of `f_b`, hence the same linear combinations of per-component tables (estimated with each
//! component's own sampler). The weights are bilinear in `ρ` and `c`, so [`VaryingPaint`] keeps
//! the basis tables `T₁ + ρ T_ρ + c T_c + ρc T_ρc`, with the parameters a call does not vary
//! folded in (a textured colour alone reads two tables per channel, the untextured paint one).
//! Per element only weights
//! are formed; the bounce factor `τ̄²ρ̄e / (1 − τ̄²ρ̄(1 − e))` and the multiple-scatter lobe's
//! normalisation are closed forms of them. The basecoat's lobe-selection weights are closed
//! forms too, so `pdf` and `sample` are the per-element material's.
//!
//! `coat_roughness` changes the coat lobe (evaluated per element with its own α) and,
//! nonlinearly, the coat's transmittance `1 − E_top(μ)` and the escape probabilities inside
//! the tables: those are tabulated over [`ALPHA_NODES`] nodes uniform in `ln α` on
//! `[0.001, 0.5]` and interpolated linearly (the interpolation error is measured in the tests
//! and `docs/speed.md`). A per-element roughness needs a rough coat: elements must lie in
//! `[0.001, 0.5]` (a smooth coat's delta lobe cannot blend into a rough one).
//!
//! The tables per component are Monte Carlo estimates like the material's own, but with each
//! component's sampler instead of the mixture's: a material built with an element's
//! parameters agrees with the varying evaluation up to the two estimates' noise (measured in
//! the tests). The mean lobe is evaluated: per-element sparkle is not part of these calls.
//!
//! Out-of-range or non-finite per-element values make that element invalid (zero outputs,
//! counted in [`crate::batch::BatchReport`]); they are never clamped and never give NaN.

use super::basecoat::{BaseParts, Basecoat, MetalBase};
use super::coat::{flake_ratio_from_mean, inside_with_ratio, ms_azimuthal, ms_pdf, ms_sample, Coat, TransmissionBlur};
use super::coated_paint::CoatedPaint;
use super::flakes::{FlakeLayer, FlakeSampler};
use super::pick3;
use super::spec_series::{series_lobe, series_widening, SpecSeries};
use crate::bxdf::{BsdfSample, LaneSample};
use crate::frame::half_vector_masked;
use crate::fresnel;
use crate::lanes::{self, keep, Lanes, Mask};
use crate::math::{Rgb, Vec3};
use crate::microfacet::{reflection_jacobian, DistributionKind, MaskingKind, Microfacet};
use crate::params::Params;
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::table::MuTable;

/// Per-element paint parameters as structure-of-arrays slices (`None`: the material's value).
/// Units as the material's JSON: `base_color` in [0, 1] per channel, `flake_density` in %,
/// `coat_roughness` the GGX α in [0.001, 0.5]. Each slice holds at least one value per element.
#[derive(Clone, Copy, Debug, Default)]
pub struct PaintTexture<'a, E> {
    /// Pigment albedo per element: the red, green and blue arrays.
    pub base_color: Option<[&'a [E]; 3]>,
    /// Metallic flake coverage per element, in %.
    pub flake_density: Option<&'a [E]>,
    /// GGX α of the coat surface per element.
    pub coat_roughness: Option<&'a [E]>,
}

impl<E> PaintTexture<'_, E> {
    /// True when no parameter varies (the calls then are the material's own batch calls).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none() && self.flake_density.is_none() && self.coat_roughness.is_none()
    }

    /// The shortest slice given (`usize::MAX` without any).
    #[must_use]
    pub fn min_len(&self) -> usize {
        let mut n = usize::MAX;
        if let Some(c) = &self.base_color {
            n = n.min(c[0].len()).min(c[1].len()).min(c[2].len());
        }
        if let Some(f) = self.flake_density {
            n = n.min(f.len());
        }
        if let Some(r) = self.coat_roughness {
            n = n.min(r.len());
        }
        n
    }
}

/// Number of `α` nodes of the tables when `coat_roughness` varies.
pub const ALPHA_NODES: usize = 32;
/// Smallest per-element coat roughness.
pub const ALPHA_MIN: f64 = 0.001;
/// Largest per-element coat roughness.
pub const ALPHA_MAX: f64 = 0.5;
/// `μ` nodes of the layer tables (as the material's).
const NODES: usize = 48;
/// `μ` nodes of the coat albedo table (as [`Coat`]'s: its nodes, so interpolation agrees).
const E_NODES: usize = 64;
/// Basecoat samples behind each table node (as the material's).
const SAMPLES: usize = 2048;

/// The coat α of grid node `j` (`j < ALPHA_NODES`): nodes uniform in `ln α` on
/// `[ALPHA_MIN, ALPHA_MAX]` (the tables' interpolation error goes as the square of the node
/// spacing in `ln α` over the whole range; docs/speed.md).
#[must_use]
pub fn alpha_node(j: usize) -> f64 {
    let (l0, l1) = (ALPHA_MIN.ln(), ALPHA_MAX.ln());
    (l0 + (l1 - l0) * j as f64 / (ALPHA_NODES - 1) as f64).exp().clamp(ALPHA_MIN, ALPHA_MAX)
}

/// A flat table read per lane: f64 values for the reference path, f32 (padded) for SIMD.
#[derive(Clone, Debug)]
struct Flat {
    v64: Vec<f64>,
    v32: Vec<f32>,
}

impl Flat {
    fn new(v64: Vec<f64>) -> Self {
        let mut v32: Vec<f32> = v64.iter().map(|&x| x as f32).collect();
        let padded = v32.len().next_multiple_of(16).max(32);
        v32.resize(padded, *v32.last().unwrap_or(&0.0));
        Self { v64, v32 }
    }

    /// Entry `idx` per lane (integral indices in range). Tables of up to 64 entries are
    /// register permutes with AVX-512 ([`Lanes::lookup_f32_`]), larger ones gathers.
    #[inline(always)]
    fn get<L: Lanes>(&self, idx: L) -> L {
        if L::WIDTH == 1 {
            let i = idx.lane(0).f64() as usize;
            return L::splat(<L::Elem as Real>::of(self.v64[i.min(self.v64.len() - 1)]));
        }
        L::lookup_f32_(&self.v32, idx)
    }

    /// Linear interpolation between entries `i` and `i + 1` with weight `t`.
    #[inline(always)]
    fn lerp<L: Lanes>(&self, i: L, t: L) -> L {
        let (a, b) = (self.get(i), self.get(i + L::c(1.0)));
        a + (b - a) * t
    }
}

/// Where `μ` falls on a table of `n` evenly spaced nodes: the lower node and the weight of the
/// upper one (computed once per direction, shared by every table read at it).
#[derive(Clone, Copy, Debug)]
struct MuAt<L> {
    i: L,
    t: L,
}

#[inline(always)]
fn mu_at<L: Lanes>(mu: L, nodes: usize) -> MuAt<L> {
    let last = (nodes - 1) as f64;
    let x = lanes::clamp(mu, L::c(0.0), L::c(1.0)) * L::c(last);
    let i = lanes::min(x.floor_(), L::c(last - 1.0));
    MuAt { i, t: x - i }
}

/// One basecoat component: its weight per element is a closed form of the parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// Unit pigment, weight `ρ (1 − c − c_p)(1 − m)`.
    Pigment,
    /// Unit pigment seen through pearl flakes, weight `ρ c_p`.
    PigmentPearl,
    /// Metal base with `F0 = 1`, weight `(1 − c − c_p) m ρ`.
    MetalOne,
    /// Metal base with `F0 = 0`, weight `(1 − c − c_p) m (1 − ρ)`.
    MetalZero,
    /// Metallic flakes of unit coverage, weight `c`.
    Flakes,
    /// The pearl flakes, weight 1.
    Pearl,
}

impl Kind {
    /// Components with equal values have the same lobes with the same roughness, so one
    /// sampler serves them ([`component_tables`]): the metal base of either `F0`, the
    /// metallic and the pearl flakes (one orientation distribution).
    fn sampler(self) -> u8 {
        match self {
            Kind::Pigment => 0,
            Kind::PigmentPearl => 1,
            Kind::MetalOne | Kind::MetalZero => 2,
            Kind::Flakes | Kind::Pearl => 3,
        }
    }
}

/// The per-element factor of a basis table: every component weight is bilinear in the
/// pigment colour `ρ` (per channel) and the flake coverage `c`, so each layer table is
/// `T₁ + ρ T_ρ + c T_c + ρc T_ρc` (the uncovered fraction `1 − c − c_p` unclamped: valid
/// elements have `c + c_p ≤ 1 + 1e-6`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Coef {
    One,
    Rho,
    C,
    RhoC,
}

impl Coef {
    const ALL: [Coef; 4] = [Coef::One, Coef::Rho, Coef::C, Coef::RhoC];

    /// Whether the factor holds `ρ` and `c`.
    fn factors(self) -> (bool, bool) {
        match self {
            Coef::One => (false, false),
            Coef::Rho => (true, false),
            Coef::C => (false, true),
            Coef::RhoC => (true, true),
        }
    }

    /// The factor of component `kind` on this basis table (`u0 = 1 − c_p`, `m` metallic).
    fn of(self, kind: Kind, u0: f64, m: f64) -> f64 {
        match (kind, self) {
            (Kind::Pigment, Coef::Rho) => u0 * (1.0 - m),
            (Kind::Pigment, Coef::RhoC) => -(1.0 - m),
            (Kind::PigmentPearl, Coef::Rho) => 1.0 - u0,
            (Kind::MetalOne, Coef::Rho) => u0 * m,
            (Kind::MetalOne, Coef::RhoC) => -m,
            (Kind::MetalZero, Coef::One) => u0 * m,
            (Kind::MetalZero, Coef::Rho) => -u0 * m,
            (Kind::MetalZero, Coef::C) => -m,
            (Kind::MetalZero, Coef::RhoC) => m,
            (Kind::Flakes, Coef::C) => 1.0,
            (Kind::Pearl, Coef::One) => 1.0,
            _ => 0.0,
        }
    }
}

/// Which of `base_color` and `flake_density` vary per element: the parameters that do not
/// are folded into the tables, so a call pays only for what its texture varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Vary {
    /// `base_color` varies.
    pub rho: bool,
    /// `flake_density` varies.
    pub c: bool,
}

impl Vary {
    /// Both vary (the most general tables; the f64 helpers use them).
    pub(crate) const ALL: Vary = Vary { rho: true, c: true };

    fn index(self) -> usize {
        usize::from(self.rho) + 2 * usize::from(self.c)
    }
}

/// The layer tables for one [`Vary`]: a few basis tables with per-element factors.
#[derive(Clone, Debug)]
struct Folded {
    /// The factor of each basis table.
    coefs: Vec<Coef>,
    /// `A1` per (basis, channel): `ALPHA × NODES` values (α node major).
    a1: Vec<Flat>,
    /// `U − A1` per (basis, channel).
    r: Vec<Flat>,
    /// Cosine average of `U − A1` per (basis, channel): one value per α node.
    r_avg: Vec<Flat>,
    /// Basecoat mean albedo per (basis, channel).
    rho_bar: Vec<[f64; 3]>,
}

/// Where an element's `α` falls on the node grid: the lower node (as a float) and the weight
/// of the upper one.
#[derive(Clone, Copy, Debug)]
struct AlphaAt<L> {
    node: L,
    t: L,
}

/// An element's parameters and the closed forms derived from them, per lane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Element<L: Lanes> {
    /// Index of the folded tables ([`Vary::index`]).
    cfg: usize,
    rho: [L; 3],
    /// Metallic flake coverage `c` (0..1).
    c: L,
    /// Coat GGX α (the material's when it does not vary).
    alpha: L,
    at: AlphaAt<L>,
    /// Factor of each basis table per channel.
    cw: [[L; 3]; 4],
    bounce: [L; 3],
    norm: [L; 3],
    /// `1/(π ΔR̄)` of the coat's multiple-scattering reflection at the element's α (α grid only).
    ms_norm: L,
    /// Basecoat lobe-selection weights: pigment, metal, flakes.
    base_sel: [L; 3],
    /// Pigment weight `(1 − c − c_p)(1 − m)`.
    pigment_weight: L,
    /// Metal base weight `(1 − c − c_p) m`.
    metal_weight: L,
}

/// The per-component tables of a coated paint (see the module docs), built once per material.
#[derive(Clone, Debug)]
pub struct VaryingPaint {
    /// The material's coat (its α-independent parts, and its lobe when α does not vary).
    coat: Coat,
    /// `ln α` of the nodes (one node, the material's α, when α does not vary).
    alpha_ln: Vec<f64>,
    /// `E_top(μ)` per α node (`E_NODES` each); unused when α does not vary.
    e_top: Flat,
    /// The crossing factor `g(μ)` (`Coat::crossing`) per α node (`E_NODES` each); unused
    /// when α does not vary.
    crossing_top: Flat,
    /// `sin θ'/sin θ` of the metal's first bounce ([`Coat::mean_refract_in`]) per α node
    /// (`E_NODES` each); unused when α does not vary.
    mean_refraction_top: Flat,
    /// The coat's multiple-scattering reflection `ΔR(μ)` per α node (`E_NODES` each,
    /// [`super::coat::MultipleScattering`]); unused when α does not vary.
    ms_top: Flat,
    /// Its cosine average `ΔR̄` per α node.
    ms_avg: Flat,
    /// The layer tables per [`Vary::index`].
    folded: Vec<Folded>,
    /// Escape probability `e` per α node.
    escape: Flat,
    /// Mean crossing transmittance `τ̄` per channel.
    tau: [f64; 3],
    /// Pearl coverage `c_p`.
    pearl_c: f64,
    /// Metallic weight `m` of the base.
    metallic: f64,
    metal: Option<MetalBase>,
    /// Flakes: metallic coverage 1 (scaled per element), pearl coverage `c_p`.
    flakes: Option<FlakeLayer>,
    pearl_transmission: Option<MuTable>,
    /// Mean normal reflectance of unit-coverage metallic flakes and of the pearl flakes (at `c_p`).
    flake_nr: [f64; 2],
    /// `mean(T_p(1))²` (the pigment-through-pearl selection weight).
    pearl_t_sel: f64,
    /// The material's own values.
    material_rho: [f64; 3],
    material_c: f64,
    material_alpha: f64,
    /// The coat's index when its rough transmission blurs the base's specular lobes (as
    /// [`Coat::transmission_blur`], with the element's α): None for a smooth coat or `η = 1`.
    blur_ior: Option<f64>,
    /// The metal base's bounce series per α node ([`SpecSeries`] of each node's coat: `[w₁,
    /// w₀, n]` and the albedos `[S₁, S₀]`, `NODES` values each): None without a metal base
    /// or a coat interface.
    spec: Option<SpecTables>,
}

/// [`SpecSeries`] tables per α node, flat (α node major).
#[derive(Clone, Debug)]
struct SpecTables {
    /// `w₁`, `w₀`, `n`.
    weights: [Flat; 3],
    /// `S₁`, `S₀` per unit metal weight.
    albedo: [Flat; 2],
    /// The metal's `α_b²` (the series adds `α_b² + α²` with the element's coat α).
    metal_alpha2: f64,
}

impl VaryingPaint {
    /// Builds the component tables of `paint` (with its parameters `p`); with `vary_alpha` the
    /// tables span the α grid, otherwise the material's own coat only. The coats and the
    /// table nodes are computed on the rayon pool.
    #[must_use]
    pub fn new(paint: &CoatedPaint, p: &Params, vary_alpha: bool) -> Self {
        use rayon::prelude::*;
        let coat = paint.coat().clone();
        let eta = coat.ior;
        let alphas: Vec<f64> =
            if vary_alpha { (0..ALPHA_NODES).map(alpha_node).collect() } else { vec![coat.roughness] };
        let coats: Vec<Coat> = if vary_alpha {
            let thickness_um = coat.thickness_mm * 1e3;
            alphas.par_iter().map(|&a| Coat::new(eta, a, thickness_um, coat.absorption_per_mm)).collect()
        } else {
            vec![coat.clone()]
        };
        let base = paint.basecoat();
        let pearl_c = p.scalar("pearl_density") / 100.0;
        let metallic = p.scalar("base_metallic");
        let material_c = p.scalar("flake_density") / 100.0;
        let material_rho = p.color("base_color");
        let flake_alpha = p.scalar("flake_orientation_deg").to_radians().tan();
        let metal_ior = fresnel::metal(p.choice("flake_material")).expect("choice list holds known metals");
        let pearl_table = base.flakes.as_ref().and_then(|f| f.pearl_reflectance.clone());
        let metal_fresnel =
            fresnel::ConductorFresnel::new(metal_ior.eta.map(|n| n / eta), metal_ior.k.map(|k| k / eta));
        let unit_flakes = |metal: f64, pearl: f64| FlakeLayer {
            alpha: flake_alpha,
            metallic_coverage: metal,
            metal: metal_fresnel.clone(),
            pearl_coverage: pearl,
            pearl_reflectance: pearl_table.clone(),
        };
        let metal_alpha = p.scalar("base_roughness");
        let metal_with = |f0: f64| MetalBase { alpha: metal_alpha, f0: [f0; 3], weight: 1.0 };
        let mut comps: Vec<(Kind, Basecoat)> =
            vec![(Kind::Pigment, Basecoat::new([1.0; 3], 1.0, 0.0, None, None, None))];
        if pearl_c > 0.0 {
            let t = base.pearl_transmission.clone();
            comps.push((Kind::PigmentPearl, Basecoat::new([1.0; 3], 0.0, 1.0, t, None, None)));
        }
        if metallic > 0.0 {
            comps.push((Kind::MetalOne, Basecoat::new([0.0; 3], 0.0, 0.0, None, Some(metal_with(1.0)), None)));
            comps.push((Kind::MetalZero, Basecoat::new([0.0; 3], 0.0, 0.0, None, Some(metal_with(0.0)), None)));
        }
        comps.push((Kind::Flakes, Basecoat::new([0.0; 3], 0.0, 0.0, None, None, Some(unit_flakes(1.0, 0.0)))));
        if pearl_c > 0.0 {
            comps.push((Kind::Pearl, Basecoat::new([0.0; 3], 0.0, 0.0, None, None, Some(unit_flakes(0.0, pearl_c)))));
        }
        let na = coats.len();
        let (escape, tau) = escape_and_tau(&coats);
        // The metal base's bounce series per α node (the material's own, `SpecSeries::build`).
        let series: Option<Vec<SpecSeries>> = if metallic > 0.0 && coat.has_interface() {
            coats.par_iter().map(|c| SpecSeries::build(c, metal_alpha)).collect()
        } else {
            None
        };
        // Per component: A1 and U − A1 per (α node, channel) as NODES values, their cosine
        // averages, and ρ̄.
        // Components with the same lobes and roughness share one set of samples per node.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, (kind, _)) in comps.iter().enumerate() {
            match groups.iter_mut().find(|g| comps[g[0]].0.sampler() == kind.sampler()) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        let mut per_comp: Vec<(usize, ComponentTables)> = groups
            .iter()
            .flat_map(|g| {
                let members: Vec<&Basecoat> = g.iter().map(|&i| &comps[i].1).collect();
                g.iter().copied().zip(component_tables(&coats, &members)).collect::<Vec<_>>()
            })
            .collect();
        per_comp.sort_by_key(|(i, _)| *i);
        let per_comp: Vec<ComponentTables> = per_comp
            .into_iter()
            .map(|(i, mut t)| {
                if series.is_some() && matches!(comps[i].0, Kind::MetalOne | Kind::MetalZero) {
                    // What the metal sends back down leaves through the bounce series, not
                    // the multiple-scatter lobe (`coated_paint::layer_tables`: for a
                    // metal-only component `R − R_spec` is 0).
                    t.r = std::array::from_fn(|_| vec![0.0; na * NODES]);
                    t.r_avg = std::array::from_fn(|_| vec![0.0; na]);
                }
                t
            })
            .collect();
        let spec = series.map(|series| {
            let col = |f: &dyn Fn(&SpecSeries) -> &MuTable, c: usize| {
                Flat::new(series.iter().flat_map(|s| f(s).values().iter().map(move |v| v[c])).collect())
            };
            SpecTables {
                weights: [0, 1, 2].map(|c| col(&|s| &s.weights, c)),
                albedo: [0, 1].map(|c| col(&|s| &s.albedo, c)),
                metal_alpha2: metal_alpha * metal_alpha,
            }
        });
        // The basis tables T_b = Σ_k coef_b(k) T_k.
        let u0 = 1.0 - pearl_c;
        let basis: Vec<ComponentTables> = Coef::ALL
            .iter()
            .map(|&b| {
                let mut out = ComponentTables::zero(na);
                for ((kind, _), t) in comps.iter().zip(&per_comp) {
                    out.add(b.of(*kind, u0, metallic), t);
                }
                out
            })
            .collect();
        let folded = (0..4)
            .map(|idx| {
                let vary = Vary { rho: idx & 1 != 0, c: idx & 2 != 0 };
                fold(&basis, vary, material_rho, material_c)
            })
            .collect();
        let mut e_top = vec![0.0; na * E_NODES];
        let mut crossing_top = vec![0.0; na * E_NODES];
        let mut mean_refraction_top = vec![0.0; na * E_NODES];
        let (mut ms_top, mut ms_avg) = (vec![0.0; na * E_NODES], vec![0.0; na]);
        for (j, cj) in coats.iter().enumerate() {
            for m in 0..E_NODES {
                e_top[j * E_NODES + m] = cj.reflectance(m as f64 / (E_NODES - 1) as f64);
                crossing_top[j * E_NODES + m] = cj.crossing(m as f64 / (E_NODES - 1) as f64);
                // The coat's own nodes (E_NODES of them): the same values.
                mean_refraction_top[j * E_NODES + m] =
                    cj.mean_refraction_ratio(m as f64 / (E_NODES - 1) as f64).unwrap_or(1.0 / eta);
            }
            if let Some(ms) = cj.multiple_scattering() {
                // The coat's own nodes (E_NODES of them), so interpolation agrees.
                for (m, v) in ms.albedo.values().iter().enumerate().take(E_NODES) {
                    ms_top[j * E_NODES + m] = v[0];
                }
                ms_avg[j] = ms.albedo.cosine_average()[0];
            }
        }
        let flakes_possible = unit_flakes(1.0, pearl_c);
        let flake_nr = [unit_flakes(1.0, 0.0).normal_reflectance(), unit_flakes(0.0, pearl_c).normal_reflectance()];
        let pearl_transmission = base.pearl_transmission.clone();
        let mean = |c: [f64; 3]| (c[0] + c[1] + c[2]) / 3.0;
        let pearl_t_sel = pearl_transmission.as_ref().map_or(0.0, |t| mean(t.eval::<f64>(1.0)).powi(2));
        let blur_ior = (coat.has_interface() && (vary_alpha || !coat.is_smooth())).then_some(eta);
        Self {
            alpha_ln: alphas.iter().map(|a| a.ln()).collect(),
            coat,
            e_top: Flat::new(e_top),
            crossing_top: Flat::new(crossing_top),
            mean_refraction_top: Flat::new(mean_refraction_top),
            ms_top: Flat::new(ms_top),
            ms_avg: Flat::new(ms_avg),
            folded,
            escape: Flat::new(escape),
            tau,
            pearl_c,
            metallic,
            metal: (metallic > 0.0).then_some(MetalBase { alpha: metal_alpha, f0: [1.0; 3], weight: 1.0 }),
            flakes: Some(flakes_possible),
            pearl_transmission,
            flake_nr,
            pearl_t_sel,
            material_rho,
            material_c,
            material_alpha: paint.coat().roughness,
            blur_ior,
            spec,
        }
    }

    /// True when the coat roughness varies per element (the tables span the α grid).
    #[must_use]
    pub fn varies_alpha(&self) -> bool {
        self.alpha_ln.len() > 1
    }

    /// The material's values `(base_color, flake coverage 0..1, coat α)`, used for the
    /// parameters an element does not vary.
    #[must_use]
    pub fn defaults(&self) -> ([f64; 3], f64, f64) {
        (self.material_rho, self.material_c, self.material_alpha)
    }

    /// `A1(μ)` and `M(μ)` of one element (f64; a report or a test, as
    /// `CoatedPaint::layer_albedos`).
    #[must_use]
    pub fn layer_albedos(&self, rho: [f64; 3], coverage: f64, alpha: f64, mu: f64) -> ([f64; 3], [f64; 3]) {
        let e = self.element::<f64>(rho, coverage, alpha, Vary::ALL);
        let m = mu_at(mu, NODES);
        (self.single(&e, &m), self.multiple(&e, &m))
    }

    /// The three terms of `f` for one element (f64; tests): top reflection, single-scatter
    /// layer, multiple scatter (as `CoatedPaint::eval_terms`).
    #[must_use]
    pub fn eval_terms(&self, rho: [f64; 3], coverage: f64, alpha: f64, wi: Vec3<f64>, wo: Vec3<f64>) -> [Rgb<f64>; 3] {
        let e = self.element::<f64>(rho, coverage, alpha, Vary::ALL);
        let (a, b) = (self.multiple(&e, &mu_at(wi.z, NODES)), self.multiple(&e, &mu_at(wo.z, NODES)));
        let m = Rgb::new(a[0] * b[0] * e.norm[0], a[1] * b[1] * e.norm[1], a[2] * b[2] * e.norm[2]);
        let (ti, to) = (self.transmittance(&e, wi.z), self.transmittance(&e, wo.z));
        [Rgb::splat(self.top_eval(&e, wi, wo)), self.layer_term(&e, wi, wo, ti, to), m]
    }

    /// The density of one element for given lobe-selection weights `s` (f64; tests: with a
    /// material's own weights it must reproduce that material's `pdf`).
    #[must_use]
    pub fn pdf_with_selection(
        &self,
        rho: [f64; 3],
        coverage: f64,
        alpha: f64,
        wi: Vec3<f64>,
        wo: Vec3<f64>,
        s: [f64; 3],
    ) -> f64 {
        let e = self.element::<f64>(rho, coverage, alpha, Vary::ALL);
        let ms = self.ms_albedo(&e, wo.z);
        self.pdf_with(&e, wi, wo, s, ms)
    }

    /// `f` and pdf of one element (f64; tests).
    #[must_use]
    pub fn eval_pdf_one(
        &self,
        rho: [f64; 3],
        coverage: f64,
        alpha: f64,
        wi: Vec3<f64>,
        wo: Vec3<f64>,
    ) -> (Rgb<f64>, f64) {
        let e = self.element::<f64>(rho, coverage, alpha, Vary::ALL);
        self.eval_pdf_lanes(&e, wi, wo)
    }

    /// Per lane: whether the raw parameters are valid (`rho`, flake density in %, α), for the
    /// ones given. Invalid lanes must not be evaluated (the caller substitutes the defaults).
    #[inline(always)]
    pub(crate) fn valid<L: Lanes>(&self, rho: Option<[L; 3]>, density: Option<L>, alpha: Option<L>) -> L::Mask {
        let mut ok = L::Mask::splat(true);
        if let Some([r, g, b]) = rho {
            ok = ok & inside(r, 0.0, 1.0) & inside(g, 0.0, 1.0) & inside(b, 0.0, 1.0);
        }
        if let Some(d) = density {
            ok = ok & inside(d, 0.0, 100.0) & lanes::le(d * L::c(0.01) + L::c(self.pearl_c), L::c(1.0 + 1e-6));
        }
        if let Some(a) = alpha {
            ok = ok & inside(a, ALPHA_MIN, ALPHA_MAX);
        }
        ok
    }

    /// The closed forms of one element (valid parameters: `rho`, coverage `c` in 0..1, α);
    /// `vary` names the parameters that may differ from the material's (the others must be
    /// the material's values: they are folded into the tables).
    #[inline(always)]
    pub(crate) fn element<L: Lanes>(&self, rho: [L; 3], c: L, alpha: L, vary: Vary) -> Element<L> {
        let zero = L::c(0.0);
        let one = L::c(1.0);
        let at = if self.varies_alpha() {
            let n = self.alpha_ln.len();
            let (s0, s1) = (self.alpha_ln[0], self.alpha_ln[n - 1]);
            let x = lanes::clamp(
                (lanes::ln(alpha) - L::c(s0)) * L::c((n - 1) as f64 / (s1 - s0)),
                zero,
                L::c((n - 1) as f64),
            );
            let node = lanes::min(x.floor_(), L::c((n - 2) as f64));
            AlphaAt { node, t: x - node }
        } else {
            AlphaAt { node: zero, t: zero }
        };
        let cfg = vary.index();
        let folded = &self.folded[cfg];
        let mut cw = [[zero; 3]; 4];
        for (w, coef) in cw.iter_mut().zip(&folded.coefs) {
            *w = match coef {
                Coef::One => [one; 3],
                Coef::Rho => rho,
                Coef::C => [c; 3],
                Coef::RhoC => rho.map(|r| r * c),
            };
        }
        let cp = L::c(self.pearl_c);
        let m = L::c(self.metallic);
        let uncovered = lanes::max(one - c - cp, zero);
        let pigment_weight = uncovered * (one - m);
        let metal_weight = uncovered * m;
        // Bounce factor and the multiple-scatter lobe's normalisation, per channel.
        let escape = self.alpha_lerp1(&self.escape, &at);
        let mut bounce = [zero; 3];
        let mut norm = [zero; 3];
        for ch in 0..3 {
            let (mut rb, mut ravg) = (zero, zero);
            for (j, w) in cw.iter().enumerate().take(folded.coefs.len()) {
                rb += w[ch] * L::c(folded.rho_bar[j][ch]);
                ravg += w[ch] * self.alpha_lerp1(&folded.r_avg[j * 3 + ch], &at);
            }
            let r = L::c(self.tau[ch] * self.tau[ch]) * rb;
            let denom = one - r * (one - escape);
            let b = lanes::select(lanes::gt(denom, L::c(1e-12)), r * escape / denom, one);
            bounce[ch] = b;
            let mbar = b * ravg;
            norm[ch] = lanes::select(lanes::gt(mbar, L::c(1e-12)), one / (L::c(std::f64::consts::PI) * mbar), zero);
        }
        // Basecoat lobe selection (as `Basecoat::new`, per element).
        let rho_mean = (rho[0] + rho[1] + rho[2]) / L::c(3.0);
        let w_pig = rho_mean * (pigment_weight + cp * L::c(self.pearl_t_sel));
        let w_metal = if self.metal.is_some() { metal_weight * lanes::max(rho_mean, L::c(0.04)) } else { zero };
        let w_flakes = c * L::c(self.flake_nr[0]) + L::c(self.flake_nr[1]);
        let total = lanes::max(w_pig + w_metal + w_flakes, L::c(1e-12));
        let floor = L::c(0.02) * total;
        let pig_present = lanes::gt(pigment_weight, zero) | lanes::gt(cp, zero);
        let flakes_present = lanes::gt(c, zero) | lanes::gt(cp, zero);
        let base_sel = [
            keep(pig_present, lanes::max(w_pig, floor)),
            if self.metal.is_some() { lanes::max(w_metal, floor) } else { zero },
            keep(flakes_present, lanes::max(w_flakes, floor)),
        ];
        let ms_norm = if self.varies_alpha() {
            let avg = self.alpha_lerp1(&self.ms_avg, &at);
            lanes::select(lanes::gt(avg, L::c(1e-12)), one / (L::c(std::f64::consts::PI) * avg), zero)
        } else {
            zero
        };
        Element { cfg, rho, c, alpha, at, cw, bounce, norm, ms_norm, base_sel, pigment_weight, metal_weight }
    }

    /// A per-α-node value (`flat` holds one per node) at the element's α.
    #[inline(always)]
    fn alpha_lerp1<L: Lanes>(&self, flat: &Flat, at: &AlphaAt<L>) -> L {
        if !self.varies_alpha() {
            return L::c(flat.v64[0]);
        }
        flat.lerp(at.node, at.t)
    }

    /// A table of `nodes` μ nodes per α node at the element's α and `μ` (bilinear).
    #[inline(always)]
    fn lookup<L: Lanes>(&self, flat: &Flat, nodes: usize, at: &AlphaAt<L>, m: &MuAt<L>) -> L {
        if !self.varies_alpha() {
            return flat.lerp(m.i, m.t);
        }
        let row = at.node * L::c(nodes as f64) + m.i;
        let a = flat.lerp(row, m.t);
        let b = flat.lerp(row + L::c(nodes as f64), m.t);
        a + (b - a) * at.t
    }

    /// A combined layer table (`A1` or `U − A1`, chosen by `pick`) per channel at `μ`.
    #[inline(always)]
    fn table<L: Lanes>(&self, single: bool, e: &Element<L>, m: &MuAt<L>) -> [L; 3] {
        let folded = &self.folded[e.cfg];
        let tabs = if single { &folded.a1 } else { &folded.r };
        let mut out = [L::c(0.0); 3];
        for (ch, o) in out.iter_mut().enumerate() {
            for (j, w) in e.cw.iter().enumerate().take(folded.coefs.len()) {
                let v = self.lookup(&tabs[j * 3 + ch], NODES, &e.at, m);
                *o = if folded.coefs[j] == Coef::One { *o + v } else { *o + w[ch] * v };
            }
        }
        out
    }

    /// `A1(μ)` of the element.
    #[inline(always)]
    fn single<L: Lanes>(&self, e: &Element<L>, m: &MuAt<L>) -> [L; 3] {
        self.table(true, e, m)
    }

    /// `M(μ) = bounce · (U − A1)(μ)` of the element.
    #[inline(always)]
    fn multiple<L: Lanes>(&self, e: &Element<L>, m: &MuAt<L>) -> [L; 3] {
        let r = self.table(false, e, m);
        [0, 1, 2].map(|c| lanes::max(e.bounce[c] * r[c], L::c(0.0)))
    }

    /// Energy the top surface reflects for incidence `μ`.
    #[inline(always)]
    fn reflectance<L: Lanes>(&self, e: &Element<L>, mu: L) -> L {
        if !self.varies_alpha() || !self.coat.has_interface() {
            return self.coat.reflectance(mu);
        }
        self.lookup(&self.e_top, E_NODES, &e.at, &mu_at(mu, E_NODES))
    }

    /// Energy the coat's multiple scattering reflects for incidence `μ` (`Coat::ms_albedo`).
    #[inline(always)]
    fn ms_albedo<L: Lanes>(&self, e: &Element<L>, mu: L) -> L {
        if !self.varies_alpha() || !self.coat.has_interface() {
            return self.coat.ms_albedo(mu);
        }
        self.lookup(&self.ms_top, E_NODES, &e.at, &mu_at(mu, E_NODES))
    }

    /// Energy entering the coat for incidence `μ`, as `Coat::transmittance`.
    #[inline(always)]
    fn transmittance<L: Lanes>(&self, e: &Element<L>, mu: L) -> L {
        if !self.varies_alpha() {
            return self.coat.transmittance(mu);
        }
        self.transmittance_of(self.reflectance(e, mu), self.ms_albedo(e, mu))
    }

    /// `1 − E_top − ΔR` from the two reflected energies (as `Coat::transmittance`).
    #[inline(always)]
    fn transmittance_of<L: Lanes>(&self, reflectance: L, ms: L) -> L {
        if !self.varies_alpha() && self.coat.multiple_scattering().is_none() {
            return lanes::max(L::c(1.0) - reflectance, L::c(0.0));
        }
        lanes::max(L::c(1.0) - reflectance - ms, L::c(0.0))
    }

    /// The glossy lobes' crossing factor `g(μ)` of the single-scatter layer term (`Coat::crossing`).
    #[inline(always)]
    fn crossing<L: Lanes>(&self, e: &Element<L>, mu: L) -> L {
        if !self.varies_alpha() || !self.coat.has_interface() {
            return self.coat.crossing(mu);
        }
        // The α grid's coats are all rough.
        self.lookup(&self.crossing_top, E_NODES, &e.at, &mu_at(mu, E_NODES))
    }

    #[inline(always)]
    fn coat_microfacet<L: Lanes>(e: &Element<L>) -> Microfacet<L> {
        Microfacet::new(DistributionKind::Ggx, e.alpha, e.alpha)
    }

    /// The rough top reflection with the element's α.
    #[inline(always)]
    fn top_eval<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> L {
        if !self.varies_alpha() {
            return self.coat.top_eval(wi, wo);
        }
        if !self.coat.has_interface() {
            return L::c(0.0);
        }
        let (h, defined) = half_vector_masked(wi, wo);
        let mf = Self::coat_microfacet(e);
        let g = mf.g(wi, wo, h, MaskingKind::HeightCorrelated);
        let f = fresnel::dielectric(wo.dot(h), L::c(self.coat.ior)) * mf.d(h) * g / (L::c(4.0) * wi.z * wo.z);
        // The multiple-scattering reflection ΔR(μi) ΔR(μo) A(wi, wo)/(π ΔR̄) at the element's α.
        let ms = self.ms_albedo(e, wi.z) * self.ms_albedo(e, wo.z) * e.ms_norm * ms_azimuthal(wi, wo);
        keep(defined & lanes::gt(g, L::c(0.0)), f) + ms
    }

    #[inline(always)]
    fn top_pdf<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> L {
        if !self.varies_alpha() {
            return self.coat.reflection_pdf(wi, wo);
        }
        let (h, defined) = half_vector_masked(wi, wo);
        keep(defined, Self::coat_microfacet(e).visible_d(wo, h) * reflection_jacobian(wo, h))
    }

    #[inline(always)]
    fn top_sample<L: Lanes>(&self, e: &Element<L>, wo: Vec3<L>, u1: L, u2: L) -> Vec3<L> {
        if !self.varies_alpha() {
            return self.coat.reflection_sample(wo, u1, u2);
        }
        crate::frame::reflect(wo, Self::coat_microfacet(e).sample_m(wo, u1, u2, true))
    }

    /// True when the element's coat is the smooth (delta) coat.
    fn smooth(&self) -> bool {
        !self.varies_alpha() && self.coat.is_smooth()
    }

    /// The basecoat BRDF of the element (directions inside the coat) as its pigment and metal
    /// base, and its flakes. The flake lobe is skipped when no lane has flakes.
    #[inline(always)]
    fn base_eval<L: Lanes>(
        &self,
        e: &Element<L>,
        wi: Vec3<L>,
        wo: Vec3<L>,
        outside: (Vec3<L>, Vec3<L>),
    ) -> (Rgb<L>, Rgb<L>) {
        let inv_pi = L::c(std::f64::consts::FRAC_1_PI);
        let pw = e.pigment_weight;
        let pigment = match &self.pearl_transmission {
            None => Rgb::new(e.rho[0] * inv_pi * pw, e.rho[1] * inv_pi * pw, e.rho[2] * inv_pi * pw),
            Some(t) => {
                let (a, b) = (t.eval_lanes(wi.z), t.eval_lanes(wo.z));
                let cp = L::c(self.pearl_c);
                Rgb::new(
                    e.rho[0] * inv_pi * (pw + cp * a[0] * b[0]),
                    e.rho[1] * inv_pi * (pw + cp * a[1] * b[1]),
                    e.rho[2] * inv_pi * (pw + cp * a[2] * b[2]),
                )
            }
        };
        let mut f = pigment;
        if let Some(m) = &self.metal {
            let (at_i, at_o) = (self.blur_one_sided(e, wi.z), self.blur_one_sided(e, wo.z));
            let rho = Rgb::new(e.rho[0], e.rho[1], e.rho[2]);
            // The first bounce at the mean refracted directions under a rough coat (the blur
            // at the macro refraction's cosines), as `CoatedPaint`'s.
            f += match (at_i, at_o) {
                (Some(a), Some(o)) => {
                    let (mi, mo) = (self.mean_refract_in(e, outside.0), self.mean_refract_in(e, outside.1));
                    m.eval_with(&m.blurred(o), Some(&m.blurred(a)), rho, e.metal_weight, mi, mo)
                }
                _ => m.eval_with(&m.microfacet::<L>(), None, rho, e.metal_weight, wi, wo),
            };
        }
        let mut flakes = Rgb::zero();
        if let Some(fl) = &self.flakes {
            if self.pearl_c > 0.0 || lanes::gt(e.c, L::c(0.0)).any() {
                // Under a rough coat at the flakes' map of the outside directions, without
                // blur (`Coat::flake_refract_in`), as `CoatedPaint`'s.
                flakes = if self.blur_ior.is_some() {
                    let (fi, fo) = (self.flake_refract_in(e, outside.0), self.flake_refract_in(e, outside.1));
                    fl.eval_scaled(fi, fo, e.c, L::c(1.0))
                } else {
                    fl.eval_scaled(wi, wo, e.c, L::c(1.0))
                };
            }
        }
        (f, flakes)
    }

    /// The inside direction of the metal's first bounce for the outside direction `w`
    /// ([`Coat::mean_refract_in`] of the element's coat).
    #[inline(always)]
    fn mean_refract_in<L: Lanes>(&self, e: &Element<L>, w: Vec3<L>) -> Vec3<L> {
        if !self.varies_alpha() {
            return self.coat.mean_refract_in(w);
        }
        inside_with_ratio(w, self.lookup(&self.mean_refraction_top, E_NODES, &e.at, &mu_at(w.z, E_NODES)))
    }

    /// The inside direction of the flakes' lobe for the outside direction `w`
    /// ([`Coat::flake_refract_in`] of the element's coat).
    #[inline(always)]
    fn flake_refract_in<L: Lanes>(&self, e: &Element<L>, w: Vec3<L>) -> Vec3<L> {
        if !self.varies_alpha() {
            return self.coat.flake_refract_in(w);
        }
        let mean = self.lookup(&self.mean_refraction_top, E_NODES, &e.at, &mu_at(w.z, E_NODES));
        inside_with_ratio(w, flake_ratio_from_mean(self.coat.ior, mean))
    }

    /// What the transmission blur adds to the base lobes' `α²` seen from an inside direction
    /// of cosine `mu` (as [`TransmissionBlur::one_sided`] with the element's α).
    #[inline(always)]
    fn blur_one_sided<L: Lanes>(&self, e: &Element<L>, mu: L) -> Option<L> {
        self.blur_ior.map(|eta| TransmissionBlur::one_sided_at(eta, e.alpha, mu))
    }

    /// Density of the element's basecoat mixture.
    #[inline(always)]
    fn base_pdf<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> L {
        let [a, b, c] = e.base_sel;
        let total = a + b + c;
        let mut p = a * cosine_hemisphere_pdf(wi.z);
        let added = self.blur_one_sided(e, wo.z);
        if let Some(m) = &self.metal {
            p += b * added.map_or_else(|| m.pdf(wi, wo), |a| MetalBase::pdf_with(&m.blurred(a), wi, wo));
        }
        if let Some(f) = &self.flakes {
            let on = lanes::gt(c, L::c(0.0));
            if on.any() {
                p += keep(on, c * f.pdf(wi, wo));
            }
        }
        keep(lanes::gt(total, L::c(0.0)), p / total)
    }

    /// The element's basecoat lobe choice and direction (as `Basecoat::sample_direction_masked`).
    #[inline(always)]
    fn base_sample<L: Lanes>(&self, e: &Element<L>, wo: Vec3<L>, u: [L; 3], active: L::Mask) -> (Vec3<L>, L::Mask) {
        let pick = pick3(e.base_sel, u[0]);
        let [pigment, metal, flake] = [pick.lobe[0] & active, pick.lobe[1] & active, pick.lobe[2] & active];
        let mut wi = Vec3::from_f64(0.0, 0.0, 1.0);
        if pigment.any() {
            wi = Vec3::select(pigment, cosine_hemisphere(u[1], u[2]), wi);
        }
        let added = self.blur_one_sided(e, wo.z);
        if let Some(m) = self.metal.as_ref().filter(|_| metal.any()) {
            let w = match added {
                None => m.sample_direction(wo, u[1], u[2]),
                Some(a) => MetalBase::sample_direction_with(&m.blurred(a), wo, u[1], u[2]),
            };
            wi = Vec3::select(metal, w, wi);
        }
        if let Some(f) = self.flakes.as_ref().filter(|_| flake.any()) {
            wi = Vec3::select(flake, f.sample_direction_masked(wo, u[1], u[2], flake), wi);
        }
        (wi, pick.valid)
    }

    /// The single-scatter layer term of the element, for the coat transmittances `ti`, `to`
    /// at `wi`, `wo`.
    #[inline(always)]
    fn layer_term<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>, ti: L, to: L) -> Rgb<L> {
        let crosses = lanes::gt(ti, L::c(0.0)) & lanes::gt(to, L::c(0.0));
        let (wi_in, wo_in) = (self.coat.refract_in(wi), self.coat.refract_in(wo));
        let scale = ti * to / L::c(self.coat.ior * self.coat.ior);
        let (mut rest, flakes) = self.base_eval(e, wi_in, wo_in, (wi, wo));
        if let (Some(spec), Some(m)) = (&self.spec, &self.metal) {
            rest += self.spec_term(e, spec, m, wi, wo, wi_in, wo_in);
        }
        let mut f = if self.varies_alpha() || self.coat.has_crossing() {
            // A rough coat: the flakes cross with `g(μi) g(μo)` (`Coat::crossing`).
            let flake_scale = self.crossing(e, wi.z) * self.crossing(e, wo.z) / L::c(self.coat.ior * self.coat.ior);
            rest * scale + flakes * flake_scale
        } else {
            (rest + flakes) * scale
        };
        if self.coat.absorbs() {
            let (ai, ao) = (self.coat.attenuation(wi_in.z), self.coat.attenuation(wo_in.z));
            f = Rgb::new(f.r * ai[0] * ao[0], f.g * ai[1] * ao[1], f.b * ai[2] * ao[2]);
        }
        Rgb::select(crosses, f, Rgb::zero())
    }

    /// The metal base's bounce series of the element (as `CoatedPaint`'s, with the element's
    /// `F0 = ρ`, metal weight and coat α; directions outside and inside the coat).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn spec_term<L: Lanes>(
        &self,
        e: &Element<L>,
        spec: &SpecTables,
        m: &MetalBase,
        wi: Vec3<L>,
        wo: Vec3<L>,
        wi_in: Vec3<L>,
        wo_in: Vec3<L>,
    ) -> Rgb<L> {
        let (mi, mo) = (mu_at(wi.z, NODES), mu_at(wo.z, NODES));
        let (w1, w0) = (&spec.weights[0], &spec.weights[1]);
        let w = (
            lanes::safe_sqrt(self.lookup(w1, NODES, &e.at, &mi) * self.lookup(w1, NODES, &e.at, &mo)),
            lanes::safe_sqrt(self.lookup(w0, NODES, &e.at, &mi) * self.lookup(w0, NODES, &e.at, &mo)),
        );
        let (n_i, n_o) =
            (self.lookup(&spec.weights[2], NODES, &e.at, &mi), self.lookup(&spec.weights[2], NODES, &e.at, &mo));
        let n_eff = (n_i + n_o) * L::c(0.5);
        let (metal_alpha2, coat_alpha2) = (L::c(spec.metal_alpha2), e.alpha * e.alpha);
        let (ei, eo) =
            (series_widening(metal_alpha2, coat_alpha2, n_i), series_widening(metal_alpha2, coat_alpha2, n_o));
        let added = match (self.blur_one_sided(e, wi_in.z), self.blur_one_sided(e, wo_in.z)) {
            (Some(a), Some(o)) => (a + ei, o + eo),
            _ => (ei, eo),
        };
        // At the mean refracted directions under a rough coat, as the first bounce
        // (`CoatedPaint::spec_term`).
        let (wi_lobe, wo_lobe) = if self.blur_ior.is_some() {
            (self.mean_refract_in(e, wi), self.mean_refract_in(e, wo))
        } else {
            (wi_in, wo_in)
        };
        let f0 = Rgb::new(e.rho[0], e.rho[1], e.rho[2]);
        series_lobe(m, f0, e.metal_weight, added, wi_lobe, wo_lobe, w, Some(n_eff))
    }

    /// The bounce series' albedo at `wo` (channels' mean; 0 without it).
    #[inline(always)]
    fn spec_albedo<L: Lanes>(&self, e: &Element<L>, m: &MuAt<L>) -> L {
        let Some(spec) = &self.spec else { return L::c(0.0) };
        let (s1, s0) = (self.lookup(&spec.albedo[0], NODES, &e.at, m), self.lookup(&spec.albedo[1], NODES, &e.at, m));
        let f0 = (e.rho[0] + e.rho[1] + e.rho[2]) / L::c(3.0);
        e.metal_weight * (f0 * s1 + (L::c(1.0) - f0) * s0)
    }

    /// What `f` and the lobe selection share at `wo`: `M(μo)` and the top reflectance.
    #[inline(always)]
    fn at_wo<L: Lanes>(&self, e: &Element<L>, wo: Vec3<L>) -> AtWo<L> {
        let m = mu_at(wo.z, NODES);
        AtWo { m, multiple: self.multiple(e, &m), reflectance: self.reflectance(e, wo.z), ms: self.ms_albedo(e, wo.z) }
    }

    /// `f_r` of the element given its values at `wo`.
    #[inline(always)]
    fn eval_with<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>, o: &AtWo<L>) -> Rgb<L> {
        let top = self.top_eval(e, wi, wo);
        let (a, b) = (self.multiple(e, &mu_at(wi.z, NODES)), o.multiple);
        let m = Rgb::new(a[0] * b[0] * e.norm[0], a[1] * b[1] * e.norm[1], a[2] * b[2] * e.norm[2]);
        // Both from `transmittance` (a smooth coat's is not `1 − reflectance`): symmetric.
        let (ti, to) = (self.transmittance(e, wi.z), self.transmittance(e, wo.z));
        Rgb::splat(top) + self.layer_term(e, wi, wo, ti, to) + m
    }

    /// `f_r` of the element (both directions above the surface).
    #[inline(always)]
    pub(crate) fn eval_lanes<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> Rgb<L> {
        self.eval_with(e, wi, wo, &self.at_wo(e, wo))
    }

    /// `f_r` and the density of the element (both directions above the surface), sharing the
    /// tables read at `wo`.
    #[inline(always)]
    pub(crate) fn eval_pdf_lanes<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> (Rgb<L>, L) {
        let o = self.at_wo(e, wo);
        let f = self.eval_with(e, wi, wo, &o);
        (f, self.pdf_with(e, wi, wo, self.selection(e, &o), o.ms))
    }

    /// Lobe-selection weights for `wo`: top reflection, single-scatter layer, multiple scatter.
    #[inline(always)]
    fn selection<L: Lanes>(&self, e: &Element<L>, o: &AtWo<L>) -> [L; 3] {
        let [a, b, c] = self.single(e, &o.m);
        let [d, f, g] = o.multiple;
        let third = L::c(1.0 / 3.0);
        [o.reflectance, (a + b + c) * third + self.spec_albedo(e, &o.m), (d + f + g) * third + o.ms]
    }

    /// Whether the coat has a multiple-scattering reflection (a rough or textured-α coat).
    #[inline(always)]
    fn has_ms(&self) -> bool {
        (self.varies_alpha() && self.coat.has_interface()) || self.coat.multiple_scattering().is_some()
    }

    /// The mixture density for the selection weights `s` at `wo`, whose cosine weight `s[2]`
    /// holds the coat's multiple-scattering reflection `ms` = `ΔR(μo)` (as
    /// `CoatedPaint::pdf_pair`).
    #[inline(always)]
    fn pdf_with<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>, s: [L; 3], ms: L) -> L {
        let total = s[0] + s[1] + s[2];
        let mut p = s[0] * self.top_pdf(e, wi, wo);
        let (wi_in, wo_in) = (self.coat.refract_in(wi), self.coat.refract_in(wo));
        let layer = s[1] * self.base_pdf(e, wi_in, wo_in) * self.coat.solid_angle_ratio(wi.z, wi_in.z);
        p += keep(lanes::gt(s[1], L::c(0.0)), layer);
        p += s[2] * cosine_hemisphere_pdf(wi.z);
        if self.has_ms() {
            p += ms * (ms_pdf(wi, wo) - cosine_hemisphere_pdf(wi.z));
        }
        keep(lanes::gt(total, L::c(0.0)), p / total)
    }

    /// Sampling density of the element (both directions above the surface).
    #[inline(always)]
    pub(crate) fn pdf_lanes<L: Lanes>(&self, e: &Element<L>, wi: Vec3<L>, wo: Vec3<L>) -> L {
        let o = self.at_wo(e, wo);
        self.pdf_with(e, wi, wo, self.selection(e, &o), o.ms)
    }

    /// A sample of the element (`wo` above the surface), as `CoatedPaint::sample_lanes`.
    #[inline(always)]
    pub(crate) fn sample_lanes<L: Lanes>(&self, e: &Element<L>, wo: Vec3<L>, u: [L; 3]) -> LaneSample<L> {
        let o = self.at_wo(e, wo);
        let selection = self.selection(e, &o);
        let pick = pick3(selection, u[0]);
        let [top, layer, multiple] = pick.lobe;
        let normal = Vec3::from_f64(0.0, 0.0, 1.0);
        let w_top = if top.any() { self.top_sample(e, wo, u[1], u[2]) } else { normal };
        let (w_layer, layer_ok) = if layer.any() {
            let wo_in = self.coat.refract_in(wo);
            let (wi_in, base_ok) = self.base_sample(e, wo_in, [pick.u, u[1], u[2]], layer);
            let (w_layer, escapes) = self.coat.refract_out_masked(wi_in);
            (w_layer, base_ok & lanes::gt(wi_in.z, L::c(0.0)) & escapes)
        } else {
            (normal, L::Mask::splat(false))
        };
        let w_multiple = if multiple.any() {
            let w = cosine_hemisphere(u[1], u[2]);
            let coat_ms = multiple & lanes::lt(pick.u * selection[2], o.ms);
            if self.has_ms() && coat_ms.any() {
                Vec3::select(coat_ms, ms_sample(wo, u[1], u[2]), w)
            } else {
                w
            }
        } else {
            normal
        };
        let wi = Vec3::select(top, w_top, Vec3::select(layer, w_layer, w_multiple));
        let valid = pick.valid & (top | (layer & layer_ok) | multiple);
        // Lanes without a sample evaluated at `wo`'s mirror direction, as
        // `CoatedPaint::sample_parts` does (the lane group's shortcuts assume unit directions).
        let drawn = valid & lanes::gt(wi.z, L::c(0.0));
        let wi_eval = Vec3::select(drawn, wi, crate::frame::mirror_z(wo));
        let f = self.eval_with(e, wi_eval, wo, &o);
        let pdf = self.pdf_with(e, wi_eval, wo, selection, o.ms);
        let s = LaneSample::from_eval(wi, f, pdf, drawn);
        if !self.smooth() {
            return s;
        }
        let delta = top;
        let p = selection[0] / (selection[0] + selection[1] + selection[2]);
        let w = selection[0] / p;
        LaneSample {
            wi,
            weight: Rgb::select(delta, Rgb::splat(w), s.weight),
            pdf: lanes::select(delta, p, s.pdf),
            valid: (delta & valid & lanes::gt(p, L::c(0.0))) | (!delta & s.valid),
            delta,
        }
    }
}

/// `lo ≤ x ≤ hi` per lane (false for NaN).
#[inline(always)]
fn inside<L: Lanes>(x: L, lo: f64, hi: f64) -> L::Mask {
    lanes::ge(x, L::c(lo)) & lanes::le(x, L::c(hi))
}

/// The element's values at `wo`, shared by `f` and the lobe selection.
#[derive(Clone, Copy, Debug)]
struct AtWo<L> {
    m: MuAt<L>,
    multiple: [L; 3],
    reflectance: L,
    /// The coat's multiple-scattering reflection `ΔR(μo)`.
    ms: L,
}

/// The layer tables of one component (or one basis combination of components), f64.
#[derive(Clone, Debug)]
struct ComponentTables {
    /// `A1` per channel: `ALPHA × NODES` values each (α node major).
    a1: [Vec<f64>; 3],
    /// `U − A1` per channel.
    r: [Vec<f64>; 3],
    /// Cosine average of `U − A1` per channel, per α node.
    r_avg: [Vec<f64>; 3],
    /// Mean albedo `ρ̄` per channel.
    rho_bar: [f64; 3],
}

impl ComponentTables {
    fn zero(na: usize) -> Self {
        Self {
            a1: std::array::from_fn(|_| vec![0.0; na * NODES]),
            r: std::array::from_fn(|_| vec![0.0; na * NODES]),
            r_avg: std::array::from_fn(|_| vec![0.0; na]),
            rho_bar: [0.0; 3],
        }
    }

    /// `self += k · other`.
    fn add(&mut self, k: f64, other: &Self) {
        if k == 0.0 {
            return;
        }
        for c in 0..3 {
            for (x, y) in self.a1[c].iter_mut().zip(&other.a1[c]) {
                *x += k * y;
            }
            for (x, y) in self.r[c].iter_mut().zip(&other.r[c]) {
                *x += k * y;
            }
            for (x, y) in self.r_avg[c].iter_mut().zip(&other.r_avg[c]) {
                *x += k * y;
            }
            self.rho_bar[c] += k * other.rho_bar[c];
        }
    }

    /// True when every value is zero (the basis table is left out).
    fn is_zero(&self) -> bool {
        self.a1.iter().chain(&self.r).chain(&self.r_avg).all(|v| v.iter().all(|&x| x == 0.0))
            && self.rho_bar.iter().all(|&x| x == 0.0)
    }
}

/// The tables for `vary` from the basis tables (`Coef::ALL` order): the factors that do not
/// vary take the material's values `rho0`, `c0`. With `rho0`, `c0` per channel the folded
/// tables are the same linear combination the element's weights give.
fn fold(basis: &[ComponentTables], vary: Vary, rho0: [f64; 3], c0: f64) -> Folded {
    let slots: Vec<Coef> = Coef::ALL
        .into_iter()
        .filter(|c| {
            let (r, k) = c.factors();
            (!r || vary.rho) && (!k || vary.c)
        })
        .collect();
    let na = basis[0].r_avg[0].len();
    let mut tabs: Vec<ComponentTables> = slots.iter().map(|_| ComponentTables::zero(na)).collect();
    for (b, t) in Coef::ALL.iter().zip(basis) {
        let (has_rho, has_c) = b.factors();
        let slot = Coef::ALL
            .into_iter()
            .find(|s| s.factors() == (has_rho && vary.rho, has_c && vary.c))
            .expect("every factor pair is a slot");
        let j = slots.iter().position(|&s| s == slot).expect("the slot is kept");
        for (c, &r0) in rho0.iter().enumerate() {
            let k = if has_rho && !vary.rho { r0 } else { 1.0 } * if has_c && !vary.c { c0 } else { 1.0 };
            if k == 0.0 {
                continue;
            }
            let d = &mut tabs[j];
            for (x, y) in d.a1[c].iter_mut().zip(&t.a1[c]) {
                *x += k * y;
            }
            for (x, y) in d.r[c].iter_mut().zip(&t.r[c]) {
                *x += k * y;
            }
            for (x, y) in d.r_avg[c].iter_mut().zip(&t.r_avg[c]) {
                *x += k * y;
            }
            d.rho_bar[c] += k * t.rho_bar[c];
        }
    }
    let keep: Vec<usize> = (0..slots.len()).filter(|&j| !tabs[j].is_zero()).collect();
    let flats = |f: &dyn Fn(&ComponentTables, usize) -> Vec<f64>| {
        keep.iter().flat_map(|&j| (0..3).map(move |c| (j, c))).map(|(j, c)| Flat::new(f(&tabs[j], c))).collect()
    };
    Folded {
        coefs: keep.iter().map(|&j| slots[j]).collect(),
        a1: flats(&|t, c| t.a1[c].clone()),
        r: flats(&|t, c| t.r[c].clone()),
        r_avg: flats(&|t, c| t.r_avg[c].clone()),
        rho_bar: keep.iter().map(|&j| tabs[j].rho_bar).collect(),
    }
}

/// The mean escape probability `e` per coat and the mean crossing transmittance `τ̄` (as
/// `coated_paint::layer_tables`).
fn escape_and_tau(coats: &[Coat]) -> (Vec<f64>, [f64; 3]) {
    let quad = 512;
    let mut escape = vec![0.0; coats.len()];
    let mut tau = [0.0; 3];
    for k in 0..quad {
        let mu = (k as f64 + 0.5) / quad as f64;
        let w = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let weight = 2.0 * mu / quad as f64;
        for (e, coat) in escape.iter_mut().zip(coats) {
            if let Some(out) = coat.refract_out(w) {
                *e += weight * coat.transmittance(out.z);
            }
        }
        let a = coats[0].attenuation(mu);
        for c in 0..3 {
            tau[c] += weight * a[c];
        }
    }
    (escape, tau)
}

/// `A1(μ)` and `U(μ) − A1(μ)` of basecoat components under each coat, their cosine
/// averages and each component's mean albedo `ρ̄` (the estimators of
/// `coated_paint::layer_tables`, the component's own sampler, seen through each coat's
/// transmission blur; `ρ̄` without it, as the material's). The coats differ only in roughness:
/// a component without specular lobes (the pigment, which the blur leaves alone) draws its
/// samples once for all of them. The `μ` nodes run on the rayon pool.
///
/// The components of `group` share one sampler: they have the same lobes with the same
/// roughness and differ only in reflectance (the metal base's `F0 = 1` and `F0 = 0`, the
/// metallic and the pearl flakes), so the first one's directions and density serve all of them
/// and each evaluates only its own BRDF at them (test
/// `shared_samples_give_each_component_its_own_tables`).
fn component_tables(coats: &[Coat], group: &[&Basecoat]) -> Vec<ComponentTables> {
    use rayon::prelude::*;
    let n = SAMPLES;
    let coat = &coats[0];
    let points: Vec<[f64; 3]> = (0..n).map(|k| super::hammersley3(k, n)).collect();
    let bare: Vec<Basecoat> = group.iter().map(|b| (*b).clone().with_blur(None)).collect();
    let na = coats.len();
    let (first, nm) = (group[0], group.len());
    let specular = first.metal.is_some() || first.flakes.is_some();
    let flakes = first.flakes.is_some();
    // The basecoats each coat sees (one for all when nothing of them blurs), member major.
    let bases: Vec<Vec<Basecoat>> = bare
        .iter()
        .map(|b| {
            if specular {
                coats.iter().map(|cj| b.clone().with_blur(cj.transmission_blur())).collect()
            } else {
                vec![b.clone()]
            }
        })
        .collect();
    // Per μ node: (A1, U − A1) per member and coat (member major).
    let per_node: Vec<Vec<([f64; 3], [f64; 3])>> = (0..NODES)
        .into_par_iter()
        .map(|k| {
            let mu = (k as f64 / (NODES - 1) as f64).max(1e-4);
            let w = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let w_in = coat.refract_in(w);
            let a_w = coat.attenuation(w_in.z);
            let mut up = vec![[0.0; 3]; nm * na];
            let mut out = vec![[0.0; 3]; nm * na];
            for b in 0..bases[0].len() {
                // The coats whose light this basecoat's samples carry.
                let js = if specular { b..b + 1 } else { 0..na };
                let driver = &bases[0][b];
                for u in &points {
                    // `Basecoat::sample_by(w_in, u, FlakeSampler::Visible)` of the first member,
                    // its direction and density shared.
                    let (wi, valid) =
                        driver.sample_direction_parts_by(w_in, *u, true, BaseParts::ALL, FlakeSampler::Visible);
                    if !valid || wi.z <= 0.0 {
                        continue;
                    }
                    let pdf = driver.pdf_parts_by(wi, w_in, BaseParts::ALL, FlakeSampler::Visible);
                    let a_v = coat.attenuation(wi.z);
                    let exit = coat.refract_out(wi);
                    for (m, member) in bases.iter().enumerate() {
                        let Some(s) = BsdfSample::from_eval(wi, member[b].eval(wi, w_in), pdf) else { continue };
                        for j in js.clone() {
                            let (up, out) = (&mut up[m * na + j], &mut out[m * na + j]);
                            for c in 0..3 {
                                up[c] += s.weight[c] * a_v[c];
                            }
                            if let Some(v) = exit {
                                // The flakes leave with the crossing factor, the pigment and
                                // the metal base with `T` (`Coat::crossing`); under a rough
                                // coat the flakes' first bounce is their lobe at their map of
                                // the outside directions (`Coat::flake_refract_in`; the change
                                // of variables of `coated_paint::base_sample_terms`).
                                let cj = &coats[j];
                                let (esc, sent) = if flakes {
                                    let sent = if cj.has_crossing() {
                                        member[b].eval(cj.flake_refract_in(v), cj.flake_refract_in(w)) * (wi.z / pdf)
                                    } else {
                                        s.weight
                                    };
                                    (cj.crossing(v.z), sent)
                                } else {
                                    (cj.transmittance(v.z), s.weight)
                                };
                                for c in 0..3 {
                                    out[c] += sent[c] * a_v[c] * esc;
                                }
                            }
                        }
                    }
                }
            }
            let norm = n as f64;
            (0..nm * na)
                .map(|i| {
                    let cj = &coats[i % na];
                    let (o, up) = (&out[i], &up[i]);
                    let t_w = cj.transmittance(mu);
                    let g_w = if flakes { cj.crossing(mu) } else { t_w };
                    let a1: [f64; 3] = [0, 1, 2].map(|c| g_w * a_w[c] * o[c] / norm);
                    let u: [f64; 3] = [0, 1, 2].map(|c| t_w * a_w[c] * up[c] / norm);
                    (a1, [0, 1, 2].map(|c| u[c] - a1[c]))
                })
                .collect()
        })
        .collect();
    bare.iter()
        .enumerate()
        .map(|(m, b)| {
            let mut t = ComponentTables::zero(na);
            t.rho_bar = super::coated_paint::mean_albedo(b, super::coated_paint::MEAN_ALBEDO_SAMPLES);
            for j in 0..na {
                let i = m * na + j;
                let rest: Vec<[f64; 3]> = (0..NODES).map(|k| per_node[k][i].1).collect();
                let avg = MuTable::from_values(rest).cosine_average();
                for (c, &a) in avg.iter().enumerate() {
                    t.r_avg[c][j] = a;
                    for (k, node) in per_node.iter().enumerate() {
                        t.a1[c][j * NODES + k] = node[i].0[c];
                        t.r[c][j * NODES + k] = node[i].1[c];
                    }
                }
            }
            t
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::Model;
    use crate::Material;

    /// [`component_tables`] of a group that shares one sampler equals each member's tables
    /// from its own samples: the metal base with `F0 = 1` and `F0 = 0`, and the metallic and
    /// pearl flakes of a pearl paint (their own flake α and thin-film table), under a smooth
    /// and two rough coats (the blur makes each coat's basecoat different). The same
    /// directions are drawn; only the density differs by rounding (the selection weight
    /// divides out), so the tables agree to rounding: measured ≤ 3.6e-16 relative to the
    /// largest value; asserted 1e-12.
    #[test]
    fn shared_samples_give_each_component_its_own_tables() {
        let paint = match Material::from_json(
            r#"{"model": "coated_paint", "flake_density": 5, "pearl_density": 10, "pearl_film_nm": 300}"#,
        )
        .unwrap()
        .model()
        {
            Model::CoatedPaint(p) => p.clone(),
            _ => unreachable!(),
        };
        let flakes = paint.basecoat().flakes.clone().unwrap();
        let coats: Vec<Coat> = [0.0, 0.1, 0.3].iter().map(|&a| Coat::new(1.5, a, 30.0, [0.0; 3])).collect();
        let only = |f: Option<FlakeLayer>, m: Option<MetalBase>| Basecoat::new([0.0; 3], 0.0, 0.0, None, m, f);
        let metal = |f0: f64| MetalBase { alpha: 0.05, f0: [f0; 3], weight: 1.0 };
        let metallic_flakes = FlakeLayer { pearl_coverage: 0.0, pearl_reflectance: None, ..flakes.clone() };
        let pearl_flakes = FlakeLayer { metallic_coverage: 0.0, ..flakes };
        for pair in [
            [only(None, Some(metal(1.0))), only(None, Some(metal(0.0)))],
            [only(Some(metallic_flakes), None), only(Some(pearl_flakes), None)],
        ] {
            let shared = component_tables(&coats, &[&pair[0], &pair[1]]);
            let mut worst = 0.0f64;
            for (member, got) in pair.iter().zip(&shared) {
                let want = &component_tables(&coats, &[member])[0];
                let scale = want.a1.iter().chain(&want.r).flatten().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(scale > 1e-3, "{scale}");
                for (g, w) in
                    got.a1.iter().chain(&got.r).chain(&got.r_avg).zip(want.a1.iter().chain(&want.r).chain(&want.r_avg))
                {
                    for (x, y) in g.iter().zip(w) {
                        worst = worst.max((x - y).abs() / scale);
                    }
                }
                assert_eq!(got.rho_bar, want.rho_bar);
            }
            eprintln!("shared vs own samples: {worst:.2e}");
            assert!(worst < 1e-12, "{worst:e}");
        }
    }
}
