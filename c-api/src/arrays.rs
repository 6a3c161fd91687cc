//! Validation of the caller's arrays before any of them is touched: NULL, alignment, byte
//! size overflow, and overlap of an output with any other array. Only after all of these
//! pass are the raw pointers turned into slices of elements (`&[[T; K]]`: an interleaved
//! array of `n` elements of `K` values has exactly the layout of `[[T; K]]`).
//!
//! What cannot be checked (and is the caller's responsibility, documented in the header):
//! that each array really holds `n` elements.

use crate::status::Failure;

/// The `N` arrays of one batch call of `n` elements, in a fixed order (a NULL optional array
/// takes its slot as an empty span). Allocation-free, and with `N` known at compile time the
/// overlap test unrolls: this runs on every call, and renderers call with n = 1.
pub(crate) struct Batch<const N: usize> {
    n: usize,
    count: usize,
    /// Bit k set: array k is an output.
    outputs: u32,
    /// Bit k set: array k is not NULL.
    present: u32,
    /// Byte range `[start, end)` of each array; empty (0, 0) for a NULL optional array.
    start: [usize; N],
    end: [usize; N],
    names: [&'static str; N],
}

impl<const N: usize> Batch<N> {
    #[inline]
    pub(crate) fn new(n: usize) -> Self {
        Self { n, count: 0, outputs: 0, present: 0, start: [0; N], end: [0; N], names: [""; N] }
    }

    /// Validates one array of `n` elements of `K` values of `T`. `Ok(false)` when `ptr` is
    /// NULL and the array is optional; an error when it is NULL and required.
    #[inline]
    fn add<T, const K: usize>(
        &mut self,
        name: &'static str,
        ptr: *const T,
        required: bool,
        output: bool,
    ) -> Result<bool, Failure> {
        let k = self.count;
        assert!(k < N, "Batch<{N}> takes {N} arrays");
        self.count = k + 1;
        self.names[k] = name;
        if ptr.is_null() {
            return if required {
                Err(Failure::null(name))
            } else {
                Ok(false) // an empty span: overlaps nothing
            };
        }
        let addr = ptr as usize;
        if !addr.is_multiple_of(std::mem::align_of::<T>()) {
            return Err(misaligned(name, addr, std::mem::align_of::<T>()));
        }
        let bytes = match self.n.checked_mul(std::mem::size_of::<[T; K]>()) {
            Some(b) if b <= isize::MAX as usize && addr.checked_add(b).is_some() => b,
            _ => return Err(too_large(name, self.n)),
        };
        self.start[k] = addr;
        self.end[k] = addr + bytes;
        self.outputs |= u32::from(output) << k;
        self.present |= 1 << k;
        Ok(true)
    }

    /// A required input array of `K` values per element.
    #[inline]
    pub(crate) fn input<'a, T, const K: usize>(
        &mut self,
        name: &'static str,
        ptr: *const T,
    ) -> Result<Raw<'a, [T; K]>, Failure> {
        self.add::<T, K>(name, ptr, true, false)?;
        Ok(Raw::new(ptr.cast(), self.n))
    }

    /// An optional input array (NULL allowed).
    #[inline]
    pub(crate) fn optional_input<'a, T, const K: usize>(
        &mut self,
        name: &'static str,
        ptr: *const T,
    ) -> Result<Option<Raw<'a, [T; K]>>, Failure> {
        Ok(self.add::<T, K>(name, ptr, false, false)?.then(|| Raw::new(ptr.cast(), self.n)))
    }

    /// A required output array.
    #[inline]
    pub(crate) fn output<'a, T, const K: usize>(
        &mut self,
        name: &'static str,
        ptr: *mut T,
    ) -> Result<RawMut<'a, [T; K]>, Failure> {
        self.add::<T, K>(name, ptr.cast_const(), true, true)?;
        Ok(RawMut::new(ptr.cast(), self.n))
    }

    /// An optional output array (NULL allowed).
    #[inline]
    pub(crate) fn optional_output<'a, T, const K: usize>(
        &mut self,
        name: &'static str,
        ptr: *mut T,
    ) -> Result<Option<RawMut<'a, [T; K]>>, Failure> {
        Ok(self.add::<T, K>(name, ptr.cast_const(), false, true)?.then(|| RawMut::new(ptr.cast(), self.n)))
    }

    /// Rejects any output that shares bytes with another array (inputs may overlap each
    /// other: they are only read). Empty spans (NULL optional arrays) overlap nothing.
    #[inline]
    pub(crate) fn check_overlaps(&self) -> Result<(), Failure> {
        debug_assert_eq!(self.count, N);
        let mut outs = self.outputs;
        while outs != 0 {
            let i = outs.trailing_zeros() as usize;
            outs &= outs - 1;
            let (a, b) = (self.start[i], self.end[i]);
            let mut others = self.present & !(1 << i);
            while others != 0 {
                let j = others.trailing_zeros() as usize;
                others &= others - 1;
                if a < self.end[j] && self.start[j] < b {
                    return Err(self.overlap());
                }
            }
        }
        Ok(())
    }

    /// The message for the first overlapping pair (slow path).
    #[cold]
    #[inline(never)]
    fn overlap(&self) -> Failure {
        for i in 0..N {
            for j in i + 1..N {
                let involves_output = (self.outputs >> i | self.outputs >> j) & 1 != 0;
                if involves_output && self.start[i] < self.end[j] && self.start[j] < self.end[i] {
                    let (out, other) = if self.outputs >> i & 1 != 0 { (i, j) } else { (j, i) };
                    return Failure::invalid(format!(
                        "output array `{}` overlaps array `{}`; outputs must not share memory with any other array",
                        self.names[out], self.names[other]
                    ));
                }
            }
        }
        Failure::invalid("overlapping arrays")
    }
}

