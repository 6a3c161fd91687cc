//! A small plotting back end for `lacquer plot`: line plots (linear or log y) and polar plots
//! drawn as a list of primitives, written as SVG (by hand) or rasterised to PNG (anti-aliased
//! lines, the renderer's 5×7 label font, the `png` crate).
//!
//! Every plotted curve carries its data in the SVG (`data-label`, `data-x`, `data-y` on its
//! `<polyline>`), so tests and scripts can read the values back without undoing the axes.

use lacquer_render::font;
use lacquer_render::output::Rgb8Image;
use std::fmt::Write as _;

/// Colours of successive curves (Okabe-Ito, colour-blind safe).
pub const PALETTE: [[u8; 3]; 7] =
    [[0, 114, 178], [213, 94, 0], [0, 158, 115], [204, 121, 167], [230, 159, 0], [86, 180, 233], [0, 0, 0]];

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// A histogram (steps between bin edges; `points` are bin centres of equal width).
    Steps,
}

/// One curve: label, data points `(x, y)` and style.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Data points.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
}

/// Axes of a plot.
#[derive(Clone, Debug)]
pub struct Plot {
    /// Title above the axes.
    pub title: String,
    /// x-axis label.
    pub xlabel: String,
    /// y-axis label.
    pub ylabel: String,
    /// Logarithmic y axis (values ≤ 0 are drawn at the bottom).
    pub log_y: bool,
    /// Polar axes: x is the angle from the normal in degrees (−90..90), y the radius.
    pub polar: bool,
    /// The curves.
    pub series: Vec<Series>,
}

/// A drawing primitive in pixel coordinates (y down).
#[derive(Clone, Debug)]
enum Item {
    Line { pts: Vec<(f64, f64)>, color: [u8; 3], width: f64, dashed: bool, data: Option<(String, Vec<(f64, f64)>)> },
    Text { x: f64, y: f64, text: String, size: f64, anchor: &'static str, color: [u8; 3] },
    Rect { x: f64, y: f64, w: f64, h: f64, fill: [u8; 3] },
}

impl Item {
    /// Black text.
    fn text(x: f64, y: f64, text: String, size: f64, anchor: &'static str) -> Item {
        Item::Text { x, y, text, size, anchor, color: [0; 3] }
    }

    /// A data series drawn through `pts` (already in pixels), carrying its data for the SVG.
    fn series(s: &Series, pts: Vec<(f64, f64)>, color: [u8; 3]) -> Item {
        Item::Line {
            pts,
            color,
            width: 2.0,
            dashed: s.style == Style::Dashed,
            data: Some((s.label.clone(), s.points.clone())),
        }
    }
}

/// A laid-out figure.
#[derive(Clone, Debug)]
pub struct Figure {
    width: u32,
    height: u32,
    items: Vec<Item>,
}

/// "Nice" tick positions covering `[lo, hi]` (about `n` of them).
fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let span = (hi - lo).abs().max(1e-300);
    let raw = span / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut v = Vec::new();
    while t <= hi + 1e-9 * span {
        v.push(if t.abs() < 1e-12 * span { 0.0 } else { t });
        t += step;
    }
    v
}

fn fmt_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

impl Plot {
    /// Lays the plot out on a `width × height` canvas.
    #[must_use]
    pub fn figure(&self, width: u32, height: u32) -> Figure {
        if self.polar {
            self.polar_figure(width, height)
        } else {
            self.cartesian_figure(width, height)
        }
    }

    /// Data range of all finite points (y in log10 for a log plot).
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for s in &self.series {
            for &(x, y) in &s.points {
                if !x.is_finite() || !y.is_finite() || (self.log_y && y <= 0.0) {
                    continue;
                }
                let y = if self.log_y { y.log10() } else { y };
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        if x1.partial_cmp(&x0) != Some(std::cmp::Ordering::Greater) {
            (x0, x1) = (x0.min(0.0).min(x1), x0.max(1.0).max(x1));
        }
        if !(y0.is_finite() && y1.is_finite()) {
            (y0, y1) = (0.0, 1.0);
        }
        if self.log_y {
            // At most 8 decades below the largest value.
            y0 = y0.max(y1 - 8.0).floor();
            y1 = y1.ceil().max(y0 + 1.0);
        } else {
            y0 = y0.min(0.0);
            if y1.partial_cmp(&y0) != Some(std::cmp::Ordering::Greater) {
                y1 = y0 + 1.0;
            }
            y1 += 0.05 * (y1 - y0);
        }
        ((x0, x1), (y0, y1))
    }

    fn legend(&self, items: &mut Vec<Item>, x: f64, y: f64) {
        let longest = self.series.iter().map(|s| s.label.chars().count()).max().unwrap_or(0) as f64;
        let (w, h) = (40.0 + 7.0 * longest, 16.0 * self.series.len() as f64 + 4.0);
        items.push(Item::Rect { x: x - 6.0, y: y - 10.0, w, h, fill: [255; 3] });
        for (i, s) in self.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let yy = y + 16.0 * i as f64;
            items.push(Item::Line {
                pts: vec![(x, yy), (x + 22.0, yy)],
                color,
                width: 2.0,
                dashed: s.style == Style::Dashed,
                data: None,
            });
            items.push(Item::text(x + 28.0, yy + 4.0, s.label.clone(), 12.0, "start"));
        }
    }

