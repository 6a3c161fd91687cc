//! Environment lighting at infinity: a constant colour, or a lat-long (equirectangular) HDR
//! map importance-sampled by luminance × sin θ (pbrt's infinite area light).
//!
//! Mapping (world y is up): `u = 1/2 + atan2(x, −z)/(2π)`, `v = acos(y)/π`, so the image
//! centre lies toward −z and the top row toward +y. Texels are looked up without
//! interpolation, which keeps the sampling density exactly proportional to what is seen.

use crate::distrib::Distribution2D;
use crate::geom::{v3, V3};
use lacquer::Rgb;
use std::f32::consts::PI;
use std::path::Path;

type C = Rgb<f32>;

/// An HDR image in linear RGB, row-major, top row first.
#[derive(Clone, Debug)]
pub struct HdrImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels.
    pub pixels: Vec<C>,
}

/// Lighting from infinitely far away.
#[derive(Clone, Debug)]
pub struct Environment {
    kind: Kind,
    /// Rotation about the up axis (radians).
    rotation: f32,
}

#[derive(Clone, Debug)]
enum Kind {
    Constant(C),
    Map { image: HdrImage, dist: Box<Distribution2D>, scale: f32 },
}

impl Environment {
    /// A constant radiance in every direction (the white furnace when 1).
    #[must_use]
    pub fn constant(radiance: C) -> Self {
        Self { kind: Kind::Constant(radiance), rotation: 0.0 }
    }

    /// A lat-long map scaled by `scale` and rotated by `rotation_deg` about the up axis.
    #[must_use]
    pub fn from_image(image: HdrImage, scale: f32, rotation_deg: f32) -> Self {
        let (w, h) = (image.width, image.height);
        let mut weights = vec![0.0f32; w * h];
        for r in 0..h {
            let sin_theta = (PI * (r as f32 + 0.5) / h as f32).sin();
            for c in 0..w {
                let p = image.pixels[r * w + c];
                // Luminance, with a floor so that dim but visible texels are still sampled.
                weights[r * w + c] = (p.luminance().max(0.0) + 1e-3 * p.max_channel().max(0.0)) * sin_theta;
            }
        }
        let dist = Box::new(Distribution2D::new(&weights, w, h));
        Self { kind: Kind::Map { image, dist, scale }, rotation: rotation_deg.to_radians() }
    }

    /// The procedural studio: a soft grey gradient, a dark floor, and three large soft boxes
    /// (top, key side, rim), whose reflections show off glossy coats and flakes.
    #[must_use]
    pub fn studio(scale: f32, rotation_deg: f32) -> Self {
        Self::from_image(studio_image(256, 128), scale, rotation_deg)
    }

