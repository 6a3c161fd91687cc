//! Typed queries for hosts that map Lacquer onto their own property systems (the Mitsuba
//! plugin's typed properties, flags and albedo AOV): parameter specifications per model, one
//! parameter's value, a material's lobes and its diffuse albedo.

use crate::material::{lq_material, material};
use crate::status::{guard, lq_status, Failure};
use crate::strings::{c_str, out_string};
use lacquer_core::lobes::bits;
use lacquer_core::models;
use lacquer_core::params::{Default as PDefault, ParamKind};
use std::ffi::{c_char, CString};
use std::sync::OnceLock;

/// Lobe bit of `lq_material_lobes`: a diffuse (pigment) lobe.
pub const LQ_LOBE_DIFFUSE: u32 = 1;
/// Lobe bit: a glossy lobe.
pub const LQ_LOBE_GLOSSY: u32 = 2;
/// Lobe bit: a Dirac delta (mirror) lobe; samples from it carry `LQ_SAMPLE_DELTA`.
pub const LQ_LOBE_DELTA: u32 = 4;
/// Lobe bit: the BRDF changes when both directions rotate about the normal.
pub const LQ_LOBE_ANISOTROPIC: u32 = 8;
/// Lobe bit: the model is not reciprocal (`f(wi, wo) != f(wo, wi)` in general).
pub const LQ_LOBE_NON_RECIPROCAL: u32 = 16;
/// Lobe bit: spatially varying (sparkle): the `*_spatial` calls differ from the plain ones.
pub const LQ_LOBE_SPATIALLY_VARYING: u32 = 32;
/// Lobe bit: spectral physics (the pearl paint's thin film, HTSG): `lq_eval_spectral` /
/// `lq_sample_spectral` carry more than the RGB value upsampled.
pub const LQ_LOBE_SPECTRAL: u32 = 64;

// The C constants are literals (cbindgen copies them); they must equal the core's bits.
const _: () = assert!(
    LQ_LOBE_DIFFUSE == bits::DIFFUSE
        && LQ_LOBE_GLOSSY == bits::GLOSSY
        && LQ_LOBE_DELTA == bits::DELTA
        && LQ_LOBE_ANISOTROPIC == bits::ANISOTROPIC
        && LQ_LOBE_NON_RECIPROCAL == bits::NON_RECIPROCAL
        && LQ_LOBE_SPATIALLY_VARYING == bits::SPATIALLY_VARYING
        && LQ_LOBE_SPECTRAL == bits::SPECTRAL
);

/// Kind of a model parameter (`lq_param_spec.kind`).
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum lq_param_kind {
    /// A number within [min, max].
    LQ_PARAM_SCALAR = 0,
    /// Linear Rec.709 RGB (or a grey scalar), each component within [min, max].
    LQ_PARAM_COLOR = 1,
    /// A whole number within [min, max].
    LQ_PARAM_INTEGER = 2,
    /// true / false.
    LQ_PARAM_BOOL = 3,
    /// One of the strings in `choices`.
    LQ_PARAM_CHOICE = 4,
    /// A structured JSON value (e.g. a list of lobes).
    LQ_PARAM_JSON = 5,
    /// A free string (e.g. a file path).
    LQ_PARAM_TEXT = 6,
}

/// One parameter of a model, as `lacquer models` lists it. Every string is static storage
/// owned by the library (valid for the life of the process; never free them).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct lq_param_spec {
    /// JSON key, e.g. "flake_density".
    pub name: *const c_char,
    /// An `lq_param_kind`.
    pub kind: i32,
    /// Smallest valid value (scalar, colour component, integer; 0 otherwise).
    pub min: f64,
    /// Largest valid value.
    pub max: f64,
    /// Default: scalar / integer / bool (0 or 1) in [0]; colour in [0..3]; 0 otherwise.
    pub default_value: [f64; 3],
    /// Default of a choice, JSON or text parameter; "" otherwise.
    pub default_text: *const c_char,
    /// The valid strings of a choice, separated by '|'; "" otherwise.
    pub choices: *const c_char,
    /// Physical unit ("" when dimensionless), e.g. "mm", "µm", "%".
    pub unit: *const c_char,
    /// One-line meaning.
    pub doc: *const c_char,
}

