//! Every registered model, whatever it is, goes through the shipped checks and through
//! property tests of the invariants every BRDF must keep.

use lacquer::check::{self, CheckConfig};
use lacquer::params::{Default as ParamDefault, ParamKind, Params};
use lacquer::{models, Error, Material, ModelInfo, Vec3};
use proptest::prelude::*;
use serde_json::{Map, Value};

/// The shipped checks pass every claim of every model (quick configuration).
///
/// CI (scripts/test.sh) skips this test and `every_preset_passes_its_claims`: its
/// `lacquer check --all --profile ci` step checks the same materials with at least these
/// samples, pairs and directions (`check::schedule::tests::ci_profile_covers_the_quick_configuration`).
#[test]
fn every_model_passes_its_claims() {
    let reports = check::check_all(&CheckConfig::quick());
    let mut failures = Vec::new();
    for r in &reports {
        if !r.passed {
            let mut lines = vec![format!("{}:", r.model)];
            for m in &r.materials {
                for v in m.verdicts.iter().filter(|v| !v.ok()) {
                    lines.push(format!("  {} = {:.3e} (limit {:.3e}) on {}", v.check, v.value, v.limit, m.material));
                }
                lines.extend(m.hard_cases.examples.iter().map(|e| format!("  hard case {e}")));
            }
            lines.extend(r.parameter_extremes.examples.iter().map(|e| format!("  extreme {e}")));
            lines.extend(r.parameter_extremes.build_errors.iter().map(|e| format!("  build {e}")));
            failures.push(lines.join("\n"));
        }
    }
    assert!(failures.is_empty(), "claims failed:\n{}", failures.join("\n"));
}

