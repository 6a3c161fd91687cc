//! Material JSON → parse, validate, build → eval / pdf / sample (f32 and f64) at adversarial
//! directions. Fails on a panic (libFuzzer aborts on any panic), on a NaN from a successfully
//! built material at finite inputs, and on hangs / allocation blow-ups (-timeout, -rss_limit_mb).
#![no_main]

use lacquer_core::math::Vec3;
use lacquer_core::Material;
use libfuzzer_sys::fuzz_target;

/// Directions a host can send: unit, grazing to 1e-7, below the horizon, non-unit, denormal,
/// huge, ±wo.
const DIRS: [[f64; 3]; 10] = [
    [0.0, 0.0, 1.0],
    [0.6, 0.0, 0.8],
    [-0.36, 0.48, 0.8],
    [1.0, 0.0, 1e-7],
    [0.0, -1.0, 1e-30],
    [0.3, 0.2, -0.9],
    [3.0, 4.0, 12.0],
    [1e-40, 0.0, 1e-40],
    [1e30, -1e30, 1e30],
    [-0.6, 0.0, 0.8],
];
const US: [[f64; 3]; 4] = [[0.0; 3], [0.5, 0.5, 0.5], [0.999_999_9, 0.999_999_9, 0.999_999_9], [0.3, 1e-30, 0.7]];

fn v(d: [f64; 3]) -> Vec3<f64> {
    Vec3::new(d[0], d[1], d[2])
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(m) = Material::from_json(text) else { return };
    // The canonical JSON of a built material builds again.
    let again = Material::from_json(&m.to_json().to_string()).expect("a material's own JSON builds");
    drop(again);
    for (a, wi) in DIRS.iter().enumerate() {
        for wo in DIRS.iter().skip(a % 3).step_by(3) {
            let f = m.eval(v(*wi), v(*wo));
            let p = m.pdf(v(*wi), v(*wo));
            assert!(!(f.r.is_nan() || f.g.is_nan() || f.b.is_nan() || p.is_nan()), "{text}: {wi:?} {wo:?} → {f:?} {p}");
            let f = m.eval(v(*wi).cast::<f32>(), v(*wo).cast::<f32>());
            let p = m.pdf(v(*wi).cast::<f32>(), v(*wo).cast::<f32>());
            assert!(
                !(f.r.is_nan() || f.g.is_nan() || f.b.is_nan() || p.is_nan()),
                "{text}: f32 {wi:?} {wo:?} → {f:?} {p}"
            );
        }
        for u in &US {
            if let Some(s) = m.sample(v(*wi), *u) {
                assert!(!(s.weight.r.is_nan() || s.pdf.is_nan() || s.wi.x.is_nan()), "{text}: sample {wi:?} {u:?}");
            }
            if let Some(s) = m.sample(v(*wi).cast::<f32>(), u.map(|x| x as f32)) {
                assert!(!(s.weight.r.is_nan() || s.pdf.is_nan() || s.wi.x.is_nan()), "{text}: f32 sample {wi:?} {u:?}");
            }
        }
    }
});
