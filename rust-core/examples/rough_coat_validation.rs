//! Measures the analytic coated-paint model under **rough** clear coats against the
//! position-free Monte Carlo reference with the lossless multiple-scattering interface
//! (Heitz et al. 2016; `lacquer::paint::rough_dielectric::RoughDielectric::sample_multiple`),
//! issue 17 item 3. Writes the table into `docs/paint-validation.md` (between the
//! `rough_coat_validation` markers) and the curves as `lacquer plot data` input to
//! `docs/data/rough-coat-validation-*.json`.
//!
//! `cargo run --release -p lacquer --example rough_coat_validation [-- --walks N] [--no-write] [--only TEXT]`
//! (`--only TEXT`: the bases whose name contains TEXT, nothing written; for iterating)
//!
//! Per configuration (coat α × base × view angle θo): the reflected lobe `f(wi, wo) cos θi`
//! binned over 12 × 6 cells of equal solid angle (cos θi × folded azimuth difference), by
//! `N` analogue reference walks and `N` samples of the analytic model's own sampler (weights
//! `f cos/pdf`, split into the top reflection and the rest by `eval_terms`). Reported:
//! - albedo error: analytic / reference − 1 of the directional albedo (luminance);
//! - lobe-shape error: the relative L2 (RMS) difference of the two lobes each normalised to
//!   unit albedo, `‖p_a − p_r‖₂ / ‖p_r‖₂` over the bins, for the whole lobe and for the light
//!   that crossed the coat ("body": walks that entered the coat; the analytic terms but the top
//!   reflection);
//! - the noise floor of both (the same quantities computed from the two estimates' standard
//!   errors alone).
//!
//! The per-cell log (stderr) also gives both albedos of the light that crossed the coat, so
//! an albedo error splits into the top reflection's and the body's, and the reference's light
//! that crossed the coat by the number of basecoat bounces before it left (1, 2, 3, 4+); the
//! model's tabulated albedos of its single-scatter layer term `A1`, the metal's bounce series
//! `S` (before the later bounces' absorption `F0^n`) and the multiple-scatter lobe `M`; and the
//! light after two or more base bounces (reference) against `S + M` (model): both albedos and
//! the lobe-shape error between them, and the light after one base bounce (reference) against
//! the single-scatter layer term without the series (model), so the first-bounce and the
//! later-bounce light can be judged apart.

use lacquer::frame::spherical_direction;
use lacquer::paint::coated_paint::CoatedPaint;
use lacquer::paint::position_free_mc::{lobe_bin, LobeHistogram, PositionFreeMc};
use lacquer::rng::Pcg32;
use lacquer::{Bxdf, Material, Model, Rgb, Vec3};
use std::fmt::Write as _;
use std::time::Instant;

