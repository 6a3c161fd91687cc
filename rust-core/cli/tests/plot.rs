//! `lacquer plot` end to end: the SVG carries the plotted values, which are the library's
//! `eval` (in-plane slice) and the exact albedo (Lambert); the PNG decodes to the asked size
//! with the curves drawn; the sampler's histogram follows its pdf; a MERL table and its fit
//! render as a sheet; bad input fails with a clear message.

use lacquer::{Material, Vec3};
use std::path::PathBuf;
use std::process::Command;

fn lacquer(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lacquer")).args(args).output().expect("runs");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lacquer-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// `(label, x, y)` of every data-carrying polyline of an SVG.
fn series(svg: &str) -> Vec<(String, Vec<f64>, Vec<f64>)> {
    let attr = |tag: &str, name: &str| -> Option<String> {
        let key = format!(" {name}=\"");
        let i = tag.find(&key)? + key.len();
        Some(tag[i..i + tag[i..].find('"')?].to_string())
    };
    let nums = |s: String| s.split_whitespace().map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>();
    svg.split("<polyline")
        .skip(1)
        .filter_map(|t| {
            let tag = &t[..t.find("/>")?];
            let label = attr(tag, "data-label")?;
            let points = attr(tag, "points")?.split_whitespace().count();
            let (x, y) = (nums(attr(tag, "data-x")?), nums(attr(tag, "data-y")?));
            // One drawn point per value (two for a histogram's steps).
            assert_eq!(x.len(), y.len());
            assert!(points == x.len() || points == 2 * x.len(), "{points} points for {} values", x.len());
            Some((label, x, y))
        })
        .collect()
}

fn luminance(m: &Material, wi: Vec3<f64>, wo: Vec3<f64>) -> f64 {
    let c = m.eval(wi, wo);
    0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b
}

#[test]
fn in_plane_svg_carries_the_eval_values_and_png_draws_them() {
    let ward = r#"{"model": "ward", "alpha_x": 0.2, "alpha_y": 0.2}"#;
    let svg_path = tmp("slice.svg");
    let (ok, _, err) = lacquer(&[
        "plot",
        "in-plane",
        "--preset",
        "gold_flake_8",
        "--material",
        ward,
        "--theta",
        "30",
        "--step",
        "5",
        "--log",
        "-o",
        svg_path.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\"") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
    let s = series(&svg);
    assert_eq!(s.len(), 2, "two curves");
    let materials = [Material::preset("gold_flake_8").unwrap(), Material::from_json(ward).unwrap()];
    let wi = Vec3::new(30f64.to_radians().sin(), 0.0, 30f64.to_radians().cos());
    for ((label, x, y), m) in s.iter().zip(&materials) {
        assert_eq!(x.len(), 35, "{label}: θo −85…85 in 5° steps");
        for (t, v) in x.iter().zip(y) {
            let wo = Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos());
            let e = luminance(m, wi, wo);
            // The SVG writes shortest round-trip decimals: equal to the last bit.
            assert_eq!(*v, e, "{label} at θo {t}");
        }
    }
    // The slice peaks at the mirror direction θo = −θi for the paint.
    let (_, x, y) = &s[0];
    let peak = x[y.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0];
    assert_eq!(peak, -30.0);

    let png_path = tmp("slice.png");
    let (ok, _, err) = lacquer(&[
        "plot",
        "polar",
        "--preset",
        "gold_flake_8",
        "--material",
        ward,
        "--width",
        "400",
        "--height",
        "300",
        "-o",
        png_path.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png_path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (400, 300));
    // Both curve colours (the first two palette entries) are drawn at full coverage.
    for c in [[0u8, 114, 178], [213, 94, 0]] {
        assert!(buf.chunks(3).any(|p| p == c), "colour {c:?} drawn");
    }
}

#[test]
fn albedo_of_lambert_is_its_albedo_and_the_sampler_follows_its_pdf() {
    let path = tmp("albedo.svg");
    let (ok, _, err) = lacquer(&[
        "plot",
        "albedo",
        "--material",
        r#"{"model": "lambert", "albedo": 0.7}"#,
        "--step",
        "10",
        "--samples",
        "64",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let s = series(&std::fs::read_to_string(&path).unwrap());
    assert_eq!(s[0].1, vec![0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0]);
    // Cosine sampling weighs every Lambert sample by ρ: exact up to rounding (measured 1e-16).
    assert!(s[0].2.iter().all(|a| (a - 0.7).abs() < 1e-12), "{:?}", s[0].2);

    let path = tmp("sampler.svg");
    let (ok, _, err) = lacquer(&[
        "plot",
        "sampler",
        "--material",
        r#"{"model": "ward", "alpha_x": 0.2, "alpha_y": 0.2}"#,
        "--theta",
        "40",
        "--samples",
        "200000",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let s = series(&std::fs::read_to_string(&path).unwrap());
    let (hist, pdf) = (&s[0].2, &s[1].2);
    assert_eq!((hist.len(), pdf.len()), (90, 90));
    // Total variation between the histogram and the pdf's marginal per 1° bin: the noise of
    // 200 000 samples in 90 bins gives ≈ 0.5 · Σ √(p/n) ≈ 0.01 (measured 0.0070); a sampler
    // off by a few percent in shape would exceed 0.03.
    let tv = 0.5 * hist.iter().zip(pdf).map(|(h, p)| (h - p).abs()).sum::<f64>();
    eprintln!("sampler histogram vs pdf: total variation {tv:.4}");
    assert!(tv < 0.03, "total variation {tv}");
    assert!((pdf.iter().sum::<f64>() - 1.0).abs() < 0.01, "pdf marginal integrates to 1");
}

#[test]
fn a_table_and_its_fit_plot_and_render_as_a_sheet() {
    let table = tmp("ward.binary");
    let (ok, _, err) = lacquer(&[
        "fit",
        "--generate",
        r#"{"model": "ward", "alpha_x": 0.15, "alpha_y": 0.15}"#,
        "--out",
        table.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let svg = tmp("fit.svg");
    let (ok, _, err) = lacquer(&[
        "plot",
        "in-plane",
        "--table",
        table.to_str().unwrap(),
        "--fit",
        "ward",
        "--fit-points",
        "4000",
        "--step",
        "5",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let s = series(&std::fs::read_to_string(&svg).unwrap());
    assert_eq!(s.len(), 2);
    assert!(s[0].0.contains("(table)") && s[1].0.contains("ward fit"), "{:?}", (&s[0].0, &s[1].0));
    // A Ward fit of a Ward table: the slices agree within 0.5 % of the peak (measured 6.4e-4;
    // the table interpolates over 1°–3° cells).
    let peak = s[0].2.iter().copied().fold(0.0, f64::max);
    let worst = s[0].2.iter().zip(&s[1].2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    eprintln!("table vs its Ward fit: largest slice difference {:.2e} of the peak", worst / peak);
    for (a, b) in s[0].2.iter().zip(&s[1].2) {
        assert!((a - b).abs() < 0.005 * peak, "{a} vs {b}");
    }
    let png = tmp("sheet.png");
    let (ok, out, err) = lacquer(&[
        "plot",
        "sheet",
        "--table",
        table.to_str().unwrap(),
        "--fit",
        "ward",
        "--fit-points",
        "4000",
        "--cell",
        "32",
        "--spp",
        "2",
        "--json",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(report["cells"].as_array().unwrap().len(), 2);
    let reader = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap())).read_info().unwrap();
    // Two 32-px cells with 6-px gaps, one label band.
    assert_eq!((reader.info().width, reader.info().height), (2 * 32 + 3 * 6, 32 + 7 + 2 * 6 + 6));
}

#[test]
fn bad_input_fails_with_a_clear_error() {
    let out = tmp("bad.svg");
    let o = out.to_str().unwrap();
    for (args, expect) in [
        (vec!["plot", "in-plane", "--preset", "nope", "-o", o], "unknown preset"),
        (vec!["plot", "in-plane", "--preset", "gold_flake_8", "-o", "x.txt"], "must end in .svg or .png"),
        (vec!["plot", "in-plane", "-o", o], "nothing to plot"),
        (vec!["plot", "in-plane", "--preset", "gold_flake_8", "--fit", "ward", "-o", o], "--fit needs a --table"),
        (vec!["plot", "in-plane", "--preset", "gold_flake_8", "--theta", "95", "-o", o], "outside [0, 89]"),
        (vec!["plot", "sampler", "--preset", "gold_flake_8", "--preset", "solid_red", "-o", o], "exactly one"),
        (vec!["plot", "albedo", "--material", "{\"model\": \"ward\", \"alpha_x\": -3}", "-o", o], "alpha_x"),
        (vec!["plot", "in-plane", "--table", "/nonexistent.binary", "-o", o], "/nonexistent.binary"),
        (vec!["plot", "sheet", "--preset", "gold_flake_8", "-o", o], "a sheet is a PNG"),
        (
            vec!["plot", "in-plane", "--preset", "gold_flake_8", "--label", "a", "--label", "b", "-o", o],
            "2 labels for 1",
        ),
    ] {
        let (ok, _, err) = lacquer(&args);
        assert!(!ok, "{args:?} should fail");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `plot data` draws curves measured elsewhere (the validation examples' JSON): the SVG carries
/// exactly the file's values; a malformed file fails with a message naming it.
#[test]
fn data_plot_draws_the_files_curves() {
    let data = tmp("curves.json");
    std::fs::write(
        &data,
        r#"{"title": "t", "xlabel": "α", "ylabel": "%", "series": [{"label": "a", "x": [0.01, 0.1, 0.3], "y": [0.5, 1.5, 4.0]}, {"label": "b", "x": [0.01, 0.3], "y": [2, 3]}]}"#,
    )
    .unwrap();
    let svg = tmp("curves.svg");
    let (ok, _, err) = lacquer(&["plot", "data", "--data", data.to_str().unwrap(), "-o", svg.to_str().unwrap()]);
    assert!(ok, "{err}");
    let got = series(&std::fs::read_to_string(&svg).unwrap());
    assert_eq!(got.len(), 2);
    assert_eq!(got[0], ("a".to_string(), vec![0.01, 0.1, 0.3], vec![0.5, 1.5, 4.0]));
    assert_eq!(got[1], ("b".to_string(), vec![0.01, 0.3], vec![2.0, 3.0]));
    std::fs::write(&data, r#"{"series": [{"label": "a", "x": [1, 2], "y": [1]}]}"#).unwrap();
    let (ok, _, err) = lacquer(&["plot", "data", "--data", data.to_str().unwrap(), "-o", svg.to_str().unwrap()]);
    assert!(!ok && err.contains("curves.json") && err.contains("2 x and 1 y"), "{err}");
}
