//! Levenberg-Marquardt least squares with box bounds.
//!
//! Minimises `½‖r(x)‖²` from a starting point inside the box `[lo, hi]`:
//! - the Jacobian is computed by forward differences (backward at the upper bound), with one
//!   residual evaluation per variable — generic over any model;
//! - each step solves `(JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr` (Marquardt's scaling, with a floor on the
//!   diagonal) by Cholesky, on the *free* variables: a variable at a bound whose gradient
//!   points out of the box is held for that step, and the step is projected onto the box;
//! - λ follows Nielsen's rule (H. B. Nielsen, "Damping parameter in Marquardt's method",
//!   IMM-REP-1999-05): shrink by `max(1/3, 1 − (2ρ − 1)³)` on a good step, grow by a doubling
//!   factor on a rejected one;
//! - a residual function may refuse a point (`false`: the parameters cannot be built, e.g. a
//!   cross-parameter constraint); such a step is rejected like one that does not decrease the
//!   cost.
//!
//! Reference: K. Levenberg (1944), D. W. Marquardt (1963); the bound handling is the projected
//! variant described by Kanzow, Yamashita and Fukushima (2004).

/// A least-squares problem.
pub trait Problem: Sync {
    /// Number of variables.
    fn n_vars(&self) -> usize;
    /// Number of residuals.
    fn n_residuals(&self) -> usize;
    /// Writes `r(x)` into `out`; returns `false` when `x` cannot be evaluated.
    fn residuals(&self, x: &[f64], out: &mut [f64]) -> bool;
}

/// Stopping rules.
#[derive(Clone, Debug)]
pub struct LmConfig {
    /// Largest number of iterations (accepted or rejected steps).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub ftol: f64,
    /// Stop when the step is shorter than `xtol · (‖x‖ + xtol)`.
    pub xtol: f64,
    /// Stop when the largest free gradient component is below this (relative to the cost).
    pub gtol: f64,
    /// Initial damping factor.
    pub lambda0: f64,
    /// Threads used for Jacobian columns.
    pub threads: usize,
    /// Stop (with [`Stop::Time`]) at the first iteration that starts after this instant.
    pub deadline: Option<std::time::Instant>,
    /// Stop (with [`Stop::Target`]) as soon as the cost is at or below this absolute value
    /// (`None`: an exact fit runs until a relative rule or `max_iterations` stops it).
    pub cost_target: Option<f64>,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            ftol: 1e-9,
            xtol: 1e-9,
            gtol: 1e-12,
            lambda0: 1e-3,
            threads: 1,
            deadline: None,
            cost_target: None,
        }
    }
}

/// Why the iteration stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stop {
    /// The relative cost reduction fell below `ftol`.
    Cost,
    /// The step fell below `xtol`.
    Step,
    /// The gradient vanished.
    Gradient,
    /// `max_iterations` was reached.
    Iterations,
    /// No step could lower the cost (λ grew without bound).
    Stalled,
    /// The starting point could not be evaluated.
    BadStart,
    /// The deadline passed.
    Time,
    /// The cost reached `cost_target`.
    Target,
}

/// Outcome of a minimisation.
#[derive(Clone, Debug)]
pub struct LmResult {
    /// Best point found.
    pub x: Vec<f64>,
    /// `½‖r(x)‖²` there.
    pub cost: f64,
    /// Iterations (Jacobians computed).
    pub iterations: usize,
    /// Residual evaluations (Jacobian columns included).
    pub evaluations: usize,
    /// Why it stopped.
    pub stop: Stop,
}

/// The instant `seconds` after `start`, for [`LmConfig::deadline`]: NaN or less than 0 is
/// `start` itself (stop at once); a time too long for a `Duration` or an `Instant` (e.g.
/// infinity) is `None`, no deadline.
#[must_use]
pub fn deadline_after(start: std::time::Instant, seconds: f64) -> Option<std::time::Instant> {
    std::time::Duration::try_from_secs_f64(seconds.max(0.0)).ok().and_then(|d| start.checked_add(d))
}

