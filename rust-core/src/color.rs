//! Colorimetry for reports and validation: linear Rec.709 RGB to CIE XYZ (D65), CIELAB, and
//! the colour differences ΔE*ab (CIE 1976) and CIEDE2000.
//!
//! RGB values are linear Rec.709 with the white `(1, 1, 1)` (a perfect reflector, as the
//! library's spectral integration normalises it); CIELAB is taken relative to that white, so
//! `(1, 1, 1)` is `L* = 100, a* = b* = 0`.
//!
//! References: CIE 15:2004 (CIELAB); IEC 61966-2-1 (the Rec.709/sRGB primaries and D65
//! matrix); Sharma, Wu & Dalal 2005, "The CIEDE2000 color-difference formula: implementation
//! notes, supplementary test data, and mathematical observations" (the formula as implemented,
//! and the test pairs below).

/// Linear Rec.709 RGB to CIE XYZ with the D65 white (IEC 61966-2-1).
#[must_use]
pub fn rgb_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb;
    [
        0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b,
        0.212_672_9 * r + 0.715_152_2 * g + 0.072_175_0 * b,
        0.019_333_9 * r + 0.119_192_0 * g + 0.950_304_1 * b,
    ]
}

/// CIE XYZ to CIELAB relative to the white `white` (CIE 15:2004, with the linear segment
/// below `(6/29)³`).
#[must_use]
pub fn xyz_to_lab(xyz: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        let d: f64 = 6.0 / 29.0;
        if t > d * d * d {
            t.cbrt()
        } else {
            t / (3.0 * d * d) + 4.0 / 29.0
        }
    };
    let [fx, fy, fz] = [0, 1, 2].map(|c| f(xyz[c] / white[c]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// Linear Rec.709 RGB to CIELAB with `(1, 1, 1)` as the white.
#[must_use]
pub fn rgb_to_lab(rgb: [f64; 3]) -> [f64; 3] {
    xyz_to_lab(rgb_to_xyz(rgb), rgb_to_xyz([1.0; 3]))
}

/// CIE 1976 colour difference ΔE*ab: the Euclidean distance in CIELAB.
#[must_use]
pub fn delta_e76(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    ((lab1[0] - lab2[0]).powi(2) + (lab1[1] - lab2[1]).powi(2) + (lab1[2] - lab2[2]).powi(2)).sqrt()
}

/// CIEDE2000 colour difference (`k_L = k_C = k_H = 1`), as written out by Sharma et al. 2005.
#[must_use]
pub fn delta_e2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let pow7 = |x: f64| x.powi(7);
    let c_bar = 0.5 * ((a1 * a1 + b1 * b1).sqrt() + (a2 * a2 + b2 * b2).sqrt());
    let g = 0.5 * (1.0 - (pow7(c_bar) / (pow7(c_bar) + pow7(25.0))).sqrt());
    let (a1p, a2p) = ((1.0 + g) * a1, (1.0 + g) * a2);
    let (c1p, c2p) = ((a1p * a1p + b1 * b1).sqrt(), (a2p * a2p + b2 * b2).sqrt());
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            b.atan2(a).to_degrees().rem_euclid(360.0)
        }
    };
    let (h1p, h2p) = (hue(b1, a1p), hue(b2, a2p));

    let dl = l2 - l1;
    let dc = c2p - c1p;
    let dh = if c1p * c2p == 0.0 {
        0.0
    } else {
        let d = h2p - h1p;
        if d > 180.0 {
            d - 360.0
        } else if d < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    let d_big_h = 2.0 * (c1p * c2p).sqrt() * (0.5 * dh).to_radians().sin();

    let l_bar = 0.5 * (l1 + l2);
    let c_bar_p = 0.5 * (c1p + c2p);
    let h_bar = if c1p * c2p == 0.0 {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        0.5 * (h1p + h2p)
    } else if h1p + h2p < 360.0 {
        0.5 * (h1p + h2p + 360.0)
    } else {
        0.5 * (h1p + h2p - 360.0)
    };
    let cosd = |deg: f64| deg.to_radians().cos();
    let t = 1.0 - 0.17 * cosd(h_bar - 30.0) + 0.24 * cosd(2.0 * h_bar) + 0.32 * cosd(3.0 * h_bar + 6.0)
        - 0.20 * cosd(4.0 * h_bar - 63.0);
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let r_c = 2.0 * (pow7(c_bar_p) / (pow7(c_bar_p) + pow7(25.0))).sqrt();
    let l50 = (l_bar - 50.0).powi(2);
    let s_l = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let s_c = 1.0 + 0.045 * c_bar_p;
    let s_h = 1.0 + 0.015 * c_bar_p * t;
    let r_t = -(2.0 * d_theta).to_radians().sin() * r_c;
    let (x, y, z) = (dl / s_l, dc / s_c, d_big_h / s_h);
    (x * x + y * y + z * z + r_t * y * z).max(0.0).sqrt()
}

