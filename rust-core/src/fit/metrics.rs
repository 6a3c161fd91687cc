//! Fit data (the valid entries of a table as direction pairs with their weights) and the
//! goodness-of-fit figures reported for a fit.
//!
//! - **Thesis error** (section 4.4.2): `E(p) = sqrt(Σ [(M − K(p)) cos θv]²)` over the table's
//!   entries and channels, `M` measured, `K` the model, `θv` the viewing (outgoing) angle.
//!   A MERL entry stands for an unordered pair (the table is reciprocal), so there the weight
//!   is the geometric mean of the two orderings' weights, `w = sqrt(cos θi cos θo)` —
//!   symmetric, and it keeps the residuals of models whose BRDF grows without bound at
//!   grazing angles (Ward's `1/sqrt(cos θi cos θo)`) bounded; a standard-table entry is
//!   ordered and uses `w = cos θout` as in the thesis. `rms_cos` is `E / sqrt(3N)`.
//! - **What the fit minimises** ([`super::Objective`]): by default the same squared error with
//!   every entry also weighted by the solid-angle measure of its table cell, so the sum is a
//!   quadrature of `∫∫ [(M − K) w]² dωi dωo` and does not depend on where the table puts its
//!   nodes (MERL puts 15 % of them within 2° of the specular direction); `entries` minimises
//!   the thesis' plain sum over entries instead.
//! - **SNR** (thesis, section 4.4.3): per channel `10 log10(VAR/MSE)`, `MSE = mean (m − s)²`,
//!   `VAR = mean (m − m̄)²` over the table's valid entries (unweighted BRDF values).
//!   `snr_weighted_db` is the same ratio for the quantities the default fit compares: values
//!   `M·w`, `K·w`, means weighted by the cell measure.
//! - **Ngan et al. 2005** ("Experimental Analysis of BRDF Models", EGSR): the cosine-weighted
//!   L2 error integrated over the domain, `sqrt(∫ [(M − K) cos θi]² dωi dωo / ∫ dωi dωo)`, each
//!   entry weighted by the solid-angle measure of its cell, entries with `θi` or `θo` beyond
//!   80° left out (as in the paper, where grazing measurements are unreliable). For MERL
//!   entries `cos θi` is replaced by the symmetric `w` above. The measure of a Rusinkiewicz
//!   cell is `dωi dωo = 4 cos θd sin θh sin θd dθh dφh dθd dφd`, integrated over the cell.

use crate::math::Vec3;
use crate::measured::merl::{self, MerlTable};
use crate::measured::parameterization::HALF_PI;
use crate::measured::standard::{self, StandardTable};
use serde::Serialize;

/// One table entry as a fit target.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Incident direction.
    pub wi: Vec3<f64>,
    /// Outgoing direction.
    pub wo: Vec3<f64>,
    /// Measured RGB BRDF (1/sr).
    pub value: [f64; 3],
    /// Thesis weight (`cos θv`; `sqrt(cos θi cos θo)` for MERL entries).
    pub weight: f64,
    /// Solid-angle measure of the entry's cell (`∫ dωi dωo`, up to a constant factor).
    pub measure: f64,
    /// Either direction is beyond 80° from the normal (left out of Ngan's figure).
    pub grazing: bool,
}

/// The valid entries of a table.
#[derive(Clone, Debug, Default)]
pub struct FitData {
    /// Entries with a measurement in every channel and both directions above the surface.
    pub samples: Vec<Sample>,
}

const GRAZING_LIMIT: f64 = 80.0 * std::f64::consts::PI / 180.0;

fn cos_of_limit() -> f64 {
    GRAZING_LIMIT.cos()
}

