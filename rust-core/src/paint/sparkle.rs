//! Sparkle: the flake lobes of the basecoat resolved into individual flakes at a surface point
//! with a pixel footprint.
//!
//! The mean flake lobe `c · R(wi·h) D(h) G2 / (4 cos θi cos θo)` (see [`super::flakes`]) is what
//! a footprint holding infinitely many flakes sees. A real footprint holds a finite, random
//! number of flakes; a flake reflects toward the viewer only when its normal is (nearly) the
//! half vector `h`. With a surface point and footprint, each flake population's lobe is
//! multiplied by
//!
//! `m(h, x) = n(h, x) / (N p)`,
//!
//! where `N` is the expected number of flakes in the footprint, `p` the probability that one
//! flake's normal falls in the direction cell of `h`, and `n(h, x)` the number that actually
//! do, drawn deterministically for the footprint at `x`. `E[m] = 1` exactly, so the average
//! over positions is the smooth lobe; `Var[m] = 1/(N p)`, so sparkle fades as the footprint
//! grows.
//!
//! ## Flakes as a point process
//! Flake centres form a Poisson process of density `c / A_flake` on the surface (`c` the area
//! coverage, `A_flake = π (d/2)²` for diameter `d`), each flake's normal independently drawn
//! from the projected-area distribution `D(m) cos θm` (all flakes have the same area, so
//! weighting by projected area is weighting by flake). A footprint of physical area `A`
//! (uv area × `surface_scale_mm²`, in µm²) then holds `Poisson(N)` flakes with `N = c A /
//! A_flake`, and the counts in disjoint direction cells are *independent* `Poisson(N p)`
//! (Poisson thinning). This is the discrete microfacet model of Jakob et al. 2014 with the
//! particles placed by a Poisson process. Jakob et al. fix the particle count of the whole
//! surface and split it hierarchically with binomial draws; Deliot & Belcour 2023 draw
//! `Binomial(N, p)` per texel. We use Poisson because (a) at paint coverages (thesis: 0–8 %)
//! flakes are dilute and nothing fixes their number inside a footprint, (b) for `p = 1/K²`
//! the two laws differ by at most `p` in total variation (Le Cam), and (c) sums of independent
//! Poisson counts are Poisson, which makes the level-of-detail blend below *exact*.
//!
//! ## Direction cells
//! The half vector `h` (in the binder, where the flakes are) is mapped to the unit square by
//! inverting the full-distribution sampler: the radial CDF of `D(m) cos θm`
//! ([`crate::microfacet::Microfacet::radial_cdf`], `1 − e^{−tan²θ/α²}` for Beckmann) gives
//! the squared radius on the unit disk and `h`'s azimuth the angle; the inverse concentric
//! map ([`crate::sampling::concentric_disk_inverse`], equal-area) takes the disk to the
//! square. A `K × K` grid on the square is then a partition of the half-vector hemisphere into
//! cells of probability exactly `p = 1/K²` each. We use the concentric map rather than the
//! polar `(u1, u2) → (θ, φ)` map of the sampler itself because the polar grid's cells around
//! the lobe's peak are `K` thin wedges meeting at the normal, whereas the concentric cells
//! are nearly square there (slope width `√π α / K`).
//!
//! Each spatial cell shifts its direction grid by its own random offset on the torus of the
//! square (as Deliot & Belcour randomise their slope grid per surface cell): cells stay
//! equal-probability, and glints across the surface do not switch on and off along shared
//! direction boundaries when the light moves.
//!
//! **Choice of `K`.** A direction cell is the angular extent of one flake's glint. A flat
//! mirror disc of diameter `d` reflects into an Airy pattern whose central lobe spans
//! `2.44 λ/d` in the reflected direction, i.e. `δ = 1.22 λ/d` in half-vector angle (`h` turns
//! half as fast as the reflection); inside the binder the wavelength is `λ/η`. Setting the
//! central cell width `√π α / K` to `δ = 1.22 λ / (η d)` with `λ = 0.55 µm` (mid-visible):
//!
//! `K = round(√π α η d / (1.22 λ))`, clamped to `[1, 1024]`.
//!
//! So larger flakes give narrower, more directional glints and more cells, and `K` scales with
//! the lobe width `α`. Coat η = 1.5, orientation 12° (α = 0.213): `d` = 15, 20, 25 µm give
//! `K` = 13, 17, 21 (`p` = 1/169, 1/289, 1/441). Equal-probability cells are wider in
//! angle in the lobe's tails (solid angle `1/(K² D cos θ)`) than the diffraction width; each
//! flake still carries exactly `1/N` of the lobe's energy. Real flakes are not perfectly flat,
//! so `δ` is a lower bound on the glint width (an upper bound on `K`). `K = 1` (nearly
//! parallel flakes, orientation ≲ 0.6°) leaves only the spatial fluctuation of the count.
//!
//! ## Footprint and level of detail
//! Spatial cells are squares on a power-of-two grid in physical units: level `l` has side
//! `2^l √A_flake`, so a level-`l` cell holds `N_l = c 4^l` flakes on average, and level 0 is one
//! flake's area. The footprint's level is `ℓ = ½ log2(A / A_flake)`, clamped at 0: a footprint
//! smaller than a flake sees at most that flake, which then covers all of it (a lit level-0
//! cell reflects like a whole mirror flake, `c m = 1/p`). Between the two nearest levels
//! `l0 = ⌊ℓ⌋`, `l1 = l0 + 1` (`t = ℓ − l0`) we *distribute the count* over both grids
//! (Deliot & Belcour 2023): `n = n0 + n1` with `n0 ~ Poisson(w0 N_l0 p)` drawn in the `l0`
//! cell containing `x` and `n1 ~ Poisson(w1 N_l1 p)` in the `l1` cell, and weights
//!
//! `w1 = (4^t − 1)/3`, `w0 = 1 − w1`,
//!
//! chosen so that `w0 N_l0 + w1 N_l1 = N_l0 4^t = N`. Then `n ~ Poisson(N p)` *exactly*: at every
//! position the multiplier has the law of a footprint of area `A`, not only its mean. (Linearly
//! blending the two levels' ratios, as the LOD schemes of Zirr & Kaplanyan 2016 and Chermain et
//! al. 2020 do with their per-level NDFs, keeps the mean but under-estimates the variance by
//! up to 37 % midway; Deliot & Belcour's binomial distribution with weights `1 − t, t`
//! over-estimates it by up to 25 %.) The draw is continuous across integer `ℓ`: at `t → 1`,
//! `n0 → 0` and `n1` uses the level-`l1` key, which is the `l0` key just past the integer.
//!
//! Each count comes from a hash of (population, level, cell ix, iy, direction cell) — the
//! SplitMix64 finaliser (Steele, Lea & Flood 2014) — by inverting the Poisson CDF (exact for
//! `λ < 40`; above, the normal approximation with continuity correction, whose mean is
//! exact and whose skewness error is below `1/√40`). Deterministic and stable across frames;
//! for a fixed position the count only grows, one flake at a time, as the footprint grows.
//! Past `N p > 10¹²` (relative fluctuation below 10⁻⁶) the multiplier is exactly 1.
//!
//! ## Properties
//! - Keyed on the binder half vector, which is symmetric in `(wi, wo)`: `eval_at` is exactly
//!   as reciprocal as `eval`.
//! - `E_x[eval_at] = eval` for any footprint; `Var_x` of the flake part is
//!   `f_flake² / (N p)`.
//! - Not energy-conserving point by point (no stochastic glint model is): at a position the
//!   flake albedo is the mean one times (flakes present)/`N`; only the average over positions
//!   conserves energy. The furnace checks the mean lobe.
//! - Sampling draws the mean lobe (the pdf does not depend on the position) and weights by
//!   `eval_at · cos / pdf`: unbiased, with the variance that glints bring. Sampling the glints
//!   themselves (Chermain et al. 2021) is not done.
//!
//! Not modelled: the footprint's shape (Deliot & Belcour's anisotropic grids; we use its area
//! only), interpolation between neighbouring spatial cells, the wavelength dependence of the
//! glint width, overlap and stacking of flakes (hard-core placement), and spatial variation of
//! the pigment seen through pearl flakes and of the multiple-scattering lobe (both smooth).
//!
//! ## References
//! Jakob, Hašan, Yan, Lawrence, Ramamoorthi & Marschner 2014, "Discrete stochastic microfacet
//! models" (SIGGRAPH); Zirr & Kaplanyan 2016, "Real-time rendering of procedural multiscale
//! materials" (I3D); Chermain, Sauvage, Dischler & Dachsbacher 2020, "Procedural physically
//! based BRDF for real-time rendering of glints" (PG/CGF 39(7)); Chermain, Lucas, Sauvage,
//! Dischler & Dachsbacher 2021, "Real-time geometric glint anti-aliasing with normal map
//! filtering" (I3D) and Chermain et al. 2021, "Importance sampling of glittering BSDFs based on
//! finite mixture distributions" (EGSR); Deliot & Belcour 2023, "Real-time rendering of glinty
//! appearances using distributed binomial laws on anisotropic grids" (HPG/CGF 42(8));
//! Shirley & Chiu 1997 (concentric map); Born & Wolf (Airy pattern of a circular aperture).

