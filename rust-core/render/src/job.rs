//! A whole render as one JSON document: the entry point for hosts that cross a language
//! boundary (the C ABI, Python, the Blender engine). A host passes the job text and a
//! progress callback `fn(fraction) -> continue?`, and gets a [`Framebuffer`] back.
//!
//! ```json
//! {"preset": "gold_flake_8", "width": 256, "height": 256, "spp": 32}
//! {"material": {"model": "lambert", "albedo": 0.5}, "scene": {...}, "max_depth": 1}
//! ```
//!
//! Keys: `preset` or `material` (material JSON; the built-in scene's sphere, or the scene's
//! material named `"paint"`), `scene` (an inline scene, see [`crate::desc`]; default: the
//! built-in scene), `width`, `height` (512), `spp` (64), `max_depth` (8), `seed` (0),
//! `threads` (0 = all cores), `aovs` (true), `lobe_aovs` (false: Diffuse/Glossy Color), `sparkle` (true), `clamp` (0), `transparent`
//! (false: camera rays that miss see black, alpha 0, instead of the environment), and for the
//! built-in scene `env` (`"studio"`, `"uniform:L"` or a lat-long file), `env_scale`,
//! `env_rotation_deg`, `key_light`, `floor`.

use crate::desc::{DefaultScene, EnvChoice, SceneDesc};
use crate::integrator::{render, Framebuffer, Progressive, RenderSettings};
use lacquer::Material;
use serde::Deserialize;
use serde_json::Value;
use std::path::PathBuf;

fn d_size() -> u32 {
    512
}
fn d_spp() -> u32 {
    64
}
fn d_depth() -> u32 {
    8
}
fn d_true() -> bool {
    true
}
fn d_one() -> f32 {
    1.0
}
fn d_studio() -> String {
    "studio".into()
}

/// A render job (see the module docs).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderJob {
    /// Preset name.
    #[serde(default)]
    pub preset: Option<String>,
    /// Material JSON.
    #[serde(default)]
    pub material: Option<Value>,
    /// Inline scene (default: the built-in scene).
    #[serde(default)]
    pub scene: Option<SceneDesc>,
    /// Image width.
    #[serde(default = "d_size")]
    pub width: u32,
    /// Image height.
    #[serde(default = "d_size")]
    pub height: u32,
    /// Samples per pixel.
    #[serde(default = "d_spp")]
    pub spp: u32,
    /// Maximum scattering events (1 = direct lighting).
    #[serde(default = "d_depth")]
    pub max_depth: u32,
    /// Seed.
    #[serde(default)]
    pub seed: u64,
    /// Worker threads (0 = all cores).
    #[serde(default)]
    pub threads: usize,
    /// Albedo and normal layers.
    #[serde(default = "d_true")]
    pub aovs: bool,
    /// Diffuse Color and Glossy Color layers (default false).
    #[serde(default)]
    pub lobe_aovs: bool,
    /// Pixel footprints for sparkle.
    #[serde(default = "d_true")]
    pub sparkle: bool,
    /// Path contribution clamp (0 = off).
    #[serde(default)]
    pub clamp: f32,
    /// Transparent film: camera rays that miss see black (alpha 0).
    #[serde(default)]
    pub transparent: bool,
    /// Built-in scene: environment.
    #[serde(default = "d_studio")]
    pub env: String,
    /// Built-in scene: environment multiplier.
    #[serde(default = "d_one")]
    pub env_scale: f32,
    /// Built-in scene: environment rotation (degrees).
    #[serde(default)]
    pub env_rotation_deg: f32,
    /// Built-in scene: key light.
    #[serde(default = "d_true")]
    pub key_light: bool,
    /// Built-in scene: floor.
    #[serde(default = "d_true")]
    pub floor: bool,
}

/// Why a job produced no image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JobError {
    /// The job or its material or scene is invalid (the message says where).
    Invalid(String),
    /// The progress callback asked to stop.
    Cancelled,
}

