//! Batch evaluation, density and sampling over arrays: the SIMD kernels, runtime CPU
//! dispatch and parallel execution that every host's batch call goes through.
//!
//! - **Layouts**: [`Src3`]/[`Dst3`] describe `n` 3-vectors as three component pointers and a
//!   stride (in elements): structure-of-arrays (stride 1), interleaved `xyz` (stride 3) and any
//!   strided layout a host holds, read and written in place without copies.
//! - **Lanes**: models with a lane implementation ([`Model::has_lane_kernel`]) run 16 (AVX-512)
//!   or 8 (AVX2 + FMA) elements per instruction; the level is detected once at run time
//!   ([`simd_level`]), so the library is built for baseline x86-64. Other models, and other
//!   CPUs, run one element at a time behind the same calls.
//! - **Threads**: batches of at least [`PARALLEL_MIN`] elements are split over a rayon pool of
//!   [`thread_count`] threads (default: all cores; [`set_thread_count`]). Results do not
//!   depend on the thread count: each element is computed the same way on any thread.
//! - **Inputs** are treated as `Material` treats them: directions need not be unit (they are
//!   normalised), a non-finite or zero-length direction makes that element invalid (zero
//!   outputs, counted in [`BatchReport`]). Inactive elements (`active[i] == 0`) get zero outputs
//!   and are not read for validation.

use crate::bxdf::{LaneSample, SurfacePoint};
use crate::frame::HORIZON_COS;
use crate::lanes::{self, Lanes, Mask};
use crate::lobes::LobeSelection;
use crate::material::Material;
use crate::math::{Rgb, Vec3};
use crate::models::{above_or_up, checked_sample, KernelVisitor, LaneKernel, Model};
use crate::paint::varying::{Element, PaintTexture, Vary, VaryingPaint};
use crate::real::Real;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Batches at least this long are split over threads (smaller ones run on the caller's thread).
pub const PARALLEL_MIN: usize = 1 << 15;
/// Elements per parallel work item.
const CHUNK: usize = 1 << 13;

/// The instruction set the batch kernels use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SimdLevel {
    /// One element at a time (any CPU).
    Scalar,
    /// 8 `f32` lanes, AVX2 + FMA (x86-64-v3).
    Avx2,
    /// 16 `f32` lanes, AVX-512F.
    Avx512,
}

impl SimdLevel {
    /// Lanes per instruction.
    #[must_use]
    pub fn width(self) -> usize {
        match self {
            SimdLevel::Scalar => 1,
            SimdLevel::Avx2 => 8,
            SimdLevel::Avx512 => 16,
        }
    }
    /// Name as `lacquer bench` and the environment variable spell it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
        }
    }
    /// The best level this CPU supports and this build has kernels for
    /// ([`SimdLevel::compiled`]).
    #[must_use]
    pub fn detect() -> Self {
        [SimdLevel::Avx512, SimdLevel::Avx2].into_iter().find(|l| l.supported()).unwrap_or(SimdLevel::Scalar)
    }
    /// True when this CPU can run the level and this build has its kernels.
    #[must_use]
    pub fn supported(self) -> bool {
        if !self.compiled() {
            return false;
        }
        match self {
            SimdLevel::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => is_x86_feature_detected!("avx512f"),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
    /// True when this build holds the level's kernels. Every build does (on x86-64), except
    /// one configured with `--cfg lacquer_simd_kernels="avx2"` or `"avx512"`, which holds that
    /// instruction set's kernels and the scalar path only: `fuzz/smoke.sh` builds so for the
    /// machine it runs on, whose runs never execute the other set's kernels, and the smoke
    /// build's compile shrinks by theirs (docs/reliability.md, "CI duration: session 45").
    #[must_use]
    pub const fn compiled(self) -> bool {
        match self {
            SimdLevel::Scalar => true,
            SimdLevel::Avx2 => cfg!(target_arch = "x86_64") && !cfg!(lacquer_simd_kernels = "avx512"),
            SimdLevel::Avx512 => cfg!(target_arch = "x86_64") && !cfg!(lacquer_simd_kernels = "avx2"),
        }
    }
}

static LEVEL: AtomicU8 = AtomicU8::new(u8::MAX);

/// The level in use: [`SimdLevel::detect`], unless lowered by [`set_simd_level`] or the
/// environment variable `LACQUER_SIMD` (`scalar`, `avx2`, `avx512`) read on first use.
#[must_use]
pub fn simd_level() -> SimdLevel {
    match LEVEL.load(Ordering::Relaxed) {
        0 => SimdLevel::Scalar,
        1 => SimdLevel::Avx2,
        2 => SimdLevel::Avx512,
        _ => {
            let detected = SimdLevel::detect();
            let wanted = match std::env::var("LACQUER_SIMD").as_deref() {
                Ok("scalar") => SimdLevel::Scalar,
                Ok("avx2") => SimdLevel::Avx2,
                _ => detected,
            };
            let level = if wanted.supported() { wanted } else { detected };
            set_simd_level(level);
            level
        }
    }
}

/// Selects the instruction set (for benchmarks and tests); a level the CPU lacks is refused
/// (returns false and changes nothing).
pub fn set_simd_level(level: SimdLevel) -> bool {
    if !level.supported() {
        return false;
    }
    let code = match level {
        SimdLevel::Scalar => 0,
        SimdLevel::Avx2 => 1,
        SimdLevel::Avx512 => 2,
    };
    LEVEL.store(code, Ordering::Relaxed);
    true
}

static THREADS: AtomicUsize = AtomicUsize::new(0);
static POOL: Mutex<Option<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// Limits the threads a large batch uses, and those a material build samples its tables on
/// (the paint's layer tables): 1 runs every batch and build on the calling thread; 0 (the
/// default) uses every core.
pub fn set_thread_count(n: usize) {
    THREADS.store(n, Ordering::Relaxed);
}

/// Threads a large batch uses ([`set_thread_count`]; 0 means all cores).
#[must_use]
pub fn thread_count() -> usize {
    match THREADS.load(Ordering::Relaxed) {
        0 => cores(),
        n => n,
    }
}

/// The cores this process may use, asked once: `available_parallelism` reads cgroup files
/// on every call (a renderer's small batches made it a quarter of their time).
fn cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

fn pool(threads: usize) -> Option<Arc<rayon::ThreadPool>> {
    let mut guard = POOL.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((n, p)) = guard.as_ref() {
        if *n == threads {
            return Some(p.clone());
        }
    }
    let p = Arc::new(
        rayon::ThreadPoolBuilder::new().num_threads(threads).thread_name(|i| format!("lacquer-{i}")).build().ok()?,
    );
    *guard = Some((threads, p.clone()));
    Some(p)
}

/// `n` read-only 3-vectors: element `i` is `(x[i·stride], y[i·stride], z[i·stride])`.
#[derive(Clone, Copy, Debug)]
pub struct Src3<'a, E> {
    p: [*const E; 3],
    stride: usize,
    n: usize,
    _life: PhantomData<&'a [E]>,
}

/// `n` writable 3-vectors (or colours), laid out as [`Src3`].
#[derive(Debug)]
pub struct Dst3<'a, E> {
    p: [*mut E; 3],
    stride: usize,
    n: usize,
    _life: PhantomData<&'a mut [E]>,
}

/// `n` writable scalars with a stride.
#[derive(Debug)]
pub struct Dst1<'a, E> {
    p: *mut E,
    stride: usize,
    n: usize,
    _life: PhantomData<&'a mut [E]>,
}

// SAFETY: the views are plain pointers into caller-owned arrays; kernels on different threads
// touch disjoint elements, and reads never race with writes (inputs and outputs are distinct
// arrays by the constructors' contracts).
unsafe impl<E: Sync> Send for Src3<'_, E> {}
unsafe impl<E: Sync> Sync for Src3<'_, E> {}
unsafe impl<E: Send> Send for Dst3<'_, E> {}
unsafe impl<E: Send> Sync for Dst3<'_, E> {}
unsafe impl<E: Send> Send for Dst1<'_, E> {}
unsafe impl<E: Send> Sync for Dst1<'_, E> {}

/// Why a view could not be built from slices.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayoutError(pub String);

impl std::fmt::Display for LayoutError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

fn check_len(name: &str, have: usize, need: usize) -> Result<(), LayoutError> {
    if have < need {
        return Err(LayoutError(format!("{name} holds {have} values, {need} needed")));
    }
    Ok(())
}

impl<'a, E> Src3<'a, E> {
    /// Structure of arrays: `x[i]`, `y[i]`, `z[i]`.
    pub fn soa(x: &'a [E], y: &'a [E], z: &'a [E]) -> Result<Self, LayoutError> {
        let n = x.len();
        check_len("y", y.len(), n)?;
        check_len("z", z.len(), n)?;
        Ok(Self { p: [x.as_ptr(), y.as_ptr(), z.as_ptr()], stride: 1, n, _life: PhantomData })
    }
    /// Interleaved `x0 y0 z0 x1 y1 z1 …` (`xyz.len() / 3` elements).
    #[must_use]
    pub fn interleaved(xyz: &'a [E]) -> Self {
        let n = xyz.len() / 3;
        let p = xyz.as_ptr();
        // SAFETY: offsets 1 and 2 stay inside (or one past the end of) the slice.
        Self { p: [p, p.wrapping_add(1), p.wrapping_add(2)], stride: 3, n, _life: PhantomData }
    }
    /// A view from raw pointers (the C ABI's strided layouts).
    ///
    /// # Safety
    /// For every `i < n`, `x.add(i * stride)` (and `y`, `z`) is readable for `'a`.
    #[must_use]
    pub unsafe fn from_raw(x: *const E, y: *const E, z: *const E, stride: usize, n: usize) -> Self {
        Self { p: [x, y, z], stride, n, _life: PhantomData }
    }
    /// Number of elements.
    #[must_use]
    pub fn len(&self) -> usize {
        self.n
    }
    /// True when there are no elements.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
}

impl<'a, E> Dst3<'a, E> {
    /// Structure of arrays.
    pub fn soa(x: &'a mut [E], y: &'a mut [E], z: &'a mut [E]) -> Result<Self, LayoutError> {
        let n = x.len();
        check_len("y", y.len(), n)?;
        check_len("z", z.len(), n)?;
        Ok(Self { p: [x.as_mut_ptr(), y.as_mut_ptr(), z.as_mut_ptr()], stride: 1, n, _life: PhantomData })
    }
    /// Interleaved `xyz` / `rgb`.
    #[must_use]
    pub fn interleaved(xyz: &'a mut [E]) -> Self {
        let n = xyz.len() / 3;
        let p = xyz.as_mut_ptr();
        Self { p: [p, p.wrapping_add(1), p.wrapping_add(2)], stride: 3, n, _life: PhantomData }
    }
    /// A view from raw pointers.
    ///
    /// # Safety
    /// For every `i < n`, `x.add(i * stride)` (and `y`, `z`) is writable for `'a`, and no other
    /// view reads or writes those elements meanwhile.
    #[must_use]
    pub unsafe fn from_raw(x: *mut E, y: *mut E, z: *mut E, stride: usize, n: usize) -> Self {
        Self { p: [x, y, z], stride, n, _life: PhantomData }
    }
}

