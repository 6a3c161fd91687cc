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

/// The SIMD levels this CPU runs, for the tests that compare every level. A CPU without AVX2 +
/// FMA would leave only the scalar path, which would skip the lane kernels' comparisons: that
/// fails here, as any skip does in this project, unless `LACQUER_ALLOW_SKIP=1` outside CI.
/// AVX-512 is tested where the CPU has it (CI hosts differ).
pub fn simd_levels() -> Vec<lacquer::batch::SimdLevel> {
    use lacquer::batch::SimdLevel;
    if !SimdLevel::Avx2.supported() {
        let ci = matches!(std::env::var("CI").as_deref(), Ok("true" | "1"));
        let allowed = std::env::var("LACQUER_ALLOW_SKIP").as_deref() == Ok("1") && !ci;
        assert!(allowed, "this CPU has no AVX2 + FMA: the lane kernels would go untested (LACQUER_ALLOW_SKIP=1 allows it outside CI)");
        eprintln!("no AVX2 + FMA: the lane kernels are not tested on this CPU");
    }
    // A build with one instruction set's kernels only (`--cfg lacquer_simd_kernels`, the fuzz
    // smoke build's) would leave the other set's comparisons out: that fails too.
    #[cfg(target_arch = "x86_64")]
    for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
        assert!(
            level.compiled(),
            "this build has no {} kernels (--cfg lacquer_simd_kernels): they would go untested",
            level.name()
        );
    }
    [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512].into_iter().filter(|l| l.supported()).collect()
}
