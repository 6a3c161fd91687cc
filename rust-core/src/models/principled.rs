//! Principled: a reference model of the Principled BSDF of Blender 4.2+ as Cycles renders it,
//! the opaque subset — a Lambertian diffuse base under a dielectric GGX specular layer (with
//! an optional thin film), mixed with a GGX conductor (F82-tint Fresnel) by `metallic`, under an
//! optional GGX dielectric coat with a tint. Parameter names are Blender's socket names in
//! snake case, with Blender's defaults.
//!
//! | parameter | kind | default | range | unit | meaning (Blender socket) |
//! |---|---|---|---|---|---|
//! | `base_color` | colour | 0.8 | [0, 1] | | Base Color: diffuse albedo; F0 of the metal |
//! | `metallic` | scalar | 0 | [0, 1] | | Metallic: mix between the dielectric base and the metal |
//! | `roughness` | scalar | 0.5 | [0, 1] | | Roughness: GGX `α = roughness²` of specular and metal |
//! | `ior` | scalar | 1.5 | [1, 4] | | IOR of the specular layer |
//! | `specular_ior_level` | scalar | 0.5 | [0, 1] | | Specular IOR Level: scales F0 by `2·level` (0.5 = physical) |
//! | `specular_tint` | colour | 1 | [0, 1] | | Specular Tint: F0 tint (dielectric), F82 tint (metal) |
//! | `coat_weight` | scalar | 0 | [0, 1] | | Coat Weight |
//! | `coat_roughness` | scalar | 0.03 | [0, 1] | | Coat Roughness: GGX `α = coat_roughness²` |
//! | `coat_ior` | scalar | 1.5 | [1, 4] | | Coat IOR |
//! | `coat_tint` | colour | 1 | [0, 1] | | Coat Tint: transmittance of the coat at normal incidence |
//! | `thin_film_thickness` | scalar | 0 | [0, 100000] | nm | Thin Film Thickness (on the specular layer) |
//! | `thin_film_ior` | scalar | 1.33 | [1, 3] | | Thin Film IOR |
//!
//! ## The model (as Cycles builds the closure, `intern/cycles/kernel/svm/closure.h`)
//! The lobes are stacked top-down with a weight `w` (RGB, starting at 1) that each layer
//! attenuates for those below, all evaluated at the viewing direction `wo`:
//! 1. **Coat** (if `coat_weight > 0`): `coat_weight · f_ggx(α_c, F_dielectric(coat_ior))`; then
//!    `w ← w·(1 − coat_weight·A_coat(wo))` and, for a tint, `w ← w·mix(1, tint^(1/cos θt),
//!    coat_weight)` with `θt` the refracted viewing angle (Beer's law normalised at normal
//!    incidence).
//! 2. **Metal** (if `metallic > 0`): `metallic·w·f_ggx(α, F82(base_color, specular_tint))`;
//!    then `w ← w·(1 − metallic)`.
//! 3. **Specular** (if its IOR is not 1 or there is a film): `w·f_ggx(α, F_s)` where `F_s` is
//!    Cycles' generalised Schlick with the real dielectric curve: `F0 = F0(ior)·2·level`,
//!    `η = ior_from_F0(F0)` and `F_s = mix(F0·tint, 1, s)`, `s = (F(η) − F0(η))/(1 − F0(η))`;
//!    with a film, the Airy reflectance of the film (ambient index 1, substrate `η`) rescaled
//!    per channel toward `F0·tint/F0(η)` as Cycles does. Then `w ← w·(1 − max_c A_spec,c(wo))`.
//! 4. **Diffuse**: `w·base_color/π` (Lambert, which Cycles 4.x uses for Principled).
//!
//! `f_ggx(α, F) = k(wo)·F(wi·h)·D(h)·G2(wi, wo)/(4 cos θi cos θo)` with the GGX distribution
//! and height-correlated Smith masking, and Cycles' "multiscatter GGX" energy preservation:
//! `k = 1 + F_ms·(1 − E(wo))/E(wo)`, `E` the albedo of the lobe with `F = 1` and
//! `F_ms = F_avg·E_avg/(1 − F_avg(1 − E_avg))` per channel. `A(wo)` is a lobe's directional
//! albedo. A lobe with `α² ≤ 10⁻⁷` is a mirror (delta), as Cycles treats it.
//!
//! ## Matches Cycles / approximates Cycles
//! - Same structure, formulas and order of the layers (above); same F82-tint, generalised
//!   Schlick, IOR-level remapping, coat tint path length and energy-preservation formula;
//!   Blender's defaults (Principled's default distribution is multiscatter GGX; the `GGX`
//!   choice, without energy preservation, is not offered).
//! - Cycles reads `E`, `E_avg` and its layering albedo estimates from small precomputed
//!   tables (32² for `E`, 16³ for the Fresnel-weighted estimates; the thin film and F82 term
//!   fall back to `F(cos θo)`), and `F_avg` from fits. Here every one of them is computed
//!   for the material's own roughness and Fresnel curve: `E` and the Fresnel-weighted lobe
//!   albedos `∫ F D G/(4 cos θo) dωi` are tabulated over `cos θo` by quadrature
//!   ([`crate::energy_compensation::AlbedoTable`], ~5·10⁻⁴) and `F_avg` integrated per
//!   channel. So the layering is energy-exact where Cycles' is approximate: a white base under
//!   any coat and specular layer reflects all the light (white furnace), and the figures can
//!   differ from a Cycles render by Cycles' table errors (typically well below 1 %).
//! - The thin film's Airy reflectance is integrated against the colour-matching functions
//!   analytically (Belcour & Barla 2017, [`crate::paint::thin_film::ThinFilm::belcour_barla_rgb`],
//!   every order) and tabulated over 64 angles; Cycles sums three orders with its own
//!   sensitivity table. Films under 1 nm blend the film index toward 1 as Cycles does.
//! - Not modelled: the thin film on the metal (Blender 4.3+; here, as in 4.2, the film sits on
//!   the dielectric specular layer only), anisotropy, sheen, subsurface, transmission, alpha,
//!   emission, normal maps, and Cycles' shading-normal corrections.
//!
//! ## Claims
//! Not reciprocal: like Cycles, every layer weight and energy scale is evaluated at `wo`
//! only (albedo scaling), so `f(wi, wo) ≠ f(wo, wi)` whenever a coat, specular or metal layer
//! is present (the check reports by how much). Energy conserving: each lobe's albedo is at
//! most one (`F ≤ 1`, `F_ms ≤ 1`) and each layer passes down at most `1 − (its albedo)`.
//! Sampled.
//!
//! ## Sampling
//! `u[0]` picks the coat, metal, specular or diffuse lobe in proportion to its albedo at `wo`
//! (times its layer weight), tabulated over `cos θo` when the material is built (64 nodes,
//! linear interpolation) so that the pdf does not redo the layer computation; GGX lobes sample
//! visible normals (Dupuy & Benyoub 2023), the diffuse lobe the cosine. The pdf is the
//! mixture with the same probabilities. Mirror lobes (`α² ≤ 10⁻⁷`) are one delta
//! component: their summed reflectance at the mirror direction, with the summed probability.
//!
//! ## References
//! Blender 4.2 manual, "Principled BSDF"; Cycles `kernel/svm/closure.h`,
//! `kernel/closure/bsdf_microfacet.h`, `bsdf_util.h` (read to learn the formulas); Kutz et
//! al. 2021 (F82-tint, "Novel aspects of the Adobe Standard Material"); Kulla & Conty 2017
//! (energy compensation); Walter et al. 2007 and Heitz 2014 (GGX, Smith masking); Belcour &
//! Barla 2017 (thin-film iridescence).

