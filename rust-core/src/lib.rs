//! # Lacquer
//!
//! Physically checked BRDFs: the classic reflectance models and a coated car-paint model,
//! each with evaluation, importance sampling and the sampling density side by side, an f64
//! reference path and an f32 fast path, and checks that ship with the library.
//!
//! ## Conventions
//! - Local shading frame: z is the surface normal, x the tangent (anisotropy axis), y = z × x.
//! - `wi` (toward the light) and `wo` (toward the viewer) are unit vectors pointing **away**
//!   from the surface. Below-horizon directions give `f = 0` and `pdf = 0`.
//! - `eval(wi, wo)` is `f_r` in 1/sr **without** the cosine, linear Rec.709 RGB.
//! - `pdf(wi, wo)` is the solid-angle density of `sample` choosing `wi` given `wo`.
//! - `sample(wo, u)` takes three uniform numbers (lobe choice, then two for the direction)
//!   and returns `wi`, `weight = f·cos θi/pdf` and `pdf`.
//! - Units: roughness α is the slope-space width (dimensionless), lengths in µm, film
//!   thickness in nm, angles in radians unless a parameter says degrees.
//!
//! ```
//! use lacquer::{Material, Vec3};
//! let m = Material::from_json(r#"{"model": "lambert", "albedo": 0.8}"#).unwrap();
//! let w = Vec3::<f64>::new(0.0, 0.0, 1.0);
//! let f = m.eval(w, w);
//! assert!((f.r - 0.8 / std::f64::consts::PI).abs() < 1e-15);
//! ```

// `!(x > 0.0)` is used on purpose throughout: it treats NaN as "not positive".
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod batch;
pub mod bench;
pub mod bxdf;
pub mod check;
pub mod color;
pub mod energy_compensation;
pub mod error;
pub mod fit;
pub mod frame;
pub mod fresnel;
pub mod lanes;
pub mod lobes;
pub mod material;
pub mod math;
pub mod measured;
pub mod microfacet;
pub mod models;
pub mod paint;
mod parallel;
pub mod params;
pub mod poly_fit;
pub mod presets;
pub mod quadrature;
pub mod real;
pub mod rng;
pub mod sampling;
pub mod special;
pub mod spectral;
pub mod table;

pub use bxdf::{BsdfSample, Bxdf, Claims, ModelInfo, SurfacePoint};
pub use error::Error;
pub use material::Material;
pub use math::{Rgb, Vec3};
pub use models::Model;
pub use real::Real;
