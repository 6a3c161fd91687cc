//! Render job / scene JSON (what `lq_render`, the CLI and the Blender engine pass): parse, build
//! the scene (inline meshes, spheres, quads, lights, materials, transforms, cameras) and render
//! it at ≤ 8 × 8 pixels, ≤ 2 spp, depth ≤ 4 on one thread, so that the fuzzer spends its time
//! on the parser and the scene builder. Fails on a panic, a hang (-timeout) or an allocation
//! blow-up (-rss_limit_mb), and on a NaN in the image (the integrator must not let one through).
#![no_main]

use lacquer_render::{render, RenderJob};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(mut job) = RenderJob::from_json(text) else { return };
    job.width = job.width.min(8);
    job.height = job.height.min(8);
    job.spp = job.spp.min(2);
    job.max_depth = job.max_depth.min(4);
    job.threads = 1;
    let Ok(scene) = job.scene() else { return };
    let fb = render(&scene, &job.settings(), &mut |_| true).expect("never cancelled");
    assert!(fb.color.iter().flatten().all(|x| !x.is_nan()), "NaN pixel: {text}");
});
