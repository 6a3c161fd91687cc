//! Image textures on a coated paint's per-element parameters: `base_color` (an RGB image),
//! `flake_density` and `coat_roughness` (grey images). Per hit the integrator looks the texels
//! up at the hit's texture coordinates and evaluates the paint with them through the core's
//! per-element path (`lacquer::batch::eval_pdf_varying` / `sample_varying`, which evaluate the
//! mean lobe: a textured material has no per-flake sparkle).
//!
//! **Lookup** (as Cycles' Image Texture node with "Repeat"): texel `(i, j)` is centred at
//! `((i + ½)/w, (j + ½)/h)` with row 0 at v = 0 (Blender's convention; image files, whose first
//! row is the top, are flipped when read); `"linear"` interpolation is bilinear, `"closest"` the
//! nearest texel. Texture coordinates are the mesh's `texture_uvs` when it has them (a Blender
//! UV map), otherwise the surface's own uv (mesh `uvs`, the sphere's and rectangle's uv).
//!
//! **Values**: `base_color` texels are the pigment albedo in [0, 1] per channel (linear
//! Rec.709); `flake_density` texels (the red channel; grey images: the grey value) times
//! `scale` are the coverage in %; `coat_roughness` texels times `scale` are the GGX α, in
//! [0.001, 0.5] and only on a rough coat. Values outside the parameter's range are an error when
//! the scene is built, naming the image and the texel.
//!
//! **Colour space**: PNG files are 8- or 16-bit encoded values; `"colorspace": "srgb"` decodes
//! them with the sRGB transfer curve (the default for a PNG bound to `base_color`), `"linear"`
//! takes them as they are (the default for everything else). EXR and Radiance HDR files and
//! inline images are linear.

use crate::desc::Packed;
use lacquer::Material;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// A decoded image: linear values, row 0 at v = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Texels, row 0 (v = 0) first.
    pub texels: Arc<[[f32; 3]]>,
    /// Where the image came from (error messages).
    pub name: String,
}

/// Interpolation between texels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Bilinear (Blender's "Linear").
    #[default]
    Linear,
    /// The nearest texel (Blender's "Closest").
    Closest,
}

/// How texel values are decoded from an 8/16-bit file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColorSpace {
    /// The sRGB transfer curve (colour images).
    Srgb,
    /// Values as stored (non-colour data).
    Linear,
}

impl Image {
    /// Texel `(i, j)` with repeat wrapping.
    #[inline]
    fn at(&self, i: i64, j: i64) -> [f32; 3] {
        let (w, h) = (self.width as i64, self.height as i64);
        self.texels[j.rem_euclid(h) as usize * self.width + i.rem_euclid(w) as usize]
    }

    /// The value at texture coordinates `uv` (repeating).
    #[must_use]
    pub fn sample(&self, uv: [f32; 2], filter: Filter) -> [f32; 3] {
        let x = f64::from(uv[0]) * self.width as f64;
        let y = f64::from(uv[1]) * self.height as f64;
        if !(x.is_finite() && y.is_finite()) {
            return self.at(0, 0);
        }
        if filter == Filter::Closest {
            return self.at(x.floor() as i64, y.floor() as i64);
        }
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let (a, b, c, d) = (self.at(i, j), self.at(i + 1, j), self.at(i, j + 1), self.at(i + 1, j + 1));
        std::array::from_fn(|k| {
            let top = a[k] + (b[k] - a[k]) * tx;
            let bottom = c[k] + (d[k] - c[k]) * tx;
            top + (bottom - top) * ty
        })
    }

