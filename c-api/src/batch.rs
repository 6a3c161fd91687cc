//! Batch evaluation, density and sampling over interleaved arrays, in f32 and f64.
//!
//! The adapter only validates and converts: every value comes from `lacquer::Material`.
//! Per-element policy: an element with a non-finite or zero-length direction (the inputs the
//! core would silently turn into zero) gets zero outputs and is counted; after the whole
//! batch the call returns `LQ_ERR_INVALID_DIRECTION` (or `LQ_ERR_INVALID_ELEMENT` for a
//! non-finite `u`, `uv` or footprint) with the count and the first offender in the message.

use crate::arrays::Batch;
use crate::material::{lq_material, material};
use crate::status::{guard, guard_value, lq_status, Failure};
use lacquer_core::lobes::LobeSelection;
use lacquer_core::{Material, Real, SurfacePoint, Vec3};
use std::ffi::c_float;

/// `flags` bit: the sample comes from a Dirac delta lobe (`pdf` is then the discrete
/// probability of choosing that lobe, and MIS should not weight it against light sampling).
pub const LQ_SAMPLE_DELTA: u32 = 1;
/// `flags` bit: no sample was produced (wo below the surface, or the sampler rejected `u`):
/// `wi`, `weight` and `pdf` are 0. This is not an error.
pub const LQ_SAMPLE_FAILED: u32 = 2;
/// `flags` bit: the element's inputs were invalid (see `LQ_ERR_INVALID_DIRECTION` and
/// `LQ_ERR_INVALID_ELEMENT`); outputs are 0.
pub const LQ_SAMPLE_INVALID_INPUT: u32 = 4;

/// The same test the core applies before treating a direction as usable: a finite, non-zero
/// squared length (NaN fails both comparisons).
#[inline(always)]
pub(crate) fn usable<T: Real>(w: Vec3<T>) -> bool {
    let l2 = w.length_squared();
    l2 > T::zero() && l2 <= T::max_value()
}

/// `x.is_finite()` as one comparison (NaN fails it).
#[inline(always)]
pub(crate) fn finite<T: Real>(x: T) -> bool {
    x.abs() <= T::max_value()
}

#[inline(always)]
pub(crate) fn vec3<T: Real>(a: &[T; 3]) -> Vec3<T> {
    Vec3::new(a[0], a[1], a[2])
}

/// A number for a message: plain for ordinary magnitudes, scientific for tiny or huge ones.
fn num<T: Real>(x: T) -> String {
    let a = x.abs().f64();
    if x.is_finite() && a != 0.0 && !(1e-4..1e7).contains(&a) {
        if std::mem::size_of::<T>() == 4 {
            format!("{:e}", x.f64() as f32) // shortest f32 form, not the widened f64 digits
        } else {
            format!("{:e}", x.f64())
        }
    } else {
        format!("{x}")
    }
}

/// Counts invalid elements and remembers the first of each kind for the message. Empty
/// (`None`) in the common case, so the hot path carries and drops nothing.
#[derive(Default)]
pub(crate) struct Invalid(Option<Box<InvalidDetail>>);

#[derive(Default)]
struct InvalidDetail {
    directions: usize,
    first_direction: Option<String>,
    others: usize,
    first_other: Option<String>,
}

impl Invalid {
    #[cold]
    #[inline(never)]
    pub(crate) fn direction<T: Real>(&mut self, i: usize, name: &str, w: Vec3<T>) {
        let d = self.0.get_or_insert_with(Box::default);
        d.directions += 1;
        if d.first_direction.is_none() {
            d.first_direction = Some(format!("element {i}: {name} = [{}, {}, {}]", num(w.x), num(w.y), num(w.z)));
        }
    }
    #[cold]
    #[inline(never)]
    pub(crate) fn other<T: Real>(&mut self, i: usize, name: &str, v: &[T]) {
        let d = self.0.get_or_insert_with(Box::default);
        d.others += 1;
        if d.first_other.is_none() {
            let v: Vec<String> = v.iter().map(|&x| num(x)).collect();
            d.first_other = Some(format!("element {i}: {name} = [{}]", v.join(", ")));
        }
    }
    #[inline]
    pub(crate) fn finish(self, n: usize) -> Result<(), Failure> {
        match self.0 {
            None => Ok(()),
            Some(d) => Err(d.failure(n)),
        }
    }
}

impl InvalidDetail {
    #[cold]
    fn failure(self, n: usize) -> Failure {
        let total = self.directions + self.others;
        let (status, what, first) = if self.directions > 0 {
            (
                lq_status::LQ_ERR_INVALID_DIRECTION,
                "a direction that is not finite or has zero length",
                self.first_direction,
            )
        } else {
            (lq_status::LQ_ERR_INVALID_ELEMENT, "a non-finite u, uv or footprint value", self.first_other)
        };
        let mut msg = format!(
            "{total} of {n} elements have {what} (first: {}); their outputs were set to 0, the other elements were evaluated",
            first.unwrap_or_default()
        );
        if self.directions > 0 && self.others > 0 {
            msg.push_str(&format!("; {} more have a non-finite u, uv or footprint value", self.others));
        }
        Failure::new(status, msg)
    }
}

/// Optional surface position and footprint of each element (see `lq_eval_spatial`).
pub(crate) struct Spatial<'a, T> {
    pub(crate) uv: Option<&'a [[T; 2]]>,
    pub(crate) duv: Option<&'a [[T; 4]]>,
}

impl<T: Real> Spatial<'_, T> {
    /// True when element `i`'s position and footprint are finite (or absent).
    #[inline(always)]
    pub(crate) fn check(&self, i: usize, bad: &mut Invalid) -> bool {
        if let Some(uv) = self.uv {
            if !uv[i].iter().all(|&x| finite(x)) {
                bad.other(i, "uv", &uv[i]);
                return false;
            }
        }
        if let Some(duv) = self.duv {
            if !duv[i].iter().all(|&x| finite(x)) {
                bad.other(i, "duv", &duv[i]);
                return false;
            }
        }
        true
    }

    /// The surface point of element `i` when both a position and a footprint were given
    /// (validated first by [`Spatial::check`]); `None` means the mean lobe.
    #[inline(always)]
    pub(crate) fn point(&self, i: usize) -> Option<SurfacePoint> {
        let (uv, duv) = (self.uv?[i], self.duv?[i]);
        Some(SurfacePoint {
            uv: [uv[0].f64(), uv[1].f64()],
            duv_dx: [duv[0].f64(), duv[1].f64()],
            duv_dy: [duv[2].f64(), duv[3].f64()],
        })
    }
}

/// eval at element `i`: at its surface point when it has one, else the mean lobe.
#[inline(always)]
fn eval_elem<T: Real>(m: &Material, i: usize, a: Vec3<T>, o: Vec3<T>, spatial: &Spatial<T>) -> [T; 3] {
    match spatial.point(i) {
        Some(at) => m.eval_at(a, o, &at).to_array(),
        None => m.eval(a, o).to_array(),
    }
}

