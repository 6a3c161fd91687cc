//! Binning scattered measurements `(wi, wo, value)` into a table, as the thesis does with the
//! BRDF samples of its camera images (section 4.3): every valid sample falls into one bin, a
//! bin's value is the mean of its samples, and bins without a sample stay without a
//! measurement (negative). Samples below the horizon or with a non-finite or negative value
//! are rejected and counted.

use super::merl::{self, MerlTable};
use super::parameterization::{to_half_diff, to_standard, wrap, HALF_PI};
use super::standard::{self, StandardTable};
use crate::math::Vec3;
use serde::Serialize;
use std::f64::consts::PI;

/// What binning did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BinStats {
    /// Samples offered.
    pub samples: usize,
    /// Samples binned.
    pub binned: usize,
    /// Samples rejected (below the horizon, zero-length or non-finite direction, non-finite
    /// or negative value).
    pub rejected: usize,
    /// Bins that received at least one sample.
    pub filled_bins: usize,
    /// Bins of the table.
    pub total_bins: usize,
}

fn usable(wi: Vec3<f64>, wo: Vec3<f64>, v: &[f64; 3]) -> Option<(Vec3<f64>, Vec3<f64>)> {
    let unit = |w: Vec3<f64>| {
        let l = w.length();
        (l.is_finite() && l > 0.0).then(|| w / l)
    };
    let (wi, wo) = (unit(wi)?, unit(wo)?);
    (wi.z > 0.0 && wo.z > 0.0 && v.iter().all(|x| x.is_finite() && *x >= 0.0)).then_some((wi, wo))
}

struct Accumulator {
    sum: Vec<[f64; 3]>,
    count: Vec<u32>,
    stats: BinStats,
}

impl Accumulator {
    fn new(n: usize) -> Self {
        Self { sum: vec![[0.0; 3]; n], count: vec![0; n], stats: BinStats { total_bins: n, ..BinStats::default() } }
    }
    fn add(&mut self, bin: Option<usize>, v: [f64; 3]) {
        match bin {
            Some(b) => {
                for (acc, x) in self.sum[b].iter_mut().zip(v) {
                    *acc += x;
                }
                self.count[b] += 1;
                self.stats.binned += 1;
            }
            None => self.stats.rejected += 1,
        }
    }
    fn finish(mut self, mut set: impl FnMut(usize, [f64; 3])) -> BinStats {
        for (b, (s, n)) in self.sum.iter().zip(&self.count).enumerate() {
            if *n > 0 {
                set(b, s.map(|x| x / f64::from(*n)));
                self.stats.filled_bins += 1;
            }
        }
        self.stats
    }
}

/// The MERL node nearest to a direction pair (rounding each continuous index; `φd` folded
/// by π, so a pair and its swap share a node).
#[must_use]
pub fn merl_node(wi: Vec3<f64>, wo: Vec3<f64>) -> usize {
    let hd = to_half_diff(wi, wo);
    let a = (hd.theta_h.max(0.0) / HALF_PI).sqrt() * merl::N_THETA_H as f64;
    let b = hd.theta_d.max(0.0) / HALF_PI * merl::N_THETA_D as f64;
    let c = wrap(hd.phi_d, PI) / PI * merl::N_PHI_D as f64;
    let ih = (a.round() as usize).min(merl::N_THETA_H - 1);
    let id = (b.round() as usize).min(merl::N_THETA_D - 1);
    let ip = (c.round() as usize) % merl::N_PHI_D;
    merl::index(ih, id, ip)
}

/// Bins samples into a MERL table: each sample goes to its nearest node.
pub fn bin_merl(samples: impl IntoIterator<Item = (Vec3<f64>, Vec3<f64>, [f64; 3])>) -> (MerlTable, BinStats) {
    let mut acc = Accumulator::new(merl::N_ENTRIES);
    for (wi, wo, v) in samples {
        acc.stats.samples += 1;
        let bin = usable(wi, wo, &v).map(|(wi, wo)| merl_node(wi, wo));
        acc.add(bin, v);
    }
    let mut t = MerlTable::empty();
    let stats = acc.finish(|b, v| t.set(b, v));
    (t, stats)
}