    /// Reads a PNG (8/16-bit grey, grey-alpha, RGB or RGBA), OpenEXR or Radiance HDR file;
    /// rows are flipped so that row 0 is the bottom (v = 0). `srgb` decodes PNG values with the
    /// sRGB curve (EXR and HDR files are linear).
    pub fn load(path: &Path, srgb: bool) -> Result<Self, String> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        let name = path.display().to_string();
        let (width, height, mut rows) = match ext.as_str() {
            "png" => read_png(path, srgb)?,
            "exr" | "hdr" | "pic" => {
                let img = if ext == "exr" { crate::output::read_exr_rgb(path)? } else { crate::env::read_rgbe(path)? };
                (img.width, img.height, img.pixels.iter().map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>())
            }
            _ => return Err(format!("{name}: texture images must be .png, .exr or .hdr")),
        };
        if width == 0 || height == 0 || rows.len() != width * height {
            return Err(format!("{name}: the image has no pixels"));
        }
        // Files store the top row first; Blender's (and the lookup's) row 0 is v = 0, the bottom.
        let mut flipped = Vec::with_capacity(rows.len());
        for j in (0..height).rev() {
            flipped.extend_from_slice(&rows[j * width..(j + 1) * width]);
        }
        rows = flipped;
        if let Some(k) = rows.iter().position(|t| !t.iter().all(|v| v.is_finite())) {
            return Err(format!("{name}: texel ({}, {}) is not finite", k % width, k / width));
        }
        Ok(Self { width, height, texels: rows.into(), name })
    }
}

/// The sRGB transfer curve, decoded.
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

type Rows = (usize, usize, Vec<[f32; 3]>);

fn read_png(path: &Path, srgb: bool) -> Result<Rows, String> {
    let name = path.display();
    let file = std::fs::File::open(path).map_err(|e| format!("{name}: {e}"))?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(file));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(|e| format!("{name}: {e}"))?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or_else(|| format!("{name}: image too large"))?];
    let info = reader.next_frame(&mut buf).map_err(|e| format!("{name}: {e}"))?;
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let (max, bytes) = match info.bit_depth {
        png::BitDepth::Sixteen => (65535.0f32, 2),
        png::BitDepth::Eight => (255.0, 1),
        d => return Err(format!("{name}: {d:?} bit PNG after expansion is not supported")),
    };
    let value = |k: usize| -> f32 {
        let raw = if bytes == 2 { u16::from_be_bytes([buf[2 * k], buf[2 * k + 1]]) as f32 } else { buf[k] as f32 };
        let v = raw / max;
        if srgb {
            srgb_to_linear(v)
        } else {
            v
        }
    };
    let mut out = Vec::with_capacity(w * h);
    for p in 0..w * h {
        let base = p * channels;
        out.push(match channels {
            1 | 2 => [value(base); 3],
            _ => [value(base), value(base + 1), value(base + 2)],
        });
    }
    Ok((w, h, out))
}

/// An inline image of the scene (`"images": {NAME: {width, height, pixels}}`), linear values,
/// row 0 at v = 0 (as Blender's `Image.pixels`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageDesc {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// `width × height` RGB texels, row 0 (v = 0) first.
    pub pixels: Packed<f32, 3>,
}

impl ImageDesc {
    /// The image, checked.
    pub fn image(&self, name: &str) -> Result<Image, String> {
        if self.width == 0 || self.height == 0 || self.width.checked_mul(self.height) != Some(self.pixels.0.len()) {
            return Err(format!(
                "image \"{name}\": {} pixels for {}×{} texels",
                self.pixels.0.len(),
                self.width,
                self.height
            ));
        }
        if let Some(k) = self.pixels.0.iter().position(|t| !t.iter().all(|v| v.is_finite())) {
            return Err(format!("image \"{name}\": texel ({}, {}) is not finite", k % self.width, k / self.width));
        }
        Ok(Image {
            width: self.width,
            height: self.height,
            texels: self.pixels.0.clone().into(),
            name: format!("image \"{name}\""),
        })
    }
}

/// A parameter's texture in a material (`"textures": {"base_color": {...}}`): an image file
/// (`file`, resolved against the scene's folder) or an inline image of the scene (`image`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BindingDesc {
    /// Image file (.png, .exr, .hdr).
    #[serde(default)]
    pub file: Option<String>,
    /// Name of an entry of the scene's `images`.
    #[serde(default)]
    pub image: Option<String>,
    /// How a PNG's values are decoded (default: `srgb` for `base_color`, else `linear`).
    #[serde(default)]
    pub colorspace: Option<ColorSpace>,
    /// Interpolation (default `linear`).
    #[serde(default)]
    pub interpolation: Filter,
    /// Multiplier of the texel values of `flake_density` and `coat_roughness` (default 1).
    #[serde(default)]
    pub scale: Option<f64>,
}

