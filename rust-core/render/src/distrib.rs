//! Piecewise-constant distributions in 1D and 2D (pbrt's `Distribution1D/2D`), for light
//! selection and environment-map importance sampling.

/// A piecewise-constant density on `[0, 1)` with `n` equal cells.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// Builds from non-negative cell values (negative or non-finite count as 0). An all-zero
    /// function becomes uniform.
    #[must_use]
    pub fn new(values: &[f32]) -> Self {
        let n = values.len().max(1);
        let mut func: Vec<f32> = values.iter().map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 }).collect();
        if func.is_empty() {
            func.push(0.0);
        }
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += func[i] as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if !(integral > 0.0) {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
            func.iter_mut().for_each(|f| *f = 1.0);
            return Self { func, cdf, integral: 0.0 };
        }
        for c in cdf.iter_mut() {
            *c /= integral;
        }
        cdf[n] = 1.0;
        Self { func, cdf, integral }
    }

    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True when there are no cells (never: an empty input becomes one zero cell).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫ f` over `[0, 1)` (0 when the input was all zero).
    #[must_use]
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Samples a continuous position: `(x ∈ [0, 1), density, cell)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // The cell with cdf[i] ≤ u < cdf[i + 1] (so never a zero-width cell).
        let i = self.cdf[1..n].partition_point(|&c| c <= u).min(n - 1);
        let lo = self.cdf[i];
        let width = self.cdf[i + 1] - lo;
        let du = if width > 0.0 { ((u - lo) / width).clamp(0.0, 1.0) } else { 0.5 };
        let x = ((i as f32 + du) / n as f32).min(1.0 - f32::EPSILON);
        (x, self.density_of(i), i)
    }

    /// Samples a cell: `(cell, probability)`.
    #[inline]
    #[must_use]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32) {
        let (_, _, i) = self.sample(u);
        (i, self.probability(i))
    }

    /// Probability of cell `i` under [`Distribution1D::sample_discrete`].
    #[inline]
    #[must_use]
    pub fn probability(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Density at cell `i` (with respect to `x ∈ [0, 1)`).
    #[inline]
    #[must_use]
    pub fn density_of(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// Density at `x ∈ [0, 1)`.
    #[inline]
    #[must_use]
    pub fn density(&self, x: f32) -> f32 {
        let n = self.func.len();
        self.density_of(((x * n as f32) as usize).min(n - 1))
    }
}

/// Walker's alias table (Vose's construction): O(1) sampling of a discrete distribution with
/// one or two memory accesses, which matters for large environment maps.
#[derive(Clone, Debug)]
pub struct AliasTable {
    bins: Vec<AliasBin>,
}

#[derive(Clone, Copy, Debug)]
struct AliasBin {
    /// Probability of keeping this bin rather than jumping to `alias`.
    keep: f32,
    /// The other bin sharing this slot.
    alias: u32,
    /// Probability of this bin.
    pmf: f32,
}

impl AliasTable {
    /// Builds from non-negative weights (negative or non-finite count as 0; all zero → uniform).
    #[must_use]
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len().max(1);
        let w: Vec<f64> = (0..n)
            .map(|i| weights.get(i).copied().filter(|v| v.is_finite() && *v > 0.0).unwrap_or(0.0) as f64)
            .collect();
        let total: f64 = w.iter().sum();
        let pmf: Vec<f64> = if total > 0.0 { w.iter().map(|v| v / total).collect() } else { vec![1.0 / n as f64; n] };
        let mut bins: Vec<AliasBin> =
            pmf.iter().enumerate().map(|(i, p)| AliasBin { keep: 1.0, alias: i as u32, pmf: *p as f32 }).collect();
        let mut scaled: Vec<f64> = pmf.iter().map(|p| p * n as f64).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
        while !small.is_empty() && !large.is_empty() {
            let (s, l) = (small.pop().unwrap_or_default(), *large.last().unwrap_or(&0));
            bins[s].keep = scaled[s] as f32;
            bins[s].alias = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Leftovers are 1 up to rounding.
        for i in small.into_iter().chain(large) {
            bins[i].keep = 1.0;
            bins[i].alias = i as u32;
        }
        Self { bins }
    }

    /// Number of bins.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// True when there are no bins (never: an empty input becomes one bin).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    /// Samples a bin: `(bin, its probability, a fresh uniform number in [0, 1) left over from u)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: f32) -> (usize, f32, f32) {
        let n = self.bins.len();
        let x = u * n as f32;
        let i = (x as usize).min(n - 1);
        let frac = (x - i as f32).clamp(0.0, 1.0);
        let b = self.bins[i];
        if frac < b.keep {
            (i, b.pmf, (frac / b.keep).min(ONE_MINUS_EPS))
        } else {
            let j = b.alias as usize;
            (j, self.bins[j].pmf, ((frac - b.keep) / (1.0 - b.keep)).clamp(0.0, ONE_MINUS_EPS))
        }
    }

    /// Probability of bin `i`.
    #[inline]
    #[must_use]
    pub fn pmf(&self, i: usize) -> f32 {
        self.bins[i].pmf
    }
}

