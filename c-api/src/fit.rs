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
/// brdf_cos_rms, snr_db, seconds}, "fit": {...}, "base_color_map": {"base_color": [9 grid
/// values], "pigment_color": [[r, g, b], ...], "ratio": [[r, g, b], ...],
/// "interpolation_max"}}` to `*out_json` (free it with `lq_string_free`); colours are
/// `[r, g, b]`. The base colour map is the Pigment Color a textured Base Color needs
/// (docs/blender-fit.md). On error leaves `*out_json` untouched and
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

/// "Model only what a scene needs", measured: evaluates the material in every configuration
/// the library offers (the f64 reference, the f32 SIMD batch kernels, and the kernels with the
/// lobes the material could drop), measures each one's cost and the maximum relative error of
/// f·cos θi against the f64 reference on `n` random direction pairs (0 = 65536), and picks
/// the cheapest within `max_error`, like `lacquer bench --material ... --max-error E`.
///
/// `material` is a live handle. On success writes `{"max_error", "picked": {"name",
/// "material", "path", "ns_per_eval", "error": {"max", "rms"}}, "candidates": [...]}` to
/// `*out_json` (free with `lq_string_free`). Returns LQ_ERR_NULL for a NULL handle or
/// `out_json`, LQ_ERR_INVALID_ARGUMENT for a negative or NaN `max_error` or `n` > 2²⁰. Takes
/// 0.05–2 s (it times the candidates).
///
/// # Safety
/// `m` is NULL or a live handle; `out_json` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_choose_configuration(
    m: *const crate::material::lq_material,
    max_error: f64,
    n: usize,
    out_json: *mut *mut c_char,
) -> lq_status {
    guard(|| {
        // SAFETY: the handle contract above.
        let m = unsafe { crate::material::material(m) }?;
        if out_json.is_null() {
            return Err(Failure::null("out_json"));
        }
        if max_error.is_nan() || max_error < 0.0 {
            return Err(Failure::invalid(format!("max_error must be a non-negative number, got {max_error}")));
        }
        if n > 1 << 20 {
            return Err(Failure::invalid(format!("n = {n} direction pairs is more than 2^20 (1048576)")));
        }
        let n = if n == 0 { 1 << 16 } else { n };
        let choice = lacquer_core::bench::choose(m, max_error, n);
        let json = serde_json::to_string(&choice).map_err(|e| Failure::invalid(format!("cannot serialise: {e}")))?;
        // SAFETY: checked non-NULL above.
        unsafe { out_string("out_json", out_json, json) }
    })
}
