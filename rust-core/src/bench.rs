//! Speed measurement of a material's eval, pdf and sample (what `lacquer bench` reports):
//! ns per element through the batch kernels (SIMD and scalar, one and all threads) and per
//! call through the scalar API in f32 and f64, on one fixed set of random direction pairs.
//!
//! Times are wall-clock minima and medians over repetitions; the machine's load moves them
//! (compare ratios measured in one run, as `bench/vs_mitsuba.py` does).

use crate::batch::{self, Dst1, Dst3, SampleOut, SimdLevel, Src3};
use crate::material::Material;
use crate::math::Vec3;
use crate::rng::Pcg32;
use crate::sampling::cosine_hemisphere;
use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Direction pairs per batch call.
    pub n: usize,
    /// Repetitions per figure (minimum and median are reported).
    pub repetitions: usize,
    /// Measure the batch calls on all threads too.
    pub all_threads: bool,
    /// Measure the scalar per-call API (f32 and f64) too.
    pub scalar_calls: bool,
}

impl Default for BenchConfig {
    fn default() -> Self {
        Self { n: 1 << 20, repetitions: 7, all_threads: true, scalar_calls: true }
    }
}

/// One figure: ns per element, minimum and median over the repetitions.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Timing {
    /// Fastest repetition.
    pub min_ns: f64,
    /// Median repetition.
    pub median_ns: f64,
}

/// One row of the report: an operation through one path.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    /// `eval`, `pdf` or `sample`.
    pub op: &'static str,
    /// `batch` (f32 arrays) or `call` (one element per call).
    pub api: &'static str,
    /// `f32` or `f64`.
    pub precision: &'static str,
    /// Instruction set (`avx512`, `avx2`, `scalar`).
    pub simd: &'static str,
    /// Threads used.
    pub threads: usize,
    /// ns per element.
    pub timing: Timing,
}

/// Everything `lacquer bench` prints for one material.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// The material as JSON.
    pub material: serde_json::Value,
    /// True when the model runs in SIMD lanes (else the batch calls loop over elements).
    pub lane_kernel: bool,
    /// Elements per batch call.
    pub n: usize,
    /// The rows.
    pub rows: Vec<BenchRow>,
}

fn time(reps: usize, per: usize, mut f: impl FnMut()) -> Timing {
    f(); // warm-up: caches, thread pool, lazily built tables
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e9 / per as f64
        })
        .collect();
    t.sort_by(f64::total_cmp);
    Timing { min_ns: t[0], median_ns: t[t.len() / 2] }
}

/// Inputs: cosine-distributed unit directions (structure of arrays) and uniform numbers.
struct Inputs {
    wi: [Vec<f32>; 3],
    wo: [Vec<f32>; 3],
    u: [Vec<f32>; 3],
}

fn inputs(n: usize) -> Inputs {
    let mut rng = Pcg32::new(2024, 13);
    let mut dir = || {
        let w: Vec3<f64> = cosine_hemisphere(rng.uniform(), rng.uniform());
        [w.x as f32, w.y as f32, w.z as f32]
    };
    let wi: Vec<[f32; 3]> = (0..n).map(|_| dir()).collect();
    let wo: Vec<[f32; 3]> = (0..n).map(|_| dir()).collect();
    let split = |v: &[[f32; 3]]| [0, 1, 2].map(|c| v.iter().map(|a| a[c]).collect::<Vec<f32>>());
    let u: Vec<[f32; 3]> = (0..n).map(|_| [0, 1, 2].map(|_| rng.uniform() as f32)).collect();
    Inputs { wi: split(&wi), wo: split(&wo), u: split(&u) }
}

