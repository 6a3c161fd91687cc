//! The ABI gives exactly what the core gives (it owns no physics), for every registered
//! model, in f32 and f64, for eval, pdf, eval_pdf, sample and the spatial variants.

use super::*;
use lacquer_core::rng::Pcg32;
use lacquer_core::{models, presets, Material, Real, Vec3};
use lq_status::*;

/// Test inputs: mostly upper-hemisphere directions, some below the horizon and some not
/// unit length, as a renderer would pass them.
pub(crate) fn inputs(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = Pcg32::new(seed, 7);
    let dir = |rng: &mut Pcg32, k: usize| -> [f64; 3] {
        let w = lacquer_core::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
        match k % 11 {
            3 => [w.x, w.y, -w.z],                  // below the horizon
            7 => [2.5 * w.x, 2.5 * w.y, 2.5 * w.z], // not unit length
            _ => [w.x, w.y, w.z],
        }
    };
    let mut wi = Vec::with_capacity(3 * n);
    let mut wo = Vec::with_capacity(3 * n);
    let mut u = Vec::with_capacity(3 * n);
    for k in 0..n {
        wi.extend(dir(&mut rng, k));
        wo.extend(dir(&mut rng, k + 5));
        u.extend(rng.uniform3());
    }
    (wi, wo, u)
}

fn v<T: Real>(a: &[T], i: usize) -> Vec3<T> {
    Vec3::new(a[3 * i], a[3 * i + 1], a[3 * i + 2])
}

fn cast<T: Real>(a: &[f64]) -> Vec<T> {
    a.iter().map(|&x| T::of(x)).collect()
}

/// The core's own answers for a batch.
struct Expected<T> {
    f: Vec<T>,
    pdf: Vec<T>,
    s_wi: Vec<T>,
    s_weight: Vec<T>,
    s_pdf: Vec<T>,
    s_flags: Vec<u32>,
}

fn expected<T: Real>(m: &Material, wi: &[T], wo: &[T], u: &[T]) -> Expected<T> {
    let n = wi.len() / 3;
    let mut e = Expected { f: vec![], pdf: vec![], s_wi: vec![], s_weight: vec![], s_pdf: vec![], s_flags: vec![] };
    for i in 0..n {
        let f = m.eval(v(wi, i), v(wo, i));
        e.f.extend(f.to_array());
        e.pdf.push(m.pdf(v(wi, i), v(wo, i)));
        match m.sample(v(wo, i), [u[3 * i], u[3 * i + 1], u[3 * i + 2]]) {
            Some(s) => {
                e.s_wi.extend([s.wi.x, s.wi.y, s.wi.z]);
                e.s_weight.extend(s.weight.to_array());
                e.s_pdf.push(s.pdf);
                e.s_flags.push(if s.delta { LQ_SAMPLE_DELTA } else { 0 });
            }
            None => {
                e.s_wi.extend([T::zero(); 3]);
                e.s_weight.extend([T::zero(); 3]);
                e.s_pdf.push(T::zero());
                e.s_flags.push(LQ_SAMPLE_FAILED);
            }
        }
    }
    e
}

/// The core's batch kernels' answers in f32 (SIMD lanes for lane models: they agree with the
/// scalar f32 path within rounding, see rust-core/tests/integration/batch.rs; the ABI must give exactly
/// these).
fn expected_batch_f32(m: &Material, wi: &[f32], wo: &[f32], u: &[f32]) -> Expected<f32> {
    use lacquer_core::batch::{self, Dst1, Dst3, SampleOut, Src3};
    let n = wi.len() / 3;
    let mut e = Expected {
        f: vec![0.0; 3 * n],
        pdf: vec![0.0; n],
        s_wi: vec![0.0; 3 * n],
        s_weight: vec![0.0; 3 * n],
        s_pdf: vec![0.0; n],
        s_flags: vec![0; n],
    };
    let (wi, wo, u) = (Src3::interleaved(wi), Src3::interleaved(wo), Src3::interleaved(u));
    batch::eval_pdf(m, &wi, &wo, None, Some(&Dst3::interleaved(&mut e.f)), Some(&Dst1::new(&mut e.pdf))).unwrap();
    let mut out = SampleOut {
        wi: Dst3::interleaved(&mut e.s_wi),
        weight: Dst3::interleaved(&mut e.s_weight),
        pdf: Dst1::new(&mut e.s_pdf),
        flags: Some(&mut e.s_flags),
    };
    batch::sample(m, &wo, &u, None, &mut out).unwrap();
    e
}

fn bits<T: Real>(a: &[T]) -> Vec<u64> {
    a.iter().map(|x| x.f64().to_bits()).collect()
}

