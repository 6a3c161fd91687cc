//! Light sources: point and spot (intensity I in W/sr, so irradiance I/r²·cos θ as in the
//! thesis' local illumination), sun (irradiance E on a surface facing it; a delta direction
//! or a small disk), spherical and rectangular area lights (radiance L), and the environment.

use crate::env::Environment;
use crate::geom::{Frame, V3};
use crate::shapes::{Quad, Sphere};
use lacquer::Rgb;
use std::f32::consts::PI;

type C = Rgb<f32>;

/// A light source.
#[derive(Clone, Debug)]
pub enum Light {
    /// Isotropic point light.
    Point {
        /// Position.
        position: V3,
        /// Radiant intensity (W/sr per channel).
        intensity: C,
    },
    /// Spot light: a point light restricted to a cone with a smooth edge.
    Spot {
        /// Position.
        position: V3,
        /// Unit axis of the cone (direction the light shines to).
        direction: V3,
        /// Intensity on the axis (W/sr).
        intensity: C,
        /// cos of the full-intensity half angle.
        cos_inner: f32,
        /// cos of the cut-off half angle.
        cos_outer: f32,
    },
    /// Distant light (the sun): irradiance `E` on a surface facing it.
    Sun {
        /// Unit direction toward the sun.
        direction: V3,
        /// Irradiance (W/m² per channel) perpendicular to `direction`.
        irradiance: C,
        /// cos of the disk's angular radius (1 = delta direction).
        cos_radius: f32,
        /// Frame around `direction` for sampling the disk.
        frame: Frame,
    },
    /// A spherical area light of uniform radiance (its sphere is also scene geometry).
    Sphere {
        /// The emitting sphere.
        sphere: Sphere,
        /// Emitted radiance.
        radiance: C,
    },
    /// A rectangular area light emitting from its front side (`edge_u × edge_v`), or the
    /// ellipse inscribed in it (disk and ellipse lights).
    Rect {
        /// The emitting rectangle.
        quad: Quad,
        /// Emitted radiance.
        radiance: C,
        /// Emit from both sides.
        two_sided: bool,
        /// Only the ellipse inscribed in the parallelogram emits (and is geometry).
        ellipse: bool,
    },
    /// The environment at infinity.
    Env(Environment),
}

/// A light sample seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction toward the light.
    pub wi: V3,
    /// Incident radiance (area, environment), or `I/r²` / `E` for delta lights.
    pub li: C,
    /// Solid-angle density (1 for delta lights).
    pub pdf: f32,
    /// Distance to the light (infinity for sun and environment).
    pub dist: f32,
    /// True for point, spot and delta-sun lights: BSDF sampling can never hit them (no MIS).
    pub delta: bool,
}

/// Samples the cone of directions within `cos_max` of `axis` uniformly.
fn sample_cone(frame: &Frame, cos_max: f32, u: [f32; 2]) -> V3 {
    let cos_t = 1.0 - u[0] * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    frame.to_world(crate::geom::v3(sin_t * phi.cos(), sin_t * phi.sin(), cos_t))
}

/// Solid angle of the cone within `cos_max` of its axis (stable for tiny cones).
fn cone_solid_angle(cos_max: f32) -> f32 {
    2.0 * PI * (1.0 - cos_max).max(1e-12)
}

impl Light {
    /// A sun from its direction, irradiance and angular diameter (0 = delta).
    #[must_use]
    pub fn sun(direction: V3, irradiance: C, angular_diameter_deg: f32) -> Self {
        let d = direction.normalize();
        let r = (0.5 * angular_diameter_deg).to_radians();
        Self::Sun {
            direction: d,
            irradiance,
            cos_radius: if r > 0.0 { r.cos() } else { 1.0 },
            frame: Frame::from_normal_tangent(d, crate::geom::v3(1.0, 0.0, 0.0)),
        }
    }

    /// True when BSDF sampling cannot hit this light.
    #[must_use]
    pub fn is_delta(&self) -> bool {
        match self {
            Light::Point { .. } | Light::Spot { .. } => true,
            Light::Sun { cos_radius, .. } => *cos_radius >= 1.0,
            _ => false,
        }
    }