impl<'a, E> Dst1<'a, E> {
    /// A contiguous array.
    #[must_use]
    pub fn new(v: &'a mut [E]) -> Self {
        Self { p: v.as_mut_ptr(), stride: 1, n: v.len(), _life: PhantomData }
    }
    /// A view from a raw pointer.
    ///
    /// # Safety
    /// As [`Dst3::from_raw`].
    #[must_use]
    pub unsafe fn from_raw(p: *mut E, stride: usize, n: usize) -> Self {
        Self { p, stride, n, _life: PhantomData }
    }
}

impl<E> Src3<'_, E> {
    /// The view copied into a local: its pointers and stride then stay in registers for the
    /// whole element loop instead of being reloaded through a reference on every lane group
    /// (the kernels' stores through raw pointers could alias any reference the compiler
    /// cannot prove otherwise).
    #[inline(always)]
    fn local_copy(&self) -> Src3<'_, E> {
        Src3 { p: self.p, stride: self.stride, n: self.n, _life: PhantomData }
    }
    /// True for the interleaved layout `x0 y0 z0 x1 …` (stride 3, components adjacent).
    #[inline(always)]
    fn is_xyz(&self) -> bool {
        self.stride == 3 && self.p[1] == self.p[0].wrapping_add(1) && self.p[2] == self.p[0].wrapping_add(2)
    }
}

impl<E> Dst3<'_, E> {
    /// As [`Src3::local_copy`]; the copy writes the same elements and lives no longer than
    /// the borrow of the original, so only the kernel that holds the original may use it.
    #[inline(always)]
    fn local_copy(&self) -> Dst3<'_, E> {
        Dst3 { p: self.p, stride: self.stride, n: self.n, _life: PhantomData }
    }
    /// True for the interleaved layout (as [`Src3::is_xyz`]).
    #[inline(always)]
    fn is_xyz(&self) -> bool {
        self.stride == 3 && self.p[1] == self.p[0].wrapping_add(1) && self.p[2] == self.p[0].wrapping_add(2)
    }
}

impl<E: Copy> Src3<'_, E> {
    /// Element `i`.
    ///
    /// # Safety
    /// `i < n`.
    #[inline(always)]
    unsafe fn get(&self, i: usize) -> [E; 3] {
        // SAFETY: the caller guarantees i < n; the constructor that every element is readable.
        unsafe { self.p.map(|p| *p.add(i * self.stride)) }
    }
}

impl<E: Copy> Dst3<'_, E> {
    /// Element `i` (as last written).
    ///
    /// # Safety
    /// `i < n`, and no other thread writes element `i` meanwhile.
    #[inline(always)]
    unsafe fn get(&self, i: usize) -> [E; 3] {
        // SAFETY: as above.
        unsafe { self.p.map(|p| *p.add(i * self.stride)) }
    }
    /// Writes element `i`.
    ///
    /// # Safety
    /// As [`Dst3::get`].
    #[inline(always)]
    unsafe fn set(&self, i: usize, v: [E; 3]) {
        for (p, v) in self.p.iter().zip(v) {
            // SAFETY: as above.
            unsafe { *p.add(i * self.stride) = v };
        }
    }
}

impl<E> Dst1<'_, E> {
    /// As [`Dst3::local_copy`].
    #[inline(always)]
    fn local_copy(&self) -> Dst1<'_, E> {
        Dst1 { p: self.p, stride: self.stride, n: self.n, _life: PhantomData }
    }
}

impl<E: Copy> Dst1<'_, E> {
    /// Element `i` (as last written). Safety: as [`Dst3::get`].
    #[inline(always)]
    unsafe fn get(&self, i: usize) -> E {
        // SAFETY: as Dst3::get.
        unsafe { *self.p.add(i * self.stride) }
    }
    /// Writes element `i`. Safety: as [`Dst3::get`].
    #[inline(always)]
    unsafe fn set(&self, i: usize, v: E) {
        // SAFETY: as Dst3::get.
        unsafe { *self.p.add(i * self.stride) = v };
    }
}

/// What a batch call found wrong with its inputs (active elements only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchReport {
    /// Elements with a non-finite or zero-length direction (outputs set to zero).
    pub invalid_directions: usize,
    /// The first such element.
    pub first_invalid_direction: Option<usize>,
    /// Elements with a non-finite `u` (sampling; outputs set to zero).
    pub invalid_u: usize,
    /// The first such element.
    pub first_invalid_u: Option<usize>,
    /// Elements whose per-element paint parameters were out of range or not finite (the
    /// `*_varying` calls; outputs set to zero).
    pub invalid_params: usize,
    /// The first such element.
    pub first_invalid_param: Option<usize>,
}

impl BatchReport {
    /// True when every active element was valid.
    #[must_use]
    pub fn ok(&self) -> bool {
        self.invalid_directions == 0 && self.invalid_u == 0 && self.invalid_params == 0
    }
    fn merge(self, o: Self) -> Self {
        let first = |a: Option<usize>, b: Option<usize>| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Self {
            invalid_directions: self.invalid_directions + o.invalid_directions,
            first_invalid_direction: first(self.first_invalid_direction, o.first_invalid_direction),
            invalid_u: self.invalid_u + o.invalid_u,
            first_invalid_u: first(self.first_invalid_u, o.first_invalid_u),
            invalid_params: self.invalid_params + o.invalid_params,
            first_invalid_param: first(self.first_invalid_param, o.first_invalid_param),
        }
    }
    #[cold]
    #[inline(never)]
    fn record<M: Mask>(&mut self, start: usize, width: usize, bad_dir: M, bad_u: M) {
        for j in 0..width {
            if bad_dir.lane(j) {
                self.invalid_directions += 1;
                self.first_invalid_direction.get_or_insert(start + j);
            } else if bad_u.lane(j) {
                self.invalid_u += 1;
                self.first_invalid_u.get_or_insert(start + j);
            }
        }
    }
    #[cold]
    #[inline(never)]
    fn record_params<M: Mask>(&mut self, start: usize, width: usize, bad: M) {
        for j in (0..width).filter(|&j| bad.lane(j)) {
            self.invalid_params += 1;
            self.first_invalid_param.get_or_insert(start + j);
        }
    }
}

/// Lanes `start..start + width` of one component (missing lanes of a short tail hold `pad`).
#[inline(always)]
unsafe fn load_comp<L: Lanes>(p: *const L::Elem, stride: usize, start: usize, width: usize, pad: L::Elem) -> L {
    if width == L::WIDTH && stride == 1 {
        // SAFETY: elements start..start+WIDTH exist (caller) and are contiguous.
        unsafe { L::load_ptr(p.add(start)) }
    } else {
        assert!(L::WIDTH <= lanes::MAX_WIDTH);
        let mut buf = [pad; lanes::MAX_WIDTH];
        for (j, b) in buf.iter_mut().enumerate().take(width) {
            // SAFETY: only lanes below `width` are read.
            *b = unsafe { *p.add((start + j) * stride) };
        }
        // SAFETY: WIDTH ≤ MAX_WIDTH values in the buffer.
        unsafe { L::load_ptr(buf.as_ptr()) }
    }
}

/// Lanes `start..start + width` of a 3-vector view (missing lanes of a short tail hold `pad`).
#[inline(always)]
unsafe fn load3<L: Lanes>(s: &Src3<L::Elem>, start: usize, width: usize, pad: [f64; 3]) -> Vec3<L> {
    let of = <L::Elem as Real>::of;
    if s.is_xyz() {
        // Interleaved `x y z`: contiguous loads deinterleaved in registers (a short tail
        // through a padded copy) rather than a gather per component.
        // SAFETY: the caller guarantees start + width ≤ n: values 3·start … 3·(start + width)
        // exist.
        let p = unsafe { s.p[0].add(3 * start) };
        let [x, y, z] = if width == L::WIDTH {
            unsafe { L::load_xyz_ptr(p) }
        } else {
            assert!(L::WIDTH <= lanes::MAX_WIDTH);
            let mut buf = [of(0.0); 3 * lanes::MAX_WIDTH];
            for (j, b) in buf.iter_mut().enumerate().take(3 * L::WIDTH) {
                *b = if j < 3 * width { unsafe { *p.add(j) } } else { of(pad[j % 3]) };
            }
            // SAFETY: 3·WIDTH ≤ 3·MAX_WIDTH values in the buffer.
            unsafe { L::load_xyz_ptr(buf.as_ptr()) }
        };
        return Vec3::new(x, y, z);
    }
    // SAFETY: the caller guarantees start + width ≤ n.
    unsafe {
        Vec3::new(
            load_comp::<L>(s.p[0], s.stride, start, width, of(pad[0])),
            load_comp::<L>(s.p[1], s.stride, start, width, of(pad[1])),
            load_comp::<L>(s.p[2], s.stride, start, width, of(pad[2])),
        )
    }
}

/// Stores lanes `start..start + width` into a 3-component view.
#[inline(always)]
unsafe fn store3<L: Lanes>(d: &Dst3<L::Elem>, start: usize, width: usize, v: [L; 3]) {
    if d.is_xyz() {
        // Interleaved: permuted in registers, contiguous stores (a short tail through a copy).
        // SAFETY: as in load3.
        let p = unsafe { d.p[0].add(3 * start) };
        if width == L::WIDTH {
            unsafe { L::store_xyz_ptr(v, p) };
        } else {
            assert!(L::WIDTH <= lanes::MAX_WIDTH);
            let mut buf = [<L::Elem as Real>::of(0.0); 3 * lanes::MAX_WIDTH];
            // SAFETY: 3·WIDTH ≤ 3·MAX_WIDTH values in the buffer; 3·width values at p are
            // writable.
            unsafe {
                L::store_xyz_ptr(v, buf.as_mut_ptr());
                std::ptr::copy_nonoverlapping(buf.as_ptr(), p, 3 * width);
            }
        }
        return;
    }
    // SAFETY: as in load3.
    unsafe {
        store_comp(d.p[0], d.stride, start, width, v[0]);
        store_comp(d.p[1], d.stride, start, width, v[1]);
        store_comp(d.p[2], d.stride, start, width, v[2]);
    }
}

#[inline(always)]
unsafe fn store_comp<L: Lanes>(p: *mut L::Elem, stride: usize, start: usize, width: usize, v: L) {
    if width == L::WIDTH && stride == 1 {
        // SAFETY: as in load3.
        unsafe { v.store_ptr(p.add(start)) }
    } else {
        assert!(L::WIDTH <= lanes::MAX_WIDTH);
        let mut buf = [<L::Elem as Real>::of(0.0); lanes::MAX_WIDTH];
        // SAFETY: WIDTH ≤ MAX_WIDTH.
        unsafe { v.store_ptr(buf.as_mut_ptr()) };
        for (j, b) in buf.iter().enumerate().take(width) {
            // SAFETY: lane j < width exists.
            unsafe { *p.add((start + j) * stride) = *b }
        }
    }
}

