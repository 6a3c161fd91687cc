//! A renderable scene: shapes in a BVH, materials, lights with a power-proportional light
//! selection distribution, and a camera. Build it with [`SceneBuilder`].

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::distrib::Distribution1D;
use crate::geom::{Aabb, Ray, V3};
use crate::lights::Light;
use crate::shapes::{Mesh, Quad, Sphere, SurfaceHit};
use crate::texture::PaintTextures;
use lacquer::lobes::{bits, LobeSelection};
use lacquer::Material;
use std::sync::Arc;

/// What a shape is made of: a material, or an area light's emitter, or both (an emitter
/// with no material is black apart from its emission).
#[derive(Clone, Copy, Debug, Default)]
struct ShapeRef {
    material: Option<u32>,
    light: Option<u32>,
    /// An emitter that is not a surface: rays pass through it (see [`SceneBuilder::light_no_surface`]).
    pass_through: bool,
    /// A rectangle of which only the inscribed ellipse exists (disk and ellipse lights).
    ellipse: bool,
}

#[derive(Clone, Copy, Debug)]
enum Prim {
    Triangle { mesh: u32, tri: u32 },
    Sphere(u32),
    Quad(u32),
}

/// A ray-surface intersection.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f32,
    /// Surface geometry.
    pub surf: SurfaceHit,
    /// True when the surface has texture coordinates (uv footprints are meaningful).
    pub has_uv: bool,
    /// Image-texture coordinates ([`crate::texture`]): a mesh's `texture_uvs`, else `surf.uv`.
    pub tex_uv: [f32; 2],
    /// Material index.
    pub material: Option<u32>,
    /// Index of the area light this surface belongs to.
    pub light: Option<u32>,
    /// The surface is an emitter that rays pass through (camera rays do not see it, shadow
    /// rays ignore it, other rays collect its emission and go on).
    pub pass_through: bool,
}

/// How a material shades a hit whose clearcoat has its own normal (a mesh's
/// [`crate::perturb::CoatNormal`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoatShading {
    /// Two frames: the lobes of `coat` (the clearcoat's top reflection) in the coat frame, those
    /// of `base` (everything under the coat) in the base frame.
    TwoFrames {
        /// The clearcoat's top reflection.
        coat: LobeSelection,
        /// The other lobes.
        base: LobeSelection,
    },
    /// One frame, the coat's: a paint with textured parameters (the per-element calls have no
    /// lobe selection), whose whole layer stack then follows the coat normal.
    CoatFrame,
    /// One frame, the base's: a material without a separable clearcoat reflection.
    BaseFrame,
}

impl CoatShading {
    /// What `m` (with textured parameters when `textured`) can do.
    #[must_use]
    pub fn of(m: &Material, textured: bool) -> Self {
        let has_coat = m.lobe_parts().iter().any(|p| p.select & bits::COAT != 0);
        if !has_coat || m.lobe_selection_weight(1.0, bits::COAT).is_none() {
            return Self::BaseFrame;
        }
        if textured {
            return Self::CoatFrame;
        }
        match (m.select_lobes(bits::COAT), m.select_lobes(bits::DIFFUSE | bits::GLOSSY)) {
            (Ok(coat), Ok(base)) => Self::TwoFrames { coat, base },
            _ => Self::CoatFrame,
        }
    }
}

/// Collects shapes, materials and lights.
#[derive(Default)]
pub struct SceneBuilder {
    materials: Vec<Material>,
    textures: Vec<Option<Arc<PaintTextures>>>,
    meshes: Vec<(Mesh, ShapeRef)>,
    spheres: Vec<(Sphere, ShapeRef)>,
    quads: Vec<(Quad, ShapeRef)>,
    lights: Vec<Light>,
}

impl SceneBuilder {
    /// An empty scene.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a material and returns its index.
    pub fn material(&mut self, m: Material) -> u32 {
        self.textured_material(m, None)
    }

    /// Adds a material whose parameters may be textured ([`crate::texture`]; `None`: plain)
    /// and returns its index.
    pub fn textured_material(&mut self, m: Material, textures: Option<Arc<PaintTextures>>) -> u32 {
        self.materials.push(m);
        self.textures.push(textures);
        (self.materials.len() - 1) as u32
    }

    /// Adds a triangle mesh made of material `m`.
    pub fn mesh(&mut self, mesh: Mesh, m: u32) -> &mut Self {
        self.meshes.push((mesh, ShapeRef { material: Some(m), light: None, pass_through: false, ellipse: false }));
        self
    }

