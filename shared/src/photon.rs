//! Photon mapping as per-item kernels (entry points in the shader crate, the same functions
//! natively), after Frolov & Ignatenko's GPU scheme and Knaus & Zwicker's progressive radius:
//!
//! 1. `emit`: photon i of a pass leaves a light chosen in proportion to power, from a uniform
//!    point, in a cosine-weighted (area lights, front side), uniform (point lights) or cone
//!    (spot lights) direction. In groups of 32 photons share one sample, each shifted by a
//!    lattice point (a toroidal shift, so each photon's marginal distribution is exactly the
//!    light's emission distribution), or each photon draws its own.
//! 2. per bounce, after the closest-hit query: `bounce` stores the photon at a diffuse hit
//!    (atomic append to a bounded record buffer), then continues with Russian roulette by
//!    albedo; mirrors reflect, glass reflects or refracts (Fresnel). Photons that reached a
//!    diffuse surface through specular bounces only are caustic photons.
//! 3. the index: `keys` gives every stored photon its cell (a `PhotonIndex`: hashed grid, or the
//!    geometry kd-tree's leaves subdivided) and its rank in the cell, a counting sort (`sort`)
//!    gives the cells' offsets and `place` writes the records in cell order.
//! 4. `gather`: at each eye path's gather point, the photons within radius r whose surface
//!    normal lies on the same side, weighted by a kernel, divided by πr²; added to the path's
//!    radiance, which the film (`render::film`) then adds up.
//!
//! Numbers come from `sampler::Sampler::photon_group` (emission) and `Sampler::photon`
//! (bounces): independent ones keyed by (pass seed, photon), or points of the render's Sobol
//! sequences at (pass, photon). Either way a pass is a function of its index and the scene
//! only, so passes can run anywhere and be summed.
use crate::kdtree::{leaves_in_box, KdNode};
use bytemuck::{Pod, Zeroable};
use glam::UVec4;
use core::mem::MaybeUninit;
use crate::query::{Answer, Closest, Near, Query};
use crate::trace::Method;
use crate::kernel::{AtomicStore, Store};
use crate::math::{
    add3, cosine_direction, cross3, direction_around, dist2_point_segment, dist2_point_triangle, dot3, exp2i, floor_u32, fma, fract_pos, isqrt,
    mul3, normalize3, scale3, sqrt, sub3,
};
use crate::parts::Parts;
use crate::pod::{
    Hit, IndexParams, LeafCells, Light, Material, PathState, Photon, PhotonParams, PhotonPath, SortParams, Triangle, FILTER_CONE, FILTER_CONSTANT, INDEX_KD,
    FILTER_EPANECHNIKOV, GATHER_EDGES, GATHER_LISTED, LIGHT_POINT, LIGHT_SPOT, MAT_MIRROR, PATH_GATHER, PATH_NEAR_EDGE, PHOTON_ACTIVE, PHOTON_SPECULAR_ONLY,
    PHOTON_STORE_DIRECT,
};
use crate::ray::Ray;
use crate::rng::pcg_hash;
use crate::sampler::{self, Sampler, DIM_EMIT_DIRECTION, DIM_EMIT_POSITION};
use crate::shade::{self, choose_light, is_specular, offset, specular_bounce, surface_point, NO_RAY};

/// Photons per coherent group.
pub const GROUP: u32 = 32;
/// Bit of `Photon::packed`: a caustic photon.
pub const CAUSTIC_BIT: u32 = 1 << 30;
/// Bit of `Photon::packed`: a photon stored at its first hit, straight from a light.
pub const DIRECT_BIT: u32 = 1 << 31;
/// The cell of an empty photon slot (left out by the counting sort).
pub const NO_CELL: u32 = u32::MAX;
/// Bound on the kd-tree walk of the index (the builder's depth limit is 48).
const KD_STACK: usize = 64;

/// Increments of the 4-D Kronecker lattice of the lanes (powers of 1/φ₄, φ₄ the real root
/// of x⁵ = x + 1: Roberts' generalised golden ratio).
const LATTICE: [f32; 4] = [0.856_674_9, 0.733_891_9, 0.628_706_7, 0.538_597_3];

// ---------------------------------------------------------------------------------------------
// Compact records

/// RGB9E5 shared-exponent encoding of a non-negative colour (components up to 65 408), each
/// mantissa rounded up with probability equal to its fraction when `dither` is uniform in
/// [0, 1): the decoded colour's expectation is the colour itself (no systematic rounding bias).
#[inline(always)]
pub fn encode_rgb9e5(c: [f32; 3], dither: f32) -> u32 {
    const MAX: f32 = 65_408.0;
    let r = c[0].max(0.0).min(MAX);
    let g = c[1].max(0.0).min(MAX);
    let b = c[2].max(0.0).min(MAX);
    let m = r.max(g).max(b);
    if !(m > 0.0) {
        return 0;
    }
    // floor(log2 m) from the exponent bits (subnormals count as tiny).
    let e = ((m.to_bits() >> 23) & 0xff) as i32 - 127;
    let mut shared = if e < -16 { -16 } else { e } + 16;
    let mut scale = exp2i(24 - shared);
    if floor_u32(m * scale + dither) >= 512 {
        shared += 1;
        scale *= 0.5;
    }
    let q = |x: f32| floor_u32(x * scale + dither).min(511);
    q(r) | (q(g) << 9) | (q(b) << 18) | ((shared as u32) << 27)
}

/// The colour of an RGB9E5 word (`encode_rgb9e5`).
#[inline(always)]
pub fn decode_rgb9e5(v: u32) -> [f32; 3] {
    let scale = exp2i((v >> 27) as i32 - 24);
    [(v & 511) as f32 * scale, ((v >> 9) & 511) as f32 * scale, ((v >> 18) & 511) as f32 * scale]
}

/// Octahedral encoding of unit vector `n` in 2 × `bits` bits.
#[inline(always)]
pub fn encode_oct(n: [f32; 3], bits: u32) -> u32 {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let (ax, ay) = (x.abs(), y.abs());
        x = (1.0 - ay) * if x >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ax) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    let levels = ((1u32 << bits) - 1) as f32;
    let q = |v: f32| floor_u32((v.max(-1.0).min(1.0) * 0.5 + 0.5) * levels + 0.5);
    q(x) | (q(y) << bits)
}

/// The direction of an `encode_oct` word of 2 × `bits` bits, not normalised (a point of the
/// octahedron |x| + |y| + |z| = 1): enough for a test of the angle to another vector, without
/// the square root and division of `decode_oct` (a photon word holds it scaled and halved in
/// whole numbers: `normal_bytes`).
#[inline(always)]
pub fn oct_vector(v: u32, bits: u32) -> [f32; 3] {
    let mask = (1u32 << bits) - 1;
    let k = 2.0 / mask as f32;
    let x = (v & mask) as f32 * k - 1.0;
    let y = ((v >> bits) & mask) as f32 * k - 1.0;
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let x = x + if x >= 0.0 { -t } else { t };
    let y = y + if y >= 0.0 { -t } else { t };
    [x, y, z]
}

/// The unit vector of an `encode_oct` word of 2 × `bits` bits.
#[inline(always)]
pub fn decode_oct(v: u32, bits: u32) -> [f32; 3] {
    normalize3(oct_vector(v, bits))
}

impl Photon {
    /// A record of a photon of power `power` at `p` on a surface whose normal on the arriving
    /// side is `n`, arriving along unit `dir` (pointing into the surface); `caustic`: a caustic
    /// photon, `direct`: stored at its first hit.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn new(p: [f32; 3], power: [f32; 3], n: [f32; 3], dir: [f32; 3], caustic: bool, direct: bool, dither: f32) -> Photon {
        let from = scale3(dir, -1.0);
        let packed = encode_oct(n, 8) | (encode_oct(from, 7) << 16) | if caustic { CAUSTIC_BIT } else { 0 } | if direct { DIRECT_BIT } else { 0 };
        Photon { position: p, power: encode_rgb9e5(power, dither), packed }
    }
    /// The photon's power (RGB), decoded from RGB9E5.
    #[inline(always)]
    pub fn power(&self) -> [f32; 3] {
        decode_rgb9e5(self.power)
    }
    /// Unit surface normal on the side the photon arrived from.
    #[inline(always)]
    pub fn normal(&self) -> [f32; 3] {
        decode_oct(self.packed & 0xffff, 8)
    }
    /// Unit direction toward where the photon came from.
    #[inline(always)]
    pub fn incoming(&self) -> [f32; 3] {
        decode_oct((self.packed >> 16) & 0x3fff, 7)
    }
    /// Whether it is a caustic photon (`CAUSTIC_BIT`).
    #[inline(always)]
    pub fn is_caustic(&self) -> bool {
        self.packed & CAUSTIC_BIT != 0
    }
    /// Whether it was stored straight from a light (`DIRECT_BIT`).
    #[inline(always)]
    pub fn is_direct(&self) -> bool {
        self.packed & DIRECT_BIT != 0
    }
}

/// Bits of a photon word's coordinates: each axis of the scene box in fewer than 2^23 steps of
/// a power of two, at most twice as coarse as `f32`'s spacing at the box's far corner.
pub const WORD_BITS: u32 = 23;
/// 2^23: `biased(m)` is 2^23 + m.
const TWO_23: f32 = 8_388_608.0;