fn cost_of(r: &[f64]) -> f64 {
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

/// Solves `A x = b` for symmetric positive definite `A` (`n × n`, row-major) by Cholesky;
/// `None` when `A` is not positive definite.
#[must_use]
pub fn cholesky_solve(a: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if !(s > 0.0) || !s.is_finite() {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    let mut y = vec![0.0; n];
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in i + 1..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    Some(x)
}

/// Forward-difference Jacobian, column-major (`jac[j·m + i] = ∂r_i/∂x_j`). Columns whose
/// perturbed point cannot be evaluated either way are left zero.
fn jacobian<P: Problem>(p: &P, x: &[f64], r: &[f64], lo: &[f64], hi: &[f64], threads: usize) -> (Vec<f64>, usize) {
    let (n, m) = (p.n_vars(), p.n_residuals());
    let column = |j: usize| -> (Vec<f64>, usize) {
        let scale = x[j].abs().max(1e-2 * (hi[j] - lo[j]).min(1.0)).max(1e-8);
        let h = 1e-6 * scale;
        let mut xp = x.to_vec();
        let mut out = vec![0.0; m];
        let mut evals = 0;
        for step in [h, -h] {
            let v = x[j] + step;
            if v > hi[j] || v < lo[j] {
                continue;
            }
            xp[j] = v;
            evals += 1;
            if p.residuals(&xp, &mut out) {
                let d = xp[j] - x[j];
                for i in 0..m {
                    out[i] = (out[i] - r[i]) / d;
                }
                return (out, evals);
            }
        }
        (vec![0.0; m], evals)
    };
    let cols: Vec<(Vec<f64>, usize)> = if threads > 1 && n > 1 {
        crate::measured::parallel_rows_with(n, threads, column)
    } else {
        (0..n).map(column).collect()
    };
    let evals = cols.iter().map(|c| c.1).sum();
    let mut jac = Vec::with_capacity(n * m);
    for (c, _) in cols {
        jac.extend(c);
    }
    (jac, evals)
}

/// Minimises `½‖r(x)‖²` over the box `[lo, hi]` from `x0` (clamped into the box).
pub fn minimize<P: Problem>(p: &P, x0: &[f64], lo: &[f64], hi: &[f64], cfg: &LmConfig) -> LmResult {
    let (n, m) = (p.n_vars(), p.n_residuals());
    let mut x: Vec<f64> = x0.iter().zip(lo.iter().zip(hi)).map(|(v, (a, b))| v.clamp(*a, *b)).collect();
    let mut r = vec![0.0; m];
    let mut evaluations = 1;
    if !p.residuals(&x, &mut r) {
        return LmResult { x, cost: f64::INFINITY, iterations: 0, evaluations, stop: Stop::BadStart };
    }
    let mut cost = cost_of(&r);
    let mut lambda = cfg.lambda0;
    let mut nu = 2.0;
    let mut iterations = 0;
    let mut need_jacobian = true;
    let (mut a, mut g) = (vec![0.0; n * n], vec![0.0; n]);
    let mut r_new = vec![0.0; m];
    let stop = loop {
        if cfg.cost_target.is_some_and(|target| cost <= target) {
            break Stop::Target;
        }
        if iterations >= cfg.max_iterations {
            break Stop::Iterations;
        }
        if cfg.deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            break Stop::Time;
        }
        iterations += 1;
        if need_jacobian {
            let (jac, e) = jacobian(p, &x, &r, lo, hi, cfg.threads);
            evaluations += e;
            for i in 0..n {
                let ci = &jac[i * m..(i + 1) * m];
                g[i] = ci.iter().zip(&r).map(|(a, b)| a * b).sum();
                for j in 0..=i {
                    let cj = &jac[j * m..(j + 1) * m];
                    let v: f64 = ci.iter().zip(cj).map(|(a, b)| a * b).sum();
                    a[i * n + j] = v;
                    a[j * n + i] = v;
                }
            }
            need_jacobian = false;
        }
        // Free variables: not at a bound with the descent direction pointing outward.
        let free: Vec<usize> = (0..n)
            .filter(|&j| {
                let at_lo = x[j] <= lo[j] && g[j] > 0.0;
                let at_hi = x[j] >= hi[j] && g[j] < 0.0;
                !(at_lo || at_hi)
            })
            .collect();
        let gmax = free.iter().map(|&j| g[j].abs()).fold(0.0, f64::max);
        if free.is_empty() || gmax <= cfg.gtol * cost.max(1e-300) {
            break Stop::Gradient;
        }
        let k = free.len();
        let max_diag = free.iter().map(|&j| a[j * n + j]).fold(0.0, f64::max).max(1e-300);
        let mut sys = vec![0.0; k * k];
        let mut rhs = vec![0.0; k];
        for (ii, &i) in free.iter().enumerate() {
            rhs[ii] = -g[i];
            for (jj, &j) in free.iter().enumerate() {
                sys[ii * k + jj] = a[i * n + j];
            }
            sys[ii * k + ii] += lambda * a[i * n + i].max(1e-9 * max_diag);
        }
        let Some(delta) = cholesky_solve(&sys, &rhs, k) else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                break Stop::Stalled;
            }
            continue;
        };
        let mut x_new = x.clone();
        for (ii, &i) in free.iter().enumerate() {
            x_new[i] = (x[i] + delta[ii]).clamp(lo[i], hi[i]);
        }
        let step: Vec<f64> = (0..n).map(|i| x_new[i] - x[i]).collect();
        let step_norm = step.iter().map(|v| v * v).sum::<f64>().sqrt();
        let x_norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if step_norm <= cfg.xtol * (x_norm + cfg.xtol) {
            break Stop::Step;
        }
        // Predicted reduction of the quadratic model along the (projected) step.
        let mut pred = 0.0;
        for i in 0..n {
            let mut as_i = 0.0;
            for j in 0..n {
                as_i += a[i * n + j] * step[j];
            }
            pred -= g[i] * step[i] + 0.5 * step[i] * as_i;
        }
        evaluations += 1;
        let ok = p.residuals(&x_new, &mut r_new);
        let cost_new = if ok { cost_of(&r_new) } else { f64::INFINITY };
        if cost_new < cost {
            let rho = if pred > 0.0 { (cost - cost_new) / pred } else { 1.0 };
            let reduction = (cost - cost_new) / cost.max(1e-300);
            x = x_new;
            std::mem::swap(&mut r, &mut r_new);
            cost = cost_new;
            need_jacobian = true;
            lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            nu = 2.0;
            if reduction < cfg.ftol {
                break Stop::Cost;
            }
        } else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                break Stop::Stalled;
            }
        }
    };
    LmResult { x, cost, iterations, evaluations, stop }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: r = (10(y − x²), 1 − x); minimum 0 at (1, 1).
    struct Rosenbrock;
    impl Problem for Rosenbrock {
        fn n_vars(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            2
        }
        fn residuals(&self, x: &[f64], out: &mut [f64]) -> bool {
            out[0] = 10.0 * (x[1] - x[0] * x[0]);
            out[1] = 1.0 - x[0];
            true
        }
    }

    /// Exponential decay y = a·exp(−b t) fitted to exact data (a = 2, b = 0.7).
    struct Decay {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Problem for Decay {
        fn n_vars(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64], out: &mut [f64]) -> bool {
            if x[1] < 0.0 {
                return false;
            }
            for (i, t) in self.t.iter().enumerate() {
                out[i] = x[0] * (-x[1] * t).exp() - self.y[i];
            }
            true
        }
    }

    #[test]
    fn rosenbrock_from_the_classic_start() {
        let inf = f64::INFINITY;
        let r = minimize(&Rosenbrock, &[-1.2, 1.0], &[-inf, -inf], &[inf, inf], &LmConfig::default());
        assert!((r.x[0] - 1.0).abs() < 1e-6 && (r.x[1] - 1.0).abs() < 1e-6, "{r:?}");
    }

    #[test]
    fn bounds_hold_and_active_bound_is_found() {
        // Minimum of Rosenbrock with x ≤ 0.5: on the bound x = 0.5, y = 0.25.
        let r = minimize(&Rosenbrock, &[-1.2, 1.0], &[-2.0, -2.0], &[0.5, 2.0], &LmConfig::default());
        assert!(r.x[0] <= 0.5);
        assert!((r.x[0] - 0.5).abs() < 1e-9 && (r.x[1] - 0.25).abs() < 1e-6, "{r:?}");
    }

    #[test]
    fn recovers_exact_parameters_and_survives_refused_points() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let p = Decay { t, y };
        let cfg = LmConfig { threads: 2, ..LmConfig::default() };
        let r = minimize(&p, &[0.5, 3.0], &[0.0, -1.0], &[10.0, 10.0], &cfg);
        assert!((r.x[0] - 2.0).abs() < 1e-7 && (r.x[1] - 0.7).abs() < 1e-7, "{r:?}");
        assert!(r.cost < 1e-16);
    }

    #[test]
    fn cost_target_stops_an_exact_fit_early() {
        // Without a target the exact fit iterates down to round-off (cost < 1e-16 above); with
        // one it stops at the first point at or below it, in fewer iterations.
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let p = Decay { t, y };
        let (lo, hi) = ([0.0, -1.0], [10.0, 10.0]);
        let full = minimize(&p, &[0.5, 3.0], &lo, &hi, &LmConfig::default());
        let cfg = LmConfig { cost_target: Some(1e-6), ..LmConfig::default() };
        let r = minimize(&p, &[0.5, 3.0], &lo, &hi, &cfg);
        assert_eq!(r.stop, Stop::Target, "{r:?}");
        assert!(r.cost <= 1e-6 && r.iterations < full.iterations, "{r:?} vs {full:?}");
        // A start already at the target returns it without an iteration.
        let at = minimize(&p, &[2.0, 0.7], &lo, &hi, &cfg);
        assert_eq!((at.stop, at.iterations), (Stop::Target, 0));
    }

    #[test]
    fn cholesky_by_hand() {
        // [[4, 2], [2, 3]] x = [2, 1] → x = [0.5, 0].
        let x = cholesky_solve(&[4.0, 2.0, 2.0, 3.0], &[2.0, 1.0], 2).unwrap();
        assert!((x[0] - 0.5).abs() < 1e-15 && x[1].abs() < 1e-15);
        assert!(cholesky_solve(&[1.0, 2.0, 2.0, 1.0], &[1.0, 1.0], 2).is_none());
    }
}
