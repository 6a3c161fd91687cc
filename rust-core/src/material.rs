//! [`Material`]: a validated model built from JSON, with input sanitising.
//!
//! This is the front door for every host (CLI, C ABI, Python). Directions that are not
//! finite give zero (and `None` for sampling); directions that are finite but not unit
//! length are normalised first.

use crate::bxdf::{BsdfSample, ModelInfo, SurfacePoint};
use crate::error::Error;
use crate::lobes::LobeSelection;
use crate::math::{Rgb, Vec3};
use crate::models::{self, Model};
use crate::params::Params;
use crate::presets;
use crate::real::Real;
use serde_json::Value;

/// What a material JSON names: a preset, or a model with its validated parameters.
enum Parsed<'a> {
    Preset(&'a str),
    Model(&'static ModelInfo, Params),
}

/// A reflectance model with validated parameters. Immutable and `Sync`: share it freely.
#[derive(Clone, Debug)]
pub struct Material {
    model: Model,
    info: &'static ModelInfo,
    params: Params,
    /// The spectral bank (`crate::spectral`), built on the first spectral evaluation.
    spectral: std::sync::OnceLock<Option<Box<crate::spectral::SpectralBank>>>,
    /// Per-component tables for per-element parameters (coated paint), built on first use:
    /// `[0]` at the material's coat roughness, `[1]` over the roughness grid.
    varying: [std::sync::OnceLock<std::sync::Arc<crate::paint::varying::VaryingPaint>>; 2],
}

/// Returns a unit version of `w`, or `None` if it is not finite or has zero length.
#[inline]
pub(crate) fn sanitize<T: Real>(w: Vec3<T>) -> Option<Vec3<T>> {
    let l2 = w.length_squared();
    if !l2.is_finite() || !(l2 > T::zero()) {
        return None;
    }
    if (l2 - T::one()).abs() > T::of(64.0) * T::epsilon() {
        Some(w / l2.sqrt())
    } else {
        Some(w)
    }
}

impl Material {
    /// The lazily built spectral bank of this material (see `crate::spectral`).
    pub(crate) fn spectral_bank_cell(&self) -> &std::sync::OnceLock<Option<Box<crate::spectral::SpectralBank>>> {
        &self.spectral
    }

    /// Parses material JSON: `{"model": ..., params...}` or `{"preset": "name"}`.
    pub fn from_json(text: &str) -> Result<Self, Error> {
        let v: Value = serde_json::from_str(text).map_err(|e| Error::Json(e.to_string()))?;
        Self::from_value(&v)
    }

    /// Builds a material from parsed JSON.
    pub fn from_value(v: &Value) -> Result<Self, Error> {
        match Self::parse_value(v)? {
            Parsed::Preset(name) => Self::preset(name),
            Parsed::Model(info, params) => Self::from_params(info, params),
        }
    }

    /// The complete JSON (every parameter, defaults filled in) of the material `v` describes,
    /// as [`Material::to_json`] of the built material gives it, without building it: a paint's
    /// layer tables cost tens of milliseconds, which a host listing presets or normalising a
    /// material file need not pay. Every parameter is checked (names, types, ranges); checks
    /// that need the built model (e.g. `rough_plastic`'s distinct indices) are not made.
    pub fn canonical_json(v: &Value) -> Result<Value, Error> {
        match Self::parse_value(v)? {
            Parsed::Preset(name) => {
                let p = presets::find(name).ok_or_else(|| Error::UnknownPreset { name: name.to_string() })?;
                p.material_json()
            }
            Parsed::Model(_, params) => Ok(params.to_json()),
        }
    }

    /// The model and its validated parameters, or the preset, that `v` names.
    fn parse_value(v: &Value) -> Result<Parsed<'_>, Error> {
        let obj = v.as_object().ok_or_else(|| Error::Shape("expected a JSON object".into()))?;
        if let Some(p) = obj.get("preset") {
            let name = p.as_str().ok_or_else(|| Error::WrongType { param: "preset".into(), expected: "a string" })?;
            if obj.len() > 1 {
                return Err(Error::Shape("{\"preset\": ...} takes no other keys".into()));
            }
            return Ok(Parsed::Preset(name));
        }
        let name = obj
            .get("model")
            .ok_or_else(|| Error::Shape("missing \"model\" (or \"preset\") key".into()))?
            .as_str()
            .ok_or_else(|| Error::WrongType { param: "model".into(), expected: "a string" })?;
        let info = models::find(name).ok_or_else(|| Error::UnknownModel {
            name: name.to_string(),
            known: models::all().iter().map(|m| m.name).collect(),
        })?;
        let params = Params::parse(info.name, info.params, obj)?;
        Ok(Parsed::Model(info, params))
    }

    /// Builds a named preset.
    pub fn preset(name: &str) -> Result<Self, Error> {
        let p = presets::find(name).ok_or_else(|| Error::UnknownPreset { name: name.to_string() })?;
        Self::from_json(p.json)
    }

    /// Builds a model from already validated parameters.
    pub fn from_params(info: &'static ModelInfo, params: Params) -> Result<Self, Error> {
        let model = (info.build)(&params)?;
        Ok(Self { model, info, params, spectral: std::sync::OnceLock::new(), varying: Default::default() })
    }

    /// Assembles a material from a model built outside its registry `build` (e.g. a measured
    /// table held in memory); `params` must be the model's.
    pub(crate) fn from_parts(info: &'static ModelInfo, params: Params, model: Model) -> Self {
        Self { model, info, params, spectral: std::sync::OnceLock::new(), varying: Default::default() }
    }

    /// A model with all its defaults.
    pub fn default_of(info: &'static ModelInfo) -> Result<Self, Error> {
        Self::from_params(info, Params::defaults(info.name, info.params))
    }

    /// The model's registry entry.
    #[must_use]
    pub fn info(&self) -> &'static ModelInfo {
        self.info
    }

    /// The model itself (no input sanitising).
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// True when [`Material::eval_at`] can differ from [`Material::eval`] (sparkle is on).
    #[must_use]
    pub fn spatially_varying(&self) -> bool {
        self.model.spatially_varying()
    }

    /// The kinds of lobes this material has: a bit set of [`crate::lobes::bits`] (diffuse,
    /// glossy, delta, anisotropic, non-reciprocal, spatially varying).
    #[must_use]
    pub fn lobes(&self) -> u32 {
        crate::lobes::lobes(self)
    }

    /// The lobe groups a lobe mask selects (one per separable group for models that separate
    /// their lobes, such as `coated_paint`: pigment, glossy base lobes, coat; one group
    /// holding every lobe for the others). What a renderer's components are.
    #[must_use]
    pub fn lobe_parts(&self) -> Vec<crate::lobes::LobePart> {
        crate::lobes::lobe_parts(self)
    }

    /// Validates a lobe mask ([`crate::lobes::bits::SELECTABLE`]) for this material: unknown
    /// bits, or a mask enabling some but not all of the lobes of a model that evaluates them
    /// together, are errors naming the mask.
    pub fn select_lobes(&self, mask: u32) -> Result<crate::lobes::LobeSelection, Error> {
        crate::lobes::select_lobes(self, mask)
    }

    /// The weight with which sampling picks the lobes of a lobe mask for an outgoing
    /// direction at `cos θo = cos_o` (the core's own lobe selection: the lobes of `mask` are
    /// picked with probability `weight(mask) / weight(all)` at that angle), for models that
    /// separate their lobes by such weights (`coated_paint`); `None` for the others.
    #[must_use]
    pub fn lobe_selection_weight(&self, cos_o: f64, mask: u32) -> Option<f64> {
        match &self.model {
            Model::CoatedPaint(p) => Some(p.selection_weight(cos_o, crate::paint::coated_paint::PaintParts::of(mask))),
            _ => None,
        }
    }

    /// [`Material::eval`] restricted to a lobe selection.
    #[inline]
    #[must_use]
    pub fn eval_lobes<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, sel: LobeSelection) -> Rgb<T> {
        match sel {
            LobeSelection::All => self.eval(wi, wo),
            LobeSelection::Nothing => Rgb::zero(),
            LobeSelection::Some(l) => match (sanitize(wi), sanitize(wo)) {
                (Some(wi), Some(wo)) => self.model.eval_lobes(wi, wo, l),
                _ => Rgb::zero(),
            },
        }
    }

    /// The density of [`Material::sample_lobes`].
    #[inline]
    #[must_use]
    pub fn pdf_lobes<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, sel: LobeSelection) -> T {
        match sel {
            LobeSelection::All => self.pdf(wi, wo),
            LobeSelection::Nothing => T::zero(),
            LobeSelection::Some(l) => match (sanitize(wi), sanitize(wo)) {
                (Some(wi), Some(wo)) => self.model.pdf_lobes(wi, wo, l),
                _ => T::zero(),
            },
        }
    }

    /// [`Material::sample`] among the selected lobes (their selection renormalised): the
    /// weight is the selected lobes' `f · cos / pdf`.
    #[inline]
    #[must_use]
    pub fn sample_lobes<T: Real>(&self, wo: Vec3<T>, u: [T; 3], sel: LobeSelection) -> Option<BsdfSample<T>> {
        match sel {
            LobeSelection::All => self.sample(wo, u),
            LobeSelection::Nothing => None,
            LobeSelection::Some(l) => {
                let wo = sanitize(wo)?;
                if !u.iter().all(|x| x.is_finite()) {
                    return None;
                }
                let one_minus = crate::sampling::one_minus_epsilon::<T>();
                self.model.sample_lobes(wo, u.map(|x| x.clamp_to(T::zero(), one_minus)), l)
            }
        }
    }

    /// [`Material::eval_at`] restricted to a lobe selection.
    #[inline]
    #[must_use]
    pub fn eval_at_lobes<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint, sel: LobeSelection) -> Rgb<T> {
        match sel {
            LobeSelection::All => self.eval_at(wi, wo, at),
            LobeSelection::Nothing => Rgb::zero(),
            LobeSelection::Some(_) if !at.is_finite() => self.eval_lobes(wi, wo, sel),
            LobeSelection::Some(l) => match (sanitize(wi), sanitize(wo)) {
                (Some(wi), Some(wo)) => self.model.eval_at_lobes(wi, wo, at, l),
                _ => Rgb::zero(),
            },
        }
    }

    /// [`Material::sample_at`] among the selected lobes; the density is [`Material::pdf_lobes`].
    #[inline]
    #[must_use]
    pub fn sample_at_lobes<T: Real>(
        &self,
        wo: Vec3<T>,
        u: [T; 3],
        at: &SurfacePoint,
        sel: LobeSelection,
    ) -> Option<BsdfSample<T>> {
        match sel {
            LobeSelection::All => self.sample_at(wo, u, at),
            LobeSelection::Nothing => None,
            LobeSelection::Some(_) if !at.is_finite() => self.sample_lobes(wo, u, sel),
            LobeSelection::Some(l) => {
                let wo = sanitize(wo)?;
                if !u.iter().all(|x| x.is_finite()) {
                    return None;
                }
                let one_minus = crate::sampling::one_minus_epsilon::<T>();
                self.model.sample_at_lobes(wo, u.map(|x| x.clamp_to(T::zero(), one_minus)), at, l)
            }
        }
    }

    /// The albedo of the diffuse (pigment) part, linear Rec.709; zero without one. What a
    /// renderer's albedo AOV should show (not the specular highlight).
    #[must_use]
    pub fn diffuse_reflectance(&self) -> [f64; 3] {
        crate::lobes::diffuse_reflectance(self)
    }

    /// The per-component tables that evaluate this material with per-element parameters
    /// ([`crate::paint::varying`]; `vary_alpha`: the coat roughness varies too), built once and
    /// kept; `None` for models other than `coated_paint` and for its EON pigment.
    #[must_use]
    pub fn varying_paint(&self, vary_alpha: bool) -> Option<&crate::paint::varying::VaryingPaint> {
        let Model::CoatedPaint(p) = &self.model else { return None };
        // The component tables are built for the Lambertian pigment (linear in its colour);
        // the EON pigment's multiple-scattering term is not, so it has no varying tables.
        if self.params.choice("pigment_model") != "lambert" {
            return None;
        }
        let cell = &self.varying[usize::from(vary_alpha)];
        Some(
            cell.get_or_init(|| {
                std::sync::Arc::new(crate::paint::varying::VaryingPaint::new(p, &self.params, vary_alpha))
            }),
        )
    }

    /// Validated parameters, defaults included.
    #[must_use]
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The complete material as JSON (model and every parameter).
    #[must_use]
    pub fn to_json(&self) -> Value {
        self.params.to_json()
    }

    /// `f_r(wi, wo)`; zero for non-finite or zero-length directions and below the surface.
    #[inline]
    #[must_use]
    pub fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        match (sanitize(wi), sanitize(wo)) {
            (Some(wi), Some(wo)) => self.model.eval(wi, wo),
            _ => Rgb::zero(),
        }
    }

    /// Density of [`Material::sample`] choosing `wi` given `wo`.
    #[inline]
    #[must_use]
    pub fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        match (sanitize(wi), sanitize(wo)) {
            (Some(wi), Some(wo)) => self.model.pdf(wi, wo),
            _ => T::zero(),
        }
    }

    /// Importance-samples `wi` given `wo` and three uniform numbers in `[0, 1)`.
    #[inline]
    #[must_use]
    pub fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let wo = sanitize(wo)?;
        if !u.iter().all(|x| x.is_finite()) {
            return None;
        }
        let one_minus = crate::sampling::one_minus_epsilon::<T>();
        let u = u.map(|x| x.clamp_to(T::zero(), one_minus));
        self.model.sample(wo, u)
    }

    /// `f_r(wi, wo)` at a surface point with a footprint (sparkle). A non-finite surface point
    /// falls back to the mean BRDF.
    #[inline]
    #[must_use]
    pub fn eval_at<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>, at: &SurfacePoint) -> Rgb<T> {
        if !at.is_finite() {
            return self.eval(wi, wo);
        }
        match (sanitize(wi), sanitize(wo)) {
            (Some(wi), Some(wo)) => self.model.eval_at(wi, wo, at),
            _ => Rgb::zero(),
        }
    }

    /// Samples at a surface point with a footprint; the density is [`Material::pdf`].
    #[inline]
    #[must_use]
    pub fn sample_at<T: Real>(&self, wo: Vec3<T>, u: [T; 3], at: &SurfacePoint) -> Option<BsdfSample<T>> {
        if !at.is_finite() {
            return self.sample(wo, u);
        }
        let wo = sanitize(wo)?;
        if !u.iter().all(|x| x.is_finite()) {
            return None;
        }
        let one_minus = crate::sampling::one_minus_epsilon::<T>();
        self.model.sample_at(wo, u.map(|x| x.clamp_to(T::zero(), one_minus)), at)
    }
}
