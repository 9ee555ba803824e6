//! The numbers an eye path draws: independent random numbers, or a pixel's own low-discrepancy
//! sequence, so that a pixel's samples — over the eye samples of a pass and over the passes —
//! cover the pixel, the lights and the hemisphere evenly instead of at random.
//!
//! **Sobol mode** (`RENDER_SOBOL`): each pixel draws the points of Sobol's (0, 2)-sequence in
//! two dimensions (its first two generator matrices: the van der Corput sequence and Pascal's
//! matrix mod 2), one point per sample index n, with nested uniform (Owen) scrambling: padded
//! as in pbrt-v4's `PaddedSobolSampler` and Burley's "Practical Hash-based Owen Scrambling"
//! (JCGT 9(4), 2020), each dimension pair (`get2`) or single dimension (`get1`) of each pixel
//! has its own shuffle of the sequence order and its own scramble of the values. Both are
//! nested uniform scrambles, computed by a hash whose every bit depends only on the bits
//! above it (Laine–Karras form, with Vegdahl's constants), so:
//!
//! * every number is uniform on [0, 1) by itself: estimates stay unbiased, whatever the
//!   integrand;
//! * the first 2^k samples of a pixel are a (0, k, 2)-net in every dimension pair — one point
//!   in each of the 2^k elementary boxes of every shape — and so is each later aligned block
//!   of 2^k samples: a render of P passes × S eye samples is stratified as one sequence of
//!   P·S samples, however it is split into passes;
//! * different pixels and different dimension pairs are independent (their scrambles are).
//!
//! Dimension pairs are numbered by where they are used (`DIM_*`, `dim`), never by the order of
//! the draws, so a path that takes another branch does not shift the numbers of the next
//! bounce.
//!
//! Photons (`PHOTON_SOBOL`) draw from two sequences of the whole render in the same way: a
//! coherent group's emission sample is point pass · groups + group of one (`photon_group`),
//! each photon's bounces point pass · photons + photon of another (`photon`).
//!
//! **Independent mode**: the same dimensions from a counter-based hash of (seed, stream,
//! dimension): plain Monte Carlo.
use crate::pod::{PhotonParams, RenderParams, PHOTON_SOBOL, RENDER_SOBOL};
use crate::rng::pcg_hash;

/// The camera's pixel jitter (2-D).
pub const DIM_CAMERA: u32 = 0;
/// The final gather's bounce direction (2-D, `render::resume`).
pub const DIM_RESUME: u32 = 1;
/// A photon group's point of emission on a light, the light chosen by the first number (2-D,
/// `photon::emission_numbers`).
pub const DIM_EMIT_POSITION: u32 = 2;
/// A photon group's direction of emission (2-D).
pub const DIM_EMIT_DIRECTION: u32 = 3;
/// Dimensions per bounce of a path (`dim`).
pub const DIMS_PER_BOUNCE: u32 = 8;
/// The point on a light for next-event estimation, the light chosen by the first number (2-D).
pub const LIGHT: u32 = 0;
/// Russian roulette (1-D).
pub const ROULETTE: u32 = 1;
/// The diffuse bounce's direction (2-D).
pub const BOUNCE: u32 = 2;
/// Reflection or refraction at glass (1-D).
pub const FRESNEL: u32 = 3;
/// The rounding of a stored photon's power (1-D, `photon::encode_rgb9e5`).
pub const DITHER: u32 = 4;

/// The dimension of use `what` (`LIGHT`, `ROULETTE`, `BOUNCE`, `FRESNEL`, `DITHER`) at bounce `bounce`;
/// a resumed path (a final gather of level `level` ≥ 1, `render::resume_level`; 0: not
/// resumed) has dimensions of its own.
#[inline(always)]
pub fn dim(bounce: u32, what: u32, level: u32) -> u32 {
    let base = if level == 0 { 0x10 } else { level.wrapping_mul(0x1000) };
    base + bounce.wrapping_mul(DIMS_PER_BOUNCE) + what
}

/// The final gather's bounce direction at level `level` ≥ 1 (2-D): `DIM_RESUME`, then for a
/// further level the top of its block of `dim` (never a bounce's: bounces stay below 511).
#[inline(always)]
pub fn resume_dim(level: u32) -> u32 {
    if level <= 1 {
        DIM_RESUME
    } else {
        level.wrapping_mul(0x1000) + 0xFFF
    }
}

/// A 32-bit fraction to a float in [0, 1): its top 24 bits, exactly representable.
#[inline(always)]
fn unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Sobol's second dimension (generator matrix: Pascal's triangle mod 2) of index `n`, as a
/// 32-bit fraction. The first is `n.reverse_bits()`.
#[inline(always)]
pub fn sobol_1(n: u32) -> u32 {
    let mut x = 0u32;
    let mut v = 1u32 << 31;
    let mut m = n;
    // At most 32 steps: one per bit of n.
    while m != 0 {
        if m & 1 != 0 {
            x ^= v;
        }
        m >>= 1;
        v ^= v >> 1;
    }
    x
}

