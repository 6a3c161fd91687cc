//! Batch evaluation, density and sampling over interleaved arrays, in f32 and f64.
//!
//! The adapter only validates and converts: every value comes from `lacquer::Material`.
//! Per-element policy: an element with a non-finite or zero-length direction (the inputs the
//! core would silently turn into zero) gets zero outputs and is counted; after the whole
//! batch the call returns `LQ_ERR_INVALID_DIRECTION` (or `LQ_ERR_INVALID_ELEMENT` for a
//! non-finite `u`, `uv` or footprint) with the count and the first offender in the message.

use crate::arrays::Batch;
use crate::material::{lq_material, material};
use crate::status::{guard, lq_status, Failure};
use lacquer_core::{Material, Real, Rgb, Vec3};
use std::ffi::c_float;

/// `flags` bit: the sample comes from a Dirac delta lobe (`pdf` is then the discrete
/// probability of choosing that lobe, and MIS should not weight it against light sampling).
pub const LQ_SAMPLE_DELTA: u32 = 1;
/// `flags` bit: no sample was produced (wo below the surface, or the sampler rejected `u`):
/// `wi`, `weight` and `pdf` are 0. This is not an error.
pub const LQ_SAMPLE_FAILED: u32 = 2;
/// `flags` bit: the element's inputs were invalid (see `LQ_ERR_INVALID_DIRECTION` and
/// `LQ_ERR_INVALID_ELEMENT`); outputs are 0.
pub const LQ_SAMPLE_INVALID_INPUT: u32 = 4;

#[inline(always)]
fn vec3<T: Real>(a: &[T], i: usize) -> Vec3<T> {
    Vec3::new(a[3 * i], a[3 * i + 1], a[3 * i + 2])
}

#[inline(always)]
fn put3<T: Real>(a: &mut [T], i: usize, v: [T; 3]) {
    a[3 * i] = v[0];
    a[3 * i + 1] = v[1];
    a[3 * i + 2] = v[2];
}

/// The same test the core applies before treating a direction as usable.
#[inline(always)]
fn usable<T: Real>(w: Vec3<T>) -> bool {
    let l2 = w.length_squared();
    l2.is_finite() && l2 > T::zero()
}

#[inline(always)]
fn all_finite<T: Real>(a: &[T], i: usize, per: usize) -> bool {
    a[per * i..per * (i + 1)].iter().all(|x| x.is_finite())
}

/// A number for a message: plain for ordinary magnitudes, scientific for tiny or huge ones.
fn num<T: Real>(x: T) -> String {
    let a = x.abs().f64();
    if x.is_finite() && a != 0.0 && !(1e-4..1e7).contains(&a) {
        if std::mem::size_of::<T>() == 4 {
            format!("{:e}", x.f64() as f32) // shortest f32 form, not the widened f64 digits
        } else {
            format!("{:e}", x.f64())
        }
    } else {
        format!("{x}")
    }
}

/// Counts invalid elements and remembers the first of each kind for the message.
#[derive(Default)]
struct Invalid {
    directions: usize,
    first_direction: Option<String>,
    others: usize,
    first_other: Option<String>,
}

impl Invalid {
    #[cold]
    fn direction<T: Real>(&mut self, i: usize, name: &str, w: Vec3<T>) {
        self.directions += 1;
        if self.first_direction.is_none() {
            self.first_direction = Some(format!(
                "element {i}: {name} = [{}, {}, {}]",
                num(w.x),
                num(w.y),
                num(w.z)
            ));
        }
    }
    #[cold]
    fn other<T: Real>(&mut self, i: usize, name: &str, v: &[T]) {
        self.others += 1;
        if self.first_other.is_none() {
            let v: Vec<String> = v.iter().map(|&x| num(x)).collect();
            self.first_other = Some(format!("element {i}: {name} = [{}]", v.join(", ")));
        }
    }
    fn finish(self, n: usize) -> Result<(), Failure> {
        let total = self.directions + self.others;
        if total == 0 {
            return Ok(());
        }
        let (status, what, first) = if self.directions > 0 {
            (
                lq_status::LQ_ERR_INVALID_DIRECTION,
                "a direction that is not finite or has zero length",
                self.first_direction,
            )
        } else {
            (
                lq_status::LQ_ERR_INVALID_ELEMENT,
                "a non-finite u, uv or footprint value",
                self.first_other,
            )
        };
        let mut msg = format!(
            "{total} of {n} elements have {what} (first: {}); their outputs were set to 0, the other elements were evaluated",
            first.unwrap_or_default()
        );
        if self.directions > 0 && self.others > 0 {
            msg.push_str(&format!(
                "; {} more have a non-finite u, uv or footprint value",
                self.others
            ));
        }
        Err(Failure::new(status, msg))
    }
}

