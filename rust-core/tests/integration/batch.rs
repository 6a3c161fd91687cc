//! The batch kernels agree per element with the scalar paths: SIMD lanes (every level this CPU
//! has), scalar f32 and the f64 reference, on random and hard-case directions, with masked-off
//! lanes, non-unit and invalid inputs, and lengths that are not a multiple of the lane count.

use crate::GLOBAL;
use lacquer::batch::{self, Dst1, Dst3, SampleOut, SimdLevel, Src3};
use lacquer::rng::Pcg32;
use lacquer::{Material, Vec3};

/// Materials covering every lane model and its branches (and one scalar-only model).
const MATERIALS: &[&str] = &[
    r#"{"model": "lambert", "albedo": [0.9, 0.5, 0.1]}"#,
    r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2, "material": "Au"}"#,
    r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.05, "alpha_v": 0.6, "masking": "smith_height_correlated"}"#,
    r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.001, "alpha_v": 0.001, "material": "Cu"}"#,
    r#"{"model": "rough_conductor", "alpha_u": 0.3, "alpha_v": 0.3, "material": "Ag"}"#,
    r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.4, "alpha_v": 0.4, "multiple_scattering": true, "material": "Al"}"#,
    r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.3, "alpha_v": 0.3, "sample_visible": false}"#,
    r#"{"model": "principled", "base_color": [0.8, 0.3, 0.2], "roughness": 0.5, "metallic": 0.5}"#,
    r#"{"model": "principled", "roughness": 0.45, "metallic": 0.3, "base_color": [0.1, 0.2, 0.6], "thin_film_thickness": 350, "thin_film_ior": 1.6, "coat_weight": 0.5, "coat_roughness": 0.5, "coat_tint": [0.8, 0.9, 1.0]}"#,
    r#"{"model": "principled", "roughness": 0, "metallic": 0.5, "base_color": [0.8, 0.2, 0.1], "coat_weight": 1, "coat_roughness": 0.2}"#,
    r#"{"model": "principled", "metallic": 1, "roughness": 0.3, "base_color": [0.95, 0.64, 0.54], "specular_tint": [0.9, 0.1, 0.0], "coat_weight": 1, "coat_roughness": 0, "coat_ior": 1.8, "coat_tint": [0.0, 0.5, 1.0]}"#,
    r#"{"model": "ward", "alpha_x": 0.2, "alpha_y": 0.3}"#,
    r#"{"model": "rough_plastic", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.5, "ext_ior": 1.0, "diffuse_reflectance": [0.2, 0.4, 0.7]}"#,
    r#"{"model": "rough_plastic", "alpha": 0.3, "diffuse_reflectance": [0.9, 0.3, 0.05], "nonlinear": true}"#,
    r#"{"model": "rough_plastic", "distribution": "ggx", "alpha": 0.05, "int_ior": 1.0, "ext_ior": 1.5, "sample_visible": false}"#,
    r#"{"model": "cook_torrance"}"#,
    r#"{"model": "cook_torrance", "kd": 0.3, "ks": 0.7, "alpha": 0.2, "masking": "smith_separable", "eta": [0.2, 0.4, 1.4], "k": [3.9, 2.4, 1.6]}"#,
    r#"{"model": "cook_torrance", "kd": 0.0, "ks": 1.0, "alpha": 0.5, "distribution": "beckmann", "masking": "vgroove", "eta": 0.2, "k": 5.0, "multiple_scattering": true}"#,
    r#"{"model": "coated_paint", "flake_density": 8, "flake_material": "Au", "base_color": [0.4, 0.25, 0.05]}"#,
    r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 8, "coat_absorption": [2, 4, 8]}"#,
    r#"{"model": "coated_paint", "coat_roughness": 0.15, "flake_density": 5, "pearl_density": 10, "pearl_film_nm": 300, "base_metallic": 0.5}"#,
    r#"{"model": "coated_paint", "flake_density": 0, "coat_roughness": 0, "base_color": 1.0}"#,
    r#"{"model": "coated_paint", "pigment_model": "eon", "pigment_roughness": 1, "coat_roughness": 0.1, "flake_density": 3, "pearl_density": 5, "base_color": [0.9, 0.5, 0.2]}"#,
];

/// Random directions (both hemispheres, not unit), hard cases (grazing to 1e-7, normal, wi = ±wo,
/// exactly opposite), and invalid ones (NaN, ∞, zero) mixed in.
fn directions(n: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut rng = Pcg32::new(seed, 3);
    let mut wi = Vec::with_capacity(n);
    let mut wo = Vec::with_capacity(n);
    let hard: [[f32; 3]; 6] =
        [[0.0, 0.0, 1.0], [1.0, 0.0, 1e-7], [0.6, 0.8, 1e-4], [0.0, 1.0, 0.0], [0.3, -0.2, 0.9], [-1.0, 0.0, 1e-6]];
    for k in 0..n {
        let mut r = || (rng.uniform() as f32) * 2.0 - 1.0;
        let (a, b) = match k % 11 {
            0 => (hard[k % 6], hard[(k / 6) % 6]),
            1 => {
                let a = [r(), r(), r().abs()];
                (a, a)
            }
            2 => {
                let a = [r(), r(), r().abs()];
                (a, [-a[0], -a[1], a[2]])
            }
            3 if k % 3 == 0 => ([f32::NAN, 0.0, 1.0], [0.0, 0.0, 1.0]),
            3 if k % 3 == 1 => ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            3 => ([0.0, 0.0, 1.0], [f32::INFINITY, 0.0, 1.0]),
            _ => ([r(), r(), r()], [r() * 3.0, r() * 3.0, r() * 3.0]),
        };
        wi.push(a);
        wo.push(b);
    }
    (wi, wo)
}

