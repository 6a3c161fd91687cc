//! Coated car paint: a clearcoat over a basecoat of pigment, metallic flakes and pearlescent
//! (thin-film) flakes. See [`coated_paint`] for the model and its derivation.

pub mod basecoat;
pub mod coat;
pub mod coated_paint;
pub mod flakes;
pub mod position_free_mc;
pub mod rough_dielectric;
pub mod sparkle;
pub mod thin_film;

pub use crate::sampling::{hammersley3, radical_inverse};
