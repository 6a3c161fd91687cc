//! Coated car paint: a clearcoat over a basecoat of pigment, metallic flakes and pearlescent
//! flakes, in physical units; reciprocal and energy-conserving by construction.
//!
//! | parameter | kind | default | range | unit | meaning |
//! |---|---|---|---|---|---|
//! | `base_color` | colour | [0.5, 0.03, 0.03] | [0, 1] | | pigment albedo ρ of the basecoat |
//! | `coat_ior` | scalar | 1.5 | [1, 2.5] | | clearcoat index of refraction (1 = no coat) |
//! | `coat_roughness` | scalar | 0.02 | 0 or [0.001, 0.5] | | GGX α of the coat surface; 0 = mirror-smooth |
//! | `coat_thickness_um` | scalar | 40 | [0, 500] | µm | clearcoat thickness (thesis: 35–45) |
//! | `coat_absorption` | colour | 0 | [0, 200] | 1/mm | absorption coefficient of the clearcoat |
//! | `flake_density` | scalar | 3 | [0, 100] | % | area coverage of metallic flakes (thesis: 0–8) |
//! | `flake_size_um` | scalar | 20 | [1, 200] | µm | metallic flake diameter (thesis: 15–25; sparkle) |
//! | `flake_orientation_deg` | scalar | 12 | [0.5, 60] | ° | RMS tilt of flake normals (Beckmann α = tan) |
//! | `flake_material` | choice | Al | Al, Ag, Au, Cu | | metal of the flakes (complex IOR) |
//! | `base_metallic` | scalar | 0 | [0, 1] | | weight of a rough metallic base under the pigment |
//! | `base_roughness` | scalar | 0.3 | [0.01, 1] | | GGX α of the metallic base |
//! | `pearl_density` | scalar | 0 | [0, 100] | % | area coverage of pearlescent (mica) flakes |
//! | `pearl_size_um` | scalar | 15 | [1, 200] | µm | pearlescent flake diameter (sparkle) |
//! | `pearl_film_nm` | scalar | 120 | [0, 1000] | nm | TiO₂/Fe₂O₃ film thickness on the mica |
//! | `pearl_film_ior` | scalar | 2.6 | [1.3, 3.2] | | film index (TiO₂ rutile ≈ 2.6–2.9) |
//! | `pearl_substrate_ior` | scalar | 1.58 | [1.3, 2.0] | | mica index |
//! | `pearl_structure` | choice | platelet | platelet, film | | `platelet`: the film on both faces of an incoherent mica core ([`super::thin_film::ThinFilm::platelet_reflectance`]); `film`: one film on semi-infinite mica (before issue 17) |
//! | `pigment_model` | choice | lambert | lambert, eon | | scattering of the pigment: Lambert `ρ/π`, or EON (energy-preserving Oren-Nayar, [`crate::models::eon`]) of albedo ρ |
//! | `pigment_roughness` | scalar | 0.5 | [0, 1] | | EON roughness r of the pigment (used with `pigment_model = eon`; 0 is Lambert) |
//! | `surface_scale_mm` | scalar | 100 | [0.001, 1e6] | mm | physical length of one uv unit (sparkle) |
//! | `sparkle` | bool | true | | | resolve individual flakes when a footprint is given |
//!
//! ## The model
//! Outside directions `wi`, `wo`; inside the coat (index η) their refracted versions `wi'`,
//! `wo'`. With `T(μ) = 1 − E_top(μ) − ΔR(μ)` the energy entering the coat (`E_top = F` for a
//! smooth coat, the tabulated albedo of the GGX reflection for a rough one; `ΔR` the rough
//! interface's multiple-scattering reflection, [`super::coat::MultipleScattering`], 0 for a
//! smooth coat), `τ(w')` the Beer-Lambert transmittance of one crossing and `f_b` the basecoat
//! BRDF (`f_top` is the coat's GGX reflection plus the separable lobe `ΔR(μi)ΔR(μo)/(πΔR̄)`):
//!
//! `f = f_top(wi, wo) + T(μi) T(μo)/η² · τ(wi') τ(wo') · f_b(wi', wo') + M(μi) M(μo) / (π M̄)`
//!
//! The middle term is light that crosses the coat, scatters once on the basecoat and leaves
//! (radiance scales by η² inside; `cos θ dω = η² cos θ' dω'`). Light the basecoat sends back
//! up but the coat reflects down again (partial and total internal reflection) is not dropped:
//! per outside direction the tables hold `U(μ)`, what returns to the coat from below after one
//! basecoat bounce, and `A1(μ)`, what of it escapes (the middle term's albedo). The rest,
//! `R = U − A1`, bounces on: each round trip crosses the coat twice (mean transmittance τ̄),
//! meets the basecoat (mean albedo ρ̄) and escapes with probability `e`, so what finally
//! leaves is `M = R · τ̄²ρ̄e / (1 − τ̄²ρ̄(1 − e))`. `M` leaves through the symmetric
//! Kulla-Conty-style lobe `M(μi)M(μo)/(πM̄)` (`M̄` its cosine-weighted mean), whose albedo
//! is exactly `M(μo)`.
//!
//! With a metallic base, the metal's share of `R` (`R_spec`, split per sample by the metal
//! lobe's share of `f_b`) does not go into `M`: a specular base keeps it near its mirror
//! direction round trip after round trip, so it leaves through the specular bounce series `S`
//! of [`super::spec_series`] (a widened copy of the metal's lobe, weighted so that its albedo
//! is at most `R_spec`, part of the `GLOSSY` lobe and of the single-scatter lobe's sampling
//! weight), and `M = R_rest · τ̄²ρ̄e / (1 − τ̄²ρ̄(1 − e))` with `R_rest = R − R_spec`. Without a
//! metallic base `S = 0` and `R_rest = R` (the model as before, bit for bit).
//!
//! Hence: every term is symmetric in (wi, wo) (reciprocal); the albedo is
//! `E_top + ΔR + A1 + S + M ≤ E_top + ΔR + U ≤ E_top + ΔR + T = 1` (energy-conserving); and a
//! lossless stack (white pigment, no absorption) reaches `E_top + ΔR + U = 1` (no energy lost
//! to the layering).
//! Under a rough coat the basecoat's metal base is seen through the coat's transmission blur
//! ([`super::coat::TransmissionBlur`]: a wider, still normalised and symmetric lobe; the
//! pigment is unchanged); `f_b` above and the tables are that blurred basecoat's, `ρ̄` the
//! unblurred one's. The flakes' broad lobe takes no blur: it is evaluated at the flakes' share
//! of the mean refraction ([`super::coat::Coat::flake_refract_in`], the same map both ways,
//! crossing with `g(μi) g(μo)/η²`; its albedo in `A1` by the change of variables to the macro
//! refraction, session 40).
//! A metal base's first bounce under a rough coat is evaluated at the mean refracted
//! directions ([`super::coat::Coat::mean_refract_in`]: from grazing directions the visible,
//! light-facing facets refract beyond the macro critical angle; same map both ways, so
//! reciprocal, `T T/η²` as before; its albedo by the change of variables of
//! [`super::coat::Coat::mean_refract_out`]); so is its bounce series `S` (session 39).
//! Approximations: the rough coat's transmission otherwise refracts at the macro normal (its
//! spread enters only through the blur of the base's specular lobes); bounces after
//! the first see the basecoat's mean albedo (and, for an absorbing coat, the mean
//! transmittance τ̄). The position-free Monte Carlo reference ([`super::position_free_mc`])
//! measures their cost (`docs/paint-validation.md`): for a smooth coat over a Lambertian base
//! the model is exact (the M lobe reduces to the bounce series) and agrees within the
//! reference's noise; an absorbing coat is 0.7 % off; flakes and pearlescent flakes 1–2 % on
//! average and up to ≈ 10 % (their light returns specularly, not diffusely). Against the
//! reference with the lossless multiple-scattering rough interface (§8 of the doc): over a
//! pigment within 1 % up to α 0.2 except at grazing view (3–4.6 % low; within 0.6 % with the
//! coat's multiple-scattering reflection, [`super::coat::MultipleScattering`]); over flakes 2–9 % high
//! for α 0.1–0.3 (1.5–7 % with the blur); over a sharp metal base (α 0.05) the blur brings the
//! lobe shape from 5–93 % to 1.6–7.2 % off at θo ≤ 40°; at θo 75° the bounce series brings it
//! from 21–24 % to 5.2–10.6 % (albedo within 2 % for coat α ≤ 0.03 and 0.2, +3.7 % at α 0.1,
//! −7.9 % at α 0.3: the symmetric blur's min loses energy at grazing view).
//!
//! ## Sparkle
//! With a surface point and footprint ([`Bxdf::eval_at`]), each flake population's lobe in
//! the single-scatter term is multiplied by a deterministic, position-dependent count of the
//! flakes whose normals fall in the binder half vector's direction cell, normalised to mean
//! one (see [`super::sparkle`]). Without flakes or with `sparkle = false`, `eval_at` is
//! `eval`. The coat reflection, the pigment and the multiple-scatter lobe stay smooth.
//!
//! ## Sampling
//! `u[0]` picks the top reflection, the single-scatter layer lobe or the cosine lobe in
//! proportion to their albedos for this `wo` (`E_top(μo)`, `A1(μo) + S(μo)` (the metal's bounce
//! series is drawn by the layer lobe's sampler), `M(μo) + ΔR(μo)`: the
//! multiple-scatter lobe and the coat's multiple-scattering reflection, both cosine-sampled); the layer lobe
//! refracts `wo` in, samples the basecoat's own mixture (cosine, GGX visible normals, the
//! flakes' Beckmann `D(m) cos θm`; the layer tables are built with the flakes' visible
//! normals instead, which give lower-variance estimates) and refracts out. `sample_at` draws the same directions (the pdf does not depend
//! on the position) and weights them by `eval_at · cos / pdf`.
//!
//! ## References
//! Weidlich & Wilkie 2007 (arbitrarily layered micro-facet surfaces); Kulla & Conty 2017
//! (reciprocal energy compensation); Belcour & Barla 2017 (thin-film Airy reflectance);
//! Ershov et al. 2001 and Günther et al. 2005 (car paint structure); the thesis in
//! `shared/seeds/004` (parameters and ranges, chapter 3).

use super::basecoat::{BasePair, BaseParts, Basecoat, MetalBase};
use super::coat::{ms_azimuthal, ms_sample, Coat, CoatAt};
use super::flakes::{FlakeLayer, FlakeSampler};
use super::pick3;
use super::sparkle::Sparkle;
use super::spec_series::{series_widening, SeriesLobe, SpecSeries};
use super::thin_film::ThinFilm;
use crate::bxdf::{BsdfSample, Bxdf, Claims, LaneBxdf, LaneSample, ModelInfo, SurfacePoint};
use crate::error::Error;
use crate::frame::HalfPair;
use crate::fresnel;
use crate::lanes::{self, keep, Lanes, Mask};
use crate::lobes::bits;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::table::MuTable;

const FLAKE_METALS: &[&str] = &["Al", "Ag", "Au", "Cu"];

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("base_color", [0.5, 0.03, 0.03], 0.0, 1.0, "pigment albedo ρ of the basecoat"),
    ParamSpec::scalar("coat_ior", 1.5, 1.0, 2.5, "", "clearcoat index of refraction (1 = no coat)"),
    ParamSpec::scalar(
        "coat_roughness",
        0.02,
        0.0,
        0.5,
        "",
        "GGX α of the clearcoat surface; 0 = mirror-smooth, else ≥ 0.001",
    ),
    ParamSpec::scalar("coat_thickness_um", 40.0, 0.0, 500.0, "µm", "clearcoat thickness (thesis: 35–45 µm)"),
    ParamSpec::color(
        "coat_absorption",
        [0.0; 3],
        0.0,
        200.0,
        "clearcoat absorption coefficient per channel, 1/mm (Beer-Lambert)",
    ),
    ParamSpec::scalar(
        "flake_density",
        3.0,
        0.0,
        100.0,
        "%",
        "area coverage of metallic flakes (thesis samples: 0–8 %)",
    ),
    ParamSpec::scalar(
        "flake_size_um",
        20.0,
        1.0,
        200.0,
        "µm",
        "metallic flake diameter (thesis: 15–25 µm, range 5–45); sets the sparkle scale",
    ),
    ParamSpec::scalar(
        "flake_orientation_deg",
        12.0,
        0.5,
        60.0,
        "°",
        "RMS tilt of the flake normals about the coat normal",
    ),
    ParamSpec::choice("flake_material", "Al", FLAKE_METALS, "metal of the flakes (measured complex IOR)"),
    ParamSpec::scalar(
        "base_metallic",
        0.0,
        0.0,
        1.0,
        "",
        "weight of a rough metallic base (uses base_color as F0) under the pigment",
    ),
    ParamSpec::scalar("base_roughness", 0.3, 0.01, 1.0, "", "GGX α of the metallic base"),
    ParamSpec::scalar("pearl_density", 0.0, 0.0, 100.0, "%", "area coverage of pearlescent (mica + oxide film) flakes"),
    ParamSpec::scalar("pearl_size_um", 15.0, 1.0, 200.0, "µm", "pearlescent flake diameter; sets the sparkle scale"),
    ParamSpec::scalar(
        "pearl_film_nm",
        120.0,
        0.0,
        1000.0,
        "nm",
        "oxide film thickness on the mica (interference colour)",
    ),
    ParamSpec::scalar("pearl_film_ior", 2.6, 1.3, 3.2, "", "oxide film index (TiO₂ rutile ≈ 2.6–2.9, Fe₂O₃ ≈ 3)"),
    ParamSpec::scalar("pearl_substrate_ior", 1.58, 1.3, 2.0, "", "mica substrate index"),
    ParamSpec::choice(
        "pearl_structure",
        "platelet",
        &["platelet", "film"],
        "platelet: oxide film on both faces of an incoherent mica core; film: one film on semi-infinite mica",
    ),
    ParamSpec::choice(
        "pigment_model",
        "lambert",
        &["lambert", "eon"],
        "lambert: the pigment scatters as ρ/π; eon: energy-preserving Oren-Nayar (OpenPBR) of albedo ρ",
    ),
    ParamSpec::scalar(
        "pigment_roughness",
        0.5,
        0.0,
        1.0,
        "",
        "EON roughness of the pigment (with pigment_model = eon; 0 is Lambert)",
    ),
    ParamSpec::scalar("surface_scale_mm", 100.0, 0.001, 1e6, "mm", "physical length of one uv unit (for sparkle)"),
    ParamSpec::boolean("sparkle", true, "resolve individual flakes when a surface position and footprint are given"),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "coated_paint",
    summary: "Clearcoat over a basecoat with pigment, metallic flakes and pearlescent thin-film flakes",
    reference: "This project (see module docs); Weidlich & Wilkie 2007; Kulla & Conty 2017; Belcour & Barla 2017",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: &[
        r#"{"flake_density": 0}"#,
        r#"{"coat_roughness": 0, "flake_density": 8, "flake_material": "Au", "coat_absorption": [2, 4, 8]}"#,
        r#"{"coat_roughness": 0.15, "flake_density": 5, "pearl_density": 10, "pearl_film_nm": 300, "base_metallic": 0.5}"#,
        r#"{"base_color": 1.0, "flake_density": 0, "coat_roughness": 0}"#,
        r#"{"pigment_model": "eon", "pigment_roughness": 1, "base_color": [0.9, 0.5, 0.2], "flake_density": 3, "coat_roughness": 0.05}"#,
    ],
    build,
};

/// Nodes of the per-material `A1`, `M` tables over `μ`.
const TABLE_NODES: usize = 48;
/// Low-discrepancy basecoat samples behind each table node.
const TABLE_SAMPLES: usize = 2048;
/// Halton-Hammersley points behind the basecoat's mean albedo `ρ̄` ([`mean_albedo`]): 4× a
/// table node's, as ρ̄ scales every bounce (within 0.2 % of a 1M-sample Monte Carlo for the
/// flaked paints and EON, 1.5 % for a dark α 0.05 metal base; +8 % to the table's
/// construction).
pub(crate) const MEAN_ALBEDO_SAMPLES: usize = 4 * TABLE_SAMPLES;

fn build(p: &Params) -> Result<Model, Error> {
    let coat_roughness = p.scalar("coat_roughness");
    if coat_roughness > 0.0 && coat_roughness < 1e-3 {
        return Err(Error::Invalid {
            param: "coat_roughness".into(),
            reason: format!(
                "{coat_roughness} is too small to sample reliably: use 0 for a smooth coat or at least 0.001"
            ),
        });
    }
    let flake_c = p.scalar("flake_density") / 100.0;
    let pearl_c = p.scalar("pearl_density") / 100.0;
    if flake_c + pearl_c > 1.0 + 1e-12 {
        return Err(Error::Invalid {
            param: "pearl_density".into(),
            reason: format!("flake_density + pearl_density = {} % exceeds 100 %", 100.0 * (flake_c + pearl_c)),
        });
    }
    Ok(Model::CoatedPaint(CoatedPaint::new(p)))
}

