//! `lacquer`: list models and presets, and run the checks.

use clap::{Args, Parser, Subcommand};
use lacquer::check::{self, CheckConfig, ModelReport};
use lacquer::{models, presets, Material};
use serde_json::{json, Value};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "lacquer",
    version,
    about = "Physically checked BRDFs for coated paint and the classic reflectance models"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every model with its parameters (default, range, unit) and claims.
    Models {
        /// Machine-readable output on stdout.
        #[arg(long)]
        json: bool,
    },
    /// List the named material presets.
    Presets {
        /// Machine-readable output (full material JSON per preset).
        #[arg(long)]
        json: bool,
    },
    /// Check models or materials against their claims (reciprocity, energy, χ², hard cases).
    Check(CheckArgs),
}

#[derive(Args)]
struct CheckArgs {
    /// Check every registered model.
    #[arg(long, conflicts_with_all = ["model", "material", "preset"])]
    all: bool,
    /// Check one model (defaults, its check sets, random parameters, extremes).
    #[arg(long)]
    model: Option<String>,
    /// Check one material: a JSON string or a path to a JSON file.
    #[arg(long)]
    material: Option<String>,
    /// Check one preset.
    #[arg(long)]
    preset: Option<String>,
    /// Fewer samples (faster, less sensitive).
    #[arg(long)]
    quick: bool,
    /// Seed of the check's random streams.
    #[arg(long)]
    seed: Option<u64>,
    /// Machine-readable report on stdout.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Models { json } => list_models(json),
        Command::Presets { json } => list_presets(json),
        Command::Check(args) => run_check(args),
    }
}

fn list_models(as_json: bool) -> ExitCode {
    if as_json {
        let list: Vec<Value> = models::all().iter().map(|m| m.to_json()).collect();
        println!("{}", serde_json::to_string_pretty(&list).expect("serialisable"));
        return ExitCode::SUCCESS;
    }
    for m in models::all() {
        let c = m.claims;
        println!("{:<28} {}", m.name, m.summary);
        println!(
            "{:<28} reciprocal: {}, energy-conserving: {}, sampled: {}  [{}]",
            "", c.reciprocal, c.energy_conserving, c.sampled, m.reference
        );
        for p in m.params {
            let unit = if p.unit.is_empty() { String::new() } else { format!(" {}", p.unit) };
            let default = serde_json::to_string(&p.default).expect("serialisable");
            println!("{:<30}{:<22} default {default}, range [{}, {}]{unit}: {}", "", p.name, p.min, p.max, p.doc);
        }
    }
    ExitCode::SUCCESS
}

fn list_presets(as_json: bool) -> ExitCode {
    if as_json {
        let list: Vec<Value> = presets::PRESETS
            .iter()
            .map(|p| {
                let material = Material::from_json(p.json).map(|m| m.to_json()).unwrap_or(Value::Null);
                json!({"name": p.name, "label": p.label, "description": p.description, "material": material})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&list).expect("serialisable"));
    } else {
        for p in presets::PRESETS {
            println!("{:<28} {}", p.name, p.description);
        }
    }
    ExitCode::SUCCESS
}

fn load_material(spec: &str) -> Result<Material, String> {
    let text = if spec.trim_start().starts_with('{') {
        spec.to_string()
    } else {
        std::fs::read_to_string(spec).map_err(|e| format!("cannot read {spec}: {e}"))?
    };
    Material::from_json(&text).map_err(|e| e.to_string())
}

fn print_model_report(r: &ModelReport) {
    let s = &r.summary;
    println!(
        "{:<28} {}  reciprocity {:9.2e}  furnace [{:.4}, {:.4}]  χ² min p {:.3}  ∫pdf ≤ {:.4}  hard-case failures {}  f32 err {:.1e}",
        r.model,
        if r.passed { "PASS" } else { "FAIL" },
        s.worst_reciprocity,
        s.furnace_min,
        s.furnace_max,
        s.chi2_min_p,
        s.pdf_integral_max,
        s.hard_case_failures,
        s.precision_max
    );
    if s.sparkle_materials > 0 {
        println!(
            "    sparkle (eval_at/sample_at) on {} parameter sets: reciprocity {:.2e}",
            s.sparkle_materials, s.worst_sparkle_reciprocity
        );
    }
    for m in &r.materials {
        for v in &m.verdicts {
            if v.status == "fail" {
                println!(
                    "    FAIL {:<18} {:.3e} (limit {:.3e}) on {}: {}",
                    v.check, v.value, v.limit, m.material, v.note
                );
            }
        }
        for e in m.hard_cases.examples.iter().take(3) {
            println!("    hard case: {e}");
        }
    }
    for e in r.parameter_extremes.examples.iter().take(3) {
        println!("    extreme parameters: {e}");
    }
    for e in &r.parameter_extremes.build_errors {
        println!("    build error: {e}");
    }
    let reported: Vec<String> = r.materials[..1.min(r.materials.len())]
        .iter()
        .flat_map(|m| {
            m.verdicts.iter().filter(|v| v.status == "reported").map(|v| format!("{} {:.3e}", v.check, v.value))
        })
        .collect();
    if !reported.is_empty() {
        println!("    not claimed, measured at defaults: {}", reported.join(", "));
    }
}