/// `∫ 4 cos θd sin θh sin θd dθh dθd` over the cell of MERL node `(θh index, θd index)` (cell
/// edges halfway between nodes in the index coordinates; per unit of `φh` and `φd`).
#[must_use]
pub fn merl_cell_measure(ih: usize, id: usize) -> f64 {
    let theta_h = |a: f64| (a.clamp(0.0, merl::N_THETA_H as f64) / merl::N_THETA_H as f64).powi(2) * HALF_PI;
    // The last nodes' cells reach π/2 (lookups beyond them hold the last node's value).
    let top = |i: usize, n: usize| if i + 1 == n { n as f64 } else { i as f64 + 0.5 };
    let (h0, h1) = (theta_h(ih as f64 - 0.5), theta_h(top(ih, merl::N_THETA_H)));
    let step = HALF_PI / merl::N_THETA_D as f64;
    let d0 = ((id as f64 - 0.5) * step).clamp(0.0, HALF_PI);
    let d1 = (top(id, merl::N_THETA_D) * step).clamp(0.0, HALF_PI);
    4.0 * (h0.cos() - h1.cos()) * 0.5 * (d1.sin().powi(2) - d0.sin().powi(2))
}

/// Rotates a pair about the normal by an azimuth that differs from entry to entry (a golden-
/// ratio sequence over the entry index). An isotropic table holds one pair per entry; spreading
/// their azimuths lets an anisotropic model see every orientation (at `φh = 0` only, Ward's
/// `ρs/(αx αy)` and `αy` could not be told apart), and changes nothing for isotropic models.
#[must_use]
pub fn spread_azimuth(wi: Vec3<f64>, wo: Vec3<f64>, entry: usize) -> (Vec3<f64>, Vec3<f64>) {
    const GOLDEN: f64 = 0.618_033_988_749_894_9;
    let phi = 2.0 * std::f64::consts::PI * (entry as f64 * GOLDEN).fract();
    let (s, c) = phi.sin_cos();
    let rot = |w: Vec3<f64>| Vec3::new(c * w.x - s * w.y, s * w.x + c * w.y, w.z);
    (rot(wi), rot(wo))
}

fn spread_azimuth_pair(p: (Vec3<f64>, Vec3<f64>), entry: usize) -> (Vec3<f64>, Vec3<f64>) {
    spread_azimuth(p.0, p.1, entry)
}

impl FitData {
    /// The valid entries of a MERL table.
    #[must_use]
    pub fn from_merl(t: &MerlTable) -> Self {
        let rows = crate::measured::parallel_rows(merl::N_THETA_H, |ih| {
            let mut out = Vec::new();
            for id in 0..merl::N_THETA_D {
                let cell = merl_cell_measure(ih, id);
                for ip in 0..merl::N_PHI_D {
                    let idx = merl::index(ih, id, ip);
                    if !t.is_valid(idx) {
                        continue;
                    }
                    let Some((wi, wo)) = MerlTable::node_directions(ih, id, ip) else { continue };
                    let (wi, wo) = spread_azimuth(wi, wo, idx);
                    let weight = (wi.z * wo.z).sqrt();
                    let grazing = wi.z < cos_of_limit() || wo.z < cos_of_limit();
                    out.push(Sample { wi, wo, value: t.get(idx), weight, measure: cell, grazing });
                }
            }
            out
        });
        Self { samples: rows.into_iter().flatten().collect() }
    }

    /// The valid entries of a standard table.
    #[must_use]
    pub fn from_standard(t: &StandardTable) -> Self {
        let step = HALF_PI / standard::N_THETA as f64;
        let band = |i: usize| (i as f64 * step).cos() - ((i + 1) as f64 * step).cos();
        let rows = crate::measured::parallel_rows(standard::N_THETA, |i| {
            let mut out = Vec::new();
            for o in 0..standard::N_THETA {
                for k in 0..standard::N_PHI {
                    let idx = standard::index(i, o, k);
                    if !t.is_valid(idx) {
                        continue;
                    }
                    let (wi, wo) = spread_azimuth_pair(StandardTable::bin_directions(i, o, k), idx);
                    let grazing = wi.z < cos_of_limit() || wo.z < cos_of_limit();
                    let measure = band(i) * band(o);
                    out.push(Sample { wi, wo, value: t.get(idx), weight: wo.z, measure, grazing });
                }
            }
            out
        });
        Self { samples: rows.into_iter().flatten().collect() }
    }

