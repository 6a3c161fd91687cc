//! Golden values from independent sources: closed forms derived by hand.

use lacquer::check::{furnace::albedo, CheckConfig};
use lacquer::rng::Pcg32;
use lacquer::{Material, Vec3};

/// Lambert's albedo equals ρ at every angle (∫ ρ/π cos dω = ρ).
#[test]
fn lambert_albedo_is_rho() {
    let m = Material::from_json(r#"{"model": "lambert", "albedo": [0.25, 0.5, 0.75]}"#).unwrap();
    let mut rng = Pcg32::new(3, 4);
    for c in [1.0f64, 0.5, 0.01] {
        let wo = Vec3::new((1.0 - c * c).sqrt(), 0.0, c);
        let (a, _) = albedo(&m, wo, 20_000, &mut rng);
        for (got, want) in a.iter().zip([0.25, 0.5, 0.75]) {
            assert!((got - want).abs() < 1e-3, "{got} vs {want}");
        }
    }
    // The standard configuration is what `lacquer check` runs; keep it deterministic.
    assert_eq!(CheckConfig::standard().seed, CheckConfig::quick().seed);
}
