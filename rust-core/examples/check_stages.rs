//! Development aid: time each check stage on one material.
use lacquer::check::{chi2_test, furnace, hard_cases, precision, reciprocity, CheckConfig};
use lacquer::Material;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let m = Material::from_json(&args[1]).unwrap();
    if args.get(2).map(String::as_str) == Some("time") {
        let mut rng = lacquer::rng::Pcg32::new(1, 1);
        let dirs: Vec<_> = (0..4096)
            .map(|_| {
                (
                    lacquer::sampling::uniform_hemisphere(rng.uniform(), rng.uniform()),
                    lacquer::sampling::uniform_hemisphere(rng.uniform(), rng.uniform()),
                )
            })
            .collect();
        let t = Instant::now();
        for (a, b) in &dirs {
            std::hint::black_box(m.eval(*a, *b));
        }
        let e = t.elapsed().as_nanos() / 4096;
        let t = Instant::now();
        for (a, b) in &dirs {
            std::hint::black_box(m.pdf(*a, *b));
        }
        println!("eval {e} ns, pdf {} ns", t.elapsed().as_nanos() / 4096);
        return;
    }
    let cfg = if args.get(2).map(String::as_str) == Some("quick") { CheckConfig::quick() } else { CheckConfig::standard() };
    let t = Instant::now();
    let r = reciprocity(&m, &cfg);
    println!("reciprocity {:.2e} in {:?}", r.max_relative_error, t.elapsed());
    let t = Instant::now();
    let f = furnace(&m, &cfg);
    println!("furnace [{:.4}, {:.4}] in {:?}", f.min_albedo, f.max_albedo, t.elapsed());
    let t = Instant::now();
    let h = hard_cases(&m);
    println!("hard cases {} in {:?}", h.failures(), t.elapsed());
    let t = Instant::now();
    let p = precision(&m, &cfg);
    println!("precision {:.1e} in {:?}", p.max_relative_error, t.elapsed());
    let t = Instant::now();
    let c = chi2_test(&m, &cfg);
    println!("chi2 {:?} in {:?}", c.iter().map(|c| c.p_value).collect::<Vec<_>>(), t.elapsed());
}