    /// Samples incident light at `p`.
    #[inline]
    #[must_use]
    pub fn sample(&self, p: V3, u: [f32; 2]) -> Option<LightSample> {
        match self {
            Light::Point { position, intensity } => {
                let d = *position - p;
                let r2 = d.length_squared();
                let dist = r2.sqrt();
                (r2 > 0.0).then(|| LightSample { wi: d / dist, li: *intensity / r2, pdf: 1.0, dist, delta: true })
            }
            Light::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                let d = *position - p;
                let r2 = d.length_squared();
                let dist = r2.sqrt();
                if !(r2 > 0.0) {
                    return None;
                }
                let wi = d / dist;
                let falloff = spot_falloff(-wi.dot(*direction), *cos_inner, *cos_outer);
                (falloff > 0.0).then(|| LightSample {
                    wi,
                    li: *intensity * (falloff / r2),
                    pdf: 1.0,
                    dist,
                    delta: true,
                })
            }
            Light::Sun { direction, irradiance, cos_radius, frame } => {
                if *cos_radius >= 1.0 {
                    return Some(LightSample {
                        wi: *direction,
                        li: *irradiance,
                        pdf: 1.0,
                        dist: f32::INFINITY,
                        delta: true,
                    });
                }
                let wi = sample_cone(frame, *cos_radius, u);
                let omega = cone_solid_angle(*cos_radius);
                Some(LightSample { wi, li: self.sun_radiance(), pdf: 1.0 / omega, dist: f32::INFINITY, delta: false })
            }
            Light::Sphere { sphere, radiance } => {
                let to_c = sphere.center - p;
                let d2 = to_c.length_squared();
                let r2 = sphere.radius * sphere.radius;
                if d2 <= r2 * 1.0001 {
                    return None; // inside or on the light: not sampled
                }
                let dc = d2.sqrt();
                let sin2_max = r2 / d2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                let frame = Frame::from_normal_tangent(to_c / dc, crate::geom::v3(1.0, 0.0, 0.0));
                let wi = sample_cone(&frame, cos_max, u);
                // Distance to the sphere's near surface along wi.
                let ray = crate::geom::Ray::new(p, wi);
                let dist = sphere.intersect(&ray, f32::INFINITY).unwrap_or(dc - sphere.radius);
                Some(LightSample { wi, li: *radiance, pdf: 1.0 / cone_solid_angle(cos_max), dist, delta: false })
            }
            Light::Rect { quad, radiance, two_sided, ellipse } => {
                let (a, b) = if *ellipse {
                    let (x, y) = lacquer::sampling::concentric_disk(u[0], u[1]);
                    (0.5 * (x + 1.0), 0.5 * (y + 1.0))
                } else {
                    (u[0], u[1])
                };
                let q = quad.corner + quad.edge_u * a + quad.edge_v * b;
                let d = q - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = d / dist;
                let cos_l = -wi.dot(quad.normal());
                if cos_l <= 0.0 && !*two_sided || cos_l == 0.0 {
                    return None;
                }
                let pdf = dist2 / (emitter_area(quad, *ellipse) * cos_l.abs());
                Some(LightSample { wi, li: *radiance, pdf, dist, delta: false })
            }
            Light::Env(env) => {
                let (wi, li, pdf) = env.sample(u)?;
                (pdf > 0.0).then_some(LightSample { wi, li, pdf, dist: f32::INFINITY, delta: false })
            }
        }
    }

    /// Solid-angle density of [`Light::sample`] at `p` for direction `wi` (which reaches the
    /// light at distance `dist` for area lights). Zero for delta lights.
    #[inline]
    #[must_use]
    pub fn pdf(&self, p: V3, wi: V3, dist: f32) -> f32 {
        match self {
            Light::Point { .. } | Light::Spot { .. } => 0.0,
            Light::Sun { direction, cos_radius, .. } => {
                if *cos_radius >= 1.0 || wi.dot(*direction) < *cos_radius {
                    0.0
                } else {
                    1.0 / cone_solid_angle(*cos_radius)
                }
            }
            Light::Sphere { sphere, .. } => {
                let d2 = (sphere.center - p).length_squared();
                let r2 = sphere.radius * sphere.radius;
                if d2 <= r2 * 1.0001 {
                    return 0.0;
                }
                1.0 / cone_solid_angle((1.0 - r2 / d2).max(0.0).sqrt())
            }
            Light::Rect { quad, two_sided, ellipse, .. } => {
                let cos_l = -wi.dot(quad.normal());
                if cos_l <= 0.0 && !*two_sided || cos_l == 0.0 {
                    return 0.0;
                }
                dist * dist / (emitter_area(quad, *ellipse) * cos_l.abs())
            }
            Light::Env(env) => env.pdf(wi),
        }
    }

    /// Radiance the light emits toward `-wi` at its surface point with normal `n`
    /// (area lights only).
    #[inline]
    #[must_use]
    pub fn emitted(&self, n: V3, wi: V3) -> C {
        match self {
            Light::Sphere { radiance, .. } => {
                if n.dot(wi) < 0.0 {
                    *radiance
                } else {
                    C::zero()
                }
            }
            Light::Rect { radiance, two_sided, .. } => {
                if n.dot(wi) < 0.0 || *two_sided {
                    *radiance
                } else {
                    C::zero()
                }
            }
            _ => C::zero(),
        }
    }

    /// Radiance arriving from direction `d` for lights at infinity (environment, sun disk).
    #[inline]
    #[must_use]
    pub fn escaped(&self, d: V3) -> C {
        match self {
            Light::Env(env) => env.radiance(d),
            Light::Sun { direction, cos_radius, .. } if *cos_radius < 1.0 && d.dot(*direction) >= *cos_radius => {
                self.sun_radiance()
            }
            _ => C::zero(),
        }
    }

    /// True for lights at infinity that BSDF-sampled rays can hit.
    #[must_use]
    pub fn is_infinite_area(&self) -> bool {
        match self {
            Light::Env(_) => true,
            Light::Sun { cos_radius, .. } => *cos_radius < 1.0,
            _ => false,
        }
    }

    /// Radiance of the sun disk: `E = ∫ L cos α dω = L π sin²α_max` for a disk centred on the
    /// normal, so `L = E / (π sin²α_max)`.
    fn sun_radiance(&self) -> C {
        match self {
            Light::Sun { irradiance, cos_radius, .. } => {
                let sin2 = (1.0 - cos_radius * cos_radius).max(1e-12);
                *irradiance / (PI * sin2)
            }
            _ => C::zero(),
        }
    }

    /// Rough emitted power for light selection, given the scene's bounding radius.
    #[must_use]
    pub fn power(&self, scene_radius: f32) -> f32 {
        let area = PI * scene_radius * scene_radius;
        let p = match self {
            Light::Point { intensity, .. } => intensity.luminance() * 4.0 * PI,
            Light::Spot { intensity, cos_inner, cos_outer, .. } => {
                intensity.luminance() * 2.0 * PI * (1.0 - 0.5 * (cos_inner + cos_outer))
            }
            Light::Sun { irradiance, .. } => irradiance.luminance() * area,
            Light::Sphere { sphere, radiance } => radiance.luminance() * 4.0 * PI * PI * sphere.radius * sphere.radius,
            Light::Rect { quad, radiance, two_sided, ellipse } => {
                radiance.luminance() * PI * emitter_area(quad, *ellipse) * if *two_sided { 2.0 } else { 1.0 }
            }
            Light::Env(env) => env.mean_radiance().luminance() * PI * area,
        };
        if p.is_finite() {
            p.max(0.0)
        } else {
            0.0
        }
    }
}