fn soa(v: &[[f32; 3]]) -> [Vec<f32>; 3] {
    [v.iter().map(|a| a[0]).collect(), v.iter().map(|a| a[1]).collect(), v.iter().map(|a| a[2]).collect()]
}

/// Relative difference with an absolute floor for values near zero.
fn close(a: f64, b: f64, rel: f64, floor: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + floor
}

/// Every level's eval/pdf equals the scalar `Material` f32 path per element (f32 rounding of a
/// different operation order: ≤ 2e-5 relative measured 3e-6 on these sets), and stays within
/// the f32-vs-f64 budget of the f64 reference (`lacquer check` reports 2.5e-5 for
/// rough_conductor; 1e-4 relative + 1e-6 absolute here). Inactive and tail lanes are zero.
/// With an active mask the general loop runs; without one the full-group loop of plain calls
/// (then the general loop for the tail).
#[test]
fn eval_and_pdf_agree_with_scalar_and_reference() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    // 1037 elements: not a multiple of 8 or 16.
    let n = 1037;
    let (wi, wo) = directions(n, 7);
    let (wi_s, wo_s) = (soa(&wi), soa(&wo));
    let mask: Vec<u8> = (0..n).map(|i| u8::from(i % 13 != 5)).collect();
    for (json, masked) in MATERIALS.iter().flat_map(|j| [(j, true), (j, false)]) {
        let m = Material::from_json(json).unwrap();
        let active = if masked { mask.clone() } else { vec![1; n] };
        let active_arg = masked.then_some(&active[..]);
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            let mut f = [vec![7.0f32; n], vec![7.0f32; n], vec![7.0f32; n]];
            let mut pdf = vec![7.0f32; n];
            let [fr, fg, fb] = &mut f;
            let report = {
                let fv = Dst3::soa(fr, fg, fb).unwrap();
                let pv = Dst1::new(&mut pdf);
                let wiv = Src3::soa(&wi_s[0], &wi_s[1], &wi_s[2]).unwrap();
                let wov = Src3::soa(&wo_s[0], &wo_s[1], &wo_s[2]).unwrap();
                batch::eval_pdf(&m, &wiv, &wov, active_arg, Some(&fv), Some(&pv)).unwrap()
            };
            let mut invalid = 0;
            for i in 0..n {
                let a = Vec3::new(wi[i][0], wi[i][1], wi[i][2]);
                let b = Vec3::new(wo[i][0], wo[i][1], wo[i][2]);
                let got = [f[0][i], f[1][i], f[2][i]];
                let usable = |w: Vec3<f32>| w.length_squared() > 0.0 && w.length_squared().is_finite();
                let bad = !(usable(a) && usable(b));
                if active[i] == 0 || bad {
                    invalid += usize::from(active[i] != 0);
                    assert_eq!(
                        (got, pdf[i]),
                        ([0.0; 3], 0.0),
                        "{json} {level:?} masked {masked} element {i} (inactive or invalid)"
                    );
                    continue;
                }
                let want32 = m.eval(a, b).to_array();
                let want64 = m.eval(a.cast::<f64>(), b.cast::<f64>()).to_array();
                for c in 0..3 {
                    assert!(
                        close(got[c] as f64, want32[c] as f64, 2e-5, 1e-7),
                        "{json} {level:?} element {i} channel {c}: {} vs scalar f32 {} (wi {a:?}, wo {b:?})",
                        got[c],
                        want32[c]
                    );
                    // Where the scalar f32 path itself is within the f32 budget of the f64
                    // reference (well-conditioned pairs), the batch must be too.
                    if close(want32[c] as f64, want64[c], 1e-4, 1e-6) {
                        assert!(
                            close(got[c] as f64, want64[c], 2e-4, 2e-6),
                            "{json} {level:?} element {i} channel {c}: {} vs f64 {}",
                            got[c],
                            want64[c]
                        );
                    }
                }
                let p32 = m.pdf(a, b) as f64;
                let p64 = m.pdf(a.cast::<f64>(), b.cast::<f64>());
                assert!(close(pdf[i] as f64, p32, 2e-5, 1e-7), "{json} {level:?} pdf {i}: {} vs {p32}", pdf[i]);
                if close(p32, p64, 1e-4, 1e-6) {
                    assert!(close(pdf[i] as f64, p64, 2e-4, 2e-6), "{json} {level:?} pdf {i}: {} vs f64 {p64}", pdf[i]);
                }
            }
            assert_eq!(report.invalid_directions, invalid, "{json} {level:?} masked {masked}");
        }
    }
}