/// Bins samples into a standard table (one-degree bins). With `reciprocal`, each sample also
/// counts for the swapped pair `(wo, wi)` (the BRDF is assumed reciprocal).
pub fn bin_standard(
    samples: impl IntoIterator<Item = (Vec3<f64>, Vec3<f64>, [f64; 3])>,
    reciprocal: bool,
) -> (StandardTable, BinStats) {
    let mut acc = Accumulator::new(standard::N_ENTRIES);
    for (wi, wo, v) in samples {
        acc.stats.samples += 1;
        match usable(wi, wo, &v) {
            Some((wi, wo)) => {
                acc.add(standard::bin_of(&to_standard(wi, wo)), v);
                if reciprocal {
                    let b = standard::bin_of(&to_standard(wo, wi));
                    if let Some(b) = b {
                        for (a, x) in acc.sum[b].iter_mut().zip(v) {
                            *a += x;
                        }
                        acc.count[b] += 1;
                    }
                }
            }
            None => acc.add(None, v),
        }
    }
    let mut t = StandardTable::empty();
    let stats = acc.finish(|b, v| t.set(b, v));
    (t, stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measured::parameterization::spherical;
    use crate::rng::Pcg32;

    fn random_pairs(n: usize, seed: u64) -> Vec<(Vec3<f64>, Vec3<f64>)> {
        let mut rng = Pcg32::new(seed, 1);
        (0..n)
            .map(|_| {
                let wi = spherical(rng.uniform().acos(), 2.0 * PI * rng.uniform());
                let wo = spherical(rng.uniform().acos(), 2.0 * PI * rng.uniform());
                (wi, wo)
            })
            .collect()
    }

    #[test]
    fn constant_brdf_bins_to_its_value_and_bad_samples_are_counted() {
        let mut samples: Vec<_> = random_pairs(200_000, 3).into_iter().map(|(a, b)| (a, b, [0.3, 0.2, 0.1])).collect();
        samples.push((Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), [1.0; 3]));
        samples.push((Vec3::new(f64::NAN, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0), [1.0; 3]));
        samples.push((Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0), [f64::INFINITY; 3]));
        let (t, stats) = bin_merl(samples.clone());
        assert_eq!(stats.samples, 200_003);
        assert_eq!(stats.rejected, 3);
        assert_eq!(stats.binned, 200_000);
        assert!(stats.filled_bins > 10_000 && stats.filled_bins <= stats.total_bins);
        for i in 0..merl::N_ENTRIES {
            if t.is_valid(i) {
                let v = t.get(i);
                assert!((0..3).all(|c| (v[c] - [0.3, 0.2, 0.1][c]).abs() < 1e-15), "{v:?}");
            }
        }
        let (s, stats) = bin_standard(samples, true);
        assert_eq!(stats.rejected, 3);
        assert!(stats.filled_bins > 100_000);
        for i in (0..standard::N_ENTRIES).step_by(13) {
            if s.is_valid(i) {
                let v = s.get(i);
                assert!((v[0] - 0.3).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn binned_smooth_brdf_matches_the_generated_table() {
        // A smooth BRDF measured at random pairs, binned to nearest nodes: the binned table
        // agrees with the table generated at the nodes to within the variation inside a bin.
        let f = |wi: Vec3<f64>, wo: Vec3<f64>| {
            let hd = to_half_diff(wi, wo);
            [0.1 + (-hd.theta_h * hd.theta_h / 0.3).exp(), 0.2, 0.2]
        };
        let pairs = random_pairs(400_000, 5);
        let (binned, _) = bin_merl(pairs.iter().map(|&(a, b)| (a, b, f(a, b))));
        let exact = MerlTable::from_fn(|a, b| Some(f(a, b)));
        let (mut n, mut err) = (0usize, 0.0f64);
        for i in 0..merl::N_ENTRIES {
            if binned.is_valid(i) && exact.is_valid(i) {
                n += 1;
                err = err.max((binned.get(i)[0] - exact.get(i)[0]).abs() / exact.get(i)[0]);
            }
        }
        assert!(n > 20_000);
        assert!(err < 0.05, "worst binned-vs-node error {err}");
        // The same pair and its swap fall in the same MERL node.
        for &(a, b) in pairs.iter().take(1000) {
            assert_eq!(merl_node(a, b), merl_node(b, a));
        }
    }
}
