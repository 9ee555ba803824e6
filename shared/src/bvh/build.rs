//! Building the compressed wide BVH, once for both sides.
//!
//! **The wide node's encoding** (`assign_slots`, `quantise_axis`, `encode_node`): children to
//! slots by octant and their boxes onto each node's grid, the rules of the module above. The
//! host's SAH builder (`kdray::bvh`) and the build below encode every node with these.
//!
//! **The linear BVH build** (Karras 2012, "Maximizing parallelism in the construction of BVHs,
//! octrees, and k-d trees"), as per-item kernels that run on the GPU and natively alike:
//!
//! 1. `boxes`: each triangle's box, twice (the list in scene order and level 0 of a range tree);
//!    `reduce`, per level, the union of pairs of the level below (the root: the scene's box).
//! 2. `morton`: each triangle's 60-bit Morton code (its box's centre on a grid of cubic cells
//!    over the scene's box, then within its cell: `morton_code`) and its top `LbvhParams::cell_bits` bits as a counting-sort key (the host
//!    sorts by it with `kdray::sort`, exact offsets); `refine`: within every cell of at most
//!    `REFINE` triangles each takes its rank by (code, triangle index), so the order is that of
//!    the full codes, deterministic on every device; a larger cell keeps the sort's order, its triangles
//!    reduced to the cell's code (codes in order, as the tree needs; equal ones split by
//!    position). It fills level 0 of the range tree again, in sorted order, and the levels
//!    above are reduced again.
//! 3. `hierarchy`: inner node i of the n − 1 of Karras's binary tree, its range of sorted
//!    triangles and its two children (codes that tie are told apart by position), its count of
//!    triangles and its children's parent; `bounds`: each inner node's box, from the range tree
//!    (at most two entries per level).
//! 4. Treelet restructuring (Karras & Aila 2013, "Fast parallel construction of high-quality
//!    bounding volume hierarchies"), in rounds of three phases: `depths` gives every inner node
//!    its depth by walking its parents; in phase k the nodes of depth k modulo 3 are treelets'
//!    roots, each growing a treelet of up to five leaves within the next two levels below it
//!    (so the treelets of a phase share no inner node and run in one dispatch, without the
//!    paper's bottom-up atomics) and rewiring its inner nodes into the topology of least SAH
//!    cost over them (`cheapest_topology`, dynamic programming over the 2^5 subsets). Areas are
//!    integers on a per-treelet grid of power-of-two steps (`AreaGrid`), so every device
//!    makes the same choices. Karras's tree cost 22–47 % more than the host's SAH build on
//!    the bench scenes; after three rounds, −4 % to +7 %. (Over a run of ever smaller
//!    triangles the cheapest treelets are chains, which can make the tree too deep: the host
//!    then builds again without them, `kdray::lbvh::build_with`.)
//! 5. `collapse`, one dispatch per level of the wide tree (indirect: `level` turns the nodes
//!    the last level made into the next one's items): a wide node takes its binary node's two
//!    children and, until it has eight, replaces the inner child of largest area by its two;
//!    a child of at most `MAX_LEAF_TRIS` triangles is a leaf (its triangles found by walking
//!    its subtree: a treelet may have grouped triangles that are not consecutive). Areas are
//!    compared on the node's `AreaGrid`. It takes its child nodes' and leaf triangles' places by
//!    atomic additions (so the layout depends on the order they happen in; the tree does
//!    not), copies its leaf
//!    triangles, and encodes itself. Levels past `MAX_BVH_DEPTH`, a box too large to quantise
//!    or more nodes than allocated are counted in their `STATE_ERROR_*` words (and end the
//!    build).
use super::{BvhNode, BVH_WIDTH, MAX_BVH_DEPTH, MAX_LEAF_TRIS};
use crate::kernel::{AtomicStore, Store};
use crate::math::exp2i;
use crate::pod::{BuildBox, LbvhParams, Triangle};
use glam::UVec4;

/// Meta byte of a slot whose child is node `s`'s: `0b001_00000 | (24 + s)`.
#[inline(always)]
pub fn node_meta(slot: u32) -> u32 {
    0b001_00000 | (24 + slot)
}

/// Meta byte of a leaf of `count` (1..=3) triangles starting `offset` after the node's first.
#[inline(always)]
pub fn leaf_meta(count: u32, offset: u32) -> u32 {
    (((1u32 << count) - 1) << 5) | offset
}

/// No child in this slot (`assign_slots`).
pub const NO_CHILD: u32 = u32::MAX;

/// `f32` bits as an unsigned key in the order of `f32::total_cmp`.
#[inline(always)]
fn ordered(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 != 0 {
        !b
    } else {
        b | 1 << 31
    }
}

/// Which child goes to which slot: the child lying first along octant o's diagonal (the
/// smallest projection of its centre minus the parent's on it, summed from −0 over x, y, z) to
/// slot o, greedily over all (cost, child, slot) triples in increasing order (cost by
/// `f32::total_cmp`; ties: lower child, then lower slot). Slot
/// s holds child `slots[s]` or `NO_CHILD`. `n` ≤ `BVH_WIDTH` children.
#[inline(always)]
pub fn assign_slots(parent: [f32; 3], centres: &[[f32; 3]; BVH_WIDTH], n: usize) -> [u32; BVH_WIDTH] {
    let mut slots = [NO_CHILD; BVH_WIDTH];
    let mut placed = 0u32;
    let mut round = 0;
    while round < n {
        // The smallest (cost, child, slot) among free children and free slots.
        let mut best = (u32::MAX, u32::MAX, u32::MAX);
        let mut i = 0;
        while i < n {
            if placed >> i & 1 == 0 {
                let c = centres[i];
                let mut s = 0;
                while s < BVH_WIDTH {
                    if slots[s] == NO_CHILD {
                        let sign = |bit: usize| if s & bit != 0 { -1.0f32 } else { 1.0 };
                        let mut cost = -0.0f32;
                        cost += (c[0] - parent[0]) * sign(4);
                        cost += (c[1] - parent[1]) * sign(2);
                        cost += (c[2] - parent[2]) * sign(1);
                        // (cost, child, slot) in lexicographic order, compared by hand (no
                        // `Ordering`, an 8-bit type, in the shader build).
                        let key = (ordered(cost), i as u32, s as u32);
                        if key.0 < best.0 || (key.0 == best.0 && (key.1 < best.1 || (key.1 == best.1 && key.2 < best.2))) {
                            best = key;
                        }
                    }
                    s += 1;
                }
            }
            i += 1;
        }
        slots[best.2 as usize] = best.1;
        placed |= 1 << best.1;
        round += 1;
    }
    slots
}