/// CIEDE2000 between two linear Rec.709 colours (white `(1, 1, 1)`).
#[must_use]
pub fn delta_e2000_rgb(rgb1: [f64; 3], rgb2: [f64; 3]) -> f64 {
    delta_e2000(rgb_to_lab(rgb1), rgb_to_lab(rgb2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sharma, Wu & Dalal 2005, Table 1 (published to four decimals): pairs chosen to exercise
    /// the hue-angle wrap, the mean-hue branches, the rotation term and dark colours.
    const SHARMA: &[[f64; 7]] = &[
        [50.0, 2.6772, -79.7751, 50.0, 0.0, -82.7485, 2.0425],
        [50.0, 3.1571, -77.2803, 50.0, 0.0, -82.7485, 2.8615],
        [50.0, 2.8361, -74.0200, 50.0, 0.0, -82.7485, 3.4412],
        [50.0, -1.3802, -84.2814, 50.0, 0.0, -82.7485, 1.0000],
        [50.0, -1.1848, -84.8006, 50.0, 0.0, -82.7485, 1.0000],
        [50.0, -0.9009, -85.5211, 50.0, 0.0, -82.7485, 1.0000],
        [50.0, 0.0, 0.0, 50.0, -1.0, 2.0, 2.3669],
        [50.0, -1.0, 2.0, 50.0, 0.0, 0.0, 2.3669],
        [50.0, 2.49, -0.001, 50.0, -2.49, 0.0009, 7.1792],
        [50.0, 2.49, -0.001, 50.0, -2.49, 0.0010, 7.1792],
        [50.0, 2.49, -0.001, 50.0, -2.49, 0.0011, 7.2195],
        [50.0, 2.49, -0.001, 50.0, -2.49, 0.0012, 7.2195],
        [50.0, -0.001, 2.49, 50.0, 0.0009, -2.49, 4.8045],
        [50.0, -0.001, 2.49, 50.0, 0.0010, -2.49, 4.8045],
        [50.0, -0.001, 2.49, 50.0, 0.0011, -2.49, 4.7461],
        [50.0, 2.5, 0.0, 50.0, 0.0, -2.5, 4.3065],
        [50.0, 2.5, 0.0, 73.0, 25.0, -18.0, 27.1492],
        [50.0, 2.5, 0.0, 61.0, -5.0, 29.0, 22.8977],
        [50.0, 2.5, 0.0, 56.0, -27.0, -3.0, 31.9030],
        [50.0, 2.5, 0.0, 58.0, 24.0, 15.0, 19.4535],
        [50.0, 2.5, 0.0, 50.0, 3.1736, 0.5854, 1.0000],
        [50.0, 2.5, 0.0, 50.0, 3.2972, 0.0, 1.0000],
        [60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644],
        [63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630],
        [61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731],
        [35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645],
        [2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082],
    ];

    #[test]
    fn ciede2000_matches_sharma_table() {
        for row in SHARMA {
            let (a, b) = ([row[0], row[1], row[2]], [row[3], row[4], row[5]]);
            let (d1, d2) = (delta_e2000(a, b), delta_e2000(b, a));
            assert!((d1 - row[6]).abs() < 6e-5, "{row:?}: {d1}");
            assert!((d1 - d2).abs() < 1e-12, "not symmetric: {row:?}");
        }
    }

    /// White is `L* = 100, a* = b* = 0`; 18 % grey is `L* ≈ 49.5` (CIE: `116·0.18^{1/3} − 16`);
    /// ΔE76 is the Euclidean distance.
    #[test]
    fn lab_of_white_grey_and_delta_e76() {
        let w = rgb_to_lab([1.0; 3]);
        assert!((w[0] - 100.0).abs() < 1e-9 && w[1].abs() < 1e-9 && w[2].abs() < 1e-9);
        let g = rgb_to_lab([0.18; 3]);
        assert!((g[0] - (116.0 * 0.18f64.cbrt() - 16.0)).abs() < 1e-9 && g[1].abs() < 1e-9);
        assert!((delta_e76([50.0, 0.0, 0.0], [53.0, 4.0, 0.0]) - 5.0).abs() < 1e-12);
    }
}
