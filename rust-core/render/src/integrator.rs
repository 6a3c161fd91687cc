//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (power heuristic, Veach 1997) between light sampling and the material's own
//! `sample`/`pdf`; Russian roulette after a few bounces; a direct-lighting-only mode
//! (`max_depth = 1`). Delta material lobes (the smooth clearcoat's mirror) and delta lights
//! take no MIS: each can only be reached by one of the two strategies.
//!
//! The image is cut into tiles rendered in parallel (rayon). Within a tile, shading is
//! wavefront-style: the paths of all the tile's pixels (one sample index at a time) advance to
//! their next vertex, then each material shades all its vertices with two batch calls through
//! the SIMD kernels (`lacquer::batch`; sparkle through the surface-point calls), then the
//! paths continue. Every pixel owns a random stream derived from the seed and its index, drawn
//! in the same order as a path traced alone, so a render is deterministic for a seed whatever
//! the number of threads, the tile order or the split into progressive rounds.

use crate::camera::CameraRay;
use crate::geom::{offset_origin, Frame, Ray, V3};
use crate::scene::{CoatShading, Hit, Scene};
use crate::texture::{PaintTextures, Texels};
use lacquer::batch::{self, Dst1, Dst3, SampleOut, Src3};
use lacquer::lobes::{bits, LobeSelection};
use lacquer::paint::varying::PaintTexture;
use lacquer::rng::Pcg32;
use lacquer::{BsdfSample, Material, Rgb, SurfacePoint};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

type C = Rgb<f32>;

/// How to render.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Samples (camera paths) per pixel.
    pub spp: u32,
    /// Maximum number of surface interactions that scatter light (1 = direct lighting only).
    pub max_depth: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Tile edge in pixels.
    pub tile_size: u32,
    /// Worker threads (0 = rayon's default, one per core).
    pub threads: usize,
    /// Also produce albedo and normal layers.
    pub aovs: bool,
    /// Also produce the Diffuse Color and Glossy Color layers ([`Framebuffer::diffuse_color`]).
    pub lobe_aovs: bool,
    /// Give camera-ray hits their pixel footprint (`eval_at`/`sample_at`: sparkle).
    pub footprints: bool,
    /// Depth from which Russian roulette may end paths.
    pub rr_depth: u32,
    /// Clamp of each path's contribution (0 = off; a clamp biases the image).
    pub clamp: f32,
    /// Jitter camera rays over the pixel (box filter); without, every ray goes through the
    /// pixel centre (analytic tests).
    pub jitter: bool,
    /// Camera rays that miss every surface see nothing (black, alpha 0) instead of the
    /// environment: a transparent film, for compositing.
    pub transparent: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            spp: 64,
            max_depth: 8,
            seed: 0,
            tile_size: 32,
            threads: 0,
            aovs: true,
            lobe_aovs: false,
            footprints: true,
            rr_depth: 3,
            clamp: 0.0,
            jitter: true,
            transparent: false,
        }
    }
}

/// A rendered image: linear RGB, alpha (1 where a camera ray hit geometry) and optional
/// first-hit layers. Rows top to bottom.
#[derive(Clone, Debug)]
pub struct Framebuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear Rec.709 radiance per pixel.
    pub color: Vec<[f32; 3]>,
    /// Coverage.
    pub alpha: Vec<f32>,
    /// Directional albedo of the first surface (mean BSDF sample weight), if requested.
    pub albedo: Option<Vec<[f32; 3]>>,
    /// World-space shading normal of the first surface, if requested.
    pub normal: Option<Vec<[f32; 3]>>,
    /// Diffuse Color (as Cycles' pass): the directional albedo of the first surface's diffuse
    /// lobe group (lobe mask `DIFFUSE`: pigment and multiple scattering), estimated by one
    /// `sample_lobes` weight per camera sample, if requested ([`RenderSettings::lobe_aovs`]).
    pub diffuse_color: Option<Vec<[f32; 3]>>,
    /// Glossy Color: the same for the glossy groups (`GLOSSY | COAT`: flakes, metallic base,
    /// the clearcoat's reflection).
    pub glossy_color: Option<Vec<[f32; 3]>>,
    /// How the render went.
    pub stats: RenderStats,
}

/// Timing and sample counts of a render.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    /// Wall-clock seconds spent tracing (scene building excluded).
    pub seconds: f64,
    /// Camera paths traced.
    pub paths: u64,
    /// Paths whose value was not finite (dropped; should be 0).
    pub invalid: u64,
    /// Paths per second.
    pub paths_per_second: f64,
}

impl Framebuffer {
    /// A black image.
    #[must_use]
    pub fn new(width: u32, height: u32, aovs: bool) -> Self {
        let n = (width * height) as usize;
        Self {
            width,
            height,
            color: vec![[0.0; 3]; n],
            alpha: vec![0.0; n],
            albedo: aovs.then(|| vec![[0.0; 3]; n]),
            normal: aovs.then(|| vec![[0.0; 3]; n]),
            diffuse_color: None,
            glossy_color: None,
            stats: RenderStats::default(),
        }
    }

    /// Mean of the colour channels over all pixels.
    #[must_use]
    pub fn mean(&self) -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for p in &self.color {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
        s.map(|v| v / self.color.len().max(1) as f64)
    }
}

/// The render was cancelled by the progress callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("render cancelled")
    }
}

impl std::error::Error for Cancelled {}

/// Per-pixel random numbers (PCG32 in `f32`).
#[derive(Clone)]
struct Sampler(Pcg32);

