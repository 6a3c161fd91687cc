//! Per-element paint parameters (textures) for `coated_paint`: `lq_eval_pdf_varying` and
//! `lq_sample_varying` over structure-of-arrays inputs (see `lacquer::paint::varying`).

use crate::arrays::Batch;
use crate::batch::{active_mask, sample_out, soa_in, soa_out};
use crate::material::{lq_material, material};
use crate::status::lq_status::{LQ_ERR_INVALID_DIRECTION, LQ_ERR_INVALID_ELEMENT};
use crate::status::{guard, lq_status, Failure};
use lacquer_core::batch::{BatchReport, Dst1, Dst3};
use lacquer_core::paint::varying::PaintTexture;
use lacquer_core::Material;
use std::ffi::c_float;

/// Per-element parameter arrays of one call, as the core's texture (NULL: not textured).
struct Texture<'a> {
    base_color: Option<[&'a [f32]; 3]>,
    flake_density: Option<&'a [f32]>,
    coat_roughness: Option<&'a [f32]>,
}

impl Texture<'_> {
    fn core(&self) -> PaintTexture<'_, f32> {
        PaintTexture {
            base_color: self.base_color,
            flake_density: self.flake_density,
            coat_roughness: self.coat_roughness,
        }
    }
}

/// Validates the texture arrays (each NULL or n aligned floats; the three colour arrays all
/// NULL or all given).
unsafe fn texture<'a, const N: usize>(
    b: &mut Batch<N>,
    n: usize,
    base: [*const c_float; 3],
    flake_density: *const c_float,
    coat_roughness: *const c_float,
) -> Result<Texture<'a>, Failure> {
    let given = base.iter().filter(|p| !p.is_null()).count();
    if given != 0 && given != 3 {
        return Err(Failure::invalid(
            "base_color_r, base_color_g and base_color_b must be all NULL (not textured) or all given",
        ));
    }
    let mut one = |name: &'static str, p: *const c_float| -> Result<Option<&'a [f32]>, Failure> {
        Ok(b.optional_input::<c_float, 1>(name, p)?.map(|_| {
            // SAFETY: validated non-NULL and aligned; n readable floats is the caller's contract.
            unsafe { std::slice::from_raw_parts(p, n) }
        }))
    };
    let r = one("base_color_r", base[0])?;
    let g = one("base_color_g", base[1])?;
    let bl = one("base_color_b", base[2])?;
    let base_color = match (r, g, bl) {
        (Some(r), Some(g), Some(bl)) => Some([r, g, bl]),
        _ => None,
    };
    Ok(Texture {
        base_color,
        flake_density: one("flake_density", flake_density)?,
        coat_roughness: one("coat_roughness", coat_roughness)?,
    })
}

/// The status of a varying call's report: invalid directions first (as `lq_eval_pdf_soa`),
/// then invalid `u`, then invalid per-element parameters.
fn report_status(report: BatchReport, tex: &Texture<'_>) -> Result<(), Failure> {
    if let Some(i) = report.first_invalid_direction {
        return Err(Failure::new(
            LQ_ERR_INVALID_DIRECTION,
            format!(
                "{} element(s) with a non-finite or zero-length direction, the first is element {i}",
                report.invalid_directions
            ),
        ));
    }
    if let Some(i) = report.first_invalid_u {
        return Err(Failure::new(
            LQ_ERR_INVALID_ELEMENT,
            format!("{} element(s) with a non-finite u, the first is element {i}", report.invalid_u),
        ));
    }
    if let Some(i) = report.first_invalid_param {
        let mut v = Vec::new();
        if let Some(c) = tex.base_color {
            v.push(format!("base_color = [{}, {}, {}] (range [0, 1])", c[0][i], c[1][i], c[2][i]));
        }
        if let Some(d) = tex.flake_density {
            v.push(format!("flake_density = {} (range [0, 100] %, with pearl_density at most 100 %)", d[i]));
        }
        if let Some(a) = tex.coat_roughness {
            v.push(format!("coat_roughness = {} (range [0.001, 0.5])", a[i]));
        }
        return Err(Failure::new(
            LQ_ERR_INVALID_ELEMENT,
            format!(
                "{} element(s) with an out-of-range or non-finite paint parameter; the first is element {i}: {}",
                report.invalid_params,
                v.join(", ")
            ),
        ));
    }
    Ok(())
}

