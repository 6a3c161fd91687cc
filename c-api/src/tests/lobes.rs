//! Lobe selection through the ABI (ABI 0.7): the groups, every lobe call against the core's
//! per-lobe answers, the full mask as the plain calls bit for bit, bad masks as a status.

use super::*;
use lacquer_core::lobes::LobeSelection;
use lacquer_core::{Material, Vec3};
use lq_status::*;

fn handle(json: &str) -> (*mut lq_material, Material) {
    let c = std::ffi::CString::new(json).unwrap();
    let mut m = std::ptr::null_mut();
    assert_eq!(unsafe { lq_material_from_json(c.as_ptr(), &mut m) }, LQ_OK);
    (m, Material::from_json(json).unwrap())
}

const PAINT: &str = r#"{"model": "coated_paint", "coat_roughness": 0.1, "flake_density": 5, "base_metallic": 0.3}"#;

#[test]
fn lobe_parts_through_the_abi() {
    let (m, _) = handle(r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 3}"#);
    let mut count = 0usize;
    assert_eq!(unsafe { lq_material_lobe_part_count(m, &mut count) }, LQ_OK);
    assert_eq!(count, 3);
    let mut got = Vec::new();
    for i in 0..count {
        let (mut s, mut k) = (0u32, 0u32);
        assert_eq!(unsafe { lq_material_lobe_part(m, i, &mut s, &mut k) }, LQ_OK);
        got.push((s, k));
    }
    assert_eq!(
        got,
        vec![(LQ_LOBE_DIFFUSE, LQ_LOBE_DIFFUSE), (LQ_LOBE_GLOSSY, LQ_LOBE_GLOSSY), (LQ_LOBE_COAT, LQ_LOBE_DELTA)]
    );
    let (mut s, mut k) = (0u32, 0u32);
    assert_eq!(unsafe { lq_material_lobe_part(m, 3, &mut s, &mut k) }, LQ_ERR_INVALID_ARGUMENT);
    let mut lobes = 0u32;
    assert_eq!(unsafe { lq_material_lobes(m, &mut lobes) }, LQ_OK);
    assert_ne!(lobes & LQ_LOBE_COAT, 0);
    unsafe { lq_material_free(m) };
}