/// The coated paint BRDF with its precomputed per-material tables.
#[derive(Clone, Debug)]
pub struct CoatedPaint {
    coat: Coat,
    base: Basecoat,
    /// `A1(μ)`: albedo of the single-scatter layer term per outside direction, a lobe-selection
    /// weight (and `M`'s complement). A metal base's first bounce under a rough coat is in it
    /// as the macro refraction gives it, not at the mean refracted directions the term uses
    /// ([`Coat::mean_refract_in`]; the per-element tables of [`super::varying`] estimate it the
    /// same way, so both sample alike); the term's own albedo, which the energy bound holds,
    /// is [`super::spec_series::first_bounce_albedo`].
    single: MuTable,
    /// `M(μ)`: energy leaving after further internal bounces.
    multiple: MuTable,
    /// `1/(π M̄)` per channel (0 where `M̄ = 0`).
    multiple_norm: [f64; 3],
    /// The metallic base's specular bounce series (None without a metallic base or without a
    /// coat interface; [`super::spec_series`]).
    spec: Option<SpecSeries>,
    /// Physical parameters kept for the sparkle layer and reports.
    pub flake_size_um: f64,
    /// Pearlescent flake diameter.
    pub pearl_size_um: f64,
    /// Physical size of one uv unit in mm.
    pub surface_scale_mm: f64,
    /// Whether sparkle is resolved when a footprint is given.
    pub sparkle: bool,
    /// The sparkle layer (None with `sparkle = false` or without flakes).
    sparkle_layer: Option<Sparkle>,
}

impl CoatedPaint {
    /// Builds the layer stack and its tables from validated parameters.
    #[must_use]
    pub fn new(p: &Params) -> Self {
        Self::build(p, None)
    }

    /// The paint whose three channels are the wavelengths `lambda_nm` instead of R, G, B (the
    /// spectral path, [`crate::spectral`]): the pearl film's Airy reflectance at each
    /// wavelength instead of its RGB integral, colours upsampled with
    /// [`crate::spectral::upsample`], the flakes' metal n, k interpolated between the RGB
    /// channels' wavelengths ([`crate::spectral::rgb_channel_interpolate`]).
    #[must_use]
    pub fn at_wavelengths(p: &Params, lambda_nm: [f64; 3]) -> Self {
        Self::build(p, Some(lambda_nm))
    }

    fn build(p: &Params, lambda_nm: Option<[f64; 3]>) -> Self {
        use crate::spectral::{rgb_channel_interpolate, upsample};
        let color = |name: &str| match lambda_nm {
            None => p.color(name),
            Some(l) => l.map(|x| upsample(p.color(name), x).max(0.0)),
        };
        let per_channel = |rgb: [f64; 3]| match lambda_nm {
            None => rgb,
            Some(l) => l.map(|x| rgb_channel_interpolate(rgb, x)),
        };
        let eta = p.scalar("coat_ior");
        let coat = Coat::new(eta, p.scalar("coat_roughness"), p.scalar("coat_thickness_um"), color("coat_absorption"));
        let flake_c = p.scalar("flake_density") / 100.0;
        let pearl_c = p.scalar("pearl_density") / 100.0;
        let metallic = p.scalar("base_metallic");
        let film = ThinFilm {
            thickness_nm: p.scalar("pearl_film_nm"),
            film_ior: p.scalar("pearl_film_ior"),
            substrate_ior: p.scalar("pearl_substrate_ior"),
            medium_ior: eta,
        };
        let platelet = p.choice("pearl_structure") == "platelet";
        let pearl_table = (pearl_c > 0.0).then(|| match lambda_nm {
            None if platelet => film.platelet_table(64),
            None => film.table(64),
            Some(l) => MuTable::build(64, |mu| {
                l.map(|x| {
                    let r = if platelet { film.platelet_reflectance(mu, x) } else { film.reflectance(mu, x) };
                    r.clamp(0.0, 1.0)
                })
            }),
        });
        let flake_alpha = p.scalar("flake_orientation_deg").to_radians().tan();
        let sparkle_layer = if p.boolean("sparkle") {
            Sparkle::new(
                flake_alpha,
                eta,
                p.scalar("surface_scale_mm"),
                (flake_c, p.scalar("flake_size_um")),
                (pearl_c, p.scalar("pearl_size_um")),
            )
        } else {
            None
        };
        let flakes = (flake_c > 0.0 || pearl_c > 0.0).then(|| {
            let metal = fresnel::metal(p.choice("flake_material")).expect("choice list holds known metals");
            FlakeLayer {
                alpha: flake_alpha,
                metallic_coverage: flake_c,
                metal: fresnel::ConductorFresnel::new(
                    per_channel(metal.eta).map(|n| n / eta),
                    per_channel(metal.k).map(|k| k / eta),
                ),
                pearl_coverage: pearl_c,
                pearl_reflectance: pearl_table.clone(),
            }
        });
        let uncovered = (1.0 - flake_c - pearl_c).max(0.0);
        let metal = (metallic > 0.0).then(|| MetalBase {
            alpha: p.scalar("base_roughness"),
            f0: color("base_color"),
            weight: uncovered * metallic,
        });
        let pearl_transmission =
            pearl_table.map(|t| MuTable::build(t.values().len(), |mu| t.eval::<f64>(mu).map(|r| 1.0 - r)));
        let base = Basecoat::new(
            color("base_color"),
            uncovered * (1.0 - metallic),
            pearl_c,
            pearl_transmission,
            metal,
            flakes,
        );
        let base = if p.choice("pigment_model") == "eon" {
            base.with_rough_pigment(p.scalar("pigment_roughness"))
        } else {
            base
        };
        let base = base.with_blur(coat.transmission_blur());
        let spec = base.metal.as_ref().and_then(|m| SpecSeries::build(&coat, m.alpha));
        let (single, multiple) = layer_tables(&coat, &base, spec.is_some());
        let m_avg = multiple.cosine_average();
        let multiple_norm = m_avg.map(|m| if m > 1e-12 { 1.0 / (std::f64::consts::PI * m) } else { 0.0 });
        Self {
            coat,
            base,
            single,
            multiple,
            multiple_norm,
            spec,
            flake_size_um: p.scalar("flake_size_um"),
            pearl_size_um: p.scalar("pearl_size_um"),
            surface_scale_mm: p.scalar("surface_scale_mm"),
            sparkle: p.boolean("sparkle"),
            sparkle_layer,
        }
    }

    /// The clearcoat.
    #[must_use]
    pub fn coat(&self) -> &Coat {
        &self.coat
    }

    /// The basecoat as the layer term sees it: with the rough coat's transmission blur
    /// ([`Basecoat::blur`]; `basecoat().clone().with_blur(None)` is the basecoat as it is).
    #[must_use]
    pub fn basecoat(&self) -> &Basecoat {
        &self.base
    }

    /// The sparkle layer, when sparkle is on and there are flakes.
    #[must_use]
    pub fn sparkle_layer(&self) -> Option<&Sparkle> {
        self.sparkle_layer.as_ref()
    }

    /// The half vector of `wi` and `wo` refracted into the coat (the flakes' frame of
    /// reference; the key of the sparkle direction cells).
    #[must_use]
    pub fn binder_half_vector(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> Option<Vec3<f64>> {
        crate::frame::half_vector(self.coat.refract_in(wi), self.coat.refract_in(wo))
    }

    /// `f` with the sparkle multipliers of the binder half vector at `at` (the basecoat sees
    /// the directions refracted into the coat).
    #[inline]
    fn eval_sparkle<T: Real>(
        &self,
        sparkle: &Sparkle,
        wi: Vec3<T>,
        wo: Vec3<T>,
        at: &SurfacePoint,
        parts: PaintParts,
    ) -> Rgb<T> {
        let [metal, pearl] = self.sparkle_multipliers(sparkle, wi, wo, at);
        self.eval_parts(wi, wo, T::of(metal), T::of(pearl), parts)
    }

    /// The sparkle's multipliers `[metallic, pearlescent]` of the flake lobes for one pair of
    /// directions at `at` (the half vector inside the coat picks the direction cell).
    fn sparkle_multipliers<T: Real>(&self, sparkle: &Sparkle, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint) -> [f64; 2] {
        let (wi_in, wo_in) = (self.coat.refract_in(wi), self.coat.refract_in(wo));
        match crate::frame::half_vector(wi_in, wo_in) {
            Some(h) => sparkle.multipliers(h.cast::<f64>(), at).into(),
            None => [1.0; 2],
        }
    }

    /// The multipliers `[metallic, pearlescent]` that turn [`Bxdf::eval`] into
    /// [`Bxdf::eval_at`] for directions above the surface: `[1, 1]` without sparkle or for a
    /// non-finite surface point (the batch calls at surface points use them with the lane kernels).
    #[must_use]
    pub fn sparkle_scales<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint) -> [f64; 2] {
        match &self.sparkle_layer {
            Some(s) if at.is_finite() => self.sparkle_multipliers(s, wi, wo, at),
            _ => [1.0; 2],
        }
    }