/// Sampling: each level draws the same direction, weight and pdf as the scalar f32 sampler for
/// the same `u` (≤ 1e-4 relative: the polynomial sin/cos differ from libm by ≤ 2e-7), and the
/// same elements fail. Interleaved layout and a length of 1001, no active mask (the
/// full-group loop, then the general loop for the tail); some `u` are non-finite, and the
/// report counts the invalid directions and `u` as the inputs say.
#[test]
fn sample_agrees_with_scalar() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = 1001;
    let (_, wo) = directions(n, 11);
    let mut rng = Pcg32::new(5, 5);
    let mut u: Vec<f32> = (0..3 * n).map(|_| rng.uniform() as f32).collect();
    for i in (7..n).step_by(19) {
        u[3 * i + i % 3] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][i % 3];
    }
    let u_ok = |i: usize| u[3 * i..3 * i + 3].iter().all(|x| x.is_finite());
    let usable = |w: &[f32; 3]| {
        let l2 = Vec3::new(w[0], w[1], w[2]).length_squared();
        l2 > 0.0 && l2.is_finite()
    };
    let want_bad_dirs = wo.iter().filter(|w| !usable(w)).count();
    let want_bad_u = (0..n).filter(|&i| usable(&wo[i]) && !u_ok(i)).count();
    assert!(want_bad_dirs > 0 && want_bad_u > 0);
    let wo_flat: Vec<f32> = wo.iter().flatten().copied().collect();
    for json in MATERIALS {
        let m = Material::from_json(json).unwrap();
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            let (mut wi, mut weight, mut pdf, mut flags) =
                (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; n], vec![0u32; n]);
            {
                let mut out = SampleOut {
                    wi: Dst3::interleaved(&mut wi),
                    weight: Dst3::interleaved(&mut weight),
                    pdf: Dst1::new(&mut pdf),
                    flags: Some(&mut flags),
                };
                let report =
                    batch::sample(&m, &Src3::interleaved(&wo_flat), &Src3::interleaved(&u), None, &mut out).unwrap();
                // A lane with an invalid direction counts as that alone (`BatchReport::record`).
                assert_eq!(
                    (report.invalid_directions, report.invalid_u),
                    (want_bad_dirs, want_bad_u),
                    "{json} {level:?}"
                );
            }
            let mut compared = 0;
            for i in 0..n {
                let o = Vec3::new(wo[i][0], wo[i][1], wo[i][2]);
                if !usable(&wo[i]) || !u_ok(i) {
                    assert_eq!(flags[i], batch::SAMPLE_FAILED | batch::SAMPLE_INVALID_INPUT, "{json} {i}");
                    assert_eq!((pdf[i], &weight[3 * i..3 * i + 3]), (0.0, &[0.0f32; 3][..]), "{json} {i}");
                    continue;
                }
                let want = m.sample(o, [u[3 * i], u[3 * i + 1], u[3 * i + 2]]);
                match want {
                    None => assert_eq!(
                        flags[i] & batch::SAMPLE_FAILED,
                        batch::SAMPLE_FAILED,
                        "{json} {level:?} {i}: scalar failed, batch did not"
                    ),
                    Some(s) => {
                        // A sample right at the horizon may fail on one side of the rounding only.
                        if flags[i] & batch::SAMPLE_FAILED != 0 {
                            assert!(s.wi.z < 1e-3, "{json} {level:?} {i}: batch failed, scalar gave {s:?}");
                            continue;
                        }
                        compared += 1;
                        let got_wi = [wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]];
                        for c in 0..3 {
                            assert!(
                                close(got_wi[c] as f64, s.wi.to_array_f64()[c], 1e-4, 1e-5),
                                "{json} {level:?} {i} wi: {got_wi:?} vs {:?}",
                                s.wi
                            );
                            assert!(
                                close(weight[3 * i + c] as f64, s.weight[c] as f64, 1e-3, 1e-5),
                                "{json} {level:?} {i} weight {c}: {} vs {}",
                                weight[3 * i + c],
                                s.weight[c]
                            );
                        }
                        assert!(
                            close(pdf[i] as f64, s.pdf as f64, 1e-3, 1e-5),
                            "{json} {level:?} {i} pdf: {} vs {}",
                            pdf[i],
                            s.pdf
                        );
                    }
                }
            }
            assert!(compared > n / 3, "{json} {level:?}: only {compared} samples compared");
        }
    }
}

trait ToArrayF64 {
    fn to_array_f64(self) -> [f64; 3];
}
impl ToArrayF64 for Vec3<f32> {
    fn to_array_f64(self) -> [f64; 3] {
        [self.x as f64, self.y as f64, self.z as f64]
    }
}

