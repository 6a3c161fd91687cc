//! The stable C ABI of Lacquer: `liblacquer.so` / `liblacquer.a` and `include/lacquer.h`
//! (generated from this crate by cbindgen; `tests/header.rs` fails when it drifts).
//!
//! This crate is an adapter: it validates and converts, and owns no physics. Every value
//! comes from `lacquer::Material`. The conventions (ownership, NULL, out-parameters,
//! per-element errors, threads) are written once in `c-api/README.md` and in the header's
//! preamble (`cbindgen.toml`).
//!
//! Every exported function runs inside [`status::guard`] (or `guard_value` for the few that
//! return a value): a Rust panic never unwinds into the host; it becomes `LQ_ERR_PANIC`.

#![allow(non_camel_case_types)]
#![warn(missing_docs)]

// The panic boundary needs unwinding: with panic = "abort" a bug would kill the host.
#[cfg(panic = "abort")]
compile_error!("lacquer-capi must be built with panic = \"unwind\" (its panic boundary relies on it)");

// Declaration order is the header's order.
mod arrays;
pub mod batch;
pub mod catalog;
pub mod fit;
pub mod introspect;
pub mod lobes;
pub mod material;
pub mod render;
pub mod status;
pub mod strings;
pub mod varying;

pub use batch::*;
pub use catalog::*;
pub use fit::*;
pub use introspect::*;
pub use lobes::*;
pub use material::*;
pub use render::*;
pub use status::lq_status;
pub use strings::*;
pub use varying::*;

use std::ffi::c_char;

/// ABI major version: incremented on any incompatible change; equals the number in the
/// shared library's SONAME (`liblacquer.so.0`).
pub const LQ_ABI_VERSION_MAJOR: u32 = 0;
/// ABI minor version: incremented when functions or status codes are added.
pub const LQ_ABI_VERSION_MINOR: u32 = 8;
/// The ABI version this header describes: `(major << 16) | minor`. Compare with
/// `lq_abi_version()` at run time: the majors must be equal and the library's minor at least
/// the header's.
pub const LQ_ABI_VERSION: u32 = (LQ_ABI_VERSION_MAJOR << 16) | LQ_ABI_VERSION_MINOR;

/// The ABI version of the loaded library, `(major << 16) | minor` (see `LQ_ABI_VERSION`).
#[no_mangle]
#[must_use]
pub extern "C" fn lq_abi_version() -> u32 {
    LQ_ABI_VERSION
}

/// The library's release version, e.g. "0.1.0" (static storage: do not free).
#[no_mangle]
#[must_use]
pub extern "C" fn lq_version() -> *const c_char {
    static VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");
    VERSION.as_ptr().cast()
}

/// The message of the most recent failed `lq_*` call on this thread, or "" if that call
/// succeeded. Never NULL. Owned by the library and valid until the next `lq_*` call on this
/// thread: copy it if you need to keep it; never free it.
#[no_mangle]
#[must_use]
pub extern "C" fn lq_last_error() -> *const c_char {
    status::guard_value(c"".as_ptr(), status::last_error_ptr)
}

/// The name of a status code ("LQ_OK", "LQ_ERR_NULL", ...), or "LQ_UNKNOWN_STATUS" for a
/// number that is not one. Static storage: do not free.
#[no_mangle]
#[must_use]
pub extern "C" fn lq_status_name(status: i32) -> *const c_char {
    status::ALL_STATUSES
        .iter()
        .find(|s| **s as i32 == status)
        .map_or(c"LQ_UNKNOWN_STATUS".as_ptr(), |s| s.name().as_ptr())
}

#[cfg(test)]
mod tests;
