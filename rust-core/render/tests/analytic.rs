//! Analytic checks of the renderer: white furnace, the thesis' point-light local illumination
//! in closed form, area lights against their closed-form irradiance, 1/√spp convergence,
//! determinism and cancellation. Images are small so that the suite runs in seconds.
//!
//! Tolerances come from the noise: each test states how it chose them.

use lacquer::{Material, Vec3};
use lacquer_render::camera::Camera;
use lacquer_render::desc::DefaultScene;
use lacquer_render::env::Environment;
use lacquer_render::geom::v3;
use lacquer_render::lights::Light;
use lacquer_render::shapes::{Quad, Sphere};
use lacquer_render::{render, render_quiet, Cancelled, Framebuffer, RenderSettings, Scene, SceneBuilder};

fn settings(spp: u32, max_depth: u32) -> RenderSettings {
    RenderSettings { spp, max_depth, aovs: false, footprints: false, ..Default::default() }
}

fn mat(json: &str) -> Material {
    Material::from_json(json).unwrap()
}

/// A sphere of `material` at the origin inside a constant environment of radiance 1.
fn furnace_scene(material: Material, size: u32) -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material(material);
    b.sphere(Sphere { center: v3(0.0, 0.0, 0.0), radius: 1.0, uv_scale: 1.0 }, m);
    b.light(Light::Env(Environment::constant(lacquer::Rgb::splat(1.0))));
    let cam = Camera::look_at(v3(0.0, 0.0, 4.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 35.0, size, size);
    b.build(cam)
}

/// Mean and worst deviation from `expected` over pixels with alpha 1 (the sphere).
fn sphere_stats(fb: &Framebuffer, expected: f64) -> (f64, f64, usize) {
    let (mut sum, mut worst, mut n) = (0.0, 0.0f64, 0);
    for (c, a) in fb.color.iter().zip(&fb.alpha) {
        if *a < 1.0 {
            continue;
        }
        for v in c {
            sum += *v as f64;
            worst = worst.max((*v as f64 - expected).abs());
        }
        n += 1;
    }
    (sum / (3 * n.max(1)) as f64, worst, n)
}

/// White furnace: a lossless Lambert sphere in a uniform environment of radiance 1 renders to
/// 1 everywhere. The sphere is convex, so every bounce escapes: per-sample values are NEE and
/// BSDF-sampled environment hits weighted by MIS, whose sum has expectation exactly 1 and
/// small variance; the tolerance (0.5 % on the mean, 15 % per pixel at 64 spp) is ~5σ.
#[test]
fn white_furnace_lambert() {
    let scene = furnace_scene(Material::preset("white_lambert").unwrap(), 24);
    let fb = render_quiet(&scene, &settings(64, 16));
    let (mean, worst, n) = sphere_stats(&fb, 1.0);
    eprintln!("furnace lambert: mean {mean:.5}, worst pixel deviation {worst:.4} over {n} pixels");
    assert!(n > 100, "sphere covers {n} pixels");
    assert!((mean - 1.0).abs() < 0.005, "mean {mean}");
    assert!(worst < 0.15, "worst pixel deviates by {worst}");
    // Background pixels see the environment itself.
    for (c, a) in fb.color.iter().zip(&fb.alpha) {
        if *a == 0.0 {
            assert!(c.iter().all(|v| (*v - 1.0).abs() < 1e-6));
        }
    }
    assert_eq!(fb.stats.invalid, 0);
}