    /// Keeps the entries whose directions are both within `max_theta` (radians) of the
    /// normal: grazing measurements are the least reliable (Ngan et al. leave out beyond 80°),
    /// and models that grow without bound at grazing angles dominate any sum that keeps them.
    #[must_use]
    pub fn within(mut self, max_theta: f64) -> Self {
        let c = max_theta.cos();
        self.samples.retain(|s| s.wi.z >= c && s.wo.z >= c);
        self
    }

    /// Number of entries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when there is no entry.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

/// Goodness of fit of a model against a table.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    /// Entries compared.
    pub entries: usize,
    /// Thesis SNR per channel (dB).
    pub snr_db: [f64; 3],
    /// Mean of the three channels' SNR (dB).
    pub snr_db_mean: f64,
    /// The SNR of the quantities the default fit compares: `M·w` against `K·w`, means
    /// weighted by the cell measure (dB, mean of the channels).
    pub snr_weighted_db: f64,
    /// Plain RMS error per channel (1/sr).
    pub rms: [f64; 3],
    /// Thesis error `E(p) = sqrt(Σ [(M − K) cos θv]²)` (1/sr).
    pub thesis_error: f64,
    /// `E(p) / sqrt(3N)`: the cos-weighted RMS error (1/sr).
    pub rms_cos: f64,
    /// Ngan et al. 2005 error (1/sr).
    pub ngan: f64,
}

/// Sums a chunk needs for the metrics.
#[derive(Clone, Copy, Default)]
pub(crate) struct Sums {
    n: usize,
    m: [f64; 3],
    mm: [f64; 3],
    err2: [f64; 3],
    cos_err2: f64,
    mu: f64,
    mu_mw: [f64; 3],
    mu_mw2: [f64; 3],
    mu_err2: [f64; 3],
    ngan_num: f64,
    ngan_den: f64,
}

impl Sums {
    pub(crate) fn add(&mut self, s: &Sample, k: [f64; 3]) {
        self.n += 1;
        self.mu += s.measure;
        for (c, kc) in k.iter().enumerate() {
            let m = s.value[c];
            let e = m - kc;
            let ew2 = (e * s.weight).powi(2);
            self.m[c] += m;
            self.mm[c] += m * m;
            self.err2[c] += e * e;
            self.cos_err2 += ew2;
            self.mu_mw[c] += s.measure * m * s.weight;
            self.mu_mw2[c] += s.measure * (m * s.weight).powi(2);
            self.mu_err2[c] += s.measure * ew2;
            if !s.grazing {
                self.ngan_num += s.measure * ew2;
            }
        }
        if !s.grazing {
            self.ngan_den += 3.0 * s.measure;
        }
    }

    pub(crate) fn merge(mut self, o: &Sums) -> Sums {
        self.n += o.n;
        self.mu += o.mu;
        for c in 0..3 {
            self.m[c] += o.m[c];
            self.mm[c] += o.mm[c];
            self.err2[c] += o.err2[c];
            self.mu_mw[c] += o.mu_mw[c];
            self.mu_mw2[c] += o.mu_mw2[c];
            self.mu_err2[c] += o.mu_err2[c];
        }
        self.cos_err2 += o.cos_err2;
        self.ngan_num += o.ngan_num;
        self.ngan_den += o.ngan_den;
        self
    }