/// True when element `i`'s directions and spatial inputs are valid; otherwise records why
/// (the element's outputs are then zero).
#[inline(always)]
pub(crate) fn valid<T: Real>(i: usize, a: Vec3<T>, o: Vec3<T>, spatial: &Spatial<T>, bad: &mut Invalid) -> bool {
    if !usable(a) {
        bad.direction(i, "wi", a);
        false
    } else if !usable(o) {
        bad.direction(i, "wo", o);
        false
    } else {
        spatial.check(i, bad)
    }
}

/// eval and/or pdf over a batch; with `uv` and `duv` the spatially varying evaluation
/// (`Material::eval_at`; the density does not depend on position, see `lq_eval_spatial`).
#[allow(clippy::too_many_arguments)]
unsafe fn eval_pdf_impl<T: CoreBatch>(
    m: *const lq_material,
    n: usize,
    wi: *const T,
    wo: *const T,
    uv: *const T,
    duv: *const T,
    f_rgb: Option<*mut T>,
    pdf: Option<*mut T>,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    if n == 0 {
        return Ok(());
    }
    let mut b = Batch::<6>::new(n);
    let wi = b.input::<T, 3>("wi", wi)?;
    let wo = b.input::<T, 3>("wo", wo)?;
    let uv = b.optional_input::<T, 2>("uv", uv)?;
    let duv = b.optional_input::<T, 4>("duv", duv)?;
    if duv.is_some() && uv.is_none() {
        return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
    }
    // A wanted output is required; an unwanted one takes its slot as an empty span.
    let f_rgb = match f_rgb {
        Some(p) => Some(b.output::<T, 3>("f_rgb", p)?),
        None => b.optional_output::<T, 3>("f_rgb", std::ptr::null_mut())?,
    };
    let pdf = match pdf {
        Some(p) => Some(b.output::<T, 1>("pdf", p)?),
        None => b.optional_output::<T, 1>("pdf", std::ptr::null_mut())?,
    };
    b.check_overlaps()?;
    // SAFETY: every array validated (non-NULL, aligned, sized, outputs disjoint); lengths are
    // the caller's contract.
    let (wi, wo) = unsafe { (wi.slice(), wo.slice()) };
    let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
    let f_rgb = f_rgb.map(|a| unsafe { a.slice() });
    let pdf = pdf.map(|a| unsafe { a.slice() });

    if spatial.uv.is_none() {
        // The core's batch kernels (SIMD lanes, threads); same per-element policy.
        let flat_f = f_rgb.map(|f| lacquer_core::batch::Dst3::interleaved(f.as_flattened_mut()));
        let flat_p = pdf.map(|p| lacquer_core::batch::Dst1::new(p.as_flattened_mut()));
        let report = T::eval_pdf(
            m,
            &lacquer_core::batch::Src3::interleaved(wi.as_flattened()),
            &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
            None,
            flat_f.as_ref(),
            flat_p.as_ref(),
        );
        return report_failure(n, report, |i| {
            let (a, o) = (vec3(&wi[i]), vec3(&wo[i]));
            if usable(a) {
                ("wo", o)
            } else {
                ("wi", a)
            }
        });
    }
    if T::HAS_SAMPLE_KERNEL && spatial.duv.is_some() {
        // f32 with footprints: the core's surface-point batch calls (SIMD kernels with the
        // flake lobes scaled per element); invalid elements are inactive (zero outputs).
        let mut bad = Invalid::default();
        let active: Vec<u8> =
            (0..n).map(|i| u8::from(valid(i, vec3(&wi[i]), vec3(&wo[i]), &spatial, &mut bad))).collect();
        let at: Vec<SurfacePoint> = (0..n).map(|i| spatial.point(i).unwrap_or(MEAN_LOBE)).collect();
        let flat_f = f_rgb.map(|f| lacquer_core::batch::Dst3::interleaved(f.as_flattened_mut()));
        let flat_p = pdf.map(|p| lacquer_core::batch::Dst1::new(p.as_flattened_mut()));
        T::eval_pdf_at(
            m,
            &lacquer_core::batch::Src3::interleaved(wi.as_flattened()),
            &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
            &at,
            &active,
            flat_f.as_ref(),
            flat_p.as_ref(),
        );
        return bad.finish(n);
    }
    let mut bad = Invalid::default();
    let pairs = wi.iter().zip(wo).enumerate();
    match (f_rgb, pdf) {
        (Some(f), None) => {
            for ((i, (a, o)), out) in pairs.zip(f) {
                let (a, o) = (vec3(a), vec3(o));
                *out =
                    if valid(i, a, o, &spatial, &mut bad) { eval_elem(m, i, a, o, &spatial) } else { [T::zero(); 3] };
            }
        }
        (None, Some(p)) => {
            for ((i, (a, o)), out) in pairs.zip(p) {
                let (a, o) = (vec3(a), vec3(o));
                out[0] = if valid(i, a, o, &spatial, &mut bad) { m.pdf(a, o) } else { T::zero() };
            }
        }
        (Some(f), Some(p)) => {
            for (((i, (a, o)), f_out), p_out) in pairs.zip(f).zip(p) {
                let (a, o) = (vec3(a), vec3(o));
                (*f_out, p_out[0]) = if valid(i, a, o, &spatial, &mut bad) {
                    (eval_elem(m, i, a, o, &spatial), m.pdf(a, o))
                } else {
                    ([T::zero(); 3], T::zero())
                };
            }
        }
        (None, None) => {}
    }
    bad.finish(n)
}

/// The precisions the core's batch kernels take (f32: SIMD lanes; f64: the reference path).
trait CoreBatch: Real {
    const HAS_SAMPLE_KERNEL: bool;
    fn eval_pdf(
        m: &Material,
        wi: &lacquer_core::batch::Src3<Self>,
        wo: &lacquer_core::batch::Src3<Self>,
        active: Option<&[u8]>,
        f: Option<&lacquer_core::batch::Dst3<Self>>,
        pdf: Option<&lacquer_core::batch::Dst1<Self>>,
    ) -> lacquer_core::batch::BatchReport;
    fn sample(
        m: &Material,
        wo: &lacquer_core::batch::Src3<Self>,
        u: &lacquer_core::batch::Src3<Self>,
        out: &mut lacquer_core::batch::SampleOut<Self>,
    ) -> lacquer_core::batch::BatchReport;
    /// `batch::eval_pdf_at` (only called when `HAS_SAMPLE_KERNEL`).
    #[allow(clippy::too_many_arguments)]
    fn eval_pdf_at(
        m: &Material,
        wi: &lacquer_core::batch::Src3<Self>,
        wo: &lacquer_core::batch::Src3<Self>,
        at: &[SurfacePoint],
        active: &[u8],
        f: Option<&lacquer_core::batch::Dst3<Self>>,
        pdf: Option<&lacquer_core::batch::Dst1<Self>>,
    );
    /// `batch::sample_at` (only called when `HAS_SAMPLE_KERNEL`).
    fn sample_at(
        m: &Material,
        wo: &lacquer_core::batch::Src3<Self>,
        u: &lacquer_core::batch::Src3<Self>,
        at: &[SurfacePoint],
        active: &[u8],
        out: &mut lacquer_core::batch::SampleOut<Self>,
    );
}

