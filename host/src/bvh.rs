//! The compressed 8-wide BVH builder (Ylitie, Karras & Laine 2017), traversed by
//! `kdray_shared::bvh` on CPU and GPU.
//!
//! 1. A binary BVH by binned SAH (`BINS` bins per axis, all three binned in one pass, leaves of
//!    at most three triangles, subtrees built in parallel, and the bounds and bins of nodes
//!    above `PARALLEL_PASS` triangles too). Object-median splits take over where the SAH finds no split
//!    or where the depth left would not suffice, so the tree is never deeper than
//!    `MAX_BVH_DEPTH`.
//! 2. Collapse to eight wide: a node's children are its binary children, then repeatedly the
//!    interior child of largest surface area is replaced by its two children until there are
//!    eight or only leaves.
//! 3. Each wide node encoded by `kdray_shared::bvh::build` (`assign_slots`, `encode_node`),
//!    the rules the kernels' own build (`crate::lbvh`) encodes its nodes by too: slots by
//!    octant (the child lying first along octant o's diagonal goes to slot o, greedily over all
//!    (child, slot) costs, so the traversal's `slot ^ (7 − octant)` order is roughly front to
//!    back), and per node and axis a power-of-two step and an origin on which every child's
//!    box is rounded outwards, every grid value exact in `f32` (`quantise_axis`; the `f64`
//!    rule it replaced is its test's oracle).
//!
//! Nodes are laid out breadth first (children after their parent, a node's child nodes
//! contiguous in slot order); leaf triangles are copied in the same order with their scene
//! index in `Triangle::_pad`.
use crate::error::{bail, Result};
use kdray_shared::bvh::build::{self, SlotChild};
use kdray_shared::bvh::{meta_is_node, BvhNode, BVH_WIDTH, MAX_BVH_DEPTH, MAX_LEAF_TRIS};
use kdray_shared::Triangle;
use rayon::prelude::*;
use std::collections::VecDeque;

/// SAH bins per axis.
const BINS: usize = 16;
/// Relative cost of visiting a node (a triangle test costs 1).
const NODE_COST: f64 = 1.0;
/// Triangles above which subtrees are built in parallel.
const PARALLEL: usize = 4096;
/// Triangles above which a node's bounds and bins are computed in parallel (the upper levels,
/// which have fewer subtrees than threads).
const PARALLEL_PASS: usize = 1 << 16;

/// A built BVH: what `Tracer::with_bvh` uploads.
#[derive(Clone, Debug)]
pub struct BvhData {
    /// The nodes; `nodes[0]` is the root.
    pub nodes: Vec<BvhNode>,
    /// The scene's triangles in leaf order, each with its scene index in `_pad`.
    pub tris: Vec<Triangle>,
    /// Levels of nodes (the root alone: 1).
    pub depth: usize,
    /// Leaf children (of at most three triangles each).
    pub leaves: usize,
    /// SAH cost of the binary tree (node visits cost `NODE_COST`, triangle tests 1).
    pub sah_cost: f64,
}

#[derive(Copy, Clone, Debug)]
struct Bounds {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Bounds {
    const EMPTY: Bounds = Bounds { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3] };
    fn grow(&mut self, b: &Bounds) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(b.lo[a]);
            self.hi[a] = self.hi[a].max(b.hi[a]);
        }
    }
    fn grow_point(&mut self, p: [f32; 3]) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(p[a]);
            self.hi[a] = self.hi[a].max(p[a]);
        }
    }
    /// Surface area, in f64 (f32 overflows from coordinates of ~1e19 on).
    fn area(&self) -> f64 {
        surface_area(self.lo, self.hi)
    }
    fn centroid(&self) -> [f32; 3] {
        [0.5 * (self.lo[0] + self.hi[0]), 0.5 * (self.lo[1] + self.hi[1]), 0.5 * (self.lo[2] + self.hi[2])]
    }
}

