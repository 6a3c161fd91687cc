//! Tables in the standard parameterisation `(θin, θout, φdiff)`, 90 × 90 × 180 bins of one
//! degree, as the thesis stores its camera measurements (section 4.3).
//!
//! Bin `(i, o, k)` covers `θin ∈ [i°, i+1°)`, `θout ∈ [o°, o+1°)`, `φdiff ∈ [k°, k+1°)` and
//! its value is read as the BRDF at the bin centre; lookups interpolate linearly between
//! centres (clamped at the edges, which for `φdiff` is the mirror-symmetric extension).

use super::merl::MerlTable;
use super::parameterization::{from_standard, to_standard, StandardAngles, HALF_PI};
use crate::math::Vec3;
use std::f64::consts::PI;

/// Bins in `θin` and in `θout`.
pub const N_THETA: usize = 90;
/// Bins in `φdiff` over `[0, π]`.
pub const N_PHI: usize = 180;
/// Entries per channel.
pub const N_ENTRIES: usize = N_THETA * N_THETA * N_PHI;

/// Flat index of bin `(θin, θout, φdiff)`.
#[inline]
#[must_use]
pub const fn index(i: usize, o: usize, k: usize) -> usize {
    k + N_PHI * (o + N_THETA * i)
}

/// Centre of polar bin `i`.
#[inline]
#[must_use]
pub fn theta_centre(i: usize) -> f64 {
    (i as f64 + 0.5) / N_THETA as f64 * HALF_PI
}

/// Centre of azimuth bin `k`.
#[inline]
#[must_use]
pub fn phi_centre(k: usize) -> f64 {
    (k as f64 + 0.5) / N_PHI as f64 * PI
}

/// Bin of standard angles (`None` outside the hemisphere).
#[inline]
#[must_use]
pub fn bin_of(s: &StandardAngles) -> Option<usize> {
    let t = |x: f64| (0.0..HALF_PI).contains(&x).then(|| ((x / HALF_PI * N_THETA as f64) as usize).min(N_THETA - 1));
    let k = ((s.phi_diff.clamp(0.0, PI) / PI * N_PHI as f64) as usize).min(N_PHI - 1);
    Some(index(t(s.theta_in)?, t(s.theta_out)?, k))
}

/// An isotropic BRDF table in the standard parameterisation (values in 1/sr, negative = no
/// measurement).
#[derive(Clone, PartialEq)]
pub struct StandardTable {
    values: Vec<f64>,
}

impl std::fmt::Debug for StandardTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let valid = (0..N_ENTRIES).filter(|&i| self.is_valid(i)).count();
        write!(f, "StandardTable {{ 90×90×180, {:.1}% valid }}", 100.0 * valid as f64 / N_ENTRIES as f64)
    }
}

impl StandardTable {
    /// A table with no measurement anywhere.
    #[must_use]
    pub fn empty() -> Self {
        Self { values: vec![-1.0; 3 * N_ENTRIES] }
    }

    /// The direction pair at the centre of bin `(i, o, k)` (`wo` at azimuth 0).
    #[must_use]
    pub fn bin_directions(i: usize, o: usize, k: usize) -> (Vec3<f64>, Vec3<f64>) {
        from_standard(&StandardAngles {
            theta_in: theta_centre(i),
            theta_out: theta_centre(o),
            phi_diff: phi_centre(k),
        })
    }

    /// Tabulates `f(wi, wo)` at every bin centre, on all cores.
    #[must_use]
    pub fn from_fn(f: impl Fn(Vec3<f64>, Vec3<f64>) -> Option<[f64; 3]> + Sync) -> Self {
        let rows = super::parallel_rows(N_THETA, |i| {
            let mut row = vec![[-1.0; 3]; N_THETA * N_PHI];
            for o in 0..N_THETA {
                for k in 0..N_PHI {
                    let (wi, wo) = Self::bin_directions(i, o, k);
                    if let Some(v) = f(wi, wo) {
                        if v.iter().all(|x| x.is_finite() && *x >= 0.0) {
                            row[k + N_PHI * o] = v;
                        }
                    }
                }
            }
            row
        });
        let mut t = Self::empty();
        for (i, row) in rows.iter().enumerate() {
            for (r, v) in row.iter().enumerate() {
                t.set(i * N_THETA * N_PHI + r, *v);
            }
        }
        t
    }

    /// Resamples a MERL table at the bin centres (its interpolation).
    #[must_use]
    pub fn from_merl(t: &MerlTable) -> Self {
        Self::from_fn(|wi, wo| Some(t.eval(wi, wo)))
    }

    /// Resamples this table at the nodes of a MERL table (entries below the horizon stay
    /// without a measurement).
    #[must_use]
    pub fn to_merl(&self) -> MerlTable {
        MerlTable::from_fn(|wi, wo| Some(self.eval(wi, wo)))
    }