/// Every preset is a valid material and passes every claim of its model.
#[test]
fn every_preset_passes_its_claims() {
    let failures: Vec<String> = check::check_presets(&CheckConfig::quick())
        .into_iter()
        .filter(|p| !p.report.passed())
        .map(|p| {
            let bad: Vec<String> = p
                .report
                .verdicts
                .iter()
                .filter(|v| !v.ok())
                .map(|v| format!("{} = {:.3e}", v.check, v.value))
                .collect();
            format!("{}: {}", p.preset, bad.join(", "))
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every model documents every parameter and builds from `{"model": name}` alone.
#[test]
fn every_model_builds_from_its_name_alone() {
    for info in models::all() {
        let m = Material::from_json(&format!("{{\"model\": \"{}\"}}", info.name));
        assert!(m.is_ok(), "{}: {:?}", info.name, m.err());
        for p in info.params {
            assert!(!p.doc.is_empty(), "{}.{} has no documentation", info.name, p.name);
            if matches!(p.kind, ParamKind::Scalar | ParamKind::Color | ParamKind::Integer) {
                assert!(p.min <= p.max, "{}.{} has an empty range", info.name, p.name);
            }
        }
        assert!(!info.reference.is_empty() && !info.summary.is_empty(), "{}", info.name);
    }
}

/// Unknown keys and out-of-range values are errors that name the parameter.
#[test]
fn bad_parameters_name_the_parameter() {
    for info in models::all() {
        let e = Material::from_json(&format!("{{\"model\": \"{}\", \"no_such_key\": 1}}", info.name)).unwrap_err();
        assert!(e.to_string().contains("no_such_key"), "{e}");
        for p in info.params.iter().filter(|p| p.kind == ParamKind::Scalar) {
            for bad in [p.min - 1.0 - p.min.abs(), p.max + 1.0 + p.max.abs()] {
                if !bad.is_finite() {
                    continue;
                }
                let e = Material::from_json(&format!("{{\"model\": \"{}\", \"{}\": {bad}}}", info.name, p.name))
                    .unwrap_err();
                assert!(e.to_string().contains(p.name), "{}: {e}", info.name);
            }
        }
    }
}

/// Maps numbers in [0, 1) onto a valid parameter object of `info`.
fn params_from_unit(info: &'static ModelInfo, u: &[f64]) -> Map<String, Value> {
    let mut obj = Map::new();
    for (i, spec) in info.params.iter().enumerate() {
        let t = u[i % u.len()];
        let lerp = |t: f64| {
            if spec.min > 0.0 && spec.max / spec.min > 100.0 {
                (spec.min.ln() + t * (spec.max.ln() - spec.min.ln())).exp().clamp(spec.min, spec.max)
            } else {
                spec.min + t * (spec.max - spec.min)
            }
        };
        let v = match spec.kind {
            ParamKind::Scalar => Value::from(lerp(t)),
            ParamKind::Color => Value::from(vec![lerp(t), lerp((t + 0.37) % 1.0), lerp((t + 0.71) % 1.0)]),
            ParamKind::Integer => Value::from(lerp(t).round() as i64),
            ParamKind::Bool => Value::from(t < 0.5),
            ParamKind::Choice(c) => Value::from(c[((t * c.len() as f64) as usize).min(c.len() - 1)]),
            ParamKind::Json | ParamKind::Text => continue,
        };
        obj.insert(spec.name.to_string(), v);
    }
    obj
}

fn unit_dir(cos_t: f64, phi: f64) -> Vec3<f64> {
    let s = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), cos_t)
}

/// The material of `info` from numbers in [0, 1), or the model's error. A set that breaks a
/// cross-parameter rule (`Error::Invalid` naming a parameter: `diffuse + specular ≤ 1`,
/// `kd + ks ≤ 1`, `flake_density + pearl_density ≤ 100 %` and alike) is repaired, still as a
/// function of `u` alone: the named parameter moves halfway towards its minimum, up to 40
/// times. Without the repair the property tests skipped those sets (`prop_assume!`) and checked
/// nine models on 0.25–50 % of their draws (`random_parameters_mostly_build`).
fn build_from_unit(info: &'static ModelInfo, u: &[f64]) -> Result<Material, String> {
    let mut obj = params_from_unit(info, u);
    let mut last = String::new();
    for _ in 0..40 {
        let params = Params::parse(info.name, info.params, &obj).map_err(|e| e.to_string())?;
        match Material::from_params(info, params) {
            Ok(m) => return Ok(m),
            Err(Error::Invalid { param, reason }) => {
                last = format!("{param}: {reason}");
                // The named parameter, or, when it is one the generator does not draw
                // (lafortune's `lobes` against `diffuse`), every drawn colour.
                let named: Vec<&str> = if obj.contains_key(&param) {
                    vec![param.as_str()]
                } else {
                    info.params.iter().filter(|p| p.kind == ParamKind::Color).map(|p| p.name).collect()
                };
                let mut changed = false;
                for spec in info.params.iter().filter(|p| named.contains(&p.name)) {
                    let halve = |v: &Value| v.as_f64().map(|x| Value::from(spec.min + (x - spec.min) / 2.0));
                    let repaired = match (obj.get(spec.name), spec.default) {
                        (Some(Value::Array(a)), _) => a.iter().map(halve).collect::<Option<Vec<_>>>().map(Value::from),
                        (Some(v), _) if spec.kind == ParamKind::Scalar => halve(v),
                        // A choice (rough_conductor's `material` with eta/k given,
                        // torrance_sparrow's Smith `masking` with the Gaussian): its default.
                        (Some(v), ParamDefault::Choice(d)) if v.as_str() != Some(d) => Some(Value::from(d)),
                        _ => None,
                    };
                    if let Some(v) = repaired {
                        obj.insert(spec.name.to_string(), v);
                        changed = true;
                    }
                }
                if !changed {
                    return Err(last);
                }
            }
            Err(e) => return Err(e.to_string()),
        }
    }
    Err(last)
}

/// Most random parameter sets build, for every model: the property tests below skip
/// (`prop_assume!`) the sets a model rejects, so a model whose builder always errored would
/// pass them without a single check. Requires ≥ 90 % of 20 draws per model.
///
/// Was ignored and failing: `params_from_unit` ignored the cross-parameter rules, and (seed
/// 0xb011d, 400 draws) coated_paint built 196, cook_torrance 194, cook_torrance_1981 191,
/// lafortune 39–41, modified_phong 7, neumann_stretch_phong 3, fast_phong 2,
/// neumann_stretch_blinn_phong 1, poulin_fournier 1 of 400 (and, at this commit,
/// rough_conductor 62 and torrance_sparrow 262). `build_from_unit` now repairs a rejected
/// set: every model builds 100/100 (release build, 2026-12-01).
#[test]
fn random_parameters_mostly_build() {
    let mut rng = lacquer::rng::Pcg32::new(0xb011d, 1);
    let mut worst = (1.0f64, "");
    for &info in models::all() {
        // 20 draws: 44 s of CPU for 100 (the seed models' and coated_paint's builds), 7.3 s for
        // 20; a builder accepting half the sets passes with probability 2e-4 (≥ 18 of 20).
        let n = 20;
        let ok = (0..n)
            .filter(|_| {
                let u: Vec<f64> = (0..8).map(|_| rng.uniform()).collect();
                build_from_unit(info, &u).is_ok()
            })
            .count();
        let rate = ok as f64 / n as f64;
        eprintln!("{}: {ok}/{n} random parameter sets build", info.name);
        if rate < worst.0 {
            worst = (rate, info.name);
        }
    }
    assert!(worst.0 >= 0.9, "{} builds only {:.1} % of random parameter sets", worst.1, 100.0 * worst.0);
}

proptest! {
    // Rejected draws are skipped (`prop_assume!`). Before `build_from_unit` repaired sets that
    // break a cross-parameter rule, 47 % of the draws were rejected (200 per 223 successes), so
    // 2 000 cases checked about 1 060 materials, few of them of the nine models concerned. Now
    // every draw builds: 1 000 cases check about as many materials (the same CI time: measured
    // 30 s of CPU for this test at 2 000 cases in a release build), spread over all models; at
    // most 100 rejects.
    #![proptest_config(ProptestConfig { cases: 1000, max_global_rejects: 100, ..ProptestConfig::default() })]

    /// Non-negative, finite, and reciprocal where claimed, for random valid parameters and
    /// directions (grazing included).
    #[test]
    fn eval_is_finite_nonnegative_and_reciprocal_where_claimed(
        model in 0..models::all().len(),
        u in proptest::collection::vec(0.0f64..1.0, 8),
        ci in prop_oneof![0.0f64..1.0, 1e-7f64..1e-3], pi in 0.0f64..6.3,
        co in prop_oneof![0.0f64..1.0, 1e-7f64..1e-3], po in 0.0f64..6.3,
    ) {
        let info = models::all()[model];
        let built = build_from_unit(info, &u);
        prop_assume!(built.is_ok());
        let m = built.expect("assumed");
        let (wi, wo) = (unit_dir(ci, pi), unit_dir(co, po));
        let f = m.eval(wi, wo);
        let g = m.eval(wo, wi);
        for c in 0..3 {
            prop_assert!(f[c].is_finite() && f[c] >= 0.0, "{} f = {:?}", info.name, f);
            if info.claims.reciprocal {
                let scale = f[c].abs().max(g[c].abs()).max(1e-10);
                prop_assert!((f[c] - g[c]).abs() / scale <= 1e-6, "{}: f(wi,wo) = {} but f(wo,wi) = {}", info.name, f[c], g[c]);
            }
        }
        let p = m.pdf(wi, wo);
        prop_assert!(p.is_finite() && p >= 0.0, "{} pdf = {}", info.name, p);
        let pf: f32 = m.pdf(wi.cast::<f32>(), wo.cast::<f32>());
        prop_assert!(pf.is_finite() && pf >= 0.0);
    }

    /// Samples lie above the surface, carry a finite non-negative weight, and report the
    /// same density as `pdf` and the same weight as `eval·cos/pdf`.
    #[test]
    fn samples_agree_with_pdf_and_eval(
        model in 0..models::all().len(),
        u in proptest::collection::vec(0.0f64..1.0, 8),
        co in prop_oneof![0.0f64..1.0, 1e-6f64..1e-2], po in 0.0f64..6.3,
        s in proptest::array::uniform3(0.0f64..1.0),
    ) {
        let info = models::all()[model];
        let built = build_from_unit(info, &u);
        prop_assume!(built.is_ok());
        let m = built.expect("assumed");
        let wo = unit_dir(co, po);
        if let Some(smp) = m.sample(wo, s) {
            prop_assert!(smp.wi.is_finite());
            prop_assert!(smp.pdf > 0.0 && smp.pdf.is_finite());
            if !smp.delta {
                prop_assert!(smp.wi.z > 0.0);
                let pdf = m.pdf(smp.wi, wo);
                prop_assert!((smp.pdf - pdf).abs() <= 1e-4 * pdf.max(smp.pdf), "{}: sample pdf {} vs pdf {}", info.name, smp.pdf, pdf);
                let f = m.eval(smp.wi, wo);
                for c in 0..3 {
                    let w = f[c] * smp.wi.z / smp.pdf;
                    prop_assert!(smp.weight[c] >= 0.0 && (smp.weight[c] - w).abs() <= 1e-4 * w.abs().max(1e-6), "{}: weight {} vs {}", info.name, smp.weight[c], w);
                }
            }
        }
    }
}
