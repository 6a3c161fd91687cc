//! Piecewise-polynomial fits of smooth RGB functions of `μ = cos θ ∈ [0, 1]` for SIMD lanes.
//!
//! Some per-material functions of one cosine cost far more to evaluate than to look up: the
//! exact conductor Fresnel takes two square roots and two divisions per channel, which is
//! a quarter to a half of a GGX conductor's eval. For a fixed material they are smooth
//! functions of `μ` alone, so a [`MuPolyFit`] replaces them by polynomial pieces, each the
//! interpolant at the Chebyshev–Lobatto points of its piece (so the pieces join
//! continuously), with every coefficient read by one register permute:
//!
//! - [`MuFit32`] (AVX-512): 32 quintic pieces uniform in `μ`; a coefficient is one
//!   two-register permute (`vpermt2ps`, [`Lanes::lookup_f32_`]): six permutes and five FMAs
//!   per channel.
//! - [`SqrtMuFit8`] (AVX2): 8 pieces of degree 7 uniform in `√μ`, where a conductor's
//!   Fresnel bends fastest (grazing incidence) getting the narrowest pieces in `μ`; a
//!   coefficient is one `vpermps` ([`Lanes::lookup8_f32_`]): eight permutes and seven FMAs per
//!   channel, and one square root for all three.
//!
//! A fit is only an implementation of the function it replaces: [`MuPolyFit::new`] measures
//! its largest relative error against the exact function (at 64 points per piece, with the
//! coefficients rounded to f32 as the lanes hold them) and returns `None` when it exceeds
//! [`FIT_TOLERANCE`] or the function is not positive (an index-matched conductor, `F ≡ 0`).
//! Callers then keep the exact formula. The one-lane paths (the f64 reference and scalar f32)
//! never use fits; only lanes with [`Lanes::REGISTER_LOOKUP`] (the 32-piece fit) or
//! [`Lanes::PERMUTE8`] (the 8-piece fit) do.

use crate::lanes::{self, Lanes};
use crate::math::Rgb;

/// The largest relative error a fit may have against its function to be used (measured for
/// [`MuFit32`]: 6e-8 for gold, 1.9e-7 for aluminium, 1.1e-7 for a dielectric of index 1.5;
/// for [`SqrtMuFit8`] see `fresnel`'s tests — at or below the rounding of the exact formula
/// evaluated in f32).
pub const FIT_TOLERANCE: f64 = 1e-6;

/// The AVX-512 fit: 32 quintic pieces uniform in `μ` (the 32 entries of a coefficient fill
/// the two registers of one two-source permute).
pub type MuFit32 = MuPolyFit<32, 6, false>;

/// The AVX2 fit: 8 pieces of degree 7 uniform in `√μ` (the 8 entries of a coefficient fill
/// one register of `vpermps`).
pub type SqrtMuFit8 = MuPolyFit<8, 8, true>;

/// An RGB function of `μ ∈ [0, 1]` as `PIECES` polynomials with `POWERS` coefficients
/// (degree `POWERS − 1`) in the position `t ∈ [0, 1]` within piece `i = ⌊PIECES · s⌋`, where
/// `s = √μ` if `SQRT`, else `s = μ`; coefficients rounded to f32.
#[derive(Clone, Debug)]
pub struct MuPolyFit<const PIECES: usize, const POWERS: usize, const SQRT: bool> {
    /// `coefficients[channel][power]` holds the coefficient of `t^(POWERS − 1 − power)` for
    /// every piece (Horner order: highest power first).
    coefficients: Box<[[[f32; PIECES]; POWERS]; 3]>,
    /// The largest relative error against the fitted function, measured at construction.
    max_relative_error: f64,
}