/// A surface point that means "no footprint": the mean lobe.
const MEAN_LOBE: SurfacePoint = SurfacePoint { uv: [f64::NAN; 2], duv_dx: [0.0; 2], duv_dy: [0.0; 2] };

impl CoreBatch for f32 {
    const HAS_SAMPLE_KERNEL: bool = true;
    fn eval_pdf(
        m: &Material,
        wi: &lacquer_core::batch::Src3<f32>,
        wo: &lacquer_core::batch::Src3<f32>,
        active: Option<&[u8]>,
        f: Option<&lacquer_core::batch::Dst3<f32>>,
        pdf: Option<&lacquer_core::batch::Dst1<f32>>,
    ) -> lacquer_core::batch::BatchReport {
        lacquer_core::batch::eval_pdf(m, wi, wo, active, f, pdf).expect("views sized by the adapter")
    }
    fn sample(
        m: &Material,
        wo: &lacquer_core::batch::Src3<f32>,
        u: &lacquer_core::batch::Src3<f32>,
        out: &mut lacquer_core::batch::SampleOut<f32>,
    ) -> lacquer_core::batch::BatchReport {
        lacquer_core::batch::sample(m, wo, u, None, out).expect("views sized by the adapter")
    }
    fn eval_pdf_at(
        m: &Material,
        wi: &lacquer_core::batch::Src3<f32>,
        wo: &lacquer_core::batch::Src3<f32>,
        at: &[SurfacePoint],
        active: &[u8],
        f: Option<&lacquer_core::batch::Dst3<f32>>,
        pdf: Option<&lacquer_core::batch::Dst1<f32>>,
    ) {
        // Elements with invalid inputs are inactive, so the report has nothing to add.
        let _ =
            lacquer_core::batch::eval_pdf_at(m, wi, wo, at, Some(active), f, pdf).expect("views sized by the adapter");
    }
    fn sample_at(
        m: &Material,
        wo: &lacquer_core::batch::Src3<f32>,
        u: &lacquer_core::batch::Src3<f32>,
        at: &[SurfacePoint],
        active: &[u8],
        out: &mut lacquer_core::batch::SampleOut<f32>,
    ) {
        let _ = lacquer_core::batch::sample_at(m, wo, u, at, Some(active), out).expect("views sized by the adapter");
    }
}

impl CoreBatch for f64 {
    const HAS_SAMPLE_KERNEL: bool = false;
    fn eval_pdf(
        m: &Material,
        wi: &lacquer_core::batch::Src3<f64>,
        wo: &lacquer_core::batch::Src3<f64>,
        active: Option<&[u8]>,
        f: Option<&lacquer_core::batch::Dst3<f64>>,
        pdf: Option<&lacquer_core::batch::Dst1<f64>>,
    ) -> lacquer_core::batch::BatchReport {
        lacquer_core::batch::eval_pdf_f64(m, wi, wo, active, f, pdf).expect("views sized by the adapter")
    }
    fn sample(
        _m: &Material,
        _wo: &lacquer_core::batch::Src3<f64>,
        _u: &lacquer_core::batch::Src3<f64>,
        _out: &mut lacquer_core::batch::SampleOut<f64>,
    ) -> lacquer_core::batch::BatchReport {
        unreachable!("f64 sampling takes the element loop (HAS_SAMPLE_KERNEL is false)")
    }
    fn eval_pdf_at(
        _m: &Material,
        _wi: &lacquer_core::batch::Src3<f64>,
        _wo: &lacquer_core::batch::Src3<f64>,
        _at: &[SurfacePoint],
        _active: &[u8],
        _f: Option<&lacquer_core::batch::Dst3<f64>>,
        _pdf: Option<&lacquer_core::batch::Dst1<f64>>,
    ) {
        unreachable!("f64 surface points take the element loop (HAS_SAMPLE_KERNEL is false)")
    }
    fn sample_at(
        _m: &Material,
        _wo: &lacquer_core::batch::Src3<f64>,
        _u: &lacquer_core::batch::Src3<f64>,
        _at: &[SurfacePoint],
        _active: &[u8],
        _out: &mut lacquer_core::batch::SampleOut<f64>,
    ) {
        unreachable!("f64 surface points take the element loop (HAS_SAMPLE_KERNEL is false)")
    }
}