/// Each lobe call equals the core's per-lobe answer (interleaved with and without sparkle
/// positions, one element, SoA), and the full mask equals the plain calls bit for bit.
#[test]
fn lobe_calls_match_the_core() {
    let (m, core) = handle(PAINT);
    let n = 64;
    let (wi, wo, u) = super::api::inputs(n, 9);
    let (wi, wo, u): (Vec<f32>, Vec<f32>, Vec<f32>) = (
        wi.iter().map(|&x| x as f32).collect(),
        wo.iter().map(|&x| x as f32).collect(),
        u.iter().map(|&x| x as f32).collect(),
    );
    let uv: Vec<f32> = (0..n).flat_map(|i| [0.01 * i as f32, 0.3]).collect();
    let duv: Vec<f32> = (0..n).flat_map(|_| [1e-4f32, 0.0, 0.0, 1e-4]).collect();
    let soa = |a: &[f32], c: usize| -> Vec<f32> { (0..n).map(|i| a[3 * i + c]).collect() };
    let (wix, wiy, wiz, wox, woy, woz) = (soa(&wi, 0), soa(&wi, 1), soa(&wi, 2), soa(&wo, 0), soa(&wo, 1), soa(&wo, 2));
    let (u0, u1, u2) = (soa(&u, 0), soa(&u, 1), soa(&u, 2));
    for mask in [LQ_LOBE_DIFFUSE, LQ_LOBE_GLOSSY, LQ_LOBE_COAT, LQ_LOBE_DIFFUSE | LQ_LOBE_COAT, LQ_LOBES_SELECTABLE] {
        let sel = core.select_lobes(mask).unwrap();
        // Interleaved, mean lobe (SIMD kernels) and at surface points (element loop).
        let (mut f, mut p) = (vec![0f32; 3 * n], vec![0f32; n]);
        let st = unsafe {
            lq_eval_pdf_lobes(
                m,
                n,
                wi.as_ptr(),
                wo.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                mask,
                f.as_mut_ptr(),
                p.as_mut_ptr(),
            )
        };
        assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION, "{st:?}");
        let (mut fa, mut pa) = (vec![0f32; 3 * n], vec![0f32; n]);
        let st = unsafe {
            lq_eval_pdf_lobes(
                m,
                n,
                wi.as_ptr(),
                wo.as_ptr(),
                uv.as_ptr(),
                duv.as_ptr(),
                mask,
                fa.as_mut_ptr(),
                pa.as_mut_ptr(),
            )
        };
        assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION, "{st:?}");
        let (mut fs_r, mut fs_g, mut fs_b, mut ps) = (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        let st = unsafe {
            lq_eval_pdf_soa_lobes(
                m,
                n,
                wix.as_ptr(),
                wiy.as_ptr(),
                wiz.as_ptr(),
                wox.as_ptr(),
                woy.as_ptr(),
                woz.as_ptr(),
                std::ptr::null(),
                mask,
                fs_r.as_mut_ptr(),
                fs_g.as_mut_ptr(),
                fs_b.as_mut_ptr(),
                ps.as_mut_ptr(),
            )
        };
        assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION, "{st:?}");
        for i in 0..n {
            let a = Vec3::new(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]);
            let o = Vec3::new(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
            let want = core.eval_lobes(a, o, sel);
            let at =
                lacquer_core::SurfacePoint { uv: [uv[2 * i] as f64, 0.3], duv_dx: [1e-4, 0.0], duv_dy: [0.0, 1e-4] };
            let want_at = core.eval_at_lobes(a, o, &at, sel);
            let pw = core.pdf_lobes(a, o, sel);
            // Kernels vs the scalar path: f32 fast maths, 2e-4 relative (as the batch tests).
            let close = |x: f32, y: f32| (x - y).abs() <= 2e-4 * y.abs().max(1e-3);
            for c in 0..3 {
                assert!(close(f[3 * i + c], want[c]), "mask {mask} element {i}: {} vs {}", f[3 * i + c], want[c]);
                assert_eq!(fa[3 * i + c], want_at[c], "mask {mask} element {i} at a point");
            }
            assert!(
                close(fs_r[i], want.r) && close(fs_g[i], want.g) && close(fs_b[i], want.b),
                "soa mask {mask} element {i}"
            );
            assert!(close(p[i], pw) && close(ps[i], pw), "mask {mask} element {i}: pdf {} / {} vs {pw}", p[i], ps[i]);
            assert_eq!(pa[i], pw);
            // One element: the scalar path itself.
            let (mut f1, mut p1) = ([0f32; 3], 0f32);
            let st = unsafe {
                lq_eval_pdf_one_lobes(m, wi[3 * i..].as_ptr(), wo[3 * i..].as_ptr(), mask, f1.as_mut_ptr(), &mut p1)
            };
            assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION);
            assert_eq!((f1, p1), (want.to_array(), pw), "one element, mask {mask}");
            let (mut w1, mut wt1, mut sp1, mut fl1) = ([0f32; 3], [0f32; 3], 0f32, 0u32);
            let st = unsafe {
                lq_sample_one_lobes(
                    m,
                    wo[3 * i..].as_ptr(),
                    u[3 * i..].as_ptr(),
                    mask,
                    w1.as_mut_ptr(),
                    wt1.as_mut_ptr(),
                    &mut sp1,
                    &mut fl1,
                )
            };
            assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION);
            let s = core.sample_lobes(o, [u[3 * i], u[3 * i + 1], u[3 * i + 2]], sel);
            assert_eq!(
                s.map(|s| ([s.wi.x, s.wi.y, s.wi.z], s.weight.to_array(), s.pdf)),
                (fl1 & LQ_SAMPLE_FAILED == 0).then_some((w1, wt1, sp1))
            );
        }
        // Sampling: interleaved (kernels) and SoA (kernels) agree with each other exactly.
        let (mut swi, mut sw, mut sp, mut sf) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n], vec![0u32; n]);
        let st = unsafe {
            lq_sample_lobes(
                m,
                n,
                wo.as_ptr(),
                u.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                mask,
                swi.as_mut_ptr(),
                sw.as_mut_ptr(),
                sp.as_mut_ptr(),
                sf.as_mut_ptr(),
            )
        };
        assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION, "{st:?}");
        let mut o: Vec<Vec<f32>> = (0..7).map(|_| vec![0f32; n]).collect();
        let mut of = vec![0u32; n];
        let st = unsafe {
            let [a, b, c, d, e, g, h] = &mut o[..] else { unreachable!() };
            lq_sample_soa_lobes(
                m,
                n,
                wox.as_ptr(),
                woy.as_ptr(),
                woz.as_ptr(),
                u0.as_ptr(),
                u1.as_ptr(),
                u2.as_ptr(),
                std::ptr::null(),
                mask,
                a.as_mut_ptr(),
                b.as_mut_ptr(),
                c.as_mut_ptr(),
                d.as_mut_ptr(),
                e.as_mut_ptr(),
                g.as_mut_ptr(),
                h.as_mut_ptr(),
                of.as_mut_ptr(),
            )
        };
        assert!(st == LQ_OK || st == LQ_ERR_INVALID_DIRECTION, "{st:?}");
        for i in 0..n {
            assert_eq!(
                [o[0][i], o[1][i], o[2][i], o[3][i], o[4][i], o[5][i], o[6][i]],
                [swi[3 * i], swi[3 * i + 1], swi[3 * i + 2], sw[3 * i], sw[3 * i + 1], sw[3 * i + 2], sp[i]]
            );
            assert_eq!(of[i], sf[i]);
        }
        if mask == LQ_LOBES_SELECTABLE {
            // The full mask is the plain calls, bit for bit.
            let (mut f0, mut p0) = (vec![0f32; 3 * n], vec![0f32; n]);
            let _ = unsafe { lq_eval_pdf(m, n, wi.as_ptr(), wo.as_ptr(), f0.as_mut_ptr(), p0.as_mut_ptr()) };
            assert_eq!((f0, p0), (f.clone(), p.clone()));
            let (mut w0, mut wt0, mut sp0) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n]);
            let _ = unsafe {
                lq_sample(m, n, wo.as_ptr(), u.as_ptr(), w0.as_mut_ptr(), wt0.as_mut_ptr(), sp0.as_mut_ptr())
            };
            assert_eq!((w0, wt0, sp0), (swi.clone(), sw.clone(), sp.clone()));
        }
    }
    unsafe { lq_material_free(m) };
}

