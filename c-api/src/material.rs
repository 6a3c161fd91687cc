//! The material handle: creation from JSON or a preset name, freeing, and its canonical JSON.

use crate::status::{guard, guard_value, lq_status, Failure};
use crate::strings::{c_str, out_string};
use lacquer_core::Material;
use std::ffi::c_char;

/// An immutable, validated material. Create it with `lq_material_from_json` or
/// `lq_material_from_preset`, release it with `lq_material_free`. It may be used from any
/// number of threads at once (every function takes it as `const`).
pub struct lq_material {
    pub(crate) inner: Material,
}

/// Borrows the material behind a handle.
///
/// # Safety
/// `m` is NULL or a live handle from `lq_material_from_*`.
pub(crate) unsafe fn material<'a>(m: *const lq_material) -> Result<&'a Material, Failure> {
    // SAFETY: non-NULL handles come from Box::into_raw and live until lq_material_free.
    unsafe { m.as_ref() }.map(|h| &h.inner).ok_or_else(|| Failure::null("m"))
}

fn store(out: *mut *mut lq_material, m: Material) {
    let boxed = Box::into_raw(Box::new(lq_material { inner: m }));
    // SAFETY: `out` was checked non-NULL by the caller; it is the caller's writable slot.
    unsafe { *out = boxed };
}

/// Parses a material: `{"model": "<name>", "<param>": value, ...}` or `{"preset": "<name>"}`.
///
/// On success writes a new handle to `*out` (free it with `lq_material_free`); on error
/// leaves `*out` untouched and returns LQ_ERR_NULL, LQ_ERR_INVALID_JSON,
/// LQ_ERR_INVALID_MATERIAL or LQ_ERR_UNKNOWN_NAME with a message naming the parameter.
///
/// # Safety
/// `json` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_from_json(json: *const c_char, out: *mut *mut lq_material) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let text = unsafe { c_str("json", json, lq_status::LQ_ERR_INVALID_JSON) }?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        store(out, Material::from_json(text)?);
        Ok(())
    })
}

/// Builds a named preset (the names are in `lq_presets_json`); same as
/// `lq_material_from_json("{\"preset\": \"<name>\"}")`.
///
/// # Safety
/// `name` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_from_preset(name: *const c_char, out: *mut *mut lq_material) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let name = unsafe { c_str("name", name, lq_status::LQ_ERR_UNKNOWN_NAME) }?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        store(out, Material::preset(name)?);
        Ok(())
    })
}

/// Releases a material. NULL is a no-op. The handle must not be in use by another thread
/// and must not be used or freed again afterwards.
///
/// # Safety
/// `m` is NULL or a live handle from `lq_material_from_*` that is freed exactly once.
#[no_mangle]
pub unsafe extern "C" fn lq_material_free(m: *mut lq_material) {
    if m.is_null() {
        return;
    }
    guard_value((), || {
        // SAFETY: the handle came from Box::into_raw and is freed once (caller's contract).
        drop(unsafe { Box::from_raw(m) });
    });
}

/// The complete material as canonical JSON (model name and every parameter, defaults
/// included). On success writes a new string to `*out_json`; free it with `lq_string_free`.
///
/// # Safety
/// `m` is NULL or a live handle; `out_json` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_to_json(m: *const lq_material, out_json: *mut *mut c_char) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        // SAFETY: checked for NULL inside.
        unsafe { out_string("out_json", out_json, m.to_json().to_string()) }
    })
}
