//! Per-element paint parameters (`batch::eval_pdf_varying`, `sample_varying`): each element
//! agrees with a material built with that element's parameters, for the f64 reference and
//! every SIMD level this CPU has, with masked lanes, invalid parameters and lengths that are
//! not a multiple of the lane count.

use crate::GLOBAL;
use lacquer::batch::{self, Dst1, Dst3, SampleOut, SimdLevel, Src3, SAMPLE_FAILED, SAMPLE_INVALID_INPUT};
use lacquer::paint::varying::{alpha_node, PaintTexture};
use lacquer::rng::Pcg32;
use lacquer::{Material, Vec3};

/// Paints covering the basecoat's components: rough coat with flakes; smooth absorbing coat;
/// pearl flakes with a metallic base.
const PAINTS: &[&str] = &[
    r#"{"model": "coated_paint", "flake_density": 3, "base_color": [0.5, 0.03, 0.03], "sparkle": false}"#,
    r#"{"model": "coated_paint", "coat_roughness": 0, "flake_density": 8, "coat_absorption": [2, 4, 8], "sparkle": false}"#,
    r#"{"model": "coated_paint", "coat_roughness": 0.15, "flake_density": 5, "pearl_density": 10, "pearl_film_nm": 300, "base_metallic": 0.5, "sparkle": false}"#,
];

/// Element parameter sets: `(base_color, flake_density %, coat α)`.
fn elements(alpha: &[f64]) -> Vec<([f64; 3], f64, f64)> {
    let colors = [[0.8, 0.1, 0.05], [0.02, 0.3, 0.9], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.25, 0.5, 0.125]];
    let densities = [0.0, 3.0, 20.0, 1.5, 60.0];
    (0..5).map(|k| (colors[k], densities[k], alpha[k % alpha.len()])).collect()
}

/// A material with the paint's parameters and the element's.
fn material_for(paint: &str, (rho, d, a): ([f64; 3], f64, f64), with_alpha: bool) -> Material {
    let mut v: serde_json::Value = serde_json::from_str(paint).unwrap();
    v["base_color"] = serde_json::json!(rho);
    v["flake_density"] = serde_json::json!(d);
    if with_alpha {
        v["coat_roughness"] = serde_json::json!(a);
    }
    Material::from_value(&v).unwrap()
}