/// Area of a rectangle light's emitter: the parallelogram, or its inscribed ellipse (π/4 of it).
fn emitter_area(quad: &Quad, ellipse: bool) -> f32 {
    quad.area() * if ellipse { PI / 4.0 } else { 1.0 }
}

/// True when the quad coordinates `(a, b)` ∈ [0, 1]² lie in the inscribed ellipse.
#[inline]
#[must_use]
pub fn in_ellipse(a: f32, b: f32) -> bool {
    let (x, y) = (2.0 * a - 1.0, 2.0 * b - 1.0);
    x * x + y * y <= 1.0
}

/// Smooth spot edge: 1 inside the inner cone, 0 outside the outer one, smoothstep between.
fn spot_falloff(cos_t: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if cos_t >= cos_inner {
        return 1.0;
    }
    if cos_t <= cos_outer {
        return 0.0;
    }
    let t = (cos_t - cos_outer) / (cos_inner - cos_outer).max(1e-9);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::v3;

    #[test]
    fn point_light_inverse_square() {
        let l = Light::Point { position: v3(0.0, 2.0, 0.0), intensity: Rgb::splat(8.0) };
        let s = l.sample(v3(0.0, 0.0, 0.0), [0.5, 0.5]).unwrap();
        assert!(s.delta && (s.li.r - 2.0).abs() < 1e-6 && (s.dist - 2.0).abs() < 1e-6);
        assert!((s.wi.y - 1.0).abs() < 1e-6);
    }

    /// Sampling densities of the area lights agree with `pdf`, and the irradiance estimate of a
    /// sphere light matches the closed form `E = π L sin²α` on a surface facing it.
    #[test]
    fn area_light_densities() {
        let sphere = Sphere { center: v3(0.0, 3.0, 0.0), radius: 1.0, uv_scale: 1.0 };
        let l = Light::Sphere { sphere, radiance: Rgb::splat(1.0) };
        let p = v3(0.0, 0.0, 0.0);
        let mut e = 0.0f64;
        let n = 20000;
        let mut rng = lacquer::rng::Pcg32::new(1, 2);
        for _ in 0..n {
            let s = l.sample(p, [rng.uniform() as f32, rng.uniform() as f32]).unwrap();
            assert!((s.pdf - l.pdf(p, s.wi, s.dist)).abs() < 1e-4 * s.pdf);
            e += (s.li.r * s.wi.y / s.pdf) as f64 / n as f64;
        }
        let expected = std::f64::consts::PI / 9.0;
        assert!((e - expected).abs() < 0.01 * expected, "{e} vs {expected}");

        let quad = Quad::centered(v3(0.0, 2.0, 0.0), v3(0.0, -1.0, 0.0), v3(1.0, 0.0, 0.0), 1.0, 1.0, 1.0);
        let l = Light::Rect { quad, radiance: Rgb::splat(1.0), two_sided: false, ellipse: false };
        for _ in 0..100 {
            let s = l.sample(p, [rng.uniform() as f32, rng.uniform() as f32]).unwrap();
            assert!((s.pdf - l.pdf(p, s.wi, s.dist)).abs() < 1e-4 * s.pdf);
            assert!(s.wi.y > 0.0);
        }
        // Behind a one-sided rectangle nothing is emitted.
        assert!(l.sample(v3(0.0, 3.0, 0.0), [0.5, 0.5]).is_none());
    }
}
