//! The hard-case grid: grazing angles (cos θ down to 1e-7), the horizon, identical and
//! mirrored directions, `wi = −wo` and opposite grazing directions (undefined half vector),
//! below-horizon, non-normalised, zero, NaN and infinite inputs, extreme uniform numbers,
//! and every parameter (and pair of parameters) at its minimum and maximum. Every output
//! must be finite and non-negative, in f32 and in f64.

use super::direction;
use crate::bxdf::ModelInfo;
use crate::material::Material;
use crate::math::{Rgb, Vec3};
use crate::params::ParamKind;
use crate::real::Real;
use serde::Serialize;
use serde_json::{Map, Value};

/// Counts of misbehaving outputs.
#[derive(Clone, Debug, Default, Serialize)]
pub struct HardCaseReport {
    /// Materials exercised.
    pub materials: usize,
    /// Outputs inspected.
    pub outputs: usize,
    /// NaN outputs.
    pub nan: usize,
    /// Infinite outputs.
    pub inf: usize,
    /// Negative outputs.
    pub negative: usize,
    /// Outputs for NaN/Inf/zero input directions that were not zero.
    pub bad_input_not_zero: usize,
    /// First few offending cases.
    pub examples: Vec<String>,
    /// Parameter combinations the model rejected with an error (expected for some corners).
    pub rejected: Vec<String>,
    /// Parameter sets that should build but did not.
    pub build_errors: Vec<String>,
}

impl HardCaseReport {
    /// NaN + Inf + negative + non-zero answers to invalid input.
    #[must_use]
    pub fn failures(&self) -> usize {
        self.nan + self.inf + self.negative + self.bad_input_not_zero
    }

    fn inspect(&mut self, v: f64, what: impl FnOnce() -> String) {
        self.outputs += 1;
        let bad = if v.is_nan() {
            self.nan += 1;
            true
        } else if v.is_infinite() {
            self.inf += 1;
            true
        } else if v < 0.0 {
            self.negative += 1;
            true
        } else {
            false
        };
        if bad && self.examples.len() < 8 {
            self.examples.push(format!("{} = {v}", what()));
        }
    }

    /// Adds the result of one extreme parameter set ([`extreme_set_hard_cases`]).
    pub fn add_extreme(&mut self, r: Result<HardCaseReport, String>) {
        match r {
            Ok(r) => self.merge(r),
            Err(e) => self.rejected.push(e),
        }
    }

    fn merge(&mut self, o: HardCaseReport) {
        self.materials += o.materials;
        self.outputs += o.outputs;
        self.nan += o.nan;
        self.inf += o.inf;
        self.negative += o.negative;
        self.bad_input_not_zero += o.bad_input_not_zero;
        for e in o.examples {
            if self.examples.len() < 8 {
                self.examples.push(e);
            }
        }
    }
}

fn grid_directions() -> Vec<Vec3<f64>> {
    let mut d = Vec::new();
    for &c in &[1.0, 0.5, 1e-2, 1e-4, 1e-7, 0.0, -1e-7, -0.5] {
        for &phi in &[0.0, 0.7, std::f64::consts::FRAC_PI_2, std::f64::consts::PI, 4.0] {
            d.push(direction(c, phi));
        }
    }
    d
}

fn run_precision<T: Real>(m: &Material, dirs: &[Vec3<f64>], r: &mut HardCaseReport, tag: &str) {
    let label = |what: &str, a: Vec3<f64>, b: Vec3<f64>| format!("{tag} {what}({a:?}, {b:?})");
    for &a in dirs {
        for &b in dirs {
            let f: Rgb<T> = m.eval(a.cast(), b.cast());
            for c in 0..3 {
                r.inspect(f[c].f64(), || label("eval", a, b));
            }
            let p: T = m.pdf(a.cast(), b.cast());
            r.inspect(p.f64(), || label("pdf", a, b));
        }
    }
    // Undefined half vectors and exact special configurations.
    let special = [
        (Vec3::new(1.0, 0.0, 1e-7), Vec3::new(-1.0, 0.0, 1e-7)),
        (Vec3::new(1.0, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0)),
        (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)),
        (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, -0.8)),
    ];
    for (a, b) in special {
        let a = a.normalize();
        let b = b.normalize();
        for (x, y) in [(a, b), (b, a)] {
            let f: Rgb<T> = m.eval(x.cast(), y.cast());
            for c in 0..3 {
                r.inspect(f[c].f64(), || label("eval", x, y));
            }
            r.inspect(m.pdf::<T>(x.cast(), y.cast()).f64(), || label("pdf", x, y));
        }
    }
    let us = [0.0, 1e-7, 0.5, 1.0 - 1e-7, 1.0];
    for &wo in dirs {
        for &u0 in &us {
            for &u1 in &us {
                for &u2 in &us {
                    let u = [T::of(u0), T::of(u1), T::of(u2)];
                    if let Some(s) = m.sample(wo.cast::<T>(), u) {
                        let what = || format!("{tag} sample(wo={wo:?}, u=[{u0}, {u1}, {u2}])");
                        for c in 0..3 {
                            r.inspect(s.weight[c].f64(), what);
                        }
                        r.inspect(s.pdf.f64(), what);
                        if !s.wi.is_finite() {
                            r.inspect(f64::NAN, || format!("{} wi", what()));
                        }
                    }
                }
            }
        }
    }
}