/// Surface area of the box [`lo`, `hi`] in f64 (f32 overflows from coordinates of ~1e19 on), 0
/// for an empty box: the SAH cost's measure, of this builder's trees and the kernels' (`crate::lbvh`).
pub(crate) fn surface_area(lo: [f32; 3], hi: [f32; 3]) -> f64 {
    if lo[0] > hi[0] {
        return 0.0;
    }
    let d = [(hi[0] - lo[0]) as f64, (hi[1] - lo[1]) as f64, (hi[2] - lo[2]) as f64];
    2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

/// A binary BVH node: a leaf holds `prims[first..first + count]`.
enum Node2 {
    Leaf { b: Bounds, first: usize, count: usize },
    Inner { b: Bounds, kids: Box<[Node2; 2]> },
}

impl Node2 {
    fn bounds(&self) -> &Bounds {
        match self {
            Node2::Leaf { b, .. } | Node2::Inner { b, .. } => b,
        }
    }
}

struct Input<'a> {
    boxes: &'a [Bounds],
    centroids: &'a [[f32; 3]],
}

/// Builds the binary tree over `prims` (their offset in the whole index list is `offset`).
fn build2(inp: &Input, prims: &mut [u32], offset: usize, depth: usize, cost: &mut f64) -> Node2 {
    let n = prims.len();
    let (b, cb) = node_bounds(inp, prims);
    let leaf = |cost: &mut f64| {
        *cost += b.area() * n as f64;
        Node2::Leaf { b, first: offset, count: n }
    };
    // Levels a balanced split of the rest would still need: past the depth that leaves,
    // object medians take over so the tree stays within `MAX_BVH_DEPTH`.
    let levels_left = usize::BITS as usize - (n.div_ceil(MAX_LEAF_TRIS)).leading_zeros() as usize + 1;
    let must_balance = depth + levels_left + 1 >= MAX_BVH_DEPTH;
    if n <= 1 || (must_balance && n <= MAX_LEAF_TRIS) {
        return leaf(cost);
    }
    let split = if must_balance { None } else { sah_split(inp, prims, &b, &cb) };
    let mid = match split {
        Some((axis, bin, split_cost)) => {
            if n <= MAX_LEAF_TRIS && split_cost >= n as f64 {
                return leaf(cost);
            }
            let (k, e) = (cb.lo[axis], cb.hi[axis] - cb.lo[axis]);
            let mut i = 0;
            for j in 0..n {
                if bin_of(inp.centroids[prims[j] as usize][axis], k, e) <= bin {
                    prims.swap(i, j);
                    i += 1;
                }
            }
            if i == 0 || i == n {
                median(inp, prims, &cb)
            } else {
                i
            }
        }
        // Every centroid at one point, or the depth left demands balance.
        None if n <= MAX_LEAF_TRIS => return leaf(cost),
        None => median(inp, prims, &cb),
    };
    *cost += b.area() * NODE_COST;
    let (l, r) = prims.split_at_mut(mid);
    let (mut cl, mut cr) = (0.0, 0.0);
    let (a, c) = if n > PARALLEL {
        rayon::join(|| build2(inp, l, offset, depth + 1, &mut cl), || build2(inp, r, offset + mid, depth + 1, &mut cr))
    } else {
        (build2(inp, l, offset, depth + 1, &mut cl), build2(inp, r, offset + mid, depth + 1, &mut cr))
    };
    *cost += cl + cr;
    Node2::Inner { b, kids: Box::new([a, c]) }
}

/// The bounds of `prims`' boxes and of their centroids; in parallel above `PARALLEL_PASS`
/// (the same bounds: minima and maxima in any order).
fn node_bounds(inp: &Input, prims: &[u32]) -> (Bounds, Bounds) {
    let pass = |prims: &[u32]| {
        let (mut b, mut cb) = (Bounds::EMPTY, Bounds::EMPTY);
        for &p in prims {
            b.grow(&inp.boxes[p as usize]);
            cb.grow_point(inp.centroids[p as usize]);
        }
        (b, cb)
    };
    if prims.len() <= PARALLEL_PASS {
        return pass(prims);
    }
    prims.par_chunks(PARALLEL_PASS / 4).map(pass).reduce(
        || (Bounds::EMPTY, Bounds::EMPTY),
        |(mut b, mut cb), (b2, cb2)| {
            b.grow(&b2);
            cb.grow(&cb2);
            (b, cb)
        },
    )
}

