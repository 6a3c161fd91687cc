//! # lacquer-render
//!
//! A reference path tracer for lacquer materials: what `lacquer render` runs, what the C ABI
//! and the Blender engine call, and the ground truth that comparisons with Mitsuba and Cycles
//! use. It does light transport only; every BRDF value, density and sample comes from
//! [`lacquer::Material`] (`eval`/`pdf`/`sample`, and `eval_at`/`sample_at` with the pixel
//! footprint for sparkle).
//!
//! - Geometry: triangle meshes (OBJ) in a binned-SAH BVH, spheres, rectangles; a pinhole camera
//!   with ray differentials (uv footprints of camera-ray hits).
//! - Lights: point and spot (`I/r²·cos θ`), sun (sharp or with a disk), spherical and
//!   rectangular area lights, lat-long environment maps importance-sampled by luminance.
//! - Integrator: path tracing with next-event estimation and MIS (power heuristic) against the
//!   material's own sampling; delta lobes and delta lights skip MIS; `max_depth = 1` is direct
//!   lighting only. Deterministic per seed; tiles in parallel; a progress callback that can cancel.
//! - Output: OpenEXR (half/float, `R G B A`, `albedo.*`, `N.*`), tone-mapped PNG previews,
//!   comparison sheets of presets.
//!
//! World space is y-up; see [`desc`] for the JSON scene format and [`job`] for a whole render
//! as one JSON document (what the C ABI and other hosts wrap: job text in, framebuffer out,
//! a `fn(progress) -> continue` callback on the calling thread).
//!
//! ```
//! use lacquer_render::{desc::DefaultScene, integrator::{render_quiet, RenderSettings}};
//! let scene = DefaultScene { width: 16, height: 16, ..Default::default() }
//!     .build(lacquer::Material::preset("gold_flake_3").unwrap())
//!     .unwrap();
//! let img = render_quiet(&scene, &RenderSettings { spp: 2, ..Default::default() });
//! assert!(img.color.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
//! ```

// `!(x > 0.0)` is used on purpose throughout: it treats NaN as "not positive".
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bvh;
pub mod camera;
pub mod desc;
pub mod distrib;
pub mod env;
pub mod font;
pub mod geom;
pub mod integrator;
pub mod job;
pub mod lights;
pub mod output;
pub mod perturb;
pub mod scene;
pub mod shapes;
pub mod sheet;
pub mod texture;

pub use integrator::{render, render_quiet, Cancelled, Framebuffer, Progressive, RenderSettings, RenderStats};
pub use job::{render_job, JobError, JobRender, RenderJob};
pub use scene::{Scene, SceneBuilder};