use crate::bxdf::{Claims, LaneBxdf, LaneSample, ModelInfo};
use crate::energy_compensation::{fresnel_average, AlbedoTable, TableRequest, WeightKey};
use crate::error::Error;
use crate::frame::{half_vector_masked, mirror_z};
use crate::lanes::{self, Lanes, Mask};
use crate::fresnel;
use crate::math::{Rgb, Vec3};
use crate::microfacet::{DistributionKind, MaskingKind, Microfacet};
use crate::models::Model;
use crate::paint::thin_film::ThinFilm;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::table::MuTable;
use std::sync::Arc;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("base_color", [0.8; 3], 0.0, 1.0, "Base Color: diffuse albedo, and F0 of the metal"),
    ParamSpec::scalar("metallic", 0.0, 0.0, 1.0, "", "Metallic: mix between the dielectric base and the metal"),
    ParamSpec::scalar("roughness", 0.5, 0.0, 1.0, "", "Roughness: GGX α = roughness² of specular and metal"),
    ParamSpec::scalar("ior", 1.5, 1.0, 4.0, "", "IOR of the specular layer"),
    ParamSpec::scalar(
        "specular_ior_level",
        0.5,
        0.0,
        1.0,
        "",
        "Specular IOR Level: scales the specular F0 by 2·level (0.5 = physical)",
    ),
    ParamSpec::color(
        "specular_tint",
        [1.0; 3],
        0.0,
        1.0,
        "Specular Tint: F0 tint of the dielectric, F82 tint of the metal",
    ),
    ParamSpec::scalar("coat_weight", 0.0, 0.0, 1.0, "", "Coat Weight"),
    ParamSpec::scalar("coat_roughness", 0.03, 0.0, 1.0, "", "Coat Roughness: GGX α = coat_roughness²"),
    ParamSpec::scalar("coat_ior", 1.5, 1.0, 4.0, "", "Coat IOR"),
    ParamSpec::color("coat_tint", [1.0; 3], 0.0, 1.0, "Coat Tint: coat transmittance at normal incidence"),
    ParamSpec::scalar(
        "thin_film_thickness",
        0.0,
        0.0,
        100_000.0,
        "nm",
        "Thin Film Thickness on the specular layer (0 = no film)",
    ),
    ParamSpec::scalar("thin_film_ior", 1.33, 1.0, 3.0, "", "Thin Film IOR"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "principled",
    summary: "Blender 4.2+ Cycles Principled BSDF, opaque subset (diffuse, specular, F82 metal, coat, thin film)",
    reference: "Blender 4.2 Principled BSDF (Cycles kernel/svm/closure.h); Kutz et al. 2021 (F82-tint); \
                Kulla & Conty 2017; Belcour & Barla 2017",
    params: PARAMS,
    claims: Claims { reciprocal: false, energy_conserving: true, sampled: true },
    check_params: &[
        r#"{"metallic": 1, "roughness": 0.55, "base_color": [0.95, 0.64, 0.54], "specular_tint": [0.9, 0.5, 0.3]}"#,
        r#"{"base_color": 1.0, "coat_weight": 1, "coat_roughness": 0.45, "roughness": 0.4}"#,
        r#"{"roughness": 0.45, "metallic": 0.3, "base_color": [0.1, 0.2, 0.6], "thin_film_thickness": 350, "thin_film_ior": 1.6, "coat_weight": 0.5, "coat_roughness": 0.5, "coat_tint": [0.8, 0.9, 1.0]}"#,
        r#"{"roughness": 0, "metallic": 0.5, "base_color": [0.8, 0.2, 0.1], "coat_weight": 1, "coat_roughness": 0}"#,
    ],
    build,
};

/// Cycles' `CLOSURE_WEIGHT_CUTOFF`: lobes with a smaller weight are not created.
const WEIGHT_CUTOFF: f64 = 1e-5;
/// Cycles' `BSDF_ROUGHNESS_SQ_THRESH`: a lobe with `α² ≤` this is a mirror.
const SINGULAR_ALPHA2: f64 = 1e-7;
/// Films thinner than this (nm) are no film (Cycles' `THINFILM_THICKNESS_CUTOFF`).
const THIN_FILM_CUTOFF_NM: f64 = 0.1;
/// Angles of the thin-film reflectance table.
const FILM_NODES: usize = 64;
/// Nodes (uniform in `cos θo`) of the lobe-selection table ([`Principled::selection`]).
const SELECTION_NODES: usize = 64;

fn build(p: &Params) -> Result<Model, Error> {
    let inputs = Inputs {
        base_color: p.color("base_color"),
        metallic: p.scalar("metallic"),
        roughness: p.scalar("roughness"),
        ior: p.scalar("ior"),
        specular_ior_level: p.scalar("specular_ior_level"),
        specular_tint: p.color("specular_tint"),
        coat_weight: p.scalar("coat_weight"),
        coat_roughness: p.scalar("coat_roughness"),
        coat_ior: p.scalar("coat_ior"),
        coat_tint: p.color("coat_tint"),
        thin_film_thickness: p.scalar("thin_film_thickness"),
        thin_film_ior: p.scalar("thin_film_ior"),
    };
    Ok(Model::Principled(Principled::new(&inputs)))
}

/// The Principled BSDF inputs this model reads, in Blender's units (see the module table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inputs {
    /// Base Color.
    pub base_color: [f64; 3],
    /// Metallic.
    pub metallic: f64,
    /// Roughness (`α = roughness²`).
    pub roughness: f64,
    /// IOR.
    pub ior: f64,
    /// Specular IOR Level.
    pub specular_ior_level: f64,
    /// Specular Tint.
    pub specular_tint: [f64; 3],
    /// Coat Weight.
    pub coat_weight: f64,
    /// Coat Roughness (`α = coat_roughness²`).
    pub coat_roughness: f64,
    /// Coat IOR.
    pub coat_ior: f64,
    /// Coat Tint.
    pub coat_tint: [f64; 3],
    /// Thin Film Thickness in nm.
    pub thin_film_thickness: f64,
    /// Thin Film IOR.
    pub thin_film_ior: f64,
}

