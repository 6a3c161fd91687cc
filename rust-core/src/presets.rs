//! Named materials: `{"preset": "name"}` or `--preset name` wherever a material is accepted.

use serde::Serialize;

/// A named material.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Preset {
    /// Name used with `--preset` and `{"preset": ...}`.
    pub name: &'static str,
    /// What it is and where its numbers come from.
    pub description: &'static str,
    /// The full material JSON.
    pub json: &'static str,
}

/// Every preset.
pub const PRESETS: &[Preset] = &[Preset {
    name: "white_lambert",
    description: "Lossless diffuse reflector (furnace reference)",
    json: r#"{"model": "lambert", "albedo": 1.0}"#,
}];

/// Looks a preset up by name.
#[must_use]
pub fn find(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}