    /// Adds a sphere made of material `m`.
    pub fn sphere(&mut self, s: Sphere, m: u32) -> &mut Self {
        self.spheres.push((s, ShapeRef { material: Some(m), light: None, pass_through: false, ellipse: false }));
        self
    }

    /// Adds a rectangle made of material `m`.
    pub fn quad(&mut self, q: Quad, m: u32) -> &mut Self {
        self.quads.push((q, ShapeRef { material: Some(m), light: None, pass_through: false, ellipse: false }));
        self
    }

    /// Adds a light; sphere and rectangle lights also become (black, emitting) geometry.
    pub fn light(&mut self, l: Light) -> &mut Self {
        self.add_light(l, false)
    }

    /// Adds a light whose emitter (sphere or rectangle) is not a surface, as lights are in
    /// Blender's Cycles: camera rays do not see it and pass through, it casts no shadows, and
    /// other rays that reach it collect its emission (with MIS) and continue behind it.
    pub fn light_no_surface(&mut self, l: Light) -> &mut Self {
        self.add_light(l, true)
    }

    fn add_light(&mut self, l: Light, pass_through: bool) -> &mut Self {
        let idx = self.lights.len() as u32;
        let r = ShapeRef { material: None, light: Some(idx), pass_through, ellipse: false };
        match &l {
            Light::Sphere { sphere, .. } => self.spheres.push((*sphere, r)),
            Light::Rect { quad, ellipse, .. } => self.quads.push((*quad, ShapeRef { ellipse: *ellipse, ..r })),
            _ => {}
        }
        self.lights.push(l);
        self
    }

    /// Number of lights added so far.
    #[must_use]
    pub fn light_count(&self) -> usize {
        self.lights.len()
    }

    /// Bounds of all geometry added so far.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::empty();
        for (m, _) in &self.meshes {
            b = b.union(m.bounds());
        }
        for (s, _) in &self.spheres {
            b = b.union(s.bounds());
        }
        for (q, _) in &self.quads {
            b = b.union(q.bounds());
        }
        b
    }

    /// Builds the BVH and the light selection distribution.
    #[must_use]
    pub fn build(self, camera: Camera) -> Scene {
        let mut prims = Vec::new();
        let mut boxes = Vec::new();
        for (mi, (m, _)) in self.meshes.iter().enumerate() {
            for t in 0..m.triangles.len() {
                prims.push(Prim::Triangle { mesh: mi as u32, tri: t as u32 });
                boxes.push(m.triangle_bounds(t));
            }
        }
        for (si, (s, _)) in self.spheres.iter().enumerate() {
            prims.push(Prim::Sphere(si as u32));
            boxes.push(s.bounds());
        }
        for (qi, (q, _)) in self.quads.iter().enumerate() {
            prims.push(Prim::Quad(qi as u32));
            boxes.push(q.bounds());
        }
        let bvh = Bvh::build(&boxes);
        let bounds = bvh.bounds();
        let radius = if bounds.is_empty() { 1.0 } else { (0.5 * (bounds.max - bounds.min).length()).max(1e-3) };
        let powers: Vec<f32> = self.lights.iter().map(|l| l.power(radius)).collect();
        let light_dist = Distribution1D::new(&powers);
        let infinite_lights =
            (0..self.lights.len() as u32).filter(|&i| self.lights[i as usize].is_infinite_area()).collect();
        let (meshes, mesh_refs) = self.meshes.into_iter().unzip();
        let (spheres, sphere_refs) = self.spheres.into_iter().unzip();
        let (quads, quad_refs) = self.quads.into_iter().unzip();
        let coat_shading =
            self.materials.iter().zip(&self.textures).map(|(m, t)| CoatShading::of(m, t.is_some())).collect();
        Scene {
            camera,
            coat_shading,
            materials: self.materials,
            textures: self.textures,
            meshes,
            mesh_refs,
            spheres,
            sphere_refs,
            quads,
            quad_refs,
            prims,
            bvh,
            lights: self.lights,
            light_dist,
            infinite_lights,
            bounds,
        }
    }
}