    fn cartesian_figure(&self, width: u32, height: u32) -> Figure {
        let (w, h) = (width as f64, height as f64);
        let (left, right, top, bottom) = (70.0, 20.0, 48.0, 50.0);
        let ((x0, x1), (y0, y1)) = self.ranges();
        let px = |x: f64| left + (x - x0) / (x1 - x0) * (w - left - right);
        let py = |y: f64| {
            let y = if self.log_y {
                if y > 0.0 {
                    y.log10().max(y0)
                } else {
                    y0
                }
            } else {
                y
            };
            h - bottom - (y - y0) / (y1 - y0) * (h - top - bottom)
        };
        let mut items = vec![Item::Rect { x: 0.0, y: 0.0, w, h, fill: [255; 3] }];
        let grey = [200, 200, 200];
        for t in ticks(x0, x1, 8) {
            items.push(Item::Line {
                pts: vec![(px(t), top), (px(t), h - bottom)],
                color: grey,
                width: 1.0,
                dashed: false,
                data: None,
            });
            items.push(Item::text(px(t), h - bottom + 16.0, fmt_tick(t), 11.0, "middle"));
        }
        let yt: Vec<f64> =
            if self.log_y { (y0 as i64..=y1 as i64).map(|e| e as f64).collect() } else { ticks(y0, y1, 6) };
        for t in yt {
            let yy = if self.log_y { h - bottom - (t - y0) / (y1 - y0) * (h - top - bottom) } else { py(t) };
            let label = if self.log_y { fmt_tick(10f64.powf(t)) } else { fmt_tick(t) };
            items.push(Item::Line {
                pts: vec![(left, yy), (w - right, yy)],
                color: grey,
                width: 1.0,
                dashed: false,
                data: None,
            });
            items.push(Item::text(left - 6.0, yy + 4.0, label, 11.0, "end"));
        }
        let frame = vec![(left, top), (w - right, top), (w - right, h - bottom), (left, h - bottom), (left, top)];
        items.push(Item::Line { pts: frame, color: [0; 3], width: 1.0, dashed: false, data: None });
        for (i, s) in self.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let mut pts = Vec::new();
            if s.style == Style::Steps && s.points.len() > 1 {
                let half = 0.5 * (s.points[1].0 - s.points[0].0);
                for &(x, y) in &s.points {
                    pts.push((px(x - half), py(y)));
                    pts.push((px(x + half), py(y)));
                }
            } else {
                pts = s
                    .points
                    .iter()
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .map(|&(x, y)| (px(x), py(y)))
                    .collect();
            }
            items.push(Item::series(s, pts, color));
        }
        items.push(Item::text(w / 2.0, 20.0, self.title.clone(), 14.0, "middle"));
        items.push(Item::text((left + w - right) / 2.0, h - 12.0, self.xlabel.clone(), 12.0, "middle"));
        items.push(Item::text(8.0, top - 8.0, self.ylabel.clone(), 12.0, "start"));
        let longest = self.series.iter().map(|s| s.label.chars().count()).max().unwrap_or(0) as f64;
        self.legend(&mut items, (w - right - 50.0 - 7.0 * longest).max(left + 10.0), top + 16.0);
        Figure { width, height, items }
    }

    fn polar_figure(&self, width: u32, height: u32) -> Figure {
        let (w, h) = (width as f64, height as f64);
        let ((_, _), (r0, r1)) = self.ranges();
        let (cx, cy) = (w / 2.0, h - 40.0);
        let radius = (w / 2.0 - 30.0).min(h - 90.0);
        let rad = |v: f64| {
            let v = if self.log_y {
                if v > 0.0 {
                    v.log10().max(r0)
                } else {
                    r0
                }
            } else {
                v.max(0.0)
            };
            (v - r0) / (r1 - r0) * radius
        };
        let at = |theta_deg: f64, r: f64| {
            let t = theta_deg.to_radians();
            (cx + r * t.sin(), cy - r * t.cos())
        };
        let mut items = vec![Item::Rect { x: 0.0, y: 0.0, w, h, fill: [255; 3] }];
        let grey = [200, 200, 200];
        let rings: Vec<f64> =
            if self.log_y { (r0 as i64..=r1 as i64).map(|e| e as f64).collect() } else { ticks(r0, r1, 4) };
        for t in rings {
            let rr = (t - r0) / (r1 - r0) * radius;
            let pts: Vec<(f64, f64)> = (0..=90).map(|k| at(-90.0 + 2.0 * k as f64, rr)).collect();
            items.push(Item::Line { pts, color: grey, width: 1.0, dashed: false, data: None });
            let label = if self.log_y { fmt_tick(10f64.powf(t)) } else { fmt_tick(t) };
            items.push(Item::text(cx + rr, cy + 14.0, label, 10.0, "middle"));
        }
        for a in [-90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0] {
            let (ex, ey) = at(a, radius);
            items.push(Item::Line {
                pts: vec![(cx, cy), (ex, ey)],
                color: grey,
                width: 1.0,
                dashed: false,
                data: None,
            });
            let (tx, ty) = at(a, radius + 12.0);
            items.push(Item::text(tx, ty + 4.0, format!("{a:.0}"), 10.0, "middle"));
        }
        for (i, s) in self.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let pts =
                s.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()).map(|&(x, y)| at(x, rad(y))).collect();
            items.push(Item::series(s, pts, color));
        }
        items.push(Item::text(w / 2.0, 20.0, self.title.clone(), 14.0, "middle"));
        items.push(Item::text(8.0, h - 8.0, format!("radius: {}", self.ylabel), 11.0, "start"));
        self.legend(&mut items, w - 250.0, 44.0);
        Figure { width, height, items }
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