/// The status and message of a core batch report, worded as the element loop words them.
pub(crate) fn report_failure<T: Real>(
    n: usize,
    report: lacquer_core::batch::BatchReport,
    offender: impl Fn(usize) -> (&'static str, Vec3<T>),
) -> Result<(), Failure> {
    let Some(i) = report.first_invalid_direction else {
        return Ok(());
    };
    let (name, w) = offender(i);
    let mut d = InvalidDetail { directions: report.invalid_directions, ..Default::default() };
    d.first_direction = Some(format!("element {i}: {name} = [{}, {}, {}]", num(w.x), num(w.y), num(w.z)));
    Err(d.failure(n))
}

/// [`report_failure`] for sampling: invalid `wo` directions and non-finite `u`.
pub(crate) fn report_failure_sample<T: Real>(
    n: usize,
    report: lacquer_core::batch::BatchReport,
    wo: impl Fn(usize) -> Vec3<T>,
    u: impl Fn(usize) -> [T; 3],
) -> Result<(), Failure> {
    if report.ok() {
        return Ok(());
    }
    let mut d = InvalidDetail { directions: report.invalid_directions, others: report.invalid_u, ..Default::default() };
    if let Some(i) = report.first_invalid_direction {
        let w = wo(i);
        d.first_direction = Some(format!("element {i}: wo = [{}, {}, {}]", num(w.x), num(w.y), num(w.z)));
    }
    if let Some(i) = report.first_invalid_u {
        let v: Vec<String> = u(i).iter().map(|&x| num(x)).collect();
        d.first_other = Some(format!("element {i}: u = [{}]", v.join(", ")));
    }
    Err(d.failure(n))
}

/// Sampling over a batch; `flags` is optional.
#[allow(clippy::too_many_arguments)]
unsafe fn sample_impl<T: CoreBatch>(
    m: *const lq_material,
    n: usize,
    wo: *const T,
    u: *const T,
    spatial: (*const T, *const T),
    wi: *mut T,
    weight_rgb: *mut T,
    pdf: *mut T,
    flags: *mut u32,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    if n == 0 {
        return Ok(());
    }
    let mut b = Batch::<8>::new(n);
    let wo = b.input::<T, 3>("wo", wo)?;
    let u = b.input::<T, 3>("u", u)?;
    let uv = b.optional_input::<T, 2>("uv", spatial.0)?;
    let duv = b.optional_input::<T, 4>("duv", spatial.1)?;
    if duv.is_some() && uv.is_none() {
        return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
    }
    let wi = b.output::<T, 3>("wi", wi)?;
    let weight = b.output::<T, 3>("weight_rgb", weight_rgb)?;
    let pdf = b.output::<T, 1>("pdf", pdf)?;
    let flags = b.optional_output::<u32, 1>("flags", flags)?;
    b.check_overlaps()?;
    // SAFETY: as in eval_pdf_impl.
    let (wo, u) = unsafe { (wo.slice(), u.slice()) };
    let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
    let (wi, weight, pdf) = unsafe { (wi.slice(), weight.slice(), pdf.slice()) };
    let mut flags = flags.map(|a| unsafe { a.slice() });

    if spatial.uv.is_none() && T::HAS_SAMPLE_KERNEL {
        let mut out = lacquer_core::batch::SampleOut {
            wi: lacquer_core::batch::Dst3::interleaved(wi.as_flattened_mut()),
            weight: lacquer_core::batch::Dst3::interleaved(weight.as_flattened_mut()),
            pdf: lacquer_core::batch::Dst1::new(pdf.as_flattened_mut()),
            flags: flags.map(|f| f.as_flattened_mut()),
        };
        let report = T::sample(
            m,
            &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
            &lacquer_core::batch::Src3::interleaved(u.as_flattened()),
            &mut out,
        );
        return report_failure_sample(n, report, |i| vec3(&wo[i]), |i| u[i]);
    }
    if T::HAS_SAMPLE_KERNEL && spatial.duv.is_some() {
        // f32 with footprints: the core's surface-point sampler (see eval_pdf_impl).
        let mut bad = Invalid::default();
        let active: Vec<u8> = (0..n)
            .map(|i| {
                let o = vec3(&wo[i]);
                let ok = if !usable(o) {
                    bad.direction(i, "wo", o);
                    false
                } else if !u[i].iter().all(|&x| finite(x)) {
                    bad.other(i, "u", &u[i]);
                    false
                } else {
                    spatial.check(i, &mut bad)
                };
                u8::from(ok)
            })
            .collect();
        let at: Vec<SurfacePoint> = (0..n).map(|i| spatial.point(i).unwrap_or(MEAN_LOBE)).collect();
        let mut own_flags = Vec::new();
        let flags: &mut [u32] = match flags {
            Some(f) => f.as_flattened_mut(),
            None => {
                own_flags.resize(n, 0);
                &mut own_flags
            }
        };
        {
            let mut out = lacquer_core::batch::SampleOut {
                wi: lacquer_core::batch::Dst3::interleaved(wi.as_flattened_mut()),
                weight: lacquer_core::batch::Dst3::interleaved(weight.as_flattened_mut()),
                pdf: lacquer_core::batch::Dst1::new(pdf.as_flattened_mut()),
                flags: Some(&mut *flags),
            };
            T::sample_at(
                m,
                &lacquer_core::batch::Src3::interleaved(wo.as_flattened()),
                &lacquer_core::batch::Src3::interleaved(u.as_flattened()),
                &at,
                &active,
                &mut out,
            );
        }
        for (f, _) in flags.iter_mut().zip(&active).filter(|(_, &a)| a == 0) {
            *f = LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT;
        }
        return bad.finish(n);
    }
    let zero = [T::zero(); 3];
    let mut bad = Invalid::default();
    let outputs = wi.iter_mut().zip(weight.iter_mut()).zip(pdf.iter_mut());
    for (i, ((o, uu), ((wi_out, w_out), p_out))) in wo.iter().zip(u).zip(outputs).enumerate() {
        let o = vec3(o);
        let ok = if !usable(o) {
            bad.direction(i, "wo", o);
            false
        } else if !uu.iter().all(|&x| finite(x)) {
            bad.other(i, "u", uu);
            false
        } else {
            spatial.check(i, &mut bad)
        };
        let s = match (ok, spatial.point(i)) {
            (false, _) => None,
            (true, Some(at)) => m.sample_at(o, *uu, &at),
            (true, None) => m.sample(o, *uu),
        };
        let flag = match &s {
            Some(s) => {
                *wi_out = [s.wi.x, s.wi.y, s.wi.z];
                *w_out = s.weight.to_array();
                p_out[0] = s.pdf;
                if s.delta {
                    LQ_SAMPLE_DELTA
                } else {
                    0
                }
            }
            None => {
                (*wi_out, *w_out, p_out[0]) = (zero, zero, T::zero());
                if ok {
                    LQ_SAMPLE_FAILED
                } else {
                    LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT
                }
            }
        };
        if let Some(fl) = flags.as_deref_mut() {
            fl[i] = [flag];
        }
    }
    bad.finish(n)
}

const NO_F32: *const c_float = std::ptr::null();
const NO_F64: *const f64 = std::ptr::null();

// ---------------------------------------------------------------------------------------
// f32 (the contract's functions)

/// Evaluates the BRDF `f_r(wi, wo)` (1/sr, cosine NOT included, linear Rec.709 RGB) for `n`
/// direction pairs.
///
/// `wi`, `wo`: 3n floats (x, y, z per element) in the local frame (z = normal, x = tangent),
/// pointing away from the surface; they need not be exactly unit length (they are
/// normalised). `f_rgb`: 3n floats written. Below-horizon directions give 0 (not an error).
///
/// Returns LQ_OK; LQ_ERR_NULL / LQ_ERR_INVALID_ARGUMENT with nothing written; or
/// LQ_ERR_INVALID_DIRECTION after writing every element, the invalid ones as 0.
/// `n == 0` is a no-op returning LQ_OK (arrays may then be NULL). Each array must hold
/// `n` elements: the library cannot check lengths, a short array is undefined behaviour.
///
/// # Safety
/// `m` is NULL or a live handle; each non-NULL array holds `n` elements, suitably aligned.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F32, NO_F32, Some(f_rgb), None) })
}

/// The solid-angle density (1/sr) with which `lq_sample` picks `wi` given `wo`; `pdf`: n
/// floats written. Same arrays, statuses and per-element policy as `lq_eval`.
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F32, NO_F32, None, Some(pdf)) })
}

/// `lq_eval` and `lq_pdf` in one pass (what a MIS integrator needs).
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F32, NO_F32, Some(f_rgb), Some(pdf)) })
}

/// Importance-samples `wi` for each `wo`.
///
/// `u`: 3n uniform numbers in [0, 1) (first picks a lobe, the other two the direction;
/// values outside are clamped into [0, 1)). Writes `wi` (3n), `weight_rgb` (3n) =
/// f_r(wi, wo)·cos θi / pdf, and `pdf` (n). A failed sample (e.g. wo below the surface) is
/// not an error: it has pdf = 0, weight = 0 and wi = 0. A non-finite or zero-length `wo`
/// gives LQ_ERR_INVALID_DIRECTION, a non-finite `u` LQ_ERR_INVALID_ELEMENT, both after
/// writing every element (the invalid ones as failed samples).
///
/// # Safety
/// As `lq_eval`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { sample_impl(m, n, wo, u, (NO_F32, NO_F32), wi, weight_rgb, pdf, std::ptr::null_mut()) })
}

// ---------------------------------------------------------------------------------------
// f64: the reference path (same semantics, double arrays)

/// `lq_eval` in double precision (the core's reference path; the f32 path agrees to about
/// 1e-4 relative, see `lacquer check`'s precision figure).
///
/// # Safety
/// As `lq_eval`, with 8-byte aligned double arrays.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    f_rgb: *mut f64,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F64, NO_F64, Some(f_rgb), None) })
}

/// `lq_pdf` in double precision.
///
/// # Safety
/// As `lq_eval_f64`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    pdf: *mut f64,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F64, NO_F64, None, Some(pdf)) })
}

