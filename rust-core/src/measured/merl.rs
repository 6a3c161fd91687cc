//! MERL BRDF tables (Matusik, Pfister, Brand and McMillan 2003, "A Data-Driven Reflectance
//! Model"): the binary format, node angles, the reference reader's nearest-bin lookup and a
//! trilinear interpolation.
//!
//! ## Format (little-endian)
//! - Header: three `int32` — the table dimensions, always `90 90 180` (θh, θd, φd).
//! - Body: three planes (red, green, blue) of `90·90·180` `f64` each; the entry of node
//!   `(i, j, k)` sits at `k + 180·(j + 90·i)` within its plane.
//! - A stored value times the channel scale (`1/1500`, `1.15/1500`, `1.66/1500`) is the BRDF
//!   in 1/sr. Negative values mark entries without a measurement (e.g. below the horizon).
//!
//! ## Nodes
//! - `θh(i) = (i/90)² · π/2` (denser near the specular peak), `θd(j) = j/90 · π/2`,
//!   `φd(k) = k/180 · π`. A table stores `φd ∈ [0, π)` only: swapping `wi` and `wo` shifts
//!   `φd` by π, so every table is reciprocal by construction.
//! - The MERL reference reader looks a direction pair up by flooring each continuous index
//!   ([`MerlTable::lookup_nearest`]). We read entry `(i, j, k)` as the BRDF *at* the node
//!   angles and interpolate linearly between nodes (in `√θh`, `θd` and periodic `φd`,
//!   [`MerlTable::interpolate`]); [`MerlTable::from_fn`] writes the BRDF at the node angles,
//!   so a generated table is reproduced exactly at its nodes. Entries without a measurement
//!   are left out of the interpolation (the weights of the valid corners are renormalised).

use super::parameterization::{from_half_diff, to_half_diff, wrap, HalfDiff, HALF_PI};
use crate::math::Vec3;
use std::f64::consts::PI;
use std::fmt;
use std::io::Read;
use std::path::Path;

/// Nodes in `θh`.
pub const N_THETA_H: usize = 90;
/// Nodes in `θd`.
pub const N_THETA_D: usize = 90;
/// Nodes in `φd` (over `[0, π)`).
pub const N_PHI_D: usize = 180;
/// Entries per channel.
pub const N_ENTRIES: usize = N_THETA_H * N_THETA_D * N_PHI_D;
/// Stored value × scale = BRDF (1/sr), per channel (red, green, blue).
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// `cos θ` at or below which a node direction counts as at the horizon.
pub const HORIZON: f64 = 1e-6;
/// Size of a MERL file in bytes.
pub const FILE_BYTES: usize = 12 + 3 * N_ENTRIES * 8;
/// The largest BRDF value (1/sr, after the channel scale) a table entry may hold; a file with a
/// larger finite value is rejected ([`TableError::OutOfRange`]), and [`MerlTable::from_fn`] and
/// [`MerlTable::set`] store one as "no measurement".
///
/// Why 1e10: a passive surface reflects at most what arrives, `∫ f cos θi dωi ≤ 1`. The table
/// cannot resolve a lobe narrower than its first `θh` cell, `θh ≤ θh(1) = (1/90)²·π/2 =
/// 1.94e-4 rad`; tilting the half vector by `θh` moves `wi` by `2θh` in the plane of incidence
/// and by `2θh cos θd` across it, so that cell covers `Ω ≈ π (2θh(1))² cos θd = 4.7e-7 cos θd`
/// sr around the mirror direction, where `cos θi = cos θd`. A value above
/// `1 / (Ω cos θi) = 2.1e6 / cos² θd` would reflect more than all incident light from that cone
/// alone; at the most grazing node above the horizon (`θd(89) = 89°`, `cos θd = 0.0175`) that is
/// 6.9e9 1/sr, rounded up to 1e10. For comparison, tables sampled from Mitsuba's rough
/// plastic and rough conductor at the nodes (`tests/test_fit_mitsuba.py`) peak at 1039 and
/// 495 1/sr, and the sharpest rough conductor Lacquer builds (α = 0.001) tabulated here at
/// 2.6e8 (a test keeps it accepted). The bound is 28 orders of magnitude below `f32::MAX`, so
/// no accepted entry, nor a sum of eight interpolated ones, overflows the f32 `eval`.
pub const MAX_BRDF: f64 = 1e10;

