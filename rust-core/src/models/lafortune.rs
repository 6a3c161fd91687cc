//! Lafortune, Foo, Torrance & Greenberg (1997): a Lambertian term plus a sum of generalised
//! cosine lobes,
//!
//! ```text
//! f(wi, wo) = ρd/π + Σ_i ρ_i · (n_i+2)/(2π) · max(0, (Cx,i wi.x wo.x + Cy,i wi.y wo.y + Cz,i wi.z wo.z) / Cmax,i)^{n_i}
//! ```
//!
//! with `Cmax,i = max(|Cx,i|, |Cy,i|, |Cz,i|)`. The paper writes each lobe as
//! `[Cx ux vx + Cy uy vy + Cz uz vz]^n`, the lobe's strength folded into the magnitude of C;
//! here the strength is the separate albedo ρ_i and C only shapes the lobe (its axis
//! `C∘wo = (Cx wo.x, Cy wo.y, Cz wo.z)` and how its peak changes with `wo`). For n > 0 the two
//! are the same family: the paper's lobe with coefficients C is this one with
//! `ρ = Cmaxⁿ · 2π/(n+2)` (times any scale factor the paper's data put in front of the lobe).
//! `C = (−1, −1, 1)` is the modified Phong lobe `ρ (n+2)/(2π) cosⁿα` around the mirror direction
//! — the paper's `−Cx = −Cy = Cz = (ρs (n+2)/(2π))^{1/n}`; `|Cx| = |Cy| > |Cz|` strengthens the
//! lobe toward grazing ("increasing reflectance") and tilts it toward the horizon (off-specular);
//! positive Cx, Cy give a retro-reflective lobe; `Cx ≠ Cy` an anisotropic one. Per-channel
//! C or n (as in the paper's fits) take one lobe per channel with albedos such as `[ρ, 0, 0]`.
//!
//! | parameter | kind | default | range | meaning |
//! |---|---|---|---|---|
//! | `diffuse` | colour | 0.5 | [0, 1] | diffuse reflectance ρd (ρd + Σ ρ_i ≤ 1 per channel) |
//! | `lobes` | JSON | `[{"cx": -1, "cy": -1, "cz": 1, "n": 20, "albedo": 0.3}]` | 0 to 8 lobes | the generalised cosine lobes, see below |
//!
//! Each lobe is an object with exactly the keys `cx`, `cy`, `cz` (numbers in [−100, 100], not
//! all zero), `n` (exponent in [0, 10⁴]) and `albedo` (a number or `[r, g, b]` in [0, 1]: the
//! lobe's albedo at normal incidence for `C = (−1, −1, 1)`, and an upper bound of it for
//! every C and `wo`). Anything else is an error naming `lobes[i].key`.
//!
//! Physics: reciprocal (each term is symmetric in wi and wo). Energy conserving, and enforced
//! (ρd + Σ ρ_i ≤ 1 per channel): for a given `wo` the lobe is `|a|ⁿ cosⁿβ` with
//! `a = C∘wo / Cmax`, `|a| ≤ 1`, β the angle between wi and `a`, and
//! `∫ cosⁿβ max(0, cos θi) dωi ≤ 2π/(n+2)` by the rearrangement inequality on the sphere
//! (equality when `a = z`); so each lobe's albedo is at most ρ_i.
//!
//! Sampling: `u[0]` picks the Lambertian term with weight ρ̄d or lobe i with weight
//! `ρ̄_i |a_i|^{n_i}` (channel means; the lobe's albedo up to the horizon's cut), then a
//! cosine-weighted direction or a direction from the power-cosine density `(n_i+1)/(2π) cos^{n_i}β`
//! around the lobe's axis `a_i/|a_i|`. The pdf is the mixture; directions below the horizon
//! are failed samples.
//!
//! Reference: E. P. F. Lafortune, S.-C. Foo, K. E. Torrance, D. P. Greenberg, "Non-linear
//! approximation of reflectance functions", SIGGRAPH 1997, 117–126.