/// `floor(log2 x)` of a positive finite `x` (subnormals: −127).
#[inline(always)]
fn ilog2(x: f32) -> i32 {
    ((x.to_bits() >> 23) & 0xff) as i32 - 127
}

/// `floor(x)` as `i32` for |x| < 2^31.
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let t = x as i32;
    if (t as f32) > x {
        t - 1
    } else {
        t
    }
}

/// One axis of a node's grid (`quantise_axis`): the step's exponent, the origin, and each
/// child's lower and upper grid coordinates (in the children's order).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AxisGrid {
    /// The step is 2^`exp`.
    pub exp: i32,
    /// The grid's origin.
    pub origin: f32,
    /// Lower and upper coordinates of child j: `origin + 2^exp · q` below and above its box.
    pub q: [[u32; 2]; BVH_WIDTH],
}

/// The grid of one axis of a node spanning [`lo`, `hi`] over its `n` children's extents
/// `kids` along it: the smallest power-of-two step 2^e (e from −100 to 119) for which there is
/// an origin, `lo` rounded down to a multiple of 2^f (f the finest power of two, at most the
/// step, whose multiples below 2^(f + 24) in magnitude hold every `origin + q · step`, q =
/// 0..=256: so every grid value is exact in `f32`), on which every child's extent rounds
/// outwards into 0..=255 with finite coordinates. `None` when no step up to 2^119 does.
///
/// All in `f32` and integers, and exact: the step's first guess may be one too small (that
/// step then fails, as `hi` lies more than 255 of them above `lo`), never too large; f is
/// computed exactly, and
/// each coordinate is the floor (ceiling) of the exact quotient, checked on the grid as the
/// kernels reconstruct it.
pub fn quantise_axis(lo: f32, hi: f32, kids: &[(f32, f32); BVH_WIDTH], n: usize) -> Option<AxisGrid> {
    // The smallest e with 255 · 2^e ≥ hi − lo (halved so it cannot overflow) or one less: the
    // rounded half extent never exceeds 127.5 · 2^e when the exact one does not (127.5 · 2^e is
    // an f32 value and rounding is monotonic), though it may fall to it from just above.
    // By exact operations only (a GPU's division need not be correctly rounded): the smallest
    // e with 127.5 · 2^e ≥ h, h half the rounded extent.
    let h = 0.5 * hi - 0.5 * lo;
    let mut e = -100;
    if h > 0.0 {
        e = ilog2(h) - 6;
        if e < -120 {
            e = -120;
        }
        if h > 127.5 * exp2i(e) {
            e += 1;
        }
    }
    let max_abs = if lo.abs() > hi.abs() { lo.abs() } else { hi.abs() };
    if max_abs > 0.0 {
        // Every grid value must be an f32 multiple of a power of two no coarser than the step.
        let m = ilog2(max_abs) + 1 - 23;
        if m > e {
            e = m;
        }
    }
    if e < -100 {
        e = -100;
    }
    let a = lo.abs();
    while e <= 119 {
        // L = floor(log2(|lo| + 2^(e + 8))), exactly.
        let big = e + 8;
        let l = if a == 0.0 || ilog2(a) < big {
            big
        } else if ilog2(a) == big {
            big + 1
        } else {
            let la = ilog2(a);
            // a + 2^big ≥ 2^(la + 1)  ⇔  a − 2^la ≥ 2^la − 2^big (both sides exact in f32
            // when la − big ≤ 23; past that 2^big is below half an ulp of a).
            if la - big <= 23 && a - exp2i(la) >= exp2i(la) - exp2i(big) {
                la + 1
            } else {
                la
            }
        };
        let mut f = l - 23;
        if f > e {
            f = e;
        }
        if f < -100 {
            f = -100;
        }
        let d = e - f;
        // k = floor(lo / 2^f); a tiny negative quotient may round to −0.
        let mut k = floor_i32(lo * exp2i(-f));
        if k == 0 && lo < 0.0 {
            k = -1;
        }
        if d <= 16 && k.unsigned_abs() + (255u32 << d) < 1 << 24 {
            // (−0 for a lower bound of −0, as `lo` rounded down in f64.)
            let origin = if k == 0 { f32::from_bits(lo.to_bits() & 0x8000_0000) } else { k as f32 * exp2i(f) };
            let s = exp2i(e);
            let inv = exp2i(-e);
            let at = |q: u32| origin + s * q as f32;
            let mut q = [[0u32; 2]; BVH_WIDTH];
            let mut fits = true;
            let mut j = 0;
            while j < n {
                let (cl, ch) = kids[j];
                let clamp = |v: f32| if v > 256.0 { 256 } else if v > 0.0 { floor_i32(v) as u32 } else { 0 };
                // The floor of (cl − origin) / step and the ceiling of (ch − origin) / step
                // (at least 0), from estimates made exact on the grid.
                let mut ql = clamp((cl - origin) * inv);
                let mut qh = clamp((ch - origin) * inv);
                while ql > 0 && at(ql) > cl {
                    ql -= 1;
                }
                while ql < 255 && at(ql + 1) <= cl {
                    ql += 1;
                }
                while qh > 0 && at(qh - 1) >= ch {
                    qh -= 1;
                }
                while qh <= 255 && at(qh) < ch {
                    qh += 1;
                }
                // Every stored coordinate finite too (a box up against f32::MAX may round past it).
                if qh > 255 || at(ql) > cl || !at(ql).is_finite() || !at(qh).is_finite() {
                    fits = false;
                    break;
                }
                q[j] = [ql, qh];
                j += 1;
            }
            if fits {
                return Some(AxisGrid { exp: e, origin, q });
            }
        }
        e += 1;
    }
    None
}

/// A child as `encode_node` takes it: its box and its meta byte (`node_meta`, `leaf_meta`; 0:
/// no child in this slot).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct SlotChild {
    /// Lower corner of its box.
    pub lo: [f32; 3],
    /// Upper corner.
    pub hi: [f32; 3],
    /// Its meta byte.
    pub meta: u32,
}

/// Packs eight bytes into two words (byte s of the pair).
#[inline(always)]
fn pack(v: &[u32; BVH_WIDTH]) -> [u32; 2] {
    [v[0] | v[1] << 8 | v[2] << 16 | v[3] << 24, v[4] | v[5] << 8 | v[6] << 16 | v[7] << 24]
}