#[inline(always)]
unsafe fn store1<L: Lanes>(d: &Dst1<L::Elem>, start: usize, width: usize, v: L) {
    // SAFETY: as in load3.
    unsafe { store_comp(d.p, d.stride, start, width, v) }
}

/// How the element loops read and write a view of three components of a plain call ([`DenseViews`]):
/// interleaved `xyz` (`Some(true)`), unit-stride components (`Some(false)`), or neither
/// (`None`: only the general loop).
#[inline(always)]
fn dense_layout(interleaved: bool, stride: usize) -> Option<bool> {
    if interleaved {
        Some(true)
    } else {
        (stride == 1).then_some(false)
    }
}

impl<E> Src3<'_, E> {
    /// [`dense_layout`] of this view.
    #[inline(always)]
    fn dense(&self) -> Option<bool> {
        dense_layout(self.is_xyz(), self.stride)
    }
}

impl<E> Dst3<'_, E> {
    /// [`dense_layout`] of this view.
    #[inline(always)]
    fn dense(&self) -> Option<bool> {
        dense_layout(self.is_xyz(), self.stride)
    }
}

/// How many elements ahead of the lane group in hand the dense loops prefetch their views
/// ([`prefetch_group`]); a multiple of every lane width, so the prefetched group is whole.
/// The GGX eval from memory (session 43) took 2.19 / 2.13 / 2.15 / 2.28 / 2.57 ns per element
/// with 64 / 128 / 256 / 512 / 1024.
const PREFETCH_AHEAD: usize = 128;

/// Prefetches the cache lines of `count` values from `p` (into the first-level cache, for
/// writing if `WRITE`); nothing on other architectures. A prefetch reads nothing and faults
/// on no address.
#[inline(always)]
fn prefetch_lines<E, const WRITE: bool>(p: *const E, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_ET0, _MM_HINT_T0};
        let bytes = count * core::mem::size_of::<E>();
        let mut k = 0;
        while k < bytes {
            let line = p.cast::<i8>().wrapping_add(k);
            // SAFETY: a prefetch is a hint; it dereferences nothing.
            unsafe {
                if WRITE {
                    _mm_prefetch::<_MM_HINT_ET0>(line);
                } else {
                    _mm_prefetch::<_MM_HINT_T0>(line);
                }
            }
            k += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, count);
}

/// Prefetches the dense views' lane group of `width` elements from element `at` (inputs for
/// reading, outputs for writing). The loops call it for the group [`PREFETCH_AHEAD`] elements
/// ahead: kernels with some arithmetic per group run too few loads for the hardware
/// prefetchers to keep ahead on batches that come from memory. Session 43: the GGX eval of
/// 10⁶ interleaved elements took 2.1 ns per element from the last-level cache and 3.0 after
/// an eviction (numpy's add of the same arrays 1.2 either way); with this, 2.15 either way.
#[inline(always)]
fn prefetch_group<E>(
    srcs: [(&Src3<E>, bool); 2],
    dsts: [Option<(&Dst3<E>, bool)>; 2],
    dst1: Option<&Dst1<E>>,
    at: usize,
    width: usize,
) {
    for (s, xyz) in srcs {
        if xyz {
            prefetch_lines::<E, false>(s.p[0].wrapping_add(3 * at), 3 * width);
        } else {
            for c in s.p {
                prefetch_lines::<E, false>(c.wrapping_add(at), width);
            }
        }
    }
    for (d, xyz) in dsts.into_iter().flatten() {
        if xyz {
            prefetch_lines::<E, true>(d.p[0].wrapping_add(3 * at).cast_const(), 3 * width);
        } else {
            for c in d.p {
                prefetch_lines::<E, true>(c.wrapping_add(at).cast_const(), width);
            }
        }
    }
    if let Some(d) = dst1 {
        prefetch_lines::<E, true>(d.p.wrapping_add(at).cast_const(), width);
    }
}

/// The full lane group at `start` of a dense view (`xyz` as [`Src3::dense`] reported it).
///
/// # Safety
/// `start + WIDTH ≤ n` and `s.dense() == Some(xyz)`.
#[inline(always)]
unsafe fn load3_full<L: Lanes>(s: &Src3<L::Elem>, xyz: bool, start: usize) -> Vec3<L> {
    // SAFETY: the caller's contract: the group's values exist in the reported layout.
    unsafe {
        if xyz {
            let [x, y, z] = L::load_xyz_ptr(s.p[0].add(3 * start));
            Vec3::new(x, y, z)
        } else {
            Vec3::new(L::load_ptr(s.p[0].add(start)), L::load_ptr(s.p[1].add(start)), L::load_ptr(s.p[2].add(start)))
        }
    }
}

/// Stores the full lane group at `start` of a dense view.
///
/// # Safety
/// As [`load3_full`].
#[inline(always)]
unsafe fn store3_full<L: Lanes>(d: &Dst3<L::Elem>, xyz: bool, start: usize, v: [L; 3]) {
    // SAFETY: as load3_full.
    unsafe {
        if xyz {
            L::store_xyz_ptr(v, d.p[0].add(3 * start));
        } else {
            v[0].store_ptr(d.p[0].add(start));
            v[1].store_ptr(d.p[1].add(start));
            v[2].store_ptr(d.p[2].add(start));
        }
    }
}

/// [`sanitize`] for a pair of directions, with one test for the common case (both unit).
#[inline(always)]
fn sanitize_pair<L: Lanes>(a: Vec3<L>, o: Vec3<L>) -> (Vec3<L>, Vec3<L>, L::Mask) {
    let tolerance = L::c(64.0) * L::splat(<L::Elem as num_traits::Float>::epsilon());
    let a_unit = lanes::le(lanes::abs(a.length_squared() - L::c(1.0)), tolerance);
    let o_unit = lanes::le(lanes::abs(o.length_squared() - L::c(1.0)), tolerance);
    if (a_unit & o_unit).all() {
        return (a, o, L::Mask::splat(true));
    }
    let ((a, a_ok), (o, o_ok)) = (sanitize(a), sanitize(o));
    (a, o, a_ok & o_ok)
}

/// Active lanes: all below `width`, and those whose `active` byte is non-zero.
#[inline(always)]
fn active_lanes<L: Lanes>(active: Option<&[u8]>, start: usize, width: usize) -> L::Mask {
    if active.is_none() && width == L::WIDTH {
        return L::Mask::splat(true);
    }
    assert!(L::WIDTH <= lanes::MAX_WIDTH);
    let mut buf = [<L::Elem as Real>::of(0.0); lanes::MAX_WIDTH];
    for (j, b) in buf.iter_mut().enumerate().take(width) {
        if active.is_none_or(|a| a[start + j] != 0) {
            *b = <L::Elem as Real>::of(1.0);
        }
    }
    // SAFETY: WIDTH ≤ MAX_WIDTH values in the buffer.
    let flags = unsafe { L::load_ptr(buf.as_ptr()) };
    lanes::gt(flags, L::c(0.5))
}

/// Per lane: the direction is usable (finite, non-zero length), and its unit version (the
/// same test and normalisation as `Material`).
#[inline(always)]
fn sanitize<L: Lanes>(w: Vec3<L>) -> (Vec3<L>, L::Mask) {
    let l2 = w.length_squared();
    let eps = <L::Elem as num_traits::Float>::epsilon();
    // The common case, one test for the group: every direction is unit (within 64 ulp of
    // length 1; NaN fails the test), hence usable and left as it is.
    if lanes::le(lanes::abs(l2 - L::c(1.0)), L::c(64.0) * L::splat(eps)).all() {
        return (w, L::Mask::splat(true));
    }
    let usable = lanes::gt(l2, L::c(0.0)) & lanes::is_finite(l2);
    let off_unit = lanes::gt(lanes::abs(l2 - L::c(1.0)), L::c(64.0) * L::splat(eps));
    // `w / |w|` as `Material` computes it, so the f64 batch path is bit-identical to it.
    let len = lanes::select(off_unit, lanes::sqrt(l2), L::c(1.0));
    (w / len, usable)
}

const UP: [f64; 3] = [0.0, 0.0, 1.0];

/// Whether the kernels of `K` at lane type `L` first run a plain call's full lane groups in
/// a loop of their own ([`eval_pdf_full_groups`], [`sample_full_groups`]): the SIMD kernels
/// of the small lane models ([`LaneKernel::SMALL`]). A constant item, so that the compiler
/// drops the branch, and never instantiates that loop, where it is off.
struct FullGroups<L, K>(core::marker::PhantomData<(L, K)>);

impl<L: Lanes, K: LaneKernel> FullGroups<L, K> {
    const ON: bool = L::WIDTH > 1 && K::SMALL;
}

/// [`LaneKernel::PAIRED`] as constant items, for the tests in [`Args::run_paired`].
struct PairedKernels<K>(core::marker::PhantomData<K>);

impl<K: LaneKernel> PairedKernels<K> {
    const EVAL_PDF: bool = K::PAIRED.eval_pdf;
    const SAMPLE: bool = K::PAIRED.sample;
}

/// The layouts of a plain call's dense views, decided once per call: the element loops read
/// and write such a call's full lane groups directly ([`load3_full`], [`store3_full`])
/// instead of through the general per-group layout tests and masks.
#[derive(Clone, Copy)]
struct DenseViews {
    /// Interleaved (`true`) or unit-stride components, per view ([`Src3::dense`]); outputs
    /// the call does not write are `false`.
    xyz: [bool; 4],
}