impl Figure {
    /// The figure as an SVG document.
    #[must_use]
    pub fn to_svg(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif">"#,
            w = self.width,
            h = self.height
        );
        for item in &self.items {
            match item {
                Item::Rect { x, y, w, h, fill } => {
                    let _ = writeln!(
                        s,
                        r#"<rect x="{x:.2}" y="{y:.2}" width="{w:.2}" height="{h:.2}" fill="{}"/>"#,
                        hex(*fill)
                    );
                }
                Item::Text { x, y, text, size, anchor, color } => {
                    let _ = writeln!(
                        s,
                        r#"<text x="{x:.2}" y="{y:.2}" font-size="{size}" text-anchor="{anchor}" fill="{}">{}</text>"#,
                        hex(*color),
                        esc(text)
                    );
                }
                Item::Line { pts, color, width, dashed, data } => {
                    let points: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.2},{y:.2}")).collect();
                    let dash = if *dashed { r#" stroke-dasharray="6,4""# } else { "" };
                    let mut extra = String::new();
                    if let Some((label, values)) = data {
                        let xs: Vec<String> = values.iter().map(|v| format!("{:e}", v.0)).collect();
                        let ys: Vec<String> = values.iter().map(|v| format!("{:e}", v.1)).collect();
                        extra = format!(
                            r#" class="series" data-label="{}" data-x="{}" data-y="{}""#,
                            esc(label),
                            xs.join(" "),
                            ys.join(" ")
                        );
                    }
                    let _ = writeln!(
                        s,
                        r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="{width}"{dash}{extra}/>"#,
                        points.join(" "),
                        hex(*color)
                    );
                }
            }
        }
        s.push_str("</svg>\n");
        s
    }

    /// The figure rasterised (lines anti-aliased by distance to the segment; text in the
    /// 5×7 label font, upper case).
    #[must_use]
    pub fn to_image(&self) -> Rgb8Image {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut img = Rgb8Image { width: self.width, height: self.height, data: vec![[255; 3]; w * h] };
        for item in &self.items {
            match item {
                Item::Rect { x, y, w: rw, h: rh, fill } => {
                    for yy in (*y as usize)..((*y + *rh) as usize).min(h) {
                        for xx in (*x as usize)..((*x + *rw) as usize).min(w) {
                            img.data[yy * w + xx] = *fill;
                        }
                    }
                }
                Item::Line { pts, color, width, dashed, .. } => {
                    let mut run = 0.0;
                    for seg in pts.windows(2) {
                        draw_segment(
                            &mut img,
                            seg[0],
                            seg[1],
                            *width,
                            *color,
                            if *dashed { Some(&mut run) } else { None },
                        );
                    }
                }
                Item::Text { x, y, text, size, anchor, color } => {
                    let fits = |k: u32| font::text_width(text, k) + 10 <= self.width;
                    let scale = if *size >= 14.0 && fits(2) { 2 } else { 1 };
                    let clean: String = text
                        .chars()
                        .map(|c| match c {
                            'θ' => 'T',
                            '−' => '-',
                            '°' | '·' => ' ',
                            c if c.is_ascii() || c == 'µ' => c,
                            _ => '?',
                        })
                        .collect();
                    let tw = font::text_width(&clean, scale) as f64;
                    let x0 = match *anchor {
                        "middle" => x - tw / 2.0,
                        "end" => x - tw,
                        _ => *x,
                    };
                    font::draw_text(&mut img, x0 as i32, (*y - 7.0 * scale as f64) as i32, &clean, scale, *color);
                }
            }
        }
        img
    }

    /// Writes the figure: `.svg` or `.png` by the path's extension.
    pub fn write(&self, path: &std::path::Path) -> Result<(), String> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("svg") => std::fs::write(path, self.to_svg()).map_err(|e| format!("{}: {e}", path.display())),
            Some("png") => self.to_image().write_png(path),
            _ => Err(format!("{}: the output must end in .svg or .png", path.display())),
        }
    }
}