impl Default for Inputs {
    /// Blender's defaults.
    fn default() -> Self {
        Self {
            base_color: [0.8; 3],
            metallic: 0.0,
            roughness: 0.5,
            ior: 1.5,
            specular_ior_level: 0.5,
            specular_tint: [1.0; 3],
            coat_weight: 0.0,
            coat_roughness: 0.03,
            coat_ior: 1.5,
            coat_tint: [1.0; 3],
            thin_film_thickness: 0.0,
            thin_film_ior: 1.33,
        }
    }
}

impl Inputs {
    /// The material JSON of these inputs (`{"model": "principled", ...}`, every parameter).
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "model": "principled",
            "base_color": self.base_color,
            "metallic": self.metallic,
            "roughness": self.roughness,
            "ior": self.ior,
            "specular_ior_level": self.specular_ior_level,
            "specular_tint": self.specular_tint,
            "coat_weight": self.coat_weight,
            "coat_roughness": self.coat_roughness,
            "coat_ior": self.coat_ior,
            "coat_tint": self.coat_tint,
            "thin_film_thickness": self.thin_film_thickness,
            "thin_film_ior": self.thin_film_ior,
        })
    }
}

/// The Fresnel curve of one lobe.
#[derive(Clone, Debug)]
enum Fresnel {
    /// Exact dielectric Fresnel of relative index `eta` (the coat).
    Dielectric { eta: f64 },
    /// F82-tint per channel (the metal).
    F82 { f0: [f64; 3], b: [f64; 3] },
    /// Cycles' generalised Schlick with the real dielectric curve remapped onto `[f0, 1]`.
    Remapped { eta: f64, f0_real: f64, f0: [f64; 3] },
    /// The thin film's tabulated RGB curve, with the film thickness, index and substrate
    /// index and the tinted F0 that made it (the keys of its shared albedo tables).
    Film { table: MuTable, key: [f64; 3], f0: [f64; 3] },
}

impl Fresnel {
    /// The RGB reflectance at `cos` (clamped to `[0, 1]`), per lane.
    #[inline(always)]
    fn eval<L: Lanes>(&self, cos: L) -> Rgb<L> {
        let cos = lanes::clamp(cos, L::c(0.0), L::c(1.0));
        match self {
            Fresnel::Dielectric { eta } => Rgb::splat(fresnel::dielectric(cos, L::c(*eta))),
            Fresnel::F82 { f0, b } => Rgb::new(
                fresnel::f82(cos, L::c(f0[0]), L::c(b[0])),
                fresnel::f82(cos, L::c(f0[1]), L::c(b[1])),
                fresnel::f82(cos, L::c(f0[2]), L::c(b[2])),
            ),
            Fresnel::Remapped { eta, f0_real, f0 } => {
                let s = remap(fresnel::dielectric(cos, L::c(*eta)), *f0_real);
                Rgb::from_array(*f0).map(|f| f + (L::c(1.0) - f) * s)
            }
            Fresnel::Film { table, .. } => {
                let [r, g, b] = table.eval_lanes(cos);
                Rgb::new(r, g, b)
            }
        }
    }

    /// One channel in f64 (for the tables).
    fn channel(&self, c: usize, cos: f64) -> f64 {
        self.eval(cos).to_array()[c]
    }
}

/// Cycles' remap of the real dielectric curve: `saturate((F − F0)/(1 − F0))`.
#[inline(always)]
fn remap<L: Lanes>(f: L, f0_real: f64) -> L {
    if !(f0_real < 1.0) {
        return L::c(0.0);
    }
    // The reciprocal in f64, once: a multiplication per lane instead of a division.
    lanes::clamp((f - L::c(f0_real)) * L::c(1.0 / (1.0 - f0_real)), L::c(0.0), L::c(1.0))
}

/// The tabulated albedos of a rough lobe.
#[derive(Clone, Debug)]
struct LobeAlbedo {
    /// `1 − E` with `F = 1`.
    e: Arc<AlbedoTable>,
    /// The Fresnel-weighted single-scattering albedo per channel as `Σ coef_c · E_w(μ)`.
    terms: Vec<(Arc<AlbedoTable>, [f64; 3])>,
    /// Cycles' `F_ms = F_avg E_avg / (1 − F_avg (1 − E_avg))` per channel.
    f_ms: [f64; 3],
}

/// A Fresnel-like weight of an albedo table.
type Weight<'a> = Box<dyn Fn(f64) -> f64 + 'a>;

/// One table request per channel of `f` (for curves not linear in the colour inputs), keyed
/// by `names[c]` and `key(c)`, each contributing to its own channel.
fn channel_requests<'a>(
    f: &'a Fresnel,
    names: [&'static str; 3],
    key: impl Fn(usize) -> Vec<f64>,
) -> Vec<(Option<WeightKey>, Weight<'a>, [f64; 3])> {
    (0..3)
        .map(|c| {
            let mut unit = [0.0; 3];
            unit[c] = 1.0;
            let w: Weight<'a> = Box::new(move |cos| f.channel(c, cos));
            (Some(WeightKey::new(names[c], &key(c))), w, unit)
        })
        .collect()
}

/// One GGX reflection lobe (isotropic), or a mirror.
#[derive(Clone, Debug)]
struct Lobe {
    alpha: f64,
    fresnel: Fresnel,
    /// `None` for a mirror.
    albedo: Option<LobeAlbedo>,
}

const GGX: DistributionKind = DistributionKind::Ggx;
const HEIGHT_CORRELATED: MaskingKind = MaskingKind::HeightCorrelated;