/// Optional surface position and footprint of each element (see `lq_eval_spatial`).
struct Spatial<'a, T> {
    uv: Option<&'a [T]>,
    duv: Option<&'a [T]>,
}

impl<T: Real> Spatial<'_, T> {
    /// True when element `i`'s position and footprint are finite (or absent).
    #[inline(always)]
    fn check(&self, i: usize, bad: &mut Invalid) -> bool {
        if let Some(uv) = self.uv {
            if !all_finite(uv, i, 2) {
                bad.other(i, "uv", &uv[2 * i..2 * i + 2]);
                return false;
            }
        }
        if let Some(duv) = self.duv {
            if !all_finite(duv, i, 4) {
                bad.other(i, "duv", &duv[4 * i..4 * i + 4]);
                return false;
            }
        }
        true
    }
}

/// eval and/or pdf over a batch. `uv`/`duv` are validated and, as no model in the core is
/// spatially varying yet, not otherwise used (see `lq_eval_spatial`).
#[allow(clippy::too_many_arguments)]
unsafe fn eval_pdf_impl<T: Real>(
    m: *const lq_material,
    n: usize,
    wi: *const T,
    wo: *const T,
    uv: *const T,
    duv: *const T,
    f_rgb: *mut T,
    pdf: *mut T,
    want_f: bool,
    want_pdf: bool,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    if n == 0 {
        return Ok(());
    }
    let mut b = Batch::new(n);
    let wi = b.input("wi", wi, 3)?;
    let wo = b.input("wo", wo, 3)?;
    let uv = b.optional_input("uv", uv, 2)?;
    let duv = b.optional_input("duv", duv, 4)?;
    if duv.is_some() && uv.is_none() {
        return Err(Failure::invalid(
            "`duv` (footprint) was given without `uv` (position)",
        ));
    }
    let f_rgb = if want_f {
        Some(b.output("f_rgb", f_rgb, 3)?)
    } else {
        None
    };
    let pdf = if want_pdf {
        Some(b.output("pdf", pdf, 1)?)
    } else {
        None
    };
    b.check_overlaps()?;
    // SAFETY: every array validated (non-NULL, aligned, sized, outputs disjoint); lengths are
    // the caller's contract.
    let (wi, wo) = unsafe { (wi.slice(), wo.slice()) };
    let spatial = unsafe {
        Spatial {
            uv: uv.map(|a| a.slice()),
            duv: duv.map(|a| a.slice()),
        }
    };
    let mut f_rgb = f_rgb.map(|a| unsafe { a.slice() });
    let mut pdf = pdf.map(|a| unsafe { a.slice() });

    let mut bad = Invalid::default();
    for i in 0..n {
        let a = vec3(wi, i);
        let o = vec3(wo, i);
        let ok = if !usable(a) {
            bad.direction(i, "wi", a);
            false
        } else if !usable(o) {
            bad.direction(i, "wo", o);
            false
        } else {
            spatial.check(i, &mut bad)
        };
        if let Some(f) = f_rgb.as_deref_mut() {
            let v = if ok { m.eval(a, o) } else { Rgb::zero() };
            put3(f, i, v.to_array());
        }
        if let Some(p) = pdf.as_deref_mut() {
            p[i] = if ok { m.pdf(a, o) } else { T::zero() };
        }
    }
    bad.finish(n)
}

