//! Geometry basics in `f32`: vectors, rays, bounding boxes, orthonormal frames.

use lacquer::Vec3;

/// World-space vector (`f32`; the renderer's fast path).
pub type V3 = Vec3<f32>;

/// Builds a vector.
#[inline(always)]
#[must_use]
pub fn v3(x: f32, y: f32, z: f32) -> V3 {
    Vec3::new(x, y, z)
}

/// Builds a vector from an `[f64; 3]` (scene descriptions are parsed as `f64`).
#[inline]
#[must_use]
pub fn v3a(a: [f64; 3]) -> V3 {
    v3(a[0] as f32, a[1] as f32, a[2] as f32)
}

/// Component `i` (0 = x, 1 = y, 2 = z).
#[inline(always)]
#[must_use]
pub fn axis(v: V3, i: usize) -> f32 {
    match i {
        0 => v.x,
        1 => v.y,
        _ => v.z,
    }
}

/// Component-wise minimum.
#[inline(always)]
#[must_use]
pub fn vmin(a: V3, b: V3) -> V3 {
    v3(a.x.min(b.x), a.y.min(b.y), a.z.min(b.z))
}

/// Component-wise maximum.
#[inline(always)]
#[must_use]
pub fn vmax(a: V3, b: V3) -> V3 {
    v3(a.x.max(b.x), a.y.max(b.y), a.z.max(b.z))
}

/// A ray `o + t d`, `t ∈ (0, tmax)`; `d` need not be unit length for intersection, but the
/// renderer keeps it unit so that `t` is a distance.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Origin.
    pub o: V3,
    /// Direction.
    pub d: V3,
    /// Far end of the segment.
    pub tmax: f32,
}

impl Ray {
    /// A ray to infinity.
    #[inline]
    #[must_use]
    pub fn new(o: V3, d: V3) -> Self {
        Self { o, d, tmax: f32::INFINITY }
    }
    /// The point at distance `t`.
    #[inline(always)]
    #[must_use]
    pub fn at(&self, t: f32) -> V3 {
        self.d.scale_add(t, self.o)
    }
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    /// Lower corner.
    pub min: V3,
    /// Upper corner.
    pub max: V3,
}

impl Aabb {
    /// The empty box (grows from nothing).
    #[must_use]
    pub fn empty() -> Self {
        Self {
            min: v3(f32::INFINITY, f32::INFINITY, f32::INFINITY),
            max: v3(-f32::INFINITY, -f32::INFINITY, -f32::INFINITY),
        }
    }
    /// The box around one point.
    #[must_use]
    pub fn point(p: V3) -> Self {
        Self { min: p, max: p }
    }
    /// Grows to include `p`.
    #[inline]
    pub fn grow(&mut self, p: V3) {
        self.min = vmin(self.min, p);
        self.max = vmax(self.max, p);
    }
    /// Union of two boxes.
    #[inline]
    #[must_use]
    pub fn union(self, o: Self) -> Self {
        Self { min: vmin(self.min, o.min), max: vmax(self.max, o.max) }
    }
    /// Centre.
    #[inline]
    #[must_use]
    pub fn center(&self) -> V3 {
        (self.min + self.max) * 0.5
    }
    /// Half the surface area (the SAH only needs ratios); 0 for an empty box.
    #[inline]
    #[must_use]
    pub fn half_area(&self) -> f32 {
        let e = self.max - self.min;
        if e.x < 0.0 || e.y < 0.0 || e.z < 0.0 {
            return 0.0;
        }
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    /// True when the box contains no point.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    /// Slab test against a ray given its inverse direction; returns the entry distance.
    #[inline(always)]
    #[must_use]
    pub fn hit(&self, o: V3, inv_d: V3, tmax: f32) -> Option<f32> {
        let tx0 = (self.min.x - o.x) * inv_d.x;
        let tx1 = (self.max.x - o.x) * inv_d.x;
        let ty0 = (self.min.y - o.y) * inv_d.y;
        let ty1 = (self.max.y - o.y) * inv_d.y;
        let tz0 = (self.min.z - o.z) * inv_d.z;
        let tz1 = (self.max.z - o.z) * inv_d.z;
        let tmin = tx0.min(tx1).max(ty0.min(ty1)).max(tz0.min(tz1)).max(0.0);
        // Robust against rounding (Ize 2013): widen the far distance by 2 ulp-ish.
        let tfar = (tx0.max(tx1).min(ty0.max(ty1)).min(tz0.max(tz1)) * 1.000_000_2).min(tmax);
        (tmin <= tfar).then_some(tmin)
    }
}

/// An orthonormal frame: `s` (tangent), `t`, `n` (normal), world ↔ local.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Tangent (the material's anisotropy axis, x in the local frame).
    pub s: V3,
    /// Bitangent `n × s`.
    pub t: V3,
    /// Normal (z in the local frame).
    pub n: V3,
}

impl Frame {
    /// A frame around the unit normal `n` whose tangent is `tangent` projected into the
    /// tangent plane (any tangent when that projection degenerates).
    #[must_use]
    pub fn from_normal_tangent(n: V3, tangent: V3) -> Self {
        let s = tangent - n * n.dot(tangent);
        let l2 = s.length_squared();
        let s = if l2 > 1e-12 && l2.is_finite() {
            s / l2.sqrt()
        } else {
            let (s, _) = lacquer::frame::basis_around(n);
            s
        };
        Self { s, t: n.cross(s), n }
    }
    /// World → local.
    #[inline(always)]
    #[must_use]
    pub fn to_local(&self, v: V3) -> V3 {
        v3(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local → world.
    #[inline(always)]
    #[must_use]
    pub fn to_world(&self, v: V3) -> V3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Moves a ray origin off a surface along the geometric normal `ng`, to the side `w` points
/// to, by an offset proportional to the point's magnitude (float error grows with it).
#[inline]
#[must_use]
pub fn offset_origin(p: V3, ng: V3, w: V3) -> V3 {
    let scale = 1e-4 * (1.0 + p.x.abs().max(p.y.abs()).max(p.z.abs()));
    let off = if ng.dot(w) >= 0.0 { ng * scale } else { ng * -scale };
    p + off
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_round_trip() {
        let n = v3(0.3, 0.4, 0.5).normalize();
        let f = Frame::from_normal_tangent(n, v3(1.0, 0.0, 0.0));
        let v = v3(0.2, -0.7, 0.1);
        let back = f.to_world(f.to_local(v));
        assert!((back - v).length() < 1e-6);
        assert!((f.to_local(n).z - 1.0).abs() < 1e-6);
        assert!(f.s.dot(f.n).abs() < 1e-6 && f.t.dot(f.n).abs() < 1e-6);
    }

    #[test]
    fn aabb_slab() {
        let b = Aabb { min: v3(-1.0, -1.0, -1.0), max: v3(1.0, 1.0, 1.0) };
        let d = v3(0.0, 0.0, 1.0);
        let inv = v3(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        assert_eq!(b.hit(v3(0.0, 0.0, -3.0), inv, f32::INFINITY), Some(2.0));
        assert!(b.hit(v3(2.0, 0.0, -3.0), inv, f32::INFINITY).is_none());
        assert!(b.hit(v3(0.0, 0.0, -3.0), inv, 1.0).is_none());
    }
}