impl Lobe {
    fn new(alpha: f64, fresnel: Fresnel) -> Self {
        if alpha * alpha <= SINGULAR_ALPHA2 {
            return Self { alpha: 0.0, fresnel, albedo: None };
        }
        // The tables this lobe needs: `E` first (key `None`), then the Fresnel-weighted ones
        // with the coefficients that combine them into each channel's albedo. Missing tables
        // are computed together in one quadrature pass per four.
        let mut requests: Vec<(Option<WeightKey>, Weight<'_>, [f64; 3])> = vec![(None, Box::new(|_| 1.0), [0.0; 3])];
        match &fresnel {
            Fresnel::Dielectric { eta } => {
                let eta = *eta;
                let w: Weight<'_> = Box::new(move |c| fresnel::dielectric(c, eta));
                requests.push((Some(WeightKey::new("dielectric", &[eta])), w, [1.0; 3]));
            }
            Fresnel::Remapped { eta, f0_real, f0 } => {
                // F = F0·1 + (1 − F0)·s(cos): the plain table and one shared weighted table.
                let (eta, f0_real) = (*eta, *f0_real);
                requests[0].2 = *f0;
                let w: Weight<'_> = Box::new(move |c| remap(fresnel::dielectric(c, eta), f0_real));
                requests.push((Some(WeightKey::new("cycles_dielectric_remap", &[eta])), w, f0.map(|v| 1.0 - v)));
            }
            Fresnel::F82 { f0, b } => {
                // F = F0·1 + (1 − F0)(1 − cos)⁵ − b·cos(1 − cos)⁶ is linear in F0 and b unless
                // the clamp to [0, 1] acts (strong tints): then one table per channel.
                let clamped = (0..3).any(|c| {
                    (0..=256).any(|i| {
                        let cos = f64::from(i) / 256.0;
                        let s = 1.0 - cos;
                        let raw = f0[c] + (1.0 - f0[c]) * s.powi(5) - b[c] * cos * s.powi(6);
                        !(0.0..=1.0).contains(&raw)
                    })
                });
                if clamped {
                requests.extend(channel_requests(&fresnel, ["f82_r", "f82_g", "f82_b"], |c| vec![f0[c], b[c]]));
                } else {
                    requests[0].2 = *f0;
                    let w: Weight<'_> = Box::new(|c| (1.0 - c).powi(5));
                    requests.push((Some(WeightKey::new("schlick5", &[])), w, f0.map(|v| 1.0 - v)));
                    if b.iter().any(|&v| v != 0.0) {
                        let w: Weight<'_> = Box::new(|c| c * (1.0 - c).powi(6));
                        requests.push((Some(WeightKey::new("f82_dip", &[])), w, b.map(|v| -v)));
                    }
                }
            }
            Fresnel::Film { key, f0, .. } => {
                requests.extend(channel_requests(&fresnel, ["film_r", "film_g", "film_b"], |c| {
                    vec![key[0], key[1], key[2], f0[c]]
                }));
            }
        }
        let asks: Vec<TableRequest<'_>> =
            requests.iter().map(|(k, w, _)| (*k, w.as_ref() as &dyn Fn(f64) -> f64)).collect();
        let tables = AlbedoTable::cached_set(GGX, HEIGHT_CORRELATED, alpha, alpha, &asks);
        let e = Arc::clone(&tables[0]);
        let terms: Vec<(Arc<AlbedoTable>, [f64; 3])> = tables
            .into_iter()
            .zip(&requests)
            .filter(|(_, r)| r.2 != [0.0; 3])
            .map(|(t, r)| (t, r.2))
            .collect();
        drop(asks);
        drop(requests);
        // The lane lookups locate μ once per lobe (`AlbedoTable::cell_lanes`).
        assert!(terms.iter().all(|(t, _)| t.same_cells(&e)), "the tables of a lobe share their nodes");
        let e_avg = e.e_avg();
        let f_ms = std::array::from_fn(|c| {
            let f_avg = fresnel_average(|mu| fresnel.channel(c, mu));
            let d = 1.0 - f_avg * (1.0 - e_avg);
            if d > 0.0 {
                (f_avg * e_avg / d).clamp(0.0, 1.0)
            } else {
                0.0
            }
        });
        Self { alpha, fresnel, albedo: Some(LobeAlbedo { e, terms, f_ms }) }
    }

    #[inline(always)]
    fn microfacet<L: Lanes>(&self) -> Microfacet<L> {
        Microfacet::uniform(GGX, self.alpha, self.alpha)
    }

    /// The E table (`None` for a mirror): its cells serve every table of the lobe.
    fn grid(&self) -> Option<&AlbedoTable> {
        self.albedo.as_ref().map(|a| a.e.as_ref())
    }

    /// Directional albedo at `μo` including the energy scale (`F(μo)` for a mirror), and
    /// Cycles' energy scale `1 + F_ms (1 − E(μo))/E(μo)` per channel (1 for a mirror). `cell`
    /// is the cell of `μo` in the lobe's tables ([`AlbedoTable::cell_lanes`]).
    #[inline(always)]
    fn albedo_and_scale<L: Lanes>(&self, mu_o: L, cell: Option<(L, L)>) -> (Rgb<L>, Rgb<L>) {
        let (Some(a), Some(cell)) = (&self.albedo, cell) else {
            return (self.fresnel.eval(mu_o), Rgb::splat(L::c(1.0)));
        };
        let e_loss = a.e.loss_at_lanes(cell);
        let e = lanes::max(L::c(1.0) - e_loss, L::c(1e-4));
        let missing = (L::c(1.0) - e) / e;
        let scale = Rgb::from_array(a.f_ms).map(|f| L::c(1.0) + f * missing);
        let mut s = Rgb::zero();
        for (t, coef) in &a.terms {
            // The E table is usually one of the terms: its value is already known.
            let loss = if Arc::ptr_eq(t, &a.e) { e_loss } else { t.loss_at_lanes(cell) };
            s += Rgb::from_array(*coef) * (L::c(1.0) - loss);
        }
        (s.map(|v| lanes::clamp(v, L::c(0.0), L::c(1.0))) * scale, scale)
    }

    /// `D G2 / (4 cos θi cos θo)` of a rough lobe at the half vector `h`, and where the lobe
    /// is non-zero (`h` defined, `G2 > 0`, the value finite).
    #[inline(always)]
    fn shape<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, h: Vec3<L>, defined: L::Mask) -> (L, L::Mask) {
        let mf = self.microfacet::<L>();
        let (v, g_positive) = mf.reflection_dg(wi, wo, h, HEIGHT_CORRELATED);
        (v, defined & g_positive & lanes::is_finite(v))
    }
}

/// The Principled BSDF with its per-material tables.
#[derive(Clone, Debug)]
pub struct Principled {
    inputs: Inputs,
    coat: Option<Lobe>,
    metal: Option<Lobe>,
    spec: Option<Lobe>,
    /// The probabilities of picking the coat, metal and specular lobes per `cos θo`
    /// ([`Principled::selection`]).
    selection: MuTable,
    /// Whether the diffuse lobe has a positive selection weight at some `cos θo` (it takes
    /// what the three tabulated probabilities leave).
    diffuse_selectable: bool,
}

/// The layer weights at one viewing direction.
struct Layers<T> {
    /// Weight of each lobe (coat, metal, specular) times its energy scale: the factor of its
    /// single-scattering term.
    scaled: [Rgb<T>; 3],
    /// Reflectance of the mirror lobes at the mirror direction.
    delta: Rgb<T>,
    /// Weight of `base_color/π`.
    diffuse: Rgb<T>,
    /// Selection weights (the lobes' albedos times their weights): coat, metal, specular,
    /// diffuse. Read when the selection table is built ([`Principled::selection`]).
    select: [T; 4],
    /// Directional albedo of the whole stack.
    albedo: Rgb<T>,
}