/// Blends `color` into pixel `(x, y)` with coverage `a`.
fn blend(img: &mut Rgb8Image, x: i64, y: i64, color: [u8; 3], a: f64) {
    if x < 0 || y < 0 || x >= img.width as i64 || y >= img.height as i64 || a <= 0.0 {
        return;
    }
    let p = &mut img.data[(y as u32 * img.width + x as u32) as usize];
    for c in 0..3 {
        p[c] = (p[c] as f64 * (1.0 - a) + color[c] as f64 * a).round() as u8;
    }
}

/// A segment of width `width`: each pixel near it gets coverage from its distance to the
/// segment. A dashed line skips 4 px after every 6 (`run` carries the phase along a polyline).
fn draw_segment(img: &mut Rgb8Image, a: (f64, f64), b: (f64, f64), width: f64, color: [u8; 3], run: Option<&mut f64>) {
    if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
        return;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let len = len2.sqrt();
    let start = run.as_ref().map_or(0.0, |r| **r);
    let r = 0.5 * width + 0.5;
    let (xmin, xmax) = ((a.0.min(b.0) - r).floor() as i64, (a.0.max(b.0) + r).ceil() as i64);
    let (ymin, ymax) = ((a.1.min(b.1) - r).floor() as i64, (a.1.max(b.1) + r).ceil() as i64);
    for y in ymin..=ymax {
        for x in xmin..=xmax {
            let (qx, qy) = (x as f64 + 0.5 - a.0, y as f64 + 0.5 - a.1);
            let t = if len2 > 0.0 { ((qx * dx + qy * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
            if run.is_some() && (start + t * len).rem_euclid(10.0) > 6.0 {
                continue;
            }
            let d = ((qx - t * dx).powi(2) + (qy - t * dy).powi(2)).sqrt();
            let cover = (0.5 * width + 0.5 - d).clamp(0.0, 1.0);
            // Pixels at segment joints are drawn twice: keep the larger coverage only
            // approximately (blending twice darkens joints slightly; acceptable for plots).
            blend(img, x, y, color, cover);
        }
    }
    if let Some(r) = run {
        *r += len;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice_and_cover_the_range() {
        assert_eq!(ticks(0.0, 1.0, 5), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        assert_eq!(ticks(-90.0, 90.0, 8), vec![-75.0, -50.0, -25.0, 0.0, 25.0, 50.0, 75.0]);
    }

    #[test]
    fn svg_carries_the_data_and_png_draws_the_line() {
        let plot = Plot {
            title: "t".into(),
            xlabel: "x".into(),
            ylabel: "y".into(),
            log_y: false,
            polar: false,
            series: vec![Series { label: "a<b".into(), points: vec![(0.0, 0.0), (1.0, 2.0)], style: Style::Line }],
        };
        let fig = plot.figure(200, 150);
        let svg = fig.to_svg();
        assert!(svg.contains(r#"data-label="a&lt;b" data-x="0e0 1e0" data-y="0e0 2e0""#), "{svg}");
        let img = fig.to_image();
        // The line is drawn in the first palette colour somewhere.
        assert!(img.data.iter().any(|p| *p == PALETTE[0]));
    }
}
