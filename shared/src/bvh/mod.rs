//! The compressed 8-wide BVH (Ylitie, Karras & Laine 2017, "Efficient incoherent ray traversal
//! on GPUs through compressed wide BVHs") as both sides see it, and its traversal, written once.
//!
//! A node is 80 bytes: the origin and per-axis power-of-two step of a grid on which its (up to)
//! eight children's boxes are stored as 8-bit coordinates, a mask of which child slots are
//! nodes, the index of its first child node and of its first leaf triangle, and one meta byte
//! per slot. Child nodes are stored contiguously in slot order; so are the triangles of the
//! children that are leaves (at most three per leaf, 24 per node).
//!
//! Traversal keeps *groups* rather than single nodes: a group is a base index and a bit mask of
//! the hit children still to visit (nodes in bits 24..32, triangles in bits 0..24). The builder
//! places the child that lies first along each ray octant's diagonal in the slot of that
//! octant, and a ray visits node slots in the order `slot ^ (7 - octant)` from the top bit down,
//! so children are taken roughly front to back without sorting. One stack entry (the rest of a
//! group) per level: the stack never holds more entries than the tree is deep
//! (`MAX_BVH_DEPTH`, which the builder guarantees and the host checks).
//!
//! Rules that keep the traversal exact (the same hits as the brute-force oracle):
//! * the quantisation grid is chosen so that every stored box coordinate `origin + step · q`
//!   is exactly representable in `f32` (the origin and the step are multiples of a power of
//!   two 2^f, and every coordinate lies below 2^(f + 24) in magnitude), and the stored box
//!   encloses the child's true box; the kernel reconstructs it exactly;
//! * the box test takes one multiply-add per plane, each near plane's offset lowered and each
//!   far plane's raised by a bound on the rounding of that axis' distances (`fast_children`,
//!   `Grid`); for a ray whose distances might not stay finite at some node (a direction
//!   parallel or nearly parallel to an axis: `BoxRay::tame`, decided once per ray) it is
//!   `aabb`'s slab test of the exactly reconstructed box at every node; so rounding never
//!   culls a box that a hit triangle lies in;
//! * a child is culled only when its box starts beyond the best hit so far (or ends before the
//!   ray's `t_min`) by more than the rounding of both distances (`widened`), so a triangle at
//!   the same `t` with a lower index (the tie rule) is still tested;
//! * every loop is bounded by the node count; invalid rays (`Ray::is_valid`) are misses.
pub mod build;
pub mod packet;
pub use packet::{packet_or_single, traverse_packet, BVH_PACKET};

use crate::aabb::{intersect_box, inv_dir, Aabb};
use crate::pod::Triangle;
use crate::query::{Near, Query};
use crate::ray::Ray;
use crate::stats::Stats;
use crate::triangle::ShearedRay;
use crate::parts::Parts;
use crate::math::{fma, max_num, min_num};
use bytemuck::{Pod, Zeroable};
use core::mem::MaybeUninit;
use glam::UVec4;

/// Children per node.
pub const BVH_WIDTH: usize = 8;
/// Triangles per leaf child at most (the meta byte's unary count has three bits).
pub const MAX_LEAF_TRIS: usize = 3;
/// Deepest tree the builder produces, and the traversal stack's capacity.
pub const MAX_BVH_DEPTH: usize = 32;
/// Meta byte of an empty slot.
pub const META_EMPTY: u32 = 0;

/// One node: 80 bytes, five 16-byte words (vectors, so a kernel loads each in one access).
///
/// * `origin_exp`: the grid origin's x, y, z (`f32` bits) and, in the fourth word, the biased
///   `f32` exponents of the steps (x in bits 0..8, y in 8..16, z in 16..24: the step along an
///   axis is `f32::from_bits(e << 23)`) and the internal-child mask (bits 24..32: bit s set when
///   slot s is a node).
/// * `bases_meta`: the first child node's index, the first leaf triangle's index, and the meta
///   bytes of slots 0..4 and 4..8 (byte s of the pair). Meta: 0 for an empty slot; a node in
///   slot s: `0b001_00000 | (24 + s)`; a leaf: its triangle count in unary in bits 5..8
///   (`0b001`, `0b011`, `0b111`) and its first triangle's offset from the node's first leaf
///   triangle in bits 0..5 (0..24).
/// * `lo_x_y`, `lo_z_hi_x`, `hi_y_z`: the children's quantised box corners, one byte per slot:
///   each pair of words holds one axis' eight bytes (slots 0..4, then 4..8): lo x, lo y, lo z,
///   hi x, hi y, hi z.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    /// Grid origin (x, y, z as `f32` bits); step exponents and the internal-child mask.
    pub origin_exp: UVec4,
    /// First child node, first leaf triangle, meta bytes of slots 0..4 and 4..8.
    pub bases_meta: UVec4,
    /// Quantised lower x, then lower y, of slots 0..8.
    pub lo_x_y: UVec4,
    /// Quantised lower z, then upper x, of slots 0..8.
    pub lo_z_hi_x: UVec4,
    /// Quantised upper y, then upper z, of slots 0..8.
    pub hi_y_z: UVec4,
}

/// Byte `s` (0..8) of the eight bytes held by the word pair `(a, b)`.
#[inline(always)]
fn byte_of(a: u32, b: u32, s: u32) -> u32 {
    let w = if s < 4 { a } else { b };
    (w >> ((s & 3) * 8)) & 0xff
}