/// Bad masks are LQ_ERR_INVALID_ARGUMENT with a message naming the mask, and nothing is
/// written; a mask of none of the lobes is valid (zeros).
#[test]
fn bad_lobe_masks_are_a_status() {
    let (m, _) = handle(PAINT);
    let (wi, wo) = ([0.3f32, 0.1, 0.95], [-0.2f32, 0.2, 0.96]);
    let (mut f, mut p) = ([7f32; 3], 7f32);
    assert_eq!(
        unsafe { lq_eval_pdf_one_lobes(m, wi.as_ptr(), wo.as_ptr(), LQ_LOBE_DELTA, f.as_mut_ptr(), &mut p) },
        LQ_ERR_INVALID_ARGUMENT
    );
    let msg = unsafe { std::ffi::CStr::from_ptr(lq_last_error()) }.to_string_lossy().into_owned();
    assert!(msg.contains("lobe mask") && msg.contains("0x4"), "{msg}");
    assert_eq!((f, p), ([7.0; 3], 7.0), "nothing written");
    assert_eq!(unsafe { lq_eval_pdf_one_lobes(m, wi.as_ptr(), wo.as_ptr(), 0, f.as_mut_ptr(), &mut p) }, LQ_OK);
    assert_eq!((f, p), ([0.0; 3], 0.0));
    let (ct, _) = handle(r#"{"model": "cook_torrance"}"#);
    assert_eq!(
        unsafe { lq_eval_pdf_one_lobes(ct, wi.as_ptr(), wo.as_ptr(), LQ_LOBE_DIFFUSE, f.as_mut_ptr(), &mut p) },
        LQ_ERR_INVALID_ARGUMENT
    );
    let msg = unsafe { std::ffi::CStr::from_ptr(lq_last_error()) }.to_string_lossy().into_owned();
    assert!(msg.contains("all or none"), "{msg}");
    let (mut w, mut wt, mut sp, mut fl) = ([0f32; 3], [0f32; 3], 0f32, 0u32);
    assert_eq!(
        unsafe {
            lq_sample_one_lobes(
                m,
                wo.as_ptr(),
                [0.5f32; 3].as_ptr(),
                1 << 9,
                w.as_mut_ptr(),
                wt.as_mut_ptr(),
                &mut sp,
                &mut fl,
            )
        },
        LQ_ERR_INVALID_ARGUMENT
    );
    assert_eq!(
        unsafe { lq_eval_pdf_one_lobes(std::ptr::null(), wi.as_ptr(), wo.as_ptr(), 1, f.as_mut_ptr(), &mut p) },
        LQ_ERR_NULL
    );
    let _ = LobeSelection::All;
    unsafe {
        lq_material_free(m);
        lq_material_free(ct);
    }
}