const ONE_MINUS_EPS: f32 = 1.0 - f32::EPSILON / 2.0;

/// A piecewise-constant density on `[0, 1)²` over `width × height` cells: a marginal over rows
/// (v) and a conditional per row (u), both alias tables.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<AliasTable>,
    marginal: AliasTable,
    width: usize,
}

impl Distribution2D {
    /// Builds from `width × height` values, row-major.
    #[must_use]
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        let rows: Vec<AliasTable> = (0..height).map(|r| AliasTable::new(&values[r * width..(r + 1) * width])).collect();
        let row_sums: Vec<f32> = (0..height)
            .map(|r| values[r * width..(r + 1) * width].iter().filter(|v| v.is_finite() && **v > 0.0).sum())
            .collect();
        Self { rows, marginal: AliasTable::new(&row_sums), width }
    }

    /// Samples `(u, v)` and the density with respect to area in `[0, 1)²`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: [f32; 2]) -> ([f32; 2], f32) {
        let h = self.rows.len();
        let (row, pr, dv) = self.marginal.sample(u[1]);
        let (col, pc, du) = self.rows[row].sample(u[0]);
        let uv = [(col as f32 + du) / self.width as f32, (row as f32 + dv) / h as f32];
        (uv.map(|x| x.min(ONE_MINUS_EPS)), pr * pc * (self.width * h) as f32)
    }

    /// Density at `(u, v)`.
    #[inline]
    #[must_use]
    pub fn density(&self, uv: [f32; 2]) -> f32 {
        let h = self.rows.len();
        let row = ((uv[1] * h as f32) as usize).min(h - 1);
        let col = ((uv[0] * self.width as f32) as usize).min(self.width - 1);
        self.marginal.pmf(row) * self.rows[row].pmf(col) * (self.width * h) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_d_probabilities_and_inverse() {
        let d = Distribution1D::new(&[1.0, 3.0, 0.0, 4.0]);
        assert!((d.probability(0) - 0.125).abs() < 1e-6);
        assert!((d.probability(1) - 0.375).abs() < 1e-6);
        assert_eq!(d.probability(2), 0.0);
        assert!((d.probability(3) - 0.5).abs() < 1e-6);
        // u in the middle of cell 1's cdf range lands in the middle of cell 1.
        let (x, pdf, i) = d.sample(0.125 + 0.375 / 2.0);
        assert_eq!(i, 1);
        assert!((x - 0.375).abs() < 1e-6);
        assert!((pdf - 1.5).abs() < 1e-6); // 3 / integral 2
                                           // Zero cells are never chosen.
        for k in 0..1000 {
            let (_, _, i) = d.sample(k as f32 / 1000.0);
            assert_ne!(i, 2);
        }
    }

    #[test]
    fn alias_frequencies_match_pmf() {
        let w = [0.5, 0.0, 3.0, 1.5, 0.01];
        let t = AliasTable::new(&w);
        let total: f32 = w.iter().sum();
        let n = 200_000;
        let mut counts = [0usize; 5];
        let mut rng = lacquer::rng::Pcg32::new(5, 0);
        let mut leftover_mean = 0.0;
        for _ in 0..n {
            let (i, p, r) = t.sample(rng.uniform() as f32);
            assert!((p - w[i] / total).abs() < 1e-6);
            counts[i] += 1;
            leftover_mean += r as f64 / n as f64;
        }
        for i in 0..5 {
            let f = counts[i] as f32 / n as f32;
            assert!((f - w[i] / total).abs() < 0.005, "bin {i}: {f} vs {}", w[i] / total);
        }
        assert_eq!(counts[1], 0);
        assert!((leftover_mean - 0.5).abs() < 0.01);
    }

    #[test]
    fn two_d_density_integrates_to_one() {
        let (w, h) = (8, 4);
        let vals: Vec<f32> = (0..w * h).map(|i| (i % 5) as f32 + 0.5 * (i / w) as f32).collect();
        let d = Distribution2D::new(&vals, w, h);
        let n = 64;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                sum += d.density([(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32]);
            }
        }
        assert!((sum / (n * n) as f32 - 1.0).abs() < 1e-4);
        let (uv, pdf) = d.sample([0.3, 0.7]);
        assert!((pdf - d.density(uv)).abs() < 1e-4 * pdf);
    }
}