impl std::fmt::Display for JobError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JobError::Invalid(m) => f.write_str(m),
            JobError::Cancelled => f.write_str("render cancelled"),
        }
    }
}

impl std::error::Error for JobError {}

impl RenderJob {
    /// Parses a job.
    pub fn from_json(text: &str) -> Result<Self, JobError> {
        serde_json::from_str(text).map_err(|e| JobError::Invalid(format!("render job: {e}")))
    }

    /// The render settings of this job.
    #[must_use]
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            spp: self.spp,
            max_depth: self.max_depth,
            seed: self.seed,
            threads: self.threads,
            aovs: self.aovs,
            lobe_aovs: self.lobe_aovs,
            footprints: self.sparkle,
            clamp: self.clamp,
            transparent: self.transparent,
            ..Default::default()
        }
    }

    fn material(&self) -> Result<Option<Material>, JobError> {
        let inv = |e: lacquer::Error| JobError::Invalid(e.to_string());
        match (&self.preset, &self.material) {
            (Some(_), Some(_)) => Err(JobError::Invalid("give \"preset\" or \"material\", not both".into())),
            (Some(p), None) => Material::preset(p).map(Some).map_err(inv),
            (None, Some(m)) => Material::from_value(m).map(Some).map_err(inv),
            (None, None) => Ok(None),
        }
    }

    /// Builds the scene (the built-in one unless `scene` is given). Relative paths in an inline
    /// scene resolve against the working directory.
    pub fn scene(&self) -> Result<crate::Scene, JobError> {
        if self.width == 0 || self.height == 0 || self.spp == 0 {
            return Err(JobError::Invalid("width, height and spp must be positive".into()));
        }
        if self.width as u64 * self.height as u64 > 1 << 28 {
            return Err(JobError::Invalid("image too large".into()));
        }
        let material = self.material()?;
        match &self.scene {
            Some(desc) => {
                desc.build(&PathBuf::from("."), self.width, self.height, material.as_ref()).map_err(JobError::Invalid)
            }
            None => {
                let env = if self.env == "studio" {
                    EnvChoice::Studio
                } else if let Some(v) = self.env.strip_prefix("uniform:") {
                    EnvChoice::Uniform(v.parse().map_err(|_| JobError::Invalid(format!("env: bad radiance \"{v}\"")))?)
                } else {
                    EnvChoice::File(PathBuf::from(&self.env))
                };
                let opts = DefaultScene {
                    width: self.width,
                    height: self.height,
                    mesh: None,
                    env,
                    env_scale: self.env_scale,
                    env_rotation_deg: self.env_rotation_deg,
                    key_light: self.key_light,
                    floor: self.floor,
                };
                let m = match material {
                    Some(m) => m,
                    None => Material::preset("gold_flake_8").map_err(|e| JobError::Invalid(e.to_string()))?,
                };
                opts.build(m).map_err(JobError::Invalid)
            }
        }
    }
}

/// Parses and renders a job. `progress(fraction)` runs on the calling thread; returning
/// `false` cancels.
pub fn render_job(json: &str, progress: &mut dyn FnMut(f32) -> bool) -> Result<Framebuffer, JobError> {
    let job = RenderJob::from_json(json)?;
    let scene = job.scene()?;
    render(&scene, &job.settings(), progress).map_err(|_| JobError::Cancelled)
}

/// A job rendered in rounds (progressive display, see [`Progressive`]): the scene is built
/// once, then each [`JobRender::advance`] adds samples per pixel.
pub struct JobRender {
    scene: crate::Scene,
    progressive: Progressive,
}

impl JobRender {
    /// Parses the job and builds its scene; no samples yet.
    pub fn new(json: &str) -> Result<Self, JobError> {
        let job = RenderJob::from_json(json)?;
        let scene = job.scene()?;
        let progressive = Progressive::new(&scene, &job.settings());
        Ok(Self { scene, progressive })
    }