    /// A sample of `wo` weighted with the BRDF `f` (the sparkle version of the lobe).
    #[inline]
    fn sample_with<T: Real>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        parts: PaintParts,
        f: impl Fn(Vec3<T>) -> Rgb<T>,
    ) -> Option<BsdfSample<T>> {
        let o = self.at_wo(wo, parts);
        let d = self.sample_direction_at(&o, u, parts);
        if !d.valid {
            return None;
        }
        if d.delta {
            let p = self.delta_probability(d.selection);
            let weight = Rgb::splat(d.selection[0] / p);
            return (p > T::zero()).then_some(BsdfSample { wi: d.wi, weight, pdf: p, delta: true });
        }
        if d.wi.z <= T::zero() {
            return None;
        }
        BsdfSample::from_eval(d.wi, f(d.wi), self.pdf_pair(&self.at_pair(d.wi, &o), &o, parts))
    }

    /// The three terms of `eval` separately: top reflection, single-scatter layer, multiple scatter.
    #[must_use]
    pub fn eval_terms<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> [Rgb<T>; 3] {
        let o = self.at_wo(wo, PaintParts::ALL);
        let p = self.at_pair(wi, &o);
        [
            Rgb::splat(self.top_term(&p, &o)),
            self.layer_term(&p, &o, T::one(), T::one(), PaintParts::ALL),
            self.multiple_term(&p, &o),
        ]
    }

    /// The metal base's bounce series `S` alone, as the paint's `eval` adds it (crossings and
    /// the coat's absorption included; 0 without a metallic base under a coat interface): for
    /// reports that compare it with the reference's light after two or more base bounces
    /// (`examples/rough_coat_validation.rs`).
    #[must_use]
    pub fn eval_series_term(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> Rgb<f64> {
        let Some(spec) = &self.spec else { return Rgb::zero() };
        let o = self.at_wo(wo, PaintParts::ALL);
        let p = self.at_pair(wi, &o);
        let (ti, to) = (p.coat.transmittance(), o.coat.transmittance());
        if !(ti > 0.0 && to > 0.0) {
            return Rgb::zero();
        }
        let f = self.spec_term(spec, wi, wo, p.wi_in, o.wo_in) * (ti * to / (self.coat.ior * self.coat.ior));
        if self.coat.absorbs() {
            let (ai, ao) = (self.coat.attenuation(p.wi_in.z), self.coat.attenuation(o.wo_in.z));
            return Rgb::new(f.r * ai[0] * ao[0], f.g * ai[1] * ao[1], f.b * ai[2] * ao[2]);
        }
        f
    }

    /// The metal base's bounce series' albedo at `cos θo = mu` (the channels' mean, its
    /// lobe-selection weight, joined to the single-scatter layer lobe's; 0 without a metallic
    /// base; [`super::spec_series`]).
    #[must_use]
    pub fn spec_series_albedo(&self, mu: f64) -> f64 {
        self.spec_albedo(mu)
    }

    /// `A1(μ)` and `M(μ)` for a report or a test.
    #[must_use]
    pub fn layer_albedos(&self, mu: f64) -> ([f64; 3], [f64; 3]) {
        (self.single.eval(mu), self.multiple.eval(mu))
    }

    /// Lobe-selection weights for `wo` from the coat's factors `coat` and the multiple-scatter
    /// table's `M(μo)` there: top reflection (single scattering, visible normals),
    /// single-scatter layer, and the cosine-sampled lobes: the multiple-scatter lobe plus the
    /// rough coat's multiple-scattering reflection ([`Coat::ms_albedo`], 0 for a smooth coat).
    /// Restricted to `parts`: the top reflection (coat), the single-scatter layer lobe times
    /// the share of the basecoat's sampling weight `parts` enables, the multiple-scatter lobe
    /// (pigment).
    #[inline(always)]
    fn selection_at<T: Lanes>(&self, coat: &CoatAt<T>, multiple: [T; 3], mu_o: T, parts: PaintParts) -> [T; 3] {
        let [a, b, c] = self.single.eval_lanes(mu_o);
        let [d, e, f] = multiple;
        // The channels' means by a product (a vector division costs the divider's throughput).
        let third = T::c(1.0 / 3.0);
        let layer = (a + b + c) * third + self.spec_albedo(mu_o);
        let mean_multiple = (d + e + f) * third;
        if parts == PaintParts::ALL {
            return [coat.reflectance, layer, mean_multiple + coat.ms];
        }
        let zero = T::c(0.0);
        let share = self.base.selection_share(parts.base());
        // The cosine-sampled weight holds the multiple-scatter lobe (pigment) and the coat's
        // multiple-scattering reflection (coat).
        let cosine = if parts.pigment { mean_multiple } else { zero } + if parts.coat { coat.ms } else { zero };
        [if parts.coat { coat.reflectance } else { zero }, if share > 0.0 { layer * T::c(share) } else { zero }, cosine]
    }

    /// The lobe-selection weights for `cos θo = mu_o` restricted to `parts`
    /// ([`Self::selection_at`]).
    #[inline(always)]
    fn selection_parts<T: Lanes>(&self, mu_o: T, parts: PaintParts) -> [T; 3] {
        self.selection_at(&self.coat.at(mu_o), self.multiple.eval_lanes(mu_o), mu_o, parts)
    }

    /// What sampling, the value and the density share at `wo` ([`AtWo`]), for the lobes
    /// `parts` enables.
    #[inline(always)]
    fn at_wo<T: Lanes>(&self, wo: Vec3<T>, parts: PaintParts) -> AtWo<T> {
        let coat = self.coat.at(wo.z);
        let multiple = self.multiple.eval_lanes(wo.z);
        let wo_in = self.coat.refract_in(wo);
        AtWo {
            wo,
            wo_in,
            coat,
            multiple,
            selection: self.selection_at(&coat, multiple, wo.z, parts),
            blur: self.base.blur_added(wo_in.z),
        }
    }

    /// What the value and the density share at `wi` and the `wo` of `o` ([`AtPair`]).
    #[inline(always)]
    fn at_pair<T: Lanes>(&self, wi: Vec3<T>, o: &AtWo<T>) -> AtPair<T> {
        self.at_pair_with(wi, o, true)
    }

    /// [`Self::at_pair`] for the value alone: under a rough coat the value reads the flakes at
    /// their own map of the directions ([`Coat::flake_refract_in`]), so without a metal base
    /// it reads no glossy lobe at the basecoat pair, whose half vector and flake `D` only the
    /// density needs ([`Basecoat::pair_at`]).
    #[inline(always)]
    fn at_pair_for_value<T: Lanes>(&self, wi: Vec3<T>, o: &AtWo<T>) -> AtPair<T> {
        self.at_pair_with(wi, o, !self.flakes_at_their_map() || self.base.metal.is_some())
    }

    /// True when the value reads the flakes at [`Coat::flake_refract_in`]'s pair rather than
    /// at the basecoat pair (a rough coat with flakes: [`Self::layer_term`]).
    #[inline(always)]
    fn flakes_at_their_map(&self) -> bool {
        self.coat.has_crossing() && self.base.flakes.is_some()
    }

    /// [`Self::at_pair`], with the basecoat pair's glossy terms only if `glossy_read`
    /// ([`Basecoat::pair_at`]).
    #[inline(always)]
    fn at_pair_with<T: Lanes>(&self, wi: Vec3<T>, o: &AtWo<T>, glossy_read: bool) -> AtPair<T> {
        let wi_in = self.coat.refract_in(wi);
        let top = HalfPair::new(wi, o.wo);
        AtPair {
            top,
            top_lobe: self.coat.reflection_eval_pdf_h(&top),
            wi_in,
            coat: self.coat.at(wi.z),
            multiple: self.multiple.eval_lanes(wi.z),
            ms_azimuthal: if self.coat.multiple_scattering().is_some() { ms_azimuthal(wi, o.wo) } else { T::c(0.0) },
            base: self.base.pair_at(wi_in, o.wo_in, o.blur, glossy_read),
        }
    }

    /// The coat's top reflection ([`Coat::top_eval`]): the single-scattering lobe plus the
    /// multiple-scattering one.
    #[inline(always)]
    fn top_term<T: Lanes>(&self, p: &AtPair<T>, o: &AtWo<T>) -> T {
        p.top_lobe.0 + self.coat.ms_lobe(p.coat.ms, o.coat.ms, p.ms_azimuthal)
    }

    /// The single-scatter layer term with the flake populations scaled by `metal_scale` and
    /// `pearl_scale` (1 for the mean lobe, the sparkle multipliers otherwise).
    #[inline(always)]
    fn layer_term<T: Lanes>(
        &self,
        p: &AtPair<T>,
        o: &AtWo<T>,
        metal_scale: T,
        pearl_scale: T,
        parts: PaintParts,
    ) -> Rgb<T> {
        let (wi, wo) = (p.top.wi, o.wo);
        let (ti, to) = (p.coat.transmittance(), o.coat.transmittance());
        let crosses = lanes::gt(ti, T::c(0.0)) & lanes::gt(to, T::c(0.0));
        let (wi_in, wo_in) = (p.wi_in, o.wo_in);
        let inv_eta2 = T::c(1.0 / (self.coat.ior * self.coat.ior));
        let mut f = if self.flakes_at_their_map() {
            // A rough coat: the flakes cross with `g(μi) g(μo)`, the pigment and the metal
            // base with `T(μi) T(μo)` (`Coat::crossing`); the flakes' lobe is evaluated at
            // their own map of the directions below.
            let mut rest = self.base.eval_pair(
                &p.base,
                metal_scale,
                pearl_scale,
                BaseParts { pigment: parts.pigment, glossy: false },
            );
            if parts.glossy {
                rest += self.metal_first_bounce(p, o);
                if let Some(spec) = &self.spec {
                    rest += self.spec_term(spec, wi, wo, wi_in, wo_in);
                }
            }
            let mut f = rest * (ti * to * inv_eta2);
            if parts.glossy {
                // The flakes' lobe at their share of the mean refraction (`Coat::flake_refract_in`).
                let (gi, go) = (p.coat.crossing, o.coat.crossing);
                let (fi, fo) = (self.coat.flake_refract_in(wi), self.coat.flake_refract_in(wo));
                f += self.base.flakes_eval(fi, fo, metal_scale, pearl_scale) * (gi * go * inv_eta2);
            }
            f
        } else {
            let mut f = if self.coat.has_mean_refraction() && self.base.metal.is_some() && parts.glossy {
                // The metal's first bounce at the mean refracted directions.
                let mut f = self.base.eval_pair(
                    &p.base,
                    metal_scale,
                    pearl_scale,
                    BaseParts { pigment: parts.pigment, glossy: false },
                );
                if self.base.flakes.is_some() {
                    f += self.base.flakes_eval_pair(&p.base, metal_scale, pearl_scale);
                }
                f + self.metal_first_bounce(p, o)
            } else {
                self.base.eval_pair(&p.base, metal_scale, pearl_scale, parts.base())
            };
            if parts.glossy {
                if let Some(spec) = &self.spec {
                    f += self.spec_term(spec, wi, wo, wi_in, wo_in);
                }
            }
            f * lanes::div_fast(ti * to, T::c(self.coat.ior * self.coat.ior))
        };
        if self.coat.absorbs() {
            let (ai, ao) = (self.coat.attenuation(wi_in.z), self.coat.attenuation(wo_in.z));
            f = Rgb::new(f.r * ai[0] * ao[0], f.g * ai[1] * ao[1], f.b * ai[2] * ao[2]);
        }
        Rgb::select(crosses, f, Rgb::zero())
    }

    /// The metal base's first bounce: under a rough coat its lobe at the mean refracted
    /// directions ([`Coat::mean_refract_in`]; the transmission blur still at the macro
    /// refraction's cosines, as calibrated), otherwise at the basecoat's pair.
    #[inline(always)]
    fn metal_first_bounce<T: Lanes>(&self, p: &AtPair<T>, o: &AtWo<T>) -> Rgb<T> {
        let (true, Some(m), Some(blur)) = (self.coat.has_mean_refraction(), &self.base.metal, &self.base.blur) else {
            return self.base.metal_eval_pair(&p.base);
        };
        let (wi, wo) = (self.coat.mean_refract_in(p.top.wi), self.coat.mean_refract_in(o.wo));
        let (added_i, added_o) = (blur.one_sided(p.wi_in.z), blur.one_sided(o.wo_in.z));
        let pair = HalfPair::new(wi, wo);
        m.eval_with_h(&m.blurred(added_o), Some(&m.blurred(added_i)), Rgb::from_array(m.f0), T::c(m.weight), &pair)
    }

    /// The metallic base's bounce series inside the coat ([`super::spec_series`]; the
    /// caller applies the coat's transmittances, as for the single-scatter term).
    #[inline(always)]
    fn spec_term<T: Lanes>(
        &self,
        spec: &SpecSeries,
        wi: Vec3<T>,
        wo: Vec3<T>,
        wi_in: Vec3<T>,
        wo_in: Vec3<T>,
    ) -> Rgb<T> {
        let Some(m) = &self.base.metal else { return Rgb::zero() };
        let (a, b) = (spec.weights.eval_lanes(wi.z), spec.weights.eval_lanes(wo.z));
        let w = (lanes::safe_sqrt(a[0] * b[0]), lanes::safe_sqrt(a[1] * b[1]));
        let n_eff = (a[2] + b[2]) * T::c(0.5);
        let (metal_alpha2, coat_alpha2) = (T::c(spec.metal_alpha2), T::c(spec.coat_alpha2));
        let (ei, eo) =
            (series_widening(metal_alpha2, coat_alpha2, a[2]), series_widening(metal_alpha2, coat_alpha2, b[2]));
        let added = match &self.base.blur {
            None => (ei, eo),
            Some(bl) => (bl.one_sided(wi_in.z) + ei, bl.one_sided(wo_in.z) + eo),
        };
        let (wi_lobe, wo_lobe) = if spec.at_mean_refraction {
            (self.coat.mean_refract_in(wi), self.coat.mean_refract_in(wo))
        } else {
            (wi_in, wo_in)
        };
        // Out of line (`Lanes::outlined`): only metal-base paints run it; inlined, it slowed
        // the flaked paints' AVX-512 eval and sample by 2–7 % (session 39).
        T::outlined(SeriesLobe {
            metal: m,
            f0: Rgb::from_array(m.f0),
            weight: T::c(m.weight),
            added,
            wi: wi_lobe,
            wo: wo_lobe,
            w,
            n_eff: Some(n_eff),
        })
    }

    /// The bounce series' albedo at `μo` (0 without it), the channels' mean.
    #[inline(always)]
    fn spec_albedo<T: Lanes>(&self, mu_o: T) -> T {
        match (&self.spec, &self.base.metal) {
            (Some(spec), Some(m)) => {
                let [s1, s0, _] = spec.albedo.eval_lanes(mu_o);
                let f0 = (m.f0[0] + m.f0[1] + m.f0[2]) / 3.0;
                T::c(m.weight) * (T::c(f0) * s1 + T::c(1.0 - f0) * s0)
            }
            _ => T::c(0.0),
        }
    }

    /// The multiple-scatter lobe `M(μi) M(μo) / (π M̄)`.
    #[inline(always)]
    fn multiple_term<T: Lanes>(&self, p: &AtPair<T>, o: &AtWo<T>) -> Rgb<T> {
        let (a, b) = (p.multiple, o.multiple);
        let n = self.multiple_norm.map(T::c);
        Rgb::new(a[0] * b[0] * n[0], a[1] * b[1] * n[1], a[2] * b[2] * n[2])
    }

    /// Evaluation with the flake populations' lobes scaled by `metal_scale` and `pearl_scale`
    /// (the sparkle layer plugs in here; 1 = the mean lobe, 0 = everything but the flakes,
    /// as explicit-flake simulations need).
    #[inline(always)]
    pub fn eval_scaled<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, metal_scale: T, pearl_scale: T) -> Rgb<T> {
        self.eval_parts(wi, wo, metal_scale, pearl_scale, PaintParts::ALL)
    }

    /// [`CoatedPaint::eval_scaled`] restricted to the lobes `parts` enables (see
    /// [`PaintParts`]); with [`PaintParts::ALL`] the same arithmetic as the full sum.
    #[inline(always)]
    pub fn eval_parts<T: Lanes>(
        &self,
        wi: Vec3<T>,
        wo: Vec3<T>,
        metal_scale: T,
        pearl_scale: T,
        parts: PaintParts,
    ) -> Rgb<T> {
        let o = self.at_wo(wo, parts);
        self.eval_pair(&self.at_pair_for_value(wi, &o), &o, metal_scale, pearl_scale, parts)
    }

    /// [`CoatedPaint::eval_parts`] at a pair of directions whose shared terms are known.
    #[inline(always)]
    fn eval_pair<T: Lanes>(
        &self,
        p: &AtPair<T>,
        o: &AtWo<T>,
        metal_scale: T,
        pearl_scale: T,
        parts: PaintParts,
    ) -> Rgb<T> {
        let mut f = if parts.coat { Rgb::splat(self.top_term(p, o)) } else { Rgb::zero() };
        if parts.pigment || parts.glossy {
            f += self.layer_term(p, o, metal_scale, pearl_scale, parts);
        }
        if parts.pigment {
            f += self.multiple_term(p, o);
        }
        f
    }

    /// The mixture density at a pair of directions whose shared terms are known, for the
    /// selection weights of `o` (restricted to `parts`, as [`Self::selection_at`] gives them).
    #[inline(always)]
    fn pdf_pair<T: Lanes>(&self, p: &AtPair<T>, o: &AtWo<T>, parts: PaintParts) -> T {
        let s = o.selection;
        let wi = p.top.wi;
        let total = s[0] + s[1] + s[2];
        let mut pdf = if parts.coat { s[0] * p.top_lobe.1 } else { T::c(0.0) };
        if parts.pigment || parts.glossy {
            let layer = s[1] * self.base.pdf_pair(&p.base, parts.base()) * self.coat.solid_angle_ratio(wi.z, p.wi_in.z);
            pdf += keep(lanes::gt(s[1], T::c(0.0)), layer);
        }
        if parts.pigment || parts.coat {
            let cosine = cosine_hemisphere_pdf(wi.z);
            pdf += s[2] * cosine;
            if parts.coat && self.coat.multiple_scattering().is_some() {
                // The coat's multiple-scattering share `ΔR(μo)` of the cosine weight draws its
                // azimuth from the lobe's wrapped Cauchy: density `A cos θi/π`
                // ([`super::coat::ms_pdf`]),
                // not `cos θi/π`.
                pdf += o.coat.ms * (cosine * p.ms_azimuthal - cosine);
            }
        }
        keep(lanes::gt(total, T::c(0.0)), lanes::div_fast(pdf, total))
    }

    /// The sum of the lobe-selection weights sampling gives the lobes `parts` enables, for an
    /// outgoing direction at `cos θo = mu_o`: sampling with [`PaintParts::ALL`] picks the lobes
    /// of `parts` with probability `selection_weight(μo, parts) / selection_weight(μo, ALL)`.
    /// What a renderer that shades two groups of lobes in two frames (a coat normal) mixes
    /// them with.
    #[must_use]
    pub fn selection_weight(&self, mu_o: f64, parts: PaintParts) -> f64 {
        let s = self.selection_parts(mu_o, parts);
        s[0] + s[1] + s[2]
    }

    /// The density of sampling restricted to `parts` ([`CoatedPaint::sample_parts`]).
    #[inline(always)]
    pub fn pdf_parts<T: Lanes>(&self, wi: Vec3<T>, wo: Vec3<T>, parts: PaintParts) -> T {
        let o = self.at_wo(wo, parts);
        self.pdf_pair(&self.at_pair(wi, &o), &o, parts)
    }

    /// Samples a direction (or the smooth coat's mirror delta) for the `wo` of `o`, per lane,
    /// choosing among the lobes `parts` enables.
    #[inline(always)]
    fn sample_direction_at<T: Lanes>(&self, o: &AtWo<T>, u: [T; 3], parts: PaintParts) -> SampledDirection<T> {
        let (wo, selection) = (o.wo, o.selection);
        let pick = pick3(selection, u[0]);
        let [top, layer, multiple] = pick.lobe;
        // Each lobe's sampler runs only when some lane chose it (for one lane: only the
        // chosen one); lanes that did not choose it never read its result.
        let normal = Vec3::from_f64(0.0, 0.0, 1.0);
        let w_top = if top.any() { self.coat.reflection_sample(wo, u[1], u[2]) } else { normal };
        // The pigment (inside) and the multiple-scatter lobe (outside) draw the same cosine
        // direction from (u1, u2), each for the lanes that chose it: on SIMD lanes, where both
        // run, it is drawn once (one lane draws it only for the lobe it chose).
        let pigment_drawn = layer.any() && self.base.selection_of(parts.base())[0] > 0.0;
        let cosine =
            if multiple.any() || (T::WIDTH > 1 && pigment_drawn) { Some(cosine_hemisphere(u[1], u[2])) } else { None };
        let (w_layer, layer_ok) = if layer.any() {
            let (wi_in, base_ok) = self.base.sample_direction_at(
                o.wo_in,
                [pick.u, u[1], u[2]],
                layer,
                parts.base(),
                FlakeSampler::Projected,
                o.blur,
                cosine,
            );
            let (w_layer, escapes) = self.coat.refract_out_masked(wi_in);
            (w_layer, base_ok & lanes::gt(wi_in.z, T::c(0.0)) & escapes)
        } else {
            (normal, T::Mask::splat(false))
        };
        let w_multiple = if multiple.any() {
            let w = match cosine {
                Some(w) => w,
                None => cosine_hemisphere(u[1], u[2]),
            };
            if parts.coat && self.coat.multiple_scattering().is_some() {
                // The cosine weight's first `ΔR(μo)` is the coat's multiple-scattering
                // reflection: its azimuth follows the lobe's wrapped Cauchy ([`ms_sample`]).
                let coat_ms = multiple & lanes::lt(pick.u * selection[2], o.coat.ms);
                if coat_ms.any() {
                    Vec3::select(coat_ms, ms_sample(wo, u[1], u[2]), w)
                } else {
                    w
                }
            } else {
                w
            }
        } else {
            normal
        };
        let wi = Vec3::select(top, w_top, Vec3::select(layer, w_layer, w_multiple));
        let valid = pick.valid & (top | (layer & layer_ok) | multiple);
        let delta = if self.coat.is_smooth() { top } else { T::Mask::splat(false) };
        SampledDirection { wi, valid, delta, selection }
    }

    /// Probability of the smooth coat's mirror lobe for `wo`'s selection weights `s`.
    #[inline(always)]
    fn delta_probability<T: Lanes>(&self, s: [T; 3]) -> T {
        s[0] / (s[0] + s[1] + s[2])
    }
}

/// A direction drawn by [`CoatedPaint::sample_direction_at`], per lane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampledDirection<T: Lanes> {
    /// The direction.
    pub wi: Vec3<T>,
    /// Lanes with a direction (a lobe was picked and the light escapes the coat).
    pub valid: T::Mask,
    /// Lanes that chose the smooth coat's mirror lobe.
    pub delta: T::Mask,
    /// The lobe-selection weights for `wo`.
    pub selection: [T; 3],
}

/// What sampling, the value and the density share at one outgoing direction, per lane
/// ([`CoatedPaint::at_wo`]): computed once per lane group in a sample (the sampler, then the
/// value and the density at the drawn direction read it).
#[derive(Clone, Copy, Debug)]
struct AtWo<T: Lanes> {
    /// The outgoing direction.
    wo: Vec3<T>,
    /// `wo` refracted into the coat.
    wo_in: Vec3<T>,
    /// The coat's factors at `μo`.
    coat: CoatAt<T>,
    /// `M(μo)`.
    multiple: [T; 3],
    /// The lobe-selection weights ([`CoatedPaint::selection_at`]).
    selection: [T; 3],
    /// The transmission blur's added `α²` at `wo_in` ([`Basecoat::blur_added`]).
    blur: Option<T>,
}

/// What the value and the density share at one pair of directions, per lane
/// ([`CoatedPaint::at_pair`]).
#[derive(Clone, Copy, Debug)]
struct AtPair<T: Lanes> {
    /// `wi`, `wo` and the top surface's half vector.
    top: HalfPair<T>,
    /// The top surface's single-scattering reflection and its sampling density
    /// ([`Coat::reflection_eval_pdf_h`]).
    top_lobe: (T, T),
    /// `wi` refracted into the coat.
    wi_in: Vec3<T>,
    /// The coat's factors at `μi`.
    coat: CoatAt<T>,
    /// `M(μi)`.
    multiple: [T; 3],
    /// The coat's multiple-scattering azimuthal factor `A(wi, wo)` ([`ms_azimuthal`]; 0
    /// without that reflection).
    ms_azimuthal: T,
    /// The basecoat's shared terms at the refracted directions.
    base: BasePair<T>,
}

/// Which of the paint's lobes a call includes, from a lobe mask ([`crate::lobes::bits`]):
/// `COAT` the clearcoat's top reflection (glossy, or the mirror delta of a smooth coat);
/// `DIFFUSE` the pigment under the coat and the multiple-scatter lobe (light that bounced
/// more than once inside the stack leaves diffusely); `GLOSSY` the basecoat's glossy lobes
/// under the coat (metallic and pearlescent flakes, the metallic base).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PaintParts {
    /// The top reflection of the clearcoat.
    pub coat: bool,
    /// The pigment and the multiple-scatter lobe.
    pub pigment: bool,
    /// The flakes and the metallic base.
    pub glossy: bool,
}

impl PaintParts {
    /// Every lobe (the plain `eval` / `pdf` / `sample`).
    pub const ALL: Self = Self { coat: true, pigment: true, glossy: true };

    /// The parts a lobe mask enables (other bits are ignored here; `Material::select_lobes`
    /// rejects them).
    #[inline(always)]
    #[must_use]
    pub fn of(lobes: u32) -> Self {
        Self { coat: lobes & bits::COAT != 0, pigment: lobes & bits::DIFFUSE != 0, glossy: lobes & bits::GLOSSY != 0 }
    }

    /// The basecoat's share of these parts.
    #[inline(always)]
    #[must_use]
    pub fn base(self) -> BaseParts {
        BaseParts { pigment: self.pigment, glossy: self.glossy }
    }
}