/// The node over `slots` (by slot) inside the box [`lo`, `hi`] (their union), its child nodes
/// from `child_base`, its leaf triangles from `tri_base`. `None` when a box is too large to
/// quantise (`quantise_axis`).
pub fn encode_node(lo: [f32; 3], hi: [f32; 3], slots: &[SlotChild; BVH_WIDTH], child_base: u32, tri_base: u32) -> Option<BvhNode> {
    let mut q = [[0u32; BVH_WIDTH]; 6];
    let mut origin = [0u32; 3];
    let mut exps = 0u32;
    let mut imask = 0u32;
    let mut meta = [0u32; BVH_WIDTH];
    let mut s = 0;
    while s < BVH_WIDTH {
        meta[s] = slots[s].meta;
        if super::meta_is_node(slots[s].meta) {
            imask |= 1 << s;
        }
        s += 1;
    }
    let mut a = 0;
    while a < 3 {
        // The present children in slot order.
        let mut kids = [(0.0f32, 0.0f32); BVH_WIDTH];
        let mut which = [0usize; BVH_WIDTH];
        let mut m = 0;
        let mut s = 0;
        while s < BVH_WIDTH {
            if slots[s].meta != 0 {
                kids[m] = (slots[s].lo[a], slots[s].hi[a]);
                which[m] = s;
                m += 1;
            }
            s += 1;
        }
        let g = quantise_axis(lo[a], hi[a], &kids, m)?;
        origin[a] = g.origin.to_bits();
        exps |= ((g.exp + 127) as u32) << (8 * a);
        let mut j = 0;
        while j < m {
            q[a][which[j]] = g.q[j][0];
            q[3 + a][which[j]] = g.q[j][1];
            j += 1;
        }
        a += 1;
    }
    let [m0, m1] = pack(&meta);
    let w = [pack(&q[0]), pack(&q[1]), pack(&q[2]), pack(&q[3]), pack(&q[4]), pack(&q[5])];
    Some(BvhNode {
        origin_exp: UVec4::new(origin[0], origin[1], origin[2], exps | (imask << 24)),
        bases_meta: UVec4::new(child_base, tri_base, m0, m1),
        lo_x_y: UVec4::new(w[0][0], w[0][1], w[1][0], w[1][1]),
        lo_z_hi_x: UVec4::new(w[2][0], w[2][1], w[3][0], w[3][1]),
        hi_y_z: UVec4::new(w[4][0], w[4][1], w[5][0], w[5][1]),
    })
}

// ---------------------------------------------------------------------------------------------
// The linear BVH build.

/// Cells of at most this many triangles are ordered by their full codes (`refine`).
pub const REFINE: u32 = 128;
/// A reference to a node of the binary tree: inner node i, or (with this bit) sorted triangle i.
pub const LEAF_BIT: u32 = 1 << 31;
/// `state` words of the build: wide nodes made so far (the root counted).
pub const STATE_NODES: usize = 0;
/// Leaf triangles placed so far.
pub const STATE_TRIS: usize = 1;
/// The first wide node of the level being collapsed.
pub const STATE_LEVEL_START: usize = 2;
/// One past its last.
pub const STATE_LEVEL_END: usize = 3;
/// Leaf children made.
pub const STATE_LEAVES: usize = 4;
/// Levels of the wide tree that made nodes.
pub const STATE_DEPTH: usize = 5;
/// Nodes that would have made children deeper than `MAX_BVH_DEPTH` (nonzero: the build failed).
pub const STATE_ERROR_DEPTH: usize = 6;
/// Nodes with a box too large to quantise (nonzero: the build failed).
pub const STATE_ERROR_QUANTISE: usize = 7;
/// Nodes that found no room for their children (nonzero: the build failed).
pub const STATE_ERROR_NODES: usize = 8;
/// Words of `state`.
pub const STATE_WORDS: usize = 9;

impl BuildBox {
    /// The empty box (the union's identity).
    pub const EMPTY: BuildBox = BuildBox { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3] };

    /// The union of two boxes.
    #[inline(always)]
    pub fn union(&self, o: &BuildBox) -> BuildBox {
        let mut b = *self;
        let mut a = 0;
        while a < 3 {
            if o.lo[a] < b.lo[a] {
                b.lo[a] = o.lo[a];
            }
            if o.hi[a] > b.hi[a] {
                b.hi[a] = o.hi[a];
            }
            a += 1;
        }
        b
    }

    /// The box of a triangle.
    #[inline(always)]
    pub fn of(t: &Triangle) -> BuildBox {
        let mut b = BuildBox { lo: t.v0, hi: t.v0 };
        b = b.union(&BuildBox { lo: t.v1, hi: t.v1 });
        b.union(&BuildBox { lo: t.v2, hi: t.v2 })
    }

    /// Its centre.
    #[inline(always)]
    pub fn centre(&self) -> [f32; 3] {
        [0.5 * (self.lo[0] + self.hi[0]), 0.5 * (self.lo[1] + self.hi[1]), 0.5 * (self.lo[2] + self.hi[2])]
    }
}

/// The range tree over `n` boxes (its levels: n, ⌈n/2⌉, … down to one): its levels above level
/// 0, and its entries.
#[inline(always)]
pub fn range_tree_shape(n: u32) -> (u32, u32) {
    let mut size = n;
    let mut total = n;
    let mut levels = 0;
    while size > 1 {
        size = size.div_ceil(2);
        total += size;
        levels += 1;
    }
    (levels, total)
}

/// The first entry of `level` of the range tree over `n` boxes, and its size.
#[inline(always)]
pub fn range_level(n: u32, level: u32) -> (u32, u32) {
    let mut off = 0;
    let mut size = n;
    let mut k = 0;
    while k < level && k < 32 {
        off += size;
        size = size.div_ceil(2);
        k += 1;
    }
    (off, size)
}

/// Triangle i's box, into the list (scene order) and level 0 of the range tree.
#[inline(always)]
pub fn boxes<S: Store<BuildBox> + ?Sized, T: Store<BuildBox> + ?Sized>(i: u32, p: &LbvhParams, tris: &[Triangle], list: &mut S, tree: &mut T) {
    if i >= p.count {
        return;
    }
    let b = BuildBox::of(&tris[i as usize]);
    list.store(i as usize, b);
    tree.store(i as usize, b);
}