impl Sampler {
    #[inline(always)]
    fn next(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
    #[inline(always)]
    fn next2(&mut self) -> [f32; 2] {
        [self.next(), self.next()]
    }
    #[inline(always)]
    fn next3(&mut self) -> [f32; 3] {
        [self.next(), self.next(), self.next()]
    }
}

/// The power heuristic with β = 2.
#[inline(always)]
fn power_heuristic(a: f32, b: f32) -> f32 {
    if a.is_infinite() {
        return 1.0;
    }
    let (a2, b2) = (a * a, b * b);
    if !(a2 + b2 > 0.0) {
        return 0.0;
    }
    let w = a2 / (a2 + b2);
    if w.is_finite() {
        w
    } else {
        1.0
    }
}

/// What one camera path returns.
struct PathValue {
    radiance: C,
    alpha: f32,
    albedo: C,
    normal: V3,
    /// Diffuse and glossy colour of the first hit ([`RenderSettings::lobe_aovs`]).
    lobe_colors: [C; 2],
}

/// The uv footprint of a camera ray's pixel, for its hit (pbrt's approach: intersect the
/// differential rays with the hit's tangent plane, then solve for ∂uv/∂x, ∂uv/∂y in least
/// squares). The footprint is the pixel's, not the sample's: it is centred where the pixel
/// centre's ray meets the tangent plane (uv moved there to first order; exactly on planes), so
/// all samples of a pixel on one surface share one footprint and the sparkle counts of one
/// set of grid cells (issue 17).
fn footprint(cr: &CameraRay, hit: &Hit) -> Option<SurfacePoint> {
    if !hit.has_uv {
        return None;
    }
    let s = &hit.surf;
    let n = s.ng;
    let plane = n.dot(s.p - cr.ray.o);
    // Where direction `d` from the eye meets the tangent plane, relative to the hit point.
    let offset = |d: V3| -> Option<V3> {
        let nd = n.dot(d);
        if nd.abs() < 1e-8 {
            return None;
        }
        let t = plane / nd;
        (t > 0.0).then(|| cr.ray.o + d * t - s.p)
    };
    let centre = offset(cr.centre)?;
    let (dpdx, dpdy) = (offset(cr.dx)? - centre, offset(cr.dy)? - centre);
    let (a, b, c) = (s.dpdu.dot(s.dpdu), s.dpdu.dot(s.dpdv), s.dpdv.dot(s.dpdv));
    let det = a * c - b * b;
    if !(det.abs() > 1e-20) {
        return None;
    }
    let solve = |d: V3| -> [f64; 2] {
        let (bu, bv) = (s.dpdu.dot(d), s.dpdv.dot(d));
        [((c * bu - b * bv) / det) as f64, ((a * bv - b * bu) / det) as f64]
    };
    let du = solve(centre);
    let uv = [s.uv[0] as f64 + du[0], s.uv[1] as f64 + du[1]];
    let sp = SurfacePoint { uv, duv_dx: solve(dpdx), duv_dy: solve(dpdy) };
    sp.is_finite().then_some(sp)
}

/// A camera path in flight: what the one-path loop kept in local variables.
struct Path {
    /// The camera ray (its differentials give the first hit's footprint).
    cr: CameraRay,
    ray: Ray,
    beta: C,
    /// The previous vertex's sampling: camera rays and delta lobes count emission in full.
    prev_delta: bool,
    prev_pdf: f32,
    prev_p: V3,
    depth: u32,
    /// Distance travelled since the last scattering vertex through emitters that are not
    /// surfaces (for the solid-angle density of what lies behind them), and how many.
    passed: f32,
    passes: u32,
    value: PathValue,
}

impl Path {
    fn new(cr: CameraRay) -> Self {
        Self {
            ray: cr.ray,
            cr,
            beta: C::splat(1.0),
            prev_delta: true,
            prev_pdf: 0.0,
            prev_p: cr.ray.o,
            depth: 0,
            passed: 0.0,
            passes: 0,
            value: PathValue {
                radiance: C::zero(),
                alpha: 0.0,
                albedo: C::zero(),
                normal: V3::zero(),
                lobe_colors: [C::zero(); 2],
            },
        }
    }

