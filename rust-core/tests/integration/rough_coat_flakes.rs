//! Issue 17, item 3 (session 40): the flakes under a rough coat, at their share of the rough
//! interface's mean refraction (`Coat::flake_refract_in`, `coat::FLAKE_MEAN_REFRACTION_SHARE`)
//! instead of a share of the transmission blur, against the lossless position-free reference
//! (`paint::position_free_mc`, Heitz et al. 2016's multiple-scattering interface). The energy
//! of the map: `coated_paint::tests::flakes_at_the_mean_refraction_conserve_energy`; the full
//! table: `examples/rough_coat_validation.rs`, docs §8.

use lacquer::paint::coated_paint::CoatedPaint;
use lacquer::paint::position_free_mc::{lobe_bin, PositionFreeMc};
use lacquer::rng::Pcg32;
use lacquer::{Bxdf, Material, Model, Vec3};

fn paint(json: &str) -> CoatedPaint {
    let m = Material::from_json(json).expect("valid paint");
    let Model::CoatedPaint(p) = m.model() else { panic!("not a coated paint: {json}") };
    p.clone()
}

fn direction(theta_deg: f64) -> Vec3<f64> {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// The relative L2 difference of two lobes over the same bins, each normalised to unit sum.
fn lobe_l2(a: &[f64], r: &[f64]) -> f64 {
    let (ta, tr): (f64, f64) = (a.iter().sum(), r.iter().sum());
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in a.iter().zip(r) {
        num += (x / ta - y / tr).powi(2);
        den += (y / tr).powi(2);
    }
    (num / den).sqrt()
}

/// The light that crossed the coat (the "body": everything but the top reflection) of Al
/// flakes 8 % over a dark pigment under a coat of α 0.3 seen at θo 75°: its lobe shape against
/// the reference's walks that entered the coat, relative L2 over 12 × 6 equal-solid-angle bins,
/// 200 000 walks and model samples (the model's body: its layer and multiple-scatter terms
/// weighted by `cos θi/pdf` at the paint's own samples). The rough interface lets the flakes'
/// light out beyond the macro critical angle, which the blurred lobe at the macro refraction
/// (sessions 23–39) sent back too far toward the viewer: 16.8 % in the validation table
/// (400 000 walks, noise removed; noise floor there 2.1 %); the flakes at their share of the
/// mean refraction: 11.0 % there, measured here (raw L2, the noise included) in the output.
/// Asserted below 14 % (fails on the old model). ≈ 2 s in release.
#[test]
fn flakes_light_through_a_rough_coat_at_grazing_view_matches_the_reference() {
    let p = paint(
        r#"{"model": "coated_paint", "coat_roughness": 0.3, "flake_density": 8, "base_color": [0.05, 0.05, 0.06], "sparkle": false}"#,
    );
    let wo = direction(75.0);
    let (n_mu, n_phi, walks) = (12, 6, 200_000);
    let mc = PositionFreeMc::new(&p);
    let (mut reference, mut model) = (vec![0.0; n_mu * n_phi], vec![0.0; n_mu * n_phi]);
    let mut rng = Pcg32::new(0xf1a4e, 75);
    for _ in 0..walks {
        if let Some(e) = mc.albedo_walk_exit(wo, &mut rng) {
            if e.entered {
                reference[lobe_bin(e.direction, 0.0, n_mu, n_phi)] += e.weight.luminance();
            }
        }
    }
    let mut rng = Pcg32::new(0xf1a4e, 76);
    for _ in 0..walks {
        let Some(s) = p.sample(wo, rng.uniform3()) else { continue };
        if s.wi.z <= 0.0 || s.delta {
            continue;
        }
        let [_, layer, multiple] = p.eval_terms(s.wi, wo);
        model[lobe_bin(s.wi, 0.0, n_mu, n_phi)] += ((layer + multiple) * (s.wi.z / s.pdf)).luminance();
    }
    let err = lobe_l2(&model, &reference);
    eprintln!("Al flakes 8 %, coat α 0.3, θo 75°: body lobe-shape error {:.2} %", 100.0 * err);
    assert!(err < 0.14, "body lobe-shape error {err}");
}