use crate::bxdf::SurfacePoint;
use crate::math::Vec3;
use crate::microfacet::{DistributionKind, Microfacet};
use crate::sampling::concentric_disk_inverse;

/// Wavelength (µm) that sets the diffraction-limited glint width.
pub const WAVELENGTH_UM: f64 = 0.55;
/// Largest number of direction cells per axis.
pub const MAX_CELLS: u32 = 1024;
/// Above this expected count per direction cell the multiplier is exactly 1.
const SMOOTH_LIMIT: f64 = 1e12;
/// Poisson draws invert the CDF below this mean, and use the normal approximation above.
const POISSON_INVERSION_LIMIT: f64 = 40.0;

/// One flake population (metallic or pearlescent) and its sparkle parameters.
#[derive(Clone, Debug)]
pub struct FlakePopulation {
    /// Area coverage `c`, 0..1.
    pub coverage: f64,
    /// Flake diameter in µm.
    pub size_um: f64,
    /// `A_flake = π (d/2)²` in µm²: also the area of a level-0 spatial cell.
    pub flake_area_um2: f64,
    /// Direction cells per axis `K`.
    pub cells: u32,
    /// `p = 1/K²`.
    pub cell_probability: f64,
    seed: u64,
}

impl FlakePopulation {
    /// A population of coverage `c` and diameter `size_um` with `K` cells per axis.
    #[must_use]
    pub fn new(coverage: f64, size_um: f64, cells: u32, seed: u64) -> Self {
        let k = cells.clamp(1, MAX_CELLS);
        Self {
            coverage,
            size_um,
            flake_area_um2: std::f64::consts::PI * 0.25 * size_um * size_um,
            cells: k,
            cell_probability: 1.0 / (k as f64 * k as f64),
            seed,
        }
    }
}

