//! The decomposed pipeline (Frolov & Ignatenko): instead of one kernel that walks the tree and
//! tests triangles, `record_leaves` walks the tree with the full stack and writes the ray's
//! non-empty leaves in traversal order into a bounded list, and `intersect_leaves` then tests
//! the listed leaves in that order. Both are the one traversal of `single`, with a visitor that
//! records instead of testing.
//!
//! Each entry carries the end of the ray's interval in its leaf; an empty leaf extends the
//! previous entry's end, so after each listed leaf `intersect_leaves` asks exactly the question
//! the single traversal would have asked after that leaf and any empty leaves behind it: the
//! result is identical. A list that fills up is marked `LEAF_OVERFLOW`; if no hit settles the
//! query within it the ray must be traced again by a monolithic kernel (never dropped).
//! The list is built locally and copied out by the caller (a storage-buffer slice held in the
//! visitor made NVIDIA's SPIR-V compiler crash, driver 580).
use super::single::traverse;
use super::stack::{Entry, FullStack};
use super::{exit_bound, KdNode, KdTree};
use crate::query::{Prims, Query, Visitor};
use crate::stats::Stats;
use crate::ray::Ray;
use crate::triangle::ShearedRay;
use bytemuck::{Pod, Zeroable};

/// A listed leaf and the end of the ray's interval inside it (and inside the empty leaves
/// that follow it).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LeafRef {
    /// The leaf as a leaf node (`KdNode::leaf`): its primitive offset and count.
    pub node: KdNode,
    /// End of the ray's interval in this leaf and the empty leaves after it.
    pub t_far: f32,
}

/// Bit of a list's status word set when the list could not hold every leaf; the low bits hold
/// the number of entries.
pub const LEAF_OVERFLOW: u32 = 1 << 31;

/// Longest leaf list: the list is built in registers / local memory, then copied out.
pub const MAX_LEAF_LIST: usize = 32;

/// One ray's leaf list under construction. The newest non-empty leaf is kept in `pending`
/// until the next one arrives, so the empty leaves behind it extend it in place.
pub struct LeafList {
    /// The listed leaves; the first `len` are valid.
    pub entries: [LeafRef; MAX_LEAF_LIST],
    /// Entries listed so far.
    pub len: u32,
    /// Most entries allowed (at most `MAX_LEAF_LIST`).
    pub cap: u32,
    /// The newest non-empty leaf, not yet appended (valid if `has_pending`).
    pub pending: LeafRef,
    /// Whether `pending` holds a leaf.
    pub has_pending: bool,
    /// Whether a leaf did not fit: the list is incomplete.
    pub overflow: bool,
}

impl LeafList {
    /// Entry count, plus `LEAF_OVERFLOW` if the list is incomplete.
    #[inline(always)]
    pub fn status(&self) -> u32 {
        self.len | if self.overflow { LEAF_OVERFLOW } else { 0 }
    }

    /// Appends the pending entry; marks an overflow if the list is full.
    #[inline(always)]
    fn flush(&mut self) {
        if self.has_pending {
            if self.len == self.cap {
                self.overflow = true;
            } else {
                self.entries[self.len as usize] = self.pending;
                self.len += 1;
            }
            self.has_pending = false;
        }
    }
}

impl Visitor for LeafList {
    #[inline(always)]
    fn leaf<S: Stats>(&mut self, _g: &Prims, first: u32, count: u32, _r: &ShearedRay, _t_min: f32, t_far: f32, _stats: &mut S) {
        if count == 0 {
            self.pending.t_far = t_far;
        } else {
            self.flush();
            self.pending = LeafRef { node: KdNode::leaf(first, count), t_far };
            self.has_pending = true;
        }
    }
    #[inline(always)]
    fn done(&self, _t: f32) -> bool {
        self.overflow
    }
}

/// Lists the leaves of `ray` (full-stack traversal), at most `cap` (≤ `MAX_LEAF_LIST`).
/// `stats` counts the nodes visited (the leaves are counted when `intersect_leaves` tests them).
#[inline(always)]
pub fn record_leaves<S: Stats>(tree: &KdTree, ray: &Ray, cap: u32, stats: &mut S) -> LeafList {
    let mut l = LeafList {
        entries: [LeafRef::default(); MAX_LEAF_LIST],
        len: 0,
        cap: if cap as usize > MAX_LEAF_LIST { MAX_LEAF_LIST as u32 } else { cap },
        pending: LeafRef::default(),
        has_pending: false,
        overflow: false,
    };
    traverse::<_, Entry, _, _, false>(tree, ray, &mut l, &mut FullStack::new(), &mut NodesOnly(stats));
    l.flush();
    l
}

/// Tests the leaves listed for `ray` (status word `status`, entries from `list[base]`) in order
/// for `q`, over the tree's primitive index list and triangles `g` (`KdTree::prims`: the nodes
/// are not needed). Returns whether `q` holds the final answer: `false` only for an overflowed list
/// that did not settle the query.
#[inline(always)]
pub fn intersect_leaves<Q: Query, S: Stats>(
    g: &Prims,
    ray: &Ray,
    list: &[LeafRef],
    base: usize,
    status: u32,
    q: &mut Q,
    stats: &mut S,
) -> bool {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return true,
    };
    let len = (status & !LEAF_OVERFLOW) as usize;
    let mut k = 0;
    while k < len {
        let e = list[base + k];
        stats.leaf();
        q.leaf(g, e.node.prim_offset(), e.node.prim_count(), &r, ray.t_min, e.t_far, stats);
        if q.done(exit_bound(e.t_far)) {
            return true;
        }
        k += 1;
    }
    status & LEAF_OVERFLOW == 0
}

/// Passes node visits through and drops the rest.
struct NodesOnly<'s, S: Stats>(&'s mut S);
impl<S: Stats> Stats for NodesOnly<'_, S> {
    #[inline(always)]
    fn node(&mut self) {
        self.0.node();
    }
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tri(&mut self) {}
    #[inline(always)]
    fn restart(&mut self) {}
}
