//! Per-hit shading-normal perturbations of meshes: a tangent-space normal map (an image, as
//! Blender's Normal Map node reads it) and orange peel (the clearcoat's waviness, a procedural
//! height field with a physical amplitude and wavelength).
//!
//! Both act on the shading normal of a mesh hit ([`crate::shapes::Mesh::surface`]): the
//! normal map first, then orange peel on the mapped surface. A mesh's [`Perturbation`] tilts
//! the whole paint; a mesh's [`CoatNormal`] (Blender's Coat Normal, orange peel) gives the
//! clearcoat's top reflection its own normal, and the integrator then shades a paint in two
//! frames: the coat's reflection in the coat frame, the lobes under the coat in the base frame
//! (as Cycles does with the Principled BSDF's Coat Normal).
//!
//! **Normal map** (Cycles' `svm_node_normal_map`, tangent space): the texel colour `c` (non-colour
//! data, bilinear, repeating; texel `(i, j)` centred at `((i + ½)/w, (j + ½)/h)`, row 0 at v = 0)
//! gives `n = normalize((2c_r − 1) T + (2c_g − 1) B + (2c_b − 1) N)` with the interpolated
//! tangent T, bitangent B and normal N, then `normalize(N + strength (n − N))`.
//!
//! **Bump map** (Cycles' `svm_node_set_bump`, world space): a height image `H(u, v)` (grey,
//! bilinear, repeating, as the normal map) gives the surface gradient `∇H = H_u ∇u + H_v ∇v`
//! (`∇u`, `∇v` the gradients of the texture coordinates along the triangle, per world unit;
//! `H_u`, `H_v` the bilinear interpolant's derivatives), then
//! `n' = normalize(n − distance ∇H)` and `normalize(strength n' + (1 − strength) n)`, as the
//! Bump node (`invert`: a negative distance). Applied after the normal map, before orange peel.
//!
//! **Orange peel**: the coat's height over the surface is a sum of [`PEEL_WAVES`] plane waves in
//! the object's metric coordinates `c` (metres on the object, per vertex):
//! `h(c) = A √(2/K) Σ_k sin(2π d_k·c / λ + φ_k)`, of RMS height A (the amplitude) and wavelength
//! λ. Its gradient is exact (`∂h/∂c`); mapped to the surface through the triangle (the affine map
//! from world positions to `c`), it tilts the normal: `n' = normalize(n − ∇_s h)`, with `∇_s h`
//! in metres of height per metre of surface (`metres_per_unit` converts world units to metres).
//! The Blender node group evaluates the same sum (blender-addon/extension/nodegroup.py).

use crate::geom::V3;
use std::sync::Arc;

/// The orange-peel waves: unit directions `d_k` (in the object's metric coordinates) and phases
/// `φ_k` (radians): eight directions of a golden-angle spiral over the upper hemisphere, so that
/// on any plane (the axis planes included) no two waves project to the same direction and
/// length (which would make them interfere coherently and change the RMS height); the Blender
/// node group uses this same table.
pub const PEEL_WAVES: [([f64; 3], f64); 8] = [
    ([0.347985273, 0.000000000, 0.937500000], 0.0),
    ([-0.429857439, 0.393784626, 0.812500000], 1.3),
    ([0.063487195, -0.723403847, 0.687500000], 2.6),
    ([0.503055598, 0.656146946, 0.562500000], 3.9),
    ([-0.885472495, -0.156627617, 0.437500000], 0.7),
    ([0.801498139, -0.509847509, 0.312500000], 2.0),
    ([-0.255000119, 0.948587734, 0.187500000], 3.3),
    ([-0.460005935, -0.885713436, 0.062500000], 4.6),
];

/// A tangent-space normal map image.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Texels, row 0 first (v = 0), raw values (non-colour data, 0.5 = no tilt); shared by instances.
    pub texels: Arc<[[f32; 3]]>,
    /// Blender's Normal Map strength (1 = as mapped, 0 = the interpolated normal).
    pub strength: f32,
}

impl NormalMap {
    /// Bilinear, repeating lookup at texture coordinates `uv` (Cycles' "Linear", "Repeat").
    #[must_use]
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = f64::from(uv[0]) * w as f64 - 0.5;
        let y = f64::from(uv[1]) * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
        let wrap = |i: i64, n: i64| i.rem_euclid(n) as usize;
        let at = |i: i64, j: i64| self.texels[wrap(j, h) * self.width + wrap(i, w)];
        let (i, j) = (x0 as i64, y0 as i64);
        let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        std::array::from_fn(|k| {
            let top = a[k] + (b[k] - a[k]) * tx;
            let bottom = c[k] + (d[k] - c[k]) * tx;
            top + (bottom - top) * ty
        })
    }
}

