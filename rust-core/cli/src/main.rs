//! `lacquer`: list models and presets, run the checks, render.

use clap::{Args, Parser, Subcommand};
use lacquer::check::{self, ModelReport, Profile};
use lacquer::{models, presets, Material};
use serde_json::{json, Value};
use std::process::ExitCode;

mod bench;
mod figure;
mod numerics;
mod plot;
mod render;

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
    /// Render a material (path tracer) to OpenEXR: `lacquer render --preset gold_flake_8 -o paint.exr`.
    Render(Box<render::RenderArgs>),
    /// Fit analytic models to a measured MERL table (Levenberg-Marquardt), or generate a table.
    Fit(FitArgs),
    /// Fit the Blender node group `Lacquer Coated Paint` (mean lobe) to a coated_paint material.
    FitNodeGroup(FitNodeGroupArgs),
    /// Measure ns per element of eval, pdf and sample (batch SIMD/scalar, 1 and all threads,
    /// scalar calls in f32 and f64): `lacquer bench --preset gold_flake_8`.
    Bench(bench::BenchArgs),
    /// Adversarial numerics report: NaN, Inf, negative outputs and reciprocity violations over
    /// 1e6 adversarial direction pairs per model and preset, f32 and f64 (docs/numerics.md).
    Numerics(numerics::NumericsArgs),
    /// Plot BRDF slices (in-plane, polar), directional albedo, the sampler against its pdf, or
    /// a render sheet of a MERL table and its fits: `lacquer plot in-plane --preset gold_flake_8 -o f.svg`.
    Plot(Box<plot::PlotArgs>),
}

#[derive(Args)]
#[command(after_help = "Examples:\n  \
lacquer fit-node-group --preset gold_flake_8\n  \
lacquer fit-node-group --material '{\"model\": \"coated_paint\", \"flake_density\": 5}' --json\n  \
lacquer fit-node-group --all-presets")]
struct FitNodeGroupArgs {
    /// A coated-paint preset.
    #[arg(long, conflicts_with_all = ["material", "all_presets"])]
    preset: Option<String>,
    /// A coated_paint material: a JSON string or a path to a JSON file.
    #[arg(long, conflicts_with = "all_presets")]
    material: Option<String>,
    /// Fit every coated-paint preset and print the fit-error table (markdown).
    #[arg(long)]
    all_presets: bool,
    /// Threads for the fit's Jacobian (default: up to 4 cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Largest number of Levenberg-Marquardt iterations.
    #[arg(long)]
    iterations: Option<usize>,
    /// Machine-readable output on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
#[command(after_help = "Examples:\n  \
lacquer fit --generate gold_8pct_25um --out gold.binary --noise 0.02\n  \
lacquer fit --table gold.binary --model ward,lambert+ward --lobes 2\n  \
lacquer fit --table gold.binary --model all --json\n  \
lacquer fit --table gold.binary --spec '[{\"model\": \"lambert\"}, {\"model\": \"ward\", \"diffuse\": 0}]'")]
struct FitArgs {
    /// The measured table to fit: a MERL .binary file.
    #[arg(long, required_unless_present = "generate", conflicts_with = "generate")]
    table: Option<String>,
    /// Models to fit, comma-separated; `a+b` is a sum of lobes; `all` = every fittable model.
    #[arg(long, value_delimiter = ',')]
    model: Vec<String>,
    /// A fit model as JSON: {"model": NAME, fixed params...} or a list of them (a sum of
    /// lobes); repeatable.
    #[arg(long)]
    spec: Vec<String>,
    /// Repeat each model's (last) lobe to this many lobes; repeated lobes hold their diffuse
    /// parameters at 0.
    #[arg(long, default_value_t = 1)]
    lobes: usize,
    /// Table entries in the refinement subset (0 = every entry).
    #[arg(long, default_value_t = 20_000)]
    points: usize,
    /// Starting points per model (the defaults plus Halton-spread values).
    #[arg(long, default_value_t = 8)]
    starts: usize,
    /// Largest number of Levenberg-Marquardt iterations of a refinement.
    #[arg(long, default_value_t = 60)]
    iterations: usize,
    /// Threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// What the fit minimises: `integral` (the thesis' cos-weighted squared error, each entry
    /// weighted by the solid angle of its cell) or `entries` (the thesis' plain sum over entries).
    #[arg(long, default_value = "integral", value_parser = ["integral", "entries"])]
    objective: String,
    /// Fit and score only entries whose directions are both within this angle of the normal
    /// (degrees; 90 = the whole table). Ngan's figure always leaves out entries beyond 80°.
    #[arg(long, default_value_t = 90.0)]
    max_angle: f64,
    /// Wall-time budget per model in seconds (coated_paint builds slowly: give it one).
    #[arg(long)]
    budget: Option<f64>,
    /// Good enough: stop each start and refinement once its weighted error on its subset is
    /// this many dB below the spread of the values there (e.g. 40; default: iterate until the
    /// fit stops improving).
    #[arg(long)]
    stop_snr: Option<f64>,
    /// Seed of the fit subsets (and of --noise).
    #[arg(long, default_value_t = 0x05ee_df17)]
    seed: u64,
    /// Write a MERL table of a material instead of fitting: a preset name, a model name,
    /// material JSON, a JSON list of materials (their BRDFs add) or a file holding one.
    #[arg(long)]
    generate: Option<String>,
    /// Output file of --generate.
    #[arg(long, requires = "generate")]
    out: Option<String>,
    /// Relative Gaussian noise added to every entry of a generated table (e.g. 0.02).
    #[arg(long, default_value_t = 0.0, requires = "generate")]
    noise: f64,
    /// Machine-readable report on stdout.
    #[arg(long)]
    json: bool,
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
    /// Fewer samples (faster, less sensitive); the same as `--profile quick`.
    #[arg(long, conflicts_with = "profile")]
    quick: bool,
    /// Sample counts: `standard` (the default; the full run), `quick`, or `ci` (standard, with
    /// fewer samples for htsg, poulin_fournier and stam; power stated in docs/checks.md).
    #[arg(long, value_parser = ["standard", "quick", "ci"])]
    profile: Option<String>,
    /// Threads (default: every core); the report is the same for any number.
    #[arg(long)]
    threads: Option<usize>,
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
        Command::Render(args) => render::run(*args),
        Command::Fit(args) => run_fit(args),
        Command::FitNodeGroup(args) => run_fit_node_group(args),
        Command::Bench(args) => bench::run(args),
        Command::Numerics(args) => numerics::run(args),
        Command::Plot(args) => plot::run(*args),
    }
}

