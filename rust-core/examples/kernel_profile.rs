//! Profiling aid: runs one batch operation of one material in a loop, so `perf record` /
//! `valgrind --tool=callgrind` see only that kernel.
//!
//! `cargo run --release -p lacquer --example kernel_profile -- <preset|material JSON> <eval|pdf|eval_pdf|sample> [n] [iterations] [threads, default 1] [soa|xyz, default soa] [warm|cold, default warm]`
//!
//! The last argument picks the array layout: `soa` (one array per component, what Dr.Jit hosts
//! hold) or `xyz` (interleaved `x y z` per element, what `lq_eval` and C/C++ renderers pass).
//! `cold` writes 256 MiB of other memory before each (timed) call, so the call's arrays come
//! from memory rather than from the caches, as in `bench/vs_mitsuba.py`, where the other
//! library's calls run between Lacquer's.
//!
//! Build it with the CLI, `cargo build --release -p lacquer-cli -p lacquer --example
//! kernel_profile`: with `-p lacquer` alone cargo resolves other features for the crates the
//! library shares with the CLI and the test build (num-traits, syn), so it compiles the
//! library a second time (6–7 min on this 2-core machine) instead of reusing theirs.
use lacquer::batch::{self, Dst1, Dst3, SampleOut, Src3};
use lacquer::Material;

/// Three component arrays, or one interleaved array (then `[xyz, [], []]`).
type Arrays = [Vec<f32>; 3];

fn src(a: &Arrays) -> Src3<'_, f32> {
    if a[1].is_empty() {
        Src3::interleaved(&a[0])
    } else {
        Src3::soa(&a[0], &a[1], &a[2]).expect("equal lengths")
    }
}

fn dst(a: &mut Arrays) -> Dst3<'_, f32> {
    let [x, y, z] = a;
    if y.is_empty() {
        Dst3::interleaved(x)
    } else {
        Dst3::soa(x, y, z).expect("equal lengths")
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage =
        "kernel_profile <preset|material JSON> <eval|pdf|eval_pdf|sample> [n] [iterations] [threads, default 1] [soa|xyz] [warm|cold]";
    let spec = args.get(1).expect(usage);
    let m = if spec.trim_start().starts_with('{') { Material::from_json(spec) } else { Material::preset(spec) }
        .expect("a preset name or material JSON");
    let op = args.get(2).map_or("eval", String::as_str);
    let n: usize = args.get(3).map_or(1 << 16, |s| s.parse().expect("n"));
    let iterations: usize = args.get(4).map_or(200, |s| s.parse().expect("iterations"));
    batch::set_thread_count(args.get(5).map_or(1, |s| s.parse().expect("threads")));
    // Deterministic directions in the upper hemisphere and uniform numbers.
    let mut state = 0x853c_49e6_748f_ea9b_u64;
    let mut next = move || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let mut dir = || {
        let (u1, u2) = (next(), next());
        let r = (1.0 - u1 * u1).sqrt();
        let phi = std::f32::consts::TAU * u2;
        [r * phi.cos(), r * phi.sin(), u1.max(1e-4)]
    };
    let xyz = match args.get(6).map_or("soa", String::as_str) {
        "soa" => false,
        "xyz" => true,
        _ => panic!("{usage}"),
    };
    let cold = match args.get(7).map_or("warm", String::as_str) {
        "warm" => false,
        "cold" => true,
        _ => panic!("{usage}"),
    };
    let mut evict = vec![0u8; if cold { 256 << 20 } else { 0 }];
    let soa = |v: Vec<[f32; 3]>| -> Arrays {
        if xyz {
            [v.as_flattened().to_vec(), Vec::new(), Vec::new()]
        } else {
            [0, 1, 2].map(|k| v.iter().map(|d| d[k]).collect())
        }
    };
    let wi = soa((0..n).map(|_| dir()).collect());
    let wo = soa((0..n).map(|_| dir()).collect());
    let uniform = soa((0..n).map(|_| [next(), next(), next()]).collect());
    let zeros = || soa(vec![[0f32; 3]; n]);
    let (mut out, mut w) = (zeros(), zeros());
    let mut pdf = vec![0f32; n];
    let (mut wall_ns, mut cpu_ns) = (0.0, Some(0));
    for k in 0..iterations {
        if cold {
            evict.fill(k as u8);
        }
        let (start, cpu_start) = (std::time::Instant::now(), thread_cpu_ns());
        let f = dst(&mut out);
        match op {
            "eval" => drop(batch::eval_pdf(&m, &src(&wi), &src(&wo), None, Some(&f), None)),
            "pdf" => drop(batch::eval_pdf(&m, &src(&wi), &src(&wo), None, None, Some(&Dst1::new(&mut pdf)))),
            "eval_pdf" => drop(batch::eval_pdf(&m, &src(&wi), &src(&wo), None, Some(&f), Some(&Dst1::new(&mut pdf)))),
            "sample" => {
                let mut s = SampleOut { wi: f, weight: dst(&mut w), pdf: Dst1::new(&mut pdf), flags: None };
                drop(batch::sample(&m, &src(&wo), &src(&uniform), None, &mut s));
            }
            _ => panic!("{usage}"),
        }
        wall_ns += start.elapsed().as_secs_f64() * 1e9;
        cpu_ns = match (cpu_ns, cpu_start, thread_cpu_ns()) {
            (Some(sum), Some(a), Some(b)) => Some(sum + (b - a)),
            _ => None,
        };
    }
    let per = |ns: f64| ns / (n * iterations) as f64;
    let wall = per(wall_ns);
    // The thread's CPU time is read per call here, and `schedstat` advances at scheduler
    // ticks: over cold calls (one per eviction) it is too coarse, so wall time only.
    let cpu = match cpu_ns {
        Some(ns) if !cold => format!(", {:.2} ns/element of this thread's CPU time", per(ns as f64)),
        _ => String::new(),
    };
    println!(
        "{op}: {wall:.2} ns/element wall{cpu} ({} lanes, {} threads, {} layout, {})",
        batch::simd_level().name(),
        batch::thread_count(),
        if xyz { "xyz" } else { "soa" },
        if cold { "cold caches" } else { "warm caches" }
    );
}

/// CPU time of the calling thread in ns (Linux `/proc/thread-self/schedstat`), which a loaded
/// machine disturbs far less than wall time (one thread only: with more, use wall time).
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat").ok()?.split_whitespace().next()?.parse().ok()
}