impl BvhNode {
    /// The grid origin.
    #[inline(always)]
    pub fn origin(&self) -> [f32; 3] {
        [f32::from_bits(self.origin_exp.x), f32::from_bits(self.origin_exp.y), f32::from_bits(self.origin_exp.z)]
    }
    /// The grid step along each axis (a power of two).
    #[inline(always)]
    pub fn steps(&self) -> [f32; 3] {
        let e = self.origin_exp.w;
        [f32::from_bits((e & 0xff) << 23), f32::from_bits(((e >> 8) & 0xff) << 23), f32::from_bits(((e >> 16) & 0xff) << 23)]
    }
    /// Bit s set when slot s is a node.
    #[inline(always)]
    pub fn imask(&self) -> u32 {
        self.origin_exp.w >> 24
    }
    /// Index of the first child node.
    #[inline(always)]
    pub fn child_base(&self) -> u32 {
        self.bases_meta.x
    }
    /// Index of the first leaf triangle.
    #[inline(always)]
    pub fn tri_base(&self) -> u32 {
        self.bases_meta.y
    }
    /// Meta byte of slot `s`.
    #[inline(always)]
    pub fn meta(&self, s: u32) -> u32 {
        byte_of(self.bases_meta.z, self.bases_meta.w, s)
    }
    /// Slot `s`'s quantised box: lower and upper grid coordinates per axis.
    #[inline(always)]
    pub fn quantised(&self, s: u32) -> ([u32; 3], [u32; 3]) {
        (
            [byte_of(self.lo_x_y.x, self.lo_x_y.y, s), byte_of(self.lo_x_y.z, self.lo_x_y.w, s), byte_of(self.lo_z_hi_x.x, self.lo_z_hi_x.y, s)],
            [byte_of(self.lo_z_hi_x.z, self.lo_z_hi_x.w, s), byte_of(self.hi_y_z.x, self.hi_y_z.y, s), byte_of(self.hi_y_z.z, self.hi_y_z.w, s)],
        )
    }
    /// Slot `s`'s box as stored (exact in `f32`: see the module's rules).
    #[inline(always)]
    pub fn child_box(&self, s: u32) -> ([f32; 3], [f32; 3]) {
        let o = self.origin();
        let st = self.steps();
        let (lo, hi) = self.quantised(s);
        (
            [o[0] + st[0] * lo[0] as f32, o[1] + st[1] * lo[1] as f32, o[2] + st[2] * lo[2] as f32],
            [o[0] + st[0] * hi[0] as f32, o[1] + st[1] * hi[1] as f32, o[2] + st[2] * hi[2] as f32],
        )
    }

    /// Every slot's quantised box as floats (the bytes of `quantised` of slots 0..8): lower x,
    /// y, z, then upper x, y, z, slot s in lane s. Natively with AVX, eight slots per
    /// instruction (the same exact values: bytes convert exactly).
    #[inline(always)]
    pub fn quantised_boxes(&self) -> [[f32; BVH_WIDTH]; 6] {
        let words = [
            (self.lo_x_y.x, self.lo_x_y.y),
            (self.lo_x_y.z, self.lo_x_y.w),
            (self.lo_z_hi_x.x, self.lo_z_hi_x.y),
            (self.lo_z_hi_x.z, self.lo_z_hi_x.w),
            (self.hi_y_z.x, self.hi_y_z.y),
            (self.hi_y_z.z, self.hi_y_z.w),
        ];
        let mut c = [[0.0f32; BVH_WIDTH]; 6];
        let mut k = 0;
        while k < 6 {
            #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
            // SAFETY: the cfg guarantees AVX and SSE4.1.
            unsafe {
                core::arch::x86_64::_mm256_storeu_ps(c[k].as_mut_ptr(), bytes_x8(words[k].0, words[k].1));
            }
            #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
            {
                let mut s = 0;
                while s < BVH_WIDTH {
                    c[k][s] = byte_of(words[k].0, words[k].1, s as u32) as f32;
                    s += 1;
                }
            }
            k += 1;
        }
        c
    }
}

/// Whether meta byte `m` is a node's (its low five bits are 24..32).
#[inline(always)]
pub fn meta_is_node(m: u32) -> bool {
    m & 0b11000 == 0b11000
}

/// A `Triangle` as three 16-byte words (the same 48 bytes), so that a kernel loads it in three
/// vector accesses rather than twelve scalar ones: v0 and `material`, v1 and `face`, v2 and
/// `_pad`, each vertex as `f32` bits.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TriWords {
    /// v0 (x, y, z bits) and `material`.
    pub a: UVec4,
    /// v1 and `face`.
    pub b: UVec4,
    /// v2 and `_pad`.
    pub c: UVec4,
}

impl TriWords {
    /// The triangle these words hold.
    #[inline(always)]
    pub fn triangle(&self) -> Triangle {
        let v = |w: UVec4| [f32::from_bits(w.x), f32::from_bits(w.y), f32::from_bits(w.z)];
        Triangle { v0: v(self.a), material: self.a.w, v1: v(self.b), face: self.b.w, v2: v(self.c), _pad: self.c.w }
    }
    /// Triangles seen as words (the same bytes).
    pub fn cast(tris: &[Triangle]) -> &[TriWords] {
        bytemuck::cast_slice(tris)
    }
    /// An array of triangles, whole or in parts, seen as words.
    pub fn parts<'a>(tris: Parts<'a, Triangle>) -> Parts<'a, TriWords> {
        tris.map(TriWords::cast)
    }
}