struct Cached {
    name: CString,
    kind: lq_param_kind,
    min: f64,
    max: f64,
    default_value: [f64; 3],
    default_text: CString,
    choices: CString,
    unit: CString,
    doc: CString,
}

fn cstring(s: &str) -> CString {
    // Names and docs in the registry contain no NUL bytes; a NUL would truncate, never fail.
    CString::new(s.replace('\0', "")).unwrap_or_default()
}

fn cache() -> &'static Vec<(&'static str, Vec<Cached>)> {
    static CACHE: OnceLock<Vec<(&'static str, Vec<Cached>)>> = OnceLock::new();
    CACHE.get_or_init(|| {
        models::all()
            .iter()
            .map(|info| {
                let params = info
                    .params
                    .iter()
                    .map(|s| {
                        let (kind, choices) = match s.kind {
                            ParamKind::Scalar => (lq_param_kind::LQ_PARAM_SCALAR, String::new()),
                            ParamKind::Color => (lq_param_kind::LQ_PARAM_COLOR, String::new()),
                            ParamKind::Integer => (lq_param_kind::LQ_PARAM_INTEGER, String::new()),
                            ParamKind::Bool => (lq_param_kind::LQ_PARAM_BOOL, String::new()),
                            ParamKind::Choice(c) => (lq_param_kind::LQ_PARAM_CHOICE, c.join("|")),
                            ParamKind::Json => (lq_param_kind::LQ_PARAM_JSON, String::new()),
                            ParamKind::Text => (lq_param_kind::LQ_PARAM_TEXT, String::new()),
                        };
                        let (default_value, default_text) = match s.default {
                            PDefault::Scalar(x) => ([x, 0.0, 0.0], ""),
                            PDefault::Color(c) => (c, ""),
                            PDefault::Integer(i) => ([i as f64, 0.0, 0.0], ""),
                            PDefault::Bool(b) => ([f64::from(u8::from(b)), 0.0, 0.0], ""),
                            PDefault::Choice(t) | PDefault::Json(t) | PDefault::Text(t) => ([0.0; 3], t),
                        };
                        let numeric = matches!(
                            kind,
                            lq_param_kind::LQ_PARAM_SCALAR
                                | lq_param_kind::LQ_PARAM_COLOR
                                | lq_param_kind::LQ_PARAM_INTEGER
                        );
                        Cached {
                            name: cstring(s.name),
                            kind,
                            min: if numeric { s.min } else { 0.0 },
                            max: if numeric { s.max } else { 0.0 },
                            default_value,
                            default_text: cstring(default_text),
                            choices: cstring(&choices),
                            unit: cstring(s.unit),
                            doc: cstring(s.doc),
                        }
                    })
                    .collect();
                (info.name, params)
            })
            .collect()
    })
}

fn model_params(model: *const c_char) -> Result<&'static [Cached], Failure> {
    // SAFETY: the caller's contract (NULL or NUL-terminated).
    let name = unsafe { c_str("model", model, lq_status::LQ_ERR_UNKNOWN_NAME) }?;
    cache().iter().find(|(n, _)| *n == name).map(|(_, p)| p.as_slice()).ok_or_else(|| {
        Failure::from(lacquer_core::Error::UnknownModel {
            name: name.to_string(),
            known: models::all().iter().map(|m| m.name).collect(),
        })
    })
}

/// The number of parameters of a registered model (`lacquer models` lists them).
/// LQ_ERR_UNKNOWN_NAME if no model has this name.
///
/// # Safety
/// `model` is NULL or a NUL-terminated string; `out_count` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_model_param_count(model: *const c_char, out_count: *mut usize) -> lq_status {
    guard(|| {
        let params = model_params(model)?;
        if out_count.is_null() {
            return Err(Failure::null("out_count"));
        }
        // SAFETY: checked non-NULL; the caller's writable slot.
        unsafe { *out_count = params.len() };
        Ok(())
    })
}

