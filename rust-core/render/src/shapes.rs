//! Shapes: triangle meshes, spheres and rectangles (planes), with uv parameterisations and
//! their derivatives (for shading frames and ray-differential footprints).
//!
//! uv conventions: spheres and rectangles use arc length times the object's `uv_scale`, so
//! one uv unit is the same physical length in both directions (flakes stay round); meshes use
//! their own texture coordinates (or none: then uv is zero and the footprint is zero).

use crate::geom::{v3, vmax, vmin, Aabb, Ray, V3};
use crate::perturb::{CoatNormal, Perturbation};

/// Geometry of a successful intersection.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Position.
    pub p: V3,
    /// Unit geometric normal (as modelled; not yet turned toward the ray).
    pub ng: V3,
    /// Unit shading normal (interpolated for meshes), on the same side as `ng`.
    pub ns: V3,
    /// The clearcoat's own unit shading normal where it differs from `ns` (a mesh's
    /// [`CoatNormal`]); `None`: the coat follows `ns`.
    pub coat_ns: Option<V3>,
    /// ∂p/∂u.
    pub dpdu: V3,
    /// ∂p/∂v.
    pub dpdv: V3,
    /// Texture coordinates.
    pub uv: [f32; 2],
}

/// A triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<V3>,
    /// Vertex normals (empty: flat shading).
    pub normals: Vec<V3>,
    /// Vertex texture coordinates (empty: none).
    pub uvs: Vec<[f32; 2]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Shading-normal perturbations (normal map, orange peel), if any.
    pub perturb: Option<Box<Perturbation>>,
    /// The clearcoat's own normal (Coat Normal, orange peel on the coat), if any.
    pub coat: Option<Box<CoatNormal>>,
    /// Vertex coordinates of image textures (a host's UV map; empty: `uvs`), see
    /// [`crate::texture`].
    pub texture_uvs: Vec<[f32; 2]>,
}

impl Mesh {
    /// The image-texture coordinates at barycentrics `(b1, b2)` of triangle `i`: `texture_uvs`
    /// when the mesh has them, else `uvs` (zero without either).
    #[must_use]
    pub fn texture_uv(&self, i: usize, b1: f32, b2: f32) -> [f32; 2] {
        let uvs = if self.texture_uvs.is_empty() { &self.uvs } else { &self.texture_uvs };
        if uvs.is_empty() {
            return [0.0; 2];
        }
        let [ia, ib, ic] = self.triangles[i].map(|k| k as usize);
        let b0 = 1.0 - b1 - b2;
        let (ta, tb, tc) = (uvs[ia], uvs[ib], uvs[ic]);
        [ta[0] * b0 + tb[0] * b1 + tc[0] * b2, ta[1] * b0 + tb[1] * b1 + tc[1] * b2]
    }

    /// Bounding box of triangle `i`.
    #[must_use]
    pub fn triangle_bounds(&self, i: usize) -> Aabb {
        let [a, b, c] = self.triangles[i].map(|k| self.positions[k as usize]);
        Aabb { min: vmin(vmin(a, b), c), max: vmax(vmax(a, b), c) }
    }