/// Per axis, the primitives counted into `BINS` bins by centroid and the bins' bounds.
#[derive(Copy, Clone)]
struct Bins {
    count: [[usize; BINS]; 3],
    boxes: [[Bounds; BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins { count: [[0; BINS]; 3], boxes: [[Bounds::EMPTY; BINS]; 3] };

    /// `prims` binned along every axis of positive centroid extent, in one pass over them.
    fn of(inp: &Input, prims: &[u32], cb: &Bounds) -> Bins {
        let e = [cb.hi[0] - cb.lo[0], cb.hi[1] - cb.lo[1], cb.hi[2] - cb.lo[2]];
        let mut bins = Bins::EMPTY;
        for &p in prims {
            let (c, b) = (inp.centroids[p as usize], &inp.boxes[p as usize]);
            for axis in 0..3 {
                if e[axis] > 0.0 {
                    let k = bin_of(c[axis], cb.lo[axis], e[axis]);
                    bins.count[axis][k] += 1;
                    bins.boxes[axis][k].grow(b);
                }
            }
        }
        bins
    }

    /// `of`, in parallel above `PARALLEL_PASS` (the same bins: counts and bounds merged).
    fn par_of(inp: &Input, prims: &[u32], cb: &Bounds) -> Bins {
        if prims.len() <= PARALLEL_PASS {
            return Bins::of(inp, prims, cb);
        }
        prims.par_chunks(PARALLEL_PASS / 4).map(|ch| Bins::of(inp, ch, cb)).reduce(
            || Bins::EMPTY,
            |mut a, b| {
                for axis in 0..3 {
                    for k in 0..BINS {
                        a.count[axis][k] += b.count[axis][k];
                        a.boxes[axis][k].grow(&b.boxes[axis][k]);
                    }
                }
                a
            },
        )
    }
}

fn bin_of(c: f32, lo: f32, extent: f32) -> usize {
    (((c - lo) / extent * BINS as f32) as usize).min(BINS - 1)
}

/// The best binned SAH split: axis, last bin of the left side, and cost relative to the node's
/// area (in triangle tests). `None` if every centroid is the same point.
fn sah_split(inp: &Input, prims: &[u32], b: &Bounds, cb: &Bounds) -> Option<(usize, usize, f64)> {
    let mut best: Option<(usize, usize, f64)> = None;
    let parent = b.area().max(f64::MIN_POSITIVE);
    let bins = Bins::par_of(inp, prims, cb);
    for axis in 0..3 {
        let e = cb.hi[axis] - cb.lo[axis];
        if !(e > 0.0) {
            continue;
        }
        let (count, boxes) = (&bins.count[axis], &bins.boxes[axis]);
        let mut right_area = [0.0f64; BINS];
        let mut right_count = [0usize; BINS];
        let (mut rb, mut rc) = (Bounds::EMPTY, 0);
        for k in (1..BINS).rev() {
            rb.grow(&boxes[k]);
            rc += count[k];
            right_area[k] = rb.area();
            right_count[k] = rc;
        }
        let (mut lb, mut lc) = (Bounds::EMPTY, 0);
        for k in 0..BINS - 1 {
            lb.grow(&boxes[k]);
            lc += count[k];
            let rc = right_count[k + 1];
            if lc == 0 || rc == 0 {
                continue;
            }
            let c = NODE_COST + (lb.area() * lc as f64 + right_area[k + 1] * rc as f64) / parent;
            if best.is_none_or(|(_, _, bc)| c < bc) {
                best = Some((axis, k, c));
            }
        }
    }
    best
}

/// Splits `prims` at its median along the centroids' longest axis; returns the split index.
fn median(inp: &Input, prims: &mut [u32], cb: &Bounds) -> usize {
    let d = [cb.hi[0] - cb.lo[0], cb.hi[1] - cb.lo[1], cb.hi[2] - cb.lo[2]];
    let axis = if d[0] >= d[1] && d[0] >= d[2] { 0 } else if d[1] >= d[2] { 1 } else { 2 };
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |&a, &b| inp.centroids[a as usize][axis].total_cmp(&inp.centroids[b as usize][axis]));
    mid
}

/// The (up to eight) children of a wide node made from `n`.
/// A wide node's children (at most `BVH_WIDTH`), in a fixed array (no allocation per node).
struct Kids<'a> {
    k: [Option<&'a Node2>; BVH_WIDTH],
    len: usize,
}

impl<'a> Kids<'a> {
    fn get(&self, i: usize) -> &'a Node2 {
        self.k[i].expect("a child below len")
    }
    fn push(&mut self, n: &'a Node2) {
        self.k[self.len] = Some(n);
        self.len += 1;
    }
    /// Removes child `i`, moving the last into its place (`Vec::swap_remove`).
    fn swap_remove(&mut self, i: usize) -> &'a Node2 {
        let n = self.get(i);
        self.k[i] = self.k[self.len - 1];
        self.k[self.len - 1] = None;
        self.len -= 1;
        n
    }
}

