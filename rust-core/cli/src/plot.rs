//! `lacquer plot`: BRDF slices (in-plane, polar), directional albedo against angle, the
//! sampler's histogram against its pdf, for any number of materials, presets, MERL tables and
//! fits of a table, overlaid; and a render sheet of a MERL table next to its fits on the same
//! shader ball. SVG or PNG (see [`crate::figure`]).

use crate::figure::{Plot, Series, Style};
use clap::Args;
use lacquer::fit::{self, FitData, FitModel, FitOptions};
use lacquer::measured::merl::MerlTable;
use lacquer::rng::Pcg32;
use lacquer::{Material, Rgb, Vec3};
use lacquer_render::desc::DefaultScene;
use lacquer_render::output::ToneMap;
use lacquer_render::{sheet, RenderSettings};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `lacquer plot`.
#[derive(Args)]
#[command(after_help = "Examples:\n  \
lacquer plot in-plane --preset gold_flake_8 --preset silver_flake_8 --theta 30 --log -o slice.svg\n  \
lacquer plot polar --material '{\"model\": \"ward\", \"alpha_x\": 0.2}' --theta 45 -o polar.png\n  \
lacquer plot albedo --material oren_nayar --material eon -o albedo.svg\n  \
lacquer plot sampler --preset gold_flake_8 --theta 40 -o sampler.svg\n  \
lacquer plot in-plane --table gold.binary --fit ward --fit cook_torrance --log -o fits.svg\n  \
lacquer plot sheet --table gold.binary --fit ward --fit cook_torrance -o sheet.png\n  \
lacquer plot data --data docs/data/rough-coat-validation-albedo.json -o albedo-error.svg")]
pub struct PlotArgs {
    /// What to plot: in-plane (BRDF in the plane of incidence), polar (the same slice in polar
    /// axes), albedo (directional albedo against the view angle), sampler (histogram of sampled
    /// θi against the marginal of the pdf), sheet (renders of the tables and their fits),
    /// data (curves measured elsewhere, from `--data`).
    #[arg(value_parser = ["in-plane", "polar", "albedo", "sampler", "sheet", "data"])]
    pub kind: String,
    /// A preset; repeatable.
    #[arg(long)]
    pub preset: Vec<String>,
    /// A material: JSON, a JSON file, a preset or model name; a JSON list is the sum of its
    /// lobes (as `lacquer fit` writes them); repeatable.
    #[arg(long)]
    pub material: Vec<String>,
    /// A measured MERL .binary table; repeatable.
    #[arg(long)]
    pub table: Vec<String>,
    /// Fit this model to the first table and plot the fit too (`a+b` is a sum of lobes, as
    /// in `lacquer fit`); repeatable.
    #[arg(long)]
    pub fit: Vec<String>,
    /// Curve labels in order: presets, materials, tables, fits (default: their names).
    #[arg(long)]
    pub label: Vec<String>,
    /// Incidence angle θi in degrees (in-plane, polar); the view angle θo (sampler).
    #[arg(long, default_value_t = 30.0)]
    pub theta: f64,
    /// Colour channel plotted: lum (Rec. 709 luminance), r, g or b.
    #[arg(long, default_value = "lum", value_parser = ["lum", "r", "g", "b"])]
    pub channel: String,
    /// Logarithmic value axis.
    #[arg(long)]
    pub log: bool,
    /// Samples per angle (albedo, default 4096) or in total (sampler, default 400000).
    #[arg(long)]
    pub samples: Option<usize>,
    /// Angle step in degrees of slices and albedo curves.
    #[arg(long, default_value_t = 1.0)]
    pub step: f64,
    /// Output file: .svg or .png.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Figure width in pixels.
    #[arg(long, default_value_t = 760)]
    pub width: u32,
    /// Figure height in pixels.
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Table entries in the fits' refinement subset.
    #[arg(long, default_value_t = 20_000)]
    pub fit_points: usize,
    /// Sheet cell size in pixels.
    #[arg(long, default_value_t = 160)]
    pub cell: u32,
    /// Sheet samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Curves for `plot data`: a JSON file `{"title", "xlabel", "ylabel", "log_y"?, "series":
    /// [{"label", "x": [...], "y": [...]}]}` (the shape `--json` prints; the validation
    /// examples write them into `docs/data/`).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Print the plotted data (or the sheet's materials) as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Plotted points `(x, y)`.
type Curve = Vec<(f64, f64)>;

/// A curve's source: a label and the lobes whose BRDFs add.
struct Source {
    label: String,
    lobes: Vec<Material>,
}

impl Source {
    fn eval(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> Rgb<f64> {
        self.lobes.iter().fold(Rgb::zero(), |acc, m| acc + m.eval(wi, wo))
    }
}

fn channel(c: Rgb<f64>, which: &str) -> f64 {
    match which {
        "r" => c.r,
        "g" => c.g,
        "b" => c.b,
        _ => 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b,
    }
}

/// Runs `lacquer plot`.
pub fn run(args: PlotArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn sources(args: &PlotArgs) -> Result<Vec<Source>, String> {
    let mut out = Vec::new();
    for p in &args.preset {
        let m = Material::preset(p).map_err(|e| format!("preset {p}: {e}"))?;
        out.push(Source { label: p.clone(), lobes: vec![m] });
    }
    for spec in &args.material {
        let lobes = fit::materials_from_spec(spec).map_err(|e| format!("material {spec}: {e}"))?;
        let label = lobes.iter().map(|m| m.info().name).collect::<Vec<_>>().join("+");
        out.push(Source { label, lobes });
    }
    let mut first_table = None;
    for path in &args.table {
        let table = MerlTable::read(path).map_err(|e| format!("table {path}: {e}"))?;
        if first_table.is_none() {
            first_table = Some(table.clone());
        }
        let name = std::path::Path::new(path).file_stem().and_then(|s| s.to_str()).unwrap_or(path).to_string();
        out.push(Source {
            label: format!("{name} (table)"),
            lobes: vec![lacquer::measured::material_from_table(table)],
        });
    }
    if !args.fit.is_empty() {
        let Some(table) = first_table else {
            return Err("--fit needs a --table to fit".into());
        };
        let data = FitData::from_merl(&table);
        let opts = FitOptions { points: args.fit_points, ..FitOptions::default() };
        for spec in &args.fit {
            let model = FitModel::parse(spec).map_err(|e| format!("fit model {spec}: {e}"))?;
            let report = fit::fit(&model, &data, &opts).map_err(|e| format!("fitting {spec}: {e}"))?;
            let mut lobes = Vec::new();
            for m in &report.materials {
                lobes.push(Material::from_json(&m.to_string()).map_err(|e| format!("fitted {spec}: {e}"))?);
            }
            out.push(Source {
                label: format!("{} fit (SNR {:.1} dB)", report.model, report.metrics.snr_db_mean),
                lobes,
            });
        }
    }
    if out.is_empty() {
        return Err("nothing to plot: give --preset, --material or --table (and --fit)".into());
    }
    if !args.label.is_empty() {
        if args.label.len() != out.len() {
            return Err(format!("{} labels for {} curves", args.label.len(), out.len()));
        }
        for (s, l) in out.iter_mut().zip(&args.label) {
            s.label = l.clone();
        }
    }
    Ok(out)
}

/// The in-plane slice at incidence `theta_i`: `(θo, f)` with θo signed, the light at
/// positive x (θo = −θi is the mirror direction).
fn in_plane(src: &Source, theta_i: f64, step: f64, ch: &str) -> Vec<(f64, f64)> {
    let ti = theta_i.to_radians();
    let wi = Vec3::new(ti.sin(), 0.0, ti.cos());
    let n = (89.0 / step).floor() as i64;
    (-n..=n)
        .map(|k| {
            let t = k as f64 * step;
            let wo = Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos());
            (t, channel(src.eval(wi, wo), ch))
        })
        .collect()
}

/// Directional albedo (mean sample weight over a stratified `√n × √n` grid) for view angles
/// 0..89°.
fn albedo(src: &Source, step: f64, n: usize, ch: &str) -> Vec<(f64, f64)> {
    let side = (n as f64).sqrt().ceil().max(1.0) as usize;
    let steps = (89.0 / step).floor() as usize;
    (0..=steps)
        .map(|k| {
            let t = k as f64 * step;
            let wo = Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos());
            let mut rng = Pcg32::new(7, k as u64);
            let mut sum = 0.0;
            for m in &src.lobes {
                let mut acc = Rgb::zero();
                for i in 0..side {
                    for j in 0..side {
                        let u = [
                            (i as f64 + rng.uniform()) / side as f64,
                            (j as f64 + rng.uniform()) / side as f64,
                            rng.uniform(),
                        ];
                        if let Some(s) = m.sample(wo, u) {
                            if s.weight.is_finite() {
                                acc += s.weight;
                            }
                        }
                    }
                }
                sum += channel(acc, ch) / (side * side) as f64;
            }
            (t, sum)
        })
        .collect()
}

/// Histogram of sampled θi (per degree; delta-lobe samples left out) and the marginal of the
/// pdf over azimuth, `∫ pdf sin θ dφ · π/180`, at the bins' centres (1° bins).
fn sampler(m: &Material, theta_o: f64, n: usize) -> (Curve, Curve, usize) {
    let to = theta_o.to_radians();
    let wo = Vec3::new(to.sin(), 0.0, to.cos());
    let mut hist = vec![0usize; 90];
    let mut rng = Pcg32::new(11, 3);
    let mut delta = 0;
    for _ in 0..n {
        let u = [rng.uniform(), rng.uniform(), rng.uniform()];
        if let Some(s) = m.sample(wo, u) {
            if s.delta {
                delta += 1;
                continue;
            }
            let t = s.wi.z.clamp(-1.0, 1.0).acos().to_degrees();
            if (0.0..90.0).contains(&t) {
                hist[t as usize] += 1;
            }
        }
    }
    let hist_pts = hist.iter().enumerate().map(|(i, c)| (i as f64 + 0.5, *c as f64 / n as f64)).collect();
    let nphi = 720;
    let pdf_pts = (0..90)
        .map(|i| {
            // Gauss-Legendre-free: the midpoint rule on 4 sub-steps in θ and 720 in φ.
            let mut acc = 0.0;
            for q in 0..4 {
                let t = (i as f64 + (q as f64 + 0.5) / 4.0).to_radians();
                for j in 0..nphi {
                    let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
                    let wi = Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos());
                    acc += m.pdf(wi, wo) * t.sin();
                }
            }
            (i as f64 + 0.5, acc / 4.0 * std::f64::consts::TAU / nphi as f64 * std::f64::consts::PI / 180.0)
        })
        .collect();
    (hist_pts, pdf_pts, delta)
}