/// Upper-hemisphere direction pairs (a few grazing, one below the surface).
fn directions(n: usize, seed: u64) -> Vec<(Vec3<f64>, Vec3<f64>)> {
    let mut rng = Pcg32::new(seed, 7);
    let dir = |rng: &mut Pcg32| {
        let z = rng.uniform().max(0.02);
        let phi = 2.0 * std::f64::consts::PI * rng.uniform();
        let s = (1.0 - z * z).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    (0..n)
        .map(|k| {
            let (a, mut b) = (dir(&mut rng), dir(&mut rng));
            if k % 17 == 5 {
                b.z = -b.z;
            }
            (a, b)
        })
        .collect()
}

/// Per-element texture arrays for `n` elements cycling through `el`.
struct Tex {
    rgb: [Vec<f64>; 3],
    density: Vec<f64>,
    alpha: Vec<f64>,
}

fn texture(el: &[([f64; 3], f64, f64)], n: usize) -> Tex {
    let pick = |i: usize| el[i % el.len()];
    Tex {
        rgb: [0, 1, 2].map(|c| (0..n).map(|i| pick(i).0[c]).collect()),
        density: (0..n).map(|i| pick(i).1).collect(),
        alpha: (0..n).map(|i| pick(i).2).collect(),
    }
}

const N: usize = 203; // not a multiple of 8 or 16

/// `f` and pdf of the varying call on `m` over `N` elements cycling through `el`: the f64
/// reference or the f32 path at a SIMD level. The material keeps the per-element tables it
/// builds on its first call, so callers comparing levels pass one material.
fn run_varying(
    m: &Material,
    el: &[([f64; 3], f64, f64)],
    with_alpha: bool,
    f32_level: Option<SimdLevel>,
) -> (Vec<f64>, Vec<f64>) {
    let n = N;
    let dirs = directions(n, 11);
    let t = texture(el, n);
    let (mut f, mut p) = (vec![0.0f64; 3 * n], vec![0.0f64; n]);
    match f32_level {
        None => {
            let wi: Vec<f64> = dirs.iter().flat_map(|d| [d.0.x, d.0.y, d.0.z]).collect();
            let wo: Vec<f64> = dirs.iter().flat_map(|d| [d.1.x, d.1.y, d.1.z]).collect();
            let tex = PaintTexture {
                base_color: Some([&t.rgb[0][..], &t.rgb[1][..], &t.rgb[2][..]]),
                flake_density: Some(&t.density[..]),
                coat_roughness: with_alpha.then_some(&t.alpha[..]),
            };
            let r = batch::eval_pdf_varying_f64(
                m,
                &tex,
                &Src3::interleaved(&wi),
                &Src3::interleaved(&wo),
                None,
                Some(&Dst3::interleaved(&mut f)),
                Some(&Dst1::new(&mut p)),
            )
            .unwrap();
            assert!(r.ok(), "{r:?}");
        }
        Some(level) => {
            assert!(batch::set_simd_level(level));
            let wi: Vec<f32> = dirs.iter().flat_map(|d| [d.0.x, d.0.y, d.0.z]).map(|x| x as f32).collect();
            let wo: Vec<f32> = dirs.iter().flat_map(|d| [d.1.x, d.1.y, d.1.z]).map(|x| x as f32).collect();
            let to32 = |v: &Vec<f64>| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
            let (r32, d32, a32) = (t.rgb.each_ref().map(to32), to32(&t.density), to32(&t.alpha));
            let tex = PaintTexture {
                base_color: Some([&r32[0][..], &r32[1][..], &r32[2][..]]),
                flake_density: Some(&d32[..]),
                coat_roughness: with_alpha.then_some(&a32[..]),
            };
            let (mut f32v, mut p32) = (vec![0.0f32; 3 * n], vec![0.0f32; n]);
            let r = batch::eval_pdf_varying(
                m,
                &tex,
                &Src3::interleaved(&wi),
                &Src3::interleaved(&wo),
                None,
                Some(&Dst3::interleaved(&mut f32v)),
                Some(&Dst1::new(&mut p32)),
            )
            .unwrap();
            assert!(r.ok(), "{r:?}");
            f = f32v.iter().map(|&x| f64::from(x)).collect();
            p = p32.iter().map(|&x| f64::from(x)).collect();
        }
    }
    (f, p)
}

/// Largest |a − b| / (|b| + 1e-3) over the elements against materials built with each
/// element's parameters, per output (f then pdf).
fn compare(paint: &str, el: &[([f64; 3], f64, f64)], with_alpha: bool, f32_level: Option<SimdLevel>) -> (f64, f64) {
    let dirs = directions(N, 11);
    let mats: Vec<Material> = el.iter().map(|&e| material_for(paint, e, with_alpha)).collect();
    let (f, p) = run_varying(&Material::from_json(paint).unwrap(), el, with_alpha, f32_level);
    let (mut ef, mut ep) = (0.0f64, 0.0f64);
    for (i, (a, b)) in dirs.iter().enumerate() {
        let mat = &mats[i % el.len()];
        let want = mat.eval(*a, *b);
        let want_p = mat.pdf(*a, *b);
        for c in 0..3 {
            let e = (f[3 * i + c] - want[c]).abs() / (want[c].abs() + 1e-3);
            assert!(e.is_finite(), "element {i}: {} vs {}", f[3 * i + c], want[c]);
            ef = ef.max(e);
        }
        ep = ep.max((p[i] - want_p).abs() / (want_p.abs() + 1e-3));
    }
    (ef, ep)
}

/// The top reflection and single-scatter terms use no layer table, and the density with the
/// material's own lobe-selection weights is fixed by the parameters: per element they equal
/// the material built with the element's parameters to rounding (f64; asserted 1e-11 relative,
/// measured ≤ 4e-15), with α at the grid's nodes.
#[test]
fn table_free_terms_and_density_equal_the_material_per_element() {
    let at_nodes: Vec<f64> = [0, 6, 14, 25, 31].map(alpha_node).to_vec();
    let dirs = directions(97, 5);
    let mut worst = 0.0f64;
    for paint in PAINTS {
        let m = Material::from_json(paint).unwrap();
        for (alphas, with_alpha) in [(vec![0.0], false), (at_nodes.clone(), true)] {
            let vp = m.varying_paint(with_alpha).unwrap();
            for e in elements(&alphas) {
                let mat = material_for(paint, e, with_alpha);
                let lacquer::Model::CoatedPaint(cp) = mat.model() else { unreachable!() };
                let alpha = if with_alpha { e.2 } else { vp.defaults().2 };
                for (wi, wo) in dirs.iter().filter(|(a, b)| a.z > 0.0 && b.z > 0.0) {
                    let want = cp.eval_terms(*wi, *wo);
                    let got = vp.eval_terms(e.0, e.1 / 100.0, alpha, *wi, *wo);
                    for t in 0..2 {
                        for c in 0..3 {
                            let err = (got[t][c] - want[t][c]).abs() / want[t][c].abs().max(1e-6);
                            worst = worst.max(err);
                            assert!(err < 1e-11, "{paint} {e:?} term {t}: {:?} vs {:?}", got[t], want[t]);
                        }
                    }
                    let (a1, mm) = cp.layer_albedos(wo.z);
                    let mean = |x: [f64; 3]| (x[0] + x[1] + x[2]) / 3.0;
                    // (the cosine lobe's weight holds the coat's multiple-scattering reflection,
                    // the layer lobe's the metal base's bounce series)
                    let sel = [
                        cp.coat().reflectance(wo.z),
                        mean(a1) + cp.spec_series_albedo(wo.z),
                        mean(mm) + cp.coat().ms_albedo(wo.z),
                    ];
                    let (got, want) =
                        (vp.pdf_with_selection(e.0, e.1 / 100.0, alpha, *wi, *wo, sel), mat.pdf(*wi, *wo));
                    let err = (got - want).abs() / want.abs().max(1e-6);
                    worst = worst.max(err);
                    assert!(err < 1e-11, "{paint} {e:?} pdf: {got} vs {want}");
                }
            }
        }
    }
    eprintln!("largest relative difference: {worst:.2e}");
}

/// For a plain pigment (no flakes, no metal, no pearl), the components' tables use the
/// material's own sampler: the whole BRDF and density agree to rounding (f64; asserted 1e-11,
/// measured ≤ 1.2e-13).
#[test]
fn pigment_only_paint_equals_the_material_exactly() {
    let paint = r#"{"model": "coated_paint", "flake_density": 0, "coat_absorption": [1, 0, 3], "sparkle": false}"#;
    let el: Vec<([f64; 3], f64, f64)> = elements(&[0.0]).into_iter().map(|(c, _, a)| (c, 0.0, a)).collect();
    let (ef, ep) = compare(paint, &el, false, None);
    eprintln!("pigment only: f {ef:.2e}, pdf {ep:.2e}");
    assert!(ef < 1e-11 && ep < 1e-11, "f {ef:e} pdf {ep:e}");
}

/// The whole BRDF and density per element against a material built with the element's
/// parameters. The difference is the two Monte Carlo estimates of the layer tables (the
/// material's mixture sampler vs each component's own). Until issue 17 both estimated the
/// basecoat's mean albedo ρ̄ with incidence directions that were not independent of the
/// samples, which put the material's `M` table 5 % (red) to 20 % (green, blue) off and this
/// difference at f 2.6e-2, pdf 2.0e-2. With independent directions
/// (`coated_paint::mean_albedo`) the measured max relative difference (floor 1e-3) is f 6.1e-3,
/// pdf 5.2e-3; asserted 1e-2. Off the α grid's nodes (32 nodes uniform in ln α) the same:
/// f 6.2e-3, pdf 5.0e-3 measured (8.4e-3, 7.3e-3 with the rough coat's transmission blur of
/// issue 17 item 3, whose tables vary more with α; 5.9e-3, 5.3e-3 since the flakes' crossing
/// factor of a rough coat; session 36, the metal series widened per later bounce from smoothed
/// walks: at most 4.3e-3, 4.0e-3 at and off the nodes, 5.4e-3, 4.2e-3 with α fixed), asserted 1e-2 (16 nodes uniform in √α and the old ρ̄ gave
/// 6.4e-2, 5.9e-2).
#[test]
fn every_element_matches_a_material_built_with_its_parameters() {
    let _g = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let at_nodes: Vec<f64> = [0, 6, 14, 25, 31].map(alpha_node).to_vec();
    let off_nodes: Vec<f64> = [0.0015, 0.02, 0.07, 0.2, 0.43].to_vec();
    for paint in PAINTS {
        for (alphas, with_alpha, tf, tp) in [
            (vec![0.0], false, 1e-2, 1e-2),
            (at_nodes.clone(), true, 1e-2, 1e-2),
            (off_nodes.clone(), true, 1e-2, 1e-2),
        ] {
            let (ef, ep) = compare(paint, &elements(&alphas), with_alpha, None);
            eprintln!("f64 α varies {with_alpha}: f {ef:.3e} pdf {ep:.3e}  {paint}");
            assert!(ef < tf && ep < tp, "f {ef:e} pdf {ep:e}");
        }
    }
}

/// The α interpolation alone: the α-grid tables at an α between nodes against the fixed-α
/// tables of a material built at that α (the same estimator and samples, so the Monte Carlo
/// noise cancels), per term of `f` (relative to |f| + 1e-3) and for the pdf (relative to
/// |pdf| + 1e-3), f64. With 32 nodes uniform in ln α, measured: top reflection 0 (evaluated
/// with the element's own α), layer 1.3e-3, multiple scatter 1.1e-3, pdf 1.7e-3 (worst at
/// α = 0.003; 16 nodes uniform in √α gave 7.5e-2, 5.9e-2, 9.4e-2); asserted 3e-3 until issue
/// 17 item 3. Since then the rough coat blurs the base's specular lobes (`paint::coat::
/// TransmissionBlur`), so the tables depend on α also through the blurred basecoat (which
/// lobes fall outside the escape cone): measured layer 1.3e-3, multiple scatter 4.2e-3, pdf
/// 5.0e-3, both worst at α = 0.43 (at α ≤ 0.2: 2.5e-3, 2.1e-3); asserted 6e-3.
#[test]
fn alpha_interpolation_error_against_fixed_alpha_tables() {
    let off_nodes = [0.0015, 0.003, 0.02, 0.07, 0.2, 0.43];
    let dirs = directions(61, 23);
    let mut worst = [0.0f64; 4];
    for paint in [PAINTS[0], PAINTS[2]] {
        let m = Material::from_json(paint).unwrap();
        let grid = m.varying_paint(true).unwrap();
        // Every α with every colour and density (5 elements per call of `elements`).
        for e in elements(&off_nodes).into_iter().chain(elements(&off_nodes[1..])) {
            let mat = material_for(paint, e, true);
            let fixed = mat.varying_paint(false).unwrap();
            let mut w = [0.0f64; 4];
            for (wi, wo) in dirs.iter().filter(|(a, b)| a.z > 0.0 && b.z > 0.0) {
                let (g, h) = (
                    grid.eval_terms(e.0, e.1 / 100.0, e.2, *wi, *wo),
                    fixed.eval_terms(e.0, e.1 / 100.0, e.2, *wi, *wo),
                );
                let sum = |t: &[lacquer::Rgb<f64>; 3], c: usize| t[0][c] + t[1][c] + t[2][c];
                for c in 0..3 {
                    for t in 0..3 {
                        w[t] = w[t].max((g[t][c] - h[t][c]).abs() / (sum(&h, c).abs() + 1e-3));
                    }
                }
                let (pg, ph) = (
                    grid.eval_pdf_one(e.0, e.1 / 100.0, e.2, *wi, *wo).1,
                    fixed.eval_pdf_one(e.0, e.1 / 100.0, e.2, *wi, *wo).1,
                );
                w[3] = w[3].max((pg - ph).abs() / (ph.abs() + 1e-3));
            }
            eprintln!("α {:.4}: top {:.2e} layer {:.2e} multiple {:.2e} pdf {:.2e}", e.2, w[0], w[1], w[2], w[3]);
            for k in 0..4 {
                worst[k] = worst[k].max(w[k]);
            }
        }
    }
    eprintln!("worst: top {:.2e} layer {:.2e} multiple {:.2e} pdf {:.2e}", worst[0], worst[1], worst[2], worst[3]);
    // Layer and multiple scatter as before (measured 1.0e-3 / 4.1e-3). Since session 35 the metal
    // series' tables come from walks (`paint::spec_series`), whose noise differs from one coat α
    // to the next: layer measured 5.9e-3 (α 0.02, the metal paint; 9.9e-3 before the first
    // bounce took four times the walks) — the bound's margin is thin; more walks or a smoothing of
    // the walked targets over α would widen it. Session 36: the series' width follows each
    // direction's later-bounce count `n` from the walks, so their noise moves the lobe's width
    // too (measured 6.8e-3 unsmoothed); with the walks smoothed over neighbouring μ nodes
    // (`spec_series`) measured 4.3e-3 (α 0.07, the metal paint). Since issue 17 item 3.1
    // the top reflection holds the coat's multiple-scattering lobe ΔR(μi)ΔR(μo)/(πΔR̄), whose ΔR
    // is read from the α grid (the GGX lobe itself stays exact): measured 1.7e-2 at grazing pairs
    // (α 0.02), asserted 3e-2; the pdf's cosine weight holds ΔR too: measured 8.2e-3 (α 0.07),
    // asserted 1e-2 (5.0e-3 before the term).
    assert!(worst[1] < 6e-3 && worst[2] < 6e-3, "{worst:?}");
    assert!(worst[0] < 3e-2 && worst[3] < 1e-2, "{worst:?}");
}

/// Every SIMD level (and scalar f32) against the f64 reference of the same call, per element:
/// relative to |f| + 1e-3, measured ≤ 1.2e-6 (f) and ≤ 7.1e-7 (pdf); asserted 1e-5.
#[test]
fn simd_levels_agree_with_the_f64_reference() {
    let _g = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let at_nodes: Vec<f64> = [0.0015, 0.02, 0.07, 0.2, 0.43].to_vec();
    for paint in PAINTS {
        // One material per paint: every level reads the same tables (built once).
        let m = Material::from_json(paint).unwrap();
        for (alphas, with_alpha) in [(vec![0.0], false), (at_nodes.clone(), true)] {
            let el = elements(&alphas);
            let (f64f, f64p) = run_varying(&m, &el, with_alpha, None);
            for l in crate::simd_levels() {
                let (f, p) = run_varying(&m, &el, with_alpha, Some(l));
                let ef = f.iter().zip(&f64f).map(|(a, b)| (a - b).abs() / (b.abs() + 1e-3)).fold(0.0, f64::max);
                let ep = p.iter().zip(&f64p).map(|(a, b)| (a - b).abs() / (b.abs() + 1e-3)).fold(0.0, f64::max);
                eprintln!("{l:?} α varies {with_alpha}: f {ef:.2e} pdf {ep:.2e}");
                assert!(ef < 1e-5 && ep < 1e-5, "{l:?} {paint}: f {ef:e} pdf {ep:e}");
            }
        }
    }
    batch::set_simd_level(SimdLevel::detect());
}

/// Invalid per-element values (NaN, out of range, density + pearl over 100 %, α outside
/// [0.001, 0.5]) zero that element, are counted and the first is named; inactive elements are
/// zero and not counted; the other elements are unchanged; nothing is NaN. Every SIMD level.
#[test]
fn invalid_parameters_and_masked_lanes_are_zero_and_reported() {
    let _g = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let paint = PAINTS[2];
    let m = Material::from_json(paint).unwrap();
    let n = 37;
    let dirs = directions(n, 3);
    let wi: Vec<f32> = dirs.iter().flat_map(|d| [d.0.x, d.0.y, d.0.z]).map(|x| x as f32).collect();
    let wo: Vec<f32> = dirs.iter().flat_map(|d| [d.1.x, d.1.y, d.1.z]).map(|x| x as f32).collect();
    let good_r = vec![0.5f32; n];
    let (mut r, mut d, mut a) = (vec![0.5f32; n], vec![4.0f32; n], vec![0.1f32; n]);
    r[3] = f32::NAN;
    r[5] = 1.5;
    r[6] = -0.1;
    d[8] = 95.0; // + 10 % pearl > 100 %
    d[9] = f32::INFINITY;
    a[11] = 0.0;
    a[12] = 0.6;
    a[13] = f32::NAN;
    let bad = [3, 5, 6, 8, 9, 11, 12, 13];
    let mut active = vec![1u8; n];
    active[20] = 0;
    active[5] = 0; // inactive and invalid: not counted
    for l in crate::simd_levels() {
        assert!(batch::set_simd_level(l));
        let run = |r: &[f32], d: &[f32], a: &[f32]| {
            let tex = PaintTexture {
                base_color: Some([r, &good_r[..], &good_r[..]]),
                flake_density: Some(d),
                coat_roughness: Some(a),
            };
            let (mut f, mut p) = (vec![9.0f32; 3 * n], vec![9.0f32; n]);
            let rep = batch::eval_pdf_varying(
                &m,
                &tex,
                &Src3::interleaved(&wi),
                &Src3::interleaved(&wo),
                Some(&active),
                Some(&Dst3::interleaved(&mut f)),
                Some(&Dst1::new(&mut p)),
            )
            .unwrap();
            (rep, f, p)
        };
        let (rep, f, p) = run(&r, &d, &a);
        assert_eq!(rep.invalid_params, bad.len() - 1, "{l:?} {rep:?}");
        assert_eq!(rep.first_invalid_param, Some(3));
        let (_, f_ok, p_ok) = run(&good_r, &vec![4.0; n], &vec![0.1; n]);
        for i in 0..n {
            assert!(f[3 * i..3 * i + 3].iter().all(|x| x.is_finite()) && p[i].is_finite());
            if bad.contains(&i) || active[i] == 0 {
                assert_eq!((&f[3 * i..3 * i + 3], p[i]), (&[0.0f32; 3][..], 0.0), "{l:?} element {i}");
            } else if r[i] == good_r[i] && d[i] == 4.0 && a[i] == 0.1 {
                assert_eq!((&f[3 * i..3 * i + 3], p[i]), (&f_ok[3 * i..3 * i + 3], p_ok[i]), "{l:?} element {i}");
            }
        }
        // Sampling: the same elements fail with SAMPLE_INVALID_INPUT.
        let u: Vec<f32> = (0..3 * n).map(|k| ((k * 7919) % 1000) as f32 / 1000.0).collect();
        let tex = PaintTexture {
            base_color: Some([&r[..], &good_r[..], &good_r[..]]),
            flake_density: Some(&d[..]),
            coat_roughness: Some(&a[..]),
        };
        let (mut swi, mut sw, mut sp, mut fl) =
            (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; n], vec![0u32; n]);
        let mut out = SampleOut {
            wi: Dst3::interleaved(&mut swi),
            weight: Dst3::interleaved(&mut sw),
            pdf: Dst1::new(&mut sp),
            flags: Some(&mut fl),
        };
        let rep =
            batch::sample_varying(&m, &tex, &Src3::interleaved(&wo), &Src3::interleaved(&u), Some(&active), &mut out)
                .unwrap();
        assert_eq!(rep.invalid_params, bad.len() - 1, "{l:?} {rep:?}");
        for i in 0..n {
            if active[i] == 0 {
                assert_eq!(fl[i], 0);
            } else if bad.contains(&i) {
                assert_eq!(fl[i], SAMPLE_FAILED | SAMPLE_INVALID_INPUT, "{l:?} element {i}");
                assert_eq!((sp[i], &sw[3 * i..3 * i + 3]), (0.0, &[0.0f32; 3][..]));
            }
        }
    }
    batch::set_simd_level(SimdLevel::detect());
}

