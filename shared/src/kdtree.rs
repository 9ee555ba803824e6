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
//!   lying in a split plane (direction component ±0), or starting, entering or ending exactly on
//!   one, needs only one of the two children: zero-length intervals are never visited, and a
//!   restart always makes progress;
//! * rays that `Ray::is_valid` rejects are misses, and every loop is bounded by the tree size.
use crate::aabb::{intersect_box, inv_dir, Aabb};
use crate::pod::{Hit, Triangle};
use crate::ray::Ray;
use crate::triangle::{intersect_triangle, ShearedRay};
use bytemuck::{Pod, Zeroable};

/// Deepest tree the builder produces; also the capacity of `FullStack`.
pub const MAX_DEPTH: usize = 48;
const LEAF: u32 = 3;

/// Interior: `a` = split position (f32 bits), `b` = first child index << 2 | axis; the children
/// are adjacent (below = first, above = first + 1). Leaf: `a` = offset into the primitive index
/// list, `b` = primitive count << 2 | 3.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct KdNode {
    pub a: u32,
    pub b: u32,
}

impl KdNode {
    pub fn interior(axis: u32, split: f32, first_child: u32) -> Self {
        KdNode { a: split.to_bits(), b: (first_child << 2) | axis }
    }
    pub fn leaf(offset: u32, count: u32) -> Self {
        KdNode { a: offset, b: (count << 2) | LEAF }
    }
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == LEAF
    }
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }
    #[inline(always)]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.a)
    }
    #[inline(always)]
    pub fn first_child(&self) -> u32 {
        self.b >> 2
    }
    #[inline(always)]
    pub fn prim_offset(&self) -> u32 {
        self.a
    }
    #[inline(always)]
    pub fn prim_count(&self) -> u32 {
        self.b >> 2
    }
}

/// The tree over `tris`: `nodes[0]` is the root, `bounds` the scene box.
#[derive(Copy, Clone)]
pub struct KdTree<'a> {
    pub nodes: &'a [KdNode],
    pub prims: &'a [u32],
    pub tris: &'a [Triangle],
    pub bounds: Aabb,
}

/// Traversal cost counters; `NoStats` compiles to nothing.
pub trait Stats {
    fn node(&mut self);
    fn leaf(&mut self);
    fn tri(&mut self);
    fn restart(&mut self);
}

pub struct NoStats;
impl Stats for NoStats {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tri(&mut self) {}
    #[inline(always)]
    fn restart(&mut self) {}
}

/// Per-ray counts: nodes visited (interior and leaf), leaves visited, triangles tested,
/// restarts. Also the GPU buffer layout of the counting kernels.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct Counters {
    pub nodes: u32,
    pub leaves: u32,
    pub tris: u32,
    pub restarts: u32,
}
impl Stats for Counters {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    #[inline(always)]
    fn tri(&mut self) {
        self.tris += 1;
    }
    #[inline(always)]
    fn restart(&mut self) {
        self.restarts += 1;
    }
}

/// What a traversal looks for: the closest hit, or any hit.
pub trait Query {
    /// Tests the triangles of a leaf.
    fn leaf<S: Stats>(&mut self, tree: &KdTree, node: KdNode, r: &ShearedRay, t_min: f32, stats: &mut S);
    /// Whether nothing beyond `t` (the end of the leaf just tested) can change the answer.
    fn done(&self, t: f32) -> bool;
}

pub struct Closest {
    pub hit: Hit,
    pub t_max: f32,
}

impl Closest {
    pub fn new(ray: &Ray) -> Self {
        Closest { hit: Hit::NONE, t_max: ray.t_max }
    }
}

impl Query for Closest {
    #[inline(always)]
    fn leaf<S: Stats>(&mut self, tree: &KdTree, node: KdNode, r: &ShearedRay, t_min: f32, stats: &mut S) {
        let off = node.prim_offset() as usize;
        let n = node.prim_count() as usize;
        let mut j = 0;
        while j < n {
            let p = tree.prims[off + j];
            let tri = &tree.tris[p as usize];
            stats.tri();
            if let Some(h) = intersect_triangle(r, tri.v0, tri.v1, tri.v2, t_min, self.t_max) {
                // Ties in t keep the lower primitive index, as the brute-force oracle does.
                if !self.hit.is_hit() || h.t < self.hit.t || (h.t == self.hit.t && p < self.hit.prim) {
                    self.hit = Hit { t: h.t, prim: p, b1: h.b1, b2: h.b2 };
                    self.t_max = h.t;
                }
            }
            j += 1;
        }
    }
    #[inline(always)]
    fn done(&self, t: f32) -> bool {
        self.hit.is_hit() && self.hit.t <= t
    }
}