/// Entry i of range-tree level `p.level` (≥ 1): the union of entries 2i and 2i + 1 of the level
/// below (the one the dispatch before wrote).
#[inline(always)]
pub fn reduce<T: Store<BuildBox> + ?Sized>(i: u32, p: &LbvhParams, tree: &mut T) {
    let (below, below_size) = range_level(p.count, p.level - 1);
    let (here, size) = range_level(p.count, p.level);
    if i >= size {
        return;
    }
    let a = 2 * i;
    let mut b = tree.load((below + a) as usize);
    if a + 1 < below_size {
        b = b.union(&tree.load((below + a + 1) as usize));
    }
    tree.store((here + i) as usize, b);
}

/// The union of sorted boxes `first..=last` from the range tree (at most two entries a level).
#[inline(always)]
pub fn range_bounds<T: Store<BuildBox> + ?Sized>(n: u32, tree: &T, first: u32, last: u32) -> BuildBox {
    let mut acc = BuildBox::EMPTY;
    let (mut l, mut r) = (first, last + 1);
    let mut off = 0;
    let mut size = n;
    let mut level = 0;
    while l < r && level < 32 {
        if l & 1 == 1 {
            acc = acc.union(&tree.load((off + l) as usize));
            l += 1;
        }
        if r & 1 == 1 {
            r -= 1;
            acc = acc.union(&tree.load((off + r) as usize));
        }
        l >>= 1;
        r >>= 1;
        off += size;
        size = size.div_ceil(2);
        level += 1;
    }
    acc
}