/// The tree: `nodes[0]` is the root; `tris` are the scene's triangles in leaf order, each with
/// its index in the scene in `Triangle::_pad` (the `Hit::prim` reported).
#[derive(Copy, Clone)]
pub struct Bvh<'a> {
    /// The nodes; `nodes[0]` is the root.
    pub nodes: Parts<'a, BvhNode>,
    /// The triangles in leaf order (as words: `TriWords::cast`); `_pad` holds each one's index
    /// in the scene.
    pub tris: Parts<'a, TriWords>,
}

/// Ray `ray`'s constants for the child box tests.
#[derive(Copy, Clone)]
struct BoxRay {
    origin: [f32; 3],
    inv: [f32; 3],
    /// Per axis: 1 where the reciprocal direction is negative (the near plane is the upper one).
    neg: [u32; 3],
    /// 7 − the ray's octant (bit 2: x < 0, bit 1: y < 0, bit 0: z < 0).
    oct_inv: u32,
}

impl BoxRay {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv = inv_dir(ray.dir);
        // Signs of the reciprocals (−0 gives −∞: negative, as `slab` needs).
        let neg = [(inv[0] < 0.0) as u32, (inv[1] < 0.0) as u32, (inv[2] < 0.0) as u32];
        BoxRay { origin: ray.origin, inv, neg, oct_inv: 7 - (neg[0] << 2 | neg[1] << 1 | neg[2]) }
    }

    /// Whether `fast_children` holds at every node of the tree whose root is `root`: the bound
    /// `Grid::new` takes for any node, (255 · step + |origin − o|) · |1/d| summed over the axes,
    /// stays below a quarter of `f32::MAX` (so every distance, offset and rounding bound in ray
    /// units is finite). Every node's step is at most twice the root's and its origin lies
    /// within 512 root steps of the root's (the host's `BvhData::validate` checks both), so the
    /// sum of (1024 · root step + |root origin − o|) · |1/d| bounds every node's; a direction
    /// parallel to an axis (an infinite reciprocal) or nearly so fails, and the walk takes
    /// `exact_children` at every node instead.
    #[inline(always)]
    fn tame(&self, root: &BvhNode) -> bool {
        let o = root.origin();
        let st = root.steps();
        let reach = |a: usize| fma(1024.0, st[a], (o[a] - self.origin[a]).abs()) * self.inv[a].abs();
        reach(0) + reach(1) + reach(2) < f32::MAX / 8.0
    }
}

/// The hit bits of a node's children, per slot, from its meta bytes, four slots at once
/// (Ylitie et al.'s packed form): 0 for an empty slot (so an empty slot's box needs no test), a
/// node's bit `24 + (slot ^ oct_inv)`, a leaf's triangle bits.
#[derive(Copy, Clone)]
struct SlotBits {
    /// Per meta byte of slots 0..4 and 4..8: its first hit bit's position (a node's slot
    /// mirrored by the octant, a leaf's first triangle offset).
    pos: [u32; 2],
    /// Per meta byte: its number of bits (the unary count).
    cnt: [u32; 2],
}

impl SlotBits {
    #[inline(always)]
    fn new(node: &BvhNode, oct_inv: u32) -> Self {
        let oct4 = oct_inv * 0x0101_0101;
        // Bit 4 of a byte is set where its low five bits are 24..32 (`meta_is_node`).
        let pos = |m: u32| (m ^ (oct4 & ((((m & (m << 1)) & 0x1010_1010) >> 4) * 0xff))) & 0x1f1f_1f1f;
        let (m0, m1) = (node.bases_meta.z, node.bases_meta.w);
        SlotBits { pos: [pos(m0), pos(m1)], cnt: [(m0 >> 5) & 0x0707_0707, (m1 >> 5) & 0x0707_0707] }
    }
    /// Slot `s`'s hit bits.
    #[inline(always)]
    fn get(&self, s: u32) -> u32 {
        let sh = (s & 3) * 8;
        let (pos, cnt) = if s < 4 { (self.pos[0], self.cnt[0]) } else { (self.pos[1], self.cnt[1]) };
        ((cnt >> sh) & 7) << ((pos >> sh) & 0x1f)
    }
}

/// Every stored box by `aabb::intersect_box` (coordinates reconstructed exactly, far planes
/// widened, parallel axes without NaN): the child test of rays that are not `BoxRay::tame`.
#[inline(always)]
fn exact_children(node: &BvhNode, r: &BoxRay, t_min: f32, t_max: f32) -> u32 {
    let bits = SlotBits::new(node, r.oct_inv);
    let mut mask = 0u32;
    let mut s = 0u32;
    while s < BVH_WIDTH as u32 {
        if node.meta(s) != META_EMPTY {
            let (min, max) = node.child_box(s);
            if intersect_box(r.origin, r.inv, &Aabb { min, max }, t_min, t_max).is_some() {
                mask |= bits.get(s);
            }
        }
        s += 1;
    }
    mask
}

/// Relative bound on the rounding of a plane distance computed by `Grid`'s multiply-add, in
/// units of (255 · step + |origin − o|) / |d|: 16ε = 32u, over three times the error (a
/// reciprocal up to three ulps off, as Vulkan allows, then four roundings: about 10u).
const PLANE_ROUNDING: f32 = 16.0 * f32::EPSILON;
/// Absolute part of that bound, in ray units: far above the few flushed subnormals (each below
/// 2^-126) a GPU may make of tiny products.
const PLANE_FLOOR: f32 = 1.0 / (1u128 << 100) as f32;