fn wide_children(n: &Node2) -> Kids<'_> {
    let mut kids = Kids { k: [None; BVH_WIDTH], len: 0 };
    match n {
        Node2::Leaf { .. } => kids.push(n),
        Node2::Inner { kids: two, .. } => {
            kids.push(&two[0]);
            kids.push(&two[1]);
        }
    }
    while kids.len < BVH_WIDTH {
        let pick = (0..kids.len)
            .map(|i| (i, kids.get(i)))
            .filter(|(_, k)| matches!(k, Node2::Inner { .. }))
            .max_by(|a, b| a.1.bounds().area().total_cmp(&b.1.bounds().area()))
            .map(|(i, _)| i);
        let Some(i) = pick else { break };
        let Node2::Inner { kids: grand, .. } = kids.swap_remove(i) else { unreachable!() };
        kids.push(&grand[0]);
        kids.push(&grand[1]);
    }
    kids
}
/// The slots of `kids` (`build::assign_slots`).
fn assign_slots<'a>(parent: &Bounds, kids: &Kids<'a>) -> [Option<&'a Node2>; BVH_WIDTH] {
    let mut centres = [[0.0f32; 3]; BVH_WIDTH];
    for (i, c) in centres.iter_mut().enumerate().take(kids.len) {
        *c = kids.get(i).bounds().centroid();
    }
    build::assign_slots(parent.centroid(), &centres, kids.len).map(|k| (k != build::NO_CHILD).then(|| kids.get(k as usize)))
}

/// Builds the compressed 8-wide BVH over `tris`.
pub fn build(tris: &[Triangle]) -> BvhData {
    try_build(tris).expect("BVH build")
}

/// Builds the compressed 8-wide BVH over `tris`; fails on a vertex that is not finite,
/// coordinates too large to quantise, or more triangles or nodes than 32-bit indices can hold.
pub fn try_build(tris: &[Triangle]) -> Result<BvhData> {
    if tris.len() >= (1usize << 31) {
        bail!(TooLarge: "{} triangles: the BVH indexes at most 2^31", tris.len());
    }
    if let Some(i) = tris.iter().position(|t| [t.v0, t.v1, t.v2].iter().flatten().any(|c| !c.is_finite())) {
        bail!(InvalidInput: "triangle {i} has a vertex that is not a finite number");
    }
    let boxes: Vec<Bounds> = tris
        .iter()
        .map(|t| {
            let mut b = Bounds::EMPTY;
            for v in [t.v0, t.v1, t.v2] {
                b.grow_point(v);
            }
            b
        })
        .collect();
    let centroids: Vec<[f32; 3]> = boxes.iter().map(Bounds::centroid).collect();
    if tris.is_empty() {
        return Ok(BvhData { nodes: vec![BvhNode::default()], tris: Vec::new(), depth: 1, leaves: 0, sah_cost: 0.0 });
    }
    let mut prims: Vec<u32> = (0..tris.len() as u32).collect();
    let mut cost = 0.0;
    let root = build2(&Input { boxes: &boxes, centroids: &centroids }, &mut prims, 0, 0, &mut cost);
    let root_area = root.bounds().area().max(f64::MIN_POSITIVE);

    let mut nodes = vec![BvhNode::default()];
    let mut out_tris: Vec<Triangle> = Vec::with_capacity(tris.len());
    let mut queue: VecDeque<(usize, &Node2, usize)> = VecDeque::from([(0, &root, 1)]);
    let (mut depth, mut leaves) = (1, 0);
    while let Some((index, n, level)) = queue.pop_front() {
        depth = depth.max(level);
        let pb = *n.bounds();
        let slots = assign_slots(&pb, &wide_children(n));
        let child_base = nodes.len();
        let tri_base = out_tris.len();
        let mut out = [SlotChild::default(); BVH_WIDTH];
        for (s, k) in slots.iter().enumerate() {
            let Some(k) = k else { continue };
            let b = k.bounds();
            out[s] = SlotChild { lo: b.lo, hi: b.hi, meta: 0 };
            match k {
                Node2::Inner { .. } => {
                    out[s].meta = build::node_meta(s as u32);
                    nodes.push(BvhNode::default());
                    queue.push_back((nodes.len() - 1, k, level + 1));
                }
                Node2::Leaf { first, count, .. } => {
                    out[s].meta = build::leaf_meta(*count as u32, (out_tris.len() - tri_base) as u32);
                    for &p in &prims[*first..first + count] {
                        out_tris.push(Triangle { _pad: p, ..tris[p as usize] });
                    }
                    leaves += 1;
                }
            }
        }
        if nodes.len() > u32::MAX as usize / 2 {
            bail!(TooLarge: "the BVH needs more than 2^31 nodes");
        }
        let Some(node) = build::encode_node(pb.lo, pb.hi, &out, child_base as u32, tri_base as u32) else {
            bail!(TooLarge: "a BVH node spans [{:?}, {:?}], too large to quantise", pb.lo, pb.hi)
        };
        nodes[index] = node;
    }
    if depth > MAX_BVH_DEPTH {
        bail!(TooLarge: "the BVH is {depth} levels deep (at most {MAX_BVH_DEPTH})");
    }
    Ok(BvhData { nodes, tris: out_tris, depth, leaves, sah_cost: cost / root_area })
}

