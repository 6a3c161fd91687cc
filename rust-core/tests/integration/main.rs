//! The integration tests of the `lacquer` crate, in one test binary: each file under
//! `tests/` would otherwise be linked against the whole crate on its own, which dominated the
//! compile time of CI's test step. Run one group with e.g.
//! `cargo test -p lacquer --test integration varying::`.

use std::sync::Mutex;

mod all_models;
mod batch;
mod fuzz_regressions;
mod golden;
mod rough_coat_flakes;
mod shared_lobes;
mod varying;

/// The SIMD level and thread count are process-wide (`batch::set_simd_level`,
/// `batch::set_thread_count`): the tests that change them, in any module, take turns.
pub static GLOBAL: Mutex<()> = Mutex::new(());
