//! A small, deterministic random number generator (PCG32, O'Neill 2014) for the checks.
//!
//! Checks must give the same numbers on every machine, so they do not depend on an
//! external RNG crate whose stream may change between versions.

/// PCG-XSH-RR 64/32 generator.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULT: u64 = 6364136223846793005;

    /// A generator for `seed` on stream `stream`; different streams never overlap.
    #[must_use]
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self { state: 0, inc: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Skips `delta` outputs of [`Pcg32::next_u32`] in O(log delta) steps (Brown 1994, as in
    /// O'Neill's `pcg_advance_lcg_64`): lets a check start one of its parts where the serial
    /// stream would be, so parts can run on different threads with identical numbers.
    pub fn advance(&mut self, delta: u64) {
        let (mut acc_mult, mut acc_plus) = (1u64, 0u64);
        let (mut cur_mult, mut cur_plus) = (Self::MULT, self.inc);
        let mut d = delta;
        while d > 0 {
            if d & 1 == 1 {
                acc_mult = acc_mult.wrapping_mul(cur_mult);
                acc_plus = acc_plus.wrapping_mul(cur_mult).wrapping_add(cur_plus);
            }
            cur_plus = cur_mult.wrapping_add(1).wrapping_mul(cur_plus);
            cur_mult = cur_mult.wrapping_mul(cur_mult);
            d >>= 1;
        }
        self.state = acc_mult.wrapping_mul(self.state).wrapping_add(acc_plus);
    }

    /// A uniform number in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        let hi = (self.next_u32() >> 5) as u64; // 27 bits
        let lo = (self.next_u32() >> 6) as u64; // 26 bits
        ((hi << 26) | lo) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Three uniform numbers, the `u` argument of `sample`.
    #[inline]
    pub fn uniform3(&mut self) -> [f64; 3] {
        [self.uniform(), self.uniform(), self.uniform()]
    }

    /// A uniform number in `[lo, hi)`.
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
}

#[cfg(test)]
mod tests {
    use super::Pcg32;

    #[test]
    fn advance_equals_stepping() {
        for delta in [0u64, 1, 2, 3, 5, 64, 1000, 6 * 300_000 + 7] {
            let mut a = Pcg32::new(0x1acc_0e12, 0xc412);
            let mut b = a.clone();
            for _ in 0..delta {
                a.next_u32();
            }
            b.advance(delta);
            let xs: Vec<u32> = (0..8).map(|_| a.next_u32()).collect();
            let ys: Vec<u32> = (0..8).map(|_| b.next_u32()).collect();
            assert_eq!(xs, ys, "delta {delta}");
        }
        // A different stream or seed does not coincide.
        let mut c = Pcg32::new(0x1acc_0e12, 0xc413);
        c.advance(1000);
        let mut d = Pcg32::new(0x1acc_0e12, 0xc412);
        d.advance(1000);
        assert_ne!(c.next_u32(), d.next_u32());
    }
}