impl Principled {
    /// Builds the lobes and their tables from Blender inputs (taken as valid).
    #[must_use]
    pub fn new(p: &Inputs) -> Self {
        let coat = (p.coat_weight > WEIGHT_CUTOFF && p.coat_ior != 1.0)
            .then(|| Lobe::new(p.coat_roughness.sqr(), Fresnel::Dielectric { eta: p.coat_ior }));
        let alpha = p.roughness.sqr();
        let metal = (p.metallic > WEIGHT_CUTOFF).then(|| {
            let f0 = p.base_color.map(|c| c.clamp(0.0, 1.0));
            let b = std::array::from_fn(|c| fresnel::f82_tint_b(f0[c], p.specular_tint[c].min(1.0)));
            Lobe::new(alpha, Fresnel::F82 { f0, b })
        });
        // IOR level: F0 scaled by 2·level, the IOR recomputed from it.
        let mut eta = p.ior;
        let mut f0 = fresnel::dielectric_f0(p.ior);
        if p.specular_ior_level != 0.5 {
            f0 *= 2.0 * p.specular_ior_level;
            eta = fresnel::ior_from_f0(f0);
        }
        let film = p.thin_film_thickness > THIN_FILM_CUTOFF_NM;
        let spec = (1.0 - p.metallic > WEIGHT_CUTOFF && (eta != 1.0 || film)).then(|| {
            let f0_real = fresnel::dielectric_f0(eta);
            let f0_tinted = p.specular_tint.map(|t| (f0 * t).clamp(0.0, 1.0));
            let fresnel = if film {
                let (table, film_ior) = film_table(p.thin_film_thickness, p.thin_film_ior, eta, f0_real, f0_tinted);
                Fresnel::Film { table, key: [p.thin_film_thickness, film_ior, eta], f0: f0_tinted }
            } else {
                Fresnel::Remapped { eta, f0_real, f0: f0_tinted }
            };
            Lobe::new(alpha, fresnel)
        });
        if let (Some(m), Some(s)) = (metal.as_ref().and_then(Lobe::grid), spec.as_ref().and_then(Lobe::grid)) {
            // The lane lookups locate μ once for both base lobes (`Principled::cells`).
            assert!(m.same_cells(s), "metal and specular tables share their nodes");
        }
        let mut model = Self {
            inputs: *p,
            coat,
            metal,
            spec,
            selection: MuTable::from_values(vec![[0.0; 3]; 2]),
            diffuse_selectable: false,
        };
        model.tabulate_selection();
        model
    }