/// Measures `m`. Restores the process-wide SIMD level and thread count afterwards.
#[must_use]
pub fn measure(m: &Material, cfg: &BenchConfig) -> BenchReport {
    let n = cfg.n.max(1);
    let inp = inputs(n);
    let (saved_level, saved_threads) = (batch::simd_level(), batch::thread_count());
    let mut rows = Vec::new();
    let mut f = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    let mut w = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    let mut p = vec![0.0f32; n];
    let wi = Src3::soa(&inp.wi[0], &inp.wi[1], &inp.wi[2]).expect("equal lengths");
    let wo = Src3::soa(&inp.wo[0], &inp.wo[1], &inp.wo[2]).expect("equal lengths");
    let u = Src3::soa(&inp.u[0], &inp.u[1], &inp.u[2]).expect("equal lengths");

    let detected = SimdLevel::detect();
    let mut configs = vec![(detected, 1)];
    if detected != SimdLevel::Scalar {
        configs.push((SimdLevel::Scalar, 1));
    }
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    if cfg.all_threads && all > 1 {
        configs.push((detected, all));
    }
    for (level, threads) in configs {
        batch::set_simd_level(level);
        batch::set_thread_count(threads);
        let simd = level.name();
        let [fr, fg, fb] = &mut f;
        let fv = Dst3::soa(fr, fg, fb).expect("equal lengths");
        let t = time(cfg.repetitions, n, || {
            black_box(batch::eval_pdf(m, &wi, &wo, None, Some(&fv), None).expect("sized"));
        });
        rows.push(BenchRow { op: "eval", api: "batch", precision: "f32", simd, threads, timing: t });
        let pv = Dst1::new(&mut p);
        let t = time(cfg.repetitions, n, || {
            black_box(batch::eval_pdf(m, &wi, &wo, None, None, Some(&pv)).expect("sized"));
        });
        rows.push(BenchRow { op: "pdf", api: "batch", precision: "f32", simd, threads, timing: t });
        let [wx, wy, wz] = &mut w;
        let mut out = SampleOut {
            wi: Dst3::soa(wx, wy, wz).expect("equal lengths"),
            weight: Dst3::soa(fr, fg, fb).expect("equal lengths"),
            pdf: Dst1::new(&mut p),
            flags: None,
        };
        let t = time(cfg.repetitions, n, || {
            black_box(batch::sample(m, &wo, &u, None, &mut out).expect("sized"));
        });
        rows.push(BenchRow { op: "sample", api: "batch", precision: "f32", simd, threads, timing: t });
    }
    batch::set_simd_level(saved_level);
    batch::set_thread_count(saved_threads);

    if cfg.scalar_calls {
        let k = n.min(1 << 16);
        let dir = |s: &[Vec<f32>; 3], i: usize| Vec3::new(s[0][i], s[1][i], s[2][i]);
        let t = time(cfg.repetitions, k, || {
            for i in 0..k {
                black_box(m.eval(dir(&inp.wi, i), dir(&inp.wo, i)));
            }
        });
        rows.push(BenchRow { op: "eval", api: "call", precision: "f32", simd: "scalar", threads: 1, timing: t });
        let t = time(cfg.repetitions, k, || {
            for i in 0..k {
                black_box(m.eval(dir(&inp.wi, i).cast::<f64>(), dir(&inp.wo, i).cast::<f64>()));
            }
        });
        rows.push(BenchRow { op: "eval", api: "call", precision: "f64", simd: "scalar", threads: 1, timing: t });
        let t = time(cfg.repetitions, k, || {
            for i in 0..k {
                black_box(m.pdf(dir(&inp.wi, i), dir(&inp.wo, i)));
            }
        });
        rows.push(BenchRow { op: "pdf", api: "call", precision: "f32", simd: "scalar", threads: 1, timing: t });
        let t = time(cfg.repetitions, k, || {
            for i in 0..k {
                black_box(m.sample(dir(&inp.wo, i), [inp.u[0][i], inp.u[1][i], inp.u[2][i]]));
            }
        });
        rows.push(BenchRow { op: "sample", api: "call", precision: "f32", simd: "scalar", threads: 1, timing: t });
    }
    BenchReport { material: m.to_json(), lane_kernel: m.model().has_lane_kernel(), n, rows }
}

// ---------------------------------------------------------------------------------------
// Error against the f64 reference, and the cheapest configuration within a tolerance.