impl DenseViews {
    /// The layouts when every view is dense (a density view of stride 1), else `None`.
    #[inline(always)]
    fn of<E>(inputs: [&Src3<E>; 2], outputs: [Option<&Dst3<E>>; 2], density: Option<&Dst1<E>>) -> Option<Self> {
        if density.is_some_and(|p| p.stride != 1) {
            return None;
        }
        let [a, b] = inputs;
        let [c, d] = outputs.map(|o| o.map(Dst3::dense));
        Some(Self { xyz: [a.dense()?, b.dense()?, c.unwrap_or(Some(false))?, d.unwrap_or(Some(false))?] })
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn eval_pdf_kernel<L: Lanes, K: LaneKernel>(
    model: &K,
    range: (usize, usize),
    wi: &Src3<L::Elem>,
    wo: &Src3<L::Elem>,
    active: Option<&[u8]>,
    f: Option<&Dst3<L::Elem>>,
    pdf: Option<&Dst1<L::Elem>>,
    scale: Option<Scales<L::Elem>>,
    lobes: Option<u32>,
) -> BatchReport {
    let mut report = BatchReport::default();
    let (wi, wo) = (&wi.local_copy(), &wo.local_copy());
    let (f, pdf) = (f.map(Dst3::local_copy), pdf.map(Dst1::local_copy));
    let (f, pdf) = (f.as_ref(), pdf.as_ref());
    // A lobe mask of none of the lobes: zero values and densities.
    let nothing = lobes == Some(0);
    // A plain call (every element active, no scales, no lobe mask) with dense views: its
    // full lane groups take direct loads and stores, one test for the group's directions and
    // no masks. The model calls below are written once for both paths (a second copy of
    // them per kernel cost minutes of compile time, docs/reliability.md).
    let dense = if active.is_none() && scale.is_none() && lobes.is_none() {
        DenseViews::of([wi, wo], [f, None], pdf)
    } else {
        None
    };
    // The layouts and whether they apply as plain values (an `Option` of them per group
    // costs selects in the loop).
    let (is_dense, d) = (dense.is_some(), dense.unwrap_or(DenseViews { xyz: [false; 4] }));
    let full_end = range.0 + (range.1 - range.0) / L::WIDTH * L::WIDTH;
    let mut start = range.0;
    if FullGroups::<L, K>::ON && is_dense {
        start = eval_pdf_full_groups::<L, K>(model, range, wi, wo, f, pdf, &mut report);
    }
    let f_view = f.map(|f| (f, d.xyz[2]));
    while start < range.1 {
        let width = L::WIDTH.min(range.1 - start);
        let fast = is_dense && start < full_end;
        if L::WIDTH > 1 && fast && start + PREFETCH_AHEAD < full_end {
            prefetch_group([(wi, d.xyz[0]), (wo, d.xyz[1])], [f_view, None], pdf, start + PREFETCH_AHEAD, L::WIDTH);
        }
        // The directions, the lanes that are active with usable directions, and the active
        // lanes with unusable ones.
        let (a, o, good, bad) = if fast {
            // SAFETY: start + WIDTH ≤ range.1 ≤ n for every view (checked by the public
            // functions), each read in the layout `DenseViews::of` found.
            let (a, o) = unsafe { (load3_full::<L>(wi, d.xyz[0], start), load3_full::<L>(wo, d.xyz[1], start)) };
            let (a, o, ok) = sanitize_pair(a, o);
            (a, o, ok, !ok)
        } else {
            // SAFETY: start + width ≤ n for every view (checked by the public functions).
            let (a, a_ok) = sanitize(unsafe { load3::<L>(wi, start, width, UP) });
            let (o, o_ok) = sanitize(unsafe { load3::<L>(wo, start, width, UP) });
            let (on, ok) = (active_lanes::<L>(active, start, width), a_ok & o_ok);
            (a, o, on & ok, on & !ok)
        };
        if bad.any() {
            report.record(start, width, bad, L::Mask::splat(false));
        }
        let keep = good & L::Mask::splat(!nothing);
        // No closures around the model calls (`Option::map`): a closure may not be inlined
        // into the `#[target_feature]` kernel, and then runs its lanes without the ISA.
        let (v, p) = if let (true, Some(_), Some(_), None, None) = (K::SHARES_EVAL_PDF, f, pdf, scale, lobes) {
            // Both outputs of a model whose value and density share work: one call.
            let (v, p) = model.eval_pdf(a, o);
            (Some(v), Some(p))
        } else {
            let one = <L::Elem as Real>::of(1.0);
            let v = if f.is_none() {
                None
            } else {
                Some(match (scale, lobes) {
                    (_, Some(0)) => Rgb::zero(),
                    (None, None) => model.eval(a, o),
                    (scale, l) => {
                        let sc = match scale {
                            // SAFETY: the scales hold the elements base..base + len ⊇
                            // start..start + width.
                            Some(sc) => unsafe {
                                [
                                    load_comp::<L>(sc.metal.as_ptr(), 1, start - sc.base, width, one),
                                    load_comp::<L>(sc.pearl.as_ptr(), 1, start - sc.base, width, one),
                                ]
                            },
                            None => [L::splat(one); 2],
                        };
                        // Every lobe is `eval_scaled` exactly (`LaneKernel::eval_lobes`): one
                        // call site for the scaled and the lobe-masked calls, so one inlined
                        // copy of the model's value in this kernel instead of three.
                        model.eval_lobes(a, o, sc, l.unwrap_or(crate::lobes::bits::SELECTABLE))
                    }
                })
            };
            let p = if pdf.is_none() {
                None
            } else {
                Some(match lobes {
                    None => model.pdf(a, o),
                    Some(0) => L::c(0.0),
                    Some(l) => model.pdf_lobes(a, o, l),
                })
            };
            (v, p)
        };
        if let (Some(f), Some(v)) = (f, v) {
            let v = Rgb::select(keep, v, Rgb::zero());
            let v = [v.r, v.g, v.b];
            // SAFETY: as the loads.
            unsafe {
                if fast {
                    store3_full(f, d.xyz[2], start, v);
                } else {
                    store3(f, start, width, v);
                }
            }
        }
        if let (Some(pdf), Some(p)) = (pdf, p) {
            let p = lanes::keep(keep, p);
            // SAFETY: as the loads; a dense call's `pdf` has stride 1.
            unsafe {
                if fast {
                    p.store_ptr(pdf.p.add(start));
                } else {
                    store1(pdf, start, width, p);
                }
            }
        }
        start += width;
    }
    report
}

/// The full lane groups of a plain call — every element active, no scales, no lobe mask,
/// every view dense ([`Src3::dense`]) — without the general loop's per-group layout tests
/// and masks: the common call of a renderer (the caller checks the mask, scales and lobe
/// mask). Returns where the general loop goes on: `range.0` when a view is not dense, else
/// the start of the tail (a partial group, or `range.1`).
#[inline(always)]
fn eval_pdf_full_groups<L: Lanes, K: LaneKernel>(
    model: &K,
    range: (usize, usize),
    wi: &Src3<L::Elem>,
    wo: &Src3<L::Elem>,
    f: Option<&Dst3<L::Elem>>,
    pdf: Option<&Dst1<L::Elem>>,
    report: &mut BatchReport,
) -> usize {
    let (Some(wi_xyz), Some(wo_xyz)) = (wi.dense(), wo.dense()) else {
        return range.0;
    };
    let f_xyz = match f.map(Dst3::dense) {
        Some(None) => return range.0,
        dense => dense.flatten().unwrap_or(false),
    };
    if pdf.is_some_and(|p| p.stride != 1) {
        return range.0;
    }
    let end = range.0 + (range.1 - range.0) / L::WIDTH * L::WIDTH;
    let f_view = f.map(|f| (f, f_xyz));
    let mut start = range.0;
    while start < end {
        if start + PREFETCH_AHEAD < end {
            prefetch_group([(wi, wi_xyz), (wo, wo_xyz)], [f_view, None], pdf, start + PREFETCH_AHEAD, L::WIDTH);
        }
        // SAFETY: start + WIDTH ≤ range.1 ≤ n for every view (checked by the public
        // functions), each read in the layout `dense` reported.
        let (a, o) = unsafe { (load3_full::<L>(wi, wi_xyz, start), load3_full::<L>(wo, wo_xyz, start)) };
        let (a, o, ok) = sanitize_pair(a, o);
        if !ok.all() {
            report.record(start, L::WIDTH, !ok, L::Mask::splat(false));
        }
        let (v, p) = match (f, pdf) {
            (Some(_), Some(_)) if K::SHARES_EVAL_PDF => {
                let (v, p) = model.eval_pdf(a, o);
                (Some(v), Some(p))
            }
            // No closures around the model calls (see `eval_pdf_kernel`).
            _ => {
                let v = if f.is_some() { Some(model.eval(a, o)) } else { None };
                let p = if pdf.is_some() { Some(model.pdf(a, o)) } else { None };
                (v, p)
            }
        };
        if let (Some(f), Some(v)) = (f, v) {
            let v = Rgb::select(ok, v, Rgb::zero());
            // SAFETY: as the loads.
            unsafe { store3_full(f, f_xyz, start, [v.r, v.g, v.b]) };
        }
        if let (Some(pdf), Some(p)) = (pdf, p) {
            // SAFETY: as the loads; `pdf` has stride 1 (checked above).
            unsafe { lanes::keep(ok, p).store_ptr(pdf.p.add(start)) };
        }
        start += L::WIDTH;
    }
    start
}

/// Outputs of [`sample`].
#[derive(Debug)]
pub struct SampleOut<'a, E> {
    /// Sampled directions.
    pub wi: Dst3<'a, E>,
    /// Weights `f cos θi / pdf`.
    pub weight: Dst3<'a, E>,
    /// Densities.
    pub pdf: Dst1<'a, E>,
    /// Optional per-element flags ([`SAMPLE_DELTA`], [`SAMPLE_FAILED`], [`SAMPLE_INVALID_INPUT`]).
    pub flags: Option<&'a mut [u32]>,
}

/// Flag: the sample comes from a Dirac delta lobe.
pub const SAMPLE_DELTA: u32 = 1;
/// Flag: no sample (wo below the surface or rejected); outputs are zero.
pub const SAMPLE_FAILED: u32 = 2;
/// Flag: the element's inputs were invalid; outputs are zero.
pub const SAMPLE_INVALID_INPUT: u32 = 4;

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sample_kernel<L: Lanes, K: LaneKernel>(
    model: &K,
    range: (usize, usize),
    wo: &Src3<L::Elem>,
    u: &Src3<L::Elem>,
    active: Option<&[u8]>,
    out: &SampleOut<L::Elem>,
    flags: Option<*mut u32>,
    lobes: Option<u32>,
) -> BatchReport {
    let mut report = BatchReport::default();
    let (wo, u) = (&wo.local_copy(), &u.local_copy());
    let out =
        &SampleOut { wi: out.wi.local_copy(), weight: out.weight.local_copy(), pdf: out.pdf.local_copy(), flags: None };
    // As in `eval_pdf_kernel`: a plain call's full groups of dense views load and store
    // directly; the sampler call is written once for both paths.
    let dense = if active.is_none() && lobes.is_none() {
        DenseViews::of([wo, u], [Some(&out.wi), Some(&out.weight)], Some(&out.pdf))
    } else {
        None
    };
    let (is_dense, d) = (dense.is_some(), dense.unwrap_or(DenseViews { xyz: [false; 4] }));
    let full_end = range.0 + (range.1 - range.0) / L::WIDTH * L::WIDTH;
    let mut start = range.0;
    if FullGroups::<L, K>::ON && is_dense {
        start = sample_full_groups::<L, K>(model, range, wo, u, out, flags, &mut report);
    }
    while start < range.1 {
        let width = L::WIDTH.min(range.1 - start);
        let fast = is_dense && start < full_end;
        if L::WIDTH > 1 && fast && start + PREFETCH_AHEAD < full_end {
            let outs = [Some((&out.wi, d.xyz[2])), Some((&out.weight, d.xyz[3]))];
            prefetch_group([(wo, d.xyz[0]), (u, d.xyz[1])], outs, Some(&out.pdf), start + PREFETCH_AHEAD, L::WIDTH);
        }
        // SAFETY: start + width ≤ n for every view (checked by `sample`); a dense group is
        // full and read in the layout `DenseViews::of` found.
        let (o, u_raw, on) = unsafe {
            if fast {
                (load3_full::<L>(wo, d.xyz[0], start), load3_full::<L>(u, d.xyz[1], start), L::Mask::splat(true))
            } else {
                (
                    load3::<L>(wo, start, width, UP),
                    load3::<L>(u, start, width, [0.5; 3]),
                    active_lanes::<L>(active, start, width),
                )
            }
        };
        let (o, o_ok) = sanitize(o);
        let (uc, u_ok) = uniforms(u_raw);
        if !((o_ok & u_ok) | !on).all() {
            report.record(start, width, on & !o_ok, on & !u_ok);
        }
        let s: LaneSample<L> = match lobes {
            None => model.sample(o, uc),
            Some(l) => {
                let s = model.sample_lobes(o, uc, l);
                LaneSample { valid: s.valid & L::Mask::splat(l != 0), ..s }
            }
        };
        match fast {
            true => {
                let inputs_ok = o_ok & u_ok;
                let (good, wi, weight, pdf) = zero_unless_good(inputs_ok, &s);
                // SAFETY: as the loads; the flags hold n values (the caller's contract).
                unsafe {
                    store3_full(&out.wi, d.xyz[2], start, wi);
                    store3_full(&out.weight, d.xyz[3], start, weight);
                    pdf.store_ptr(out.pdf.p.add(start));
                    if let Some(fl) = flags {
                        store_flags(fl, start, L::WIDTH, L::Mask::splat(true), inputs_ok, good, s.delta);
                    }
                }
            }
            // SAFETY: start + width ≤ n for every output (checked by `sample`).
            false => unsafe { store_sample(out, flags, start, width, on, on & o_ok & u_ok, &s) },
        }
        start += width;
    }
    report
}

/// Uniform numbers as the samplers take them: clamped into [0, 1), and which lanes were finite.
#[inline(always)]
fn uniforms<L: Lanes>(u: Vec3<L>) -> ([L; 3], L::Mask) {
    let below_one = <L::Elem as Real>::of(1.0) - <L::Elem as num_traits::Float>::epsilon() * <L::Elem as Real>::of(0.5);
    let (lo, hi) = (L::c(0.0), L::splat(below_one));
    let finite = lanes::is_finite(u.x) & lanes::is_finite(u.y) & lanes::is_finite(u.z);
    ([lanes::clamp(u.x, lo, hi), lanes::clamp(u.y, lo, hi), lanes::clamp(u.z, lo, hi)], finite)
}

/// As [`eval_pdf_full_groups`] for [`sample_kernel`] (every element active, no lobe mask,
/// every view dense).
#[inline(always)]
fn sample_full_groups<L: Lanes, K: LaneKernel>(
    model: &K,
    range: (usize, usize),
    wo: &Src3<L::Elem>,
    u: &Src3<L::Elem>,
    out: &SampleOut<L::Elem>,
    flags: Option<*mut u32>,
    report: &mut BatchReport,
) -> usize {
    let (Some(wo_xyz), Some(u_xyz)) = (wo.dense(), u.dense()) else {
        return range.0;
    };
    let (Some(wi_xyz), Some(weight_xyz)) = (out.wi.dense(), out.weight.dense()) else {
        return range.0;
    };
    if out.pdf.stride != 1 {
        return range.0;
    }
    let end = range.0 + (range.1 - range.0) / L::WIDTH * L::WIDTH;
    let mut start = range.0;
    while start < end {
        if start + PREFETCH_AHEAD < end {
            let outs = [Some((&out.wi, wi_xyz)), Some((&out.weight, weight_xyz))];
            prefetch_group([(wo, wo_xyz), (u, u_xyz)], outs, Some(&out.pdf), start + PREFETCH_AHEAD, L::WIDTH);
        }
        // SAFETY: start + WIDTH ≤ range.1 ≤ n for every view (checked by `sample`), each
        // read and written in the layout `dense` reported.
        let (o, o_ok) = sanitize(unsafe { load3_full::<L>(wo, wo_xyz, start) });
        let (uc, u_ok) = uniforms(unsafe { load3_full::<L>(u, u_xyz, start) });
        let inputs_ok = o_ok & u_ok;
        if !inputs_ok.all() {
            report.record(start, L::WIDTH, !o_ok, !u_ok);
        }
        let s = model.sample(o, uc);
        let (good, wi, weight, pdf) = zero_unless_good(inputs_ok, &s);
        // SAFETY: as the loads; the flags hold n values (the caller's contract).
        unsafe {
            store3_full(&out.wi, wi_xyz, start, wi);
            store3_full(&out.weight, weight_xyz, start, weight);
            pdf.store_ptr(out.pdf.p.add(start));
            if let Some(fl) = flags {
                store_flags(fl, start, L::WIDTH, L::Mask::splat(true), inputs_ok, good, s.delta);
            }
        }
        start += L::WIDTH;
    }
    start
}

/// A lane group of samples with zeros where the inputs or the sample are invalid: the mask
/// of good lanes, `wi`, the weight and the density.
#[inline(always)]
fn zero_unless_good<L: Lanes>(inputs_ok: L::Mask, s: &LaneSample<L>) -> (L::Mask, [L; 3], [L; 3], L) {
    let good = inputs_ok & s.valid;
    let wi = Vec3::select(good, s.wi, Vec3::zero());
    let weight = Rgb::select(good, s.weight, Rgb::zero());
    (good, [wi.x, wi.y, wi.z], [weight.r, weight.g, weight.b], lanes::keep(good, s.pdf))
}

/// Stores one lane group of samples (zero where the inputs or the sample are invalid) and
/// their flags: `on` the active lanes, `inputs_ok` the active lanes with valid inputs.
///
/// # Safety
/// `start + width` ≤ the length of every output view and of `flags`.
#[inline(always)]
unsafe fn store_sample<L: Lanes>(
    out: &SampleOut<L::Elem>,
    flags: Option<*mut u32>,
    start: usize,
    width: usize,
    on: L::Mask,
    inputs_ok: L::Mask,
    s: &LaneSample<L>,
) {
    let (good, wi, weight, pdf) = zero_unless_good(inputs_ok, s);
    // SAFETY: the caller guarantees the outputs hold start + width values.
    unsafe {
        store3(&out.wi, start, width, wi);
        store3(&out.weight, start, width, weight);
        store1(&out.pdf, start, width, pdf);
    }
    if let Some(fl) = flags {
        // SAFETY: as above.
        unsafe { store_flags(fl, start, width, on, inputs_ok, good, s.delta) };
    }
}

/// Writes the [`SampleOut::flags`] of one lane group.
///
/// # Safety
/// `fl` holds `start + width` values.
#[inline(always)]
unsafe fn store_flags<M: Mask>(fl: *mut u32, start: usize, width: usize, on: M, inputs_ok: M, good: M, delta: M) {
    for j in 0..width {
        let v = if !on.lane(j) {
            0
        } else if !inputs_ok.lane(j) {
            SAMPLE_FAILED | SAMPLE_INVALID_INPUT
        } else if !good.lane(j) {
            SAMPLE_FAILED
        } else if delta.lane(j) {
            SAMPLE_DELTA
        } else {
            0
        };
        // SAFETY: the flags slice holds start + width values (the caller's contract).
        unsafe { *fl.add(start + j) = v };
    }
}

/// Runs `kernel` over `0..n`, split over the thread pool when the batch is large.
fn run<K>(n: usize, kernel: K) -> BatchReport
where
    K: Fn(usize, usize) -> BatchReport + Sync,
{
    if n < PARALLEL_MIN {
        return kernel(0, n);
    }
    let threads = thread_count();
    if threads <= 1 {
        return kernel(0, n);
    }
    let Some(pool) = pool(threads) else {
        return kernel(0, n);
    };
    use rayon::prelude::*;
    let chunks = n.div_ceil(CHUNK);
    pool.install(|| {
        (0..chunks)
            .into_par_iter()
            .map(|c| kernel(c * CHUNK, ((c + 1) * CHUNK).min(n)))
            .reduce(BatchReport::default, BatchReport::merge)
    })
}

/// The arguments of one f32 batch call, so the per-level kernels have one signature.
#[derive(Clone, Copy)]
enum Args<'v, 'a> {
    EvalPdf {
        wi: &'v Src3<'a, f32>,
        wo: &'v Src3<'a, f32>,
        active: Option<&'a [u8]>,
        f: Option<&'v Dst3<'a, f32>>,
        pdf: Option<&'v Dst1<'a, f32>>,
        scale: Option<Scales<'v, f32>>,
        lobes: Option<u32>,
    },
    Sample {
        wo: &'v Src3<'a, f32>,
        u: &'v Src3<'a, f32>,
        active: Option<&'a [u8]>,
        out: &'v SampleOut<'a, f32>,
        flags: Option<*mut u32>,
        lobes: Option<u32>,
    },
}

// SAFETY: see the views' Send/Sync; `flags` points to disjoint elements per thread.
unsafe impl Send for Args<'_, '_> {}
unsafe impl Sync for Args<'_, '_> {}

impl Args<'_, '_> {
    /// The eval/pdf kernel for `range` (nothing for [`Args::Sample`]) at lane type `L`, or at
    /// the pair `P` of `L` groups when the model runs it paired
    /// ([`LaneBxdf::PAIRED`](crate::bxdf::LaneBxdf::PAIRED)): kernels bound by one group's
    /// dependency chain, whose two interleaved chains overlap. Constant tests, so only the
    /// chosen lane type's kernel is compiled. The eval/pdf and sampling kernels are separate
    /// functions at every instruction set, so that no compiled function holds both a model's
    /// eval/pdf and its sampler: the compile's memory grows faster than its functions' sizes
    /// (docs/reliability.md, "CI memory").
    #[inline(always)]
    fn run_eval_pdf<L: Lanes<Elem = f32>, P: Lanes<Elem = f32>, K: LaneKernel>(
        self,
        kernel: &K,
        range: (usize, usize),
    ) -> BatchReport {
        let Args::EvalPdf { wi, wo, active, f, pdf, scale, lobes } = self else {
            return BatchReport::default();
        };
        if PairedKernels::<K>::EVAL_PDF {
            eval_pdf_kernel::<P, K>(kernel, range, wi, wo, active, f, pdf, scale, lobes)
        } else {
            eval_pdf_kernel::<L, K>(kernel, range, wi, wo, active, f, pdf, scale, lobes)
        }
    }

