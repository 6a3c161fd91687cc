//! Development aid: the worst f32-vs-f64 pair of a material.
use lacquer::rng::Pcg32;
use lacquer::{Material, Vec3};

fn main() {
    let m = Material::from_json(&std::env::args().nth(1).unwrap()).unwrap();
    let mut rng = Pcg32::new(0x1acc_0e12, 0x3232);
    let mut worst = (0.0, Vec3::<f64>::zero(), Vec3::<f64>::zero(), [0.0; 3], [0.0; 3], 0.0, 0.0);
    for _ in 0..4000 {
        let wi = lacquer::sampling::uniform_hemisphere(rng.uniform().max(1e-12), rng.uniform()).cast::<f32>();
        let wo = lacquer::sampling::uniform_hemisphere(rng.uniform().max(1e-12), rng.uniform()).cast::<f32>();
        let a = m.eval(wi.cast::<f64>(), wo.cast::<f64>());
        let b = m.eval(wi, wo).cast::<f64>();
        let pa = m.pdf(wi.cast::<f64>(), wo.cast::<f64>());
        let pb = m.pdf(wi, wo) as f64;
        for c in 0..3 {
            let e = (a[c] - b[c]).abs() / a[c].abs().max(1e-12);
            if e > worst.0 && a[c] > 1e-6 {
                worst = (e, wi.cast(), wo.cast(), a.to_array(), b.to_array(), pa, pb);
            }
        }
        let e = (pa - pb).abs() / pa.max(1e-12);
        if e > worst.0 && pa > 1e-6 {
            worst = (e, wi.cast(), wo.cast(), a.to_array(), b.to_array(), pa, pb);
        }
    }
    println!("{worst:?}");
    let (wi, wo) = (worst.1, worst.2);
    for scale in [1.0, 1.0 + 1e-15, 1.0 - 1e-15, 1.0 + 1e-12] {
        println!("scale {scale}: {:?}", m.model().eval(wi.normalize() * scale, wo.normalize()));
    }
}

#[allow(dead_code)]
fn probe2() {}