/// A node's grid in a ray's units, per axis: the distance to grid plane q along the ray is
/// `q · scale + offset` (Ylitie et al.'s one multiply-add per plane), with `offset` =
/// (origin − o)/d. `near` and `far` are that offset lowered and raised by a bound on the
/// rounding of the whole distance, (255 · step + |origin − o|) · |1/d| · `PLANE_ROUNDING` +
/// `PLANE_FLOOR`: near planes computed with `near` lie before the exact planes of the stored
/// box, far planes with `far` beyond them, so a box the ray's exact interval overlaps is never
/// culled. Each axis carries its own bound: a nearly parallel axis, whose distances are huge
/// and coarse, widens only its own slab (one bound for all axes would let such a ray enter
/// every box it passes near).
#[derive(Copy, Clone)]
struct Grid {
    scale: [f32; 3],
    near: [f32; 3],
    far: [f32; 3],
}

impl Grid {
    /// For a `BoxRay::tame` ray: every value finite.
    #[inline(always)]
    fn new(node: &BvhNode, r: &BoxRay) -> Self {
        let o = node.origin();
        let st = node.steps();
        // Per axis; written out per axis, as an array indexed at run time may be placed in a
        // GPU's local memory.
        let (x, y, z) = (grid_axis(o[0], st[0], r.origin[0], r.inv[0]), grid_axis(o[1], st[1], r.origin[1], r.inv[1]), grid_axis(o[2], st[2], r.origin[2], r.inv[2]));
        Grid { scale: [x.0, y.0, z.0], near: [x.1, y.1, z.1], far: [x.2, y.2, z.2] }
    }
}

/// One axis of `Grid`: (scale, near, far) of a node whose grid origin and step along the axis
/// are `o` and `st`, for a ray whose origin and reciprocal direction along it are `origin` and
/// `inv` (the packet walk's fast test computes the same per lane).
#[inline(always)]
fn grid_axis(o: f32, st: f32, origin: f32, inv: f32) -> (f32, f32, f32) {
    let rel = o - origin;
    let offset = rel * inv;
    let err = fma(PLANE_ROUNDING, fma(255.0, st, rel.abs()) * inv.abs(), PLANE_FLOOR);
    (st * inv, offset - err, offset + err)
}

/// The hit mask of `node`'s children for a `BoxRay::tame` ray `r` within [`t_min`, `t_max`]:
/// node slots in bits 24..32 (slot s at bit `24 + (s ^ oct_inv)`), leaf triangles in bits
/// 0..24 (offsets from the node's first leaf triangle). Six multiply-adds per slot on `Grid`'s
/// planes (natively with AVX, eight slots per instruction: `fast_children_x8`). Written out
/// per slot (constant byte positions; an empty slot contributes no bits, so it is not skipped).
#[inline(always)]
#[cfg_attr(all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma"), allow(dead_code))]
fn fast_children(node: &BvhNode, r: &BoxRay, t_min: f32, t_max: f32) -> u32 {
    let g = Grid::new(node, r);
    // Per axis, the words of the near and far planes' bytes (swapped where the ray goes down).
    let pick = |lo: (u32, u32), hi: (u32, u32), neg: u32| if neg != 0 { (hi, lo) } else { (lo, hi) };
    let (nx, fx) = pick((node.lo_x_y.x, node.lo_x_y.y), (node.lo_z_hi_x.z, node.lo_z_hi_x.w), r.neg[0]);
    let (ny, fy) = pick((node.lo_x_y.z, node.lo_x_y.w), (node.hi_y_z.x, node.hi_y_z.y), r.neg[1]);
    let (nz, fz) = pick((node.lo_z_hi_x.x, node.lo_z_hi_x.y), (node.hi_y_z.z, node.hi_y_z.w), r.neg[2]);
    let bits = SlotBits::new(node, r.oct_inv);
    let child = |s: u32| -> u32 {
        let b = |w: (u32, u32)| byte_of(w.0, w.1, s) as f32;
        // No NaN: every distance is finite (`BoxRay::tame`), t_min and t_max are not NaN.
        let near = max_num(max_num(fma(b(nx), g.scale[0], g.near[0]), fma(b(ny), g.scale[1], g.near[1])), max_num(fma(b(nz), g.scale[2], g.near[2]), t_min));
        let far = min_num(min_num(fma(b(fx), g.scale[0], g.far[0]), fma(b(fy), g.scale[1], g.far[1])), min_num(fma(b(fz), g.scale[2], g.far[2]), t_max));
        if near <= far {
            bits.get(s)
        } else {
            0
        }
    };
    child(0) | child(1) | child(2) | child(3) | child(4) | child(5) | child(6) | child(7)
}

/// The eight bytes of the word pair (`lo`, `hi`) as eight floats (byte s of the pair in lane s,
/// as `byte_of`), natively with AVX.
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
#[inline(always)]
fn bytes_x8(lo: u32, hi: u32) -> core::arch::x86_64::__m256 {
    use core::arch::x86_64::*;
    // SAFETY: the cfg guarantees AVX and SSE4.1 (which AVX implies).
    unsafe {
        let v = _mm_cvtsi64_si128(((hi as u64) << 32 | lo as u64) as i64);
        _mm256_cvtepi32_ps(_mm256_set_m128i(_mm_cvtepu8_epi32(_mm_srli_si128::<4>(v)), _mm_cvtepu8_epi32(v)))
    }
}

