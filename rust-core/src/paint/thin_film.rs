//! Thin-film interference (Airy reflectance) for pearlescent flakes: a film of thickness `d`
//! and index `n2` (TiO₂ or Fe₂O₃ on mica) on a substrate `n3` (mica), seen from a medium `n1`
//! (the paint binder).
//!
//! [`ThinFilm::spectral_rgb`] is the brute-force reference: the unpolarised Airy reflectance
//! per wavelength (Born & Wolf, *Principles of Optics*, §1.6.4) integrated over 380–780 nm
//! against the CIE 1931 colour-matching functions (analytic multi-lobe fit of Wyman, Sloan &
//! Shirley 2013) under an equal-energy illuminant, converted to linear Rec.709 and normalised
//! so a perfect reflector is white. The model evaluates a table of it over `cos θ`.

use crate::table::MuTable;

/// A thin dielectric film on a dielectric substrate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilm {
    /// Film thickness in nm.
    pub thickness_nm: f64,
    /// Film refractive index.
    pub film_ior: f64,
    /// Substrate refractive index (mica ≈ 1.58).
    pub substrate_ior: f64,
    /// Index of the medium the light arrives from (the binder).
    pub medium_ior: f64,
}

/// One lobe of the Wyman-Sloan-Shirley CMF fit: a Gaussian with different widths left and right.
fn lobe(l: f64, mu: f64, s_left: f64, s_right: f64) -> f64 {
    let s = if l < mu { s_left } else { s_right };
    let t = (l - mu) / s;
    (-0.5 * t * t).exp()
}

/// CIE 1931 2° colour-matching functions (Wyman, Sloan & Shirley 2013, multi-lobe fit).
#[must_use]
pub fn cie_xyz(lambda_nm: f64) -> [f64; 3] {
    let l = lambda_nm;
    let x =
        1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) - 0.065 * lobe(l, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
    [x, y, z]
}

/// CIE XYZ to linear Rec.709 RGB (IEC 61966-2-1).
#[must_use]
pub fn xyz_to_rgb(xyz: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz;
    [
        3.2404542 * x - 1.5371385 * y - 0.4985314 * z,
        -0.9692660 * x + 1.8760108 * y + 0.0415560 * z,
        0.0556434 * x - 0.2040259 * y + 1.0572252 * z,
    ]
}

/// Wavelength grid of the spectral reference (nm).
const LAMBDA_MIN: f64 = 380.0;
const LAMBDA_MAX: f64 = 780.0;
const LAMBDA_STEP: f64 = 2.0;

/// Integrates a reflectance spectrum to linear RGB, normalised so `R(λ) = 1` gives white.
#[must_use]
pub fn spectrum_to_rgb(mut reflectance: impl FnMut(f64) -> f64) -> [f64; 3] {
    let mut xyz = [0.0; 3];
    let mut white = [0.0; 3];
    let n = ((LAMBDA_MAX - LAMBDA_MIN) / LAMBDA_STEP) as usize;
    for i in 0..=n {
        let l = LAMBDA_MIN + i as f64 * LAMBDA_STEP;
        let w = if i == 0 || i == n { 0.5 } else { 1.0 };
        let cmf = cie_xyz(l);
        let r = reflectance(l);
        for c in 0..3 {
            xyz[c] += w * r * cmf[c];
            white[c] += w * cmf[c];
        }
    }
    let rgb = xyz_to_rgb(xyz);
    let rgb_white = xyz_to_rgb(white);
    [0, 1, 2].map(|c| rgb[c] / rgb_white[c])
}

impl ThinFilm {
    /// Unpolarised Airy reflectance at one wavelength for incidence `cos θ1` in the medium.
    #[must_use]
    pub fn reflectance(&self, cos_theta1: f64, lambda_nm: f64) -> f64 {
        let (n1, n2, n3) = (self.medium_ior, self.film_ior, self.substrate_ior);
        let c1 = cos_theta1.clamp(0.0, 1.0);
        let s1_2 = 1.0 - c1 * c1;
        let c2_2 = 1.0 - s1_2 * (n1 / n2).powi(2);
        let c3_2 = 1.0 - s1_2 * (n1 / n3).powi(2);
        if c2_2 <= 0.0 || c3_2 <= 0.0 {
            return 1.0; // total internal reflection at the film (cannot happen for n2, n3 > n1)
        }
        let (c2, c3) = (c2_2.sqrt(), c3_2.sqrt());
        // Phase difference of one round trip through the film.
        let delta = 4.0 * std::f64::consts::PI * n2 * self.thickness_nm * c2 / lambda_nm;
        let cos_d = delta.cos();
        let airy = |r12: f64, r23: f64| {
            let num = r12 * r12 + r23 * r23 + 2.0 * r12 * r23 * cos_d;
            let den = 1.0 + r12 * r12 * r23 * r23 + 2.0 * r12 * r23 * cos_d;
            num / den
        };
        let rs = airy((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2), (n2 * c2 - n3 * c3) / (n2 * c2 + n3 * c3));
        let rp = airy((n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2), (n3 * c2 - n2 * c3) / (n3 * c2 + n2 * c3));
        0.5 * (rs + rp)
    }

    /// Brute-force RGB reflectance at `cos θ1` (spectral integration, 2 nm steps).
    #[must_use]
    pub fn spectral_rgb(&self, cos_theta1: f64) -> [f64; 3] {
        spectrum_to_rgb(|l| self.reflectance(cos_theta1, l)).map(|v| v.clamp(0.0, 1.0))
    }

    /// A table of [`ThinFilm::spectral_rgb`] over `cos θ1` for fast evaluation.
    #[must_use]
    pub fn table(&self, nodes: usize) -> MuTable {
        MuTable::build(nodes, |mu| self.spectral_rgb(mu))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_thickness_film_is_the_bare_substrate() {
        // d = 0: the film vanishes; R is the Fresnel reflectance of the medium/substrate pair.
        let f = ThinFilm { thickness_nm: 0.0, film_ior: 2.6, substrate_ior: 1.58, medium_ior: 1.5 };
        for c in [1.0, 0.7, 0.2] {
            let expect = crate::fresnel::dielectric(c, 1.58 / 1.5);
            assert!((f.reflectance(c, 550.0) - expect).abs() < 1e-12);
        }
    }

    #[test]
    fn quarter_wave_film_has_the_textbook_peak() {
        // Quarter-wave layer at normal incidence (n2 d = λ/4): R = ((n1 n3 − n2²)/(n1 n3 + n2²))².
        let (n1, n2, n3) = (1.5, 2.6, 1.58);
        let f = ThinFilm { thickness_nm: 550.0 / (4.0 * n2), film_ior: n2, substrate_ior: n3, medium_ior: n1 };
        let expect = ((n1 * n3 - n2 * n2) / (n1 * n3 + n2 * n2)).powi(2);
        assert!((f.reflectance(1.0, 550.0) - expect).abs() < 1e-12);
    }

    #[test]
    fn white_spectrum_is_white_and_cmfs_peak_where_cie_says() {
        let w = spectrum_to_rgb(|_| 1.0);
        for c in w {
            assert!((c - 1.0).abs() < 1e-12);
        }
        // CIE 1931 ȳ peaks at 555 nm with value 1.0 (the fit is within a few percent).
        let y555 = cie_xyz(555.0)[1];
        assert!((y555 - 1.0).abs() < 0.03, "{y555}");
    }
}