impl BvhData {
    /// Checks what the kernels rely on for a scene of `scene_tris` triangles: every child node
    /// after its parent, in range and with one parent; every leaf's triangles in range and
    /// every triangle in exactly one leaf; every scene index named once; grid steps whose
    /// exponents the builder can produce (2^-100 to 2^119), each at most twice the root's, and
    /// origins within 512 root steps of the root's (the traversal's `tame` bound); depth ≤
    /// `MAX_BVH_DEPTH`. (Whether
    /// boxes enclose their triangles is the builder's to guarantee: `tests/bvh.rs` checks it.)
    pub fn validate(&self, scene_tris: usize) -> Result<()> {
        let n = self.nodes.len();
        if n == 0 {
            bail!(InvalidInput: "a BVH without a root node");
        }
        if self.tris.len() != scene_tris {
            bail!(InvalidInput: "the BVH holds {} triangles, the scene {scene_tris}", self.tris.len());
        }
        let mut seen = vec![false; scene_tris];
        for t in &self.tris {
            let p = t._pad as usize;
            if p >= scene_tris || std::mem::replace(&mut seen[p], true) {
                bail!(InvalidInput: "the BVH does not belong to this scene: it names triangle {p} of {scene_tris} (or twice)");
            }
        }
        let mut level = vec![0usize; n];
        level[0] = 1;
        let (root_o, root_st) = (self.nodes[0].origin(), self.nodes[0].steps());
        let mut in_leaf = vec![false; self.tris.len()];
        for (i, node) in self.nodes.iter().enumerate() {
            let e = node.origin_exp.w;
            if node.origin_exp.w & 0x00ff_ffff != 0 && (0..3).any(|a| !(27..=246).contains(&((e >> (8 * a)) & 0xff))) {
                bail!(InvalidInput: "BVH node {i}: a grid step outside 2^-100..2^119");
            }
            // `BoxRay::tame`'s bound holds for every node: steps at most twice the root's,
            // origins within 512 root steps of the root's.
            // Written so that a NaN or infinite origin fails too.
            let (o, st) = (node.origin(), node.steps());
            let within = |a: usize| o[a].is_finite() && st[a] as f64 <= 2.0 * root_st[a] as f64 && (o[a] as f64 - root_o[a] as f64).abs() <= 512.0 * root_st[a] as f64;
            if !(within(0) && within(1) && within(2)) {
                bail!(InvalidInput: "BVH node {i}: a grid beyond the root's reach");
            }
            let inner = node.imask().count_ones() as usize;
            let base = node.child_base() as usize;
            if inner > 0 && (base <= i || base + inner > n) {
                bail!(InvalidInput: "BVH node {i}: child nodes {base}..{} out of order or range", base + inner);
            }
            let mut covered = 0u32;
            for s in 0..BVH_WIDTH as u32 {
                let m = node.meta(s);
                let is_node = node.imask() >> s & 1 != 0;
                if m == 0 {
                    if is_node {
                        bail!(InvalidInput: "BVH node {i}: slot {s} is empty but marked a node");
                    }
                    continue;
                }
                if meta_is_node(m) != is_node || (is_node && m != 0b001_00000 | (24 + s)) {
                    bail!(InvalidInput: "BVH node {i}: slot {s}'s meta byte {m:#x} disagrees with the node mask");
                }
                if !is_node {
                    let count = match m >> 5 {
                        0b001 => 1,
                        0b011 => 2,
                        0b111 => 3,
                        _ => bail!(InvalidInput: "BVH node {i}: slot {s}'s triangle count {:#b} is not unary", m >> 5),
                    };
                    let off = m & 0x1f;
                    let bits = ((1u32 << count) - 1) << off;
                    if off + count > 24 || node.tri_base() as usize + (off + count) as usize > self.tris.len() || covered & bits != 0 {
                        bail!(InvalidInput: "BVH node {i}: slot {s}'s triangles out of range or shared");
                    }
                    covered |= bits;
                    for k in node.tri_base() as usize + off as usize..node.tri_base() as usize + (off + count) as usize {
                        if std::mem::replace(&mut in_leaf[k], true) {
                            bail!(InvalidInput: "BVH triangle {k} lies in two leaves");
                        }
                    }
                }
            }
            let mut k = 0;
            for s in 0..BVH_WIDTH as u32 {
                if node.imask() >> s & 1 != 0 {
                    let c = base + k;
                    k += 1;
                    if level[c] != 0 {
                        bail!(InvalidInput: "BVH node {c} has two parents");
                    }
                    level[c] = level[i] + 1;
                    if level[c] > MAX_BVH_DEPTH {
                        bail!(InvalidInput: "the BVH is deeper than {MAX_BVH_DEPTH} levels");
                    }
                }
            }
        }
        if let Some(k) = in_leaf.iter().position(|c| !c) {
            bail!(InvalidInput: "BVH triangle {k} lies in no leaf");
        }
        Ok(())
    }