/// The sparkle layer of a coated paint: the flakes' orientation distribution, the physical
/// scale of the uv parameterisation, and the flake populations.
#[derive(Clone, Debug)]
pub struct Sparkle {
    /// Beckmann α of the flake normals (shared by both populations).
    pub alpha: f64,
    /// Micrometres per uv unit.
    pub um_per_uv: f64,
    /// Metallic flakes (None without).
    pub metal: Option<FlakePopulation>,
    /// Pearlescent flakes (None without).
    pub pearl: Option<FlakePopulation>,
}

/// Seeds of the two populations' hash streams.
const METAL_SEED: u64 = 0x6d65_7461_6c5f_666c;
const PEARL_SEED: u64 = 0x7065_6172_6c5f_666c;

/// Direction cells per axis for flakes of diameter `size_um` whose normals have Beckmann
/// width `alpha`, under a coat of index `eta` (see the module docs).
#[must_use]
pub fn direction_cells(alpha: f64, eta: f64, size_um: f64) -> u32 {
    let glint_width = 1.22 * WAVELENGTH_UM / (eta.max(1.0) * size_um);
    let k = (std::f64::consts::PI.sqrt() * alpha / glint_width).round();
    if k.is_finite() {
        k.clamp(1.0, MAX_CELLS as f64) as u32
    } else {
        1
    }
}