/// A height image for bump mapping (Blender's Bump node fed by an Image Texture).
#[derive(Clone, Debug, PartialEq)]
pub struct BumpMap {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Heights, row 0 first (v = 0); shared by instances.
    pub texels: Arc<[f32]>,
    /// Blender's Bump strength (1 = full, 0 = the unperturbed normal).
    pub strength: f32,
    /// Blender's Bump distance: world units of displacement per unit of height (negative: invert).
    pub distance: f32,
}

impl BumpMap {
    /// The bilinear, repeating height at `uv` and its derivatives `(H, ∂H/∂u, ∂H/∂v)`.
    #[must_use]
    pub fn sample(&self, uv: [f32; 2]) -> (f32, f32, f32) {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = f64::from(uv[0]) * w as f64 - 0.5;
        let y = f64::from(uv[1]) * h as f64 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return (0.0, 0.0, 0.0);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
        let at = |i: i64, j: i64| self.texels[j.rem_euclid(h) as usize * self.width + i.rem_euclid(w) as usize];
        let (i, j) = (x0 as i64, y0 as i64);
        let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        let top = a + (b - a) * tx;
        let bottom = c + (d - c) * tx;
        let value = top + (bottom - top) * ty;
        let du = ((b - a) + ((d - c) - (b - a)) * ty) * self.width as f32;
        let dv = (bottom - top) * self.height as f32;
        (value, du, dv)
    }
}

/// Orange peel of the clearcoat: RMS height and wavelength in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrangePeel {
    /// RMS height of the coat surface (m).
    pub amplitude_m: f64,
    /// Wavelength (m).
    pub wavelength_m: f64,
    /// Metres per world unit (the host's unit scale).
    pub metres_per_unit: f64,
}

impl OrangePeel {
    /// The height `h(c)` (m) at metric coordinates `c` (m).
    #[must_use]
    pub fn height(&self, c: [f64; 3]) -> f64 {
        let a = self.amplitude_m * (2.0 / PEEL_WAVES.len() as f64).sqrt();
        let k = std::f64::consts::TAU / self.wavelength_m;
        PEEL_WAVES.iter().map(|(d, phi)| a * (k * (d[0] * c[0] + d[1] * c[1] + d[2] * c[2]) + phi).sin()).sum()
    }

    /// The gradient `∂h/∂c` (dimensionless: metres of height per metre) at `c`.
    #[must_use]
    pub fn gradient(&self, c: [f64; 3]) -> [f64; 3] {
        let a = self.amplitude_m * (2.0 / PEEL_WAVES.len() as f64).sqrt();
        let k = std::f64::consts::TAU / self.wavelength_m;
        let mut g = [0.0; 3];
        for (d, phi) in &PEEL_WAVES {
            let s = a * k * (k * (d[0] * c[0] + d[1] * c[1] + d[2] * c[2]) + phi).cos();
            for (gi, di) in g.iter_mut().zip(d) {
                *gi += s * di;
            }
        }
        g
    }
}

/// A normal map with its per-vertex texture coordinates, tangents and bitangents.
pub type MappedNormals = (NormalMap, Vec<[f32; 2]>, Vec<V3>, Vec<V3>);

/// A mesh's perturbations with their per-vertex data (one entry per mesh position).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Perturbation {
    /// The normal map, with per-vertex texture coordinates, tangents and bitangents.
    pub normal_map: Option<MappedNormals>,
    /// Orange peel, with per-vertex metric coordinates (m).
    pub orange_peel: Option<(OrangePeel, Vec<[f64; 3]>)>,
    /// A bump map, with per-vertex texture coordinates.
    pub bump: Option<(BumpMap, Vec<[f32; 2]>)>,
}

fn lerp3(v: [V3; 3], b: [f32; 3]) -> V3 {
    v[0] * b[0] + v[1] * b[1] + v[2] * b[2]
}

fn normalize_or(v: V3, fallback: V3) -> V3 {
    let l2 = v.length_squared();
    if l2 > 1e-20 && l2.is_finite() {
        v / l2.sqrt()
    } else {
        fallback
    }
}