/// `lq_eval_pdf_soa` with per-element paint parameters of a `coated_paint` material: element i
/// is evaluated as the material with `base_color = (base_color_r[i], base_color_g[i],
/// base_color_b[i])` (each in [0, 1]), `flake_density = flake_density[i]` (%, [0, 100], with
/// the material's pearl_density at most 100 %) and `coat_roughness = coat_roughness[i]` (GGX
/// α in [0.001, 0.5]). Each parameter array is NULL (the material's value) or n floats; the
/// three colour arrays are all NULL or all given. The mean lobe is evaluated (no sparkle).
/// `f_*` or `pdf` may be NULL (not computed) but not both. An element with an out-of-range or
/// non-finite parameter gets zero outputs, the others are computed, and the call returns
/// `LQ_ERR_INVALID_ELEMENT` naming the first such element and its values. With every parameter
/// array NULL this is `lq_eval_pdf_soa`. Another model with a parameter array given:
/// `LQ_ERR_INVALID_ARGUMENT`.
///
/// # Safety
/// As `lq_eval_pdf_soa`; every non-NULL parameter array holds n floats.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_eval_pdf_varying(
    m: *const lq_material,
    n: usize,
    wi_x: *const c_float,
    wi_y: *const c_float,
    wi_z: *const c_float,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    base_color_r: *const c_float,
    base_color_g: *const c_float,
    base_color_b: *const c_float,
    flake_density: *const c_float,
    coat_roughness: *const c_float,
    active: *const u8,
    f_r: *mut c_float,
    f_g: *mut c_float,
    f_b: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        let m: &Material = material(m)?;
        if n == 0 {
            return Ok(());
        }
        let want_f = !(f_r.is_null() && f_g.is_null() && f_b.is_null());
        if !want_f && pdf.is_null() {
            return Err(Failure::null("f_r/f_g/f_b and pdf (at least one output is needed)"));
        }
        let mut b = Batch::<15>::new(n);
        let wi = soa_in(&mut b, &["wi_x", "wi_y", "wi_z"], [wi_x, wi_y, wi_z], n)?.view;
        let wo = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], [wo_x, wo_y, wo_z], n)?.view;
        let tex = texture(&mut b, n, [base_color_r, base_color_g, base_color_b], flake_density, coat_roughness)?;
        if want_f {
            soa_out(&mut b, &["f_r", "f_g", "f_b"], [f_r, f_g, f_b])?;
        }
        if !pdf.is_null() {
            b.output::<c_float, 1>("pdf", pdf)?;
        }
        b.check_overlaps()?;
        let f_v = want_f.then(|| Dst3::from_raw(f_r, f_g, f_b, 1, n));
        let pdf_v = (!pdf.is_null()).then(|| Dst1::from_raw(pdf, 1, n));
        let active = active_mask(active, n);
        let report =
            lacquer_core::batch::eval_pdf_varying(m, &tex.core(), &wi, &wo, active, f_v.as_ref(), pdf_v.as_ref())
                .map_err(|e| Failure::invalid(e.to_string()))?;
        report_status(report, &tex)
    })
}

