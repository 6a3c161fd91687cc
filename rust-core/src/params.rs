//! Model parameters: their specification (name, kind, default, range, unit, meaning) and
//! the validated values parsed from material JSON.

use crate::error::Error;
use serde::Serialize;
use serde_json::{Map, Value};

/// What kind of value a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamKind {
    /// A number within `[min, max]`.
    Scalar,
    /// `[r, g, b]` or a scalar (grey), each within `[min, max]`.
    Color,
    /// A whole number within `[min, max]`.
    Integer,
    /// `true` / `false`.
    Bool,
    /// One of a fixed set of strings.
    Choice(&'static [&'static str]),
    /// A structured JSON value validated by the model itself (e.g. Lafortune's lobe list).
    Json,
    /// A free string (e.g. a file path); the model validates its content when it builds.
    Text,
}

/// The default value of a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Default {
    /// A number.
    Scalar(f64),
    /// A colour.
    Color([f64; 3]),
    /// A whole number.
    Integer(i64),
    /// A flag.
    Bool(bool),
    /// A string choice.
    Choice(&'static str),
    /// JSON text.
    Json(&'static str),
    /// A free string.
    Text(&'static str),
}

/// Specification of one model parameter; `lacquer models --json` prints these.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ParamSpec {
    /// JSON key.
    pub name: &'static str,
    /// Value kind.
    pub kind: ParamKind,
    /// Value when the key is absent.
    pub default: Default,
    /// Smallest valid value (numbers, colours, integers).
    pub min: f64,
    /// Largest valid value.
    pub max: f64,
    /// Physical unit ("" when dimensionless).
    pub unit: &'static str,
    /// One-line meaning.
    pub doc: &'static str,
}

impl ParamSpec {
    /// A scalar parameter.
    #[must_use]
    pub const fn scalar(
        name: &'static str,
        default: f64,
        min: f64,
        max: f64,
        unit: &'static str,
        doc: &'static str,
    ) -> Self {
        Self { name, kind: ParamKind::Scalar, default: Default::Scalar(default), min, max, unit, doc }
    }
    /// A colour parameter (linear Rec.709 RGB).
    #[must_use]
    pub const fn color(name: &'static str, default: [f64; 3], min: f64, max: f64, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Color, default: Default::Color(default), min, max, unit: "", doc }
    }
    /// An integer parameter.
    #[must_use]
    pub const fn integer(name: &'static str, default: i64, min: i64, max: i64, doc: &'static str) -> Self {
        Self {
            name,
            kind: ParamKind::Integer,
            default: Default::Integer(default),
            min: min as f64,
            max: max as f64,
            unit: "",
            doc,
        }
    }
    /// A boolean parameter.
    #[must_use]
    pub const fn boolean(name: &'static str, default: bool, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Bool, default: Default::Bool(default), min: 0.0, max: 1.0, unit: "", doc }
    }
    /// A string choice.
    #[must_use]
    pub const fn choice(
        name: &'static str,
        default: &'static str,
        choices: &'static [&'static str],
        doc: &'static str,
    ) -> Self {
        Self {
            name,
            kind: ParamKind::Choice(choices),
            default: Default::Choice(default),
            min: 0.0,
            max: 0.0,
            unit: "",
            doc,
        }
    }
    /// A free string parameter (e.g. a file path), validated by the model when it builds.
    #[must_use]
    pub const fn text(name: &'static str, default: &'static str, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Text, default: Default::Text(default), min: 0.0, max: 0.0, unit: "", doc }
    }
    /// A structured JSON parameter, validated by the model.
    #[must_use]
    pub const fn json(name: &'static str, default: &'static str, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Json, default: Default::Json(default), min: 0.0, max: 0.0, unit: "", doc }
    }
}

/// A parsed parameter value.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// Number.
    Scalar(f64),
    /// Colour.
    Color([f64; 3]),
    /// Whole number.
    Integer(i64),
    /// Flag.
    Bool(bool),
    /// Choice or free string.
    Text(String),
    /// Structured value.
    Json(Value),
}