/// The bumped normal at barycentrics `b` of a triangle with world positions `p` and texture
/// coordinates `uv` (the Bump node's formula; `n` unchanged where the uv map is degenerate).
fn bump_normal(bump: &BumpMap, uv: [[f32; 2]; 3], b: [f32; 3], p: [V3; 3], n: V3) -> V3 {
    let at = [uv[0][0] * b[0] + uv[1][0] * b[1] + uv[2][0] * b[2], uv[0][1] * b[0] + uv[1][1] * b[1] + uv[2][1] * b[2]];
    let (_, hu, hv) = bump.sample(at);
    // ∇u and ∇v along the triangle: the dual basis of ∂p/∂u, ∂p/∂v.
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (du1, dv1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
    let (du2, dv2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
    let det = du1 * dv2 - dv1 * du2;
    if !(det.abs() > 1e-20) {
        return n;
    }
    let dpdu = (e1 * dv2 - e2 * dv1) / det;
    let dpdv = (e2 * du1 - e1 * du2) / det;
    let (g11, g12, g22) = (dpdu.dot(dpdu), dpdu.dot(dpdv), dpdv.dot(dpdv));
    let gdet = g11 * g22 - g12 * g12;
    if !(gdet > 1e-30 * g11 * g22 && gdet.is_finite()) {
        return n;
    }
    let grad_u = (dpdu * g22 - dpdv * g12) / gdet;
    let grad_v = (dpdv * g11 - dpdu * g12) / gdet;
    let grad = grad_u * hu + grad_v * hv;
    let tangential = grad - n * grad.dot(n);
    let bumped = normalize_or(n - tangential * bump.distance, n);
    let s = bump.strength.max(0.0);
    normalize_or(bumped * s + n * (1.0 - s), n)
}

impl Perturbation {
    /// The perturbed shading normal at barycentrics `b` of the triangle with vertex indices `idx`
    /// and world positions `p`, whose unperturbed unit shading normal is `ns`.
    #[must_use]
    pub fn apply(&self, idx: [usize; 3], b: [f32; 3], p: [V3; 3], ns: V3) -> V3 {
        let mut n = ns;
        if let Some((map, uvs, tangents, bitangents)) = &self.normal_map {
            let uv = [
                uvs[idx[0]][0] * b[0] + uvs[idx[1]][0] * b[1] + uvs[idx[2]][0] * b[2],
                uvs[idx[0]][1] * b[0] + uvs[idx[1]][1] * b[1] + uvs[idx[2]][1] * b[2],
            ];
            let t = lerp3(idx.map(|i| tangents[i]), b);
            let bt = lerp3(idx.map(|i| bitangents[i]), b);
            let c = map.sample(uv);
            let mapped = normalize_or(t * (2.0 * c[0] - 1.0) + bt * (2.0 * c[1] - 1.0) + n * (2.0 * c[2] - 1.0), n);
            n = normalize_or(n + (mapped - n) * map.strength.max(0.0), n);
        }
        if let Some((bump, uvs)) = &self.bump {
            n = bump_normal(bump, idx.map(|i| uvs[i]), b, p, n);
        }
        if let Some((peel, coords)) = &self.orange_peel {
            let c = |i: usize| coords[idx[i]];
            let cp =
                [0, 1, 2].map(|k| c(0)[k] * f64::from(b[0]) + c(1)[k] * f64::from(b[1]) + c(2)[k] * f64::from(b[2]));
            let g = peel.gradient(cp);
            // The in-plane world gradient G: G·e1 = g·f1, G·e2 = g·f2, G in span(e1, e2).
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let (f1, f2) = ([0, 1, 2].map(|k| c(1)[k] - c(0)[k]), [0, 1, 2].map(|k| c(2)[k] - c(0)[k]));
            let h1 = g[0] * f1[0] + g[1] * f1[1] + g[2] * f1[2];
            let h2 = g[0] * f2[0] + g[1] * f2[1] + g[2] * f2[2];
            let (e11, e12, e22) = (f64::from(e1.dot(e1)), f64::from(e1.dot(e2)), f64::from(e2.dot(e2)));
            let det = e11 * e22 - e12 * e12;
            if det > 1e-30 * e11 * e22 && det.is_finite() {
                let a = (h1 * e22 - h2 * e12) / det;
                let bb = (h2 * e11 - h1 * e12) / det;
                // Metres of height per world unit → per metre of surface.
                let s = 1.0 / peel.metres_per_unit;
                let grad = e1 * (a * s) as f32 + e2 * (bb * s) as f32;
                let tangential = grad - n * grad.dot(n);
                n = normalize_or(n - tangential, n);
            }
        }
        n
    }
}

/// The clearcoat's own normal (Blender's Coat Normal input, orange peel): perturbations applied
/// to the mesh's interpolated normal (`follows_normal == false`: a Coat Normal connected to its
/// own normal map or bump, which replaces Normal for the coat in Cycles) or to the base's
/// perturbed normal (`true`: the coat follows Normal, then e.g. orange peel tilts it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoatNormal {
    /// The coat's perturbations.
    pub perturb: Perturbation,
    /// Start from the base's perturbed normal instead of the interpolated one.
    pub follows_normal: bool,
}

impl CoatNormal {
    /// The coat's normal at barycentrics `b` of the triangle `idx` with world positions `p`:
    /// `interpolated` is the mesh's unit shading normal, `base` the base's perturbed normal.
    #[must_use]
    pub fn apply(&self, idx: [usize; 3], b: [f32; 3], p: [V3; 3], interpolated: V3, base: V3) -> V3 {
        self.perturb.apply(idx, b, p, if self.follows_normal { base } else { interpolated })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::v3;

    fn flat_map(c: [f32; 3]) -> NormalMap {
        NormalMap { width: 2, height: 2, texels: vec![c; 4].into(), strength: 1.0 }
    }

    #[test]
    fn flat_normal_map_keeps_the_normal_and_a_tilted_one_tilts_it() {
        let idx = [0, 1, 2];
        let b = [0.2, 0.3, 0.5];
        let p = [v3(0.0, 0.0, 0.0), v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0)];
        let (t, bt, n) = (v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(0.0, 0.0, 1.0));
        let mk = |map: NormalMap| Perturbation {
            normal_map: Some((map, vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], vec![t; 3], vec![bt; 3])),
            ..Default::default()
        };
        let same = mk(flat_map([0.5, 0.5, 1.0])).apply(idx, b, p, n);
        assert!((same - n).length() < 1e-6, "{same:?}");
        // Texel (0.75, 0.5, 0.9): tangent-space (0.5, 0, 0.8) → normalized, along +x (the tangent).
        let tilted = mk(flat_map([0.75, 0.5, 0.9])).apply(idx, b, p, n);
        let want = v3(0.5, 0.0, 0.8).normalize();
        assert!((tilted - want).length() < 1e-6, "{tilted:?} vs {want:?}");
        // Strength 0.5: halfway (then normalized), as Cycles.
        let mut half = flat_map([0.75, 0.5, 0.9]);
        half.strength = 0.5;
        let got = mk(half).apply(idx, b, p, n);
        let want = (n + (want - n) * 0.5).normalize();
        assert!((got - want).length() < 1e-6);
    }

    #[test]
    fn bilinear_lookup_follows_blender_texel_centres_and_repeats() {
        let map =
            NormalMap { width: 2, height: 1, texels: vec![[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]].into(), strength: 1.0 };
        // Texel centres at u = 0.25 and 0.75; halfway between them 0.5; u = 0 is halfway between
        // the last texel (wrapped) and the first.
        assert!((map.sample([0.25, 0.5])[0] - 0.0).abs() < 1e-6);
        assert!((map.sample([0.75, 0.5])[0] - 1.0).abs() < 1e-6);
        assert!((map.sample([0.5, 0.5])[0] - 0.5).abs() < 1e-6);
        assert!((map.sample([0.0, 0.5])[0] - 0.5).abs() < 1e-6);
        assert!((map.sample([1.25, 0.5])[0] - 0.0).abs() < 1e-6);
    }

    #[test]
    fn orange_peel_gradient_is_the_height_fields_derivative_and_has_the_stated_slope() {
        let peel = OrangePeel { amplitude_m: 5e-6, wavelength_m: 2e-3, metres_per_unit: 1.0 };
        // Central differences of the height against the analytic gradient (f64; measured
        // agreement ~1e-10 relative, tolerance 1e-6).
        let c = [0.0123, -0.0456, 0.0789];
        let g = peel.gradient(c);
        let e = 1e-7;
        for k in 0..3 {
            let (mut a, mut b) = (c, c);
            a[k] += e;
            b[k] -= e;
            let fd = (peel.height(a) - peel.height(b)) / (2.0 * e);
            assert!((fd - g[k]).abs() <= 1e-6 * g.iter().map(|x| x.abs()).fold(0.0, f64::max), "{k}: {fd} vs {}", g[k]);
        }
        // RMS height over a large patch of a plane ≈ the amplitude (sum of sines of random
        // phase along the plane; measured 1.001 A over this grid, tolerance 10 %).
        let mut sum2 = 0.0;
        let n = 200;
        for i in 0..n {
            for j in 0..n {
                let c = [i as f64 * 0.37e-3, j as f64 * 0.41e-3, 0.0];
                sum2 += peel.height(c).powi(2);
            }
        }
        let rms = (sum2 / (n * n) as f64).sqrt();
        assert!((rms / 5e-6 - 1.0).abs() < 0.1, "rms {rms}");
    }

    #[test]
    fn orange_peel_tilts_a_plane_by_the_gradient_in_world_units() {
        // A triangle in the world's xy plane, 1 world unit = 0.5 m, with metric coordinates
        // c = 0.5 × position: the normal tilts by −∇h along the plane.
        let peel = OrangePeel { amplitude_m: 20e-6, wavelength_m: 1e-3, metres_per_unit: 0.5 };
        let p = [v3(0.0, 0.0, 0.0), v3(0.01, 0.0, 0.0), v3(0.0, 0.01, 0.0)];
        let coords = p.iter().map(|q| [0.5 * f64::from(q.x), 0.5 * f64::from(q.y), 0.5 * f64::from(q.z)]).collect();
        let pert = Perturbation { orange_peel: Some((peel, coords)), ..Default::default() };
        let b = [0.3, 0.3, 0.4];
        let n = pert.apply([0, 1, 2], b, p, v3(0.0, 0.0, 1.0));
        let c = [0.5 * 0.003, 0.5 * 0.004, 0.0];
        let g = peel.gradient(c);
        let want = v3(-g[0] as f32, -g[1] as f32, 1.0).normalize();
        assert!((n - want).length() < 1e-5, "{n:?} vs {want:?}");
        assert!(n.z < 0.9999, "orange peel of 20 µm at 1 mm tilts the normal visibly: {n:?}");
    }

    #[test]
    fn bump_map_tilts_by_distance_times_the_height_slope() {
        // Heights rising linearly along u: 8 texels 0, 1, …, 7 repeat, so between texel centres
        // ∂H/∂u = 8 per uv unit. A triangle in the xy plane with u = x / 2 (world units): the
        // world slope is 4 per unit, so n' = normalize((−4 d, 0, 1)) for distance d.
        let texels: Vec<f32> = (0..8).map(|i| i as f32).collect();
        let bump = BumpMap { width: 8, height: 1, texels: texels.into(), strength: 1.0, distance: 0.05 };
        let (h, hu, hv) = bump.sample([0.3, 0.5]);
        assert!((h - (0.3 * 8.0 - 0.5)).abs() < 1e-5 && (hu - 8.0).abs() < 1e-4 && hv.abs() < 1e-6, "{h} {hu} {hv}");
        let p = [v3(0.0, 0.0, 0.0), v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0)];
        let uvs = vec![[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]];
        let mk = |bump: BumpMap| Perturbation { bump: Some((bump, uvs.clone())), ..Default::default() };
        let b = [0.4, 0.5, 0.1]; // u = 0.25: between texel centres 1 and 2
        let n = mk(bump.clone()).apply([0, 1, 2], b, p, v3(0.0, 0.0, 1.0));
        let want = v3(-4.0 * 0.05, 0.0, 1.0).normalize();
        assert!((n - want).length() < 1e-5, "{n:?} vs {want:?}");
        // Invert (negative distance) tilts the other way; strength 0 keeps the normal.
        let inv = mk(BumpMap { distance: -0.05, ..bump.clone() }).apply([0, 1, 2], b, p, v3(0.0, 0.0, 1.0));
        assert!((inv - v3(4.0 * 0.05, 0.0, 1.0).normalize()).length() < 1e-5, "{inv:?}");
        let off = mk(BumpMap { strength: 0.0, ..bump }).apply([0, 1, 2], b, p, v3(0.0, 0.0, 1.0));
        assert!((off - v3(0.0, 0.0, 1.0)).length() < 1e-6, "{off:?}");
    }
}
