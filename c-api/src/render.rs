//! Rendering with the reference renderer (`lacquer-render`): one JSON job in, one float RGBA
//! image out. The renderer owns light transport; materials are the core's.

use crate::status::{guard, guard_value, lq_status, Failure};
use crate::strings::c_str;
use lacquer_render::{render_job, Framebuffer, JobError, JobRender};
use std::ffi::{c_char, c_void};

/// A rendered image. Free it with `lq_image_free`.
pub struct lq_image {
    width: u32,
    height: u32,
    rgba: Vec<f32>,
    albedo: Option<Vec<f32>>,
    normal: Option<Vec<f32>>,
    diffuse_color: Option<Vec<f32>>,
    glossy_color: Option<Vec<f32>>,
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
            diffuse_color: fb.diffuse_color.as_deref().map(flatten),
            glossy_color: fb.glossy_color.as_deref().map(flatten),
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
        let fb = render_job(text, &mut report).map_err(job_failure)?;
        // SAFETY: checked non-NULL above; the caller's writable slot.
        unsafe { *out = Box::into_raw(Box::new(lq_image::from(fb))) };
        Ok(())
    })
}

/// A render refined in rounds (progressive display): create it with `lq_render_session_new`,
/// add samples with `lq_render_session_advance`, read the image so far with
/// `lq_render_session_image`, free it with `lq_render_session_free`. Any split of the job's
/// `spp` into rounds gives `lq_render`'s image bit for bit. One thread at a time per session.
pub struct lq_render_session {
    job: JobRender,
}

fn job_failure(e: JobError) -> Failure {
    match e {
        JobError::Invalid(m) => Failure::invalid(m),
        JobError::Cancelled => Failure::new(lq_status::LQ_ERR_CANCELLED, "the render was cancelled"),
    }
}

/// Parses a render job (the JSON of `lq_render`) and builds its scene; no samples yet. On
/// success writes a new session to `*out`. Errors: LQ_ERR_NULL, LQ_ERR_INVALID_JSON (not UTF-8),
/// LQ_ERR_INVALID_ARGUMENT (the job, its material or its scene is invalid). `*out` is
/// untouched on error.
///
/// # Safety
/// `job_json` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render_session_new(job_json: *const c_char, out: *mut *mut lq_render_session) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let text = unsafe { c_str("job_json", job_json, lq_status::LQ_ERR_INVALID_JSON) }?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let job = JobRender::new(text).map_err(job_failure)?;
        // SAFETY: checked non-NULL above; the caller's writable slot.
        unsafe { *out = Box::into_raw(Box::new(lq_render_session { job })) };
        Ok(())
    })
}

/// Adds up to `samples` samples per pixel (never beyond the job's `spp`) and writes how many
/// were added to `*added` (may be NULL). `progress` (may be NULL) is called on this thread with
/// the fraction of this round done; returning `false` cancels the round, which leaves the
/// session as it was before it (LQ_ERR_CANCELLED; a later call resumes). Errors: LQ_ERR_NULL,
/// LQ_ERR_CANCELLED.
///
/// # Safety
/// `session` is NULL or a live session not used by another thread during the call;
/// `progress` is NULL or callable with `user`; `added` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render_session_advance(
    session: *mut lq_render_session,
    samples: u32,
    progress: lq_progress_fn,
    user: *mut c_void,
    added: *mut u32,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let s = unsafe { session.as_mut() }.ok_or_else(|| Failure::null("session"))?;
        let mut report = |fraction: f32| match progress {
            // SAFETY: the caller guarantees the callback accepts `user`.
            Some(f) => unsafe { f(fraction, user) },
            None => true,
        };
        let n = s.job.advance(samples, &mut report).map_err(job_failure)?;
        if !added.is_null() {
            // SAFETY: checked non-NULL; the caller's writable slot.
            unsafe { *added = n };
        }
        Ok(())
    })
}

/// Samples per pixel done so far (0 for NULL).
///
/// # Safety
/// `session` is NULL or a live session.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render_session_samples(session: *const lq_render_session) -> u32 {
    // SAFETY: the caller's contract above.
    guard_value(0, || unsafe { session.as_ref() }.map_or(0, |s| s.job.samples()))
}

/// The job's samples per pixel, i.e. when the render is complete (0 for NULL).
///
/// # Safety
/// `session` is NULL or a live session.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render_session_target(session: *const lq_render_session) -> u32 {
    // SAFETY: the caller's contract above.
    guard_value(0, || unsafe { session.as_ref() }.map_or(0, |s| s.job.target()))
}

/// The image so far (the mean of the samples done; black before the first round) as a new
/// image in `*out` (free it with `lq_image_free`). Errors: LQ_ERR_NULL.
///
/// # Safety
/// `session` is NULL or a live session; `out` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_render_session_image(
    session: *const lq_render_session,
    out: *mut *mut lq_image,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let s = unsafe { session.as_ref() }.ok_or_else(|| Failure::null("session"))?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let img = lq_image::from(s.job.framebuffer());
        // SAFETY: checked non-NULL above; the caller's writable slot.
        unsafe { *out = Box::into_raw(Box::new(img)) };
        Ok(())
    })
}

/// Releases a session. NULL is a no-op.
///
/// # Safety
/// `session` is NULL or a live session, freed exactly once.
#[no_mangle]
pub unsafe extern "C" fn lq_render_session_free(session: *mut lq_render_session) {
    if !session.is_null() {
        // SAFETY: sessions come from Box::into_raw in lq_render_session_new.
        guard_value((), || drop(unsafe { Box::from_raw(session) }));
    }
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
    guard_value(std::ptr::null(), || unsafe { optional_layer(img, |i| &i.albedo) })
}

/// First-hit world-space shading normal (width × height × 3 floats), or NULL without AOVs.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_normal(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || unsafe { optional_layer(img, |i| &i.normal) })
}

/// Diffuse Color (as Cycles' pass): the first hit's diffuse lobe group's directional albedo
/// (lobe mask `LQ_LOBE_DIFFUSE`, the mean of its sampled weights; width × height × 3 floats),
/// or NULL unless the job had `"lobe_aovs": true`. ABI 0.8.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_diffuse_color(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || unsafe { optional_layer(img, |i| &i.diffuse_color) })
}

/// Glossy Color: the same for the glossy groups (`LQ_LOBE_GLOSSY | LQ_LOBE_COAT`: flakes,
/// metallic base, the clearcoat's reflection), or NULL unless the job had `"lobe_aovs": true`.
/// ABI 0.8.
///
/// # Safety
/// `img` is NULL or a live image.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_image_glossy_color(img: *const lq_image) -> *const f32 {
    // SAFETY: the caller's contract above.
    guard_value(std::ptr::null(), || unsafe { optional_layer(img, |i| &i.glossy_color) })
}

/// The pointer to an optional image layer, or NULL for a NULL image or a layer the job did
/// not ask for (the four optional-layer getters above).
///
/// # Safety
/// `img` is NULL or a live image.
unsafe fn optional_layer(img: *const lq_image, layer: impl Fn(&lq_image) -> &Option<Vec<f32>>) -> *const f32 {
    // SAFETY: the caller's contract above.
    unsafe { img.as_ref() }.and_then(|i| layer(i).as_ref()).map_or(std::ptr::null(), |v| v.as_ptr())
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
