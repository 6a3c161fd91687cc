//! What the library offers (models, presets) and the shipped checks, as JSON strings.

use crate::material::{lq_material, material};
use crate::status::{guard, lq_status, Failure};
use crate::strings::{c_str, out_string};
use lacquer_core::check::{self, CheckConfig};
use lacquer_core::{models, presets};
use serde_json::{json, Value};
use std::ffi::c_char;

/// How thorough `lq_check_*` is.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum lq_check_level {
    /// `lacquer check --quick`: fewer samples (about a second per material).
    LQ_CHECK_QUICK = 0,
    /// `lacquer check`: what the project's CI runs (several seconds per material).
    LQ_CHECK_STANDARD = 1,
}

fn config(level: i32) -> Result<CheckConfig, Failure> {
    match level {
        x if x == lq_check_level::LQ_CHECK_QUICK as i32 => Ok(CheckConfig::quick()),
        x if x == lq_check_level::LQ_CHECK_STANDARD as i32 => Ok(CheckConfig::standard()),
        other => Err(Failure::invalid(format!(
            "unknown check level {other}; use LQ_CHECK_QUICK (0) or LQ_CHECK_STANDARD (1)"
        ))),
    }
}

fn to_text(v: &impl serde::Serialize) -> Result<String, Failure> {
    // Non-finite figures serialise as null; serialisation itself cannot fail for these types.
    serde_json::to_string(v).map_err(|e| Failure::invalid(format!("cannot serialise: {e}")))
}

/// Every registered model as a JSON array (what `lacquer models --json` prints): name,
/// summary, reference, claims {reciprocal, energy_conserving, sampled} and params (name,
/// kind, default, min, max, unit, doc). Free the string with `lq_string_free`.
///
/// # Safety
/// `out_json` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_models_json(out_json: *mut *mut c_char) -> lq_status {
    guard(|| {
        let list: Vec<Value> = models::all().iter().map(|m| m.to_json()).collect();
        // SAFETY: checked for NULL inside.
        unsafe { out_string("out_json", out_json, to_text(&list)?) }
    })
}

/// Every preset as a JSON array of {name, description, material} where material is the full
/// material JSON (what `lacquer presets --json` prints). Free it with `lq_string_free`.
///
/// # Safety
/// `out_json` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_presets_json(out_json: *mut *mut c_char) -> lq_status {
    guard(|| {
        let list: Vec<Value> = presets::PRESETS
            .iter()
            .map(|p| {
                let material = p.material_json().unwrap_or(Value::Null);
                json!({"name": p.name, "description": p.description, "material": material})
            })
            .collect();
        // SAFETY: checked for NULL inside.
        unsafe { out_string("out_json", out_json, to_text(&list)?) }
    })
}

/// Runs the shipped checks (reciprocity, white furnace, χ² of the sampler, pdf integral,
/// sample/eval consistency, hard cases, f32 vs f64) on one material and judges them against
/// what its model claims, like `lacquer check --material ... --json`.
///
/// `level` is an `lq_check_level`. On success writes the JSON report to `*out_report`
/// (free with `lq_string_free`; `verdicts` lists each check's status pass / fail / reported)
/// and to `*out_passed` whether every claimed property held. A material that fails its
/// checks is still LQ_OK: the status is about the call, `*out_passed` about the material.
/// Takes from about a second (quick) to tens of seconds (standard).
///
/// # Safety
/// `m` is NULL or a live handle; the out-parameters are NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_check_material(
    m: *const lq_material,
    level: i32,
    out_report: *mut *mut c_char,
    out_passed: *mut bool,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        let cfg = config(level)?;
        if out_report.is_null() {
            return Err(Failure::null("out_report"));
        }
        if out_passed.is_null() {
            return Err(Failure::null("out_passed"));
        }
        let report = check::check_material(m, &cfg, "material", true);
        let passed = report.passed();
        // SAFETY: checked non-NULL above.
        unsafe { out_string("out_report", out_report, to_text(&report)?) }?;
        unsafe { *out_passed = passed };
        Ok(())
    })
}

/// Runs every check on one registered model (its defaults, its check parameter sets, random
/// parameter sets and parameter extremes), like `lacquer check --model NAME --json`.
/// LQ_ERR_UNKNOWN_NAME if no model has this name. Output as `lq_check_material`.
///
/// # Safety
/// `model` is NULL or a NUL-terminated string; the out-parameters are NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_check_model(
    model: *const c_char,
    level: i32,
    out_report: *mut *mut c_char,
    out_passed: *mut bool,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let name = unsafe { c_str("model", model, lq_status::LQ_ERR_UNKNOWN_NAME) }?;
        let cfg = config(level)?;
        if out_report.is_null() {
            return Err(Failure::null("out_report"));
        }
        if out_passed.is_null() {
            return Err(Failure::null("out_passed"));
        }
        let info = models::find(name).ok_or_else(|| {
            Failure::from(lacquer_core::Error::UnknownModel {
                name: name.to_string(),
                known: models::all().iter().map(|m| m.name).collect(),
            })
        })?;
        let report = check::check_model(info, &cfg);
        // SAFETY: checked non-NULL above.
        unsafe { out_string("out_report", out_report, to_text(&report)?) }?;
        unsafe { *out_passed = report.passed };
        Ok(())
    })
}
