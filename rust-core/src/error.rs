//! Errors for material construction and input validation. Every message names the
//! parameter at fault and, where there is one, its valid range.

use std::fmt;

/// Why a material or an input was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// The text is not valid JSON (message from the parser, with line and column).
    Json(String),
    /// The JSON is valid but not an object with a `"model"` (or `"preset"`) string.
    Shape(String),
    /// No model has this name.
    UnknownModel { name: String, known: Vec<&'static str> },
    /// No preset has this name.
    UnknownPreset { name: String },
    /// A key the model does not have.
    UnknownKey { model: &'static str, key: String, known: Vec<&'static str> },
    /// A value of the wrong JSON type.
    WrongType { param: String, expected: &'static str },
    /// A number outside its documented range (or NaN/∞).
    OutOfRange { param: String, value: f64, min: f64, max: f64, unit: &'static str },
    /// A combination of values the model cannot represent.
    Invalid { param: String, reason: String },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Json(m) => write!(f, "invalid JSON: {m}"),
            Error::Shape(m) => write!(f, "invalid material: {m}"),
            Error::UnknownModel { name, known } => {
                write!(f, "unknown model \"{name}\"; known models: {}", known.join(", "))
            }
            Error::UnknownPreset { name } => {
                write!(f, "unknown preset \"{name}\" (list them with `lacquer presets`)")
            }
            Error::UnknownKey { model, key, known } => {
                write!(f, "model \"{model}\" has no parameter \"{key}\"; its parameters are: {}", known.join(", "))
            }
            Error::WrongType { param, expected } => {
                write!(f, "parameter \"{param}\" must be {expected}")
            }
            Error::OutOfRange { param, value, min, max, unit } => {
                let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
                write!(f, "parameter \"{param}\" = {value} is outside its range [{min}, {max}]{unit}")
            }
            Error::Invalid { param, reason } => write!(f, "parameter \"{param}\": {reason}"),
        }
    }
}

impl std::error::Error for Error {}