    /// The sampling kernel for `range` (nothing for [`Args::EvalPdf`]); lane types as
    /// [`Args::run_eval_pdf`].
    #[inline(always)]
    fn run_sample<L: Lanes<Elem = f32>, P: Lanes<Elem = f32>, K: LaneKernel>(
        self,
        kernel: &K,
        range: (usize, usize),
    ) -> BatchReport {
        let Args::Sample { wo, u, active, out, flags, lobes } = self else {
            return BatchReport::default();
        };
        if PairedKernels::<K>::SAMPLE {
            sample_kernel::<P, K>(kernel, range, wo, u, active, out, flags, lobes)
        } else {
            sample_kernel::<L, K>(kernel, range, wo, u, active, out, flags, lobes)
        }
    }

    /// Runs the kernel for `range`: the model's own kernel (one loop per model, see
    /// [`Model::visit_kernel`]) at the selected instruction set.
    fn dispatch(self, model: &Model, range: (usize, usize)) -> BatchReport {
        model.visit_kernel(Dispatch { args: self, range })
    }
}

/// [`Args::dispatch`] once the model's kernel type is known.
struct Dispatch<'v, 'a> {
    args: Args<'v, 'a>,
    range: (usize, usize),
}

impl KernelVisitor for Dispatch<'_, '_> {
    type Output = BatchReport;