/// `fast_children` natively on x86-64 with AVX (which FMA implies, so every build of this
/// repository's `.cargo/config.toml`): the same multiply-adds, minima, maxima and comparison per
/// slot, eight slots per instruction, so the same mask bit for bit (no operand is NaN, so
/// `vmaxps`/`vminps` pick as `max_num`/`min_num` do; a unit test compares the two on random
/// nodes and rays). Only the hit slots' bits are then gathered one by one.
#[cfg(all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma"))]
#[inline(always)]
fn fast_children_x8(node: &BvhNode, r: &BoxRay, t_min: f32, t_max: f32) -> u32 {
    use core::arch::x86_64::*;
    let g = Grid::new(node, r);
    // SAFETY: the cfg guarantees AVX, FMA and SSE4.1 (which AVX implies).
    unsafe {
        let plane = |w: (u32, u32), a: usize, off: &[f32; 3]| _mm256_fmadd_ps(bytes_x8(w.0, w.1), _mm256_set1_ps(g.scale[a]), _mm256_set1_ps(off[a]));
        let pick = |lo: (u32, u32), hi: (u32, u32), neg: u32| if neg != 0 { (hi, lo) } else { (lo, hi) };
        let (nx, fx) = pick((node.lo_x_y.x, node.lo_x_y.y), (node.lo_z_hi_x.z, node.lo_z_hi_x.w), r.neg[0]);
        let (ny, fy) = pick((node.lo_x_y.z, node.lo_x_y.w), (node.hi_y_z.x, node.hi_y_z.y), r.neg[1]);
        let (nz, fz) = pick((node.lo_z_hi_x.x, node.lo_z_hi_x.y), (node.hi_y_z.z, node.hi_y_z.w), r.neg[2]);
        let near = _mm256_max_ps(_mm256_max_ps(plane(nx, 0, &g.near), plane(ny, 1, &g.near)), _mm256_max_ps(plane(nz, 2, &g.near), _mm256_set1_ps(t_min)));
        let far = _mm256_min_ps(_mm256_min_ps(plane(fx, 0, &g.far), plane(fy, 1, &g.far)), _mm256_min_ps(plane(fz, 2, &g.far), _mm256_set1_ps(t_max)));
        let mut hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        let bits = SlotBits::new(node, r.oct_inv);
        let mut mask = 0u32;
        while hit != 0 {
            mask |= bits.get(hit.trailing_zeros());
            hit &= hit - 1;
        }
        mask
    }
}

/// Relative widening of the interval the child boxes are tested against: far above the
/// rounding of the box distances (γ(3)) and of the triangle test's `t` together.
const BAND: f32 = 32.0 * f32::EPSILON;

/// The interval [`t0`, `t1`] widened so that a box holding a triangle whose computed hit lies in
/// it is never culled: by `BAND` relative, plus `BAND` of the node's extent along the ray (a
/// triangle's `t` is rounded relative to its vertices' distance from the origin, not to `t`).
#[inline(always)]
fn widened(t0: f32, t1: f32, node: &BvhNode, inv_dmax: f32) -> (f32, f32) {
    let st = node.steps();
    let slack = BAND * (255.0 * (st[0] + st[1] + st[2]) * inv_dmax);
    (t0 - t0.abs() * BAND - slack, t1 + t1.abs() * BAND + slack)
}

/// Walks `bvh` along `ray`, testing every triangle of every leaf whose box the ray's interval
/// still overlaps with `q` (closest or any hit), roughly front to back. Whether the child boxes
/// are tested by `fast_children` or `exact_children` is decided once per ray
/// (`BoxRay::tame`), so the walk is one of two loops, neither with the other's test inside it
/// (a branch per node kept both tests' registers live: 80 instead of 64 on the H200 driver).
#[inline(always)]
pub fn traverse<Q: Query, S: Stats>(bvh: &Bvh, ray: &Ray, q: &mut Q, stats: &mut S) {
    traverse_from(bvh, 0, ray, q, stats)
}

/// `traverse` through the subtree of node `start` alone (0: the whole tree), `start`'s own box
/// untested (its parent's test let the ray in); an index past the nodes walks nothing. Any-hit
/// packets hand a node they would enter for at most `packet::SOLO` lanes to those lanes.
#[inline(always)]
pub(crate) fn traverse_from<Q: Query, S: Stats>(bvh: &Bvh, start: u32, ray: &Ray, q: &mut Q, stats: &mut S) {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return,
    };
    if bvh.nodes.is_empty() {
        return;
    }
    let br = BoxRay::new(ray);
    // SAFETY: the tree has a node (checked above).
    let root = unsafe { bvh.nodes.get_unchecked(0) };
    if br.tame(&root) {
        walk::<Q, S, true>(bvh, start, ray, &r, &br, q, stats);
    } else {
        walk::<Q, S, false>(bvh, start, ray, &r, &br, q, stats);
    }
}

