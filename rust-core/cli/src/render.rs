//! `lacquer render`: the main job. Renders a preset or material in the built-in scene (or a
//! JSON scene, or an OBJ mesh in the built-in scene), or a comparison sheet of presets, to
//! OpenEXR with an optional PNG preview.

use clap::{Args, ValueEnum};
use lacquer::Material;
use lacquer_render::desc::{load_obj, DefaultScene, EnvChoice, SceneDesc};
use lacquer_render::output::{write_exr, ExrPrecision, Rgb8Image, ToneMap};
use lacquer_render::{render, sheet, Framebuffer, RenderSettings};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::ExitCode;

/// Default preset when neither `--preset` nor `--material` is given.
const DEFAULT_PRESET: &str = "gold_flake_8";

#[derive(Clone, Copy, ValueEnum)]
pub enum Precision {
    /// 16-bit half floats.
    Half,
    /// 32-bit floats.
    Float,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Tone {
    /// ACES filmic curve (Narkowicz fit).
    Filmic,
    /// Linear, clipped at 1.
    Clamp,
}

#[derive(Args)]
pub struct RenderArgs {
    /// Preset to render (see `lacquer presets`); default gold_flake_8.
    #[arg(long, conflicts_with = "material")]
    preset: Option<String>,
    /// Material to render: JSON string or path to a JSON file.
    #[arg(long)]
    material: Option<String>,
    /// Render a comparison sheet of presets instead: thesis-density, thesis-size, paints.
    #[arg(long, conflicts_with_all = ["preset", "material", "scene", "mesh"])]
    sheet: Option<String>,
    /// JSON scene file (see the lacquer-render docs); --preset/--material replace its "paint".
    #[arg(long, conflicts_with = "mesh")]
    scene: Option<PathBuf>,
    /// OBJ mesh to show in the built-in scene instead of the sphere.
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Output OpenEXR file.
    #[arg(short, long, default_value = "lacquer.exr")]
    output: PathBuf,
    /// Also write a tone-mapped PNG preview.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Image width in pixels.
    #[arg(long, default_value_t = 512)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Cell size of a sheet in pixels.
    #[arg(long, default_value_t = 192)]
    cell: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Maximum scattering events per path (1 = direct lighting).
    #[arg(long, default_value_t = 8)]
    max_depth: u32,
    /// Direct lighting only (same as --max-depth 1).
    #[arg(long)]
    direct: bool,
    /// Seed of the random streams (renders are deterministic per seed).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// EXR sample type.
    #[arg(long, value_enum, default_value = "half")]
    precision: Precision,
    /// Leave out the albedo.* and N.* layers.
    #[arg(long)]
    no_aovs: bool,
    /// Mean BRDF everywhere (no pixel footprints, so no sparkle).
    #[arg(long)]
    no_sparkle: bool,
    /// Environment of the built-in scene: studio, uniform:L, or a lat-long .hdr/.exr file.
    #[arg(long, default_value = "studio")]
    env: String,
    /// Environment multiplier.
    #[arg(long, default_value_t = 1.0)]
    env_scale: f32,
    /// Environment rotation about the up axis (degrees).
    #[arg(long, default_value_t = 0.0)]
    env_rotation: f32,
    /// Built-in scene without the key light.
    #[arg(long)]
    no_key_light: bool,
    /// Built-in scene without the floor.
    #[arg(long)]
    no_floor: bool,
    /// Clamp each path's contribution (biased; 0 = off).
    #[arg(long, default_value_t = 0.0)]
    clamp: f32,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
    /// PNG tone curve.
    #[arg(long, value_enum, default_value = "filmic")]
    tonemap: Tone,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Machine-readable report on stdout.
    #[arg(long)]
    json: bool,
}

fn material_of(args: &RenderArgs) -> Result<(Material, String), String> {
    if let Some(spec) = &args.material {
        let text = if spec.trim_start().starts_with('{') {
            spec.clone()
        } else {
            std::fs::read_to_string(spec).map_err(|e| format!("cannot read {spec}: {e}"))?
        };
        let m = Material::from_json(&text).map_err(|e| e.to_string())?;
        let label = m.to_json().to_string();
        return Ok((m, label));
    }
    let name = args.preset.as_deref().unwrap_or(DEFAULT_PRESET);
    Ok((Material::preset(name).map_err(|e| e.to_string())?, name.to_string()))
}

fn env_of(spec: &str) -> Result<EnvChoice, String> {
    if spec == "studio" {
        return Ok(EnvChoice::Studio);
    }
    if let Some(v) = spec.strip_prefix("uniform:") {
        let l: f32 = v.parse().map_err(|_| format!("--env uniform:L needs a number, got \"{v}\""))?;
        return Ok(EnvChoice::Uniform(l));
    }
    if spec == "uniform" {
        return Ok(EnvChoice::Uniform(1.0));
    }
    Ok(EnvChoice::File(PathBuf::from(spec)))
}

/// Runs `lacquer render`.
pub fn run(args: RenderArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn progress_bar(args: &RenderArgs) -> indicatif::ProgressBar {
    if args.quiet || args.json {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(1000);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} rendering [{bar:40}] {percent:>3}%  {elapsed} (eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb
}

fn run_inner(args: &RenderArgs) -> Result<(), String> {
    if args.width == 0 || args.height == 0 || args.spp == 0 || args.cell == 0 {
        return Err("--width, --height, --cell and --spp must be positive".into());
    }
    let settings = RenderSettings {
        spp: args.spp,
        max_depth: if args.direct { 1 } else { args.max_depth },
        seed: args.seed,
        threads: args.threads,
        aovs: !args.no_aovs,
        footprints: !args.no_sparkle,
        clamp: args.clamp,
        ..Default::default()
    };
    let scene_opts = DefaultScene {
        width: args.width,
        height: args.height,
        mesh: match &args.mesh {
            Some(p) => Some(load_obj(p)?),
            None => None,
        },
        env: env_of(&args.env)?,
        env_scale: args.env_scale,
        env_rotation_deg: args.env_rotation,
        key_light: !args.no_key_light,
        floor: !args.no_floor,
    };
    let tone = match args.tonemap {
        Tone::Filmic => ToneMap::Filmic,
        Tone::Clamp => ToneMap::Clamp,
    };
    let pb = progress_bar(args);
    let mut on_progress = |f: f32| {
        pb.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
        true
    };
    let started = std::time::Instant::now();

    let (fb, png_image, what): (Framebuffer, Option<Rgb8Image>, Value) = if let Some(name) = &args.sheet {
        let spec = sheet::find(name).ok_or_else(|| {
            let known: Vec<&str> = sheet::SHEETS.iter().map(|s| s.name).collect();
            format!("unknown sheet \"{name}\" (known: {})", known.join(", "))
        })?;
        let img = spec.render(args.cell, &scene_opts, &settings, &mut on_progress)?;
        let png = args.png.as_ref().map(|_| img.to_png_image(args.exposure, tone));
        let presets: Vec<&str> = spec.rows.iter().flat_map(|r| r.1.iter().map(|c| c.0)).collect();
        (img.fb, png, json!({"sheet": spec.name, "title": spec.title, "presets": presets}))
    } else {
        let explicit = args.preset.is_some() || args.material.is_some();
        let (scene, info) = match &args.scene {
            Some(path) => {
                let desc = SceneDesc::load(path)?;
                let base = path.parent().map(|p| p.to_path_buf()).unwrap_or_default();
                let paint = if explicit { Some(material_of(args)?) } else { None };
                let scene = desc.build(&base, args.width, args.height, paint.as_ref().map(|m| &m.0))?;
                let mut info = json!({"scene": path.display().to_string()});
                if let Some((m, label)) = paint {
                    info["material"] = json!(label);
                    info["material_json"] = m.to_json();
                }
                (scene, info)
            }
            None => {
                let (material, label) = material_of(args)?;
                let info = json!({"material": label, "material_json": material.to_json(), "scene": "built-in"});
                (scene_opts.build(material)?, info)
            }
        };
        let fb = render(&scene, &settings, &mut on_progress).map_err(|e| e.to_string())?;
        let png = args.png.as_ref().map(|_| Rgb8Image::from_framebuffer(&fb, args.exposure, tone));
        (fb, png, info)
    };
    pb.finish_and_clear();

    let precision = match args.precision {
        Precision::Half => ExrPrecision::Half,
        Precision::Float => ExrPrecision::Float,
    };
    let meta = [
        ("lacquer:render", what.to_string()),
        ("lacquer:spp", settings.spp.to_string()),
        ("lacquer:max_depth", settings.max_depth.to_string()),
        ("lacquer:seed", settings.seed.to_string()),
        ("lacquer:seconds", format!("{:.3}", fb.stats.seconds)),
    ];
    write_exr(&fb, &args.output, precision, &meta)?;
    if let (Some(path), Some(img)) = (&args.png, png_image) {
        img.write_png(path)?;
    }
    let total = started.elapsed().as_secs_f64();
    let s = fb.stats;
    if args.json {
        let report = json!({
            "output": args.output,
            "png": args.png,
            "width": fb.width,
            "height": fb.height,
            "spp": settings.spp,
            "max_depth": settings.max_depth,
            "seed": settings.seed,
            "render_seconds": s.seconds,
            "total_seconds": total,
            "paths": s.paths,
            "paths_per_second": s.paths_per_second,
            "invalid_paths": s.invalid,
            "mean_rgb": fb.mean(),
            "what": what,
        });
        println!("{}", serde_json::to_string_pretty(&report).expect("serialisable"));
    } else if !args.quiet {
        eprintln!(
            "wrote {} ({}×{}, {} spp, max depth {}): render {:.2} s, {:.2} M paths/s{}",
            args.output.display(),
            fb.width,
            fb.height,
            settings.spp,
            settings.max_depth,
            s.seconds,
            s.paths_per_second / 1e6,
            args.png.as_ref().map_or(String::new(), |p| format!("; preview {}", p.display()))
        );
        if s.invalid > 0 {
            eprintln!("warning: {} paths gave a non-finite or negative value and were dropped", s.invalid);
        }
    }
    Ok(())
}