/// `lq_sample_soa` with per-element paint parameters (as `lq_eval_pdf_varying`): element i is
/// sampled as the material with element i's parameters (mean lobe). Invalid parameters: zero
/// outputs, flags `LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT`, status `LQ_ERR_INVALID_ELEMENT`.
///
/// # Safety
/// As `lq_sample_soa`; every non-NULL parameter array holds n floats.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_sample_varying(
    m: *const lq_material,
    n: usize,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    u0: *const c_float,
    u1: *const c_float,
    u2: *const c_float,
    base_color_r: *const c_float,
    base_color_g: *const c_float,
    base_color_b: *const c_float,
    flake_density: *const c_float,
    coat_roughness: *const c_float,
    active: *const u8,
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
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<19>::new(n);
        let wo = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], [wo_x, wo_y, wo_z], n)?.view;
        let u = soa_in(&mut b, &["u0", "u1", "u2"], [u0, u1, u2], n)?.view;
        let tex = texture(&mut b, n, [base_color_r, base_color_g, base_color_b], flake_density, coat_roughness)?;
        let wi_p = soa_out(&mut b, &["wi_x", "wi_y", "wi_z"], [wi_x, wi_y, wi_z])?;
        let w_p = soa_out(&mut b, &["w_r", "w_g", "w_b"], [w_r, w_g, w_b])?;
        b.output::<c_float, 1>("pdf", pdf)?;
        b.optional_output::<u32, 1>("flags", flags)?;
        b.check_overlaps()?;
        let mut out = sample_out(n, wi_p, w_p, pdf, (!flags.is_null()).then_some(flags));
        let active = active_mask(active, n);
        let report = lacquer_core::batch::sample_varying(m, &tex.core(), &wo, &u, active, &mut out)
            .map_err(|e| Failure::invalid(e.to_string()))?;
        report_status(report, &tex)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{lq_material_free, lq_material_from_json};
    use crate::status::lq_status::{LQ_ERR_INVALID_ARGUMENT, LQ_ERR_NULL, LQ_OK};
    use lacquer_core::batch::Src3;
    use std::ffi::CString;

    fn load(json: &str) -> *mut lq_material {
        let c = CString::new(json).unwrap();
        let mut m = std::ptr::null_mut();
        assert_eq!(unsafe { lq_material_from_json(c.as_ptr(), &mut m) }, LQ_OK);
        m
    }

    fn last_error() -> String {
        unsafe { std::ffi::CStr::from_ptr(crate::lq_last_error()) }.to_string_lossy().into_owned()
    }

    /// The C calls agree with the core's varying calls (bit-identical: same kernels), report
    /// invalid parameters by element, and reject NULL outputs, half-given colours and a
    /// texture on another model without panicking.
    /// `lq_eval_pdf_varying` on SoA directions with the colour and density arrays given or
    /// NULL (`None`), without roughness or mask.
    #[allow(clippy::too_many_arguments)]
    fn eval_varying(
        m: *const lq_material,
        n: usize,
        wi: &[Vec<f32>; 3],
        wo: &[Vec<f32>; 3],
        rgb: [Option<&[f32]>; 3],
        dens: Option<&[f32]>,
        f: [*mut f32; 3],
        p: *mut f32,
    ) -> lq_status {
        let ptr = |a: Option<&[f32]>| a.map_or(std::ptr::null(), <[f32]>::as_ptr);
        let null = std::ptr::null();
        let [a, b, c] = [&wi[0], &wi[1], &wi[2]].map(|v| v.as_ptr());
        let [d, e, g] = [&wo[0], &wo[1], &wo[2]].map(|v| v.as_ptr());
        // SAFETY: every non-NULL array holds n values.
        unsafe {
            lq_eval_pdf_varying(
                m,
                n,
                a,
                b,
                c,
                d,
                e,
                g,
                ptr(rgb[0]),
                ptr(rgb[1]),
                ptr(rgb[2]),
                ptr(dens),
                null,
                null.cast(),
                f[0],
                f[1],
                f[2],
                p,
            )
        }
    }

    #[test]
    fn varying_calls_through_the_abi() {
        let m = load(r#"{"model": "coated_paint", "flake_density": 3}"#);
        let n = 13;
        let wi: [Vec<f32>; 3] = [vec![0.3; n], vec![0.1; n], vec![0.9; n]];
        let wo: [Vec<f32>; 3] = [vec![-0.4; n], vec![0.2; n], vec![0.85; n]];
        let red: Vec<f32> = (0..n).map(|i| i as f32 / n as f32).collect();
        let mut green = vec![0.2f32; n];
        let blue = vec![0.1f32; n];
        let dens: Vec<f32> = (0..n).map(|i| i as f32).collect();
        green[7] = 2.0; // out of range
        let (mut f, mut p) = ([vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]], vec![0.0f32; n]);
        let [fr, fg, fb] = &mut f;
        let st = eval_varying(
            m,
            n,
            &wi,
            &wo,
            [Some(&red[..]), Some(&green[..]), Some(&blue[..])],
            Some(&dens[..]),
            [fr.as_mut_ptr(), fg.as_mut_ptr(), fb.as_mut_ptr()],
            p.as_mut_ptr(),
        );
        assert_eq!(st, LQ_ERR_INVALID_ELEMENT);
        let msg = last_error();
        assert!(msg.contains("element 7") && msg.contains("base_color"), "{msg}");
        assert_eq!((fr[7], fg[7], fb[7], p[7]), (0.0, 0.0, 0.0, 0.0));
        // The core call gives the same values for the valid elements.
        let mat: &Material = unsafe { material(m) }.unwrap();
        let tex = PaintTexture {
            base_color: Some([&red[..], &green[..], &blue[..]]),
            flake_density: Some(&dens[..]),
            coat_roughness: None,
        };
        let mut fc = vec![0.0f32; 3 * n];
        let a = Src3::soa(&wi[0], &wi[1], &wi[2]).unwrap();
        let b = Src3::soa(&wo[0], &wo[1], &wo[2]).unwrap();
        lacquer_core::batch::eval_pdf_varying(mat, &tex, &a, &b, None, Some(&Dst3::interleaved(&mut fc)), None)
            .unwrap();
        for i in (0..n).filter(|&i| i != 7) {
            assert_eq!([fr[i], fg[i], fb[i]], [fc[3 * i], fc[3 * i + 1], fc[3 * i + 2]], "element {i}");
            assert!(fr[i] > 0.0 && p[i] > 0.0);
        }
        let null = std::ptr::null_mut::<f32>();
        let st = eval_varying(
            m,
            n,
            &wi,
            &wo,
            [Some(&red[..]), None, Some(&blue[..])],
            None,
            [fr.as_mut_ptr(), fg.as_mut_ptr(), fb.as_mut_ptr()],
            p.as_mut_ptr(),
        );
        assert_eq!(st, LQ_ERR_INVALID_ARGUMENT, "{}", last_error());
        // A density texture alone, on material `mat` into `f`, `pdf`.
        let density_only = |mat: *const lq_material, f: [*mut f32; 3], pdf: *mut f32| {
            eval_varying(mat, n, &wi, &wo, [None, None, None], Some(&dens[..]), f, pdf)
        };
        assert_eq!(density_only(m, [null; 3], null), LQ_ERR_NULL, "{}", last_error());
        let (f_out, p_out) = ([fr.as_mut_ptr(), fg.as_mut_ptr(), fb.as_mut_ptr()], p.as_mut_ptr());
        assert_eq!(density_only(std::ptr::null(), f_out, p_out), LQ_ERR_NULL);
        // Sampling: coat roughness out of range on element 2; NULL flags allowed.
        let u = [vec![0.3f32; n], vec![0.6f32; n], vec![0.2f32; n]];
        let mut rough = vec![0.05f32; n];
        rough[2] = 0.0;
        let (mut swi, mut sw, mut sp, mut fl) = (
            [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]],
            [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]],
            vec![0.0f32; n],
            vec![0u32; n],
        );
        let [wx, wy, wz] = &mut swi;
        let [wr, wg, wb] = &mut sw;
        let st = unsafe {
            lq_sample_varying(
                m,
                n,
                wo[0].as_ptr(),
                wo[1].as_ptr(),
                wo[2].as_ptr(),
                u[0].as_ptr(),
                u[1].as_ptr(),
                u[2].as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                rough.as_ptr(),
                std::ptr::null(),
                wx.as_mut_ptr(),
                wy.as_mut_ptr(),
                wz.as_mut_ptr(),
                wr.as_mut_ptr(),
                wg.as_mut_ptr(),
                wb.as_mut_ptr(),
                sp.as_mut_ptr(),
                fl.as_mut_ptr(),
            )
        };
        assert_eq!(st, LQ_ERR_INVALID_ELEMENT);
        assert!(last_error().contains("coat_roughness = 0"), "{}", last_error());
        assert_eq!(fl[2], lacquer_core::batch::SAMPLE_FAILED | lacquer_core::batch::SAMPLE_INVALID_INPUT);
        assert!(sp[3] > 0.0 && fl[3] == 0);
        unsafe { lq_material_free(m) };
        // A texture on another model is an argument error, not a panic.
        let l = load(r#"{"model": "lambert"}"#);
        assert_eq!(density_only(l, f_out, p_out), LQ_ERR_INVALID_ARGUMENT);
        assert!(last_error().contains("coated_paint"), "{}", last_error());
        unsafe { lq_material_free(l) };
    }
}
