//! Every registered model, whatever it is, goes through the shipped checks and through
//! property tests of the invariants every BRDF must keep.

use lacquer::check::{self, CheckConfig};
use lacquer::params::{ParamKind, Params};
use lacquer::{models, Material, ModelInfo, Vec3};
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

/// The material of `info` from numbers in [0, 1), or the model's error.
fn build_from_unit(info: &'static ModelInfo, u: &[f64]) -> Result<Material, String> {
    let params = Params::parse(info.name, info.params, &params_from_unit(info, u)).map_err(|e| e.to_string())?;
    Material::from_params(info, params).map_err(|e| e.to_string())
}

/// Most random parameter sets build, for every model: the property tests below skip
/// (`prop_assume!`) the sets a model rejects, so a model whose builder always errored would
/// pass them without a single check. Requires ≥ 90 % of 400 draws per model.
///
/// Ignored, and failing: measured (seed 0xb011d) 18 models build 400/400, but coated_paint
/// 196, cook_torrance 194, cook_torrance_1981 191, lafortune 39, modified_phong 7,
/// neumann_stretch_phong 3, fast_phong 2, neumann_stretch_blinn_phong 1 and poulin_fournier 1
/// of 400: `params_from_unit` ignores the cross-parameter rules (`diffuse + specular ≤ 1` and
/// alike), so before `prop_assume!` the property tests checked those models on almost no
/// parameter sets while reporting success. Open (issue 16): the generator must respect the
/// rules; run with `--ignored` to see the rates.
#[test]
#[ignore = "fails: 9 models build < 90 % of random parameter sets (see the doc comment); open in issue 16"]
fn random_parameters_mostly_build() {
    let mut rng = lacquer::rng::Pcg32::new(0xb011d, 1);
    let mut worst = (1.0f64, "");
    for &info in models::all() {
        let n = 400;
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
    // Rejected draws are skipped (`prop_assume!`), at most 4 000 over the 2 000 cases:
    // measured 200 rejects per 223 successes (47 %, about 1 800 expected), nearly all from the
    // nine models `random_parameters_mostly_build` lists; the limit goes down when the
    // generator respects the cross-parameter rules.
    #![proptest_config(ProptestConfig { cases: 2000, max_global_rejects: 4000, ..ProptestConfig::default() })]

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