    /// Adds emission seen along the path, MIS-weighted against the light sampling of the
    /// previous vertex.
    fn add_emission(&mut self, scene: &Scene, li: u32, le: C, dist: f32) {
        let w = if self.prev_delta {
            1.0
        } else {
            let pl =
                scene.light_probability(li as usize) * scene.lights[li as usize].pdf(self.prev_p, self.ray.d, dist);
            power_heuristic(self.prev_pdf, pl)
        };
        self.value.radiance += self.beta * le * w;
    }
}

/// The light sample of a vertex's next-event estimation, where it can contribute.
struct LightVisit {
    /// Toward the light, world and local.
    wi_world: V3,
    wi: V3,
    li: C,
    /// Light selection probability × the light's density.
    pl: f32,
    delta: bool,
    dist: f32,
}

/// A path vertex waiting for its material, with the random numbers its shading uses (drawn
/// in the order the one-path loop drew them, so every pixel's stream is consumed alike).
struct Vertex {
    path: u32,
    material: u32,
    frame: Frame,
    /// The clearcoat's own frame, when the paint is shaded in two frames (`frame` is then the
    /// base's; see [`shade_two_frames`]).
    coat_frame: Option<Frame>,
    ng: V3,
    p: V3,
    wo: V3,
    at: Option<SurfacePoint>,
    light: Option<LightVisit>,
    u: [f32; 3],
    /// The material's textured parameters at the hit ([`crate::texture`]), if it has any.
    texels: Option<Texels>,
    /// A camera hit whose Diffuse/Glossy Color is wanted.
    lobe_aov: bool,
}

/// What the material returned for a vertex.
#[derive(Clone, Copy)]
struct Shaded {
    /// `f(wi_light, wo)` and the material's density there (next-event estimation).
    f_light: C,
    pdf_light: f32,
    sample: Option<BsdfSample<f32>>,
    /// `f_light` already holds `f · cos θ` (two frames: each part with its own cosine).
    f_cos: bool,
}

impl Default for Shaded {
    fn default() -> Self {
        Self { f_light: C::zero(), pdf_light: 0.0, sample: None, f_cos: false }
    }
}

/// The lobe masks of the Diffuse Color and Glossy Color layers for a material: `DIFFUSE` and
/// `GLOSSY | COAT` when it separates them; otherwise everything in the layer of its kind
/// (a diffuse-only model in Diffuse Color, any other in Glossy Color).
fn lobe_color_selections(m: &Material) -> [LobeSelection; 2] {
    match (m.select_lobes(bits::DIFFUSE), m.select_lobes(bits::GLOSSY | bits::COAT)) {
        (Ok(d), Ok(g)) => [d, g],
        _ if m.lobes() & (bits::GLOSSY | bits::DELTA) == 0 => [LobeSelection::All, LobeSelection::Nothing],
        _ => [LobeSelection::Nothing, LobeSelection::All],
    }
}

/// One estimate of the Diffuse Color and Glossy Color of a camera hit: each lobe group's
/// sampled weight (`f·cos/pdf` of the group alone; its mean over samples is the group's
/// directional albedo at `wo`), drawn with the vertex's own numbers (no random stream is
/// consumed) in the base frame.
fn lobe_colors(m: &Material, v: &Vertex) -> [C; 2] {
    let mean = SurfacePoint { uv: [f64::NAN; 2], ..SurfacePoint::default() };
    let at = v.at.unwrap_or(mean);
    lobe_color_selections(m).map(|sel| match sel {
        LobeSelection::Nothing => C::zero(),
        sel => m.sample_at_lobes(v.wo, v.u, &at, sel).map_or(C::zero(), |s| s.weight),
    })
}

/// Moves a path to its next vertex that needs the material (`None`: the path ended),
/// collecting emission on the way.
fn advance(scene: &Scene, set: &RenderSettings, path: &mut Path, rng: &mut Sampler) -> Option<Vertex> {
    loop {
        let Some(hit) = scene.intersect(&path.ray) else {
            if !(path.depth == 0 && set.transparent) {
                for &li in scene.infinite_lights() {
                    let le = scene.lights[li as usize].escaped(path.ray.d);
                    if !le.is_black() {
                        path.add_emission(scene, li, le, f32::INFINITY);
                    }
                }
            }
            return None;
        };
        if hit.pass_through {
            // An emitter that is not a surface: camera rays do not see it; other rays collect
            // its emission and go on behind it.
            if let (Some(li), true) = (hit.light, path.depth > 0) {
                let le = scene.lights[li as usize].emitted(hit.surf.ng, path.ray.d);
                if !le.is_black() {
                    path.add_emission(scene, li, le, path.passed + hit.t);
                }
            }
            path.passes += 1;
            if path.passes > 64 {
                return None;
            }
            path.passed += hit.t;
            path.ray = Ray::new(offset_origin(hit.surf.p, hit.surf.ng, path.ray.d), path.ray.d);
            continue;
        }
        if path.depth == 0 {
            path.value.alpha = 1.0;
        }
        // Emission of area lights.
        if let Some(li) = hit.light {
            let le = scene.lights[li as usize].emitted(hit.surf.ng, path.ray.d);
            if !le.is_black() {
                path.add_emission(scene, li, le, path.passed + hit.t);
            }
        }
        if path.depth >= set.max_depth {
            return None;
        }
        let material = hit.material?;
        let texels = scene.textures[material as usize].as_ref().map(|t| t.lookup(hit.tex_uv));

        // Two-sided surfaces: turn the normals toward the viewer.
        let wo_world = -path.ray.d;
        let (mut ng, mut ns, mut coat_ns) = (hit.surf.ng, hit.surf.ns, hit.surf.coat_ns);
        if ng.dot(wo_world) < 0.0 {
            ng = -ng;
            ns = -ns;
            coat_ns = coat_ns.map(|n| -n);
        }
        if ns.dot(wo_world) <= 0.0 {
            ns = ng;
        }
        // The clearcoat's own normal (facing the viewer as `ns`): a second frame, or the only
        // one for materials that cannot split their lobes ([`CoatShading`]).
        let coat_ns = coat_ns.map(|n| if n.dot(wo_world) <= 0.0 { ng } else { n }).filter(|&n| n != ns);
        let mut coat_frame = None;
        let mut frame = Frame::from_normal_tangent(ns, hit.surf.dpdu);
        if let Some(n) = coat_ns {
            match scene.coat_shading[material as usize] {
                CoatShading::TwoFrames { .. } => coat_frame = Some(Frame::from_normal_tangent(n, hit.surf.dpdu)),
                CoatShading::CoatFrame => frame = Frame::from_normal_tangent(n, hit.surf.dpdu),
                CoatShading::BaseFrame => {}
            }
        }
        let at = if path.depth == 0 && set.footprints { footprint(&path.cr, &hit) } else { None };
        if path.depth == 0 && set.aovs {
            path.value.normal = ns;
        }
        let p = hit.surf.p;

        // Next-event estimation: one light, chosen by power.
        let u_pick = rng.next();
        let u_light = rng.next2();
        let light = scene.pick_light(u_pick).and_then(|(li, p_pick)| {
            let ls = scene.lights[li].sample(p, u_light)?;
            (ls.wi.dot(ng) > 0.0 && ls.pdf > 0.0 && !ls.li.is_black()).then(|| LightVisit {
                wi_world: ls.wi,
                wi: frame.to_local(ls.wi),
                li: ls.li,
                pl: p_pick * ls.pdf,
                delta: ls.delta,
                dist: ls.dist,
            })
        });
        let u = rng.next3();
        let wo = frame.to_local(wo_world);
        let lobe_aov = path.depth == 0 && set.lobe_aovs;
        return Some(Vertex { path: 0, material, frame, coat_frame, ng, p, wo, at, light, u, texels, lobe_aov });
    }
}

/// Adds the vertex's light sample and continues the path with the material's sample;
/// `false` when the path ends here.
fn finish(scene: &Scene, set: &RenderSettings, path: &mut Path, v: &Vertex, s: &Shaded, rng: &mut Sampler) -> bool {
    if v.lobe_aov {
        path.value.lobe_colors = lobe_colors(&scene.materials[v.material as usize], v);
    }
    if let Some(l) = &v.light {
        let cos = if s.f_cos { 1.0 } else { l.wi.z };
        if cos > 0.0 && !s.f_light.is_black() {
            let o = offset_origin(v.p, v.ng, l.wi_world);
            let tmax = if l.dist.is_finite() { l.dist * (1.0 - 1e-3) } else { f32::INFINITY };
            if !scene.occluded(&Ray { o, d: l.wi_world, tmax }) {
                let w = if l.delta { 1.0 } else { power_heuristic(l.pl, s.pdf_light) };
                path.value.radiance += path.beta * s.f_light * l.li * (cos * w / l.pl);
            }
        }
    }
    let Some(bs) = s.sample else { return false };
    if path.depth == 0 && set.aovs {
        path.value.albedo = bs.weight;
    }
    let wi_world = v.frame.to_world(bs.wi);
    if wi_world.dot(v.ng) <= 0.0 {
        return false;
    }
    path.beta = path.beta * bs.weight;
    path.prev_delta = bs.delta;
    path.prev_pdf = bs.pdf;
    path.prev_p = v.p;
    path.ray = Ray::new(offset_origin(v.p, v.ng, wi_world), wi_world);
    path.passed = 0.0;
    path.depth += 1;
    if path.depth >= set.rr_depth {
        let q = path.beta.max_channel();
        if q < 1.0 {
            let q = q.max(0.05);
            if rng.next() >= q {
                return false;
            }
            path.beta = path.beta / q;
        }
    }
    true
}

/// Structure-of-arrays staging of one material's vertices for the batch calls.
#[derive(Default)]
struct ShadeBuffers {
    wo: [Vec<f32>; 3],
    wi_light: [Vec<f32>; 3],
    u: [Vec<f32>; 3],
    f: [Vec<f32>; 3],
    pdf: Vec<f32>,
    wi: [Vec<f32>; 3],
    weight: [Vec<f32>; 3],
    sample_pdf: Vec<f32>,
    flags: Vec<u32>,
    eval_active: Vec<u8>,
    at: Vec<SurfacePoint>,
    /// Textured parameters per vertex: red, green, blue, flake density, coat roughness.
    tex: [Vec<f32>; 5],
    /// The vertices of a group shaded in one frame (when others have a coat frame).
    one_frame: Vec<u32>,
}

impl ShadeBuffers {
    fn resize(&mut self, n: usize) {
        for v in self.wo.iter_mut().chain(&mut self.wi_light).chain(&mut self.u).chain(&mut self.f) {
            v.resize(n, 0.0);
        }
        for v in self.wi.iter_mut().chain(&mut self.weight) {
            v.resize(n, 0.0);
        }
        self.pdf.resize(n, 0.0);
        self.sample_pdf.resize(n, 0.0);
        self.flags.resize(n, 0);
        self.eval_active.resize(n, 0);
        for v in &mut self.tex {
            v.resize(n, 0.0);
        }
    }
}

fn src3(v: &[Vec<f32>; 3]) -> Src3<'_, f32> {
    Src3::soa(&v[0], &v[1], &v[2]).expect("staging arrays have equal lengths")
}

