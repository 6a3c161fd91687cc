//! Comparison sheets: a grid of presets, each rendered in the built-in scene, composed into
//! one image with a label under every cell (labels are drawn on the PNG only; the EXR keeps
//! the radiance). The thesis' figures 5.3–5.7 vary flake density (0–8 % at 25 µm) and flake
//! size (15–25 µm at 8 %) of a gold paint; the sheets add the silver series as a second row.

use crate::desc::DefaultScene;
use crate::font;
use crate::integrator::{render, Cancelled, Framebuffer, RenderSettings, RenderStats};
use crate::output::{Rgb8Image, ToneMap};
use lacquer::Material;

/// A sheet: rows of presets with labels.
#[derive(Clone, Copy, Debug)]
pub struct SheetSpec {
    /// Name used with `--sheet`.
    pub name: &'static str,
    /// What it shows.
    pub title: &'static str,
    /// Rows: (row label, [(preset, column label)]).
    pub rows: &'static [(&'static str, &'static [(&'static str, &'static str)])],
}

const DENSITY_GOLD: &[(&str, &str)] = &[
    ("gold_flake_0", "0 %"),
    ("gold_flake_2", "2 %"),
    ("gold_flake_3", "3 %"),
    ("gold_flake_5", "5 %"),
    ("gold_flake_8", "8 %"),
];
const DENSITY_SILVER: &[(&str, &str)] = &[
    ("silver_flake_0", "0 %"),
    ("silver_flake_2", "2 %"),
    ("silver_flake_3", "3 %"),
    ("silver_flake_5", "5 %"),
    ("silver_flake_8", "8 %"),
];
const SIZE_GOLD: &[(&str, &str)] =
    &[("gold_flake_8_size_15", "15 µm"), ("gold_flake_8_size_20", "20 µm"), ("gold_flake_8_size_25", "25 µm")];
const SIZE_SILVER: &[(&str, &str)] =
    &[("silver_flake_8_size_15", "15 µm"), ("silver_flake_8_size_20", "20 µm"), ("silver_flake_8_size_25", "25 µm")];
const OTHERS: &[(&str, &str)] = &[
    ("solid_red", "solid red"),
    ("solid_white", "solid white"),
    ("pearl_white", "pearl white"),
    ("pearl_blue", "pearl blue"),
    ("automotive_silver_metallic", "auto silver"),
];

/// Every sheet.
pub const SHEETS: &[SheetSpec] = &[
    SheetSpec {
        name: "thesis-density",
        title: "Flake density 0-8 % at 25 µm (thesis figs. 5.3, 5.7): gold, silver",
        rows: &[("gold", DENSITY_GOLD), ("silver", DENSITY_SILVER)],
    },
    SheetSpec {
        name: "thesis-size",
        title: "Flake size 15-25 µm at 8 % (thesis fig. 5.4): gold, silver",
        rows: &[("gold", SIZE_GOLD), ("silver", SIZE_SILVER)],
    },
    SheetSpec { name: "paints", title: "Solid and pearlescent paints", rows: &[("", OTHERS)] },
];

/// Looks a sheet up by name.
#[must_use]
pub fn find(name: &str) -> Option<&'static SheetSpec> {
    SHEETS.iter().find(|s| s.name == name)
}

/// A rendered sheet: the composed image and where its labels go.
#[derive(Clone, Debug)]
pub struct SheetImage {
    /// The composed radiance.
    pub fb: Framebuffer,
    /// (x, y, text) of each label (top-left corner, PNG pixels).
    pub labels: Vec<(u32, u32, String)>,
    /// Font scale of the labels.
    pub label_scale: u32,
}

const GAP: u32 = 6;

impl SheetSpec {
    /// Number of columns.
    #[must_use]
    pub fn columns(&self) -> usize {
        self.rows.iter().map(|r| r.1.len()).max().unwrap_or(0)
    }