    /// Bounds of the whole mesh.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.positions.iter().fold(Aabb::empty(), |mut b, p| {
            b.grow(*p);
            b
        })
    }

    /// Möller-Trumbore: distance and barycentrics `(b1, b2)` of the hit, if within `(tmin, tmax)`.
    #[inline(always)]
    #[must_use]
    pub fn intersect(&self, i: usize, ray: &Ray, tmax: f32) -> Option<(f32, f32, f32)> {
        let [a, b, c] = self.triangles[i].map(|k| self.positions[k as usize]);
        let e1 = b - a;
        let e2 = c - a;
        let pv = ray.d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-20 {
            return None;
        }
        let inv = 1.0 / det;
        let tv = ray.o - a;
        let b1 = tv.dot(pv) * inv;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qv = tv.cross(e1);
        let b2 = ray.d.dot(qv) * inv;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = e2.dot(qv) * inv;
        (t > 0.0 && t < tmax).then_some((t, b1, b2))
    }

    /// Surface data at barycentrics `(b1, b2)` of triangle `i`.
    #[must_use]
    pub fn surface(&self, i: usize, b1: f32, b2: f32) -> SurfaceHit {
        let [ia, ib, ic] = self.triangles[i].map(|k| k as usize);
        let (a, b, c) = (self.positions[ia], self.positions[ib], self.positions[ic]);
        let b0 = 1.0 - b1 - b2;
        let p = a * b0 + b * b1 + c * b2;
        let e1 = b - a;
        let e2 = c - a;
        let ng = e1.cross(e2).normalize();
        let (uv, dpdu, dpdv) = if self.uvs.is_empty() {
            let (s, t) = lacquer::frame::basis_around(ng);
            ([0.0, 0.0], s, t)
        } else {
            let (ta, tb, tc) = (self.uvs[ia], self.uvs[ib], self.uvs[ic]);
            let uv = [ta[0] * b0 + tb[0] * b1 + tc[0] * b2, ta[1] * b0 + tb[1] * b1 + tc[1] * b2];
            let (du1, dv1) = (tb[0] - ta[0], tb[1] - ta[1]);
            let (du2, dv2) = (tc[0] - ta[0], tc[1] - ta[1]);
            let det = du1 * dv2 - dv1 * du2;
            if det.abs() < 1e-12 {
                let (s, t) = lacquer::frame::basis_around(ng);
                (uv, s, t)
            } else {
                let inv = 1.0 / det;
                ((uv), (e1 * dv2 - e2 * dv1) * inv, (e2 * du1 - e1 * du2) * inv)
            }
        };
        let mut ns = ng;
        if !self.normals.is_empty() {
            let n = self.normals[ia] * b0 + self.normals[ib] * b1 + self.normals[ic] * b2;
            let l2 = n.length_squared();
            if l2 > 1e-20 && l2.is_finite() {
                ns = n / l2.sqrt();
            }
        }
        // Keep the geometric normal on the side the mesh's normals say is outside.
        let ng = if ng.dot(ns) < 0.0 { -ng } else { ng };
        let interpolated = ns;
        if let Some(pert) = &self.perturb {
            let n = pert.apply([ia, ib, ic], [b0, b1, b2], [a, b, c], ns);
            // A normal tilted past the surface is not a valid shading normal: keep the mesh's.
            if n.dot(ng) > 1e-3 {
                ns = n;
            }
        }
        let coat_ns = self.coat.as_ref().and_then(|coat| {
            let n = coat.apply([ia, ib, ic], [b0, b1, b2], [a, b, c], interpolated, ns);
            // As above: a coat normal past the surface falls back to the base's.
            (n.dot(ng) > 1e-3 && n != ns).then_some(n)
        });
        SurfaceHit { p, ng, ns, coat_ns, dpdu, dpdv, uv }
    }
}

/// A sphere.
#[derive(Clone, Copy, Debug)]
pub struct Sphere {
    /// Centre.
    pub center: V3,
    /// Radius.
    pub radius: f32,
    /// uv units per unit of arc length.
    pub uv_scale: f32,
}

impl Sphere {
    /// Bounding box.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let r = v3(self.radius, self.radius, self.radius);
        Aabb { min: self.center - r, max: self.center + r }
    }

    /// Nearest hit distance in `(0, tmax)` (unit ray direction).
    #[inline]
    #[must_use]
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<f32> {
        let oc = ray.o - self.center;
        let b = oc.dot(ray.d);
        // Discriminant from the closest-approach vector (pbrt-v4): accurate for far spheres.
        let f = oc - ray.d * b;
        let disc = self.radius * self.radius - f.length_squared();
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let c = oc.length_squared() - self.radius * self.radius;
        // Stable roots: q = -(b + sign(b) s); t0 = c/q, t1 = q.
        let q = if b > 0.0 { -(b + s) } else { -b + s };
        let (mut t0, mut t1) = (c / q, q);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        let eps = 1e-5 * self.radius;
        if t0 > eps && t0 < tmax {
            Some(t0)
        } else if t1 > eps && t1 < tmax {
            Some(t1)
        } else {
            None
        }
    }

    /// Surface data at point `p` (projected onto the sphere).
    #[must_use]
    pub fn surface(&self, p: V3) -> SurfaceHit {
        let n = (p - self.center).normalize();
        let p = self.center + n * self.radius;
        let theta = n.y.clamp(-1.0, 1.0).acos();
        let phi = n.z.atan2(n.x);
        let k = self.radius * self.uv_scale;
        let uv = [phi * k, theta * k];
        // x = sinθ cosφ, y = cosθ, z = sinθ sinφ.
        let (st, ct) = (theta.sin(), theta.cos());
        let (sp, cp) = (phi.sin(), phi.cos());
        let dpdu = v3(-st * sp, 0.0, st * cp) / self.uv_scale;
        let dpdv = v3(ct * cp, -st, ct * sp) / self.uv_scale;
        SurfaceHit { p, ng: n, ns: n, coat_ns: None, dpdu, dpdv, uv }
    }
}

/// A rectangle (parallelogram) `corner + a·edge_u + b·edge_v`, `a, b ∈ [0, 1]`; its normal is
/// `edge_u × edge_v`.
#[derive(Clone, Copy, Debug)]
pub struct Quad {
    /// Corner.
    pub corner: V3,
    /// First edge.
    pub edge_u: V3,
    /// Second edge.
    pub edge_v: V3,
    /// uv units per unit of length.
    pub uv_scale: f32,
}

impl Quad {
    /// A rectangle centred at `center`, facing `normal`, of size `w × h`; `tangent` orients it.
    #[must_use]
    pub fn centered(center: V3, normal: V3, tangent: V3, w: f32, h: f32, uv_scale: f32) -> Self {
        let f = crate::geom::Frame::from_normal_tangent(normal.normalize(), tangent);
        // edge_u × edge_v must point along the normal: s × t = n.
        let (eu, ev) = (f.s * w, f.t * h);
        Self { corner: center - eu * 0.5 - ev * 0.5, edge_u: eu, edge_v: ev, uv_scale }
    }

