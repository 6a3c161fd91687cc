//! What kinds of lobes a material has, and the albedo of its diffuse (pigment) part: the
//! queries a renderer needs to set its component flags (Mitsuba's `BSDFFlags`) and its
//! albedo AOVs without probing the BRDF.
//!
//! Decided from the model and its parameter values (the same thresholds the models use to
//! build their lobes); `tests` checks the delta and anisotropy bits against sampling and
//! evaluation of every model's check materials.

use crate::material::Material;
use serde_json::Value;

/// Lobe bits of [`Material::lobes`] (the same numbers as the C ABI's `LQ_LOBE_*`).
pub mod bits {
    /// A diffuse (Lambert-like, wide) lobe: a pigment or diffuse term.
    pub const DIFFUSE: u32 = 1;
    /// A glossy (smooth, direction-dependent) lobe.
    pub const GLOSSY: u32 = 2;
    /// A Dirac delta (mirror) lobe: `sample` can return `delta` samples.
    pub const DELTA: u32 = 4;
    /// The BRDF changes when both directions rotate about the normal.
    pub const ANISOTROPIC: u32 = 8;
    /// The model does not claim `f(wi, wo) = f(wo, wi)`.
    pub const NON_RECIPROCAL: u32 = 16;
    /// `eval_at` differs from `eval` (sparkle: uv and footprint matter).
    pub const SPATIALLY_VARYING: u32 = 32;
    /// The value depends on the wavelength beyond its RGB projection (thin film, HTSG):
    /// `Material::eval_spectral` evaluates the physics per wavelength.
    pub const SPECTRAL: u32 = 64;
    /// The material has a clearcoat top reflection that a lobe mask selects on its own
    /// (`COAT` in [`SELECTABLE`]); its kind (`GLOSSY`, or `DELTA` for a smooth coat) is in
    /// [`crate::Material::lobe_parts`].
    pub const COAT: u32 = 128;
    /// The bits a lobe mask may hold ([`crate::Material::select_lobes`]): `DIFFUSE` (pigment,
    /// diffuse terms), `GLOSSY` (glossy lobes other than a coat's top reflection: flakes,
    /// metallic base, specular lobes) and `COAT` (the clearcoat's top reflection).
    pub const SELECTABLE: u32 = DIFFUSE | GLOSSY | COAT;
}

/// A lobe group of a material that a lobe mask selects: `select` the mask bit(s) that enable
/// it ([`bits::SELECTABLE`]), `kinds` what it is (`DIFFUSE`, `GLOSSY`, `DELTA` bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LobePart {
    /// The lobe-mask bits that enable this group (all of them must be set for models that
    /// do not separate their lobes).
    pub select: u32,
    /// Its kinds: [`bits::DIFFUSE`], [`bits::GLOSSY`], [`bits::DELTA`].
    pub kinds: u32,
}

/// A lobe mask validated against a material ([`crate::Material::select_lobes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeSelection {
    /// Every lobe the material has: the plain calls (no cost, the same results).
    All,
    /// None of its lobes: zero values and densities, failed samples.
    Nothing,
    /// Some of the lobes of a model that separates them (the mask, restricted to its parts).
    Some(u32),
}

/// The lobe groups of a material (see [`LobePart`]).
pub(crate) fn lobe_parts(m: &Material) -> Vec<LobePart> {
    let split = match m.model() {
        crate::Model::CoatedPaint(p) => Some(p.lobe_parts()),
        crate::Model::RoughPlastic(p) => Some(p.lobe_parts()),
        _ => None,
    };
    if let Some(parts) = split.filter(|p| !p.is_empty()) {
        return parts.into_iter().map(|(select, kinds)| LobePart { select, kinds }).collect();
    }
    let kinds = lobes(m) & (bits::DIFFUSE | bits::GLOSSY | bits::DELTA);
    let select =
        if DIFFUSE_ONLY.contains(&m.info().name) { bits::DIFFUSE } else { bits::GLOSSY | (kinds & bits::DIFFUSE) };
    vec![LobePart { select, kinds: if kinds == 0 { select } else { kinds } }]
}

/// Validates a lobe mask for a material (see [`crate::Material::select_lobes`]).
pub(crate) fn select_lobes(m: &Material, mask: u32) -> Result<LobeSelection, crate::Error> {
    if mask & !bits::SELECTABLE != 0 {
        return Err(crate::Error::Invalid {
            param: "lobes".into(),
            reason: format!(
                "lobe mask {mask:#x} has bits other than DIFFUSE (1), GLOSSY (2) and COAT (128): {:#x}",
                mask & !bits::SELECTABLE
            ),
        });
    }
    let parts = lobe_parts(m);
    let union = parts.iter().fold(0, |a, p| a | p.select);
    if mask & union == union {
        return Ok(LobeSelection::All);
    }
    if mask & union == 0 {
        return Ok(LobeSelection::Nothing);
    }
    if m.model().separates_lobes() {
        return Ok(LobeSelection::Some(mask & union));
    }
    Err(crate::Error::Invalid {
        param: "lobes".into(),
        reason: format!(
            "model \"{}\" evaluates its lobes (mask bits {union:#x}) together: a lobe mask must enable all or none of them (got {mask:#x})",
            m.info().name
        ),
    })
}