/// Sampling over a batch; `flags` is optional.
#[allow(clippy::too_many_arguments)]
unsafe fn sample_impl<T: Real>(
    m: *const lq_material,
    n: usize,
    wo: *const T,
    u: *const T,
    spatial: (*const T, *const T),
    wi: *mut T,
    weight_rgb: *mut T,
    pdf: *mut T,
    flags: *mut u32,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    if n == 0 {
        return Ok(());
    }
    let mut b = Batch::new(n);
    let wo = b.input("wo", wo, 3)?;
    let u = b.input("u", u, 3)?;
    let uv = b.optional_input("uv", spatial.0, 2)?;
    let duv = b.optional_input("duv", spatial.1, 4)?;
    if duv.is_some() && uv.is_none() {
        return Err(Failure::invalid(
            "`duv` (footprint) was given without `uv` (position)",
        ));
    }
    let wi = b.output("wi", wi, 3)?;
    let weight = b.output("weight_rgb", weight_rgb, 3)?;
    let pdf = b.output("pdf", pdf, 1)?;
    let flags = b.optional_output("flags", flags, 1)?;
    b.check_overlaps()?;
    // SAFETY: as in eval_pdf_impl.
    let (wo, u) = unsafe { (wo.slice(), u.slice()) };
    let spatial = unsafe {
        Spatial {
            uv: uv.map(|a| a.slice()),
            duv: duv.map(|a| a.slice()),
        }
    };
    let (wi, weight, pdf) = unsafe { (wi.slice(), weight.slice(), pdf.slice()) };
    let mut flags = flags.map(|a| unsafe { a.slice() });

    let zero = [T::zero(); 3];
    let mut bad = Invalid::default();
    for i in 0..n {
        let o = vec3(wo, i);
        let ok = if !usable(o) {
            bad.direction(i, "wo", o);
            false
        } else if !all_finite(u, i, 3) {
            bad.other(i, "u", &u[3 * i..3 * i + 3]);
            false
        } else {
            spatial.check(i, &mut bad)
        };
        let s = if ok {
            m.sample(o, [u[3 * i], u[3 * i + 1], u[3 * i + 2]])
        } else {
            None
        };
        let flag = match &s {
            Some(s) => {
                put3(wi, i, [s.wi.x, s.wi.y, s.wi.z]);
                put3(weight, i, s.weight.to_array());
                pdf[i] = s.pdf;
                if s.delta {
                    LQ_SAMPLE_DELTA
                } else {
                    0
                }
            }
            None => {
                put3(wi, i, zero);
                put3(weight, i, zero);
                pdf[i] = T::zero();
                if ok {
                    LQ_SAMPLE_FAILED
                } else {
                    LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT
                }
            }
        };
        if let Some(fl) = flags.as_deref_mut() {
            fl[i] = flag;
        }
    }
    bad.finish(n)
}

const NO_F32: *const c_float = std::ptr::null();
const NO_F64: *const f64 = std::ptr::null();

// ---------------------------------------------------------------------------------------
// f32 (the contract's functions)

/// Evaluates the BRDF `f_r(wi, wo)` (1/sr, cosine NOT included, linear Rec.709 RGB) for `n`
/// direction pairs.
///
/// `wi`, `wo`: 3n floats (x, y, z per element) in the local frame (z = normal, x = tangent),
/// pointing away from the surface; they need not be exactly unit length (they are
/// normalised). `f_rgb`: 3n floats written. Below-horizon directions give 0 (not an error).
///
/// Returns LQ_OK; LQ_ERR_NULL / LQ_ERR_INVALID_ARGUMENT with nothing written; or
/// LQ_ERR_INVALID_DIRECTION after writing every element, the invalid ones as 0.
/// `n == 0` is a no-op returning LQ_OK (arrays may then be NULL). Each array must hold
/// `n` elements: the library cannot check lengths, a short array is undefined behaviour.
///
/// # Safety
/// `m` is NULL or a live handle; each non-NULL array holds `n` elements, suitably aligned.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            NO_F32,
            NO_F32,
            f_rgb,
            std::ptr::null_mut(),
            true,
            false,
        )
    })
}

/// The solid-angle density (1/sr) with which `lq_sample` picks `wi` given `wo`; `pdf`: n
/// floats written. Same arrays, statuses and per-element policy as `lq_eval`.
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            NO_F32,
            NO_F32,
            std::ptr::null_mut(),
            pdf,
            false,
            true,
        )
    })
}

/// `lq_eval` and `lq_pdf` in one pass (what a MIS integrator needs).
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F32, NO_F32, f_rgb, pdf, true, true) })
}

/// Importance-samples `wi` for each `wo`.
///
/// `u`: 3n uniform numbers in [0, 1) (first picks a lobe, the other two the direction;
/// values outside are clamped into [0, 1)). Writes `wi` (3n), `weight_rgb` (3n) =
/// f_r(wi, wo)·cos θi / pdf, and `pdf` (n). A failed sample (e.g. wo below the surface) is
/// not an error: it has pdf = 0, weight = 0 and wi = 0. A non-finite or zero-length `wo`
/// gives LQ_ERR_INVALID_DIRECTION, a non-finite `u` LQ_ERR_INVALID_ELEMENT, both after
/// writing every element (the invalid ones as failed samples).
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        sample_impl(
            m,
            n,
            wo,
            u,
            (NO_F32, NO_F32),
            wi,
            weight_rgb,
            pdf,
            std::ptr::null_mut(),
        )
    })
}