impl CoatedPaint {
    /// The selectable lobe groups this paint has, as `(select bit, kind bits)` pairs
    /// ([`crate::lobes::bits`]): the pigment / multiple-scatter lobe (`DIFFUSE`, when the
    /// pigment or the multiple-scatter table is non-zero), the glossy base lobes (`GLOSSY`,
    /// with flakes or a metallic base), the coat's top reflection (`COAT`: `GLOSSY`, or
    /// `DELTA` for a smooth coat; absent for a coat of index 1).
    #[must_use]
    pub fn lobe_parts(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        let b = &self.base;
        let pigment = b.pigment.iter().any(|&x| x > 0.0) && (b.pigment_weight > 0.0 || b.pearl_coverage > 0.0);
        let multiple = self.multiple.values().iter().any(|v| v.iter().any(|&x| x > 0.0));
        if pigment || multiple {
            out.push((bits::DIFFUSE, bits::DIFFUSE));
        }
        if b.has_glossy() {
            out.push((bits::GLOSSY, bits::GLOSSY));
        }
        if self.coat.ior != 1.0 {
            out.push((bits::COAT, if self.coat.is_smooth() { bits::DELTA } else { bits::GLOSSY }));
        }
        out
    }

    /// [`Bxdf::eval_at`] restricted to `parts`.
    #[must_use]
    pub fn eval_at_parts<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint, parts: PaintParts) -> Rgb<T> {
        match &self.sparkle_layer {
            Some(s) if at.is_finite() => self.eval_sparkle(s, wi, wo, at, parts),
            _ => self.eval_parts(wi, wo, T::one(), T::one(), parts),
        }
    }

    /// [`Bxdf::sample_at`] restricted to `parts` (the density is [`CoatedPaint::pdf_parts`]).
    #[must_use]
    pub fn sample_at_parts<T: Real>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        at: &SurfacePoint,
        parts: PaintParts,
    ) -> Option<BsdfSample<T>> {
        match &self.sparkle_layer {
            Some(_) if at.is_finite() => self.sample_with(wo, u, parts, |wi| self.eval_at_parts(wi, wo, at, parts)),
            _ => self.sample_parts(wo, u, parts).into_option(),
        }
    }
}

/// Base-`b` radical inverse of `k` (Halton's sequence in base `b`).
fn radical_inverse_base(b: usize, mut k: usize) -> f64 {
    let (mut x, mut inv) = (0.0, 1.0 / b as f64);
    while k > 0 {
        x += (k % b) as f64 * inv;
        k /= b;
        inv /= b as f64;
    }
    x
}

/// The basecoat's mean albedo `ρ̄ = (1/π) ∫∫ f_b cos θi cos θo dωi dωo` (cosine-distributed
/// incidence), estimated with `n` points of the 5-D Halton-Hammersley set
/// `[(k + ½)/n, Φ₂(k), Φ₃(k), Φ₅(k + 1), Φ₇(k + 1)]`: the incidence direction from
/// `(Φ₅, Φ₇)` (from k + 1: the point (0, 0) maps to the horizon), the basecoat's own sample
/// from the other three. Every dimension is a different radical inverse, so the incidence
/// directions are independent of the samples. (Until issue 17 the incidence
/// came from point `k·7919 mod n` of the same 3-D set, which is not independent of point `k`:
/// ρ̄ was off by −15 % to +5 % per channel for flaked paints, +23 % for a white EON pigment.)
pub(crate) fn mean_albedo(base: &Basecoat, n: usize) -> [f64; 3] {
    let mut rho_bar = [0.0; 3];
    for k in 0..n {
        let w = cosine_hemisphere(radical_inverse_base(5, k + 1), radical_inverse_base(7, k + 1));
        if let Some(s) = base.sample_by(w, super::hammersley3(k, n), FlakeSampler::Visible) {
            for (c, r) in rho_bar.iter_mut().enumerate() {
                *r += s.weight[c] / n as f64;
            }
        }
    }
    rho_bar
}

/// What one basecoat sample contributes to [`layer_tables`].
struct BaseSampleTerms {
    /// The sample's weight attenuated on its way up to the coat's underside.
    up: [f64; 3],
    /// The coat's transmittance on its way out (`T` at the outside direction; 0 under total
    /// internal reflection).
    escape: f64,
    /// The crossing factor of the flakes on its way out ([`Coat::escape`]).
    escape_flakes: f64,
    /// The flakes' share of the sample (per channel, in [0, 1]; 0 unless the coat is rough
    /// and the basecoat has flakes: then that share crosses with [`Coat::crossing`]).
    flake_share: [f64; 3],
    /// What of the sample leaves as the flakes' first bounce, relative to the sample (per
    /// channel, ≥ 0; 0 unless the flakes' share is): the flakes' lobe at their map
    /// ([`Coat::flake_refract_in`]) of the sample's exit direction and the node's outside
    /// direction, over the basecoat's value at the sampled pair. The sample stands for
    /// `f μ'/pdf` at the macro-refracted inside direction `w'`; the layer term sees the flakes
    /// at the mapped pair of the outside directions, and `μ dω = η² μ' dω'` turns its
    /// albedo into an integral over `w'` with that value in place of the sample's.
    flake_out_share: [f64; 3],
    /// The metal lobe's share of the sample (per channel, in [0, 1]; zero without `spec_series`).
    metal_share: [f64; 3],
}

/// One basecoat sample seen from `w_in` (inside the coat) for [`layer_tables`].
///
/// Not inlined on purpose (the same cause as `check::precision::both_paths`): inlined into the
/// sample loop, the optimiser hoisted the loop-invariant parts of the basecoat's optional lobes
/// (the metal base, the coat's transmission blur) into the loop preheader and branched on the
/// unused bytes of a `None`, which hold whatever the stack held when `CoatedPaint::build` made
/// the basecoat. The tables never depended on them, but valgrind (c-api/test.sh) reported
/// "conditional jump depends on uninitialised value" in `layer_tables` and in the `exp` it calls.
#[inline(never)]
fn base_sample_terms(
    coat: &Coat,
    base: &Basecoat,
    w: Vec3<f64>,
    w_in: Vec3<f64>,
    u: [f64; 3],
    spec_series: bool,
) -> Option<BaseSampleTerms> {
    let s = base.sample_by(w_in, u, FlakeSampler::Visible)?;
    let a_v = coat.attenuation(s.wi.z);
    let escape = coat.refract_out(s.wi).map_or(0.0, |v| coat.transmittance(v.z));
    let split = coat.has_crossing() && base.flakes.is_some();
    // `f_b` and the two components whose shares are needed, each lobe evaluated once: `f_b`
    // is summed as `Basecoat::eval` sums it (pigment, + metal, + flakes), so it is the same
    // value bit for bit.
    let (metal, flakes, fb) = if spec_series || split {
        let metal = base.metal_eval(s.wi, w_in);
        let flakes = base.flakes_eval(s.wi, w_in, 1.0, 1.0);
        let mut fb = base.eval_parts(s.wi, w_in, 1.0, 1.0, BaseParts { pigment: true, glossy: false });
        if base.metal.is_some() {
            fb += metal;
        }
        if base.flakes.is_some() {
            fb += flakes;
        }
        (metal, flakes, fb)
    } else {
        (Rgb::zero(), Rgb::zero(), Rgb::zero())
    };
    let share = |f: Rgb<f64>| [0, 1, 2].map(|c| if fb[c] > 0.0 { (f[c] / fb[c]).clamp(0.0, 1.0) } else { 0.0 });
    let metal_share = if spec_series { share(metal) } else { [0.0; 3] };
    let (escape_flakes, flake_share, flake_out_share) = if split {
        let mapped = match coat.refract_out(s.wi) {
            Some(v) => base.flakes_eval(coat.flake_refract_in(v), coat.flake_refract_in(w), 1.0, 1.0),
            None => Rgb::zero(),
        };
        let out_share = [0, 1, 2].map(|c| if fb[c] > 0.0 { mapped[c].max(0.0) / fb[c] } else { 0.0 });
        (coat.escape(s.wi), share(flakes), out_share)
    } else {
        (escape, [0.0; 3], [0.0; 3])
    };
    Some(BaseSampleTerms {
        up: [0, 1, 2].map(|c| s.weight[c] * a_v[c]),
        escape,
        escape_flakes,
        flake_share,
        flake_out_share,
        metal_share,
    })
}

/// Builds `A1(μ)` and `M(μ)` (see the module docs) by stratified sampling of the basecoat.
/// The flakes are sampled by their visible normals here ([`FlakeSampler::Visible`]: lower
/// variance than the render-time closed form, see docs/speed.md).
///
/// With `spec_series` (a metallic base, [`super::spec_series`]) the metal's share of what
/// the coat reflects back down, `R_spec`, leaves through the bounce series instead: `M` keeps
/// `bounce · (R − R_spec)`, split per sample by the metal lobe's share `f_metal/f_b` of the
/// basecoat's value (non-negative by construction).
fn layer_tables(coat: &Coat, base: &Basecoat, spec_series: bool) -> (MuTable, MuTable) {
    // Mean escape probability e, mean crossing transmittance τ̄ (cosine-distributed light
    // inside), and the basecoat's mean albedo ρ̄ for cosine-distributed incidence.
    let quad = 512;
    let (mut escape, mut tau) = (0.0, [0.0; 3]);
    for k in 0..quad {
        let mu = (k as f64 + 0.5) / quad as f64;
        let w = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let weight = 2.0 * mu / quad as f64;
        if let Some(out) = coat.refract_out(w) {
            escape += weight * coat.transmittance(out.z);
        }
        let a = coat.attenuation(mu);
        for c in 0..3 {
            tau[c] += weight * a[c];
        }
    }
    let n = TABLE_SAMPLES;
    let points: Vec<[f64; 3]> = (0..n).map(|k| super::hammersley3(k, n)).collect();
    // An energy-conserving basecoat has ρ̄ ≤ 1; an estimate above it (noise, for a white
    // pigment) would make the bounce series return more than it received.
    // ρ̄ is the basecoat's as it is (without the coat's transmission blur, which changes the
    // shape of its specular lobes, not their energy much): the per-element tables
    // (`super::varying`) share one ρ̄ for every coat roughness.
    let bare = base.clone().with_blur(None);
    let rho_bar = mean_albedo(&bare, MEAN_ALBEDO_SAMPLES).map(|r: f64| r.min(1.0));
    let bounce: [f64; 3] = [0, 1, 2].map(|c| {
        let r = tau[c] * tau[c] * rho_bar[c];
        let denom = 1.0 - r * (1.0 - escape);
        if denom > 1e-12 {
            r * escape / denom
        } else {
            1.0
        }
    });

    // The nodes are independent: they run on up to `batch::thread_count()` threads, each node
    // summing its samples in the same order as on one thread (the same tables, bit for bit).
    let nodes = crate::parallel::map_indices(TABLE_NODES, |k| {
        let mu = (k as f64 / (TABLE_NODES - 1) as f64).max(1e-4);
        let w = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        // What enters (T) and the flakes' crossing factor (g ≤ T; g = T for a smooth coat):
        // of the light that enters, the single-scatter term lets out `T·T_out` of the
        // pigment's and the metal's share and `g·g_out` of the flakes'.
        let (t_w, g_w) = (coat.transmittance(mu), coat.crossing(mu));
        let g_over_t = if t_w > 0.0 { g_w / t_w } else { 0.0 };
        let w_in = coat.refract_in(w);
        let a_w = coat.attenuation(w_in.z);
        let (mut up, mut out, mut out_flakes, mut rest) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        for u in &points {
            let Some(t) = base_sample_terms(coat, base, w, w_in, *u, spec_series) else { continue };
            for c in 0..3 {
                let (q, p, q_out) = (t.flake_share[c], 1.0 - t.flake_share[c], t.flake_out_share[c]);
                up[c] += t.up[c];
                out[c] += t.up[c] * p * t.escape;
                out_flakes[c] += t.up[c] * q_out * t.escape_flakes;
                // Not let out and not the metal's: `(1 − esc)(1 − metal)` as for a smooth
                // coat, plus what the flakes' crossing and map keep in (`q esc − q_out g_out g/T`).
                rest[c] += t.up[c] * (1.0 - t.escape) * (1.0 - t.metal_share[c])
                    + t.up[c] * (q * t.escape - q_out * t.escape_flakes * g_over_t);
            }
        }
        let norm = n as f64;
        let a1: [f64; 3] = [0, 1, 2].map(|c| (t_w * a_w[c] * out[c] + g_w * a_w[c] * out_flakes[c]) / norm);
        let u: [f64; 3] = [0, 1, 2].map(|c| t_w * a_w[c] * up[c] / norm);
        let m = if spec_series {
            // What the pigment and the flakes send back down, `R − R_spec` (each term ≥ 0).
            [0, 1, 2].map(|c| bounce[c] * t_w * a_w[c] * rest[c] / norm)
        } else {
            [0, 1, 2].map(|c| (bounce[c] * (u[c] - a1[c])).max(0.0))
        };
        (a1, m)
    });
    let (single, multiple): (Vec<_>, Vec<_>) = nodes.into_iter().unzip();
    (MuTable::from_values(single), MuTable::from_values(multiple))
}

impl LaneBxdf for CoatedPaint {
    #[inline(always)]
    fn eval_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> Rgb<L> {
        self.eval_scaled(wi, wo, L::c(1.0), L::c(1.0))
    }

    #[inline(always)]
    fn eval_scaled_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, scale: [L; 2]) -> Rgb<L> {
        self.eval_scaled(wi, wo, scale[0], scale[1])
    }

    #[inline(always)]
    fn pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> L {
        self.pdf_parts(wi, wo, PaintParts::ALL)
    }

    #[inline(always)]
    fn sample_lanes<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3]) -> LaneSample<L> {
        self.sample_parts(wo, u, PaintParts::ALL)
    }

    #[inline(always)]
    fn eval_lobes_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, scale: [L; 2], lobes: u32) -> Rgb<L> {
        self.eval_parts(wi, wo, scale[0], scale[1], PaintParts::of(lobes))
    }

    #[inline(always)]
    fn pdf_lobes_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>, lobes: u32) -> L {
        self.pdf_parts(wi, wo, PaintParts::of(lobes))
    }

    #[inline(always)]
    fn sample_lobes_lanes<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3], lobes: u32) -> LaneSample<L> {
        self.sample_parts(wo, u, PaintParts::of(lobes))
    }

    const SHARES_EVAL_PDF: bool = true;

    /// The value and the density sharing their refractions, half vectors, table values and
    /// the coat's azimuthal factor ([`AtWo`], [`AtPair`]).
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(&self, wi: Vec3<L>, wo: Vec3<L>) -> (Rgb<L>, L) {
        let o = self.at_wo(wo, PaintParts::ALL);
        let p = self.at_pair(wi, &o);
        (self.eval_pair(&p, &o, L::c(1.0), L::c(1.0), PaintParts::ALL), self.pdf_pair(&p, &o, PaintParts::ALL))
    }
}

impl CoatedPaint {
    /// A sample among the lobes `parts` enables (their selection weights renormalised; the
    /// weight is the restricted `f · cos / pdf`); [`PaintParts::ALL`] is [`Bxdf::sample`].
    #[inline(always)]
    pub fn sample_parts<L: Lanes>(&self, wo: Vec3<L>, u: [L; 3], parts: PaintParts) -> LaneSample<L> {
        let o = self.at_wo(wo, parts);
        let d = self.sample_direction_at(&o, u, parts);
        // Lanes without a sample (total internal reflection leaves a direction of zero `z`
        // and a tangent part longer than one; a reflection below the horizon) are evaluated
        // at `wo`'s mirror direction instead, a unit vector above the surface, and dropped
        // below as before. Left as they were, they failed the whole lane group's shortcuts
        // that assume unit directions (Beckmann's negligible `Λ` in the flakes' masking:
        // the full formula ran in most groups of `gold_flake_8`'s sampler). The sampled
        // lanes' values are the same bit for bit. The value and the density at the drawn
        // direction share their refractions, half vectors, table values and the coat's
        // azimuthal factor ([`AtPair`]).
        let drawn = d.valid & lanes::gt(d.wi.z, L::c(0.0));
        let p = self.at_pair(Vec3::select(drawn, d.wi, crate::frame::mirror_z(wo)), &o);
        let f = self.eval_pair(&p, &o, L::c(1.0), L::c(1.0), parts);
        let pdf = self.pdf_pair(&p, &o, parts);
        let s = LaneSample::from_eval(d.wi, f, pdf, drawn);
        if !self.coat.is_smooth() {
            return s;
        }
        // The smooth coat's mirror lobe: a delta with the lobe's probability as its "pdf".
        let p = self.delta_probability(d.selection);
        let w = d.selection[0] / p;
        LaneSample {
            wi: d.wi,
            weight: Rgb::select(d.delta, Rgb::splat(w), s.weight),
            pdf: lanes::select(d.delta, p, s.pdf),
            valid: (d.delta & d.valid & lanes::gt(p, L::c(0.0))) | (!d.delta & s.valid),
            delta: d.delta,
        }
    }
}

