//! Tests of the exported functions, called as the C host calls them (raw pointers, statuses,
//! `lq_last_error`). They live inside the crate because the crate builds no rlib.

mod api;
mod bad_input;
mod boundary;
mod header;
mod threads;

use crate::*;
use std::ffi::{c_char, CStr, CString};

/// `lq_last_error()` as a Rust string.
pub(crate) fn last_error() -> String {
    unsafe { CStr::from_ptr(lq_last_error()) }.to_str().expect("UTF-8 message").to_string()
}

/// Builds a material from JSON; panics with the message on error.
pub(crate) fn material(json: &str) -> *mut lq_material {
    let c = CString::new(json).unwrap();
    let mut m = std::ptr::null_mut();
    let s = unsafe { lq_material_from_json(c.as_ptr(), &mut m) };
    assert_eq!(s, lq_status::LQ_OK, "{json}: {}", last_error());
    assert!(!m.is_null());
    m
}

/// Takes ownership of a library string.
pub(crate) fn take_string(p: *mut c_char) -> String {
    assert!(!p.is_null());
    let s = unsafe { CStr::from_ptr(p) }.to_str().unwrap().to_string();
    unsafe { lq_string_free(p) };
    s
}
mod lobes;