/// A model whose value and density share work (the coated paint: refractions, half vectors,
/// table values, the coat's azimuthal factor) gives in one `eval_pdf` call exactly what the
/// value-only and density-only calls give, bit for bit, at every SIMD level and in f64.
#[test]
fn joint_eval_pdf_equals_the_separate_calls() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = 1037;
    let (wi, wo) = directions(n, 17);
    let (wi_f, wo_f): (Vec<f32>, Vec<f32>) =
        (wi.iter().flatten().copied().collect(), wo.iter().flatten().copied().collect());
    let (wi_d, wo_d): (Vec<f64>, Vec<f64>) =
        (wi_f.iter().map(|&x| f64::from(x)).collect(), wo_f.iter().map(|&x| f64::from(x)).collect());
    let active: Vec<u8> = (0..n).map(|i| u8::from(i % 13 != 5)).collect();
    let mut names: Vec<&str> = MATERIALS.iter().copied().filter(|j| j.contains("coated_paint")).collect();
    names.push(r#"{"preset": "gold_flake_8"}"#);
    names.push(r#"{"model": "coated_paint", "coat_roughness": 0.2, "base_metallic": 1, "base_roughness": 0.05, "flake_density": 0}"#);
    for name in names {
        let m = &Material::from_json(name).unwrap();
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            // With the mask: the general loop; without: the full-group loop of plain calls.
            for active in [Some(&active[..]), None] {
                let (wiv, wov) = (Src3::interleaved(&wi_f), Src3::interleaved(&wo_f));
                let (mut f_joint, mut p_joint) = (vec![7.0f32; 3 * n], vec![7.0f32; n]);
                let (mut f_alone, mut p_alone) = (vec![7.0f32; 3 * n], vec![7.0f32; n]);
                let joint = (Some(&Dst3::interleaved(&mut f_joint)), Some(&Dst1::new(&mut p_joint)));
                batch::eval_pdf(m, &wiv, &wov, active, joint.0, joint.1).unwrap();
                batch::eval_pdf(m, &wiv, &wov, active, Some(&Dst3::interleaved(&mut f_alone)), None).unwrap();
                batch::eval_pdf(m, &wiv, &wov, active, None, Some(&Dst1::new(&mut p_alone))).unwrap();
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                let masked = active.is_some();
                assert_eq!(bits(&f_joint), bits(&f_alone), "{name} {level:?} masked {masked}: value");
                assert_eq!(bits(&p_joint), bits(&p_alone), "{name} {level:?} masked {masked}: density");
                assert!(p_joint.iter().any(|&p| p > 0.0), "{name} {level:?}: some density");
            }
        }
        let (wiv, wov) = (Src3::interleaved(&wi_d), Src3::interleaved(&wo_d));
        let (mut f_joint, mut p_joint) = (vec![7.0f64; 3 * n], vec![7.0f64; n]);
        let (mut f_alone, mut p_alone) = (vec![7.0f64; 3 * n], vec![7.0f64; n]);
        let joint = (Some(&Dst3::interleaved(&mut f_joint)), Some(&Dst1::new(&mut p_joint)));
        batch::eval_pdf_f64(m, &wiv, &wov, Some(&active), joint.0, joint.1).unwrap();
        batch::eval_pdf_f64(m, &wiv, &wov, Some(&active), Some(&Dst3::interleaved(&mut f_alone)), None).unwrap();
        batch::eval_pdf_f64(m, &wiv, &wov, Some(&active), None, Some(&Dst1::new(&mut p_alone))).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&f_joint), bits(&f_alone), "{name} f64: value");
        assert_eq!(bits(&p_joint), bits(&p_alone), "{name} f64: density");
    }
    assert!(batch::set_simd_level(SimdLevel::detect()));
}

/// A lobe mask of every selectable lobe gives exactly the plain call's values and densities,
/// bit for bit, for every material and SIMD level, with and without an active mask: the batch
/// kernels evaluate the lobe-masked and the sparkle-scaled calls through one model call
/// (`LaneKernel::eval_lobes` with `bits::SELECTABLE` standing for "every lobe") and rely on
/// this identity.
#[test]
fn a_mask_of_every_lobe_is_the_plain_call() {
    use lacquer::lobes::{bits, LobeSelection};
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = 1037;
    let (wi, wo) = directions(n, 23);
    let (wi_f, wo_f): (Vec<f32>, Vec<f32>) =
        (wi.iter().flatten().copied().collect(), wo.iter().flatten().copied().collect());
    let active: Vec<u8> = (0..n).map(|i| u8::from(i % 13 != 5)).collect();
    let bits_of = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for name in MATERIALS.iter().copied().chain([r#"{"preset": "gold_flake_8"}"#]) {
        let m = &Material::from_json(name).unwrap();
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            for active in [Some(&active[..]), None] {
                let (wiv, wov) = (Src3::interleaved(&wi_f), Src3::interleaved(&wo_f));
                let every = LobeSelection::Some(bits::SELECTABLE);
                let (mut f_plain, mut p_plain) = (vec![7.0f32; 3 * n], vec![7.0f32; n]);
                let (mut f_mask, mut p_mask) = (vec![7.0f32; 3 * n], vec![7.0f32; n]);
                batch::eval_pdf(m, &wiv, &wov, active, Some(&Dst3::interleaved(&mut f_plain)), None).unwrap();
                batch::eval_pdf(m, &wiv, &wov, active, None, Some(&Dst1::new(&mut p_plain))).unwrap();
                let f_view = Dst3::interleaved(&mut f_mask);
                batch::eval_pdf_lobes(m, every, &wiv, &wov, active, Some(&f_view), None).unwrap();
                batch::eval_pdf_lobes(m, every, &wiv, &wov, active, None, Some(&Dst1::new(&mut p_mask))).unwrap();
                let masked = active.is_some();
                assert_eq!(bits_of(&f_plain), bits_of(&f_mask), "{name} {level:?} masked {masked}: value");
                assert_eq!(bits_of(&p_plain), bits_of(&p_mask), "{name} {level:?} masked {masked}: density");
                assert!(f_plain.iter().any(|&f| f > 0.0), "{name} {level:?}: some value");
            }
        }
    }
    assert!(batch::set_simd_level(SimdLevel::detect()));
}

