//! Rendering with the reference renderer (`lacquer-render`): one JSON job in, one float RGBA
//! image out. The renderer owns light transport; materials are the core's.

use crate::status::{guard, guard_value, lq_status, Failure};
use crate::strings::c_str;
use lacquer_render::{render_job, Framebuffer, JobError};
use std::ffi::{c_char, c_void};

/// A rendered image. Free it with `lq_image_free`.
pub struct lq_image {
    width: u32,
    height: u32,
    rgba: Vec<f32>,
    albedo: Option<Vec<f32>>,
    normal: Option<Vec<f32>>,
}

/// Progress callback of `lq_render`: called on the thread that called `lq_render` (never on a
/// worker thread) with the fraction done in [0, 1] and the caller's `user` pointer. Return
/// `false` to cancel the render.
pub type lq_progress_fn = Option<unsafe extern "C" fn(progress: f32, user: *mut c_void) -> bool>;

fn flatten(v: &[[f32; 3]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

impl From<Framebuffer> for lq_image {
    fn from(fb: Framebuffer) -> Self {
        let rgba = fb.color.iter().zip(&fb.alpha).flat_map(|(c, a)| [c[0], c[1], c[2], *a]).collect();
        Self {
            width: fb.width,
            height: fb.height,
            rgba,
            albedo: fb.albedo.as_deref().map(flatten),
            normal: fb.normal.as_deref().map(flatten),
        }
    }
}

/// Renders a job: a JSON object with `preset` or `material`, an optional inline `scene`
/// (default: the built-in shader-ball scene), `width`, `height`, `spp`, `max_depth`, `seed`,
/// `threads`, `aovs`, `sparkle`, ... (docs/render.md lists every key). `progress` may be NULL.
///
/// On success writes a new image to `*out`. Errors: LQ_ERR_NULL, LQ_ERR_INVALID_JSON (not
/// UTF-8), LQ_ERR_INVALID_ARGUMENT (the job, its material or its scene is invalid; the
/// message says where), LQ_ERR_CANCELLED (the callback returned false). `*out` is untouched
/// on error.
///
/// # Safety
/// `job_json` is NULL or a NUL-terminated string; `progress` is NULL or callable with `user`;
/// `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render(
    job_json: *const c_char,
    progress: lq_progress_fn,
    user: *mut c_void,
    out: *mut *mut lq_image,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let text = unsafe { c_str("job_json", job_json, lq_status::LQ_ERR_INVALID_JSON) }?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let mut report = |fraction: f32| match progress {
            // SAFETY: the caller guarantees the callback accepts `user`.
            Some(f) => unsafe { f(fraction, user) },
            None => true,
        };
        let fb = render_job(text, &mut report).map_err(|e| match e {
            JobError::Invalid(m) => Failure::invalid(m),
            JobError::Cancelled => Failure::new(lq_status::LQ_ERR_CANCELLED, "the render was cancelled"),
        })?;
        // SAFETY: checked non-NULL above; the caller's writable slot.
        unsafe { *out = Box::into_raw(Box::new(lq_image::from(fb))) };
        Ok(())
    })
}

/// Width in pixels (0 for NULL).
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_width(img: *const lq_image) -> u32 {
    // SAFETY: the caller's contract above.
    guard_value(0, || unsafe { img.as_ref() }.map_or(0, |i| i.width))
}

/// Height in pixels (0 for NULL).
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_height(img: *const lq_image) -> u32 {
    // SAFETY: the caller's contract above.
    guard_value(0, || unsafe { img.as_ref() }.map_or(0, |i| i.height))
}

/// Linear Rec.709 radiance and coverage: width × height × 4 floats, rows top first. Valid
/// until `lq_image_free`; NULL for NULL.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_rgba(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || unsafe { img.as_ref() }.map_or(std::ptr::null(), |i| i.rgba.as_ptr()))
}

/// First-hit albedo (width × height × 3 floats), or NULL when the job had `"aovs": false`.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_albedo(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || {
        unsafe { img.as_ref() }.and_then(|i| i.albedo.as_ref()).map_or(std::ptr::null(), |v| v.as_ptr())
    })
}

/// First-hit world-space shading normal (width × height × 3 floats), or NULL without AOVs.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_normal(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || {
        unsafe { img.as_ref() }.and_then(|i| i.normal.as_ref()).map_or(std::ptr::null(), |v| v.as_ptr())
    })
}

/// Releases an image. NULL is a no-op.
///
/// # Safety
/// `img` is NULL or a live image, freed exactly once.
#[no_mangle]
pub unsafe extern "C" fn lq_image_free(img: *mut lq_image) {
    if !img.is_null() {
        // SAFETY: images come from Box::into_raw in lq_render.
        guard_value((), || drop(unsafe { Box::from_raw(img) }));
    }
}