use super::phong::{mean, MAX_EXPONENT};
use crate::bxdf::{BsdfSample, Bxdf, Claims, ModelInfo};
use crate::error::Error;
use crate::frame::versine_between;
use crate::math::{Rgb, Vec3};
use crate::models::Model;
use crate::params::{ParamSpec, Params};
use crate::real::Real;
use crate::sampling::{
    cos_pow_versine, cosine_hemisphere, cosine_hemisphere_pdf, pick_lobe, power_cosine_around,
    power_cosine_pdf_versine,
};
use serde_json::Value;

/// Most lobes a material may have.
pub const MAX_LOBES: usize = 8;
/// Largest |Cx|, |Cy|, |Cz| accepted (only their ratios matter).
const MAX_C: f64 = 100.0;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::color("diffuse", [0.5; 3], 0.0, 1.0, "diffuse reflectance ρd (ρd + Σ lobe albedos ≤ 1 per channel)"),
    ParamSpec::json(
        "lobes",
        r#"[{"cx": -1, "cy": -1, "cz": 1, "n": 20, "albedo": 0.3}]"#,
        "0 to 8 lobes {\"cx\", \"cy\", \"cz\" in [-100, 100] (not all 0), \"n\" in [0, 10000], \
         \"albedo\": number or [r, g, b] in [0, 1]}",
    ),
];

/// Registry entry.
pub static INFO: ModelInfo = ModelInfo {
    name: "lafortune",
    summary: "Lafortune et al. 1997 generalised cosine lobes (C∘wo axis), albedo-normalised, + Lambert",
    reference: "E. P. F. Lafortune, S.-C. Foo, K. E. Torrance, D. P. Greenberg, Non-linear approximation \
                of reflectance functions, SIGGRAPH 1997",
    params: PARAMS,
    claims: Claims { reciprocal: true, energy_conserving: true, sampled: true },
    check_params: &[
        r#"{"diffuse": 0.0, "lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 5, "albedo": 1.0}]}"#,
        r#"{"diffuse": [0.3, 0.2, 0.1], "lobes": [{"cx": -1.0, "cy": -0.6, "cz": 0.8, "n": 40, "albedo": [0.3, 0.4, 0.5]},
            {"cx": 0.9, "cy": 0.9, "cz": 0.7, "n": 8, "albedo": 0.2}]}"#,
        r#"{"diffuse": 0.1, "lobes": [{"cx": -1, "cy": -1, "cz": 0.3, "n": 30, "albedo": 0.6},
            {"cx": -0.5, "cy": -0.5, "cz": 1, "n": 300, "albedo": [0.3, 0.2, 0.1]}]}"#,
    ],
    build,
};

/// One generalised cosine lobe.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobe {
    /// `(Cx, Cy, Cz) / Cmax`: the shape, scaled so that the largest magnitude is 1.
    pub c: [f64; 3],
    /// Exponent n.
    pub n: f64,
    /// Albedo ρ per channel.
    pub albedo: [f64; 3],
}

fn invalid(param: String, reason: impl Into<String>) -> Error {
    Error::Invalid { param, reason: reason.into() }
}

/// A number within `[lo, hi]` from `obj[key]`, or an error naming `lobes[i].key`.
fn number(obj: &serde_json::Map<String, Value>, i: usize, key: &str, lo: f64, hi: f64) -> Result<f64, Error> {
    let name = format!("lobes[{i}].{key}");
    let v = obj.get(key).ok_or_else(|| invalid(name.clone(), "is missing"))?;
    let x = v.as_f64().ok_or_else(|| invalid(name.clone(), "must be a number"))?;
    if !(lo..=hi).contains(&x) {
        return Err(invalid(name, format!("{x} is outside [{lo}, {hi}]")));
    }
    Ok(x)
}

