//! Probe: a high-statistics χ² run of one material (development aid).
use lacquer::check::{chi2_test, CheckConfig};
use lacquer::Material;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let m = Material::from_json(&args[1]).unwrap();
    let n: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(10_000_000);
    let mut cfg = CheckConfig::standard();
    cfg.chi2_samples = n;
    if let Some(c) = args.get(3) {
        let c: f64 = c.parse().unwrap();
        cfg.chi2_directions = vec![(c, 2.5)];
    }
    for seed in 0..3 {
        cfg.seed = seed;
        for c in chi2_test(&m, &cfg) {
            println!(
                "seed {seed} cos {} chi2 {:.1} dof {} p {:.4} int {:.5} outside {:.5} {}",
                c.cos_theta, c.chi2, c.dof, c.p_value, c.pdf_integral, c.outside_fraction, c.note
            );
        }
    }
}
