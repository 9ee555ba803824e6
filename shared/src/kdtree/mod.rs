//! The kd-tree as both sides see it (8-byte nodes, children adjacent, a primitive index list)
//! and the traversal family of Foley & Sugerman 2005 and Horn et al. 2007, written once:
//!
//! | algorithm | stack | push-down |
//! |---|---|---|
//! | full stack (classic) | `FullStack` (never drops) | no |
//! | kd-restart | `NoStack` | no |
//! | kd-restart + push-down | `NoStack` | yes |
//! | push-down + short stack of N | `ShortStack<N>` (drops its oldest entry when full) | yes |
//!
//! A traversal that runs out of stacked work after having dropped entries restarts: from the
//! root, or with push-down from the deepest node whose ray interval was never split since the
//! last restart, with the interval [t_max of the last leaf, t_max of the scene].
//!
//! Rules that keep every variant exact (the papers' pseudocode does not):
//! * a hit anywhere in the ray's interval is kept as the best so far; the traversal stops only
//!   once the best hit lies at or before the end of the current leaf, so a hit found in a leaf
//!   but beyond it (a triangle spanning several cells) never ends the search early;
//! * every triangle of a leaf is tested and the closest taken;
//! * the builder never puts a split plane through a vertex (host `kdtree::sah`): a point on a
//!   plane belongs only to triangles that straddle it, which are in both children, so a ray
//!   lying in a split plane (direction component ±0) needs only the child of its origin;
//! * the ray parameter t of a plane, (p − o)·(1/d), is rounded (`PLANE_TOL`), and a cell may be
//!   thinner along the ray than that rounding (a scene small against the ray's distance, or
//!   noise-thin geometry): a plane whose t lies within rounding of an end of the interval is
//!   ambiguous. The full stack visits both children there; a stack that may drop entries
//!   cannot keep both for certain (a restart from the end of a leaf could pass over a cell that
//!   thin), so the ray is walked again from the start with the full stack (counted as a
//!   restart). A restart starts on the plane that ended the last leaf, the one plane whose t
//!   equals the new start by construction, and goes beyond it. The search ends only when the
//!   best hit lies below the end of the leaf by more than the roundings (`exit_bound`);
//! * rays that `Ray::is_valid` rejects are misses, and every loop is bounded by the tree size.
//!
//! Modules: `single` (the one-ray traversal above), `packet` (four rays at once with lane
//! masks, the same decisions per lane), `leaf_list` (the decomposed pipeline's leaf lists),
//! `stack` (no stack, short stack, full stack). What happens at a leaf (closest / any hit,
//! leaf recording) is the crate-level `query` module, shared with every structure.
mod leaf_list;
mod packet;
mod single;
mod stack;

pub use leaf_list::{intersect_leaves, record_leaves, LeafList, LeafRef, LEAF_OVERFLOW, MAX_LEAF_LIST};
pub use packet::{direction_signs, packet_or_single, run_packet, traverse_packet, PacketEntry, PacketTraversal, PACKET};
pub use single::{any_hit, closest_hit, run, traverse, Algorithm, with_traversal, Full, PushDown, Restart, Short, Traversal, WithTraversal, MAX_SHORT_STACK};
pub use stack::{Entry, ExitEntry, FullStack, NoStack, ShortStack, Stack, StackEntry, NO_NODE};

use crate::aabb::Aabb;
use crate::parts::Parts;
use crate::pod::Triangle;
use crate::query::{Near, Prims};
use bytemuck::{Pod, Zeroable};

/// Deepest tree the builder produces; also the capacity of `FullStack`.
pub const MAX_DEPTH: usize = 48;

/// Relative bound on the rounding of a ray parameter t at a split plane, (p − o) · (1/d): three
/// roundings, 3u|t| (u = 2^-24), doubled.
pub const PLANE_TOL: f32 = 1.0 / (1u32 << 21) as f32;

/// Relative margin below the end of a leaf's interval under which a hit ends the search: the
/// rounding of the end itself and of the triangle test's t.
pub const EXIT_TOL: f32 = 1.0 / (1u32 << 19) as f32;

/// A ray parameter (`f32`), or one per lane of a packet (`Vec4`): the plane rules below are
/// written once over it, for the single-ray and the packet traversals.
pub trait Param: Copy + core::ops::Add<Output = Self> + core::ops::Sub<Output = Self> + core::ops::Mul<Output = Self> {
    /// What a comparison gives: `bool`, or a lane mask.
    type Mask;
    /// `x` (in every lane).
    fn splat(x: f32) -> Self;
    /// |self|.
    fn magnitude(self) -> Self;
    /// self ≤ other.
    fn at_most(self, other: Self) -> Self::Mask;
}

impl Param for f32 {
    type Mask = bool;
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn magnitude(self) -> f32 {
        self.abs()
    }
    #[inline(always)]
    fn at_most(self, other: f32) -> bool {
        self <= other
    }
}

impl Param for glam::Vec4 {
    type Mask = glam::BVec4A;
    #[inline(always)]
    fn splat(x: f32) -> glam::Vec4 {
        glam::Vec4::splat(x)
    }
    #[inline(always)]
    fn magnitude(self) -> glam::Vec4 {
        self.abs()
    }
    #[inline(always)]
    fn at_most(self, other: glam::Vec4) -> glam::BVec4A {
        self.cmple(other)
    }
}

/// How far a split plane's computed ray parameter `ts` and an interval end computed the same
/// way may lie apart and still come in either order along the ray: their roundings
/// (`PLANE_TOL` each, of `ts`'s magnitude where they are that close). The full stack visits
/// both children of a plane this near an end.
#[inline(always)]
pub fn plane_band<P: Param>(ts: P) -> P {
    P::splat(2.0 * PLANE_TOL) * ts.magnitude()
}