/// Parses and validates the `lobes` parameter.
fn parse_lobes(v: &Value) -> Result<Vec<Lobe>, Error> {
    let items = v.as_array().ok_or_else(|| invalid("lobes".into(), "must be an array of lobe objects"))?;
    if items.len() > MAX_LOBES {
        return Err(invalid("lobes".into(), format!("has {} lobes; at most {MAX_LOBES} are allowed", items.len())));
    }
    let mut lobes = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let obj = item.as_object().ok_or_else(|| {
            invalid(format!("lobes[{i}]"), "must be an object {\"cx\", \"cy\", \"cz\", \"n\", \"albedo\"}")
        })?;
        for key in obj.keys() {
            if !["cx", "cy", "cz", "n", "albedo"].contains(&key.as_str()) {
                return Err(invalid(
                    format!("lobes[{i}].{key}"),
                    "is not a lobe key; a lobe has exactly cx, cy, cz, n, albedo",
                ));
            }
        }
        let c = [
            number(obj, i, "cx", -MAX_C, MAX_C)?,
            number(obj, i, "cy", -MAX_C, MAX_C)?,
            number(obj, i, "cz", -MAX_C, MAX_C)?,
        ];
        let cmax = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if cmax == 0.0 {
            return Err(invalid(format!("lobes[{i}]"), "cx, cy and cz are all zero: the lobe has no direction"));
        }
        let n = number(obj, i, "n", 0.0, MAX_EXPONENT)?;
        let name = format!("lobes[{i}].albedo");
        let raw = obj.get("albedo").ok_or_else(|| invalid(name.clone(), "is missing"))?;
        const EXPECTED: &str = "must be a number or [r, g, b], each in [0, 1]";
        let albedo = if let Some(x) = raw.as_f64() {
            [x; 3]
        } else {
            let a = raw.as_array().filter(|a| a.len() == 3).ok_or_else(|| invalid(name.clone(), EXPECTED))?;
            let mut out = [0.0; 3];
            for (o, x) in out.iter_mut().zip(a) {
                *o = x.as_f64().ok_or_else(|| invalid(name.clone(), EXPECTED))?;
            }
            out
        };
        if albedo.iter().any(|x| !(0.0..=1.0).contains(x)) {
            return Err(invalid(name, format!("{albedo:?}: {EXPECTED}")));
        }
        lobes.push(Lobe { c: c.map(|x| x / cmax), n, albedo });
    }
    Ok(lobes)
}

fn build(p: &Params) -> Result<Model, Error> {
    let diffuse = p.color("diffuse");
    let lobes = parse_lobes(p.json("lobes"))?;
    for (ch, d) in diffuse.iter().enumerate() {
        let total = d + lobes.iter().map(|l| l.albedo[ch]).sum::<f64>();
        if total > 1.0 + 1e-9 {
            return Err(invalid(
                "lobes".into(),
                format!(
                    "diffuse + the lobe albedos must not exceed 1 in any channel, so that the albedo stays \
                     at most 1 (channel {ch}: {total})"
                ),
            ));
        }
    }
    Ok(Model::Lafortune(Lafortune { diffuse, lobes }))
}

/// The Lafortune BRDF.
#[derive(Clone, Debug)]
pub struct Lafortune {
    /// Diffuse reflectance ρd per channel.
    pub diffuse: [f64; 3],
    /// The lobes.
    pub lobes: Vec<Lobe>,
}

impl Lobe {
    /// The (unnormalised) axis `a = C∘w / Cmax`.
    #[inline]
    fn axis<T: Real>(&self, w: Vec3<T>) -> Vec3<T> {
        Vec3::new(T::of(self.c[0]) * w.x, T::of(self.c[1]) * w.y, T::of(self.c[2]) * w.z)
    }

    /// `|a|ⁿ`, the lobe's peak for this `wo` (as a fraction of its largest).
    #[inline]
    fn peak<T: Real>(&self, a: Vec3<T>) -> T {
        let l2 = a.length_squared();
        if !(l2 > T::zero()) {
            return T::zero();
        }
        if self.n == 0.0 {
            return T::one();
        }
        (T::of(self.n) * T::of(0.5) * l2.ln()).exp()
    }

    /// `(max(0, wi·a))ⁿ = |a|ⁿ cosⁿβ`, β the angle between wi and a, with `cos β` taken from
    /// its versine so that sharp lobes keep their precision in f32.
    #[inline]
    fn power<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let a = self.axis(wo);
        let peak = self.peak(a);
        if peak == T::zero() {
            return T::zero();
        }
        peak * cos_pow_versine(versine_between(wi, a.normalize()), T::of(self.n))
    }
}