/// Models whose only lobe is diffuse.
const DIFFUSE_ONLY: &[&str] = &["lambert", "oren_nayar", "oren_nayar_qualitative", "eon"];
/// Models anisotropic by construction (gratings, cylinders).
const ALWAYS_ANISOTROPIC: &[&str] = &["stam", "poulin_fournier"];
/// Parameter pairs whose inequality makes a model anisotropic.
const ANISO_PAIRS: &[(&str, &str)] =
    &[("alpha_x", "alpha_y"), ("alpha_u", "alpha_v"), ("nu", "nv"), ("correlation_x", "correlation_y")];
/// Cycles' mirror threshold on α² (as `models::principled` uses it).
const PRINCIPLED_SINGULAR_ALPHA2: f64 = 1e-7;
/// Cycles' lobe weight cutoff (as `models::principled` uses it).
const PRINCIPLED_WEIGHT_CUTOFF: f64 = 1e-5;

struct View<'a>(&'a serde_json::Map<String, Value>);

impl View<'_> {
    fn num(&self, name: &str) -> Option<f64> {
        self.0.get(name).and_then(Value::as_f64)
    }
    fn color(&self, name: &str) -> Option<[f64; 3]> {
        match self.0.get(name)? {
            Value::Array(a) if a.len() == 3 => Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?]),
            v => v.as_f64().map(|x| [x; 3]),
        }
    }
}

fn scale(c: [f64; 3], s: f64) -> [f64; 3] {
    c.map(|x| x * s)
}

/// The diffuse (pigment) albedo of a material, linear Rec.709 (zero when it has none).
pub(crate) fn diffuse_reflectance(m: &Material) -> [f64; 3] {
    let json = m.to_json();
    let Some(obj) = json.as_object() else { return [0.0; 3] };
    let p = View(obj);
    match m.info().name {
        "lambert" | "oren_nayar" | "oren_nayar_qualitative" | "eon" => p.color("albedo").unwrap_or([0.0; 3]),
        "cook_torrance" | "cook_torrance_1981" => {
            scale(p.color("albedo").unwrap_or([0.0; 3]), p.num("kd").unwrap_or(0.0))
        }
        "coated_paint" => p.color("base_color").unwrap_or([0.0; 3]),
        "principled" => scale(p.color("base_color").unwrap_or([0.0; 3]), 1.0 - p.num("metallic").unwrap_or(0.0)),
        "rough_plastic" => p.color("diffuse_reflectance").unwrap_or([0.0; 3]),
        _ => p.color("diffuse").unwrap_or([0.0; 3]),
    }
}

/// The lobe bits ([`bits`]) of a material.
pub(crate) fn lobes(m: &Material) -> u32 {
    let info = m.info();
    let json = m.to_json();
    let empty = serde_json::Map::new();
    let p = View(json.as_object().unwrap_or(&empty));
    let name = info.name;
    let mut out = 0;
    if diffuse_reflectance(m).iter().any(|&x| x > 0.0) {
        out |= bits::DIFFUSE;
    }
    if !DIFFUSE_ONLY.contains(&name) {
        out |= bits::GLOSSY;
    }
    match name {
        // coated_paint: from its lobe groups, below.
        "principled" => {
            let singular = |r: f64| (r * r) * (r * r) <= PRINCIPLED_SINGULAR_ALPHA2;
            let coat = p.num("coat_weight").unwrap_or(0.0) > PRINCIPLED_WEIGHT_CUTOFF
                && p.num("coat_ior").is_some_and(|e| e != 1.0);
            if singular(p.num("roughness").unwrap_or(1.0)) || (coat && singular(p.num("coat_roughness").unwrap_or(1.0)))
            {
                out |= bits::DELTA;
            }
        }
        "htsg" => out |= bits::DELTA,
        _ => {}
    }
    if let crate::Model::CoatedPaint(paint) = m.model() {
        // The kinds are those of the lobe groups a mask selects (the built paint's): the coat's
        // top reflection (none for a coat of index 1), and a diffuse group that also holds the
        // multiple-scatter lobe (non-zero over a black pigment with flakes).
        out &= !(bits::DIFFUSE | bits::GLOSSY | bits::DELTA);
        for (select, kinds) in paint.lobe_parts() {
            out |= kinds | (select & bits::COAT);
        }
    }
    if ALWAYS_ANISOTROPIC.contains(&name)
        || ANISO_PAIRS.iter().any(|(a, b)| matches!((p.num(a), p.num(b)), (Some(x), Some(y)) if x != y))
        || lafortune_anisotropic(&p)
    {
        out |= bits::ANISOTROPIC;
    }
    if !info.claims.reciprocal {
        out |= bits::NON_RECIPROCAL;
    }
    if m.spatially_varying() {
        out |= bits::SPATIALLY_VARYING;
    }
    if crate::spectral::is_spectral(m) {
        out |= bits::SPECTRAL;
    }
    out
}