    /// Renders every cell at `cell × cell` pixels in the built-in scene and composes them.
    /// `progress` receives the fraction of the whole sheet.
    pub fn render(
        &self,
        cell: u32,
        scene: &DefaultScene,
        set: &RenderSettings,
        progress: &mut dyn FnMut(f32) -> bool,
    ) -> Result<SheetImage, String> {
        let mut rows = Vec::new();
        for (row_label, cells) in self.rows {
            let mut row = Vec::new();
            for (preset, col_label) in cells.iter() {
                let material = Material::preset(preset).map_err(|e| e.to_string())?;
                let text =
                    if row_label.is_empty() { col_label.to_string() } else { format!("{row_label} {col_label}") };
                row.push((text, material));
            }
            rows.push(row);
        }
        render_cells(&rows, cell, scene, set, progress)
    }
}

/// Renders rows of labelled materials, each at `cell × cell` pixels in the built-in scene (the
/// same shader ball, light and seed for every cell), and composes them with a label under
/// every cell. `progress` receives the fraction of the whole sheet.
pub fn render_cells(
    rows: &[Vec<(String, Material)>],
    cell: u32,
    scene: &DefaultScene,
    set: &RenderSettings,
    progress: &mut dyn FnMut(f32) -> bool,
) -> Result<SheetImage, String> {
    let label_scale = if cell >= 192 { 2 } else { 1 };
    let band = 7 * label_scale + 2 * GAP;
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let nrows = rows.len() as u32;
    let width = cols * cell + (cols + 1) * GAP;
    let height = nrows * (cell + band) + GAP;
    let mut fb = Framebuffer::new(width, height, set.aovs);
    let mut labels = Vec::new();
    let total = rows.iter().map(Vec::len).sum::<usize>().max(1) as f32;
    let mut k = 0usize;
    let mut stats = RenderStats::default();
    let mut cell_scene = scene.clone();
    cell_scene.width = cell;
    cell_scene.height = cell;
    for (r, cells) in rows.iter().enumerate() {
        for (c, (text, material)) in cells.iter().enumerate() {
            let sc = cell_scene.build(material.clone())?;
            let done = k as f32;
            let img = render(&sc, set, &mut |f| progress((done + f) / total))
                .map_err(|Cancelled| "render cancelled".to_string())?;
            stats.seconds += img.stats.seconds;
            stats.paths += img.stats.paths;
            stats.invalid += img.stats.invalid;
            let (x0, y0) = (GAP + c as u32 * (cell + GAP), GAP + r as u32 * (cell + band));
            blit(&mut fb, &img, x0, y0);
            let tw = font::text_width(text, label_scale);
            labels.push((x0 + cell.saturating_sub(tw) / 2, y0 + cell + GAP, text.clone()));
            k += 1;
        }
    }
    stats.paths_per_second = stats.paths as f64 / stats.seconds.max(1e-9);
    fb.stats = stats;
    Ok(SheetImage { fb, labels, label_scale })
}

fn blit(dst: &mut Framebuffer, src: &Framebuffer, x0: u32, y0: u32) {
    for y in 0..src.height {
        for x in 0..src.width {
            let (dx, dy) = (x0 + x, y0 + y);
            if dx >= dst.width || dy >= dst.height {
                continue;
            }
            let d = (dy * dst.width + dx) as usize;
            let s = (y * src.width + x) as usize;
            dst.color[d] = src.color[s];
            dst.alpha[d] = src.alpha[s];
            if let (Some(a), Some(b)) = (dst.albedo.as_mut(), src.albedo.as_ref()) {
                a[d] = b[s];
            }
            if let (Some(a), Some(b)) = (dst.normal.as_mut(), src.normal.as_ref()) {
                a[d] = b[s];
            }
        }
    }
}

impl SheetImage {
    /// Tone-maps the sheet and draws its labels.
    #[must_use]
    pub fn to_png_image(&self, exposure: f32, tone: ToneMap) -> Rgb8Image {
        let mut img = Rgb8Image::from_framebuffer(&self.fb, exposure, tone);
        for (x, y, text) in &self.labels {
            font::draw_text(&mut img, *x as i32, *y as i32, text, self.label_scale, [230, 230, 230]);
        }
        img
    }
}