    /// Loads a lat-long map from a Radiance `.hdr` or an OpenEXR file.
    pub fn load(path: &Path, scale: f32, rotation_deg: f32) -> Result<Self, String> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        let image = match ext.as_str() {
            "hdr" | "pic" => read_rgbe(path)?,
            "exr" => crate::output::read_exr_rgb(path)?,
            _ => return Err(format!("{}: environment maps must be .hdr or .exr", path.display())),
        };
        Ok(Self::from_image(image, scale, rotation_deg))
    }

    fn world_to_map(&self, d: V3) -> V3 {
        if self.rotation == 0.0 {
            return d;
        }
        let (s, c) = self.rotation.sin_cos();
        v3(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    fn map_to_world(&self, d: V3) -> V3 {
        if self.rotation == 0.0 {
            return d;
        }
        let (s, c) = self.rotation.sin_cos();
        v3(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
    }

    /// Radiance arriving from direction `d` (unit, pointing away from the scene toward the sky).
    #[inline]
    #[must_use]
    pub fn radiance(&self, d: V3) -> C {
        match &self.kind {
            Kind::Constant(c) => *c,
            Kind::Map { image, scale, .. } => {
                let [u, v] = dir_to_uv(self.world_to_map(d));
                let x = ((u * image.width as f32) as usize).min(image.width - 1);
                let y = ((v * image.height as f32) as usize).min(image.height - 1);
                image.pixels[y * image.width + x] * *scale
            }
        }
    }

    /// Samples a direction: `(d, radiance, solid-angle density)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: [f32; 2]) -> Option<(V3, C, f32)> {
        match &self.kind {
            Kind::Constant(c) => {
                let z = 1.0 - 2.0 * u[0];
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u[1];
                Some((v3(r * phi.cos(), z, r * phi.sin()), *c, 1.0 / (4.0 * PI)))
            }
            Kind::Map { dist, .. } => {
                let (uv, pdf_uv) = dist.sample(u);
                if !(pdf_uv > 0.0) {
                    return None;
                }
                let theta = uv[1] * PI;
                let sin_theta = theta.sin();
                if !(sin_theta > 0.0) {
                    return None;
                }
                let d = self.map_to_world(uv_to_dir(uv));
                let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
                Some((d, self.radiance(d), pdf))
            }
        }
    }

    /// Solid-angle density of [`Environment::sample`] for direction `d`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, d: V3) -> f32 {
        match &self.kind {
            Kind::Constant(_) => 1.0 / (4.0 * PI),
            Kind::Map { dist, .. } => {
                let m = self.world_to_map(d);
                let uv = dir_to_uv(m);
                let sin_theta = (1.0 - m.y * m.y).max(0.0).sqrt();
                if !(sin_theta > 0.0) {
                    return 0.0;
                }
                dist.density(uv) / (2.0 * PI * PI * sin_theta)
            }
        }
    }

    /// Mean radiance over the sphere (for light selection by power).
    #[must_use]
    pub fn mean_radiance(&self) -> C {
        match &self.kind {
            Kind::Constant(c) => *c,
            Kind::Map { image, scale, .. } => {
                let (w, h) = (image.width, image.height);
                let mut sum = C::zero();
                let mut wsum = 0.0;
                for r in 0..h {
                    let s = (PI * (r as f32 + 0.5) / h as f32).sin();
                    for c in 0..w {
                        sum += image.pixels[r * w + c] * s;
                    }
                    wsum += s * w as f32;
                }
                sum * (*scale / wsum)
            }
        }
    }
}

/// Direction (map frame) → `[u, v]`.
#[inline]
#[must_use]
pub fn dir_to_uv(d: V3) -> [f32; 2] {
    let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    [u.clamp(0.0, 1.0 - f32::EPSILON), v.clamp(0.0, 1.0 - f32::EPSILON)]
}

