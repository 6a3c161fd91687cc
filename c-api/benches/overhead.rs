//! Per-call overhead of the C ABI against the Rust API, in ns per element, for n = 1 and
//! n = 10^6 (eval and sample, f32, Lambert: the cheapest model, so the overhead is most
//! visible).
//!
//! The C side is called exactly as a host calls it: through `dlopen` of the built
//! `liblacquer.so` (found next to this bench's `deps/` folder, or at `$LACQUER_LIBRARY`).
//! The Rust side is the same loop over the same interleaved arrays, calling
//! `Material::eval` / `Material::sample` directly.
//!
//! Run (short, as recorded in docs/c-api.md):
//!   cargo build --release -p lacquer-capi
//!   cargo bench -p lacquer-capi --bench overhead -- --warm-up-time 1 --measurement-time 3
//!
//! Instruction counts, which a loaded machine does not disturb: `c-api/benches/callgrind.sh`
//! runs this binary with `LACQUER_OVERHEAD_COUNT=n` under callgrind: each `count_*` function
//! then runs its variant a fixed number of times (n = 1: 100 000 calls; otherwise one call).

use criterion::{black_box, criterion_group, BenchmarkId, Criterion, Throughput};
use lacquer_core::rng::Pcg32;
use lacquer_core::{Material, Vec3};
use std::ffi::{c_char, c_void};
use std::path::PathBuf;

type FromJson = unsafe extern "C" fn(*const c_char, *mut *mut c_void) -> i32;
type Free = unsafe extern "C" fn(*mut c_void);
type Eval = unsafe extern "C" fn(*const c_void, usize, *const f32, *const f32, *mut f32) -> i32;
type EvalOne = unsafe extern "C" fn(*const c_void, *const f32, *const f32, *mut f32) -> i32;
type SampleOne =
    unsafe extern "C" fn(*const c_void, *const f32, *const f32, *mut f32, *mut f32, *mut f32, *mut u32) -> i32;
type SampleFn = unsafe extern "C" fn(*const c_void, usize, *const f32, *const f32, *mut f32, *mut f32, *mut f32) -> i32;

const JSON: &str = r#"{"model": "lambert", "albedo": [0.8, 0.6, 0.4]}"#;

fn library_path() -> PathBuf {
    if let Some(p) = std::env::var_os("LACQUER_LIBRARY") {
        return p.into();
    }
    // target/<profile>/deps/overhead-<hash> -> target/<profile>/liblacquer.so
    let exe = std::env::current_exe().expect("bench path");
    exe.parent().and_then(|deps| deps.parent()).map(|dir| dir.join("liblacquer.so")).expect("target folder")
}

fn inputs(n: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let mut rng = Pcg32::new(5, 6);
    let mut wi = Vec::with_capacity(3 * n);
    let mut wo = Vec::with_capacity(3 * n);
    let mut u = Vec::with_capacity(3 * n);
    for _ in 0..n {
        for dst in [&mut wi, &mut wo] {
            let w = lacquer_core::sampling::uniform_hemisphere(rng.uniform(), rng.uniform());
            dst.extend([w.x as f32, w.y as f32, w.z as f32]);
        }
        u.extend(rng.uniform3().map(|x| x as f32));
    }
    (wi, wo, u)
}

/// The Rust API over the same interleaved arrays.
fn rust_eval(m: &Material, wi: &[f32], wo: &[f32], f: &mut [f32]) {
    for ((a, b), out) in wi.chunks_exact(3).zip(wo.chunks_exact(3)).zip(f.chunks_exact_mut(3)) {
        let v = m.eval(Vec3::new(a[0], a[1], a[2]), Vec3::new(b[0], b[1], b[2]));
        out.copy_from_slice(&v.to_array());
    }
}