#[test]
fn every_model_matches_the_core_bit_for_bit() {
    let n = 2000;
    let (wi, wo, u) = inputs(n, 3);
    for info in models::all() {
        let core = Material::default_of(info).expect("defaults build");
        let json = core.to_json().to_string();
        let m = material(&json);

        // f32
        let (wi32, wo32, u32_): (Vec<f32>, Vec<f32>, Vec<f32>) = (cast(&wi), cast(&wo), cast(&u));
        let e = expected_batch_f32(&core, &wi32, &wo32, &u32_);
        if !core.model().has_lane_kernel() {
            // Without a lane kernel the batch runs the scalar path element by element.
            let scalar = expected(&core, &wi32, &wo32, &u32_);
            assert_eq!((bits(&e.f), bits(&e.pdf)), (bits(&scalar.f), bits(&scalar.pdf)), "{}", info.name);
            assert_eq!(
                (bits(&e.s_wi), bits(&e.s_weight)),
                (bits(&scalar.s_wi), bits(&scalar.s_weight)),
                "{}",
                info.name
            );
            assert_eq!(e.s_flags, scalar.s_flags, "{}", info.name);
        }
        let mut f = vec![0f32; 3 * n];
        let mut p = vec![0f32; n];
        let (mut f2, mut p2) = (vec![0f32; 3 * n], vec![0f32; n]);
        let (mut swi, mut sw, mut sp, mut fl) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n], vec![9u32; n]);
        unsafe {
            assert_eq!(lq_eval(m, n, wi32.as_ptr(), wo32.as_ptr(), f.as_mut_ptr()), LQ_OK);
            assert_eq!(lq_pdf(m, n, wi32.as_ptr(), wo32.as_ptr(), p.as_mut_ptr()), LQ_OK);
            let s = lq_eval_pdf(m, n, wi32.as_ptr(), wo32.as_ptr(), f2.as_mut_ptr(), p2.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let s = lq_sample_spatial(
                m,
                n,
                wo32.as_ptr(),
                u32_.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                swi.as_mut_ptr(),
                sw.as_mut_ptr(),
                sp.as_mut_ptr(),
                fl.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK);
        }
        assert_eq!(bits(&f), bits(&e.f), "{}: lq_eval", info.name);
        assert_eq!(bits(&p), bits(&e.pdf), "{}: lq_pdf", info.name);
        assert_eq!(bits(&f2), bits(&e.f), "{}: lq_eval_pdf f", info.name);
        assert_eq!(bits(&p2), bits(&e.pdf), "{}: lq_eval_pdf pdf", info.name);
        assert_eq!(bits(&swi), bits(&e.s_wi), "{}: sample wi", info.name);
        assert_eq!(bits(&sw), bits(&e.s_weight), "{}: sample weight", info.name);
        assert_eq!(bits(&sp), bits(&e.s_pdf), "{}: sample pdf", info.name);
        assert_eq!(fl, e.s_flags, "{}: sample flags", info.name);
        // The plain lq_sample agrees with the flagged one.
        let (mut swi2, mut sw2, mut sp2) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n]);
        let s = unsafe {
            lq_sample(m, n, wo32.as_ptr(), u32_.as_ptr(), swi2.as_mut_ptr(), sw2.as_mut_ptr(), sp2.as_mut_ptr())
        };
        assert_eq!(s, LQ_OK);
        assert_eq!((bits(&swi2), bits(&sw2), bits(&sp2)), (bits(&swi), bits(&sw), bits(&sp)));

        // f64
        let e = expected(&core, &wi, &wo, &u);
        let mut f = vec![0f64; 3 * n];
        let mut p = vec![0f64; n];
        let (mut f2, mut p2) = (vec![0f64; 3 * n], vec![0f64; n]);
        let (mut swi, mut sw, mut sp, mut fl) = (vec![0f64; 3 * n], vec![0f64; 3 * n], vec![0f64; n], vec![9u32; n]);
        unsafe {
            assert_eq!(lq_eval_f64(m, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr()), LQ_OK);
            assert_eq!(lq_pdf_f64(m, n, wi.as_ptr(), wo.as_ptr(), p.as_mut_ptr()), LQ_OK);
            let s = lq_eval_pdf_f64(m, n, wi.as_ptr(), wo.as_ptr(), f2.as_mut_ptr(), p2.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let s = lq_sample_f64(
                m,
                n,
                wo.as_ptr(),
                u.as_ptr(),
                swi.as_mut_ptr(),
                sw.as_mut_ptr(),
                sp.as_mut_ptr(),
                fl.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK);
        }
        assert_eq!(bits(&f), bits(&e.f), "{}: lq_eval_f64", info.name);
        assert_eq!(bits(&p), bits(&e.pdf), "{}: lq_pdf_f64", info.name);
        assert_eq!(bits(&f2), bits(&e.f));
        assert_eq!(bits(&p2), bits(&e.pdf));
        assert_eq!(bits(&swi), bits(&e.s_wi), "{}: lq_sample_f64 wi", info.name);
        assert_eq!(bits(&sw), bits(&e.s_weight));
        assert_eq!(bits(&sp), bits(&e.s_pdf));
        assert_eq!(fl, e.s_flags);
        unsafe { lq_material_free(m) };
    }
}

