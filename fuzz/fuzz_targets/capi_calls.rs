//! Sequences of C ABI calls driven by the input: material handles created (presets, fixed and
//! fuzzed JSON) and freed, batch calls (f32, f64, spatial, one-element, SoA) with fuzzed `n`
//! (including sizes whose byte count overflows), NULL / misaligned / overlapping pointers, and
//! NaN / ±Inf / denormal / huge / non-unit directions, `u`, `uv` and footprints.
//!
//! The c-api crate builds no rlib (its library name collides with the core's), so its modules
//! are compiled into this binary from their sources (`#[path]`): the same code as
//! `liblacquer.so`, instrumented for coverage. Checked after every call:
//! - no panic reaches the boundary (libFuzzer aborts on any panic, even a caught one);
//! - `lq_last_error()` is a readable C string;
//! - on `LQ_ERR_NULL` / `LQ_ERR_INVALID_ARGUMENT` no output was written (outputs start as a
//!   sentinel), per the documented contract;
//! - on `LQ_OK` no output is NaN.
//!
//! Every handle is freed at the end (ASan's leak check counts a leaked one).
#![no_main]
#![allow(dead_code, unused_imports, non_camel_case_types, clippy::all)]

#[path = "../../c-api/src/arrays.rs"]
mod arrays;
#[path = "../../c-api/src/batch.rs"]
mod batch;
#[path = "../../c-api/src/catalog.rs"]
mod catalog;
#[path = "../../c-api/src/fit.rs"]
mod fit;
#[path = "../../c-api/src/material.rs"]
mod material;
#[path = "../../c-api/src/render.rs"]
mod render;
#[path = "../../c-api/src/status.rs"]
mod status;
#[path = "../../c-api/src/strings.rs"]
mod strings;

use batch::*;
use libfuzzer_sys::fuzz_target;
use material::*;
use status::lq_status::{self, *};
use std::ffi::{c_char, CStr, CString};

/// Values a host may pass, indexed by an input byte < 16.
const PAL: [f32; 16] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    0.707_106_77,
    1e-45, // denormal
    -1e-45,
    f32::MIN_POSITIVE,
    1e-7,
    1e38,
    f32::MAX,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    0.999_999_94,
];

const JSONS: [&str; 12] = [
    r#"{"preset": "gold_flake_8"}"#,
    r#"{"preset": "solid_red"}"#,
    r#"{"preset": "white_lambert"}"#,
    r#"{"model": "lambert", "albedo": 0.8}"#,
    r#"{"model": "rough_conductor", "alpha_u": 0.001, "alpha_v": 1.0}"#,
    r#"{"model": "rough_plastic"}"#,
    r#"{"model": "coated_paint"}"#,
    r#"{"model": "cook_torrance"}"#,
    r#"{"model": "phong", "exponent": 1e6}"#,
    r#"{"model": "measured"}"#,
    r#"{"model": "lambert", "albedo": NaN}"#,
    r#"{"model": "#,
];
const PRESETS: [&str; 4] = ["gold_flake_8", "solid_red", "no_such_preset", ""];
const SENTINEL: f32 = 12345.0;
const SENTINEL64: f64 = 12345.0;

struct In<'a> {
    d: &'a [u8],
    i: usize,
}

impl In<'_> {
    fn byte(&mut self) -> u8 {
        let b = self.d.get(self.i).copied().unwrap_or(0);
        self.i += 1;
        b
    }
    fn done(&self) -> bool {
        self.i >= self.d.len()
    }
    fn f32(&mut self) -> f32 {
        let p = self.byte();
        match p {
            0..16 => PAL[p as usize],
            16..32 => f32::from_bits(u32::from_le_bytes([self.byte(), self.byte(), self.byte(), self.byte()])),
            _ => (p - 32) as f32 / 111.5 - 1.0,
        }
    }
}