fn rust_sample(m: &Material, wo: &[f32], u: &[f32], wi: &mut [f32], w: &mut [f32], p: &mut [f32]) {
    for (i, (o, uu)) in wo.chunks_exact(3).zip(u.chunks_exact(3)).enumerate() {
        match m.sample(Vec3::new(o[0], o[1], o[2]), [uu[0], uu[1], uu[2]]) {
            Some(s) => {
                wi[3 * i..3 * i + 3].copy_from_slice(&[s.wi.x, s.wi.y, s.wi.z]);
                w[3 * i..3 * i + 3].copy_from_slice(&s.weight.to_array());
                p[i] = s.pdf;
            }
            None => {
                wi[3 * i..3 * i + 3].fill(0.0);
                w[3 * i..3 * i + 3].fill(0.0);
                p[i] = 0.0;
            }
        }
    }
}

/// The C functions, loaded from liblacquer.so.
struct Abi {
    _lib: libloading::Library,
    free: Free,
    eval: Eval,
    sample: SampleFn,
    eval_one: EvalOne,
    sample_one: SampleOne,
    handle: *mut c_void,
}

fn load() -> Abi {
    let path = library_path();
    // SAFETY: loading our own library, whose initialisers are Rust std's.
    let lib = unsafe { libloading::Library::new(&path) }.unwrap_or_else(|e| {
        panic!("cannot load {} ({e}); run `cargo build --release -p lacquer-capi` first", path.display())
    });
    let (from_json, free, eval, sample, eval_one, sample_one) = unsafe {
        (
            *lib.get::<FromJson>(b"lq_material_from_json\0").unwrap(),
            *lib.get::<Free>(b"lq_material_free\0").unwrap(),
            *lib.get::<Eval>(b"lq_eval\0").unwrap(),
            *lib.get::<SampleFn>(b"lq_sample\0").unwrap(),
            *lib.get::<EvalOne>(b"lq_eval_one\0").unwrap(),
            *lib.get::<SampleOne>(b"lq_sample_one\0").unwrap(),
        )
    };
    let json = std::ffi::CString::new(JSON).unwrap();
    let mut handle = std::ptr::null_mut();
    assert_eq!(unsafe { from_json(json.as_ptr(), &mut handle) }, 0);
    Abi { _lib: lib, free, eval, sample, eval_one, sample_one, handle }
}

impl Drop for Abi {
    fn drop(&mut self) {
        unsafe { (self.free)(self.handle) };
    }
}

fn bench(c: &mut Criterion) {
    let abi = load();
    let (eval, sample, handle) = (abi.eval, abi.sample, abi.handle);
    let m = Material::from_json(JSON).unwrap();

    for n in [1usize, 1_000_000] {
        let (wi, wo, u) = inputs(n);
        let mut f = vec![0f32; 3 * n];
        let (mut swi, mut sw, mut sp) = (vec![0f32; 3 * n], vec![0f32; 3 * n], vec![0f32; n]);

        // Same answers both ways (the adapter adds no physics).
        let mut f_rust = vec![0f32; 3 * n];
        rust_eval(&m, &wi, &wo, &mut f_rust);
        assert_eq!(unsafe { eval(handle, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr()) }, 0);
        assert_eq!(f, f_rust);

        let mut g = c.benchmark_group("eval_f32");
        g.throughput(Throughput::Elements(n as u64));
        if n > 1 {
            g.sample_size(10);
        }
        g.bench_with_input(BenchmarkId::new("rust_api", n), &n, |b, _| {
            b.iter(|| rust_eval(&m, black_box(&wi), black_box(&wo), black_box(&mut f)));
        });
        g.bench_with_input(BenchmarkId::new("c_abi", n), &n, |b, &n| {
            b.iter(|| unsafe { eval(handle, black_box(n), wi.as_ptr(), wo.as_ptr(), black_box(f.as_mut_ptr())) });
        });
        g.finish();

        let mut g = c.benchmark_group("sample_f32");
        g.throughput(Throughput::Elements(n as u64));
        if n > 1 {
            g.sample_size(10);
        }
        g.bench_with_input(BenchmarkId::new("rust_api", n), &n, |b, _| {
            b.iter(|| rust_sample(&m, black_box(&wo), black_box(&u), &mut swi, &mut sw, &mut sp));
        });
        g.bench_with_input(BenchmarkId::new("c_abi", n), &n, |b, &n| {
            b.iter(|| unsafe {
                sample(
                    handle,
                    black_box(n),
                    wo.as_ptr(),
                    u.as_ptr(),
                    swi.as_mut_ptr(),
                    sw.as_mut_ptr(),
                    black_box(sp.as_mut_ptr()),
                )
            });
        });
        g.finish();
    }
}