/// Spreads the low 10 bits of `v` to every third bit.
#[inline(always)]
fn spread(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

/// The 60-bit Morton code of point `c` in the box [`lo`, `hi`], as its top and bottom 30 bits:
/// on a grid of cubic cells (a flat scene's first splits then cut along its long sides, not
/// across its thin one) whose side is a power of two, 512 to 1024 of them along the box's
/// longest side, then on 1024³ steps within the cell. Only exact
/// operations (halving, subtraction, scaling by a power of two), so every device computes the
/// same codes (a GPU's division need not be correctly rounded).
#[inline(always)]
pub fn morton_code(c: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> [u32; 2] {
    // Halves, so that no difference overflows.
    let mut m = 0.0f32;
    let mut a = 0;
    while a < 3 {
        let h = 0.5 * hi[a] - 0.5 * lo[a];
        if h > m {
            m = h;
        }
        a += 1;
    }
    // 2^k with m · 2^k ≤ 1024 (m is half the longest side): k = 10 − ⌈log2 m⌉.
    let mut k = if m > 0.0 { 10 - (ilog2(m) + if m.to_bits() & 0x7f_ffff != 0 { 1 } else { 0 }) } else { 0 };
    k = k.clamp(-126, 127);
    let scale = exp2i(k);
    let mut q = [0u32; 3];
    let mut f = [0u32; 3];
    let mut a = 0;
    while a < 3 {
        let u = (0.5 * c[a] - 0.5 * lo[a]) * scale;
        q[a] = if u >= 1023.0 { 1023 } else if u > 0.0 { u as u32 } else { 0 };
        // The position within the cell, on 1024 steps (exact: u < 2^10 has 14 bits below 1).
        let r = (u - q[a] as f32) * 1024.0;
        f[a] = if r >= 1023.0 { 1023 } else if r > 0.0 { r as u32 } else { 0 };
        a += 1;
    }
    [spread(q[0]) << 2 | spread(q[1]) << 1 | spread(q[2]), spread(f[0]) << 2 | spread(f[1]) << 1 | spread(f[2])]
}

/// Triangle i's Morton code over the scene's box (the range tree's root, `p.root`) and its
/// sort key, the code's top `p.cell_bits` bits.
#[inline(always)]
pub fn morton<C: Store<[u32; 2]> + ?Sized, S: Store<u32> + ?Sized>(i: u32, p: &LbvhParams, list: &[BuildBox], tree: &[BuildBox], codes: &mut C, keys: &mut S) {
    if i >= p.count {
        return;
    }
    let root = tree[p.root as usize];
    let code = morton_code(list[i as usize].centre(), root.lo, root.hi);
    codes.store(i as usize, code);
    keys.store(i as usize, code[0] >> (30 - p.cell_bits));
}

/// Sorted position i: the triangle the counting sort put there (`order`, by cell) moved to its
/// rank by (code, triangle index) within its cell when the cell holds at most `REFINE`
/// triangles (its place, and the cell's code, otherwise): `sorted` and `sorted_codes` at that
/// rank, and its box at that position of level 0 of the range tree.
#[inline(always)]
pub fn refine<S: Store<u32> + ?Sized, C: Store<[u32; 2]> + ?Sized, T: Store<BuildBox> + ?Sized>(
    i: u32,
    p: &LbvhParams,
    order: &[u32],
    offsets: &[u32],
    codes: &[[u32; 2]],
    list: &[BuildBox],
    sorted: &mut S,
    sorted_codes: &mut C,
    tree: &mut T,
) {
    if i >= p.count {
        return;
    }
    let t = order[i as usize];
    let code = codes[t as usize];
    let shift = 30 - p.cell_bits;
    let cell = (code[0] >> shift) as usize;
    let (start, end) = (offsets[cell], offsets[cell + 1]);
    // A larger cell keeps the sort's order and its triangles the cell's code (its top bits):
    // Karras's tree needs codes in order, and equal codes split by position.
    let mut rank = i - start;
    let mut key = [(code[0] >> shift) << shift, 0];
    if end - start <= REFINE {
        key = code;
        rank = 0;
        let mut j = start;
        while j < end && j < p.count {
            let u = order[j as usize];
            let cu = codes[u as usize];
            if cu[0] < code[0] || (cu[0] == code[0] && (cu[1] < code[1] || (cu[1] == code[1] && u < t))) {
                rank += 1;
            }
            j += 1;
        }
    }
    let at = (start + rank) as usize;
    sorted.store(at, t);
    sorted_codes.store(at, key);
    tree.store(at, list[t as usize]);
}

/// The length of the common prefix of the sorted codes at `a` and `b` (a code's two halves of
/// 30 bits each counted as 32; position tells apart codes that tie: 64 more than their
/// positions' common prefix); −1 when `b` lies outside 0..n.
#[inline(always)]
fn delta(codes: &[[u32; 2]], n: u32, a: u32, b: i32) -> i32 {
    if b < 0 || b as u32 >= n {
        return -1;
    }
    let b = b as u32;
    let (ka, kb) = (codes[a as usize], codes[b as usize]);
    if ka[0] != kb[0] {
        (ka[0] ^ kb[0]).leading_zeros() as i32
    } else if ka[1] != kb[1] {
        32 + (ka[1] ^ kb[1]).leading_zeros() as i32
    } else {
        64 + (a ^ b).leading_zeros() as i32
    }
}

/// Inner node i (of n − 1; the root is 0) of Karras's tree over the `p.count` sorted codes
/// (fewer than 2^29): its range `first..=last` of sorted triangles and its children
/// (`LEAF_BIT` | position for a single triangle) as `[left, right, first, last]`, its number
/// of triangles in `counts`, and itself as its inner children's parent in `parents`.
#[inline(always)]
pub fn hierarchy<S: Store<[u32; 4]> + ?Sized, C: Store<u32> + ?Sized, P: Store<u32> + ?Sized>(
    i: u32,
    p: &LbvhParams,
    codes: &[[u32; 2]],
    nodes: &mut S,
    counts: &mut C,
    parents: &mut P,
) {
    let n = p.count;
    if n < 2 || i >= n - 1 {
        return;
    }
    let ii = i as i32;
    // Direction: towards the neighbour sharing the longer prefix.
    let d: i32 = if delta(codes, n, i, ii + 1) > delta(codes, n, i, ii - 1) { 1 } else { -1 };
    let dmin = delta(codes, n, i, ii - d);
    // An upper bound of the range's length (a power of two, below 2^30), then the length by
    // binary search.
    let mut lmax: i32 = 2;
    while lmax < 1 << 29 && delta(codes, n, i, ii + lmax * d) > dmin {
        lmax *= 2;
    }
    let mut l: i32 = 0;
    let mut t = lmax / 2;
    while t >= 1 {
        if delta(codes, n, i, ii + (l + t) * d) > dmin {
            l += t;
        }
        t /= 2;
    }
    let j = ii + l * d;
    // The split: the last position sharing more than the range's common prefix with i.
    let dnode = delta(codes, n, i, j);
    let mut s: i32 = 0;
    let mut step = l;
    let mut guard = 0;
    loop {
        step = (step + 1) / 2;
        if delta(codes, n, i, ii + (s + step) * d) > dnode {
            s += step;
        }
        guard += 1;
        if step <= 1 || guard >= 32 {
            break;
        }
    }
    let gamma = ii + s * d + if d < 0 { -1 } else { 0 };
    let (first, last) = if d > 0 { (ii, j) } else { (j, ii) };
    let left = if first == gamma { gamma as u32 | LEAF_BIT } else { gamma as u32 };
    let right = if last == gamma + 1 { (gamma + 1) as u32 | LEAF_BIT } else { (gamma + 1) as u32 };
    nodes.store(i as usize, [left, right, first as u32, last as u32]);
    counts.store(i as usize, (last - first + 1) as u32);
    if left & LEAF_BIT == 0 {
        parents.store(left as usize, i);
    }
    if right & LEAF_BIT == 0 {
        parents.store(right as usize, i);
    }
}

/// Inner node i's box, from the range tree over the sorted boxes.
#[inline(always)]
pub fn bounds<S: Store<BuildBox> + ?Sized>(i: u32, p: &LbvhParams, nodes: &[[u32; 4]], tree: &[BuildBox], out: &mut S) {
    if p.count < 2 || i >= p.count - 1 {
        return;
    }
    let nd = nodes[i as usize];
    out.store(i as usize, range_bounds(p.count, tree, nd[2], nd[3]));
}

/// Leaves of a treelet at most: its cheapest topology is searched over all 2^5 subsets of them.
/// Karras & Aila take seven; five in three rounds give trees within 2 % of seven in two on the
/// bench scenes, with a ninth of the search (3^5 against 3^7 steps) and a quarter of its
/// per-item memory (on the H100, seven took 7.7–7.8 ms a phase on 1.5 M triangles, five 1.1).
pub const TREELET_LEAVES: usize = 5;
/// Depths `depths` counts up to; a node at `DEPTH_LIMIT − 3` or deeper is never a treelet's
/// root (so every node a treelet expands has its exact depth).
pub const DEPTH_LIMIT: u32 = 256;
/// Nodes2's range words of an inner node that a treelet rebuilt (its triangles are no longer
/// consecutive in sorted order; `counts` holds how many there are).
pub const NO_RANGE: u32 = u32::MAX;

/// Inner node i's depth in the binary tree (the root's is 0), by its parents; `DEPTH_LIMIT`
/// where the walk reaches it (or a parent index is out of range).
#[inline(always)]
pub fn depths<S: Store<u32> + ?Sized>(i: u32, p: &LbvhParams, parents: &[u32], out: &mut S) {
    let n = p.count;
    if n < 2 || i >= n - 1 {
        return;
    }
    let mut x = i;
    let mut d = 0;
    while x != 0 && d < DEPTH_LIMIT {
        x = parents[x as usize];
        d += 1;
        if x >= n - 1 {
            d = DEPTH_LIMIT;
        }
    }
    out.store(i as usize, d);
}

/// The box of binary node `r`: a triangle's (`LEAF_BIT` | sorted position) from level 0 of the
/// range tree, an inner node's from `boxes2`.
#[inline(always)]
fn ref_box<B: Store<BuildBox> + ?Sized>(r: u32, tree: &[BuildBox], boxes2: &B) -> BuildBox {
    if r & LEAF_BIT != 0 {
        tree[(r & !LEAF_BIT) as usize]
    } else {
        boxes2.load(r as usize)
    }
}

/// Steps of a treelet's grid along its root's longest side at most (`AreaGrid`).
pub const TREELET_GRID_BITS: i32 = 11;
// `cheapest_topology`'s table: a cost of `TREELET_LEAVES − 1` areas of at most 3 · 4^bits each,
// shifted by `TREELET_LEAVES` bits, fits in a word.
const _: () = assert!((((TREELET_LEAVES as u64 - 1) * 3) << (2 * TREELET_GRID_BITS as u64 + TREELET_LEAVES as u64)) < 1 << 32);

/// A box on a treelet's grid: lower and upper steps per axis (`[lo; 3]`, `[hi; 3]`).
pub type GridBox = [[u32; 3]; 2];

/// The grid that boxes within a box (a treelet's root's; a wide node's) are compared by area
/// on: its lower corner, and a power of two `scale` that puts its longest side at most
/// 2^`TREELET_GRID_BITS` steps. A box snaps outwards to whole steps by a subtraction, a
/// multiplication by a power of two and an integer conversion (each exact or correctly rounded
/// on every Vulkan device, none a multiply-add a driver could fuse, subnormal values flushed on
/// every device alike), and areas are integers: so every device makes the same choices, bit for
/// bit (float areas did not: lavapipe's and the CPU's trees differed where two topologies cost
/// nearly the same).
#[derive(Copy, Clone)]
pub struct AreaGrid {
    lo: [f32; 3],
    scale: f32,
}

impl AreaGrid {
    /// The grid over `root`; `None` for a box of no extent or of one that is not finite (every
    /// area within it then counts as 0).
    #[inline(always)]
    pub fn new(root: &BuildBox) -> Option<Self> {
        let mut m = 0.0f32;
        let mut a = 0;
        while a < 3 {
            let e = root.hi[a] - root.lo[a];
            if !(e <= f32::MAX) {
                return None;
            }
            if e > m {
                m = e;
            }
            a += 1;
        }
        // (A subnormal extent counts as none: a GPU may flush it to zero.)
        if !(m >= f32::MIN_POSITIVE) {
            return None;
        }
        // 2^k with m · 2^k ≤ 2^TREELET_GRID_BITS: k = bits − ⌈log2 m⌉.
        let k = TREELET_GRID_BITS - (ilog2(m) + if m.to_bits() & 0x7f_ffff != 0 { 1 } else { 0 });
        Some(AreaGrid { lo: root.lo, scale: exp2i(k.clamp(-126, 127)) })
    }

    /// `b` on the grid, rounded outwards (clamped to the grid).
    #[inline(always)]
    pub fn snap(&self, b: &BuildBox) -> GridBox {
        let top = (1u32 << TREELET_GRID_BITS) as f32;
        let mut g = [[0u32; 3]; 2];
        let mut a = 0;
        while a < 3 {
            // Subnormal differences and products as zero, as a GPU may flush them.
            let l = flush(flush(b.lo[a] - self.lo[a]) * self.scale);
            let h = flush(flush(b.hi[a] - self.lo[a]) * self.scale);
            g[0][a] = if l >= top { 1 << TREELET_GRID_BITS } else if l > 0.0 { l as u32 } else { 0 };
            let hc = if h >= top { 1 << TREELET_GRID_BITS } else if h > 0.0 { h as u32 } else { 0 };
            g[1][a] = if (hc as f32) < h && hc < 1 << TREELET_GRID_BITS { hc + 1 } else { hc };
            a += 1;
        }
        g
    }
}

/// `x`, or 0 where it is subnormal (below `f32::MIN_POSITIVE` in magnitude), on every device
/// alike: Vulkan lets a GPU flush subnormal values to zero.
#[inline(always)]
fn flush(x: f32) -> f32 {
    if x.abs() < f32::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}

/// Half the surface area of a grid box, in steps² (at most 3 · 4^`TREELET_GRID_BITS` on a
/// treelet's grid).
#[inline(always)]
#[allow(clippy::implicit_saturating_sub)] // `saturating_sub`: not in rust-gpu 0.11
pub fn grid_area(b: &GridBox) -> u32 {
    let side = |a: usize| if b[1][a] > b[0][a] { b[1][a] - b[0][a] } else { 0 };
    let d = [side(0), side(1), side(2)];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// The union of the grid boxes of `set`'s members (bit k: `boxes[k]`).
#[inline(always)]
fn union_of(boxes: &[GridBox; TREELET_LEAVES], set: u32) -> GridBox {
    let mut u = GRID_EMPTY;
    let mut k = 0;
    while k < TREELET_LEAVES {
        if set >> k & 1 != 0 {
            u = grid_union(&u, &boxes[k]);
        }
        k += 1;
    }
    u
}

/// The union of two grid boxes.
#[inline(always)]
fn grid_union(a: &GridBox, b: &GridBox) -> GridBox {
    [[a[0][0].min(b[0][0]), a[0][1].min(b[0][1]), a[0][2].min(b[0][2])], [a[1][0].max(b[1][0]), a[1][1].max(b[1][1]), a[1][2].max(b[1][2])]]
}

/// No box: the identity of `grid_union`.
const GRID_EMPTY: GridBox = [[u32::MAX; 3], [0; 3]];

/// The cheapest binary tree over the `m` (2..=`TREELET_LEAVES`) grid boxes `boxes[..m]` by the
/// SAH: the least sum of its inner nodes' areas (the leaves' own costs are the same in every
/// topology). Dynamic programming over the subsets (Karras & Aila 2013): for every subset of two
/// or more, the split into two that costs least. `table[set]` holds the set's cost shifted up
/// by `TREELET_LEAVES` bits and, below, the part holding its lowest member (`table_part`; ties:
/// the first found, parts in decreasing order): one word per set, as the table lives in each
/// item's local memory. Returns the whole set's cost.
#[inline(always)]
pub fn cheapest_topology(boxes: &[GridBox; TREELET_LEAVES], m: usize, table: &mut [u32; 1 << TREELET_LEAVES]) -> u32 {
    let full = (1u32 << m) - 1;
    let mut s = 1u32;
    while s <= full {
        if s & (s - 1) == 0 {
            table[s as usize] = 0;
        } else {
            let low = s & s.wrapping_neg();
            let mut best = u32::MAX;
            let mut bp = low;
            // Every proper non-empty subset, in decreasing order; those holding the lowest
            // member (each split once).
            let mut q = (s - 1) & s;
            while q != 0 {
                if q & low != 0 {
                    let c = (table[q as usize] >> TREELET_LEAVES) + (table[(s ^ q) as usize] >> TREELET_LEAVES);
                    if c < best {
                        best = c;
                        bp = q;
                    }
                }
                q = (q - 1) & s;
            }
            table[s as usize] = (grid_area(&union_of(boxes, s)) + best) << TREELET_LEAVES | bp;
        }
        s += 1;
    }
    table[full as usize] >> TREELET_LEAVES
}

/// The part of `set` that `cheapest_topology` chose (the one holding its lowest member).
#[inline(always)]
pub fn table_part(table: &[u32; 1 << TREELET_LEAVES], set: u32) -> u32 {
    table[set as usize] & ((1 << TREELET_LEAVES) - 1)
}

/// Treelet restructuring (Karras & Aila 2013), phase `p.level` (0..3) of a round: inner node i
/// is a treelet's root when its depth is that phase modulo 3. Its treelet grows from its two
/// children by replacing the inner leaf of largest area with its two children, only at depths
/// 1 and 2 below i, until there are `TREELET_LEAVES` leaves; the treelet's inner nodes are then
/// rewired into the cheapest topology over those leaves (`cheapest_topology`) where that costs
/// less. So two roots of one phase never share an inner node (each owns the nodes at depths 1
/// and 2 below it, expanded or not, and its leaves at depth 3 are other roots, whose box and
/// count no item changes): the items of a phase write disjoint nodes, and read only their own
/// and those that no item writes. A rebuilt node's box and count are rewritten (the root keeps
/// its box and count), and every inner node of the new topology, rebuilt or leaf, gets its new
/// parent; a rebuilt node's range words become `NO_RANGE`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn treelet<N: Store<[u32; 4]> + ?Sized, B: Store<BuildBox> + ?Sized, C: Store<u32> + ?Sized, P: Store<u32> + ?Sized>(
    i: u32,
    p: &LbvhParams,
    depths: &[u32],
    tree: &[BuildBox],
    nodes2: &mut N,
    boxes2: &mut B,
    counts: &mut C,
    parents: &mut P,
) {
    let n = p.count;
    if n < 3 || i >= n - 1 {
        return;
    }
    let d = depths[i as usize];
    if d % 3 != p.level || d + 3 >= DEPTH_LIMIT {
        return;
    }
    let grid = match AreaGrid::new(&boxes2.load(i as usize)) {
        Some(g) => g,
        None => return,
    };
    let root = nodes2.load(i as usize);
    let mut leaves = [0u32; TREELET_LEAVES];
    leaves[0] = root[0];
    leaves[1] = root[1];
    let mut below = [1u32; TREELET_LEAVES];
    let mut inner = [i; TREELET_LEAVES - 1];
    let mut m = 2usize;
    while m < TREELET_LEAVES {
        let mut pick = TREELET_LEAVES;
        let mut best = 0u32;
        let mut k = 0;
        while k < m {
            if leaves[k] & LEAF_BIT == 0 && below[k] <= 2 {
                let a = grid_area(&grid.snap(&boxes2.load(leaves[k] as usize)));
                if pick == TREELET_LEAVES || a > best {
                    pick = k;
                    best = a;
                }
            }
            k += 1;
        }
        if pick == TREELET_LEAVES {
            break;
        }
        let r = leaves[pick];
        inner[m - 1] = r;
        let c = nodes2.load(r as usize);
        leaves[pick] = c[0];
        leaves[m] = c[1];
        below[pick] += 1;
        below[m] = below[pick];
        m += 1;
    }
    if m < 3 {
        return;
    }
    let mut snapped = [GRID_EMPTY; TREELET_LEAVES];
    let mut sizes = [0u32; TREELET_LEAVES];
    let mut k = 0;
    while k < m {
        snapped[k] = grid.snap(&ref_box(leaves[k], tree, boxes2));
        sizes[k] = if leaves[k] & LEAF_BIT != 0 { 1 } else { counts.load(leaves[k] as usize) };
        k += 1;
    }
    // The topology's cost now, on the same grid (snapping a union is the union of the snapped
    // boxes: rounding is monotonic).
    let mut now = 0u32;
    let mut k = 0;
    while k < m - 1 {
        now += grid_area(&grid.snap(&boxes2.load(inner[k] as usize)));
        k += 1;
    }
    let mut table = [0u32; 1 << TREELET_LEAVES];
    let full = (1u32 << m) - 1;
    if cheapest_topology(&snapped, m, &mut table) >= now {
        return;
    }
    // The new topology, top down: each set of two or more leaves takes the next inner node.
    let mut sets = [0u32; TREELET_LEAVES];
    let mut nodes = [0u32; TREELET_LEAVES];
    sets[0] = full;
    nodes[0] = i;
    let mut sp = 1usize;
    let mut next = 1usize;
    let mut guard = 0;
    while sp > 0 && guard < TREELET_LEAVES {
        guard += 1;
        sp -= 1;
        let (s, x) = (sets[sp], nodes[sp]);
        let halves = [table_part(&table, s), s ^ table_part(&table, s)];
        let mut kids = [0u32; 2];
        let mut h = 0;
        while h < 2 {
            let set = halves[h];
            if set & (set - 1) == 0 {
                kids[h] = leaves[set.trailing_zeros() as usize];
            } else if next < m - 1 && sp < TREELET_LEAVES {
                kids[h] = inner[next];
                next += 1;
                sets[sp] = set;
                nodes[sp] = kids[h];
                sp += 1;
            }
            if kids[h] & LEAF_BIT == 0 {
                parents.store(kids[h] as usize, x);
            }
            h += 1;
        }
        if x == i {
            nodes2.store(x as usize, [kids[0], kids[1], root[2], root[3]]);
        } else {
            nodes2.store(x as usize, [kids[0], kids[1], NO_RANGE, NO_RANGE]);
            // The leaves' boxes again (no item of the phase writes them), rather than kept.
            let mut b = BuildBox::EMPTY;
            let mut c = 0;
            let mut k = 0;
            while k < m {
                if s >> k & 1 != 0 {
                    b = b.union(&ref_box(leaves[k], tree, boxes2));
                    c += sizes[k];
                }
                k += 1;
            }
            boxes2.store(x as usize, b);
            counts.store(x as usize, c);
        }
    }
}

/// The level pass (one item): the nodes made since the last level become the next level's
/// items (`state`'s level start and end), and the indirect dispatch's workgroup counts.
#[inline(always)]
pub fn level<S: Store<u32> + ?Sized, A: Store<[u32; 3]> + ?Sized>(i: u32, state: &mut S, args: &mut A) {
    if i != 0 {
        return;
    }
    let start = state.load(STATE_LEVEL_END);
    let end = state.load(STATE_NODES);
    state.store(STATE_LEVEL_START, start);
    state.store(STATE_LEVEL_END, end);
    if end > start {
        state.store(STATE_DEPTH, state.load(STATE_DEPTH) + 1);
    }
    args.store(0, crate::kernel::dispatch_args(end - start));
}

/// The binary tree as `collapse` reads it.
struct Binary<'a> {
    nodes: &'a [[u32; 4]],
    boxes: &'a [BuildBox],
    counts: &'a [u32],
    tree: &'a [BuildBox],
}

impl Binary<'_> {
    /// Triangles under `r`.
    #[inline(always)]
    fn size(&self, r: u32) -> u32 {
        if r & LEAF_BIT != 0 {
            1
        } else {
            self.counts[r as usize]
        }
    }
    /// Its box.
    #[inline(always)]
    fn bounds(&self, r: u32) -> BuildBox {
        if r & LEAF_BIT != 0 {
            self.tree[(r & !LEAF_BIT) as usize]
        } else {
            self.boxes[r as usize]
        }
    }
}

