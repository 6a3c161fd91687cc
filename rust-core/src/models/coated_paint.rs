//! Registry entry for the coated paint model, which lives in [`crate::paint`].

pub use crate::paint::coated_paint::{CoatedPaint, INFO};
