//! Small tables of precomputed functions of `cos θ`, linearly interpolated.

use crate::lanes::{self, Lanes};
use crate::real::Real;

/// An RGB function of `μ = cos θ ∈ [0, 1]` sampled at evenly spaced nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct MuTable {
    values: Vec<[f64; 3]>,
    /// The node values rounded to f32, one array per channel, padded with the last node to a
    /// multiple of 16 entries (at least 32) for the lane types with register lookups
    /// ([`Lanes::lookup_pairs_f32_`]: AVX-512).
    lane_values: [Vec<f32>; 3],
    /// `n − 1` and `n − 2` for `n` nodes, as f32 (exact): the SIMD lookups' scale and last
    /// interval, read as f32 constants rather than converted from the length per call.
    lane_scale: [f32; 2],
    /// The same f32 values as rows for [`Lanes::lookup_rows3_f32_`] (SIMD lanes without
    /// register lookups): row `j` holds the three channels at node `j`, then at node `j + 1`.
    lane_rows: Vec<[f32; 8]>,
}

/// Rows of node `j` and node `j + 1` for [`Lanes::lookup_rows3_f32_`], the values rounded to f32.
fn lane_rows(values: &[[f64; 3]]) -> Vec<[f32; 8]> {
    values
        .windows(2)
        .map(|w| {
            let [a, b] = [w[0], w[1]].map(|v| v.map(|x| x as f32));
            [a[0], a[1], a[2], 0.0, b[0], b[1], b[2], 0.0]
        })
        .collect()
}

/// Per-channel f32 copies of `values`, padded for [`Lanes::lookup_f32_`].
fn lane_values(values: &[[f64; 3]]) -> [Vec<f32>; 3] {
    let padded = values.len().next_multiple_of(16).max(32);
    [0, 1, 2].map(|c| {
        let last = values[values.len() - 1][c] as f32;
        let mut v: Vec<f32> = values.iter().map(|x| x[c] as f32).collect();
        v.resize(padded, last);
        v
    })
}

impl MuTable {
    /// Tabulates `f(μ)` at `n ≥ 2` nodes `μ_k = k/(n−1)`.
    #[must_use]
    pub fn build(n: usize, mut f: impl FnMut(f64) -> [f64; 3]) -> Self {
        let n = n.max(2);
        Self::from_values((0..n).map(|k| f(k as f64 / (n - 1) as f64)).collect())
    }

    /// A table from node values at `μ_k = k/(n−1)` (`n ≥ 2`).
    #[must_use]
    pub fn from_values(values: Vec<[f64; 3]>) -> Self {
        assert!(values.len() >= 2, "a table needs at least two nodes");
        let last = values.len() - 1;
        Self {
            lane_values: lane_values(&values),
            lane_scale: [last as f32, (last - 1) as f32],
            lane_rows: lane_rows(&values),
            values,
        }
    }

    /// Node values.
    #[must_use]
    pub fn values(&self) -> &[[f64; 3]] {
        &self.values
    }

    /// Linear interpolation at `μ` (clamped to `[0, 1]`).
    #[inline]
    #[must_use]
    pub fn eval<T: Real>(&self, mu: T) -> [T; 3] {
        let last = self.values.len() - 1;
        let x = mu.f64().clamp(0.0, 1.0) * last as f64;
        let i = (x as usize).min(last - 1);
        let t = x - i as f64;
        let (a, b) = (self.values[i], self.values[i + 1]);
        [0, 1, 2].map(|c| T::of(a[c] + (b[c] - a[c]) * t))
    }

    /// [`MuTable::eval`] per lane (the interpolation weight in the lane precision; the
    /// table values, rounded to f32, looked up per lane: with AVX-512 by register permutes
    /// ([`Lanes::lookup_pairs_f32_`]; the hardware gather for tables of more than 64 nodes),
    /// with AVX2 one row of both neighbours' three channels per lane
    /// ([`Lanes::lookup_rows3_f32_`])).
    #[inline(always)]
    #[must_use]
    pub fn eval_lanes<L: Lanes>(&self, mu: L) -> [L; 3] {
        if L::WIDTH == 1 {
            // One lane (the scalar paths): one index for all three channels, interpolated in
            // f64 as `eval` does (six clamped per-lane gathers cost the scalar paths ~2×).
            let [a, b, c] = self.eval::<L::Elem>(mu.lane(0));
            return [L::splat(a), L::splat(b), L::splat(c)];
        }
        let (last, last_interval) = (L::c(f64::from(self.lane_scale[0])), L::c(f64::from(self.lane_scale[1])));
        let x = lanes::clamp(mu, L::c(0.0), L::c(1.0)) * last;
        let i = lanes::min(x.floor_(), last_interval);
        let t = x - i;
        let pairs = if L::REGISTER_LOOKUP {
            let [r, g, b] = &self.lane_values;
            L::lookup_pairs_f32_([r.as_slice(), g.as_slice(), b.as_slice()], i)
        } else {
            L::lookup_rows3_f32_(&self.lane_rows, i)
        };
        // A plain loop by reference, not a closure (which may not inline into the SIMD
        // kernels) nor an array's by-value iterator (which cost the release build 20 %).
        let mut out = [L::c(0.0); 3];
        for (o, &(a, b)) in out.iter_mut().zip(pairs.iter()) {
            *o = lanes::mul_add(b - a, t, a);
        }
        out
    }

    /// `2 ∫₀¹ f(μ) μ dμ` per channel (the cosine-weighted hemispherical average), by the
    /// trapezoid rule on the nodes (exact for the piecewise-linear interpolant times μ up to
    /// O(h²)).
    #[must_use]
    pub fn cosine_average(&self) -> [f64; 3] {
        let n = self.values.len();
        let h = 1.0 / (n - 1) as f64;
        let mut s = [0.0; 3];
        for k in 0..n - 1 {
            let (m0, m1) = (k as f64 * h, (k + 1) as f64 * h);
            for (c, acc) in s.iter_mut().enumerate() {
                let (a, b) = (self.values[k][c], self.values[k + 1][c]);
                // ∫ (a + (b−a)(μ−m0)/h) μ dμ over [m0, m1], exactly.
                *acc += h * (a * (2.0 * m0 + m1) + b * (m0 + 2.0 * m1)) / 6.0;
            }
        }
        s.map(|v| 2.0 * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_average_of_constant_and_linear() {
        let t = MuTable::build(17, |_| [1.0, 0.5, 0.0]);
        let a = t.cosine_average();
        assert!((a[0] - 1.0).abs() < 1e-14 && (a[1] - 0.5).abs() < 1e-14);
        // f(μ) = μ: 2∫μ² = 2/3, exact for a linear function.
        let t = MuTable::build(9, |m| [m; 3]);
        assert!((t.cosine_average()[0] - 2.0 / 3.0).abs() < 1e-14);
        assert!((t.eval(0.3f64)[0] - 0.3).abs() < 1e-14);
    }
}
