//! Validation of the caller's arrays before any of them is touched: NULL, alignment, byte
//! size overflow, and overlap of an output with any other array. Only after all of these
//! pass are the raw pointers turned into slices of elements (`&[[T; K]]`: an interleaved
//! array of `n` elements of `K` values has exactly the layout of `[[T; K]]`).
//!
//! What cannot be checked (and is the caller's responsibility, documented in the header):
//! that each array really holds `n` elements.

use crate::status::Failure;

/// Most arrays one call takes (`lq_sample_spatial`: wo, u, uv, duv, wi, weight, pdf, flags).
const MAX_ARRAYS: usize = 8;

/// The arrays of one batch call of `n` elements. Kept small and allocation-free: this runs
/// on every call, and renderers call with n = 1.
pub(crate) struct Batch {
    n: usize,
    count: usize,
    /// Bit k set: array k is an output.
    outputs: u32,
    addr: [usize; MAX_ARRAYS],
    bytes: [usize; MAX_ARRAYS],
    names: [&'static str; MAX_ARRAYS],
}

impl Batch {
    #[inline]
    pub(crate) fn new(n: usize) -> Self {
        Self {
            n,
            count: 0,
            outputs: 0,
            addr: [0; MAX_ARRAYS],
            bytes: [0; MAX_ARRAYS],
            names: [""; MAX_ARRAYS],
        }
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
        if ptr.is_null() {
            return if required {
                Err(Failure::null(name))
            } else {
                Ok(false)
            };
        }
        let addr = ptr as usize;
        if addr % std::mem::align_of::<T>() != 0 {
            return Err(misaligned(name, addr, std::mem::align_of::<T>()));
        }
        let bytes = match self.n.checked_mul(std::mem::size_of::<[T; K]>()) {
            Some(b) if b <= isize::MAX as usize && addr.checked_add(b).is_some() => b,
            _ => return Err(too_large(name, self.n)),
        };
        let k = self.count;
        debug_assert!(k < MAX_ARRAYS);
        self.addr[k] = addr;
        self.bytes[k] = bytes;
        self.names[k] = name;
        self.outputs |= u32::from(output) << k;
        self.count = k + 1;
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
        Ok(self
            .add::<T, K>(name, ptr, false, false)?
            .then(|| Raw::new(ptr.cast(), self.n)))
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
        Ok(self
            .add::<T, K>(name, ptr.cast_const(), false, true)?
            .then(|| RawMut::new(ptr.cast(), self.n)))
    }

    /// Rejects any output that shares bytes with another array (inputs may overlap each
    /// other: they are only read).
    #[inline]
    pub(crate) fn check_overlaps(&self) -> Result<(), Failure> {
        for i in 0..self.count {
            for j in i + 1..self.count {
                let involves_output = (self.outputs >> i | self.outputs >> j) & 1 != 0;
                if involves_output
                    && self.addr[i] < self.addr[j] + self.bytes[j]
                    && self.addr[j] < self.addr[i] + self.bytes[i]
                {
                    return Err(self.overlap(i, j));
                }
            }
        }
        Ok(())
    }

    #[cold]
    #[inline(never)]
    fn overlap(&self, i: usize, j: usize) -> Failure {
        let (out, other) = if self.outputs >> i & 1 != 0 {
            (i, j)
        } else {
            (j, i)
        };
        Failure::invalid(format!(
            "output array `{}` overlaps array `{}`; outputs must not share memory with any other array",
            self.names[out], self.names[other]
        ))
    }
}

#[cold]
#[inline(never)]
fn misaligned(name: &str, addr: usize, align: usize) -> Failure {
    Failure::invalid(format!(
        "array `{name}` at {addr:#x} is not aligned to {align} bytes"
    ))
}

#[cold]
#[inline(never)]
fn too_large(name: &str, n: usize) -> Failure {
    Failure::invalid(format!(
        "n = {n} is too large: array `{name}` would not fit in the address space"
    ))
}

/// A validated input pointer to `len` elements; a slice once every array is validated.
pub(crate) struct Raw<'a, E> {
    ptr: *const E,
    len: usize,
    _life: std::marker::PhantomData<&'a E>,
}

impl<'a, E> Raw<'a, E> {
    fn new(ptr: *const E, len: usize) -> Self {
        Self {
            ptr,
            len,
            _life: std::marker::PhantomData,
        }
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
        Self {
            ptr,
            len,
            _life: std::marker::PhantomData,
        }
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
        let mut b = Batch::new(2);
        b.input::<f32, 3>("wi", p.cast_const()).unwrap();
        b.input::<f32, 3>("wo", p.cast_const()).unwrap(); // inputs may alias
        b.check_overlaps().unwrap();
        b.output::<f32, 3>("f_rgb", unsafe { p.add(5) }).unwrap(); // shares element 5
        let e = b.check_overlaps().unwrap_err();
        assert!(e.message.contains("f_rgb"), "{}", e.message);

        let mut b = Batch::new(2);
        b.input::<f32, 3>("wi", p.cast_const()).unwrap();
        b.output::<f32, 3>("f_rgb", unsafe { p.add(6) }).unwrap(); // adjacent, not overlapping
        b.check_overlaps().unwrap();
    }

    #[test]
    fn alignment_and_size() {
        let buf = [0f32; 8];
        let mis = (buf.as_ptr() as usize + 1) as *const f32;
        assert!(Batch::new(1).input::<f32, 3>("wi", mis).is_err());
        assert!(Batch::new(usize::MAX / 4)
            .input::<f32, 3>("wi", buf.as_ptr())
            .is_err());
        assert!(Batch::new(1)
            .input::<f32, 3>("wi", std::ptr::null())
            .is_err());
        assert!(Batch::new(1)
            .optional_input::<f32, 2>("uv", std::ptr::null())
            .unwrap()
            .is_none());
    }
}