    /// Adds up to `n` samples per pixel (never beyond the job's `spp`); returns how many.
    /// `progress(fraction of this round)` may cancel the round, which leaves the render as it was.
    pub fn advance(&mut self, n: u32, progress: &mut dyn FnMut(f32) -> bool) -> Result<u32, JobError> {
        self.progressive.advance(&self.scene, n, progress).map_err(|_| JobError::Cancelled)
    }

    /// Samples per pixel done so far.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.progressive.samples()
    }

    /// The job's samples per pixel.
    #[must_use]
    pub fn target(&self) -> u32 {
        self.progressive.target()
    }

    /// The mean of the samples so far.
    #[must_use]
    pub fn framebuffer(&self) -> Framebuffer {
        self.progressive.framebuffer()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_renders_and_reports_errors() {
        let fb =
            render_job(r#"{"preset": "white_lambert", "width": 8, "height": 6, "spp": 2}"#, &mut |_| true).unwrap();
        assert_eq!((fb.width, fb.height), (8, 6));
        assert!(fb.albedo.is_some());
        let inline = r#"{"material": {"model": "lambert"}, "width": 4, "height": 4, "spp": 1, "aovs": false,
            "scene": {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "fov_deg": 40},
                      "objects": [{"type": "mesh", "material": "paint",
                                   "positions": [[-1, -1, 0], [1, -1, 0], [0, 1, 0]], "triangles": [[0, 1, 2]]}],
                      "lights": [{"type": "environment", "radiance": 1}]}}"#;
        let fb = render_job(inline, &mut |_| true).unwrap();
        // The triangle covers the middle of the frame and is lit by the environment.
        let hits: Vec<f32> = fb.color.iter().zip(&fb.alpha).filter(|(_, a)| **a == 1.0).map(|(c, _)| c[0]).collect();
        assert!(hits.len() >= 4 && hits.iter().all(|v| *v > 0.0 && *v < 1.5), "{hits:?}");
        for bad in [
            r#"{"preset": "nope"}"#,
            r#"{"widht": 3}"#,
            r#"{"preset": "white_lambert", "material": {"model": "lambert"}}"#,
            r#"{"spp": 0}"#,
        ] {
            assert!(matches!(render_job(bad, &mut |_| true), Err(JobError::Invalid(_))), "{bad}");
        }
        let r = render_job(r#"{"width": 64, "height": 64, "spp": 4096}"#, &mut |_| false);
        assert_eq!(r.err(), Some(JobError::Cancelled));
    }

    #[test]
    fn progressive_rounds_equal_the_one_shot_render_bit_for_bit() {
        let job = r#"{"preset": "gold_flake_8", "width": 40, "height": 24, "spp": 7}"#;
        let once = render_job(job, &mut |_| true).unwrap();
        let mut p = JobRender::new(job).unwrap();
        assert_eq!((p.samples(), p.target()), (0, 7));
        assert!(p.framebuffer().color.iter().flatten().all(|v| *v == 0.0));
        let mut rounds = Vec::new();
        for n in [1, 2, 3, 5] {
            rounds.push(p.advance(n, &mut |_| true).unwrap());
        }
        assert_eq!(rounds, [1, 2, 3, 1]); // never beyond spp
        let fb = p.framebuffer();
        assert_eq!(p.samples(), 7);
        assert_eq!(fb.color, once.color);
        assert_eq!(fb.alpha, once.alpha);
        assert_eq!(fb.albedo, once.albedo);
        assert_eq!(fb.normal, once.normal);
        assert_eq!(fb.stats.paths, once.stats.paths);
        assert!(once.color.iter().flatten().any(|v| *v > 0.0));
        // A cancelled round (the callback runs after 0.1 s) leaves the render as it was.
        let mut big = JobRender::new(r#"{"width": 64, "height": 64, "spp": 4096}"#).unwrap();
        assert_eq!(big.advance(4096, &mut |_| false).err(), Some(JobError::Cancelled));
        assert_eq!(big.samples(), 0);
        assert_eq!(big.advance(1, &mut |_| true), Ok(1));
    }
}