impl<const PIECES: usize, const POWERS: usize, const SQRT: bool> MuPolyFit<PIECES, POWERS, SQRT> {
    /// Fits `f` (per channel) and measures the fit; `None` when its largest relative error
    /// exceeds [`FIT_TOLERANCE`] or `f` is not positive and finite at every check point.
    #[must_use]
    pub fn new(f: impl Fn(f64) -> [f64; 3]) -> Option<Self> {
        let mut coefficients = Box::new([[[0.0f32; PIECES]; POWERS]; 3]);
        let degree = POWERS - 1;
        // Chebyshev–Lobatto points on [0, 1]: both ends included, so neighbouring pieces
        // agree where they meet.
        let nodes: [f64; POWERS] =
            std::array::from_fn(|j| 0.5 - 0.5 * (j as f64 * std::f64::consts::PI / degree as f64).cos());
        for piece in 0..PIECES {
            let values: [[f64; 3]; POWERS] = nodes.map(|t| f(Self::mu_of((piece as f64 + t) / PIECES as f64)));
            for (c, channel) in coefficients.iter_mut().enumerate() {
                let monomial = interpolate(&nodes, &values.map(|v| v[c]))?;
                for (power, row) in channel.iter_mut().enumerate() {
                    row[piece] = monomial[degree - power] as f32;
                }
            }
        }
        let mut fit = Self { coefficients, max_relative_error: 0.0 };
        const CHECKS_PER_PIECE: usize = 64;
        for j in 0..=PIECES * CHECKS_PER_PIECE {
            // Check at f32 cosines, the inputs the lanes see, spread as the pieces are.
            let s = j as f64 / (PIECES * CHECKS_PER_PIECE) as f64;
            let mu = f64::from(Self::mu_of(s) as f32);
            let exact = f(mu);
            let fitted = fit.eval_f64(mu);
            for c in 0..3 {
                if !(exact[c] > 0.0 && exact[c].is_finite()) {
                    return None;
                }
                let relative = (fitted[c] - exact[c]).abs() / exact[c];
                fit.max_relative_error = fit.max_relative_error.max(relative);
            }
        }
        (fit.max_relative_error <= FIT_TOLERANCE).then_some(fit)
    }

    /// `μ` at the fit's variable `s` (`s²` or `s`).
    fn mu_of(s: f64) -> f64 {
        if SQRT {
            s * s
        } else {
            s
        }
    }

    /// The largest relative error against the fitted function, measured at construction
    /// (f32 coefficients, evaluated in f64 at 64 f32 cosines per piece).
    #[must_use]
    pub fn max_relative_error(&self) -> f64 {
        self.max_relative_error
    }

    /// The fit at `μ` (clamped to `[0, 1]`) in f64 arithmetic, from the f32 coefficients.
    #[must_use]
    pub fn eval_f64(&self, mu: f64) -> [f64; 3] {
        let mu = mu.clamp(0.0, 1.0);
        let x = if SQRT { mu.sqrt() } else { mu } * PIECES as f64;
        let piece = (x as usize).min(PIECES - 1);
        let t = x - piece as f64;
        self.coefficients.map(|channel| channel.iter().fold(0.0, |y, row| y * t + f64::from(row[piece])))
    }

    /// The fit at `μ` (clamped to `[0, 1]`) per lane: the piece's coefficients read with one
    /// register permute each ([`Lanes::lookup8_f32_`] for 8 pieces, else
    /// [`Lanes::lookup_f32_`]), then Horner's rule with FMAs.
    #[inline(always)]
    #[must_use]
    pub fn eval_lanes<L: Lanes>(&self, mu: L) -> Rgb<L> {
        let mu = lanes::clamp(mu, L::c(0.0), L::c(1.0));
        let x = if SQRT { lanes::sqrt(mu) } else { mu } * L::c(PIECES as f64);
        // A NaN cosine: the SIMD clamp (`max`/`min`) turns it into 0, so the lane gets F(0);
        // lanes whose clamp keeps NaN read piece 0 (the lookups send NaN to entry 0) and stay
        // NaN through `t`. Either way in bounds; the batch calls zero invalid elements.
        let piece = lanes::min(x.floor_(), L::c((PIECES - 1) as f64));
        let t = x - piece;
        // Written out per channel, not with a closure: closures are not inlined into the
        // `#[target_feature]` kernels, and the intrinsics would become calls.
        Rgb::new(
            horner(&self.coefficients[0], piece, t),
            horner(&self.coefficients[1], piece, t),
            horner(&self.coefficients[2], piece, t),
        )
    }
}

