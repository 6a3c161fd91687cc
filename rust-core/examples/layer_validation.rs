//! Measures the analytic coated-paint model against the position-free Monte Carlo reference of
//! the same layer stack (`lacquer::paint::position_free_mc`) and writes the tables into
//! `docs/paint-validation.md` (between the `layer_validation` markers).
//!
//! `cargo run --release -p lacquer --example layer_validation [-- --walks N] [--no-write]`
//!
//! Per configuration: BRDF slices in the plane of incidence at θo = 0°, 30°, 60°, 75° (θi from
//! −85° to 85° in 5° steps, negative = back-scattering side), compared on the light that
//! crosses the top surface ("body": `f − f_top`; the top reflection is the same formula in
//! both and is excluded), the directional albedo (top reflection included), and the cost.

use lacquer::check::furnace::albedo as analytic_albedo;
use lacquer::frame::spherical_direction;
use lacquer::paint::coated_paint::CoatedPaint;
use lacquer::paint::position_free_mc::PositionFreeMc;
use lacquer::paint::rough_dielectric::{Lobes, RoughDielectric};
use lacquer::rng::Pcg32;
use lacquer::{Bxdf, Material, Model, Rgb, Vec3};
use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

const CONFIGS: &[(&str, &str)] = &[
    ("solid, smooth coat", r#"{"coat_roughness": 0, "flake_density": 0}"#),
    ("solid, rough coat α 0.1", r#"{"coat_roughness": 0.1, "flake_density": 0}"#),
    ("solid, rough coat α 0.3", r#"{"coat_roughness": 0.3, "flake_density": 0}"#),
    ("Al flakes 3 %", r#"{"flake_density": 3}"#),
    ("Al flakes 8 %", r#"{"flake_density": 8}"#),
    ("Au flakes 8 %", r#"{"flake_density": 8, "flake_material": "Au", "base_color": [0.35, 0.2, 0.03]}"#),
    (
        "pearlescent 15 %, 300 nm",
        r#"{"flake_density": 0, "pearl_density": 15, "pearl_film_nm": 300, "base_color": [0.05, 0.05, 0.08]}"#,
    ),
    ("lossless white, smooth", r#"{"base_color": 1.0, "flake_density": 0, "coat_roughness": 0}"#),
    ("lossless white, rough α 0.3", r#"{"base_color": 1.0, "flake_density": 0, "coat_roughness": 0.3}"#),
    (
        "absorbing coat",
        r#"{"base_color": 0.8, "flake_density": 0, "coat_roughness": 0, "coat_absorption": [5, 10, 20], "coat_thickness_um": 100}"#,
    ),
];

const THETA_O: [f64; 4] = [0.0, 30.0, 60.0, 75.0];
const ALBEDO_THETA: [f64; 6] = [0.0, 30.0, 45.0, 60.0, 75.0, 85.0];

fn dir(theta_deg: f64, phi: f64) -> Vec3<f64> {
    let t = theta_deg.to_radians();
    spherical_direction(t.sin(), t.cos(), phi)
}

/// `wi` in the plane of incidence of `wo` (which lies at φ = 0): signed angle, positive on
/// the mirror side.
fn in_plane(theta_signed_deg: f64) -> Vec3<f64> {
    let t = theta_signed_deg.to_radians();
    Vec3::new(-t.sin(), 0.0, t.cos())
}

struct SliceStats {
    rel_lum: Vec<f64>,
    worst_channel: f64,
    noise: Vec<f64>,
    z: Vec<f64>,
    per_slice: Vec<(f64, f64)>,
}

/// θo, analytic albedo, reference albedo and its standard error.
type AlbedoRow = (f64, Rgb<f64>, Rgb<f64>, Rgb<f64>);

struct Row {
    name: &'static str,
    slices: SliceStats,
    /// θo, analytic albedo, reference albedo.
    albedo: Vec<AlbedoRow>,
    ns_analytic_f64: f64,
    ns_analytic_f32: f64,
    ns_walk: f64,
    walk_rel_sd: f64,
}

fn paint_of(m: &Material) -> &CoatedPaint {
    match m.model() {
        Model::CoatedPaint(p) => p,
        _ => unreachable!("coated_paint material"),
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        0.0
    } else {
        v[v.len() / 2]
    }
}

fn time_analytic(p: &CoatedPaint) -> (f64, f64) {
    let mut rng = Pcg32::new(1, 1);
    let pairs: Vec<(Vec3<f64>, Vec3<f64>)> = (0..4096)
        .map(|_| {
            (
                dir(rng.range(0.0, 89.0), rng.range(0.0, std::f64::consts::TAU)),
                dir(rng.range(0.0, 89.0), rng.range(0.0, std::f64::consts::TAU)),
            )
        })
        .collect();
    let pairs32: Vec<(Vec3<f32>, Vec3<f32>)> = pairs.iter().map(|(a, b)| (a.cast(), b.cast())).collect();
    // The fastest of 7 repetitions: the machine is shared, and interference only adds time.
    let reps = 10;
    let (mut ns64, mut ns32) = (f64::INFINITY, f64::INFINITY);
    let (mut acc, mut acc32) = (0.0, 0.0f32);
    for _ in 0..7 {
        let t = Instant::now();
        for _ in 0..reps {
            for (wi, wo) in &pairs {
                acc += black_box(p.eval(black_box(*wi), black_box(*wo))).r;
            }
        }
        ns64 = ns64.min(t.elapsed().as_nanos() as f64 / (reps * pairs.len()) as f64);
        let t = Instant::now();
        for _ in 0..reps {
            for (wi, wo) in &pairs32 {
                acc32 += black_box(p.eval(black_box(*wi), black_box(*wo))).r;
            }
        }
        ns32 = ns32.min(t.elapsed().as_nanos() as f64 / (reps * pairs.len()) as f64);
    }
    black_box((acc, acc32));
    (ns64, ns32)
}

fn measure(name: &'static str, json: &str, walks: usize) -> Row {
    let full = format!(r#"{{"model": "coated_paint", {}"#, &json[1..]);
    let material = Material::from_json(&full).expect("valid material");
    let p = paint_of(&material);
    let mc = PositionFreeMc::new(p);

    let mut slices =
        SliceStats { rel_lum: Vec::new(), worst_channel: 0.0, noise: Vec::new(), z: Vec::new(), per_slice: Vec::new() };
    let mut walk_time = 0.0;
    let mut walk_count = 0usize;
    let mut rel_sd = Vec::new();
    let mut seed = 0;
    for &to in &THETA_O {
        let wo = dir(to, 0.0);
        let (mut sum, mut max) = (0.0, 0.0f64);
        let mut count = 0;
        for k in 0..=34 {
            let ts = -85.0 + 5.0 * k as f64;
            let wi = in_plane(ts);
            seed += 1;
            let t = Instant::now();
            let r = mc.eval(wi, wo, walks, seed);
            walk_time += t.elapsed().as_secs_f64();
            walk_count += walks;
            let top = mc.top_reflection(wi, wo);
            let body_ref = r.value - Rgb::splat(top);
            let body_an = p.eval(wi, wo) - Rgb::splat(p.coat().reflection_eval(wi, wo));
            let (yr, ya) = (body_ref.luminance(), body_an.luminance());
            if yr <= 0.0 {
                continue;
            }
            let e = (ya - yr).abs() / yr;
            sum += e;
            max = max.max(e);
            count += 1;
            slices.rel_lum.push(e);
            slices.noise.push(r.std_error.luminance() / yr);
            slices.z.push((ya - yr).abs() / r.std_error.luminance().max(1e-300));
            rel_sd.push(r.std_error.luminance() * (walks as f64).sqrt() / yr);
            let floor = 1e-3 * body_ref.max_channel();
            for c in 0..3 {
                let ec = (body_an[c] - body_ref[c]).abs() / body_ref[c].max(floor);
                slices.worst_channel = slices.worst_channel.max(ec);
            }
        }
        slices.per_slice.push((sum / count.max(1) as f64, max));
    }

    let mut albedo = Vec::new();
    for (k, &to) in ALBEDO_THETA.iter().enumerate() {
        let wo = dir(to, 0.0);
        let mut rng = Pcg32::new(77, k as u64);
        let (a, _) = analytic_albedo(&material, wo, 1 << 16, &mut rng);
        let r = mc.albedo(wo, 20 * walks, 1000 + k as u64);
        albedo.push((to, Rgb::from_array(a), r.value, r.std_error));
    }
    let (ns_analytic_f64, ns_analytic_f32) = time_analytic(p);
    // Walks needed for 1 % noise: mean of σ_rel² over the slice points (RMS), i.e. the walk
    // count that gives 1 % RMS relative noise over the slices.
    let ms = rel_sd.iter().map(|s| s * s).sum::<f64>() / rel_sd.len().max(1) as f64;
    Row {
        name,
        slices,
        albedo,
        ns_analytic_f64,
        ns_analytic_f32,
        ns_walk: walk_time * 1e9 / walk_count as f64,
        walk_rel_sd: ms.sqrt(),
    }
}

fn pct(x: f64) -> String {
    if x < 0.001 {
        format!("{:.3} %", 100.0 * x)
    } else if x < 0.1 {
        format!("{:.2} %", 100.0 * x)
    } else {
        format!("{:.1} %", 100.0 * x)
    }
}

fn sci(x: f64) -> String {
    if x >= 1e4 {
        let e = x.log10().floor();
        format!("{:.1}e{}", x / 10f64.powf(e), e as i32)
    } else {
        format!("{x:.0}")
    }
}

fn report(rows: &[Row], walks: usize, seconds: f64) -> String {
    let mut s = String::new();
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -p lacquer --example layer_validation -- --walks {walks}` \
         on {cpu}, {cores} cores shared with other jobs (timings are indicative), single-threaded, {seconds:.0} s.\n"
    );
    let _ = writeln!(s, "### BRDF slices (light that crosses the top surface)\n");
    let _ = writeln!(
        s,
        "Relative error of the analytic body term `f − f_top` against the reference, Rec.709 \
         luminance, over 4 slices × 35 directions (θo = 0°, 30°, 60°, 75°; θi = −85°…85° in the \
         plane of incidence); `worst ch.` is the largest per-channel relative error (floored at \
         10⁻³ of the point's largest channel); `noise` is the median relative standard error of the \
         reference ({walks} walks per point); `|Δ|/σ` the mean error in units of the reference's standard \
         error (about 0.8 when the difference is noise alone).\n"
    );
    let _ = writeln!(
        s,
        "| configuration | mean | max | worst ch. | noise | \\|Δ\\|/σ | θo 0° mean/max | θo 30° | θo 60° | θo 75° |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let mean = r.slices.rel_lum.iter().sum::<f64>() / r.slices.rel_lum.len().max(1) as f64;
        let max = r.slices.rel_lum.iter().cloned().fold(0.0, f64::max);
        let mut noise = r.slices.noise.clone();
        let z = r.slices.z.iter().sum::<f64>() / r.slices.z.len().max(1) as f64;
        let _ = write!(
            s,
            "| {} | {} | {} | {} | {} | {:.1} |",
            r.name,
            pct(mean),
            pct(max),
            pct(r.slices.worst_channel),
            pct(median(&mut noise)),
            z
        );
        for (m, x) in &r.slices.per_slice {
            let _ = write!(s, " {} / {} |", pct(*m), pct(*x));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "\n### Directional albedo (top reflection included)\n");
    let _ = writeln!(
        s,
        "Analytic albedo (furnace estimator, 65 536 stratified samples) and reference albedo \
         (analogue walks, {} per angle), luminance; `max abs. diff` is the largest absolute difference of \
         any channel over the angles.\n",
        20 * walks
    );
    let _ = write!(s, "| configuration |");
    for t in ALBEDO_THETA {
        let _ = write!(s, " θo {t}° analytic / ref |");
    }
    let _ = writeln!(s, " max abs. diff (ch, θo) |");
    let _ = writeln!(s, "|---|{}---|", "---|".repeat(ALBEDO_THETA.len()));
    for r in rows {
        let _ = write!(s, "| {} |", r.name);
        let (mut worst, mut at) = (0.0f64, (0usize, 0.0));
        for (t, a, rf, _) in &r.albedo {
            let _ = write!(s, " {:.4} / {:.4} |", a.luminance(), rf.luminance());
            for c in 0..3 {
                let d = (a[c] - rf[c]).abs();
                if d > worst {
                    worst = d;
                    at = (c, *t);
                }
            }
        }
        let _ = writeln!(s, " {:.4} ({}, {}°) |", worst, ["R", "G", "B"][at.0], at.1);
    }
    let _ = writeln!(s, "\n### Cost\n");
    let _ = writeln!(
        s,
        "`analytic` is one `eval` (f64 / f32) at random direction pairs (fastest of 7 repetitions); `walk` one reference walk; \
         `σ/walk` the RMS over the slice points of one walk's relative standard deviation (luminance); \
         a reference evaluation at 1 % noise needs `(σ/walk / 0.01)²` walks; `ratio` = its cost / \
         the f64 analytic eval.\n"
    );
    let _ = writeln!(
        s,
        "| configuration | analytic f64 | analytic f32 | walk | σ/walk | walks for 1 % | reference at 1 % | ratio |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for r in rows {
        let walks1 = (r.walk_rel_sd / 0.01).powi(2).max(1.0);
        let ns_ref = walks1 * r.ns_walk;
        let _ = writeln!(
            s,
            "| {} | {:.0} ns | {:.0} ns | {:.0} ns | {:.2} | {} | {:.2} ms | {} |",
            r.name,
            r.ns_analytic_f64,
            r.ns_analytic_f32,
            r.ns_walk,
            r.walk_rel_sd,
            sci(walks1.ceil()),
            ns_ref * 1e-6,
            sci(ns_ref / r.ns_analytic_f64)
        );
    }
    s
}

/// Energy the reference's rough interface keeps (`R + T`, transmission counted as energy, not
/// radiance) for one crossing from outside and from inside, by its own sampler.
fn interface_energy() -> String {
    let mut s = String::new();
    let mus = [1.0, 0.7, 0.5, 0.3, 0.1];
    let _ = writeln!(s, "\n### Energy kept by the reference's rough interface\n");
    let _ = writeln!(
        s,
        "The reference's top is Walter et al.'s single-scattering microfacet dielectric (η 1.5): \
         light that would scatter more than once on the microsurface is lost, most of all from \
         inside the coat, where steep facets reflect light back up into the microsurface. `R + T` \
         (energy) per crossing, 10⁶ samples each; 1 − value is lost per interaction.\n"
    );
    let _ = write!(s, "| α | side |");
    for mu in mus {
        let _ = write!(s, " μ {mu} |");
    }
    let _ = writeln!(s, "\n|---|---|{}", "---|".repeat(mus.len()));
    for alpha in [0.02, 0.1, 0.3] {
        let top = RoughDielectric { eta: 1.5, alpha };
        for (side, name) in [(1.0f64, "outside"), (-1.0, "inside")] {
            let _ = write!(s, "| {alpha} | {name} |");
            let mut rng = Pcg32::new(5, 5);
            for mu in mus {
                let wo = Vec3::new((1.0f64 - mu * mu).sqrt(), 0.0, side * mu);
                let n = 1_000_000;
                let mut e = 0.0;
                for _ in 0..n {
                    if let Some(smp) = top.sample(wo, rng.uniform3(), Lobes::All) {
                        // Radiance transmission carries (η_o/η_i)²; energy does not.
                        let scale = if smp.wi.z * wo.z > 0.0 {
                            1.0
                        } else if wo.z > 0.0 {
                            2.25
                        } else {
                            1.0 / 2.25
                        };
                        e += smp.weight * scale;
                    }
                }
                let _ = write!(s, " {:.3} |", e / n as f64);
            }
            let _ = writeln!(s);
        }
    }
    s
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let walks = args
        .iter()
        .position(|a| a == "--walks")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000usize);
    let write = !args.iter().any(|a| a == "--no-write");
    let only: Option<String> = args.iter().position(|a| a == "--only").and_then(|i| args.get(i + 1)).cloned();
    let start = Instant::now();
    let mut rows = Vec::new();
    for (name, json) in CONFIGS {
        if only.as_ref().is_some_and(|o| !name.contains(o.as_str())) {
            continue;
        }
        let t = Instant::now();
        rows.push(measure(name, json, walks));
        eprintln!("{name}: {:.1} s", t.elapsed().as_secs_f64());
    }
    let mut text = report(&rows, walks, start.elapsed().as_secs_f64());
    text.push_str(&interface_energy());
    println!("{text}");
    if write && only.is_none() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/paint-validation.md");
        replace_section(&path, "layer_validation", &text);
        eprintln!("wrote {}", path.display());
    }
}

/// Replaces the text between `<!-- NAME:begin -->` and `<!-- NAME:end -->` (appends the
/// section when the markers are missing).
fn replace_section(path: &std::path::Path, name: &str, body: &str) {
    let (begin, end) = (format!("<!-- {name}:begin -->"), format!("<!-- {name}:end -->"));
    let old = std::fs::read_to_string(path).unwrap_or_default();
    let new = match (old.find(&begin), old.find(&end)) {
        (Some(b), Some(e)) if e > b => format!("{}{begin}\n{body}{}", &old[..b], &old[e..]),
        _ => format!("{old}\n{begin}\n{body}{end}\n"),
    };
    std::fs::write(path, new).expect("write docs/paint-validation.md");
}