    pub(crate) fn metrics(&self) -> Metrics {
        let n = self.n.max(1) as f64;
        let mu = if self.mu > 0.0 { self.mu } else { 1.0 };
        let mut snr = [0.0; 3];
        let mut rms = [0.0; 3];
        let mut snr_w = 0.0;
        for c in 0..3 {
            let mean = self.m[c] / n;
            let var = (self.mm[c] / n - mean * mean).max(0.0);
            let mse = self.err2[c] / n;
            rms[c] = mse.sqrt();
            snr[c] = snr_db(var, mse);
            let mean_w = self.mu_mw[c] / mu;
            let var_w = (self.mu_mw2[c] / mu - mean_w * mean_w).max(0.0);
            snr_w += snr_db(var_w, self.mu_err2[c] / mu) / 3.0;
        }
        Metrics {
            entries: self.n,
            snr_db: snr,
            snr_db_mean: (snr[0] + snr[1] + snr[2]) / 3.0,
            snr_weighted_db: snr_w,
            rms,
            thesis_error: self.cos_err2.sqrt(),
            rms_cos: (self.cos_err2 / (3.0 * n)).sqrt(),
            ngan: if self.ngan_den > 0.0 { (self.ngan_num / self.ngan_den).sqrt() } else { 0.0 },
        }
    }
}

/// `10 log10(VAR/MSE)`, capped at 200 dB for an exact fit (and 0 dB for a constant signal
/// that is matched exactly).
#[must_use]
pub fn snr_db(var: f64, mse: f64) -> f64 {
    if mse <= 0.0 {
        return if var > 0.0 { 200.0 } else { 0.0 };
    }
    if var <= 0.0 {
        return -200.0;
    }
    (10.0 * (var / mse).log10()).clamp(-200.0, 200.0)
}

/// Metrics of predictions `k(sample)` over all samples, on all cores.
pub fn evaluate(data: &FitData, k: impl Fn(&Sample) -> [f64; 3] + Sync) -> Metrics {
    let chunk = 8192;
    let n_chunks = data.samples.len().div_ceil(chunk);
    let parts = crate::measured::parallel_rows(n_chunks, |c| {
        let mut s = Sums::default();
        for smp in &data.samples[c * chunk..((c + 1) * chunk).min(data.samples.len())] {
            s.add(smp, k(smp));
        }
        s
    });
    parts.iter().fold(Sums::default(), |a, b| a.merge(b)).metrics()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snr_by_hand() {
        // Signal 1, 3 (mean 2, VAR 1); prediction off by 0.1 everywhere (MSE 0.01): 20 dB.
        assert!((snr_db(1.0, 0.01) - 20.0).abs() < 1e-12);
        assert_eq!(snr_db(1.0, 0.0), 200.0);
    }

    #[test]
    fn cell_measures_sum_to_the_domain() {
        // Σ over all (θh, θd) cells of 4 ∫sin θh ∫cos θd sin θd = 4 · 1 · ½ = 2 (the last θh
        // cell is cut at π/2).
        let total: f64 =
            (0..merl::N_THETA_H).flat_map(|i| (0..merl::N_THETA_D).map(move |j| merl_cell_measure(i, j))).sum();
        assert!((total - 2.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn metrics_of_exact_and_offset_predictions() {
        let full = MerlTable::from_fn(|_, _| Some([1.0, 2.0, 3.0]));
        let d = FitData::from_merl(&full);
        assert!(d.samples.iter().all(|s| s.grazing == (s.wi.z < cos_of_limit() || s.wo.z < cos_of_limit())));
        let m = evaluate(&d, |s| s.value);
        assert_eq!(m.rms, [0.0; 3]);
        assert_eq!(m.ngan, 0.0);
        // A constant offset of 0.1: RMS 0.1 per channel; the cos-weighted errors are 0.1 × a
        // weighted mean of cosines, so strictly between 0 and 0.1.
        let m = evaluate(&d, |s| s.value.map(|v| v + 0.1));
        assert!((m.rms[0] - 0.1).abs() < 1e-12 && (m.rms[2] - 0.1).abs() < 1e-12);
        assert!(m.ngan > 0.0 && m.ngan < 0.1 && m.rms_cos > 0.0 && m.rms_cos < 0.1);
        assert!((m.thesis_error - m.rms_cos * (3.0 * d.len() as f64).sqrt()).abs() < 1e-9);
    }
}
