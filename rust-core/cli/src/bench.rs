//! `lacquer bench`: speed of eval, pdf and sample for models, presets or material JSON.

use clap::Args;
use lacquer::batch::SimdLevel;
use lacquer::bench::{measure, BenchConfig, BenchReport};
use lacquer::{models, presets, Material};
use std::process::ExitCode;

#[derive(Args)]
#[command(after_help = "Examples:\n  \
lacquer bench --preset gold_flake_8\n  \
lacquer bench --material '{\"model\": \"rough_conductor\", \"distribution\": \"ggx\", \"alpha_u\": 0.2, \"alpha_v\": 0.2}'\n  \
lacquer bench --model lambert --n 100000 --json\n  \
lacquer bench --all-models --quick")]
pub struct BenchArgs {
    /// A registered model with its defaults.
    #[arg(long)]
    model: Option<String>,
    /// A named preset.
    #[arg(long)]
    preset: Option<String>,
    /// Material JSON.
    #[arg(long)]
    material: Option<String>,
    /// Every registered model with its defaults.
    #[arg(long)]
    all_models: bool,
    /// Direction pairs per batch call.
    #[arg(long, default_value_t = 1 << 20)]
    n: usize,
    /// Repetitions per figure (minimum and median reported).
    #[arg(long, default_value_t = 7)]
    repetitions: usize,
    /// Small and fast: n = 65536, 3 repetitions, no all-threads rows.
    #[arg(long)]
    quick: bool,
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// The speed-vs-error report: every model's f32 batch path against its f64 reference and
    /// every approximation the library offers against the exact form (docs/speed-vs-error.md).
    #[arg(long)]
    report: bool,
    /// Pick the cheapest configuration of the material whose maximum relative error of
    /// f·cos θ against its f64 reference stays within this tolerance, and say which.
    #[arg(long)]
    max_error: Option<f64>,
}

fn materials(args: &BenchArgs) -> Result<Vec<(String, Material)>, String> {
    let mut out = Vec::new();
    if let Some(name) = &args.model {
        let info = models::find(name).ok_or_else(|| format!("unknown model {name:?} (see `lacquer models`)"))?;
        out.push((name.clone(), Material::default_of(info).map_err(|e| e.to_string())?));
    }
    if let Some(p) = &args.preset {
        presets::find(p).ok_or_else(|| format!("unknown preset {p:?} (see `lacquer presets`)"))?;
        out.push((p.clone(), Material::preset(p).map_err(|e| e.to_string())?));
    }
    if let Some(json) = &args.material {
        out.push(("material".into(), Material::from_json(json).map_err(|e| e.to_string())?));
    }
    if args.all_models {
        for info in models::all() {
            out.push((info.name.to_string(), Material::default_of(info).map_err(|e| e.to_string())?));
        }
    }
    if out.is_empty() {
        return Err("give --model, --preset, --material or --all-models".into());
    }
    Ok(out)
}

fn print_table(name: &str, r: &BenchReport) {
    println!(
        "\n{name} ({} elements; {}):",
        r.n,
        if r.lane_kernel { "SIMD lane kernel" } else { "no lane kernel: batch calls loop over elements" }
    );
    println!("| op | api | precision | simd | threads | ns/elem (min) | ns/elem (median) |");
    println!("|---|---|---|---|---|---|---|");
    for row in &r.rows {
        println!(
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} |",
            row.op, row.api, row.precision, row.simd, row.threads, row.timing.min_ns, row.timing.median_ns
        );
    }
}

pub fn run(args: BenchArgs) -> ExitCode {
    if args.report {
        return run_report(&args);
    }
    let list = match materials(&args) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let cfg = if args.quick {
        BenchConfig { n: 1 << 16, repetitions: 3, all_threads: false, scalar_calls: true }
    } else {
        BenchConfig { n: args.n.max(1), repetitions: args.repetitions.max(1), ..BenchConfig::default() }
    };
    if !args.json {
        println!("CPU SIMD level: {} (batch kernels dispatch at run time)", SimdLevel::detect().name());
    }
    if let Some(tol) = args.max_error {
        return run_choose(&args, &list, tol);
    }
    let mut reports = Vec::new();
    for (name, m) in &list {
        let r = measure(m, &cfg);
        if !args.json {
            print_table(name, &r);
        }
        reports.push(serde_json::json!({"name": name, "report": r}));
    }
    if args.json {
        let doc = serde_json::json!({"simd_detected": SimdLevel::detect().name(), "materials": reports});
        println!("{}", serde_json::to_string_pretty(&doc).expect("serialisable"));
    }
    ExitCode::SUCCESS
}

fn run_report(args: &BenchArgs) -> ExitCode {
    let n = if args.quick { 1 << 14 } else { args.n.min(1 << 18) };
    let rows = lacquer::bench::speed_error_report(n);
    if args.json {
        let doc = serde_json::json!({"simd": SimdLevel::detect().name(), "n": n, "rows": rows});
        println!("{}", serde_json::to_string_pretty(&doc).expect("serialisable"));
        return ExitCode::SUCCESS;
    }
    println!("Speed vs error ({n} random direction pairs; error of f·cos θi, relative, floor 1e-3 of the peak):\n");
    println!("| model / approximation | comparison | ns fast | ns reference | max error | RMS error |");
    println!("|---|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {} | {:.1} | {:.1} | {:.2e} | {:.2e} |",
            r.what, r.comparison, r.ns_fast, r.ns_reference, r.error.max, r.error.rms
        );
    }
    ExitCode::SUCCESS
}

fn run_choose(args: &BenchArgs, list: &[(String, Material)], tol: f64) -> ExitCode {
    if tol.is_nan() || tol < 0.0 {
        eprintln!("error: --max-error must be a non-negative number, got {tol}");
        return ExitCode::from(2);
    }
    let n = if args.quick { 1 << 14 } else { args.n.min(1 << 18) };
    let mut out = Vec::new();
    for (name, m) in list {
        let c = lacquer::bench::choose(m, tol, n);
        if !args.json {
            println!("\n{name}: tolerance {tol:e} on the maximum relative error of f·cos θi ({n} direction pairs)");
            println!("| configuration | path | ns/eval | max error | RMS error | within |");
            println!("|---|---|---|---|---|---|");
            for k in &c.candidates {
                println!(
                    "| {} | {} | {:.2} | {:.2e} | {:.2e} | {} |",
                    k.name,
                    k.path,
                    k.ns_per_eval,
                    k.error.max,
                    k.error.rms,
                    if k.error.max <= tol { "yes" } else { "no" }
                );
            }
            println!(
                "picked: {} ({}), {:.2} ns/eval, max error {:.2e}",
                c.picked.name, c.picked.path, c.picked.ns_per_eval, c.picked.error.max
            );
            println!("material: {}", c.picked.material);
        }
        out.push(serde_json::json!({"name": name, "choice": c}));
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out).expect("serialisable"));
    }
    ExitCode::SUCCESS
}
