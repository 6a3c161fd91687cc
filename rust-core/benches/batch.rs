//! ns/element of the batch kernels (structure of arrays, f32, one thread) at every SIMD level
//! this CPU has, for the lane models and presets, and for a model without a lane kernel (the
//! element loop behind the same call).
//! Run: `cargo bench -p lacquer --bench batch` (`-- rough_conductor` for one group).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use lacquer::batch::{self, Dst1, Dst3, SampleOut, SimdLevel, Src3};
use lacquer::rng::Pcg32;
use lacquer::Material;

const N: usize = 16 * 1024;

const MATERIALS: &[(&str, &str)] = &[
    ("lambert", r#"{"model": "lambert"}"#),
    (
        "rough_conductor_ggx",
        r#"{"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2, "material": "Au"}"#,
    ),
    ("rough_conductor_beckmann", r#"{"model": "rough_conductor", "alpha_u": 0.2, "alpha_v": 0.2, "material": "Au"}"#),
    ("ward_no_lane_kernel", r#"{"model": "ward"}"#),
];

fn soa(rng: &mut Pcg32) -> [Vec<f32>; 3] {
    let mut v = [Vec::with_capacity(N), Vec::with_capacity(N), Vec::with_capacity(N)];
    for _ in 0..N {
        let w = lacquer::sampling::cosine_hemisphere::<f64>(rng.uniform(), rng.uniform());
        v[0].push(w.x as f32);
        v[1].push(w.y as f32);
        v[2].push(w.z as f32);
    }
    v
}

fn bench_batch(c: &mut Criterion) {
    let mut rng = Pcg32::new(3, 4);
    let (wi, wo) = (soa(&mut rng), soa(&mut rng));
    let u: [Vec<f32>; 3] = [0, 1, 2].map(|_| (0..N).map(|_| rng.uniform() as f32).collect());
    let (wi_v, wo_v) = (Src3::soa(&wi[0], &wi[1], &wi[2]).unwrap(), Src3::soa(&wo[0], &wo[1], &wo[2]).unwrap());
    let u_v = Src3::soa(&u[0], &u[1], &u[2]).unwrap();
    let mut presets: Vec<(String, Material)> =
        MATERIALS.iter().map(|(n, j)| (n.to_string(), Material::from_json(j).unwrap())).collect();
    for p in ["gold_flake_8", "solid_red", "pearl_white"] {
        presets.push((format!("preset_{p}"), Material::preset(p).unwrap()));
    }
    batch::set_thread_count(1);
    for (name, m) in &presets {
        let mut g = c.benchmark_group(format!("batch/{name}"));
        g.throughput(criterion::Throughput::Elements(N as u64));
        for level in [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512] {
            if !batch::set_simd_level(level) {
                continue;
            }
            let mut f = [vec![0.0f32; N], vec![0.0f32; N], vec![0.0f32; N]];
            let mut p = vec![0.0f32; N];
            let mut w = [vec![0.0f32; N], vec![0.0f32; N], vec![0.0f32; N]];
            g.bench_function(format!("eval_{}", level.name()), |b| {
                let [r, gg, bl] = &mut f;
                let fv = Dst3::soa(r, gg, bl).unwrap();
                b.iter(|| black_box(batch::eval_pdf(m, &wi_v, &wo_v, None, Some(&fv), None).unwrap()))
            });
            g.bench_function(format!("pdf_{}", level.name()), |b| {
                let pv = Dst1::new(&mut p);
                b.iter(|| black_box(batch::eval_pdf(m, &wi_v, &wo_v, None, None, Some(&pv)).unwrap()))
            });
            g.bench_function(format!("sample_{}", level.name()), |b| {
                let [r, gg, bl] = &mut f;
                let [x, y, z] = &mut w;
                let mut out = SampleOut {
                    wi: Dst3::soa(x, y, z).unwrap(),
                    weight: Dst3::soa(r, gg, bl).unwrap(),
                    pdf: Dst1::new(&mut p),
                    flags: None,
                };
                b.iter(|| black_box(batch::sample(m, &wo_v, &u_v, None, &mut out).unwrap()))
            });
        }
        g.finish();
    }
    batch::set_simd_level(SimdLevel::detect());
    batch::set_thread_count(0);
}

criterion_group!(benches, bench_batch);
criterion_main!(benches);