    /// Fills the lobe-selection table: the selection weights of [`Principled::layers`]
    /// normalised to probabilities at [`SELECTION_NODES`] values of `cos θo`.
    fn tabulate_selection(&mut self) {
        let mut diffuse = false;
        let nodes = (0..SELECTION_NODES)
            .map(|k| {
                // The batch calls never see `cos θo = 0`; the first node holds the weights just
                // above it.
                let mu = (k as f64 / (SELECTION_NODES - 1) as f64).max(1e-4);
                let s = self.layers::<f64>(mu).select;
                let total: f64 = s.iter().sum();
                diffuse |= s[3] > 0.0;
                if total > 0.0 && total.is_finite() {
                    [s[0] / total, s[1] / total, s[2] / total]
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        self.selection = MuTable::from_values(nodes);
        self.diffuse_selectable = diffuse;
    }

    /// The probabilities of picking the coat, metal, specular and diffuse lobe at
    /// `cos θo = mu_o`, which sampling and the density share: the lobes' selection weights
    /// (albedo times layer weight, [`Layers::select`]) normalised, tabulated over `cos θo` when
    /// the material is built and interpolated linearly. They sum to 1, or are all 0 for a
    /// material that reflects nothing. Any positive probabilities give an unbiased estimator
    /// as long as the sampler and the density agree; the table spares the density the layer
    /// computation (tables, energy scales, the coat's tint) at every call.
    #[inline(always)]
    fn selection<L: Lanes>(&self, mu_o: L) -> [L; 4] {
        let [coat, metal, spec] = self.selection.eval_lanes(mu_o);
        let zero = L::c(0.0);
        let diffuse =
            if self.diffuse_selectable { lanes::max(L::c(1.0) - coat - metal - spec, zero) } else { zero };
        [coat, metal, spec, diffuse]
    }

    /// The inputs this model was built from.
    #[must_use]
    pub fn inputs(&self) -> &Inputs {
        &self.inputs
    }

    /// Directional albedo `∫ f cos θi dωi` at `cos θo = mu_o`, from the layer tables.
    #[must_use]
    pub fn albedo(&self, mu_o: f64) -> [f64; 3] {
        self.layers(mu_o.clamp(1e-9, 1.0)).albedo.to_array()
    }

    fn lobes(&self) -> [Option<&Lobe>; 3] {
        [self.coat.as_ref(), self.metal.as_ref(), self.spec.as_ref()]
    }

    /// The cells of `μo` in the tables of the coat and of the base lobes (metal and specular
    /// share the roughness, hence the table nodes).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn cells<L: Lanes>(&self, mu_o: L) -> (Option<(L, L)>, Option<(L, L)>) {
        let coat = self.coat.as_ref().and_then(Lobe::grid).map(|t| t.cell_lanes(mu_o));
        let base = self.metal.as_ref().or(self.spec.as_ref()).and_then(Lobe::grid).map(|t| t.cell_lanes(mu_o));
        (coat, base)
    }

    /// The layer weights at `cos θo = mu_o` (see the module docs), per lane.
    #[inline(always)]
    fn layers<L: Lanes>(&self, mu_o: L) -> Layers<L> {
        let p = &self.inputs;
        let zero = L::c(0.0);
        let one = L::c(1.0);
        let mut l = Layers {
            scaled: [Rgb::zero(); 3],
            delta: Rgb::zero(),
            diffuse: Rgb::zero(),
            select: [zero; 4],
            albedo: Rgb::zero(),
        };
        let (coat_cell, base_cell) = self.cells(mu_o);
        let mut w = Rgb::splat(one);
        if p.coat_weight > WEIGHT_CUTOFF {
            let cw = L::c(p.coat_weight);
            if let Some(coat) = &self.coat {
                let albedo = l.add(0, coat, Rgb::splat(cw), mu_o, coat_cell);
                w *= lanes::clamp(one - cw * max_channel(albedo), zero, one);
            }
            if p.coat_tint != [1.0; 3] {
                // Beer's law along the refracted viewing direction, normalised at normal
                // incidence: tint^(1/cos θt), as e^(ln(tint)/cos θt).
                let inv = one / L::c(p.coat_ior);
                let cos_t = lanes::safe_sqrt(one - inv * inv * (one - mu_o * mu_o));
                let depth = one / cos_t;
                let t = p.coat_tint;
                w = w * Rgb::new(tinted(t[0], depth, cw), tinted(t[1], depth, cw), tinted(t[2], depth, cw));
            }
        }
        if let Some(metal) = &self.metal {
            let m = L::c(p.metallic);
            l.add(1, metal, w * m, mu_o, base_cell);
            w *= one - m;
        }
        if let Some(spec) = &self.spec {
            let albedo = l.add(2, spec, w, mu_o, base_cell);
            // Cycles: w · saturate(1 − max over the channels with w ≠ 0 of A_c).
            let mut m = zero;
            for (wc, ac) in [(w.r, albedo.r), (w.g, albedo.g), (w.b, albedo.b)] {
                m = lanes::select(lanes::gt(wc, zero), lanes::max(m, ac), m);
            }
            w *= lanes::clamp(one - m, zero, one);
        }
        let rho = w * Rgb::from_array(p.base_color);
        l.diffuse = w * L::c(std::f64::consts::FRAC_1_PI);
        l.select[3] = average(rho);
        l.albedo += rho;
        l
    }

    /// `f_r` with the layer weights of this `wo`.
    #[inline(always)]
    fn eval_with<L: Lanes>(&self, l: &Layers<L>, wi: Vec3<L>, wo: Vec3<L>) -> Rgb<L> {
        let (h, defined) = half_vector_masked(wi, wo);
        let mut f = l.diffuse * Rgb::from_array(self.inputs.base_color);
        // Metal and specular share the roughness: one D·G term for both.
        let base = self.metal.as_ref().or(self.spec.as_ref()).filter(|b| b.albedo.is_some());
        let base_shape = base.map(|b| b.shape(wi, wo, h, defined));
        let cos_ih = wi.dot(h);
        for (i, lobe) in self.lobes().into_iter().enumerate() {
            let Some(lobe) = lobe.filter(|lobe| lobe.albedo.is_some()) else { continue };
            let (v, ok) = match (i, base_shape) {
                (1 | 2, Some(s)) => s,
                _ => lobe.shape(wi, wo, h, defined),
            };
            f += l.scaled[i] * Rgb::select(ok, lobe.fresnel.eval(cos_ih) * v, Rgb::zero());
        }
        f
    }

    /// The sampling density with the lobe-selection probabilities `select` of this `wo`
    /// ([`Principled::selection`]).
    #[inline(always)]
    fn pdf_with<L: Lanes>(&self, select: &[L; 4], wi: Vec3<L>, wo: Vec3<L>) -> L {
        let zero = L::c(0.0);
        let mut p = select[3] * cosine_hemisphere_pdf(wi.z);
        let base = self.metal.as_ref().or(self.spec.as_ref()).filter(|b| b.albedo.is_some());
        let base_pdf = base.map(|b| b.microfacet::<L>().reflection_pdf(wi, wo, true));
        for (i, (lobe, &s)) in self.lobes().into_iter().zip(select).enumerate() {
            let Some(lobe) = lobe.filter(|lobe| lobe.albedo.is_some()) else { continue };
            let pdf = match (i, base_pdf) {
                (1 | 2, Some(pdf)) => pdf,
                _ => lobe.microfacet::<L>().reflection_pdf(wi, wo, true),
            };
            p += lanes::keep(lanes::gt(s, zero), s * pdf);
        }
        p
    }
}

impl<L: Lanes> Layers<L> {
    /// Records lobe `i` with layer weight `weight`; returns its albedo at `μo`.
    #[inline(always)]
    fn add(&mut self, i: usize, lobe: &Lobe, weight: Rgb<L>, mu_o: L, cell: Option<(L, L)>) -> Rgb<L> {
        let (albedo, scale) = lobe.albedo_and_scale(mu_o, cell);
        let a = weight * albedo;
        self.select[i] = average(a);
        self.albedo += a;
        if lobe.albedo.is_none() {
            self.delta += a;
        } else {
            self.scaled[i] = weight * scale;
        }
        albedo
    }
}

/// The coat's tint factor `1 − cw + cw·t^depth` of one channel (`t^depth` as `e^(depth ln t)`).
#[inline(always)]
fn tinted<L: Lanes>(t: f64, depth: L, cw: L) -> L {
    let tr = if t == 1.0 {
        L::c(1.0)
    } else if t > 0.0 {
        lanes::exp(depth * L::c(t.ln()))
    } else {
        L::c(0.0)
    };
    L::c(1.0) - cw + cw * tr
}

/// Mean of the three channels (as [`Rgb::average`]), per lane.
#[inline(always)]
fn average<L: Lanes>(c: Rgb<L>) -> L {
    (c.r + c.g + c.b) / L::c(3.0)
}

/// Largest channel (as [`Rgb::max_channel`]), per lane.
#[inline(always)]
fn max_channel<L: Lanes>(c: Rgb<L>) -> L {
    lanes::max(lanes::max(c.r, c.g), c.b)
}

/// The thin-film Fresnel curve of the specular layer (Cycles' iridescent generalised
/// Schlick): the Airy reflectance of the film in air over a substrate of index `eta`, each
/// channel then scaled toward `F0·tint/F0(η)` in proportion to how close it is to `F0(η)`.
fn film_table(thickness: f64, film_ior: f64, eta: f64, f0_real: f64, f0: [f64; 3]) -> (MuTable, f64) {
    // Below 1 nm the wave-optical model no longer applies: blend the film index toward the
    // ambient index (Cycles).
    let film_ior = if thickness < 1.0 {
        let t = thickness.clamp(0.0, 1.0);
        1.0 + (film_ior - 1.0) * t * t * (3.0 - 2.0 * t)
    } else {
        film_ior
    };
    let film = ThinFilm { thickness_nm: thickness, film_ior, substrate_ior: eta, medium_ior: 1.0 };
    let table = MuTable::build(FILM_NODES, |mu| {
        let mut f = film.belcour_barla_rgb(mu.max(1e-6));
        if f0_real > 1e-5 && f != [1.0; 3] {
            for c in 0..3 {
                let s = ((f[c] - 1.0) / (f0_real - 1.0)).clamp(0.0, 1.0);
                f[c] *= 1.0 + (f0[c] / f0_real - 1.0) * s;
            }
        }
        f.map(|v| v.clamp(0.0, 1.0))
    });
    (table, film_ior)
}

impl LaneBxdf for Principled {
    #[inline(always)]
    fn eval_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> Rgb<L> {
        self.eval_with(&self.layers(wo.z), wi, wo)
    }

    #[inline(always)]
    fn pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> L {
        self.pdf_with(&self.selection(wo.z), wi, wo)
    }

    #[inline(always)]
    fn sample_lanes<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3]) -> LaneSample<L> {
        let zero = L::c(0.0);
        let none = L::Mask::splat(false);
        let l = self.layers(wo.z);
        let select = self.selection(wo.z);
        // The lobe u[0] picks in proportion to the selection probabilities (as `pick_lobe`):
        // the first positive one whose cumulative sum passes u[0]·total, the diffuse lobe
        // last; past the end by rounding, the last positive one.
        let total = select.iter().fold(zero, |a, &b| a + b);
        let target = u[0] * total;
        let mut acc = zero;
        let mut done = none;
        let mut chosen = [none; 4];
        for (i, (c, &w)) in chosen.iter_mut().zip(&select).enumerate() {
            let positive = lanes::gt(w, zero);
            let hit = if i == 3 { positive } else { positive & lanes::lt(target, acc + w) };
            *c = hit & !done;
            done = done | hit;
            acc += w;
        }
        let mut later = none;
        for (c, &w) in chosen.iter_mut().zip(&select).rev() {
            let positive = lanes::gt(w, zero);
            *c = *c | (!done & positive & !later);
            later = later | positive;
        }
        let picked = lanes::gt(total, zero);
        let lobes = self.lobes();
        let rough = |i: usize| lobes[i].is_some_and(|lobe| lobe.albedo.is_some());
        let mirror = |i: usize| lobes[i].is_some_and(|lobe| lobe.albedo.is_none());

        // Rough lobes: visible normals of the coat's or the base's roughness.
        let diffuse_wi = cosine_hemisphere(u[1], u[2]);
        let base_alpha = self.metal.as_ref().or(self.spec.as_ref()).map_or(0.0, |b| b.alpha);
        let coat_alpha = self.coat.as_ref().map_or(0.0, |c| c.alpha);
        let alpha = match (rough(0), rough(1) || rough(2)) {
            (true, true) => Some(lanes::select(chosen[0], L::c(coat_alpha), L::c(base_alpha))),
            (true, false) => Some(L::c(coat_alpha)),
            (false, true) => Some(L::c(base_alpha)),
            (false, false) => None,
        };
        let (wi, smooth_ok) = match alpha {
            Some(a) => {
                let (spec_wi, spec_ok) = Microfacet::new(GGX, a, a).sample_reflection_masked(wo, u[1], u[2], true);
                (Vec3::select(chosen[3], diffuse_wi, spec_wi), chosen[3] | spec_ok)
            }
            None => (diffuse_wi, chosen[3]),
        };
        let valid = picked & smooth_ok & lanes::gt(wi.z, zero);
        let s = LaneSample::from_eval(wi, self.eval_with(&l, wi, wo), self.pdf_with(&select, wi, wo), valid);
        if !(0..3).any(mirror) {
            return s;
        }
        // The mirror lobes, together: one delta component.
        let mut delta = none;
        let mut p = zero;
        for (i, (&c, &w)) in chosen.iter().zip(&select).enumerate().take(3) {
            if mirror(i) {
                delta = delta | c;
                p += w;
            }
        }
        let weight = l.delta / p;
        let finite = lanes::is_finite(weight.r) & lanes::is_finite(weight.g) & lanes::is_finite(weight.b);
        let delta_ok = picked & lanes::gt(p, zero) & finite;
        LaneSample {
            wi: Vec3::select(delta, mirror_z(wo), s.wi),
            weight: Rgb::select(delta, weight, s.weight),
            pdf: lanes::select(delta, p, s.pdf),
            valid: (delta & delta_ok) | (!delta & s.valid),
            delta,
        }
    }
}

