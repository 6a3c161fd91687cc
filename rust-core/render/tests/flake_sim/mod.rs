//! An explicit flake simulation of a painted plane under a point light, pixel by pixel, for
//! the pixel statistics of rendered sparkle (issue 17, item 1).
//!
//! Discrete flakes are scattered on the plane: centres uniform (a Poisson process, of
//! `c / A_flake` flakes per unit area times `⟨1/cos θm⟩`: the number of flakes of area
//! `A_flake` whose projected areas cover the fraction `c`), normals drawn per flake from the
//! orientation distribution `D(m) / ∫D dω` (Beckmann, α = tan of the paint's RMS tilt; drawn
//! from `D cos θm` and thinned by `1/(M cos θm)`, `M = 3`, which no Beckmann α ≤ 0.25
//! normal exceeds in practice: `P(1/cos θm > 3) = e^{−8/α²} < 1e-55`). Each flake is a mirror
//! whose glint covers one diffraction-limited direction cell around its normal (the model's
//! glint width, `paint/sparkle.rs`): the equal-area direction square's box of side `1/K`
//! centred on the flake normal, probability `p = 1/K²` under `D cos θm`. A flake at `x` sends
//! the camera the light's glint when the binder half vector `h(x)` of the light and camera
//! directions at `x` lies in its box, and then contributes
//!
//! `L_k = A_flake cos θh / (c p A_pixel) · L_flakes(x)`,
//!
//! to its pixel (`A_pixel` the pixel's exact quad on the plane, `L_flakes(x)` the mean flake
//! lobe's radiance at `x`, `f_flakes cos θi I / r²`): the discrete normal density
//! `Σ_k A_flake K_g(h, m_k) / A`, with `K_g` the box's normalised kernel
//! (`D(h) cos θh / p` inside), divided by its mean `c D(h)`. Every pixel also gets the
//! smooth rest of the paint (coat, multiple scattering) at its centre. Values are reported as
//! `r = (L − L_rest) / L_flakes` at the pixel centre: the flake multiplier, mean 1.
//!
//! Nothing here comes from the sparkle layer except the direction-square map (the equal-area
//! parameterisation of `h` and `m`) and `K`: positions, counts and normals are the
//! simulation's own.

use lacquer::models::Model;
use lacquer::paint::coated_paint::CoatedPaint;
use lacquer::rng::Pcg32;
use lacquer::{Material, Vec3};
use lacquer_render::camera::Camera;
use lacquer_render::geom::v3;

/// A painted plane seen by a camera under a point light at the camera's mirror direction.
#[derive(Clone, Copy, Debug)]
pub struct PlaneSetup {
    /// Metallic flake coverage in %.
    pub density_pct: f64,
    /// Camera distance from the plane's centre (mm; scene units are millimetres).
    pub distance_mm: f64,
    /// Image side in pixels.
    pub pixels: u32,
    /// Vertical field of view (degrees).
    pub fov_deg: f64,
    /// Angle of the camera (and light) from the normal (degrees).
    pub theta_deg: f64,
    /// Light distance (mm).
    pub light_distance_mm: f64,
    /// Light intensity (W/sr).
    pub intensity: f64,
}

impl PlaneSetup {
    /// The paint (20 µm Al flakes, 12° RMS tilt, black pigment, mirror-smooth coat: the point
    /// light's coat reflection is a delta the camera does not see).
    pub fn material_json(&self) -> String {
        format!(
            r#"{{"model": "coated_paint", "base_color": 0, "coat_roughness": 0, "flake_density": {},
               "flake_size_um": 20, "flake_orientation_deg": 12, "surface_scale_mm": 100}}"#,
            self.density_pct
        )
    }

    fn camera_position(&self) -> [f64; 3] {
        let t = self.theta_deg.to_radians();
        [self.distance_mm * t.sin(), self.distance_mm * t.cos(), 0.0]
    }

    fn light_position(&self) -> [f64; 3] {
        let t = self.theta_deg.to_radians();
        [-self.light_distance_mm * t.sin(), self.light_distance_mm * t.cos(), 0.0]
    }

    /// The `lacquer render` job: the same plane (y = 0, uv_scale 0.01 uv/mm, so one uv unit is
    /// the paint's `surface_scale_mm` = 100 mm), camera and light; direct lighting only.
    pub fn job_json(&self, spp: u32) -> String {
        let c = self.camera_position();
        let l = self.light_position();
        let size = self.distance_mm;
        format!(
            r#"{{"material": {m}, "width": {n}, "height": {n}, "spp": {spp}, "max_depth": 1, "aovs": false,
                "scene": {{"camera": {{"position": [{}, {}, {}], "look_at": [0, 0, 0], "fov_deg": {fov}}},
                          "objects": [{{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0],
                                        "size": [{size}, {size}], "material": "paint", "uv_scale": 0.01}}],
                          "lights": [{{"type": "point", "position": [{}, {}, {}], "intensity": {i}}}]}}}}"#,
            c[0],
            c[1],
            c[2],
            l[0],
            l[1],
            l[2],
            m = self.material_json(),
            n = self.pixels,
            fov = self.fov_deg,
            i = self.intensity,
        )
    }

    fn camera(&self) -> Camera {
        let c = self.camera_position();
        Camera::look_at(
            v3(c[0] as f32, c[1] as f32, c[2] as f32),
            v3(0.0, 0.0, 0.0),
            v3(0.0, 1.0, 0.0),
            self.fov_deg as f32,
            self.pixels,
            self.pixels,
        )
    }
}