impl Sparkle {
    /// The sparkle layer for flakes of Beckmann width `alpha` under a coat of index `eta`, on a
    /// surface where one uv unit is `surface_scale_mm`; `metal` and `pearl` are
    /// `(coverage, diameter µm)`. `None` when there are no flakes.
    #[must_use]
    pub fn new(alpha: f64, eta: f64, surface_scale_mm: f64, metal: (f64, f64), pearl: (f64, f64)) -> Option<Self> {
        let population = |(c, d): (f64, f64), seed| {
            (c > 0.0 && d > 0.0).then(|| FlakePopulation::new(c, d, direction_cells(alpha, eta, d), seed))
        };
        let metal = population(metal, METAL_SEED);
        let pearl = population(pearl, PEARL_SEED);
        (metal.is_some() || pearl.is_some()).then_some(Self { alpha, um_per_uv: surface_scale_mm * 1e3, metal, pearl })
    }

    /// Physical footprint area in µm².
    #[inline]
    #[must_use]
    pub fn footprint_area_um2(&self, at: &SurfacePoint) -> f64 {
        at.footprint_area() * self.um_per_uv * self.um_per_uv
    }

    /// Expected number of flakes of `pop` in the footprint, `N = c · max(A, A_flake)/A_flake`.
    #[must_use]
    pub fn expected_flakes(&self, pop: &FlakePopulation, at: &SurfacePoint) -> f64 {
        pop.coverage * (self.footprint_area_um2(at) / pop.flake_area_um2).max(1.0)
    }

    /// Position of the half vector `h` (binder, z up) on the unit square of the flakes'
    /// equal-probability direction grid.
    #[inline]
    #[must_use]
    pub fn direction_square(&self, h: Vec3<f64>) -> [f64; 2] {
        let mf = Microfacet::new(DistributionKind::Beckmann, self.alpha, self.alpha);
        let radius = mf.radial_cdf(h).clamp(0.0, 1.0).sqrt();
        let s = (h.x * h.x + h.y * h.y).sqrt();
        let (x, y) = if s > 0.0 { (radius * h.x / s, radius * h.y / s) } else { (0.0, 0.0) };
        let (a, b) = concentric_disk_inverse(x, y);
        [a, b]
    }

    /// Sparkle multipliers `(metal, pearl)` for the binder half vector `h` at `at`
    /// (1 for an absent population).
    #[inline]
    #[must_use]
    pub fn multipliers(&self, h: Vec3<f64>, at: &SurfacePoint) -> (f64, f64) {
        let square = self.direction_square(h);
        let m = self.metal.as_ref().map_or(1.0, |p| self.multiplier(p, square, at));
        let q = self.pearl.as_ref().map_or(1.0, |p| self.multiplier(p, square, at));
        (m, q)
    }

    /// The multiplier `n/(N p)` of one population for a direction-square position.
    #[must_use]
    pub fn multiplier(&self, pop: &FlakePopulation, square: [f64; 2], at: &SurfacePoint) -> f64 {
        let p = pop.cell_probability;
        let ratio = self.footprint_area_um2(at) / pop.flake_area_um2;
        // ℓ = ½ log2(A / A_flake), clamped at level 0 (NaN and zero areas included).
        let level = if ratio > 1.0 { 0.5 * ratio.log2() } else { 0.0 };
        let l0 = level.floor();
        let t = level - l0;
        let n0 = pop.coverage * 4f64.powf(l0);
        let four_t = 4f64.powf(t);
        let n = n0 * four_t;
        let mean = n * p;
        if !(mean <= SMOOTH_LIMIT) {
            return 1.0;
        }
        let w1 = (four_t - 1.0) / 3.0;
        let l0 = l0 as i64;
        let mut count = self.cell_count(pop, l0, square, at.uv, (1.0 - w1) * n0 * p);
        if w1 > 0.0 {
            count += self.cell_count(pop, l0 + 1, square, at.uv, w1 * 4.0 * n0 * p);
        }
        count / mean
    }

    /// The number of flakes of `pop` whose normals fall in the direction cell of `square`, in
    /// the level-`level` spatial cell containing `uv`, for an expected count `lambda`.
    fn cell_count(&self, pop: &FlakePopulation, level: i64, square: [f64; 2], uv: [f64; 2], lambda: f64) -> f64 {
        if !(lambda > 0.0) {
            return 0.0;
        }
        let side = pop.flake_area_um2.sqrt() * 2f64.powi(level as i32);
        let ix = (uv[0] * self.um_per_uv / side).floor() as i64;
        let iy = (uv[1] * self.um_per_uv / side).floor() as i64;
        let cell = hash(&[pop.seed, level as u64, ix as u64, iy as u64]);
        // Per-cell random shift of the direction grid on the torus of the square.
        let k = pop.cells as f64;
        let jx = ((square[0] + unit(mix64(cell ^ 0x51))).fract() * k) as u64;
        let jy = ((square[1] + unit(mix64(cell ^ 0xa3))).fract() * k) as u64;
        let max = pop.cells as u64 - 1;
        let u = unit(hash(&[cell, jx.min(max), jy.min(max)]));
        poisson_inverse(lambda, u)
    }
}