pub struct AnyHit {
    pub found: bool,
    pub t_max: f32,
}

impl AnyHit {
    pub fn new(ray: &Ray) -> Self {
        AnyHit { found: false, t_max: ray.t_max }
    }
}

impl Query for AnyHit {
    #[inline(always)]
    fn leaf<S: Stats>(&mut self, tree: &KdTree, node: KdNode, r: &ShearedRay, t_min: f32, stats: &mut S) {
        let off = node.prim_offset() as usize;
        let n = node.prim_count() as usize;
        let mut j = 0;
        while j < n && !self.found {
            let tri = &tree.tris[tree.prims[off + j] as usize];
            stats.tri();
            if intersect_triangle(r, tri.v0, tri.v1, tri.v2, t_min, self.t_max).is_some() {
                self.found = true;
            }
            j += 1;
        }
    }
    #[inline(always)]
    fn done(&self, _t: f32) -> bool {
        self.found
    }
}

#[derive(Copy, Clone, Default)]
pub struct Entry {
    pub node: u32,
    pub t0: f32,
    pub t1: f32,
}

/// Where a traversal keeps the far children it still has to visit.
pub trait Stack {
    fn clear(&mut self);
    fn push(&mut self, e: Entry);
    fn pop(&mut self) -> Option<Entry>;
    /// Whether an entry was lost since the last `clear` (then a restart is needed).
    fn dropped(&self) -> bool;
}

/// No stack: every far child is "dropped" and found again by restarting.
pub struct NoStack {
    dropped: bool,
}
impl NoStack {
    pub fn new() -> Self {
        NoStack { dropped: false }
    }
}
impl Default for NoStack {
    fn default() -> Self {
        Self::new()
    }
}
impl Stack for NoStack {
    #[inline(always)]
    fn clear(&mut self) {
        self.dropped = false;
    }
    #[inline(always)]
    fn push(&mut self, _e: Entry) {
        self.dropped = true;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry> {
        None
    }
    #[inline(always)]
    fn dropped(&self) -> bool {
        self.dropped
    }
}

/// A ring buffer of N entries: pushing onto a full stack overwrites the oldest entry.
pub struct ShortStack<const N: usize> {
    items: [Entry; N],
    top: usize,
    len: usize,
    dropped: bool,
}
impl<const N: usize> ShortStack<N> {
    pub fn new() -> Self {
        ShortStack { items: [Entry { node: 0, t0: 0.0, t1: 0.0 }; N], top: 0, len: 0, dropped: false }
    }
}
impl<const N: usize> Default for ShortStack<N> {
    fn default() -> Self {
        Self::new()
    }
}
impl<const N: usize> Stack for ShortStack<N> {
    #[inline(always)]
    fn clear(&mut self) {
        self.len = 0;
        self.dropped = false;
    }
    #[inline(always)]
    fn push(&mut self, e: Entry) {
        self.items[self.top] = e;
        self.top = if self.top + 1 == N { 0 } else { self.top + 1 };
        if self.len == N {
            self.dropped = true;
        } else {
            self.len += 1;
        }
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry> {
        if self.len == 0 {
            return None;
        }
        self.top = if self.top == 0 { N - 1 } else { self.top - 1 };
        self.len -= 1;
        Some(self.items[self.top])
    }
    #[inline(always)]
    fn dropped(&self) -> bool {
        self.dropped
    }
}

/// The classic full stack: deep enough for any tree the builder makes, so it never drops.
pub type FullStack = ShortStack<MAX_DEPTH>;

/// Walks the tree for `q`. `PUSHDOWN` selects Horn's push-down restart node.
#[inline(always)]
pub fn traverse<Q: Query, K: Stack, S: Stats, const PUSHDOWN: bool>(
    tree: &KdTree,
    ray: &Ray,
    q: &mut Q,
    stack: &mut K,
    stats: &mut S,
) {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return,
    };
    let o = ray.origin;
    let inv = inv_dir(ray.dir);
    let (scene_t0, scene_t1) = match intersect_box(o, inv, &tree.bounds, ray.t_min, ray.t_max) {
        Some(i) => i,
        None => return,
    };
    let n_nodes = tree.nodes.len() as u32;
    // Hang guard: a valid ray visits far fewer nodes than this.
    let max_steps = n_nodes.min(1 << 24) * MAX_DEPTH as u32 + 64;
    let mut steps = 0u32;