/// A material's textures as written in a scene (`"textures"` next to the material's keys).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TexturesDesc {
    /// Pigment colour.
    #[serde(default)]
    pub base_color: Option<BindingDesc>,
    /// Flake coverage (%).
    #[serde(default)]
    pub flake_density: Option<BindingDesc>,
    /// Coat roughness (GGX α).
    #[serde(default)]
    pub coat_roughness: Option<BindingDesc>,
}

/// One parameter's texture.
#[derive(Clone, Debug)]
pub struct Binding {
    /// The image.
    pub image: Arc<Image>,
    /// Interpolation.
    pub filter: Filter,
    /// Multiplier of the texel values.
    pub scale: f32,
}

impl Binding {
    fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        self.image.sample(uv, self.filter).map(|v| v * self.scale)
    }
}

/// A material's textured parameters (at least one is bound).
#[derive(Clone, Debug)]
pub struct PaintTextures {
    /// Pigment colour per hit.
    pub base_color: Option<Binding>,
    /// Flake coverage (%) per hit.
    pub flake_density: Option<Binding>,
    /// Coat roughness (GGX α) per hit.
    pub coat_roughness: Option<Binding>,
}

/// Parameter values at one hit: `[r, g, b, flake_density, coat_roughness]` (unbound entries
/// unused).
pub type Texels = [f32; 5];

impl PaintTextures {
    /// The bound parameters' values at texture coordinates `uv`.
    #[must_use]
    pub fn lookup(&self, uv: [f32; 2]) -> Texels {
        let mut t = [0.0; 5];
        if let Some(b) = &self.base_color {
            t[..3].copy_from_slice(&b.sample(uv));
        }
        if let Some(b) = &self.flake_density {
            t[3] = b.sample(uv)[0];
        }
        if let Some(b) = &self.coat_roughness {
            t[4] = b.sample(uv)[0];
        }
        t
    }