    /// RGB value of entry `idx`.
    #[inline]
    #[must_use]
    pub fn get(&self, idx: usize) -> [f64; 3] {
        [self.values[idx], self.values[idx + N_ENTRIES], self.values[idx + 2 * N_ENTRIES]]
    }

    /// Sets entry `idx`.
    #[inline]
    pub fn set(&mut self, idx: usize, v: [f64; 3]) {
        for (c, x) in v.iter().enumerate() {
            self.values[idx + c * N_ENTRIES] = *x;
        }
    }

    /// True when every channel of entry `idx` holds a measurement.
    #[inline]
    #[must_use]
    pub fn is_valid(&self, idx: usize) -> bool {
        (0..3).all(|c| self.values[idx + c * N_ENTRIES] >= 0.0)
    }

    /// Trilinear interpolation between bin centres (clamped at the edges), skipping missing
    /// entries per channel; 0 where no neighbour holds a measurement.
    #[must_use]
    pub fn interpolate(&self, s: &StandardAngles) -> [f64; 3] {
        let coord = |x: f64, range: f64, n: usize| {
            let u = (x / range * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
            let i = (u as usize).min(n - 2);
            (i, u - i as f64)
        };
        let (i, ti) = coord(s.theta_in, HALF_PI, N_THETA);
        let (o, to) = coord(s.theta_out, HALF_PI, N_THETA);
        let (k, tk) = coord(s.phi_diff, PI, N_PHI);
        let mut sum = [0.0; 3];
        let mut wsum = [0.0; 3];
        for (a, wa) in [(i, 1.0 - ti), (i + 1, ti)] {
            for (b, wb) in [(o, 1.0 - to), (o + 1, to)] {
                for (c, wc) in [(k, 1.0 - tk), (k + 1, tk)] {
                    let w = wa * wb * wc;
                    if w <= 0.0 {
                        continue;
                    }
                    let v = self.get(index(a, b, c));
                    for ch in 0..3 {
                        if v[ch] >= 0.0 {
                            sum[ch] += w * v[ch];
                            wsum[ch] += w;
                        }
                    }
                }
            }
        }
        [0, 1, 2].map(|ch| if wsum[ch] > 0.0 { sum[ch] / wsum[ch] } else { 0.0 })
    }

    /// The interpolated BRDF of a direction pair.
    #[inline]
    #[must_use]
    pub fn eval(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> [f64; 3] {
        self.interpolate(&to_standard(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measured::parameterization::{spherical, to_half_diff};

    fn smooth(wi: Vec3<f64>, wo: Vec3<f64>) -> Option<[f64; 3]> {
        let hd = to_half_diff(wi, wo);
        Some([0.2 + (-hd.theta_h * hd.theta_h / 0.2).exp(), 0.3, 0.1 + 0.1 * wi.z * wo.z])
    }

    #[test]
    fn exact_at_centres_and_bins_agree() {
        let t = StandardTable::from_fn(smooth);
        for (i, o, k) in [(0, 0, 0), (10, 50, 179), (89, 3, 90)] {
            let (wi, wo) = StandardTable::bin_directions(i, o, k);
            let want = smooth(wi, wo).unwrap();
            let got = t.eval(wi, wo);
            assert!((0..3).all(|c| (got[c] - want[c]).abs() < 1e-12), "{got:?} {want:?}");
            assert_eq!(bin_of(&to_standard(wi, wo)), Some(index(i, o, k)));
        }
    }

    #[test]
    fn merl_and_standard_conversions_agree() {
        let merl = MerlTable::from_fn(smooth);
        let std_t = StandardTable::from_merl(&merl);
        let back = std_t.to_merl();
        let mut worst = 0.0f64;
        for (th, td, pd) in [(0.1, 0.4, 0.3), (0.5, 0.2, 2.0), (0.02, 0.9, 1.0), (0.3, 0.3, 3.0)] {
            let (wi, wo) = super::super::parameterization::from_half_diff(&super::super::parameterization::HalfDiff {
                theta_h: th,
                phi_h: 0.7,
                theta_d: td,
                phi_d: pd,
            });
            let want = smooth(wi, wo).unwrap();
            for got in [merl.eval(wi, wo), std_t.eval(wi, wo), back.eval(wi, wo)] {
                worst = worst.max((got[0] - want[0]).abs() / want[0]);
            }
        }
        assert!(worst < 0.01, "{worst}");
        // Directions in different frames but with the same standard angles read the same value.
        let a = std_t.eval(spherical(0.4, 1.0), spherical(0.7, 2.5));
        let b = std_t.eval(spherical(0.4, -1.5), spherical(0.7, 0.0));
        assert!((a[0] - b[0]).abs() < 1e-12);
    }
}