fn print_preset_report(p: &check::PresetReport) {
    let r = &p.report;
    let min_p = r.chi2.iter().map(|c| c.p_value).fold(1.0, f64::min);
    println!(
        "preset {:<28} {}  reciprocity {:9.2e}  furnace [{:.4}, {:.4}]  χ² min p {:.3}  hard-case failures {}  f32 err {:.1e}",
        p.preset,
        if r.passed() { "PASS" } else { "FAIL" },
        r.reciprocity.max_relative_error,
        r.furnace.min_albedo,
        r.furnace.max_albedo,
        min_p,
        r.hard_cases.failures(),
        r.precision.max_relative_error
    );
    for v in r.verdicts.iter().filter(|v| v.status == "fail") {
        println!("    FAIL {:<18} {:.3e} (limit {:.3e}): {}", v.check, v.value, v.limit, v.note);
    }
}

fn run_check(args: CheckArgs) -> ExitCode {
    let mut cfg = if args.quick { CheckConfig::quick() } else { CheckConfig::standard() };
    if let Some(seed) = args.seed {
        cfg.seed = seed;
    }
    let mut preset_reports = Vec::new();
    let reports: Vec<ModelReport> = if args.all {
        preset_reports = check::check_presets(&cfg);
        check::check_all(&cfg)
    } else if let Some(name) = &args.model {
        match models::find(name) {
            Some(info) => vec![check::check_model(info, &cfg)],
            None => {
                eprintln!("error: unknown model \"{name}\" (see `lacquer models`)");
                return ExitCode::from(2);
            }
        }
    } else if let Some(spec) = args
        .material
        .as_deref()
        .map(str::to_string)
        .or(args.preset.as_ref().map(|p| format!("{{\"preset\": {}}}", Value::from(p.as_str()))))
    {
        match load_material(&spec) {
            Ok(m) => {
                let report = check::check_material(&m, &cfg, "material", true);
                if args.json {
                    println!("{}", serde_json::to_string_pretty(&report).expect("serialisable"));
                } else {
                    println!("{}", m.to_json());
                    for v in &report.verdicts {
                        println!(
                            "  {:<18} {:<8} {:.4e} (limit {:.3e}): {}",
                            v.check, v.status, v.value, v.limit, v.note
                        );
                    }
                }
                return if report.passed() { ExitCode::SUCCESS } else { ExitCode::FAILURE };
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        }
    } else {
        eprintln!("error: give --all, --model NAME, --material JSON_OR_FILE or --preset NAME");
        return ExitCode::from(2);
    };
    let passed = reports.iter().all(|r| r.passed) && preset_reports.iter().all(|p| p.report.passed());
    if args.json {
        let out = if args.all {
            json!({"models": reports, "presets": preset_reports})
        } else {
            serde_json::to_value(&reports).expect("serialisable")
        };
        println!("{}", serde_json::to_string_pretty(&out).expect("serialisable"));
    } else {
        for r in &reports {
            print_model_report(r);
        }
        for p in &preset_reports {
            print_preset_report(p);
        }
        if !preset_reports.is_empty() {
            let failed: Vec<_> = preset_reports.iter().filter(|p| !p.report.passed()).map(|p| p.preset).collect();
            println!(
                "{} presets checked, {} failed{}",
                preset_reports.len(),
                failed.len(),
                if failed.is_empty() { String::new() } else { format!(": {}", failed.join(", ")) }
            );
        }
        let failed: Vec<_> = reports.iter().filter(|r| !r.passed).map(|r| r.model).collect();
        println!(
            "{} models checked, {} failed{}",
            reports.len(),
            failed.len(),
            if failed.is_empty() { String::new() } else { format!(": {}", failed.join(", ")) }
        );
    }
    if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
