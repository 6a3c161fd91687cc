//! Status codes, the thread-local error message and the panic boundary every exported
//! function goes through.

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Result of every fallible `lq_*` call. `LQ_OK` is 0; every other value is an error, and
/// `lq_last_error()` then describes it. The numbers are part of the ABI: they never change
/// and new codes are only ever appended.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum lq_status {
    /// Success.
    LQ_OK = 0,
    /// A required pointer argument (handle, string, array or out-parameter) is NULL.
    LQ_ERR_NULL = 1,
    /// The text is not UTF-8 or not valid JSON (message has line and column).
    LQ_ERR_INVALID_JSON = 2,
    /// Valid JSON that is not a valid material: not an object, no "model", unknown key,
    /// wrong type, value out of range, or an impossible combination. The message names the
    /// parameter and its range.
    LQ_ERR_INVALID_MATERIAL = 3,
    /// No model or preset has this name (the message lists where to find the names).
    LQ_ERR_UNKNOWN_NAME = 4,
    /// An argument is unusable as a whole: a misaligned array, an output array overlapping
    /// another array, `n` so large that the arrays' byte size overflows, or an unknown enum
    /// value. Nothing was written.
    LQ_ERR_INVALID_ARGUMENT = 5,
    /// Per-element: at least one element has a direction (`wi` or `wo`) that is not finite
    /// or has zero length. Every element was processed; the invalid ones got zero outputs.
    LQ_ERR_INVALID_DIRECTION = 6,
    /// Per-element: at least one element has a non-finite `u`, `uv` or footprint (and valid
    /// directions). Every element was processed; the invalid ones got zero outputs.
    LQ_ERR_INVALID_ELEMENT = 7,
    /// A bug inside the library was caught at the ABI boundary (a Rust panic). The host
    /// keeps running; output arrays may be partly written. Please report the message.
    LQ_ERR_PANIC = 8,
}

use lq_status::*;

/// Every status, in numeric order (for `lq_status_name` and tests).
pub(crate) const ALL_STATUSES: [lq_status; 9] = [
    LQ_OK,
    LQ_ERR_NULL,
    LQ_ERR_INVALID_JSON,
    LQ_ERR_INVALID_MATERIAL,
    LQ_ERR_UNKNOWN_NAME,
    LQ_ERR_INVALID_ARGUMENT,
    LQ_ERR_INVALID_DIRECTION,
    LQ_ERR_INVALID_ELEMENT,
    LQ_ERR_PANIC,
];

impl lq_status {
    /// The constant's name as a static C string.
    pub(crate) fn name(self) -> &'static CStr {
        match self {
            LQ_OK => c"LQ_OK",
            LQ_ERR_NULL => c"LQ_ERR_NULL",
            LQ_ERR_INVALID_JSON => c"LQ_ERR_INVALID_JSON",
            LQ_ERR_INVALID_MATERIAL => c"LQ_ERR_INVALID_MATERIAL",
            LQ_ERR_UNKNOWN_NAME => c"LQ_ERR_UNKNOWN_NAME",
            LQ_ERR_INVALID_ARGUMENT => c"LQ_ERR_INVALID_ARGUMENT",
            LQ_ERR_INVALID_DIRECTION => c"LQ_ERR_INVALID_DIRECTION",
            LQ_ERR_INVALID_ELEMENT => c"LQ_ERR_INVALID_ELEMENT",
            LQ_ERR_PANIC => c"LQ_ERR_PANIC",
        }
    }
}

/// An error on its way out through the ABI: a status and a message for `lq_last_error`.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: lq_status,
    pub message: String,
}

impl Failure {
    #[cold]
    pub(crate) fn new(status: lq_status, message: impl Into<String>) -> Self {
        Self { status, message: message.into() }
    }
    #[cold]
    #[inline(never)]
    pub(crate) fn null(arg: &str) -> Self {
        Self::new(LQ_ERR_NULL, format!("argument `{arg}` is NULL"))
    }
    #[cold]
    pub(crate) fn invalid(message: impl Into<String>) -> Self {
        Self::new(LQ_ERR_INVALID_ARGUMENT, message)
    }
}