/// Results do not depend on the thread count (bit-identical), for a batch large enough to run
/// in parallel.
#[test]
fn threads_give_identical_results() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = batch::PARALLEL_MIN * 3 + 5;
    let (wi, wo) = directions(n, 13);
    let (wi_f, wo_f): (Vec<f32>, Vec<f32>) =
        (wi.iter().flatten().copied().collect(), wo.iter().flatten().copied().collect());
    let m = Material::from_json(MATERIALS[1]).unwrap();
    let run = |threads: usize| {
        batch::set_thread_count(threads);
        let mut f = vec![0.0f32; 3 * n];
        batch::eval_pdf(
            &m,
            &Src3::interleaved(&wi_f),
            &Src3::interleaved(&wo_f),
            None,
            Some(&Dst3::interleaved(&mut f)),
            None,
        )
        .unwrap();
        f
    };
    let one = run(1);
    let two = run(2);
    batch::set_thread_count(0);
    assert!(one.iter().zip(&two).all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// The batch calls at surface points (`eval_pdf_at`, `sample_at`: sparkle) equal the scalar
/// f32 `Material::eval_at` / `sample_at` per element, on every level: footprints from a few
/// flakes to thousands (uv derivatives 1e-5…1e-2 at 100 mm per uv unit), some non-finite
/// (the mean BRDF), masked-off elements and a length of 1003. The flake multipliers are the
/// same scalar code in both, so the tolerances are those of the mean-BRDF tests above
/// (measured ≤ 3e-6 for eval; sampling within 1e-3 as in `sample_agrees_with_scalar`); a
/// pair whose half vector sits on a direction-cell border could pick a different cell, which
/// these fixed inputs do not hit (counted: every element compared).
#[test]
fn surface_point_calls_agree_with_eval_at_and_sample_at() {
    use lacquer::SurfacePoint;
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = 1003;
    let (wi, wo) = directions(n, 23);
    let (wi_s, wo_s) = (soa(&wi), soa(&wo));
    let mut rng = Pcg32::new(9, 9);
    let at: Vec<SurfacePoint> = (0..n)
        .map(|i| {
            let scale = 10f64.powf(rng.range(-5.0, -2.0));
            let uv = [rng.range(0.0, 10.0), rng.range(0.0, 10.0)];
            let (a, b) = (rng.range(0.5, 1.5), rng.range(-0.3, 0.3));
            let nan = if i % 17 == 3 { f64::NAN } else { 0.0 };
            SurfacePoint { uv: [uv[0] + nan, uv[1]], duv_dx: [a * scale, b * scale], duv_dy: [-b * scale, a * scale] }
        })
        .collect();
    let active: Vec<u8> = (0..n).map(|i| u8::from(i % 13 != 5)).collect();
    let mut u_rng = Pcg32::new(4, 4);
    let u: Vec<f32> = (0..3 * n).map(|_| u_rng.uniform() as f32).collect();
    let u_s = [0, 1, 2].map(|c| (0..n).map(|i| u[3 * i + c]).collect::<Vec<f32>>());
    for name in ["gold_flake_8", "pearl_white"] {
        let m = Material::from_json(lacquer::presets::find(name).unwrap().json).unwrap();
        assert!(m.spatially_varying(), "{name} has sparkle");
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            let mut f = [vec![7.0f32; n], vec![7.0f32; n], vec![7.0f32; n]];
            let mut pdf = vec![7.0f32; n];
            {
                let [fr, fg, fb] = &mut f;
                let fv = Dst3::soa(fr, fg, fb).unwrap();
                let pv = Dst1::new(&mut pdf);
                let wiv = Src3::soa(&wi_s[0], &wi_s[1], &wi_s[2]).unwrap();
                let wov = Src3::soa(&wo_s[0], &wo_s[1], &wo_s[2]).unwrap();
                batch::eval_pdf_at(&m, &wiv, &wov, &at, Some(&active), Some(&fv), Some(&pv)).unwrap();
            }
            let (mut swi, mut sweight, mut spdf, mut flags) =
                (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; n], vec![0u32; n]);
            {
                let mut out = SampleOut {
                    wi: Dst3::interleaved(&mut swi),
                    weight: Dst3::interleaved(&mut sweight),
                    pdf: Dst1::new(&mut spdf),
                    flags: Some(&mut flags),
                };
                let wov = Src3::soa(&wo_s[0], &wo_s[1], &wo_s[2]).unwrap();
                let uv = Src3::soa(&u_s[0], &u_s[1], &u_s[2]).unwrap();
                batch::sample_at(&m, &wov, &uv, &at, Some(&active), &mut out).unwrap();
            }
            let (mut varied, mut sampled) = (0, 0);
            for i in 0..n {
                let a = Vec3::new(wi[i][0], wi[i][1], wi[i][2]);
                let b = Vec3::new(wo[i][0], wo[i][1], wo[i][2]);
                let usable = |w: Vec3<f32>| w.length_squared() > 0.0 && w.length_squared().is_finite();
                if active[i] == 0 || !(usable(a) && usable(b)) {
                    assert_eq!([f[0][i], f[1][i], f[2][i], pdf[i]], [0.0; 4], "{name} {level:?} {i}");
                    if active[i] == 0 {
                        assert_eq!(flags[i], 0, "{name} {level:?} {i}: inactive");
                    }
                    continue;
                }
                let want = m.eval_at(a, b, &at[i]).to_array();
                let mean = m.eval(a, b).to_array();
                varied += usize::from((0..3).any(|c| !close(want[c] as f64, mean[c] as f64, 1e-3, 1e-6)));
                for c in 0..3 {
                    assert!(
                        close(f[c][i] as f64, want[c] as f64, 2e-5, 1e-7),
                        "{name} {level:?} {i} channel {c}: {} vs eval_at {} (mean {})",
                        f[c][i],
                        want[c],
                        mean[c]
                    );
                }
                assert!(close(pdf[i] as f64, m.pdf(a, b) as f64, 2e-5, 1e-7), "{name} {level:?} pdf {i}");
                match m.sample_at(b, [u[3 * i], u[3 * i + 1], u[3 * i + 2]], &at[i]) {
                    None => assert_ne!(flags[i] & batch::SAMPLE_FAILED, 0, "{name} {level:?} {i}: scalar failed"),
                    Some(s) if flags[i] & batch::SAMPLE_FAILED != 0 => {
                        assert!(s.wi.z < 1e-3, "{name} {level:?} {i}: batch failed, scalar gave {s:?}")
                    }
                    Some(s) => {
                        sampled += 1;
                        assert_eq!(flags[i] & batch::SAMPLE_DELTA != 0, s.delta, "{name} {level:?} {i}");
                        for c in 0..3 {
                            assert!(
                                close(sweight[3 * i + c] as f64, s.weight[c] as f64, 1e-3, 1e-5),
                                "{name} {level:?} {i} weight {c}: {} vs sample_at {}",
                                sweight[3 * i + c],
                                s.weight[c]
                            );
                        }
                        assert!(close(spdf[i] as f64, s.pdf as f64, 1e-3, 1e-5), "{name} {level:?} {i} pdf");
                    }
                }
            }
            // The footprints make a difference for many pairs (else this tests the mean BRDF).
            assert!(varied > n / 10, "{name} {level:?}: only {varied} elements vary with the footprint");
            assert!(sampled > n / 3, "{name} {level:?}: only {sampled} samples compared");
        }
    }
}

