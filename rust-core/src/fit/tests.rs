//! Recovery tests: tables generated from known parameters are fitted back to them.

use super::*;
use crate::measured::standard::StandardTable;
use crate::measured::tabulate;

fn table_of(json: &str) -> MerlTable {
    tabulate(&materials_from_spec(json).unwrap())
}

fn quick() -> FitOptions {
    FitOptions { points: 6_000, coarse_points: 1_000, starts: 6, ..FitOptions::default() }
}

fn param(r: &FitReport, name: &str) -> f64 {
    r.parameters.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no {name} in {:?}", r.parameters)).1
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-3)
}

#[test]
fn ward_parameters_are_recovered() {
    let truth = r#"{"model": "ward", "diffuse": [0.3, 0.1, 0.05], "specular": [0.2, 0.25, 0.3], "alpha_x": 0.08, "alpha_y": 0.08}"#;
    let data = FitData::from_merl(&table_of(truth));
    let r = fit(&FitModel::parse("ward").unwrap(), &data, &quick()).unwrap();
    assert!(r.metrics.snr_db_mean > 60.0, "{:?}", r.metrics);
    for (name, want) in
        [("diffuse[0]", 0.3), ("diffuse[2]", 0.05), ("specular[1]", 0.25), ("alpha_x", 0.08), ("alpha_y", 0.08)]
    {
        assert!(close(param(&r, name), want, 1e-3), "{name}: {} vs {want}; {:?}", param(&r, name), r.parameters);
    }
}