/// How far one evaluation path is from a reference over the same direction pairs.
///
/// The error of element `i` is `|a_i − b_i| / max(|b_i|, floor)` over the RGB channels of
/// `f·cos θi`, with `floor = 1e-3 · max_i |b_i|` so that values near zero (grazing, below a
/// lobe's tail) do not dominate; `rms` is the root mean square of that over all elements.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct ErrorStats {
    /// Largest relative error.
    pub max: f64,
    /// Root-mean-square relative error.
    pub rms: f64,
}

/// The error statistics of `test` against `reference` (values of `f·cos θi`, RGB per element).
#[must_use]
pub fn error_stats(test: &[[f64; 3]], reference: &[[f64; 3]]) -> ErrorStats {
    let peak = reference.iter().flatten().fold(0.0f64, |m, &v| m.max(v.abs()));
    let floor = (1e-3 * peak).max(f64::MIN_POSITIVE);
    let (mut max, mut sum2, mut count) = (0.0f64, 0.0f64, 0usize);
    for (a, b) in test.iter().zip(reference) {
        for c in 0..3 {
            let e = (a[c] - b[c]).abs() / b[c].abs().max(floor);
            let e = if e.is_finite() { e } else { f64::INFINITY };
            max = max.max(e);
            sum2 += e * e;
            count += 1;
        }
    }
    ErrorStats { max, rms: (sum2 / count.max(1) as f64).sqrt() }
}

/// `f·cos θi` of `m` in f64 (the reference path) on the bench inputs.
fn reference_values(m: &Material, inp: &Inputs) -> Vec<[f64; 3]> {
    (0..inp.wi[0].len())
        .map(|i| {
            let wi = Vec3::new(inp.wi[0][i], inp.wi[1][i], inp.wi[2][i]).cast::<f64>();
            let wo = Vec3::new(inp.wo[0][i], inp.wo[1][i], inp.wo[2][i]).cast::<f64>();
            (m.eval(wi, wo) * wi.z).to_array()
        })
        .collect()
}

/// `f·cos θi` of `m` through the f32 batch kernels at the current SIMD level.
fn batch_values(m: &Material, inp: &Inputs) -> Vec<[f64; 3]> {
    let n = inp.wi[0].len();
    let mut f = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    {
        let [r, g, b] = &mut f;
        let fv = Dst3::soa(r, g, b).expect("equal lengths");
        let wi = Src3::soa(&inp.wi[0], &inp.wi[1], &inp.wi[2]).expect("equal lengths");
        let wo = Src3::soa(&inp.wo[0], &inp.wo[1], &inp.wo[2]).expect("equal lengths");
        batch::eval_pdf(m, &wi, &wo, None, Some(&fv), None).expect("sized");
    }
    (0..n).map(|i| [0, 1, 2].map(|c| f64::from(f[c][i]) * f64::from(inp.wi[2][i]))).collect()
}

/// One configuration a material can run in, with its measured cost and error.
#[derive(Clone, Debug, Serialize)]
pub struct Configuration {
    /// What it is: the evaluation path and any parameter overrides.
    pub name: String,
    /// The material JSON this configuration evaluates.
    pub material: serde_json::Value,
    /// `f64` (scalar reference calls), `f32` (scalar calls) or `f32 batch <simd>`.
    pub path: String,
    /// ns per eval (batch: per element, one thread).
    pub ns_per_eval: f64,
    /// Error of `f·cos θi` against the f64 reference of the original material.
    pub error: ErrorStats,
}

