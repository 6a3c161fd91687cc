//! ns/eval, ns/sample for every model at its defaults, f32 and f64 (criterion).
//! Run: `cargo bench -p lacquer --bench eval`

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use lacquer::rng::Pcg32;
use lacquer::{models, Material, Vec3};

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

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_millis(800));
    targets = bench_models, bench_paint
}
criterion_main!(benches);