fn run_inner(args: &PlotArgs) -> Result<(), String> {
    if !(0.0..=89.0).contains(&args.theta) {
        return Err(format!("--theta {} is outside [0, 89] degrees", args.theta));
    }
    if !(args.step > 0.0 && args.step <= 30.0) {
        return Err(format!("--step {} is outside (0, 30] degrees", args.step));
    }
    if args.width < 200 || args.height < 150 || args.width > 8000 || args.height > 8000 {
        return Err("--width and --height must be in [200, 8000] × [150, 8000]".into());
    }
    match args.output.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("svg") | Some("png") => {}
        _ => return Err(format!("{}: the output must end in .svg or .png", args.output.display())),
    }
    if args.kind == "sheet" && args.output.extension().and_then(|e| e.to_str()) != Some("png") {
        return Err("a sheet is a PNG: give -o FILE.png".into());
    }
    if args.kind == "data" {
        let plot = data_plot(args)?;
        plot.figure(args.width, args.height).write(&args.output)?;
        eprintln!("wrote {} ({} curves)", args.output.display(), plot.series.len());
        return Ok(());
    }
    let srcs = sources(args)?;
    let ch = args.channel.as_str();
    let what = if ch == "lum" { "luminance".to_string() } else { format!("channel {ch}") };
    let mut plot = Plot {
        title: String::new(),
        xlabel: String::new(),
        ylabel: String::new(),
        log_y: args.log,
        polar: false,
        series: Vec::new(),
    };
    match args.kind.as_str() {
        "in-plane" | "polar" => {
            plot.polar = args.kind == "polar";
            plot.title = format!("BRDF in the plane of incidence, θi = {}° ({what})", args.theta);
            plot.xlabel = "θo (degrees; the mirror direction is at −θi)".into();
            plot.ylabel = "f (1/sr)".into();
            for s in &srcs {
                plot.series.push(Series {
                    label: s.label.clone(),
                    points: in_plane(s, args.theta, args.step, ch),
                    style: Style::Line,
                });
            }
        }
        "albedo" => {
            let n = args.samples.unwrap_or(4096);
            plot.title = format!("Directional albedo ({what}, {n} stratified samples per angle)");
            plot.xlabel = "θo (degrees)".into();
            plot.ylabel = "albedo".into();
            for s in &srcs {
                plot.series.push(Series {
                    label: s.label.clone(),
                    points: albedo(s, args.step, n, ch),
                    style: Style::Line,
                });
            }
        }
        "sampler" => {
            if srcs.len() != 1 || srcs[0].lobes.len() != 1 {
                return Err(
                    "sampler plots one material (one lobe): give exactly one --preset, --material or --table".into()
                );
            }
            let n = args.samples.unwrap_or(400_000);
            let (hist, pdf, delta) = sampler(&srcs[0].lobes[0], args.theta, n);
            plot.title = format!("{}: sampled θi at θo = {}° ({n} samples; {delta} delta)", srcs[0].label, args.theta);
            plot.xlabel = "θi (degrees)".into();
            plot.ylabel = "density per degree".into();
            plot.series.push(Series { label: "histogram of sample()".into(), points: hist, style: Style::Steps });
            plot.series.push(Series { label: "pdf() marginal".into(), points: pdf, style: Style::Dashed });
        }
        "sheet" => return run_sheet(args, srcs),
        _ => unreachable!("clap checks the kind"),
    }
    plot.figure(args.width, args.height).write(&args.output)?;
    if args.json {
        let series: Vec<Value> =
            plot.series.iter().map(|s| json!({"label": s.label, "x": s.points.iter().map(|p| p.0).collect::<Vec<_>>(), "y": s.points.iter().map(|p| p.1).collect::<Vec<_>>()})).collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({"output": args.output, "kind": args.kind, "series": series}))
                .expect("serialisable")
        );
    } else {
        eprintln!("wrote {} ({} curves)", args.output.display(), plot.series.len());
    }
    Ok(())
}