fn dst3(v: &mut [Vec<f32>; 3]) -> Dst3<'_, f32> {
    let [x, y, z] = v;
    Dst3::soa(x, y, z).expect("staging arrays have equal lengths")
}

/// Shades the vertices `group` (indices into `vertices`, all of material `mat`) with two batch
/// calls through the SIMD kernels: the light samples' `f` and density, then the material's
/// samples. Camera-ray hits carry their footprint, so a spatially varying material (sparkle)
/// gets `eval_at`/`sample_at` values: the batch calls at surface points scale the flake lobes
/// per element. A material with textured parameters (`textures`) is shaded through the
/// per-element calls instead (`batch::eval_pdf_varying`, `sample_varying`: the mean lobe, no
/// sparkle) with each vertex's texel values.
fn shade_group(
    mat: &Material,
    textures: Option<&PaintTextures>,
    coat: CoatShading,
    vertices: &[Vertex],
    group: &[u32],
    buf: &mut ShadeBuffers,
    out: &mut [Shaded],
) {
    // Vertices with a coat frame are shaded one by one in two frames, the others in batches.
    if let CoatShading::TwoFrames { coat, base } = coat {
        if group.iter().any(|&vi| vertices[vi as usize].coat_frame.is_some()) {
            let mut one = std::mem::take(&mut buf.one_frame);
            one.clear();
            for &vi in group {
                let v = &vertices[vi as usize];
                match v.coat_frame {
                    Some(cf) => out[vi as usize] = shade_two_frames(mat, coat, base, v, cf),
                    None => one.push(vi),
                }
            }
            if !one.is_empty() {
                shade_batch(mat, textures, vertices, &one, buf, out);
            }
            buf.one_frame = one;
            return;
        }
    }
    shade_batch(mat, textures, vertices, group, buf, out);
}