/// Whether split plane `ts` lies within rounding of the interval end `t` (each rounded by
/// `PLANE_TOL` of its own magnitude), so that the two may come in either order along the ray:
/// the plane is ambiguous there, and a traversal that may drop stack entries hands the ray to
/// the full stack.
#[inline(always)]
pub fn near_end<P: Param>(ts: P, t: P) -> P::Mask {
    (ts - t).magnitude().at_most(P::splat(PLANE_TOL) * (ts.magnitude() + t.magnitude()))
}

/// What a hit must lie before (`Visitor::done`) to end the search after a leaf whose interval
/// ends at `t1`: below the least t at which a cell after it can begin, less the triangle
/// test's rounding.
#[inline(always)]
pub fn exit_bound(t1: f32) -> f32 {
    t1 - EXIT_TOL * t1.abs()
}
const LEAF: u32 = 3;

/// Interior: `a` = split position (f32 bits), `b` = first child index << 2 | axis; the children
/// are adjacent (below = first, above = first + 1). Leaf: `a` = offset into the primitive index
/// list, `b` = primitive count << 2 | 3.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct KdNode {
    /// Interior: split position (f32 bits). Leaf: offset into the primitive index list.
    pub a: u32,
    /// Interior: first child index << 2 | axis. Leaf: primitive count << 2 | 3.
    pub b: u32,
}

impl KdNode {
    /// An interior node splitting `axis` (0..=2) at `split`, with children `first_child` and
    /// `first_child + 1`.
    pub fn interior(axis: u32, split: f32, first_child: u32) -> Self {
        KdNode { a: split.to_bits(), b: (first_child << 2) | axis }
    }
    /// A leaf holding the primitive index list entries `offset..offset + count`.
    pub fn leaf(offset: u32, count: u32) -> Self {
        KdNode { a: offset, b: (count << 2) | LEAF }
    }
    /// Whether this is a leaf (low two bits 3).
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == LEAF
    }
    /// Split axis of an interior node (0: x, 1: y, 2: z).
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }
    /// Split position of an interior node.
    #[inline(always)]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.a)
    }
    /// Index of an interior node's first child (below the plane); the second (above) follows it.
    #[inline(always)]
    pub fn first_child(&self) -> u32 {
        self.b >> 2
    }
    /// Offset of a leaf's primitives in the primitive index list.
    #[inline(always)]
    pub fn prim_offset(&self) -> u32 {
        self.a
    }
    /// Number of primitives in a leaf.
    #[inline(always)]
    pub fn prim_count(&self) -> u32 {
        self.b >> 2
    }
}

/// The tree over `tris`: `nodes[0]` is the root, `bounds` the scene box.
#[derive(Copy, Clone)]
pub struct KdTree<'a> {
    /// The nodes; `nodes[0]` is the root.
    pub nodes: Parts<'a, KdNode>,
    /// The primitive index list: each leaf holds a range of it, each entry an index into `tris`.
    pub prims: Parts<'a, u32>,
    /// The triangles.
    pub tris: Parts<'a, Triangle>,
    /// The scene box: the root's cell.
    pub bounds: Aabb,
}


impl<'a> KdTree<'a> {
    /// The primitive index list and triangles its leaves refer to.
    #[inline(always)]
    pub fn prims(&self) -> Prims<'a> {
        Prims { index: self.prims, tris: self.tris }
    }
}

/// Capacity of `leaves_in_box`'s stack: it holds at most one pending child per level of a tree
/// at most `MAX_DEPTH` deep.
pub const BOX_STACK: usize = MAX_DEPTH + 16;

/// Calls `leaf(i, node)` for every leaf of a tree of `n` nodes (`node(i)` reads node i) whose
/// cell overlaps the box `lo`..`hi`, touching included (a triangle lying in a split plane may
/// be in either child), until `leaf` returns false. Every node is entered at most once.
#[inline(always)]
pub fn leaves_in_box<F: Fn(usize) -> KdNode, L: FnMut(usize, KdNode) -> bool>(n: usize, node: F, lo: [f32; 3], hi: [f32; 3], mut leaf: L) {
    let mut stack = [0u32; BOX_STACK];
    let mut top = 1usize;
    let mut guard = 0usize;
    while top > 0 && guard < n {
        guard += 1;
        top -= 1;
        let i = stack[top] as usize;
        if i >= n {
            return;
        }
        let nd = node(i);
        if nd.is_leaf() {
            if !leaf(i, nd) {
                return;
            }
            continue;
        }
        let (c, a, s) = (nd.first_child(), nd.axis(), nd.split());
        if hi[a] >= s && top < BOX_STACK {
            stack[top] = c + 1;
            top += 1;
        }
        if lo[a] <= s && top < BOX_STACK {
            stack[top] = c;
            top += 1;
        }
    }
}

/// Whether a triangle of a leaf whose cell overlaps the box `lo`..`hi` answers `q`
/// (`query::Near`).
#[inline(always)]
pub fn near<N: Near>(t: &KdTree, lo: [f32; 3], hi: [f32; 3], q: &N) -> bool {
    let (prims, tris) = (t.prims, t.tris);
    let mut found = false;
    leaves_in_box(t.nodes.len(), |i| t.nodes.get(i), lo, hi, |_, nd| {
        let (first, count) = (nd.prim_offset() as usize, nd.prim_count() as usize);
        let mut j = 0;
        while j < count {
            let p = prims.get(first + j);
            found |= q.test(p, &tris.get(p as usize));
            j += 1;
        }
        true
    });
    found
}