    /// Bytes of the nodes and leaf triangles together.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.nodes[..]) + std::mem::size_of_val(&self.tris[..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `build::quantise_axis` as the old tests called it.
    fn quantise_axis(lo: f32, hi: f32, kids: &[(f32, f32)]) -> Option<(i32, f32, [(u32, u32); BVH_WIDTH])> {
        let mut k = [(0.0, 0.0); BVH_WIDTH];
        k[..kids.len()].copy_from_slice(kids);
        let g = build::quantise_axis(lo, hi, &k, kids.len())?;
        Some((g.exp, g.origin, g.q.map(|[a, b]| (a, b))))
    }

    /// The grid rule in `f64` (the builder's until the rule moved into `kdray_shared` in `f32`
    /// and integers): the oracle `quantise_axis` must equal.
    fn reference_quantise(lo: f32, hi: f32, kids: &[(f32, f32)]) -> Option<(i32, f32, [(u32, u32); BVH_WIDTH])> {
        let extent = (hi as f64 - lo as f64).max(0.0);
        let max_abs = lo.abs().max(hi.abs()) as f64;
        // Steps from 2^-100 (no subnormal coordinate anywhere) to 2^119 (255 steps stay finite).
        let mut e = if extent > 0.0 { (extent / 255.0).log2().ceil() as i32 } else { -100 };
        if max_abs > 0.0 {
            // Every grid value must be an f32 multiple of a power of two no coarser than the step.
            e = e.max(max_abs.log2().floor() as i32 + 1 - 23);
        }
        e = e.max(-100);
        while e <= 119 {
            let s = (e as f64).exp2();
            // The origin: `lo` rounded down to a multiple of 2^f, the finest power of two (at most
            // the step) whose multiples below 2^(f + 24) in magnitude, every grid value
            // origin + q·step among them, are all f32. The finer it is, the closer the origin lies
            // to `lo`: a child whose box is flat at the node's lower bound is then flat on the grid
            // too, not one step thick.
            let reach = lo.abs() as f64 + 256.0 * s;
            let f = e.min(reach.log2().floor() as i32 - 23).max(-100);
            let q0 = (f as f64).exp2();
            let k = (lo as f64 / q0).floor();
            if k.abs() * q0 + 255.0 * s < (f as f64 + 24.0).exp2() {
                let origin = (k * q0) as f32;
                let s32 = s as f32;
                let at = |q: u32| origin + s32 * q as f32;
                let mut qs = [(0u32, 0u32); BVH_WIDTH];
                let mut fits = true;
                for (j, &(cl, ch)) in kids.iter().enumerate() {
                    let mut ql = ((cl as f64 - k * q0) / s).floor().max(0.0) as u32;
                    let mut qh = ((ch as f64 - k * q0) / s).ceil().max(0.0) as u32;
                    // As the kernels compute the coordinates: exact, and around the child's box.
                    while ql > 0 && at(ql) > cl {
                        ql -= 1;
                    }
                    while qh <= 255 && at(qh) < ch {
                        qh += 1;
                    }
                    // Every stored coordinate finite too (a box up against f32::MAX may round past it).
                    if qh > 255 || at(ql) > cl || !at(ql).is_finite() || !at(qh).is_finite() {
                        fits = false;
                        break;
                    }
                    qs[j] = (ql, qh);
                }
                if fits {
                    return Some((e, origin, qs));
                }
            }
            e += 1;
        }
        None
    }