/// The batch calls of [`shade_group`] for vertices shaded in one frame.
fn shade_batch(
    mat: &Material,
    textures: Option<&PaintTextures>,
    vertices: &[Vertex],
    group: &[u32],
    buf: &mut ShadeBuffers,
    out: &mut [Shaded],
) {
    let n = group.len();
    buf.resize(n);
    // No footprint: the mean BRDF (a non-finite surface point means exactly that).
    let mean = SurfacePoint { uv: [f64::NAN; 2], ..SurfacePoint::default() };
    buf.at.clear();
    for (k, &vi) in group.iter().enumerate() {
        let v = &vertices[vi as usize];
        let wi = v.light.as_ref().map_or(V3::zero(), |l| l.wi);
        for (c, (o, i)) in [(v.wo.x, wi.x), (v.wo.y, wi.y), (v.wo.z, wi.z)].into_iter().enumerate() {
            buf.wo[c][k] = o;
            buf.wi_light[c][k] = i;
            buf.u[c][k] = v.u[c];
        }
        buf.eval_active[k] = u8::from(v.light.is_some());
        buf.at.push(v.at.unwrap_or(mean));
        if let Some(t) = &v.texels {
            for (c, x) in t.iter().enumerate() {
                buf.tex[c][k] = *x;
            }
        }
    }
    match textures {
        Some(t) => shade_varying(mat, t, buf, n),
        None => shade_plain(mat, buf),
    }
    for (k, &vi) in group.iter().enumerate() {
        let s = &mut out[vi as usize];
        if vertices[vi as usize].light.is_some() {
            s.f_light = C::new(buf.f[0][k], buf.f[1][k], buf.f[2][k]);
            s.pdf_light = buf.pdf[k];
        }
        let flags = buf.flags[k];
        s.sample = (flags & (batch::SAMPLE_FAILED | batch::SAMPLE_INVALID_INPUT) == 0).then(|| BsdfSample {
            wi: V3::new(buf.wi[0][k], buf.wi[1][k], buf.wi[2][k]),
            weight: C::new(buf.weight[0][k], buf.weight[1][k], buf.weight[2][k]),
            pdf: buf.sample_pdf[k],
            delta: flags & batch::SAMPLE_DELTA != 0,
        });
    }
}

/// A paint shaded in two frames (the clearcoat's own normal, as Cycles' Coat Normal): the lobes
/// of `coat` (the top reflection) in the coat frame `cf`, those of `base` in the base frame
/// `v.frame`. The value is the sum of the two parts, each with its own cosine:
/// `f·cos = f_coat(wi_c, wo_c) cos θ_c + f_base(wi_b, wo_b) cos θ_b`. Sampling picks the coat
/// part with probability `P_c = w_c / (w_c + w_b)` (the core's own lobe-selection weights of
/// the two groups, [`Material::lobe_selection_weight`], each at its frame's `cos θo`: with equal
/// frames exactly the core's selection) and samples it in its frame; the density is the
/// mixture `P_c p_coat(wi_c) + (1 − P_c) p_base(wi_b)`, which light sampling's MIS weights use
/// too, so next-event estimation and MIS stay unbiased. A delta coat sample (smooth coat) has
/// the probability `P_c` and the weight `F / P_c`. The sample's direction is returned in the
/// base frame, `f_light` as `f · cos` ([`Shaded::f_cos`]).
fn shade_two_frames(mat: &Material, coat: LobeSelection, base: LobeSelection, v: &Vertex, cf: Frame) -> Shaded {
    let bf = v.frame;
    let wo_b = v.wo;
    let wo_c = cf.to_local(bf.to_world(wo_b));
    let mean = SurfacePoint { uv: [f64::NAN; 2], ..SurfacePoint::default() };
    let at = v.at.unwrap_or(mean);
    let weight = |cos: f32, mask: u32| mat.lobe_selection_weight(f64::from(cos), mask).unwrap_or(0.0).max(0.0);
    let (w_c, w_b) = (weight(wo_c.z, bits::COAT), weight(wo_b.z, bits::DIFFUSE | bits::GLOSSY));
    let p_c = if w_c + w_b > 0.0 { (w_c / (w_c + w_b)) as f32 } else { 0.0 };
    let value = |wi_world: V3| -> (C, f32) {
        let (wi_c, wi_b) = (cf.to_local(wi_world), bf.to_local(wi_world));
        let f = mat.eval_at_lobes(wi_c, wo_c, &at, coat) * wi_c.z.max(0.0)
            + mat.eval_at_lobes(wi_b, wo_b, &at, base) * wi_b.z.max(0.0);
        let pdf = p_c * mat.pdf_lobes(wi_c, wo_c, coat) + (1.0 - p_c) * mat.pdf_lobes(wi_b, wo_b, base);
        (f, pdf)
    };
    let mut out = Shaded { f_cos: true, ..Shaded::default() };
    if let Some(l) = &v.light {
        (out.f_light, out.pdf_light) = value(l.wi_world);
    }
    let [u0, u1, u2] = v.u;
    let one_minus = 1.0 - f32::EPSILON / 2.0;
    let (frame, wo, sel, p, u0) = if u0 < p_c {
        (cf, wo_c, coat, p_c, (u0 / p_c).min(one_minus))
    } else {
        (bf, wo_b, base, 1.0 - p_c, ((u0 - p_c) / (1.0 - p_c)).min(one_minus))
    };
    out.sample = mat.sample_at_lobes(wo, [u0, u1, u2], &at, sel).and_then(|s| {
        let wi_world = frame.to_world(s.wi);
        let wi = bf.to_local(wi_world);
        if s.delta {
            return Some(BsdfSample { wi, weight: s.weight / p, pdf: s.pdf * p, delta: true });
        }
        let (f, pdf) = value(wi_world);
        (pdf > 0.0 && pdf.is_finite()).then(|| BsdfSample { wi, weight: f / pdf, pdf, delta: false })
    });
    out
}