/// Parameter overrides that make a model cheaper by dropping or simplifying a lobe, tried by
/// [`choose`] (each kept only if the error stays within the tolerance).
fn cheaper_overrides(model: &str) -> &'static [(&'static str, &'static str)] {
    match model {
        "rough_conductor" | "cook_torrance" => &[("no multiple-scattering lobe", r#"{"multiple_scattering": false}"#)],
        "coated_paint" => &[
            ("no sparkle", r#"{"sparkle": false}"#),
            ("no coat absorption", r#"{"coat_absorption": [0, 0, 0]}"#),
            ("no pearlescent flakes", r#"{"pearl_density": 0}"#),
            ("no metallic flakes", r#"{"flake_density": 0}"#),
            ("no metallic base", r#"{"base_metallic": 0}"#),
        ],
        "principled" => &[("no coat", r#"{"coat_weight": 0}"#), ("no thin film", r#"{"thin_film_thickness": 0}"#)],
        _ => &[],
    }
}

fn with_override(m: &Material, patch: &str) -> Option<Material> {
    let mut json = m.to_json();
    let patch: serde_json::Value = serde_json::from_str(patch).ok()?;
    let (obj, p) = (json.as_object_mut()?, patch.as_object()?);
    for (k, v) in p {
        if !obj.contains_key(k) {
            return None; // not a parameter of this material
        }
        obj.insert(k.clone(), v.clone());
    }
    let next = Material::from_value(&json).ok()?;
    // Already at that value: not a different configuration.
    (next.to_json() != m.to_json()).then_some(next)
}

fn time_batch_eval(m: &Material, inp: &Inputs, reps: usize) -> f64 {
    let n = inp.wi[0].len();
    let mut f = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    let [r, g, b] = &mut f;
    let fv = Dst3::soa(r, g, b).expect("equal lengths");
    let wi = Src3::soa(&inp.wi[0], &inp.wi[1], &inp.wi[2]).expect("equal lengths");
    let wo = Src3::soa(&inp.wo[0], &inp.wo[1], &inp.wo[2]).expect("equal lengths");
    time(reps, n, || {
        black_box(batch::eval_pdf(m, &wi, &wo, None, Some(&fv), None).expect("sized"));
    })
    .min_ns
}

fn time_f64_calls(m: &Material, inp: &Inputs, reps: usize) -> f64 {
    let k = inp.wi[0].len().min(1 << 14);
    time(reps, k, || {
        for i in 0..k {
            let wi = Vec3::new(inp.wi[0][i], inp.wi[1][i], inp.wi[2][i]).cast::<f64>();
            let wo = Vec3::new(inp.wo[0][i], inp.wo[1][i], inp.wo[2][i]).cast::<f64>();
            black_box(m.eval(wi, wo));
        }
    })
    .min_ns
}

/// The outcome of [`choose`]: every configuration measured and the one picked.
#[derive(Clone, Debug, Serialize)]
pub struct Choice {
    /// The tolerance on the maximum relative error.
    pub max_error: f64,
    /// The cheapest configuration whose maximum error is within the tolerance (the f64
    /// reference itself when nothing else is).
    pub picked: Configuration,
    /// Every configuration tried, cheapest first.
    pub candidates: Vec<Configuration>,
}

/// "Model only what a scene needs", measured: evaluates `m` in every configuration the
/// library offers (the f64 reference, the f32 SIMD batch kernels, and the f32 kernels with
/// lobes dropped or simplified that the material does not need), measures each one's cost and
/// its error against the f64 reference of `m` on `n` random direction pairs, and picks the
/// cheapest whose maximum error is at most `max_error`. Restores the process-wide SIMD level.
#[must_use]
pub fn choose(m: &Material, max_error: f64, n: usize) -> Choice {
    let inp = inputs(n.max(256));
    let reference = reference_values(m, &inp);
    let reps = 3;
    let simd = batch::simd_level();
    let mut candidates = vec![Configuration {
        name: "f64 reference".into(),
        material: m.to_json(),
        path: "f64".into(),
        ns_per_eval: time_f64_calls(m, &inp, reps),
        error: ErrorStats::default(),
    }];
    let batch_config = |name: String, mat: &Material| Configuration {
        name,
        material: mat.to_json(),
        path: format!("f32 batch {}", simd.name()),
        ns_per_eval: time_batch_eval(mat, &inp, reps),
        error: error_stats(&batch_values(mat, &inp), &reference),
    };
    candidates.push(batch_config("f32 batch".into(), m));
    // Greedy: drop lobes one after another while the error stays within the tolerance.
    let mut current = m.clone();
    let mut dropped: Vec<&str> = Vec::new();
    for (what, patch) in cheaper_overrides(m.info().name) {
        let Some(next) = with_override(&current, patch) else {
            continue;
        };
        dropped.push(what);
        let c = batch_config(format!("f32 batch, {}", dropped.join(", ")), &next);
        if c.error.max <= max_error {
            current = next;
        } else {
            dropped.pop();
        }
        candidates.push(c);
    }
    candidates.sort_by(|a, b| a.ns_per_eval.total_cmp(&b.ns_per_eval));
    let picked =
        candidates.iter().find(|c| c.error.max <= max_error).cloned().unwrap_or_else(|| {
            candidates.iter().find(|c| c.path == "f64").cloned().expect("the reference is a candidate")
        });
    Choice { max_error, picked, candidates }
}

/// One row of the speed-vs-error report.
#[derive(Clone, Debug, Serialize)]
pub struct ReportRow {
    /// The model or approximation.
    pub what: String,
    /// What is compared with what.
    pub comparison: String,
    /// ns per eval of the cheaper side (f32 batch, one thread, SIMD level as detected).
    pub ns_fast: f64,
    /// ns per eval of the reference side.
    pub ns_reference: f64,
    /// Error of the cheaper side against the reference.
    pub error: ErrorStats,
}

/// The speed-vs-error report: every model's f32 batch path against its f64 reference, and
/// each approximation the library offers against the exact form it replaces. Every time is
/// one thread's (the batch calls run with [`batch::set_thread_count`] 1, restored after), the
/// minimum of 7 calls.
#[must_use]
pub fn speed_error_report(n: usize) -> Vec<ReportRow> {
    let saved_threads = batch::thread_count();
    batch::set_thread_count(1);
    let rows = speed_error_rows(n);
    batch::set_thread_count(saved_threads);
    rows
}

fn speed_error_rows(n: usize) -> Vec<ReportRow> {
    let inp = inputs(n.max(256));
    // Seven calls, not three: with three the minimum still moved 2× between runs on a shared
    // machine (e.g. `rough_conductor` 6.6 / 12.6 ns, two threads).
    let reps = 7;
    let mut rows = Vec::new();
    let simd = batch::simd_level().name();
    for info in crate::models::all() {
        let Ok(m) = Material::default_of(info) else { continue };
        let reference = reference_values(&m, &inp);
        rows.push(ReportRow {
            what: info.name.to_string(),
            comparison: format!("f32 batch ({simd}) vs f64 reference"),
            ns_fast: time_batch_eval(&m, &inp, reps),
            ns_reference: time_f64_calls(&m, &inp, reps),
            error: error_stats(&batch_values(&m, &inp), &reference),
        });
    }
    // Approximations, each against the exact form (both f64 for the error; the cost is the
    // f32 batch cost of each side).
    let pairs: &[(&str, &str, &str, &str)] = &[
        (
            "Kulla-Conty compensation (rough_conductor GGX α 0.5, F = 1)",
            "single scattering vs with the multiple-scattering lobe",
            r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.5, "alpha_v": 0.5}"#,
            r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.5, "alpha_v": 0.5, "multiple_scattering": true}"#,
        ),
        (
            "Tabulated exponent (fast_phong n = 30)",
            "fast_phong vs modified_phong",
            r#"{"model": "fast_phong", "exponent": 30}"#,
            r#"{"model": "modified_phong", "exponent": 30}"#,
        ),
        (
            "Pearl film dropped (pearl_white)",
            "pearl_density 0 vs the preset",
            r#"{"preset": "pearl_white"}"#,
            r#"{"preset": "pearl_white"}"#,
        ),
    ];
    for (what, comparison, fast, exact) in pairs {
        let (Ok(mut fast_m), Ok(exact_m)) = (Material::from_json(fast), Material::from_json(exact)) else {
            continue;
        };
        if what.starts_with("Pearl") {
            match with_override(&fast_m, r#"{"pearl_density": 0}"#) {
                Some(m) => fast_m = m,
                None => continue,
            }
        }
        let reference = reference_values(&exact_m, &inp);
        let fast_f64 = reference_values(&fast_m, &inp);
        rows.push(ReportRow {
            what: (*what).to_string(),
            comparison: (*comparison).to_string(),
            ns_fast: time_batch_eval(&fast_m, &inp, reps),
            ns_reference: time_batch_eval(&exact_m, &inp, reps),
            error: error_stats(&fast_f64, &reference),
        });
    }
    // The conductor Fresnel's fits, which only the SIMD lanes use (AVX-512: 32 quintic pieces
    // in μ; AVX2: 8 pieces of degree 7 in √μ): the GGX gold conductor's f32 batch eval with
    // the fit of this CPU's level against the same model with the exact formula everywhere
    // (timed side by side); error of the fitted batch against the f64 reference.
    let ggx_au =
        r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2, "material": "Au"}"#;
    if let Ok(fitted) = Material::from_json(ggx_au) {
        if let crate::models::Model::RoughConductor(rc) = fitted.model() {
            let exact_model =
                crate::models::rough_conductor::RoughConductor { fresnel: rc.fresnel.exact_only(), ..rc.clone() };
            let exact = Material::from_parts(
                fitted.info(),
                fitted.params().clone(),
                crate::models::Model::RoughConductor(exact_model),
            );
            let reference = reference_values(&fitted, &inp);
            let exact_error = error_stats(&batch_values(&exact, &inp), &reference);
            rows.push(ReportRow {
                what: "Conductor Fresnel fit (AVX-512: 32 quintic pieces in μ; AVX2: 8 degree-7 pieces in √μ)".into(),
                comparison: format!(
                    "GGX gold batch eval at {}, fit vs exact formula; error vs f64 (exact formula in f32: max {:.1e}, rms {:.1e}; fits alone {:.1e} (AVX-512), {:.1e} (AVX2))",
                    crate::batch::simd_level().name(),
                    exact_error.max,
                    exact_error.rms,
                    rc.fresnel.fit_error().unwrap_or(f64::NAN),
                    rc.fresnel.fit8_error().unwrap_or(f64::NAN)
                ),
                ns_fast: time_batch_eval(&fitted, &inp, reps),
                ns_reference: time_batch_eval(&exact, &inp, reps),
                error: error_stats(&batch_values(&fitted, &inp), &reference),
            });
        }
    }
    // Schlick's approximation against the exact conductor Fresnel (gold, per channel, over
    // cos θ), and the polynomial exp / sin / cos of the SIMD lanes against f64 (in the lane
    // tests: `lanes::x86` tests report their maxima).
    let au = crate::fresnel::metal("Au").expect("gold is listed");
    let (mut test, mut refv) = (Vec::new(), Vec::new());
    for i in 0..=1000 {
        let c = i as f64 / 1000.0;
        let exact = [0, 1, 2].map(|k| crate::fresnel::conductor(c, au.eta[k], au.k[k]));
        let f0 = [0, 1, 2].map(|k| crate::fresnel::conductor(1.0, au.eta[k], au.k[k]));
        test.push([0, 1, 2].map(|k| crate::fresnel::schlick(c, f0[k])));
        refv.push(exact);
    }
    let t_schlick = time(reps, 1 << 16, || {
        for i in 0..(1 << 16) {
            black_box(crate::fresnel::schlick(black_box((i as f32) * 1.5e-5), 0.9f32));
        }
    });
    let t_exact = time(reps, 1 << 16, || {
        for i in 0..(1 << 16) {
            black_box(crate::fresnel::conductor(black_box((i as f32) * 1.5e-5), 0.14f32, 3.98));
        }
    });
    rows.push(ReportRow {
        what: "Schlick Fresnel (gold, F0 from the exact value)".into(),
        comparison: "schlick(cos, F0) vs exact conductor Fresnel, 1001 cosines, per scalar f32 call".into(),
        ns_fast: t_schlick.min_ns,
        ns_reference: t_exact.min_ns,
        error: error_stats(&test, &refv),
    });
    rows
}