/// The plot of `--data`: curves measured elsewhere (see [`PlotArgs::data`]).
fn data_plot(args: &PlotArgs) -> Result<Plot, String> {
    let path = args.data.as_ref().ok_or("plot data needs --data FILE.json")?;
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let text_of = |k: &str| v.get(k).and_then(Value::as_str).unwrap_or("").to_string();
    let numbers = |s: &Value, k: &str| -> Result<Vec<f64>, String> {
        s.get(k)
            .and_then(Value::as_array)
            .ok_or(format!("{}: a series lacks the list \"{k}\"", path.display()))?
            .iter()
            .map(|x| x.as_f64().ok_or(format!("{}: \"{k}\" holds a non-number", path.display())))
            .collect()
    };
    let list = v.get("series").and_then(Value::as_array).ok_or(format!("{}: no \"series\" list", path.display()))?;
    let mut series = Vec::new();
    for s in list {
        let (x, y) = (numbers(s, "x")?, numbers(s, "y")?);
        if x.len() != y.len() || x.is_empty() {
            return Err(format!("{}: a series has {} x and {} y values", path.display(), x.len(), y.len()));
        }
        let label = s.get("label").and_then(Value::as_str).unwrap_or("").to_string();
        series.push(Series { label, points: x.into_iter().zip(y).collect(), style: Style::Line });
    }
    Ok(Plot {
        title: text_of("title"),
        xlabel: text_of("xlabel"),
        ylabel: text_of("ylabel"),
        log_y: args.log || v.get("log_y").and_then(Value::as_bool).unwrap_or(false),
        polar: false,
        series,
    })
}

