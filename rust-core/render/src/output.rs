//! Image output: OpenEXR (linear RGBA in half or float, optional `albedo.*` and `N.*`
//! layers, render metadata) and a tone-mapped sRGB PNG preview.

use crate::env::HdrImage;
use crate::integrator::Framebuffer;
use lacquer::Rgb;
use std::path::Path;

/// Sample type of the EXR channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrPrecision {
    /// 16-bit half floats (smaller files, ~3 significant digits).
    Half,
    /// 32-bit floats.
    Float,
}

/// Keeps printable ASCII (EXR text attributes are byte strings).
fn ascii(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii() && !c.is_ascii_control() { c } else { '?' }).collect()
}

/// Writes the framebuffer as a single-part scanline EXR: channels `R G B A`, and with AOVs
/// `albedo.R albedo.G albedo.B` and `N.X N.Y N.Z`. `metadata` pairs become string attributes.
pub fn write_exr(
    fb: &Framebuffer,
    path: &Path,
    precision: ExrPrecision,
    metadata: &[(&str, String)],
) -> Result<(), String> {
    use exr::prelude::*;
    let (w, h) = (fb.width as usize, fb.height as usize);
    let samples = |v: Vec<f32>| match precision {
        ExrPrecision::Half => FlatSamples::F16(v.into_iter().map(f16::from_f32).collect()),
        ExrPrecision::Float => FlatSamples::F32(v),
    };
    let plane = |src: &[[f32; 3]], c: usize| -> Vec<f32> { src.iter().map(|p| p[c]).collect() };
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        channels.push(AnyChannel::new(*name, samples(plane(&fb.color, c))));
    }
    channels.push(AnyChannel::new("A", samples(fb.alpha.clone())));
    if let Some(al) = &fb.albedo {
        for (c, name) in ["albedo.R", "albedo.G", "albedo.B"].iter().enumerate() {
            channels.push(AnyChannel::new(*name, samples(plane(al, c))));
        }
    }
    if let Some(n) = &fb.normal {
        for (c, name) in ["N.X", "N.Y", "N.Z"].iter().enumerate() {
            channels.push(AnyChannel::new(*name, samples(plane(n, c))));
        }
    }
    let mut attrs = LayerAttributes { software_name: Some(Text::from("lacquer render")), ..Default::default() };
    for (k, v) in metadata {
        attrs.other.insert(Text::from(ascii(k).as_str()), AttributeValue::Text(Text::from(ascii(v).as_str())));
    }
    let layer = Layer::new((w, h), attrs, Encoding::FAST_LOSSLESS, AnyChannels::sort(SmallVec::from_vec(channels)));
    Image::from_layer(layer).write().to_file(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Reads the RGB channels of the first RGBA layer of an EXR (environment maps, tests).
pub fn read_exr_rgb(path: &Path) -> Result<HdrImage, String> {
    use exr::prelude::*;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| HdrImage {
            width: res.width(),
            height: res.height(),
            pixels: vec![Rgb::zero(); res.width() * res.height()],
        },
        |img: &mut HdrImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(img.layer_data.channel_data.pixels)
}

/// Tone curve of the PNG preview.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToneMap {
    /// The ACES filmic fit of Narkowicz (2015), per channel.
    Filmic,
    /// Linear, clipped at 1.
    Clamp,
}

#[inline]
fn aces(x: f32) -> f32 {
    let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
    ((x * (a * x + b)) / (x * (c * x + d) + e)).clamp(0.0, 1.0)
}

#[inline]
fn srgb_oetf(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit sRGB of a linear colour after exposure (stops) and the tone curve.
#[must_use]
pub fn to_srgb8(c: [f32; 3], exposure: f32, tone: ToneMap) -> [u8; 3] {
    let k = exposure.exp2();
    c.map(|v| {
        let v = if v.is_finite() { (v * k).max(0.0) } else { 0.0 };
        let t = match tone {
            ToneMap::Filmic => aces(v),
            ToneMap::Clamp => v.min(1.0),
        };
        (srgb_oetf(t) * 255.0 + 0.5) as u8
    })
}

/// An 8-bit sRGB image (previews, sheets with labels).
#[derive(Clone, Debug)]
pub struct Rgb8Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels, row-major.
    pub data: Vec<[u8; 3]>,
}

impl Rgb8Image {
    /// Tone-maps a framebuffer.
    #[must_use]
    pub fn from_framebuffer(fb: &Framebuffer, exposure: f32, tone: ToneMap) -> Self {
        Self {
            width: fb.width,
            height: fb.height,
            data: fb.color.iter().map(|c| to_srgb8(*c, exposure, tone)).collect(),
        }
    }

    /// Writes a PNG (tagged sRGB).
    pub fn write_png(&self, path: &Path) -> Result<(), String> {
        let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = enc.write_header().map_err(|e| format!("{}: {e}", path.display()))?;
        let bytes: Vec<u8> = self.data.iter().flatten().copied().collect();
        writer.write_image_data(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        writer.finish().map_err(|e| format!("{}: {e}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip() {
        let mut fb = Framebuffer::new(3, 2, true);
        for (i, c) in fb.color.iter_mut().enumerate() {
            *c = [i as f32 * 0.5, 1.0, 2.0];
        }
        let dir = std::env::temp_dir().join(format!("lacquer-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.exr");
        write_exr(&fb, &path, ExrPrecision::Float, &[("lacquer:spp", "4".into())]).unwrap();
        let back = read_exr_rgb(&path).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        assert_eq!(back.pixels[5], Rgb::new(2.5, 1.0, 2.0));
        write_exr(&fb, &path, ExrPrecision::Half, &[]).unwrap();
        assert_eq!(read_exr_rgb(&path).unwrap().pixels[3], Rgb::new(1.5, 1.0, 2.0));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn tone_curve_endpoints() {
        assert_eq!(to_srgb8([0.0, 1.0, 100.0], 0.0, ToneMap::Clamp), [0, 255, 255]);
        // sRGB code 128 (0.50196) decodes to linear 0.2159.
        assert_eq!(to_srgb8([0.2159, 0.0, 0.0], 0.0, ToneMap::Clamp)[0], 128);
        assert!(to_srgb8([1e6, 0.0, 0.0], 0.0, ToneMap::Filmic)[0] == 255);
    }
}