crate::bxdf_from_lanes!(Principled);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bxdf::Bxdf;
    use crate::Material;

    fn principled(json: &str) -> Principled {
        match Material::from_json(json).unwrap().model() {
            Model::Principled(p) => p.clone(),
            _ => unreachable!(),
        }
    }

    fn dir(cos: f64, phi: f64) -> Vec3<f64> {
        let s = (1.0 - cos * cos).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), cos)
    }

    /// A white Lambert base (no specular: IOR level 0) is exactly `1/π`.
    #[test]
    fn white_lambert_base_is_one_over_pi() {
        let p = principled(r#"{"model": "principled", "base_color": 1.0, "specular_ior_level": 0}"#);
        let f = p.eval(dir(0.6, 0.3), dir(0.9, 2.0));
        for c in 0..3 {
            assert!((f[c] - std::f64::consts::FRAC_1_PI).abs() < 1e-15, "{f:?}");
        }
    }

    /// Metallic 1, roughness 0 is a mirror whose reflectance at normal incidence is the base
    /// colour (F82-tint at cos = 1 is F0).
    #[test]
    fn smooth_metal_reflects_its_base_colour_at_normal_incidence() {
        let p = principled(r#"{"model": "principled", "metallic": 1, "roughness": 0, "base_color": [0.9, 0.6, 0.3], "specular_tint": [0.5, 0.7, 0.9]}"#);
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        let s = p.sample(n, [0.5, 0.5, 0.5]).unwrap();
        assert!(s.delta);
        let r = s.weight * s.pdf;
        for (c, want) in [0.9, 0.6, 0.3].iter().enumerate() {
            assert!((r[c] - want).abs() < 1e-12, "{r:?}");
        }
    }

    /// A smooth dielectric of IOR 1.5 reflects 4 % at normal incidence
    /// (`((1.5 − 1)/(1.5 + 1))²`), and a black base adds nothing.
    #[test]
    fn smooth_dielectric_reflects_four_percent_at_normal_incidence() {
        let p = principled(r#"{"model": "principled", "roughness": 0, "base_color": 0}"#);
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        let s = p.sample(n, [0.5, 0.5, 0.5]).unwrap();
        assert!(s.delta);
        let r = s.weight * s.pdf;
        for c in 0..3 {
            assert!((r[c] - 0.04).abs() < 1e-12, "{r:?}");
        }
        assert!((p.albedo(1.0)[0] - 0.04).abs() < 1e-12);
    }

    /// Coat weight 0 is no coat, whatever the other coat inputs.
    #[test]
    fn zero_coat_weight_is_no_coat() {
        let a = principled(r#"{"model": "principled", "roughness": 0.4, "base_color": [0.2, 0.5, 0.7]}"#);
        let b = principled(
            r#"{"model": "principled", "roughness": 0.4, "base_color": [0.2, 0.5, 0.7], "coat_weight": 0, "coat_roughness": 0.2, "coat_ior": 2.0, "coat_tint": [0.1, 0.5, 0.9]}"#,
        );
        for (ci, co) in [(0.9, 0.4), (0.3, 0.8), (0.05, 0.5)] {
            let (wi, wo) = (dir(ci, 0.1), dir(co, 2.9));
            assert_eq!(a.eval(wi, wo), b.eval(wi, wo));
            assert_eq!(a.pdf(wi, wo), b.pdf(wi, wo));
        }
    }

    /// A white Lambert base under a rough specular layer and a rough coat reflects all the
    /// light: the directional albedo, integrated by Monte Carlo over `eval`, is 1 (the layer
    /// weights are one minus the albedos of the layers above, and nothing absorbs).
    #[test]
    fn white_base_under_coat_and_specular_is_a_white_furnace() {
        let m = Material::from_json(
            r#"{"model": "principled", "base_color": 1.0, "roughness": 0.6, "coat_weight": 1, "coat_roughness": 0.5}"#,
        )
        .unwrap();
        let mut rng = crate::rng::Pcg32::new(3, 4);
        for mu in [1.0, 0.6, 0.2, 0.05] {
            let (a, se) = crate::check::furnace::albedo(&m, dir(mu, 0.4), 100_000, &mut rng);
            for v in a {
                assert!((v - 1.0).abs() < 2e-3 + 3.0 * se, "μ {mu}: {a:?} ± {se}");
            }
        }
    }

    /// The coat tint follows Beer's law along the refracted viewing path, normalised at normal
    /// incidence: at normal incidence a coat of IOR 1 (no reflection) with tint t and weight 1
    /// multiplies the base by t.
    #[test]
    fn coat_tint_at_normal_incidence_is_the_tint() {
        let p = principled(
            r#"{"model": "principled", "base_color": 1.0, "specular_ior_level": 0, "coat_weight": 1, "coat_ior": 1.0, "coat_tint": [0.5, 0.25, 1.0]}"#,
        );
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        let f = p.eval(dir(0.7, 0.2), n);
        for (c, t) in [0.5, 0.25, 1.0].iter().enumerate() {
            assert!((f[c] - t / std::f64::consts::PI).abs() < 1e-12, "{f:?}");
        }
        // At 60° through IOR 1 the path is twice as long: t².
        let f = p.eval(n, dir(0.5, 0.0));
        assert!((f[0] - 0.25 / std::f64::consts::PI).abs() < 1e-12, "{f:?}");
    }

    /// Specular IOR level 0 removes the specular layer; level 1 doubles F0 (so the smooth
    /// reflectance at normal incidence is 0.08 for IOR 1.5).
    #[test]
    fn ior_level_scales_f0() {
        let p = principled(r#"{"model": "principled", "roughness": 0, "base_color": 0, "specular_ior_level": 1}"#);
        assert!((p.albedo(1.0)[1] - 0.08).abs() < 1e-9, "{:?}", p.albedo(1.0));
        let p = principled(r#"{"model": "principled", "roughness": 0, "base_color": 0, "specular_ior_level": 0}"#);
        assert_eq!(p.albedo(1.0), [0.0; 3]);
    }

    /// A quarter-wave film at normal incidence: with film index √η (the antireflection
    /// condition n_f² = n_ambient·n_substrate) and n_f·d = 550/4 nm the reflectance at 550 nm
    /// vanishes, so the green channel drops far below the bare 4 % of IOR 1.5.
    #[test]
    fn quarter_wave_film_suppresses_green_at_normal_incidence() {
        let nf = 1.5f64.sqrt();
        let d = 550.0 / (4.0 * nf);
        let p = principled(&format!(
            r#"{{"model": "principled", "roughness": 0, "base_color": 0, "thin_film_thickness": {d}, "thin_film_ior": {nf}}}"#
        ));
        let a = p.albedo(1.0);
        assert!(a[1] < 0.01 && a[1] < a[0] && a[1] < a[2], "{a:?}");
    }

    /// The lobe-selection table ([`Principled::selection`]) holds the layers' selection
    /// weights normalised: at its nodes to rounding, between them within the linear
    /// interpolation's error (measured 1.53e-3 at most at the midpoints of these four
    /// materials, absolute probability; asserted 2e-3), summing to 1; a material that reflects nothing keeps density 0 and no
    /// samples.
    #[test]
    fn selection_table_holds_the_normalised_layer_weights() {
        let materials = [
            r#"{"model": "principled", "base_color": [0.8, 0.3, 0.2], "roughness": 0.5, "metallic": 0.5}"#,
            r#"{"model": "principled", "roughness": 0.45, "metallic": 0.3, "base_color": [0.1, 0.2, 0.6], "thin_film_thickness": 350, "thin_film_ior": 1.6, "coat_weight": 0.5, "coat_roughness": 0.5, "coat_tint": [0.8, 0.9, 1.0]}"#,
            r#"{"model": "principled", "roughness": 0, "metallic": 0.5, "base_color": [0.8, 0.2, 0.1], "coat_weight": 1, "coat_roughness": 0}"#,
            r#"{"model": "principled", "metallic": 1, "roughness": 0.2, "base_color": [0.9, 0.6, 0.3]}"#,
        ];
        let mut worst = 0.0f64;
        for json in materials {
            let p = principled(json);
            let n = SELECTION_NODES - 1;
            for k in 2..2 * n {
                let mu = k as f64 / (2 * n) as f64;
                let w = p.layers::<f64>(mu).select;
                let total: f64 = w.iter().sum();
                let got = p.selection::<f64>(mu);
                assert!((got.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{json} μ {mu}: {got:?}");
                for (g, w) in got.iter().zip(w) {
                    let err = (g - w / total).abs();
                    if k % 2 == 0 {
                        assert!(err < 1e-12, "{json} node μ {mu}: {got:?} against {w}/{total}");
                    }
                    worst = worst.max(err);
                }
            }
        }
        assert!(worst < 2e-3, "largest probability error between nodes {worst}");
        eprintln!("largest selection-probability error between nodes: {worst:.2e}");

        let black = principled(r#"{"model": "principled", "base_color": 0, "specular_ior_level": 0}"#);
        let (wi, wo) = (dir(0.6, 0.3), dir(0.8, 2.0));
        assert_eq!(black.pdf(wi, wo), 0.0);
        assert!(black.sample(wo, [0.3, 0.5, 0.7]).is_none());
    }

    #[test]
    fn passes_its_claims() {
        let r = crate::check::check_model(&INFO, &crate::check::CheckConfig::quick());
        let bad: Vec<String> = r
            .materials
            .iter()
            .flat_map(|m| m.verdicts.iter().filter(|v| !v.ok()).map(move |v| format!("{} {} {}", m.material, v.check, v.value)))
            .collect();
        assert!(r.passed, "{bad:?} {:?}", r.parameter_extremes.examples);
    }
}