/// The batch calls of an untextured material at the staged surface points (sparkle).
fn shade_plain(mat: &Material, buf: &mut ShadeBuffers) {
    // The views are built from arrays of one length, so the calls cannot fail.
    {
        let (wo, wi) = (src3(&buf.wo), src3(&buf.wi_light));
        let f = dst3(&mut buf.f);
        let pdf = Dst1::new(&mut buf.pdf);
        let _ = batch::eval_pdf_at(mat, &wi, &wo, &buf.at, Some(&buf.eval_active), Some(&f), Some(&pdf));
    }
    let (wo, u) = (src3(&buf.wo), src3(&buf.u));
    let mut so = SampleOut {
        wi: dst3(&mut buf.wi),
        weight: dst3(&mut buf.weight),
        pdf: Dst1::new(&mut buf.sample_pdf),
        flags: Some(&mut buf.flags),
    };
    let _ = batch::sample_at(mat, &wo, &u, &buf.at, None, &mut so);
}

/// The per-element batch calls of a material with textured parameters (`n` vertices staged).
fn shade_varying(mat: &Material, t: &PaintTextures, buf: &mut ShadeBuffers, n: usize) {
    let [r, g, b, density, rough] = &buf.tex;
    let tex = PaintTexture {
        base_color: t.base_color.as_ref().map(|_| [&r[..n], &g[..n], &b[..n]]),
        flake_density: t.flake_density.as_ref().map(|_| &density[..n]),
        coat_roughness: t.coat_roughness.as_ref().map(|_| &rough[..n]),
    };
    // The views are built from arrays of one length, and the scene checked that the material
    // can vary these parameters (`PaintTextures::build`), so the calls cannot fail; an element
    // whose values the core rejects gets zero outputs and a failed sample.
    {
        let (wo, wi) = (src3(&buf.wo), src3(&buf.wi_light));
        let f = dst3(&mut buf.f);
        let pdf = Dst1::new(&mut buf.pdf);
        let _ = batch::eval_pdf_varying(mat, &tex, &wi, &wo, Some(&buf.eval_active), Some(&f), Some(&pdf));
    }
    let (wo, u) = (src3(&buf.wo), src3(&buf.u));
    let mut so = SampleOut {
        wi: dst3(&mut buf.wi),
        weight: dst3(&mut buf.weight),
        pdf: Dst1::new(&mut buf.sample_pdf),
        flags: Some(&mut buf.flags),
    };
    let _ = batch::sample_varying(mat, &tex, &wo, &u, None, &mut so);
}

/// One pixel between rounds of a progressive render: its random stream and the running sums
/// of its samples (colour, alpha, albedo, normal; f64 as the one-shot render always summed).
#[derive(Clone)]
struct PixelState {
    rng: Sampler,
    c: [f64; 3],
    a: f64,
    al: [f64; 3],
    n: [f64; 3],
    /// Sums of the Diffuse Color and Glossy Color estimates.
    lc: [[f64; 3]; 2],
}

impl PixelState {
    fn new(set: &RenderSettings, width: u32, x: u32, y: u32) -> Self {
        Self {
            rng: Sampler(Pcg32::new(set.seed, y as u64 * width as u64 + x as u64)),
            c: [0.0; 3],
            a: 0.0,
            al: [0.0; 3],
            n: [0.0; 3],
            lc: [[0.0; 3]; 2],
        }
    }

    /// The mean of `samples` samples: colour, alpha, albedo, unit normal.
    fn value(&self, samples: u32) -> PixelValue {
        let inv = 1.0 / samples.max(1) as f64;
        let n = self.n;
        let nl = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let normal = if nl > 0.0 { n.map(|v| (v / nl) as f32) } else { [0.0; 3] };
        (self.c.map(|v| (v * inv) as f32), (self.a * inv) as f32, self.al.map(|v| (v * inv) as f32), normal)
    }
}

