//! A pinhole perspective camera with ray differentials (the directions through the pixel's
//! centre and one pixel to the right and down of it), from which hit points get their uv
//! footprint: one footprint per pixel, whatever the sample's position inside it.

use crate::geom::{Ray, V3};

/// A perspective camera.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Eye position.
    pub position: V3,
    forward: V3,
    right: V3,
    up: V3,
    /// tan(vertical fov / 2).
    tan_half: f32,
    width: u32,
    height: u32,
}

/// A camera ray with its differentials (same origin; the directions through the centre of the
/// ray's pixel and through the centres of the pixels one to the right and one down).
#[derive(Clone, Copy, Debug)]
pub struct CameraRay {
    /// The ray (unit direction).
    pub ray: Ray,
    /// Direction through the centre of the ray's pixel (the footprint's centre).
    pub centre: V3,
    /// Direction through the centre of the pixel one to the right.
    pub dx: V3,
    /// Direction through the centre of the pixel one down.
    pub dy: V3,
}

impl Camera {
    /// A camera at `position` looking at `target` with `up` roughly up and a vertical field
    /// of view in degrees, for an image of `width × height` pixels.
    #[must_use]
    pub fn look_at(position: V3, target: V3, up: V3, vfov_deg: f32, width: u32, height: u32) -> Self {
        let forward = (target - position).normalize();
        let mut right = forward.cross(up);
        if !(right.length_squared() > 1e-12) {
            right = forward.cross(crate::geom::v3(0.0, 0.0, 1.0));
        }
        let right = right.normalize();
        let up = right.cross(forward);
        let tan_half = (0.5 * vfov_deg.clamp(0.01, 179.0)).to_radians().tan();
        Self { position, forward, right, up, tan_half, width: width.max(1), height: height.max(1) }
    }

    /// Image width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The same camera for another image size (same vertical field of view).
    #[must_use]
    pub fn with_size(mut self, width: u32, height: u32) -> Self {
        self.width = width.max(1);
        self.height = height.max(1);
        self
    }

    /// Unnormalised direction through raster position `(x, y)` (pixels, y down).
    #[inline]
    fn dir(&self, x: f32, y: f32) -> V3 {
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half;
        self.forward + self.right * sx + self.up * sy
    }

    /// The ray through raster position `(x, y)`, its differentials centred on it (as if
    /// `(x, y)` were a pixel centre).
    #[inline]
    #[must_use]
    pub fn generate(&self, x: f32, y: f32) -> CameraRay {
        let d = self.dir(x, y);
        CameraRay {
            ray: Ray::new(self.position, d.normalize()),
            centre: d.normalize(),
            dx: self.dir(x + 1.0, y).normalize(),
            dy: self.dir(x, y + 1.0).normalize(),
        }
    }

    /// The ray through `offset` ∈ [0, 1)² inside pixel `(px, py)`, with the differentials of
    /// the pixel's centre: every sample of a pixel gets the same footprint (issue 17: with
    /// differentials centred on each jittered sample, averaging a pixel's samples also
    /// averaged the sparkle counts of the 1–4 grid cells the shifted footprints overlapped).
    #[inline]
    #[must_use]
    pub fn generate_in_pixel(&self, px: u32, py: u32, offset: [f32; 2]) -> CameraRay {
        let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
        CameraRay {
            ray: Ray::new(self.position, self.dir(px as f32 + offset[0], py as f32 + offset[1]).normalize()),
            centre: self.dir(cx, cy).normalize(),
            dx: self.dir(cx + 1.0, cy).normalize(),
            dy: self.dir(cx, cy + 1.0).normalize(),
        }
    }

    /// Raster position of world point `p`, if in front of the camera.
    #[must_use]
    pub fn project(&self, p: V3) -> Option<(f32, f32)> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if !(z > 0.0) {
            return None;
        }
        let aspect = self.width as f32 / self.height as f32;
        let sx = d.dot(self.right) / z / (self.tan_half * aspect);
        let sy = d.dot(self.up) / z / self.tan_half;
        Some(((sx + 1.0) * 0.5 * self.width as f32, (1.0 - sy) * 0.5 * self.height as f32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::v3;

    #[test]
    fn centre_ray_and_projection() {
        let c = Camera::look_at(v3(0.0, 0.0, 5.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 40.0, 200, 100);
        let r = c.generate(100.0, 50.0);
        assert!((r.ray.d - v3(0.0, 0.0, -1.0)).length() < 1e-6);
        let (x, y) = c.project(v3(0.3, -0.2, 1.0)).unwrap();
        let back = c.generate(x, y).ray;
        let to_p = (v3(0.3, -0.2, 1.0) - back.o).normalize();
        assert!((back.d - to_p).length() < 1e-5);
        // Pixel (0, 0) is top left: pointing up and left.
        let tl = c.generate(0.0, 0.0).ray.d;
        assert!(tl.x < 0.0 && tl.y > 0.0);
    }

    /// Every sample of a pixel carries the pixel centre's differentials (one footprint per
    /// pixel), and its own ray goes through its offset.
    #[test]
    fn samples_of_a_pixel_share_the_centre_differentials() {
        let c = Camera::look_at(v3(0.0, 0.0, 5.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 40.0, 200, 100);
        let centre = c.generate(30.5, 70.5);
        for o in [[0.0, 0.0], [0.9, 0.1], [0.25, 0.99]] {
            let r = c.generate_in_pixel(30, 70, o);
            assert_eq!((r.centre, r.dx, r.dy), (centre.centre, centre.dx, centre.dy));
            let own = c.generate(30.0 + o[0], 70.0 + o[1]).ray.d;
            assert!((r.ray.d - own).length() < 1e-7);
        }
    }
}
