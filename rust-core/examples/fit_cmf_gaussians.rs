//! Fits sums of Gaussians in wavenumber space to the colour-matching functions the spectral
//! reference uses (`lacquer::paint::thin_film::cie_xyz`), for the Fourier-space (Belcour &
//! Barla 2017) thin-film integration, and prints them as Rust constants.
//!
//! `cargo run --release -p lacquer --example fit_cmf_gaussians [-- PER_LOBE]`
//!
//! Target per channel: `g(k) = cmf(1000/k) · 1000/k²` for `k = 1/λ` in µm⁻¹ (so that
//! `∫ cmf(λ) dλ = ∫ g(k) dk`), on 360–830 nm. Model: `Σ a exp(−(k − μ)²/(2 s²))`, started from
//! the Wyman-Sloan-Shirley lobes mapped to wavenumber (each lobe split into `PER_LOBE`
//! Gaussians), refined by Levenberg-Marquardt on all parameters.

use lacquer::paint::thin_film::cie_xyz;

/// Wyman-Sloan-Shirley lobes per channel: (amplitude, centre nm, σ left, σ right).
const LOBES: [&[(f64, f64, f64, f64)]; 3] = [
    &[(1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)],
    &[(0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)],
    &[(1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)],
];

fn model(p: &[f64], k: f64) -> f64 {
    p.chunks(3).map(|g| g[0] * (-(k - g[1]).powi(2) / (2.0 * g[2] * g[2])).exp()).sum()
}

/// Solves `A x = b` (small dense, Gaussian elimination with partial pivoting).
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap();
        a.swap(c, p);
        b.swap(c, p);
        let (pivot_row, pivot_b) = (a[c].clone(), b[c]);
        for (row, rhs) in a.iter_mut().zip(b.iter_mut()).skip(c + 1) {
            let f = row[c] / pivot_row[c];
            for (x, y) in row.iter_mut().zip(&pivot_row).skip(c) {
                *x -= f * y;
            }
            *rhs -= f * pivot_b;
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x
}

fn fit(channel: usize, per_lobe: usize) -> Vec<f64> {
    let ks: Vec<f64> =
        (0..3000).map(|i| 1000.0 / 830.0 + (1000.0 / 360.0 - 1000.0 / 830.0) * i as f64 / 2999.0).collect();
    let target: Vec<f64> = ks.iter().map(|&k| cie_xyz(1000.0 / k)[channel] * 1000.0 / (k * k)).collect();
    // Initial guess: each (asymmetric) lobe as `per_lobe` Gaussians across its centre.
    let mut p = Vec::new();
    for &(amp, mu, sl, sr) in LOBES[channel] {
        let k0 = 1000.0 / mu;
        for j in 0..per_lobe {
            let off = if per_lobe == 1 { 0.0 } else { (j as f64 / (per_lobe - 1) as f64 - 0.5) * 1.2 };
            let s_nm = if off < 0.0 {
                sr
            } else if off > 0.0 {
                sl
            } else {
                0.5 * (sl + sr)
            };
            let s = 1000.0 * s_nm / (mu * mu);
            p.extend([amp * mu * mu / 1000.0 / per_lobe as f64, k0 + off * s, s]);
        }
    }
    // A small ridge on the amplitudes keeps the fit from pairs of large, cancelling Gaussians.
    let ridge = 1e-4;
    let cost = |p: &[f64]| {
        ks.iter().zip(&target).map(|(&k, &t)| (model(p, k) - t).powi(2)).sum::<f64>()
            + ridge * p.chunks(3).map(|g| g[0] * g[0]).sum::<f64>()
    };
    let mut lambda = 1e-3;
    let mut c = cost(&p);
    for _ in 0..2000 {
        let n = p.len();
        let mut jtj = vec![vec![0.0; n]; n];
        let mut jtr = vec![0.0; n];
        for (&k, &t) in ks.iter().zip(&target) {
            let r = model(&p, k) - t;
            let mut row = vec![0.0; n];
            for (g, chunk) in p.chunks(3).enumerate() {
                let (a, mu, s) = (chunk[0], chunk[1], chunk[2]);
                let e = (-(k - mu).powi(2) / (2.0 * s * s)).exp();
                row[3 * g] = e;
                row[3 * g + 1] = a * e * (k - mu) / (s * s);
                row[3 * g + 2] = a * e * (k - mu).powi(2) / (s * s * s);
            }
            for i in 0..n {
                jtr[i] += row[i] * r;
                for j in 0..n {
                    jtj[i][j] += row[i] * row[j];
                }
            }
        }
        for g in 0..n / 3 {
            jtj[3 * g][3 * g] += ridge;
            jtr[3 * g] += ridge * p[3 * g];
        }
        for (i, row) in jtj.iter_mut().enumerate() {
            row[i] *= 1.0 + lambda;
        }
        let step = solve(jtj, jtr);
        let q: Vec<f64> = p.iter().zip(&step).map(|(a, d)| a - d).collect();
        let cq = cost(&q);
        if cq < c && q.chunks(3).all(|g| g[2] > 1e-3) {
            let done = (c - cq) < 1e-14 * c;
            p = q;
            c = cq;
            lambda = (lambda * 0.3).max(1e-12);
            if done {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    let peak = target.iter().cloned().fold(0.0, f64::max);
    let max_err = ks.iter().zip(&target).map(|(&k, &t)| (model(&p, k) - t).abs()).fold(0.0, f64::max);
    eprintln!("channel {channel}: {} Gaussians, max |error| {:.2e} of peak {:.3}", p.len() / 3, max_err / peak, peak);
    p
}

fn main() {
    let per_lobe = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(1usize);
    for (c, name) in ["X", "Y", "Z"].iter().enumerate() {
        let p = fit(c, per_lobe);
        println!("/// `{name}`: (amplitude, centre µm⁻¹, width µm⁻¹).");
        println!("const GAUSSIANS_{name}: [[f64; 3]; {}] = [", p.len() / 3);
        for g in p.chunks(3) {
            println!("    [{:.10e}, {:.10e}, {:.10e}],", g[0], g[1], g[2]);
        }
        println!("];");
    }
}