/// `lq_eval_pdf` in double precision.
///
/// # Safety
/// As `lq_eval_f64`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_f64(
    m: *const lq_material,
    n: usize,
    wi: *const f64,
    wo: *const f64,
    f_rgb: *mut f64,
    pdf: *mut f64,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, NO_F64, NO_F64, Some(f_rgb), Some(pdf)) })
}

/// `lq_sample` in double precision; `flags` (n values, may be NULL) as in
/// `lq_sample_spatial`.
///
/// # Safety
/// As `lq_eval_f64`; `flags` is NULL or holds n 4-byte aligned values.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_f64(
    m: *const lq_material,
    n: usize,
    wo: *const f64,
    u: *const f64,
    wi: *mut f64,
    weight_rgb: *mut f64,
    pdf: *mut f64,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe { sample_impl(m, n, wo, u, (NO_F64, NO_F64), wi, weight_rgb, pdf, flags) })
}

// ---------------------------------------------------------------------------------------
// Spatially varying inputs (sparkle): surface position and footprint per element

/// `lq_eval` with a surface position and footprint per element, for spatially varying
/// materials (sparkle), per the contract's "Spatially varying effects".
///
/// `uv`: 2n floats (u, v) or NULL; `duv`: 4n floats (du/dx, dv/dx, du/dy, dv/dy: the pixel
/// footprint in uv) or NULL. NULL `uv` means "no position": the mean lobe (footprint → ∞).
/// NULL `duv` with a `uv` also means the mean lobe until a model defines a point query;
/// `duv` without `uv` is LQ_ERR_INVALID_ARGUMENT. A non-finite uv/duv value gives
/// LQ_ERR_INVALID_ELEMENT for that element (outputs 0).
///
/// With both `uv` and `duv`, spatially varying materials (the coated paint with flakes and
/// `sparkle: true`) resolve individual flakes in the footprint; every other material gives
/// the same result as `lq_eval`. The pdf never depends on position (sparkle samples the
/// mean lobe and changes only the weight).
///
/// # Safety
/// As `lq_eval`; `uv`/`duv` are NULL or hold 2n / 4n floats.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    f_rgb: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, uv, duv, Some(f_rgb), None) })
}

/// `lq_pdf` with surface position and footprint (see `lq_eval_spatial`).
///
/// # Safety
/// As `lq_eval_spatial`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, uv, duv, None, Some(pdf)) })
}

/// `lq_eval_pdf` with surface position and footprint (see `lq_eval_spatial`).
///
/// # Safety
/// As `lq_eval_spatial`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_spatial(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_impl(m, n, wi, wo, uv, duv, Some(f_rgb), Some(pdf)) })
}

/// `lq_sample` with surface position and footprint (see `lq_eval_spatial`) and per-element
/// `flags` (n values, may be NULL): a combination of LQ_SAMPLE_DELTA, LQ_SAMPLE_FAILED and
/// LQ_SAMPLE_INVALID_INPUT. With `uv = duv = NULL` this is `lq_sample` plus flags.
///
/// # Safety
/// As `lq_eval_spatial`; `flags` is NULL or holds n 4-byte aligned values.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_spatial(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe { sample_impl(m, n, wo, u, (uv, duv), wi, weight_rgb, pdf, flags) })
}

// ---------------------------------------------------------------------------------------
// One element: the cheap path for scalar renderers (one shading point per call)

/// Checks one pointer to `K` values of `T` (NULL, alignment) without reading it.
#[inline(always)]
pub(crate) fn check_ptr<T>(name: &'static str, p: *const T) -> Result<(), Failure> {
    if p.is_null() {
        return Err(Failure::null(name));
    }
    if !(p as usize).is_multiple_of(std::mem::align_of::<T>()) {
        return Err(Failure::invalid(format!(
            "array `{name}` at {:#x} is not aligned to {} bytes",
            p as usize,
            std::mem::align_of::<T>()
        )));
    }
    Ok(())
}

/// The lobe selection of a `_lobes` call (`Some(mask)`; a bad mask is the call's error) or of
/// a plain call (`None`: every lobe, the plain path).
pub(crate) fn select_lobes(m: &Material, lobes: Option<u32>) -> Result<LobeSelection, Failure> {
    lobes.map_or(Ok(LobeSelection::All), |mask| m.select_lobes(mask).map_err(|e| Failure::invalid(e.to_string())))
}

/// Single-element eval and/or pdf. Inputs are read before outputs are written, through raw
/// pointers: arrays may overlap (in place is fine), so no overlap check is needed.
pub(crate) unsafe fn one_eval_pdf(
    m: *const lq_material,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: Option<*mut c_float>,
    pdf: Option<*mut c_float>,
    lobes: Option<u32>,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    let sel = select_lobes(m, lobes)?;
    check_ptr("wi", wi)?;
    check_ptr("wo", wo)?;
    if let Some(f) = f_rgb {
        check_ptr("f_rgb", f.cast_const())?;
    }
    if let Some(p) = pdf {
        check_ptr("pdf", p.cast_const())?;
    }
    // SAFETY: non-NULL and aligned; 3 readable floats each by the caller's contract.
    let (a, o) = unsafe { (vec3(&wi.cast::<[c_float; 3]>().read()), vec3(&wo.cast::<[c_float; 3]>().read())) };
    let mut bad = Invalid::default();
    let ok = valid(0, a, o, &Spatial { uv: None, duv: None }, &mut bad);
    // SAFETY: non-NULL, aligned, writable by the caller's contract; raw writes, no references.
    if let Some(f) = f_rgb {
        let v = if ok { m.eval_lobes(a, o, sel).to_array() } else { [0.0; 3] };
        unsafe { f.cast::<[c_float; 3]>().write(v) };
    }
    if let Some(p) = pdf {
        let v = if ok { m.pdf_lobes(a, o, sel) } else { 0.0 };
        unsafe { p.write(v) };
    }
    bad.finish(1)
}

/// `lq_eval` for one element: `wi`, `wo` and `f_rgb` point to 3 floats each. Cheaper per
/// call than `lq_eval` with n = 1 (no batch validation); the arrays may overlap, as inputs
/// are read before the output is written. Same statuses and per-element policy.
///
/// # Safety
/// `m` is NULL or a live handle; each non-NULL pointer points to 3 floats, 4-byte aligned.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_one(
    m: *const lq_material,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
) -> lq_status {
    guard(|| unsafe { one_eval_pdf(m, wi, wo, Some(f_rgb), None, None) })
}

/// `lq_pdf` for one element (`pdf` points to 1 float); see `lq_eval_one`.
///
/// # Safety
/// As `lq_eval_one`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_pdf_one(
    m: *const lq_material,
    wi: *const c_float,
    wo: *const c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { one_eval_pdf(m, wi, wo, None, Some(pdf), None) })
}

/// `lq_eval_pdf` for one element; see `lq_eval_one`.
///
/// # Safety
/// As `lq_eval_one`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_pdf_one(
    m: *const lq_material,
    wi: *const c_float,
    wo: *const c_float,
    f_rgb: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { one_eval_pdf(m, wi, wo, Some(f_rgb), Some(pdf), None) })
}

