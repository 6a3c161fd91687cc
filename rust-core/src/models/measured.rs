//! Registry entry for the measured (tabulated) model, which lives in [`crate::measured`].

pub use crate::measured::{Measured, INFO};