// ---------------------------------------------------------------------------------------
// f64: the reference path (same semantics, double arrays)

/// `lq_eval` in double precision (the core's reference path; the f32 path agrees to about
/// 1e-4 relative, see `lacquer check`'s precision figure).
///
/// # Safety
/// As `lq_eval`, with 8-byte aligned double arrays.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    f_rgb: *mut f64,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            NO_F64,
            NO_F64,
            f_rgb,
            std::ptr::null_mut(),
            true,
            false,
        )
    })
}

/// `lq_pdf` in double precision.
///
/// # Safety
/// As `lq_eval_f64`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    pdf: *mut f64,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            NO_F64,
            NO_F64,
            std::ptr::null_mut(),
            pdf,
            false,
            true,
        )
    })
}

/// `lq_eval_pdf` in double precision.
///
/// # Safety
/// As `lq_eval_f64`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    f_rgb: *mut f64,
    pdf: *mut f64,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F64, NO_F64, f_rgb, pdf, true, true) })
}

/// `lq_sample` in double precision; `flags` (n values, may be NULL) as in
/// `lq_sample_spatial`.
///
/// # Safety
/// As `lq_eval_f64`; `flags` is NULL or holds n 4-byte aligned values.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_f64(
    m: *const lq_material,
    n: usize,
    wo: *const f64,
    u: *const f64,
    wi: *mut f64,
    weight_rgb: *mut f64,
    pdf: *mut f64,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe { sample_impl(m, n, wo, u, (NO_F64, NO_F64), wi, weight_rgb, pdf, flags) })
}

// ---------------------------------------------------------------------------------------
// Spatially varying inputs (sparkle): surface position and footprint per element

/// `lq_eval` with a surface position and footprint per element, for spatially varying
/// materials (sparkle), per the contract's "Spatially varying effects".
///
/// `uv`: 2n floats (u, v) or NULL; `duv`: 4n floats (du/dx, dv/dx, du/dy, dv/dy: the pixel
/// footprint in uv) or NULL. NULL `uv` means "no position": the mean lobe (footprint → ∞).
/// NULL `duv` with a `uv` also means the mean lobe until a model defines a point query;
/// `duv` without `uv` is LQ_ERR_INVALID_ARGUMENT. A non-finite uv/duv value gives
/// LQ_ERR_INVALID_ELEMENT for that element (outputs 0).
///
/// Current behaviour: no model in the core is spatially varying yet, so after validation
/// uv and duv do not change the result, which equals `lq_eval`. The signature is stable:
/// when a spatial model lands, these values are passed to it unchanged.
///
/// # Safety
/// As `lq_eval`; `uv`/`duv` are NULL or hold 2n / 4n floats.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    f_rgb: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            uv,
            duv,
            f_rgb,
            std::ptr::null_mut(),
            true,
            false,
        )
    })
}

/// `lq_pdf` with surface position and footprint (see `lq_eval_spatial`).
///
/// # Safety
/// As `lq_eval_spatial`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_impl(
            m,
            n,
            wi,
            wo,
            uv,
            duv,
            std::ptr::null_mut(),
            pdf,
            false,
            true,
        )
    })
}

/// `lq_eval_pdf` with surface position and footprint (see `lq_eval_spatial`).
///
/// # Safety
/// As `lq_eval_spatial`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, uv, duv, f_rgb, pdf, true, true) })
}

/// `lq_sample` with surface position and footprint (see `lq_eval_spatial`) and per-element
/// `flags` (n values, may be NULL): a combination of LQ_SAMPLE_DELTA, LQ_SAMPLE_FAILED and
/// LQ_SAMPLE_INVALID_INPUT. With `uv = duv = NULL` this is `lq_sample` plus flags.
///
/// # Safety
/// As `lq_eval_spatial`; `flags` is NULL or holds n 4-byte aligned values.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_spatial(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe { sample_impl(m, n, wo, u, (uv, duv), wi, weight_rgb, pdf, flags) })
}