    #[inline(always)]
    fn visit<K: LaneKernel>(self, kernel: &K) -> BatchReport {
        let (args, range) = (self.args, self.range);
        let sample = matches!(args, Args::Sample { .. });
        #[cfg(target_arch = "x86_64")]
        {
            use crate::lanes::pair::X2;
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            use crate::lanes::x86::F32x16;
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            use crate::lanes::x86::F32x8;
            // One function per instruction set and operation (see `Args::run_eval_pdf`); an
            // instruction set left out of the build (`SimdLevel::compiled`) has none.
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            #[target_feature(enable = "avx2,fma")]
            fn avx2_eval_pdf<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
                args.run_eval_pdf::<F32x8, X2<F32x8>, K>(kernel, range)
            }
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            #[target_feature(enable = "avx2,fma")]
            fn avx2_sample<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
                args.run_sample::<F32x8, X2<F32x8>, K>(kernel, range)
            }
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            #[target_feature(enable = "avx512f")]
            fn avx512_eval_pdf<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
                args.run_eval_pdf::<F32x16, X2<F32x16>, K>(kernel, range)
            }
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            #[target_feature(enable = "avx512f")]
            fn avx512_sample<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
                args.run_sample::<F32x16, X2<F32x16>, K>(kernel, range)
            }
            if K::NATIVE {
                // SAFETY: simd_level() only reports levels the CPU has (detected at run time).
                match (simd_level(), sample) {
                    #[cfg(not(lacquer_simd_kernels = "avx2"))]
                    (SimdLevel::Avx512, false) => return unsafe { avx512_eval_pdf(args, kernel, range) },
                    #[cfg(not(lacquer_simd_kernels = "avx2"))]
                    (SimdLevel::Avx512, true) => return unsafe { avx512_sample(args, kernel, range) },
                    #[cfg(not(lacquer_simd_kernels = "avx512"))]
                    (SimdLevel::Avx2, false) => return unsafe { avx2_eval_pdf(args, kernel, range) },
                    #[cfg(not(lacquer_simd_kernels = "avx512"))]
                    (SimdLevel::Avx2, true) => return unsafe { avx2_sample(args, kernel, range) },
                    // The scalar level, or one this build has no kernels for (never selected:
                    // `SimdLevel::supported`).
                    _ => {}
                }
            }
        }
        // The scalar path out of line, per model and operation: inlined here it made one
        // function of every model's scalar kernels (`Args::dispatch`, 0.6 MB of machine code).
        #[inline(never)]
        fn scalar_eval_pdf<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
            args.run_eval_pdf::<f32, f32, K>(kernel, range)
        }
        #[inline(never)]
        fn scalar_sample<K: LaneKernel>(args: Args<'_, '_>, kernel: &K, range: (usize, usize)) -> BatchReport {
            args.run_sample::<f32, f32, K>(kernel, range)
        }
        if sample {
            scalar_sample(args, kernel, range)
        } else {
            scalar_eval_pdf(args, kernel, range)
        }
    }
}

fn check_views(n: usize, lens: &[(&str, usize)]) -> Result<(), LayoutError> {
    for &(name, len) in lens {
        check_len(name, len, n)?;
    }
    Ok(())
}

/// `f_r(wi, wo)` and/or the sampling density for `n = wi.len()` elements in f32, through the
/// SIMD kernels. `active` (optional) holds `n` bytes, 0 = inactive.
pub fn eval_pdf(
    m: &Material,
    wi: &Src3<f32>,
    wo: &Src3<f32>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f32>>,
    pdf: Option<&Dst1<f32>>,
) -> Result<BatchReport, LayoutError> {
    eval_pdf_impl(m, wi, wo, active, f, pdf, None)
}

/// The lobe mask of a [`LobeSelection`] as the kernels take it: `None` = every lobe (the
/// plain kernels), `Some(0)` = none.
fn kernel_lobes(sel: LobeSelection) -> Option<u32> {
    match sel {
        LobeSelection::All => None,
        LobeSelection::Nothing => Some(0),
        LobeSelection::Some(l) => Some(l),
    }
}

/// [`eval_pdf`] restricted to a lobe selection (`Material::select_lobes`): the same SIMD
/// kernels; [`LobeSelection::All`] runs exactly [`eval_pdf`].
pub fn eval_pdf_lobes(
    m: &Material,
    sel: LobeSelection,
    wi: &Src3<f32>,
    wo: &Src3<f32>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f32>>,
    pdf: Option<&Dst1<f32>>,
) -> Result<BatchReport, LayoutError> {
    eval_pdf_impl(m, wi, wo, active, f, pdf, kernel_lobes(sel))
}