/// Parameter `index` (0 ≤ index < `lq_model_param_count`) of a registered model: name, kind,
/// range, default, choices, unit and meaning, in `lacquer models` order. Strings in `*out`
/// are static (never free them). LQ_ERR_UNKNOWN_NAME for an unknown model,
/// LQ_ERR_INVALID_ARGUMENT for an index out of range.
///
/// # Safety
/// `model` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_model_param(model: *const c_char, index: usize, out: *mut lq_param_spec) -> lq_status {
    guard(|| {
        let params = model_params(model)?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let p = params.get(index).ok_or_else(|| {
            Failure::invalid(format!("parameter index {index} out of range (the model has {})", params.len()))
        })?;
        let spec = lq_param_spec {
            name: p.name.as_ptr(),
            kind: p.kind as i32,
            min: p.min,
            max: p.max,
            default_value: p.default_value,
            default_text: p.default_text.as_ptr(),
            choices: p.choices.as_ptr(),
            unit: p.unit.as_ptr(),
            doc: p.doc.as_ptr(),
        };
        // SAFETY: checked non-NULL; the caller's writable slot.
        unsafe { *out = spec };
        Ok(())
    })
}

/// The value of one parameter of a material as JSON text (`0.5`, `[0.1, 0.2, 0.3]`, `true`,
/// `"Al"`, or a structured value); `name` may also be "model" (the model name as a JSON
/// string). Free the string with `lq_string_free`. LQ_ERR_UNKNOWN_NAME if the material's
/// model has no such parameter.
///
/// # Safety
/// `m` is NULL or a live handle; `name` is NULL or a NUL-terminated string; `out_json` is
/// NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_param_json(
    m: *const lq_material,
    name: *const c_char,
    out_json: *mut *mut c_char,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        // SAFETY: the caller's contract above.
        let key = unsafe { c_str("name", name, lq_status::LQ_ERR_UNKNOWN_NAME) }?;
        let json = m.to_json();
        let value = json.get(key).ok_or_else(|| {
            let known: Vec<&str> = m.info().params.iter().map(|p| p.name).collect();
            Failure::new(
                lq_status::LQ_ERR_UNKNOWN_NAME,
                format!("model {} has no parameter \"{key}\" (it has: model, {})", m.info().name, known.join(", ")),
            )
        })?;
        // SAFETY: checked for NULL inside.
        unsafe { out_string("out_json", out_json, value.to_string()) }
    })
}

/// The kinds of lobes of a material: a bit set of `LQ_LOBE_DIFFUSE`, `LQ_LOBE_GLOSSY`,
/// `LQ_LOBE_DELTA`, `LQ_LOBE_ANISOTROPIC`, `LQ_LOBE_NON_RECIPROCAL`,
/// `LQ_LOBE_SPATIALLY_VARYING`, `LQ_LOBE_SPECTRAL` and `LQ_LOBE_COAT` (a clearcoat top
/// reflection a lobe mask selects on its own, see `lq_material_lobe_part`), decided by the
/// core from the model and its parameters (no sampling).
///
/// # Safety
/// `m` is NULL or a live handle; `out_lobes` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_lobes(m: *const lq_material, out_lobes: *mut u32) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        if out_lobes.is_null() {
            return Err(Failure::null("out_lobes"));
        }
        // SAFETY: checked non-NULL.
        unsafe { *out_lobes = m.lobes() };
        Ok(())
    })
}

/// The albedo of the material's diffuse (pigment) part, linear Rec.709 RGB (3 floats; zero
/// when it has no diffuse lobe): what an albedo AOV should show, without the specular
/// highlight.
///
/// # Safety
/// `m` is NULL or a live handle; `out_rgb` is NULL or holds 3 writable floats.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_diffuse_reflectance(m: *const lq_material, out_rgb: *mut f32) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        if out_rgb.is_null() {
            return Err(Failure::null("out_rgb"));
        }
        let d = m.diffuse_reflectance();
        for (i, v) in d.iter().enumerate() {
            // SAFETY: the caller provides 3 writable floats.
            unsafe { *out_rgb.add(i) = *v as f32 };
        }
        Ok(())
    })
}