impl Lafortune {
    /// Selection weights `[diffuse, lobe 0, …]` for this `wo` (an even split when all vanish),
    /// written into `w`; returns how many are used.
    #[inline]
    fn weights<T: Real>(&self, wo: Vec3<T>, w: &mut [T; MAX_LOBES + 1]) -> usize {
        let count = self.lobes.len() + 1;
        w[0] = T::of(mean(self.diffuse));
        for (wi, l) in w[1..].iter_mut().zip(&self.lobes) {
            *wi = T::of(mean(l.albedo)) * l.peak(l.axis(wo));
        }
        let total = w[..count].iter().fold(T::zero(), |s, &x| s + x);
        if !(total > T::zero()) {
            w[..count].iter_mut().for_each(|x| *x = T::one());
        }
        count
    }
}

impl Bxdf for Lafortune {
    #[inline]
    fn eval<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> Rgb<T> {
        let mut f = Rgb::from_array(self.diffuse) * T::inv_pi();
        for l in &self.lobes {
            let power = l.power(wi, wo);
            let n = T::of(l.n);
            f += Rgb::from_array(l.albedo) * ((n + T::of(2.0)) * T::inv_pi() * T::of(0.5) * power);
        }
        f
    }

    #[inline]
    fn pdf<T: Real>(&self, wi: Vec3<T>, wo: Vec3<T>) -> T {
        let mut w = [T::zero(); MAX_LOBES + 1];
        let count = self.weights(wo, &mut w);
        let total = w[..count].iter().fold(T::zero(), |s, &x| s + x);
        let mut p = w[0] * cosine_hemisphere_pdf(wi.z);
        for (l, &wl) in self.lobes.iter().zip(&w[1..count]) {
            if wl > T::zero() {
                let a = l.axis(wo);
                if a.length_squared() > T::zero() {
                    p += wl * power_cosine_pdf_versine(T::of(l.n), versine_between(wi, a.normalize()));
                }
            }
        }
        p / total
    }