/// Why a table file was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum TableError {
    /// The file could not be read.
    Io(String),
    /// The header is not `90 90 180`.
    Header(String),
    /// The file size does not match what the header claims.
    Size(String),
    /// A value is NaN or infinite.
    NotFinite(String),
    /// A finite value above [`MAX_BRDF`] after scaling (e.g. a flipped exponent byte).
    OutOfRange(String),
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::Io(m) => write!(f, "cannot read the table: {m}"),
            TableError::Header(m) => write!(f, "not a MERL table: {m}"),
            TableError::Size(m) => write!(f, "MERL table has the wrong size: {m}"),
            TableError::NotFinite(m) => write!(f, "MERL table holds a non-finite value: {m}"),
            TableError::OutOfRange(m) => write!(f, "MERL table holds a value no reflectance can have: {m}"),
        }
    }
}

impl std::error::Error for TableError {}

/// Checks a 12-byte header and returns the body size it implies.
fn body_bytes(header: &[u8]) -> Result<usize, TableError> {
    if header.len() < 12 {
        return Err(TableError::Size(format!(
            "{} bytes, shorter than the 12-byte header (three int32: 90 90 180)",
            header.len()
        )));
    }
    let dims: Vec<i32> =
        (0..3).map(|i| i32::from_le_bytes(header[4 * i..4 * i + 4].try_into().expect("4 bytes"))).collect();
    if dims != [N_THETA_H as i32, N_THETA_D as i32, N_PHI_D as i32] {
        return Err(TableError::Header(format!(
            "header says {} × {} × {}; a MERL table is 90 × 90 × 180 (θh, θd, φd)",
            dims[0], dims[1], dims[2]
        )));
    }
    Ok(3 * N_ENTRIES * 8)
}

/// An isotropic BRDF table in the MERL layout, values in 1/sr (negative = no measurement).
#[derive(Clone, PartialEq)]
pub struct MerlTable {
    /// Three planes (r, g, b) of [`N_ENTRIES`] values.
    values: Vec<f64>,
}

impl fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MerlTable {{ 90×90×180, {:.1}% valid }}", 100.0 * self.valid_fraction())
    }
}

/// Flat index of node `(θh index, θd index, φd index)` within a channel plane.
#[inline]
#[must_use]
pub const fn index(ih: usize, id: usize, ip: usize) -> usize {
    ip + N_PHI_D * (id + N_THETA_D * ih)
}

/// `θh` of node `i`.
#[inline]
#[must_use]
pub fn theta_h_node(i: usize) -> f64 {
    let u = i as f64 / N_THETA_H as f64;
    u * u * HALF_PI
}

/// `θd` of node `j`.
#[inline]
#[must_use]
pub fn theta_d_node(j: usize) -> f64 {
    j as f64 / N_THETA_D as f64 * HALF_PI
}

/// `φd` of node `k`.
#[inline]
#[must_use]
pub fn phi_d_node(k: usize) -> f64 {
    k as f64 / N_PHI_D as f64 * PI
}

/// Continuous node coordinates `(θh, θd, φd)` of half/difference angles (φd wrapped to [0, 180)).
#[inline]
fn coordinates(hd: &HalfDiff) -> (f64, f64, f64) {
    let a = (hd.theta_h.max(0.0) / HALF_PI).sqrt() * N_THETA_H as f64;
    let b = hd.theta_d.max(0.0) / HALF_PI * N_THETA_D as f64;
    let c = wrap(hd.phi_d, PI) / PI * N_PHI_D as f64;
    (a, b, if c >= N_PHI_D as f64 { 0.0 } else { c })
}

/// Lower node and fraction of a clamped coordinate on `n` nodes.
#[inline]
fn split(x: f64, n: usize) -> (usize, f64) {
    let x = x.clamp(0.0, (n - 1) as f64);
    let i = (x as usize).min(n - 2);
    (i, x - i as f64)
}

impl MerlTable {
    /// A table with no measurement anywhere.
    #[must_use]
    pub fn empty() -> Self {
        Self { values: vec![-1.0; 3 * N_ENTRIES] }
    }

    /// Half/difference angles of node `(i, j, k)` (with `φh = 0`).
    #[must_use]
    pub fn node(ih: usize, id: usize, ip: usize) -> HalfDiff {
        HalfDiff { theta_h: theta_h_node(ih), phi_h: 0.0, theta_d: theta_d_node(id), phi_d: phi_d_node(ip) }
    }

