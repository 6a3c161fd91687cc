//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (power heuristic, Veach 1997) between light sampling and the material's own
//! `sample`/`pdf`; Russian roulette after a few bounces; a direct-lighting-only mode
//! (`max_depth = 1`). Delta material lobes (the smooth clearcoat's mirror) and delta lights
//! take no MIS: each can only be reached by one of the two strategies.
//!
//! The image is cut into tiles rendered in parallel (rayon). Every pixel owns a random stream
//! derived from the seed and its index, so a render is deterministic for a seed whatever the
//! number of threads or the tile order.

use crate::camera::CameraRay;
use crate::geom::{offset_origin, Frame, Ray, V3};
use crate::scene::{Hit, Scene};
use lacquer::rng::Pcg32;
use lacquer::{Rgb, SurfacePoint};
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
}

/// The uv footprint of a camera ray's hit from its differentials (pbrt's approach: intersect
/// the offset rays with the tangent plane, then solve for ∂uv/∂x, ∂uv/∂y in least squares).
fn footprint(cr: &CameraRay, hit: &Hit) -> Option<SurfacePoint> {
    if !hit.has_uv {
        return None;
    }
    let s = &hit.surf;
    let n = s.ng;
    let plane = n.dot(s.p - cr.ray.o);
    let offset = |d: V3| -> Option<V3> {
        let nd = n.dot(d);
        if nd.abs() < 1e-8 {
            return None;
        }
        let t = plane / nd;
        (t > 0.0).then(|| cr.ray.o + d * t - s.p)
    };
    let (dpdx, dpdy) = (offset(cr.dx)?, offset(cr.dy)?);
    let (a, b, c) = (s.dpdu.dot(s.dpdu), s.dpdu.dot(s.dpdv), s.dpdv.dot(s.dpdv));
    let det = a * c - b * b;
    if !(det.abs() > 1e-20) {
        return None;
    }
    let solve = |d: V3| -> [f64; 2] {
        let (bu, bv) = (s.dpdu.dot(d), s.dpdv.dot(d));
        [((c * bu - b * bv) / det) as f64, ((a * bv - b * bu) / det) as f64]
    };
    let sp = SurfacePoint { uv: [s.uv[0] as f64, s.uv[1] as f64], duv_dx: solve(dpdx), duv_dy: solve(dpdy) };
    sp.is_finite().then_some(sp)
}

/// Traces one camera path.
fn trace(scene: &Scene, set: &RenderSettings, cr: &CameraRay, rng: &mut Sampler) -> PathValue {
    let mut out = PathValue { radiance: C::zero(), alpha: 0.0, albedo: C::zero(), normal: V3::zero() };
    let mut ray = cr.ray;
    let mut beta = C::splat(1.0);
    // The previous vertex's sampling: camera rays and delta lobes count emission in full.
    let mut prev_delta = true;
    let mut prev_pdf = 0.0f32;
    let mut prev_p = ray.o;
    let mut depth = 0u32;
    // Distance travelled since the last scattering vertex through emitters that are not
    // surfaces (for the solid-angle density of what lies behind them), and how many.
    let mut passed = 0.0f32;
    let mut passes = 0u32;
    loop {
        let Some(hit) = scene.intersect(&ray) else {
            if depth == 0 && set.transparent {
                break;
            }
            for &li in scene.infinite_lights() {
                let light = &scene.lights[li as usize];
                let le = light.escaped(ray.d);
                if le.is_black() {
                    continue;
                }
                let w = if prev_delta {
                    1.0
                } else {
                    let pl = scene.light_probability(li as usize) * light.pdf(prev_p, ray.d, f32::INFINITY);
                    power_heuristic(prev_pdf, pl)
                };
                out.radiance += beta * le * w;
            }
            break;
        };
        if hit.pass_through {
            // An emitter that is not a surface: camera rays do not see it; other rays collect
            // its emission and go on behind it.
            if let (Some(li), true) = (hit.light, depth > 0) {
                let light = &scene.lights[li as usize];
                let le = light.emitted(hit.surf.ng, ray.d);
                if !le.is_black() {
                    let w = if prev_delta {
                        1.0
                    } else {
                        let pl = scene.light_probability(li as usize) * light.pdf(prev_p, ray.d, passed + hit.t);
                        power_heuristic(prev_pdf, pl)
                    };
                    out.radiance += beta * le * w;
                }
            }
            passes += 1;
            if passes > 64 {
                break;
            }
            passed += hit.t;
            ray = Ray::new(offset_origin(hit.surf.p, hit.surf.ng, ray.d), ray.d);
            continue;
        }
        if depth == 0 {
            out.alpha = 1.0;
        }
        // Emission of area lights.
        if let Some(li) = hit.light {
            let light = &scene.lights[li as usize];
            let le = light.emitted(hit.surf.ng, ray.d);
            if !le.is_black() {
                let w = if prev_delta {
                    1.0
                } else {
                    let pl = scene.light_probability(li as usize) * light.pdf(prev_p, ray.d, passed + hit.t);
                    power_heuristic(prev_pdf, pl)
                };
                out.radiance += beta * le * w;
            }
        }
        if depth >= set.max_depth {
            break;
        }
        let Some(mi) = hit.material else { break };
        let mat = &scene.materials[mi as usize];

        // Two-sided surfaces: turn the normals toward the viewer.
        let wo_world = -ray.d;
        let (mut ng, mut ns) = (hit.surf.ng, hit.surf.ns);
        if ng.dot(wo_world) < 0.0 {
            ng = -ng;
            ns = -ns;
        }
        if ns.dot(wo_world) <= 0.0 {
            ns = ng;
        }
        let frame = Frame::from_normal_tangent(ns, hit.surf.dpdu);
        let wo = frame.to_local(wo_world);
        let at = if depth == 0 && set.footprints { footprint(cr, &hit) } else { None };
        if depth == 0 && set.aovs {
            out.normal = ns;
        }
        let p = hit.surf.p;

        // Next-event estimation: one light, chosen by power.
        let u_pick = rng.next();
        let u_light = rng.next2();
        if let Some((li, p_pick)) = scene.pick_light(u_pick) {
            let light = &scene.lights[li];
            if let Some(ls) = light.sample(p, u_light) {
                if ls.wi.dot(ng) > 0.0 && ls.pdf > 0.0 && !ls.li.is_black() {
                    let wi = frame.to_local(ls.wi);
                    let f = match &at {
                        Some(at) => mat.eval_at(wi, wo, at),
                        None => mat.eval(wi, wo),
                    };
                    if wi.z > 0.0 && !f.is_black() {
                        let o = offset_origin(p, ng, ls.wi);
                        let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-3) } else { f32::INFINITY };
                        if !scene.occluded(&Ray { o, d: ls.wi, tmax }) {
                            let pl = p_pick * ls.pdf;
                            let w = if ls.delta { 1.0 } else { power_heuristic(pl, mat.pdf(wi, wo)) };
                            out.radiance += beta * f * ls.li * (wi.z * w / pl);
                        }
                    }
                }
            }
        }

        // Continue the path by sampling the material.
        let u = rng.next3();
        let s = match &at {
            Some(at) => mat.sample_at(wo, u, at),
            None => mat.sample(wo, u),
        };
        let Some(s) = s else { break };
        if depth == 0 && set.aovs {
            out.albedo = s.weight;
        }
        let wi_world = frame.to_world(s.wi);
        if wi_world.dot(ng) <= 0.0 {
            break;
        }
        beta = beta * s.weight;
        prev_delta = s.delta;
        prev_pdf = s.pdf;
        prev_p = p;
        ray = Ray::new(offset_origin(p, ng, wi_world), wi_world);
        passed = 0.0;
        depth += 1;
        if depth >= set.rr_depth {
            let q = beta.max_channel();
            if q < 1.0 {
                let q = q.max(0.05);
                if rng.next() >= q {
                    break;
                }
                beta = beta / q;
            }
        }
    }
    out
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
}