/// `lq_sample_spatial` without uv for one element: `wo`, `u`, `wi`, `weight_rgb` point to 3
/// floats, `pdf` to 1, `flags` to 1 `uint32_t` or is NULL. Inputs are read before outputs are
/// written, so the arrays may overlap. Same statuses and per-element policy as `lq_sample`.
///
/// # Safety
/// As `lq_eval_one`; `flags` is NULL or points to one 4-byte aligned `uint32_t`.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_one(
    m: *const lq_material,
    wo: *const c_float,
    u: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe { one_sample(m, wo, u, wi, weight_rgb, pdf, flags, None) })
}

/// `lq_sample_one` restricted to the lobe selection `lobes` (None: every lobe); the body of
/// `lq_sample_one` and `lq_sample_one_lobes`.
///
/// # Safety
/// As `lq_sample_one`.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn one_sample(
    m: *const lq_material,
    wo: *const c_float,
    u: *const c_float,
    wi: *mut c_float,
    weight_rgb: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
    lobes: Option<u32>,
) -> Result<(), Failure> {
    // SAFETY: handle contract above.
    let m: &Material = unsafe { material(m) }?;
    let sel = select_lobes(m, lobes)?;
    check_ptr("wo", wo)?;
    check_ptr("u", u)?;
    check_ptr("wi", wi.cast_const())?;
    check_ptr("weight_rgb", weight_rgb.cast_const())?;
    check_ptr("pdf", pdf.cast_const())?;
    if !flags.is_null() {
        check_ptr("flags", flags.cast_const())?;
    }
    // SAFETY: checked non-NULL and aligned; sizes by the caller's contract.
    let (o, uu) = unsafe { (vec3(&wo.cast::<[c_float; 3]>().read()), u.cast::<[c_float; 3]>().read()) };
    let mut bad = Invalid::default();
    let ok = if !usable(o) {
        bad.direction(0, "wo", o);
        false
    } else if !uu.iter().all(|&x| finite(x)) {
        bad.other(0, "u", &uu);
        false
    } else {
        true
    };
    let (w, f, p, flag) = match if ok { m.sample_lobes(o, uu, sel) } else { None } {
        Some(s) => ([s.wi.x, s.wi.y, s.wi.z], s.weight.to_array(), s.pdf, if s.delta { LQ_SAMPLE_DELTA } else { 0 }),
        None => {
            ([0.0; 3], [0.0; 3], 0.0, if ok { LQ_SAMPLE_FAILED } else { LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT })
        }
    };
    // SAFETY: checked non-NULL and aligned; raw writes, so overlapping arrays are fine.
    unsafe {
        wi.cast::<[c_float; 3]>().write(w);
        weight_rgb.cast::<[c_float; 3]>().write(f);
        pdf.write(p);
        if !flags.is_null() {
            flags.write(flag);
        }
    }
    bad.finish(1)
}

// ---------------------------------------------------------------------------------------
// Structure of arrays (x[], y[], z[]): what SIMD hosts (Mitsuba's JIT variants, ISPC code)
// hold, read and written in place.

/// Validated SoA arrays of one call: the component pointers as core views.
pub(crate) struct SoaIn<'a> {
    /// The three arrays as one core view.
    pub(crate) view: lacquer_core::batch::Src3<'a, f32>,
}

/// Validates three component arrays of `n` floats each (one SoA 3-vector).
pub(crate) fn soa_in<'a, const N: usize>(
    b: &mut Batch<N>,
    name: &'static [&'static str; 3],
    p: [*const c_float; 3],
    n: usize,
) -> Result<SoaIn<'a>, Failure> {
    let x = b.input::<c_float, 1>(name[0], p[0])?;
    let y = b.input::<c_float, 1>(name[1], p[1])?;
    let z = b.input::<c_float, 1>(name[2], p[2])?;
    // SAFETY: validated non-NULL and aligned; `n` elements is the caller's contract.
    let view = unsafe {
        lacquer_core::batch::Src3::from_raw(
            x.slice().as_ptr().cast(),
            y.slice().as_ptr().cast(),
            z.slice().as_ptr().cast(),
            1,
            n,
        )
    };
    Ok(SoaIn { view })
}

/// Validates three output arrays (one SoA 3-vector) and returns their pointers.
pub(crate) fn soa_out<const N: usize>(
    b: &mut Batch<N>,
    name: &'static [&'static str; 3],
    p: [*mut c_float; 3],
) -> Result<[*mut c_float; 3], Failure> {
    Ok([
        b.output::<c_float, 1>(name[0], p[0])?.ptr().cast(),
        b.output::<c_float, 1>(name[1], p[1])?.ptr().cast(),
        b.output::<c_float, 1>(name[2], p[2])?.ptr().cast(),
    ])
}

/// The SoA outputs of a sample call as core views.
///
/// # Safety
/// Every pointer is validated (non-NULL, aligned, not overlapping) and holds `n` values.
pub(crate) unsafe fn sample_out<'a>(
    n: usize,
    wi: [*mut c_float; 3],
    w: [*mut c_float; 3],
    pdf: *mut c_float,
    flags: Option<*mut u32>,
) -> lacquer_core::batch::SampleOut<'a, f32> {
    use lacquer_core::batch::{Dst1, Dst3, SampleOut};
    // SAFETY: the caller's contract.
    unsafe {
        SampleOut {
            wi: Dst3::from_raw(wi[0], wi[1], wi[2], 1, n),
            weight: Dst3::from_raw(w[0], w[1], w[2], 1, n),
            pdf: Dst1::from_raw(pdf, 1, n),
            flags: flags.map(|p| std::slice::from_raw_parts_mut(p, n)),
        }
    }
}

/// The `active` bytes (NULL: all active).
pub(crate) unsafe fn active_mask<'a>(active: *const u8, n: usize) -> Option<&'a [u8]> {
    // SAFETY: NULL or n readable bytes (caller's contract); u8 needs no alignment.
    (!active.is_null()).then(|| unsafe { std::slice::from_raw_parts(active, n) })
}

#[allow(clippy::too_many_arguments)]
unsafe fn eval_pdf_soa_impl(
    m: *const lq_material,
    n: usize,
    wi: [*const c_float; 3],
    wo: [*const c_float; 3],
    active: *const u8,
    f: Option<[*mut c_float; 3]>,
    pdf: Option<*mut c_float>,
) -> Result<(), Failure> {
    // SAFETY: handle contract of the exported caller.
    let m: &Material = unsafe { material(m) }?;
    if n == 0 {
        return Ok(());
    }
    let mut b = Batch::<10>::new(n);
    let wi_v = soa_in(&mut b, &["wi_x", "wi_y", "wi_z"], wi, n)?;
    let wo_v = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], wo, n)?;
    // A wanted output is required; an unwanted one takes its slot as an empty span.
    let f = match f {
        Some(p) => Some(soa_out(&mut b, &["f_r", "f_g", "f_b"], p)?),
        None => {
            for name in ["f_r", "f_g", "f_b"] {
                b.optional_output::<c_float, 1>(name, std::ptr::null_mut())?;
            }
            None
        }
    };
    let pdf = match pdf {
        Some(p) => Some(b.output::<c_float, 1>("pdf", p)?.ptr().cast::<c_float>()),
        None => {
            b.optional_output::<c_float, 1>("pdf", std::ptr::null_mut())?;
            None
        }
    };
    b.check_overlaps()?;
    // SAFETY: validated, disjoint outputs of n elements (caller's contract for lengths).
    let f_v = f.map(|[r, g, bl]| unsafe { lacquer_core::batch::Dst3::from_raw(r, g, bl, 1, n) });
    let pdf_v = pdf.map(|p| unsafe { lacquer_core::batch::Dst1::from_raw(p, 1, n) });
    let active = unsafe { active_mask(active, n) };
    let report = lacquer_core::batch::eval_pdf(m, &wi_v.view, &wo_v.view, active, f_v.as_ref(), pdf_v.as_ref())
        .map_err(|e| Failure::invalid(e.to_string()))?;
    let read = |p: [*const c_float; 3], i: usize| unsafe { Vec3::new(*p[0].add(i), *p[1].add(i), *p[2].add(i)) };
    report_failure(n, report, |i| if usable(read(wi, i)) { ("wo", read(wo, i)) } else { ("wi", read(wi, i)) })
}