/// 2^23 + `m` for `m` < 2^23, exactly, by setting the bits of `m` under the exponent of 2^23: a
/// bitwise or instead of an integer-to-float conversion, which GPUs run at a fraction of the rate
/// of float arithmetic (the gather's distance test converts three fields of every photon it tests).
/// The bias cancels in a multiply-add by a power of two s in [2^-126, 2^103]: `biased(m) · s` is
/// exact, so `fma(biased(m), s, c)` is the same fused or not (Vulkan lets a driver split an `fma`).
#[inline(always)]
fn biased(m: u32) -> f32 {
    f32::from_bits(m | 0x4b00_0000)
}

/// A photon of the index (cell order) as the gather reads it: everything a gather needs in one
/// 16-byte word, loaded in one vector access — its position in fixed point over the scene box
/// (`WordFrame`, 23 bits an axis), its normal (`Photon::packed`'s octahedral normal unfolded
/// into a vector of whole numbers, three bytes: `normal_bytes`) and its power (`word_power`:
/// a float per channel, dithered from the record's RGB9E5).
///
/// Bits: `x` = qx | the normal's x byte << 24; `y` = qy | its y byte << 24; `z` = qz | its z
/// byte << 24; `w` = power. (With the z byte at bit 23 and a padding bit of its own, the
/// gather took 2.0–2.5 % longer on the H100: a mask and a test more per photon.)
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Pod, Zeroable)]
pub struct PhotonWord {
    /// Coordinates, normal and power, packed as the type says.
    pub word: UVec4,
}

/// The fixed-point frame of photon words (`PhotonWord`): the scene box of an index's
/// parameters cut into steps of a power of two, at most 2^23 − 1 per axis. Coordinate q
/// decodes to `fma(biased(q), step, origin)`, `origin` = `min` − 2^23 · `step` (rounded), one
/// rounding on every runtime, fused or not (`biased`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct WordFrame {
    /// The box's minimum corner (q = 0).
    pub min: [f32; 3],
    /// One step per axis (a power of two, or 0 for a box without extent along the axis).
    pub step: [f32; 3],
    /// Steps per unit per axis (0 for a box without extent along the axis).
    pub inv: [f32; 3],
    /// `min` − 2^23 · `step`: the decoding's offset (`biased`).
    pub origin: [f32; 3],
    /// The power range (`IndexParams::power_top`, clamped to `POWER_TOP`).
    pub power_top: i32,
}

impl WordFrame {
    /// The frame of the scene box of `p`.
    #[inline(always)]
    pub fn new(p: &IndexParams) -> WordFrame {
        let e = sub3(p.bounds_max, p.bounds_min);
        // Bits only (a driver's division may be off by ulps, and then the host would decode
        // other positions than the GPU placed): for an extent in [2^k, 2^(k+1)), the step
        // 2^(k − 22), so the extent is below 2^23 steps; kept within [2^-126, 2^103] (so
        // `origin` stays finite). Its reciprocal, exactly, by the exponent alone.
        let bits = |x: f32| -> u32 {
            if x > 0.0 && x.to_bits() < 0x7f80_0000 {
                ((x.to_bits() & 0x7f80_0000) as i32 - (22 << 23)).clamp(1 << 23, (103 + 127) << 23) as u32
            } else {
                0
            }
        };
        let b = [bits(e[0]), bits(e[1]), bits(e[2])];
        let step = [f32::from_bits(b[0]), f32::from_bits(b[1]), f32::from_bits(b[2])];
        let inv_of = |b: u32| if b == 0 { 0.0 } else { f32::from_bits(0x7f00_0000 - b) };
        let inv = [inv_of(b[0]), inv_of(b[1]), inv_of(b[2])];
        let o = |a: usize| p.bounds_min[a] - TWO_23 * step[a];
        WordFrame { min: p.bounds_min, step, inv, origin: [o(0), o(1), o(2)], power_top: p.power_top.clamp(POWER_TOP[0], POWER_TOP[1]) }
    }
    /// The nearest coordinates of a point (clamped to the box).
    #[inline(always)]
    pub fn encode(&self, x: [f32; 3]) -> [u32; 3] {
        let top = (1u32 << WORD_BITS) - 1;
        let q = |a: usize| floor_u32((x[a] - self.min[a]) * self.inv[a] + 0.5).min(top);
        [q(0), q(1), q(2)]
    }
    /// Where a photon at `x` lies in its word (`PhotonWord::of`): `position` of `encode(x)`,
    /// without the word's other fields.
    #[inline(always)]
    pub fn snap(&self, x: [f32; 3]) -> [f32; 3] {
        let q = self.encode(x);
        self.position(UVec4::new(q[0], q[1], q[2], 0))
    }
    /// The position of word `w`.
    #[inline(always)]
    pub fn position(&self, w: UVec4) -> [f32; 3] {
        self.offset(w, self.origin)
    }
    /// `origin − x`: what the words' offsets from a point `x` are decoded against (`offset`).
    #[inline(always)]
    pub fn base(&self, x: [f32; 3]) -> [f32; 3] {
        sub3(self.origin, x)
    }
    /// Word `w`'s position less a point x, given `base(x)`: `fma(biased(q), step, origin − x)`
    /// per axis, the gather's distances (`Disc::test`). One rounding, fused or not (`biased`);
    /// and a driver that moves a subtraction after a multiply-add into it (Mesa's inexact
    /// rules may) finds none to move.
    #[inline(always)]
    pub fn offset(&self, w: UVec4, base: [f32; 3]) -> [f32; 3] {
        const Q: u32 = (1 << WORD_BITS) - 1;
        let c = |q: u32, a: usize| fma(biased(q & Q), self.step[a], base[a]);
        [c(w.x, 0), c(w.y, 1), c(w.z, 2)]
    }
}

impl PhotonWord {
    /// The word of `ph` in `frame`.
    #[inline(always)]
    pub fn of(ph: &Photon, frame: &WordFrame) -> PhotonWord {
        let q = frame.encode(ph.position);
        let n = normal_bytes(ph.packed & 0xffff);
        // The power's dither: a hash of the record (every runtime draws the same).
        let b = |x: f32| x.to_bits();
        let h = pcg_hash(b(ph.position[0]) ^ pcg_hash(b(ph.position[1]) ^ pcg_hash(b(ph.position[2]) ^ pcg_hash(ph.packed ^ ph.power))));
        PhotonWord { word: UVec4::new(q[0] | n[0] << 24, q[1] | n[1] << 24, q[2] | n[2] << 24, word_power(ph.power, frame.power_top, h)) }
    }
    /// Where the photon landed, to a step of `frame`.
    #[inline(always)]
    pub fn position(&self, frame: &WordFrame) -> [f32; 3] {
        frame.position(self.word)
    }
    /// Unit surface normal on the side the photon arrived from (`normal_bytes`' vector,
    /// normalised).
    #[inline(always)]
    pub fn normal(&self) -> [f32; 3] {
        let m = word_normal(self.word);
        normalize3([m[0] as f32, m[1] as f32, m[2] as f32])
    }
    /// The photon's power (RGB, `word_power`) in `frame`.
    #[inline(always)]
    pub fn power(&self, frame: &WordFrame) -> [f32; 3] {
        scale3(power_floats(self.word.w), power_scale(frame.power_top))
    }
}

/// The range of `IndexParams::power_top` (clamped): the records' powers (RGB9E5) lie within
/// [2^-24, 2^16) or are 0, so a range of [2^-54, 2^-23) at the lowest still holds the smallest
/// without clamping, one of [2^-14, 2^17) at the highest the largest; `power_scale` stays
/// within [2^72, 2^112], times a filter's weight (at most 3) finite.
pub const POWER_TOP: [i32; 2] = [-23, 17];
/// Mantissa bits of a word's power channels (red, green, blue; `word_power`).
const POWER_MANTISSA: [u32; 3] = [6, 6, 5];
/// Where each channel's 5 + mantissa bits start in a word's power.
const POWER_SHIFT: [u32; 3] = [0, 11, 22];