/// Adds `n` samples to the pixels of tile `t` (`states`: their random streams and sums, rows
/// of the tile), all pixels' paths of one sample index at a time (a wave): paths are traced to
/// their next vertex one by one, then every vertex of a material is shaded in one batch call,
/// then the paths go on. Each pixel's random stream is drawn in the same order as a path
/// traced alone. Returns the number of dropped (non-finite) paths, or `None` when cancelled
/// (the states are then partly updated: the caller discards them).
fn render_tile(
    scene: &Scene,
    set: &RenderSettings,
    t: &Tile,
    states: &mut [PixelState],
    n: u32,
    cancel: &AtomicBool,
    done: &AtomicU64,
) -> Option<u64> {
    let coords: Vec<(u32, u32)> = (t.y0..t.y1).flat_map(|y| (t.x0..t.x1).map(move |x| (x, y))).collect();
    debug_assert_eq!(coords.len(), states.len());
    let mut invalid = 0u64;
    let mut paths: Vec<Path> = Vec::with_capacity(coords.len());
    let (mut alive, mut next): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
    let mut vertices: Vec<Vertex> = Vec::with_capacity(coords.len());
    let mut shaded: Vec<Shaded> = Vec::new();
    let mut groups: Vec<Vec<u32>> = vec![Vec::new(); scene.materials.len()];
    let mut buf = ShadeBuffers::default();
    for _ in 0..n {
        if cancel.load(Ordering::Relaxed) {
            return None;
        }
        paths.clear();
        for (st, &(x, y)) in states.iter_mut().zip(&coords) {
            let j = if set.jitter { st.rng.next2() } else { [0.5, 0.5] };
            paths.push(Path::new(scene.camera.generate_in_pixel(x, y, j)));
        }
        alive.clear();
        alive.extend(0..coords.len() as u32);
        while !alive.is_empty() {
            vertices.clear();
            for &i in &alive {
                if let Some(mut v) = advance(scene, set, &mut paths[i as usize], &mut states[i as usize].rng) {
                    v.path = i;
                    vertices.push(v);
                }
            }
            shaded.clear();
            shaded.resize(vertices.len(), Shaded::default());
            for g in &mut groups {
                g.clear();
            }
            for (vi, v) in vertices.iter().enumerate() {
                groups[v.material as usize].push(vi as u32);
            }
            for (mi, g) in groups.iter().enumerate() {
                if !g.is_empty() {
                    let tex = scene.textures[mi].as_deref();
                    let coat = scene.coat_shading[mi];
                    shade_group(&scene.materials[mi], tex, coat, &vertices, g, &mut buf, &mut shaded);
                }
            }
            next.clear();
            for (v, s) in vertices.iter().zip(&shaded) {
                let i = v.path as usize;
                if finish(scene, set, &mut paths[i], v, s, &mut states[i].rng) {
                    next.push(v.path);
                }
            }
            std::mem::swap(&mut alive, &mut next);
        }
        for (st, path) in states.iter_mut().zip(&paths) {
            let v = &path.value;
            let mut r = v.radiance;
            if !r.is_finite() || r.min_channel() < 0.0 {
                invalid += 1;
                continue;
            }
            if set.clamp > 0.0 {
                let m = r.max_channel();
                if m > set.clamp {
                    r *= set.clamp / m;
                }
            }
            for k in 0..3 {
                st.c[k] += r[k] as f64;
            }
            st.a += v.alpha as f64;
            if set.lobe_aovs && v.lobe_colors.iter().all(|c| c.is_finite()) {
                for (sum, c) in st.lc.iter_mut().zip(&v.lobe_colors) {
                    for k in 0..3 {
                        sum[k] += c[k] as f64;
                    }
                }
            }
            if set.aovs && v.albedo.is_finite() {
                for (k, nk) in [v.normal.x, v.normal.y, v.normal.z].into_iter().enumerate() {
                    st.al[k] += v.albedo[k] as f64;
                    st.n[k] += nk as f64;
                }
            }
        }
        done.fetch_add(coords.len() as u64, Ordering::Relaxed);
    }
    Some(invalid)
}

/// Colour, alpha, albedo, normal of one pixel.
type PixelValue = ([f32; 3], f32, [f32; 3], [f32; 3]);

struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

/// A render refined in rounds, for hosts that show the image while it converges (Blender's
/// render window and viewport): [`Progressive::advance`] adds samples per pixel, and
/// [`Progressive::framebuffer`] is the mean of the samples so far. Every pixel continues its
/// own random stream and sums in the same order, so any split of `spp` samples into rounds
/// gives the image [`render`] gives, bit for bit. Memory: about 100 bytes per pixel.
pub struct Progressive {
    width: u32,
    height: u32,
    set: RenderSettings,
    pixels: Vec<PixelState>,
    samples: u32,
    invalid: u64,
    seconds: f64,
}

