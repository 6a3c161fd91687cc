//! Lobe selection (ABI 0.7): the lobe groups of a material, and eval / pdf / sample
//! restricted to a lobe mask, for renderers with per-component queries (Mitsuba's
//! `BSDFContext::component` / `type_mask`, Diffuse/Glossy render passes, a separate coat
//! normal).
//!
//! A lobe mask holds `LQ_LOBE_DIFFUSE` (pigment and diffuse terms; for the coated paint also
//! the multiple-scatter lobe under the coat), `LQ_LOBE_GLOSSY` (glossy lobes other than a
//! coat's top reflection: flakes, metallic base, specular lobes) and `LQ_LOBE_COAT` (the
//! clearcoat's top reflection, glossy or a mirror delta). `coated_paint` evaluates, samples
//! and pdfs each group on its own; every other model evaluates its lobes together and takes
//! a mask only as all or none of its groups. A mask enabling every group of the material is
//! exactly the plain call; one enabling none gives zero values, zero densities and failed
//! samples. Any other bit, or a partial mask for a model that cannot separate its lobes, is
//! `LQ_ERR_INVALID_ARGUMENT` with nothing written.

use crate::arrays::Batch;
use crate::batch::{
    active_mask, finite, one_eval_pdf, one_sample, report_failure, report_failure_sample, sample_out, soa_in, soa_out,
    usable, valid, vec3, Invalid, Spatial,
};
use crate::material::{lq_material, material};
use crate::status::{guard, Failure};
use crate::{LQ_SAMPLE_DELTA, LQ_SAMPLE_FAILED, LQ_SAMPLE_INVALID_INPUT};
use lacquer_core::lobes::{bits, LobeSelection};
use lacquer_core::{Material, Vec3};
use std::ffi::c_float;

/// Lobe-mask bit and `lq_material_lobes` bit: the material has a clearcoat top reflection
/// that a lobe mask selects on its own (its kind, glossy or delta, is in
/// `lq_material_lobe_part`).
pub const LQ_LOBE_COAT: u32 = 128;
/// Every bit a lobe mask may hold: `LQ_LOBE_DIFFUSE | LQ_LOBE_GLOSSY | LQ_LOBE_COAT`.
pub const LQ_LOBES_SELECTABLE: u32 = 131;

const _: () = assert!(LQ_LOBE_COAT == bits::COAT && LQ_LOBES_SELECTABLE == bits::SELECTABLE);

/// The material's lobe selection for `lobes`, or LQ_ERR_INVALID_ARGUMENT naming the mask.
fn select(m: &Material, lobes: u32) -> Result<LobeSelection, Failure> {
    m.select_lobes(lobes).map_err(|e| Failure::invalid(e.to_string()))
}

/// The number of lobe groups of a material (what a renderer's components are): up to 3 for
/// `coated_paint` (pigment, glossy base lobes, coat), 1 for every other model.
///
/// # Safety
/// `m` is NULL or a live handle; `out_count` is NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_lobe_part_count(m: *const lq_material, out_count: *mut usize) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        if out_count.is_null() {
            return Err(Failure::null("out_count"));
        }
        // SAFETY: checked non-NULL.
        unsafe { *out_count = m.lobe_parts().len() };
        Ok(())
    })
}

/// Lobe group `index` (0 ≤ index < `lq_material_lobe_part_count`): `out_select` the lobe-mask
/// bits that enable it (`LQ_LOBE_DIFFUSE`, `LQ_LOBE_GLOSSY`, `LQ_LOBE_COAT`; a model that
/// evaluates its lobes together has one group whose mask bits must all be set), `out_kinds`
/// what it is (`LQ_LOBE_DIFFUSE`, `LQ_LOBE_GLOSSY`, `LQ_LOBE_DELTA` bits). An index out of
/// range is LQ_ERR_INVALID_ARGUMENT.
///
/// # Safety
/// `m` is NULL or a live handle; the outputs are NULL or writable.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_material_lobe_part(
    m: *const lq_material,
    index: usize,
    out_select: *mut u32,
    out_kinds: *mut u32,
) -> lq_status {
    guard(|| {
        // SAFETY: the caller's contract above.
        let m = unsafe { material(m) }?;
        if out_select.is_null() {
            return Err(Failure::null("out_select"));
        }
        if out_kinds.is_null() {
            return Err(Failure::null("out_kinds"));
        }
        let parts = m.lobe_parts();
        let p = parts.get(index).ok_or_else(|| {
            Failure::invalid(format!("lobe part index {index} out of range (the material has {})", parts.len()))
        })?;
        // SAFETY: checked non-NULL.
        unsafe {
            *out_select = p.select;
            *out_kinds = p.kinds;
        }
        Ok(())
    })
}