/// A photon word's power (`PhotonWord`'s `w`) from its record's RGB9E5 power `rgb9e5`, by
/// integer arithmetic alone (every runtime writes the same bits): each channel a float of its
/// own, a 5-bit exponent E and a mantissa M of f = 6 (red, green) or 5 (blue) bits, holding
/// 2^(E − 32 + top)·(1 + M/2^f) for E in 1..=31 (E = M = 0: zero), top = `power_top`
/// (clamped to `POWER_TOP`). Its bits, placed in an `f32`'s exponent and mantissa
/// (`power_floats`: a shift and a mask), read as 2^(E − 127)·(1 + M/2^f), a normal float,
/// and one multiplication by `power_scale` makes that the power: the gather decodes a
/// channel in three operations (the shared exponent of RGB9E5 took about twice as many; a
/// decode of that cost took 7–11 % off the gather at ~50 photons a point, H100,
/// docs/gpu-runs/2026-12-06-gather-ablations-h100.md).
///
/// Rounding is dithered by the bits of `h` (a hash): over uniform `h` a channel's expectation is
/// its value exactly, so a pass's photons, which mostly share their power, add up to their power
/// however coarse the mantissa. Below the range (2^(top − 31)) a channel becomes the smallest value
/// with probability value / smallest, else 0 (unbiased too: a record's channel lies at most 2^-10
/// below the range, `POWER_TOP`, so the draw's 32 bits resolve it); above the largest value,
/// 2^top·(1 − 2^-(f + 1)), it is clamped to that (the host sets `top` two binades above every
/// photon's power: `IndexParams::power_top`).
#[inline(always)]
pub fn word_power(rgb9e5: u32, power_top: i32, h: u32) -> u32 {
    let top = power_top.clamp(POWER_TOP[0], POWER_TOP[1]);
    let s = (rgb9e5 >> 27) as i32;
    let mut out = 0u32;
    let mut c = 0usize;
    while c < 3 {
        let m = (rgb9e5 >> (9 * c as u32)) & 511;
        let f = POWER_MANTISSA[c];
        if m != 0 {
            // m · 2^(s − 24) = (m / 2^p) · 2^(p + s − 24), m in [2^p, 2^(p + 1)).
            let p = 31 - m.leading_zeros();
            let mut e = p as i32 + s - 24 + 32 - top;
            // f bits after the leading one: p − f bits dropped (at most 3), rounded up with
            // probability their fraction (8 dither bits of h a channel).
            let mut mm = if p > f {
                let k = p - f;
                (m + ((h >> (8 * c as u32)) & ((1 << k) - 1))) >> k
            } else {
                m << (f - p)
            };
            if mm >> (f + 1) != 0 {
                mm >>= 1;
                e += 1;
            }
            let bits = if e > 31 {
                (31 << f) | ((1 << f) - 1)
            } else if e >= 1 {
                ((e as u32) << f) | (mm - (1 << f))
            } else {
                // The smallest value (E = 1, M = 0) with probability mm / 2^(f + 1 − e).
                let k = f as i32 + 1 - e;
                let u = pcg_hash(h ^ (0x9E37_79B9u32.wrapping_mul(c as u32 + 1)));
                if k < 32 && (u & ((1u32 << k) - 1)) < mm {
                    1 << f
                } else {
                    0
                }
            };
            out |= bits << POWER_SHIFT[c];
        }
        c += 1;
    }
    out
}

/// The three `f32`s the bits of a word's power read as (`word_power`): each channel's power
/// divided by `power_scale`, exactly. A shift and a mask each.
#[inline(always)]
pub fn power_floats(v: u32) -> [f32; 3] {
    [f32::from_bits((v << 17) & 0x0ffe_0000), f32::from_bits((v << 6) & 0x0ffe_0000), f32::from_bits((v >> 4) & 0x0ffc_0000)]
}

/// What `power_floats` are multiplied by for the powers: 2^(95 + top), top = `power_top`
/// clamped to `POWER_TOP` (then within [2^72, 2^112]; the products are exact).
#[inline(always)]
pub fn power_scale(power_top: i32) -> f32 {
    exp2i(95 + power_top.clamp(POWER_TOP[0], POWER_TOP[1]))
}

/// The length of the normal vectors of photon words (`normal_bytes`), to within 0.9.
pub const NORMAL_LENGTH: f32 = 127.0;

/// An octahedral normal of 2 × 8 bits (`encode_oct`) as the three bytes a photon word holds: the
/// direction as a vector of length `NORMAL_LENGTH` in whole numbers (each in −127..=127), stored in
/// two's complement (so an arithmetic shift reads one). By integer arithmetic alone, so every
/// runtime writes the same bytes: `oct_vector` × 255 (unfolded on the lower half), its length by an
/// integer square root (× 16), each component scaled by 127 over it in a rounded division. Each
/// component is off by at most 1/2 (and the length by 1/16 of a unit), so the direction is within
/// 0.4° of the code's and the length within 0.9 of 127: the gather reads a vector without the
/// octahedral fold (`word_normal`) and tests it by one dot product against a fixed bound
/// (`facing`), not against its length.
#[inline(always)]
pub fn normal_bytes(oct: u32) -> [u32; 3] {
    let x = 2 * (oct & 0xff) as i32 - 255;
    let y = 2 * ((oct >> 8) & 0xff) as i32 - 255;
    let z = 255 - x.abs() - y.abs();
    let t = (-z).max(0);
    // x, y odd: never 0, so each moves towards 0 by t (and the vector is never 0).
    let toward_zero = |v: i32| if v < 0 { v + t } else { v - t };
    let (x, y) = (toward_zero(x), toward_zero(y));
    // 16 |v| rounded down (256 |v|² < 2^26), at least 22.
    let l = isqrt((x * x + y * y + z * z) as u32 * 256);
    // round(127 · 16 |c| / l), at most 127: |c| ≤ |v| and 16 |v| < l + 1.
    let byte = |c: i32| {
        let q = (c.unsigned_abs() * (2 * 127 * 16) + l) / (2 * l);
        if c < 0 {
            (256 - q) & 255
        } else {
            q
        }
    };
    [byte(x), byte(y), byte(z)]
}

/// The normal vector of a word's bytes (`normal_bytes`), in whole numbers (−127..=127, of
/// length `NORMAL_LENGTH` within 0.9): an arithmetic shift each.
#[inline(always)]
pub fn word_normal(w: UVec4) -> [i32; 3] {
    [(w.x as i32) >> 24, (w.y as i32) >> 24, (w.z as i32) >> 24]
}

/// A unit vector in whole numbers for `facing`: × 2^15, rounded (each within 1/2).
#[inline(always)]
pub fn normal_units(n: [f32; 3]) -> [i32; 3] {
    let r = |v: f32| {
        let v = v * 32768.0;
        (if v >= 0.0 { v + 0.5 } else { v - 0.5 }) as i32
    };
    [r(n[0]), r(n[1]), r(n[2])]
}

/// The index's photons in cell order: cell c's are `offsets[s]..offsets[s + 1]` of `words`,
/// s its `offset_slot` (`cell_range`).
#[derive(Copy, Clone)]
pub struct SortedPhotons<'a> {
    /// The photons' words (`PhotonWord`).
    pub words: &'a [PhotonWord],
    /// Each cell's first photon, at the cell's `offset_slot`; its end at the next entry.
    pub offsets: &'a [u32],
}

// ---------------------------------------------------------------------------------------------
// Emission

/// The four uniform numbers of photon `photon` of the pass of `p` (light and position ×2,
/// direction ×2): its own (`p.spread` 0), or its group's shifted by its lane's lattice point
/// times `p.spread`, modulo 1 (a toroidal shift: each photon's numbers are still uniform).
/// Independent or from the render's group sequence (`Sampler::photon_group`, `PHOTON_SOBOL`).
#[inline(always)]
pub fn emission_numbers(p: &PhotonParams, photon: u32) -> [f32; 4] {
    if p.spread > 0.0 {
        let smp = Sampler::photon_group(p, photon / GROUP, GROUP);
        let a = smp.get2(DIM_EMIT_POSITION);
        let b = smp.get2(DIM_EMIT_DIRECTION);
        let base = [a[0], a[1], b[0], b[1]];
        let lane = (photon % GROUP) as f32;
        let mut u = [0.0f32; 4];
        let mut k = 0;
        while k < 4 {
            u[k] = fract_pos(base[k] + fract_pos(lane * LATTICE[k]) * p.spread);
            k += 1;
        }
        u
    } else {
        let smp = Sampler::photon_group(p, photon, 1);
        let a = smp.get2(DIM_EMIT_POSITION);
        let b = smp.get2(DIM_EMIT_DIRECTION);
        [a[0], a[1], b[0], b[1]]
    }
}

/// A photon leaving the lights: its ray and power (1/`emitted` of the lights' total in
/// expectation), from the four numbers `u`: the first chooses the light and, rescaled to the
/// light's share, goes on with the second to place the point; the last two, the direction.
#[inline(always)]
pub fn emit_photon(lights: &[Light], light_count: u32, emitted: u32, u: [f32; 4]) -> (Ray, [f32; 3]) {
    if light_count == 0 || emitted == 0 {
        return (NO_RAY, [0.0; 3]);
    }
    let (li, p_select, u1) = choose_light(lights, light_count, u[0], true);
    let light = &lights[li];
    let norm = 1.0 / (p_select * emitted as f32);
    if light.kind == LIGHT_POINT {
        let d = direction_around([0.0, 0.0, 1.0], 1.0 - 2.0 * u[2], u[3]);
        let power = scale3(light.emission, 4.0 * core::f32::consts::PI * norm);
        return (Ray::new(light.p0, d, 0.0, f32::INFINITY), power);
    }
    if light.kind == LIGHT_SPOT {
        let cos_max = light.e2[0];
        let cos_theta = 1.0 - u[2] * (1.0 - cos_max);
        let d = direction_around(light.e1, cos_theta, u[3]);
        let solid = 2.0 * core::f32::consts::PI * (1.0 - cos_max);
        let power = scale3(light.emission, shade::spot_falloff(light, d) * solid * norm);
        return (Ray::new(light.p0, d, 0.0, f32::INFINITY), power);
    }
    let s = crate::math::sqrt(u1);
    let q = add3(add3(light.p0, scale3(light.e1, 1.0 - s)), scale3(light.e2, u[1] * s));
    let n = normalize3(cross3(light.e1, light.e2));
    let d = cosine_direction(n, u[2], u[3]);
    // A Lambertian emitter on its front side: power π · area · radiance.
    let power = scale3(light.emission, core::f32::consts::PI * light.area * norm);
    (Ray::new(offset(q, n), d, 0.0, f32::INFINITY), power)
}