    /// The direction pair `(wi, wo)` of node `(i, j, k)`; `None` when one is below or at the
    /// horizon (`cos θ ≤ 1e-6`: nodes with `θh + θd = 90°` land there up to rounding). Such
    /// entries stay without a measurement.
    #[must_use]
    pub fn node_directions(ih: usize, id: usize, ip: usize) -> Option<(Vec3<f64>, Vec3<f64>)> {
        let (wi, wo) = from_half_diff(&Self::node(ih, id, ip));
        (wi.z > HORIZON && wo.z > HORIZON).then_some((wi, wo))
    }

    /// Tabulates `f(wi, wo)` (RGB, 1/sr) at every node above the horizon, on all cores.
    /// `None` or a negative, non-finite or above-[`MAX_BRDF`] value leaves the entry without a
    /// measurement.
    #[must_use]
    pub fn from_fn(f: impl Fn(Vec3<f64>, Vec3<f64>) -> Option<[f64; 3]> + Sync) -> Self {
        let rows: Vec<Vec<[f64; 3]>> = super::parallel_rows(N_THETA_H, |ih| {
            let mut row = vec![[-1.0; 3]; N_THETA_D * N_PHI_D];
            for id in 0..N_THETA_D {
                for ip in 0..N_PHI_D {
                    if let Some((wi, wo)) = Self::node_directions(ih, id, ip) {
                        if let Some(v) = f(wi, wo) {
                            if v.iter().all(|x| (0.0..=MAX_BRDF).contains(x)) {
                                row[ip + N_PHI_D * id] = v;
                            }
                        }
                    }
                }
            }
            row
        });
        let mut t = Self::empty();
        for (ih, row) in rows.iter().enumerate() {
            for (r, v) in row.iter().enumerate() {
                t.set(ih * N_THETA_D * N_PHI_D + r, *v);
            }
        }
        t
    }

    /// RGB value of entry `idx` (negative channels: no measurement).
    #[inline]
    #[must_use]
    pub fn get(&self, idx: usize) -> [f64; 3] {
        [self.values[idx], self.values[idx + N_ENTRIES], self.values[idx + 2 * N_ENTRIES]]
    }

    /// Sets entry `idx` (negative channels mark no measurement). A channel that is NaN or above
    /// [`MAX_BRDF`] (infinity included) is stored as no measurement: no table entry can make
    /// the f32 `eval` overflow.
    #[inline]
    pub fn set(&mut self, idx: usize, v: [f64; 3]) {
        for (c, x) in v.iter().enumerate() {
            self.values[idx + c * N_ENTRIES] = if *x <= MAX_BRDF { *x } else { -1.0 };
        }
    }

    /// True when every channel of entry `idx` holds a measurement.
    #[inline]
    #[must_use]
    pub fn is_valid(&self, idx: usize) -> bool {
        (0..3).all(|c| self.values[idx + c * N_ENTRIES] >= 0.0)
    }

    /// Fraction of entries with a measurement.
    #[must_use]
    pub fn valid_fraction(&self) -> f64 {
        (0..N_ENTRIES).filter(|&i| self.is_valid(i)).count() as f64 / N_ENTRIES as f64
    }