    /// Unit normal.
    #[must_use]
    pub fn normal(&self) -> V3 {
        self.edge_u.cross(self.edge_v).normalize()
    }

    /// Area.
    #[must_use]
    pub fn area(&self) -> f32 {
        self.edge_u.cross(self.edge_v).length()
    }

    /// Bounding box.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::point(self.corner);
        b.grow(self.corner + self.edge_u);
        b.grow(self.corner + self.edge_v);
        b.grow(self.corner + self.edge_u + self.edge_v);
        // Pad flat boxes so the slab test never sees a zero-width box with NaNs.
        let pad = 1e-5 * (1.0 + (b.max - b.min).length());
        Aabb { min: b.min - v3(pad, pad, pad), max: b.max + v3(pad, pad, pad) }
    }

    /// Hit distance and `(a, b)` coordinates.
    #[inline]
    #[must_use]
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<(f32, f32, f32)> {
        let n = self.edge_u.cross(self.edge_v);
        let denom = n.dot(ray.d);
        if denom.abs() < 1e-20 {
            return None;
        }
        let t = n.dot(self.corner - ray.o) / denom;
        if !(t > 0.0 && t < tmax) {
            return None;
        }
        let q = ray.at(t) - self.corner;
        let n2 = n.length_squared();
        let a = q.cross(self.edge_v).dot(n) / n2;
        let b = self.edge_u.cross(q).dot(n) / n2;
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some((t, a, b))
    }

    /// Surface data at coordinates `(a, b)`.
    #[must_use]
    pub fn surface(&self, a: f32, b: f32) -> SurfaceHit {
        let p = self.corner + self.edge_u * a + self.edge_v * b;
        let n = self.normal();
        let (lu, lv) = (self.edge_u.length(), self.edge_v.length());
        let uv = [a * lu * self.uv_scale, b * lv * self.uv_scale];
        let dpdu = self.edge_u / (lu * self.uv_scale);
        let dpdv = self.edge_v / (lv * self.uv_scale);
        SurfaceHit { p, ng: n, ns: n, coat_ns: None, dpdu, dpdv, uv }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_hits_front_then_back() {
        let s = Sphere { center: v3(0.0, 0.0, 5.0), radius: 1.0, uv_scale: 1.0 };
        let r = Ray::new(v3(0.0, 0.0, 0.0), v3(0.0, 0.0, 1.0));
        assert!((s.intersect(&r, f32::INFINITY).unwrap() - 4.0).abs() < 1e-5);
        let inside = Ray::new(v3(0.0, 0.0, 5.0), v3(0.0, 0.0, 1.0));
        assert!((s.intersect(&inside, f32::INFINITY).unwrap() - 1.0).abs() < 1e-5);
        let h = s.surface(v3(0.0, 0.0, 4.0));
        assert!((h.ng.z + 1.0).abs() < 1e-6);
        // dp/du and dp/dv are orthogonal, tangent, and of length 1/uv_scale at the equator.
        assert!(h.dpdu.dot(h.ng).abs() < 1e-6 && h.dpdv.dot(h.ng).abs() < 1e-6);
        assert!((h.dpdu.length() - 1.0).abs() < 1e-5 && (h.dpdv.length() - 1.0).abs() < 1e-5);
    }

    #[test]
    fn triangle_and_quad() {
        let m = Mesh {
            positions: vec![v3(0.0, 0.0, 0.0), v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0)],
            uvs: vec![[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]],
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        };
        let r = Ray::new(v3(0.25, 0.25, 1.0), v3(0.0, 0.0, -1.0));
        let (t, b1, b2) = m.intersect(0, &r, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        let h = m.surface(0, b1, b2);
        assert!((h.uv[0] - 0.5).abs() < 1e-6 && (h.uv[1] - 0.5).abs() < 1e-6);
        assert!((h.dpdu - v3(0.5, 0.0, 0.0)).length() < 1e-6);
        assert!((h.ng.z - 1.0).abs() < 1e-6);
        let q = Quad::centered(v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(1.0, 0.0, 0.0), 2.0, 4.0, 1.0);
        assert!((q.normal().y - 1.0).abs() < 1e-6);
        assert!((q.area() - 8.0).abs() < 1e-5);
        let r = Ray::new(v3(0.5, 3.0, 1.5), v3(0.0, -1.0, 0.0));
        let (t, a, b) = q.intersect(&r, f32::INFINITY).unwrap();
        assert!((t - 3.0).abs() < 1e-6);
        let h = q.surface(a, b);
        assert!((h.p - v3(0.5, 0.0, 1.5)).length() < 1e-5);
        assert!(q.intersect(&Ray::new(v3(1.5, 3.0, 0.0), v3(0.0, -1.0, 0.0)), f32::INFINITY).is_none());
    }
}