/// Lafortune lobes with `cx != cy` are anisotropic.
fn lafortune_anisotropic(p: &View) -> bool {
    let Some(Value::Array(lobes)) = p.0.get("lobes") else { return false };
    lobes.iter().any(|l| {
        let g = |k: &str| l.get(k).and_then(Value::as_f64);
        matches!((g("cx"), g("cy")), (Some(x), Some(y)) if x != y)
    })
}

#[cfg(test)]
mod tests {
    use super::bits;
    use crate::math::Vec3;
    use crate::models;
    use crate::Material;

    /// Every model's defaults and check parameter sets that build (at least one per model).
    fn materials() -> Vec<(String, Material)> {
        let mut out = Vec::new();
        for info in models::all() {
            let before = out.len();
            if let Ok(m) = Material::default_of(info) {
                out.push((format!("{} defaults", info.name), m));
            }
            for (i, extra) in info.check_params.iter().enumerate() {
                let mut v: serde_json::Value = serde_json::from_str(extra).expect("check params are JSON");
                v["model"] = info.name.into();
                if let Ok(m) = Material::from_value(&v) {
                    out.push((format!("{} check set {i}", info.name), m));
                }
            }
            assert!(out.len() > before || info.name == "measured", "no material of {} builds", info.name);
        }
        out
    }

    fn dir(theta: f64, phi: f64) -> Vec3<f64> {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// DELTA is set exactly when sampling (4 view angles × 64 lobe numbers) returns a delta
    /// sample.
    #[test]
    fn delta_bit_matches_sampling() {
        for (name, m) in materials() {
            let mut seen = false;
            for &c in &[1.0f64, 0.5, 0.1, 0.02] {
                let wo = Vec3::new((1.0 - c * c).sqrt(), 0.0, c);
                for i in 0..64 {
                    if m.sample(wo, [(i as f64 + 0.5) / 64.0, 0.37, 0.61]).is_some_and(|s| s.delta) {
                        seen = true;
                    }
                }
            }
            assert_eq!(m.lobes() & bits::DELTA != 0, seen, "{name}: DELTA bit vs sampled delta lobes");
        }
    }

    /// ANISOTROPIC is set exactly when rotating both directions about the normal changes f
    /// (relative change > 1e-6 on 64 pairs × 3 rotations; isotropic models measure ≤ 1e-12 in f64).
    #[test]
    fn anisotropic_bit_matches_rotation() {
        for (name, m) in materials() {
            let mut changed = false;
            for k in 0..64 {
                let (t1, p1) =
                    (0.1 + 1.3 * ((k * 37 % 64) as f64 / 64.0), std::f64::consts::TAU * ((k * 11 % 64) as f64 / 64.0));
                let (t2, p2) =
                    (0.1 + 1.3 * ((k * 13 % 64) as f64 / 64.0), std::f64::consts::TAU * ((k * 29 % 64) as f64 / 64.0));
                let f0 = m.eval(dir(t1, p1), dir(t2, p2));
                for rot in [0.4, 1.1, 2.3] {
                    let f1 = m.eval(dir(t1, p1 + rot), dir(t2, p2 + rot));
                    let d = (f1.r - f0.r).abs().max((f1.g - f0.g).abs()).max((f1.b - f0.b).abs());
                    let s = f0.r.abs().max(f0.g.abs()).max(f0.b.abs()).max(1e-12);
                    if d / s > 1e-6 {
                        changed = true;
                    }
                }
            }
            assert_eq!(m.lobes() & bits::ANISOTROPIC != 0, changed, "{name}: ANISOTROPIC bit vs rotation");
        }
    }

    /// A material reports DIFFUSE exactly when its diffuse albedo is non-zero (the coated
    /// paint also over a black pigment when its multiple-scatter lobe is non-zero; none of
    /// the check sets has one), and pure diffuse models report no glossy lobe.
    #[test]
    fn diffuse_bit_and_albedo() {
        for (name, m) in materials() {
            let d = m.diffuse_reflectance();
            assert_eq!(m.lobes() & bits::DIFFUSE != 0, d.iter().any(|&x| x > 0.0), "{name}");
            assert!(d.iter().all(|&x| (0.0..=1.0).contains(&x)), "{name}: diffuse albedo {d:?}");
        }
        let l = Material::from_json(r#"{"model": "lambert", "albedo": [0.2, 0.4, 0.6]}"#).unwrap();
        assert_eq!(l.lobes(), bits::DIFFUSE);
        assert_eq!(l.diffuse_reflectance(), [0.2, 0.4, 0.6]);
    }
}