#[test]
fn bad_budget_or_stop_is_a_clear_error() {
    let data = FitData::from_merl(&table_of(r#"{"model": "lambert", "albedo": 0.5}"#));
    let model = FitModel::parse("lambert").unwrap();
    let bad = [
        ("budget_seconds", FitOptions { budget_seconds: Some(f64::NAN), ..quick() }),
        ("budget_seconds", FitOptions { budget_seconds: Some(f64::INFINITY), ..quick() }),
        ("budget_seconds", FitOptions { budget_seconds: Some(-1.0), ..quick() }),
        ("stop_snr_db", FitOptions { stop_snr_db: Some(f64::NAN), ..quick() }),
        ("stop_snr_db", FitOptions { stop_snr_db: Some(f64::NEG_INFINITY), ..quick() }),
    ];
    for (name, opts) in bad {
        match fit(&model, &data, &opts) {
            Err(Error::Invalid { param, .. }) => assert_eq!(param, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    // A budget longer than a `Duration` holds is no deadline (it panicked in
    // `Duration::from_secs_f64`), and the fit runs to its answer.
    let r = fit(&model, &data, &FitOptions { budget_seconds: Some(1e300), ..quick() }).unwrap();
    assert!(close(param(&r, "albedo[0]"), 0.5, 1e-3), "{:?}", r.parameters);
}

#[test]
fn every_model_refits_a_table_of_its_own() {
    // For every registered model: a table generated at parameters away from its defaults is
    // fitted back by the same model (multi-start from the defaults and Halton points), to the
    // stated tolerance in BRDF space: SNR ≥ 30 dB on the whole table. The coated paint, whose
    // material builds its layer tables (242 ms per build at 30 % of the parameter ranges,
    // release, session 17; the next slowest, principled, 0.37 ms, the others below 0.01 ms),
    // fits its first colour and first two scalar parameters, the others held at the truth, to
    // keep the test short. Chosen by name, not by timing a build (which a loaded machine could
    // push across a threshold: a different test from run to run).
    let mut failures = Vec::new();
    for info in fittable_models() {
        let mut model = FitModel::parse(info.name).unwrap();
        // Scalars at 30 % of their range; where that set does not build (rough_plastic: equal
        // interior and exterior indices), repeated bounds are spread to 30, 35, 40 % (another
        // truth, never a start point). No fallback to a start point (the defaults), which
        // would let the fit begin at the answer: a truth that does not build panics.
        let truth_at = |spread: f64| -> Vec<f64> {
            let mut seen: Vec<(f64, f64)> = Vec::new();
            model
                .variables()
                .iter()
                .map(|v| {
                    let (lo, hi) = v.bounds();
                    if v.channel.is_some() {
                        v.internal(0.8 * v.default)
                    } else {
                        let repeats = seen.iter().filter(|b| **b == (lo, hi)).count() as f64;
                        seen.push((lo, hi));
                        lo + (0.3 + spread * repeats) * (hi - lo)
                    }
                })
                .collect()
        };
        let truth = [0.0, 0.05]
            .iter()
            .find_map(|&spread| model.materials(&truth_at(spread)).ok())
            .unwrap_or_else(|| panic!("{}: the truth parameters do not build", info.name));
        if info.name == "coated_paint" {
            let mut obj = truth[0].to_json().as_object().unwrap().clone();
            let colour = info.params.iter().find(|p| p.kind == ParamKind::Color).map(|p| p.name);
            let scalars: Vec<&str> =
                info.params.iter().filter(|p| p.kind == ParamKind::Scalar).take(2).map(|p| p.name).collect();
            obj.retain(|k, _| k == "model" || (Some(k.as_str()) != colour && !scalars.contains(&k.as_str())));
            model = FitModel::parse(&Value::Object(obj).to_string()).unwrap();
        }
        let data = FitData::from_merl(&tabulate(&truth));
        // Six starts, two refinements, also for the slow model: coated_paint reached SNR 36.2 dB
        // in 70.6 s of this test's ≈ 98 s; with two starts and one refinement (41 s) it stopped
        // at 21.3 dB (coat_ior 1.75 for 1.45), below the 30 dB the test asks (session 16).
        // Each start and refinement stops at 60 dB on its subset (`stop_snr_db`), 30 dB above
        // what the test asks of the whole table: without it an exact fit iterates to round-off
        // (200 dB): coated_paint took 175 s of this test's 204 s, with the stop 108 s of 137 s,
        // and the lowest whole-table SNR is principled's 55.7 dB (session 46, release, 2 cores).
        let opts = FitOptions {
            points: 4_000,
            coarse_points: 800,
            starts: 6,
            stop_snr_db: Some(60.0),
            ..FitOptions::default()
        };
        let result = fit(&model, &data, &opts);
        if let Ok(r) = &result {
            // Per model (`-- --nocapture`): what the fit cost and reached.
            eprintln!(
                "{}: SNR {:.1} dB, {} starts, {} iterations ({} total), {} evaluations, {:.1} s",
                info.name, r.metrics.snr_db_mean, r.starts, r.iterations, r.total_iterations, r.evaluations, r.seconds
            );
        }
        match result {
            Ok(r) if r.metrics.snr_db_mean >= 30.0 => {}
            Ok(r) => failures.push(format!(
                "{}: SNR {:.1} dB, truth {:?}, fitted {:?}",
                info.name,
                r.metrics.snr_db_mean,
                truth.iter().map(Material::to_json).collect::<Vec<_>>(),
                r.parameters
            )),
            Err(e) => failures.push(format!("{}: {e}", info.name)),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn two_lobe_sum_is_recovered() {
    let truth = r#"[{"model": "lambert", "albedo": [0.2, 0.1, 0.05]},
        {"model": "ward", "diffuse": 0, "specular": 0.05, "alpha_x": 0.04, "alpha_y": 0.04},
        {"model": "ward", "diffuse": 0, "specular": 0.3, "alpha_x": 0.3, "alpha_y": 0.3}]"#;
    let data = FitData::from_merl(&table_of(truth));
    let model = FitModel::parse("ward").unwrap().with_lobes(2).unwrap();
    assert_eq!(model.label(), "ward×2");
    assert!(model.variables().iter().all(|v| !(v.lobe == 1 && v.param == "diffuse")));
    let opts = FitOptions { starts: 8, ..quick() };
    let r = fit(&model, &data, &opts).unwrap();
    assert!(r.metrics.snr_db_mean > 40.0, "{:?} {:?}", r.metrics, r.parameters);
    let mut alphas = [param(&r, "0.alpha_x"), param(&r, "1.alpha_x")];
    alphas.sort_by(f64::total_cmp);
    assert!(close(alphas[0], 0.04, 0.02) && close(alphas[1], 0.3, 0.02), "{alphas:?}");
    assert!(close(param(&r, "0.diffuse[0]"), 0.2, 0.02), "{:?}", r.parameters);
}

#[test]
fn noisy_table_fits_to_the_noise_level_and_standard_tables_fit_too() {
    let truth = r#"{"model": "ward", "diffuse": [0.4, 0.2, 0.1], "specular": 0.2, "alpha_x": 0.12, "alpha_y": 0.12}"#;
    let mut t = table_of(truth);
    add_noise(&mut t, 0.05, 7);
    let data = FitData::from_merl(&t);
    let r = fit(&FitModel::parse("ward").unwrap(), &data, &quick()).unwrap();
    assert!(close(param(&r, "alpha_x"), 0.12, 0.03), "{:?}", r.parameters);
    assert!(close(param(&r, "diffuse[0]"), 0.4, 0.03), "{:?}", r.parameters);
    // 5 % multiplicative noise bounds the SNR: MSE ≈ 0.0025·mean(m²).
    assert!(r.metrics.snr_db_mean > 10.0 && r.metrics.snr_db_mean < 40.0, "{:?}", r.metrics);

    let std_t = StandardTable::from_fn(|wi, wo| Some(materials_from_spec(truth).unwrap()[0].eval(wi, wo).to_array()));
    let r = fit(&FitModel::parse("ward").unwrap(), &FitData::from_standard(&std_t), &quick()).unwrap();
    assert!(r.metrics.snr_db_mean > 50.0, "{:?}", r.metrics);
    assert!(close(param(&r, "alpha_y"), 0.12, 1e-3), "{:?}", r.parameters);
}

#[test]
fn fit_models_parse_and_reject_clearly() {
    let sum = FitModel::parse("lambert+ward").unwrap();
    assert_eq!(sum.label(), "lambert+ward");
    assert!(sum.variables().iter().all(|v| !(v.lobe == 1 && v.param == "diffuse")));
    let m = FitModel::parse(r#"{"model": "ward", "alpha_y": 0.2}"#).unwrap();
    assert!(m.variables().iter().all(|v| v.param != "alpha_y"));
    assert!(FitModel::parse("nope").unwrap_err().to_string().contains("unknown model"));
    let e = FitModel::parse("measured").unwrap_err().to_string();
    assert!(e.contains("no free numeric parameter"), "{e}");
    let e = FitModel::parse(r#"{"model": "ward", "alpha_x": 7}"#).unwrap_err().to_string();
    assert!(e.contains("alpha_x"), "{e}");
    // Log-space variables for ranges over two decades.
    let w = FitModel::parse("ward").unwrap();
    assert!(w.variables().iter().find(|v| v.param == "alpha_x").unwrap().log);
    assert!(!w.variables().iter().find(|v| v.param == "diffuse").unwrap().log);
    let v = w.variables().iter().find(|v| v.param == "alpha_x").unwrap();
    assert!((v.value(v.internal(0.37)) - 0.37).abs() < 1e-14);
    assert!(fittable_models().iter().all(|m| m.name != "measured"));
}

#[test]
fn models_left_out_of_isotropic_fits_are_anisotropic() {
    // Rotating both directions about the normal changes their value at the defaults (and no
    // parameter makes them isotropic: the cylinders and grating always have an axis).
    for name in super::NO_ISOTROPIC_CONFIGURATION {
        let m = Material::from_json(&format!(r#"{{"model": "{name}"}}"#)).unwrap();
        let rot = |v: crate::Vec3<f64>, a: f64| {
            crate::Vec3::new(v.x * a.cos() - v.y * a.sin(), v.x * a.sin() + v.y * a.cos(), v.z)
        };
        let mut rng = crate::rng::Pcg32::new(7, 7);
        let mut gap = 0.0f64;
        for _ in 0..64 {
            let wi = crate::sampling::uniform_hemisphere(rng.uniform().max(0.05), rng.uniform());
            let wo = crate::sampling::uniform_hemisphere(rng.uniform().max(0.05), rng.uniform());
            let (a, b) = (m.eval(wi, wo), m.eval(rot(wi, 1.2), rot(wo, 1.2)));
            for c in 0..3 {
                gap = gap.max((a[c] - b[c]).abs() / a[c].abs().max(b[c].abs()).max(1e-12));
            }
        }
        assert!(gap > 0.05, "{name}: value unchanged by a rotation about the normal ({gap})");
        assert!(fittable_models().iter().all(|i| i.name != *name));
    }
}