/// The SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mixer with full
/// avalanche.
#[inline]
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hash of a sequence of words.
#[inline]
fn hash(words: &[u64]) -> u64 {
    words.iter().fold(0x9e37_79b9_7f4a_7c15u64, |h, &w| mix64(h.wrapping_add(w).wrapping_mul(0x9e37_79b9_7f4a_7c15)))
}

/// A hash mapped to the open interval (0, 1) (53 bits).
#[inline]
fn unit(h: u64) -> f64 {
    ((h >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// The Poisson(`lambda`) count at probability `u ∈ (0, 1)`: the smallest `k` with
/// `P(X ≤ k) ≥ u` for `lambda < 40`; above, `⌊λ + √λ z + ½⌋` (clamped at 0) with `z` the
/// standard normal quantile of `u`.
#[must_use]
pub fn poisson_inverse(lambda: f64, u: f64) -> f64 {
    if !(lambda > 0.0) {
        return 0.0;
    }
    if lambda < POISSON_INVERSION_LIMIT {
        let mut term = (-lambda).exp();
        let mut cdf = term;
        let mut k = 0.0;
        while u > cdf {
            k += 1.0;
            term *= lambda / k;
            cdf += term;
            // Rounding can leave the summed CDF a few ulp short of 1: stop in the far tail.
            if k > lambda && term < 1e-17 * cdf {
                break;
            }
        }
        return k;
    }
    let z = std::f64::consts::SQRT_2 * crate::special::erfinv(2.0 * u - 1.0);
    (lambda + lambda.sqrt() * z + 0.5).floor().max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn at(uv: [f64; 2], side: f64) -> SurfacePoint {
        SurfacePoint { uv, duv_dx: [side, 0.0], duv_dy: [0.0, side] }
    }

    /// Mean and variance of the Poisson draws over a uniform grid of `u` equal `λ` (the
    /// inversion is exact; the normal branch to its O(1/λ) rounding).
    #[test]
    fn poisson_draws_have_poisson_moments() {
        for &lambda in &[1e-3, 0.05, 0.7, 3.0, 17.0, 39.0, 41.0, 300.0, 1e5] {
            let n = 200_000;
            let (mut s, mut s2) = (0.0, 0.0);
            for i in 0..n {
                let k = poisson_inverse(lambda, (i as f64 + 0.5) / n as f64);
                s += k;
                s2 += k * k;
            }
            let mean = s / n as f64;
            let var = s2 / n as f64 - mean * mean;
            // Stratified u: the error is the quadrature error of the step function, not noise.
            assert!((mean / lambda - 1.0).abs() < 2e-3 + 2.0 / (n as f64 * lambda), "λ {lambda}: mean {mean}");
            assert!((var / lambda - 1.0).abs() < 2e-2 + 4.0 / (n as f64 * lambda).sqrt(), "λ {lambda}: var {var}");
        }
        assert_eq!(poisson_inverse(0.0, 0.5), 0.0);
        assert_eq!(poisson_inverse(f64::NAN, 0.5), 0.0);
        assert!(poisson_inverse(30.0, 1.0 - 1e-16) < 100.0);
    }

    /// `K` from the diffraction width: hand evaluation of `√π α η d / (1.22 λ)` for the thesis
    /// sizes at 12° orientation under η = 1.5.
    #[test]
    fn direction_cells_follow_the_diffraction_width() {
        let alpha = 12f64.to_radians().tan();
        // √π · 0.21256 · 1.5 · d / (1.22 · 0.55) = 0.84226 · d ... rounded.
        assert_eq!(direction_cells(alpha, 1.5, 15.0), 13);
        assert_eq!(direction_cells(alpha, 1.5, 20.0), 17);
        assert_eq!(direction_cells(alpha, 1.5, 25.0), 21);
        assert_eq!(direction_cells(0.5f64.to_radians().tan(), 1.5, 20.0), 1);
        assert_eq!(direction_cells(60f64.to_radians().tan(), 2.5, 200.0), MAX_CELLS);
    }

    /// Normals drawn from `D cos θ` fall uniformly into the `K × K` direction cells (χ² test),
    /// so every cell has probability `1/K²`.
    #[test]
    fn direction_cells_are_equally_probable() {
        for &(alpha, k) in &[(0.2126f64, 17u32), (0.05, 5), (1.0, 9)] {
            let s = Sparkle::new(alpha, 1.5, 100.0, (0.03, 20.0), (0.0, 0.0)).unwrap();
            let mf = Microfacet::new(DistributionKind::Beckmann, alpha, alpha);
            let mut rng = Pcg32::new(11, k as u64);
            let cells = (k * k) as usize;
            let per_cell = 400.0;
            let n = (per_cell * cells as f64) as usize;
            let mut hist = vec![0.0f64; cells];
            for _ in 0..n {
                let m = mf.sample_m(Vec3::new(0.0, 0.0, 1.0), rng.uniform(), rng.uniform(), false);
                let [a, b] = s.direction_square(m);
                let (i, j) =
                    (((a * k as f64) as usize).min(k as usize - 1), ((b * k as f64) as usize).min(k as usize - 1));
                hist[i * k as usize + j] += 1.0;
            }
            let chi2: f64 = hist.iter().map(|o| (o - per_cell).powi(2) / per_cell).sum();
            let p = crate::check::stats::chi2_sf(chi2, (cells - 1) as f64);
            assert!(p > 1e-3, "α {alpha} K {k}: χ² {chi2} on {} dof, p {p}", cells - 1);
        }
    }

    /// The multiplier is continuous across integer levels of detail: just below and just above
    /// `ℓ = 3` the same flakes are counted.
    #[test]
    fn level_of_detail_is_continuous_across_levels() {
        let s = Sparkle::new(0.2126, 1.5, 100.0, (0.05, 20.0), (0.0, 0.0)).unwrap();
        let pop = s.metal.as_ref().unwrap();
        let side_uv = |level: f64| (pop.flake_area_um2 * 4f64.powf(level)).sqrt() / s.um_per_uv;
        let mut rng = Pcg32::new(5, 6);
        let mut differ = 0;
        for _ in 0..20_000 {
            let uv = [rng.range(0.0, 100.0), rng.range(0.0, 100.0)];
            let sq = [rng.uniform(), rng.uniform()];
            let below = s.multiplier(pop, sq, &at(uv, side_uv(3.0 - 1e-9)));
            let above = s.multiplier(pop, sq, &at(uv, side_uv(3.0 + 1e-9)));
            if (below - above).abs() > 1e-6 * above.max(1.0) {
                differ += 1;
            }
        }
        assert!(differ <= 2, "{differ} of 20000 positions jump across the level boundary");
    }

    /// Zero, tiny, huge and non-finite footprints and positions give finite, non-negative
    /// multipliers; a footprint past the smooth limit gives exactly 1.
    #[test]
    fn degenerate_footprints_are_finite() {
        let s = Sparkle::new(0.2126, 1.5, 100.0, (0.03, 20.0), (1e-9, 1.0)).unwrap();
        let h = Vec3::new(0.01f64, -0.02, 1.0).normalize();
        for side in [0.0, 1e-300, 1e-12, 1e-3, 1.0, 1e3, 1e150, f64::MAX] {
            for uv in [[0.0, 0.0], [-3.7, 1e6], [1e300, -1e300], [f64::NAN, 0.5]] {
                let (m, q) = s.multipliers(h, &at(uv, side));
                assert!(m.is_finite() && m >= 0.0 && q.is_finite() && q >= 0.0, "side {side} uv {uv:?}: {m} {q}");
            }
        }
        assert_eq!(s.multipliers(h, &at([0.3, 0.4], 1e6)).0, 1.0);
        for h in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1e-200, 0.0, 1.0)] {
            let [a, b] = s.direction_square(h);
            assert!((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b), "{h:?}: {a} {b}");
        }
    }
}
