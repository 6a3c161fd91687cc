//! Bad inputs through the C ABI: each case is called as a C host would, and its status,
//! message and effect on the outputs are checked. The same table is the one in
//! docs/c-api.md; regenerate that section with
//!     LACQUER_BLESS_DOCS=1 cargo test -p lacquer-capi bad_input
//! (c-api/python/tests/test_bad_input.py mirrors these cases through Python.)

use super::*;
use lacquer_core::models;
use lacquer_core::params::ParamKind;
use lq_status::*;
use std::ptr::{null, null_mut};

/// What one case did.
struct Outcome {
    status: lq_status,
    message: String,
    /// What happened to the outputs, checked by the case itself.
    outputs: &'static str,
}

struct Case {
    function: &'static str,
    input: String,
    expect: lq_status,
    /// A substring the message must contain ("" when the status is LQ_OK).
    contains: String,
    run: Box<dyn Fn() -> Outcome>,
}

fn status_name(s: lq_status) -> &'static str {
    s.name().to_str().unwrap()
}

/// A sentinel handle value: `*out` must still hold it after a failed creation.
const UNTOUCHED: *mut lq_material = 0x10 as *mut lq_material;

/// `lq_material_from_json` on raw bytes (NUL appended); checks `*out` is untouched on error.
fn from_json_bytes(bytes: &[u8]) -> Outcome {
    let c = CString::new(bytes.to_vec()).unwrap();
    let mut out = UNTOUCHED;
    let status = unsafe { lq_material_from_json(c.as_ptr(), &mut out) };
    let message = last_error();
    if status == LQ_OK {
        assert!(!out.is_null() && out != UNTOUCHED);
        unsafe { lq_material_free(out) };
        Outcome { status, message, outputs: "new handle in *out" }
    } else {
        assert_eq!(out, UNTOUCHED, "*out written on error");
        Outcome { status, message, outputs: "*out untouched" }
    }
}

fn json_case(input: &str, bytes: &[u8], expect: lq_status, contains: &str) -> Case {
    let bytes = bytes.to_vec();
    Case {
        function: "lq_material_from_json",
        input: input.to_string(),
        expect,
        contains: contains.to_string(),
        run: Box::new(move || from_json_bytes(&bytes)),
    }
}

