//! Strings across the boundary: borrowed C strings in, library-allocated strings out.

use crate::status::{lq_status, Failure};
use std::ffi::{c_char, CStr, CString};

/// Borrows a NUL-terminated UTF-8 string; `bad_utf8` is the status for invalid UTF-8.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives `'a`.
pub(crate) unsafe fn c_str<'a>(name: &str, p: *const c_char, bad_utf8: lq_status) -> Result<&'a str, Failure> {
    if p.is_null() {
        return Err(Failure::null(name));
    }
    // SAFETY: non-NULL and NUL-terminated by the caller's contract.
    let c = unsafe { CStr::from_ptr(p) };
    c.to_str().map_err(|e| {
        Failure::new(bad_utf8, format!("argument `{name}` is not UTF-8 (invalid byte at offset {})", e.valid_up_to()))
    })
}

/// Hands a new string to the caller through `out` (to be freed with `lq_string_free`).
///
/// # Safety
/// `out` is NULL or writable.
pub(crate) unsafe fn out_string(name: &str, out: *mut *mut c_char, text: String) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null(name));
    }
    // JSON produced by serde_json never contains a raw NUL (it is escaped as \u0000).
    let c = CString::new(text).map_err(|_| Failure::invalid("string contains a NUL byte"))?;
    // SAFETY: checked non-NULL; the caller's writable slot.
    unsafe { *out = c.into_raw() };
    Ok(())
}

/// Releases a string returned by this library (`lq_models_json`, `lq_material_to_json`,
/// `lq_check_*`...). NULL is a no-op. Never pass `lq_last_error()` or `lq_version()` here.
///
/// # Safety
/// `s` is NULL or a string from this library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn lq_string_free(s: *mut c_char) {
    if s.is_null() {
        return;
    }
    crate::status::guard_value((), || {
        // SAFETY: came from CString::into_raw (caller's contract), freed once.
        drop(unsafe { CString::from_raw(s) });
    });
}