const BASES: &[(&str, &str)] = &[
    ("pigment", r#""flake_density": 0, "base_color": [0.5, 0.03, 0.03]"#),
    ("Al flakes 8 %", r#""flake_density": 8, "base_color": [0.05, 0.05, 0.06]"#),
    (
        "metal base α 0.05",
        r#""flake_density": 0, "base_metallic": 1, "base_roughness": 0.05, "base_color": [0.9, 0.9, 0.9]"#,
    ),
];
const ALPHAS: [f64; 5] = [0.01, 0.03, 0.1, 0.2, 0.3];
const THETA_O: [f64; 3] = [0.0, 40.0, 75.0];
const N_MU: usize = 12;
const N_PHI: usize = 6;

fn dir(theta_deg: f64) -> Vec3<f64> {
    let t = theta_deg.to_radians();
    spherical_direction(t.sin(), t.cos(), 0.0)
}

/// `(α, error in %)` points of one base.
type Curve = Vec<(f64, f64)>;

struct Lobe {
    all: LobeHistogram,
    body: LobeHistogram,
    /// The light that left after two or more basecoat bounces: the reference's walks with
    /// `base_bounces ≥ 2`; the model's bounce series `S` plus its multiple-scatter lobe `M`
    /// (the terms that stand for those orders).
    later: LobeHistogram,
    /// The light that left after one basecoat bounce: the reference's walks that entered with
    /// `base_bounces ≤ 1`; the model's single-scatter layer term without the bounce series
    /// (`A1`'s lobe).
    first: LobeHistogram,
    /// The reference's light that crossed the coat by the number of basecoat bounces before
    /// it left (1, 2, 3, 4 or more; luminance albedo): which orders an albedo error sits in.
    by_bounces: [f64; 4],
}

fn accumulate(sum: &mut [[f64; 3]], sum2: &mut [[f64; 3]], b: usize, v: Rgb<f64>) {
    for c in 0..3 {
        sum[b][c] += v[c];
        sum2[b][c] += v[c] * v[c];
    }
}

fn reference(paint: &CoatedPaint, wo: Vec3<f64>, walks: usize, seed: u64) -> Lobe {
    let mc = PositionFreeMc::new(paint);
    let bins = N_MU * N_PHI;
    let (mut s, mut s2, mut b, mut b2) =
        (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins], vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    let mut rng = Pcg32::new(seed, 0x7c0a7);
    let mut by_bounces = [0.0; 4];
    let (mut l, mut l2) = (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    let (mut f, mut f2) = (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    for _ in 0..walks {
        let Some(exit) = mc.albedo_walk_exit(wo, &mut rng) else { continue };
        let k = lobe_bin(exit.direction, 0.0, N_MU, N_PHI);
        accumulate(&mut s, &mut s2, k, exit.weight);
        if exit.entered {
            accumulate(&mut b, &mut b2, k, exit.weight);
            by_bounces[(exit.base_bounces.max(1) as usize - 1).min(3)] += exit.weight.luminance() / walks as f64;
            if exit.base_bounces >= 2 {
                accumulate(&mut l, &mut l2, k, exit.weight);
            } else {
                accumulate(&mut f, &mut f2, k, exit.weight);
            }
        }
    }
    Lobe {
        all: LobeHistogram::from_sums(&s, &s2, walks, N_MU, N_PHI),
        body: LobeHistogram::from_sums(&b, &b2, walks, N_MU, N_PHI),
        later: LobeHistogram::from_sums(&l, &l2, walks, N_MU, N_PHI),
        first: LobeHistogram::from_sums(&f, &f2, walks, N_MU, N_PHI),
        by_bounces,
    }
}

fn analytic(paint: &CoatedPaint, wo: Vec3<f64>, samples: usize, seed: u64) -> Lobe {
    let bins = N_MU * N_PHI;
    let (mut s, mut s2, mut b, mut b2) =
        (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins], vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    let mut rng = Pcg32::new(seed, 0xa7a1);
    let (mut l, mut l2) = (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    let (mut f, mut f2) = (vec![[0.0; 3]; bins], vec![[0.0; 3]; bins]);
    for _ in 0..samples {
        let Some(smp) = paint.sample(wo, rng.uniform3()) else { continue };
        if smp.wi.z <= 0.0 || smp.delta {
            continue;
        }
        let k = lobe_bin(smp.wi, 0.0, N_MU, N_PHI);
        accumulate(&mut s, &mut s2, k, smp.weight);
        let [_, layer, multiple] = paint.eval_terms(smp.wi, wo);
        let body = (layer + multiple) * (smp.wi.z / smp.pdf);
        accumulate(&mut b, &mut b2, k, body);
        let series = paint.eval_series_term(smp.wi, wo);
        let later = (series + multiple) * (smp.wi.z / smp.pdf);
        accumulate(&mut l, &mut l2, k, later);
        accumulate(&mut f, &mut f2, k, (layer - series) * (smp.wi.z / smp.pdf));
    }
    Lobe {
        all: LobeHistogram::from_sums(&s, &s2, samples, N_MU, N_PHI),
        body: LobeHistogram::from_sums(&b, &b2, samples, N_MU, N_PHI),
        later: LobeHistogram::from_sums(&l, &l2, samples, N_MU, N_PHI),
        first: LobeHistogram::from_sums(&f, &f2, samples, N_MU, N_PHI),
        by_bounces: [0.0; 4],
    }
}

/// `(albedo a, albedo r, albedo error, its noise, lobe L2 with the noise's share removed
/// (`√max(0, L2² − floor²)`), the noise floor)` in luminance.
fn compare(a: &LobeHistogram, r: &LobeHistogram) -> [f64; 6] {
    let (la, lr) = (a.luminance(), r.luminance());
    let lum_se =
        |h: &LobeHistogram| h.std_error.iter().map(|e| Rgb::<f64>::from_array(*e).luminance()).collect::<Vec<f64>>();
    let (sa, sr) = (lum_se(a), lum_se(r));
    let (ta, tr): (f64, f64) = (la.iter().sum(), lr.iter().sum());
    let var_a: f64 = sa.iter().map(|x| x * x).sum();
    let var_r: f64 = sr.iter().map(|x| x * x).sum();
    let albedo_err = ta / tr - 1.0;
    let albedo_noise = (var_a / (ta * ta) + var_r / (tr * tr)).sqrt();
    let (mut num, mut den, mut noise) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..la.len() {
        let (pa, pr) = (la[k] / ta, lr[k] / tr);
        num += (pa - pr).powi(2);
        den += pr * pr;
        noise += (sa[k] / ta).powi(2) + (sr[k] / tr).powi(2);
    }
    [ta, tr, albedo_err, albedo_noise, ((num - noise).max(0.0) / den).sqrt(), (noise / den).sqrt()]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let walks = args
        .iter()
        .position(|a| a == "--walks")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(200_000usize);
    // `--only TEXT`: the bases whose name contains TEXT (implies --no-write; for iterating).
    let only = args.iter().position(|a| a == "--only").and_then(|i| args.get(i + 1)).cloned();
    let write = !args.iter().any(|a| a == "--no-write") && only.is_none();
    let start = Instant::now();
    let mut table = String::new();
    let mut curves: Vec<(String, Curve, Curve, Curve)> = Vec::new();
    for (base_name, base_json) in BASES.iter().filter(|(n, _)| only.as_ref().is_none_or(|o| n.contains(o.as_str()))) {
        let (mut alb, mut lobe, mut body) = (Vec::new(), Vec::new(), Vec::new());
        for &alpha in &ALPHAS {
            let json = format!(r#"{{"model": "coated_paint", "coat_roughness": {alpha}, {base_json}}}"#);
            let material = Material::from_json(&json).expect("valid material");
            let Model::CoatedPaint(paint) = material.model() else { unreachable!() };
            let mut cells = Vec::new();
            let (mut worst_alb, mut worst_lobe, mut worst_body) = (0.0f64, 0.0f64, 0.0f64);
            for (k, &theta) in THETA_O.iter().enumerate() {
                let wo = dir(theta);
                let seed = 1000 + k as u64;
                let (r, a) = (reference(paint, wo, walks, seed), analytic(paint, wo, walks, seed));
                let all = compare(&a.all, &r.all);
                let b = compare(&a.body, &r.body);
                let lt = compare(&a.later, &r.later);
                let ft = compare(&a.first, &r.first);
                if base_json.contains("base_metallic") {
                    // The reference's effective number of later metal bounces: the same walks
                    // (same seed) over a white metal give the later light without absorption,
                    // `n = ln(L_F/L_1)/ln F − 1` (the first bounce's `F` taken out; F = 0.9, the
                    // base colour above).
                    let white_json = json.replace("[0.9, 0.9, 0.9]", "[1, 1, 1]");
                    assert_ne!(white_json, json, "the metal base's colour is 0.9 (see BASES)");
                    let white = Material::from_json(&white_json).expect("valid");
                    let Model::CoatedPaint(white) = white.model() else { unreachable!() };
                    let w = reference(white, wo, walks, seed);
                    let (later_f, later_1): (f64, f64) =
                        (r.by_bounces[1..].iter().sum(), w.by_bounces[1..].iter().sum());
                    eprintln!(
                        "{base_name} α {alpha} θo {theta}: the reference's later light {later_f:.4} (white metal {later_1:.4}): effective later metal bounces n = {:.2}",
                        (later_f / later_1).ln() / 0.9f64.ln() - 1.0
                    );
                }
                eprintln!(
                    "{base_name} α {alpha} θo {theta}: later light {:.4} vs {:.4}, lobe {:.2} % (noise {:.2})",
                    lt[0],
                    lt[1],
                    100.0 * lt[4],
                    100.0 * lt[5]
                );
                eprintln!(
                    "{base_name} α {alpha} θo {theta}: first-bounce light {:.4} vs {:.4}, lobe {:.2} % (noise {:.2})",
                    ft[0],
                    ft[1],
                    100.0 * ft[4],
                    100.0 * ft[5]
                );
                // The model's terms' albedos at θo (its tables): single-scatter layer `A1`,
                // the metal's bounce series `S`, the multiple-scatter lobe `M` (luminance).
                let (a1, m) = paint.layer_albedos(wo.z);
                let terms =
                    [Rgb::from_array(a1).luminance(), paint.spec_series_albedo(wo.z), Rgb::from_array(m).luminance()];
                eprintln!(
                    "{base_name} α {alpha} θo {theta}: the model's A1 / S / M {:.4} / {:.4} / {:.4}",
                    terms[0], terms[1], terms[2]
                );
                eprintln!(
                    "{base_name} α {alpha} θo {theta}: albedo {:.4} vs {:.4} ({:+.2} % ± {:.2}; of it through the coat {:.4} vs {:.4}; the reference's after 1 / 2 / 3 / 4+ base bounces {:.4} / {:.4} / {:.4} / {:.4}), lobe {:.2} % (noise {:.2}), body lobe {:.2} % (noise {:.2}) [{:.0} s]",
                    all[0], all[1], 100.0 * all[2], 100.0 * all[3], b[0], b[1],
                    r.by_bounces[0], r.by_bounces[1], r.by_bounces[2], r.by_bounces[3],
                    100.0 * all[4], 100.0 * all[5], 100.0 * b[4], 100.0 * b[5],
                    start.elapsed().as_secs_f64()
                );
                cells.push(format!(
                    "{:+.2} ± {:.2} % / {:.1} % ({:.1}) / {:.1} % ({:.1})",
                    100.0 * all[2],
                    100.0 * all[3],
                    100.0 * all[4],
                    100.0 * all[5],
                    100.0 * b[4],
                    100.0 * b[5]
                ));
                if all[2].abs() > worst_alb.abs() {
                    worst_alb = all[2];
                }
                worst_lobe = worst_lobe.max(all[4]);
                worst_body = worst_body.max(b[4]);
                let _ = (all[3], all[5], b[5]);
            }
            let _ = writeln!(table, "| {base_name} | {alpha} | {} |", cells.join(" | "));
            alb.push((alpha, 100.0 * worst_alb.abs()));
            lobe.push((alpha, 100.0 * worst_lobe));
            body.push((alpha, 100.0 * worst_body));
        }
        curves.push((base_name.to_string(), alb, lobe, body));
    }
    let secs = start.elapsed().as_secs_f64();
    let mut md = format!(
        "Generated by `cargo run --release -p lacquer --example rough_coat_validation -- --walks {walks}` ({walks} reference walks and {walks} analytic samples per cell, single-threaded, {secs:.0} s; 2 shared cores).\n\n"
    );
    md.push_str("Cells: albedo error (analytic/reference − 1, luminance) ± its standard error / lobe-shape error of the whole lobe (its noise floor) / of the light that crossed the coat (its noise floor). Lobe-shape error: relative L2 difference over 12 × 6 equal-solid-angle bins (cos θi × folded azimuth), each lobe normalised to unit albedo, with the noise's expected share removed (`√max(0, L2² − floor²)`; the floor is what the two estimates' standard errors alone give).\n\n");
    md.push_str("| base | coat α | θo 0° | θo 40° | θo 75° |\n|---|---|---|---|---|\n");
    md.push_str(&table);
    println!("{md}");
    if write {
        let doc = "docs/paint-validation.md";
        let text = std::fs::read_to_string(doc).expect("run from the repository root");
        let (b, e) = ("<!-- rough_coat_validation:begin -->", "<!-- rough_coat_validation:end -->");
        if let (Some(i), Some(j)) = (text.find(b), text.find(e)) {
            let new = format!("{}{}\n{}{}", &text[..i + b.len()], "\n", md, &text[j..]);
            std::fs::write(doc, new).expect("writable");
        } else {
            eprintln!("markers not found in {doc}: table printed only");
        }
        for (what, idx, ylabel) in [
            ("albedo", 1usize, "largest |albedo error| over θo (%)"),
            ("lobe", 2, "largest lobe-shape error over θo (%)"),
            ("body", 3, "largest body-lobe error over θo (%)"),
        ] {
            let series: Vec<serde_json::Value> = curves
                .iter()
                .map(|c| {
                    let pts = match idx {
                        1 => &c.1,
                        2 => &c.2,
                        _ => &c.3,
                    };
                    serde_json::json!({"label": c.0, "x": pts.iter().map(|p| p.0).collect::<Vec<_>>(), "y": pts.iter().map(|p| p.1).collect::<Vec<_>>()})
                })
                .collect();
            let v = serde_json::json!({
                "title": format!("Rough coats: analytic model against the lossless reference ({what})"),
                "xlabel": "coat GGX α",
                "ylabel": ylabel,
                "series": series,
            });
            let path = format!("docs/data/rough-coat-validation-{what}.json");
            std::fs::write(&path, serde_json::to_string_pretty(&v).expect("json")).expect("writable");
            eprintln!("wrote {path}");
        }
    }
}