/// Buffers of one variant: inputs and outputs for `n` elements.
struct Buffers {
    wi: Vec<f32>,
    wo: Vec<f32>,
    u: Vec<f32>,
    f: Vec<f32>,
    swi: Vec<f32>,
    sw: Vec<f32>,
    sp: Vec<f32>,
}

fn buffers(n: usize) -> Buffers {
    let (wi, wo, u) = inputs(n);
    Buffers { wi, wo, u, f: vec![0.0; 3 * n], swi: vec![0.0; 3 * n], sw: vec![0.0; 3 * n], sp: vec![0.0; n] }
}

/// Calls per variant in count mode: elements per call times calls is 10^5 or 10^6.
fn calls(n: usize) -> usize {
    if n == 1 {
        100_000
    } else {
        1
    }
}

#[inline(never)]
fn count_rust_eval(m: &Material, b: &mut Buffers, n: usize) {
    for _ in 0..calls(n) {
        rust_eval(m, black_box(&b.wi), black_box(&b.wo), black_box(&mut b.f));
    }
}

#[inline(never)]
fn count_capi_eval(abi: &Abi, b: &mut Buffers, n: usize) {
    for _ in 0..calls(n) {
        let s = unsafe { (abi.eval)(abi.handle, black_box(n), b.wi.as_ptr(), b.wo.as_ptr(), b.f.as_mut_ptr()) };
        assert_eq!(s, 0);
    }
}

#[inline(never)]
fn count_rust_sample(m: &Material, b: &mut Buffers, n: usize) {
    for _ in 0..calls(n) {
        rust_sample(m, black_box(&b.wo), black_box(&b.u), &mut b.swi, &mut b.sw, &mut b.sp);
    }
}

#[inline(never)]
fn count_capi_sample(abi: &Abi, b: &mut Buffers, n: usize) {
    for _ in 0..calls(n) {
        let s = unsafe {
            (abi.sample)(
                abi.handle,
                black_box(n),
                b.wo.as_ptr(),
                b.u.as_ptr(),
                b.swi.as_mut_ptr(),
                b.sw.as_mut_ptr(),
                b.sp.as_mut_ptr(),
            )
        };
        assert_eq!(s, 0);
    }
}

#[inline(never)]
fn count_capi_one_eval(abi: &Abi, b: &mut Buffers) {
    for _ in 0..calls(1) {
        let s = unsafe { (abi.eval_one)(abi.handle, black_box(b.wi.as_ptr()), b.wo.as_ptr(), b.f.as_mut_ptr()) };
        assert_eq!(s, 0);
    }
}

#[inline(never)]
fn count_capi_one_sample(abi: &Abi, b: &mut Buffers) {
    for _ in 0..calls(1) {
        let s = unsafe {
            (abi.sample_one)(
                abi.handle,
                black_box(b.wo.as_ptr()),
                b.u.as_ptr(),
                b.swi.as_mut_ptr(),
                b.sw.as_mut_ptr(),
                b.sp.as_mut_ptr(),
                std::ptr::null_mut(),
            )
        };
        assert_eq!(s, 0);
    }
}

/// Fixed-count runs of batches of `n` elements for callgrind (see the module comment).
fn count_mode(n: usize) {
    let abi = load();
    let m = Material::from_json(JSON).unwrap();
    let mut b = buffers(n);
    count_rust_eval(&m, &mut b, n);
    count_capi_eval(&abi, &mut b, n);
    count_rust_sample(&m, &mut b, n);
    count_capi_sample(&abi, &mut b, n);
    if n == 1 {
        count_capi_one_eval(&abi, &mut b);
        count_capi_one_sample(&abi, &mut b);
    }
    black_box(&b.f);
    black_box(&b.sp);
}

criterion_group!(benches, bench);

fn main() {
    if let Ok(n) = std::env::var("LACQUER_OVERHEAD_COUNT") {
        count_mode(n.parse().expect("LACQUER_OVERHEAD_COUNT is the batch size n"));
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
