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
