//! One material handle used from 8 threads at once gives results bit-identical to one
//! thread; `lq_last_error` is per thread.

use super::*;
use lacquer_core::models;
use lq_status::*;

/// A raw handle shared across threads (the ABI documents handles as thread-safe).
#[derive(Clone, Copy)]
struct Shared(*const lq_material);
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

/// eval, pdf and sample over one batch; returns every output's bits.
fn run(m: Shared, wi: &[f32], wo: &[f32], u: &[f32]) -> Vec<u32> {
    let n = wi.len() / 3;
    let (mut f, mut p) = (vec![0f32; 3 * n], vec![0f32; n]);
    let (mut swi, mut sw, mut sp) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n]);
    unsafe {
        assert_eq!(lq_eval(m.0, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr()), LQ_OK);
        assert_eq!(lq_pdf(m.0, n, wi.as_ptr(), wo.as_ptr(), p.as_mut_ptr()), LQ_OK);
        let s = lq_sample(m.0, n, wo.as_ptr(), u.as_ptr(), swi.as_mut_ptr(), sw.as_mut_ptr(), sp.as_mut_ptr());
        assert_eq!(s, LQ_OK);
    }
    [f, p, swi, sw, sp].iter().flatten().map(|x| x.to_bits()).collect()
}

#[test]
fn eight_threads_match_one_thread_bit_for_bit() {
    let n = 4096;
    let (wi, wo, u) = super::api::inputs(n, 99);
    let f32s = |a: &[f64]| a.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let (wi, wo, u) = (f32s(&wi), f32s(&wo), f32s(&u));
    for info in models::all() {
        let m = Shared(material(&format!("{{\"model\": \"{}\"}}", info.name)));
        let reference = run(m, &wi, &wo, &u);
        let results: Vec<Vec<u32>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..8)
                .map(|_| {
                    s.spawn(|| {
                        // Several rounds per thread so the calls really interleave.
                        let mut last = Vec::new();
                        for _ in 0..4 {
                            last = run(m, &wi, &wo, &u);
                        }
                        last
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for (t, r) in results.iter().enumerate() {
            assert!(r == &reference, "{}: thread {t} differs", info.name);
        }
        unsafe { lq_material_free(m.0.cast_mut()) };
    }
}

#[test]
fn last_error_is_per_thread() {
    let mut m = std::ptr::null_mut();
    assert_eq!(unsafe { lq_material_from_json(c"{\"model\": 1}".as_ptr(), &mut m) }, LQ_ERR_INVALID_MATERIAL);
    let here = last_error();
    assert!(here.contains("\"model\""), "{here}");
    std::thread::spawn(|| {
        assert_eq!(last_error(), "");
        let mut m = std::ptr::null_mut();
        assert_eq!(unsafe { lq_material_from_json(c"[".as_ptr(), &mut m) }, LQ_ERR_INVALID_JSON);
        assert!(last_error().starts_with("invalid JSON"));
    })
    .join()
    .unwrap();
    assert_eq!(last_error(), here);
}