    /// Parses a MERL file's bytes: checks the header, the size and every value (finite, and at
    /// most [`MAX_BRDF`] after scaling; the error names the first offending entry).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, TableError> {
        let body = body_bytes(bytes)?;
        if bytes.len() != 12 + body {
            return Err(TableError::Size(format!(
                "{} bytes, but a 90 × 90 × 180 table takes {} bytes ({})",
                bytes.len(),
                12 + body,
                if bytes.len() < 12 + body { "truncated" } else { "trailing data" }
            )));
        }
        let mut values = Vec::with_capacity(3 * N_ENTRIES);
        for (n, chunk) in bytes[12..].chunks_exact(8).enumerate() {
            let raw = f64::from_le_bytes(chunk.try_into().expect("8 bytes"));
            let c = n / N_ENTRIES;
            let where_ = || {
                let i = n % N_ENTRIES;
                format!(
                    "channel {} entry {i} (θh index {}, θd index {}, φd index {})",
                    ["red", "green", "blue"][c],
                    i / (N_THETA_D * N_PHI_D),
                    (i / N_PHI_D) % N_THETA_D,
                    i % N_PHI_D
                )
            };
            if !raw.is_finite() {
                return Err(TableError::NotFinite(format!("{raw} in {}", where_())));
            }
            let v = raw * SCALE[c];
            if v > MAX_BRDF {
                return Err(TableError::OutOfRange(format!(
                    "stored {raw:e} (BRDF {v:e} 1/sr) in {}, above the bound of {MAX_BRDF:e} 1/sr \
                     (lacquer::measured::merl::MAX_BRDF: more than a passive surface can reflect \
                     at the table's resolution; a corrupted file?)",
                    where_()
                )));
            }
            values.push(v);
        }
        Ok(Self { values })
    }

    /// Reads a MERL file. The size is checked against the header before the body is read.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, TableError> {
        let path = path.as_ref();
        let io = |e: std::io::Error| TableError::Io(format!("{}: {e}", path.display()));
        let mut file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let mut header = [0u8; 12];
        let got = file.by_ref().take(12).read(&mut header).map_err(io)?;
        let body = body_bytes(&header[..got]).map_err(|e| match e {
            TableError::Size(m) => TableError::Size(format!("{}: {m}", path.display())),
            TableError::Header(m) => TableError::Header(format!("{}: {m}", path.display())),
            other => other,
        })?;
        if len != (12 + body) as u64 {
            return Err(TableError::Size(format!(
                "{}: {len} bytes, but a 90 × 90 × 180 table takes {} bytes ({})",
                path.display(),
                12 + body,
                if len < (12 + body) as u64 { "truncated" } else { "trailing data" }
            )));
        }
        let mut bytes = Vec::with_capacity(12 + body);
        bytes.extend_from_slice(&header);
        file.read_to_end(&mut bytes).map_err(io)?;
        Self::from_bytes(&bytes).map_err(|e| match e {
            TableError::NotFinite(m) => TableError::NotFinite(format!("{}: {m}", path.display())),
            TableError::OutOfRange(m) => TableError::OutOfRange(format!("{}: {m}", path.display())),
            TableError::Size(m) => TableError::Size(format!("{}: {m} (the file changed while read)", path.display())),
            other => other,
        })
    }

    /// The file's bytes (values divided by the channel scales; missing entries stay negative).
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FILE_BYTES);
        for d in [N_THETA_H, N_THETA_D, N_PHI_D] {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for (n, v) in self.values.iter().enumerate() {
            let raw = if *v >= 0.0 { v / SCALE[n / N_ENTRIES] } else { -1.0 };
            out.extend_from_slice(&raw.to_le_bytes());
        }
        out
    }

    /// Writes a MERL file.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), TableError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_bytes()).map_err(|e| TableError::Io(format!("{}: {e}", path.display())))
    }

    /// The MERL reference reader's lookup: each continuous index floored (φd folded by π).
    /// Missing entries read as 0.
    #[must_use]
    pub fn lookup_nearest(&self, hd: &HalfDiff) -> [f64; 3] {
        let (a, b, c) = coordinates(hd);
        let ih = (a as usize).min(N_THETA_H - 1);
        let id = (b as usize).min(N_THETA_D - 1);
        let ip = (c as usize).min(N_PHI_D - 1);
        self.get(index(ih, id, ip)).map(|v| v.max(0.0))
    }

    /// Trilinear interpolation between nodes (`√θh`, `θd` clamped at the last node, `φd`
    /// periodic with period π); entries without a measurement are skipped per channel and
    /// the remaining weights renormalised. 0 where no corner holds a measurement.
    #[must_use]
    pub fn interpolate(&self, hd: &HalfDiff) -> [f64; 3] {
        let (a, b, c) = coordinates(hd);
        let (ih, ta) = split(a, N_THETA_H);
        let (id, tb) = split(b, N_THETA_D);
        let ip = (c as usize).min(N_PHI_D - 1);
        let tc = c - ip as f64;
        let ip1 = (ip + 1) % N_PHI_D;
        let mut sum = [0.0; 3];
        let mut wsum = [0.0; 3];
        for (i, wa) in [(ih, 1.0 - ta), (ih + 1, ta)] {
            for (j, wb) in [(id, 1.0 - tb), (id + 1, tb)] {
                for (k, wc) in [(ip, 1.0 - tc), (ip1, tc)] {
                    let w = wa * wb * wc;
                    if w <= 0.0 {
                        continue;
                    }
                    let idx = index(i, j, k);
                    for ch in 0..3 {
                        let v = self.values[idx + ch * N_ENTRIES];
                        if v >= 0.0 {
                            sum[ch] += w * v;
                            wsum[ch] += w;
                        }
                    }
                }
            }
        }
        [0, 1, 2].map(|ch| if wsum[ch] > 0.0 { sum[ch] / wsum[ch] } else { 0.0 })
    }

    /// The interpolated BRDF of a direction pair (unit vectors above the surface).
    #[inline]
    #[must_use]
    pub fn eval(&self, wi: Vec3<f64>, wo: Vec3<f64>) -> [f64; 3] {
        self.interpolate(&to_half_diff(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn analytic(wi: Vec3<f64>, wo: Vec3<f64>) -> Option<[f64; 3]> {
        // A smooth, reciprocal test function of the half vector and θd.
        let hd = to_half_diff(wi, wo);
        let g = (-hd.theta_h * hd.theta_h / 0.08).exp();
        Some([0.1 + 2.0 * g, 0.05 + g * hd.theta_d.cos(), 0.2])
    }

    #[test]
    fn node_angles_and_layout() {
        assert_eq!(theta_h_node(0), 0.0);
        assert!((theta_h_node(45) - 0.25 * HALF_PI).abs() < 1e-15);
        assert!((theta_d_node(45) - PI / 4.0).abs() < 1e-15);
        assert!((phi_d_node(90) - PI / 2.0).abs() < 1e-15);
        assert_eq!(index(1, 0, 0), 90 * 180);
        assert_eq!(index(0, 1, 0), 180);
        assert_eq!(FILE_BYTES, 34_992_012);
    }

    #[test]
    fn write_read_round_trip_and_scales() {
        let t = MerlTable::from_fn(analytic);
        let bytes = t.to_bytes();
        assert_eq!(bytes.len(), FILE_BYTES);
        assert_eq!(&bytes[..12], &[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]);
        // The blue plane holds 0.2 / (1.66/1500) where valid.
        let idx = index(10, 20, 30);
        let raw = f64::from_le_bytes(bytes[12 + 8 * (2 * N_ENTRIES + idx)..][..8].try_into().unwrap());
        assert!((raw - 0.2 * 1500.0 / 1.66).abs() < 1e-9);
        let back = MerlTable::from_bytes(&bytes).unwrap();
        for i in (0..N_ENTRIES).step_by(97) {
            let (a, b) = (t.get(i), back.get(i));
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-15 * a[c].abs() || (a[c] < 0.0 && b[c] < 0.0));
            }
        }
        let dir = std::env::temp_dir().join(format!("lacquer-merl-{}.binary", std::process::id()));
        t.write(&dir).unwrap();
        let read = MerlTable::read(&dir).unwrap();
        std::fs::remove_file(&dir).ok();
        assert_eq!(read.to_bytes(), bytes);
    }

    #[test]
    fn bad_files_are_rejected_with_clear_errors() {
        let good = MerlTable::from_fn(analytic).to_bytes();
        let e = MerlTable::from_bytes(&good[..7]).unwrap_err();
        assert!(matches!(e, TableError::Size(_)) && e.to_string().contains("12-byte header"), "{e}");
        let mut bad = good.clone();
        bad[0] = 91;
        let e = MerlTable::from_bytes(&bad).unwrap_err();
        assert!(e.to_string().contains("91 × 90 × 180"), "{e}");
        // A header claiming a huge table is rejected on its dimensions, before any allocation.
        let mut huge = good[..12].to_vec();
        huge[..4].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(matches!(MerlTable::from_bytes(&huge).unwrap_err(), TableError::Header(_)));
        let e = MerlTable::from_bytes(&good[..good.len() - 8]).unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
        let mut long = good.clone();
        long.push(0);
        assert!(MerlTable::from_bytes(&long).unwrap_err().to_string().contains("trailing"));
        let mut nan = good.clone();
        let at = 12 + 8 * (N_ENTRIES + index(3, 4, 5));
        nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let e = MerlTable::from_bytes(&nan).unwrap_err();
        assert!(e.to_string().contains("green") && e.to_string().contains("θh index 3"), "{e}");
        // Files: truncated and wrong header, checked before reading the body.
        let p = std::env::temp_dir().join(format!("lacquer-merl-bad-{}.binary", std::process::id()));
        std::fs::write(&p, &good[..1000]).unwrap();
        let e = MerlTable::read(&p).unwrap_err();
        assert!(e.to_string().contains("truncated") && e.to_string().contains("1000 bytes"), "{e}");
        std::fs::write(&p, [1u8, 2, 3]).unwrap();
        assert!(MerlTable::read(&p).unwrap_err().to_string().contains("header"));
        std::fs::remove_file(&p).ok();
        assert!(matches!(MerlTable::read("/no/such/file.binary").unwrap_err(), TableError::Io(_)));
    }

    #[test]
    fn interpolation_is_exact_at_nodes_and_close_between() {
        let t = MerlTable::from_fn(analytic);
        for (ih, id, ip) in [(0, 0, 0), (5, 30, 17), (40, 10, 179), (89, 0, 90), (12, 60, 100)] {
            let Some((wi, wo)) = MerlTable::node_directions(ih, id, ip) else { continue };
            let want = analytic(wi, wo).unwrap();
            let got = t.eval(wi, wo);
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() <= 1e-9 * want[c], "node {ih},{id},{ip}: {got:?} vs {want:?}");
            }
        }
        let mut rng = Pcg32::new(9, 9);
        let mut worst = 0.0f64;
        for _ in 0..20_000 {
            let z = |r: &mut Pcg32| r.uniform() * 0.95 + 0.05;
            let wi = super::super::parameterization::spherical(z(&mut rng).acos(), 2.0 * PI * rng.uniform());
            let wo = super::super::parameterization::spherical(z(&mut rng).acos(), 2.0 * PI * rng.uniform());
            let want = analytic(wi, wo).unwrap();
            let got = t.eval(wi, wo);
            worst = worst.max((got[0] - want[0]).abs() / want[0]);
            assert!(t.eval(wo, wi) == got || (t.eval(wo, wi)[0] - got[0]).abs() < 1e-12 * got[0]);
        }
        assert!(worst < 0.01, "worst relative interpolation error {worst}");
    }

    #[test]
    fn nearest_lookup_follows_the_reference_reader() {
        let mut t = MerlTable::empty();
        t.set(index(1, 2, 3), [1.0, 2.0, 3.0]);
        // θh just above node 1 (index floor = 1), θd in [2, 3), φd in [3, 4) — and φd − π.
        let hd = HalfDiff {
            theta_h: theta_h_node(1) * 1.01,
            phi_h: 0.0,
            theta_d: theta_d_node(2) + 0.001,
            phi_d: phi_d_node(3) + 0.001,
        };
        assert_eq!(t.lookup_nearest(&hd), [1.0, 2.0, 3.0]);
        assert_eq!(t.lookup_nearest(&HalfDiff { phi_d: hd.phi_d - PI, ..hd }), [1.0, 2.0, 3.0]);
        // Interpolation between missing entries gives the valid one's value, never a mix with −1.
        assert_eq!(t.interpolate(&hd), [1.0, 2.0, 3.0]);
        assert_eq!(t.interpolate(&MerlTable::node(50, 50, 50)), [0.0; 3]);
    }

    /// A table file whose raw values are all `raw`, except that `put(n)` may replace value `n`.
    fn file_with(put: impl Fn(usize) -> Option<f64>) -> Vec<u8> {
        let mut bytes = MerlTable::from_fn(analytic).to_bytes();
        for n in 0..3 * N_ENTRIES {
            if let Some(v) = put(n) {
                bytes[12 + 8 * n..20 + 8 * n].copy_from_slice(&v.to_le_bytes());
            }
        }
        bytes
    }

    #[test]
    fn absurd_finite_values_are_rejected_naming_the_entry() {
        // Issue 16: 1e300 in every 97th value (finite in f64) used to be accepted, and the f32
        // eval then returned +Inf for ~19 % of direction pairs.
        let e = MerlTable::from_bytes(&file_with(|n| (n % 97 == 96).then_some(1e300))).unwrap_err();
        assert!(matches!(e, TableError::OutOfRange(_)), "{e:?}");
        let m = e.to_string();
        assert!(m.contains("red entry 96 ") && m.contains("1e300") && m.contains("φd index 96"), "{m}");
        // A value that fits in f64 and overflows f32 only after scaling (blue: × 1.66/1500).
        let raw = 2.0 * f64::from(f32::MAX) / SCALE[2];
        let at = 2 * N_ENTRIES + index(7, 8, 9);
        let e = MerlTable::from_bytes(&file_with(|n| (n == at).then_some(raw))).unwrap_err();
        assert!(e.to_string().contains("blue entry") && e.to_string().contains("θh index 7"), "{e}");
        // A flipped top byte of a plausible value (0.3 · 1500 stored): exponent × 2^±512-ish.
        let mut flipped = 450.0f64.to_le_bytes();
        flipped[7] ^= 0x3c;
        let e = MerlTable::from_bytes(&file_with(|n| (n == 1234).then_some(f64::from_le_bytes(flipped)))).unwrap_err();
        assert!(e.to_string().contains("entry 1234"), "{e}");
        // Just above and just below the bound (red scale 1/1500).
        let over = MAX_BRDF * 1500.0 * (1.0 + 1e-9);
        assert!(MerlTable::from_bytes(&file_with(|n| (n == 5).then_some(over))).is_err());
        let under = MAX_BRDF * 1500.0 * (1.0 - 1e-9);
        let t = MerlTable::from_bytes(&file_with(|n| (n == 5).then_some(under))).unwrap();
        assert!(t.is_valid(5) && t.get(5)[0] > 0.99 * MAX_BRDF);
        // Files go through the same check and name the path.
        let p = std::env::temp_dir().join(format!("lacquer-merl-absurd-{}.binary", std::process::id()));
        std::fs::write(&p, file_with(|n| (n % 97 == 96).then_some(1e300))).unwrap();
        let e = MerlTable::read(&p).unwrap_err();
        std::fs::remove_file(&p).ok();
        assert!(e.to_string().contains("lacquer-merl-absurd") && e.to_string().contains("entry 96 "), "{e}");
    }

    #[test]
    fn in_memory_absurd_values_are_marked_without_measurement() {
        let mut t = MerlTable::empty();
        t.set(3, [1e300, 0.5, 0.5]);
        t.set(4, [0.5, f64::INFINITY, 0.5]);
        t.set(5, [0.5, 0.5, f64::NAN]);
        t.set(6, [0.5, MAX_BRDF, 0.5]);
        assert!(!t.is_valid(3) && !t.is_valid(4) && !t.is_valid(5) && t.is_valid(6));
        let t = MerlTable::from_fn(|_, _| Some([1e300, 1.0, 1.0]));
        assert_eq!(t.valid_fraction(), 0.0);
    }

    #[test]
    fn the_bound_keeps_the_f32_eval_finite_and_accepts_sharp_real_lobes() {
        // Every entry at the bound: the f32 eval stays finite (the interpolation sums eight
        // corners with weights summing to one).
        let mut t = MerlTable::empty();
        for i in 0..N_ENTRIES {
            t.set(i, [MAX_BRDF; 3]);
        }
        let m = crate::measured::material_from_table(t);
        let mut rng = Pcg32::new(16, 1);
        for _ in 0..2000 {
            let z = |r: &mut Pcg32| r.uniform() * 0.999 + 0.001;
            let wi = super::super::parameterization::spherical(z(&mut rng).acos(), 2.0 * PI * rng.uniform());
            let wo = super::super::parameterization::spherical(z(&mut rng).acos(), 2.0 * PI * rng.uniform());
            let f = m.eval(wi.cast::<f32>(), wo.cast::<f32>());
            assert!(f.r.is_finite() && f.g.is_finite() && f.b.is_finite(), "{f:?}");
        }
        // The sharpest rough conductor Lacquer builds (α = 0.001) tabulates below the bound
        // (its peak, at the most grazing node, is ~2.6e8 1/sr: stated at MAX_BRDF).
        let sharp =
            crate::material::Material::from_json(r#"{"model": "rough_conductor", "alpha_u": 0.001, "alpha_v": 0.001}"#)
                .unwrap();
        let mut peak = 0.0f64;
        let t = MerlTable::from_fn(|wi, wo| {
            let f = sharp.model().eval(wi, wo);
            Some([f[0], f[1], f[2]])
        });
        for i in 0..N_ENTRIES {
            if t.is_valid(i) {
                peak = peak.max(t.get(i).into_iter().fold(0.0, f64::max));
            }
        }
        assert!((1e8..=3e8).contains(&peak), "peak {peak:e} 1/sr (stated at MAX_BRDF: ~2.6e8)");
        let bytes = t.to_bytes();
        assert_eq!(MerlTable::from_bytes(&bytes).unwrap().to_bytes(), bytes);
    }
}