fn eval_pdf_impl(
    m: &Material,
    wi: &Src3<f32>,
    wo: &Src3<f32>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f32>>,
    pdf: Option<&Dst1<f32>>,
    lobes: Option<u32>,
) -> Result<BatchReport, LayoutError> {
    let n = wi.n;
    check_views(n, &[("wo", wo.n)])?;
    check_views(n, &[("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("f", f.map_or(n, |f| f.n)), ("pdf", pdf.map_or(n, |p| p.n))])?;
    let args = Args::EvalPdf { wi, wo, active, f, pdf, scale: None, lobes };
    Ok(run(n, |s, e| args.dispatch(m.model(), (s, e))))
}

/// Samples `wi` for `n = wo.len()` elements in f32; `u` holds three uniform numbers per element
/// (clamped into [0, 1)).
pub fn sample(
    m: &Material,
    wo: &Src3<f32>,
    u: &Src3<f32>,
    active: Option<&[u8]>,
    out: &mut SampleOut<f32>,
) -> Result<BatchReport, LayoutError> {
    sample_impl(m, wo, u, active, out, None)
}

/// [`sample`] among the lobes of a lobe selection (`Material::select_lobes`), their
/// selection renormalised; [`LobeSelection::All`] runs exactly [`sample`].
pub fn sample_lobes(
    m: &Material,
    sel: LobeSelection,
    wo: &Src3<f32>,
    u: &Src3<f32>,
    active: Option<&[u8]>,
    out: &mut SampleOut<f32>,
) -> Result<BatchReport, LayoutError> {
    sample_impl(m, wo, u, active, out, kernel_lobes(sel))
}

fn sample_impl(
    m: &Material,
    wo: &Src3<f32>,
    u: &Src3<f32>,
    active: Option<&[u8]>,
    out: &mut SampleOut<f32>,
    lobes: Option<u32>,
) -> Result<BatchReport, LayoutError> {
    let n = wo.n;
    check_views(n, &[("u", u.n), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("wi", out.wi.n), ("weight", out.weight.n), ("pdf", out.pdf.n)])?;
    check_views(n, &[("flags", out.flags.as_ref().map_or(n, |f| f.len()))])?;
    let flags = out.flags.as_mut().map(|f| f.as_mut_ptr());
    let out: &SampleOut<f32> = out;
    let args = Args::Sample { wo, u, active, out, flags, lobes };
    Ok(run(n, |s, e| args.dispatch(m.model(), (s, e))))
}

/// Per-element multipliers of the spatially varying lobes for the elements
/// `base..base + metal.len()` (see [`LaneKernel::eval_scaled`]).
#[derive(Clone, Copy)]
struct Scales<'s, E> {
    metal: &'s [E],
    pearl: &'s [E],
    base: usize,
}

/// A raw pointer that parallel work items use for disjoint elements.
#[derive(Clone, Copy)]
struct Shared<T>(*mut T);
// SAFETY: every work item of one call touches only the elements of its own range.
unsafe impl<T> Send for Shared<T> {}
unsafe impl<T> Sync for Shared<T> {}

impl<T> Shared<T> {
    /// The pointer (a method, so closures capture the `Sync` wrapper, not the field).
    #[inline(always)]
    fn ptr(&self) -> *mut T {
        self.0
    }
}

/// A direction as `Material` sanitises it: `None` for non-finite or zero-length input,
/// otherwise the unit vector (unchanged when already unit to rounding).
fn unit(v: [f32; 3]) -> Option<Vec3<f32>> {
    let v = Vec3::new(v[0], v[1], v[2]);
    let l2 = v.length_squared();
    if !(l2 > 0.0 && l2.is_finite()) {
        return None;
    }
    Some(if (l2 - 1.0).abs() > 64.0 * f32::EPSILON { v / l2.sqrt() } else { v })
}

/// The sparkle multipliers of elements `s..e` (`[1, 1]` for inactive or invalid elements).
fn scales_of(
    model: &Model,
    wi: impl Fn(usize) -> [f32; 3],
    wo: &Src3<f32>,
    at: &[SurfacePoint],
    use_element: impl Fn(usize) -> bool,
    (s, e): (usize, usize),
) -> (Vec<f32>, Vec<f32>) {
    let (mut metal, mut pearl) = (vec![1.0f32; e - s], vec![1.0f32; e - s]);
    for i in s..e {
        if !use_element(i) {
            continue;
        }
        // SAFETY: i < n for every view (checked by the public functions).
        let (a, o) = (unit(wi(i)), unit(unsafe { wo.get(i) }));
        if let (Some(a), Some(o)) = (a, o) {
            let [m, p] = model.sparkle_scales(a, o, &at[i]);
            (metal[i - s], pearl[i - s]) = (m as f32, p as f32);
        }
    }
    (metal, pearl)
}

/// [`eval_pdf`] at surface points: `f` is `Material::eval_at(wi, wo, at[i])` (sparkle: the
/// flake lobes scaled by the flake counts in each element's footprint), computed by the same
/// SIMD kernels with per-element multipliers; the multipliers themselves (the footprint's
/// flake counts) are scalar work. A non-finite `at[i]` gives the mean BRDF, as
/// `Material::eval_at` does. Materials that do not vary in space ignore `at`.
pub fn eval_pdf_at(
    m: &Material,
    wi: &Src3<f32>,
    wo: &Src3<f32>,
    at: &[SurfacePoint],
    active: Option<&[u8]>,
    f: Option<&Dst3<f32>>,
    pdf: Option<&Dst1<f32>>,
) -> Result<BatchReport, LayoutError> {
    if !m.spatially_varying() || f.is_none() {
        return eval_pdf(m, wi, wo, active, f, pdf);
    }
    let n = wi.n;
    check_views(n, &[("wo", wo.n), ("at", at.len()), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("f", f.map_or(n, |f| f.n)), ("pdf", pdf.map_or(n, |p| p.n))])?;
    Ok(run(n, |s, e| {
        let on = |i: usize| active.is_none_or(|a| a[i] != 0);
        // SAFETY: i < n (checked above).
        let (metal, pearl) = scales_of(m.model(), |i| unsafe { wi.get(i) }, wo, at, on, (s, e));
        let scale = Some(Scales { metal: &metal, pearl: &pearl, base: s });
        Args::EvalPdf { wi, wo, active, f, pdf, scale, lobes: None }.dispatch(m.model(), (s, e))
    }))
}

/// [`sample`] at surface points: the directions and densities of [`sample`], the weights of
/// `Material::sample_at` (`eval_at(wi, wo, at[i]) cos θi / pdf`: sparkle). A non-finite
/// `at[i]` gives the mean BRDF's weight. Materials that do not vary in space ignore `at`.
pub fn sample_at(
    m: &Material,
    wo: &Src3<f32>,
    u: &Src3<f32>,
    at: &[SurfacePoint],
    active: Option<&[u8]>,
    out: &mut SampleOut<f32>,
) -> Result<BatchReport, LayoutError> {
    if !m.spatially_varying() || wo.n == 0 {
        return sample(m, wo, u, active, out);
    }
    let n = wo.n;
    check_views(n, &[("u", u.n), ("at", at.len()), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("wi", out.wi.n), ("weight", out.weight.n), ("pdf", out.pdf.n)])?;
    check_views(n, &[("flags", out.flags.as_ref().map_or(n, |f| f.len()))])?;
    let mut own_flags = Vec::new();
    let flags = Shared(match out.flags.as_mut() {
        Some(f) => f.as_mut_ptr(),
        None => {
            own_flags.resize(n, 0u32);
            own_flags.as_mut_ptr()
        }
    });
    let out: &SampleOut<f32> = out;
    // Pass 1: the mean BRDF's samples, then the multipliers at the sampled directions and
    // which elements need their weight recomputed.
    let (mut metal, mut pearl, mut rescale) = (vec![1.0f32; n], vec![1.0f32; n], vec![0u8; n]);
    let (metal_w, pearl_w, rescale_w) =
        (Shared(metal.as_mut_ptr()), Shared(pearl.as_mut_ptr()), Shared(rescale.as_mut_ptr()));
    let report = run(n, |s, e| {
        let report =
            Args::Sample { wo, u, active, out, flags: Some(flags.ptr()), lobes: None }.dispatch(m.model(), (s, e));
        // SAFETY (this closure): the work item owns elements s..e of every buffer; i < n.
        let good = |i: usize| active.is_none_or(|a| a[i] != 0) && unsafe { *flags.ptr().add(i) } == 0;
        let (ms, ps) = scales_of(m.model(), |i| unsafe { out.wi.get(i) }, wo, at, good, (s, e));
        for i in s..e {
            let differs = ms[i - s] != 1.0 || ps[i - s] != 1.0;
            unsafe {
                *metal_w.ptr().add(i) = ms[i - s];
                *pearl_w.ptr().add(i) = ps[i - s];
                *rescale_w.ptr().add(i) = u8::from(good(i) && differs);
            }
        }
        report
    });
    // Pass 2: the flake-scaled BRDF at the sampled directions, and the weights from it.
    let mut f_buf = vec![0.0f32; 3 * n];
    let f_dst = Dst3::interleaved(&mut f_buf);
    // SAFETY: out.wi holds n elements, written in pass 1; pass 2 reads an element before the
    // same work item may overwrite it.
    let wi_src = unsafe { Src3::from_raw(out.wi.p[0], out.wi.p[1], out.wi.p[2], out.wi.stride, n) };
    let scale = Some(Scales { metal: &metal, pearl: &pearl, base: 0 });
    let rescale = &rescale;
    run(n, |s, e| {
        Args::EvalPdf { wi: &wi_src, wo, active: Some(rescale), f: Some(&f_dst), pdf: None, scale, lobes: None }
            .dispatch(m.model(), (s, e));
        for i in (s..e).filter(|&i| rescale[i] != 0) {
            // SAFETY: i < n, element of this work item.
            unsafe {
                let (fv, wi, pdf) = (f_dst.get(i), out.wi.get(i), out.pdf.get(i));
                let w = fv.map(|c| c * (wi[2] / pdf));
                if w.iter().all(|x| x.is_finite()) {
                    out.weight.set(i, w);
                } else {
                    out.wi.set(i, [0.0; 3]);
                    out.weight.set(i, [0.0; 3]);
                    out.pdf.set(i, 0.0);
                    *flags.ptr().add(i) = SAMPLE_FAILED;
                }
            }
        }
        BatchReport::default()
    });
    Ok(report)
}

/// [`eval_pdf`] in f64 (the reference path, one element at a time, same layouts and rules).
pub fn eval_pdf_f64(
    m: &Material,
    wi: &Src3<f64>,
    wo: &Src3<f64>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f64>>,
    pdf: Option<&Dst1<f64>>,
) -> Result<BatchReport, LayoutError> {
    let n = wi.n;
    check_views(n, &[("wo", wo.n), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("f", f.map_or(n, |f| f.n)), ("pdf", pdf.map_or(n, |p| p.n))])?;
    struct F64<'v, 'a> {
        wi: &'v Src3<'a, f64>,
        wo: &'v Src3<'a, f64>,
        active: Option<&'a [u8]>,
        f: Option<&'v Dst3<'a, f64>>,
        pdf: Option<&'v Dst1<'a, f64>>,
        range: (usize, usize),
    }
    impl KernelVisitor for F64<'_, '_> {
        type Output = BatchReport;
        fn visit<K: LaneKernel>(self, k: &K) -> BatchReport {
            eval_pdf_kernel::<f64, K>(k, self.range, self.wi, self.wo, self.active, self.f, self.pdf, None, None)
        }
    }
    Ok(run(n, |s, e| m.model().visit_kernel(F64 { wi, wo, active, f, pdf, range: (s, e) })))
}

// ---------------------------------------------------------------------------------------------
// Per-element paint parameters (textures): `eval_pdf_varying`, `sample_varying`.

/// One lane batch of per-element parameters: the element's closed forms, and the lanes whose
/// given parameters are valid (the others are evaluated with the material's values and zeroed).
///
/// # Safety
/// `start + width` ≤ the length of every slice in `tex`.
#[inline(always)]
unsafe fn load_element<L: Lanes>(
    vp: &VaryingPaint,
    tex: &PaintTexture<L::Elem>,
    start: usize,
    width: usize,
) -> (Element<L>, L::Mask) {
    let (rho0, c0, a0) = vp.defaults();
    let of = <L::Elem as Real>::of;
    // SAFETY: the caller guarantees the slices hold start + width values.
    let load = |s: &[L::Elem], pad: f64| unsafe { load_comp::<L>(s.as_ptr(), 1, start, width, of(pad)) };
    let rho = tex.base_color.map(|c| [load(c[0], rho0[0]), load(c[1], rho0[1]), load(c[2], rho0[2])]);
    let density = tex.flake_density.map(|d| load(d, 100.0 * c0));
    let alpha = tex.coat_roughness.map(|a| load(a, a0));
    let ok = vp.valid(rho, density, alpha);
    let rho = match rho {
        Some(r) => [0, 1, 2].map(|c| lanes::select(ok, r[c], L::c(rho0[c]))),
        None => rho0.map(L::c),
    };
    let c = density.map_or(L::c(c0), |d| lanes::select(ok, d * L::c(0.01), L::c(c0)));
    let alpha = alpha.map_or(L::c(a0), |a| lanes::select(ok, a, L::c(if vp.varies_alpha() { 0.1 } else { a0 })));
    let vary = Vary { rho: tex.base_color.is_some(), c: tex.flake_density.is_some() };
    (vp.element(rho, c, alpha, vary), ok)
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn eval_pdf_varying_kernel<L: Lanes>(
    vp: &VaryingPaint,
    tex: &PaintTexture<L::Elem>,
    range: (usize, usize),
    wi: &Src3<L::Elem>,
    wo: &Src3<L::Elem>,
    active: Option<&[u8]>,
    f: Option<&Dst3<L::Elem>>,
    pdf: Option<&Dst1<L::Elem>>,
) -> BatchReport {
    let mut report = BatchReport::default();
    let (wi, wo) = (&wi.local_copy(), &wo.local_copy());
    let (f, pdf) = (f.map(Dst3::local_copy), pdf.map(Dst1::local_copy));
    let (f, pdf) = (f.as_ref(), pdf.as_ref());
    let mut start = range.0;
    while start < range.1 {
        let width = L::WIDTH.min(range.1 - start);
        let on = active_lanes::<L>(active, start, width);
        // SAFETY: start + width ≤ n for every view and texture (checked by the public functions).
        let (a, a_ok) = sanitize(unsafe { load3::<L>(wi, start, width, UP) });
        let (o, o_ok) = sanitize(unsafe { load3::<L>(wo, start, width, UP) });
        let (e, p_ok) = unsafe { load_element::<L>(vp, tex, start, width) };
        let ok = a_ok & o_ok;
        if !(ok | !on).all() {
            report.record(start, width, on & !ok, L::Mask::splat(false));
        }
        if !(p_ok | !on | !ok).all() {
            report.record_params(start, width, on & ok & !p_ok);
        }
        let keep = on & ok & p_ok;
        let above = lanes::gt(a.z, L::c(HORIZON_COS)) & lanes::gt(o.z, L::c(HORIZON_COS));
        let (a, o) = (above_or_up(above, a), above_or_up(above, o));
        let keep = keep & above;
        match (f, pdf) {
            (Some(f), Some(pdf)) => {
                let (v, p) = vp.eval_pdf_lanes(&e, a, o);
                let v = Rgb::select(keep, v, Rgb::zero());
                unsafe {
                    store3(f, start, width, [v.r, v.g, v.b]);
                    store1(pdf, start, width, lanes::keep(keep, p));
                }
            }
            (Some(f), None) => {
                let v = Rgb::select(keep, vp.eval_lanes(&e, a, o), Rgb::zero());
                unsafe { store3(f, start, width, [v.r, v.g, v.b]) };
            }
            (None, Some(pdf)) => {
                let v = lanes::keep(keep, vp.pdf_lanes(&e, a, o));
                unsafe { store1(pdf, start, width, v) };
            }
            (None, None) => {}
        }
        start += width;
    }
    report
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sample_varying_kernel<L: Lanes>(
    vp: &VaryingPaint,
    tex: &PaintTexture<L::Elem>,
    range: (usize, usize),
    wo: &Src3<L::Elem>,
    u: &Src3<L::Elem>,
    active: Option<&[u8]>,
    out: &SampleOut<L::Elem>,
    flags: Option<*mut u32>,
) -> BatchReport {
    let mut report = BatchReport::default();
    let (wo, u) = (&wo.local_copy(), &u.local_copy());
    let out =
        &SampleOut { wi: out.wi.local_copy(), weight: out.weight.local_copy(), pdf: out.pdf.local_copy(), flags: None };
    let mut start = range.0;
    while start < range.1 {
        let width = L::WIDTH.min(range.1 - start);
        let on = active_lanes::<L>(active, start, width);
        // SAFETY: as in eval_pdf_varying_kernel.
        let (o, o_ok) = sanitize(unsafe { load3::<L>(wo, start, width, UP) });
        let (uc, u_ok) = uniforms(unsafe { load3::<L>(u, start, width, [0.5; 3]) });
        let (e, p_ok) = unsafe { load_element::<L>(vp, tex, start, width) };
        if !((o_ok & u_ok) | !on).all() {
            report.record(start, width, on & !o_ok, on & !u_ok);
        }
        if !(p_ok | !on | !(o_ok & u_ok)).all() {
            report.record_params(start, width, on & o_ok & u_ok & !p_ok);
        }
        let above = lanes::gt(o.z, L::c(HORIZON_COS));
        let s = checked_sample(vp.sample_lanes(&e, above_or_up(above, o), uc), above);
        // SAFETY: start + width ≤ n for every output (checked by `sample_varying`).
        unsafe { store_sample(out, flags, start, width, on, on & o_ok & u_ok & p_ok, &s) };
        start += width;
    }
    report
}

/// The arguments of one varying call, so the per-level kernels have one signature.
#[derive(Clone, Copy)]
enum VaryingArgs<'v, 'a, E> {
    EvalPdf {
        wi: &'v Src3<'a, E>,
        wo: &'v Src3<'a, E>,
        active: Option<&'a [u8]>,
        f: Option<&'v Dst3<'a, E>>,
        pdf: Option<&'v Dst1<'a, E>>,
    },
    Sample {
        wo: &'v Src3<'a, E>,
        u: &'v Src3<'a, E>,
        active: Option<&'a [u8]>,
        out: &'v SampleOut<'a, E>,
        flags: Option<*mut u32>,
    },
}

// SAFETY: as `Args`.
unsafe impl<E: Sync> Send for VaryingArgs<'_, '_, E> {}
unsafe impl<E: Sync> Sync for VaryingArgs<'_, '_, E> {}

impl<E: Real> VaryingArgs<'_, '_, E> {
    /// Runs the kernel for `range` at lane type `L`.
    #[inline(always)]
    fn run<L: Lanes<Elem = E>>(self, vp: &VaryingPaint, tex: &PaintTexture<E>, range: (usize, usize)) -> BatchReport {
        match self {
            VaryingArgs::EvalPdf { .. } => self.run_eval_pdf::<L>(vp, tex, range),
            VaryingArgs::Sample { .. } => self.run_sample::<L>(vp, tex, range),
        }
    }

    /// The eval/pdf kernel (nothing for [`VaryingArgs::Sample`]); a function of its own per
    /// instruction set, as [`Args::run_eval_pdf`].
    #[inline(always)]
    fn run_eval_pdf<L: Lanes<Elem = E>>(
        self,
        vp: &VaryingPaint,
        tex: &PaintTexture<E>,
        range: (usize, usize),
    ) -> BatchReport {
        let VaryingArgs::EvalPdf { wi, wo, active, f, pdf } = self else {
            return BatchReport::default();
        };
        eval_pdf_varying_kernel::<L>(vp, tex, range, wi, wo, active, f, pdf)
    }

    /// The sampling kernel (nothing for [`VaryingArgs::EvalPdf`]).
    #[inline(always)]
    fn run_sample<L: Lanes<Elem = E>>(
        self,
        vp: &VaryingPaint,
        tex: &PaintTexture<E>,
        range: (usize, usize),
    ) -> BatchReport {
        let VaryingArgs::Sample { wo, u, active, out, flags } = self else {
            return BatchReport::default();
        };
        sample_varying_kernel::<L>(vp, tex, range, wo, u, active, out, flags)
    }
}

impl VaryingArgs<'_, '_, f32> {
    /// Runs the kernel for `range` at the selected instruction set.
    fn dispatch(self, vp: &VaryingPaint, tex: &PaintTexture<f32>, range: (usize, usize)) -> BatchReport {
        let sample = matches!(self, VaryingArgs::Sample { .. });
        #[cfg(target_arch = "x86_64")]
        {
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            use crate::lanes::x86::F32x16;
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            use crate::lanes::x86::F32x8;
            // One function per instruction set and operation (see `Args::run_eval_pdf`), none
            // for an instruction set left out of the build (`SimdLevel::compiled`).
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            #[target_feature(enable = "avx2,fma")]
            fn avx2_eval_pdf(
                a: VaryingArgs<'_, '_, f32>,
                vp: &VaryingPaint,
                t: &PaintTexture<f32>,
                r: (usize, usize),
            ) -> BatchReport {
                a.run_eval_pdf::<F32x8>(vp, t, r)
            }
            #[cfg(not(lacquer_simd_kernels = "avx512"))]
            #[target_feature(enable = "avx2,fma")]
            fn avx2_sample(
                a: VaryingArgs<'_, '_, f32>,
                vp: &VaryingPaint,
                t: &PaintTexture<f32>,
                r: (usize, usize),
            ) -> BatchReport {
                a.run_sample::<F32x8>(vp, t, r)
            }
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            #[target_feature(enable = "avx512f")]
            fn avx512_eval_pdf(
                a: VaryingArgs<'_, '_, f32>,
                vp: &VaryingPaint,
                t: &PaintTexture<f32>,
                r: (usize, usize),
            ) -> BatchReport {
                a.run_eval_pdf::<F32x16>(vp, t, r)
            }
            #[cfg(not(lacquer_simd_kernels = "avx2"))]
            #[target_feature(enable = "avx512f")]
            fn avx512_sample(
                a: VaryingArgs<'_, '_, f32>,
                vp: &VaryingPaint,
                t: &PaintTexture<f32>,
                r: (usize, usize),
            ) -> BatchReport {
                a.run_sample::<F32x16>(vp, t, r)
            }
            // SAFETY: simd_level() only reports levels the CPU has (detected at run time).
            match (simd_level(), sample) {
                #[cfg(not(lacquer_simd_kernels = "avx2"))]
                (SimdLevel::Avx512, false) => return unsafe { avx512_eval_pdf(self, vp, tex, range) },
                #[cfg(not(lacquer_simd_kernels = "avx2"))]
                (SimdLevel::Avx512, true) => return unsafe { avx512_sample(self, vp, tex, range) },
                #[cfg(not(lacquer_simd_kernels = "avx512"))]
                (SimdLevel::Avx2, false) => return unsafe { avx2_eval_pdf(self, vp, tex, range) },
                #[cfg(not(lacquer_simd_kernels = "avx512"))]
                (SimdLevel::Avx2, true) => return unsafe { avx2_sample(self, vp, tex, range) },
                // The scalar level, or one this build has no kernels for (never selected).
                _ => {}
            }
        }
        #[inline(never)]
        fn scalar_eval_pdf(
            a: VaryingArgs<'_, '_, f32>,
            vp: &VaryingPaint,
            t: &PaintTexture<f32>,
            r: (usize, usize),
        ) -> BatchReport {
            a.run_eval_pdf::<f32>(vp, t, r)
        }
        #[inline(never)]
        fn scalar_sample(
            a: VaryingArgs<'_, '_, f32>,
            vp: &VaryingPaint,
            t: &PaintTexture<f32>,
            r: (usize, usize),
        ) -> BatchReport {
            a.run_sample::<f32>(vp, t, r)
        }
        if sample {
            scalar_sample(self, vp, tex, range)
        } else {
            scalar_eval_pdf(self, vp, tex, range)
        }
    }
}

/// The material's per-component tables for `tex`, after checking the model and the lengths.
fn varying_for<'m, E>(m: &'m Material, tex: &PaintTexture<E>, n: usize) -> Result<&'m VaryingPaint, LayoutError> {
    check_len("texture", tex.min_len(), n)?;
    m.varying_paint(tex.coat_roughness.is_some()).ok_or_else(|| {
        LayoutError(if m.info().name == "coated_paint" {
            "per-element parameters need a coated_paint with pigment_model \"lambert\" (the EON pigment has no per-component tables)".to_string()
        } else {
            format!("per-element parameters need a coated_paint material, not {}", m.info().name)
        })
    })
}

/// [`eval_pdf`] with per-element paint parameters (`tex`; see [`crate::paint::varying`]):
/// element `i` is evaluated as the material with `tex`'s values at `i` (the mean lobe: no
/// sparkle). Elements with out-of-range or non-finite parameters get zero outputs and are
/// counted in [`BatchReport::invalid_params`]. With no texture this is [`eval_pdf`]; a
/// texture on a model other than `coated_paint` is an error.
#[allow(clippy::too_many_arguments)]
pub fn eval_pdf_varying(
    m: &Material,
    tex: &PaintTexture<f32>,
    wi: &Src3<f32>,
    wo: &Src3<f32>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f32>>,
    pdf: Option<&Dst1<f32>>,
) -> Result<BatchReport, LayoutError> {
    if tex.is_empty() {
        return eval_pdf(m, wi, wo, active, f, pdf);
    }
    let n = wi.n;
    check_views(n, &[("wo", wo.n), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("f", f.map_or(n, |f| f.n)), ("pdf", pdf.map_or(n, |p| p.n))])?;
    let vp = varying_for(m, tex, n)?;
    let args = VaryingArgs::EvalPdf { wi, wo, active, f, pdf };
    Ok(run(n, |s, e| args.dispatch(vp, tex, (s, e))))
}

/// [`eval_pdf_varying`] in f64 (the reference path, one element at a time).
#[allow(clippy::too_many_arguments)]
pub fn eval_pdf_varying_f64(
    m: &Material,
    tex: &PaintTexture<f64>,
    wi: &Src3<f64>,
    wo: &Src3<f64>,
    active: Option<&[u8]>,
    f: Option<&Dst3<f64>>,
    pdf: Option<&Dst1<f64>>,
) -> Result<BatchReport, LayoutError> {
    if tex.is_empty() {
        return eval_pdf_f64(m, wi, wo, active, f, pdf);
    }
    let n = wi.n;
    check_views(n, &[("wo", wo.n), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("f", f.map_or(n, |f| f.n)), ("pdf", pdf.map_or(n, |p| p.n))])?;
    let vp = varying_for(m, tex, n)?;
    let args = VaryingArgs::EvalPdf { wi, wo, active, f, pdf };
    Ok(run(n, |s, e| args.run::<f64>(vp, tex, (s, e))))
}

/// [`sample`] with per-element paint parameters (`tex`): element `i` is sampled as the material
/// with `tex`'s values at `i` (mean lobe). Invalid parameters: zero outputs, flags
/// `SAMPLE_FAILED | SAMPLE_INVALID_INPUT`, counted in [`BatchReport::invalid_params`].
pub fn sample_varying(
    m: &Material,
    tex: &PaintTexture<f32>,
    wo: &Src3<f32>,
    u: &Src3<f32>,
    active: Option<&[u8]>,
    out: &mut SampleOut<f32>,
) -> Result<BatchReport, LayoutError> {
    if tex.is_empty() {
        return sample(m, wo, u, active, out);
    }
    let n = wo.n;
    check_views(n, &[("u", u.n), ("active", active.map_or(n, <[u8]>::len))])?;
    check_views(n, &[("wi", out.wi.n), ("weight", out.weight.n), ("pdf", out.pdf.n)])?;
    check_views(n, &[("flags", out.flags.as_ref().map_or(n, |f| f.len()))])?;
    let vp = varying_for(m, tex, n)?;
    let flags = out.flags.as_mut().map(|f| f.as_mut_ptr());
    let out: &SampleOut<f32> = out;
    let args = VaryingArgs::Sample { wo, u, active, out, flags };
    Ok(run(n, |s, e| args.dispatch(vp, tex, (s, e))))
}