/// `lq_eval` on structure-of-arrays inputs and outputs: element i is
/// `(wi_x[i], wi_y[i], wi_z[i])`, its value `(f_r[i], f_g[i], f_b[i])`. `active`: NULL (all
/// elements) or n bytes, 0 = inactive: an inactive element is not read for validation and its
/// outputs are set to 0. Same statuses and per-element policy as `lq_eval`. Runs the SIMD
/// kernels (AVX-512 or AVX2 detected at run time) and, for n ≥ 32768, several threads (see
/// `lq_set_thread_count`).
///
/// # Safety
/// `m` is NULL or a live handle; every non-NULL array holds `n` values, 4-byte aligned.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_eval_soa(
    m: *const lq_material,
    n: usize,
    wi_x: *const c_float,
    wi_y: *const c_float,
    wi_z: *const c_float,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    active: *const u8,
    f_r: *mut c_float,
    f_g: *mut c_float,
    f_b: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_soa_impl(m, n, [wi_x, wi_y, wi_z], [wo_x, wo_y, wo_z], active, Some([f_r, f_g, f_b]), None)
    })
}

/// `lq_pdf` on structure-of-arrays inputs (see `lq_eval_soa`); `pdf`: n floats.
///
/// # Safety
/// As `lq_eval_soa`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_pdf_soa(
    m: *const lq_material,
    n: usize,
    wi_x: *const c_float,
    wi_y: *const c_float,
    wi_z: *const c_float,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    active: *const u8,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe { eval_pdf_soa_impl(m, n, [wi_x, wi_y, wi_z], [wo_x, wo_y, wo_z], active, None, Some(pdf)) })
}

/// `lq_eval_pdf` on structure-of-arrays inputs (see `lq_eval_soa`).
///
/// # Safety
/// As `lq_eval_soa`.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_eval_pdf_soa(
    m: *const lq_material,
    n: usize,
    wi_x: *const c_float,
    wi_y: *const c_float,
    wi_z: *const c_float,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    active: *const u8,
    f_r: *mut c_float,
    f_g: *mut c_float,
    f_b: *mut c_float,
    pdf: *mut c_float,
) -> lq_status {
    guard(|| unsafe {
        eval_pdf_soa_impl(m, n, [wi_x, wi_y, wi_z], [wo_x, wo_y, wo_z], active, Some([f_r, f_g, f_b]), Some(pdf))
    })
}

/// `lq_sample` on structure-of-arrays inputs and outputs (see `lq_eval_soa`): `u0` picks the
/// lobe, `u1`, `u2` the direction; writes `wi_*`, `w_*` (weight) and `pdf`; `flags` (NULL or
/// n values) as in `lq_sample_f64`. Inactive elements get zero outputs and flags 0.
///
/// # Safety
/// As `lq_eval_soa`; `flags` is NULL or holds n 4-byte aligned values.
#[no_mangle]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn lq_sample_soa(
    m: *const lq_material,
    n: usize,
    wo_x: *const c_float,
    wo_y: *const c_float,
    wo_z: *const c_float,
    u0: *const c_float,
    u1: *const c_float,
    u2: *const c_float,
    active: *const u8,
    wi_x: *mut c_float,
    wi_y: *mut c_float,
    wi_z: *mut c_float,
    w_r: *mut c_float,
    w_g: *mut c_float,
    w_b: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| unsafe {
        let m: &Material = material(m)?;
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<14>::new(n);
        let wo_v = soa_in(&mut b, &["wo_x", "wo_y", "wo_z"], [wo_x, wo_y, wo_z], n)?;
        let u_v = soa_in(&mut b, &["u0", "u1", "u2"], [u0, u1, u2], n)?;
        let wi_p = soa_out(&mut b, &["wi_x", "wi_y", "wi_z"], [wi_x, wi_y, wi_z])?;
        let w_p = soa_out(&mut b, &["w_r", "w_g", "w_b"], [w_r, w_g, w_b])?;
        let pdf_p = b.output::<c_float, 1>("pdf", pdf)?.ptr().cast::<c_float>();
        let flags_p = b.optional_output::<u32, 1>("flags", flags)?.map(|a| a.ptr());
        b.check_overlaps()?;
        let mut out = sample_out(n, wi_p, w_p, pdf_p, flags_p.map(|p| p.cast::<u32>()));
        let report = lacquer_core::batch::sample(m, &wo_v.view, &u_v.view, active_mask(active, n), &mut out)
            .map_err(|e| Failure::invalid(e.to_string()))?;
        let wo3 = [wo_x, wo_y, wo_z];
        let u3 = [u0, u1, u2];
        report_failure_sample(
            n,
            report,
            |i| Vec3::new(*wo3[0].add(i), *wo3[1].add(i), *wo3[2].add(i)),
            |i| [*u3[0].add(i), *u3[1].add(i), *u3[2].add(i)],
        )
    })
}

/// Limits the threads a large batch call (n ≥ 32768) uses, and those a paint material's
/// creation samples its layer tables on: 1 runs every call and creation on the calling thread,
/// 0 (the default) uses every core. Process-wide; results do not depend on it.
#[no_mangle]
pub extern "C" fn lq_set_thread_count(n: u32) {
    guard_value((), || lacquer_core::batch::set_thread_count(n as usize));
}

/// The instruction set the batch kernels use on this CPU: "avx512", "avx2" or "scalar"
/// (static string). `LACQUER_SIMD=scalar|avx2` in the environment lowers it.
#[no_mangle]
pub extern "C" fn lq_simd_level() -> *const std::ffi::c_char {
    guard_value(c"scalar".as_ptr(), || match lacquer_core::batch::simd_level() {
        lacquer_core::batch::SimdLevel::Avx512 => c"avx512".as_ptr(),
        lacquer_core::batch::SimdLevel::Avx2 => c"avx2".as_ptr(),
        lacquer_core::batch::SimdLevel::Scalar => c"scalar".as_ptr(),
    })
}

// ---------------------------------------------------------------------------------------
// Spectral: values at four wavelengths per element (Mitsuba's scalar_spectral and any host
// that traces wavelengths)