    let mut restart_node = 0u32;
    let mut node_idx = 0u32;
    let mut t0 = scene_t0;
    let mut t1 = scene_t1;
    let mut pushdown = true;
    stack.clear();
    while steps < max_steps {
        steps += 1;
        if node_idx >= n_nodes {
            return;
        }
        let node = tree.nodes[node_idx as usize];
        stats.node();
        if !node.is_leaf() {
            let k = node.axis();
            let p = node.split();
            let below = node.first_child();
            let above = below + 1;
            // The child the ray is in before the plane (A) and after it (B).
            let (a, b, t_split) = if inv[k].is_infinite() {
                // Parallel to the plane: the side of the origin (on the plane: below, which
                // holds every triangle touching the plane too).
                let c = if o[k] <= p { below } else { above };
                (c, c, f32::INFINITY)
            } else {
                let ts = (p - o[k]) * inv[k];
                if inv[k] > 0.0 {
                    (below, above, ts)
                } else {
                    (above, below, ts)
                }
            };
            if t_split >= t1 {
                node_idx = a;
            } else if t_split <= t0 {
                node_idx = b;
            } else {
                stack.push(Entry { node: b, t0: t_split, t1 });
                node_idx = a;
                t1 = t_split;
                pushdown = false;
            }
            if PUSHDOWN && pushdown {
                restart_node = node_idx;
            }
            continue;
        }
        stats.leaf();
        q.leaf(tree, node, &r, ray.t_min, stats);
        if q.done(t1) {
            return;
        }
        match stack.pop() {
            Some(e) => {
                node_idx = e.node;
                t0 = e.t0;
                t1 = e.t1;
            }
            None => {
                if !stack.dropped() || t1 >= scene_t1 {
                    return;
                }
                stats.restart();
                t0 = t1;
                t1 = scene_t1;
                node_idx = if PUSHDOWN { restart_node } else { 0 };
                pushdown = true;
                stack.clear();
            }
        }
    }
}

/// The algorithms by name. Short stacks of 1 to `MAX_SHORT_STACK` entries are instantiated.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Algorithm {
    Stack,
    Restart,
    PushDown,
    ShortStack(u32),
}

pub const MAX_SHORT_STACK: u32 = 8;

/// Runs `alg` for query `q` (short-stack sizes outside 1..=8 fall back to 8).
#[inline(always)]
pub fn run<Q: Query, S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, q: &mut Q, stats: &mut S) {
    match alg {
        Algorithm::Stack => traverse::<_, _, _, false>(tree, ray, q, &mut FullStack::new(), stats),
        Algorithm::Restart => traverse::<_, _, _, false>(tree, ray, q, &mut NoStack::new(), stats),
        Algorithm::PushDown => traverse::<_, _, _, true>(tree, ray, q, &mut NoStack::new(), stats),
        Algorithm::ShortStack(1) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<1>::new(), stats),
        Algorithm::ShortStack(2) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<2>::new(), stats),
        Algorithm::ShortStack(3) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<3>::new(), stats),
        Algorithm::ShortStack(4) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<4>::new(), stats),
        Algorithm::ShortStack(5) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<5>::new(), stats),
        Algorithm::ShortStack(6) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<6>::new(), stats),
        Algorithm::ShortStack(7) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<7>::new(), stats),
        Algorithm::ShortStack(_) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<8>::new(), stats),
    }
}

#[inline(always)]
pub fn closest_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> Hit {
    let mut q = Closest::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.hit
}

#[inline(always)]
pub fn any_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> bool {
    let mut q = AnyHit::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.found
}