/// One layout of `n` 3-vectors: the backing array and how to view it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    /// One array per component (three arrays of `n`).
    Soa,
    /// Interleaved `x y z` (the contiguous-load path of the SIMD kernels).
    Xyz,
    /// `x y z w` with a padding value (stride 4: the general strided path).
    Xyzw,
}

impl Layout {
    /// Lays `v` out (padding and guard values NaN) and returns the flat array.
    fn pack(self, v: &[[f32; 3]]) -> Vec<f32> {
        match self {
            Layout::Soa => (0..3).flat_map(|c| v.iter().map(move |a| a[c])).collect(),
            Layout::Xyz => v.iter().flatten().copied().chain([f32::NAN]).collect(),
            Layout::Xyzw => v.iter().flat_map(|a| [a[0], a[1], a[2], f32::NAN]).collect(),
        }
    }
    fn src(self, a: &[f32], n: usize) -> Src3<'_, f32> {
        match self {
            Layout::Soa => Src3::soa(&a[..n], &a[n..2 * n], &a[2 * n..3 * n]).unwrap(),
            Layout::Xyz => Src3::interleaved(&a[..3 * n]),
            // SAFETY: element i's components are a[4i], a[4i + 1], a[4i + 2], inside `a`.
            Layout::Xyzw => unsafe { Src3::from_raw(a.as_ptr(), a.as_ptr().add(1), a.as_ptr().add(2), 4, n) },
        }
    }
    fn dst(self, a: &mut [f32], n: usize) -> Dst3<'_, f32> {
        match self {
            Layout::Soa => {
                let (x, rest) = a.split_at_mut(n);
                let (y, z) = rest.split_at_mut(n);
                Dst3::soa(x, y, &mut z[..n]).unwrap()
            }
            Layout::Xyz => Dst3::interleaved(&mut a[..3 * n]),
            // SAFETY: as in `src`; nothing else touches `a` while the view lives.
            Layout::Xyzw => unsafe {
                let p = a.as_mut_ptr();
                Dst3::from_raw(p, p.add(1), p.add(2), 4, n)
            },
        }
    }
    /// Element `i` of a packed output.
    fn get(self, a: &[f32], n: usize, i: usize) -> [f32; 3] {
        match self {
            Layout::Soa => [a[i], a[n + i], a[2 * n + i]],
            Layout::Xyz => [a[3 * i], a[3 * i + 1], a[3 * i + 2]],
            Layout::Xyzw => [a[4 * i], a[4 * i + 1], a[4 * i + 2]],
        }
    }
    /// Values of a packed output that are not elements (must stay untouched).
    fn untouched(self, a: &[f32], n: usize) -> bool {
        match self {
            Layout::Soa => a.len() == 3 * n,
            Layout::Xyz => a[3 * n].is_nan(),
            Layout::Xyzw => (0..n).all(|i| a[4 * i + 3].is_nan()),
        }
    }
}