use crate::lq_status;

/// `lq_eval_pdf_spatial` restricted to the lobes of the mask `lobes` (see the lobe-mask rules
/// above): interleaved arrays, `uv`/`duv` NULL (the mean lobe) or per element (sparkle);
/// `f_rgb` and/or `pdf` may be NULL (not both). `pdf` is the density of `lq_sample_lobes`
/// with the same mask.
///
/// # Safety
/// As `lq_eval_spatial`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_eval_pdf_lobes(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    lobes: u32,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| {
        // SAFETY: handle contract of the caller.
        let m: &Material = unsafe { material(m) }?;
        let sel = select(m, lobes)?;
        if f_rgb.is_null() && pdf.is_null() {
            return Err(Failure::null("f_rgb and pdf"));
        }
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<6>::new(n);
        let wi = b.input::<c_float, 3>("wi", wi)?;
        let wo = b.input::<c_float, 3>("wo", wo)?;
        let uv = b.optional_input::<c_float, 2>("uv", uv)?;
        let duv = b.optional_input::<c_float, 4>("duv", duv)?;
        if duv.is_some() && uv.is_none() {
            return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
        }
        let f_rgb = b.optional_output::<c_float, 3>("f_rgb", f_rgb)?;
        let pdf = b.optional_output::<c_float, 1>("pdf", pdf)?;
        b.check_overlaps()?;
        // SAFETY: validated arrays (non-NULL, aligned, outputs disjoint); lengths are the
        // caller's contract.
        let (wi, wo) = unsafe { (wi.slice(), wo.slice()) };
        let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
        let mut f_rgb = f_rgb.map(|a| unsafe { a.slice() });
        let mut pdf = pdf.map(|a| unsafe { a.slice() });
        if spatial.uv.is_none() {
            // The core's SIMD kernels with the mask.
            let flat_f = f_rgb.map(|f| lacquer_core::batch::Dst3::interleaved(f.as_flattened_mut()));
            let flat_p = pdf.map(|p| lacquer_core::batch::Dst1::new(p.as_flattened_mut()));
            let report = lacquer_core::batch::eval_pdf_lobes(
                m,
                sel,
                &lacquer_core::batch::Src3::interleaved(wi.as_flattened()),
                &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
                None,
                flat_f.as_ref(),
                flat_p.as_ref(),
            )
            .map_err(|e| Failure::invalid(e.to_string()))?;
            return report_failure(n, report, |i| {
                let (a, o) = (vec3(&wi[i]), vec3(&wo[i]));
                if usable(a) {
                    ("wo", o)
                } else {
                    ("wi", a)
                }
            });
        }
        let mut bad = Invalid::default();
        for i in 0..n {
            let (a, o) = (vec3(&wi[i]), vec3(&wo[i]));
            let ok = valid(i, a, o, &spatial, &mut bad);
            if let Some(f) = f_rgb.as_deref_mut() {
                f[i] = match (ok, spatial.point(i)) {
                    (false, _) => [0.0; 3],
                    (true, Some(at)) => m.eval_at_lobes(a, o, &at, sel).to_array(),
                    (true, None) => m.eval_lobes(a, o, sel).to_array(),
                };
            }
            if let Some(p) = pdf.as_deref_mut() {
                p[i] = [if ok { m.pdf_lobes(a, o, sel) } else { 0.0 }];
            }
        }
        bad.finish(n)
    })
}