fn run_fit_node_group(args: FitNodeGroupArgs) -> ExitCode {
    use lacquer::fit::node_group::{fit_node_group_json_with, NodeGroupOptions};
    let mut opts = NodeGroupOptions::default();
    if let Some(t) = args.threads {
        opts.threads = t.max(1);
    }
    if let Some(i) = args.iterations {
        opts.max_iterations = i;
    }
    // (name, material JSON): the fit builds the material, so its seconds include the paint's tables.
    let mut jobs: Vec<(String, String)> = Vec::new();
    if args.all_presets {
        for p in presets::PRESETS {
            if p.json.contains("\"coated_paint\"") {
                jobs.push((p.name.to_string(), p.json.to_string()));
            }
        }
    } else {
        match (&args.preset, &args.material) {
            (Some(p), _) => jobs.push((p.clone(), format!("{{\"preset\": {}}}", Value::from(p.as_str())))),
            (None, Some(m)) => {
                let text = if m.trim_start().starts_with('{') {
                    m.clone()
                } else {
                    match std::fs::read_to_string(m) {
                        Ok(t) => t,
                        Err(e) => {
                            eprintln!("error: cannot read {m}: {e}");
                            return ExitCode::from(2);
                        }
                    }
                };
                jobs.push(("material".into(), text));
            }
            (None, None) => {
                eprintln!("error: give --preset NAME, --material JSON_OR_FILE or --all-presets");
                return ExitCode::from(2);
            }
        }
    }
    let mut results = Vec::new();
    let mut failed = false;
    if args.all_presets && !args.json {
        println!("| preset | albedo rms | albedo max | brdf rel rms | brdf cos rms (1/sr) | SNR dB | seconds |");
        println!("|---|---|---|---|---|---|---|");
    }
    for (name, text) in &jobs {
        match fit_node_group_json_with(text, &opts) {
            Ok(fit) => {
                let e = fit.error;
                if args.all_presets && !args.json {
                    println!(
                        "| `{name}` | {:.4} | {:.4} | {:.3} | {:.3e} | {:.1} | {:.2} |",
                        e.albedo_rms, e.albedo_max, e.brdf_rel_rms, e.brdf_cos_rms, e.snr_db, e.seconds
                    );
                } else if !args.json {
                    println!(
                        "{}",
                        serde_json::to_string_pretty(&Value::from(
                            fit.inputs.clone().into_iter().collect::<serde_json::Map<_, _>>()
                        ))
                        .expect("serialisable")
                    );
                    println!(
                        "albedo rms {:.4}, max {:.4}; brdf rel rms {:.3}, cos rms {:.3e} 1/sr; SNR {:.1} dB; {} iterations ({:?}); {:.2} s",
                        e.albedo_rms, e.albedo_max, e.brdf_rel_rms, e.brdf_cos_rms, e.snr_db, fit.fit.iterations, fit.fit.stop, e.seconds
                    );
                }
                results.push(json!({"preset": name, "fit": fit.to_json()}));
            }
            Err(e) => {
                failed = true;
                eprintln!("error: {name}: {e}");
            }
        }
    }
    if args.json {
        let out = if args.all_presets {
            Value::from(results)
        } else {
            results.into_iter().next().map(|r| r["fit"].clone()).unwrap_or(Value::Null)
        };
        println!("{}", serde_json::to_string_pretty(&out).expect("serialisable"));
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
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
                let material = p.material_json().unwrap_or(Value::Null);
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
    if !r.claims.energy_conserving && s.furnace_max > 1.0 + 1e-3 {
        println!(
            "    finding: directional albedo up to {:.4} (> 1; the model does not claim energy conservation)",
            s.furnace_max
        );
    }
    if s.sparkle_materials > 0 {
        println!(
            "    sparkle (eval_at/sample_at) on {} parameter sets: reciprocity {:.2e}",
            s.sparkle_materials, s.worst_sparkle_reciprocity
        );
    }
    for m in &r.materials {
        print_first_stage(m, &m.material.to_string());
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

/// A material whose first χ² stage fell below its level: both stages' figures and the
/// combined verdict (the first stage is reported, never dropped).
fn print_first_stage(m: &check::MaterialReport, what: &str) {
    if m.chi2_retest.is_empty() {
        return;
    }
    let min_p = |cases: &[check::Chi2Case]| cases.iter().map(|c| c.p_value).fold(1.0, f64::min);
    if let Some(v) = m.verdicts.iter().find(|v| v.check == "chi2") {
        println!(
            "    χ² first stage below its level on {what}: smallest p {:.3e}, second stage {:.3e}, Fisher-combined {:.3e} (level {:.3e}): {}",
            min_p(&m.chi2),
            min_p(&m.chi2_retest),
            v.value,
            v.limit,
            v.status
        );
    }
}

fn print_preset_report(p: &check::PresetReport) {
    let r = &p.report;
    let min_p = r.verdicts.iter().find(|v| v.check == "chi2").map_or(1.0, |v| v.value);
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
    print_first_stage(r, p.preset);
    for v in r.verdicts.iter().filter(|v| v.status == "fail") {
        println!("    FAIL {:<18} {:.3e} (limit {:.3e}): {}", v.check, v.value, v.limit, v.note);
    }
}

fn run_check(args: CheckArgs) -> ExitCode {
    let name = if args.quick { "quick" } else { args.profile.as_deref().unwrap_or("standard") };
    let mut profile = Profile::by_name(name).expect("clap checks the profile name");
    if let Some(seed) = args.seed {
        profile = profile.with_seed(seed);
    }
    let threads = args.threads.unwrap_or_else(check::default_threads).max(1);
    let mut preset_reports = Vec::new();
    let reports: Vec<ModelReport> = if args.all {
        let (models, presets) = check::check_everything(&profile, threads);
        preset_reports = presets;
        models
    } else if let Some(name) = &args.model {
        match models::find(name) {
            Some(info) => check::check_models(&profile, &[info], threads),
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
                let report = check::check_material(&m, profile.config_for(m.info().name), "material", true);
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
        for (model, c) in &profile.overrides {
            println!(
                "profile {}: {model} with {} χ² samples (retest {}), {} furnace samples, {} random parameter sets",
                profile.name,
                c.chi2_samples,
                4 * c.chi2_samples,
                c.furnace_samples,
                c.random_param_sets
            );
        }
    }
    if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

fn run_fit(args: FitArgs) -> ExitCode {
    use lacquer::fit::{self, FitData, FitModel, FitOptions};
    use lacquer::measured::merl::MerlTable;
    let t0 = std::time::Instant::now();
    if let Some(spec) = &args.generate {
        let Some(out) = &args.out else {
            eprintln!("error: --generate needs --out FILE.binary");
            return ExitCode::from(2);
        };
        let materials = match fit::materials_from_spec(spec) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        };
        let mut table = lacquer::measured::tabulate(&materials);
        fit::add_noise(&mut table, args.noise, args.seed);
        if let Err(e) = table.write(out) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
        let summary = json!({
            "generated": out,
            "materials": materials.iter().map(Material::to_json).collect::<Vec<_>>(),
            "noise": args.noise,
            "valid_fraction": table.valid_fraction(),
            "seconds": t0.elapsed().as_secs_f64(),
        });
        if args.json {
            println!("{}", serde_json::to_string_pretty(&summary).expect("serialisable"));
        } else {
            println!(
                "wrote {out}: {} material(s), {:.1} % of entries valid, noise {}, {:.2} s",
                materials.len(),
                100.0 * table.valid_fraction(),
                args.noise,
                t0.elapsed().as_secs_f64()
            );
        }
        return ExitCode::SUCCESS;
    }
    let path = args.table.as_deref().expect("clap requires --table without --generate");
    let mut models = Vec::new();
    for name in &args.model {
        if name == "all" {
            models.extend(fit::fittable_models().iter().map(|m| Ok(m.name.to_string())));
        } else {
            models.push(Ok(name.clone()));
        }
    }
    models.extend(args.spec.iter().map(|s| Err(s.clone())));
    if models.is_empty() {
        eprintln!("error: give --model NAME[,NAME...] (or `all`) or --spec JSON");
        return ExitCode::from(2);
    }
    let mut targets = Vec::new();
    for m in &models {
        let text = match m {
            Ok(s) | Err(s) => s,
        };
        match FitModel::parse(text).and_then(|f| f.with_lobes(args.lobes)) {
            Ok(f) => targets.push(f),
            Err(e) => {
                eprintln!("error: fit model {text}: {e}");
                return ExitCode::from(2);
            }
        }
    }
    let table = match MerlTable::read(path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let data = FitData::from_merl(&table).within(args.max_angle.clamp(0.0, 90.0).to_radians());
    let load_seconds = t0.elapsed().as_secs_f64();
    let mut opts = FitOptions {
        points: args.points,
        starts: args.starts,
        max_iterations: args.iterations,
        seed: args.seed,
        ..FitOptions::default()
    };
    if let Some(t) = args.threads {
        opts.threads = t.max(1);
    }
    opts.budget_seconds = args.budget;
    opts.stop_snr_db = args.stop_snr;
    if args.objective == "entries" {
        opts.objective = fit::Objective::Entries;
    }
    let mut reports = Vec::new();
    let mut failed = false;
    if !args.json {
        println!(
            "table {path}: {} entries with a measurement ({:.1} %) within {}° of the normal, read in {load_seconds:.2} s",
            data.len(),
            100.0 * data.len() as f64 / lacquer::measured::merl::N_ENTRIES as f64,
            args.max_angle
        );
        println!(
            "{:<34} {:>4}  {:>6} {:>6} {:>6} {:>6} {:>7}  {:>9} {:>9}  {:>5} {:>7}",
            "model", "vars", "SNR R", "SNR G", "SNR B", "SNR", "SNRw", "cos-RMS", "Ngan", "iters", "time"
        );
    }
    for target in &targets {
        match fit::fit(target, &data, &opts) {
            Ok(r) => {
                if !args.json {
                    let m = &r.metrics;
                    println!(
                        "{:<34} {:>4}  {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>7.2}  {:>9.3e} {:>9.3e}  {:>5} {:>6.2}s",
                        r.model,
                        r.parameters.len(),
                        m.snr_db[0],
                        m.snr_db[1],
                        m.snr_db[2],
                        m.snr_db_mean,
                        m.snr_weighted_db,
                        m.rms_cos,
                        m.ngan,
                        r.iterations,
                        r.seconds
                    );
                }
                reports.push(r);
            }
            Err(e) => {
                failed = true;
                eprintln!("error: fitting {}: {e}", target.label());
            }
        }
    }
    let total = t0.elapsed().as_secs_f64();
    if args.json {
        let out = json!({
            "table": path,
            "entries": data.len(),
            "max_angle_deg": args.max_angle,
            "load_seconds": load_seconds,
            "options": opts,
            "fits": reports,
            "total_seconds": total,
        });
        println!("{}", serde_json::to_string_pretty(&out).expect("serialisable"));
    } else {
        println!("fitted parameters:");
        for r in &reports {
            let mats: Vec<String> = r.materials.iter().map(Value::to_string).collect();
            println!("  {}: {}", r.model, mats.join(" + "));
        }
        println!(
            "{} fit(s) in {total:.2} s. SNR: the thesis' 10·log10(VAR/MSE) per channel on the whole table (SNR: mean \
             of the channels; SNRw: the same for the cos- and solid-angle-weighted values the fit compares); cos-RMS: the thesis' \
             E(p)/sqrt(3N); Ngan: Ngan et al. 2005's error",
            reports.len()
        );
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