#[test]
fn spatial_inputs_reach_the_core_unchanged() {
    // With uv and duv, the ABI must return exactly the core's surface-point batch calls
    // (`batch::eval_pdf_at` / `sample_at`: the SIMD kernels with the flake lobes scaled per
    // element, which rust-core/tests/integration/batch.rs holds to Material::eval_at / sample_at within f32
    // rounding); with uv alone, exactly Material::eval (the mean lobe); the pdf never depends
    // on position.
    let n = 500;
    let (wi, wo, u) = inputs(n, 11);
    let (wi, wo, u): (Vec<f32>, Vec<f32>, Vec<f32>) = (cast(&wi), cast(&wo), cast(&u));
    let uv: Vec<f32> = (0..2 * n).map(|k| (k as f32 * 0.37).fract()).collect();
    let duv: Vec<f32> = (0..4 * n).map(|k| [1e-4, 0.0, 0.0, 1e-4][k % 4] * (1 + k % 7) as f32).collect();
    let at = |i: usize| lacquer_core::SurfacePoint {
        uv: [uv[2 * i] as f64, uv[2 * i + 1] as f64],
        duv_dx: [duv[4 * i] as f64, duv[4 * i + 1] as f64],
        duv_dy: [duv[4 * i + 2] as f64, duv[4 * i + 3] as f64],
    };
    let v3 = |a: &[f32], i: usize| lacquer_core::Vec3::new(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
    let mut sparkle_seen = false;
    for info in models::all() {
        let json = format!("{{\"model\": \"{}\"}}", info.name);
        let core = lacquer_core::Material::from_json(&json).unwrap();
        let m = material(&json);
        let (mut f_s, mut p_s, mut f_uv) = (vec![1f32; 3 * n], vec![1f32; n], vec![1f32; 3 * n]);
        let mut out_s = [vec![1f32; 3 * n], vec![1f32; 3 * n], vec![1f32; n]];
        unsafe {
            let s = lq_eval_spatial(m, n, wi.as_ptr(), wo.as_ptr(), uv.as_ptr(), duv.as_ptr(), f_s.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let s = lq_eval_spatial(m, n, wi.as_ptr(), wo.as_ptr(), uv.as_ptr(), std::ptr::null(), f_uv.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let s = lq_pdf_spatial(m, n, wi.as_ptr(), wo.as_ptr(), uv.as_ptr(), duv.as_ptr(), p_s.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let [a, b, c] = &mut out_s;
            let s = lq_sample_spatial(
                m,
                n,
                wo.as_ptr(),
                u.as_ptr(),
                uv.as_ptr(),
                duv.as_ptr(),
                a.as_mut_ptr(),
                b.as_mut_ptr(),
                c.as_mut_ptr(),
                std::ptr::null_mut(),
            );
            assert_eq!(s, LQ_OK);
            lq_material_free(m);
        }
        let ats: Vec<lacquer_core::SurfacePoint> = (0..n).map(at).collect();
        let e = {
            use lacquer_core::batch::{self, Dst1, Dst3, SampleOut, Src3};
            let (mut f, mut p) = (vec![0f32; 3 * n], vec![0f32; n]);
            let (mut swi, mut sw, mut sp) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n]);
            let (wiv, wov, uv3) = (Src3::interleaved(&wi), Src3::interleaved(&wo), Src3::interleaved(&u));
            batch::eval_pdf_at(
                &core,
                &wiv,
                &wov,
                &ats,
                None,
                Some(&Dst3::interleaved(&mut f)),
                Some(&Dst1::new(&mut p)),
            )
            .unwrap();
            let mut out = SampleOut {
                wi: Dst3::interleaved(&mut swi),
                weight: Dst3::interleaved(&mut sw),
                pdf: Dst1::new(&mut sp),
                flags: None,
            };
            batch::sample_at(&core, &wov, &uv3, &ats, None, &mut out).unwrap();
            [f, p, swi, sw, sp]
        };
        for i in 0..n {
            let (a, o) = (v3(&wi, i), v3(&wo, i));
            assert_eq!(bits(&f_s[3 * i..3 * i + 3]), bits(&e[0][3 * i..3 * i + 3]), "{} element {i}", info.name);
            let mean = core.eval(a, o).to_array();
            assert_eq!(bits(&f_uv[3 * i..3 * i + 3]), bits(&mean), "{} element {i} (uv only)", info.name);
            sparkle_seen |= core.eval_at(a, o, &at(i)).to_array() != mean;
            assert_eq!(p_s[i].to_bits(), e[1][i].to_bits(), "{} pdf {i}", info.name);
            assert_eq!(bits(&out_s[0][3 * i..3 * i + 3]), bits(&e[2][3 * i..3 * i + 3]), "{} sample wi {i}", info.name);
            assert_eq!(bits(&out_s[1][3 * i..3 * i + 3]), bits(&e[3][3 * i..3 * i + 3]), "{} weight {i}", info.name);
            assert_eq!(out_s[2][i].to_bits(), e[4][i].to_bits(), "{} sample pdf {i}", info.name);
        }
    }
    assert!(sparkle_seen, "the default coated paint sparkles through the ABI");
}

#[test]
fn lambert_closed_form_through_the_abi() {
    // f = ρ/π and pdf = cos θi/π for Lambert (closed forms, not computed by the code).
    let m = material(r#"{"model": "lambert", "albedo": [0.8, 0.5, 0.25]}"#);
    let wi = [0.0f64, 0.6, 0.8];
    let wo = [0.0f64, 0.0, 1.0];
    let mut f = [0f64; 3];
    let mut p = [0f64; 1];
    unsafe {
        assert_eq!(lq_eval_pdf_f64(m, 1, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), p.as_mut_ptr()), LQ_OK);
        lq_material_free(m);
    }
    let pi = std::f64::consts::PI;
    for (got, rho) in f.iter().zip([0.8, 0.5, 0.25]) {
        assert!((got - rho / pi).abs() < 1e-15, "{got}");
    }
    assert!((p[0] - 0.8 / pi).abs() < 1e-15);
}

#[test]
fn versions_names_and_last_error() {
    assert_eq!(lq_abi_version(), LQ_ABI_VERSION);
    assert_eq!(LQ_ABI_VERSION >> 16, LQ_ABI_VERSION_MAJOR);
    assert_eq!(LQ_ABI_VERSION & 0xffff, LQ_ABI_VERSION_MINOR);
    let v = unsafe { CStr::from_ptr(lq_version()) }.to_str().unwrap();
    assert_eq!(v, env!("CARGO_PKG_VERSION"));
    for s in crate::status::ALL_STATUSES {
        let name = unsafe { CStr::from_ptr(lq_status_name(s as i32)) };
        assert_eq!(name, s.name());
    }
    // A failure sets the message; the next successful call clears it.
    let mut m = std::ptr::null_mut();
    assert_eq!(unsafe { lq_material_from_json(c"{".as_ptr(), &mut m) }, LQ_ERR_INVALID_JSON);
    assert!(last_error().starts_with("invalid JSON"), "{}", last_error());
    // lq_last_error itself does not clear it.
    assert!(!last_error().is_empty());
    let m = material(r#"{"model": "lambert"}"#);
    assert_eq!(last_error(), "");
    unsafe { lq_material_free(m) };
}

#[test]
fn json_round_trip_presets_and_catalog() {
    for info in models::all() {
        let m = material(&format!("{{\"model\": \"{}\"}}", info.name));
        let mut out = std::ptr::null_mut();
        assert_eq!(unsafe { lq_material_to_json(m, &mut out) }, LQ_OK);
        let canonical = take_string(out);
        let m2 = material(&canonical);
        let mut out2 = std::ptr::null_mut();
        assert_eq!(unsafe { lq_material_to_json(m2, &mut out2) }, LQ_OK);
        assert_eq!(take_string(out2), canonical);
        let v: serde_json::Value = serde_json::from_str(&canonical).unwrap();
        assert_eq!(v["model"], info.name);
        unsafe {
            lq_material_free(m);
            lq_material_free(m2);
        }
    }

    let mut out = std::ptr::null_mut();
    assert_eq!(unsafe { lq_models_json(&mut out) }, LQ_OK);
    let list: Vec<serde_json::Value> = serde_json::from_str(&take_string(out)).unwrap();
    let names: Vec<&str> = list.iter().map(|m| m["name"].as_str().unwrap()).collect();
    let registry: Vec<&str> = models::all().iter().map(|m| m.name).collect();
    assert_eq!(names, registry);
    for m in &list {
        for key in ["summary", "reference", "claims", "params"] {
            assert!(m.get(key).is_some(), "{key} missing from {m}");
        }
        assert!(m["claims"]["reciprocal"].is_boolean());
    }

    let mut out = std::ptr::null_mut();
    assert_eq!(unsafe { lq_presets_json(&mut out) }, LQ_OK);
    let list: Vec<serde_json::Value> = serde_json::from_str(&take_string(out)).unwrap();
    assert_eq!(list.len(), presets::PRESETS.len());
    for (p, entry) in presets::PRESETS.iter().zip(&list) {
        assert_eq!(entry["name"], p.name);
        assert!(entry["material"]["model"].is_string(), "{entry}");
        // By name and through {"preset": ...}: the same material.
        let name = CString::new(p.name).unwrap();
        let mut a = std::ptr::null_mut();
        assert_eq!(unsafe { lq_material_from_preset(name.as_ptr(), &mut a) }, LQ_OK);
        let b = material(&format!("{{\"preset\": \"{}\"}}", p.name));
        let (mut ja, mut jb) = (std::ptr::null_mut(), std::ptr::null_mut());
        unsafe {
            assert_eq!(lq_material_to_json(a, &mut ja), LQ_OK);
            assert_eq!(lq_material_to_json(b, &mut jb), LQ_OK);
            lq_material_free(a);
            lq_material_free(b);
        }
        let (ja, jb) = (take_string(ja), take_string(jb));
        assert_eq!(ja, jb);
        assert_eq!(serde_json::from_str::<serde_json::Value>(&ja).unwrap(), entry["material"]);
    }
}

#[test]
fn checks_through_the_abi() {
    let m = material(r#"{"model": "lambert", "albedo": 0.9}"#);
    let mut report = std::ptr::null_mut();
    let mut passed = false;
    let s = unsafe { lq_check_material(m, lq_check_level::LQ_CHECK_QUICK as i32, &mut report, &mut passed) };
    assert_eq!(s, LQ_OK, "{}", last_error());
    let r: serde_json::Value = serde_json::from_str(&take_string(report)).unwrap();
    assert!(passed, "{r}");
    let checks: Vec<&str> = r["verdicts"].as_array().unwrap().iter().map(|v| v["check"].as_str().unwrap()).collect();
    for c in ["reciprocity", "energy", "hard_cases", "precision", "chi2"] {
        assert!(checks.contains(&c), "{c} missing: {checks:?}");
    }
    assert!(r["furnace"]["max_albedo"].as_f64().unwrap() < 0.95);
    unsafe { lq_material_free(m) };

    let mut report = std::ptr::null_mut();
    let mut passed = false;
    let s =
        unsafe { lq_check_model(c"lambert".as_ptr(), lq_check_level::LQ_CHECK_QUICK as i32, &mut report, &mut passed) };
    assert_eq!(s, LQ_OK, "{}", last_error());
    let r: serde_json::Value = serde_json::from_str(&take_string(report)).unwrap();
    assert_eq!(r["model"], "lambert");
    assert_eq!(r["passed"].as_bool(), Some(passed));
    assert!(passed);
}

/// `lq_fit_node_group` returns the contract's JSON: every socket, every error figure, and
/// the same answer as the core.
#[test]
fn fit_node_group_through_the_abi() {
    let mut out = std::ptr::null_mut();
    assert_eq!(unsafe { lq_fit_node_group(c"{\"preset\": \"solid_red\"}".as_ptr(), &mut out) }, LQ_OK);
    let text = unsafe { CStr::from_ptr(out) }.to_str().unwrap().to_string();
    unsafe { lq_string_free(out) };
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let inputs = v["inputs"].as_object().unwrap();
    assert_eq!(inputs.len(), 16);
    for key in ["Pigment Color", "Flake Coverage", "Coat IOR", "Coat Tint", "Sparkle", "Pearl Film Thickness"] {
        assert!(inputs.contains_key(key), "{key}");
    }
    for key in ["albedo_rms", "albedo_max", "brdf_rel_rms", "brdf_cos_rms", "snr_db", "seconds"] {
        assert!(v["error"][key].as_f64().is_some_and(f64::is_finite), "{key}: {text}");
    }
    let core = lacquer_core::fit::node_group::fit_node_group_json("solid_red").unwrap();
    assert_eq!(v["inputs"], serde_json::to_value(&core.inputs).unwrap());
    // The base colour map (for textured base colours): the core's, on its grid.
    assert_eq!(v["base_color_map"], serde_json::to_value(&core.base_color_map).unwrap());
    assert_eq!(v["base_color_map"]["ratio"].as_array().map(Vec::len), Some(9), "{text}");
}

#[test]
fn one_element_functions_match_the_batch_functions() {
    let n = 600;
    let (wi, wo, u) = inputs(n, 21);
    let (wi, wo, u): (Vec<f32>, Vec<f32>, Vec<f32>) = (cast(&wi), cast(&wo), cast(&u));
    for info in models::all() {
        let m = material(&format!("{{\"model\": \"{}\"}}", info.name));
        let lane_kernel = Material::default_of(info).expect("defaults build").model().has_lane_kernel();
        let (mut f, mut p) = (vec![0f32; 3 * n], vec![0f32; n]);
        let (mut swi, mut sw, mut sp, mut fl) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n], vec![0u32; n]);
        unsafe {
            let s = lq_eval_pdf(m, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), p.as_mut_ptr());
            assert_eq!(s, LQ_OK);
            let s = lq_sample_spatial(
                m,
                n,
                wo.as_ptr(),
                u.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                swi.as_mut_ptr(),
                sw.as_mut_ptr(),
                sp.as_mut_ptr(),
                fl.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK);
        }
        for i in 0..n {
            let (a, o, uu) = (&wi[3 * i..3 * i + 3], &wo[3 * i..3 * i + 3], &u[3 * i..3 * i + 3]);
            let (mut f1, mut f2, mut p1, mut p2) = ([0f32; 3], [0f32; 3], 0f32, 0f32);
            let (mut w1, mut g1, mut q1, mut fl1) = ([0f32; 3], [0f32; 3], 0f32, 0u32);
            unsafe {
                assert_eq!(lq_eval_one(m, a.as_ptr(), o.as_ptr(), f1.as_mut_ptr()), LQ_OK);
                assert_eq!(lq_pdf_one(m, a.as_ptr(), o.as_ptr(), &mut p1), LQ_OK);
                assert_eq!(lq_eval_pdf_one(m, a.as_ptr(), o.as_ptr(), f2.as_mut_ptr(), &mut p2), LQ_OK);
                let s = lq_sample_one(m, o.as_ptr(), uu.as_ptr(), w1.as_mut_ptr(), g1.as_mut_ptr(), &mut q1, &mut fl1);
                assert_eq!(s, LQ_OK);
            }
            assert_eq!(bits(&f1), bits(&f2), "{} eval {i}", info.name);
            assert_eq!(p1.to_bits(), p2.to_bits());
            if lane_kernel {
                // The batch runs SIMD lanes, `_one` the scalar f32 path: the same source, so
                // they agree within f32 rounding (2e-5 relative here; measured ≤ 3e-6; the
                // per-element test over hard cases is rust-core/tests/integration/batch.rs).
                let close = |a: f32, b: f32, what: &str| {
                    assert!((a - b).abs() <= 2e-5 * a.abs().max(b.abs()) + 1e-6, "{} {what} {i}: {a} vs {b}", info.name)
                };
                (0..3).for_each(|c| close(f1[c], f[3 * i + c], "eval"));
                close(p1, p[i], "pdf");
                if fl1 == 0 && fl[i] == 0 {
                    (0..3).for_each(|c| close(w1[c], swi[3 * i + c], "sample wi"));
                    // Where the scalar f32 weight is itself more than 2e-5 from the f64
                    // reference (an ill-conditioned sample: coated_paint element 512 leaves the
                    // coat at cos θ 0.0053, next to the critical angle; scalar f32 3.0e-5 and AVX2
                    // 1.2e-4 from f64), the batch must be within the f32 budget of the f64
                    // reference instead (2e-4, as rust-core/tests/integration/batch.rs).
                    let core = Material::default_of(info).expect("defaults build");
                    let o64 = Vec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2]));
                    let s64 = core.sample(o64, [f64::from(uu[0]), f64::from(uu[1]), f64::from(uu[2])]);
                    let w64 = s64.map(|s| s.weight.to_array());
                    for c in 0..3 {
                        let well_conditioned =
                            w64.is_none_or(|w| (f64::from(g1[c]) - w[c]).abs() <= 2e-5 * w[c].abs() + 1e-6);
                        if well_conditioned {
                            close(g1[c], sw[3 * i + c], "sample weight");
                        } else if let Some(w) = w64 {
                            let (b, r) = (f64::from(sw[3 * i + c]), w[c]);
                            assert!(
                                (b - r).abs() <= 2e-4 * r.abs() + 2e-6,
                                "{} sample weight {i}: {b} vs f64 {r}",
                                info.name
                            );
                        }
                    }
                    close(q1, sp[i], "sample pdf");
                }
                continue;
            }
            assert_eq!(bits(&f1), bits(&f[3 * i..3 * i + 3]), "{} eval {i}", info.name);
            assert_eq!((p1.to_bits(), p2.to_bits()), (p[i].to_bits(), p[i].to_bits()));
            assert_eq!(bits(&w1), bits(&swi[3 * i..3 * i + 3]), "{} sample {i}", info.name);
            assert_eq!(bits(&g1), bits(&sw[3 * i..3 * i + 3]));
            assert_eq!((q1.to_bits(), fl1), (sp[i].to_bits(), fl[i]));
        }
        unsafe { lq_material_free(m) };
    }
}