/// True when element `i`'s four wavelengths are finite.
#[inline(always)]
fn wavelengths_ok(i: usize, l: &[c_float; 4], bad: &mut Invalid) -> bool {
    if l.iter().all(|&x| finite(x)) {
        true
    } else {
        bad.other(i, "wavelengths_nm", l);
        false
    }
}

/// `lq_eval_spatial` at four wavelengths per element: `wavelengths_nm` holds 4n floats (nm),
/// `f` receives 4n floats, f_r at each element's four wavelengths (1/sr, no cosine).
///
/// For the materials `LQ_LOBE_SPECTRAL` marks (the pearl paint's thin film, HTSG) the core
/// evaluates its physics at each wavelength (a bank of the model built at wavelength nodes
/// every 5 nm over 360-830 nm, interpolated linearly; built on the first spectral call, so
/// that call costs more). Every other material returns its RGB value upsampled to a spectrum
/// that integrates back to that RGB against the CIE 1931 matching functions (three box bands
/// 360-490-590-830 nm). Wavelengths outside 360-830 nm are clamped; a non-finite wavelength is
/// LQ_ERR_INVALID_ELEMENT for its element. `uv` / `duv` as in `lq_eval_spatial` (NULL: the
/// mean lobe). The pdf does not depend on wavelength: use `lq_pdf`.
///
/// # Safety
/// As `lq_eval_spatial`; `wavelengths_nm` and `f` hold 4n floats.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_eval_spectral(
    m: *const lq_material,
    n: usize,
    wi: *const c_float,
    wo: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    wavelengths_nm: *const c_float,
    f: *mut c_float,
) -> lq_status {
    guard(|| {
        // SAFETY: handle contract above.
        let m: &Material = unsafe { material(m) }?;
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<6>::new(n);
        let wi = b.input::<c_float, 3>("wi", wi)?;
        let wo = b.input::<c_float, 3>("wo", wo)?;
        let uv = b.optional_input::<c_float, 2>("uv", uv)?;
        let duv = b.optional_input::<c_float, 4>("duv", duv)?;
        if duv.is_some() && uv.is_none() {
            return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
        }
        let lambda = b.input::<c_float, 4>("wavelengths_nm", wavelengths_nm)?;
        let f = b.output::<c_float, 4>("f", f)?;
        b.check_overlaps()?;
        // SAFETY: every array validated (non-NULL, aligned, sized, output disjoint).
        let (wi, wo, lambda, f) = unsafe { (wi.slice(), wo.slice(), lambda.slice(), f.slice()) };
        let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
        let mut bad = Invalid::default();
        for i in 0..n {
            let (a, o) = (vec3(&wi[i]), vec3(&wo[i]));
            f[i] = if valid(i, a, o, &spatial, &mut bad) && wavelengths_ok(i, &lambda[i], &mut bad) {
                let at = spatial.point(i);
                m.eval_spectral(a.cast(), o.cast(), at.as_ref(), lambda[i].map(f64::from)).map(|x| x as c_float)
            } else {
                [0.0; 4]
            };
        }
        bad.finish(n)
    })
}

/// `lq_sample_spatial` with the weight at four wavelengths per element: `wavelengths_nm`
/// holds 4n floats (nm), `weight` receives 4n floats (f_r · cos θi / pdf at each
/// wavelength). The direction, pdf and flags are those of `lq_sample_spatial` with the same
/// inputs; the weight is the spectral `f` of `lq_eval_spectral` times cos θi / pdf (a delta
/// sample: its lobe's reflectance at each wavelength over the lobe's probability). `uv`,
/// `duv` and `flags` may be NULL.
///
/// # Safety
/// As `lq_sample_spatial`; `wavelengths_nm` and `weight` hold 4n floats.
#[no_mangle]
#[must_use]
pub unsafe extern "C" fn lq_sample_spectral(
    m: *const lq_material,
    n: usize,
    wo: *const c_float,
    u: *const c_float,
    uv: *const c_float,
    duv: *const c_float,
    wavelengths_nm: *const c_float,
    wi: *mut c_float,
    weight: *mut c_float,
    pdf: *mut c_float,
    flags: *mut u32,
) -> lq_status {
    guard(|| {
        // SAFETY: handle contract above.
        let m: &Material = unsafe { material(m) }?;
        if n == 0 {
            return Ok(());
        }
        let mut b = Batch::<9>::new(n);
        let wo = b.input::<c_float, 3>("wo", wo)?;
        let u = b.input::<c_float, 3>("u", u)?;
        let uv = b.optional_input::<c_float, 2>("uv", uv)?;
        let duv = b.optional_input::<c_float, 4>("duv", duv)?;
        if duv.is_some() && uv.is_none() {
            return Err(Failure::invalid("`duv` (footprint) was given without `uv` (position)"));
        }
        let lambda = b.input::<c_float, 4>("wavelengths_nm", wavelengths_nm)?;
        let wi = b.output::<c_float, 3>("wi", wi)?;
        let weight = b.output::<c_float, 4>("weight", weight)?;
        let pdf = b.output::<c_float, 1>("pdf", pdf)?;
        let flags = b.optional_output::<u32, 1>("flags", flags)?;
        b.check_overlaps()?;
        // SAFETY: every array validated (non-NULL, aligned, sized, outputs disjoint).
        let (wo, u, lambda) = unsafe { (wo.slice(), u.slice(), lambda.slice()) };
        let (wi, weight, pdf) = unsafe { (wi.slice(), weight.slice(), pdf.slice()) };
        let mut flags = flags.map(|a| unsafe { a.slice() });
        let spatial = unsafe { Spatial { uv: uv.map(|a| a.slice()), duv: duv.map(|a| a.slice()) } };
        let mut bad = Invalid::default();
        for i in 0..n {
            let o = vec3(&wo[i]);
            let ok = if !usable(o) {
                bad.direction(i, "wo", o);
                false
            } else if !u[i].iter().all(|&x| finite(x)) {
                bad.other(i, "u", &u[i]);
                false
            } else {
                spatial.check(i, &mut bad) && wavelengths_ok(i, &lambda[i], &mut bad)
            };
            let at = spatial.point(i);
            let s = if ok {
                m.sample_spectral(o.cast(), u[i].map(f64::from), at.as_ref(), lambda[i].map(f64::from))
            } else {
                None
            };
            let flag = match s {
                Some((s, w)) if w.iter().all(|x| x.is_finite()) => {
                    wi[i] = [s.wi.x as c_float, s.wi.y as c_float, s.wi.z as c_float];
                    weight[i] = w.map(|x| x as c_float);
                    pdf[i][0] = s.pdf as c_float;
                    if s.delta {
                        LQ_SAMPLE_DELTA
                    } else {
                        0
                    }
                }
                _ => {
                    (wi[i], weight[i], pdf[i][0]) = ([0.0; 3], [0.0; 4], 0.0);
                    if ok {
                        LQ_SAMPLE_FAILED
                    } else {
                        LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT
                    }
                }
            };
            if let Some(fl) = flags.as_deref_mut() {
                fl[i][0] = flag;
            }
        }
        bad.finish(n)
    })
}