    /// The shared rule in `f32` and integers (what the GPU build runs) gives the grids of the
    /// `f64` rule exactly: random nodes from 2^-127 to 2^128 in magnitude, either sign, flat,
    /// thin and wide, with children anywhere inside, at powers of two and next to them.
    #[test]
    fn the_shared_grid_rule_is_the_f64_rule() {
        // Compared bit for bit (an origin of −0 is not one of +0).
        let bits = |g: Option<(i32, f32, [(u32, u32); BVH_WIDTH])>| g.map(|(e, o, q)| (e, o.to_bits(), q));
        let mut rng = kdray_shared::rng::Rng::new(11, 0);
        let mut next = move || rng.next_u32();
        let (mut some, mut none) = (0, 0);
        for i in 0..400_000u32 {
            let r = next();
            let mag = ((r % 255) as i32 - 127) as f32;
            let unit = |r: u32| (r >> 8) as f32 / (1u32 << 24) as f32;
            let sign = if r >> 31 == 0 { 1.0 } else { -1.0 };
            let mut lo = sign * mag.exp2() * (1.0 + unit(next()));
            if i % 7 == 0 {
                lo = sign * mag.exp2(); // a power of two
            } else if i % 7 == 1 {
                lo = f32::from_bits((sign * mag.exp2()).to_bits().wrapping_sub(1)); // just below one
            } else if i % 11 == 2 {
                lo = 0.0;
            }
            let width = match i % 5 {
                0 => 0.0,
                1 => lo.abs() * 1e-6 * unit(next()),
                2 => ((mag + (next() % 40) as f32 - 20.0).exp2()) * unit(next()),
                3 => lo.abs() * 4.0 * unit(next()),
                _ => ((next() % 250) as f32 - 125.0).exp2(),
            };
            let hi = lo + width;
            if !lo.is_finite() || !hi.is_finite() || hi < lo {
                continue;
            }
            let n = 1 + (next() % 8) as usize;
            let mut kids = [(lo, hi); BVH_WIDTH];
            for k in kids.iter_mut().take(n).skip(2) {
                let (a, b) = (lo + (hi - lo) * unit(next()), lo + (hi - lo) * unit(next()));
                *k = (a.min(b).max(lo), a.max(b).min(hi));
            }
            if n >= 2 {
                kids[0] = (lo, lo + (hi - lo) * unit(next()));
                kids[1] = (lo + (hi - lo) * unit(next()), hi);
                kids[1].0 = kids[1].0.min(hi);
            }
            let got = quantise_axis(lo, hi, &kids[..n]);
            let want = reference_quantise(lo, hi, &kids[..n]);
            assert_eq!(bits(got), bits(want), "case {i}: [{lo:e}, {hi:e}] {:?}", &kids[..n]);
            if got.is_some() { some += 1 } else { none += 1 }
        }
        // Where the finest power of two changes: |lo| + 2^(e + 8) at, just below and just above
        // a power of two, for a node whose step is 2^e.
        for e in -90..100 {
            for g in 1..26 {
                let a = (e as f32 + 8.0 + g as f32).exp2() - (e as f32 + 8.0).exp2();
                for lo in [a, f32::from_bits(a.to_bits() - 1), f32::from_bits(a.to_bits() + 1)].into_iter().flat_map(|a| [a, -a]) {
                    let hi = lo + 0.9 * 255.0 * (e as f32).exp2();
                    if !lo.is_finite() || !hi.is_finite() {
                        continue;
                    }
                    let kids = [(lo, lo + 0.3 * (hi - lo)), (lo + 0.5 * (hi - lo), hi)];
                    assert_eq!(bits(quantise_axis(lo, hi, &kids)), bits(reference_quantise(lo, hi, &kids)), "[{lo:e}, {hi:e}]");
                    some += 1;
                }
            }
        }
        // Signed zeros (the origin is −0 for a bound of −0, as in f64).
        for (lo, hi) in [(-0.0f32, 1.0f32), (0.0, 1.0), (-0.0, 0.0), (-0.0, -0.0), (0.0, 3e-38)] {
            let kids = [(lo, hi), (lo, hi)];
            assert_eq!(bits(quantise_axis(lo, hi, &kids)), bits(reference_quantise(lo, hi, &kids)), "[{lo:e}, {hi:e}]");
        }
        assert!(some > 300_000 && none > 20, "{some} quantised, {none} not");
    }

