//! Named materials: `{"preset": "name"}` or `--preset name` wherever a material is accepted.
//!
//! The coated-paint presets follow the thesis' sample set (seed 004, §4.2, figures 4.3a/b):
//! gold and silver paints with metallic flake density 0, 2, 3, 5 and 8 % at 25 µm, and flake
//! sizes 15, 20 and 25 µm at 8 %. The thesis measures its samples and does not publish their
//! formulation, so the pigment colours, flake metal (aluminium, as §3.2 says metallic flakes
//! usually are) and flake orientation spread are this project's choices, kept identical across
//! a series so that only the thesis' variable changes. Mapping of the thesis' microstructure
//! terms: "flake density" → `flake_density` (% of area covered), "average flake size" →
//! `flake_size_um` (diameter), "clearcoat 35–45 µm" → `coat_thickness_um`, "flakes act like
//! small mirrors" → the flake lobe's conductor Fresnel and orientation spread, "pearlescent
//! (mica + TiO₂/Fe₂O₃) interference" → `pearl_*` (thin-film Airy reflectance of a platelet:
//! the oxide film on both faces of a mica core).

use serde::Serialize;

/// A named material.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Preset {
    /// Name used with `--preset` and `{"preset": ...}`.
    pub name: &'static str,
    /// Human-readable label (menus).
    pub label: &'static str,
    /// What it is and where its numbers come from.
    pub description: &'static str,
    /// The full material JSON.
    pub json: &'static str,
}

macro_rules! thesis_paint {
    ($name:literal, $label:literal, $base:expr, $density:literal, $size:literal) => {
        Preset {
            name: $name,
            label: $label,
            description: concat!(
                "Thesis sample series (seed 004 fig. 4.3): ",
                $density,
                " % aluminium flakes of ",
                $size,
                " µm under a 40 µm clearcoat"
            ),
            json: concat!(
                r#"{"model": "coated_paint", "base_color": "#,
                $base,
                r#", "flake_density": "#,
                $density,
                r#", "flake_size_um": "#,
                $size,
                r#", "flake_material": "Al", "flake_orientation_deg": 12, "coat_ior": 1.5, "coat_roughness": 0.02, "coat_thickness_um": 40}"#
            ),
        }
    };
}

/// Gold paint pigment (an ochre that gives a gold look together with aluminium flakes).
macro_rules! gold {
    () => {
        "[0.55, 0.36, 0.07]"
    };
}
/// Silver paint pigment (a light neutral grey).
macro_rules! silver {
    () => {
        "[0.42, 0.43, 0.45]"
    };
}

