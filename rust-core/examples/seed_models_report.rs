//! Figures for docs/seed-models.md: ns/eval of the HTSG, Poulin-Fournier and Stam models, the
//! HTSG series-truncation cost-versus-error table, and HTSG against a fitted Beckmann
//! (Cook-Torrance) lobe. A plain timing loop (no criterion): the machine load is printed with
//! the figures. Run: `cargo run --release -p lacquer --example seed_models_report`.

use lacquer::models::htsg::{series, Htsg, LAMBDA_RGB_UM};
use lacquer::rng::Pcg32;
use lacquer::sampling::uniform_hemisphere;
use lacquer::{Material, Vec3};
use std::f64::consts::PI;
use std::hint::black_box;
use std::time::Instant;

const AL_ETA: [f64; 3] = [1.65746, 0.880369, 0.521229];
const AL_K: [f64; 3] = [9.22387, 6.26952, 4.837];

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

/// Direction pairs: half uniform, half sampled from the material (so lobes are exercised).
fn pairs(m: &Material, n: usize, seed: u64) -> Vec<(Vec3<f64>, Vec3<f64>, [f64; 3])> {
    let mut rng = Pcg32::new(seed, 7);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let wo = uniform_hemisphere(rng.uniform().max(1e-3), rng.uniform());
        let u = rng.uniform3();
        let wi = if out.len() % 2 == 0 {
            uniform_hemisphere(rng.uniform().max(1e-3), rng.uniform())
        } else {
            match m.sample(wo, rng.uniform3()) {
                Some(s) if !s.delta => s.wi,
                _ => continue,
            }
        };
        out.push((wi, wo, u));
    }
    out
}

fn time_ns(reps: usize, n: usize, mut f: impl FnMut()) -> f64 {
    // Best of `reps` runs: the least disturbed by the other processes on the machine.
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_nanos() as f64 / n as f64);
    }
    best
}