/// Renders every source on the built-in shader ball, one row: tables first, then fits.
/// Fits with several lobes render as the table of their sum.
fn run_sheet(args: &PlotArgs, srcs: Vec<Source>) -> Result<(), String> {
    if args.cell < 16 || args.cell > 2048 || args.spp == 0 {
        return Err("--cell must be in [16, 2048] and --spp positive".into());
    }
    let mut row = Vec::new();
    let mut info = Vec::new();
    for s in srcs {
        info.push(json!({"label": s.label, "materials": s.lobes.iter().map(Material::to_json).collect::<Vec<_>>()}));
        let m = if s.lobes.len() == 1 {
            s.lobes.into_iter().next().expect("one lobe")
        } else {
            lacquer::measured::material_from_table(lacquer::measured::tabulate(&s.lobes))
        };
        row.push((s.label, m));
    }
    let settings = RenderSettings { spp: args.spp, ..Default::default() };
    let img = sheet::render_cells(&[row], args.cell, &DefaultScene::default(), &settings, &mut |_| true)?;
    img.to_png_image(0.0, ToneMap::Filmic).write_png(&args.output)?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({"output": args.output, "cells": info})).expect("serialisable")
        );
    } else {
        eprintln!("wrote {} ({} cells, {:.1} s)", args.output.display(), info.len(), img.fb.stats.seconds);
    }
    Ok(())
}