impl Bxdf for CoatedPaint {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        self.eval_lanes(wi, wo)
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        self.pdf_lanes(wi, wo)
    }

    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        self.sample_lanes(wo, u).into_option()
    }

    #[inline]
    fn eval_at<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint) -> Rgb<T> {
        match &self.sparkle_layer {
            Some(s) if at.is_finite() => self.eval_sparkle(s, wi, wo, at, PaintParts::ALL),
            _ => self.eval(wi, wo),
        }
    }

    fn sample_at<T: Real>(&self, wo: Vec3<T>, u: [T; 3], at: &SurfacePoint) -> Option<BsdfSample<T>> {
        match &self.sparkle_layer {
            Some(_) if at.is_finite() => self.sample_with(wo, u, PaintParts::ALL, |wi| self.eval_at(wi, wo, at)),
            _ => self.sample(wo, u),
        }
    }

    #[inline]
    fn spatially_varying(&self) -> bool {
        self.sparkle_layer.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Material;

    fn paint(json: &str) -> CoatedPaint {
        match Material::from_json(json).unwrap().model() {
            Model::CoatedPaint(p) => p.clone(),
            _ => unreachable!(),
        }
    }

    /// Issue 17, item 4: pearl flakes are platelets by default (the film on both faces of the
    /// mica): the flake reflectance at normal incidence on the flake is the platelet's
    /// spectral RGB (quarter-wave TiO₂: about 0.37 against 0.23 for one film), the pigment
    /// behind sees `1 − R` of it; `pearl_structure = film` keeps the one-film values. Table
    /// node at μ = 1: exact to rounding (asserted 1e-12).
    #[test]
    fn pearl_flakes_are_platelets_unless_asked_for_one_film() {
        let json = |structure: &str| {
            format!(
                r#"{{"model": "coated_paint", "pearl_density": 10, "pearl_film_nm": 52.9, "pearl_film_ior": 2.6{structure}}}"#
            )
        };
        let film = ThinFilm { thickness_nm: 52.9, film_ior: 2.6, substrate_ior: 1.58, medium_ior: 1.5 };
        for (structure, want) in
            [("", film.platelet_spectral_rgb(1.0)), (r#", "pearl_structure": "film""#, film.spectral_rgb(1.0))]
        {
            let p = paint(&json(structure));
            let flakes = p.base.flakes.as_ref().unwrap();
            let got = flakes.pearl_reflectance(1.0f64);
            let through = p.base.pearl_transmission.as_ref().unwrap().eval::<f64>(1.0);
            eprintln!("pearl_structure {structure:?}: R(1) = {got:?}");
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() < 1e-12, "{structure}: {got:?} vs {want:?}");
                assert!((through[c] - (1.0 - want[c])).abs() < 1e-12, "{structure}: {through:?}");
            }
        }
        let (one, both) = (film.spectral_rgb(1.0), film.platelet_spectral_rgb(1.0));
        assert!(both[1] > one[1] + 0.1, "platelet {both:?} vs one film {one:?}");
    }

    /// Issue 17, item 3: the rough coat's transmission blur vanishes as the coat smooths. A
    /// smooth coat (α = 0) gives the basecoat no blur at all (the old model, bit for bit); at
    /// α = 0.001 the blurred metal base (α 0.05; the flakes take no blur) is within 1e-3 of the unblurred
    /// ones (relative to the largest value; the added `α²` is at most 2·c·0.25·1e-6 = 2.3e-6,
    /// `c(0.001)` = 4.66 ([`super::super::coat::ggx_slope_variance`]), against 2.5e-3, so `D`
    /// moves by at most ≈ 9e-4 near the peak; measured 7.5e-4, 2.8e-4 with the constant
    /// `c` = 1.75 before session 23); at
    /// α 0.2 they are not (asserted > 10 % somewhere, so the test can fail).
    /// The blurred lobe is reciprocal (asserted 1e-12 relative) and, for fixed `wo'`, below the
    /// normalised one-sided lobe (asserted pointwise, to 1e-12 relative rounding).
    #[test]
    fn transmission_blur_vanishes_as_the_coat_smooths_and_keeps_reciprocity() {
        let json = |alpha: f64| {
            format!(
                r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 8, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9, "sparkle": false}}"#
            )
        };
        assert!(paint(&json(0.0)).base.blur.is_none());
        let mut rng = crate::rng::Pcg32::new(17, 3);
        let dirs: Vec<(Vec3<f64>, Vec3<f64>)> = (0..400)
            .map(|_| {
                let wo = crate::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
                // Around the mirror direction (where the sharp lobes are) and anywhere.
                let m = crate::frame::mirror_z(wo);
                let j = Vec3::new(0.2 * (rng.uniform() - 0.5), 0.2 * (rng.uniform() - 0.5), 0.0);
                let wi = if rng.uniform() < 0.5 {
                    (m + j).normalize()
                } else {
                    crate::sampling::uniform_hemisphere(rng.uniform(), rng.uniform())
                };
                (wi, wo)
            })
            .filter(|(wi, wo)| wi.z > 0.05 && wo.z > 0.05)
            .collect();
        for (alpha, limit) in [(0.001, Some(1e-3)), (0.2, None)] {
            let p = paint(&json(alpha));
            let blurred = &p.base;
            let bare = p.base.clone().with_blur(None);
            let (mut worst, mut scale) = (0.0f64, 0.0f64);
            for (wi, wo) in &dirs {
                let (a, b) = (blurred.eval(*wi, *wo), bare.eval(*wi, *wo));
                scale = scale.max(b.max_channel());
                worst = worst.max((a - b).max_channel().abs().max((b - a).max_channel().abs()));
                let r = blurred.eval(*wo, *wi);
                for c in 0..3 {
                    assert!((a[c] - r[c]).abs() <= 1e-12 * a[c].abs().max(1e-300), "α {alpha}: {a:?} vs {r:?}");
                }
                // Below the one-sided lobe seen from wo (the normalised one).
                let blur = blurred.blur.unwrap();
                let m = blurred.metal.as_ref().unwrap();
                let one =
                    m.eval_with(&m.blurred(blur.one_sided(wo.z)), None, Rgb::from_array(m.f0), m.weight, *wi, *wo);
                let ours = m.eval_with(
                    &m.blurred(blur.one_sided(wo.z)),
                    Some(&m.blurred(blur.one_sided(wi.z))),
                    Rgb::from_array(m.f0),
                    m.weight,
                    *wi,
                    *wo,
                );
                // (to rounding: the two products are associated differently)
                assert!(ours.max_channel() <= one.max_channel() * (1.0 + 1e-12), "{ours:?} vs {one:?}");
            }
            let rel = worst / scale;
            eprintln!("coat α {alpha}: largest |f_blur − f| / max f = {rel:.2e}");
            match limit {
                Some(l) => assert!(rel < l, "α {alpha}: {rel}"),
                None => assert!(rel > 0.1, "α {alpha}: the blur should show: {rel}"),
            }
        }
    }

    /// The paint's sampled lobe against the position-free reference's walks at `wo`, `walks`
    /// of each drawn alternately from `rng`: the lobe-shape error (relative L2 difference of the
    /// two lobes, each normalised to unit albedo, over 12 × 6 equal-solid-angle bins) and the
    /// two albedo estimates (analytic, reference).
    fn lobe_against_the_reference(
        p: &CoatedPaint,
        wo: Vec3<f64>,
        walks: usize,
        rng: &mut crate::rng::Pcg32,
    ) -> (f64, f64, f64) {
        use crate::paint::position_free_mc::{lobe_bin, PositionFreeMc};
        let (n_mu, n_phi) = (12, 6);
        let mc = PositionFreeMc::new(p);
        let (mut r, mut a) = (vec![0.0; n_mu * n_phi], vec![0.0; n_mu * n_phi]);
        for _ in 0..walks {
            if let Some(e) = mc.albedo_walk_exit(wo, rng) {
                r[lobe_bin(e.direction, 0.0, n_mu, n_phi)] += e.weight.luminance();
            }
            if let Some(s) = p.sample(wo, rng.uniform3()) {
                if s.wi.z > 0.0 {
                    a[lobe_bin(s.wi, 0.0, n_mu, n_phi)] += s.weight.luminance();
                }
            }
        }
        let (ta, tr): (f64, f64) = (a.iter().sum(), r.iter().sum());
        let (mut num, mut den) = (0.0, 0.0);
        for k in 0..a.len() {
            num += (a[k] / ta - r[k] / tr).powi(2);
            den += (r[k] / tr).powi(2);
        }
        ((num / den).sqrt(), ta / walks as f64, tr / walks as f64)
    }

    /// Issue 17, item 3: under a rough coat (α 0.2) the sharp metal base's lobe is blurred as
    /// the lossless reference's (multiple-scattering interface) is. Lobe-shape error: the
    /// relative L2 difference of the two lobes normalised to unit albedo over 12 × 6
    /// equal-solid-angle bins, 100 000 reference walks and analytic samples per view, noise
    /// floor ≈ 1.5 %. Without the blur: 20.6 % (θo 0°) and 58.7 % (θo 40°) (§8 of
    /// docs/paint-validation.md, 400 000 walks); with it measured 1.4 % / 4.2 % here (2.3 % /
    /// 6.4 % with the constant slope-variance factor before session 23).
    /// Asserted ≤ 10 % (the old model fails both views). 0.25 s in release.
    #[test]
    fn rough_coat_blurs_a_sharp_metal_base_as_the_reference() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.2, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}"#,
        );
        for theta in [0.0f64, 40.0] {
            let t = theta.to_radians();
            let wo = Vec3::new(t.sin(), 0.0, t.cos());
            let mut rng = crate::rng::Pcg32::new(0xb1, theta as u64);
            let (err, analytic, reference) = lobe_against_the_reference(&p, wo, 100_000, &mut rng);
            eprintln!("θo {theta}°: lobe-shape error {:.2} %, albedo {analytic:.4} vs {reference:.4}", 100.0 * err);
            assert!(err < 0.10, "θo {theta}°: lobe-shape error {err}");
        }
    }

    /// Issue 17, item 3 (session 23): the transmission blur's slope-variance factor depends on
    /// the coat's roughness ([`super::super::coat::ggx_slope_variance`]); the flakes take no
    /// blur and are seen at their share of the mean refraction
    /// ([`super::super::coat::FLAKE_MEAN_REFRACTION_SHARE`], session 40). Against the lossless
    /// reference (100 000 walks each): a metal base (α 0.05) under α 0.1 at θo 40°, lobe-shape
    /// error measured 3.2 % (raw L2, noise included; the constant factor 1.75: 7.3 % at 400 000
    /// walks with the noise removed, docs §8), asserted 5 %; Al flakes 8 % under α 0.3 at θo
    /// 40°, albedo error measured −0.36 % (session 23's quarter of the blur: −0.75 %; the whole
    /// blur: −4.05 % at 400 000 walks), asserted within 2.5 %. The factor itself at the
    /// calibration points: 3.76, 2.56, 1.95, 1.77 at α 0.03, 0.1, 0.2, 0.3 (asserted 0.01).
    #[test]
    fn rough_coat_blur_is_calibrated_per_roughness_and_per_lobe() {
        for (alpha, c) in [(0.03f64, 3.762), (0.1, 2.560), (0.2, 1.946), (0.3, 1.771)] {
            let got: f64 = super::super::coat::ggx_slope_variance(alpha);
            assert!((got - c).abs() < 0.01, "c({alpha}) = {got}");
        }
        let t = 40f64.to_radians();
        let wo = Vec3::new(t.sin(), 0.0, t.cos());
        let metal = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.1, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}"#,
        );
        let mut rng = crate::rng::Pcg32::new(0xca1, 40);
        let (err, analytic, reference) = lobe_against_the_reference(&metal, wo, 100_000, &mut rng);
        eprintln!(
            "metal base, coat α 0.1, θo 40°: lobe-shape error {:.2} %, albedo {analytic:.4} vs {reference:.4}",
            100.0 * err
        );
        assert!(err < 0.05, "metal base lobe-shape error {err}");
        let flakes = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.3, "flake_density": 8, "base_color": [0.05, 0.05, 0.06]}"#,
        );
        let mut rng = crate::rng::Pcg32::new(0xca2, 40);
        let (err, analytic, reference) = lobe_against_the_reference(&flakes, wo, 100_000, &mut rng);
        let albedo_err = analytic / reference - 1.0;
        eprintln!(
            "Al flakes, coat α 0.3, θo 40°: albedo {:+.2} %, lobe-shape error {:.2} %",
            100.0 * albedo_err,
            100.0 * err
        );
        assert!(albedo_err.abs() < 0.025, "Al flakes albedo error {albedo_err}");
    }

    /// Issue 17, item 3: the metal base's specular bounce series ([`super::super::spec_series`]).
    /// A sharp metal base (α 0.05, F0 0.9) under a nearly smooth coat (α 0.01) at θo 75°: the
    /// light the coat sends back down (near the critical angle) stays near the mirror direction
    /// in the reference (100 000 walks). Measured: lobe-shape error 0.86 % (raw L2, noise
    /// included), albedo +0.39 % (session 39; 4.8 % and −0.1 % when the series was first
    /// added); asserted 10 % and 2 %. The old model (that light in the
    /// diffuse `M` lobe): 21 % and +9.3 %. Also: the series is reciprocal (1e-12 relative), a
    /// pigment or flake paint has none (the old model bit for bit), and a white metal (F0 1)
    /// under a smooth and a rough coat keeps its albedo ≤ 1 (`E_top + ΔR + A1 + S + M` at the
    /// series' nodes from μ 1e-3, `A1` under a rough coat the first bounce's own albedo at the
    /// mean refraction, `spec_series::first_bounce_albedo`; asserted 1 + 1e-9). 1.2 s in release.
    #[test]
    fn metal_base_bounce_series_keeps_grazing_light_near_the_mirror_direction() {
        assert!(paint(r#"{"model": "coated_paint", "flake_density": 8}"#).spec.is_none());
        assert!(paint(r#"{"model": "coated_paint", "flake_density": 0, "coat_roughness": 0.2}"#).spec.is_none());
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.01, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}"#,
        );
        assert!(p.spec.is_some());
        let t = 75f64.to_radians();
        let wo = Vec3::new(t.sin(), 0.0, t.cos());
        let mut rng = crate::rng::Pcg32::new(0x5e7, 75);
        let (err, analytic, reference) = lobe_against_the_reference(&p, wo, 100_000, &mut rng);
        let albedo_err = analytic / reference - 1.0;
        eprintln!("θo 75°, coat α 0.01: lobe-shape error {:.2} %, albedo {:+.2} %", 100.0 * err, 100.0 * albedo_err);
        assert!(err < 0.10, "lobe-shape error {err}");
        assert!(albedo_err.abs() < 0.02, "albedo error {albedo_err}");
        // Reciprocity of the whole paint (the series included).
        let mut rng = crate::rng::Pcg32::new(0x5e8, 1);
        for _ in 0..200 {
            let (wi, wo) =
                (cosine_hemisphere(rng.uniform(), rng.uniform()), cosine_hemisphere(rng.uniform(), rng.uniform()));
            let (f, g) = (p.eval(wi, wo), p.eval(wo, wi));
            for c in 0..3 {
                assert!((f[c] - g[c]).abs() <= 1e-12 * f[c].abs().max(1e-300), "{f:?} vs {g:?}");
            }
        }
        // Energy: a white metal base keeps E_top + ΔR + A1 + S + M ≤ 1 per table node.
        for alpha in [0.0, 0.1, 0.3] {
            let w = paint(&format!(
                r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 1.0}}"#
            ));
            let spec = w.spec.as_ref().unwrap();
            let points: Vec<[f64; 3]> = (0..2048).map(|k| crate::sampling::hammersley3(k, 2048)).collect();
            let metal = w.base.metal.clone().unwrap();
            // At the series' own nodes (its weights are capped there). The first node is
            // taken at μ 1e-3 (as the session-36 version of this test): the series builds it
            // at μ 1e-4 (θ 89.994°), where the tables' linear interpolation between μ 0 and
            // the next node gives a total of 1 + 1.4e-4 under the smooth coat (measured).
            let nodes = spec.albedo.values().len();
            for k in 0..nodes {
                let mu = (k as f64 / (nodes - 1) as f64).max(1e-3);
                let (mut a1, m) = w.layer_albedos(mu);
                if w.coat.has_mean_refraction() {
                    // The first bounce at the mean refracted directions: its own albedo (the
                    // `A1` table keeps the macro refraction's, a sampling weight).
                    a1 = super::super::spec_series::first_bounce_albedo(&w.coat, &metal, mu, &points, true);
                }
                let s = spec.albedo.eval::<f64>(mu)[0];
                let total = w.coat.reflectance(mu) + w.coat.ms_albedo(mu) + a1[0] + s + m[0];
                assert!(total <= 1.0 + 1e-9, "α {alpha}, μ {mu}: {total}");
                assert!(m.iter().all(|&x| x >= 0.0));
            }
        }
    }

    /// `eval_series_term` is the part of the layer term that the bounce series adds: the
    /// paint's layer term less the same paint's without its series, on a rough coat (with and
    /// without flakes, whose crossing takes the other branch of `layer_term`) and a smooth
    /// one; zero for a paint without a metallic base. The bound, 1e-12 of the layer term, is for
    /// the rounding of the subtraction (the two layer terms are sums of the same f64 parts).
    #[test]
    fn series_term_is_what_the_series_adds_to_the_layer_term() {
        let flat = paint(r#"{"model": "coated_paint", "flake_density": 8, "coat_roughness": 0.2}"#);
        assert!(flat.eval_series_term(Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(0.0, 0.0, 1.0)) == Rgb::zero());
        for json in [
            r#"{"model": "coated_paint", "coat_roughness": 0.3, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}"#,
            r#"{"model": "coated_paint", "coat_roughness": 0.1, "flake_density": 5, "base_metallic": 0.6, "base_roughness": 0.1, "base_color": [0.8, 0.5, 0.2], "coat_absorption": [0.2, 0.1, 0.0]}"#,
            r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}"#,
        ] {
            let p = paint(json);
            assert!(p.spec.is_some(), "{json}");
            let mut without = p.clone();
            without.spec = None;
            let mut rng = crate::rng::Pcg32::new(0x5e71e5, 3);
            let mut positive = 0;
            for _ in 0..2000 {
                let (wi, wo) =
                    (cosine_hemisphere(rng.uniform(), rng.uniform()), cosine_hemisphere(rng.uniform(), rng.uniform()));
                let (full, rest) = (p.eval_terms(wi, wo)[1], without.eval_terms(wi, wo)[1]);
                let series = p.eval_series_term(wi, wo);
                for c in 0..3 {
                    let expected = full[c] - rest[c];
                    assert!(
                        (series[c] - expected).abs() <= 1e-12 * full[c].abs().max(1e-300),
                        "{json}: {series:?} against {expected} (channel {c})"
                    );
                    assert!(series[c] >= 0.0);
                }
                positive += usize::from(series.r > 0.0);
            }
            // The widened lobe reaches every pair: measured 2000 of 2000 for each paint here.
            eprintln!("{json}: {positive} of 2000 pairs with a positive series term");
            assert!(positive > 1000, "{json}: {positive} pairs with a positive series term");
        }
    }

    /// Issue 17, item 3 (third and sixth pass): the albedo of a sharp metal base (α 0.05, F0
    /// 0.9) under rough coats against the lossless reference (100 000 walks and analytic
    /// samples per view, noise ±0.5 %), at the cells that missed the 2 % goal before session 35:
    /// +2.3 % (coat α 0.1, θo 75°), +2.1 % / −8.1 % (α 0.3, θo 0° / 75°; §8 of
    /// docs/paint-validation.md, 400 000 walks) — the bounce series returned what the blurred
    /// `min` lobe sends back down, with too few later bounces. Now its target and `n` come from
    /// walks with the reference's physics (`spec_series::reference_walks`). Measured here
    /// (100 000): +0.91 / +0.83 / +0.86 / +1.37 / +0.65 / +0.60 % (+1.13 / +0.97 / +1.38 / +1.12 /
    /// +0.91 / −0.49 % with a quarter of the first-bounce walks, `spec_series::FIRST_BOUNCE_FACTOR`);
    /// with the series' width per later bounce and the smoothed walks (session 36) +1.09 /
    /// +0.92 / +0.79 / +1.39 / +0.63 / −0.31 %; with the first bounce at the mean refracted
    /// directions (session 37) −0.23 / −0.37 / −0.81 / −0.13 / −0.81 / −1.55 %. Asserted: within
    /// the 2 % goal at each cell (the old model fails three). ≈ 3 s in release.
    #[test]
    fn rough_coat_metal_base_albedo_against_the_reference() {
        for (alpha, theta) in [(0.1, 75.0), (0.2, 40.0), (0.2, 75.0), (0.3, 0.0), (0.3, 40.0), (0.3, 75.0)] {
            let p = paint(&format!(
                r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}}"#
            ));
            let t = f64::to_radians(theta);
            let wo = Vec3::new(t.sin(), 0.0, t.cos());
            let mut rng = crate::rng::Pcg32::new(0x3e7a1, theta as u64);
            let (_, analytic, reference) = lobe_against_the_reference(&p, wo, 100_000, &mut rng);
            let err = analytic / reference - 1.0;
            eprintln!("coat α {alpha}, θo {theta}°: albedo {analytic:.4} vs {reference:.4} ({:+.2} %)", 100.0 * err);
            assert!(err.abs() < 0.02, "coat α {alpha}, θo {theta}°: albedo error {err}");
        }
    }

    /// Issue 17, item 3 (seventh pass): the shape of a sharp metal base's lobe (α 0.05, F0 0.9)
    /// at grazing view (θo 75°) under coats of α 0.01–0.3 against the lossless
    /// reference (200 000 walks and analytic samples per cell; raw L2 of
    /// `lobe_against_the_reference`, the noise included). There half the light that crosses
    /// the coat leaves after two or more metal bounces (trapped beyond the critical angle),
    /// in a lobe as wide as that many bounces make it; the bounce series widened by one round
    /// trip at every direction gave 4.8 / 5.2 / 6.1 % (400 000 walks with the noise floor
    /// removed, §8 of docs/paint-validation.md, so more here), the widening per later bounce
    /// ([`super::super::spec_series::series_widening`]) measured 0.71 / 1.20 / 3.73 % here; with the
    /// first bounce at the mean refracted directions (session 37, `Coat::mean_refract_in`)
    /// 0.68 / 1.81 / 3.45 % and 2.93 % at α 0.2 (5.8 % at 400 000 walks before it); with the
    /// bounce series at the mean refracted directions too and the share 0.5 (session 39)
    /// 0.69 / 1.84 / 4.15 / 4.66 % and 4.26 % at α 0.3 (session 37's model: 6.7 % there at
    /// 400 000 walks with the noise floor removed, so more here). Asserted: the 5 % goal
    /// (session 35's model fails α 0.03 and 0.1, session 36's α 0.2, session 37's α 0.3).
    /// ≈ 6 s in release.
    #[test]
    fn rough_coat_metal_base_grazing_lobe_against_the_reference() {
        for alpha in [0.01, 0.03, 0.1, 0.2, 0.3] {
            let p = paint(&format!(
                r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 0.9}}"#
            ));
            let t = 75f64.to_radians();
            let wo = Vec3::new(t.sin(), 0.0, t.cos());
            let mut rng = crate::rng::Pcg32::new(0x75e1, (alpha * 1000.0) as u64);
            let (err, analytic, reference) = lobe_against_the_reference(&p, wo, 200_000, &mut rng);
            eprintln!(
                "coat α {alpha}, θo 75°: lobe-shape error {:.2} %, albedo {analytic:.4} vs {reference:.4}",
                100.0 * err
            );
            assert!(err < 0.05, "coat α {alpha}, θo 75°: lobe-shape error {err}");
        }
    }

    /// Issue 17, item 3 (eighth pass): the mean refracted direction of a rough coat
    /// (`Coat::mean_refract_in`, 48 × 48 midpoint quadrature of the visible normals per node)
    /// against an independent simulation (numpy, 4 · 10⁶ visible normals drawn by Heitz's 2018
    /// sampler per cell, weights `1 − F`, standard error ≤ 5e-5 in `sin θ'`) at the table's
    /// nodes μ = 16/63 (θ 75.3°) and 48/63 (θ 40.4°), η 1.5: the simulation's tangent-plane
    /// means `s̄`, taken with the share `MEAN_REFRACTION_SHARE` of their shift from the macro
    /// refraction. Asserted within 1e-3 in `sin θ'` (measured: within 2.8e-4). The map is the
    /// macro refraction for a smooth coat and at the normal.
    #[test]
    fn mean_refraction_against_an_independent_simulation() {
        use crate::paint::coat::{Coat, MEAN_REFRACTION_SHARE};
        let smooth = Coat::new(1.5, 0.0, 40.0, [0.0; 3]);
        assert!(!smooth.has_mean_refraction());
        let w = Vec3::new(0.6, 0.0, 0.8);
        assert_eq!(smooth.mean_refract_in(w), smooth.refract_in(w));
        // (α, node k of 63, s̄ from the simulation).
        let golden = [
            (0.1, 16, 0.68549),
            (0.1, 48, 0.43738),
            (0.2, 16, 0.73642),
            (0.2, 48, 0.44941),
            (0.3, 16, 0.77597),
            (0.3, 48, 0.46477),
        ];
        for (alpha, k, mean) in golden {
            let coat = Coat::new(1.5, alpha, 40.0, [0.0; 3]);
            assert!((coat.mean_refraction_ratio(1.0).unwrap() - 1.0 / 1.5).abs() < 1e-12);
            let mu = k as f64 / 63.0;
            let s = (1.0 - mu * mu).sqrt();
            let expected = s / 1.5 + MEAN_REFRACTION_SHARE * (mean - s / 1.5);
            let got = coat.mean_refract_in(Vec3::new(s, 0.0, mu));
            let sin = (1.0 - got.z * got.z).sqrt();
            eprintln!("α {alpha}, μ {k}/63: sin θ' {sin:.5} against {expected:.5} (macro {:.5})", s / 1.5);
            assert!((sin - expected).abs() < 1e-3, "α {alpha}, μ {k}/63: {sin} against {expected}");
            assert!((got.x - sin).abs() < 1e-6 && got.y == 0.0);
        }
    }

    /// Issue 17, item 3 (eighth pass): with the metal's first bounce at the mean refracted
    /// directions, whose light leaves with `T/(η² J)` (`Coat::mean_refract_out`), a white metal
    /// base (F0 1, α 0.05) under coats of α 0.1 / 0.3 / 0.5 (the parameter's range) reflects at
    /// most what arrives: the albedo from 100 000 samples of the paint's own sampler (weights
    /// `f cos/pdf`, standard error ≤ 0.35 %) at θo 87° / 75° / 53° / 0° is at most 1 + 4σ
    /// (measured, session 39: 0.951 / 0.963 / 0.982 / 0.993 at α 0.1, 0.964 / 0.967 / 0.978 /
    /// 0.992 at α 0.3, 0.965 / 0.968 / 0.972 / 0.986 at α 0.5). ≈ 4 s in release.
    #[test]
    fn metal_first_bounce_at_the_mean_refraction_conserves_energy() {
        albedo_stays_at_most_one(
            |alpha| {
                format!(
                    r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": 1}}"#
                )
            },
            0xe4e,
        );
    }

    /// Issue 17, item 3 (tenth pass): the flakes' map changes the solid angle their first
    /// bounce leaves into (`J` of [`Coat::mean_refract_out`]); `A1` follows it
    /// (`base_sample_terms`' `flake_out_share`) and what the map keeps in goes to `M`. A nearly
    /// lossless stack (white pigment, 20 % Al flakes) under coats of α 0.1 / 0.3 / 0.5 reflects
    /// at most what arrives (sampled albedo ≤ 1 + 4σ at θo 87° / 75° / 53° / 0°; measured,
    /// session 40: 0.957 / 0.950 / 0.943 / 0.949 at α 0.1, 0.949 / 0.945 / 0.944 / 0.946 at α
    /// 0.3, 0.945 / 0.943 / 0.941 / 0.946 at α 0.5). ≈ 4 s in release.
    #[test]
    fn flakes_at_the_mean_refraction_conserve_energy() {
        albedo_stays_at_most_one(
            |alpha| {
                format!(
                    r#"{{"model": "coated_paint", "coat_roughness": {alpha}, "flake_density": 20, "base_color": 1, "sparkle": false}}"#
                )
            },
            0xe4f,
        );
    }

    /// Asserts that the paint `json(α)` for coats of α 0.1 / 0.3 / 0.5 reflects at most what
    /// arrives: its albedo from 100 000 samples of its own sampler (luminance of the weights
    /// `f cos/pdf`) at `cos θo` 0.05 / 0.26 / 0.6 / 1 is at most 1 + 4σ (printed).
    fn albedo_stays_at_most_one(json: impl Fn(f64) -> String, seed: u64) {
        for alpha in [0.1, 0.3, 0.5] {
            let p = paint(&json(alpha));
            for mu in [0.05, 0.26, 0.6, 1.0] {
                let wo = Vec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
                let mut rng = crate::rng::Pcg32::new(seed, (alpha * 100.0 + mu * 10.0) as u64);
                let n = 100_000;
                let (mut sum, mut sum2) = (0.0, 0.0);
                for _ in 0..n {
                    if let Some(smp) = p.sample(wo, rng.uniform3()) {
                        let w = smp.weight.luminance();
                        sum += w;
                        sum2 += w * w;
                    }
                }
                let mean = sum / n as f64;
                let sigma = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
                eprintln!("coat α {alpha}, μo {mu}: albedo {mean:.4} ± {sigma:.4}");
                assert!(mean < 1.0 + 4.0 * sigma, "coat α {alpha}, μo {mu}: albedo {mean} ± {sigma}");
            }
        }
    }

    /// Issue 17, item 3: a rough interface lets less light out from inside near the normal
    /// than a smooth one (its facets tilted beyond the critical angle reflect it back down)
    /// and some beyond the critical angle. `Coat::escape_from_inside` (Walter's
    /// single-scattering transmission plus a fitted share of its loss) against the lossless
    /// walk (Heitz et al. 2016; 100 000 walks per direction, σ ≤ 1.6e-3) at α 0.1 / 0.2 / 0.3,
    /// μ' 1 / 0.9 / 0.8 / 0.7 / 0.5: asserted within 0.008 (measured in the output). The
    /// smooth refraction the layer term used before (`T` at the refracted direction, 0 beyond
    /// the critical angle) is 0.095 too high at μ' 1 for α 0.3 (asserted > 0.05, so the test
    /// fails on it). The crossing factor `g` stays below `T` (energy), equals `T` for a
    /// smooth coat, and is below `T` at normal incidence for α 0.3. ≈ 1 s in release.
    #[test]
    fn escape_from_inside_matches_the_lossless_walk() {
        use crate::paint::coat::Coat;
        use crate::paint::rough_dielectric::RoughDielectric;
        let smooth = Coat::new(1.5, 0.0, 40.0, [0.0; 3]);
        for k in 0..=20 {
            let mu = k as f64 / 20.0;
            assert_eq!(smooth.crossing(mu), smooth.transmittance(mu));
        }
        let walks = 100_000;
        let mut worst = 0.0f64;
        for alpha in [0.1, 0.2, 0.3] {
            let coat = Coat::new(1.5, alpha, 40.0, [0.0; 3]);
            let top = RoughDielectric { eta: 1.5, alpha };
            for mu_in in [1.0f64, 0.9, 0.8, 0.7, 0.5] {
                let w = Vec3::new((1.0 - mu_in * mu_in).sqrt(), 0.0, -mu_in);
                let mut rng = crate::rng::Pcg32::new(0xe5c, (mu_in * 100.0) as u64);
                let up =
                    (0..walks).filter(|_| top.sample_multiple(w, &mut rng).is_some_and(|(d, _)| d.z > 0.0)).count();
                let walk = up as f64 / walks as f64;
                let model = coat.escape_from_inside(mu_in);
                let smooth_refraction =
                    coat.refract_out(Vec3::new(w.x, w.y, mu_in)).map_or(0.0, |o| coat.transmittance(o.z));
                eprintln!(
                    "α {alpha} μ' {mu_in}: walk {walk:.4}, escape_from_inside {model:.4} ({:+.4}), smooth refraction {smooth_refraction:.4} ({:+.4})",
                    model - walk,
                    smooth_refraction - walk
                );
                worst = worst.max((model - walk).abs());
                assert!((model - walk).abs() < 0.008, "α {alpha} μ' {mu_in}: {model} vs {walk}");
                if alpha == 0.3 && mu_in == 1.0 {
                    assert!(smooth_refraction - walk > 0.05, "{smooth_refraction} vs {walk}");
                }
            }
            for k in 0..=40 {
                let mu = k as f64 / 40.0;
                assert!(coat.crossing(mu) <= coat.transmittance(mu) + 1e-12, "α {alpha} μ {mu}");
            }
        }
        eprintln!("largest |escape_from_inside − walk| {worst:.4}");
        let rough = Coat::new(1.5, 0.3, 40.0, [0.0; 3]);
        assert!(rough.crossing(1.0f64) < rough.transmittance(1.0f64) - 0.02);
    }

    /// Issue 17, item 3: the rough coat's multiple-scattering reflection
    /// ([`super::super::coat::MultipleScattering`]). Against the lossless interface's walk
    /// (Heitz et al. 2016; 400 000 walks per direction, σ ≤ 7e-4): the coat's reflected energy
    /// `E_top + ΔR` at θo 0° / 60° / 75°, α 0.1 / 0.2 / 0.3. Single scattering alone (`E_top`,
    /// the old model) is up to 0.0104 low at 75° (asserted > 0.006 there, so the test fails on
    /// it); with ΔR asserted within 0.004 (measured in the output). A smooth coat has no such
    /// term (the old values bit for bit: no table), at α 0.001 it is below 1e-4 (κ fades out
    /// as α²/(α² + 0.02²); without that it was 8.4e-3 at the grazing node); the lobe is
    /// reciprocal and `E_top + ΔR + T = 1`. ≈ 2 s in release.
    #[test]
    fn rough_coat_reflects_what_the_lossless_interface_reflects() {
        use crate::paint::coat::Coat;
        use crate::paint::rough_dielectric::RoughDielectric;
        let smooth = Coat::new(1.5, 0.0, 40.0, [0.0; 3]);
        assert!(smooth.multiple_scattering().is_none());
        assert_eq!(smooth.ms_albedo(0.3f64), 0.0);
        let tiny = Coat::new(1.5, 0.001, 40.0, [0.0; 3]);
        let worst_tiny = (0..=20).map(|k| tiny.ms_albedo(k as f64 / 20.0)).fold(0.0f64, f64::max);
        eprintln!("α 0.001: largest ΔR {worst_tiny:.2e}");
        assert!(worst_tiny < 1e-4, "{worst_tiny}");
        let walks = 400_000;
        for alpha in [0.1, 0.2, 0.3] {
            let coat = Coat::new(1.5, alpha, 40.0, [0.0; 3]);
            let top = RoughDielectric { eta: 1.5, alpha };
            eprintln!("α {alpha}: κ {:.4}", coat.multiple_scattering().unwrap().kappa);
            for theta in [0.0f64, 60.0, 75.0] {
                let mu = theta.to_radians().cos();
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let mut rng = crate::rng::Pcg32::new(0x3c, theta as u64);
                let up =
                    (0..walks).filter(|_| top.sample_multiple(wo, &mut rng).is_some_and(|(w, _)| w.z > 0.0)).count();
                let r = up as f64 / walks as f64;
                let (old, ms) = (coat.reflectance(mu), coat.ms_albedo(mu));
                let new = old + ms;
                eprintln!(
                    "α {alpha} θo {theta}°: walk {r:.4} ± {:.4}; E_top {old:.4} ({:+.4}), E_top + ΔR {new:.4} ({:+.4})",
                    (r * (1.0 - r) / walks as f64).sqrt(),
                    old - r,
                    new - r
                );
                assert!((new - r).abs() < 0.004, "α {alpha} θo {theta}°: {new} vs {r}");
                if theta == 75.0 {
                    assert!(r - old > 0.006, "α {alpha}: single scattering should miss: {old} vs {r}");
                }
                assert!((coat.transmittance(mu) + new - 1.0).abs() < 1e-12);
                let wi = Vec3::new(-0.3f64, 0.5, 0.812_403_840_463_596).normalize();
                let (a, b) = (coat.ms_eval(wi, wo), coat.ms_eval(wo, wi));
                assert!((a - b).abs() <= 1e-15 * a, "{a} vs {b}");
            }
        }
    }

    /// The coat's multiple-scattering reflection is sampled with its azimuth
    /// ([`crate::paint::coat::ms_sample`]): χ² of 200 000 draws per `wo` against its density
    /// [`crate::paint::coat::ms_pdf`] integrated over 8 × 24 cells (equal `sin² θi` bands ×
    /// `Δφ`; 16 × 16 midpoint nodes per cell), at θo 0°/40°/75°/89°, with cells of expected
    /// count < 5 pooled. Measured χ²/dof 0.86–1.16 (dof 191); asserted below
    /// dof + 5√(2 dof), about 1.5 × dof. A sampler that drew a uniform azimuth (the cosine lobe)
    /// gives χ²/dof > 100 at θo 75°. The density's integral is 1 (the same quadrature, asserted 1e-4).
    #[test]
    fn ms_sampler_draws_its_density() {
        use crate::paint::coat::{ms_pdf, ms_sample};
        use crate::rng::Pcg32;
        use std::f64::consts::PI;
        let (n_mu, n_phi, sub) = (8, 24, 16);
        for (k, theta_o) in [0.0f64, 40.0, 75.0, 89.0].into_iter().enumerate() {
            let t = theta_o.to_radians();
            // wo at azimuth 0.7 rad, so the test also covers the rotation to wo's azimuth.
            let wo = crate::frame::spherical_direction(t.sin(), t.cos(), 0.7);
            let cell = |wi: Vec3<f64>| {
                let s2 = (wi.x * wi.x + wi.y * wi.y).min(1.0 - 1e-15);
                let dphi = (wi.y.atan2(wi.x) - 0.7).rem_euclid(2.0 * PI);
                ((s2 * n_mu as f64) as usize).min(n_mu - 1) * n_phi
                    + ((dphi / (2.0 * PI) * n_phi as f64) as usize).min(n_phi - 1)
            };
            // Expected probability per cell: sin² θ = s in the band, dω = dμ dφ = ds dφ/(2μ).
            let mut expected = vec![0.0; n_mu * n_phi];
            for (c, e) in expected.iter_mut().enumerate() {
                let (i, j) = (c / n_phi, c % n_phi);
                for a in 0..sub {
                    for b in 0..sub {
                        let s2 = (i as f64 + (a as f64 + 0.5) / sub as f64) / n_mu as f64;
                        let phi = 0.7 + (j as f64 + (b as f64 + 0.5) / sub as f64) / n_phi as f64 * 2.0 * PI;
                        let mu = (1.0 - s2).sqrt();
                        let wi = crate::frame::spherical_direction(s2.sqrt(), mu, phi);
                        let area = (1.0 / (n_mu * sub) as f64) * (2.0 * PI / (n_phi * sub) as f64) / (2.0 * mu);
                        *e += ms_pdf(wi, wo) * area;
                    }
                }
            }
            let total: f64 = expected.iter().sum();
            assert!((total - 1.0).abs() < 1e-4, "θo {theta_o}: ∫ pdf = {total}");
            let draws = 200_000;
            let mut counts = vec![0.0; n_mu * n_phi];
            let mut rng = Pcg32::new(17, k as u64);
            for _ in 0..draws {
                let wi = ms_sample(wo, rng.uniform(), rng.uniform());
                assert!(wi.z >= 0.0 && (wi.dot(wi) - 1.0).abs() < 1e-9, "{wi:?}");
                counts[cell(wi)] += 1.0;
            }
            // Pool cells with expected count < 5 into one.
            let (mut chi2, mut dof, mut pool_e, mut pool_o) = (0.0, 0usize, 0.0, 0.0);
            for (e, o) in expected.iter().zip(&counts) {
                let e = e * draws as f64;
                if e < 5.0 {
                    (pool_e, pool_o) = (pool_e + e, pool_o + o);
                } else {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            if pool_e > 0.0 {
                chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e.max(1.0);
                dof += 1;
            }
            let dof = dof - 1;
            let limit = dof as f64 + 5.0 * (2.0 * dof as f64).sqrt();
            eprintln!("θo {theta_o}°: χ² {chi2:.1}, dof {dof}, χ²/dof {:.2}", chi2 / dof as f64);
            assert!(chi2 < limit, "θo {theta_o}°: χ² {chi2:.1} ≥ {limit:.1} (dof {dof})");
        }
    }

    /// The paint's sampling of its multiple-scattering coat reflection ([`crate::paint::coat::ms_sample`]):
    /// a black pigment under a rough coat (α 0.3), where the cosine-sampled weight is nearly all
    /// the coat's `ΔR`, so drawing `ΔR`'s forward azimuth matters most. Relative variance of the
    /// sample weight (green) over 200 000 samples at θo 60° / 75°: measured 0.245 / 0.392 with
    /// the wrapped-Cauchy azimuth, 0.287 / 0.447 with the cosine lobe alone (uniform azimuth; the
    /// sampler before); asserted 0.265 / 0.42. (A mid-grey pigment, base 0.5, α 0.05–0.1, moves
    /// the other way by 1–8 % at θo 75°–88°: the pigment's cosine lobe then dominates the weight.)
    /// 0.1 s in release.
    #[test]
    fn rough_coat_ms_sampling_lowers_weight_variance_on_dark_paint() {
        use crate::rng::Pcg32;
        let p = paint(
            r#"{"model": "coated_paint", "base_color": [0.0, 0.0, 0.0], "flake_density": 0, "coat_roughness": 0.3}"#,
        );
        for (theta_o, measured, limit) in [(60.0f64, 0.245, 0.265), (75.0, 0.392, 0.42)] {
            let t = theta_o.to_radians();
            let wo = Vec3::new(t.sin(), 0.0, t.cos());
            let mut rng = Pcg32::new(5, 0);
            let (mut sum, mut sum2, n) = (0.0, 0.0, 200_000);
            for _ in 0..n {
                if let Some(s) = p.sample(wo, rng.uniform3()) {
                    sum += s.weight.g;
                    sum2 += s.weight.g * s.weight.g;
                }
            }
            let mean = sum / n as f64;
            let rel_var = (sum2 / n as f64 - mean * mean) / (mean * mean);
            eprintln!("θo {theta_o}°: albedo {mean:.4}, relative variance {rel_var:.4} (measured {measured})");
            assert!(rel_var < limit, "θo {theta_o}°: relative variance {rel_var:.4} ≥ {limit}");
        }
    }

    /// The azimuthal factor keeps the working precision at its peak (both directions grazing,
    /// `Δφ` ≈ π), where `1 + ρ² + 2ρ cos Δφ` written directly cancels down to `(1 − ρ)²` ≈
    /// 0.0025: scalar f32 on f32-rounded directions against f64 on the same directions
    /// normalised (as `Material` evaluates them), 200 000 pairs with
    /// `cos θ` = u³ (grazing-heavy) and `Δφ` within 3° of π. Measured: the direct form 1.3e-4
    /// (a numpy replica of this distribution; the paint's f32 batch path was 1.8e-5 off its
    /// f64 reference at such a pair), the cancellation-free form 9.3e-7; asserted 4e-6.
    /// The two forms agree in f64 to 2.7e-13 on the same pairs (asserted 1e-12).
    #[test]
    fn ms_azimuthal_keeps_f32_precision_at_its_peak() {
        use crate::paint::coat::{ms_azimuthal, MS_FORWARD_CONCENTRATION};
        use crate::rng::Pcg32;
        let direct = |wi: Vec3<f64>, wo: Vec3<f64>| {
            let (si2, so2) = (wi.x * wi.x + wi.y * wi.y, wo.x * wo.x + wo.y * wo.y);
            let ss = (si2 * so2).sqrt();
            let cos_dphi = ((wi.x * wo.x + wi.y * wo.y) / ss).clamp(-1.0, 1.0);
            let rho = MS_FORWARD_CONCENTRATION * ss.sqrt();
            (1.0 - rho * rho) / (1.0 + rho * rho + 2.0 * rho * cos_dphi)
        };
        let mut rng = Pcg32::new(22, 5);
        let (mut worst_f32, mut worst_f64) = (0.0f64, 0.0f64);
        for _ in 0..200_000 {
            let (mi, mo) = (rng.uniform().powi(3), rng.uniform().powi(3));
            let phi = 2.0 * std::f64::consts::PI * rng.uniform();
            let dphi = std::f64::consts::PI + 0.1 * (rng.uniform() - 0.5);
            let wi = crate::frame::spherical_direction((1.0 - mi * mi).sqrt(), mi, phi).cast::<f32>();
            let wo = crate::frame::spherical_direction((1.0 - mo * mo).sqrt(), mo, phi + dphi).cast::<f32>();
            // The f64 reference sees the f32 directions normalised in f64, as `Material` and
            // the f64 batch path do (the f32 path takes them as given: unit to ~1e-7).
            let (a, b) = (wi.cast::<f64>().normalize(), wo.cast::<f64>().normalize());
            let reference = ms_azimuthal(a, b);
            worst_f32 = worst_f32.max((f64::from(ms_azimuthal(wi, wo)) / reference - 1.0).abs());
            worst_f64 = worst_f64.max((reference / direct(a, b) - 1.0).abs());
        }
        // At and near the normal (the quotient's terms vanish like s^1.5 there): finite, and
        // within the factor's range around 1.
        for tilt in [0.0f64, 1e-30, 1e-20, 1e-13, 1e-7, 1e-3] {
            let (a, b) = (Vec3::new(tilt, 0.0, 1.0).normalize(), Vec3::new(-0.99, 0.1, 0.1).normalize());
            let (v64, v32) = (ms_azimuthal(a, b), ms_azimuthal(a.cast::<f32>(), b.cast::<f32>()));
            // ρ ≤ r √tilt, and |A − 1| ≤ 2ρ/(1 − ρ).
            let rho = MS_FORWARD_CONCENTRATION * tilt.sqrt();
            let bound = 2.0 * rho / (1.0 - rho) + 1e-6;
            assert!((v64 - 1.0).abs() <= bound && (f64::from(v32) - 1.0).abs() <= bound, "tilt {tilt}: {v64} {v32}");
        }
        eprintln!("ms_azimuthal: f32 vs f64 {worst_f32:.2e}, f64 against the direct form {worst_f64:.2e}");
        assert!(worst_f32 < 4e-6, "f32: {worst_f32}");
        assert!(worst_f64 < 1e-12, "f64: {worst_f64}");
    }

    /// Issue 17, item 3: the shape of the coat's multiple-scattering reflection against the
    /// lossless walk's reflections after more than one event, at θo 75° (where `ΔR` matters),
    /// α 0.2 and 0.3, 400 000 walks: relative L2 difference of the two lobes, each normalised,
    /// over 12 × 6 equal-solid-angle bins. Measured 18.2 % (α 0.2) and 15.0 % (α 0.3) with the
    /// azimuthal factor, asserted 25 %; the separable lobe alone (azimuth uniform) gives 89.9 /
    /// 86.0 % (the walk sends 74–86 % into the forward 30°, the uniform lobe 17 %). Also: the
    /// factor's azimuthal mean is 1 (the albedo stays `ΔR(μo)`; midpoint quadrature of 4096
    /// points, asserted 1e-9) and it is symmetric. 0.2 s in release.
    #[test]
    fn rough_coat_ms_reflection_goes_forward_as_the_walk() {
        use crate::paint::coat::ms_azimuthal;
        use std::f64::consts::PI;
        let dir = |mu: f64, phi: f64| crate::frame::spherical_direction((1.0 - mu * mu).sqrt(), mu, phi);
        for (mu_i, mu_o) in [(0.9, 0.1), (0.3, 0.26), (0.05, 0.02), (1.0, 0.5)] {
            let n = 4096;
            let mean = (0..n)
                .map(|k| ms_azimuthal(dir(mu_i, (k as f64 + 0.5) / n as f64 * 2.0 * PI), dir(mu_o, 0.0)))
                .sum::<f64>()
                / n as f64;
            assert!((mean - 1.0).abs() < 1e-9, "μ {mu_i} {mu_o}: {mean}");
            let (a, b) = (dir(mu_i, 2.0), dir(mu_o, 0.3));
            assert!((ms_azimuthal(a, b) - ms_azimuthal(b, a)).abs() < 1e-15);
        }
        for (alpha, measured) in [(0.2, 0.182), (0.3, 0.150)] {
            let (err, forward) = ms_lobe_shape_against_the_walk(alpha, 75.0, 400_000, |c, wi, wo| c.ms_eval(wi, wo));
            eprintln!(
                "α {alpha} θo 75°: ms lobe shape {:.1} % (measured {:.1} %), walk forward share {forward:.3}",
                100.0 * err,
                100.0 * measured
            );
            assert!(err < 0.25, "α {alpha}: {err}");
        }
    }

    /// The coat's multiple-scattering reflection lobe `model(coat, wi, wo)` against the lossless
    /// walk's reflections after more than one event at `theta_deg` (η 1.5, coat `alpha`, `walks`
    /// walks): the relative L2 difference of the two lobes `f cos θi`, each normalised, over
    /// 12 × 6 equal-solid-angle bins, and the walk's share in the forward azimuth bin.
    fn ms_lobe_shape_against_the_walk(
        alpha: f64,
        theta_deg: f64,
        walks: usize,
        model: impl Fn(&crate::paint::coat::Coat, Vec3<f64>, Vec3<f64>) -> f64,
    ) -> (f64, f64) {
        use crate::paint::coat::Coat;
        use crate::paint::position_free_mc::lobe_bin;
        use crate::paint::rough_dielectric::RoughDielectric;
        use std::f64::consts::PI;
        let dir = |mu: f64, phi: f64| crate::frame::spherical_direction((1.0 - mu * mu).sqrt(), mu, phi);
        let (n_mu, n_phi) = (12, 6);
        let wo = dir(theta_deg.to_radians().cos(), 0.0);
        let coat = Coat::new(1.5, alpha, 40.0, [0.0; 3]);
        let top = RoughDielectric { eta: 1.5, alpha };
        let mut walk = vec![0.0; n_mu * n_phi];
        let mut rng = crate::rng::Pcg32::new(0x3d, theta_deg as u64);
        for _ in 0..walks {
            if let Some((w, events)) = top.sample_multiple(wo, &mut rng) {
                if w.z > 0.0 && events >= 2 {
                    walk[lobe_bin(w, 0.0, n_mu, n_phi)] += 1.0;
                }
            }
        }
        // The model's lobe f cos θi per bin (midpoint rule; the folded azimuth counts twice).
        let (q_mu, q_phi) = (8, 24);
        let mut lobe = vec![0.0; n_mu * n_phi];
        for (k, m) in lobe.iter_mut().enumerate() {
            let (i, j) = (k / n_phi, k % n_phi);
            for a in 0..q_mu {
                for b in 0..q_phi {
                    let mu = (i as f64 + (a as f64 + 0.5) / q_mu as f64) / n_mu as f64;
                    let phi = (j as f64 + (b as f64 + 0.5) / q_phi as f64) / n_phi as f64 * PI;
                    *m += model(&coat, dir(mu, phi), wo) * mu;
                }
            }
        }
        let (sw, sm) = (walk.iter().sum::<f64>(), lobe.iter().sum::<f64>());
        let (mut d2, mut n2) = (0.0, 0.0);
        for (w, m) in walk.iter().zip(&lobe) {
            d2 += (w / sw - m / sm).powi(2);
            n2 += (w / sw).powi(2);
        }
        let forward = (0..n_mu).map(|i| walk[i * n_phi + n_phi - 1]).sum::<f64>() / sw;
        ((d2 / n2).sqrt(), forward)
    }

    /// The scan behind [`crate::paint::coat::MS_FORWARD_CONCENTRATION`] (docs §8): the wrapped
    /// Cauchy factor with `ρ = r (sin θi sin θo)^p` for p 0–1 and r 0.85–0.99 at θo 60°/75°/85°,
    /// α 0.1–0.3, 2 · 10⁶ walks per direction. A measurement, not a check (100 s in release):
    /// `cargo test --release -p lacquer --lib -- --ignored ms_azimuth_scan --nocapture`.
    #[test]
    #[ignore = "a measurement for docs §8, 100 s"]
    fn ms_azimuth_scan() {
        for (p, r) in
            [0.0, 0.25, 0.5, 1.0].into_iter().flat_map(|p| [0.85, 0.9, 0.93, 0.96, 0.98, 0.99].map(|r| (p, r)))
        {
            let mut line = format!("p {p} r {r}:");
            for alpha in [0.1, 0.2, 0.3] {
                for theta in [60.0, 75.0, 85.0] {
                    let (err, _) = ms_lobe_shape_against_the_walk(alpha, theta, 2_000_000, |c, wi, wo| {
                        let m = c.multiple_scattering().expect("a rough coat");
                        let ss = ((1.0 - wi.z * wi.z) * (1.0 - wo.z * wo.z)).max(0.0).sqrt();
                        let rho = r * ss.powf(p);
                        let cos_dphi = if ss > 0.0 { ((wi.x * wo.x + wi.y * wo.y) / ss).clamp(-1.0, 1.0) } else { 0.0 };
                        let a = (1.0 - rho * rho) / (1.0 + rho * rho + 2.0 * rho * cos_dphi);
                        c.ms_albedo(wi.z) * c.ms_albedo(wo.z) * m.norm * a
                    });
                    line += &format!(" α {alpha} θo {theta}: {:.1} %", 100.0 * err);
                }
            }
            eprintln!("{line}");
        }
    }

    /// Issue 17, item 3: a pigment under a rough coat (α 0.2) at grazing view (θo 75°): the
    /// analytic albedo against the lossless reference, 100 000 walks (±0.7 %). Without the
    /// coat's multiple-scattering reflection −4.6 % (§8, 400 000 walks); asserted within 2.5 %
    /// (measured in the output). ≈ 0.5 s in release.
    #[test]
    fn rough_coat_pigment_albedo_at_grazing_view_matches_the_reference() {
        use crate::paint::position_free_mc::PositionFreeMc;
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0.2, "flake_density": 0, "base_color": [0.5, 0.03, 0.03]}"#,
        );
        let mu = 75f64.to_radians().cos();
        let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let reference = PositionFreeMc::new(&p).albedo(wo, 100_000, 75);
        let (a1, m) = p.layer_albedos(mu);
        let top = p.coat().reflectance(mu) + p.coat().ms_albedo(mu);
        let ours = Rgb::new(top + a1[0] + m[0], top + a1[1] + m[1], top + a1[2] + m[2]).luminance();
        let (r, se) = (reference.value.luminance(), reference.std_error.luminance());
        eprintln!("θo 75°: analytic {ours:.5}, reference {r:.5} ± {se:.5}: {:+.2} %", 100.0 * (ours / r - 1.0));
        assert!((ours / r - 1.0).abs() < 0.025, "{ours} vs {r}");
    }

    /// No coat (η = 1, no absorption) over a Lambert pigment is exactly Lambert: the layering
    /// adds nothing when there is nothing to layer.
    #[test]
    fn without_a_coat_it_is_the_basecoat() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_ior": 1.0, "coat_roughness": 0, "flake_density": 0, "base_color": [0.2, 0.4, 0.6]}"#,
        );
        let wi = Vec3::new(0.3f64, 0.1, 0.948_683_298_050_513_8).normalize();
        let wo = Vec3::new(-0.5f64, 0.2, 0.8).normalize();
        let f = p.eval(wi, wo);
        for (c, rho) in [0.2, 0.4, 0.6].iter().enumerate() {
            assert!((f[c] - rho / std::f64::consts::PI).abs() < 1e-12, "{f:?}");
        }
    }

    /// Issue 16 (`lacquer numerics`): a rough coat of index 1 reflected the rounding residue of
    /// the Fresnel formula (0 in exact arithmetic) through `D G / (4 cos θi cos θo)`, which at
    /// grazing, nearly mirror-symmetric pairs gave up to 8e-10 /sr one way and 2e-10 /sr the
    /// other (relative reciprocity errors up to 0.69). The pairs are the report's examples; with
    /// no pigment and no flakes there is nothing but that residue, so f must be exactly 0, and
    /// with a pigment it must be reciprocal to 1e-12.
    #[test]
    fn a_coat_of_index_one_reflects_nothing_and_stays_reciprocal_at_grazing() {
        let pairs = [
            (
                [-0.7499908038050798, 0.6614482551249252, 4.449774533588684e-8],
                [0.7497630273467385, -0.6617064325090485, 4.4482430345980863e-8],
            ),
            (
                [0.24338282356037405, -0.969930200856681, 0.0004546008118651432],
                [-0.24338246343996048, 0.9699302912210503, 0.00045460064307879913],
            ),
            (
                [0.38144815582552904, -0.9243901405794519, 0.00041523102507719754],
                [-0.3814481488577413, 0.9243901434546999, 0.00041523102194730515],
            ),
            (
                [-0.5153391871154128, 0.856986302237781, 2.0046486483928204e-7],
                [0.5151324293546051, -0.8571105997636377, 2.0041651556598514e-7],
            ),
        ];
        let v = |a: [f64; 3]| Vec3::new(a[0], a[1], a[2]);
        for rough in [0.0, 0.001, 0.02, 0.5] {
            let bare = paint(&format!(
                r#"{{"model": "coated_paint", "coat_ior": 1.0, "coat_roughness": {rough}, "flake_density": 0, "base_color": 0}}"#
            ));
            let pigment = paint(&format!(r#"{{"model": "coated_paint", "coat_ior": 1.0, "coat_roughness": {rough}}}"#));
            assert_eq!(bare.coat().reflectance(0.3f64), 0.0);
            for (wi, wo) in pairs.map(|(a, b)| (v(a), v(b))) {
                assert_eq!(bare.coat().reflection_eval(wi, wo), 0.0);
                assert_eq!((bare.eval(wi, wo), bare.eval(wo, wi)), (Rgb::zero(), Rgb::zero()), "α {rough}");
                let (a, b) = (pigment.eval(wi, wo), pigment.eval(wo, wi));
                for c in 0..3 {
                    assert!((a[c] - b[c]).abs() <= 1e-12 * a[c].abs().max(1e-10), "α {rough}: {a:?} vs {b:?}");
                }
            }
        }
    }

    /// A smooth coat over a white Lambert base at normal incidence: the single-scatter term is
    /// `(1 − F0)² / η² · 1/π` (hand-derived from the radiance η² law).
    #[test]
    fn single_scatter_term_at_normal_incidence_matches_hand_derivation() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_ior": 1.5, "coat_roughness": 0, "flake_density": 0, "base_color": 1.0}"#,
        );
        let n = Vec3::new(0.0f64, 0.0, 1.0);
        let f0 = 0.04f64;
        let expect = (1.0 - f0).powi(2) / 2.25 / std::f64::consts::PI;
        let o = p.at_wo(n, PaintParts::ALL);
        let got = p.layer_term(&p.at_pair(n, &o), &o, 1.0, 1.0, PaintParts::ALL);
        assert!((got.r - expect).abs() < 1e-12, "{} vs {expect}", got.r);
    }
    /// `∫ f(wi, wo) cos θi dωi` by Gauss-Legendre product quadrature split at EON's kinks
    /// (μi = μo; Δφ = ±π/2, where `s` changes sign).
    fn quadrature_albedo(f: impl Fn(Vec3<f64>) -> f64, mu_o: f64) -> f64 {
        use crate::quadrature::gauss_legendre_on;
        use std::f64::consts::PI;
        let mut total = 0.0;
        for (m0, m1) in [(0.0, mu_o), (mu_o, 1.0)] {
            let (mus, wm) = gauss_legendre_on(40, m0, m1);
            for (mu, wmu) in mus.iter().zip(&wm) {
                for (p0, p1) in [(-PI, -0.5 * PI), (-0.5 * PI, 0.5 * PI), (0.5 * PI, PI)] {
                    let (phis, wp) = gauss_legendre_on(40, p0, p1);
                    for (phi, wphi) in phis.iter().zip(&wp) {
                        let s = (1.0 - mu * mu).sqrt();
                        total += wmu * wphi * mu * f(Vec3::new(s * phi.cos(), s * phi.sin(), *mu));
                    }
                }
            }
        }
        total
    }

    /// Issue 17, item 5: `pigment_model = eon` makes the pigment scatter by EON. Without a coat
    /// (η = 1) and flakes the paint *is* EON of albedo ρ (asserted 1e-12 relative; the old model
    /// rejected the parameter, and its pigment was Lambert, 5–30 % away at r = 1), its albedo is
    /// EON's closed form `ρE(μ) + ρ_ms(1 − E(μ))` (quadrature, asserted 2e-9; measured ≤ 4.0e-10)
    /// and the tabulated single-scatter albedo the sampler uses agrees with it (2048
    /// Hammersley samples per node: asserted 2e-3 for μ ≥ 0.2, measured ≤ 1.2e-3; 8e-3 at
    /// μ 0.05, measured 4.8e-3). `pigment_model =
    /// lambert` (the default) is the old model bit for bit.
    #[test]
    fn eon_pigment_is_eon_and_keeps_its_closed_form_albedo() {
        let rho = [0.9, 0.5, 0.2];
        let r = 1.0;
        let json = |extra: &str| {
            format!(
                r#"{{"model": "coated_paint", "coat_ior": 1.0, "coat_roughness": 0, "flake_density": 0, "base_color": [0.9, 0.5, 0.2]{extra}}}"#
            )
        };
        let p = paint(&json(r#", "pigment_model": "eon", "pigment_roughness": 1"#));
        let eon = crate::models::eon::Eon::new(rho, r);
        let lambert = paint(&json(""));
        let explicit = paint(&json(r#", "pigment_model": "lambert", "pigment_roughness": 1"#));
        let mut rng = crate::rng::Pcg32::new(17, 5);
        let mut max_dev_from_lambert = 0.0f64;
        for _ in 0..200 {
            let wi = crate::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
            let wo = crate::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
            let (got, want) = (p.eval(wi, wo), eon.eval(wi, wo));
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() <= 1e-12 * want[c], "{got:?} vs EON {want:?}");
                max_dev_from_lambert = max_dev_from_lambert.max((got[c] * std::f64::consts::PI / rho[c] - 1.0).abs());
            }
            assert_eq!(lambert.eval(wi, wo), explicit.eval(wi, wo));
            assert_eq!(lambert.pdf(wi, wo), explicit.pdf(wi, wo));
        }
        assert!(max_dev_from_lambert > 0.05, "EON at r = 1 should differ from Lambert: {max_dev_from_lambert}");
        for mu in [1.0, 0.8, 0.5, 0.2, 0.05] {
            let wo = Vec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
            let table = p.layer_albedos(mu).0;
            for c in 0..3 {
                let closed = crate::models::eon::Eon::directional_albedo(rho[c], r, mu);
                let quad = quadrature_albedo(|wi| p.eval(wi, wo)[c], mu);
                eprintln!("μ {mu} ch {c}: closed {closed:.12} quadrature {quad:.12} table {:.6}", table[c]);
                assert!((quad - closed).abs() < 2e-9, "μ {mu}: quadrature {quad} vs closed form {closed}");
                // Grazing nodes are the noisiest (EON's lobe leans to grazing while the
                // pigment is sampled by the cosine): 4.8e-3 measured at μ 0.05.
                let tol = if mu < 0.1 { 8e-3 } else { 2e-3 };
                assert!((table[c] - closed).abs() < tol, "μ {mu}: table {} vs closed form {closed}", table[c]);
            }
        }
    }

    /// A lossless smooth coat over a white EON pigment (r = 1) keeps the energy EON preserves:
    /// the analytic albedo stays within [0.99, 1 + 1e-9] at every angle (measured 0.9995–0.9996;
    /// before ρ̄ was capped at 1, sampling noise in ρ̄ gave 1.012 at μ 1).
    #[test]
    fn lossless_coat_over_white_eon_keeps_its_energy() {
        let p = paint(
            r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 0, "base_color": 1.0, "pigment_model": "eon", "pigment_roughness": 1}"#,
        );
        for mu in [1.0, 0.7, 0.4, 0.15] {
            let (a1, m) = p.layer_albedos(mu);
            let albedo = p.coat().reflectance(mu) + a1[1] + m[1];
            eprintln!("μ {mu}: albedo {albedo:.5}");
            assert!((0.99..=1.0 + 1e-9).contains(&albedo), "μ {mu}: {albedo}");
        }
    }

    /// Issue 17: the basecoat's mean albedo ρ̄ (which scales every bounce of the `M` table)
    /// against independent estimates. Until issue 17 the incidence directions were point
    /// `k·7919 mod n` of the sample set itself, not independent of the samples: ρ̄ came out
    /// +3.4 to +5.3 % (red) and −3 to −15 % (green, blue) off for the flaked paints, +12 % for a sharp metal
    /// base, +23 % for a white EON pigment. Now, against a 1M-sample plain-RNG Monte Carlo of
    /// the basecoat's own sampler (standard error ≤ 0.25 %): asserted 0.5 % relative, measured
    /// ≤ 0.17 % for the flaked paints, 0.11 % for a bright metal, 0.20 % for EON (the old
    /// estimator fails it on the flaked paints and EON), 2 % for a dark metal base (1.5 %
    /// measured); a Lambert pigment under pearl flakes against its closed form `ρ (w + c_p (∫ 2μ T_p dμ)²)`: asserted 1e-3 relative, measured
    /// ≤ 9.4e-5.
    #[test]
    fn basecoat_mean_albedo_agrees_with_independent_estimates() {
        let paints = [
            r#"{"model": "coated_paint", "flake_density": 3, "base_color": [0.5, 0.03, 0.03], "sparkle": false}"#,
            r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 8, "coat_absorption": [2, 4, 8], "sparkle": false}"#,
            r#"{"model": "coated_paint", "coat_roughness": 0.15, "flake_density": 5, "pearl_density": 10, "pearl_film_nm": 300, "base_metallic": 0.5, "sparkle": false}"#,
            r#"{"model": "coated_paint", "base_metallic": 1, "base_roughness": 0.05, "flake_density": 0, "base_color": 0.9}"#,
            r#"{"model": "coated_paint", "flake_density": 0, "base_color": 1, "pigment_model": "eon", "pigment_roughness": 1}"#,
            r#"{"model": "coated_paint", "base_metallic": 1, "base_roughness": 0.05, "flake_density": 0, "base_color": 0}"#,
        ];
        for (i, js) in paints.iter().enumerate() {
            // The dark α 0.05 metal (F0 0.04: the albedo is Schlick's grazing rise, which the
            // 8192 points resolve less well): asserted 2 %, measured 1.5 % (0.04203 vs 0.04141).
            let tol = if i == 5 { 2e-2 } else { 5e-3 };
            let b = &paint(js).base;
            let got = mean_albedo(b, MEAN_ALBEDO_SAMPLES);
            let mut rng = crate::rng::Pcg32::new(0x00a1_bed0, i as u64);
            let m = 1_000_000;
            let (mut sum, mut sq) = ([0.0; 3], [0.0; 3]);
            for _ in 0..m {
                let w = cosine_hemisphere(rng.uniform(), rng.uniform());
                if let Some(s) = b.sample(w, rng.uniform3()) {
                    for c in 0..3 {
                        sum[c] += s.weight[c];
                        sq[c] += s.weight[c] * s.weight[c];
                    }
                }
            }
            for c in 0..3 {
                let mean = sum[c] / m as f64;
                let se = ((sq[c] / m as f64 - mean * mean) / m as f64).sqrt();
                let rel = (got[c] - mean).abs() / mean;
                eprintln!("{js} ch {c}: ρ̄ {:.5} MC {mean:.5} ± {se:.1e}: {rel:.2e}", got[c]);
                assert!(se < 3e-3 * mean, "{js}: reference too noisy: {se}");
                assert!(rel < tol, "{js} ch {c}: ρ̄ {} vs MC {mean}", got[c]);
            }
        }
        // Lambert pigment behind pearl flakes (no metallic flakes): closed form.
        let p = paint(
            r#"{"model": "coated_paint", "flake_density": 0, "pearl_density": 30, "pearl_film_nm": 200, "base_color": [0.8, 0.5, 0.2]}"#,
        );
        let b = &p.base;
        let base_only =
            Basecoat::new(b.pigment, b.pigment_weight, b.pearl_coverage, b.pearl_transmission.clone(), None, None);
        let t = b.pearl_transmission.as_ref().unwrap();
        let (mus, ws) = crate::quadrature::gauss_legendre_on(64, 0.0, 1.0);
        let got = mean_albedo(&base_only, MEAN_ALBEDO_SAMPLES);
        for (c, g) in got.iter().enumerate() {
            let t_bar: f64 = mus.iter().zip(&ws).map(|(mu, w)| w * 2.0 * mu * t.eval::<f64>(*mu)[c]).sum();
            let want = b.pigment[c] * (b.pigment_weight + b.pearl_coverage * t_bar * t_bar);
            let rel = (g - want).abs() / want;
            eprintln!("pigment behind pearls ch {c}: ρ̄ {g:.6} closed form {want:.6}: {rel:.2e}");
            assert!(rel < 1e-3, "ch {c}: {g} vs {want}");
        }
    }
}