/// White furnace through a delta lobe: a lossless coated paint (white pigment, no absorption,
/// no flakes) with a mirror-smooth clearcoat. Its albedo is 1 up to the model's table error
/// (`lacquer check` measures 0.998–0.999), so the sphere renders to ≈ 1; mixing the delta coat
/// reflection with the MIS'd diffuse lobes must neither double-count nor drop light. The
/// rough-coat version exercises MIS with a glossy lobe.
///
/// Measured (issue 16; 8 seeds each, this test's scene and settings): the sphere's mean is
/// 0.9964 for both coats (the sphere averages grazing views too, where the model's albedo is
/// lower than the 0.998–0.999 `lacquer check` reports) and one render's mean scatters by
/// σ = 0.0010 (0.00099 smooth, 0.00091 rough; seed 0, used here: 0.99443 / 0.99442). The mean
/// must lie in [1 − 0.009, 1 + 0.005]: the measured model deficit 0.0036 plus 5σ below, 5σ of
/// noise above 1 (an energy gain is a bug); it was ±1.5 %. Worst pixel: 0.17–0.24 over the 16
/// renders (heavy-tailed at 64 spp), bound 0.35.
#[test]
fn white_furnace_lossless_coat() {
    for rough in [0.0, 0.1] {
        let json =
            format!(r#"{{"model": "coated_paint", "base_color": 1, "flake_density": 0, "coat_roughness": {rough}}}"#);
        let scene = furnace_scene(mat(&json), 24);
        let fb = render_quiet(&scene, &settings(64, 64));
        let (mean, worst, _) = sphere_stats(&fb, 1.0);
        eprintln!("furnace lossless coat (roughness {rough}): mean {mean:.5}, worst pixel deviation {worst:.4}");
        assert!(mean > 1.0 - 0.009 && mean < 1.0 + 0.005, "coat roughness {rough}: mean {mean}");
        assert!(worst < 0.35, "coat roughness {rough}: worst pixel deviates by {worst}");
        assert_eq!(fb.stats.invalid, 0);
    }
}

/// Ray-sphere intersection in f64 (independent of the renderer's f32 code).
fn hit_sphere(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Option<[f64; 3]> {
    let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    let cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r * r;
    let disc = b * b - cc;
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then(|| [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]])
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// The thesis' local illumination (seed 004, "Local Illumination"): with point lights only,
/// `L(x → v) = Σ_j f_r(l_j, v) · I_j / r_j² · cos θ_j`. Direct lighting, one point light,
/// rays through pixel centres: every sample is the same, so the renderer must match the
/// closed form (evaluated here in f64 with the material's f64 path) to f32 precision.
#[test]
fn point_light_matches_local_illumination() {
    let light_pos = [2.0, 3.0, 4.0];
    let intensity = [30.0, 20.0, 10.0];
    for json in [
        r#"{"model": "lambert", "albedo": [0.8, 0.5, 0.2]}"#,
        r#"{"preset": "gold_flake_5"}"#,
        r#"{"model": "ward", "alpha_x": 0.2, "alpha_y": 0.2}"#,
    ] {
        let material = mat(json);
        for spot in [false, true] {
            let size = 32;
            let mut b = SceneBuilder::new();
            let m = b.material(material.clone());
            b.sphere(Sphere { center: v3(0.0, 0.0, 0.0), radius: 1.0, uv_scale: 1.0 }, m);
            let position = v3(light_pos[0] as f32, light_pos[1] as f32, light_pos[2] as f32);
            let i = lacquer::Rgb::new(intensity[0] as f32, intensity[1] as f32, intensity[2] as f32);
            b.light(if spot {
                // The sphere lies well inside the full-intensity cone (half angle 11° < 25°).
                Light::Spot {
                    position,
                    direction: (v3(0.0, 0.0, 0.0) - position).normalize(),
                    intensity: i,
                    cos_inner: 25f32.to_radians().cos(),
                    cos_outer: 30f32.to_radians().cos(),
                }
            } else {
                Light::Point { position, intensity: i }
            });
            let cam = Camera::look_at(v3(0.0, 0.5, 4.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 35.0, size, size);
            let scene = b.build(cam);
            let set = RenderSettings { jitter: false, ..settings(1, 1) };
            let fb = render_quiet(&scene, &set);
            let mut checked = 0;
            let mut worst = 0.0f64;
            for y in 0..size {
                for x in 0..size {
                    let cr = scene.camera.generate(x as f32 + 0.5, y as f32 + 0.5);
                    let o = [cr.ray.o.x as f64, cr.ray.o.y as f64, cr.ray.o.z as f64];
                    let d = unit([cr.ray.d.x as f64, cr.ray.d.y as f64, cr.ray.d.z as f64]);
                    let got = fb.color[(y * size + x) as usize];
                    let Some(p) = hit_sphere(o, d, [0.0; 3], 1.0) else {
                        assert_eq!(got, [0.0; 3]);
                        continue;
                    };
                    let n = unit(p);
                    let to_l = sub(light_pos, p);
                    let r2 = dot(to_l, to_l);
                    let wi_w = unit(to_l);
                    let wo_w = [-d[0], -d[1], -d[2]];
                    let (s, t) = lacquer::frame::basis_around(Vec3::new(n[0], n[1], n[2]));
                    let local = |w: [f64; 3]| Vec3::new(dot(w, [s.x, s.y, s.z]), dot(w, [t.x, t.y, t.z]), dot(w, n));
                    let (wi, wo) = (local(wi_w), local(wo_w));
                    let f = material.eval::<f64>(wi, wo);
                    let cos = wi.z.max(0.0);
                    let expected = [f.r, f.g, f.b].map(|fc| if cos > 0.0 { fc * cos / r2 } else { 0.0 });
                    for c in 0..3 {
                        let e = expected[c] * intensity[c];
                        let g = got[c] as f64;
                        if e > 1e-3 {
                            worst = worst.max((g / e - 1.0).abs());
                        }
                        // f32 geometry near the terminator moves cos θ by ~1e-6.
                        assert!(
                            (g - e).abs() <= 2e-3 * e + 2e-5,
                            "{json} spot={spot} pixel ({x},{y}) channel {c}: rendered {g}, closed form {e}"
                        );
                    }
                    checked += 1;
                }
            }
            eprintln!("point light ({json}, spot {spot}): {checked} pixels, worst relative error {worst:.2e}");
            assert!(checked > 200);
        }
    }
}

/// A Lambert floor lit by one area light, seen through a 1° camera from just below the light:
/// the pixels cover a ±0.5 % patch around the point below the light, whose outgoing radiance
/// is `ρ/π · E` with the closed-form irradiance:
/// - sphere light (radius r, centre at distance d above): `E = π L (r/d)²`;
/// - square light of side a at height h, facing down: `E = π L F`, with the view factor of a
///   parallel rectangle from a point below its corner (Howell's catalogue, C-11) summed over
///   the four quarters: `F = 4 · 1/(2π) [X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))]`,
///   `X = Y = a/(2h)`.
///
/// Direct lighting with MIS (light sampling and the Lambert sampler both find the light).
/// 8×8 pixels × 256 spp; tolerance 1 % on the mean (noise ≈ 0.2 %).
#[test]
fn area_lights_match_closed_form_irradiance() {
    let rho = 0.5f64;
    let radiance = 10.0f64;
    let x = 0.5f64;
    let f_corner = (x / (1.0 + x * x).sqrt() * (x / (1.0 + x * x).sqrt()).atan()) * 2.0 / (2.0 * std::f64::consts::PI);
    let cases = [
        (
            "sphere",
            Light::Sphere {
                sphere: Sphere { center: v3(0.0, 2.0, 0.0), radius: 0.5, uv_scale: 1.0 },
                radiance: lacquer::Rgb::splat(radiance as f32),
            },
            rho * radiance * 0.25f64.powi(2),
        ),
        (
            "rectangle",
            Light::Rect {
                quad: Quad::centered(v3(0.0, 1.0, 0.0), v3(0.0, -1.0, 0.0), v3(1.0, 0.0, 0.0), 1.0, 1.0, 1.0),
                radiance: lacquer::Rgb::splat(radiance as f32),
                two_sided: false,
                ellipse: false,
            },
            rho * radiance * 4.0 * f_corner,
        ),
    ];
    for (name, light, expected) in cases {
        let mut b = SceneBuilder::new();
        let m = b.material(mat(r#"{"model": "lambert", "albedo": 0.5}"#));
        b.quad(Quad::centered(v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(1.0, 0.0, 0.0), 20.0, 20.0, 1.0), m);
        b.light(light);
        let cam = Camera::look_at(v3(0.0, 0.5, 0.0), v3(0.0, 0.0, 0.0), v3(0.0, 0.0, -1.0), 1.0, 8, 8);
        let scene = b.build(cam);
        let fb = render_quiet(&scene, &settings(256, 1));
        let mean = fb.mean();
        eprintln!("{name} light: rendered {:.5}, closed form {expected:.5}", mean[1]);
        for (c, m) in mean.iter().enumerate() {
            assert!((m / expected - 1.0).abs() < 0.01, "{name}: channel {c} rendered {m}, closed form {expected}");
        }
    }
}

/// A sharp sun (delta direction, irradiance E) on a tilted Lambert plane: `L = ρ/π E cos θ`,
/// exact per sample.
#[test]
fn sun_on_lambert_plane() {
    let mut b = SceneBuilder::new();
    let m = b.material(mat(r#"{"model": "lambert", "albedo": 0.6}"#));
    b.quad(Quad::centered(v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(1.0, 0.0, 0.0), 20.0, 20.0, 1.0), m);
    let dir = v3(1.0, 2.0, 0.5).normalize();
    b.light(Light::sun(dir, lacquer::Rgb::splat(3.0), 0.0));
    let cam = Camera::look_at(v3(0.0, 3.0, 3.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 20.0, 8, 8);
    let scene = b.build(cam);
    let fb = render_quiet(&scene, &RenderSettings { jitter: false, ..settings(1, 1) });
    let expected = 0.6 / std::f64::consts::PI * 3.0 * dir.y as f64;
    for c in &fb.color {
        assert!((c[1] as f64 / expected - 1.0).abs() < 1e-4, "{} vs {expected}", c[1]);
    }
}

/// Root-mean-square difference of two images.
fn rmse(a: &Framebuffer, b: &Framebuffer) -> f64 {
    let mut s = 0.0;
    for (p, q) in a.color.iter().zip(&b.color) {
        for c in 0..3 {
            s += (p[c] as f64 - q[c] as f64).powi(2);
        }
    }
    (s / (3 * a.color.len()) as f64).sqrt()
}

/// Convergence: the RMSE against a 4096-spp reference falls as spp^(−1/2). The built-in scene
/// without its floor (studio map, key light, a flake paint on the sphere) at 20×20; the floor
/// would add caustics (Lambert floor → glossy coat → small key light), whose heavy-tailed
/// noise makes a handful of low-spp images underestimate the variance. The reference's own
/// error adds
/// `σ²/4096` to each MSE, which we subtract using the MSE at 4096 spp expected from the
/// 4-spp estimate. The fitted log-log slope over 4…64 spp must lie in [−0.6, −0.4].
#[test]
fn rmse_falls_as_inverse_sqrt_spp() {
    let opts = DefaultScene { width: 20, height: 20, floor: false, ..Default::default() };
    let scene = opts.build(Material::preset("gold_flake_5").unwrap()).unwrap();
    let reference = render_quiet(&scene, &RenderSettings { seed: 1000, ..settings(4096, 8) });
    let spps = [4u32, 8, 16, 32, 64];
    // Average the MSE over a few seeds to steady the estimate.
    let mses: Vec<f64> = spps
        .iter()
        .map(|&spp| {
            (0..4u64)
                .map(|seed| {
                    rmse(&render_quiet(&scene, &RenderSettings { seed, ..settings(spp, 8) }), &reference).powi(2)
                })
                .sum::<f64>()
                / 4.0
        })
        .collect();
    let sigma2 = mses[0] * 4.0 / (1.0 + 4.0 / 4096.0);
    let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
    for (spp, mse) in spps.iter().zip(&mses) {
        let x = (*spp as f64).ln();
        let y = 0.5 * (mse - sigma2 / 4096.0).max(1e-30).ln();
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    let n = spps.len() as f64;
    let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    let rmses: Vec<String> = mses.iter().map(|m| format!("{:.4}", m.sqrt())).collect();
    eprintln!("convergence: log-log slope {slope:.3}, RMSE at {spps:?} spp: {rmses:?}");
    assert!((-0.6..=-0.4).contains(&slope), "slope {slope}, RMSE {rmses:?}");
}

/// Same seed, same image, whatever the thread count and tile size; another seed differs.
#[test]
fn deterministic_per_seed() {
    let opts = DefaultScene { width: 24, height: 16, ..Default::default() };
    let scene = opts.build(Material::preset("silver_flake_3").unwrap()).unwrap();
    let one = render_quiet(&scene, &RenderSettings { threads: 1, tile_size: 8, ..settings(4, 8) });
    let two = render_quiet(&scene, &RenderSettings { threads: 2, tile_size: 5, ..settings(4, 8) });
    assert_eq!(one.color, two.color);
    let other = render_quiet(&scene, &RenderSettings { seed: 9, ..settings(4, 8) });
    assert_ne!(one.color, other.color);
}

/// The progress callback sees increasing fractions ending at 1, and returning false cancels.
#[test]
fn progress_and_cancel() {
    let opts = DefaultScene { width: 64, height: 64, ..Default::default() };
    let scene = opts.build(Material::preset("gold_flake_0").unwrap()).unwrap();
    let mut seen = Vec::new();
    let fb = render(&scene, &settings(2, 4), &mut |f| {
        seen.push(f);
        true
    })
    .unwrap();
    assert_eq!(*seen.last().unwrap(), 1.0);
    assert!(seen.windows(2).all(|w| w[0] <= w[1]));
    assert!(fb.color.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    let r = render(&scene, &settings(4096, 8), &mut |_| false);
    assert_eq!(r.err(), Some(Cancelled));
}

/// An octahedron subdivided `levels` times and pushed onto the unit sphere, as OBJ text
/// (flat: no vertex normals, so shading normals are the facet normals).
fn icosphere_obj(levels: usize) -> String {
    let mut v: Vec<[f64; 3]> =
        vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let mut f: Vec<[usize; 3]> =
        vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    for _ in 0..levels {
        let mut nf = Vec::new();
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| -> usize {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = [0, 1, 2].map(|k| 0.5 * (v[a][k] + v[b][k]));
                let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
                v.push(m.map(|x| x / l));
                v.len() - 1
            })
        };
        for [a, b, c] in f {
            let (ab, bc, ca) = (midpoint(a, b, &mut v), midpoint(b, c, &mut v), midpoint(c, a, &mut v));
            nf.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        f = nf;
    }
    let mut s = String::from("# icosphere\n");
    for p in &v {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &f {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

/// Meshes: an OBJ polyhedron (512 flat triangles, through the BVH) of lossless Lambert in the
/// white furnace renders to 1 (it is convex, so the argument of the sphere furnace holds), and
/// a scene file with that mesh, fitted and transformed, loads and renders.
#[test]
fn obj_mesh_furnace_and_scene_file() {
    let dir = std::env::temp_dir().join(format!("lacquer-render-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("ball.obj");
    std::fs::write(&obj, icosphere_obj(3)).unwrap();
    let mesh = lacquer_render::desc::load_obj(&obj).unwrap();
    assert_eq!(mesh.triangles.len(), 512);
    let mut b = SceneBuilder::new();
    let m = b.material(Material::preset("white_lambert").unwrap());
    b.mesh(mesh, m);
    b.light(Light::Env(Environment::constant(lacquer::Rgb::splat(1.0))));
    let cam = Camera::look_at(v3(0.0, 0.0, 4.0), v3(0.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), 35.0, 24, 24);
    let scene = b.build(cam);
    assert_eq!(scene.primitive_count(), 512);
    let fb = render_quiet(&scene, &settings(64, 16));
    let (mean, worst, n) = sphere_stats(&fb, 1.0);
    eprintln!("furnace OBJ mesh: mean {mean:.5}, worst pixel deviation {worst:.4} over {n} pixels");
    assert!(n > 100 && (mean - 1.0).abs() < 0.005 && worst < 0.15, "mean {mean}, worst {worst}");

    let scene_json = r#"{
        "camera": {"position": [0, 3, 3], "look_at": [0, 0, 0], "fov_deg": 40},
        "materials": {"paint": {"preset": "gold_flake_3"}},
        "objects": [
            {"type": "mesh", "file": "ball.obj", "material": "paint", "fit_radius": 0.5,
             "transform": {"rotate_deg": [0, 30, 0], "translate": [0.2, 0, 0]}},
            {"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "size": [10, 10], "material": {"model": "lambert"}}
        ],
        "lights": [{"type": "sun", "direction": [1, 2, 1], "irradiance": 3, "angle_deg": 0.5},
                   {"type": "environment", "map": "studio"}]
    }"#;
    let path = dir.join("scene.json");
    std::fs::write(&path, scene_json).unwrap();
    let desc = lacquer_render::desc::SceneDesc::load(&path).unwrap();
    let scene = desc.build(&dir, 16, 12, None).unwrap();
    assert_eq!(scene.primitive_count(), 513);
    let fb = render_quiet(&scene, &settings(4, 4));
    assert!(fb.color.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    assert!(fb.alpha.iter().all(|a| *a == 1.0)); // floor and ball fill the frame
                                                 // Unknown keys and bad references are errors that say where.
    let bad = scene_json.replace("\"fit_radius\"", "\"fit_radios\"");
    std::fs::write(&path, bad).unwrap();
    assert!(lacquer_render::desc::SceneDesc::load(&path).unwrap_err().contains("fit_radios"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A rectangle filling the view (uv ∈ [0.1, 0.9] across it) under a sun and a constant sky,
/// made of `material` (JSON, may carry `textures`), with the scene's `images`.
fn textured_scene(dir: &std::path::Path, material: &str, images: &str) -> Result<Scene, String> {
    let json = format!(
        r#"{{
        "camera": {{"position": [0, 0, 3], "look_at": [0, 0, 0], "fov_deg": 30}},
        "images": {{{images}}},
        "objects": [{{"type": "rectangle", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0],
                      "uv_scale": 0.5, "material": {material}}}],
        "lights": [{{"type": "sun", "direction": [0.4, 0.5, 1], "irradiance": 3}},
                   {{"type": "environment", "radiance": 0.5}}]
    }}"#
    );
    let desc: lacquer_render::desc::SceneDesc = serde_json::from_str(&json).map_err(|e| e.to_string())?;
    desc.build(dir, 32, 32, None)
}

/// Worst relative difference per channel between `a` and `b` over pixel columns `cols`.
fn worst_rel(a: &Framebuffer, b: &Framebuffer, cols: std::ops::Range<usize>) -> f64 {
    let w = a.width as usize;
    let mut worst = 0.0f64;
    for (i, (p, q)) in a.color.iter().zip(&b.color).enumerate() {
        if cols.contains(&(i % w)) {
            for c in 0..3 {
                let (x, y) = (f64::from(p[c]), f64::from(q[c]));
                worst = worst.max((x - y).abs() / y.abs().max(1e-3));
            }
        }
    }
    worst
}

/// Largest relative difference per channel between the means of `a` and `b` over pixel
/// columns `cols`.
fn mean_rel(a: &Framebuffer, b: &Framebuffer, cols: std::ops::Range<usize>) -> f64 {
    let w = a.width as usize;
    let (mut sa, mut sb) = ([0.0f64; 3], [0.0f64; 3]);
    for (i, (p, q)) in a.color.iter().zip(&b.color).enumerate() {
        if cols.contains(&(i % w)) {
            for c in 0..3 {
                sa[c] += f64::from(p[c]);
                sb[c] += f64::from(q[c]);
            }
        }
    }
    (0..3).map(|c| (sa[c] - sb[c]).abs() / sb[c]).fold(0.0, f64::max)
}

/// A two-colour image (left half `a`, right half `b`) of 16×16 texels as an inline image.
fn halves(a: [f32; 3], b: [f32; 3]) -> String {
    let px: Vec<[f32; 3]> = (0..256).map(|k| if k % 16 < 8 { a } else { b }).collect();
    format!(r#""halves": {{"width": 16, "height": 16, "pixels": {}}}"#, serde_json::to_string(&px).unwrap())
}

#[test]
fn textured_halves_equal_the_untextured_materials() {
    let dir = std::env::temp_dir().join(format!("lacquer-render-tex-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Direct and one bounce, every ray through the pixel centre, one seed: the textured and the
    // untextured renders draw the same random numbers, so they differ only by the BRDF.
    let set = RenderSettings { jitter: false, ..settings(16, 2) };
    // Pixel columns whose uv is inside one half away from the bilinear blend at u = 0.5
    // (u = 0.098 + 0.804 (x + ½)/32: columns 0..12 have u < 0.42, 20..32 have u > 0.61).
    let (left, right) = (0..12, 20..32);

    // base_color from a PNG file (linear values k/255, exact in 8 bits) on a pigment-only paint,
    // whose per-element evaluation equals a material built with the texel colour (3e-14, docs/speed.md).
    let (ca, cb) = ([204u8, 26, 13], [13u8, 77, 178]);
    let f = |c: [u8; 3]| c.map(|v| f32::from(v) / 255.0);
    {
        let file = std::fs::File::create(dir.join("halves.png")).unwrap();
        let mut e = png::Encoder::new(std::io::BufWriter::new(file), 16, 16);
        e.set_color(png::ColorType::Rgb);
        let data: Vec<u8> = (0..256).flat_map(|k| if k % 16 < 8 { ca } else { cb }).collect();
        e.write_header().unwrap().write_image_data(&data).unwrap();
    }
    let paint = |c: [f32; 3]| {
        format!(r#"{{"model": "coated_paint", "flake_density": 0, "coat_roughness": 0.05, "base_color": {c:?}}}"#)
    };
    let textured = r#"{"model": "coated_paint", "flake_density": 0, "coat_roughness": 0.05,
        "textures": {"base_color": {"file": "halves.png", "colorspace": "linear"}}}"#;
    let t = render_quiet(&textured_scene(&dir, textured, "").unwrap(), &set);
    let a = render_quiet(&textured_scene(&dir, &paint(f(ca)), "").unwrap(), &set);
    let b = render_quiet(&textured_scene(&dir, &paint(f(cb)), "").unwrap(), &set);
    let (dl, dr, ab) =
        (worst_rel(&t, &a, left.clone()), worst_rel(&t, &b, right.clone()), worst_rel(&a, &b, left.clone()));
    eprintln!("base_color halves: left vs A {dl:.2e}, right vs B {dr:.2e} (A vs B {ab:.2})");
    // Measured 1.8e-7 and 1.7e-7 (f32 rounding of the SIMD paths); A and B differ by > 50 %.
    assert!(dl < 1e-4 && dr < 1e-4, "left {dl}, right {dr}");
    assert!(ab > 0.5, "the two colours must render differently: {ab}");

    // flake_density from an inline image (1 % and 6 %) on a gold flake paint, mean lobe on both
    // sides (the settings have no footprints, so the untextured renders have no sparkle either).
    let gold_json = |d: Option<f32>| {
        let mut v = Material::preset("gold_flake_3").unwrap().to_json();
        match d {
            Some(d) => v["flake_density"] = serde_json::json!(d),
            None => v["textures"] = serde_json::json!({"flake_density": {"image": "halves"}}),
        }
        v.to_string()
    };
    let gold = |d: f32| gold_json(Some(d));
    let textured = &gold_json(None);
    let images = halves([1.0; 3], [6.0; 3]);
    let t = render_quiet(&textured_scene(&dir, textured, &images).unwrap(), &set);
    let a = render_quiet(&textured_scene(&dir, &gold(1.0), "").unwrap(), &set);
    let b = render_quiet(&textured_scene(&dir, &gold(6.0), "").unwrap(), &set);
    let (dl, dr, ab) =
        (mean_rel(&t, &a, left.clone()), mean_rel(&t, &b, right.clone()), mean_rel(&a, &b, left.clone()));
    let (wl, wr) = (worst_rel(&t, &a, left), worst_rel(&t, &b, right));
    eprintln!("flake_density halves: means left vs A {dl:.2e}, right vs B {dr:.2e} (A vs B {ab:.2}); worst pixels {wl:.2e}, {wr:.2e}");
    // The per-component layer tables and the material's own table are two Monte Carlo
    // estimates of the multiple scattering (up to 2.6 % apart in f, docs/speed.md), and the lobe
    // weights differ as much, so a few paths pick another lobe and diverge (worst pixel 11 %):
    // compared on the halves' means, measured 0.29 % (left) and 1.03 % (right); tolerance 4 %.
    assert!(dl < 0.04 && dr < 0.04, "left {dl}, right {dr}");
    assert!(ab > 0.1, "1 % and 6 % flakes must render differently: {ab}");

    // Bad input: clear errors naming the file, the image or the parameter, never a panic.
    let missing = r#"{"preset": "gold_flake_3", "textures": {"base_color": {"file": "nope.png"}}}"#;
    let e = textured_scene(&dir, missing, "").err().unwrap();
    assert!(e.contains("nope.png") && e.contains("base_color"), "{e}");
    let range = r#"{"preset": "gold_flake_3", "textures": {"base_color": {"image": "halves"}}}"#;
    let e = textured_scene(&dir, range, &images).err().unwrap();
    assert!(e.contains("halves") && e.contains("outside [0, 1]"), "{e}");
    let lambert = r#"{"model": "lambert", "textures": {"base_color": {"file": "halves.png"}}}"#;
    let e = textured_scene(&dir, lambert, "").err().unwrap();
    assert!(e.contains("coated_paint"), "{e}");
    let unknown = r#"{"preset": "gold_flake_3", "textures": {"albedo": {"file": "halves.png"}}}"#;
    let e = textured_scene(&dir, unknown, "").err().unwrap();
    assert!(e.contains("albedo"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