    /// Grids are exact in `f32` and enclose their children, the origin lies within a step below
    /// the node's lower bound, and a child flat at that bound is flat on the grid wherever the
    /// bound is a multiple of the grid's power of two: for nodes away from zero (most nodes of a
    /// scene), nearly always (a multiple of the step, the old origin, almost never is).
    #[test]
    fn grids_are_exact_and_flat_at_the_lower_bound() {
        let mut rng = kdray_shared::rng::Rng::new(3, 0);
        let mut next = move || rng.next_u32();
        let (mut far, mut thin) = (0u32, 0u32);
        for i in 0..20_000 {
            let scale = [1e-3f32, 1.0, 300.0, 1e5][i % 4];
            let unit = |r: u32| (r % 10_001) as f32 / 10_000.0;
            let lo = (unit(next()) * 2.0 - 1.0) * scale * 100.0;
            let hi = lo + (unit(next()) + 1e-4) * scale;
            let mut kids = [(lo, lo); 5];
            kids[1] = (hi, hi);
            for k in &mut kids[2..] {
                let (a, b) = (lo + (hi - lo) * unit(next()), lo + (hi - lo) * unit(next()));
                *k = (a.min(b).max(lo), a.max(b).min(hi));
            }
            let (e, origin, qs) = quantise_axis(lo, hi, &kids).unwrap();
            let s = (e as f32).exp2();
            for (&(cl, ch), &(ql, qh)) in kids.iter().zip(&qs) {
                for q in [ql, qh] {
                    assert_eq!((origin + s * q as f32) as f64, origin as f64 + s as f64 * q as f64, "case {i}: grid value {q} not exact");
                }
                assert!(origin + s * ql as f32 <= cl && origin + s * qh as f32 >= ch, "case {i}: a child outside its box");
            }
            assert!(origin <= lo && (lo as f64) < origin as f64 + s as f64, "case {i}: origin {origin} for {lo}");
            if origin == lo {
                assert_eq!(qs[0], (0, 0), "case {i}");
            }
            if lo.abs() > 512.0 * s {
                far += 1;
                thin += (qs[0] == (0, 0)) as u32;
            }
        }
        assert!(far > 5_000 && thin as f64 > 0.95 * far as f64, "{thin} of {far} flat children thin");
    }
}
