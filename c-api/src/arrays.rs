//! Validation of the caller's arrays before any of them is touched: NULL, alignment, byte
//! size overflow, and overlap of an output with any other array. Only after all of these
//! pass are the raw pointers turned into slices.
//!
//! What cannot be checked (and is the caller's responsibility, documented in the header):
//! that each array really holds `n` elements.

use crate::status::Failure;

/// One array argument: its name (for messages), address and byte length.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Span {
    name: &'static str,
    addr: usize,
    bytes: usize,
    output: bool,
}

/// The arrays of one batch call of `n` elements.
pub(crate) struct Batch {
    n: usize,
    spans: Vec<Span>,
}

impl Batch {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            n,
            spans: Vec::with_capacity(6),
        }
    }

    /// Validates one array of `per` values of `T` per element. `None` when `ptr` is NULL and
    /// the array is optional; an error when it is NULL and required.
    fn add<T>(
        &mut self,
        name: &'static str,
        ptr: *const T,
        per: usize,
        required: bool,
        output: bool,
    ) -> Result<Option<()>, Failure> {
        if ptr.is_null() {
            return if required {
                Err(Failure::null(name))
            } else {
                Ok(None)
            };
        }
        let align = std::mem::align_of::<T>();
        let addr = ptr as usize;
        if addr % align != 0 {
            return Err(Failure::invalid(format!(
                "array `{name}` at {addr:#x} is not aligned to {align} bytes"
            )));
        }
        let bytes = self
            .n
            .checked_mul(per)
            .and_then(|v| v.checked_mul(std::mem::size_of::<T>()))
            .filter(|&b| b <= isize::MAX as usize && addr.checked_add(b).is_some())
            .ok_or_else(|| {
                Failure::invalid(format!(
                    "n = {} is too large: array `{name}` would not fit in the address space",
                    self.n
                ))
            })?;
        self.spans.push(Span {
            name,
            addr,
            bytes,
            output,
        });
        Ok(Some(()))
    }

    /// A required input array.
    pub(crate) fn input<'a, T>(
        &mut self,
        name: &'static str,
        ptr: *const T,
        per: usize,
    ) -> Result<Raw<'a, T>, Failure> {
        self.add(name, ptr, per, true, false)?;
        Ok(Raw::new(ptr, self.n * per))
    }

    /// An optional input array (NULL allowed).
    pub(crate) fn optional_input<'a, T>(
        &mut self,
        name: &'static str,
        ptr: *const T,
        per: usize,
    ) -> Result<Option<Raw<'a, T>>, Failure> {
        Ok(self
            .add(name, ptr, per, false, false)?
            .map(|()| Raw::new(ptr, self.n * per)))
    }

    /// A required output array.
    pub(crate) fn output<'a, T>(
        &mut self,
        name: &'static str,
        ptr: *mut T,
        per: usize,
    ) -> Result<RawMut<'a, T>, Failure> {
        self.add(name, ptr.cast_const(), per, true, true)?;
        Ok(RawMut::new(ptr, self.n * per))
    }

    /// An optional output array (NULL allowed).
    pub(crate) fn optional_output<'a, T>(
        &mut self,
        name: &'static str,
        ptr: *mut T,
        per: usize,
    ) -> Result<Option<RawMut<'a, T>>, Failure> {
        Ok(self
            .add(name, ptr.cast_const(), per, false, true)?
            .map(|()| RawMut::new(ptr, self.n * per)))
    }

    /// Rejects any output that shares bytes with another array (inputs may overlap each
    /// other: they are only read).
    pub(crate) fn check_overlaps(&self) -> Result<(), Failure> {
        for (i, a) in self.spans.iter().enumerate() {
            for b in &self.spans[i + 1..] {
                if !(a.output || b.output) || a.bytes == 0 || b.bytes == 0 {
                    continue;
                }
                if a.addr < b.addr + b.bytes && b.addr < a.addr + a.bytes {
                    return Err(Failure::invalid(format!(
                        "output array `{}` overlaps array `{}`; outputs must not share memory with any other array",
                        if a.output { a.name } else { b.name },
                        if a.output { b.name } else { a.name },
                    )));
                }
            }
        }
        Ok(())
    }
}

/// A validated input pointer; becomes a slice once every array of the call is validated.
pub(crate) struct Raw<'a, T> {
    ptr: *const T,
    len: usize,
    _life: std::marker::PhantomData<&'a T>,
}

impl<'a, T> Raw<'a, T> {
    fn new(ptr: *const T, len: usize) -> Self {
        Self {
            ptr,
            len,
            _life: std::marker::PhantomData,
        }
    }
    /// # Safety
    /// The caller guarantees `len` readable values at `ptr` for `'a` (the C contract), and
    /// [`Batch::check_overlaps`] has passed.
    pub(crate) unsafe fn slice(self) -> &'a [T] {
        // SAFETY: non-NULL, aligned, size within isize::MAX (checked in `Batch::add`);
        // length and lifetime are the caller's contract.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

/// A validated output pointer.
pub(crate) struct RawMut<'a, T> {
    ptr: *mut T,
    len: usize,
    _life: std::marker::PhantomData<&'a mut T>,
}

impl<'a, T> RawMut<'a, T> {
    fn new(ptr: *mut T, len: usize) -> Self {
        Self {
            ptr,
            len,
            _life: std::marker::PhantomData,
        }
    }
    /// # Safety
    /// As [`Raw::slice`], and the memory is writable and overlaps no other array of the call.
    pub(crate) unsafe fn slice(self) -> &'a mut [T] {
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
        b.input("wi", p.cast_const(), 3).unwrap();
        b.input("wo", p.cast_const(), 3).unwrap(); // inputs may alias
        b.check_overlaps().unwrap();
        b.output("f_rgb", unsafe { p.add(5) }, 3).unwrap(); // shares element 5
        let e = b.check_overlaps().unwrap_err();
        assert!(e.message.contains("f_rgb"), "{}", e.message);

        let mut b = Batch::new(2);
        b.input("wi", p.cast_const(), 3).unwrap();
        b.output("f_rgb", unsafe { p.add(6) }, 3).unwrap(); // adjacent, not overlapping
        b.check_overlaps().unwrap();
    }

    #[test]
    fn alignment_and_size() {
        let buf = [0f32; 8];
        let mis = (buf.as_ptr() as usize + 1) as *const f32;
        assert!(Batch::new(1).input("wi", mis, 3).is_err());
        assert!(Batch::new(usize::MAX / 4)
            .input("wi", buf.as_ptr(), 3)
            .is_err());
        assert!(Batch::new(1)
            .input::<f32>("wi", std::ptr::null(), 3)
            .is_err());
        assert!(Batch::new(1)
            .optional_input::<f32>("uv", std::ptr::null(), 2)
            .unwrap()
            .is_none());
    }
}