/// `[u, v]` → direction (map frame).
#[inline]
#[must_use]
pub fn uv_to_dir(uv: [f32; 2]) -> V3 {
    let phi = (uv[0] - 0.5) * 2.0 * PI;
    let theta = uv[1] * PI;
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    v3(st * sp, ct, -st * cp)
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A soft rectangular panel in (azimuth, elevation) degrees with soft edges.
fn panel(az: f32, el: f32, az0: f32, az1: f32, el0: f32, el1: f32, soft: f32) -> f32 {
    let mut a = az;
    // Wrap the azimuth to the panel's centre.
    let mid = 0.5 * (az0 + az1);
    while a - mid > 180.0 {
        a -= 360.0;
    }
    while a - mid < -180.0 {
        a += 360.0;
    }
    smoothstep(az0 - soft, az0 + soft, a)
        * (1.0 - smoothstep(az1 - soft, az1 + soft, a))
        * smoothstep(el0 - soft, el0 + soft, el)
        * (1.0 - smoothstep(el1 - soft, el1 + soft, el))
}

/// The procedural studio map (see [`Environment::studio`]). Azimuth 0 is −z (behind a camera
/// on +z looking at the origin), 180 is +z (behind the camera).
#[must_use]
pub fn studio_image(width: usize, height: usize) -> HdrImage {
    let mut pixels = Vec::with_capacity(width * height);
    for r in 0..height {
        for c in 0..width {
            let d = uv_to_dir([(c as f32 + 0.5) / width as f32, (r as f32 + 0.5) / height as f32]);
            let el = d.y.clamp(-1.0, 1.0).asin().to_degrees();
            let az = d.x.atan2(-d.z).to_degrees();
            // Walls: a soft grey gradient, brighter near the horizon, a dark floor.
            let wall = if el >= 0.0 {
                let t = (el / 90.0).clamp(0.0, 1.0);
                v3(0.26, 0.27, 0.30) * (1.0 - t) + v3(0.12, 0.13, 0.15) * t
            } else {
                let t = (-el / 90.0).clamp(0.0, 1.0);
                v3(0.10, 0.095, 0.09) * (1.0 - t) + v3(0.04, 0.04, 0.04) * t
            };
            // Soft boxes: a large overhead panel, a key strip front-left, a rim strip behind right.
            let top = panel(az, el, -60.0, 60.0, 55.0, 85.0, 6.0) * 6.0;
            let key = panel(az, el, 120.0, 150.0, 5.0, 45.0, 3.0) * 10.0;
            let rim = panel(az, el, -40.0, -25.0, 0.0, 35.0, 2.0) * 8.0;
            let e = top + key + rim;
            pixels.push(Rgb::new(wall.x + e, wall.y + e * 0.98, wall.z + e * 0.95));
        }
    }
    HdrImage { width, height, pixels }
}

/// Reads a Radiance RGBE (`.hdr`) file: uncompressed or new-style run-length encoded, `-Y H +X W`.
pub fn read_rgbe(path: &Path) -> Result<HdrImage, String> {
    let data = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let err = |m: &str| format!("{}: {m}", path.display());
    // Header lines until an empty line, then the resolution line.
    let mut pos = 0;
    let mut line_start = 0;
    let mut header_done = false;
    while pos < data.len() {
        if data[pos] == b'\n' {
            if pos == line_start {
                header_done = true;
                pos += 1;
                break;
            }
            let line = String::from_utf8_lossy(&data[line_start..pos]);
            if line.starts_with("FORMAT=") && !line.contains("32-bit_rle_rgbe") {
                return Err(err("only 32-bit_rle_rgbe is supported"));
            }
            line_start = pos + 1;
        }
        pos += 1;
    }
    if !header_done {
        return Err(err("no header end"));
    }
    let eol = data[pos..].iter().position(|&b| b == b'\n').ok_or_else(|| err("no resolution line"))?;
    let res = String::from_utf8_lossy(&data[pos..pos + eol]).to_string();
    pos += eol + 1;
    let parts: Vec<&str> = res.split_whitespace().collect();
    if parts.len() != 4 || parts[0] != "-Y" || parts[2] != "+X" {
        return Err(err(&format!("unsupported orientation \"{res}\" (need -Y H +X W)")));
    }
    let height: usize = parts[1].parse().map_err(|_| err("bad height"))?;
    let width: usize = parts[3].parse().map_err(|_| err("bad width"))?;
    if width == 0 || height == 0 || width > 1 << 15 || height > 1 << 15 {
        return Err(err("bad size"));
    }
    let mut pixels = Vec::with_capacity(width * height);
    let mut scan = vec![[0u8; 4]; width];
    let byte = |p: &mut usize| -> Result<u8, String> {
        let b = *data.get(*p).ok_or_else(|| err("truncated"))?;
        *p += 1;
        Ok(b)
    };
    for _ in 0..height {
        let rle = (8..32768).contains(&width)
            && data.get(pos) == Some(&2)
            && data.get(pos + 1) == Some(&2)
            && data.get(pos + 2).is_some_and(|&b| b & 0x80 == 0);
        if rle {
            let w = ((data[pos + 2] as usize) << 8) | data[pos + 3] as usize;
            if w != width {
                return Err(err("scanline width mismatch"));
            }
            pos += 4;
            for ch in 0..4 {
                let mut x = 0;
                while x < width {
                    let count = byte(&mut pos)? as usize;
                    if count > 128 {
                        let n = count - 128;
                        let v = byte(&mut pos)?;
                        if x + n > width {
                            return Err(err("bad run"));
                        }
                        for s in &mut scan[x..x + n] {
                            s[ch] = v;
                        }
                        x += n;
                    } else {
                        if count == 0 || x + count > width {
                            return Err(err("bad run"));
                        }
                        for s in &mut scan[x..x + count] {
                            s[ch] = byte(&mut pos)?;
                        }
                        x += count;
                    }
                }
            }
        } else {
            for s in scan.iter_mut() {
                for ch in s.iter_mut() {
                    *ch = byte(&mut pos)?;
                }
            }
        }
        for s in &scan {
            pixels.push(if s[3] == 0 {
                Rgb::zero()
            } else {
                let f = (s[3] as f32 - 136.0).exp2();
                Rgb::new(s[0] as f32 * f, s[1] as f32 * f, s[2] as f32 * f)
            });
        }
    }
    Ok(HdrImage { width, height, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_round_trip() {
        for &d in &[v3(0.0, 0.0, -1.0), v3(0.6, 0.0, 0.8), v3(-0.3, 0.5, 0.2)] {
            let d = d.normalize();
            let back = uv_to_dir(dir_to_uv(d));
            assert!((back - d).length() < 1e-5, "{d:?} -> {back:?}");
        }
        assert!((dir_to_uv(v3(0.0, 0.0, -1.0))[0] - 0.5).abs() < 1e-6);
    }

    /// The sampling density matches `pdf()` and integrates to one over the sphere.
    #[test]
    fn map_sampling_density() {
        let env = Environment::from_image(studio_image(64, 32), 1.0, 30.0);
        let mut rng = lacquer::rng::Pcg32::new(3, 1);
        for _ in 0..1000 {
            let u = [rng.uniform() as f32, rng.uniform() as f32];
            if let Some((d, l, pdf)) = env.sample(u) {
                assert!((pdf - env.pdf(d)).abs() <= 2e-3 * pdf, "{pdf} vs {}", env.pdf(d));
                assert!((l - env.radiance(d)).max_channel().abs() < 1e-6);
            }
        }
        // ∫ pdf dω = 1 (midpoint rule in (cos θ, φ)).
        let (nt, np) = (200, 400);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let z = -1.0 + 2.0 * (i as f32 + 0.5) / nt as f32;
            let r = (1.0 - z * z).sqrt();
            for j in 0..np {
                let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                sum += env.pdf(v3(r * phi.cos(), z, r * phi.sin())) as f64;
            }
        }
        let integral = sum * 4.0 * std::f64::consts::PI / (nt * np) as f64;
        assert!((integral - 1.0).abs() < 0.01, "{integral}");
    }

    #[test]
    fn rgbe_reads_flat_and_rle() {
        let dir = std::env::temp_dir().join(format!("lacquer-rgbe-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A 8×2 image: row 0 flat-encoded, row 1 run-length encoded; value 1.0 = (128,128,128,129).
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 8\n".to_vec();
        for _ in 0..8 {
            bytes.extend_from_slice(&[128, 128, 128, 129]);
        }
        bytes.extend_from_slice(&[2, 2, 0, 8]);
        for v in [64u8, 128, 192, 130] {
            bytes.extend_from_slice(&[128 + 8, v]);
        }
        let path = dir.join("t.hdr");
        std::fs::write(&path, bytes).unwrap();
        let img = read_rgbe(&path).unwrap();
        assert_eq!((img.width, img.height), (8, 2));
        assert_eq!(img.pixels[3], Rgb::new(1.0, 1.0, 1.0));
        assert_eq!(img.pixels[8 + 5], Rgb::new(1.0, 2.0, 3.0));
        std::fs::remove_dir_all(&dir).ok();
    }
}