#[test]
fn one_element_functions_work_in_place_and_apply_the_policy() {
    let m = material(r#"{"model": "lambert", "albedo": 0.5}"#);
    let pi = std::f32::consts::PI;
    // In place: the output overwrites the input it was computed from.
    let mut buf = [0f32, 0.6, 0.8];
    let wo = [0f32, 0.0, 1.0];
    let p = buf.as_mut_ptr();
    assert_eq!(unsafe { lq_eval_one(m, p, wo.as_ptr(), p) }, LQ_OK);
    assert!((buf[0] - 0.5 / pi).abs() < 1e-7, "{buf:?}");
    // NaN: zero output and the per-element status.
    let nan = [f32::NAN, 0.0, 1.0];
    let mut f = [7f32; 3];
    assert_eq!(unsafe { lq_eval_one(m, nan.as_ptr(), wo.as_ptr(), f.as_mut_ptr()) }, LQ_ERR_INVALID_DIRECTION);
    assert_eq!(f, [0.0; 3]);
    assert!(last_error().contains("wi = [NaN, 0, 1]"), "{}", last_error());
    // NULL and misaligned: nothing written.
    let mut f = [7f32; 3];
    assert_eq!(unsafe { lq_eval_one(m, std::ptr::null(), wo.as_ptr(), f.as_mut_ptr()) }, LQ_ERR_NULL);
    let raw = [0u8; 32];
    let base = raw.as_ptr() as usize;
    let odd = (base + (4 - base % 4) + 1) as *const f32; // 1 mod 4: not aligned
    assert_eq!(unsafe { lq_eval_one(m, odd, wo.as_ptr(), f.as_mut_ptr()) }, LQ_ERR_INVALID_ARGUMENT);
    assert_eq!(f, [7.0; 3]);
    // Sampling: NaN u, flags optional.
    let (mut w, mut g, mut q, mut fl) = ([7f32; 3], [7f32; 3], 7f32, 0u32);
    let s = unsafe {
        lq_sample_one(m, wo.as_ptr(), [0.5, f32::NAN, 0.5].as_ptr(), w.as_mut_ptr(), g.as_mut_ptr(), &mut q, &mut fl)
    };
    assert_eq!(s, LQ_ERR_INVALID_ELEMENT);
    assert_eq!((w, g, q, fl), ([0.0; 3], [0.0; 3], 0.0, LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT));
    let s = unsafe {
        lq_sample_one(
            m,
            wo.as_ptr(),
            [0.5, 0.3, 0.6].as_ptr(),
            w.as_mut_ptr(),
            g.as_mut_ptr(),
            &mut q,
            std::ptr::null_mut(),
        )
    };
    assert_eq!(s, LQ_OK);
    assert!(q > 0.0 && (g[0] - 0.5).abs() < 1e-6);
    unsafe { lq_material_free(m) };
}

#[test]
fn render_produces_an_image_reports_errors_and_cancels() {
    use crate::render::*;
    use std::ffi::{c_void, CString};
    let job = CString::new(r#"{"preset": "white_lambert", "width": 8, "height": 6, "spp": 2}"#).unwrap();
    let mut img: *mut lq_image = std::ptr::null_mut();
    unsafe extern "C" fn count(_p: f32, user: *mut c_void) -> bool {
        unsafe { *(user as *mut u32) += 1 };
        true
    }
    let mut calls = 0u32;
    unsafe {
        assert_eq!(lq_render(job.as_ptr(), Some(count), (&mut calls as *mut u32).cast(), &mut img), LQ_OK);
        assert!(calls > 0);
        assert_eq!((lq_image_width(img), lq_image_height(img)), (8, 6));
        let px = std::slice::from_raw_parts(lq_image_rgba(img), 8 * 6 * 4);
        assert!(px.iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(!lq_image_albedo(img).is_null());
        // Diffuse/Glossy Color only with "lobe_aovs": a Lambert's diffuse colour is its albedo.
        assert!(lq_image_diffuse_color(img).is_null() && lq_image_glossy_color(img).is_null());
        assert!(lq_image_diffuse_color(std::ptr::null()).is_null());
        lq_image_free(img);
        let lobes = CString::new(
            r#"{"preset": "white_lambert", "width": 4, "height": 4, "spp": 2, "lobe_aovs": true, "floor": false}"#,
        )
        .unwrap();
        assert_eq!(lq_render(lobes.as_ptr(), None, std::ptr::null_mut(), &mut img), LQ_OK);
        let (d, g) = (lq_image_diffuse_color(img), lq_image_glossy_color(img));
        assert!(!d.is_null() && !g.is_null());
        let (d, g) = (std::slice::from_raw_parts(d, 4 * 4 * 3), std::slice::from_raw_parts(g, 4 * 4 * 3));
        assert!(d.iter().any(|v| *v > 0.0) && g.iter().all(|v| *v == 0.0), "{d:?} {g:?}");
        lq_image_free(img);
        lq_image_free(std::ptr::null_mut());
        assert_eq!(lq_image_width(std::ptr::null()), 0);
    }
    unsafe extern "C" fn stop(_p: f32, _user: *mut c_void) -> bool {
        false
    }
    let mut img2: *mut lq_image = std::ptr::null_mut();
    let bad = CString::new(r#"{"preset": "no_such_preset"}"#).unwrap();
    // Progress is polled every 100 ms: a cancellable job must run longer than that.
    let long = CString::new(r#"{"preset": "gold_flake_0", "width": 64, "height": 64, "spp": 4096}"#).unwrap();
    unsafe {
        assert_eq!(lq_render(long.as_ptr(), Some(stop), std::ptr::null_mut(), &mut img2), lq_status::LQ_ERR_CANCELLED);
        assert!(img2.is_null());
        assert_eq!(lq_render(bad.as_ptr(), None, std::ptr::null_mut(), &mut img2), lq_status::LQ_ERR_INVALID_ARGUMENT);
        assert!(img2.is_null());
        assert_eq!(lq_render(std::ptr::null(), None, std::ptr::null_mut(), &mut img2), lq_status::LQ_ERR_NULL);
        assert_eq!(lq_render(job.as_ptr(), None, std::ptr::null_mut(), std::ptr::null_mut()), lq_status::LQ_ERR_NULL);
    }
}

/// A render session refined in rounds ends with `lq_render`'s image bit for bit; the image
/// between rounds is readable; a cancelled round leaves the session as it was; NULLs are refused.
#[test]
fn render_session_rounds_equal_lq_render() {
    use crate::render::*;
    use std::ffi::{c_void, CString};
    let job = CString::new(r#"{"preset": "gold_flake_8", "width": 12, "height": 10, "spp": 5}"#).unwrap();
    let pixels = |img: *mut lq_image| -> Vec<f32> {
        // SAFETY: a live image from the calls below.
        let v = unsafe { std::slice::from_raw_parts(lq_image_rgba(img), 12 * 10 * 4) }.to_vec();
        unsafe { lq_image_free(img) };
        v
    };
    let mut img: *mut lq_image = std::ptr::null_mut();
    let mut s: *mut lq_render_session = std::ptr::null_mut();
    unsafe {
        assert_eq!(lq_render(job.as_ptr(), None, std::ptr::null_mut(), &mut img), LQ_OK);
        let once = pixels(img);
        assert_eq!(lq_render_session_new(job.as_ptr(), &mut s), LQ_OK);
        assert_eq!((lq_render_session_samples(s), lq_render_session_target(s)), (0, 5));
        let mut added = 0u32;
        assert_eq!(lq_render_session_advance(s, 2, None, std::ptr::null_mut(), &mut added), LQ_OK);
        assert_eq!(added, 2);
        assert_eq!(lq_render_session_image(s, &mut img), LQ_OK);
        let partial = pixels(img);
        assert!(partial != once && partial.iter().all(|v| v.is_finite()));
        assert_eq!(lq_render_session_advance(s, 9, None, std::ptr::null_mut(), &mut added), LQ_OK);
        assert_eq!((added, lq_render_session_samples(s)), (3, 5));
        assert_eq!(lq_render_session_image(s, &mut img), LQ_OK);
        assert_eq!(pixels(img), once);
        assert_eq!(lq_render_session_image(s, std::ptr::null_mut()), lq_status::LQ_ERR_NULL);
        lq_render_session_free(s);
        lq_render_session_free(std::ptr::null_mut());
        assert_eq!(lq_render_session_samples(std::ptr::null()), 0);
        assert_eq!(
            lq_render_session_advance(std::ptr::null_mut(), 1, None, std::ptr::null_mut(), &mut added),
            lq_status::LQ_ERR_NULL
        );
        let bad = CString::new(r#"{"preset": "no_such_preset"}"#).unwrap();
        s = std::ptr::null_mut();
        assert_eq!(lq_render_session_new(bad.as_ptr(), &mut s), lq_status::LQ_ERR_INVALID_ARGUMENT);
        assert!(s.is_null());
    }
    unsafe extern "C" fn stop(_p: f32, _user: *mut c_void) -> bool {
        false
    }
    let long = CString::new(r#"{"preset": "gold_flake_0", "width": 64, "height": 64, "spp": 4096}"#).unwrap();
    unsafe {
        assert_eq!(lq_render_session_new(long.as_ptr(), &mut s), LQ_OK);
        let st = lq_render_session_advance(s, 4096, Some(stop), std::ptr::null_mut(), std::ptr::null_mut());
        assert_eq!(st, lq_status::LQ_ERR_CANCELLED);
        assert_eq!(lq_render_session_samples(s), 0);
        lq_render_session_free(s);
    }
}

/// The structure-of-arrays calls give exactly the interleaved calls' values (same kernels),
/// zero outputs for inactive elements, the same statuses for invalid elements, and refuse
/// NULL component arrays; lq_set_thread_count does not change any value.
#[test]
fn soa_calls_match_the_interleaved_calls() {
    let n = 1003;
    let (wi, wo, u) = inputs(n, 31);
    let (wi, wo, u): (Vec<f32>, Vec<f32>, Vec<f32>) = (cast(&wi), cast(&wo), cast(&u));
    let split = |a: &[f32]| -> [Vec<f32>; 3] { [0, 1, 2].map(|c| a.iter().skip(c).step_by(3).copied().collect()) };
    let (wis, wos, us) = (split(&wi), split(&wo), split(&u));
    let active: Vec<u8> = (0..n).map(|i| u8::from(i % 7 != 3)).collect();
    for json in [
        r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2, "material": "Au"}"#,
        r#"{"model": "lambert"}"#,
        r#"{"preset": "gold_flake_8"}"#,
        r#"{"model": "ward"}"#,
    ] {
        let m = material(json);
        let (mut f, mut p) = (vec![0f32; 3 * n], vec![0f32; n]);
        let (mut swi, mut sw, mut sp, mut fl) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n], vec![0u32; n]);
        let mut out = [vec![9f32; n], vec![9f32; n], vec![9f32; n], vec![9f32; n]];
        let mut s_wi = [vec![9f32; n], vec![9f32; n], vec![9f32; n]];
        let mut s_w = [vec![9f32; n], vec![9f32; n], vec![9f32; n]];
        let (mut s_p, mut s_fl) = (vec![9f32; n], vec![9u32; n]);
        unsafe {
            assert_eq!(lq_eval_pdf(m, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), p.as_mut_ptr()), LQ_OK);
            let s = lq_sample_spatial(
                m,
                n,
                wo.as_ptr(),
                u.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                swi.as_mut_ptr(),
                sw.as_mut_ptr(),
                sp.as_mut_ptr(),
                fl.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK);
            lq_set_thread_count(1);
            let [fr, fg, fb, pdf] = &mut out;
            let s = lq_eval_pdf_soa(
                m,
                n,
                wis[0].as_ptr(),
                wis[1].as_ptr(),
                wis[2].as_ptr(),
                wos[0].as_ptr(),
                wos[1].as_ptr(),
                wos[2].as_ptr(),
                active.as_ptr(),
                fr.as_mut_ptr(),
                fg.as_mut_ptr(),
                fb.as_mut_ptr(),
                pdf.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK, "{json}");
            lq_set_thread_count(0);
            let [x, y, z] = &mut s_wi;
            let [r, g, b] = &mut s_w;
            let s = lq_sample_soa(
                m,
                n,
                wos[0].as_ptr(),
                wos[1].as_ptr(),
                wos[2].as_ptr(),
                us[0].as_ptr(),
                us[1].as_ptr(),
                us[2].as_ptr(),
                active.as_ptr(),
                x.as_mut_ptr(),
                y.as_mut_ptr(),
                z.as_mut_ptr(),
                r.as_mut_ptr(),
                g.as_mut_ptr(),
                b.as_mut_ptr(),
                s_p.as_mut_ptr(),
                s_fl.as_mut_ptr(),
            );
            assert_eq!(s, LQ_OK, "{json}");
        }
        for i in 0..n {
            let on = active[i] != 0;
            for c in 0..3 {
                let want = if on { f[3 * i + c] } else { 0.0 };
                assert_eq!(out[c][i].to_bits(), want.to_bits(), "{json} eval {i} {c}");
                let want = if on { swi[3 * i + c] } else { 0.0 };
                assert_eq!(s_wi[c][i].to_bits(), want.to_bits(), "{json} sample wi {i} {c}");
                let want = if on { sw[3 * i + c] } else { 0.0 };
                assert_eq!(s_w[c][i].to_bits(), want.to_bits(), "{json} sample weight {i} {c}");
            }
            assert_eq!(out[3][i].to_bits(), if on { p[i] } else { 0.0 }.to_bits(), "{json} pdf {i}");
            assert_eq!(s_p[i].to_bits(), if on { sp[i] } else { 0.0 }.to_bits(), "{json} sample pdf {i}");
            assert_eq!(s_fl[i], if on { fl[i] } else { 0 }, "{json} flags {i}");
        }
        // An invalid direction in an active element: the status and message of lq_eval.
        let mut bad = wis.clone();
        bad[0][10] = f32::NAN;
        let mut f2 = [vec![0f32; n], vec![0f32; n], vec![0f32; n]];
        let [r, g, b] = &mut f2;
        let s = unsafe {
            lq_eval_soa(
                m,
                n,
                bad[0].as_ptr(),
                bad[1].as_ptr(),
                bad[2].as_ptr(),
                wos[0].as_ptr(),
                wos[1].as_ptr(),
                wos[2].as_ptr(),
                std::ptr::null(),
                r.as_mut_ptr(),
                g.as_mut_ptr(),
                b.as_mut_ptr(),
            )
        };
        assert_eq!(s, LQ_ERR_INVALID_DIRECTION, "{json}");
        let msg = last_error();
        assert!(msg.contains("1 of 1003 elements") && msg.contains("element 10: wi = [NaN"), "{msg}");
        assert_eq!((f2[0][10], f2[1][10], f2[2][10]), (0.0, 0.0, 0.0));
        // A NULL component array is refused before anything is written.
        let s = unsafe {
            lq_pdf_soa(
                m,
                n,
                wis[0].as_ptr(),
                std::ptr::null(),
                wis[2].as_ptr(),
                wos[0].as_ptr(),
                wos[1].as_ptr(),
                wos[2].as_ptr(),
                std::ptr::null(),
                f2[0].as_mut_ptr(),
            )
        };
        assert_eq!(s, LQ_ERR_NULL, "{json}");
        assert!(last_error().contains("wi_y"), "{}", last_error());
        unsafe { lq_material_free(m) };
    }
}

#[test]
fn spectral_calls_reach_the_core_unchanged() {
    // lq_eval_spectral / lq_sample_spectral give exactly Material::eval_spectral /
    // sample_spectral (rounded to f32), with and without a footprint; the direction, pdf and
    // flags of a spectral sample are lq_sample_spatial's; bad wavelengths are per-element
    // errors; the lobe bit says which materials are spectral.
    let n = 64;
    let (wi, wo, u) = inputs(n, 23);
    let (wi, wo, u): (Vec<f32>, Vec<f32>, Vec<f32>) = (cast(&wi), cast(&wo), cast(&u));
    let lambda: Vec<f32> = (0..4 * n).map(|k| 360.0 + ((k * 37) % 470) as f32).collect();
    let uv: Vec<f32> = (0..2 * n).map(|k| (k as f32 * 0.37).fract()).collect();
    let duv: Vec<f32> = (0..4 * n).map(|k| [1e-4, 0.0, 0.0, 1e-4][k % 4]).collect();
    let v3 = |a: &[f32], i: usize| Vec3::new(a[3 * i] as f64, a[3 * i + 1] as f64, a[3 * i + 2] as f64);
    let l4 = |i: usize| [0, 1, 2, 3].map(|c| lambda[4 * i + c] as f64);
    for (json, spectral) in [
        (r#"{"model": "coated_paint", "pearl_density": 20, "flake_density": 3}"#, true),
        (r#"{"model": "htsg"}"#, true),
        (r#"{"model": "lambert", "albedo": [0.2, 0.5, 0.1]}"#, false),
    ] {
        let core = Material::from_json(json).unwrap();
        let m = material(json);
        let mut lobes = 0u32;
        assert_eq!(unsafe { lq_material_lobes(m, &mut lobes) }, LQ_OK);
        assert_eq!(lobes & LQ_LOBE_SPECTRAL != 0, spectral, "{json}");
        for spatial in [false, true] {
            let (uvp, duvp) = if spatial { (uv.as_ptr(), duv.as_ptr()) } else { (std::ptr::null(), std::ptr::null()) };
            let mut f = vec![1f32; 4 * n];
            let s =
                unsafe { lq_eval_spectral(m, n, wi.as_ptr(), wo.as_ptr(), uvp, duvp, lambda.as_ptr(), f.as_mut_ptr()) };
            assert_eq!(s, LQ_OK);
            let (mut swi, mut sw, mut sp, mut sf) =
                (vec![1f32; 3 * n], vec![1f32; 4 * n], vec![1f32; n], vec![9u32; n]);
            let s = unsafe {
                lq_sample_spectral(
                    m,
                    n,
                    wo.as_ptr(),
                    u.as_ptr(),
                    uvp,
                    duvp,
                    lambda.as_ptr(),
                    swi.as_mut_ptr(),
                    sw.as_mut_ptr(),
                    sp.as_mut_ptr(),
                    sf.as_mut_ptr(),
                )
            };
            assert_eq!(s, LQ_OK);
            let (mut rwi, mut rw, mut rp, mut rf) =
                (vec![1f32; 3 * n], vec![1f32; 3 * n], vec![1f32; n], vec![9u32; n]);
            let s = unsafe {
                lq_sample_spatial(
                    m,
                    n,
                    wo.as_ptr(),
                    u.as_ptr(),
                    uvp,
                    duvp,
                    rwi.as_mut_ptr(),
                    rw.as_mut_ptr(),
                    rp.as_mut_ptr(),
                    rf.as_mut_ptr(),
                )
            };
            assert_eq!(s, LQ_OK);
            for i in 0..n {
                let at = spatial.then(|| lacquer_core::SurfacePoint {
                    uv: [uv[2 * i] as f64, uv[2 * i + 1] as f64],
                    duv_dx: [duv[4 * i] as f64, duv[4 * i + 1] as f64],
                    duv_dy: [duv[4 * i + 2] as f64, duv[4 * i + 3] as f64],
                });
                let want = core.eval_spectral(v3(&wi, i), v3(&wo, i), at.as_ref(), l4(i)).map(|x| x as f32);
                assert_eq!(&f[4 * i..4 * i + 4], &want, "{json} eval element {i}");
                let uu = [0, 1, 2].map(|c| u[3 * i + c] as f64);
                match core.sample_spectral(v3(&wo, i), uu, at.as_ref(), l4(i)) {
                    Some((smp, w)) => {
                        assert_eq!(&sw[4 * i..4 * i + 4], &w.map(|x| x as f32), "{json} weight {i}");
                        assert_eq!(sp[i], smp.pdf as f32);
                        assert_eq!(sf[i] & LQ_SAMPLE_DELTA != 0, smp.delta);
                    }
                    None => assert_eq!((sp[i], sf[i] & LQ_SAMPLE_FAILED), (0.0, LQ_SAMPLE_FAILED), "{json} {i}"),
                }
                // Same direction, pdf and flags as the RGB sampler (the f64 core path here,
                // the f32 ABI there: equal within f32 rounding).
                if sf[i] & LQ_SAMPLE_FAILED == 0 && rf[i] & LQ_SAMPLE_FAILED == 0 {
                    assert!(
                        (sp[i] - rp[i]).abs() <= 1e-4 * rp[i].abs().max(1.0),
                        "{json} pdf {i}: {} vs {}",
                        sp[i],
                        rp[i]
                    );
                    assert_eq!(sf[i] & LQ_SAMPLE_DELTA, rf[i] & LQ_SAMPLE_DELTA);
                }
            }
        }
        // A NaN wavelength: that element is zero, the others are evaluated, the status says so.
        let mut bad = lambda.clone();
        bad[5] = f32::NAN;
        let mut f = vec![1f32; 4 * n];
        let s = unsafe {
            lq_eval_spectral(
                m,
                n,
                wi.as_ptr(),
                wo.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                bad.as_ptr(),
                f.as_mut_ptr(),
            )
        };
        assert_eq!(s, LQ_ERR_INVALID_ELEMENT);
        assert_eq!(&f[4..8], &[0.0; 4]);
        assert!(last_error().contains("wavelengths_nm"), "{}", last_error());
        unsafe { lq_material_free(m) };
    }
}