/// How a pointer argument is passed.
#[derive(Clone, Copy, PartialEq)]
enum Ptr {
    Valid,
    Null,
    Misaligned,
    /// Points at input buffer 0 (outputs: must be rejected as overlapping).
    Alias,
}

fn ptr_kind(inp: &mut In) -> Ptr {
    match inp.byte() {
        0..=229 => Ptr::Valid,
        230..=239 => Ptr::Null,
        240..=247 => Ptr::Misaligned,
        _ => Ptr::Alias,
    }
}

/// Buffers of one call: inputs filled from the input, outputs with a sentinel.
struct Bufs<T> {
    ins: Vec<Vec<T>>,
    outs: Vec<Vec<T>>,
    kinds_in: Vec<Ptr>,
    kinds_out: Vec<Ptr>,
}

impl<T: Copy> Bufs<T> {
    fn new<'d>(
        inp: &mut In<'d>,
        n: usize,
        in_w: &[usize],
        out_w: &[usize],
        gen: impl Fn(&mut In<'d>) -> T,
        sentinel: T,
    ) -> Self {
        let cap = |w: usize| n.min(1 << 16) * w + 1;
        let mut ins = Vec::new();
        for &w in in_w {
            let mut v = Vec::with_capacity(cap(w));
            // Fill from the input; when it runs out, repeat what was read (a large n stays cheap).
            for k in 0..cap(w) {
                if inp.done() && !v.is_empty() {
                    let x = v[k % v.len()];
                    v.push(x);
                } else {
                    v.push(gen(inp));
                }
            }
            ins.push(v);
        }
        let outs = out_w.iter().map(|&w| vec![sentinel; cap(w)]).collect();
        let kinds_in = in_w.iter().map(|_| ptr_kind(inp)).collect();
        let kinds_out = out_w.iter().map(|_| ptr_kind(inp)).collect();
        Self { ins, outs, kinds_in, kinds_out }
    }
    fn inp(&mut self, k: usize) -> *const T {
        let base = self.ins[0].as_mut_ptr();
        let own = self.ins[k].as_mut_ptr();
        pick(self.kinds_in[k], own, base)
    }
    fn out(&mut self, k: usize) -> *mut T {
        let base = self.ins[0].as_mut_ptr();
        let own = self.outs[k].as_mut_ptr();
        pick(self.kinds_out[k], own, base)
    }
}

fn pick<T>(kind: Ptr, own: *mut T, alias: *mut T) -> *mut T {
    match kind {
        Ptr::Valid => own,
        Ptr::Null => std::ptr::null_mut(),
        // SAFETY: one byte into a buffer with one spare element.
        Ptr::Misaligned => unsafe { own.cast::<u8>().add(1).cast::<T>() },
        Ptr::Alias => alias,
    }
}