fn timing() {
    println!("## ns per call (best of 5 runs over 4096 direction pairs; load average {})\n", load());
    println!("| material | eval f32 | eval f64 | pdf f64 | sample f64 |");
    println!("|---|---|---|---|---|");
    let mats = [
        ("htsg (defaults: σ₀ 0.18 µm, τ 3 µm)", r#"{"model": "htsg"}"#),
        ("htsg σ₀ 0.05 µm, τ 1 µm", r#"{"model": "htsg", "sigma0": 0.05, "tau": 1.0}"#),
        ("htsg σ₀ 1 µm, τ 10 µm", r#"{"model": "htsg", "sigma0": 1.0, "tau": 10.0}"#),
        ("htsg defaults, tolerance 1e-2", r#"{"model": "htsg", "series_tolerance": 0.01}"#),
        ("poulin_fournier (defaults: n 40)", r#"{"model": "poulin_fournier"}"#),
        ("poulin_fournier grooves, n 1000", r#"{"model": "poulin_fournier", "profile": "grooves", "exponent": 1000}"#),
        ("stam (defaults: binary CD grating)", r#"{"model": "stam"}"#),
        ("stam sine, pitch 1 µm", r#"{"model": "stam", "profile": "sine", "pitch": 1.0, "depth": 0.3}"#),
        ("stam binary, pitch 5 µm", r#"{"model": "stam", "pitch": 5.0, "depth": 0.3}"#),
        ("stam random", r#"{"model": "stam", "profile": "random"}"#),
        ("lambert (reference)", r#"{"model": "lambert"}"#),
    ];
    for (name, json) in mats {
        let m = Material::from_json(json).unwrap();
        let p = pairs(&m, 4096, 3);
        let p32: Vec<_> = p.iter().map(|(a, b, u)| (a.cast::<f32>(), b.cast::<f32>(), u.map(|x| x as f32))).collect();
        let n = p.len();
        let e32 = time_ns(5, n, || {
            for (a, b, _) in &p32 {
                black_box(m.eval(black_box(*a), black_box(*b)));
            }
        });
        let e64 = time_ns(5, n, || {
            for (a, b, _) in &p {
                black_box(m.eval(black_box(*a), black_box(*b)));
            }
        });
        let pdf = time_ns(5, n, || {
            for (a, b, _) in &p {
                black_box(m.pdf(black_box(*a), black_box(*b)));
            }
        });
        let smp = time_ns(5, n, || {
            for (_, b, u) in &p {
                black_box(m.sample(black_box(*b), black_box(*u)));
            }
        });
        println!("| {name} | {e32:.0} | {e64:.0} | {pdf:.0} | {smp:.0} |");
    }
    println!();
}

fn htsg(sigma0: f64, tau: f64, tolerance: f64) -> Htsg {
    Htsg { sigma0, tau, eta: AL_ETA, k: AL_K, diffuse: [0.0; 3], tolerance, lambda_um: LAMBDA_RGB_UM }
}

/// The directional diffuse term with the series replaced by its leading asymptotic term
/// `(1/g) e^{−A/g}` (Beckmann 1963's rough-surface limit, Westin's "rough approximation").
fn asymptotic(m: &Htsg, wi: Vec3<f64>, wo: Vec3<f64>, c: usize) -> f64 {
    let (ci, co) = (wi.z, wo.z);
    let w = ci + co;
    let dot = wi.dot(wo);
    let geo = (1.0 + dot).powi(2) / (ci * co * w * w);
    let k = 2.0 * PI / LAMBDA_RGB_UM[c];
    let kt2 = (k * m.tau).powi(2);
    let g = (k * m.effective_sigma(ci, co) * w).powi(2);
    let a = 0.25 * kt2 * ((wi.x + wo.x).powi(2) + (wi.y + wo.y).powi(2));
    let cos_local = (0.5 * (1.0 + dot)).sqrt();
    let f = lacquer::fresnel::conductor(cos_local, AL_ETA[c], AL_K[c]);
    f * m.shadowing(ci) * m.shadowing(co) * geo * kt2 / (4.0 * PI) * (-a / g).exp() / g
}

fn truncation_table() {
    println!("## HTSG series truncation: cost versus error (load average {})\n", load());
    println!("Relative error of the directional-diffuse term against ε = 1e-14, over 20 000 direction pairs");
    println!("(half uniform, half drawn by the sampler; pairs where the term is below 1e-6 of its largest value");
    println!("are left out). Terms: Σ over the three channels per evaluation. g: range of (kσw)² over the pairs.\n");
    println!("| surface | g (green, median / max) | ε | terms / eval | ns / eval | max rel. error | mean rel. error |");
    println!("|---|---|---|---|---|---|---|");
    for &(sigma0, tau) in &[(0.02, 1.0), (0.05, 1.0), (0.18, 3.0), (0.5, 5.0), (1.0, 10.0)] {
        let reference = htsg(sigma0, tau, 1e-14);
        let json = format!(r#"{{"model": "htsg", "sigma0": {sigma0}, "tau": {tau}}}"#);
        let mat = Material::from_json(&json).unwrap();
        let p = pairs(&mat, 20_000, 11);
        let exact: Vec<[f64; 3]> = p.iter().map(|(a, b, _)| reference.directional_diffuse(*a, *b).0).collect();
        let peak = exact.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
        let mut gs: Vec<f64> = p
            .iter()
            .map(|(a, b, _)| {
                let k = 2.0 * PI / LAMBDA_RGB_UM[1];
                (k * reference.effective_sigma(a.z, b.z) * (a.z + b.z)).powi(2)
            })
            .collect();
        gs.sort_by(f64::total_cmp);
        let grange = format!("{:.3} / {:.3}", gs[gs.len() / 2], gs[gs.len() - 1]);
        let row = |label: &str, f: &dyn Fn(Vec3<f64>, Vec3<f64>) -> ([f64; 3], usize)| {
            let mut terms = 0usize;
            let (mut max_err, mut sum_err, mut count) = (0.0f64, 0.0, 0usize);
            for (i, (a, b, _)) in p.iter().enumerate() {
                let (v, t) = f(*a, *b);
                terms += t;
                for c in 0..3 {
                    if exact[i][c] > 1e-6 * peak {
                        let e = (v[c] - exact[i][c]).abs() / exact[i][c];
                        max_err = max_err.max(e);
                        sum_err += e;
                        count += 1;
                    }
                }
            }
            let ns = time_ns(3, p.len(), || {
                for (a, b, _) in &p {
                    black_box(f(black_box(*a), black_box(*b)));
                }
            });
            println!(
                "| σ₀ {sigma0} µm, τ {tau} µm | {grange} | {label} | {:.1} | {ns:.0} | {max_err:.1e} | {:.1e} |",
                terms as f64 / p.len() as f64,
                sum_err / count.max(1) as f64
            );
        };
        for eps in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8] {
            let m = htsg(sigma0, tau, eps);
            row(&format!("{eps:.0e}"), &|a, b| m.directional_diffuse(a, b));
        }
        row("leading term (1/g)e^{−A/g}", &|a, b| ([0, 1, 2].map(|c| asymptotic(&reference, a, b, c)), 0));
    }
    println!();
    // The series alone, per call, at fixed (g, A): isolates the truncation from the geometry.
    println!("Series alone (one channel): terms and ns per call at A = g (one lobe width off specular).\n");
    println!("| g | ε = 1e-2 | ε = 1e-4 | ε = 1e-8 |");
    println!("|---|---|---|---|");
    for g in [0.1, 1.0, 10.0, 100.0, 1000.0, 10000.0] {
        let mut cells = Vec::new();
        for eps in [1e-2, 1e-4, 1e-8] {
            let s = series(g, g, eps);
            let ns = time_ns(5, 2000, || {
                for i in 0..2000 {
                    black_box(series(black_box(g * (1.0 + 1e-6 * i as f64)), black_box(g), eps));
                }
            });
            cells.push(format!("{} terms, {ns:.0} ns", s.terms));
        }
        println!("| {g} | {} |", cells.join(" | "));
    }
    println!();
}

fn fits() {
    println!("## HTSG against a fitted Beckmann (Cook-Torrance) lobe, green channel\n");
    println!("| surface | 2σ₀/τ | fitted α | fitted scale | relative RMS residual |");
    println!("|---|---|---|---|---|");
    for &(sigma0, tau) in &[(0.03, 1.0), (0.05, 1.0), (0.18, 3.0), (0.5, 5.0), (1.0, 8.0)] {
        let f = htsg(sigma0, tau, 1e-8).beckmann_fit(1);
        println!(
            "| σ₀ {sigma0} µm, τ {tau} µm | {:.3} | {:.3} | {:.3} | {:.3} |",
            2.0 * sigma0 / tau,
            f.alpha,
            f.scale,
            f.rel_rms
        );
    }
    println!();
}

fn main() {
    let what = std::env::args().nth(1).unwrap_or_default();
    if what.is_empty() || what == "timing" {
        timing();
    }
    if what.is_empty() || what == "truncation" {
        truncation_table();
    }
    if what.is_empty() || what == "fit" {
        fits();
    }
}