fn lambert() -> *mut lq_material {
    material(r#"{"model": "lambert", "albedo": 0.5}"#)
}

const SENTINEL: f32 = 7.0;

/// `lq_eval` with `n` elements from `wi`/`wo`; checks the output policy for the status.
fn eval_case(wi: Vec<f32>, wo: Vec<f32>) -> Outcome {
    let n = wi.len() / 3;
    let m = lambert();
    let mut f = vec![SENTINEL; 3 * n];
    let status = unsafe { lq_eval(m, n, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr()) };
    let message = last_error();
    unsafe { lq_material_free(m) };
    let outputs = match status {
        LQ_OK => {
            assert!(f.iter().all(|&x| x != SENTINEL), "{f:?}");
            "every element written"
        }
        LQ_ERR_INVALID_DIRECTION => {
            // Every element written: invalid ones as 0, valid ones as the core's value.
            assert!(f.iter().all(|&x| x != SENTINEL), "{f:?}");
            "every element written; invalid elements 0"
        }
        _ => {
            assert!(f.iter().all(|&x| x == SENTINEL));
            "nothing written"
        }
    };
    Outcome { status, message, outputs }
}

/// `lq_sample` on one element with `wo` and `u`; returns the flags through the message.
fn sample_case(wo: [f32; 3], u: [f32; 3]) -> Outcome {
    let m = lambert();
    let (mut wi, mut w, mut p, mut fl) = ([SENTINEL; 3], [SENTINEL; 3], [SENTINEL], [99u32]);
    let status = unsafe {
        lq_sample_spatial(
            m,
            1,
            wo.as_ptr(),
            u.as_ptr(),
            null(),
            null(),
            wi.as_mut_ptr(),
            w.as_mut_ptr(),
            p.as_mut_ptr(),
            fl.as_mut_ptr(),
        )
    };
    let message = last_error();
    unsafe { lq_material_free(m) };
    let outputs = if fl[0] & LQ_SAMPLE_FAILED != 0 {
        assert_eq!((wi, w, p), ([0.0; 3], [0.0; 3], [0.0]));
        if fl[0] & LQ_SAMPLE_INVALID_INPUT != 0 {
            "failed sample (wi = weight = pdf = 0), flags FAILED|INVALID_INPUT"
        } else {
            "failed sample (wi = weight = pdf = 0), flags FAILED"
        }
    } else {
        assert!(p[0] > 0.0 && wi[2] > 0.0, "{p:?} {wi:?}");
        "a valid sample, flags 0"
    };
    Outcome { status, message, outputs }
}

fn batch_case(
    function: &'static str,
    input: &str,
    expect: lq_status,
    contains: &str,
    run: impl Fn() -> Outcome + 'static,
) -> Case {
    Case { function, input: input.to_string(), expect, contains: contains.to_string(), run: Box::new(run) }
}

/// The first registered scalar parameter whose name contains one of `patterns`.
fn find_param(patterns: &[&str]) -> Option<(&'static str, &'static str, f64)> {
    models::all().iter().find_map(|m| {
        m.params
            .iter()
            .find(|p| p.kind == ParamKind::Scalar && patterns.iter().any(|pat| p.name.contains(pat)))
            .map(|p| (m.name, p.name, p.min))
    })
}

/// A case for a parameter that may not exist yet in the registry (other models land later).
fn registry_param_case(what: &str, patterns: &[&str], value: impl Fn(f64) -> f64) -> Case {
    match find_param(patterns) {
        Some((model, param, min)) => {
            let v = value(min);
            let json = format!("{{\"model\": \"{model}\", \"{param}\": {v}}}");
            json_case(&format!("{what}: `{json}`"), json.as_bytes(), LQ_ERR_INVALID_MATERIAL, &format!("\"{param}\""))
        }
        None => Case {
            function: "lq_material_from_json",
            input: format!("{what} (no registered model has such a parameter yet: covered by the every-parameter row)"),
            expect: LQ_ERR_INVALID_MATERIAL,
            contains: String::new(),
            run: Box::new(|| Outcome {
                status: LQ_ERR_INVALID_MATERIAL,
                message: "(not run)".into(),
                outputs: "*out untouched",
            }),
        },
    }
}

fn cases() -> Vec<Case> {
    let up = vec![0.0f32, 0.0, 1.0];
    let mut v = vec![
        // --- material JSON
        Case {
            function: "lq_material_from_json",
            input: "`json` = NULL".into(),
            expect: LQ_ERR_NULL,
            contains: "`json` is NULL".into(),
            run: Box::new(|| {
                let mut out = UNTOUCHED;
                let status = unsafe { lq_material_from_json(null(), &mut out) };
                assert_eq!(out, UNTOUCHED);
                Outcome { status, message: last_error(), outputs: "*out untouched" }
            }),
        },
        Case {
            function: "lq_material_from_json",
            input: "`out` = NULL".into(),
            expect: LQ_ERR_NULL,
            contains: "`out` is NULL".into(),
            run: Box::new(|| {
                let status = unsafe { lq_material_from_json(c"{\"model\": \"lambert\"}".as_ptr(), null_mut()) };
                Outcome { status, message: last_error(), outputs: "nothing allocated" }
            }),
        },
        json_case("empty string", b"", LQ_ERR_INVALID_JSON, "EOF while parsing"),
        json_case("garbage `lambert please`", b"lambert please", LQ_ERR_INVALID_JSON, "invalid JSON"),
        json_case(
            "truncated `{\"model\": \"lambert\", \"albedo\": 0.`",
            b"{\"model\": \"lambert\", \"albedo\": 0.",
            LQ_ERR_INVALID_JSON,
            "line 1 column",
        ),
        json_case(
            "trailing garbage `{\"model\": \"lambert\"} x`",
            b"{\"model\": \"lambert\"} x",
            LQ_ERR_INVALID_JSON,
            "trailing characters",
        ),
        json_case("invalid UTF-8 (bytes ff fe)", b"{\"model\": \"\xff\xfe\"}", LQ_ERR_INVALID_JSON, "not UTF-8"),
        json_case(
            "NaN parameter `{\"model\": \"lambert\", \"albedo\": NaN}` (JSON has no NaN)",
            b"{\"model\": \"lambert\", \"albedo\": NaN}",
            LQ_ERR_INVALID_JSON,
            "expected value",
        ),
        json_case(
            "infinite parameter `\"albedo\": 1e999`",
            b"{\"model\": \"lambert\", \"albedo\": 1e999}",
            LQ_ERR_INVALID_JSON,
            "number out of range",
        ),
        json_case(
            "nesting 100000 deep `[[[[...`",
            "[".repeat(100_000).as_bytes(),
            LQ_ERR_INVALID_JSON,
            "recursion limit exceeded",
        ),
        json_case("not an object `[1, 2, 3]`", b"[1, 2, 3]", LQ_ERR_INVALID_MATERIAL, "expected a JSON object"),
        json_case("`null`", b"null", LQ_ERR_INVALID_MATERIAL, "expected a JSON object"),
        json_case("empty object `{}`", b"{}", LQ_ERR_INVALID_MATERIAL, "missing \"model\""),
        json_case("`{\"model\": 3}`", b"{\"model\": 3}", LQ_ERR_INVALID_MATERIAL, "\"model\" must be a string"),
        json_case(
            "unknown model `{\"model\": \"phongg\"}`",
            b"{\"model\": \"phongg\"}",
            LQ_ERR_UNKNOWN_NAME,
            "unknown model \"phongg\"",
        ),
        json_case(
            "unknown key `{\"model\": \"lambert\", \"albdo\": 0.5}`",
            b"{\"model\": \"lambert\", \"albdo\": 0.5}",
            LQ_ERR_INVALID_MATERIAL,
            "has no parameter \"albdo\"",
        ),
        json_case(
            "wrong type `\"albedo\": \"red\"`",
            b"{\"model\": \"lambert\", \"albedo\": \"red\"}",
            LQ_ERR_INVALID_MATERIAL,
            "\"albedo\"",
        ),
        json_case(
            "colour with 2 components `\"albedo\": [0.1, 0.2]`",
            b"{\"model\": \"lambert\", \"albedo\": [0.1, 0.2]}",
            LQ_ERR_INVALID_MATERIAL,
            "\"albedo\"",
        ),
        json_case(
            "negative value `\"albedo\": -0.1`",
            b"{\"model\": \"lambert\", \"albedo\": -0.1}",
            LQ_ERR_INVALID_MATERIAL,
            "outside its range [0, 1]",
        ),
        json_case(
            "value above range `\"albedo\": [0.5, 1.5, 0.5]`",
            b"{\"model\": \"lambert\", \"albedo\": [0.5, 1.5, 0.5]}",
            LQ_ERR_INVALID_MATERIAL,
            "outside its range [0, 1]",
        ),
        json_case(
            "duplicate key `{\"model\": \"lambert\", \"albedo\": 0.1, \"albedo\": 0.2}` (accepted: the last value wins)",
            b"{\"model\": \"lambert\", \"albedo\": 0.1, \"albedo\": 0.2}",
            LQ_OK,
            "",
        ),
        json_case(
            "unknown preset `{\"preset\": \"no_such_paint\"}`",
            b"{\"preset\": \"no_such_paint\"}",
            LQ_ERR_UNKNOWN_NAME,
            "unknown preset \"no_such_paint\"",
        ),
        json_case(
            "preset with extra keys `{\"preset\": \"white_lambert\", \"albedo\": 0.5}`",
            b"{\"preset\": \"white_lambert\", \"albedo\": 0.5}",
            LQ_ERR_INVALID_MATERIAL,
            "takes no other keys",
        ),
        json_case("`{\"preset\": 1}`", b"{\"preset\": 1}", LQ_ERR_INVALID_MATERIAL, "\"preset\" must be a string"),
        Case {
            function: "lq_material_from_preset",
            input: "`name` = NULL".into(),
            expect: LQ_ERR_NULL,
            contains: "`name` is NULL".into(),
            run: Box::new(|| {
                let mut out = UNTOUCHED;
                let status = unsafe { lq_material_from_preset(null(), &mut out) };
                assert_eq!(out, UNTOUCHED);
                Outcome { status, message: last_error(), outputs: "*out untouched" }
            }),
        },
        Case {
            function: "lq_material_from_preset",
            input: "`name` = \"gold \" (trailing space)".into(),
            expect: LQ_ERR_UNKNOWN_NAME,
            contains: "unknown preset".into(),
            run: Box::new(|| {
                let mut out = UNTOUCHED;
                let status = unsafe { lq_material_from_preset(c"gold ".as_ptr(), &mut out) };
                assert_eq!(out, UNTOUCHED);
                Outcome { status, message: last_error(), outputs: "*out untouched" }
            }),
        },
    ];
    v.push(registry_param_case("negative roughness", &["rough", "alpha"], |_| -0.1));
    v.push(registry_param_case("IOR < 1", &["ior", "eta"], |_| 0.5));
    v.push(Case {
        function: "lq_material_from_json",
        input: "every scalar/colour/integer parameter of every registered model set below its minimum and above its maximum".into(),
        expect: LQ_ERR_INVALID_MATERIAL,
        contains: "outside its range".into(),
        run: Box::new(every_parameter_out_of_range),
    });

    // --- handles and arrays
    let (a, b) = (up.clone(), up.clone());
    v.push(batch_case("lq_eval", "`m` = NULL", LQ_ERR_NULL, "`m` is NULL", move || {
        let mut f = [SENTINEL; 3];
        let status = unsafe { lq_eval(null(), 1, a.as_ptr(), b.as_ptr(), f.as_mut_ptr()) };
        assert_eq!(f, [SENTINEL; 3]);
        Outcome { status, message: last_error(), outputs: "nothing written" }
    }));
    let a = up.clone();
    v.push(batch_case("lq_eval", "`wi` = NULL, n = 1", LQ_ERR_NULL, "`wi` is NULL", move || {
        let m = lambert();
        let mut f = [SENTINEL; 3];
        let status = unsafe { lq_eval(m, 1, null(), a.as_ptr(), f.as_mut_ptr()) };
        let message = last_error();
        unsafe { lq_material_free(m) };
        assert_eq!(f, [SENTINEL; 3]);
        Outcome { status, message, outputs: "nothing written" }
    }));
    let a = up.clone();
    v.push(batch_case("lq_pdf", "`pdf` (output) = NULL", LQ_ERR_NULL, "`pdf` is NULL", move || {
        let m = lambert();
        let status = unsafe { lq_pdf(m, 1, a.as_ptr(), a.as_ptr(), null_mut()) };
        let message = last_error();
        unsafe { lq_material_free(m) };
        Outcome { status, message, outputs: "nothing written" }
    }));
    v.push(batch_case("lq_eval", "n = 0 with every array NULL", LQ_OK, "", || {
        let m = lambert();
        let status = unsafe { lq_eval(m, 0, null(), null(), null_mut()) };
        let message = last_error();
        unsafe { lq_material_free(m) };
        Outcome { status, message, outputs: "no-op" }
    }));
    v.push(batch_case("lq_eval", "n = 0 with `m` = NULL", LQ_ERR_NULL, "`m` is NULL", || {
        let status = unsafe { lq_eval(null(), 0, null(), null(), null_mut()) };
        Outcome { status, message: last_error(), outputs: "no-op" }
    }));
    let a = up.clone();
    v.push(batch_case(
        "lq_eval",
        "n = SIZE_MAX / 4 (byte size overflows)",
        LQ_ERR_INVALID_ARGUMENT,
        "is too large",
        move || {
            let m = lambert();
            let mut f = [SENTINEL; 3];
            let status = unsafe { lq_eval(m, usize::MAX / 4, a.as_ptr(), a.as_ptr(), f.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(f, [SENTINEL; 3]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case(
        "lq_eval",
        "misaligned `wi` (float array at an odd address)",
        LQ_ERR_INVALID_ARGUMENT,
        "is not aligned to 4 bytes",
        || {
            let m = lambert();
            let buf = [0u8; 64];
            let base = buf.as_ptr() as usize;
            let odd = (base + 4 - base % 4 + 1) as *const f32;
            let good = [0f32, 0.0, 1.0];
            let mut f = [SENTINEL; 3];
            let status = unsafe { lq_eval(m, 1, odd, good.as_ptr(), f.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(f, [SENTINEL; 3]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case(
        "lq_eval_f64",
        "double array only 4-byte aligned",
        LQ_ERR_INVALID_ARGUMENT,
        "is not aligned to 8 bytes",
        || {
            let m = lambert();
            let buf = [0f64; 8];
            let four = (buf.as_ptr() as usize + 4) as *const f64;
            let mut f = [7.0f64; 3];
            let status = unsafe { lq_eval_f64(m, 1, four, buf.as_ptr(), f.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(f, [7.0; 3]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case(
        "lq_eval",
        "output `f_rgb` is the same buffer as input `wi` (in place)",
        LQ_ERR_INVALID_ARGUMENT,
        "output array `f_rgb` overlaps array `wi`",
        || {
            let m = lambert();
            let mut buf = [0f32, 0.0, 1.0];
            let wo = [0f32, 0.0, 1.0];
            let p = buf.as_mut_ptr();
            let status = unsafe { lq_eval(m, 1, p, wo.as_ptr(), p) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(buf, [0.0, 0.0, 1.0]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case(
        "lq_sample",
        "outputs `wi` and `weight_rgb` overlap by one element",
        LQ_ERR_INVALID_ARGUMENT,
        "overlaps",
        || {
            let m = lambert();
            let wo = [0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
            let u = [0.5f32; 6];
            let mut buf = [SENTINEL; 9];
            let mut pdf = [SENTINEL; 2];
            let p = buf.as_mut_ptr();
            let status = unsafe { lq_sample(m, 2, wo.as_ptr(), u.as_ptr(), p, p.add(3), pdf.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(buf, [SENTINEL; 9]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    let a = up.clone();
    v.push(batch_case("lq_eval", "`wi` and `wo` are the same buffer (inputs may alias)", LQ_OK, "", move || {
        eval_case(a.clone(), a.clone())
    }));
    v.push(batch_case(
        "lq_eval",
        "NaN in one direction of a batch of 3 (`wi[1] = (NaN, 0, 1)`)",
        LQ_ERR_INVALID_DIRECTION,
        "1 of 3 elements have a direction that is not finite or has zero length (first: element 1: wi = [NaN, 0, 1])",
        || {
            let wi = vec![0.0, 0.0, 1.0, f32::NAN, 0.0, 1.0, 0.6, 0.0, 0.8];
            let wo = vec![0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
            eval_case(wi, wo)
        },
    ));
    v.push(batch_case("lq_eval", "+Inf in `wo`", LQ_ERR_INVALID_DIRECTION, "wo = [inf, 0, 1]", || {
        eval_case(vec![0.0, 0.0, 1.0], vec![f32::INFINITY, 0.0, 1.0])
    }));
    v.push(batch_case("lq_eval", "zero-length `wi` (0, 0, 0)", LQ_ERR_INVALID_DIRECTION, "wi = [0, 0, 0]", || {
        eval_case(vec![0.0, 0.0, 0.0], vec![0.0, 0.0, 1.0])
    }));
    v.push(batch_case(
        "lq_eval",
        "tiny direction (1e-30, 0, 1e-30): its squared length underflows to 0 in f32",
        LQ_ERR_INVALID_DIRECTION,
        "zero length",
        || eval_case(vec![1e-30, 0.0, 1e-30], vec![0.0, 0.0, 1.0]),
    ));
    v.push(batch_case("lq_eval", "direction not unit length (0, 0, 5)", LQ_OK, "", || {
        eval_case(vec![0.0, 0.0, 5.0], vec![0.0, 0.0, 1.0])
    }));
    v.push(batch_case("lq_eval", "`wi` below the horizon (0, 0, -1)", LQ_OK, "", || {
        let o = eval_case(vec![0.0, 0.0, -1.0], vec![0.0, 0.0, 1.0]);
        Outcome { outputs: "f = 0 (not an error: the opaque one-sided convention)", ..o }
    }));
    v.push(batch_case("lq_sample", "`wo` below the horizon", LQ_OK, "", || sample_case([0.0, 0.0, -1.0], [0.5; 3])));
    v.push(batch_case("lq_sample", "NaN in `u`", LQ_ERR_INVALID_ELEMENT, "element 0: u = [0.5, NaN, 0.5]", || {
        sample_case([0.0, 0.0, 1.0], [0.5, f32::NAN, 0.5])
    }));
    v.push(batch_case(
        "lq_sample",
        "`u` outside [0, 1): (7, 0.3, 0.6) and (-2, 0.3, 0.6)",
        LQ_OK,
        "",
        || {
            let o = sample_case([0.0, 0.0, 1.0], [7.0, 0.3, 0.6]);
            let o2 = sample_case([0.0, 0.0, 1.0], [-2.0, 0.3, 0.6]);
            assert_eq!(o2.outputs, o.outputs);
            Outcome {
                outputs: "u clamped into [0, 1); a valid sample (u[1] or u[2] clamped to an edge of the square may map to the horizon: a failed sample)",
                ..o
            }
        },
    ));
    v.push(batch_case("lq_sample", "NaN `wo`", LQ_ERR_INVALID_DIRECTION, "wo = [NaN, NaN, NaN]", || {
        sample_case([f32::NAN; 3], [0.5; 3])
    }));
    v.push(batch_case(
        "lq_eval_spatial",
        "`duv` given without `uv`",
        LQ_ERR_INVALID_ARGUMENT,
        "`duv` (footprint) was given without `uv`",
        || {
            let m = lambert();
            let d = [0f32, 0.0, 1.0];
            let duv = [0.01f32; 4];
            let mut f = [SENTINEL; 3];
            let status = unsafe { lq_eval_spatial(m, 1, d.as_ptr(), d.as_ptr(), null(), duv.as_ptr(), f.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(f, [SENTINEL; 3]);
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case(
        "lq_eval_spatial",
        "`uv` = (NaN, 0.5)",
        LQ_ERR_INVALID_ELEMENT,
        "element 0: uv = [NaN, 0.5]",
        || {
            let m = lambert();
            let d = [0f32, 0.0, 1.0];
            let uv = [f32::NAN, 0.5];
            let mut f = [SENTINEL; 3];
            let status = unsafe { lq_eval_spatial(m, 1, d.as_ptr(), d.as_ptr(), uv.as_ptr(), null(), f.as_mut_ptr()) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert_eq!(f, [0.0; 3]);
            Outcome { status, message, outputs: "element written as 0" }
        },
    ));

    v.push(batch_case("lq_eval_one", "output `f_rgb` = NULL", LQ_ERR_NULL, "`f_rgb` is NULL", || {
        let m = lambert();
        let d = [0f32, 0.0, 1.0];
        let status = unsafe { lq_eval_one(m, d.as_ptr(), d.as_ptr(), null_mut()) };
        let message = last_error();
        unsafe { lq_material_free(m) };
        Outcome { status, message, outputs: "nothing written" }
    }));
    v.push(batch_case(
        "lq_eval_one",
        "output `f_rgb` is the input `wi` (in place; allowed for one element)",
        LQ_OK,
        "",
        || {
            let m = lambert();
            let mut buf = [0f32, 0.0, 1.0];
            let wo = [0f32, 0.0, 1.0];
            let p = buf.as_mut_ptr();
            let status = unsafe { lq_eval_one(m, p, wo.as_ptr(), p) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert!((buf[0] - 0.5 / std::f32::consts::PI).abs() < 1e-7);
            Outcome { status, message, outputs: "f written over wi (inputs are read first)" }
        },
    ));

    // --- catalogue, checks, strings
    v.push(batch_case("lq_models_json", "`out_json` = NULL", LQ_ERR_NULL, "`out_json` is NULL", || {
        let status = unsafe { lq_models_json(null_mut()) };
        Outcome { status, message: last_error(), outputs: "nothing allocated" }
    }));
    v.push(batch_case(
        "lq_check_material",
        "level = 7 (not an lq_check_level)",
        LQ_ERR_INVALID_ARGUMENT,
        "unknown check level 7",
        || {
            let m = lambert();
            let mut report = null_mut();
            let mut passed = false;
            let status = unsafe { lq_check_material(m, 7, &mut report, &mut passed) };
            let message = last_error();
            unsafe { lq_material_free(m) };
            assert!(report.is_null());
            Outcome { status, message, outputs: "nothing written" }
        },
    ));
    v.push(batch_case("lq_check_material", "`out_passed` = NULL", LQ_ERR_NULL, "`out_passed` is NULL", || {
        let m = lambert();
        let mut report = null_mut();
        let status = unsafe { lq_check_material(m, 0, &mut report, null_mut()) };
        let message = last_error();
        unsafe { lq_material_free(m) };
        assert!(report.is_null());
        Outcome { status, message, outputs: "nothing written, no check run" }
    }));
    v.push(batch_case(
        "lq_check_model",
        "unknown model \"nope\"",
        LQ_ERR_UNKNOWN_NAME,
        "unknown model \"nope\"",
        || {
            let mut report = null_mut();
            let mut passed = true;
            let status = unsafe { lq_check_model(c"nope".as_ptr(), 0, &mut report, &mut passed) };
            assert!(report.is_null() && passed);
            Outcome { status, message: last_error(), outputs: "nothing written" }
        },
    ));
    // A sentinel string pointer: `*out_json` must still hold it after a failed fit.
    fn fit_case(json: Option<&'static CStr>) -> Outcome {
        let sentinel = 0x10 as *mut std::ffi::c_char;
        let mut out = sentinel;
        let status = unsafe { lq_fit_node_group(json.map_or(null(), CStr::as_ptr), &mut out) };
        assert_eq!(out, sentinel, "*out_json written on error");
        Outcome { status, message: last_error(), outputs: "*out_json untouched" }
    }
    v.push(batch_case("lq_fit_node_group", "`material_json` = NULL", LQ_ERR_NULL, "`material_json` is NULL", || {
        fit_case(None)
    }));
    v.push(batch_case("lq_fit_node_group", "`out_json` = NULL", LQ_ERR_NULL, "`out_json` is NULL", || {
        let status = unsafe { lq_fit_node_group(c"solid_red".as_ptr(), null_mut()) };
        Outcome { status, message: last_error(), outputs: "nothing allocated, no fit run" }
    }));
    v.push(batch_case(
        "lq_fit_node_group",
        "`{\"model\": \"lambert\"}` (not a coated_paint)",
        LQ_ERR_INVALID_MATERIAL,
        "approximates a coated_paint material",
        || fit_case(Some(c"{\"model\": \"lambert\"}")),
    ));
    v.push(batch_case(
        "lq_fit_node_group",
        "unknown preset \"nope\"",
        LQ_ERR_UNKNOWN_NAME,
        "unknown preset \"nope\"",
        || fit_case(Some(c"nope")),
    ));
    v.push(batch_case("lq_fit_node_group", "`{not json`", LQ_ERR_INVALID_JSON, "invalid JSON", || {
        fit_case(Some(c"{not json"))
    }));
    v.push(batch_case("lq_material_free / lq_string_free", "NULL", LQ_OK, "", || {
        unsafe {
            lq_material_free(null_mut());
            lq_string_free(null_mut());
        }
        Outcome { status: LQ_OK, message: String::new(), outputs: "no-op" }
    }));
    v.push(batch_case("lq_status_name", "999 (not a status)", LQ_OK, "", || {
        let name = unsafe { CStr::from_ptr(lq_status_name(999)) }.to_str().unwrap();
        assert_eq!(name, "LQ_UNKNOWN_STATUS");
        Outcome { status: LQ_OK, message: String::new(), outputs: "returns \"LQ_UNKNOWN_STATUS\"" }
    }));
    v
}

/// Every bounded numeric parameter of every registered model, just outside its range.
fn every_parameter_out_of_range() -> Outcome {
    let mut tried = 0;
    let mut last = String::new();
    for info in models::all() {
        for p in info.params {
            let numeric = matches!(p.kind, ParamKind::Scalar | ParamKind::Color | ParamKind::Integer);
            if !numeric {
                continue;
            }
            let step = if p.kind == ParamKind::Integer { 1.0 } else { 0.1 * (p.max - p.min).abs().max(1e-3) };
            for bad in [p.min - step, p.max + step] {
                if !bad.is_finite() {
                    continue;
                }
                let value = if p.kind == ParamKind::Integer { format!("{}", bad as i64) } else { format!("{bad}") };
                let json = format!("{{\"model\": \"{}\", \"{}\": {value}}}", info.name, p.name);
                let o = from_json_bytes(json.as_bytes());
                assert_eq!(o.status, LQ_ERR_INVALID_MATERIAL, "{json}: {}", o.message);
                // Colours name the channel: "albedo[0]".
                assert!(o.message.contains(&format!("\"{}", p.name)), "{json}: {}", o.message);
                tried += 1;
                last = o.message;
            }
        }
    }
    assert!(tried > 0);
    Outcome {
        status: LQ_ERR_INVALID_MATERIAL,
        message: format!("{tried} values tried, e.g.: {last}"),
        outputs: "*out untouched",
    }
}

fn md_escape(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

#[test]
fn bad_inputs_give_the_documented_status_and_message() {
    let cases = cases();
    assert!(cases.len() >= 30);
    let mut rows = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        let o = (c.run)();
        assert_eq!(
            o.status,
            c.expect,
            "case {k} ({} {}): got {} \"{}\"",
            c.function,
            c.input,
            status_name(o.status),
            o.message
        );
        assert!(
            o.message.contains(&c.contains),
            "case {k} ({} {}): message \"{}\" lacks \"{}\"",
            c.function,
            c.input,
            o.message,
            c.contains
        );
        if o.status == LQ_OK {
            assert_eq!(o.message, "", "success must clear the message");
        }
        let mut msg = o.message.clone();
        if msg.chars().count() > 160 {
            msg = msg.chars().take(157).collect::<String>() + "...";
        }
        rows.push(format!(
            "| {} | `{}` | {} | `{}` | {} | {} |",
            k + 1,
            c.function,
            md_escape(&c.input),
            status_name(o.status),
            if msg.is_empty() { "(empty)".to_string() } else { md_escape(&msg) },
            md_escape(o.outputs)
        ));
    }
    if std::env::var_os("LACQUER_BLESS_DOCS").is_some() {
        let table = format!(
            "| # | function | input | status | message (`lq_last_error()`) | outputs |\n|---|---|---|---|---|---|\n{}\n",
            rows.join("\n")
        );
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/c-api.md");
        let doc = std::fs::read_to_string(&path).expect("docs/c-api.md exists");
        let (begin, end) = ("<!-- bad-input-table:begin -->\n", "<!-- bad-input-table:end -->");
        let a = doc.find(begin).expect("begin marker") + begin.len();
        let b = doc.find(end).expect("end marker");
        std::fs::write(&path, format!("{}{table}{}", &doc[..a], &doc[b..])).unwrap();
    }
}