/// Photon `i` of the dispatch (`p.first + i` of the pass) leaves a light.
#[inline(always)]
pub fn emit<R: Store<Ray> + ?Sized, S: Store<PhotonPath> + ?Sized>(i: u32, p: &PhotonParams, lights: &[Light], rays: &mut R, paths: &mut S) {
    if i < p.count {
        let u = emission_numbers(p, p.first + i);
        let (ray, power) = emit_photon(lights, p.light_count, p.emitted, u);
        let flags = if ray.is_valid() { PHOTON_ACTIVE | PHOTON_SPECULAR_ONLY } else { 0 };
        rays.store(i as usize, ray);
        paths.store(i as usize, PhotonPath { power, flags });
    }
}

// ---------------------------------------------------------------------------------------------
// Bounces

/// What happens to photon `photon` of the pass at its `bounce`-th hit `hit`: stored at a
/// diffuse surface (unless it comes straight from a light and direct light is left to shadow
/// rays), then continued (`ray` replaced, `path.flags` active) or absorbed; the counter
/// `counter[0]` counts every photon to store, including those past `p.capacity` (which are not
/// stored).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn bounce_step<O, C>(
    p: &PhotonParams,
    bounce: u32,
    photon: u32,
    ray: &mut Ray,
    hit: &Hit,
    tris: &Parts<Triangle>,
    materials: &[Material],
    path: &mut PhotonPath,
    photons: &mut O,
    counter: &mut C,
) where
    O: Store<Photon> + ?Sized,
    C: AtomicStore + ?Sized,
{
    let mut next = NO_RAY;
    let mut flags = 0;
    if hit.is_hit() {
        let tri = &tris.get(hit.prim as usize);
        let mat = &materials[tri.material as usize];
        let (pt, n) = surface_point(tri, hit, ray);
        let smp = Sampler::photon(p, photon);
        let last = bounce >= p.max_bounces;
        if is_specular(mat) {
            if !last {
                next = specular_bounce(mat, tri, pt, normalize3(ray.dir), smp.get1(sampler::dim(bounce, sampler::FRESNEL, 0)));
                if mat.flags & MAT_MIRROR != 0 {
                    path.power = mul3(path.power, mat.diffuse);
                }
                flags = PHOTON_ACTIVE | (path.flags & PHOTON_SPECULAR_ONLY);
            }
        } else {
            if bounce > 0 || p.flags & PHOTON_STORE_DIRECT != 0 {
                let caustic = p.caustic_map != 0 && bounce > 0 && path.flags & PHOTON_SPECULAR_ONLY != 0;
                let slot = counter.atomic_add(0, 1);
                if slot < p.capacity {
                    photons.store(slot as usize, Photon::new(pt, path.power, n, normalize3(ray.dir), caustic, bounce == 0, smp.get1(sampler::dim(bounce, sampler::DITHER, 0))));
                }
            }
            let a = mat.diffuse;
            let q = a[0].max(a[1]).max(a[2]).min(1.0);
            if !last && smp.get1(sampler::dim(bounce, sampler::ROULETTE, 0)) < q {
                let u = smp.get2(sampler::dim(bounce, sampler::BOUNCE, 0));
                let d = cosine_direction(n, u[0], u[1]);
                next = Ray::new(offset(pt, n), d, 0.0, f32::INFINITY);
                path.power = mul3(path.power, scale3(a, 1.0 / q));
                flags = PHOTON_ACTIVE;
            }
        }
    }
    path.flags = flags;
    *ray = next;
}

/// Photon `i` of the dispatch at its `p.bounce`-th hit (the closest-hit answer `hits[i]`):
/// `bounce_step` on the photon's state in the buffers.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn bounce<R, S, O, C>(
    i: u32,
    p: &PhotonParams,
    rays: &mut R,
    hits: &[Hit],
    tris: &Parts<Triangle>,
    materials: &[Material],
    paths: &mut S,
    photons: &mut O,
    counter: &mut C,
) where
    R: Store<Ray> + ?Sized,
    S: Store<PhotonPath> + ?Sized,
    O: Store<Photon> + ?Sized,
    C: AtomicStore + ?Sized,
{
    if i >= p.count {
        return;
    }
    let k = i as usize;
    let mut path = paths.load(k);
    if path.flags & PHOTON_ACTIVE == 0 {
        return;
    }
    let mut ray = rays.load(k);
    bounce_step(p, p.bounce, p.first + i, &mut ray, &hits[k], tris, materials, &mut path, photons, counter);
    rays.store(k, ray);
    paths.store(k, path);
}

