//! The χ² test of one configured outgoing direction for every model's defaults and check
//! sets and every preset (the materials `lacquer check` runs χ² on), with the check's own
//! two-stage verdict for that direction alone: a retest with an independent seed and 4× the
//! samples when the first stage falls below the level. Used for issue 17, item 6 (the
//! cos θo = 0.4 direction added to the check):
//!
//! `cargo run --release -p lacquer --example chi2_direction_sweep -- 3`
//!
//! The argument is the index into `CheckConfig::standard().chi2_directions` (default 3, the
//! cos 0.4 direction); an optional second argument keeps only materials whose origin contains
//! it (e.g. a model name).
use lacquer::check::{build, chi2_direction, Profile};
use lacquer::Material;
use serde_json::{Map, Value};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let k: usize = args.get(1).map_or(3, |s| s.parse().expect("direction index"));
    let filter = args.get(2).cloned().unwrap_or_default();
    let profile = Profile::standard();
    let mut materials: Vec<(String, Material, &str)> = Vec::new();
    for info in lacquer::models::all() {
        if let Ok(m) = Material::default_of(info) {
            materials.push((format!("{} defaults", info.name), m, info.name));
        }
        for (i, text) in info.check_params.iter().enumerate() {
            let obj: Map<String, Value> = serde_json::from_str(text).expect("check_params are JSON objects");
            if let Ok(m) = build(info, &obj) {
                materials.push((format!("{} check set {i}", info.name), m, info.name));
            }
        }
    }
    for p in lacquer::presets::PRESETS {
        materials.push((format!("preset {}", p.name), Material::preset(p.name).expect("preset"), ""));
    }
    let mut failed = 0;
    for (origin, m, model) in materials.iter().filter(|(o, _, _)| o.contains(&filter)) {
        if !m.info().claims.sampled {
            continue;
        }
        let cfg = if model.is_empty() { &profile.base } else { profile.config_for(model) };
        // The level of one direction among the configured ones (Šidák), as in the check.
        let level = 1.0 - (1.0 - cfg.significance).powf(1.0 / cfg.chi2_directions.len() as f64);
        let t = std::time::Instant::now();
        let first = chi2_direction(m, cfg, k);
        let mut line = format!(
            "{origin}: cos {} χ² {:.1} dof {} p {:.4} ∫pdf {:.5}",
            first.cos_theta, first.chi2, first.dof, first.p_value, first.pdf_integral
        );
        let mut pass = first.p_value >= level && first.note.is_empty();
        if !pass && first.note.is_empty() {
            let retest = lacquer::check::CheckConfig {
                seed: cfg.seed ^ 0x7e57_7e57,
                chi2_samples: 4 * cfg.chi2_samples,
                ..cfg.clone()
            };
            let second = chi2_direction(m, &retest, k);
            line += &format!(" | retest χ² {:.1} dof {} p {:.4}", second.chi2, second.dof, second.p_value);
            pass = second.p_value >= level;
        }
        if !first.note.is_empty() {
            line += &format!(" | {}", first.note);
        }
        failed += usize::from(!pass);
        println!("{} {line} ({:.1} s)", if pass { "ok  " } else { "FAIL" }, t.elapsed().as_secs_f64());
    }
    println!("{failed} failed");
}
