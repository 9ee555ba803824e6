//! Counter-based RNG: the n-th number of stream (key) is a pure function of (key, n), so CPU and
//! GPU produce bit-identical sequences and any pixel/sample can be regenerated independently.
//! Built on the PCG-RXS-M-XS 32-bit hash (Jarzynski & Olano, JCGT 9(3), 2020), u32 only, so no
//! Int64 capability is needed on the GPU.

/// The PCG-RXS-M-XS 32-bit hash of `v`.
#[inline(always)]
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A random stream: number n is `pcg_hash(key + n·0x9E3779B9)`, the key a hash of (seed, index).
#[derive(Copy, Clone, Debug)]
pub struct Rng {
    key: u32,
    counter: u32,
}

impl Rng {
    /// Stream for (`seed`, `index`), e.g. a frame seed and a pixel index.
    #[inline(always)]
    pub fn new(seed: u32, index: u32) -> Self {
        Self { key: pcg_hash(index ^ pcg_hash(seed)), counter: 0 }
    }

    /// The stream's next number.
    #[inline(always)]
    pub fn next_u32(&mut self) -> u32 {
        let x = pcg_hash(self.key.wrapping_add(self.counter.wrapping_mul(0x9E37_79B9)));
        self.counter = self.counter.wrapping_add(1);
        x
    }

    /// Uniform in [0, 1): the top 24 bits, exactly representable.
    #[inline(always)]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}