fn last_error() -> String {
    let p = lacquer_last_error();
    assert!(!p.is_null());
    // SAFETY: the library promises a NUL-terminated string valid until the next call.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

fn lacquer_last_error() -> *const c_char {
    status::guard_value(c"".as_ptr(), status::last_error_ptr)
}

/// The contract after a batch call: outputs untouched on whole-call errors, no NaN on success.
fn verify(st: lq_status, outs: &[Vec<f32>], kinds: &[Ptr], what: &str) {
    let msg = last_error();
    assert!(st != LQ_ERR_PANIC, "{what}: panic: {msg}");
    if matches!(st, LQ_ERR_NULL | LQ_ERR_INVALID_ARGUMENT) {
        for (o, k) in outs.iter().zip(kinds) {
            if *k == Ptr::Valid {
                assert!(o.iter().all(|x| *x == SENTINEL), "{what}: {st:?} ({msg}) but an output was written");
            }
        }
    }
    if st == LQ_OK {
        for (o, k) in outs.iter().zip(kinds) {
            if *k == Ptr::Valid {
                assert!(o.iter().all(|x| !x.is_nan()), "{what}: LQ_OK with a NaN output");
            }
        }
    }
}

fn verify64(st: lq_status, outs: &[Vec<f64>], kinds: &[Ptr], what: &str) {
    let msg = last_error();
    assert!(st != LQ_ERR_PANIC, "{what}: panic: {msg}");
    if matches!(st, LQ_ERR_NULL | LQ_ERR_INVALID_ARGUMENT) {
        for (o, k) in outs.iter().zip(kinds) {
            if *k == Ptr::Valid {
                assert!(o.iter().all(|x| *x == SENTINEL64), "{what}: {st:?} ({msg}) but an output was written");
            }
        }
    }
    if st == LQ_OK {
        for (o, k) in outs.iter().zip(kinds) {
            if *k == Ptr::Valid {
                assert!(o.iter().all(|x| !x.is_nan()), "{what}: LQ_OK with a NaN output");
            }
        }
    }
}

fn count(inp: &mut In) -> usize {
    match inp.byte() {
        255 => usize::MAX / 2 - inp.byte() as usize, // byte size overflows: must be rejected
        254 => isize::MAX as usize / 4 + 1,          // overflows isize for every width
        253 => 40_000,                               // the threaded path (≥ 32768)
        b => b as usize % 40,
    }
}

fuzz_target!(|data: &[u8]| {
    let mut inp = In { d: data, i: 0 };
    let mut handles: Vec<*mut lq_material> = Vec::new();
    let mut steps = 0;
    while !inp.done() && steps < 64 {
        steps += 1;
        let op = inp.byte() % 14;
        let hb = inp.byte();
        let m: *const lq_material =
            if handles.is_empty() || hb == 255 { std::ptr::null() } else { handles[hb as usize % handles.len()] };
        // SAFETY (all calls below): pointers are NULL, valid buffers sized for n (+1 spare),
        // misaligned by one byte, or aliases of a buffer of the same size; handles are live.
        unsafe {
            match op {
                0 | 1 | 2 => {
                    let text = match op {
                        0 => CString::new(JSONS[hb as usize % JSONS.len()]).unwrap(),
                        1 => {
                            let len = inp.byte() as usize;
                            let bytes: Vec<u8> = (0..len).map(|_| inp.byte()).filter(|b| *b != 0).collect();
                            CString::new(bytes).unwrap()
                        }
                        _ => CString::new(PRESETS[hb as usize % PRESETS.len()]).unwrap(),
                    };
                    let mut out: *mut lq_material = std::ptr::null_mut();
                    let null_out = inp.byte() == 0;
                    let outp = if null_out { std::ptr::null_mut() } else { &mut out as *mut _ };
                    let st = if op == 2 {
                        lq_material_from_preset(text.as_ptr(), outp)
                    } else {
                        lq_material_from_json(text.as_ptr(), outp)
                    };
                    let msg = last_error();
                    assert!(st != LQ_ERR_PANIC, "from_json: panic: {msg}");
                    assert_eq!(st == LQ_OK, !out.is_null(), "{st:?} {msg}");
                    if !out.is_null() {
                        if handles.len() >= 4 {
                            lq_material_free(handles.remove(0));
                        }
                        handles.push(out);
                    }
                }
                3 => {
                    if !handles.is_empty() && hb != 255 {
                        lq_material_free(handles.remove(hb as usize % handles.len()));
                    } else {
                        lq_material_free(std::ptr::null_mut());
                    }
                }
                4 => {
                    let n = count(&mut inp);
                    let mut b = Bufs::new(&mut inp, n, &[3, 3], &[3, 1], In::f32, SENTINEL);
                    let st = match inp.byte() % 3 {
                        0 => lq_eval(m, n, b.inp(0), b.inp(1), b.out(0)),
                        1 => lq_pdf(m, n, b.inp(0), b.inp(1), b.out(1)),
                        _ => lq_eval_pdf(m, n, b.inp(0), b.inp(1), b.out(0), b.out(1)),
                    };
                    verify(st, &b.outs, &b.kinds_out, "eval/pdf");
                }
                5 => {
                    let n = count(&mut inp);
                    let mut b = Bufs::new(&mut inp, n, &[3, 3], &[3, 3, 1], In::f32, SENTINEL);
                    let st = lq_sample(m, n, b.inp(0), b.inp(1), b.out(0), b.out(1), b.out(2));
                    verify(st, &b.outs, &b.kinds_out, "sample");
                }
                6 => {
                    let n = count(&mut inp);
                    let g = |i: &mut In| f64::from(i.f32());
                    let mut b = Bufs::new(&mut inp, n, &[3, 3], &[3, 1, 3, 3, 1], g, SENTINEL64);
                    let st = match inp.byte() % 4 {
                        0 => lq_eval_f64(m, n, b.inp(0), b.inp(1), b.out(0)),
                        1 => lq_pdf_f64(m, n, b.inp(0), b.inp(1), b.out(1)),
                        2 => lq_eval_pdf_f64(m, n, b.inp(0), b.inp(1), b.out(0), b.out(1)),
                        _ => {
                            let mut flags = vec![0u32; n.min(1 << 16) + 1];
                            let fp = if inp.byte() % 2 == 0 { flags.as_mut_ptr() } else { std::ptr::null_mut() };
                            lq_sample_f64(m, n, b.inp(0), b.inp(1), b.out(2), b.out(3), b.out(4), fp)
                        }
                    };
                    verify64(st, &b.outs, &b.kinds_out, "f64");
                }
                7 => {
                    let n = count(&mut inp);
                    // wi, wo, uv, duv (u for sample = wi's buffer); outputs f, pdf, wi, weight.
                    let mut b = Bufs::new(&mut inp, n, &[3, 3, 2, 4], &[3, 1, 3, 3], In::f32, SENTINEL);
                    let st = match inp.byte() % 4 {
                        0 => lq_eval_spatial(m, n, b.inp(0), b.inp(1), b.inp(2), b.inp(3), b.out(0)),
                        1 => lq_pdf_spatial(m, n, b.inp(0), b.inp(1), b.inp(2), b.inp(3), b.out(1)),
                        2 => lq_eval_pdf_spatial(m, n, b.inp(0), b.inp(1), b.inp(2), b.inp(3), b.out(0), b.out(1)),
                        _ => {
                            let mut flags = vec![0u32; n.min(1 << 16) + 1];
                            let fp = if inp.byte() % 2 == 0 { flags.as_mut_ptr() } else { std::ptr::null_mut() };
                            lq_sample_spatial(
                                m,
                                n,
                                b.inp(1),
                                b.inp(0),
                                b.inp(2),
                                b.inp(3),
                                b.out(2),
                                b.out(3),
                                b.out(1),
                                fp,
                            )
                        }
                    };
                    verify(st, &b.outs, &b.kinds_out, "spatial");
                }
                8 => {
                    let mut b = Bufs::new(&mut inp, 1, &[3, 3], &[3, 1, 3, 3], In::f32, SENTINEL);
                    let st = match inp.byte() % 4 {
                        0 => lq_eval_one(m, b.inp(0), b.inp(1), b.out(0)),
                        1 => lq_pdf_one(m, b.inp(0), b.inp(1), b.out(1)),
                        2 => lq_eval_pdf_one(m, b.inp(0), b.inp(1), b.out(0), b.out(1)),
                        _ => {
                            let mut flags = 0u32;
                            lq_sample_one(m, b.inp(0), b.inp(1), b.out(2), b.out(3), b.out(1), &mut flags)
                        }
                    };
                    // The one-element calls may alias (in place): only the panic and NaN checks.
                    let msg = last_error();
                    assert!(st != LQ_ERR_PANIC, "one: panic: {msg}");
                    if st == LQ_OK {
                        for (o, k) in b.outs.iter().zip(&b.kinds_out) {
                            if *k == Ptr::Valid {
                                assert!(o.iter().all(|x| !x.is_nan()), "one: LQ_OK with a NaN output");
                            }
                        }
                    }
                }
                9 => {
                    let n = count(&mut inp);
                    // wi xyz, wo xyz, u0..2 (inputs 0..9); outputs f rgb, pdf, wi xyz, w rgb.
                    let mut b = Bufs::new(&mut inp, n, &[1; 9], &[1; 10], In::f32, SENTINEL);
                    let mut active: Vec<u8> = (0..n.min(1 << 16) + 1).map(|k| (k % 3 != 1) as u8).collect();
                    let ap = if inp.byte() % 2 == 0 { active.as_mut_ptr() } else { std::ptr::null_mut() };
                    let st = match inp.byte() % 4 {
                        0 => lq_eval_soa(
                            m,
                            n,
                            b.inp(0),
                            b.inp(1),
                            b.inp(2),
                            b.inp(3),
                            b.inp(4),
                            b.inp(5),
                            ap,
                            b.out(0),
                            b.out(1),
                            b.out(2),
                        ),
                        1 => lq_pdf_soa(m, n, b.inp(0), b.inp(1), b.inp(2), b.inp(3), b.inp(4), b.inp(5), ap, b.out(3)),
                        2 => lq_eval_pdf_soa(
                            m,
                            n,
                            b.inp(0),
                            b.inp(1),
                            b.inp(2),
                            b.inp(3),
                            b.inp(4),
                            b.inp(5),
                            ap,
                            b.out(0),
                            b.out(1),
                            b.out(2),
                            b.out(3),
                        ),
                        _ => {
                            let mut flags = vec![0u32; n.min(1 << 16) + 1];
                            let fp = if inp.byte() % 2 == 0 { flags.as_mut_ptr() } else { std::ptr::null_mut() };
                            lq_sample_soa(
                                m,
                                n,
                                b.inp(3),
                                b.inp(4),
                                b.inp(5),
                                b.inp(6),
                                b.inp(7),
                                b.inp(8),
                                ap,
                                b.out(4),
                                b.out(5),
                                b.out(6),
                                b.out(7),
                                b.out(8),
                                b.out(9),
                                b.out(3),
                                fp,
                            )
                        }
                    };
                    verify(st, &b.outs, &b.kinds_out, "soa");
                }
                10 => {
                    let mut s: *mut c_char = std::ptr::null_mut();
                    let outp = if inp.byte() == 0 { std::ptr::null_mut() } else { &mut s as *mut _ };
                    let st = lq_material_to_json(m, outp);
                    assert!(st != LQ_ERR_PANIC);
                    assert_eq!(st == LQ_OK, !s.is_null());
                    if !s.is_null() {
                        // The canonical JSON builds the same material again.
                        let mut again: *mut lq_material = std::ptr::null_mut();
                        let st2 = lq_material_from_json(s, &mut again);
                        assert_eq!(st2, LQ_OK, "{}: {}", CStr::from_ptr(s).to_string_lossy(), last_error());
                        lq_material_free(again);
                        strings::lq_string_free(s);
                    }
                }
                11 => {
                    let code = i32::from_le_bytes([hb, inp.byte(), inp.byte(), inp.byte()]);
                    let name = status::ALL_STATUSES.iter().find(|s| **s as i32 == code).map(|s| s.name());
                    assert!(name.is_none() || (0..10).contains(&code));
                    let _ = last_error();
                }
                12 => lq_set_thread_count(u32::from(hb % 3)),
                _ => {
                    // lq_choose_configuration and lq_check_* are too slow to fuzz per input;
                    // their NULL paths are cheap.
                    let st = catalog::lq_check_material(m, 0, std::ptr::null_mut(), std::ptr::null_mut());
                    assert!(st == LQ_ERR_NULL, "{st:?}");
                }
            }
        }
    }
    for h in handles {
        // SAFETY: live handles from lq_material_from_*.
        unsafe { lq_material_free(h) };
    }
});
