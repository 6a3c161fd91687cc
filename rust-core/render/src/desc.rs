//! Scene descriptions: the built-in default scene, JSON scene files and OBJ meshes.
//!
//! World space is right-handed with **y up** (OBJ's convention); lengths are arbitrary scene
//! units. A JSON scene file:
//!
//! ```json
//! {
//!   "camera": {"position": [0, 1.6, 5.5], "look_at": [0, 0.9, 0], "fov_deg": 30},
//!   "materials": {"paint": {"preset": "gold_flake_8"}, "floor": {"model": "lambert", "albedo": 0.3}},
//!   "objects": [
//!     {"type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "paint", "uv_scale": 0.5},
//!     {"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "size": [40, 40], "material": "floor"},
//!     {"type": "mesh", "file": "bunny.obj", "material": "paint", "fit_radius": 1}
//!   ],
//!   "lights": [
//!     {"type": "environment", "map": "studio", "scale": 1},
//!     {"type": "sphere", "center": [-4, 6, 5], "radius": 0.6, "radiance": 150}
//!   ]
//! }
//! ```
//!
//! Objects: `sphere` (center, radius), `plane` (center, normal, size `[w, h]`, optional
//! tangent), `rectangle` (corner, edge_u, edge_v), `mesh` (an OBJ `file`, inline
//! `positions` + `triangles` with optional `normals` and `uvs`, or `"mesh": NAME`, an entry of
//! the top-level `meshes` that any number of objects may instance; with an optional
//! `transform` `{scale, rotate_deg: [x, y, z], translate, matrix}` or `fit_radius`, which
//! centres the mesh above y = 0 and scales its bounding sphere to that radius). `matrix` is a
//! row-major 4×4 affine matrix applied after the other three (normals by its inverse
//! transpose). A `material` is the name of an entry in `materials`, a preset name, or inline
//! material JSON.
//!
//! Inline mesh arrays (`positions`, `triangles`, `normals`, `uvs`, in objects or in `meshes`)
//! are JSON arrays of `[x, y, z]` / `[i, j, k]` / `[u, v]`, or a string `"base64:..."` of
//! little-endian `f32` (`u32` for triangles) values: the compact form hosts such as Blender
//! write for large meshes.
//!
//! An entry of `meshes` may also perturb its shading normals ([`crate::perturb`]):
//! `"normal_map": {width, height, pixels, strength, uvs, tangents, bitangents}` (a tangent-space
//! normal map as Blender's Normal Map node reads it; `pixels` are `width × height` RGB texels,
//! row 0 at v = 0; uvs, tangents and bitangents one per vertex) and
//! `"orange_peel": {amplitude_um, wavelength_mm, metres_per_unit, coords}` (the clearcoat's
//! waviness: a height field of that RMS height and wavelength over the per-vertex metric
//! coordinates `coords`, in metres), `"bump": {width, height, pixels, strength, distance, uvs}`
//! (a height image as Blender's Bump node reads it: `pixels` are `width × height` heights,
//! `distance` world units per unit of height), `"texture_uvs"` (per-vertex coordinates of image
//! textures, a host's UV map; default `uvs`), and `"coat_normal": {follows_normal, normal_map,
//! bump, orange_peel}` (the clearcoat's own normal, [`crate::perturb::CoatNormal`]: the paint is
//! then shaded in two frames).
//!
//! A material given as JSON (named or inline) may carry `"textures"`: images on its
//! `base_color`, `flake_density` and `coat_roughness` (a `coated_paint` with the Lambert
//! pigment), each `{"file": "albedo.png"}` (PNG, EXR or HDR, relative to the scene; optional
//! `"colorspace": "srgb" | "linear"`, `"interpolation": "linear" | "closest"`, and `"scale"` for
//! the scalars) or `{"image": NAME}`, an entry of the scene's top-level
//! `"images": {NAME: {width, height, pixels}}` (linear RGB, row 0 at v = 0, inline or base64).
//! See [`crate::texture`] for the lookup, the units and the checks.
//!
//! Lights: `point` (position, intensity W/sr), `spot` (position, target, intensity,
//! cone_deg = half angle, blend_deg = soft edge), `sun` (direction toward the sun,
//! irradiance, angle_deg = angular diameter, 0 = sharp), `sphere` (center, radius, radiance),
//! `rectangle` (corner, edge_u, edge_v, radiance, two_sided; `"ellipse": true` keeps only the
//! ellipse inscribed in it: disk and ellipse lights), `environment` (`map`:
//! `"studio"`, an `.hdr`/`.exr` lat-long path, or absent for a constant `radiance`; `scale`,
//! `rotation_deg`). Sphere and rectangle lights are surfaces (the camera sees them, they cast
//! shadows) unless `"surface": false`, which makes them behave as lights do in Blender's
//! Cycles: camera rays and shadow rays pass through the emitter, and other rays that reach it
//! collect its emission (with MIS) and continue behind it. Colours are a number or `[r, g, b]`.