/// A hash of `x` in which output bit i depends only on `seed` and input bits 0..=i: each step
/// (adding, multiplying by an odd number, xor with a product by an even number) keeps that.
/// Bit-reversed, it is a nested uniform scramble (`owen`).
#[inline(always)]
fn lk_hash(x: u32, seed: u32) -> u32 {
    let mut x = x;
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Nested uniform (Owen) scrambling of the 32-bit fraction `x`: bit i (from the top) is
/// flipped by a function of `seed` and the bits above it.
#[inline(always)]
pub fn owen(x: u32, seed: u32) -> u32 {
    lk_hash(x.reverse_bits(), seed).reverse_bits()
}

/// A path's source of numbers (see the module notes).
#[derive(Copy, Clone, Debug)]
pub struct Sampler {
    /// The pixel's (Sobol) or the stream's (independent) hash.
    key: u32,
    /// The sample's index in its pixel's sequence (Sobol).
    index: u32,
    sobol: bool,
}

impl Sampler {
    /// The sampler of the path with random stream `stream` (`PathState::pixel`: its pixel plus
    /// its sample within the dispatch times the image's pixels) of the render `p`: in Sobol
    /// mode the sample's index in its pixel's sequence is `p.sample_base` plus that sample,
    /// the scramble a function of `p.sequence` and the pixel alone; otherwise the numbers are
    /// a hash of `p.seed` and the stream.
    #[inline(always)]
    pub fn new(p: &RenderParams, stream: u32) -> Sampler {
        if p.flags & RENDER_SOBOL != 0 {
            let pixels = (p.camera.width * p.camera.height).max(1);
            let pixel = stream % pixels;
            Sampler::sobol(pcg_hash(pixel ^ pcg_hash(p.sequence)), p.sample_base.wrapping_add(stream / pixels))
        } else {
            Sampler::independent(pcg_hash(stream ^ pcg_hash(p.seed ^ 0x6A09_E667)))
        }
    }

    /// Point `index` of the sequence whose shuffles and scrambles `key` determines.
    #[inline(always)]
    pub fn sobol(key: u32, index: u32) -> Sampler {
        Sampler { key, index, sobol: true }
    }

    /// Independent numbers, a hash of `key` and the dimension.
    #[inline(always)]
    pub fn independent(key: u32) -> Sampler {
        Sampler { key, index: 0, sobol: false }
    }

    /// The bounces' sampler of photon `photon` of the pass of `p`: with `PHOTON_SOBOL`, point
    /// `p.pass · p.emitted + photon` of the render's one photon sequence (`p.sequence`), so
    /// that the photons of all passes together are stratified at every bounce; otherwise
    /// independent numbers of (`p.seed`, photon).
    #[inline(always)]
    pub fn photon(p: &PhotonParams, photon: u32) -> Sampler {
        if p.flags & PHOTON_SOBOL != 0 {
            Sampler::sobol(pcg_hash(p.sequence ^ 0x7F4A_7C15), p.pass.wrapping_mul(p.emitted).wrapping_add(photon))
        } else {
            Sampler::independent(pcg_hash(photon ^ pcg_hash(p.seed ^ 0xB7E1_5163)))
        }
    }

    /// The emission sampler of photon group `group` (photons `GROUP · group ..`) of the pass
    /// of `p`: with `PHOTON_SOBOL`, point `p.pass · groups + group` of the render's group
    /// sequence, so that the groups of all passes together are stratified over the lights'
    /// surfaces and directions; otherwise independent numbers of (`p.seed`, group).
    #[inline(always)]
    pub fn photon_group(p: &PhotonParams, group: u32, group_size: u32) -> Sampler {
        if p.flags & PHOTON_SOBOL != 0 {
            let groups = p.emitted.div_ceil(group_size.max(1));
            Sampler::sobol(pcg_hash(p.sequence ^ 0x1B87_3593), p.pass.wrapping_mul(groups).wrapping_add(group))
        } else {
            Sampler::independent(pcg_hash(group ^ pcg_hash(p.seed)))
        }
    }

    /// Two numbers in [0, 1) of dimension pair `dim`.
    #[inline(always)]
    pub fn get2(&self, dim: u32) -> [f32; 2] {
        let k = pcg_hash(self.key ^ dim.wrapping_mul(0x9E37_79B9));
        if self.sobol {
            let n = owen(self.index, k);
            let k1 = pcg_hash(k ^ 0x85EB_CA6B);
            let k2 = pcg_hash(k ^ 0xC2B2_AE35);
            [unit(owen(n.reverse_bits(), k1)), unit(owen(sobol_1(n), k2))]
        } else {
            [unit(pcg_hash(k)), unit(pcg_hash(k ^ 0x2545_F491))]
        }
    }

    /// One number in [0, 1) of dimension `dim` (the first of `get2`'s pair's own kind: a
    /// scrambled van der Corput sequence in Sobol mode).
    #[inline(always)]
    pub fn get1(&self, dim: u32) -> f32 {
        let k = pcg_hash(self.key ^ dim.wrapping_mul(0x9E37_79B9));
        if self.sobol {
            let n = owen(self.index, k);
            unit(owen(n.reverse_bits(), pcg_hash(k ^ 0x85EB_CA6B)))
        } else {
            unit(pcg_hash(k))
        }
    }
}