#[cold]
#[inline(never)]
fn misaligned(name: &str, addr: usize, align: usize) -> Failure {
    Failure::invalid(format!("array `{name}` at {addr:#x} is not aligned to {align} bytes"))
}

#[cold]
#[inline(never)]
fn too_large(name: &str, n: usize) -> Failure {
    Failure::invalid(format!("n = {n} is too large: array `{name}` would not fit in the address space"))
}

/// A validated input pointer to `len` elements; a slice once every array is validated.
pub(crate) struct Raw<'a, E> {
    ptr: *const E,
    len: usize,
    _life: std::marker::PhantomData<&'a E>,
}

impl<'a, E> Raw<'a, E> {
    fn new(ptr: *const E, len: usize) -> Self {
        Self { ptr, len, _life: std::marker::PhantomData }
    }
    /// # Safety
    /// The caller guarantees `len` readable elements at `ptr` for `'a` (the C contract), and
    /// [`Batch::check_overlaps`] has passed.
    pub(crate) unsafe fn slice(self) -> &'a [E] {
        // SAFETY: non-NULL, aligned (`[T; K]` has `T`'s alignment), size within isize::MAX
        // (checked in `Batch::add`); length and lifetime are the caller's contract.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

/// A validated output pointer to `len` elements.
pub(crate) struct RawMut<'a, E> {
    ptr: *mut E,
    len: usize,
    _life: std::marker::PhantomData<&'a mut E>,
}

impl<'a, E> RawMut<'a, E> {
    fn new(ptr: *mut E, len: usize) -> Self {
        Self { ptr, len, _life: std::marker::PhantomData }
    }
    /// The validated pointer (for views that keep raw pointers, e.g. strided SoA arrays).
    pub(crate) fn ptr(&self) -> *mut E {
        self.ptr
    }
    /// # Safety
    /// As [`Raw::slice`], and the memory is writable and overlaps no other array of the call.
    pub(crate) unsafe fn slice(self) -> &'a mut [E] {
        // SAFETY: as `Raw::slice`; exclusivity comes from `Batch::check_overlaps`.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_rules() {
        let mut buf = [0f32; 12];
        let p = buf.as_mut_ptr();
        let mut b = Batch::<2>::new(2);
        b.input::<f32, 3>("wi", p.cast_const()).unwrap();
        b.input::<f32, 3>("wo", p.cast_const()).unwrap(); // inputs may alias
        b.check_overlaps().unwrap();

        let mut b = Batch::<3>::new(2);
        b.input::<f32, 3>("wi", p.cast_const()).unwrap();
        b.input::<f32, 3>("wo", p.cast_const()).unwrap();
        b.output::<f32, 3>("f_rgb", unsafe { p.add(5) }).unwrap(); // shares element 5
        let e = b.check_overlaps().unwrap_err();
        assert!(e.message.contains("`f_rgb` overlaps array `wi`"), "{}", e.message);

        let mut b = Batch::<3>::new(2);
        b.input::<f32, 3>("wi", p.cast_const()).unwrap();
        b.optional_input::<f32, 2>("uv", std::ptr::null()).unwrap(); // empty span
        b.output::<f32, 3>("f_rgb", unsafe { p.add(6) }).unwrap(); // adjacent, not overlapping
        b.check_overlaps().unwrap();
    }

    #[test]
    fn alignment_and_size() {
        let buf = [0f32; 8];
        let mis = (buf.as_ptr() as usize + 1) as *const f32;
        assert!(Batch::<1>::new(1).input::<f32, 3>("wi", mis).is_err());
        assert!(Batch::<1>::new(usize::MAX / 4).input::<f32, 3>("wi", buf.as_ptr()).is_err());
        assert!(Batch::<1>::new(1).input::<f32, 3>("wi", std::ptr::null()).is_err());
        assert!(Batch::<1>::new(1).optional_input::<f32, 2>("uv", std::ptr::null()).unwrap().is_none());
    }
}