/// The photons of item `i` of the dispatch, each from the light to its absorption: photons
/// `i`, `i + s`, `i + 2s`, … of the dispatch (`s`: `p.stride`, or `p.count` when that is 0,
/// one photon per item), the next one emitted as soon as the last is absorbed. A photon is
/// `emit`, then per bounce (up to `p.max_bounces`) a closest-hit query by `M` and
/// `bounce_step` — the same photons as the schedule of separate passes, without a dispatch per
/// bounce or state in buffers between them. Starting the next photon at once keeps a SIMD
/// group's lanes busy: with one photon per item a group runs as long as its longest path
/// (Russian roulette makes path lengths geometric), its other lanes idle. Bounded: at most
/// `p.max_bounces + 1` steps per photon and ⌈count / s⌉ photons per item.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn trace_photons<M: Method, O: Store<Photon> + ?Sized, C: AtomicStore + ?Sized>(
    i: u32,
    p: &PhotonParams,
    accel: &M::Accel<'_>,
    tris: &Parts<Triangle>,
    lights: &[Light],
    materials: &[Material],
    photons: &mut O,
    counter: &mut C,
) {
    let stride = if p.stride == 0 { p.count } else { p.stride };
    // Items past the stride (the rest of the last workgroup) trace nothing.
    let mut next = if i < stride { i } else { p.count };
    let mut photon = 0;
    let mut bounce = 0;
    let mut ray = NO_RAY;
    let mut path = PhotonPath { power: [0.0; 3], flags: 0 };
    loop {
        if path.flags & PHOTON_ACTIVE == 0 {
            if next >= p.count {
                break;
            }
            photon = p.first + next;
            // next + stride, without overflowing past count.
            next = if stride.max(1) >= p.count - next { p.count } else { next + stride };
            let (r, power) = emit_photon(lights, p.light_count, p.emitted, emission_numbers(p, photon));
            ray = r;
            path = PhotonPath { power, flags: if ray.is_valid() { PHOTON_ACTIVE | PHOTON_SPECULAR_ONLY } else { 0 } };
            bounce = 0;
            if !ray.is_valid() {
                continue;
            }
        }
        let mut q = Closest::new(&ray);
        M::find(accel, &ray, &mut q);
        let hit = q.answer();
        bounce_step(p, bounce, photon, &mut ray, &hit, tris, materials, &mut path, photons, counter);
        bounce += 1;
        if bounce > p.max_bounces {
            // `bounce_step` ends every path at its last bounce; kept for the bound.
            path.flags = 0;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The index

/// Receives the photons that a gather visits, one at a time, with the photons in cell order.
/// (The photons are passed along rather than held: a mutable visitor holding storage buffer
/// slices crashed NVIDIA's SPIR-V compiler, driver 580.)
pub trait CellVisitor {
    /// Visits a photon of `sorted` whose word (`PhotonWord`) is `w` if `real` — else pads the
    /// grid's step (`GRID_STEP` photons) past a run's end (`w` is then the run's last photon
    /// again, not to be counted).
    fn word(&mut self, w: UVec4, real: bool, sorted: &SortedPhotons);
}

/// Photons a step of the grid's gather loads and visits (`HashGrid::visit`), padding included.
pub const GRID_STEP: u32 = 4;
// `HashGrid::visit`'s step is written out for four photons.
const _: () = assert!(GRID_STEP == 4);

impl SortedPhotons<'_> {
    /// The photons of a run of cells whose offsets are at `first..end` (`offset_slot`): from
    /// `offsets[first]` to `offsets[end]`, both clamped to the words held, so that every
    /// photon of the range can be loaded without a bounds check (`word`), and a step past its
    /// start cannot wrap (the words of a binding number fewer than 2^31).
    #[inline(always)]
    pub fn run(&self, first: u32, end: u32) -> (u32, u32) {
        // Slots clamped to the table (an index's slots lie within it), so the loads need no
        // bounds check: the render's gathers 1.3–1.6 % faster on the H100 than with the checks
        // and the multiplicative block hash (`block_hash`; H → G in
        // docs/gpu-runs/2026-12-06-gather-hash-h100.md).
        let n = self.offsets.len() as u32;
        if n == 0 {
            return (0, 0);
        }
        let end = end.min(n - 1);
        let first = first.min(end);
        // SAFETY: first ≤ end < n.
        let (f, e) = unsafe { (*crate::kernel::at(self.offsets, first as usize), *crate::kernel::at(self.offsets, end as usize)) };
        let b = e.min(self.words.len() as u32);
        (f.min(b), b)
    }
    /// Photon `j`'s word, for `j` below the end of a range of `run`.
    ///
    /// # Safety
    /// `j < words.len()` (a range from `run` holds only such photons).
    #[inline(always)]
    pub unsafe fn word(&self, j: u32) -> UVec4 {
        // SAFETY: the caller's contract.
        unsafe { crate::kernel::at(self.words, j as usize).word }
    }
    /// Visits (`CellVisitor`) the photons of a run of cells whose offsets are at `first..end`.
    #[inline(always)]
    pub fn visit_run<V: CellVisitor>(&self, first: u32, end: u32, v: &mut V) {
        let (mut j, b) = self.run(first, end);
        while j < b {
            // SAFETY: j < b, and `run` clamps b to the words held.
            v.word(unsafe { self.word(j) }, true, self);
            j += 1;
        }
    }
}

/// Where photons live: the cell of a photon, and the cells a disc query must look at.
pub trait PhotonIndex {
    /// The cell (of `map`: 0 global, 1 caustic) that holds a photon at `p`.
    fn cell(&self, p: [f32; 3], map: u32) -> u32;
    /// Visits (`CellVisitor`) the photons of runs of consecutive cells of `map` that hold
    /// every cell that may hold a photon within `r` of `x` (and possibly others), each such
    /// cell once.
    fn visit<V: CellVisitor>(&self, x: [f32; 3], r: f32, map: u32, sorted: &SortedPhotons, v: &mut V);
}

/// How far from a query point x a photon that `Disc::test` counts at radius `r` may lie, along
/// any axis: `r` widened by 10^-5 relative and by `slack`, the index's `gather_slack` (which
/// each index keeps). Each index visits every cell that holds photons within it of x, so a
/// gather finds every photon brute force counts, however small `r` is against the scene box.
#[inline(always)]
fn reach(r: f32, slack: f32) -> f32 {
    fma(r, 1e-5, r) + slack
}

/// A bound on how much farther than the radius a photon that `Disc::test` counts may lie from
/// the query point, in scene units: the test decodes a word's offset from x against `base(x)` =
/// origin − x rounded (`WordFrame`), whose rounding is up to half an ulp of |origin − x|, about
/// a word step (origin lies 2^23 steps below the box); the word's position, which places the
/// photon in its cell, is rounded to half an ulp of its magnitude. For x within the box (or
/// within the radius of it) both together stay below 2^-22 of the largest magnitude m of the
/// frame's origin and the box's corners: this is twice that, m · 2^-21 (0 for an empty box).
/// Against a radius of 10^-6 of the box (where it matters) the test's rounding is about as
/// large as the radius: without this the grid's window missed such photons (found by a code
/// review, 2026-12-05).
#[inline(always)]
pub fn gather_slack(p: &IndexParams) -> f32 {
    let f = WordFrame::new(p);
    let mut m = 0.0f32;
    let mut a = 0;
    while a < 3 {
        m = m.max(f.origin[a].abs()).max(p.bounds_min[a].abs()).max(p.bounds_max[a].abs());
        a += 1;
    }
    m * (1.0 / 2_097_152.0)
}

/// (B) A hashed uniform grid per map, its cells `wx` × w × w to a query's window (`grid_windows`):
/// across the rows (y and z) cells of 2r/(w − 1) for w = 2 or 3 (cells of 2r or r), along them
/// (x) cells of 2r/(wx − 1), as fine or finer (wx = w, or 5, 7 or 9 cells of r/2, r/3 or r/4
/// with w = 3), so a disc of radius r overlaps at most wx × w × w cells. Cells are grouped in
/// blocks of wx × w × w; a block is hashed to one of `blocks` slots (a power of two) and a
/// cell's bucket is its block's slot times wx·w² plus its place in the block (coordinates
/// modulo wx, w and w). Any wx consecutive cells along x (w along y or z) differ modulo wx (w),
/// so the cells of one query never share a bucket: each is visited once, with no bookkeeping.
/// A block's cells are sorted together, as one segment (`sort::segment_offsets`: its offsets at
/// `offset_slot`), so that each row of a window within a block is one run, however many cells
/// long: finer cells along x cost no runs, and a row is clipped to the chord the query's
/// sphere cuts from it (`visit`), so a row in the disc's plane tests the photons of about 2r
/// of its length instead of 3r. The default, wx = 7 (cells of r/3 along x): at ~50 photons
/// found a point, 21–29 % fewer photons tested than cubes of r (Cornell box 157.6 → 123.8,
/// conference room 208.3 → 149.0) and the gather 5–20 % faster in tiles (H100,
/// `docs/gpu-runs/2026-12-05-gather-rows-h100.md`); wx = 9 had fewer blocks for its cells and
/// tested more. Finer cells across the rows (windows of 4 and 5 cells on every axis) tested
/// fewer photons but ran 10–25 % slower (H200, `docs/gpu-runs/2026-12-03-gather-order-h200.md`),
/// and 15–40 % slower with runs listed before the photon loop (H100,
/// `docs/gpu-runs/2026-12-05-gather-runs-h100.md`): each row is a run.
pub struct HashGrid {
    /// The scene box's minimum corner; cells are counted from one cell below it.
    pub origin: [f32; 3],
    /// Buckets per map: `blocks` × wx·w².
    pub cells: u32,
    /// Cells along x of a query's window (2, 3, 5, 7 or 9).
    pub wx: u32,
    /// Cells along y and along z of a query's window (2 or 3).
    pub w: u32,
    /// Hashed slots of blocks per map (a power of two).
    pub blocks: u32,
    /// Per map (global, caustic): the cell size along x, and along y and z.
    pub cell_size: [[f32; 2]; 2],
    /// `gather_slack` of the index's parameters.
    pub slack: f32,
}

/// The values of `IndexParams::grid` (a grid's cells along x a query visits: `grid_windows`).
pub const GRID_WINDOWS: [u32; 5] = [2, 3, 5, 7, 9];

/// The windows (cells along x, and along y and z, a query visits) of `IndexParams::grid`
/// g (one of `GRID_WINDOWS`): (2, 2) for g = 2; (g, 3) for g = 5, 7 or 9; (3, 3) otherwise.
#[inline(always)]
pub fn grid_windows(grid: u32) -> [u32; 2] {
    if grid == 2 {
        [2, 2]
    } else if grid == 5 || grid == 7 || grid == 9 {
        [grid, 3]
    } else {
        [3, 3]
    }
}

impl HashGrid {
    /// The grid of `p`: origin `bounds_min`, `cells` buckets, cells of 2s/(wx − 1) along x and
    /// 2s/(w − 1) along y and z for each map's radius r, s its `reach` widened once more
    /// by as much (so a window of wx × w × w cells spans the reach on both sides of any point,
    /// whatever the rounding of the cells' coordinates; at most 2^23 + 2 cells along an axis, so
    /// `coord` counts them exactly in `f32`).
    #[inline(always)]
    pub fn new(p: &IndexParams) -> HashGrid {
        let [wx, w] = grid_windows(p.grid);
        let (kx, k) = (2.0 / (wx - 1) as f32, 2.0 / (w - 1) as f32);
        let slack = gather_slack(p);
        let size = |r: f32| {
            let s = fma(r, 2e-5, r) + 2.0 * slack;
            [kx * s, k * s]
        };
        HashGrid { origin: p.bounds_min, cells: p.cells, wx, w, blocks: p.cells / (wx * w * w), cell_size: [size(p.radius[0]), size(p.radius[1])], slack }
    }
    #[inline(always)]
    fn coord(&self, x: f32, o: f32, inv: f32) -> u32 {
        // Cells counted from one below the scene box, so points slightly outside stay >= 0.
        floor_u32((x - o) * inv + 1.0)
    }
    #[inline(always)]
    fn bucket(&self, c: [u32; 3], map: u32) -> u32 {
        let (wx, w) = (self.wx, self.w);
        let h = block_hash(c[0] / wx, block_yz(c[1] / w, c[2] / w), self.blocks);
        let place = c[0] % wx + wx * (c[1] % w + w * (c[2] % w));
        h * (wx * w * w) + place + map * self.cells
    }
}

impl PhotonIndex for HashGrid {
    #[inline(always)]
    fn cell(&self, p: [f32; 3], map: u32) -> u32 {
        let s = self.cell_size[map as usize];
        let (ix, i) = (1.0 / s[0], 1.0 / s[1]);
        let o = self.origin;
        self.bucket([self.coord(p[0], o[0], ix), self.coord(p[1], o[1], i), self.coord(p[2], o[2], i)], map)
    }
    #[inline(always)]
    fn visit<V: CellVisitor>(&self, x: [f32; 3], r: f32, map: u32, sorted: &SortedPhotons, v: &mut V) {
        let s = self.cell_size[map as usize];
        let (ix, i, c) = (1.0 / s[0], 1.0 / s[1], s[1]);
        let o = self.origin;
        let (wx, w) = (self.wx, self.w);
        // Every photon `Disc::test` may count lies within the reach (`reach`).
        let r = reach(r, self.slack);
        let lo = [self.coord(x[0] - r, o[0], ix), self.coord(x[1] - r, o[1], i), self.coord(x[2] - r, o[2], i)];
        // At most wx (w) cells along x (y, z): the reach spans 2r, less than wx − 1 (w − 1)
        // cell sizes. (Wrapping: a point at infinity has lo = u32::MAX, and then no window.)
        let hi = [
            self.coord(x[0] + r, o[0], ix).min(lo[0].wrapping_add(wx - 1)),
            self.coord(x[1] + r, o[1], i).min(lo[1].wrapping_add(w - 1)),
            self.coord(x[2] + r, o[2], i).min(lo[2].wrapping_add(w - 1)),
        ];
        // Along x, the cells of one block are consecutive buckets: a row of the window is one
        // run, or two where it crosses into the next block. The block hash is nested as in
        // `bucket`. Offsets come by segments of a block's wx·w² cells (`offset_slot`), one
        // more entry each.
        let first_block = map * self.blocks;
        let seg = wx * w * w;
        let (qx0, mx0) = (lo[0] / wx, lo[0] % wx);
        // Each row (y, z) is clipped to the sphere: at distance d from x its rectangle across
        // y and z holds photons within r only along the chord x ± √(r² − d²), and none where
        // d > r. Widened so that no photon a `Disc::test` counts is lost to rounding: r is the
        // reach (above), distances and the half chord are widened by `eps`, far above the
        // rounding of coordinates of magnitude `m` (the cells' bounds, `coord`'s products) and
        // of a GPU's square root.
        let m = x[0].abs().max(x[1].abs()).max(x[2].abs()) + o[0].abs().max(o[1].abs()).max(o[2].abs()) + r;
        let eps = 1e-6 * m;
        let r2 = r * r;
        // The window's first row along y and along z (`RowAxis`).
        let axis = |a: usize| RowAxis { k: lo[a], q: lo[a] / w, m: lo[a] % w, lo: fma(lo[a] as f32 - 1.0, c, o[a]) };
        let (y0, mut z) = (axis(1), axis(2));
        // A row's distance from x along y or z, less `eps`, at least 0.
        let dist = |a: &RowAxis, x: f32| ((a.lo - x).max(x - (a.lo + c)) - eps).max(0.0);
        // First every run's photons (`sorted.run`), in visiting order, the empty ones left
        // out; then one loop over their photons. Computing a run (hashes, offsets) inside the
        // photon loop made a subgroup take that step at nearly every photon step (its lanes
        // reach the ends of their runs at different steps, and an empty row, most of a window
        // around a floor's point, cost a step): the gather at ~50 photons a point took 15–25 %
        // longer on the H100 (2026-12-05). Not initialised (a store per entry otherwise,
        // 2–4 %): entries below `count` are written before they are read.
        let mut runs = [MaybeUninit::<[u32; 2]>::uninit(); MAX_RUNS];
        let mut count = 0usize;
        while z.k <= hi[2] {
            let dz = dist(&z, x[2]);
            let mut y = y0;
            while y.k <= hi[1] {
                let dy = dist(&y, x[1]);
                let h2 = r2 - dy * dy - dz * dz;
                if h2 >= 0.0 {
                    let h = sqrt(h2) + eps;
                    // The chord's cells, within the window (so a ≤ b: both hold x's cell).
                    let a = self.coord(x[0] - h, o[0], ix).max(lo[0]);
                    let b = self.coord(x[0] + h, o[0], ix).min(hi[0]);
                    // a's block and place along x, from lo's: a − lo[0] < wx.
                    let mut ma = mx0 + (a - lo[0]);
                    let mut qa = qx0;
                    if ma >= wx {
                        ma -= wx;
                        qa += 1;
                    }
                    let n = b + 1 - a.min(b);
                    let first = n.min(wx - ma);
                    let hy = block_yz(y.q, z.q);
                    let place = wx * (y.m + w * z.m);
                    let slot = |q: u32| (block_hash(q, hy, self.blocks) + first_block) * (seg + 1) + place;
                    // Stored whatever they hold, kept (counted) only if they hold photons. At
                    // most MAX_RUNS runs: w ≤ 3 rows per axis, two runs a row.
                    let s0 = slot(qa) + ma;
                    let (j, e) = sorted.run(s0, s0 + first);
                    runs[count.min(MAX_RUNS - 1)] = MaybeUninit::new([j, e]);
                    count += (j < e) as usize;
                    if first < n {
                        let s1 = slot(qa + 1);
                        let (j, e) = sorted.run(s1, s1 + n - first);
                        runs[count.min(MAX_RUNS - 1)] = MaybeUninit::new([j, e]);
                        count += (j < e) as usize;
                    }
                }
                y.step(w, c);
            }
            z.step(w, c);
        }
        // One loop over the photons of every run (a run's photons, or the next run): the
        // lanes of a subgroup step through photons together even where their runs differ in
        // length, instead of waiting at the end of each run for the longest.
        let count = count.min(MAX_RUNS);
        let mut next = 0usize;
        let (mut j, mut b) = (0u32, 0u32);
        loop {
            if j >= b {
                if next >= count {
                    break;
                }
                // SAFETY: next < count, and entries below count were written above.
                [j, b] = unsafe { runs[next].assume_init() };
                next += 1;
            }
            // Four photons a step: all four loads are issued before any is tested. The places
            // past a run's end load the run's last photon again and pass it as not real (not
            // counted): no separate step for a run's last one to three photons, which the other
            // lanes waited on. (Two a step was 8–11 % slower on the H100 at ~50 photons found a
            // point, the conference room the same. A padding word selected in their place, four
            // selections each, rejected by its zero normal: the gather 4–5 % slower, H100,
            // docs/gpu-runs/2026-12-06-power-format-h100.md.)
            let j1 = (j + 1).min(b - 1);
            let j2 = (j + 2).min(b - 1);
            let j3 = (j + 3).min(b - 1);
            // SAFETY: j ≤ j1 ≤ j2 ≤ j3 < b (a kept run is not empty), and `run` clamps b to the
            // words held.
            let (w0, w1, w2, w3) = unsafe { (sorted.word(j), sorted.word(j1), sorted.word(j2), sorted.word(j3)) };
            v.word(w0, true, sorted);
            v.word(w1, j1 > j, sorted);
            v.word(w2, j2 > j1, sorted);
            v.word(w3, j3 > j2, sorted);
            j = (j + GRID_STEP).min(b);
        }
    }
}

/// The first half of a grid block's hash (`block_hash`): its coordinates along y and z.
#[inline(always)]
fn block_yz(qy: u32, qz: u32) -> u32 {
    qy.wrapping_mul(0x9E37_79B1) ^ qz.wrapping_mul(0x85EB_CA6B)
}

/// The hashed slot, of `blocks` (a power of two), of the grid block (qx, qy, qz) whose
/// `block_yz` is `yz`: multiplicative, with the high bits folded into the low ones. In place of
/// three nested `pcg_hash`es (a block's hash about 9 operations against 30; within a row of a
/// gather, where y and z are hashed once, 6 a slot against 11): the same images, in the global
/// map at most 0.7 % more photons tested a point, the glass sphere's gather in tiles at ~50
/// photons a point 3.6 % faster, the Cornell box's the same, at the default radius 1–2 % slower
/// (H100, docs/gpu-runs/2026-12-06-gather-hash-h100.md, D → H).
#[inline(always)]
fn block_hash(qx: u32, yz: u32, blocks: u32) -> u32 {
    let h = (qx.wrapping_mul(0xC2B2_AE35) ^ yz).wrapping_mul(0x27D4_EB2F);
    (h ^ (h >> 15)) & (blocks - 1)
}

/// A coordinate of a grid query's rows (y or z): the cell `k`, its block `q` = k / w and place
/// `m` = k % w in the block, and the cell's lower bound `lo` (cell k spans
/// [o + (k − 1)·c, o + k·c) for the grid's origin o and cell size c), stepped from one row to
/// the next without divisions (w is a push constant: a division by it costs tens of
/// instructions).
#[derive(Copy, Clone)]
struct RowAxis {
    k: u32,
    q: u32,
    m: u32,
    lo: f32,
}

impl RowAxis {
    /// The next row's: a cell further, into the next block after w places.
    #[inline(always)]
    fn step(&mut self, w: u32, c: f32) {
        self.k += 1;
        self.lo += c;
        self.m += 1;
        if self.m == w {
            self.m = 0;
            self.q += 1;
        }
    }
}

/// Most runs of photons a grid query visits: windows of at most three cells along y and z
/// (`grid_windows`), each row of a window one run or two (where it crosses into the next block).
const MAX_RUNS: usize = 2 * 3 * 3;

/// (A) The paper's index: the geometry kd-tree's leaves, each subdivided into a grid of cells
/// of about the gather radius (`LeafCells`, one entry per node); a photon's leaf is found by
/// point location from the root, a query's by walking the tree with the query box.
pub struct KdCells<'a> {
    /// The geometry kd-tree's nodes.
    pub nodes: &'a [KdNode],
    /// Each node's cells, indexed like `nodes` (interior nodes' have `dims` 0).
    pub leaves: &'a [LeafCells],
    /// Cells of one map; the caustic map's cells are numbered after the global map's.
    pub cells: u32,
    /// `gather_slack` of the index's parameters.
    pub slack: f32,
}

#[inline(always)]
fn dims(l: &LeafCells) -> [u32; 3] {
    [l.dims & 1023, (l.dims >> 10) & 1023, (l.dims >> 20) & 1023]
}

/// Cell coordinate of `x` along one axis of a leaf (clamped into the leaf).
#[inline(always)]
fn leaf_coord(x: f32, lo: f32, hi: f32, n: u32) -> u32 {
    let w = hi - lo;
    let t = if w > 0.0 { (x - lo) / w * n as f32 } else { 0.0 };
    floor_u32(t).min(n - 1)
}

impl<'a> KdCells<'a> {
    /// The index of `p` over the tree's `nodes` and their cells `leaves`.
    #[inline(always)]
    pub fn new(p: &IndexParams, nodes: &'a [KdNode], leaves: &'a [LeafCells]) -> Self {
        KdCells { nodes, leaves, cells: p.cells, slack: gather_slack(p) }
    }
}

impl KdCells<'_> {
    #[inline(always)]
    fn locate(&self, p: [f32; 3]) -> usize {
        let mut node = 0usize;
        let mut steps = 0;
        while !self.nodes[node].is_leaf() && steps < KD_STACK {
            let nd = self.nodes[node];
            let c = nd.first_child() as usize;
            node = if p[nd.axis()] < nd.split() { c } else { c + 1 };
            steps += 1;
        }
        node
    }
}