/// Every preset.
pub const PRESETS: &[Preset] = &[
    thesis_paint!("gold_flake_0", "Gold solid (0 % flakes)", gold!(), "0", "25"),
    thesis_paint!("gold_flake_2", "Gold metallic 2 %", gold!(), "2", "25"),
    thesis_paint!("gold_flake_3", "Gold metallic 3 %", gold!(), "3", "25"),
    thesis_paint!("gold_flake_5", "Gold metallic 5 %", gold!(), "5", "25"),
    thesis_paint!("gold_flake_8", "Gold metallic 8 %", gold!(), "8", "25"),
    thesis_paint!("gold_flake_8_size_15", "Gold metallic 8 %, 15 µm flakes", gold!(), "8", "15"),
    thesis_paint!("gold_flake_8_size_20", "Gold metallic 8 %, 20 µm flakes", gold!(), "8", "20"),
    thesis_paint!("gold_flake_8_size_25", "Gold metallic 8 %, 25 µm flakes", gold!(), "8", "25"),
    thesis_paint!("silver_flake_0", "Silver solid (0 % flakes)", silver!(), "0", "25"),
    thesis_paint!("silver_flake_2", "Silver metallic 2 %", silver!(), "2", "25"),
    thesis_paint!("silver_flake_3", "Silver metallic 3 %", silver!(), "3", "25"),
    thesis_paint!("silver_flake_5", "Silver metallic 5 %", silver!(), "5", "25"),
    thesis_paint!("silver_flake_8", "Silver metallic 8 %", silver!(), "8", "25"),
    thesis_paint!("silver_flake_8_size_15", "Silver metallic 8 %, 15 µm flakes", silver!(), "8", "15"),
    thesis_paint!("silver_flake_8_size_20", "Silver metallic 8 %, 20 µm flakes", silver!(), "8", "20"),
    thesis_paint!("silver_flake_8_size_25", "Silver metallic 8 %, 25 µm flakes", silver!(), "8", "25"),
    Preset {
        name: "solid_red",
        label: "Solid red",
        description: "Solid (conventional) paint: red pigment, no flakes, smooth clearcoat",
        json: r#"{"model": "coated_paint", "base_color": [0.45, 0.02, 0.02], "flake_density": 0, "coat_roughness": 0.01}"#,
    },
    Preset {
        name: "solid_white",
        label: "Solid white",
        description: "Solid white paint (TiO₂ pigment), no flakes",
        json: r#"{"model": "coated_paint", "base_color": [0.85, 0.85, 0.83], "flake_density": 0, "coat_roughness": 0.01}"#,
    },
    Preset {
        name: "solid_black",
        label: "Solid black",
        description: "Solid black paint: the clearcoat reflection dominates",
        json: r#"{"model": "coated_paint", "base_color": [0.02, 0.02, 0.02], "flake_density": 0, "coat_roughness": 0.01}"#,
    },
    Preset {
        name: "pearl_white",
        label: "Pearl white",
        description: "White pearlescent: mica platelets coated on both faces with a ~70 nm TiO₂ film (silver-white interference; the two faces add incoherently through the mica) over a white base",
        json: r#"{"model": "coated_paint", "base_color": [0.8, 0.8, 0.78], "flake_density": 0, "pearl_density": 12, "pearl_film_nm": 70, "pearl_film_ior": 2.6, "pearl_size_um": 15, "coat_roughness": 0.02}"#,
    },
    Preset {
        name: "pearl_blue",
        label: "Blue interference pearl",
        description: "Blue pearlescent: mica platelets coated on both faces with a ~140 nm TiO₂ film (blue interference, yellow transmission; the two faces add incoherently through the mica) over a dark blue base",
        json: r#"{"model": "coated_paint", "base_color": [0.03, 0.05, 0.18], "flake_density": 1, "pearl_density": 10, "pearl_film_nm": 140, "pearl_film_ior": 2.6, "pearl_size_um": 18, "coat_roughness": 0.02}"#,
    },
    Preset {
        name: "automotive_silver_metallic",
        label: "Automotive silver metallic",
        description: "A typical automotive silver metallic: 20 µm aluminium flakes at 6 % over a grey base, slightly absorbing clearcoat",
        json: r#"{"model": "coated_paint", "base_color": [0.3, 0.3, 0.32], "flake_density": 6, "flake_size_um": 20, "flake_orientation_deg": 10, "coat_roughness": 0.015, "coat_thickness_um": 40, "coat_absorption": [0.5, 0.5, 0.6]}"#,
    },
    Preset {
        name: "white_lambert",
        label: "White Lambert (furnace reference)",
        description: "Lossless diffuse reflector: the white-furnace reference",
        json: r#"{"model": "lambert", "albedo": 1.0}"#,
    },
];

impl Preset {
    /// The preset's complete material JSON (every parameter), as `to_json` of the built
    /// material gives it, without building the material (see [`crate::Material::canonical_json`]).
    pub fn material_json(&self) -> Result<serde_json::Value, crate::Error> {
        let v: serde_json::Value = serde_json::from_str(self.json).map_err(|e| crate::Error::Json(e.to_string()))?;
        crate::Material::canonical_json(&v)
    }
}

/// Looks a preset up by name.
#[must_use]
pub fn find(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Material;
    use serde_json::{json, Value};

    /// The listing's JSON comes from the parameters alone; the built material (the other path)
    /// must say the same, for the preset's JSON and for `{"preset": name}`.
    #[test]
    fn material_json_is_the_built_materials_json() {
        for p in PRESETS {
            let built = Material::from_json(p.json).unwrap().to_json();
            assert_eq!(p.material_json().unwrap(), built, "{}", p.name);
            assert_eq!(Material::canonical_json(&json!({ "preset": p.name })).unwrap(), built, "{}", p.name);
        }
    }

    /// Without the build, the parameter checks still run: the same errors as `from_value`.
    #[test]
    fn canonical_json_rejects_what_building_rejects() {
        for bad in [
            r#"{"model": "lambert", "albedo": -0.5}"#,
            r#"{"model": "lambert", "roughness": 0.1}"#,
            r#"{"model": "coated_paint", "coat_ior": "1.5"}"#,
            r#"{"model": "nope"}"#,
            r#"{"preset": "nope"}"#,
            r#"{"preset": "gold_flake_8", "coat_ior": 1.5}"#,
            r#"{"albedo": 0.5}"#,
            "[1]",
        ] {
            let v: Value = serde_json::from_str(bad).unwrap();
            let canonical = Material::canonical_json(&v).unwrap_err().to_string();
            let built = Material::from_value(&v).unwrap_err().to_string();
            assert_eq!(canonical, built, "{bad}");
        }
    }
}
