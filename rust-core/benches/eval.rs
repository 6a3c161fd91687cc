//! ns/eval, ns/sample for every model at its defaults, f32 and f64 (criterion), and the
//! sparkle path of the coated paint (`eval_at`, `sample_at`).
//! Run: `cargo bench -p lacquer --bench eval` (`-- sparkle` for the sparkle group only).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use lacquer::rng::Pcg32;
use lacquer::{models, Material, SurfacePoint, Vec3};

fn directions(n: usize) -> Vec<(Vec3<f64>, Vec3<f64>, [f64; 3])> {
    let mut rng = Pcg32::new(1, 2);
    (0..n)
        .map(|_| {
            let a = lacquer::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
            let b = lacquer::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
            (a, b, rng.uniform3())
        })
        .collect()
}

fn bench_models(c: &mut Criterion) {
    let dirs64 = directions(1024);
    let dirs32: Vec<_> =
        dirs64.iter().map(|(a, b, u)| (a.cast::<f32>(), b.cast::<f32>(), u.map(|x| x as f32))).collect();
    for info in models::all() {
        let m = Material::default_of(info).expect("defaults build");
        let mut g = c.benchmark_group(info.name);
        g.throughput(criterion::Throughput::Elements(dirs64.len() as u64));
        g.bench_function("eval_f32", |b| {
            b.iter(|| {
                for (wi, wo, _) in &dirs32 {
                    black_box(m.model().eval(black_box(*wi), black_box(*wo)));
                }
            })
        });
        g.bench_function("eval_f64", |b| {
            b.iter(|| {
                for (wi, wo, _) in &dirs64 {
                    black_box(m.model().eval(black_box(*wi), black_box(*wo)));
                }
            })
        });
        g.bench_function("sample_f32", |b| {
            b.iter(|| {
                for (_, wo, u) in &dirs32 {
                    black_box(m.model().sample(black_box(*wo), black_box(*u)));
                }
            })
        });
        g.finish();
    }
}

/// The coated paint in configurations of growing complexity: a material pays only for the
/// lobes it has (no flakes, no film, no absorption → fewer lobes, less time).
fn bench_paint(c: &mut Criterion) {
    let dirs64 = directions(1024);
    let dirs32: Vec<_> =
        dirs64.iter().map(|(a, b, u)| (a.cast::<f32>(), b.cast::<f32>(), u.map(|x| x as f32))).collect();
    for preset in ["solid_red", "silver_flake_5", "gold_flake_8", "pearl_blue", "automotive_silver_metallic"] {
        let m = Material::preset(preset).expect("preset builds");
        let mut g = c.benchmark_group(format!("paint/{preset}"));
        g.throughput(criterion::Throughput::Elements(dirs64.len() as u64));
        g.bench_function("eval_f32", |b| {
            b.iter(|| {
                for (wi, wo, _) in &dirs32 {
                    black_box(m.model().eval(black_box(*wi), black_box(*wo)));
                }
            })
        });
        g.bench_function("eval_f64", |b| {
            b.iter(|| {
                for (wi, wo, _) in &dirs64 {
                    black_box(m.model().eval(black_box(*wi), black_box(*wo)));
                }
            })
        });
        g.bench_function("sample_f32", |b| {
            b.iter(|| {
                for (_, wo, u) in &dirs32 {
                    black_box(m.model().sample(black_box(*wo), black_box(*u)));
                }
            })
        });
        g.finish();
    }
    let mut g = c.benchmark_group("paint/build");
    for preset in ["solid_red", "gold_flake_8", "pearl_blue"] {
        let json = lacquer::presets::find(preset).expect("preset").json;
        g.bench_function(preset, |b| b.iter(|| black_box(Material::from_json(black_box(json)).expect("builds"))));
    }
    g.finish();
}

/// Surface points at random positions with square footprints of `side` uv units (the default
/// `surface_scale_mm` is 100 mm per uv unit, so side 1e-3 is a 0.1 mm pixel footprint).
fn surface_points(n: usize, side: f64) -> Vec<SurfacePoint> {
    let mut rng = Pcg32::new(3, 4);
    (0..n)
        .map(|_| SurfacePoint { uv: [rng.uniform(), rng.uniform()], duv_dx: [side, 0.0], duv_dy: [0.0, side] })
        .collect()
}

/// The coated paint with sparkle: `eval_at` at a close-up footprint (0.1 mm: ~1 flake per
/// footprint at the default 3 %, 20 µm), a distant one (10 mm: ~10⁴ flakes), the mean `eval`
/// and `eval_at` with sparkle off for reference, and `sample_at`.
fn bench_sparkle(c: &mut Criterion) {
    let dirs64 = directions(1024);
    let dirs32: Vec<_> =
        dirs64.iter().map(|(a, b, u)| (a.cast::<f32>(), b.cast::<f32>(), u.map(|x| x as f32))).collect();
    let sparkle = Material::from_json(r#"{"model": "coated_paint"}"#).expect("defaults build");
    let smooth = Material::from_json(r#"{"model": "coated_paint", "sparkle": false}"#).expect("builds");
    let near = surface_points(dirs64.len(), 1e-3);
    let far = surface_points(dirs64.len(), 1e-1);
    let mut g = c.benchmark_group("sparkle");
    g.throughput(criterion::Throughput::Elements(dirs64.len() as u64));
    g.bench_function("eval_f32_mean", |b| {
        b.iter(|| {
            for (wi, wo, _) in &dirs32 {
                black_box(sparkle.model().eval(black_box(*wi), black_box(*wo)));
            }
        })
    });
    for (name, points) in [("near", &near), ("far", &far)] {
        g.bench_function(format!("eval_at_f32_{name}"), |b| {
            b.iter(|| {
                for ((wi, wo, _), at) in dirs32.iter().zip(points.iter()) {
                    black_box(sparkle.model().eval_at(black_box(*wi), black_box(*wo), black_box(at)));
                }
            })
        });
        g.bench_function(format!("eval_at_f64_{name}"), |b| {
            b.iter(|| {
                for ((wi, wo, _), at) in dirs64.iter().zip(points.iter()) {
                    black_box(sparkle.model().eval_at(black_box(*wi), black_box(*wo), black_box(at)));
                }
            })
        });
    }
    g.bench_function("eval_at_f32_sparkle_off", |b| {
        b.iter(|| {
            for ((wi, wo, _), at) in dirs32.iter().zip(near.iter()) {
                black_box(smooth.model().eval_at(black_box(*wi), black_box(*wo), black_box(at)));
            }
        })
    });
    g.bench_function("sample_at_f32_near", |b| {
        b.iter(|| {
            for ((_, wo, u), at) in dirs32.iter().zip(near.iter()) {
                black_box(sparkle.model().sample_at(black_box(*wo), black_box(*u), black_box(at)));
            }
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_millis(800));
    targets = bench_models, bench_paint, bench_sparkle
}
criterion_main!(benches);