/// One channel of [`MuPolyFit::eval_lanes`]: the piece's coefficients and Horner's rule.
#[inline(always)]
fn horner<L: Lanes, const PIECES: usize, const POWERS: usize>(rows: &[[f32; PIECES]; POWERS], piece: L, t: L) -> L {
    let lookup = |row: &[f32; PIECES]| {
        if PIECES == 8 {
            L::lookup8_f32_(row, piece)
        } else {
            L::lookup_f32_(row, piece)
        }
    };
    let mut y = lookup(&rows[0]);
    let mut power = 1;
    while power < POWERS {
        y = lanes::mul_add(y, t, lookup(&rows[power]));
        power += 1;
    }
    y
}

/// The monomial coefficients (constant first) of the polynomial through `(nodes[j], values[j])`,
/// by Gaussian elimination with partial pivoting on the Vandermonde system; `None` if singular.
fn interpolate<const N: usize>(nodes: &[f64; N], values: &[f64; N]) -> Option<[f64; N]> {
    // Rows of the Vandermonde matrix, each with its right-hand side.
    let mut a: [([f64; N], f64); N] = std::array::from_fn(|j| {
        let mut p = 1.0;
        let row = std::array::from_fn(|_| {
            let entry = p;
            p *= nodes[j];
            entry
        });
        (row, values[j])
    });
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i].0[col].abs().total_cmp(&a[j].0[col].abs()))?;
        if a[pivot].0[col] == 0.0 || !a[pivot].0[col].is_finite() {
            return None;
        }
        a.swap(col, pivot);
        let (pivot_row, pivot_rhs) = a[col];
        for (row, rhs) in a.iter_mut().skip(col + 1) {
            let factor = row[col] / pivot_row[col];
            for (entry, p) in row.iter_mut().zip(pivot_row.iter()).skip(col) {
                *entry -= factor * p;
            }
            *rhs -= factor * pivot_rhs;
        }
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let tail: f64 = (row + 1..N).map(|k| a[row].0[k] * x[k]).sum();
        x[row] = (a[row].1 - tail) / a[row].0[row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_reproduces_a_quintic_exactly() {
        // A degree-5 polynomial is its own interpolant: the fit's only error is f32 rounding
        // of the coefficients (~6e-8 relative for values of order 1).
        let p = |x: f64| 1.0 + x * (0.5 + x * (-0.25 + x * (0.125 + x * (0.3 + x * 0.2))));
        let fit = MuFit32::new(|x| [p(x), 2.0 * p(x), 3.0 + x]).expect("a quintic fits");
        assert!(fit.max_relative_error() < 2e-7, "{}", fit.max_relative_error());
    }

    #[test]
    fn interpolation_in_sqrt_mu_reproduces_a_degree_7_polynomial_of_sqrt_mu_exactly() {
        // A degree-7 polynomial of √μ is degree 7 in each piece's position t: the 8-piece
        // fit's only error is the f32 rounding of its coefficients.
        let p = |s: f64| 0.5 + s * (0.25 + s * (-0.5 + s * (0.75 + s * (0.1 + s * (-0.2 + s * (0.3 - s * 0.05))))));
        let fit = SqrtMuFit8::new(|mu| [p(mu.sqrt()), 1.0 + mu, 2.0 * p(mu.sqrt())]).expect("fits");
        assert!(fit.max_relative_error() < 2e-7, "{}", fit.max_relative_error());
        // The f64 evaluation places μ as the lanes do (piece ⌊8√μ⌋).
        for mu in [0.0, 1e-6, 0.015625, 0.3, 0.999, 1.0] {
            let got = fit.eval_f64(mu)[0];
            assert!((got - p(mu.sqrt())).abs() < 2e-7 * p(mu.sqrt()), "{mu}: {got}");
        }
    }

    #[test]
    fn a_kink_is_refused() {
        // |x − 0.3| + 0.1 has a kink inside piece 9: no quintic gets within 1e-6 of it there.
        assert!(MuFit32::new(|x| [(x - 0.3).abs() + 0.1; 3]).is_none());
        // … nor a degree-7 polynomial in √μ (the kink is at √0.3 ≈ 0.548, inside piece 4).
        assert!(SqrtMuFit8::new(|x| [(x - 0.3).abs() + 0.1; 3]).is_none());
    }

    #[test]
    fn a_zero_function_is_refused() {
        assert!(MuFit32::new(|_| [0.0; 3]).is_none());
        assert!(SqrtMuFit8::new(|_| [0.0; 3]).is_none());
    }
}