impl From<lacquer_core::Error> for Failure {
    fn from(e: lacquer_core::Error) -> Self {
        use lacquer_core::Error as E;
        let status = match &e {
            E::Json(_) => LQ_ERR_INVALID_JSON,
            E::UnknownModel { .. } | E::UnknownPreset { .. } => LQ_ERR_UNKNOWN_NAME,
            _ => LQ_ERR_INVALID_MATERIAL,
        };
        Self::new(status, e.to_string())
    }
}

thread_local! {
    // Const-initialised: no lazy-initialisation check on the hot path (every call clears it).
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

/// Stores the message `lq_last_error` returns on this thread (interior NULs become spaces).
#[cold]
fn set_last_error(message: &str) {
    let c = CString::new(message.replace('\0', " ")).unwrap_or_default();
    // `try_with`: during thread teardown the slot may be gone; losing the message is fine.
    let _ = LAST_ERROR.try_with(|slot| *slot.borrow_mut() = Some(c));
}

/// Empties the message (a successful call); nothing to do when it is already empty.
#[inline]
fn clear_last_error() {
    let _ = LAST_ERROR.try_with(|slot| {
        let mut slot = slot.borrow_mut();
        if slot.is_some() {
            *slot = None;
        }
    });
}

/// Pointer to this thread's message; valid until the next `lq_*` call on this thread.
pub(crate) fn last_error_ptr() -> *const c_char {
    LAST_ERROR.try_with(|slot| slot.borrow().as_ref().map_or(c"".as_ptr(), |c| c.as_ptr())).unwrap_or(c"".as_ptr())
}

/// Text of a panic payload (`panic!("...")` carries a `&str` or a `String`).
fn panic_text(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)")
}

/// The panic boundary: runs `body`, turns its error or panic into a status and a message,
/// and clears the message on success. Every fallible exported function is one call to this.
#[inline]
pub(crate) fn guard(body: impl FnOnce() -> Result<(), Failure>) -> lq_status {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            clear_last_error();
            LQ_OK
        }
        Ok(Err(f)) => {
            set_last_error(&f.message);
            f.status
        }
        Err(payload) => {
            let text =
                format!("internal error (Rust panic caught at the C ABI boundary): {}", panic_text(payload.as_ref()));
            // Dropping the payload could itself panic; never let that escape.
            let _ = catch_unwind(AssertUnwindSafe(move || drop(payload)));
            set_last_error(&text);
            LQ_ERR_PANIC
        }
    }
}

/// Like [`guard`] for functions that return a value instead of a status (no message is set;
/// a panic yields `fallback`).
#[inline]
pub(crate) fn guard_value<R>(fallback: R, body: impl FnOnce() -> R) -> R {
    catch_unwind(AssertUnwindSafe(body)).unwrap_or(fallback)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panics_become_a_status_and_a_message() {
        let s = guard(|| panic!("boom {}", 42));
        assert_eq!(s, LQ_ERR_PANIC);
        let msg = unsafe { CStr::from_ptr(last_error_ptr()) }.to_str().unwrap();
        assert!(msg.contains("boom 42"), "{msg}");
        // A later success clears the message.
        assert_eq!(guard(|| Ok(())), LQ_OK);
        assert_eq!(unsafe { CStr::from_ptr(last_error_ptr()) }.to_bytes(), b"");
    }

    #[test]
    fn static_str_panics_and_interior_nuls() {
        assert_eq!(guard(|| panic!("plain")), LQ_ERR_PANIC);
        let s = guard(|| Err(Failure::invalid("a\0b")));
        assert_eq!(s, LQ_ERR_INVALID_ARGUMENT);
        let msg = unsafe { CStr::from_ptr(last_error_ptr()) }.to_str().unwrap();
        assert_eq!(msg, "a b");
    }

    #[test]
    fn statuses_are_numbered_in_order() {
        for (i, s) in ALL_STATUSES.iter().enumerate() {
            assert_eq!(*s as i32, i as i32);
        }
    }
}