/// `traverse_from`'s walk from node `start`, every child test by `fast_children` (`FAST`, for a
/// `BoxRay::tame` ray) or by `exact_children`.
#[inline(always)]
fn walk<Q: Query, S: Stats, const FAST: bool>(bvh: &Bvh, start: u32, ray: &Ray, r: &ShearedRay, br: &BoxRay, q: &mut Q, stats: &mut S) {
    let n_nodes = bvh.nodes.len() as u32;
    let n_tris = bvh.tris.len() as u32;
    let d = ray.dir;
    let inv_dmax = 1.0 / d[0].abs().max(d[1].abs()).max(d[2].abs());
    // Not initialised (64 stores a ray otherwise): entries below `sp` are written before read.
    let mut stack = [MaybeUninit::<[u32; 2]>::uninit(); MAX_BVH_DEPTH];
    let mut sp = 0usize;
    // The start node as the only node of a group with no internal mask: bit 31, relative index
    // 0.
    let mut nodes = [start, 1 << 31];
    // Hang guard: every step enters one node, and a tree enters each node at most once.
    let max_steps = n_nodes.min(u32::MAX - 1) + 1;
    let mut steps = 0u32;
    while steps < max_steps {
        steps += 1;
        let mut tris = [0u32, 0u32];
        if nodes[1] > 0x00ff_ffff {
            let bit = 31 - nodes[1].leading_zeros();
            let imask = nodes[1] & 0xff;
            nodes[1] &= !(1u32 << bit);
            let slot = (bit - 24) ^ br.oct_inv;
            let index = nodes[0] + (imask & ((1u32 << slot) - 1)).count_ones();
            if nodes[1] > 0x00ff_ffff && sp < MAX_BVH_DEPTH {
                stack[sp] = MaybeUninit::new(nodes);
                sp += 1;
            }
            if index >= n_nodes {
                return;
            }
            // SAFETY: index < n_nodes, checked above.
            let node = unsafe { bvh.nodes.get_unchecked(index as usize) };
            stats.node();
            let (t0, t1) = widened(ray.t_min, q.bound(), &node, inv_dmax);
            let hits = if FAST {
                #[cfg(all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma"))]
                let h = fast_children_x8(&node, br, t0, t1);
                #[cfg(not(all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma")))]
                let h = fast_children(&node, br, t0, t1);
                h
            } else {
                exact_children(&node, br, t0, t1)
            };
            nodes = [node.child_base(), (hits & 0xff00_0000) | node.imask()];
            tris = [node.tri_base(), hits & 0x00ff_ffff];
            if tris[1] != 0 {
                stats.leaf();
            }
        }
        // No return inside this loop: ended by the query's answer (or a corrupt index) here, the
        // walk ends below.
        while tris[1] != 0 && q.open() {
            let k = tris[0] + tris[1].trailing_zeros();
            tris[1] &= tris[1] - 1;
            if k < n_tris {
                // SAFETY: k < n_tris, checked above.
                let tri = unsafe { bvh.tris.get_unchecked(k as usize) }.triangle();
                q.test(tri._pad, &tri, r, ray.t_min, stats);
            } else {
                steps = max_steps;
                tris[1] = 0;
            }
        }
        if !q.open() || steps >= max_steps {
            return;
        }
        if nodes[1] <= 0x00ff_ffff {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: entry sp < the pushes' count was written by the push that made it.
            nodes = unsafe { stack[sp].assume_init() };
        }
    }
}

/// The hit mask (as `fast_children`'s, octant 0) of `node`'s children whose stored boxes
/// overlap the box `lo`..`hi`, touching included. Written out per slot, as `fast_children`
/// (an empty slot contributes no bits).
#[inline(always)]
fn overlapping_children(node: &BvhNode, lo: [f32; 3], hi: [f32; 3]) -> u32 {
    let bits = SlotBits::new(node, 0);
    let child = |s: u32| -> u32 {
        let (min, max) = node.child_box(s);
        if min[0] <= hi[0] && min[1] <= hi[1] && min[2] <= hi[2] && max[0] >= lo[0] && max[1] >= lo[1] && max[2] >= lo[2] {
            bits.get(s)
        } else {
            0
        }
    };
    child(0) | child(1) | child(2) | child(3) | child(4) | child(5) | child(6) | child(7)
}

