//! Fits across the boundary: the Blender node group `Lacquer Coated Paint` fitted to a paint.

use crate::status::{guard, lq_status, Failure};
use crate::strings::{c_str, out_string};
use lacquer_core::fit::node_group;
use std::ffi::c_char;

/// Fits the inputs of the Blender node group `Lacquer Coated Paint` (its mean lobe, built
/// from Principled BSDFs) to a `coated_paint` material, like `lacquer fit-node-group --json`.
///
/// `material_json` is a coated_paint material (`{"model": "coated_paint", ...}`), a preset
/// (`{"preset": "<name>"}`) or a bare preset name. On success writes
/// `{"inputs": {socket name: value}, "error": {albedo_rms, albedo_max, brdf_rel_rms,
/// brdf_cos_rms, snr_db, seconds}, "fit": {...}}` to `*out_json` (free it with
/// `lq_string_free`); colours are `[r, g, b]`. On error leaves `*out_json` untouched and
/// returns LQ_ERR_NULL, LQ_ERR_INVALID_JSON, LQ_ERR_UNKNOWN_NAME or LQ_ERR_INVALID_MATERIAL
/// (also for a valid material that is not a coated_paint). Takes about 0.1–2 s.
///
/// # Safety
/// `material_json` is NULL or a NUL-terminated string; `out_json` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_fit_node_group(material_json: *const c_char, out_json: *mut *mut c_char) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let text = unsafe { c_str("material_json", material_json, lq_status::LQ_ERR_INVALID_JSON) }?;
        if out_json.is_null() {
            return Err(Failure::null("out_json"));
        }
        let fit = node_group::fit_node_group_json(text)?;
        let json =
            serde_json::to_string(&fit.to_json()).map_err(|e| Failure::invalid(format!("cannot serialise: {e}")))?;
        // SAFETY: checked non-NULL above.
        unsafe { out_string("out_json", out_json, json) }
    })
}