impl PhotonIndex for KdCells<'_> {
    #[inline(always)]
    fn cell(&self, p: [f32; 3], map: u32) -> u32 {
        let l = &self.leaves[self.locate(p)];
        let d = dims(l);
        if d[0] == 0 {
            return NO_CELL;
        }
        let c = [leaf_coord(p[0], l.lo[0], l.hi[0], d[0]), leaf_coord(p[1], l.lo[1], l.hi[1], d[1]), leaf_coord(p[2], l.lo[2], l.hi[2], d[2])];
        l.base + (c[2] * d[1] + c[1]) * d[0] + c[0] + map * self.cells
    }
    #[inline(always)]
    fn visit<V: CellVisitor>(&self, x: [f32; 3], r: f32, map: u32, sorted: &SortedPhotons, v: &mut V) {
        // Every photon `Disc::test` may count lies within the reach (`reach`); the
        // leaves' planes and cells place photons and the box's corners by the same monotonic
        // comparisons and coordinates.
        let r = reach(r, self.slack);
        let lo = sub3(x, [r; 3]);
        let hi = add3(x, [r; 3]);
        let nodes = self.nodes;
        leaves_in_box(nodes.len(), |i| nodes[i], lo, hi, |node, _| {
            let l = &self.leaves[node];
            let d = dims(l);
            if d[0] == 0 {
                return true;
            }
            let a = [leaf_coord(lo[0], l.lo[0], l.hi[0], d[0]), leaf_coord(lo[1], l.lo[1], l.hi[1], d[1]), leaf_coord(lo[2], l.lo[2], l.hi[2], d[2])];
            let b = [leaf_coord(hi[0], l.lo[0], l.hi[0], d[0]), leaf_coord(hi[1], l.lo[1], l.hi[1], d[1]), leaf_coord(hi[2], l.lo[2], l.hi[2], d[2])];
            let mut z = a[2];
            while z <= b[2] {
                let mut y = a[1];
                while y <= b[1] {
                    // A row of the leaf's cells along x is a run of consecutive cells.
                    let c = l.base + (z * d[1] + y) * d[0] + map * self.cells;
                    sorted.visit_run(c + a[0], c + b[0] + 1, v);
                    y += 1;
                }
                z += 1;
            }
            true
        });
    }
}