/// A sample's weight is `f cos θi / pdf` and its pdf the density of the same call at the
/// sampled direction, per element (f64 reference of eval/pdf vs the f32 sampler: relative to
/// |x| + 1e-3, measured ≤ 7.3e-4 — the f32 sampler on a coat of α = 0.0015, whose peak moves
/// that much with f32 rounding — and ≤ 1e-6 elsewhere; asserted 2e-3), for every SIMD level;
/// smooth-coat mirror samples are flagged delta.
#[test]
fn samples_are_consistent_with_eval_and_pdf() {
    let _g = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    for (paint, with_alpha) in [(PAINTS[0], true), (PAINTS[1], false), (PAINTS[2], false)] {
        let m = Material::from_json(paint).unwrap();
        let n = 301;
        let el = elements(&[0.0015, 0.02, 0.07, 0.2, 0.43]);
        let t = texture(&el, n);
        let to32 = |v: &Vec<f64>| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let (r32, d32, a32) = (t.rgb.each_ref().map(to32), to32(&t.density), to32(&t.alpha));
        let tex = PaintTexture {
            base_color: Some([&r32[0][..], &r32[1][..], &r32[2][..]]),
            flake_density: Some(&d32[..]),
            coat_roughness: with_alpha.then_some(&a32[..]),
        };
        let dirs = directions(n, 17);
        let wo: Vec<f32> = dirs.iter().flat_map(|d| [d.1.x, d.1.y, d.1.z.abs()]).map(|x| x as f32).collect();
        let mut rng = Pcg32::new(9, 1);
        let u: Vec<f32> = (0..3 * n).map(|_| rng.uniform() as f32).collect();
        for l in crate::simd_levels() {
            assert!(batch::set_simd_level(l));
            let (mut swi, mut sw, mut sp, mut fl) =
                (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; n], vec![0u32; n]);
            let mut out = SampleOut {
                wi: Dst3::interleaved(&mut swi),
                weight: Dst3::interleaved(&mut sw),
                pdf: Dst1::new(&mut sp),
                flags: Some(&mut fl),
            };
            let rep = batch::sample_varying(&m, &tex, &Src3::interleaved(&wo), &Src3::interleaved(&u), None, &mut out)
                .unwrap();
            assert!(rep.ok());
            // f64 eval/pdf at the sampled directions.
            let wi64: Vec<f64> = swi.iter().map(|&x| f64::from(x)).collect();
            let wo64: Vec<f64> = wo.iter().map(|&x| f64::from(x)).collect();
            let tex64 = PaintTexture {
                base_color: Some([&t.rgb[0][..], &t.rgb[1][..], &t.rgb[2][..]]),
                flake_density: Some(&t.density[..]),
                coat_roughness: with_alpha.then_some(&t.alpha[..]),
            };
            let (mut f, mut p) = (vec![0.0f64; 3 * n], vec![0.0f64; n]);
            batch::eval_pdf_varying_f64(
                &m,
                &tex64,
                &Src3::interleaved(&wi64),
                &Src3::interleaved(&wo64),
                None,
                Some(&Dst3::interleaved(&mut f)),
                Some(&Dst1::new(&mut p)),
            )
            .unwrap();
            let (mut checked, mut deltas, mut worst) = (0, 0, 0.0f64);
            for i in 0..n {
                if fl[i] & batch::SAMPLE_DELTA != 0 {
                    deltas += 1;
                    continue;
                }
                if fl[i] != 0 {
                    continue;
                }
                checked += 1;
                let e = (f64::from(sp[i]) - p[i]).abs() / (p[i] + 1e-3);
                worst = worst.max(e);
                for c in 0..3 {
                    let want = f[3 * i + c] * wi64[3 * i + 2] / p[i];
                    worst = worst.max((f64::from(sw[3 * i + c]) - want).abs() / (want.abs() + 1e-3));
                }
            }
            eprintln!("{l:?} {paint}: {checked} samples, {deltas} delta, worst {worst:.2e}");
            assert!(checked + deltas > n / 2 && worst < 2e-3, "{l:?}: {checked} checked, worst {worst:e}");
            assert_eq!(deltas > 0, !with_alpha && paint.contains(r#""coat_roughness": 0,"#));
        }
    }
    batch::set_simd_level(SimdLevel::detect());
}

/// Without a texture the calls are the material's own batch calls (bit-identical); a texture
/// on another model, or shorter than the batch, is an error.
#[test]
fn no_texture_is_the_material_and_bad_inputs_are_errors() {
    let m = Material::from_json(PAINTS[0]).unwrap();
    let n = 19;
    let dirs = directions(n, 1);
    let wi: Vec<f32> = dirs.iter().flat_map(|d| [d.0.x, d.0.y, d.0.z]).map(|x| x as f32).collect();
    let wo: Vec<f32> = dirs.iter().flat_map(|d| [d.1.x, d.1.y, d.1.z]).map(|x| x as f32).collect();
    let (mut f1, mut f2) = (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n]);
    let (a, b) = (Src3::interleaved(&wi), Src3::interleaved(&wo));
    batch::eval_pdf(&m, &a, &b, None, Some(&Dst3::interleaved(&mut f1)), None).unwrap();
    batch::eval_pdf_varying(&m, &PaintTexture::default(), &a, &b, None, Some(&Dst3::interleaved(&mut f2)), None)
        .unwrap();
    assert_eq!(f1, f2);
    let short = vec![3.0f32; n - 1];
    let tex = PaintTexture { flake_density: Some(&short[..]), ..Default::default() };
    let err = batch::eval_pdf_varying(&m, &tex, &a, &b, None, Some(&Dst3::interleaved(&mut f2)), None).unwrap_err();
    assert!(err.0.contains("texture"), "{err}");
    let lambert = Material::from_json(r#"{"model": "lambert"}"#).unwrap();
    let full = vec![3.0f32; n];
    let tex = PaintTexture { flake_density: Some(&full[..]), ..Default::default() };
    let err =
        batch::eval_pdf_varying(&lambert, &tex, &a, &b, None, Some(&Dst3::interleaved(&mut f2)), None).unwrap_err();
    assert!(err.0.contains("coated_paint"), "{err}");
    // The EON pigment is not linear in its colour: no component tables, a clear error.
    let eon = Material::from_json(r#"{"model": "coated_paint", "pigment_model": "eon"}"#).unwrap();
    let err = batch::eval_pdf_varying(&eon, &tex, &a, &b, None, Some(&Dst3::interleaved(&mut f2)), None).unwrap_err();
    assert!(err.0.contains("pigment_model"), "{err}");
}

/// Cost of per-element parameters against the untextured paint (docs/speed.md): ns per
/// element of `eval_pdf` and `eval_pdf_varying` (f, pdf) at the detected SIMD level, one
/// thread. Not a CI test: `cargo test --release -p lacquer --test integration -- --ignored --nocapture varying::cost`.
#[test]
#[ignore]
fn cost_against_the_untextured_paint() {
    let _g = GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    batch::set_thread_count(1);
    let n = 1 << 16;
    let dirs = directions(n, 2);
    let wi: [Vec<f32>; 3] = [0, 1, 2].map(|c| dirs.iter().map(|d| [d.0.x, d.0.y, d.0.z][c] as f32).collect());
    let wo: [Vec<f32>; 3] = [0, 1, 2].map(|c| dirs.iter().map(|d| [d.1.x, d.1.y, d.1.z.abs()][c] as f32).collect());
    let t = texture(&elements(&[0.0015, 0.02, 0.07, 0.2, 0.43]), n);
    let to32 = |v: &Vec<f64>| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let (r32, d32, a32) = (t.rgb.each_ref().map(to32), to32(&t.density), to32(&t.alpha));
    let (a, b) = (Src3::soa(&wi[0], &wi[1], &wi[2]).unwrap(), Src3::soa(&wo[0], &wo[1], &wo[2]).unwrap());
    let (mut f, mut p) = (vec![0.0f32; 3 * n], vec![0.0f32; n]);
    for paint in [PAINTS[0], PAINTS[2]] {
        let m = Material::from_json(paint).unwrap();
        let t0 = std::time::Instant::now();
        let _ = m.varying_paint(false);
        let t1 = std::time::Instant::now();
        let _ = m.varying_paint(true);
        eprintln!(
            "{paint}\n  tables: {:.0} ms (fixed α), {:.0} ms (α grid)",
            (t1 - t0).as_secs_f64() * 1e3,
            t1.elapsed().as_secs_f64() * 1e3
        );
        let cases: [(&str, PaintTexture<f32>); 4] = [
            ("untextured (eval_pdf)", PaintTexture::default()),
            (
                "base_color",
                PaintTexture { base_color: Some([&r32[0][..], &r32[1][..], &r32[2][..]]), ..Default::default() },
            ),
            (
                "base_color + flake_density",
                PaintTexture {
                    base_color: Some([&r32[0][..], &r32[1][..], &r32[2][..]]),
                    flake_density: Some(&d32[..]),
                    coat_roughness: None,
                },
            ),
            (
                "all three",
                PaintTexture {
                    base_color: Some([&r32[0][..], &r32[1][..], &r32[2][..]]),
                    flake_density: Some(&d32[..]),
                    coat_roughness: Some(&a32[..]),
                },
            ),
        ];
        for (name, tex) in cases {
            let mut best = f64::MAX;
            for _ in 0..5 {
                let s = std::time::Instant::now();
                batch::eval_pdf_varying(
                    &m,
                    &tex,
                    &a,
                    &b,
                    None,
                    Some(&Dst3::interleaved(&mut f)),
                    Some(&Dst1::new(&mut p)),
                )
                .unwrap();
                best = best.min(s.elapsed().as_secs_f64() * 1e9 / n as f64);
            }
            eprintln!("  {:?} {name}: {best:.1} ns/element", batch::simd_level());
        }
    }
    batch::set_thread_count(0);
}