/// `lq_sample_spatial` among the lobes of the mask `lobes` (their selection renormalised;
/// the weight is the selected lobes' `f cos θi / pdf`, the pdf that of `lq_eval_pdf_lobes`).
/// A mask selecting none of the material's lobes gives failed samples (LQ_SAMPLE_FAILED).
///
/// # Safety
/// As `lq_sample_spatial`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_sample_lobes(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    lobes: u32,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| {
        // SAFETY: handle contract of the caller.
        let m: &Material = unsafe { material(m) }?;
        let sel = select(m, lobes)?;
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<8>::new(n);
        let wo = b.input::<c_float, 3>("wo", wo)?;
        let u = b.input::<c_float, 3>("u", u)?;
        let uv = b.optional_input::<c_float, 2>("uv", uv)?;
        let duv = b.optional_input::<c_float, 4>("duv", duv)?;
        if duv.is_some() && uv.is_none() {
            return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
        }
        let wi = b.output::<c_float, 3>("wi", wi)?;
        let weight = b.output::<c_float, 3>("weight_rgb", weight_rgb)?;
        let pdf = b.output::<c_float, 1>("pdf", pdf)?;
        let flags = b.optional_output::<u32, 1>("flags", flags)?;
        b.check_overlaps()?;
        // SAFETY: as in lq_eval_pdf_lobes.
        let (wo, u) = unsafe { (wo.slice(), u.slice()) };
        let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
        let (wi, weight, pdf) = unsafe { (wi.slice(), weight.slice(), pdf.slice()) };
        let mut flags = flags.map(|a| unsafe { a.slice() });
        if spatial.uv.is_none() {
            let mut out = lacquer_core::batch::SampleOut {
                wi: lacquer_core::batch::Dst3::interleaved(wi.as_flattened_mut()),
                weight: lacquer_core::batch::Dst3::interleaved(weight.as_flattened_mut()),
                pdf: lacquer_core::batch::Dst1::new(pdf.as_flattened_mut()),
                flags: flags.map(|f| f.as_flattened_mut()),
            };
            let report = lacquer_core::batch::sample_lobes(
                m,
                sel,
                &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
                &lacquer_core::batch::Src3::interleaved(u.as_flattened()),
                None,
                &mut out,
            )
            .map_err(|e| Failure::invalid(e.to_string()))?;
            return report_failure_sample(n, report, |i| vec3(&wo[i]), |i| u[i]);
        }
        let mut bad = Invalid::default();
        for i in 0..n {
            let o = vec3(&wo[i]);
            let ok = if !usable(o) {
                bad.direction(i, "wo", o);
                false
            } else if !u[i].iter().all(|&x| finite(x)) {
                bad.other(i, "u", &u[i]);
                false
            } else {
                spatial.check(i, &mut bad)
            };
            let s = match (ok, spatial.point(i)) {
                (false, _) => None,
                (true, Some(at)) => m.sample_at_lobes(o, u[i], &at, sel),
                (true, None) => m.sample_lobes(o, u[i], sel),
            };
            let flag = match &s {
                Some(s) => {
                    (wi[i], weight[i], pdf[i]) = ([s.wi.x, s.wi.y, s.wi.z], s.weight.to_array(), [s.pdf]);
                    if s.delta {
                        LQ_SAMPLE_DELTA
                    } else {
                        0
                    }
                }
                None => {
                    (wi[i], weight[i], pdf[i]) = ([0.0; 3], [0.0; 3], [0.0]);
                    if ok {
                        LQ_SAMPLE_FAILED
                    } else {
                        LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT
                    }
                }
            };
            if let Some(fl) = flags.as_deref_mut() {
                fl[i] = [flag];
            }
        }
        bad.finish(n)
    })
}

/// `lq_eval_pdf_one` restricted to the lobes of the mask `lobes`; `f_rgb` or `pdf` may be
/// NULL (not both). Inputs are read before outputs are written (arrays may overlap).
///
/// # Safety
/// As `lq_eval_one`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_one_lobes(
    m: *const lq_material,
    wi: *const c_float,
    wo: *const c_float,
    lobes: u32,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| {
        if f_rgb.is_null() && pdf.is_null() {
            return Err(Failure::null("f_rgb and pdf"));
        }
        let some = |p: *mut c_float| (!p.is_null()).then_some(p);
        // SAFETY: the caller's contract, as lq_eval_pdf_one's.
        unsafe { one_eval_pdf(m, wi, wo, some(f_rgb), some(pdf), Some(lobes)) }
    })
}

/// `lq_sample_one` among the lobes of the mask `lobes` (see `lq_sample_lobes`).
///
/// # Safety
/// As `lq_sample_one`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_sample_one_lobes(
    m: *const lq_material,
    wo: *const c_float,
    u: *const c_float,
    lobes: u32,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    // SAFETY: the caller's contract, as lq_sample_one's.
    guard(|| unsafe { one_sample(m, wo, u, wi, weight_rgb, pdf, flags, Some(lobes)) })
}