/// The map a photon belongs to: 1 (caustic) when there is a caustic map and it is a caustic
/// photon, else 0.
#[inline(always)]
fn map_of(p: &IndexParams, ph: &Photon) -> u32 {
    if p.maps > 1 && ph.is_caustic() {
        1
    } else {
        0
    }
}

/// The cell of photon slot `i` (that of its word's position, `PhotonWord`; `NO_CELL` past the
/// stored photons), and the photon's place among its cell's (`sort::count_rank`, fused: one
/// pass reads the photons once; its `sort::start` too).
#[inline(always)]
pub fn keys<I: PhotonIndex, K: Store<u32> + ?Sized, C: AtomicStore + ?Sized, S: AtomicStore + Store<u32> + ?Sized, R: Store<u32> + ?Sized>(
    i: u32,
    p: &IndexParams,
    index: &I,
    photons: &[Photon],
    counter: &[u32],
    keys: &mut K,
    counts: &mut C,
    segments: &mut S,
    ranks: &mut R,
) {
    let sp = sort_params(p);
    crate::sort::start(i, &sp, segments);
    if i < p.count {
        let stored = counter[0].min(p.count);
        let key = if i < stored {
            // The cell of the photon's word (`place`), where a gather decodes it.
            let ph = &photons[i as usize];
            index.cell(WordFrame::new(p).snap(ph.position), map_of(p, ph))
        } else {
            NO_CELL
        };
        keys.store(i as usize, key);
        ranks.store(i as usize, crate::sort::rank(key, &sp, counts, segments));
    }
}

/// The index's counting sort: `p.cells · p.maps` keys, by segments of a block's cells for the
/// hashed grid (`sort::segment_offsets`), exact for the kd index.
#[inline(always)]
pub fn sort_params(p: &IndexParams) -> SortParams {
    let [wx, w] = grid_windows(p.grid);
    SortParams { count: p.count, cells: p.cells * p.maps, segment: if p.kind == INDEX_KD { 0 } else { wx * w * w }, _pad: 0 }
}

/// Where the offset of cell `cell` is: the hashed grid's offsets come by segments of a block's
/// cells (`sort::segment_slot`), the kd index's in cell order.
#[inline(always)]
pub fn offset_slot(p: &IndexParams, cell: u32) -> u32 {
    crate::sort::offset_slot(cell, &sort_params(p))
}

/// The photons of cell `cell`: `offsets[s]..offsets[s + 1]` for its `offset_slot` s.
#[inline(always)]
pub fn cell_range(p: &IndexParams, offsets: &[u32], cell: u32) -> (u32, u32) {
    let s = offset_slot(p, cell) as usize;
    (offsets[s], offsets[s + 1])
}

