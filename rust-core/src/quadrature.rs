//! Numerical quadrature used where a model tabulates an integral of itself at construction
//! (energy compensation tables, rough-plastic transmittance).

/// Gauss-Legendre nodes and weights of order `n` on `[-1, 1]`: exact for polynomials of
/// degree `2n − 1`. Nodes are the roots of `P_n`, found by Newton's method from the
/// Tricomi initial guesses (Abramowitz & Stegun 25.4.29; Numerical Recipes `gauleg`).
#[must_use]
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n > 0, "quadrature order must be positive");
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Initial guess for the i-th largest root.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let kf = k as f64;
                let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 1 { x } else { p1 };
            let pn_1 = if n == 1 { 1.0 } else { p0 };
            dp = nf * (x * pn - pn_1) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        nodes[n - 1 - i] = x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

/// Gauss-Legendre nodes and weights of order `n` mapped to `[a, b]`.
#[must_use]
pub fn gauss_legendre_on(n: usize, a: f64, b: f64) -> (Vec<f64>, Vec<f64>) {
    let (x, w) = gauss_legendre(n);
    let (half, mid) = (0.5 * (b - a), 0.5 * (a + b));
    (x.iter().map(|x| mid + half * x).collect(), w.iter().map(|w| half * w).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_polynomials_exactly() {
        for n in [1usize, 2, 3, 8, 32, 128] {
            let (x, w) = gauss_legendre(n);
            // ∫_{-1}^{1} x^k dx = 2/(k+1) for even k, 0 for odd k.
            for k in 0..(2 * n).min(40) {
                let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let want = if k % 2 == 0 { 2.0 / (k as f64 + 1.0) } else { 0.0 };
                assert!((got - want).abs() < 1e-13, "n={n} k={k}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn integrates_smooth_functions_on_an_interval() {
        // ∫_0^{π/2} cos x dx = 1.
        let (x, w) = gauss_legendre_on(16, 0.0, std::f64::consts::FRAC_PI_2);
        let s: f64 = x.iter().zip(&w).map(|(x, w)| w * x.cos()).sum();
        assert!((s - 1.0).abs() < 1e-14);
    }
}