    /// Builds a material's textures from their description: reads or finds the images, checks
    /// that the material can vary these parameters and that every texel is in range.
    pub fn build(
        desc: &TexturesDesc,
        material: &Material,
        base: &Path,
        images: &BTreeMap<String, Arc<Image>>,
        files: &mut BTreeMap<(String, bool), Arc<Image>>,
    ) -> Result<Self, String> {
        let vary_alpha = desc.coat_roughness.is_some();
        if material.varying_paint(vary_alpha).is_none() {
            return Err(format!(
                "textures need a coated_paint with pigment_model \"lambert\", not {}",
                if material.info().name == "coated_paint" { "the EON pigment" } else { material.info().name }
            ));
        }
        if vary_alpha && material.params().scalar("coat_roughness") == 0.0 {
            return Err("textures.coat_roughness needs a rough coat (coat_roughness > 0 in the material)".into());
        }
        let bind = |key: &str,
                    d: &Option<BindingDesc>,
                    files: &mut BTreeMap<(String, bool), Arc<Image>>,
                    range: (f32, f32),
                    channels: usize|
         -> Result<Option<Binding>, String> {
            let Some(d) = d else { return Ok(None) };
            let ctx = |e: String| format!("textures.{key}: {e}");
            let image = match (&d.file, &d.image) {
                (Some(f), None) => {
                    let srgb =
                        d.colorspace.unwrap_or(if key == "base_color" { ColorSpace::Srgb } else { ColorSpace::Linear })
                            == ColorSpace::Srgb;
                    let path = base.join(f);
                    let k = (path.display().to_string(), srgb);
                    match files.get(&k) {
                        Some(i) => i.clone(),
                        None => {
                            let i = Arc::new(Image::load(&path, srgb).map_err(ctx)?);
                            files.insert(k, i.clone());
                            i
                        }
                    }
                }
                (None, Some(name)) => {
                    if d.colorspace == Some(ColorSpace::Srgb) {
                        return Err(ctx("inline images are linear (\"colorspace\": \"srgb\" applies to files)".into()));
                    }
                    images.get(name).cloned().ok_or_else(|| ctx(format!("image \"{name}\" is not in \"images\"")))?
                }
                _ => return Err(ctx("give exactly one of \"file\" or \"image\"".into())),
            };
            let scale = d.scale.unwrap_or(1.0);
            if key == "base_color" && d.scale.is_some() {
                return Err(ctx("\"scale\" applies to flake_density and coat_roughness".into()));
            }
            if !(scale.is_finite() && scale >= 0.0) {
                return Err(ctx(format!("scale {scale} must be finite and >= 0")));
            }
            let scale = scale as f32;
            for (k, t) in image.texels.iter().enumerate() {
                for &v in &t[..channels] {
                    let v = v * scale;
                    if !(v >= range.0 && v <= range.1) {
                        return Err(ctx(format!(
                            "{}: texel ({}, {}) gives {v}, outside [{}, {}]",
                            image.name,
                            k % image.width,
                            k / image.width,
                            range.0,
                            range.1
                        )));
                    }
                }
            }
            Ok(Some(Binding { image, filter: d.interpolation, scale }))
        };
        let alpha = (lacquer::paint::varying::ALPHA_MIN as f32, lacquer::paint::varying::ALPHA_MAX as f32);
        let out = Self {
            base_color: bind("base_color", &desc.base_color, files, (0.0, 1.0), 3)?,
            flake_density: bind("flake_density", &desc.flake_density, files, (0.0, 100.0), 1)?,
            coat_roughness: bind("coat_roughness", &desc.coat_roughness, files, alpha, 1)?,
        };
        if out.base_color.is_none() && out.flake_density.is_none() && out.coat_roughness.is_none() {
            return Err("textures: bind at least one of base_color, flake_density, coat_roughness".into());
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, t: Vec<[f32; 3]>) -> Image {
        Image { width: w, height: h, texels: t.into(), name: "test".into() }
    }

    #[test]
    fn lookup_uses_texel_centres_repeats_and_closest_picks_the_texel() {
        let im = img(2, 1, vec![[0.0; 3], [1.0; 3]]);
        assert!((im.sample([0.25, 0.5], Filter::Linear)[0] - 0.0).abs() < 1e-6);
        assert!((im.sample([0.75, 0.5], Filter::Linear)[0] - 1.0).abs() < 1e-6);
        assert!((im.sample([0.5, 0.5], Filter::Linear)[0] - 0.5).abs() < 1e-6);
        assert!((im.sample([1.25, 0.5], Filter::Linear)[0] - 0.0).abs() < 1e-6);
        assert_eq!(im.sample([0.49, 0.5], Filter::Closest)[0], 0.0);
        assert_eq!(im.sample([0.51, 0.5], Filter::Closest)[0], 1.0);
        assert_eq!(im.sample([-0.2, 0.5], Filter::Closest)[0], 1.0);
    }

    #[test]
    fn png_rows_are_flipped_and_srgb_decoded() {
        let dir = std::env::temp_dir().join(format!("lacquer-tex-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.png");
        {
            let f = std::fs::File::create(&path).unwrap();
            let mut e = png::Encoder::new(std::io::BufWriter::new(f), 1, 2);
            e.set_color(png::ColorType::Rgb);
            e.set_depth(png::BitDepth::Eight);
            let mut w = e.write_header().unwrap();
            // Top row (file row 0) mid grey 188, bottom row black.
            w.write_image_data(&[188, 188, 188, 0, 0, 0]).unwrap();
        }
        let srgb = Image::load(&path, true).unwrap();
        assert_eq!(srgb.texels[0], [0.0; 3], "row 0 is the bottom (v = 0)");
        // sRGB 188/255 = 0.7373 decodes to 0.5029 (the curve at that value).
        assert!((srgb.texels[1][0] - 0.502_886).abs() < 1e-4, "{:?}", srgb.texels[1]);
        let lin = Image::load(&path, false).unwrap();
        assert!((lin.texels[1][0] - 188.0 / 255.0).abs() < 1e-6);
        let missing = Image::load(&dir.join("nope.png"), true).unwrap_err();
        assert!(missing.contains("nope.png"), "{missing}");
        std::fs::write(dir.join("bad.png"), b"not a png").unwrap();
        let bad = Image::load(&dir.join("bad.png"), true).unwrap_err();
        assert!(bad.contains("bad.png"), "{bad}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