/// Inputs and outputs in different layouts (structure-of-arrays in, interleaved out, and
/// every other pairing), and a density output with a stride of 2, give the same bits as the
/// structure-of-arrays call without an active mask: the full-group loop takes a call only
/// when every view is dense, and hands any other to the general loop from the start.
#[test]
fn mixed_layouts_give_identical_results() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let layouts = [Layout::Soa, Layout::Xyz, Layout::Xyzw];
    for json in [MATERIALS[1], MATERIALS[12], MATERIALS[18]] {
        let m = Material::from_json(json).unwrap();
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            for n in [17usize, 1037] {
                let (wi, wo) = directions(n, 3 * n as u64);
                let mut rng = Pcg32::new(n as u64, 11);
                let u: Vec<[f32; 3]> = (0..n).map(|_| [0, 1, 2].map(|_| rng.uniform() as f32)).collect();
                let mut want: Option<Vec<[u32; 8]>> = None;
                for (input, output, pdf_stride) in
                    layouts.iter().flat_map(|&i| layouts.iter().flat_map(move |&o| [(i, o, 1usize), (i, o, 2)]))
                {
                    let (a, b, uu) = (input.pack(&wi), input.pack(&wo), input.pack(&u));
                    let blank = || output.pack(&vec![[f32::NAN; 3]; n]);
                    let (mut f, mut swi, mut sw) = (blank(), blank(), blank());
                    let (mut pdf, mut spdf) = (vec![f32::NAN; n * pdf_stride], vec![f32::NAN; n * pdf_stride]);
                    // SAFETY: element i of each density view is p[i·stride] < n·stride.
                    let pdf_view = |p: &mut [f32]| unsafe { Dst1::from_raw(p.as_mut_ptr(), pdf_stride, n) };
                    batch::eval_pdf(
                        &m,
                        &input.src(&a, n),
                        &input.src(&b, n),
                        None,
                        Some(&output.dst(&mut f, n)),
                        Some(&pdf_view(&mut pdf)),
                    )
                    .unwrap();
                    {
                        let mut out = SampleOut {
                            wi: output.dst(&mut swi, n),
                            weight: output.dst(&mut sw, n),
                            pdf: pdf_view(&mut spdf),
                            flags: None,
                        };
                        batch::sample(&m, &input.src(&b, n), &input.src(&uu, n), None, &mut out).unwrap();
                    }
                    let what = format!("{json} {level:?} n {n} {input:?} in, {output:?} out, pdf stride {pdf_stride}");
                    for (name, arr) in [("f", &f), ("sample wi", &swi), ("sample weight", &sw)] {
                        assert!(output.untouched(arr, n), "{what}: {name} wrote padding");
                    }
                    if pdf_stride == 2 {
                        assert!(
                            (0..n).all(|i| pdf[2 * i + 1].is_nan() && spdf[2 * i + 1].is_nan()),
                            "{what}: pdf gap written"
                        );
                    }
                    let per: Vec<[u32; 8]> = (0..n)
                        .map(|i| {
                            let (fv, w, s) = (output.get(&f, n, i), output.get(&swi, n, i), output.get(&sw, n, i));
                            let (p, sp) = (pdf[i * pdf_stride], spdf[i * pdf_stride]);
                            [fv[0], fv[1], fv[2], p, w[0], w[2], s[1], sp].map(f32::to_bits)
                        })
                        .collect();
                    // Enough values and samples are non-zero for the comparison to say something.
                    let values = per.iter().filter(|v| v[0] != 0).count();
                    let samples = per.iter().filter(|v| v[7] != 0).count();
                    assert!(
                        values > n / 8 && samples > n / 4,
                        "{what}: only {values} values, {samples} samples non-zero"
                    );
                    match &want {
                        None => want = Some(per),
                        Some(w) => {
                            for i in 0..n {
                                assert_eq!(per[i], w[i], "{what}: element {i} differs from SoA in and out");
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The interleaved (contiguous loads, register permutes) and strided paths give the same
/// bits as the structure-of-arrays one at every SIMD level, for eval, pdf and sample, with
/// masked lanes and lengths around the lane counts (1 … 49 and 1037): each element's lane
/// work does not depend on where its values came from. Padding and values past the end stay
/// untouched. Calls without an active mask (the full-group loop for unit-stride and
/// interleaved views, the general loop for the strided one and for tails) give the same bits
/// as the masked calls at the active elements.
#[test]
fn layouts_give_identical_results() {
    let _turn = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let lens = [1usize, 2, 7, 8, 9, 15, 16, 17, 31, 33, 47, 48, 49, 1037];
    let layouts = [Layout::Soa, Layout::Xyz, Layout::Xyzw];
    for json in [MATERIALS[0], MATERIALS[1], MATERIALS[7], MATERIALS[12], MATERIALS[18], MATERIALS[11]] {
        let m = Material::from_json(json).unwrap();
        for level in crate::simd_levels() {
            assert!(batch::set_simd_level(level));
            for &n in &lens {
                let (wi, wo) = directions(n, n as u64);
                let mut rng = Pcg32::new(n as u64, 9);
                let u: Vec<[f32; 3]> = (0..n).map(|_| [0, 1, 2].map(|_| rng.uniform() as f32)).collect();
                let active: Vec<u8> = (0..n).map(|i| u8::from(i % 7 != 3)).collect();
                let mut results: Vec<(Layout, Vec<[f32; 8]>)> = Vec::new();
                let mut unmasked: Vec<(Layout, Vec<[f32; 8]>)> = Vec::new();
                for (layout, masked) in layouts.iter().flat_map(|&l| [(l, true), (l, false)]) {
                    let mask = masked.then_some(&active[..]);
                    let (a, b, uu) = (layout.pack(&wi), layout.pack(&wo), layout.pack(&u));
                    let blank = || layout.pack(&vec![[f32::NAN; 3]; n]);
                    let (mut f, mut swi, mut sw) = (blank(), blank(), blank());
                    let (mut pdf, mut spdf) = (vec![f32::NAN; n], vec![f32::NAN; n]);
                    batch::eval_pdf(
                        &m,
                        &layout.src(&a, n),
                        &layout.src(&b, n),
                        mask,
                        Some(&layout.dst(&mut f, n)),
                        Some(&Dst1::new(&mut pdf)),
                    )
                    .unwrap();
                    {
                        let mut out = SampleOut {
                            wi: layout.dst(&mut swi, n),
                            weight: layout.dst(&mut sw, n),
                            pdf: Dst1::new(&mut spdf),
                            flags: None,
                        };
                        batch::sample(&m, &layout.src(&b, n), &layout.src(&uu, n), mask, &mut out).unwrap();
                    }
                    for (name, arr) in [("f", &f), ("sample wi", &swi), ("sample weight", &sw)] {
                        assert!(layout.untouched(arr, n), "{json} {level:?} n {n} {layout:?}: {name} wrote padding");
                    }
                    let per: Vec<[f32; 8]> = (0..n)
                        .map(|i| {
                            let (fv, w, s) = (layout.get(&f, n, i), layout.get(&swi, n, i), layout.get(&sw, n, i));
                            [fv[0], fv[1], fv[2], pdf[i], w[0], w[2], s[1], spdf[i]]
                        })
                        .collect();
                    if !masked {
                        unmasked.push((layout, per));
                        continue;
                    }
                    for (i, v) in per.iter().enumerate() {
                        if active[i] == 0 {
                            assert_eq!(v, &[0.0; 8], "{json} {level:?} n {n} {layout:?}: inactive element {i}");
                        }
                    }
                    results.push((layout, per));
                }
                let bits = |v: &[f32; 8]| v.map(f32::to_bits);
                for (runs, what) in [(&results, "masked"), (&unmasked, "unmasked")] {
                    let (_, want) = &runs[0];
                    for (layout, got) in &runs[1..] {
                        for i in 0..n {
                            assert_eq!(
                                bits(&got[i]),
                                bits(&want[i]),
                                "{json} {level:?} n {n} {layout:?} {what} element {i}: {:?} vs SoA {:?}",
                                got[i],
                                want[i]
                            );
                        }
                    }
                }
                for i in (0..n).filter(|&i| active[i] != 0) {
                    assert_eq!(
                        bits(&unmasked[0].1[i]),
                        bits(&results[0].1[i]),
                        "{json} {level:?} n {n} element {i}: unmasked vs masked call"
                    );
                }
            }
        }
    }
}