/// Photon slot `i` into cell order: its word (`PhotonWord`, in the frame of `p`'s scene box)
/// at its cell's offset plus its rank (slots without a cell are left out); the sort's scatter,
/// so the first photon of a cell zeroes its count (`sort::release`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn place<C: Store<u32> + ?Sized, W: Store<PhotonWord> + ?Sized>(
    i: u32,
    p: &IndexParams,
    photons: &[Photon],
    keys: &[u32],
    ranks: &[u32],
    offsets: &[u32],
    counts: &mut C,
    words: &mut W,
) {
    if i < p.count {
        let key = keys[i as usize];
        if key < p.cells * p.maps {
            let rank = ranks[i as usize];
            let slot = (offsets[offset_slot(p, key) as usize] + rank) as usize;
            words.store(slot, PhotonWord::of(&photons[i as usize], &WordFrame::new(p)));
            crate::sort::release(key, rank, counts);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Gather

/// A gather's disc: a point `x` with unit normal n (on the viewing side; held as its `units`),
/// radius² `r2`, and the frame of the photon words it tests (`WordFrame`) with its `base` at `x`.
#[derive(Copy, Clone, Debug)]
pub struct Disc {
    /// The words' frame.
    pub frame: WordFrame,
    /// The centre.
    pub x: [f32; 3],
    /// The radius, squared.
    pub r2: f32,
    /// `frame.base(x)`.
    pub base: [f32; 3],
    /// `power_scale(frame.power_top)`: what a word's `power_floats` are multiplied by.
    pub power_scale: f32,
    /// `normal_units(n)`.
    pub units: [i32; 3],
}

impl Disc {
    /// The disc of radius `r` at `x` (normal `n`) over the photon words of an index of `p`.
    #[inline(always)]
    pub fn new(p: &IndexParams, x: [f32; 3], n: [f32; 3], r: f32) -> Disc {
        let frame = WordFrame::new(p);
        Disc { frame, x, r2: r * r, base: frame.base(x), power_scale: power_scale(frame.power_top), units: normal_units(n) }
    }

    /// Whether the photon of word `w` counts: within the radius, its surface's normal within 60°
    /// of `n` (photons on the back side or of another orientation never count; `facing`). Also
    /// its distance² (the filters' argument).
    #[inline(always)]
    pub fn test(&self, w: UVec4) -> (bool, f32) {
        let d = self.frame.offset(w, self.base);
        let d2 = dot3(d, d);
        // No branches: a subgroup's lanes pay for every side of one.
        ((d2 <= self.r2) & facing(w, self.units), d2)
    }
}

/// Whether the normal of word `w` lies within 60° of the unit vector n whose `normal_units` are
/// `units`: m · n > 127/2 for its vector m (`word_normal`, of length 127 within 0.9: cos > 0.5
/// within 0.7 %, 0.25° at 60°), in whole numbers, m · units > 127 · 2^14 (n's units within 1/2 of n
/// · 2^15: the dot product within 111 of m · n · 2^15, 2^-14 of the bound), exact on every runtime.
/// One dot product against a fixed bound, no square root or division: the test runs for every
/// photon a gather visits. Against m's own length instead (4 (m·n)² > |m|², m·n > 0), with a test
/// of the filter at every photon too, the gather took 12–19 % longer (H100, 2026-12-05; the
/// filter's test alone 8–13 %: `irradiance`). In integers (an arithmetic shift and a multiply-add a
/// component) rather than floats (a shift, an or and a subtraction to make the component a float,
/// then a multiply-add) the renders' gathers took 1.1–1.5 % less time, in tiles at ~50 photons a
/// point 2–6 % less on three scenes, 0.7 % more on the Cornell box (H100,
/// docs/gpu-runs/2026-12-06-power-format-h100.md).
#[inline(always)]
pub fn facing(w: UVec4, units: [i32; 3]) -> bool {
    let m = word_normal(w);
    // |m · units| ≤ 127 · 32768 · √3 · (1 + 2^-15): no overflow.
    m[0] * units[0] + m[1] * units[1] + m[2] * units[2] > 127 * 16384
}

/// Sums the photons of visited cells within a disc, weighted by the filter (`FILTER_*`;
/// `CONSTANT`: the constant filter, weight 1, without a test of `filter` at every photon).
struct Sum<const CONSTANT: bool> {
    disc: Disc,
    filter: u32,
    sum: [f32; 3],
    found: u32,
}

impl<const CONSTANT: bool> CellVisitor for Sum<CONSTANT> {
    /// One 16-byte word a photon: its place, normal and power.
    #[inline(always)]
    fn word(&mut self, w: UVec4, real: bool, _sorted: &SortedPhotons) {
        // Branch-free: every photon's power is added, weighted 0 outside the disc (a branch
        // made the lanes of a subgroup that counted nothing wait for those that did: 10 % of
        // the gather on the H200).
        let (counts, d2) = self.disc.test(w);
        // A step's padding (`HashGrid::visit`) counts nowhere.
        let counts = counts & real;
        // Natively a branch is cheaper than the work it skips (most visited photons lie
        // outside the disc; adding their zeros instead leaves the same sum): the native
        // Cornell box render, 16 passes at 512², 15.3 → 11.9 s on 2 cores, the same image.
        #[cfg(not(target_arch = "spirv"))]
        if !counts {
            return;
        }
        let r2 = self.disc.r2;
        let k = if CONSTANT {
            1.0
        } else if self.filter == FILTER_CONE {
            3.0 * (1.0 - sqrt(d2 / r2))
        } else if self.filter == FILTER_EPANECHNIKOV {
            2.0 * (1.0 - d2 / r2)
        } else {
            1.0
        };
        // The power (`word_power`): each channel's float (`power_floats`) times the scale, a
        // power of two (exact, so fused or not, the sum's addition rounds once), times the
        // filter's weight k (0 outside the disc).
        let f = power_floats(w.w);
        if CONSTANT {
            let ks = if counts { self.disc.power_scale } else { 0.0 };
            self.sum = [fma(f[0], ks, self.sum[0]), fma(f[1], ks, self.sum[1]), fma(f[2], ks, self.sum[2])];
        } else {
            self.sum = add3(self.sum, scale3(scale3(f, self.disc.power_scale), if counts { k } else { 0.0 }));
        }
        self.found += counts as u32;
    }
}

/// A density estimate at a point (`irradiance`).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Irradiance, Σ w·Φ / (π r²).
    pub irradiance: [f32; 3],
    /// Photons that counted.
    pub found: u32,
}

/// Irradiance at `x` (normal `n` on the viewing side) from one map: Σ w·Φ / (π r²) over the
/// photons within the map's radius on the same side.
#[inline(always)]
pub fn irradiance<I: PhotonIndex>(index: &I, p: &IndexParams, sorted: &SortedPhotons, x: [f32; 3], n: [f32; 3], map: u32) -> Estimate {
    let r = p.radius[map as usize];
    let disc = Disc::new(p, x, n, r);
    // The constant filter (the default) in a loop of its own: a test of the filter at every
    // photon cost 8–13 % of the gather (H100, 2026-12-05).
    let (sum, found) = if p.filter == FILTER_CONSTANT {
        let mut s = Sum::<true> { disc, filter: p.filter, sum: [0.0; 3], found: 0 };
        index.visit(x, r, map, sorted, &mut s);
        (s.sum, s.found)
    } else {
        let mut s = Sum::<false> { disc, filter: p.filter, sum: [0.0; 3], found: 0 };
        index.visit(x, r, map, sorted, &mut s);
        (s.sum, s.found)
    };
    Estimate { irradiance: scale3(sum, 1.0 / (core::f32::consts::PI * r * r)), found }
}

/// Path `i` (or, under `GATHER_LISTED`, the `i`-th path listed in `points`): if it ended at a
/// gather point, adds the reflected radiance the photons of maps `p.first_map..p.maps` give
/// (throughput already holds albedo/π) to its radiance (the film then adds the paths up).
/// Under `GATHER_EDGES` a point near an edge (marked `PATH_NEAR_EDGE` by `mark_edges`) takes
/// the caustic map only, stays a gather point (for the final gather) and is listed in
/// `next_points` (its count in `next_points[0]`, cleared before; a list without room for every
/// path, one element, lists none); every other point stops being one. A list: element 0 the
/// count, then the paths' indices.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn gather<I: PhotonIndex, P: Store<PathState> + ?Sized, L: Store<u32> + AtomicStore + ?Sized>(
    i: u32,
    p: &IndexParams,
    index: &I,
    rays: &[Ray],
    sorted: &SortedPhotons,
    paths: &mut P,
    points: &[u32],
    next_points: &mut L,
) {
    if i >= p.count {
        return;
    }
    let mut k = i as usize;
    if p.gather_flags & GATHER_LISTED != 0 {
        if i >= points[0] {
            return;
        }
        k = points[1 + i as usize] as usize;
    }
    let mut path = paths.load(k);
    if path.flags & PATH_GATHER != 0 {
        let g = rays[k];
        let edges = p.gather_flags & GATHER_EDGES != 0;
        let near_edge = edges && path.flags & PATH_NEAR_EDGE != 0;
        let mut e = [0.0; 3];
        // A point near an edge leaves the global map (map 0) to the final gather.
        let mut map = if near_edge { p.first_map.max(1) } else { p.first_map };
        while map < p.maps {
            e = add3(e, irradiance(index, p, sorted, g.origin, g.dir, map).irradiance);
            map += 1;
        }
        path.radiance = add3(path.radiance, mul3(path.throughput, e));
        if edges {
            if near_edge {
                let slot = next_points.atomic_add(0, 1) as usize;
                // A list without room (none kept: the next gather runs over every path).
                if 1 + slot < next_points.len() {
                    next_points.store(1 + slot, k as u32);
                }
            } else {
                path.flags &= !PATH_GATHER;
            }
        }
        paths.store(k, path);
    }
}

// ---------------------------------------------------------------------------------------------
// Edges

/// Whether a gather disc (centre `x`, unit normal `n`, radius² `r2`) reaches past its surface:
/// a triangle within the radius faces another way (normals more than 60° apart, either side:
/// a corner or a crease), or an open edge lies within it (an edge no other triangle shares:
/// where a surface ends). There a density estimate counts photons over less than πr² of
/// surface, and is biased low. A `Near` query over the scene's triangles; `open_edges[t]` has
/// bit k set where edge k of triangle t (from vertex k to vertex k + 1 mod 3) is open.
pub struct EdgeProbe<'a> {
    /// The disc's centre.
    pub x: [f32; 3],
    /// Its normal (unit).
    pub n: [f32; 3],
    /// Its radius, squared.
    pub r2: f32,
    /// Each triangle's open edges (bits 0..3).
    pub open_edges: &'a [u32],
}

impl Near for EdgeProbe<'_> {
    #[inline(always)]
    fn test(&self, prim: u32, tri: &Triangle) -> bool {
        if dist2_point_triangle(self.x, tri.v0, tri.v1, tri.v2) > self.r2 {
            return false;
        }
        let nt = cross3(sub3(tri.v1, tri.v0), sub3(tri.v2, tri.v0));
        let c = dot3(nt, self.n);
        // |cos| ≤ 1/2, without normalising nt.
        let crease = 4.0 * c * c <= dot3(nt, nt);
        let open = if (prim as usize) < self.open_edges.len() { self.open_edges[prim as usize] } else { 0 };
        let r2 = self.r2;
        crease
            || (open & 1 != 0 && dist2_point_segment(self.x, tri.v0, tri.v1) <= r2)
            || (open & 2 != 0 && dist2_point_segment(self.x, tri.v1, tri.v2) <= r2)
            || (open & 4 != 0 && dist2_point_segment(self.x, tri.v2, tri.v0) <= r2)
    }
}

/// Whether the disc of radius `r` at `x` (unit normal `n`) reaches past its surface
/// (`EdgeProbe`), from the triangles `M` finds near the disc's box.
#[inline(always)]
pub fn near_edge<M: Method>(accel: &M::Accel<'_>, open_edges: &[u32], x: [f32; 3], n: [f32; 3], r: f32) -> bool {
    M::near(accel, sub3(x, [r; 3]), add3(x, [r; 3]), &EdgeProbe { x, n, r2: r * r, open_edges })
}

/// Path `i`: if it ended at a gather point, marks it `PATH_NEAR_EDGE` where the global map's
/// disc there (radius `p.radius[0]`) reaches past its surface (`near_edge`), and clears the
/// mark elsewhere; the next gather under `GATHER_EDGES` leaves the marked points to the final
/// gather. Geometry alone decides, not photons: a corner the photons seldom reach is found
/// as surely as a lit one.
#[inline(always)]
pub fn mark_edges<M: Method, P: Store<PathState> + ?Sized>(
    i: u32,
    p: &IndexParams,
    accel: &M::Accel<'_>,
    open_edges: &[u32],
    rays: &[Ray],
    paths: &mut P,
) {
    if i >= p.count {
        return;
    }
    let k = i as usize;
    let mut path = paths.load(k);
    if path.flags & PATH_GATHER != 0 {
        let g = rays[k];
        let near = near_edge::<M>(accel, open_edges, g.origin, g.dir, p.radius[0]);
        path.flags = (path.flags & !PATH_NEAR_EDGE) | if near { PATH_NEAR_EDGE } else { 0 };
        paths.store(k, path);
    }
}