/// Whether a triangle of a leaf whose box overlaps the box `lo`..`hi` answers `q`
/// (`query::Near`): `traverse`'s walk of groups (octant 0), children by box overlap, every
/// leaf triangle offered (no early end). Written apart from `traverse`: one walk taking the
/// query through a walker struct made the NVIDIA driver 580's compiler crash on this kernel.
#[inline(always)]
pub fn near<N: Near>(bvh: &Bvh, lo: [f32; 3], hi: [f32; 3], q: &N) -> bool {
    let n_nodes = bvh.nodes.len() as u32;
    let n_tris = bvh.tris.len() as u32;
    let mut found = false;
    if n_nodes == 0 {
        return found;
    }
    // Not initialised: entries below `sp` are written before read.
    let mut stack = [MaybeUninit::<[u32; 2]>::uninit(); MAX_BVH_DEPTH];
    let mut sp = 0usize;
    let mut nodes = [0u32, 1 << 31];
    // Every step enters one node, each node at most once.
    let max_steps = n_nodes.min(u32::MAX - 1) + 1;
    let mut steps = 0u32;
    while steps < max_steps {
        steps += 1;
        let mut tris = [0u32, 0u32];
        if nodes[1] > 0x00ff_ffff {
            let bit = 31 - nodes[1].leading_zeros();
            let imask = nodes[1] & 0xff;
            nodes[1] &= !(1u32 << bit);
            let index = nodes[0] + (imask & ((1u32 << (bit - 24)) - 1)).count_ones();
            if nodes[1] > 0x00ff_ffff && sp < MAX_BVH_DEPTH {
                stack[sp] = MaybeUninit::new(nodes);
                sp += 1;
            }
            if index >= n_nodes {
                return found;
            }
            // SAFETY: index < n_nodes, checked above.
            let node = unsafe { bvh.nodes.get_unchecked(index as usize) };
            let hits = overlapping_children(&node, lo, hi);
            nodes = [node.child_base(), (hits & 0xff00_0000) | node.imask()];
            tris = [node.tri_base(), hits & 0x00ff_ffff];
        }
        while tris[1] != 0 {
            let k = tris[0] + tris[1].trailing_zeros();
            tris[1] &= tris[1] - 1;
            if k >= n_tris {
                return found;
            }
            // SAFETY: k < n_tris, checked above.
            let tri = unsafe { bvh.tris.get_unchecked(k as usize) }.triangle();
            found |= q.test(tri._pad, &tri);
        }
        if nodes[1] <= 0x00ff_ffff {
            if sp == 0 {
                return found;
            }
            sp -= 1;
            // SAFETY: entry sp < the pushes' count was written by the push that made it.
            nodes = unsafe { stack[sp].assume_init() };
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The native eight-wide child test gives the scalar one's mask bit for bit (and the native
    /// eight-wide decoding of the quantised boxes the scalar one's bytes), on random
    /// nodes (any bytes: empty and inverted boxes, every meta byte) and rays in every octant,
    /// with intervals that end inside the boxes, at infinity, and equal distances (bytes shared
    /// by neighbouring slots).
    #[cfg(all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma"))]
    #[test]
    fn eight_wide_child_test_is_the_scalar_one() {
        let mut rng = Rng::new(7, 0);
        let word = |rng: &mut Rng, small: bool| if small { rng.next_u32() & 0x0303_0303 } else { rng.next_u32() };
        let mut hits = 0u32;
        for i in 0..200_000u32 {
            let small = i % 3 == 0;
            let f = |rng: &mut Rng, s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
            let exps = (118 + rng.next_u32() % 6) | (118 + rng.next_u32() % 6) << 8 | (118 + rng.next_u32() % 6) << 16 | (rng.next_u32() & 0xff) << 24;
            let node = BvhNode {
                origin_exp: UVec4::new(f(&mut rng, 8.0).to_bits(), f(&mut rng, 8.0).to_bits(), f(&mut rng, 8.0).to_bits(), exps),
                bases_meta: UVec4::new(rng.next_u32(), rng.next_u32(), rng.next_u32() | 0x2020_2020, rng.next_u32() | 0x2020_2020),
                lo_x_y: UVec4::new(word(&mut rng, small), word(&mut rng, small), word(&mut rng, small), word(&mut rng, small)),
                lo_z_hi_x: UVec4::new(word(&mut rng, small), word(&mut rng, small), word(&mut rng, small), word(&mut rng, small)),
                hi_y_z: UVec4::new(word(&mut rng, small), word(&mut rng, small), word(&mut rng, small), word(&mut rng, small)),
            };
            let origin = [f(&mut rng, 16.0), f(&mut rng, 16.0), f(&mut rng, 16.0)];
            // Towards a random point of the node's grid.
            let (o, st) = (node.origin(), node.steps());
            let d: [f32; 3] = core::array::from_fn(|a| o[a] + st[a] * 255.0 * rng.next_f32() - origin[a]);
            let r = BoxRay::new(&Ray::new(origin, d, 0.0, f32::INFINITY));
            let t_min = if i % 7 == 0 { 0.0 } else { f(&mut rng, 1.0) };
            let t_max = if i % 4 == 0 { f32::INFINITY } else { t_min + rng.next_f32() * 2.0 };
            // All eight quantised boxes at once are the boxes one by one.
            let q = node.quantised_boxes();
            for s in 0..BVH_WIDTH {
                let (l1, h1) = node.quantised(s as u32);
                assert_eq!(([q[0][s], q[1][s], q[2][s]], [q[3][s], q[4][s], q[5][s]]), (l1.map(|b| b as f32), h1.map(|b| b as f32)), "case {i}, slot {s}");
            }
            let scalar = fast_children(&node, &r, t_min, t_max);
            assert_eq!(fast_children_x8(&node, &r, t_min, t_max), scalar, "case {i}");
            hits += (scalar != 0) as u32;
        }
        // Both outcomes are exercised.
        assert!(hits > 10_000 && hits < 190_000, "{hits}");
    }

    /// `fast_children` never culls a box that the ray's exact interval meets, however closely:
    /// rays aimed exactly at a corner, an edge or a face of a random slot's stored box (or one
    /// grid step beside it), intervals ending or starting exactly there, directions scaled by
    /// powers of two, all in every octant, half of them with reciprocals up to three ulps off
    /// (as a GPU may compute them). The reference decides in exact arithmetic: every
    /// coordinate is a multiple of 2^-4 below 2^8, so the slab distances compared as fractions
    /// (cross-multiplied in `f64`) are exact. It also checks that the test is not loose: a box
    /// the ray misses passes only if missed by less than twice `Grid`'s bound of one axis.
    #[test]
    fn fast_test_never_culls_a_box_the_ray_meets() {
        let mut rng = Rng::new(11, 0);
        let grid = |rng: &mut Rng, half: u32| (rng.next_u32() % (2 * half * 16)) as f32 / 16.0 - half as f32;
        let (mut touching, mut met, mut loose, mut tested) = (0u32, 0u32, 0u32, 0u32);
        for i in 0..100_000u32 {
            let exps = (123 + rng.next_u32() % 5) | (123 + rng.next_u32() % 5) << 8 | (123 + rng.next_u32() % 5) << 16 | (rng.next_u32() & 0xff) << 24;
            let small = |rng: &mut Rng| rng.next_u32() & 0x0f0f_0f0f;
            let mut node = BvhNode {
                origin_exp: UVec4::new(grid(&mut rng, 64).to_bits(), grid(&mut rng, 64).to_bits(), grid(&mut rng, 64).to_bits(), exps),
                // Slot s: a leaf of one triangle at offset s (its own hit bit).
                bases_meta: UVec4::new(0, 0, 0x2322_2120, 0x2726_2524),
                ..Default::default()
            };
            // Upper bytes at or above the lower ones (some boxes flat along an axis).
            let lo = [small(&mut rng), small(&mut rng), small(&mut rng), small(&mut rng), small(&mut rng), small(&mut rng)];
            let ext = |rng: &mut Rng| if rng.next_u32() % 4 == 0 { 0 } else { rng.next_u32() & 0x0f0f_0f0f };
            let hi = [lo[0] + ext(&mut rng), lo[1] + ext(&mut rng), lo[2] + ext(&mut rng), lo[3] + ext(&mut rng), lo[4] + ext(&mut rng), lo[5] + ext(&mut rng)];
            node.lo_x_y = UVec4::new(lo[0], lo[1], lo[2], lo[3]);
            node.lo_z_hi_x = UVec4::new(lo[4], lo[5], hi[0], hi[1]);
            node.hi_y_z = UVec4::new(hi[2], hi[3], hi[4], hi[5]);
            let origin = [grid(&mut rng, 32), grid(&mut rng, 32), grid(&mut rng, 32)];
            // A point of one slot's box: per axis its lower or upper plane, or between them, or
            // one step beyond.
            let (bl, bh) = node.child_box(rng.next_u32() % 8);
            let st = node.steps();
            let target: [f32; 3] = core::array::from_fn(|a| match rng.next_u32() % 5 {
                0 => bl[a],
                1 => bh[a],
                2 => (bl[a] + bh[a]) * 0.5,
                3 => bl[a] - st[a],
                _ => bh[a] + st[a],
            });
            let k = (rng.next_u32() % 5) as i32 - 2;
            let d: [f32; 3] = core::array::from_fn(|a| (target[a] - origin[a]) * (k as f32).exp2());
            if d.iter().any(|&c| c == 0.0) {
                continue;
            }
            // The target lies at t = 2^-k: intervals ending or starting there, or open.
            let at = (-k as f32).exp2();
            let (t_min, t_max) = match rng.next_u32() % 4 {
                0 => (0.0, f32::INFINITY),
                1 => (0.0, at),
                2 => (at, f32::INFINITY),
                _ => (grid(&mut rng, 2).abs(), f32::INFINITY),
            };
            let mut r = BoxRay::new(&Ray::new(origin, d, t_min, t_max));
            // A GPU's reciprocal may be up to three ulps off (Vulkan's OpFDiv): half the cases
            // take one so perturbed.
            if i % 2 == 1 {
                for v in &mut r.inv {
                    let k = (rng.next_u32() % 7) as i32 - 3;
                    *v = f32::from_bits((v.to_bits() as i32 + k) as u32);
                }
            }
            assert!(r.tame(&node), "case {i}");
            let fast = fast_children(&node, &r, t_min, t_max);
            // Exact: t = num / den with den > 0; fractions compared by cross-multiplying.
            let bits = SlotBits::new(&node, r.oct_inv);
            let le = |a: (f64, f64), b: (f64, f64)| a.0 * b.1 <= b.0 * a.1;
            let frac = |t: f32| if t.is_infinite() { (1.0, 0.0) } else { (t as f64, 1.0) };
            for s in 0..BVH_WIDTH as u32 {
                if node.meta(s) == META_EMPTY {
                    continue;
                }
                let (bl, bh) = node.child_box(s);
                let mut near = frac(t_min);
                let mut far = frac(t_max);
                for a in 0..3 {
                    let den = (d[a] as f64).abs();
                    let sign = d[a].signum() as f64;
                    let (p, q) = if d[a] > 0.0 { (bl[a], bh[a]) } else { (bh[a], bl[a]) };
                    let n = (((p as f64) - origin[a] as f64) * sign, den);
                    let f = (((q as f64) - origin[a] as f64) * sign, den);
                    if le(near, n) {
                        near = n;
                    }
                    if le(f, far) {
                        far = f;
                    }
                }
                let meets = le(near, far);
                tested += 1;
                if meets {
                    met += 1;
                    touching += le(far, near) as u32;
                    assert!(fast & bits.get(s) != 0, "case {i}, slot {s}: the fast test culled a box the ray meets");
                } else if fast & bits.get(s) != 0 {
                    // Missed by less than the rounding bound (`Grid`'s, of the largest axis).
                    let o = node.origin();
                    let bound = (0..3).map(|a| (255.0 * st[a] as f64 + (o[a] as f64 - origin[a] as f64).abs()) / (d[a] as f64).abs()).fold(0.0, f64::max);
                    let gap = near.0 / near.1 - far.0 / far.1;
                    assert!(gap <= 2.0 * PLANE_ROUNDING as f64 * bound, "case {i}, slot {s}: a box missed by {gap} passed (bound {bound})");
                    loose += 1;
                }
            }
        }
        // Rays that only touch a box (an empty overlap of one point) are among the cases, and
        // the boxes the ray misses that pass are missed by less than the rounding bound.
        assert!(touching > 1000 && met > 50_000, "{touching} touching, {met} met");
        assert!(loose < tested, "{loose} of {tested}");
    }
}