/// `lq_eval_pdf_soa` restricted to the lobes of the mask `lobes`, through the SIMD kernels
/// (a mask enabling every lobe runs exactly `lq_eval_pdf_soa`). `f_r`, `f_g`, `f_b` (all
/// three) or `pdf` may be NULL (not both).
///
/// # Safety
/// As `lq_eval_soa`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_eval_pdf_soa_lobes(
    m: *const lq_material,
    n: usize,
    wi_x: *const c_float,
    wi_y: *const c_float,
    wi_z: *const c_float,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    active: *const u8,
    lobes: u32,
    f_r: *mut c_float,
    f_g: *mut c_float,
    f_b: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        let m: &Material = material(m)?;
        let sel = select(m, lobes)?;
        let want_f = !(f_r.is_null() && f_g.is_null() && f_b.is_null());
        if !want_f && pdf.is_null() {
            return Err(Failure::null("f_r, f_g, f_b and pdf"));
        }
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<10>::new(n);
        let wi3 = [wi_x, wi_y, wi_z];
        let wo3 = [wo_x, wo_y, wo_z];
        let wi_v = soa_in(&mut b, &["wi_x", "wi_y", "wi_z"], wi3, n)?;
        let wo_v = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], wo3, n)?;
        let f = if want_f { Some(soa_out(&mut b, &["f_r", "f_g", "f_b"], [f_r, f_g, f_b])?) } else { None };
        let pdf = if pdf.is_null() { None } else { Some(b.output::<c_float, 1>("pdf", pdf)?.ptr().cast::<c_float>()) };
        b.check_overlaps()?;
        let f_v = f.map(|[r, g, bl]| lacquer_core::batch::Dst3::from_raw(r, g, bl, 1, n));
        let pdf_v = pdf.map(|p| lacquer_core::batch::Dst1::from_raw(p, 1, n));
        let report = lacquer_core::batch::eval_pdf_lobes(
            m,
            sel,
            &wi_v.view,
            &wo_v.view,
            active_mask(active, n),
            f_v.as_ref(),
            pdf_v.as_ref(),
        )
        .map_err(|e| Failure::invalid(e.to_string()))?;
        let read = |p: [*const c_float; 3], i: usize| Vec3::new(*p[0].add(i), *p[1].add(i), *p[2].add(i));
        report_failure(n, report, |i| if usable(read(wi3, i)) { ("wo", read(wo3, i)) } else { ("wi", read(wi3, i)) })
    })
}

/// `lq_sample_soa` among the lobes of the mask `lobes` (see `lq_sample_lobes`), through the
/// SIMD kernels.
///
/// # Safety
/// As `lq_sample_soa`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_sample_soa_lobes(
    m: *const lq_material,
    n: usize,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    u0: *const c_float,
    u1: *const c_float,
    u2: *const c_float,
    active: *const u8,
    lobes: u32,
    wi_x: *mut c_float,
    wi_y: *mut c_float,
    wi_z: *mut c_float,
    w_r: *mut c_float,
    w_g: *mut c_float,
    w_b: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe {
        let m: &Material = material(m)?;
        let sel = select(m, lobes)?;
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<14>::new(n);
        let wo_v = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], [wo_x, wo_y, wo_z], n)?;
        let u_v = soa_in(&mut b, &["u0", "u1", "u2"], [u0, u1, u2], n)?;
        let wi_p = soa_out(&mut b, &["wi_x", "wi_y", "wi_z"], [wi_x, wi_y, wi_z])?;
        let w_p = soa_out(&mut b, &["w_r", "w_g", "w_b"], [w_r, w_g, w_b])?;
        let pdf_p = b.output::<c_float, 1>("pdf", pdf)?.ptr().cast::<c_float>();
        let flags_p = b.optional_output::<u32, 1>("flags", flags)?.map(|a| a.ptr());
        b.check_overlaps()?;
        let mut out = sample_out(n, wi_p, w_p, pdf_p, flags_p.map(|p| p.cast::<u32>()));
        let report = lacquer_core::batch::sample_lobes(m, sel, &wo_v.view, &u_v.view, active_mask(active, n), &mut out)
            .map_err(|e| Failure::invalid(e.to_string()))?;
        let wo3 = [wo_x, wo_y, wo_z];
        let u3 = [u0, u1, u2];
        report_failure_sample(
            n,
            report,
            |i| Vec3::new(*wo3[0].add(i), *wo3[1].add(i), *wo3[2].add(i)),
            |i| [*u3[0].add(i), *u3[1].add(i), *u3[2].add(i)],
        )
    })
}
