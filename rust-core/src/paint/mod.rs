//! Coated car paint: a clearcoat over a basecoat of pigment, metallic flakes and pearlescent
//! (thin-film) flakes. See [`coated_paint`] for the model and its derivation.

pub mod basecoat;
pub mod coat;
pub mod coated_paint;
pub mod flakes;
#[cfg(test)]
mod lobe_tests;
pub mod position_free_mc;
pub mod rough_dielectric;
pub mod sparkle;
pub mod spec_series;
pub mod thin_film;
pub mod varying;

pub use crate::sampling::{hammersley3, radical_inverse};

use crate::lanes::{self, Lanes};

/// The lobe [`crate::sampling::pick_lobe`] chooses among three non-negative weights, per lane:
/// one mask per lobe, the remapped `u` and where a lobe was chosen at all (positive total).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pick3<L: Lanes> {
    /// Lanes that chose each lobe.
    pub lobe: [L::Mask; 3],
    /// `u` remapped to `[0, 1)` inside the chosen lobe.
    pub u: L,
    /// Lanes with a positive total weight.
    pub valid: L::Mask,
}

/// [`crate::sampling::pick_lobe`] for three weights in lanes, with the same rules (a lobe of
/// zero weight is never chosen; rounding past the end falls back to the last positive weight)
/// and the same arithmetic, so one-lane results are identical.
#[inline(always)]
pub(crate) fn pick3<L: Lanes>(w: [L; 3], u: L) -> Pick3<L> {
    let zero = L::c(0.0);
    let total = w[0] + w[1] + w[2];
    let target = u * total;
    let acc2 = w[0] + w[1];
    let pos = [lanes::gt(w[0], zero), lanes::gt(w[1], zero), lanes::gt(w[2], zero)];
    let p0 = pos[0] & lanes::lt(target, w[0]);
    let p1 = !p0 & pos[1] & lanes::lt(target, acc2);
    let p2 = !p0 & !p1 & pos[2];
    let rest = !p0 & !p1 & !p2;
    let f1 = rest & pos[1];
    let f0 = rest & !pos[1];
    let hi = L::splat(crate::sampling::one_minus_epsilon::<L::Elem>());
    let r = lanes::select(
        p0,
        target / w[0],
        lanes::select(p1, (target - w[0]) / w[1], lanes::select(p2, (target - acc2) / w[2], hi)),
    );
    let valid = lanes::gt(total, zero);
    Pick3 { lobe: [p0 | f0, p1 | f1, p2], u: lanes::clamp(r, zero, hi), valid }
}
