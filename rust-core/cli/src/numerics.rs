//! `lacquer numerics`: the adversarial numerics report (NaN, Inf, negative outputs and
//! reciprocity violations over ≥ 1e6 adversarial direction pairs per model and preset).

use clap::Args;
use lacquer::check::numerics::{numerics, NumericsConfig, NumericsRow};
use lacquer::{models, presets};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `lacquer numerics`.
#[derive(Args)]
#[command(after_help = "Examples:\n  \
lacquer numerics                      (every model and preset, 1e6 pairs each: docs/numerics.md)\n  \
lacquer numerics --model ward --pairs 100000\n  \
lacquer numerics --smoke --json")]
pub struct NumericsArgs {
    /// Models to run, comma-separated (default: every model and every preset).
    #[arg(long, value_delimiter = ',')]
    model: Vec<String>,
    /// Presets to run, comma-separated.
    #[arg(long, value_delimiter = ',')]
    preset: Vec<String>,
    /// Direction pairs per model and per preset (default 1e6).
    #[arg(long)]
    pairs: Option<usize>,
    /// The smoke configuration of `cargo test` (1e4 pairs).
    #[arg(long, conflicts_with = "pairs")]
    smoke: bool,
    /// Seed of the random streams.
    #[arg(long)]
    seed: Option<u64>,
    /// Threads (default: every core); the report is the same for any number.
    #[arg(long)]
    threads: Option<usize>,
    /// Machine-readable report on stdout.
    #[arg(long)]
    json: bool,
}

/// Runs `lacquer numerics`: exit 0 when every count is zero or explained
/// (`lacquer::check::numerics::EXPLAINED`), 1 otherwise, 2 on a usage error.
pub fn run(args: NumericsArgs) -> ExitCode {
    let mut cfg = if args.smoke { NumericsConfig::smoke() } else { NumericsConfig::full() };
    if let Some(p) = args.pairs {
        cfg.pairs = p;
    }
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    let (mut ms, mut ps) = (Vec::new(), Vec::new());
    for name in &args.model {
        match models::find(name) {
            Some(info) => ms.push(info),
            None => {
                eprintln!("error: unknown model \"{name}\" (see `lacquer models`)");
                return ExitCode::from(2);
            }
        }
    }
    for name in &args.preset {
        match presets::PRESETS.iter().find(|p| p.name == name.as_str()) {
            Some(p) => ps.push(p),
            None => {
                eprintln!("error: unknown preset \"{name}\" (see `lacquer presets`)");
                return ExitCode::from(2);
            }
        }
    }
    if ms.is_empty() && ps.is_empty() {
        ms = models::all().to_vec();
        ps = presets::PRESETS.iter().collect();
    }
    let threads = args.threads.unwrap_or_else(lacquer::check::default_threads).max(1);
    let start = Instant::now();
    let rows = numerics(&ms, &ps, &cfg, threads);
    let seconds = start.elapsed().as_secs_f64();
    let failures: usize = rows.iter().map(NumericsRow::failures).sum();
    let unexplained: usize = rows.iter().map(NumericsRow::unexplained_failures).sum();
    if args.json {
        let out = serde_json::json!({"config": cfg, "threads": threads, "seconds": seconds, "rows": rows});
        println!("{}", serde_json::to_string_pretty(&out).expect("serialisable"));
    } else {
        print_table(&rows);
        println!(
            "\n{} rows, {} pairs, {} outputs inspected, {failures} failures ({unexplained} not covered by a known exception); {seconds:.0} s on {threads} threads",
            rows.len(),
            rows.iter().map(|r| r.pairs).sum::<usize>(),
            rows.iter().map(|r| r.f64.outputs + r.f32.outputs).sum::<usize>(),
        );
        for r in rows.iter().filter(|r| !r.examples.is_empty()) {
            println!("\n{}:", r.name);
            if let Some(why) = r.explained() {
                println!(
                    "  known (violations at cos θ ≤ {:.1e}, |Δf| ≤ {:.1e} /sr): {why}",
                    r.worst_violation_cos, r.worst_violation_abs
                );
            }
            for e in &r.examples {
                println!("  {e}");
            }
        }
    }
    if unexplained == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// The markdown table of docs/numerics.md.
fn print_table(rows: &[NumericsRow]) {
    println!("| model / preset | materials (rejected) | out-of-range rejected | pairs | outputs f64 / f32 | NaN f64 / f32 | Inf f64 / f32 | negative f64 / f32 | bad wi f64 / f32 | reciprocity violations (worst) | nearly opposite pairs: worst reciprocity error |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let recip = if r.reciprocal && r.explained().is_some() {
            format!(
                "{} ({:.1e}; known finding: all at cos θ ≤ {:.0e}, \\|Δf\\| ≤ {:.0e} /sr)",
                r.reciprocity_violations, r.worst_reciprocity, r.worst_violation_cos, r.worst_violation_abs
            )
        } else if r.reciprocal {
            format!("{} ({:.1e})", r.reciprocity_violations, r.worst_reciprocity)
        } else {
            format!("not claimed ({} over 1e-6, worst {:.1e})", r.reciprocity_violations, r.worst_reciprocity)
        };
        let oor = if r.kind == "preset" {
            "—".to_string()
        } else {
            format!("{}/{}", r.out_of_range_rejected.0, r.out_of_range_rejected.1)
        };
        println!(
            "| {} | {} ({}) | {oor} | {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {recip} | {}: {:.1e} |",
            r.name,
            r.materials,
            r.rejected,
            r.pairs,
            r.f64.outputs,
            r.f32.outputs,
            r.f64.nan,
            r.f32.nan,
            r.f64.inf,
            r.f32.inf,
            r.f64.negative,
            r.f32.negative,
            r.f64.bad_direction,
            r.f32.bad_direction,
            r.opposite_pairs,
            r.worst_reciprocity_opposite,
        );
    }
}