/// Per-pixel geometry and the smooth parts of the paint at the pixel centre.
pub struct Pixels {
    /// Area of each pixel on the plane (mm²).
    pub area_mm2: Vec<f64>,
    /// Radiance of everything but the flakes at the centre (green).
    pub rest: Vec<f64>,
    /// Radiance of the mean flake lobe at the centre (green).
    pub flakes: Vec<f64>,
    /// Expected glinting flakes `N p` (if all lay flat: `N = c A / A_flake`).
    pub lambda: Vec<f64>,
}

/// The paint of `setup` as a coated paint.
pub fn paint(setup: &PlaneSetup) -> CoatedPaint {
    match Material::from_json(&setup.material_json()).unwrap().model() {
        Model::CoatedPaint(p) => p.clone(),
        _ => unreachable!("coated_paint"),
    }
}

/// Where the ray through raster `(x, y)` meets the plane y = 0 (x, z in mm).
fn on_plane(cam: &Camera, x: f32, y: f32) -> [f64; 2] {
    let r = cam.generate(x, y).ray;
    let (o, d) = ([r.o.x as f64, r.o.y as f64, r.o.z as f64], [r.d.x as f64, r.d.y as f64, r.d.z as f64]);
    let t = -o[1] / d[1];
    [o[0] + t * d[0], o[2] + t * d[2]]
}

