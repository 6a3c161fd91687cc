//! MERL table loading: bytes → `MerlTable::from_bytes` → f32 evaluation.
//!
//! A valid table is 34,992,012 bytes, far beyond what libFuzzer mutates, so the input has two
//! modes. First byte even: the rest is the whole file (header and size paths). First byte odd:
//! the rest is a list of patches applied to a valid table's bytes — 4 bytes of byte offset
//! (modulo the file size) and 8 bytes written there (flipped bytes, 1e300, NaN, a bad header,
//! …). A table that loads must give finite, non-negative f32 values (`Material::eval::<f32>`
//! casts the f64 interpolation) at the patched nodes and at fixed directions.
#![no_main]

use lacquer_core::math::Vec3;
use lacquer_core::measured::merl::{self, MerlTable, FILE_BYTES, N_ENTRIES, N_PHI_D, N_THETA_D};
use lacquer_core::measured::parameterization::to_half_diff;
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn base() -> &'static [u8] {
    static BASE: OnceLock<Vec<u8>> = OnceLock::new();
    BASE.get_or_init(|| {
        MerlTable::from_fn(|wi, wo| {
            let hd = to_half_diff(wi, wo);
            let g = (-hd.theta_h * hd.theta_h / 0.01).exp();
            Some([0.1 + 20.0 * g, 0.05 + 10.0 * g, 0.2 + g])
        })
        .to_bytes()
    })
}

fn check_finite(t: &MerlTable, wi: Vec3<f64>, wo: Vec3<f64>) {
    let f = t.eval(wi, wo);
    for x in f {
        let x32 = x as f32;
        assert!(x32.is_finite() && x32 >= 0.0, "eval {wi:?} {wo:?} = {f:?}");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    let mut patched: Vec<usize> = Vec::new();
    let loaded = if mode % 2 == 0 {
        MerlTable::from_bytes(rest)
    } else {
        let mut bytes = base().to_vec();
        for p in rest.chunks_exact(12) {
            let at = u32::from_le_bytes(p[..4].try_into().unwrap()) as usize % (FILE_BYTES - 7);
            bytes[at..at + 8].copy_from_slice(&p[4..]);
            if at >= 12 {
                patched.push(((at - 12) / 8) % N_ENTRIES);
            }
        }
        MerlTable::from_bytes(&bytes)
    };
    let Ok(t) = loaded else { return };
    for i in patched {
        let (ih, id, ip) = (i / (N_THETA_D * N_PHI_D), (i / N_PHI_D) % N_THETA_D, i % N_PHI_D);
        if let Some((wi, wo)) = MerlTable::node_directions(ih, id, ip) {
            check_finite(&t, wi, wo);
        }
        assert!(!t.is_valid(i) || t.get(i).iter().all(|v| *v <= merl::MAX_BRDF));
    }
    for (wi, wo) in [
        (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0)),
        (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8)),
        (Vec3::new(0.3, 0.4, 0.866), Vec3::new(-0.8, 0.1, 0.59)),
    ] {
        check_finite(&t, wi.normalize(), wo.normalize());
    }
});