impl PixelState {
    fn new(set: &RenderSettings, width: u32, x: u32, y: u32) -> Self {
        Self {
            rng: Sampler(Pcg32::new(set.seed, y as u64 * width as u64 + x as u64)),
            c: [0.0; 3],
            a: 0.0,
            al: [0.0; 3],
            n: [0.0; 3],
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

/// Adds `n` samples to one pixel's sums; returns the number of dropped (non-finite) paths.
fn render_samples(scene: &Scene, set: &RenderSettings, x: u32, y: u32, st: &mut PixelState, n: u32) -> u64 {
    let mut invalid = 0;
    for _ in 0..n {
        let rng = &mut st.rng;
        let j = if set.jitter { rng.next2() } else { [0.5, 0.5] };
        let cr = scene.camera.generate(x as f32 + j[0], y as f32 + j[1]);
        let v = trace(scene, set, &cr, rng);
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
        if set.aovs && v.albedo.is_finite() {
            st.al[0] += v.albedo.r as f64;
            st.al[1] += v.albedo.g as f64;
            st.al[2] += v.albedo.b as f64;
            st.n[0] += v.normal.x as f64;
            st.n[1] += v.normal.y as f64;
            st.n[2] += v.normal.z as f64;
        }
    }
    invalid
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
        let total = tiles.iter().map(|t| (t.y1 - t.y0) as u64 * (t.x1 - t.x0) as u64).sum::<u64>().max(1);
        let done = AtomicU64::new(0);
        let invalid = AtomicU64::new(0);
        let cancel = AtomicBool::new(false);
        let start = Instant::now();
        let pixels = &self.pixels;

        let work = || -> Vec<Option<Vec<PixelState>>> {
            tiles
                .par_iter()
                .map(|t| {
                    let mut px = Vec::with_capacity(((t.x1 - t.x0) * (t.y1 - t.y0)) as usize);
                    for y in t.y0..t.y1 {
                        if cancel.load(Ordering::Relaxed) {
                            return None;
                        }
                        for x in t.x0..t.x1 {
                            let mut st = pixels[(y * w + x) as usize].clone();
                            let bad = render_samples(scene, set, x, y, &mut st, n);
                            if bad > 0 {
                                invalid.fetch_add(bad, Ordering::Relaxed);
                            }
                            px.push(st);
                        }
                        done.fetch_add((t.x1 - t.x0) as u64, Ordering::Relaxed);
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