/// `eval_at` and `sample_at` of a spatially varying material on degenerate and extreme
/// surface points (zero, tiny, huge and sheared footprints; huge positions) over a direction
/// grid that includes the mirror configuration.
fn run_spatial<T: Real>(m: &Material, r: &mut HardCaseReport, tag: &str) {
    let mut dirs: Vec<Vec3<f64>> = Vec::new();
    for &c in &[1.0, 0.9, 0.5, 1e-2, 1e-7, 0.0, -0.5] {
        for &phi in &[0.0, std::f64::consts::FRAC_PI_2, std::f64::consts::PI] {
            dirs.push(direction(c, phi));
        }
    }
    for at in super::sparkle::extreme_surface_points() {
        for &a in &dirs {
            for &b in &dirs {
                let f: Rgb<T> = m.eval_at(a.cast(), b.cast(), &at);
                for c in 0..3 {
                    r.inspect(f[c].f64(), || format!("{tag} eval_at({a:?}, {b:?}, {at:?})"));
                }
            }
            for u1 in [0.0, 0.5, 1.0 - 1e-7] {
                for u2 in [0.0, 0.37, 1.0 - 1e-7] {
                    for u0 in [0.0, 0.3, 0.7, 1.0 - 1e-7] {
                        let u = [T::of(u0), T::of(u1), T::of(u2)];
                        if let Some(s) = m.sample_at(a.cast::<T>(), u, &at) {
                            let what = || format!("{tag} sample_at(wo={a:?}, u=[{u0}, {u1}, {u2}], {at:?})");
                            for c in 0..3 {
                                r.inspect(s.weight[c].f64(), what);
                            }
                            r.inspect(s.pdf.f64(), what);
                        }
                    }
                }
            }
        }
    }
}

/// Runs the direction grid and bad inputs on one material, in f32 and f64 (and the spatial
/// path on extreme surface points for a material that sparkles).
#[must_use]
pub fn hard_cases(m: &Material) -> HardCaseReport {
    let mut r = HardCaseReport { materials: 1, ..Default::default() };
    let dirs = grid_directions();
    run_precision::<f64>(m, &dirs, &mut r, "f64");
    run_precision::<f32>(m, &dirs, &mut r, "f32");
    if m.spatially_varying() {
        run_spatial::<f64>(m, &mut r, "f64");
        run_spatial::<f32>(m, &mut r, "f32");
    }
    // Finite but not unit length: normalised by the front end, so results must be finite.
    let good = direction(0.6, 0.3);
    for scale in [1e-3, 7.0, 1e3] {
        let f = m.eval(good * scale, direction(0.8, 2.0) * scale);
        for c in 0..3 {
            r.inspect(f[c], || format!("eval with directions scaled by {scale}"));
        }
    }
    // Invalid input: must answer zero / no sample.
    let bad = [
        Vec3::new(f64::NAN, 0.0, 1.0),
        Vec3::new(0.0, f64::INFINITY, 1.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, f64::NEG_INFINITY),
    ];
    for b in bad {
        let zero = m.eval(b, good).is_black()
            && m.eval(good, b).is_black()
            && m.pdf(b, good) == 0.0
            && m.pdf(good, b) == 0.0
            && m.sample(b, [0.5; 3]).is_none()
            && m.sample(good, [f64::NAN, 0.5, 0.5]).is_none();
        if !zero {
            r.bad_input_not_zero += 1;
            if r.examples.len() < 8 {
                r.examples.push(format!("invalid direction {b:?} gave a non-zero answer"));
            }
        }
    }
    r
}

/// Hard cases over parameter extremes: each numeric parameter at its min and max, and each
/// pair of them at the four corners (covers e.g. anisotropy ratios α_x/α_y of 1000).
#[must_use]
pub fn parameter_extremes(info: &'static ModelInfo) -> HardCaseReport {
    let mut total = HardCaseReport::default();
    for obj in extreme_parameter_sets(info) {
        total.add_extreme(extreme_set_hard_cases(info, &obj));
    }
    total
}

/// The parameter sets of [`parameter_extremes`], in its order: each numeric parameter at its
/// min and max, and each pair at the four corners.
#[must_use]
pub fn extreme_parameter_sets(info: &'static ModelInfo) -> Vec<Map<String, Value>> {
    let numeric: Vec<_> = info
        .params
        .iter()
        .filter(|s| matches!(s.kind, ParamKind::Scalar | ParamKind::Integer | ParamKind::Color))
        .collect();
    let value = |s: &crate::params::ParamSpec, hi: bool| {
        let v = if hi { s.max } else { s.min };
        if s.kind == ParamKind::Integer {
            Value::from(v as i64)
        } else {
            Value::from(v)
        }
    };
    let mut sets: Vec<Map<String, Value>> = Vec::new();
    for (i, a) in numeric.iter().enumerate() {
        for hi in [false, true] {
            let mut o = Map::new();
            o.insert(a.name.into(), value(a, hi));
            sets.push(o);
        }
        for b in numeric.iter().skip(i + 1) {
            for (ha, hb) in [(false, false), (false, true), (true, false), (true, true)] {
                let mut o = Map::new();
                o.insert(a.name.into(), value(a, ha));
                o.insert(b.name.into(), value(b, hb));
                sets.push(o);
            }
        }
    }
    sets
}

/// The hard cases of one extreme parameter set, or the model's error when it rejects the set
/// (fold the results in order with [`HardCaseReport::add_extreme`]).
pub fn extreme_set_hard_cases(info: &'static ModelInfo, obj: &Map<String, Value>) -> Result<HardCaseReport, String> {
    match super::build(info, obj) {
        Ok(m) => {
            let mut r = hard_cases(&m);
            let params = Value::Object(obj.clone());
            r.examples = r.examples.into_iter().map(|e| format!("{params}: {e}")).collect();
            Ok(r)
        }
        Err(e) => Err(format!("{}: {e}", Value::Object(obj.clone()))),
    }
}