/// Light and camera directions at plane point `(x, z)` in the paint's local frame (z up =
/// world y), and the light's irradiance factor `cos θi · I / r²`.
fn directions(setup: &PlaneSetup, p: [f64; 2]) -> (Vec3<f64>, Vec3<f64>, f64) {
    let local = |q: [f64; 3]| {
        let d = [q[0] - p[0], q[1], q[2] - p[1]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (Vec3::new(d[0] / l, -d[2] / l, d[1] / l), l)
    };
    let (wi, rl) = local(setup.light_position());
    let (wo, _) = local(setup.camera_position());
    (wi, wo, wi.z * setup.intensity / (rl * rl))
}

/// Radiance `(rest, flakes)` at plane point `p` (green channel).
fn radiance(paint: &CoatedPaint, setup: &PlaneSetup, p: [f64; 2]) -> (f64, f64) {
    let (wi, wo, e) = directions(setup, p);
    let rest = paint.eval_scaled(wi, wo, 0.0, 0.0).g;
    let all = paint.eval_scaled(wi, wo, 1.0, 0.0).g;
    (rest * e, (all - rest) * e)
}

/// The pixels' geometry and smooth radiance.
pub fn pixels(setup: &PlaneSetup) -> Pixels {
    let paint = paint(setup);
    let pop = paint.sparkle_layer().unwrap().metal.clone().unwrap();
    let cam = setup.camera();
    let n = setup.pixels;
    let mut px = Pixels { area_mm2: vec![], rest: vec![], flakes: vec![], lambda: vec![] };
    for y in 0..n {
        for x in 0..n {
            let (xf, yf) = (x as f32, y as f32);
            let c = [on_plane(&cam, xf, yf), on_plane(&cam, xf + 1.0, yf), on_plane(&cam, xf + 1.0, yf + 1.0)];
            let d = on_plane(&cam, xf, yf + 1.0);
            let (a, b) = ([c[2][0] - c[0][0], c[2][1] - c[0][1]], [d[0] - c[1][0], d[1] - c[1][1]]);
            let area = 0.5 * (a[0] * b[1] - a[1] * b[0]).abs();
            let (rest, flakes) = radiance(&paint, setup, on_plane(&cam, xf + 0.5, yf + 0.5));
            px.area_mm2.push(area);
            px.rest.push(rest);
            px.flakes.push(flakes);
            px.lambda.push(pop.coverage * area * 1e6 / pop.flake_area_um2 * pop.cell_probability);
        }
    }
    px
}

/// The explicit simulation: the flake multiplier `r` of every pixel (row-major).
pub fn simulate(setup: &PlaneSetup, px: &Pixels, seed: u64) -> Vec<f64> {
    let paint = paint(setup);
    let sparkle = paint.sparkle_layer().unwrap();
    let pop = sparkle.metal.clone().unwrap();
    let (alpha, k) = (sparkle.alpha, pop.cells as f64);
    let cam = setup.camera();
    let n = setup.pixels;
    // The region the image sees on the plane.
    let corners =
        [(0.0, 0.0), (n as f32, 0.0), (0.0, n as f32), (n as f32, n as f32)].map(|(x, y)| on_plane(&cam, x, y));
    let lo = [0, 1].map(|i| corners.iter().map(|c| c[i]).fold(f64::INFINITY, f64::min));
    let hi = [0, 1].map(|i| corners.iter().map(|c| c[i]).fold(f64::NEG_INFINITY, f64::max));
    let m_max = 3.0;
    let per_mm2 = pop.coverage / (pop.flake_area_um2 * 1e-6) * m_max;
    let candidates = (per_mm2 * (hi[0] - lo[0]) * (hi[1] - lo[1])).round() as u64;
    // Centre half vector's direction-square position per pixel (a cheap pre-filter: h moves
    // by < 1/20 of a cell across a pixel here, so a 2/K window misses no glint).
    let centre_sq: Vec<[f64; 2]> = (0..n * n)
        .map(|i| {
            let p = on_plane(&cam, (i % n) as f32 + 0.5, (i / n) as f32 + 0.5);
            let (wi, wo, _) = directions(setup, p);
            sparkle.direction_square(paint.binder_half_vector(wi, wo).unwrap())
        })
        .collect();
    let mut r = vec![0.0; (n * n) as usize];
    let mut rng = Pcg32::new(seed, 99);
    for _ in 0..candidates {
        let p = [rng.range(lo[0], hi[0]), rng.range(lo[1], hi[1])];
        let (u1, u2, u3) = (rng.uniform(), rng.uniform(), rng.uniform());
        // Beckmann normal from D cos θm, thinned to D: keep with probability 1/(M cos θm).
        let tan2 = -alpha * alpha * (1.0 - u1).ln();
        let cos = 1.0 / (1.0 + tan2).sqrt();
        if u3 * m_max * cos > 1.0 {
            continue;
        }
        let Some((fx, fy)) = cam.project(v3(p[0] as f32, 0.0, p[1] as f32)) else { continue };
        if !(fx >= 0.0 && fy >= 0.0 && fx < n as f32 && fy < n as f32) {
            continue;
        }
        let i = (fy as u32 * n + fx as u32) as usize;
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let m = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        let sq_m = sparkle.direction_square(m);
        let c = centre_sq[i];
        if (sq_m[0] - c[0]).abs() > 1.0 / k || (sq_m[1] - c[1]).abs() > 1.0 / k {
            continue;
        }
        let (wi, wo, _) = directions(setup, p);
        let h = paint.binder_half_vector(wi, wo).unwrap();
        let sq_h = sparkle.direction_square(h);
        if (sq_m[0] - sq_h[0]).abs() < 0.5 / k && (sq_m[1] - sq_h[1]).abs() < 0.5 / k {
            let (_, flakes) = radiance(&paint, setup, p);
            let area_um2 = px.area_mm2[i] * 1e6;
            r[i] += pop.flake_area_um2 * h.z / (pop.coverage * pop.cell_probability * area_um2) * flakes / px.flakes[i];
        }
    }
    r
}

/// The flake multiplier `r = (L − L_rest)/L_flakes` of every pixel of a render (green).
pub fn render_multipliers(px: &Pixels, color: &[[f32; 3]]) -> Vec<f64> {
    color.iter().enumerate().map(|(i, c)| (c[1] as f64 - px.rest[i]) / px.flakes[i]).collect()
}

/// Pixel statistics of flake multipliers.
#[derive(Clone, Copy, Debug)]
pub struct PixelStats {
    /// Pixels.
    pub n: usize,
    /// Mean multiplier.
    pub mean: f64,
    /// Variance of the multiplier.
    pub var: f64,
    /// Fourth central moment (for the variance's standard error).
    pub m4: f64,
    /// Fraction of pixels showing at least half a flake's glint.
    pub glint: f64,
    /// Pixels by glinting flakes `round(r N p)`: 0, 1, 2, ≥ 3.
    pub hist: [usize; 4],
    /// Correlation of horizontally neighbouring pixels.
    pub neighbour_corr: f64,
}

/// Statistics of `r` (row-major, `width` per row) with the pixels' `N p`.
pub fn stats(r: &[f64], px: &Pixels, width: usize) -> PixelStats {
    let n = r.len();
    let mean = r.iter().sum::<f64>() / n as f64;
    let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n as f64 - 1.0);
    let m4 = r.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / n as f64;
    let mut hist = [0usize; 4];
    for (v, l) in r.iter().zip(&px.lambda) {
        let flakes = (v * l).round().clamp(0.0, 3.0) as usize;
        hist[flakes] += 1;
    }
    let glint = (n - hist[0]) as f64 / n as f64;
    let (mut c, mut pairs) = (0.0, 0);
    for (i, v) in r.iter().enumerate() {
        if (i + 1) % width != 0 {
            c += (v - mean) * (r[i + 1] - mean);
            pairs += 1;
        }
    }
    PixelStats { n, mean, var, m4, glint, hist, neighbour_corr: c / pairs as f64 / var }
}
