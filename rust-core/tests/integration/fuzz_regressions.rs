//! Regression tests for what the fuzz targets found (fuzz/, docs/reliability.md).
//!
//! `material_json` found `{"model": "rough_plastic"}` evaluating to NaN in f32 at
//! `wi = wo = (0, −1, 1e-30)`: a direction above the horizon by a cosine whose square and
//! fourth power underflow in f32. A sweep showed the same for every microfacet model at
//! `cos θ ≤ 1e-12` (NaN or ±Inf), through `Material::eval` and the SIMD batch kernels alike.
//! Fixed in the dispatcher: `cos θ ≤ frame::HORIZON_COS = 1e-8` counts as the horizon.

use lacquer::batch::{self, Dst1, Dst3, SampleOut, Src3};
use lacquer::frame::HORIZON_COS;
use lacquer::models;
use lacquer::{Material, Vec3};

/// Grazing cosines from ordinary to denormal, on both sides of `HORIZON_COS`.
const ZS: [f64; 14] = [0.3, 1e-3, 1e-5, 1e-7, 2e-8, 1e-8, 1e-9, 1e-12, 1e-15, 1e-20, 1e-30, 1e-38, 1e-40, 1e-44];

/// Direction pairs with one or both directions grazing: wi = wo, wi = mirror of wo, one normal.
fn pairs() -> Vec<([f64; 3], [f64; 3])> {
    let mut out = Vec::new();
    for &z in &ZS {
        for (a, b) in [
            ([0.0, -1.0, z], [0.0, -1.0, z]),
            ([0.0, -1.0, z], [0.0, 1.0, z]),
            ([1.0, 0.0, z], [0.0, 0.0, 1.0]),
            ([0.0, 0.0, 1.0], [1.0, 0.0, z]),
            ([0.7, -0.7, z], [0.3, 0.2, 0.9]),
            ([0.6, 0.8, z], [0.6, 0.8, z]),
        ] {
            out.push((a, b));
        }
    }
    out
}

fn materials() -> Vec<(String, Material)> {
    let mut out: Vec<(String, Material)> = models::all()
        .iter()
        .map(|i| (i.name.to_string(), Material::from_json(&format!("{{\"model\": \"{}\"}}", i.name)).unwrap()))
        .collect();
    for j in [
        r#"{"model": "rough_conductor", "alpha_u": 0.001, "alpha_v": 0.001}"#,
        r#"{"model": "rough_conductor", "alpha_u": 0.001, "alpha_v": 1.0}"#,
        r#"{"model": "rough_plastic", "alpha": 0.001}"#,
        r#"{"preset": "gold_flake_8"}"#,
    ] {
        out.push((j.to_string(), Material::from_json(j).unwrap()));
    }
    out
}

fn v(a: [f64; 3]) -> Vec3<f64> {
    Vec3::new(a[0], a[1], a[2])
}

#[test]
fn the_fuzz_crash_input_is_finite() {
    // fuzz/artifacts: material_json crash input `{"model": "rough_plastic"}` at these directions.
    let m = Material::from_json(r#"{"model": "rough_plastic"}"#).unwrap();
    let w = Vec3::new(0.0f32, -1.0, 1e-30);
    let (f, p) = (m.eval(w, w), m.pdf(w, w));
    assert!(f.r.is_finite() && f.g.is_finite() && f.b.is_finite() && p.is_finite(), "{f:?} {p}");
    assert_eq!((f.r, p), (0.0, 0.0), "1e-30 is below HORIZON_COS = {HORIZON_COS}: the horizon");
}

#[test]
fn grazing_directions_never_give_nan_or_inf_in_f32_or_f64() {
    let mut bad = Vec::new();
    let mut nonzero_at_1e_7 = 0;
    for (name, m) in materials() {
        for (a, b) in pairs() {
            let f64v = m.eval(v(a), v(b));
            let p64 = m.pdf(v(a), v(b));
            let f32v = m.eval(v(a).cast::<f32>(), v(b).cast::<f32>());
            let p32 = m.pdf(v(a).cast::<f32>(), v(b).cast::<f32>());
            let all = [f64v.r, f64v.g, f64v.b, p64, f32v.r as f64, f32v.g as f64, f32v.b as f64, p32 as f64];
            if all.iter().any(|x| !x.is_finite() || *x < 0.0) {
                bad.push(format!("{name} {a:?} {b:?}: {all:?}"));
            }
            if a[2] == 1e-7 && f64v.r > 0.0 {
                nonzero_at_1e_7 += 1;
            }
            for u in [[0.1, 0.5, 0.5], [0.9, 0.999, 0.01]] {
                for w in [a, b] {
                    if let Some(s) = m.sample(v(w).cast::<f32>(), u.map(|x| x as f32)) {
                        if !(s.weight.is_finite() && s.pdf.is_finite() && s.wi.z as f64 > HORIZON_COS || s.delta) {
                            bad.push(format!("{name} sample {w:?} {u:?}: {s:?}"));
                        }
                    }
                }
            }
        }
    }
    assert!(bad.is_empty(), "{} non-finite or negative results:\n{}", bad.len(), bad[..bad.len().min(20)].join("\n"));
    // Grazing at cos θ = 1e-7 is still above the horizon and evaluated (not zeroed).
    assert!(nonzero_at_1e_7 > 20, "{nonzero_at_1e_7} non-zero values at cos θ = 1e-7");
}

#[test]
fn grazing_directions_never_give_nan_or_inf_through_the_simd_kernels() {
    let ps = pairs();
    let n = ps.len();
    let wi: Vec<f32> = ps.iter().flat_map(|(a, _)| a.map(|x| x as f32)).collect();
    let wo: Vec<f32> = ps.iter().flat_map(|(_, b)| b.map(|x| x as f32)).collect();
    let u: Vec<f32> = (0..3 * n).map(|k| ((k * 7919) % 1000) as f32 / 1000.0).collect();
    for (name, m) in materials() {
        let (mut f, mut pdf) = (vec![0f32; 3 * n], vec![0f32; n]);
        batch::eval_pdf(
            &m,
            &Src3::interleaved(&wi),
            &Src3::interleaved(&wo),
            None,
            Some(&Dst3::interleaved(&mut f)),
            Some(&Dst1::new(&mut pdf)),
        )
        .unwrap();
        assert!(f.iter().chain(&pdf).all(|x| x.is_finite() && *x >= 0.0), "{name}: eval/pdf {f:?} {pdf:?}");
        let (mut swi, mut sw, mut sp, mut flags) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n], vec![0u32; n]);
        let mut out = SampleOut {
            wi: Dst3::interleaved(&mut swi),
            weight: Dst3::interleaved(&mut sw),
            pdf: Dst1::new(&mut sp),
            flags: Some(&mut flags),
        };
        batch::sample(&m, &Src3::interleaved(&wo), &Src3::interleaved(&u), None, &mut out).unwrap();
        assert!(swi.iter().chain(&sw).chain(&sp).all(|x| x.is_finite()), "{name}: sample");
    }
}