/// Wide node `state[STATE_LEVEL_START] + i` of level `p.level` (its binary node in `pending`):
/// see the module. Its child nodes' binary nodes go to `pending` at their places.
#[inline(always)]
pub fn collapse<S: AtomicStore + Store<u32> + ?Sized, P: Store<u32> + ?Sized, N: Store<BvhNode> + ?Sized, T: Store<Triangle> + ?Sized>(
    i: u32,
    p: &LbvhParams,
    tris: &[Triangle],
    sorted: &[u32],
    nodes2: &[[u32; 4]],
    boxes2: &[BuildBox],
    counts: &[u32],
    tree: &[BuildBox],
    state: &mut S,
    pending: &mut P,
    out_nodes: &mut N,
    out_tris: &mut T,
) {
    let start = state.load(STATE_LEVEL_START);
    let end = state.load(STATE_LEVEL_END);
    if i >= end - start {
        return;
    }
    // After a failure the tree is not finished: nothing more is made.
    if state.load(STATE_ERROR_DEPTH) != 0 || state.load(STATE_ERROR_QUANTISE) != 0 || state.load(STATE_ERROR_NODES) != 0 {
        return;
    }
    let w = start + i;
    let bin = Binary { nodes: nodes2, boxes: boxes2, counts, tree };
    let b = pending.load(w as usize);
    let parent = bin.bounds(b);
    // The children: the binary node's two, then the inner child of largest area replaced by its
    // two until there are eight (a node of at most MAX_LEAF_TRIS triangles is a leaf). Areas on
    // the node's grid (`AreaGrid`), so every device picks the same children (float areas by a
    // multiply-add differed between lavapipe and the CPU where two children nearly tied).
    let grid = AreaGrid::new(&parent);
    let area = |b: &BuildBox| match grid {
        Some(g) => grid_area(&g.snap(b)),
        None => 0,
    };
    let mut kids = [b; BVH_WIDTH];
    let mut n = 1;
    if bin.size(b) > MAX_LEAF_TRIS as u32 {
        let nd = nodes2[b as usize];
        kids[0] = nd[0];
        kids[1] = nd[1];
        n = 2;
        while n < BVH_WIDTH {
            let mut pick = BVH_WIDTH;
            let mut best = 0u32;
            let mut k = 0;
            while k < n {
                if bin.size(kids[k]) > MAX_LEAF_TRIS as u32 {
                    let a = area(&bin.bounds(kids[k]));
                    if pick == BVH_WIDTH || a >= best {
                        pick = k;
                        best = a;
                    }
                }
                k += 1;
            }
            if pick == BVH_WIDTH {
                break;
            }
            let nd = nodes2[kids[pick] as usize];
            kids[pick] = kids[n - 1];
            kids[n - 1] = nd[0];
            kids[n] = nd[1];
            n += 1;
        }
    }
    let mut centres = [[0.0f32; 3]; BVH_WIDTH];
    let mut k = 0;
    while k < n {
        centres[k] = bin.bounds(kids[k]).centre();
        k += 1;
    }
    let slots = assign_slots(parent.centre(), &centres, n);
    // Places: child nodes and leaf triangles in slot order.
    let (mut inner, mut leaf_tris) = (0u32, 0u32);
    let mut s = 0;
    while s < BVH_WIDTH {
        if slots[s] != NO_CHILD {
            let size = bin.size(kids[slots[s] as usize]);
            if size > MAX_LEAF_TRIS as u32 {
                inner += 1;
            } else {
                leaf_tris += size;
            }
        }
        s += 1;
    }
    if inner > 0 && p.level + 1 >= MAX_BVH_DEPTH as u32 {
        state.atomic_add(STATE_ERROR_DEPTH, 1);
        return;
    }
    // Every item of the level takes its places (possibly none) in the same two calls.
    let child_base = state.atomic_add_shared(STATE_NODES, inner);
    let tri_base = state.atomic_add_shared(STATE_TRIS, leaf_tris);
    if child_base + inner > out_nodes.len() as u32 || child_base + inner > pending.len() as u32 {
        state.atomic_add(STATE_ERROR_NODES, 1);
        return;
    }
    let mut out = [SlotChild::default(); BVH_WIDTH];
    let (mut next_node, mut next_tri, mut leaves) = (0u32, 0u32, 0u32);
    let mut s = 0;
    while s < BVH_WIDTH {
        if slots[s] != NO_CHILD {
            let r = kids[slots[s] as usize];
            let bb = bin.bounds(r);
            let size = bin.size(r);
            out[s].lo = bb.lo;
            out[s].hi = bb.hi;
            if size > MAX_LEAF_TRIS as u32 {
                out[s].meta = node_meta(s as u32);
                pending.store((child_base + next_node) as usize, r);
                next_node += 1;
            } else {
                out[s].meta = leaf_meta(size, next_tri);
                // Its triangles, left to right (a treelet may have made them other than
                // consecutive in sorted order): at most MAX_LEAF_TRIS, so at most two inner
                // nodes below it and three entries on the stack.
                let mut todo = [r; 2 * MAX_LEAF_TRIS];
                let mut nt = 1usize;
                let mut placed = 0;
                let mut guard = 0;
                while nt > 0 && guard < 2 * MAX_LEAF_TRIS {
                    guard += 1;
                    nt -= 1;
                    let x = todo[nt];
                    if x & LEAF_BIT != 0 {
                        if placed < size {
                            let scene = sorted[(x & !LEAF_BIT) as usize];
                            let mut t = tris[scene as usize];
                            t._pad = scene;
                            out_tris.store((tri_base + next_tri) as usize, t);
                            next_tri += 1;
                            placed += 1;
                        }
                    } else if nt + 2 <= 2 * MAX_LEAF_TRIS {
                        let c = bin.nodes[x as usize];
                        todo[nt] = c[1];
                        todo[nt + 1] = c[0];
                        nt += 2;
                    }
                }
                leaves += 1;
            }
        }
        s += 1;
    }
    if leaves > 0 {
        state.atomic_add(STATE_LEAVES, leaves);
    }
    match encode_node(parent.lo, parent.hi, &out, child_base, tri_base) {
        Some(node) => out_nodes.store(w as usize, node),
        None => {
            state.atomic_add(STATE_ERROR_QUANTISE, 1);
        }
    }
}