use crate::camera::Camera;
use crate::env::Environment;
use crate::geom::{v3, v3a, V3};
use crate::lights::Light;
use crate::perturb::{BumpMap, CoatNormal, NormalMap, OrangePeel, Perturbation};
use crate::scene::{Scene, SceneBuilder};
use crate::shapes::{Mesh, Quad, Sphere};
use crate::texture::{Image, ImageDesc, PaintTextures, TexturesDesc};
use lacquer::{Material, Rgb};
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A colour in JSON: a grey or `[r, g, b]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum ColorDesc {
    /// Grey.
    Grey(f64),
    /// RGB.
    Rgb([f64; 3]),
}

impl ColorDesc {
    fn rgb(self) -> Rgb<f32> {
        match self {
            ColorDesc::Grey(g) => Rgb::splat(g as f32),
            ColorDesc::Rgb(c) => Rgb::new(c[0] as f32, c[1] as f32, c[2] as f32),
        }
    }
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}

/// The camera.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position.
    pub position: [f64; 3],
    /// Point looked at.
    pub look_at: [f64; 3],
    /// Up direction.
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_deg: f64,
}

/// Mesh placement.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDesc {
    /// Uniform or per-axis scale.
    #[serde(default)]
    pub scale: Option<ColorDesc>,
    /// Rotations about x, then y, then z (degrees).
    #[serde(default)]
    pub rotate_deg: Option<[f64; 3]>,
    /// Translation (applied after scale and rotation).
    #[serde(default)]
    pub translate: Option<[f64; 3]>,
    /// Row-major 4×4 affine matrix (applied last; the bottom row must be `[0, 0, 0, 1]`).
    #[serde(default)]
    pub matrix: Option<[[f64; 4]; 4]>,
}

/// A list of fixed-size elements: JSON arrays, or a `"base64:..."` string of little-endian
/// 32-bit values (`f32`, or `u32` for indices).
#[derive(Clone, Debug, PartialEq)]
pub struct Packed<T, const N: usize>(pub Vec<[T; N]>);

/// A 32-bit value type that [`Packed`] can decode from little-endian bytes.
pub trait Le32: Copy + Default {
    /// From 4 little-endian bytes.
    fn from_le(b: [u8; 4]) -> Self;
}
impl Le32 for f32 {
    fn from_le(b: [u8; 4]) -> Self {
        f32::from_le_bytes(b)
    }
}
impl Le32 for u32 {
    fn from_le(b: [u8; 4]) -> Self {
        u32::from_le_bytes(b)
    }
}

/// Decodes standard base64 (with or without `=` padding; whitespace is not allowed).
pub fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    fn val(c: u8) -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    }
    let bytes = text.trim_end_matches('=').as_bytes();
    if bytes.len() % 4 == 1 {
        return Err("base64: truncated".into());
    }
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let mut acc = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            let v = val(c).ok_or_else(|| format!("base64: invalid character {:?}", c as char))?;
            acc |= v << (18 - 6 * k);
        }
        let n = chunk.len() * 6 / 8;
        out.extend_from_slice(&acc.to_be_bytes()[1..1 + n]);
    }
    Ok(out)
}

impl<'de, T, const N: usize> Deserialize<'de> for Packed<T, N>
where
    T: Le32,
    [T; N]: serde::de::DeserializeOwned,
{
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged, bound = "[T; N]: serde::de::DeserializeOwned")]
        enum Repr<T, const N: usize> {
            Inline(Vec<[T; N]>),
            Text(String),
        }
        use serde::de::Error;
        let text = match Repr::<T, N>::deserialize(d) {
            Ok(Repr::Inline(v)) => return Ok(Packed(v)),
            Ok(Repr::Text(t)) => t,
            Err(_) => {
                return Err(D::Error::custom(format!(
                    "expected an array of {N}-element arrays or a \"base64:...\" string"
                )))
            }
        };
        let body =
            text.strip_prefix("base64:").ok_or_else(|| D::Error::custom("packed arrays start with \"base64:\""))?;
        let bytes = decode_base64(body).map_err(D::Error::custom)?;
        if bytes.len() % (4 * N) != 0 {
            return Err(D::Error::custom(format!(
                "base64 array: {} bytes is not a multiple of {}",
                bytes.len(),
                4 * N
            )));
        }
        let v = bytes
            .chunks_exact(4 * N)
            .map(|el| {
                let mut a = [T::default(); N];
                for (k, x) in a.iter_mut().enumerate() {
                    *x = T::from_le([el[4 * k], el[4 * k + 1], el[4 * k + 2], el[4 * k + 3]]);
                }
                a
            })
            .collect();
        Ok(Packed(v))
    }
}

/// Mesh data shared by instances (`"meshes": {NAME: {...}}`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Packed<f32, 3>,
    /// Triangles as vertex indices.
    pub triangles: Packed<u32, 3>,
    /// Vertex normals (optional).
    #[serde(default)]
    pub normals: Option<Packed<f32, 3>>,
    /// Vertex texture coordinates (optional).
    #[serde(default)]
    pub uvs: Option<Packed<f32, 2>>,
    /// A tangent-space normal map perturbing the shading normal (optional).
    #[serde(default)]
    pub normal_map: Option<NormalMapDesc>,
    /// Orange peel of a clearcoat perturbing the shading normal (optional).
    #[serde(default)]
    pub orange_peel: Option<OrangePeelDesc>,
    /// Vertex coordinates of image textures (a UV map; optional, default `uvs`).
    #[serde(default)]
    pub texture_uvs: Option<Packed<f32, 2>>,
    /// A bump map perturbing the shading normal (optional).
    #[serde(default)]
    pub bump: Option<BumpDesc>,
    /// The clearcoat's own normal (optional): the paint is then shaded in two frames.
    #[serde(default)]
    pub coat_normal: Option<CoatNormalDesc>,
}

/// A mesh's clearcoat normal (`meshes.NAME.coat_normal`; [`crate::perturb::CoatNormal`]): its
/// own normal map, bump and orange peel (the same fields as the mesh's), applied to the mesh's
/// interpolated normal, or to its perturbed normal with `follows_normal`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoatNormalDesc {
    /// Start from the mesh's perturbed normal (Blender: Coat Normal not connected, so the coat
    /// follows Normal) instead of the interpolated one (default false: Coat Normal connected).
    #[serde(default)]
    pub follows_normal: bool,
    /// The coat's tangent-space normal map.
    #[serde(default)]
    pub normal_map: Option<NormalMapDesc>,
    /// Orange peel on the coat.
    #[serde(default)]
    pub orange_peel: Option<OrangePeelDesc>,
    /// The coat's bump map.
    #[serde(default)]
    pub bump: Option<BumpDesc>,
}

/// A mesh's bump map (`meshes.NAME.bump`; [`crate::perturb::BumpMap`]): a height image, the
/// Bump node's strength and distance, and per-vertex texture coordinates.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BumpDesc {
    /// Image width in texels.
    pub width: usize,
    /// Image height in texels.
    pub height: usize,
    /// `width × height` heights, row 0 (v = 0) first.
    pub pixels: Packed<f32, 1>,
    /// Strength (default 1).
    #[serde(default = "one")]
    pub strength: f64,
    /// Distance: world units per unit of height (default 1; negative inverts).
    #[serde(default = "one")]
    pub distance: f64,
    /// Texture coordinates per vertex.
    pub uvs: Packed<f32, 2>,
}

/// A mesh's tangent-space normal map (`meshes.NAME.normal_map`; [`crate::perturb`]): the image
/// and, per vertex, its texture coordinates, tangent and bitangent (object space, as the
/// mesh's normals).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormalMapDesc {
    /// Image width in texels.
    pub width: usize,
    /// Image height in texels.
    pub height: usize,
    /// `width × height` RGB texels, row 0 (v = 0) first, non-colour values in [0, 1].
    pub pixels: Packed<f32, 3>,
    /// Strength (Blender's Normal Map node; default 1).
    #[serde(default = "one")]
    pub strength: f64,
    /// Texture coordinates per vertex.
    pub uvs: Packed<f32, 2>,
    /// Tangent per vertex.
    pub tangents: Packed<f32, 3>,
    /// Bitangent per vertex (sign × N × T).
    pub bitangents: Packed<f32, 3>,
}

/// A mesh's orange peel (`meshes.NAME.orange_peel`; [`crate::perturb::OrangePeel`]).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrangePeelDesc {
    /// RMS height of the coat's waviness in µm (0 = off).
    pub amplitude_um: f64,
    /// Wavelength in mm.
    pub wavelength_mm: f64,
    /// Metres per world unit.
    #[serde(default = "one")]
    pub metres_per_unit: f64,
    /// Metric coordinates per vertex (metres on the object: object coordinates × the object's
    /// scale in metres), where the waves are evaluated.
    pub coords: Packed<f32, 3>,
}

/// The perturbations of a mesh with `n` vertices from their descriptions, checked.
pub fn perturbation(
    n: usize,
    normal_map: Option<&NormalMapDesc>,
    orange_peel: Option<&OrangePeelDesc>,
    bump: Option<&BumpDesc>,
) -> Result<Option<Box<Perturbation>>, String> {
    let mut out = Perturbation::default();
    if let Some(m) = normal_map {
        if m.width == 0 || m.height == 0 || m.width.checked_mul(m.height) != Some(m.pixels.0.len()) {
            return Err(format!("normal_map: {} pixels for {}×{} texels", m.pixels.0.len(), m.width, m.height));
        }
        if m.uvs.0.len() != n || m.tangents.0.len() != n || m.bitangents.0.len() != n {
            return Err(format!("normal_map: uvs, tangents and bitangents need one entry per position ({n})"));
        }
        let finite = m.pixels.0.iter().flatten().chain(m.uvs.0.iter().flatten()).all(|v| v.is_finite())
            && m.tangents.0.iter().chain(m.bitangents.0.iter()).flatten().all(|v| v.is_finite());
        let strength_ok = m.strength.is_finite() && m.strength >= 0.0;
        if !finite || !strength_ok {
            return Err("normal_map: values must be finite and the strength >= 0".into());
        }
        let vecs = |v: &[[f32; 3]]| v.iter().map(|t| v3(t[0], t[1], t[2])).collect::<Vec<_>>();
        out.normal_map = Some((
            NormalMap {
                width: m.width,
                height: m.height,
                texels: m.pixels.0.clone().into(),
                strength: m.strength as f32,
            },
            m.uvs.0.clone(),
            vecs(&m.tangents.0),
            vecs(&m.bitangents.0),
        ));
    }
    if let Some(p) = orange_peel {
        let amplitude_ok = p.amplitude_um.is_finite() && p.amplitude_um >= 0.0;
        if !amplitude_ok {
            return Err("orange_peel: amplitude_um must be >= 0".into());
        }
        let lengths_ok = p.wavelength_mm.is_finite()
            && p.wavelength_mm > 0.0
            && p.metres_per_unit.is_finite()
            && p.metres_per_unit > 0.0;
        if !lengths_ok {
            return Err("orange_peel: wavelength_mm and metres_per_unit must be > 0".into());
        }
        if p.coords.0.len() != n || p.coords.0.iter().flatten().any(|v| !v.is_finite()) {
            return Err(format!("orange_peel: coords need one finite entry per position ({n})"));
        }
        if p.amplitude_um > 0.0 {
            let peel = OrangePeel {
                amplitude_m: p.amplitude_um * 1e-6,
                wavelength_m: p.wavelength_mm * 1e-3,
                metres_per_unit: p.metres_per_unit,
            };
            out.orange_peel = Some((peel, p.coords.0.iter().map(|c| c.map(f64::from)).collect()));
        }
    }
    if let Some(m) = bump {
        if m.width == 0 || m.height == 0 || m.width.checked_mul(m.height) != Some(m.pixels.0.len()) {
            return Err(format!("bump: {} pixels for {}×{} texels", m.pixels.0.len(), m.width, m.height));
        }
        if m.uvs.0.len() != n {
            return Err(format!("bump: uvs need one entry per position ({n})"));
        }
        let finite = m.pixels.0.iter().flatten().chain(m.uvs.0.iter().flatten()).all(|v| v.is_finite());
        let ok = finite && m.strength.is_finite() && m.strength >= 0.0 && m.distance.is_finite();
        if !ok {
            return Err("bump: values must be finite and the strength >= 0".into());
        }
        let map = BumpMap {
            width: m.width,
            height: m.height,
            texels: m.pixels.0.iter().map(|t| t[0]).collect(),
            strength: m.strength as f32,
            distance: m.distance as f32,
        };
        out.bump = Some((map, m.uvs.0.clone()));
    }
    Ok((out.normal_map.is_some() || out.orange_peel.is_some() || out.bump.is_some()).then(|| Box::new(out)))
}

/// A scene object.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObjectDesc {
    /// A sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
        /// Material name, preset name or inline JSON.
        material: Value,
        /// uv units per unit of arc length.
        #[serde(default = "one")]
        uv_scale: f64,
    },
    /// A finite plane (rectangle) by centre, normal and size.
    Plane {
        /// Centre.
        center: [f64; 3],
        /// Normal.
        normal: [f64; 3],
        /// Width and height.
        size: [f64; 2],
        /// Direction of the width (and of the anisotropy axis).
        #[serde(default)]
        tangent: Option<[f64; 3]>,
        /// Material.
        material: Value,
        /// uv units per unit of length.
        #[serde(default = "one")]
        uv_scale: f64,
    },
    /// A parallelogram by corner and edges (front side `edge_u × edge_v`).
    Rectangle {
        /// Corner.
        corner: [f64; 3],
        /// First edge.
        edge_u: [f64; 3],
        /// Second edge.
        edge_v: [f64; 3],
        /// Material.
        material: Value,
        /// uv units per unit of length.
        #[serde(default = "one")]
        uv_scale: f64,
    },
    /// A triangle mesh: a Wavefront OBJ file, or inline arrays (hosts such as Blender).
    Mesh {
        /// OBJ path (relative to the scene file).
        #[serde(default)]
        file: Option<PathBuf>,
        /// An entry of the scene's `meshes` (instead of `file` or inline arrays).
        #[serde(default)]
        mesh: Option<String>,
        /// Inline vertex positions (instead of `file`).
        #[serde(default)]
        positions: Option<Packed<f32, 3>>,
        /// Inline triangles as vertex indices.
        #[serde(default)]
        triangles: Option<Packed<u32, 3>>,
        /// Inline vertex normals (optional).
        #[serde(default)]
        normals: Option<Packed<f32, 3>>,
        /// Inline vertex texture coordinates (optional).
        #[serde(default)]
        uvs: Option<Packed<f32, 2>>,
        /// Material.
        material: Value,
        /// Placement (boxed: a matrix makes it large).
        #[serde(default)]
        transform: Option<Box<TransformDesc>>,
        /// Centre above y = 0 and scale to this bounding radius (applied before `transform`).
        #[serde(default)]
        fit_radius: Option<f64>,
    },
}

/// A light.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightDesc {
    /// Point light.
    Point {
        /// Position.
        position: [f64; 3],
        /// Intensity (W/sr).
        intensity: ColorDesc,
    },
    /// Spot light.
    Spot {
        /// Position.
        position: [f64; 3],
        /// Point on the axis.
        target: [f64; 3],
        /// Intensity on the axis (W/sr).
        intensity: ColorDesc,
        /// Half angle of the cone (degrees).
        cone_deg: f64,
        /// Width of the soft edge inside the cone (degrees).
        #[serde(default)]
        blend_deg: f64,
    },
    /// Sun (distant light).
    Sun {
        /// Direction toward the sun.
        direction: [f64; 3],
        /// Irradiance on a surface facing the sun.
        irradiance: ColorDesc,
        /// Angular diameter (degrees); 0 = sharp shadows.
        #[serde(default)]
        angle_deg: f64,
    },
    /// Spherical area light.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
        /// Radiance.
        radiance: ColorDesc,
        /// The emitter is a surface (seen by the camera, casting shadows); false: as Cycles'
        /// lights, camera and shadow rays pass through it.
        #[serde(default = "yes")]
        surface: bool,
    },
    /// Rectangular area light.
    Rectangle {
        /// Corner.
        corner: [f64; 3],
        /// First edge.
        edge_u: [f64; 3],
        /// Second edge.
        edge_v: [f64; 3],
        /// Radiance.
        radiance: ColorDesc,
        /// Emit from both sides.
        #[serde(default)]
        two_sided: bool,
        /// Only the ellipse inscribed in the parallelogram emits (disk and ellipse lights).
        #[serde(default)]
        ellipse: bool,
        /// The emitter is a surface (seen by the camera, casting shadows); false: as Cycles'
        /// lights, camera and shadow rays pass through it.
        #[serde(default = "yes")]
        surface: bool,
    },
    /// Environment at infinity.
    Environment {
        /// `"studio"` or a lat-long `.hdr`/`.exr` path; absent: constant `radiance`.
        #[serde(default)]
        map: Option<String>,
        /// Constant radiance (when no map).
        #[serde(default)]
        radiance: Option<ColorDesc>,
        /// Multiplier.
        #[serde(default = "one")]
        scale: f64,
        /// Rotation about the up axis (degrees).
        #[serde(default)]
        rotation_deg: f64,
    },
}

/// A whole scene file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Camera.
    pub camera: CameraDesc,
    /// Named materials.
    #[serde(default)]
    pub materials: BTreeMap<String, Value>,
    /// Named meshes that `mesh` objects instance by name.
    #[serde(default)]
    pub meshes: BTreeMap<String, MeshData>,
    /// Named inline images that materials' `textures` bind by name ([`crate::texture`]).
    #[serde(default)]
    pub images: BTreeMap<String, ImageDesc>,
    /// Objects.
    pub objects: Vec<ObjectDesc>,
    /// Lights.
    #[serde(default)]
    pub lights: Vec<LightDesc>,
}

/// Loads an OBJ file (all its objects merged into one mesh; quads and polygons triangulated).
pub fn load_obj(path: &Path) -> Result<Mesh, String> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _) = tobj::load_obj(path, &opts).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut mesh = Mesh::default();
    let all_normals = models.iter().all(|m| !m.mesh.normals.is_empty());
    let all_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
    for m in &models {
        let base = mesh.positions.len() as u32;
        let g = &m.mesh;
        mesh.positions.extend(g.positions.chunks_exact(3).map(|p| v3(p[0], p[1], p[2])));
        if all_normals {
            mesh.normals.extend(g.normals.chunks_exact(3).map(|n| v3(n[0], n[1], n[2])));
        }
        if all_uvs {
            mesh.uvs.extend(g.texcoords.chunks_exact(2).map(|t| [t[0], t[1]]));
        }
        mesh.triangles.extend(g.indices.chunks_exact(3).map(|t| [base + t[0], base + t[1], base + t[2]]));
    }
    if mesh.triangles.is_empty() {
        return Err(format!("{}: no triangles", path.display()));
    }
    let n = mesh.positions.len() as u32;
    if mesh.triangles.iter().flatten().any(|&i| i >= n) {
        return Err(format!("{}: vertex index out of range", path.display()));
    }
    Ok(mesh)
}

/// Builds a mesh from inline arrays, checking indices and array lengths.
pub fn inline_mesh(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
    uvs: Option<&[[f32; 2]]>,
) -> Result<Mesh, String> {
    let n = positions.len();
    if triangles.is_empty() {
        return Err("no triangles".into());
    }
    if triangles.iter().flatten().any(|&i| i as usize >= n) {
        return Err(format!("vertex index out of range (there are {n} positions)"));
    }
    if normals.is_some_and(|v| v.len() != n) || uvs.is_some_and(|v| v.len() != n) {
        return Err(format!("normals and uvs need one entry per position ({n})"));
    }
    if positions.iter().flatten().any(|v| !v.is_finite()) {
        return Err("positions must be finite".into());
    }
    Ok(Mesh {
        positions: positions.iter().map(|p| v3(p[0], p[1], p[2])).collect(),
        normals: normals.map_or(Vec::new(), |v| v.iter().map(|p| v3(p[0], p[1], p[2])).collect()),
        uvs: uvs.map_or(Vec::new(), <[_]>::to_vec),
        triangles: triangles.to_vec(),
        perturb: None,
        coat: None,
        texture_uvs: Vec::new(),
    })
}

/// Centres a mesh on the y axis, rests it on y = 0 and scales its bounding sphere to `radius`.
pub fn fit_mesh(mesh: &mut Mesh, radius: f32) {
    let b = mesh.bounds();
    if b.is_empty() {
        return;
    }
    let c = b.center();
    let half = 0.5 * (b.max - b.min).length();
    let s = if half > 0.0 { radius / half } else { 1.0 };
    for p in &mut mesh.positions {
        *p = v3((p.x - c.x) * s, (p.y - b.min.y) * s, (p.z - c.z) * s);
    }
}

/// Applies scale, rotation (x, y, z order) and translation.
pub fn transform_mesh(mesh: &mut Mesh, t: &TransformDesc) {
    let s = match t.scale {
        None => v3(1.0, 1.0, 1.0),
        Some(ColorDesc::Grey(g)) => v3(g as f32, g as f32, g as f32),
        Some(ColorDesc::Rgb(c)) => v3a(c),
    };
    let r = t.rotate_deg.unwrap_or([0.0; 3]).map(|a| (a as f32).to_radians());
    let rot = |p: V3| -> V3 {
        let (sx, cx) = r[0].sin_cos();
        let p = v3(p.x, cx * p.y - sx * p.z, sx * p.y + cx * p.z);
        let (sy, cy) = r[1].sin_cos();
        let p = v3(cy * p.x + sy * p.z, p.y, -sy * p.x + cy * p.z);
        let (sz, cz) = r[2].sin_cos();
        v3(cz * p.x - sz * p.y, sz * p.x + cz * p.y, p.z)
    };
    let tr = v3a(t.translate.unwrap_or([0.0; 3]));
    for p in &mut mesh.positions {
        *p = rot(v3(p.x * s.x, p.y * s.y, p.z * s.z)) + tr;
    }
    for_each_normal(mesh, |n| rot(v3(n.x / s.x, n.y / s.y, n.z / s.z)).normalize());
    if let Some(m) = &t.matrix {
        apply_matrix(mesh, m);
    }
}

/// Checks that a row-major 4×4 matrix is an invertible affine transform.
pub fn check_matrix(m: &[[f64; 4]; 4]) -> Result<(), String> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err("matrix must be finite".into());
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err("matrix must be affine (bottom row [0, 0, 0, 1])".into());
    }
    if !(det3(m).abs() > 1e-30) {
        return Err("matrix must be invertible".into());
    }
    Ok(())
}

fn det3(m: &[[f64; 4]; 4]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Transforms positions by a row-major affine matrix and normals by its inverse transpose.
pub fn apply_matrix(mesh: &mut Mesh, m: &[[f64; 4]; 4]) {
    for p in &mut mesh.positions {
        let q = [p.x as f64, p.y as f64, p.z as f64];
        let r = |i: usize| m[i][0] * q[0] + m[i][1] * q[1] + m[i][2] * q[2] + m[i][3];
        *p = v3(r(0) as f32, r(1) as f32, r(2) as f32);
    }
    // Inverse transpose of the 3×3 part = cofactor matrix / det (the 1/det only scales).
    let c = |i: usize, j: usize| {
        let (i1, i2, j1, j2) = ((i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    let cof = [[c(0, 0), c(0, 1), c(0, 2)], [c(1, 0), c(1, 1), c(1, 2)], [c(2, 0), c(2, 1), c(2, 2)]];
    let sign = det3(m).signum();
    for_each_normal(mesh, |n| {
        let q = [n.x as f64, n.y as f64, n.z as f64];
        let r = |i: usize| sign * (cof[i][0] * q[0] + cof[i][1] * q[1] + cof[i][2] * q[2]);
        v3(r(0) as f32, r(1) as f32, r(2) as f32).normalize()
    });
}

/// Applies a normal transform to the vertex normals and to a normal map's tangents and
/// bitangents: Cycles combines them in object space and transforms the result as a normal,
/// which this reproduces for rotations and uniform scales.
fn for_each_normal(mesh: &mut Mesh, f: impl Fn(V3) -> V3) {
    for n in &mut mesh.normals {
        *n = f(*n);
    }
    let coat_map = mesh.coat.as_mut().and_then(|c| c.perturb.normal_map.as_mut());
    for (_, _, t, b) in mesh.perturb.as_mut().and_then(|p| p.normal_map.as_mut()).into_iter().chain(coat_map) {
        for v in t.iter_mut().chain(b.iter_mut()) {
            *v = f(*v);
        }
    }
}

/// A resolved material reference: the material and its textured parameters.
type Resolved = (Material, Option<Arc<PaintTextures>>);

/// What textures resolve against: the scene's folder, its inline images, the files read so far.
struct TexContext<'a> {
    base: &'a Path,
    images: BTreeMap<String, Arc<Image>>,
    files: BTreeMap<(String, bool), Arc<Image>>,
}

/// Resolves a material reference: a name in `named`, a preset name, or inline JSON (which
/// may carry `"textures"`, [`crate::texture`]).
fn resolve_material(v: &Value, named: &BTreeMap<String, Resolved>, tex: &mut TexContext) -> Result<Resolved, String> {
    match v {
        Value::String(s) => {
            if let Some(m) = named.get(s) {
                return Ok(m.clone());
            }
            let m = Material::preset(s).map_err(|e| format!("material \"{s}\": not in \"materials\" and {e}"))?;
            Ok((m, None))
        }
        Value::Object(o) => {
            let Some(t) = o.get("textures") else {
                return Ok((Material::from_value(v).map_err(|e| e.to_string())?, None));
            };
            let mut plain = o.clone();
            plain.remove("textures");
            let m = Material::from_value(&Value::Object(plain)).map_err(|e| e.to_string())?;
            let desc: TexturesDesc = serde_json::from_value(t.clone()).map_err(|e| format!("textures: {e}"))?;
            let t = PaintTextures::build(&desc, &m, tex.base, &tex.images, &mut tex.files)?;
            Ok((m, Some(Arc::new(t))))
        }
        _ => Err("a material is a name, a preset name or a JSON object".into()),
    }
}

impl SceneDesc {
    /// Parses a scene file.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Builds the scene for a `width × height` image. Relative paths resolve against `base`.
    /// `override_material`, if given, replaces the material named `"paint"`.
    pub fn build(
        &self,
        base: &Path,
        width: u32,
        height: u32,
        override_material: Option<&Material>,
    ) -> Result<Scene, String> {
        let mut tex = TexContext { base, images: BTreeMap::new(), files: BTreeMap::new() };
        for (k, d) in &self.images {
            tex.images.insert(k.clone(), Arc::new(d.image(k).map_err(|e| format!("images.{k}: {e}"))?));
        }
        let mut named = BTreeMap::new();
        for (k, v) in &self.materials {
            let r = resolve_material(v, &named, &mut tex).map_err(|e| format!("materials.{k}: {e}"))?;
            named.insert(k.clone(), r);
        }
        if let Some(m) = override_material {
            named.insert("paint".to_string(), (m.clone(), None));
        }
        let mut shared = BTreeMap::new();
        for (k, m) in &self.meshes {
            let mut mesh = inline_mesh(
                &m.positions.0,
                &m.triangles.0,
                m.normals.as_ref().map(|v| &v.0[..]),
                m.uvs.as_ref().map(|v| &v.0[..]),
            )
            .map_err(|e| format!("meshes.{k}: {e}"))?;
            mesh.perturb =
                perturbation(mesh.positions.len(), m.normal_map.as_ref(), m.orange_peel.as_ref(), m.bump.as_ref())
                    .map_err(|e| format!("meshes.{k}: {e}"))?;
            if let Some(c) = &m.coat_normal {
                let n = mesh.positions.len();
                let p = perturbation(n, c.normal_map.as_ref(), c.orange_peel.as_ref(), c.bump.as_ref())
                    .map_err(|e| format!("meshes.{k}.coat_normal: {e}"))?;
                // Nothing to perturb and following the mesh's normal: the coat is the base's.
                if p.is_some() || !c.follows_normal {
                    mesh.coat = Some(Box::new(CoatNormal {
                        perturb: p.map(|b| *b).unwrap_or_default(),
                        follows_normal: c.follows_normal,
                    }));
                }
            }
            if let Some(t) = &m.texture_uvs {
                if t.0.len() != mesh.positions.len() || t.0.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(format!(
                        "meshes.{k}: texture_uvs need one finite entry per position ({})",
                        mesh.positions.len()
                    ));
                }
                mesh.texture_uvs = t.0.clone();
            }
            shared.insert(k.clone(), mesh);
        }
        let mut b = SceneBuilder::new();
        let mut cache: Vec<(String, u32)> = Vec::new();
        let mut mat = |b: &mut SceneBuilder, v: &Value| -> Result<u32, String> {
            let key = v.to_string();
            if let Some((_, i)) = cache.iter().find(|(k, _)| *k == key) {
                return Ok(*i);
            }
            let (m, t) = resolve_material(v, &named, &mut tex)?;
            let i = b.textured_material(m, t);
            cache.push((key, i));
            Ok(i)
        };
        for (k, o) in self.objects.iter().enumerate() {
            let ctx = |e: String| format!("objects[{k}]: {e}");
            match o {
                ObjectDesc::Sphere { center, radius, material, uv_scale } => {
                    if !(*radius > 0.0) {
                        return Err(ctx("radius must be > 0".into()));
                    }
                    let m = mat(&mut b, material).map_err(ctx)?;
                    b.sphere(Sphere { center: v3a(*center), radius: *radius as f32, uv_scale: *uv_scale as f32 }, m);
                }
                ObjectDesc::Plane { center, normal, size, tangent, material, uv_scale } => {
                    let m = mat(&mut b, material).map_err(ctx)?;
                    let n = v3a(*normal);
                    let t = tangent.map(v3a).unwrap_or_else(|| lacquer::frame::basis_around(n.normalize()).0);
                    b.quad(Quad::centered(v3a(*center), n, t, size[0] as f32, size[1] as f32, *uv_scale as f32), m);
                }
                ObjectDesc::Rectangle { corner, edge_u, edge_v, material, uv_scale } => {
                    let m = mat(&mut b, material).map_err(ctx)?;
                    b.quad(
                        Quad {
                            corner: v3a(*corner),
                            edge_u: v3a(*edge_u),
                            edge_v: v3a(*edge_v),
                            uv_scale: *uv_scale as f32,
                        },
                        m,
                    );
                }
                ObjectDesc::Mesh {
                    file,
                    mesh,
                    positions,
                    triangles,
                    normals,
                    uvs,
                    material,
                    transform,
                    fit_radius,
                } => {
                    let m = mat(&mut b, material).map_err(ctx)?;
                    let mut mesh = match (file, mesh, positions, triangles) {
                        (Some(f), None, None, None) => load_obj(&base.join(f)).map_err(ctx)?,
                        (None, Some(name), None, None) => shared
                            .get(name)
                            .cloned()
                            .ok_or_else(|| ctx(format!("mesh \"{name}\" is not in \"meshes\"")))?,
                        (None, None, Some(p), Some(t)) => {
                            inline_mesh(&p.0, &t.0, normals.as_ref().map(|v| &v.0[..]), uvs.as_ref().map(|v| &v.0[..]))
                                .map_err(ctx)?
                        }
                        _ => {
                            return Err(ctx(
                                "a mesh needs exactly one of \"file\", \"mesh\" or \"positions\" + \"triangles\""
                                    .into(),
                            ))
                        }
                    };
                    if let Some(r) = fit_radius {
                        fit_mesh(&mut mesh, *r as f32);
                    }
                    if let Some(t) = transform {
                        if let Some(mx) = &t.matrix {
                            check_matrix(mx).map_err(|e| ctx(format!("transform: {e}")))?;
                        }
                        transform_mesh(&mut mesh, t);
                    }
                    b.mesh(mesh, m);
                }
            }
        }
        for (k, l) in self.lights.iter().enumerate() {
            let ctx = |e: String| format!("lights[{k}]: {e}");
            let surface = match l {
                LightDesc::Sphere { surface, .. } | LightDesc::Rectangle { surface, .. } => *surface,
                _ => true,
            };
            let light = match l {
                LightDesc::Point { position, intensity } => {
                    Light::Point { position: v3a(*position), intensity: intensity.rgb() }
                }
                LightDesc::Spot { position, target, intensity, cone_deg, blend_deg } => {
                    let outer = cone_deg.clamp(0.01, 179.0).to_radians();
                    let inner = (cone_deg - blend_deg).clamp(0.0, *cone_deg).to_radians();
                    Light::Spot {
                        position: v3a(*position),
                        direction: (v3a(*target) - v3a(*position)).normalize(),
                        intensity: intensity.rgb(),
                        cos_inner: (inner as f32).cos(),
                        cos_outer: (outer as f32).cos(),
                    }
                }
                LightDesc::Sun { direction, irradiance, angle_deg } => {
                    Light::sun(v3a(*direction), irradiance.rgb(), *angle_deg as f32)
                }
                LightDesc::Sphere { center, radius, radiance, .. } => Light::Sphere {
                    sphere: Sphere { center: v3a(*center), radius: *radius as f32, uv_scale: 1.0 },
                    radiance: radiance.rgb(),
                },
                LightDesc::Rectangle { corner, edge_u, edge_v, radiance, two_sided, ellipse, .. } => Light::Rect {
                    quad: Quad { corner: v3a(*corner), edge_u: v3a(*edge_u), edge_v: v3a(*edge_v), uv_scale: 1.0 },
                    radiance: radiance.rgb(),
                    two_sided: *two_sided,
                    ellipse: *ellipse,
                },
                LightDesc::Environment { map, radiance, scale, rotation_deg } => {
                    let env = match map.as_deref() {
                        Some("studio") => Environment::studio(*scale as f32, *rotation_deg as f32),
                        Some(file) => {
                            Environment::load(&base.join(file), *scale as f32, *rotation_deg as f32).map_err(ctx)?
                        }
                        None => Environment::constant(radiance.unwrap_or(ColorDesc::Grey(1.0)).rgb() * *scale as f32),
                    };
                    Light::Env(env)
                }
            };
            if surface {
                b.light(light);
            } else {
                b.light_no_surface(light);
            }
        }
        let c = &self.camera;
        let camera = Camera::look_at(v3a(c.position), v3a(c.look_at), v3a(c.up), c.fov_deg as f32, width, height);
        Ok(b.build(camera))
    }
}

/// The environment of the built-in scene.
#[derive(Clone, Debug)]
pub enum EnvChoice {
    /// The procedural studio.
    Studio,
    /// A constant radiance.
    Uniform(f32),
    /// A lat-long file.
    File(PathBuf),
}

/// Options of the built-in scene.
#[derive(Clone, Debug)]
pub struct DefaultScene {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Replaces the sphere (fitted to radius 1, resting on the floor).
    pub mesh: Option<Mesh>,
    /// Environment.
    pub env: EnvChoice,
    /// Environment multiplier.
    pub env_scale: f32,
    /// Environment rotation (degrees).
    pub env_rotation_deg: f32,
    /// Add the key light.
    pub key_light: bool,
    /// Add the floor.
    pub floor: bool,
}

impl Default for DefaultScene {
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            mesh: None,
            env: EnvChoice::Studio,
            env_scale: 1.0,
            env_rotation_deg: 0.0,
            key_light: true,
            floor: true,
        }
    }
}

/// Radius of the default scene's sphere in millimetres: the thesis measured hemispherical
/// samples; a 100 mm ball. With the paint's default `surface_scale_mm` = 100 mm per uv unit,
/// the sphere's uv (arc length × uv_scale) is in physical units when uv_scale = r / 100 mm.
pub const DEFAULT_SPHERE_RADIUS_MM: f32 = 50.0;

impl DefaultScene {
    /// Builds the scene: the material on a unit sphere (or the mesh) standing on a grey floor,
    /// under the studio environment and a soft key light from the upper left.
    pub fn build(&self, material: Material) -> Result<Scene, String> {
        let mut b = SceneBuilder::new();
        let paint = b.material(material);
        match &self.mesh {
            Some(m) => {
                let mut m = m.clone();
                fit_mesh(&mut m, 1.0);
                b.mesh(m, paint);
            }
            None => {
                b.sphere(
                    Sphere { center: v3(0.0, 1.0, 0.0), radius: 1.0, uv_scale: DEFAULT_SPHERE_RADIUS_MM / 100.0 },
                    paint,
                );
            }
        }
        if self.floor {
            let floor =
                b.material(Material::from_json(r#"{"model": "lambert", "albedo": 0.18}"#).map_err(|e| e.to_string())?);
            b.quad(Quad::centered(v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(1.0, 0.0, 0.0), 40.0, 40.0, 1.0), floor);
        }
        let env = match &self.env {
            EnvChoice::Studio => Environment::studio(self.env_scale, self.env_rotation_deg),
            EnvChoice::Uniform(l) => Environment::constant(Rgb::splat(*l * self.env_scale)),
            EnvChoice::File(p) => Environment::load(p, self.env_scale, self.env_rotation_deg)?,
        };
        b.light(Light::Env(env));
        if self.key_light {
            b.light(Light::Sphere {
                sphere: Sphere { center: v3(-4.0, 6.0, 5.0), radius: 0.6, uv_scale: 1.0 },
                radiance: Rgb::new(200.0, 190.0, 175.0),
            });
        }
        let camera =
            Camera::look_at(v3(0.0, 1.6, 5.5), v3(0.0, 0.9, 0.0), v3(0.0, 1.0, 0.0), 30.0, self.width, self.height);
        Ok(b.build(camera))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::render_job;

    fn b64(bytes: &[u8]) -> String {
        const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut s = String::new();
        for c in bytes.chunks(3) {
            let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
            for k in 0..=c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            }
        }
        s
    }

    #[test]
    fn base64_decodes_with_and_without_padding() {
        assert_eq!(decode_base64("TWFu").unwrap(), b"Man");
        assert_eq!(decode_base64("TWE=").unwrap(), b"Ma");
        assert_eq!(decode_base64("TQ==").unwrap(), b"M");
        assert_eq!(decode_base64("TQ").unwrap(), b"M");
        assert_eq!(decode_base64("").unwrap(), b"");
        assert!(decode_base64("TW!u").unwrap_err().contains("invalid character"));
        assert!(decode_base64("TWFuT").unwrap_err().contains("truncated"));
        let all: Vec<u8> = (0..=255).collect();
        assert_eq!(decode_base64(&b64(&all)).unwrap(), all);
    }

    #[test]
    fn packed_arrays_inline_or_base64() {
        let vals: Vec<f32> = vec![1.0, -2.5, 3.25, 0.0, 1e-3, 7.0];
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let text = format!("\"base64:{}\"", b64(&bytes));
        let a: Packed<f32, 3> = serde_json::from_str(&text).unwrap();
        let b: Packed<f32, 3> = serde_json::from_str("[[1, -2.5, 3.25], [0, 0.001, 7]]").unwrap();
        assert_eq!(a, b);
        let idx: Packed<u32, 3> =
            serde_json::from_str(&format!("\"base64:{}\"", b64(&[0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]))).unwrap();
        assert_eq!(idx.0, vec![[0, 1, 2]]);
        for bad in ["\"AAAA\"", "\"base64:AAAA\"", "\"base64:A!AA\"", "[[1, 2]]", "3"] {
            assert!(serde_json::from_str::<Packed<f32, 3>>(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn matrix_transforms_positions_and_normals() {
        // Non-uniform scale, a mirror and a translation: normals stay perpendicular to the surface.
        let mut mesh = inline_mesh(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
            &[[0, 1, 2]],
            Some(&[[-0.5f32.sqrt(), 0.0, 0.5f32.sqrt()]; 3]),
            None,
        )
        .unwrap();
        let m = [[3.0, 0.0, 0.0, 1.0], [0.0, -1.0, 0.0, 2.0], [0.0, 0.0, 0.5, -1.0], [0.0, 0.0, 0.0, 1.0]];
        check_matrix(&m).unwrap();
        apply_matrix(&mut mesh, &m);
        assert_eq!(mesh.positions[1], v3(4.0, 2.0, -0.5));
        let e1 = mesh.positions[1] - mesh.positions[0];
        let e2 = mesh.positions[2] - mesh.positions[0];
        for n in &mesh.normals {
            assert!(n.dot(e1).abs() < 1e-6 && n.dot(e2).abs() < 1e-6 && (n.length() - 1.0).abs() < 1e-6, "{n:?}");
        }
        let singular = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        assert!(check_matrix(&singular).unwrap_err().contains("invertible"));
        let projective = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]];
        assert!(check_matrix(&projective).unwrap_err().contains("affine"));
    }

    /// A 1×1 rectangle light (radiance 5) at height 1 above a Lambert floor (albedo 0.5) and a
    /// sun from straight above (irradiance 1), seen from above through the light. As a surface,
    /// the light hides the floor (its back is black) and shadows the sun; with `"surface": false`
    /// the camera sees the floor below it, lit by both: `ρ L F + ρ E/π` with the view factor
    /// `F` of the square from the point below its centre (four corner rectangles, Howell C-11).
    #[test]
    fn normal_maps_and_orange_peel_perturb_the_shading_normal() {
        // A square of two triangles facing a sun straight above it (Lambert 0.5, camera above):
        // radiance = 0.5/π × E × (n'·l). A flat normal map keeps n' = n; a texel (0.75, 0.5, 0.9)
        // tilts it to normalize(0.5 T + 0.8 N), cos = 0.8/√0.89; a bad array length is an error.
        let job = |extra: &str| {
            format!(
                r#"{{"material": {{"model": "lambert", "albedo": 0.5}}, "width": 5, "height": 5, "spp": 4,
                "max_depth": 1, "aovs": false,
                "scene": {{"camera": {{"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_deg": 5}},
                  "meshes": {{"sq": {{"positions": [[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]],
                    "triangles": [[0, 2, 1], [0, 3, 2]], "normals": [[0, 1, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]]
                    {extra}}}}},
                  "objects": [{{"type": "mesh", "mesh": "sq", "material": "paint"}}],
                  "lights": [{{"type": "sun", "direction": [0, 1, 0], "irradiance": 1}}]}}}}"#
            )
        };
        let map = |texel: &str, n: usize| {
            format!(
                r#", "normal_map": {{"width": 1, "height": 1, "pixels": [{texel}],
                "uvs": [{uvs}], "tangents": [{t}], "bitangents": [{b}]}}"#,
                uvs = vec!["[0.5, 0.5]"; n].join(","),
                t = vec!["[1, 0, 0]"; n].join(","),
                b = vec!["[0, 0, 1]"; n].join(",")
            )
        };
        let centre = |fb: &crate::Framebuffer| fb.color[2 * 5 + 2][0] as f64;
        let lambert = 0.5 / std::f64::consts::PI;
        let plain = centre(&render_job(&job(""), &mut |_| true).unwrap());
        let flat = centre(&render_job(&job(&map("[0.5, 0.5, 1.0]", 4)), &mut |_| true).unwrap());
        let tilted = centre(&render_job(&job(&map("[0.75, 0.5, 0.9]", 4)), &mut |_| true).unwrap());
        // A sharp sun and a Lambert surface: exact up to f32 (measured within 1e-7).
        assert!((plain - lambert).abs() < 1e-5 * lambert, "{plain}");
        assert!((flat - plain).abs() < 1e-6, "{flat} vs {plain}");
        let want = lambert * 0.8 / 0.89f64.sqrt();
        assert!((tilted - want).abs() < 1e-5 * want, "{tilted} vs {want}");
        let err = render_job(&job(&map("[0.5, 0.5, 1.0]", 3)), &mut |_| true).unwrap_err();
        assert!(format!("{err:?}").contains("one entry per position"), "{err:?}");
        // Orange peel of 30 µm RMS at 0.5 mm on a 2 m square seen 5 × 5: every pixel's normal
        // tilts differently, so pixels differ (without it, all equal the Lambert value).
        let peel = r#", "orange_peel": {"amplitude_um": 30, "wavelength_mm": 0.5,
            "coords": [[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]]}"#;
        let fb = render_job(&job(peel), &mut |_| true).unwrap();
        let v: Vec<f64> = fb.color.iter().map(|c| c[0] as f64).collect();
        let spread = v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread > 1e-3 * lambert && v.iter().all(|x| *x <= lambert * 1.0001), "{v:?}");
        let bad =
            r#", "orange_peel": {"amplitude_um": 1, "wavelength_mm": 0, "coords": [[0,0,0],[0,0,0],[0,0,0],[0,0,0]]}"#;
        assert!(render_job(&job(bad), &mut |_| true).is_err());
        // A coat normal: the tilted map on `coat_normal` only. A Lambert surface has no
        // clearcoat, so it keeps the base frame (the plain value exactly); bad arrays there are
        // errors naming `coat_normal`. (Two-frame shading: `integrator::coat_tests`.)
        let coat = |m: &str| format!(r#", "coat_normal": {{"follows_normal": false {m}}}"#);
        let kept = centre(&render_job(&job(&coat(&map("[0.75, 0.5, 0.9]", 4))), &mut |_| true).unwrap());
        assert!(kept == plain, "{kept} vs {plain}");
        let err = render_job(&job(&coat(&map("[0.5, 0.5, 1.0]", 3))), &mut |_| true).unwrap_err();
        assert!(format!("{err:?}").contains("coat_normal: normal_map: uvs"), "{err:?}");
    }

    #[test]
    fn lights_that_are_not_surfaces() {
        let job = |surface: bool| {
            format!(
                r#"{{"material": {{"model": "lambert", "albedo": 0.5}}, "width": 9, "height": 9, "spp": 512,
                "max_depth": 1, "aovs": false,
                "scene": {{"camera": {{"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_deg": 2}},
                  "objects": [{{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "size": [20, 20],
                                "material": "paint"}}],
                  "lights": [{{"type": "rectangle", "corner": [-0.5, 1, -0.5], "edge_u": [1, 0, 0],
                               "edge_v": [0, 0, 1], "radiance": 5, "surface": {surface}}},
                             {{"type": "sun", "direction": [0, 1, 0], "irradiance": 1}}]}}}}"#
            )
        };
        let corner = |a: f64, b: f64| {
            let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
            (a / sa * (b / sa).atan() + b / sb * (a / sb).atan()) / (2.0 * std::f64::consts::PI)
        };
        let expected = 0.5 * 5.0 * 4.0 * corner(0.5, 0.5) + 0.5 / std::f64::consts::PI;
        let centre = |fb: &crate::Framebuffer| {
            let mut sum = 0.0;
            for y in 3..6 {
                for x in 3..6 {
                    sum += fb.color[y * 9 + x][0] as f64;
                }
            }
            (sum / 9.0, fb.alpha[4 * 9 + 4])
        };
        let (c, a) = centre(&render_job(&job(true), &mut |_| true).unwrap());
        assert!(c == 0.0 && a == 1.0, "a surface light hides the floor: {c} {a}");
        let (c, a) = centre(&render_job(&job(false), &mut |_| true).unwrap());
        assert!(a == 1.0 && (c - expected).abs() < 0.02 * expected, "{c} vs {expected}");
    }

    /// A disk light (the ellipse inscribed in a 1×1 square, radiance 5, height 1, not a surface)
    /// above a Lambert floor (albedo 0.5), seen from above through it: on the axis the floor's
    /// radiance is `ρ L R²/(R² + h²)` = 0.5 (the full square would give 0.599), and the camera
    /// sees the floor through the disk.
    #[test]
    fn disk_lights() {
        let job = r#"{"material": {"model": "lambert", "albedo": 0.5}, "width": 9, "height": 9, "spp": 512,
            "max_depth": 1, "aovs": false,
            "scene": {"camera": {"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_deg": 2},
              "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "size": [20, 20],
                           "material": "paint"}],
              "lights": [{"type": "rectangle", "corner": [-0.5, 1, -0.5], "edge_u": [1, 0, 0],
                          "edge_v": [0, 0, 1], "radiance": 5, "ellipse": true, "surface": false}]}}"#;
        let fb = render_job(job, &mut |_| true).unwrap();
        let mut sum = 0.0;
        for y in 3..6 {
            for x in 3..6 {
                sum += fb.color[y * 9 + x][0] as f64;
            }
        }
        let c = sum / 9.0;
        assert!((c - 0.5).abs() < 0.01, "{c} vs 0.5");
        // As a surface, the disk hides the floor only inside the ellipse: a ray through the
        // square's corner region reaches the floor.
        let mut mesh_scene = job.replace("\"surface\": false", "\"surface\": true");
        mesh_scene = mesh_scene.replace("\"fov_deg\": 2", "\"fov_deg\": 22");
        let fb = render_job(&mesh_scene, &mut |_| true).unwrap();
        // 9 px span 2·3·tan(11°) = 1.17 units at the floor (0.78 at the light): the centre pixel
        // looks at the disk's back (black), the corner pixel past the disk's rim.
        assert_eq!(fb.color[4 * 9 + 4][0], 0.0);
        assert!(fb.color[0][0] > 0.05, "corner {}", fb.color[0][0]);
    }

    /// Two instances of one named mesh (a unit quad in z = 0), placed by matrices left and right of
    /// the centre, in the white furnace: the instances are white (1), the gap between them is
    /// the environment, or black with a transparent film.
    #[test]
    fn instanced_meshes_with_matrices_and_transparent_film() {
        let quad_pos: Vec<u8> = [[-0.5f32, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]]
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let scene = |transparent: bool| {
            format!(
                r#"{{"material": {{"model": "lambert", "albedo": 1}}, "width": 24, "height": 8, "spp": 16,
                "aovs": false, "transparent": {transparent},
                "scene": {{"camera": {{"position": [0, 0, 10], "look_at": [0, 0, 0], "fov_deg": 7.628}},
                  "meshes": {{"quad": {{"positions": "base64:{}", "triangles": [[0, 1, 2], [0, 2, 3]]}}}},
                  "objects": [
                    {{"type": "mesh", "mesh": "quad", "material": "paint",
                      "transform": {{"matrix": [[1, 0, 0, -1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}}},
                    {{"type": "mesh", "mesh": "quad", "material": "paint",
                      "transform": {{"scale": 0.5, "matrix": [[2, 0, 0, 1], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}}}}],
                  "lights": [{{"type": "environment", "radiance": 0.5}}]}}}}"#,
                b64(&quad_pos)
            )
        };
        for transparent in [false, true] {
            let fb = render_job(&scene(transparent), &mut |_| true).unwrap();
            // 24 px span 4 units at the quads' depth: x in [-1.5, -0.5] is pixels 3..9, the
            // centre gap pixels 9..15, the right quad pixels 15..21.
            let at = |x: usize| (fb.color[4 * 24 + x][0], fb.alpha[4 * 24 + x]);
            for x in [5, 6, 17, 18] {
                let (c, a) = at(x);
                assert!(a == 1.0 && (c - 0.5).abs() < 0.05, "x {x}: {c} {a}");
            }
            let (c, a) = at(12);
            assert_eq!(a, 0.0);
            assert!(if transparent { c == 0.0 } else { (c - 0.5).abs() < 1e-6 }, "gap {c}");
        }
        let bad = r#"{"scene": {"camera": {"position": [0, 0, 1], "look_at": [0, 0, 0], "fov_deg": 30},
            "objects": [{"type": "mesh", "mesh": "nope", "material": "white_lambert"}]}}"#;
        let e = render_job(bad, &mut |_| true).unwrap_err().to_string();
        assert!(e.contains("\"nope\" is not in \"meshes\""), "{e}");
    }
}