    #[inline]
    fn sample<T: Real>(&self, wo: Vec3<T>, u: [T; 3]) -> Option<BsdfSample<T>> {
        let mut w = [T::zero(); MAX_LOBES + 1];
        let count = self.weights(wo, &mut w);
        let (k, _) = pick_lobe(&w[..count], u[0])?;
        let wi = if k == 0 {
            cosine_hemisphere(u[1], u[2])
        } else {
            let l = &self.lobes[k - 1];
            let a = l.axis(wo);
            if !(a.length_squared() > T::zero()) {
                return None;
            }
            power_cosine_around(a.normalize(), T::of(l.n), u[1], u[2])
        };
        if !(wi.z > T::zero() && wi.is_finite()) {
            return None;
        }
        BsdfSample::from_eval(wi, self.eval(wi, wo), self.pdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::super::phong::testing::albedo_around;
    use super::*;
    use crate::frame::{mirror_z, spherical_direction};
    use crate::material::Material;
    use std::f64::consts::PI;

    fn lafortune(json: &str) -> Result<Material, Error> {
        Material::from_json(&format!(r#"{{"model": "lafortune", {json}}}"#))
    }

    fn pairs() -> Vec<(Vec3<f64>, Vec3<f64>)> {
        let d = |c: f64, p: f64| spherical_direction((1.0 - c * c).sqrt(), c, p);
        vec![(d(0.7, 0.3), d(0.8, 3.2)), (d(0.2, 1.0), d(0.9, 4.0)), (d(0.95, 2.0), d(0.3, 5.3)), (d(0.5, 0.0), d(0.5, PI))]
    }

    /// `C = (−1, −1, 1)` is the modified Phong lobe around the mirror direction.
    #[test]
    fn mirror_lobe_is_modified_phong() {
        let m = lafortune(r#""diffuse": 0.2, "lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 17, "albedo": [0.3, 0.5, 0.7]}]"#)
            .unwrap();
        let p = Material::from_json(
            r#"{"model": "modified_phong", "diffuse": 0.2, "specular": [0.3, 0.5, 0.7], "exponent": 17}"#,
        )
        .unwrap();
        for (wi, wo) in pairs() {
            let (a, b) = (m.eval(wi, wo), p.eval(wi, wo));
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-12 * b[c], "{a:?} vs {b:?}");
            }
        }
        // The paper's scale: −Cx = −Cy = Cz = (ρ (n+2)/(2π))^{1/n} gives the same lobe.
        let k = (0.3f64 * 19.0 / (2.0 * PI)).powf(1.0 / 17.0);
        for (wi, wo) in pairs() {
            let paper = (-k * wi.x * wo.x - k * wi.y * wo.y + k * wi.z * wo.z).max(0.0).powf(17.0);
            let ours = m.eval(wi, wo).r - 0.2 / PI;
            assert!((ours - paper).abs() < 1e-12 * paper.max(1e-300), "{ours} vs {paper}");
        }
    }

    /// The general lobe against the paper's expression with the scale `ρ (n+2)/(2π) / Cmaxⁿ`,
    /// including a retro-reflective lobe (positive Cx, Cy) peaking at wi = wo.
    #[test]
    fn general_lobes_match_papers_expression() {
        let m = lafortune(
            r#""diffuse": 0.0, "lobes": [{"cx": -0.9, "cy": -0.4, "cz": 0.6, "n": 7, "albedo": 0.3},
                {"cx": 0.5, "cy": 0.5, "cz": 0.25, "n": 3, "albedo": 0.2}]"#,
        )
        .unwrap();
        for (wi, wo) in pairs() {
            let lobe = |c: [f64; 3], n: f64, rho: f64| {
                let cmax = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let dot = c[0] * wi.x * wo.x + c[1] * wi.y * wo.y + c[2] * wi.z * wo.z;
                rho * (n + 2.0) / (2.0 * PI) * (dot.max(0.0) / cmax).powf(n)
            };
            let expect = lobe([-0.9, -0.4, 0.6], 7.0, 0.3) + lobe([0.5, 0.5, 0.25], 3.0, 0.2);
            let got = m.eval(wi, wo).g;
            assert!((got - expect).abs() < 1e-12 * expect.max(1e-12), "{got} vs {expect}");
            assert!((m.eval(wo, wi).g - got).abs() < 1e-13);
        }
        // Retro-reflection: at wi = wo = z the retro lobe is ρ (n+2)/(2π) (0.25/0.5)³.
        let z = Vec3::new(0.0, 0.0, 1.0);
        let retro = 0.2 * 5.0 / (2.0 * PI) * 0.125;
        let mirror = 0.3 * 9.0 / (2.0 * PI) * (0.6f64 / 0.9).powi(7);
        assert!((m.eval(z, z).b - retro - mirror).abs() < 1e-14);
    }

    /// Normal incidence: the mirror lobe's albedo is ρ exactly; with `Cz/Cmax = 1/2` the axis
    /// is `z/2`, so the albedo is `ρ · 2⁻ⁿ`.
    #[test]
    fn normal_incidence_albedos() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        let m = lafortune(r#""diffuse": 0.1, "lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 200, "albedo": 0.9}]"#).unwrap();
        assert!((albedo_around(&m, z, z)[0] - 1.0).abs() < 2e-4);
        let m = lafortune(r#""diffuse": 0.0, "lobes": [{"cx": -1, "cy": -1, "cz": 0.5, "n": 3, "albedo": 0.8}]"#).unwrap();
        assert!((albedo_around(&m, z, z)[0] - 0.8 / 8.0).abs() < 2e-4);
    }

    /// Lobes stronger toward grazing (|Cx| > |Cz|) still stay below their albedo.
    #[test]
    fn grazing_lobe_albedo_stays_below_rho() {
        let m = lafortune(r#""diffuse": 0.0, "lobes": [{"cx": -1, "cy": -1, "cz": 0.2, "n": 10, "albedo": 1.0}]"#).unwrap();
        let mut largest = 0.0f64;
        for c in [0.9f64, 0.5, 0.2, 0.05] {
            let wo = spherical_direction((1.0 - c * c).sqrt(), c, 0.6);
            let a = m.model();
            let Model::Lafortune(l) = a else { panic!() };
            let axis = l.lobes[0].axis(wo).normalize();
            let alb = albedo_around(&m, wo, axis)[0];
            assert!(alb < 1.0, "cos θo = {c}: {alb}");
            largest = largest.max(alb);
        }
        // And it does grow toward grazing (the point of such a lobe).
        let wo = spherical_direction(0.6f64, 0.8, 0.6);
        assert!(largest > albedo_around(&m, wo, mirror_z(wo))[0]);
    }

    /// The hard-case grid (grazing, degenerate, f32) on lobe extremes the generic parameter
    /// sweep cannot reach inside the JSON: n = 10⁴, n = 0, an axis below the horizon, a
    /// vanishing axis at normal incidence, extreme ratios of C, eight lobes.
    #[test]
    fn lobe_extremes_pass_the_hard_cases() {
        for lobes in [
            r#"[{"cx": -1, "cy": -1, "cz": 1, "n": 10000, "albedo": 1.0}]"#,
            r#"[{"cx": -1, "cy": -1, "cz": 1, "n": 0, "albedo": 1.0}]"#,
            r#"[{"cx": 0.3, "cy": 0.1, "cz": -1, "n": 10000, "albedo": 0.5}, {"cx": 0, "cy": 0, "cz": -1, "n": 0, "albedo": 0.5}]"#,
            r#"[{"cx": 100, "cy": -1e-9, "cz": 0, "n": 10000, "albedo": 0.5}, {"cx": -1, "cy": 1, "cz": 0, "n": 3, "albedo": 0.5}]"#,
            r#"[{"cx": 1, "cy": 1, "cz": 1e-9, "n": 10000, "albedo": 0.125}, {"cx": 1, "cy": 1, "cz": 1e-9, "n": 10000, "albedo": 0.125},
                {"cx": -1, "cy": -1, "cz": 1, "n": 1, "albedo": 0.125}, {"cx": -1, "cy": -1, "cz": 1, "n": 10, "albedo": 0.125},
                {"cx": -1, "cy": -1, "cz": 1, "n": 100, "albedo": 0.125}, {"cx": -1, "cy": -1, "cz": 1, "n": 1000, "albedo": 0.125},
                {"cx": -1, "cy": -0.1, "cz": 1, "n": 50, "albedo": 0.125}, {"cx": 1, "cy": 1, "cz": 1, "n": 5, "albedo": 0.125}]"#,
        ] {
            let m = lafortune(&format!(r#""diffuse": 0.0, "lobes": {lobes}"#)).unwrap();
            let r = crate::check::hard_cases(&m);
            assert_eq!(r.failures(), 0, "{lobes}: {:?}", r.examples);
        }
    }

    #[test]
    fn validation_names_the_lobe_and_key() {
        let err = |j: &str| lafortune(j).unwrap_err().to_string();
        assert!(err(r#""lobes": {"cx": 1}"#).contains("array"));
        assert!(err(r#""lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 20}]"#).contains("lobes[0].albedo"));
        assert!(err(r#""lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 20, "albedo": 0.1, "k": 2}]"#).contains("lobes[0].k"));
        assert!(err(r#""lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": -2, "albedo": 0.1}]"#).contains("lobes[0].n"));
        assert!(err(r#""lobes": [{"cx": 0, "cy": 0, "cz": 0, "n": 2, "albedo": 0.1}]"#).contains("all zero"));
        assert!(err(r#""lobes": [{"cx": "a", "cy": 0, "cz": 1, "n": 2, "albedo": 0.1}]"#).contains("lobes[0].cx"));
        assert!(err(r#""lobes": [{"cx": -1, "cy": -1, "cz": 1, "n": 2, "albedo": [0.1, 2, 0]}]"#).contains("albedo"));
        let two = r#"{"cx": -1, "cy": -1, "cz": 1, "n": 2, "albedo": 0.3}"#;
        assert!(err(&format!(r#""diffuse": 0.5, "lobes": [{two}, {two}]"#)).contains("must not exceed 1"));
        let nine = [two; 9].join(", ");
        assert!(err(&format!(r#""diffuse": 0.0, "lobes": [{nine}]"#)).contains("at most 8"));
        // No lobes: plain Lambert.
        let m = lafortune(r#""diffuse": 0.4, "lobes": []"#).unwrap();
        let (wi, wo) = pairs()[0];
        assert!((m.eval(wi, wo).r - 0.4 / PI).abs() < 1e-15);
    }
}