/// A scene ready to render. Immutable and `Sync`.
pub struct Scene {
    /// The camera (its size is the image size).
    pub camera: Camera,
    /// Materials, indexed by shapes.
    pub materials: Vec<Material>,
    /// Textured parameters per material (`None`: the material is uniform).
    pub textures: Vec<Option<Arc<PaintTextures>>>,
    /// Per material: how it shades hits whose clearcoat has its own normal.
    pub coat_shading: Vec<CoatShading>,
    meshes: Vec<Mesh>,
    mesh_refs: Vec<ShapeRef>,
    spheres: Vec<Sphere>,
    sphere_refs: Vec<ShapeRef>,
    quads: Vec<Quad>,
    quad_refs: Vec<ShapeRef>,
    prims: Vec<Prim>,
    bvh: Bvh,
    /// Lights.
    pub lights: Vec<Light>,
    light_dist: Distribution1D,
    infinite_lights: Vec<u32>,
    bounds: Aabb,
}

impl Scene {
    /// Bounds of the geometry.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of primitives (triangles, spheres, rectangles).
    #[must_use]
    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    /// Picks a light with probability proportional to its power: `(index, probability)`.
    #[inline]
    #[must_use]
    pub fn pick_light(&self, u: f32) -> Option<(usize, f32)> {
        if self.lights.is_empty() {
            return None;
        }
        let (i, p) = self.light_dist.sample_discrete(u);
        (p > 0.0).then_some((i, p))
    }

    /// Probability that [`Scene::pick_light`] picks light `i`.
    #[inline]
    #[must_use]
    pub fn light_probability(&self, i: usize) -> f32 {
        if self.lights.is_empty() {
            0.0
        } else {
            self.light_dist.probability(i)
        }
    }

    /// Lights at infinity that rays leaving the scene can see.
    #[must_use]
    pub fn infinite_lights(&self) -> &[u32] {
        &self.infinite_lights
    }

    #[inline(always)]
    fn test(&self, p: u32, ray: &Ray, tmax: f32) -> Option<(f32, f32, f32)> {
        match self.prims[p as usize] {
            Prim::Triangle { mesh, tri } => self.meshes[mesh as usize].intersect(tri as usize, ray, tmax),
            Prim::Sphere(s) => self.spheres[s as usize].intersect(ray, tmax).map(|t| (t, 0.0, 0.0)),
            Prim::Quad(q) => {
                let h = self.quads[q as usize].intersect(ray, tmax)?;
                (!self.quad_refs[q as usize].ellipse || crate::lights::in_ellipse(h.1, h.2)).then_some(h)
            }
        }
    }

    /// The nearest intersection along `ray` (within `ray.tmax`).
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut r = *ray;
        let mut best: Option<(u32, f32, f32)> = None;
        self.bvh.traverse(&mut r, false, |p, tmax| {
            let (t, a, b) = self.test(p, ray, tmax)?;
            best = Some((p, a, b));
            Some(t)
        });
        let (p, a, b) = best?;
        let t = r.tmax;
        let (surf, shape, has_uv, tex_uv) = match self.prims[p as usize] {
            Prim::Triangle { mesh, tri } => {
                let m = &self.meshes[mesh as usize];
                let surf = m.surface(tri as usize, a, b);
                (surf, self.mesh_refs[mesh as usize], !m.uvs.is_empty(), m.texture_uv(tri as usize, a, b))
            }
            Prim::Sphere(s) => {
                let surf = self.spheres[s as usize].surface(ray.at(t));
                (surf, self.sphere_refs[s as usize], true, surf.uv)
            }
            Prim::Quad(q) => {
                let surf = self.quads[q as usize].surface(a, b);
                (surf, self.quad_refs[q as usize], true, surf.uv)
            }
        };
        Some(Hit {
            t,
            surf,
            has_uv,
            tex_uv,
            material: shape.material,
            light: shape.light,
            pass_through: shape.pass_through,
        })
    }

    fn passes_through(&self, p: u32) -> bool {
        match self.prims[p as usize] {
            Prim::Triangle { .. } => false,
            Prim::Sphere(s) => self.sphere_refs[s as usize].pass_through,
            Prim::Quad(q) => self.quad_refs[q as usize].pass_through,
        }
    }

    /// True when anything blocks `ray` before `ray.tmax` (emitters that are not surfaces do not).
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut r = *ray;
        self.bvh.traverse(&mut r, true, |p, tmax| {
            if self.passes_through(p) {
                return None;
            }
            self.test(p, ray, tmax).map(|h| h.0)
        })
    }

    /// The point on the image a world point projects to (tests, sheet labels).
    #[must_use]
    pub fn project(&self, p: V3) -> Option<(f32, f32)> {
        self.camera.project(p)
    }
}