/// Validated parameter values of one material, every parameter present (defaults filled in).
#[derive(Clone, Debug)]
pub struct Params {
    model: &'static str,
    values: Vec<(&'static str, ParamValue)>,
}

fn check_range(spec: &ParamSpec, param: &str, v: f64) -> Result<f64, Error> {
    if !v.is_finite() || v < spec.min || v > spec.max {
        return Err(Error::OutOfRange {
            param: param.to_string(),
            value: v,
            min: spec.min,
            max: spec.max,
            unit: spec.unit,
        });
    }
    Ok(v)
}

fn parse_value(spec: &ParamSpec, v: &Value) -> Result<ParamValue, Error> {
    let name = spec.name;
    let wrong = |expected| Error::WrongType { param: name.to_string(), expected };
    Ok(match spec.kind {
        ParamKind::Scalar => ParamValue::Scalar(check_range(spec, name, v.as_f64().ok_or_else(|| wrong("a number"))?)?),
        ParamKind::Color => {
            const EXPECTED: &str = "a number or an array of three numbers [r, g, b]";
            let c = if let Some(x) = v.as_f64() {
                [x; 3]
            } else {
                let a = v.as_array().filter(|a| a.len() == 3).ok_or_else(|| wrong(EXPECTED))?;
                let mut c = [0.0; 3];
                for (i, x) in a.iter().enumerate() {
                    c[i] = x.as_f64().ok_or_else(|| wrong(EXPECTED))?;
                }
                c
            };
            for (i, x) in c.iter().enumerate() {
                check_range(spec, &format!("{name}[{i}]"), *x)?;
            }
            ParamValue::Color(c)
        }
        ParamKind::Integer => {
            let i = v.as_i64().ok_or_else(|| wrong("a whole number"))?;
            check_range(spec, name, i as f64)?;
            ParamValue::Integer(i)
        }
        ParamKind::Bool => ParamValue::Bool(v.as_bool().ok_or_else(|| wrong("true or false"))?),
        ParamKind::Choice(choices) => {
            let s = v.as_str().ok_or_else(|| wrong("a string"))?;
            if !choices.contains(&s) {
                return Err(Error::Invalid {
                    param: name.to_string(),
                    reason: format!("\"{s}\" is not one of: {}", choices.join(", ")),
                });
            }
            ParamValue::Text(s.to_string())
        }
        ParamKind::Json => ParamValue::Json(v.clone()),
        ParamKind::Text => ParamValue::Text(v.as_str().ok_or_else(|| wrong("a string"))?.to_string()),
    })
}

fn default_value(spec: &ParamSpec) -> ParamValue {
    match spec.default {
        Default::Scalar(x) => ParamValue::Scalar(x),
        Default::Color(c) => ParamValue::Color(c),
        Default::Integer(i) => ParamValue::Integer(i),
        Default::Bool(b) => ParamValue::Bool(b),
        Default::Choice(s) | Default::Text(s) => ParamValue::Text(s.to_string()),
        Default::Json(s) => ParamValue::Json(serde_json::from_str(s).expect("default JSON of a parameter is valid")),
    }
}

impl Params {
    /// Validates `object` (without its `"model"` key) against `specs`: unknown keys, wrong
    /// types and out-of-range values are errors; absent keys take their defaults.
    pub fn parse(model: &'static str, specs: &'static [ParamSpec], object: &Map<String, Value>) -> Result<Self, Error> {
        for key in object.keys() {
            if key != "model" && !specs.iter().any(|s| s.name == key) {
                return Err(Error::UnknownKey {
                    model,
                    key: key.clone(),
                    known: specs.iter().map(|s| s.name).collect(),
                });
            }
        }
        let mut values = Vec::with_capacity(specs.len());
        for spec in specs {
            let value = match object.get(spec.name) {
                Some(v) => parse_value(spec, v)?,
                None => default_value(spec),
            };
            values.push((spec.name, value));
        }
        Ok(Self { model, values })
    }

    /// All defaults of a model.
    #[must_use]
    pub fn defaults(model: &'static str, specs: &'static [ParamSpec]) -> Self {
        Self { model, values: specs.iter().map(|s| (s.name, default_value(s))).collect() }
    }

    /// The model these parameters belong to.
    #[must_use]
    pub fn model(&self) -> &'static str {
        self.model
    }

    fn get(&self, name: &str) -> &ParamValue {
        &self
            .values
            .iter()
            .find(|(n, _)| *n == name)
            .unwrap_or_else(|| panic!("model {} reads undeclared parameter {name}", self.model))
            .1
    }

    /// A scalar parameter's value.
    #[must_use]
    pub fn scalar(&self, name: &str) -> f64 {
        match self.get(name) {
            ParamValue::Scalar(x) => *x,
            ParamValue::Integer(i) => *i as f64,
            other => panic!("parameter {name} is not a scalar: {other:?}"),
        }
    }
    /// A colour parameter's value.
    #[must_use]
    pub fn color(&self, name: &str) -> [f64; 3] {
        match self.get(name) {
            ParamValue::Color(c) => *c,
            other => panic!("parameter {name} is not a colour: {other:?}"),
        }
    }
    /// An integer parameter's value.
    #[must_use]
    pub fn integer(&self, name: &str) -> i64 {
        match self.get(name) {
            ParamValue::Integer(i) => *i,
            other => panic!("parameter {name} is not an integer: {other:?}"),
        }
    }
    /// A boolean parameter's value.
    #[must_use]
    pub fn boolean(&self, name: &str) -> bool {
        match self.get(name) {
            ParamValue::Bool(b) => *b,
            other => panic!("parameter {name} is not a flag: {other:?}"),
        }
    }
    /// A choice parameter's value.
    #[must_use]
    pub fn choice(&self, name: &str) -> &str {
        match self.get(name) {
            ParamValue::Text(s) => s,
            other => panic!("parameter {name} is not a choice: {other:?}"),
        }
    }
    /// A text parameter's value.
    #[must_use]
    pub fn text(&self, name: &str) -> &str {
        match self.get(name) {
            ParamValue::Text(s) => s,
            other => panic!("parameter {name} is not text: {other:?}"),
        }
    }
    /// A structured parameter's JSON.
    #[must_use]
    pub fn json(&self, name: &str) -> &Value {
        match self.get(name) {
            ParamValue::Json(v) => v,
            other => panic!("parameter {name} is not JSON: {other:?}"),
        }
    }

    /// The complete material as JSON (model plus every parameter, defaults included).
    #[must_use]
    pub fn to_json(&self) -> Value {
        let mut map = Map::new();
        map.insert("model".into(), Value::String(self.model.into()));
        for (name, v) in &self.values {
            map.insert((*name).into(), serde_json::to_value(v).expect("parameter values serialise"));
        }
        Value::Object(map)
    }
}