impl Progressive {
    /// A render of `scene` with `set` (its `spp` is the target) with no samples yet.
    #[must_use]
    pub fn new(scene: &Scene, set: &RenderSettings) -> Self {
        let (w, h) = (scene.camera.width(), scene.camera.height());
        let pixels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| PixelState::new(set, w, x, y));
        Self { width: w, height: h, set: set.clone(), pixels: pixels.collect(), samples: 0, invalid: 0, seconds: 0.0 }
    }

    /// Samples per pixel done so far.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The samples per pixel asked for (the settings' `spp`).
    #[must_use]
    pub fn target(&self) -> u32 {
        self.set.spp
    }

    /// Adds up to `n` samples per pixel (never beyond the target) and returns how many were
    /// added. `progress(fraction of this round)` runs on the calling thread about ten times a
    /// second; returning `false` cancels the round, which leaves the render as it was before it
    /// (`Err(Cancelled)`; a later `advance` resumes). `scene` must be the scene given to `new`.
    ///
    /// # Panics
    /// If `scene`'s image size differs from the one given to `new`.
    pub fn advance(&mut self, scene: &Scene, n: u32, progress: &mut dyn FnMut(f32) -> bool) -> Result<u32, Cancelled> {
        use rayon::prelude::*;
        let (w, h) = (self.width, self.height);
        assert_eq!((scene.camera.width(), scene.camera.height()), (w, h), "advance: not the scene of new()");
        let n = n.min(self.set.spp.saturating_sub(self.samples));
        if n == 0 {
            return Ok(0);
        }
        let set = &self.set;
        let ts = set.tile_size.max(1);
        let mut tiles = Vec::new();
        for y0 in (0..h).step_by(ts as usize) {
            for x0 in (0..w).step_by(ts as usize) {
                tiles.push(Tile { x0, y0, x1: (x0 + ts).min(w), y1: (y0 + ts).min(h) });
            }
        }
        // Progress counts pixel samples (a tile reports after each sample index of the round).
        let total =
            (tiles.iter().map(|t| (t.y1 - t.y0) as u64 * (t.x1 - t.x0) as u64).sum::<u64>() * u64::from(n)).max(1);
        let done = AtomicU64::new(0);
        let invalid = AtomicU64::new(0);
        let cancel = AtomicBool::new(false);
        let start = Instant::now();
        let pixels = &self.pixels;

        let work = || -> Vec<Option<Vec<PixelState>>> {
            tiles
                .par_iter()
                .map(|t| {
                    let mut px: Vec<PixelState> = (t.y0..t.y1)
                        .flat_map(|y| (t.x0..t.x1).map(move |x| pixels[(y * w + x) as usize].clone()))
                        .collect();
                    let bad = render_tile(scene, set, t, &mut px, n, &cancel, &done)?;
                    if bad > 0 {
                        invalid.fetch_add(bad, Ordering::Relaxed);
                    }
                    Some(px)
                })
                .collect()
        };
        let pool =
            if set.threads > 0 { rayon::ThreadPoolBuilder::new().num_threads(set.threads).build().ok() } else { None };
        let finished = AtomicBool::new(false);
        let caller = std::thread::current();
        let (results, seconds) = std::thread::scope(|s| {
            let handle = s.spawn(|| {
                let r = match &pool {
                    Some(p) => p.install(work),
                    None => work(),
                };
                let seconds = start.elapsed().as_secs_f64();
                finished.store(true, Ordering::Release);
                caller.unpark();
                (r, seconds)
            });
            while !finished.load(Ordering::Acquire) {
                std::thread::park_timeout(Duration::from_millis(100));
                if finished.load(Ordering::Acquire) {
                    break;
                }
                if !cancel.load(Ordering::Relaxed) && !progress(done.load(Ordering::Relaxed) as f32 / total as f32) {
                    cancel.store(true, Ordering::Relaxed);
                }
            }
            handle.join().expect("render worker panicked")
        });
        if cancel.load(Ordering::Relaxed) || results.iter().any(Option::is_none) {
            return Err(Cancelled);
        }
        for (t, px) in tiles.iter().zip(results) {
            let mut px = px.into_iter().flatten();
            for y in t.y0..t.y1 {
                for x in t.x0..t.x1 {
                    if let Some(st) = px.next() {
                        self.pixels[(y * w + x) as usize] = st;
                    }
                }
            }
        }
        self.samples += n;
        self.invalid += invalid.load(Ordering::Relaxed);
        self.seconds += seconds;
        Ok(n)
    }

    /// The mean of the samples so far (black before the first round).
    #[must_use]
    pub fn framebuffer(&self) -> Framebuffer {
        let mut fb = Framebuffer::new(self.width, self.height, self.set.aovs);
        for (i, st) in self.pixels.iter().enumerate() {
            let (c, a, al, n) = st.value(self.samples);
            fb.color[i] = c;
            fb.alpha[i] = a;
            if let Some(v) = fb.albedo.as_mut() {
                v[i] = al;
            }
            if let Some(v) = fb.normal.as_mut() {
                v[i] = n;
            }
            if self.set.lobe_aovs {
                let inv = 1.0 / self.samples.max(1) as f64;
                let [d, g] = st.lc.map(|c| c.map(|x| (x * inv) as f32));
                fb.diffuse_color.get_or_insert_with(Vec::new).push(d);
                fb.glossy_color.get_or_insert_with(Vec::new).push(g);
            }
        }
        let paths = self.width as u64 * self.height as u64 * self.samples as u64;
        fb.stats = RenderStats {
            seconds: self.seconds,
            paths,
            invalid: self.invalid,
            paths_per_second: paths as f64 / self.seconds.max(1e-9),
        };
        fb
    }
}

/// Renders `scene` (image size = the camera's). `progress(fraction)` is called on the calling
/// thread about ten times a second and once at the end; returning `false` cancels the render.
pub fn render(
    scene: &Scene,
    set: &RenderSettings,
    progress: &mut dyn FnMut(f32) -> bool,
) -> Result<Framebuffer, Cancelled> {
    let mut p = Progressive::new(scene, set);
    p.advance(scene, set.spp, progress)?;
    let fb = p.framebuffer();
    progress(1.0);
    Ok(fb)
}

/// Renders without progress reporting.
#[must_use]
pub fn render_quiet(scene: &Scene, set: &RenderSettings) -> Framebuffer {
    render(scene, set, &mut |_| true).expect("not cancellable")
}

#[cfg(test)]
mod coat_tests;
