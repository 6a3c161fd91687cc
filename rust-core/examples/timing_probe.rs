use lacquer::{Material, Vec3};
fn main() {
    for json in [r#"{"model":"coated_paint"}"#, r#"{"preset":"gold_flake_8"}"#, r#"{"model":"ward"}"#] {
        let t = std::time::Instant::now();
        let n = 20;
        for _ in 0..n { let _ = Material::from_json(json).unwrap(); }
        let build = t.elapsed().as_secs_f64() / n as f64;
        let m = Material::from_json(json).unwrap();
        let t = std::time::Instant::now();
        let mut s = 0.0;
        let k = 200_000;
        for i in 0..k {
            let a = i as f64 * 0.001;
            let wi = Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 0.95).normalize();
            let wo = Vec3::new(-0.5, 0.1 * a.sin(), 0.8).normalize();
            s += m.model().eval(wi, wo).r;
        }
        println!("{json}: build {:.3} ms, eval {:.3} us ({s})", build * 1e3, t.elapsed().as_secs_f64() / k as f64 * 1e6);
    }
}
