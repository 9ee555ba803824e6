//! O(N log N) SAH kd-tree construction (Wald & Havran 2006): per-axis event lists sorted once,
//! a sweep per node that evaluates every candidate plane exactly, "perfect splits" (triangles
//! straddling a plane are clipped to each child and only their new events are sorted and merged),
//! and an empty-space bonus.
//!
//! One deliberate refinement: a split plane never passes through a vertex. Candidate planes lie
//! strictly between consecutive event positions — halfway between two, or, for a cut that
//! separates empty space, 1/64 of the empty gap away from the geometry — so each plane splits
//! the same triangle sets as one of Wald & Havran's planes (a flat triangle goes to the side of
//! the gap chosen) while every triangle lies strictly on one side of it or straddles it and is
//! clipped into both children. A point on a plane then belongs only to straddling triangles,
//! and a ray meeting a plane exactly at an end of its interval (starting on a flat wall, lying
//! in the plane, ending on it, passing through a cell corner) finds its hit in whichever child
//! it visits. Cells may be thinner than the rounding of a ray's t at their planes (any ray from
//! far enough away sees them so): the traversals resolve that (the rules in `kdray_shared::kdtree`, `plane_band`); planes
//! stay out of gaps narrower than 2^-18 of the scene's extent (`MIN_GAP`) for speed only.
use super::clip::{clipped_bounds, overlap, tri_bounds, Bounds};
use crate::error::{bail, Result};
use kdray_shared::aabb::Aabb;
use kdray_shared::kdtree::{KdNode, KdTree, MAX_DEPTH};
use kdray_shared::parts::Parts;
use kdray_shared::Triangle;
use std::time::Instant;

/// The SAH cost model and limits of a build; `Default` gives K_T = 15, K_I = 20, λ = 0.8.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// Cost of a traversal step (K_T).
    pub k_t: f32,
    /// Cost of a triangle test (K_I).
    pub k_i: f32,
    /// Cost factor of a split that cuts off empty space (λ, Wald & Havran use 0.8).
    pub empty_bonus: f32,
    /// Maximum depth; default 8 + 1.3·log2 N (below `MAX_DEPTH`).
    pub max_depth: Option<u32>,
    /// Nodes with at most this many triangles become leaves without evaluating splits.
    pub leaf_size: usize,
    /// Nodes with more triangles than this build their children in parallel.
    pub parallel_threshold: usize,
    /// Most triangle references in the leaves per triangle (at least 1): splits that clip
    /// triangles into both children duplicate references, and a scene of large overlapping
    /// triangles (a soup) would otherwise multiply the tree's memory and build time. Each node
    /// gets a share of the budget in proportion to its children's triangles and takes only the
    /// splits that fit, so the whole tree holds at most this many references per triangle.
    pub max_duplication: f32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions { k_t: 15.0, k_i: 20.0, empty_bonus: 0.8, max_depth: None, leaf_size: 1, parallel_threshold: 8192, max_duplication: DEFAULT_MAX_DUPLICATION }
    }
}

/// `BuildOptions::max_duplication` by default.
pub const DEFAULT_MAX_DUPLICATION: f32 = 32.0;

/// What the build produced, for reports.
#[derive(Clone, Debug, Default)]
pub struct TreeStats {
    /// Triangles the tree was built over.
    pub triangles: usize,
    /// Nodes, interior and leaf.
    pub nodes: usize,
    /// Leaves, empty ones included.
    pub leaves: usize,
    /// Leaves with no triangle.
    pub empty_leaves: usize,
    /// Triangle references in leaves / non-empty leaves.
    pub avg_leaf_size: f64,
    /// Triangle references in all leaves (the primitive index list's length); over
    /// `triangles` it is the reference duplication, bounded by `BuildOptions::max_duplication`.
    pub references: usize,
    /// Depth of the deepest node (the root is at depth 0).
    pub max_depth: u32,
    /// The depth limit the build used: `BuildOptions::max_depth` or its default, below `MAX_DEPTH`.
    pub depth_limit: u32,
    /// Expected cost under the SAH model, relative to the root's surface area.
    pub sah_cost: f64,
    /// Size of the node and primitive index arrays, in bytes.
    pub bytes: usize,
    /// Wall-clock time of the build, in seconds.
    pub build_seconds: f64,
}

/// A built tree: the buffers the traversals read.
#[derive(Clone, Debug)]
pub struct KdTreeData {
    /// The nodes, root first; an interior node's two children are adjacent.
    pub nodes: Vec<KdNode>,
    /// Triangle indices, each leaf's a contiguous run (`KdNode::leaf`'s offset and count).
    pub prims: Vec<u32>,
    /// The root cell: the box around every triangle.
    pub bounds: Aabb,
    /// Sizes and cost of the tree, for reports.
    pub stats: TreeStats,
}

impl KdTreeData {
    /// The tree as the traversals read it, over `tris`: the triangles it was built from.
    pub fn view<'a>(&'a self, tris: &'a [Triangle]) -> KdTree<'a> {
        KdTree { nodes: Parts::one(&self.nodes), prims: Parts::one(&self.prims), tris: Parts::one(tris), bounds: self.bounds }
    }
}

#[derive(Copy, Clone, Debug)]
struct Event {
    pos: f32,
    /// 0 = end, 1 = planar, 2 = start: the sweep order at equal positions.
    kind: u8,
    tri: u32,
}

/// Where an empty-space cut goes, as a fraction of the empty gap measured from the geometry.
const EMPTY_MARGIN: f32 = 1.0 / 64.0;

const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

fn sort_events(e: &mut [Event]) {
    e.sort_unstable_by(|a, b| a.pos.total_cmp(&b.pos).then(a.kind.cmp(&b.kind)));
}

fn push_events(ev: &mut [Vec<Event>; 3], b: &Bounds, tri: u32) {
    for (k, e) in ev.iter_mut().enumerate() {
        push_axis_events(e, b, k, tri);
    }
}

fn push_axis_events(ev: &mut Vec<Event>, b: &Bounds, k: usize, tri: u32) {
    if b.0[k] == b.1[k] {
        ev.push(Event { pos: b.0[k], kind: PLANAR, tri });
    } else {
        ev.push(Event { pos: b.0[k], kind: START, tri });
        ev.push(Event { pos: b.1[k], kind: END, tri });
    }
}

/// A node's work: triangles (global ids), their clipped bounds, and the sorted events of
/// each axis (events refer to positions in `tris`).
struct Work {
    tris: Vec<u32>,
    bounds: Vec<Bounds>,
    events: [Vec<Event>; 3],
    cell: Bounds,
    depth: u32,
    /// Most references this node's subtree may hold (its share of `max_duplication`; at least
    /// `tris.len()`).
    budget: f64,
}

/// A subtree as the traversals read it, built in place: its nodes (its root first, each
/// interior node's two children adjacent, in the order of a depth-first walk that places both
/// children of a node before either's subtree) and the primitive list its leaves index. Values
/// past the node format's widths wrap here; `build_within` checks the sizes before use.
#[derive(Default)]
struct Flat {
    nodes: Vec<KdNode>,
    prims: Vec<u32>,
    largest_leaf: usize,
}

impl Flat {
    /// Appends subtree `sub`, its root into slot `at` (allocated, empty) and its other nodes
    /// at the end, renumbering child indices and leaf offsets.
    fn append(&mut self, sub: Flat, at: usize) {
        let base = self.nodes.len() as u32 - 1;
        let prim_base = self.prims.len() as u32;
        let moved = |n: KdNode| {
            if n.is_leaf() {
                KdNode { a: n.a.wrapping_add(prim_base), b: n.b }
            } else {
                KdNode { a: n.a, b: n.b.wrapping_add(base << 2) }
            }
        };
        self.nodes[at] = moved(sub.nodes[0]);
        self.nodes.extend(sub.nodes[1..].iter().map(|&n| moved(n)));
        self.prims.extend_from_slice(&sub.prims);
        self.largest_leaf = self.largest_leaf.max(sub.largest_leaf);
    }
}

fn area(b: &Bounds) -> f64 {
    let d = [(b.1[0] - b.0[0]) as f64, (b.1[1] - b.0[1]) as f64, (b.1[2] - b.0[2]) as f64];
    2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

#[derive(Copy, Clone, Debug)]
struct Split {
    cost: f64,
    axis: usize,
    pos: f32,
}

struct Ctx<'a> {
    tris: &'a [Triangle],
    opt: &'a BuildOptions,
    depth_limit: u32,
    /// Smallest gap between event positions a plane may go into (see `MIN_GAP`).
    min_gap: f32,
}

/// Planes go only into gaps between event positions of at least this fraction of the scene's
/// extent: geometry closer together than that — a face that is axis-aligned up to rounding
/// noise — is not cut apart. Not for correctness (the traversals resolve cells of any
/// thinness: the rules in `kdray_shared::kdtree`) but for speed: a ray meeting a cell thinner than the
/// rounding of its t is traversed again with the full stack. Relative to the extent, not to
/// the coordinates, so a scene far from the origin gets the tree it gets at the origin.
const MIN_GAP: f32 = 1.0 / 262_144.0;

impl Ctx<'_> {
    fn sah(&self, cell: &Bounds, area_cell: f64, axis: usize, pos: f32, nl: usize, nr: usize) -> f64 {
        let mut l = *cell;
        let mut r = *cell;
        l.1[axis] = pos;
        r.0[axis] = pos;
        let c = self.opt.k_t as f64
            + self.opt.k_i as f64 * (area(&l) / area_cell * nl as f64 + area(&r) / area_cell * nr as f64);
        if nl == 0 || nr == 0 {
            c * self.opt.empty_bonus as f64
        } else {
            c
        }
    }

    /// The sweep: every event position strictly inside the cell is a candidate plane, if its
    /// children's references fit the node's budget.
    fn best_split(&self, w: &Work) -> Option<Split> {
        let n = w.tris.len();
        let area_cell = area(&w.cell);
        if area_cell <= 0.0 {
            return None;
        }
        let mut best: Option<Split> = None;
        for k in 0..3 {
            let ev = &w.events[k];
            let (lo, hi) = (w.cell.0[k], w.cell.1[k]);
            let (mut nl, mut nr) = (0usize, n);
            let mut i = 0;
            // Candidate planes lie strictly between consecutive event positions (and between
            // the cell's faces and the geometry): left = triangles starting at or before the
            // lower position, right = those ending at or after the upper one.
            let consider = |pos: f32, cl: usize, cr: usize, best: &mut Option<Split>| {
                if pos > lo && pos < hi && (cl + cr) as f64 <= w.budget {
                    let cost = self.sah(&w.cell, area_cell, k, pos, cl, cr);
                    if best.is_none_or(|b| cost < b.cost) {
                        *best = Some(Split { cost, axis: k, pos });
                    }
                }
            };
            if let Some(first) = ev.first() {
                // Empty space below the geometry: keep the cut close to it.
                let pos = lo + (first.pos - lo) * (1.0 - EMPTY_MARGIN);
                if pos < first.pos && first.pos - lo >= self.min_gap {
                    consider(pos, 0, n, &mut best);
                }
            }
            while i < ev.len() {
                let p = ev[i].pos;
                let (mut pe, mut pp, mut ps) = (0, 0, 0);
                while i < ev.len() && ev[i].pos == p && ev[i].kind == END {
                    pe += 1;
                    i += 1;
                }
                while i < ev.len() && ev[i].pos == p && ev[i].kind == PLANAR {
                    pp += 1;
                    i += 1;
                }
                while i < ev.len() && ev[i].pos == p && ev[i].kind == START {
                    ps += 1;
                    i += 1;
                }
                nr -= pp + pe;
                nl += ps + pp;
                let upper = if i < ev.len() { ev[i].pos } else { hi };
                let pos = if i < ev.len() {
                    p + (ev[i].pos - p) * 0.5
                } else {
                    // Empty space above the geometry.
                    p + (hi - p) * EMPTY_MARGIN
                };
                if pos > p && pos < upper && upper - p >= self.min_gap {
                    consider(pos, nl, nr, &mut best);
                }
            }
        }
        best
    }

    /// Whether a node of `count` triangles at `depth` is a leaf without a split being looked for.
    fn leaf_at_once(&self, count: usize, depth: u32) -> bool {
        count <= self.opt.leaf_size || depth >= self.depth_limit
    }

    /// The subtree of `w` on its own (its root at index 0).
    fn subtree(&self, w: Work) -> Flat {
        let mut out = Flat { nodes: vec![KdNode::default()], ..Default::default() };
        self.build(w, &mut out, 0);
        out
    }

    /// Builds the subtree of `w` into `out`, its root into the (allocated) slot `idx`.
    fn build(&self, w: Work, out: &mut Flat, idx: usize) {
        let n = w.tris.len();
        let leaf = |out: &mut Flat, tris: &[u32]| {
            out.nodes[idx] = KdNode::leaf(out.prims.len() as u32, tris.len() as u32);
            out.prims.extend_from_slice(tris);
            out.largest_leaf = out.largest_leaf.max(tris.len());
        };
        if self.leaf_at_once(n, w.depth) {
            return leaf(out, &w.tris);
        }
        let split = match self.best_split(&w) {
            Some(s) if s.cost < self.opt.k_i as f64 * n as f64 => s,
            _ => return leaf(out, &w.tris),
        };
        let (mut left, mut right) = self.split(w, split);
        // The children share the budget in proportion to their triangles: each keeps at least
        // its own count (up to rounding, hence the max), and together they keep the parent's.
        let whole = (left.tris.len() + right.tris.len()) as f64;
        for c in [&mut left, &mut right] {
            let n = c.tris.len() as f64;
            c.budget = if n == 0.0 { 0.0 } else { (c.budget * (n / whole)).max(n) };
        }
        let c = out.nodes.len();
        out.nodes.extend([KdNode::default(); 2]);
        out.nodes[idx] = KdNode::interior(split.axis as u32, split.pos, c as u32);
        if n > self.opt.parallel_threshold {
            let (l, r) = rayon::join(|| self.subtree(left), || self.subtree(right));
            out.append(l, c);
            out.append(r, c + 1);
        } else {
            self.build(left, out, c);
            self.build(right, out, c + 1);
        }
    }

    /// Distributes the triangles: one-sided ones keep their (already sorted) events, straddlers
    /// are clipped to each child and their new events sorted and merged in.
    fn split(&self, w: Work, s: Split) -> (Work, Work) {
        let k = s.axis;
        let p = s.pos;
        let mut lcell = w.cell;
        let mut rcell = w.cell;
        lcell.1[k] = p;
        rcell.0[k] = p;
        let n = w.tris.len();
        // Side of each triangle: bit 0 = left, bit 1 = right.
        let side: Vec<u8> = w
            .bounds
            .iter()
            .map(|b| if b.0[k] == p && b.1[k] == p { 1 } else if b.1[k] <= p { 1 } else if b.0[k] >= p { 2 } else { 3 })
            .collect();
        // Each child's triangles, and per axis the events its one-sided triangles keep (one for a
        // triangle flat along the axis, else two), so every array is allocated once.
        let (mut nl, mut nr) = (0usize, 0usize);
        let (mut el, mut er) = ([0usize; 3], [0usize; 3]);
        for (b, &sd) in w.bounds.iter().zip(&side) {
            nl += (sd & 1) as usize;
            nr += (sd >> 1) as usize;
            if sd != 3 {
                let e = if sd == 1 { &mut el } else { &mut er };
                for a in 0..3 {
                    e[a] += 1 + (b.0[a] != b.1[a]) as usize;
                }
            }
        }
        let ns = nl + nr - n;
        // A child that `build` will make a leaf without looking at it needs only its triangles:
        // no bounds, no clipping, no events (most leaves; the same tree).
        let (l_leaf, r_leaf) = (self.leaf_at_once(nl, w.depth + 1), self.leaf_at_once(nr, w.depth + 1));
        let mut lw = Work { tris: Vec::with_capacity(nl), bounds: Vec::with_capacity(if l_leaf { 0 } else { nl }), events: Default::default(), cell: lcell, depth: w.depth + 1, budget: w.budget };
        let mut rw = Work { tris: Vec::with_capacity(nr), bounds: Vec::with_capacity(if r_leaf { 0 } else { nr }), events: Default::default(), cell: rcell, depth: w.depth + 1, budget: w.budget };
        // A one-sided triangle's index in its child; the straddlers are clipped into both and
        // listed (their indices in each child) for their new events.
        let mut local = vec![0u32; n];
        let mut straddlers: Vec<[u32; 2]> = Vec::with_capacity(ns);
        for i in 0..n {
            let g = w.tris[i];
            match side[i] {
                1 => {
                    local[i] = lw.tris.len() as u32;
                    lw.tris.push(g);
                    if !l_leaf {
                        lw.bounds.push(w.bounds[i]);
                    }
                }
                2 => {
                    local[i] = rw.tris.len() as u32;
                    rw.tris.push(g);
                    if !r_leaf {
                        rw.bounds.push(w.bounds[i]);
                    }
                }
                _ => {
                    let t = &self.tris[g as usize];
                    let v = [t.v0, t.v1, t.v2];
                    let mut ids = [0u32; 2];
                    for (c, (cell, cw, is_leaf)) in [(lcell, &mut lw, l_leaf), (rcell, &mut rw, r_leaf)].into_iter().enumerate() {
                        ids[c] = cw.tris.len() as u32;
                        cw.tris.push(g);
                        if is_leaf {
                            continue;
                        }
                        // Numerically empty: the box overlap instead (conservative).
                        let clipped = clipped_bounds(v, cell).unwrap_or_else(|| overlap(w.bounds[i], cell));
                        cw.bounds.push(clipped);
                    }
                    straddlers.push(ids);
                }
            }
        }
        // Per axis and child: the one-sided triangles' events in their (sorted) order, then the
        // straddlers' new events sorted and merged in, in the one array the child keeps.
        let mut new = Vec::with_capacity(2 * ns);
        for a in 0..3 {
            let mut le = Vec::with_capacity(if l_leaf { 0 } else { el[a] + 2 * ns });
            let mut re = Vec::with_capacity(if r_leaf { 0 } else { er[a] + 2 * ns });
            for e in &w.events[a] {
                let i = e.tri as usize;
                match side[i] {
                    1 if !l_leaf => le.push(Event { tri: local[i], ..*e }),
                    2 if !r_leaf => re.push(Event { tri: local[i], ..*e }),
                    _ => {}
                }
            }
            for (c, (cw, events, is_leaf)) in [(&lw, &mut le, l_leaf), (&rw, &mut re, r_leaf)].into_iter().enumerate() {
                if is_leaf {
                    continue;
                }
                new.clear();
                for s in &straddlers {
                    push_axis_events(&mut new, &cw.bounds[s[c] as usize], a, s[c]);
                }
                sort_events(&mut new);
                merge_into(events, &new);
            }
            lw.events[a] = le;
            rw.events[a] = re;
        }
        (lw, rw)
    }
}

/// Merges sorted `b` into sorted `a`, in place (from the back; `a` has the room): on equal keys
/// `a`'s events come first.
fn merge_into(a: &mut Vec<Event>, b: &[Event]) {
    if b.is_empty() {
        return;
    }
    let (mut i, mut j) = (a.len(), b.len());
    a.resize(i + j, b[0]);
    let mut k = i + j;
    while j > 0 {
        // Take from `a` only when it sorts strictly after `b`'s next (ties: `b` goes last).
        let take_a = i > 0 && {
            let (x, y) = (&a[i - 1], &b[j - 1]);
            !(x.pos < y.pos || (x.pos == y.pos && x.kind <= y.kind))
        };
        k -= 1;
        if take_a {
            i -= 1;
            a[k] = a[i];
        } else {
            j -= 1;
            a[k] = b[j];
        }
    }
}

/// What the buffers can address: an interior `KdNode` stores its first child's index << 2 and a
/// leaf its primitive count << 2 in a u32 (so both must be below 2^30), a leaf's offset into
/// the primitive index list is a u32, and triangle ids are u32 with `MISS` (u32::MAX) reserved.
#[derive(Copy, Clone, Debug)]
struct Limits {
    /// Most nodes in the tree (every index below it).
    nodes: u64,
    /// Most primitives in one leaf.
    leaf_prims: u64,
    /// Most entries in the primitive index list.
    prim_refs: u64,
    /// Most triangles.
    triangles: u64,
}

const FORMAT_LIMITS: Limits =
    Limits { nodes: 1 << 30, leaf_prims: (1 << 30) - 1, prim_refs: u32::MAX as u64, triangles: u32::MAX as u64 };

/// The sizes of a built tree that the node format must address.
#[derive(Copy, Clone, Debug, Default)]
struct TreeCounts {
    nodes: u64,
    largest_leaf: u64,
    prim_refs: u64,
}

/// `2^k` or `2^k - 1` where it is one, else the number.
fn limit_str(v: u64) -> String {
    if v.is_power_of_two() {
        format!("2^{}", v.trailing_zeros())
    } else if (v + 1).is_power_of_two() {
        format!("2^{} - 1", (v + 1).trailing_zeros())
    } else {
        v.to_string()
    }
}

fn check_triangles(triangles: u64, lim: &Limits) -> Result<()> {
    if triangles > lim.triangles {
        bail!(TooLarge:
            "scene too large for the kd-tree: {triangles} triangles exceed the {} that u32 triangle ids address",
            limit_str(lim.triangles)
        );
    }
    Ok(())
}

fn check_counts(c: &TreeCounts, lim: &Limits) -> Result<()> {
    if c.nodes > lim.nodes {
        bail!(TooLarge:
            "scene too large for the kd-tree: {} nodes exceed the {} the 8-byte node format addresses",
            c.nodes,
            limit_str(lim.nodes)
        );
    }
    if c.largest_leaf > lim.leaf_prims {
        bail!(TooLarge:
            "scene too large for the kd-tree: a leaf of {} triangles exceeds the {} the 8-byte node format counts",
            c.largest_leaf,
            limit_str(lim.leaf_prims)
        );
    }
    if c.prim_refs > lim.prim_refs {
        bail!(TooLarge:
            "scene too large for the kd-tree: {} triangle references in leaves exceed the {} that u32 leaf offsets address",
            c.prim_refs,
            limit_str(lim.prim_refs)
        );
    }
    Ok(())
}

/// Fails if a tree of `nodes` nodes whose largest leaf holds `largest_leaf` triangles, with
/// `prim_refs` triangle references in all leaves, over `triangles` triangles, cannot be
/// stored: more than 2^30 nodes, a leaf of 2^30 or more triangles, 2^32 or more references
/// or triangles (the 8-byte `KdNode` and the u32 index lists would silently truncate).
/// `try_build` checks this itself.
pub fn check_limits(nodes: usize, largest_leaf: usize, prim_refs: usize, triangles: usize) -> Result<()> {
    check_triangles(triangles as u64, &FORMAT_LIMITS)?;
    check_counts(
        &TreeCounts { nodes: nodes as u64, largest_leaf: largest_leaf as u64, prim_refs: prim_refs as u64 },
        &FORMAT_LIMITS,
    )
}

/// Builds the tree over `tris` (which must be non-empty and finite).
///
/// # Panics
/// If the scene is too large for the node format (see `try_build`), with `try_build`'s message.
pub fn build(tris: &[Triangle], opt: &BuildOptions) -> KdTreeData {
    try_build(tris, opt).unwrap_or_else(|e| panic!("{e:#}"))
}

/// Builds the tree over `tris` (which must be non-empty and finite), or fails with one line
/// (`scene too large for the kd-tree: …`) if the tree cannot be stored in the 8-byte node
/// format: more than 2^30 nodes, a leaf of 2^30 or more triangles, 2^32 or more triangle
/// references in leaves, or 2^32 or more triangles (see `check_limits`).
pub fn try_build(tris: &[Triangle], opt: &BuildOptions) -> Result<KdTreeData> {
    build_within(tris, opt, &FORMAT_LIMITS)
}

fn build_within(tris: &[Triangle], opt: &BuildOptions, limits: &Limits) -> Result<KdTreeData> {
    let start = Instant::now();
    let n = tris.len();
    check_triangles(n as u64, limits)?;
    let default_depth = (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32;
    let depth_limit = opt.max_depth.unwrap_or(default_depth).min(MAX_DEPTH as u32 - 1);
    let mut bounds = Vec::with_capacity(n);
    let mut events: [Vec<Event>; 3] = Default::default();
    let mut scene: Bounds = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (i, t) in tris.iter().enumerate() {
        let b = tri_bounds([t.v0, t.v1, t.v2]);
        for k in 0..3 {
            scene.0[k] = scene.0[k].min(b.0[k]);
            scene.1[k] = scene.1[k].max(b.1[k]);
        }
        push_events(&mut events, &b, i as u32);
        bounds.push(b);
    }
    for e in events.iter_mut() {
        sort_events(e);
    }
    let extent = (0..3).fold(0.0f32, |m, k| m.max(scene.1[k] - scene.0[k]));
    let ctx = Ctx { tris, opt, depth_limit, min_gap: extent * MIN_GAP };
    let budget = opt.max_duplication.max(1.0) as f64 * n as f64;
    let Flat { nodes, prims, largest_leaf } = ctx.subtree(Work { tris: (0..n as u32).collect(), bounds, events, cell: scene, depth: 0, budget });
    check_counts(&TreeCounts { nodes: nodes.len() as u64, largest_leaf: largest_leaf as u64, prim_refs: prims.len() as u64 }, limits)?;

    let mut st = TreeStats { triangles: n, depth_limit, ..Default::default() };
    let root_area = area(&scene).max(f64::MIN_POSITIVE);
    walk_stats(&nodes, 0, scene, 0, &mut st, opt, root_area);
    st.nodes = nodes.len();
    st.avg_leaf_size = prims.len() as f64 / (st.leaves - st.empty_leaves).max(1) as f64;
    st.references = prims.len();
    st.bytes = nodes.len() * std::mem::size_of::<KdNode>() + prims.len() * 4;
    st.build_seconds = start.elapsed().as_secs_f64();
    Ok(KdTreeData { nodes, prims, bounds: Aabb { min: scene.0, max: scene.1 }, stats: st })
}

#[allow(clippy::too_many_arguments)]
/// Leaves, depth and SAH cost of the built tree, node by node from `idx` (the cost summed in
/// the order of a depth-first walk, left before right).
fn walk_stats(nodes: &[KdNode], idx: usize, cell: Bounds, depth: u32, st: &mut TreeStats, opt: &BuildOptions, root_area: f64) {
    st.max_depth = st.max_depth.max(depth);
    let rel = area(&cell) / root_area;
    let node = nodes[idx];
    if node.is_leaf() {
        let count = node.prim_count() as usize;
        st.leaves += 1;
        st.empty_leaves += (count == 0) as usize;
        st.sah_cost += rel * opt.k_i as f64 * count as f64;
        return;
    }
    st.sah_cost += rel * opt.k_t as f64;
    let (axis, split, c) = (node.axis(), node.split(), node.first_child() as usize);
    let (mut l, mut r) = (cell, cell);
    l.1[axis] = split;
    r.0[axis] = split;
    walk_stats(nodes, c, l, depth + 1, st, opt, root_area);
    walk_stats(nodes, c + 1, r, depth + 1, st, opt, root_area);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SAH splits the Cornell box and the stored tree is cheaper than one leaf (640).
    #[test]
    fn cornell_box_tree_beats_a_leaf() {
        let s = crate::scene::load("cornell").unwrap();
        let t = build(&s.triangles, &BuildOptions::default());
        assert!(t.stats.nodes > 1 && t.stats.sah_cost < 640.0, "{:?}", t.stats);
        assert!(t.stats.max_depth <= t.stats.depth_limit);
        // Every triangle is referenced by some leaf.
        let mut seen = vec![false; s.triangles.len()];
        for p in &t.prims {
            seen[*p as usize] = true;
        }
        assert!(seen.iter().all(|x| *x));
    }

    /// The limits are exactly what the node format holds: the largest child index, leaf count
    /// and offset within them survive packing.
    #[test]
    fn format_limits_match_the_node_packing() {
        let last_node = (FORMAT_LIMITS.nodes - 1) as u32;
        let max_first_child = last_node - 1;
        assert_eq!(KdNode::interior(2, 1.5, max_first_child).first_child(), max_first_child);
        let n = KdNode::leaf(FORMAT_LIMITS.prim_refs as u32, FORMAT_LIMITS.leaf_prims as u32);
        assert_eq!((n.prim_offset() as u64, n.prim_count() as u64), (FORMAT_LIMITS.prim_refs, FORMAT_LIMITS.leaf_prims));
        assert!(n.is_leaf());
        // One more would truncate: the reason for the checks.
        assert_ne!(KdNode::interior(0, 0.0, 1 << 30).first_child(), 1 << 30);
        assert_ne!(KdNode::leaf(0, 1 << 30).prim_count(), 1 << 30);
    }

    #[test]
    fn check_limits_at_the_boundaries() {
        let (n, l, r, t) = (1usize << 30, (1usize << 30) - 1, u32::MAX as usize, u32::MAX as usize);
        check_limits(n, l, r, t).unwrap();
        let e = check_limits(n + 1, 1, 1, 1).unwrap_err().to_string();
        assert_eq!(e, format!("scene too large for the kd-tree: {} nodes exceed the 2^30 the 8-byte node format addresses", n + 1));
        let e = check_limits(1, l + 1, l + 1, l + 1).unwrap_err().to_string();
        assert!(e.contains("a leaf of 1073741824 triangles exceeds the 2^30 - 1"), "{e}");
        let e = check_limits(1, 1, r + 1, 1).unwrap_err().to_string();
        assert!(e.contains("4294967296 triangle references in leaves exceed the 2^32 - 1"), "{e}");
        let e = check_limits(1, 1, 1, t + 1).unwrap_err().to_string();
        assert!(e.contains("4294967296 triangles exceed the 2^32 - 1 that u32 triangle ids address"), "{e}");
    }

    /// A real build checked against small limits fails with the message, never truncating.
    #[test]
    fn try_build_reports_a_tree_beyond_the_limits() {
        let s = crate::scene::load("cornell").unwrap();
        let opt = BuildOptions::default();
        let ok = try_build(&s.triangles, &opt).unwrap();
        let nodes = ok.nodes.len() as u64;
        let fits = Limits { nodes, leaf_prims: 64, prim_refs: ok.prims.len() as u64, triangles: 32 };
        build_within(&s.triangles, &opt, &fits).unwrap();
        let e = build_within(&s.triangles, &opt, &Limits { nodes: nodes - 1, ..fits }).unwrap_err().to_string();
        assert_eq!(
            e,
            format!("scene too large for the kd-tree: {nodes} nodes exceed the {} the 8-byte node format addresses", limit_str(nodes - 1))
        );
        let e = build_within(&s.triangles, &opt, &Limits { prim_refs: 10, ..fits }).unwrap_err().to_string();
        assert!(e.contains("triangle references in leaves exceed the 10 "), "{e}");
        let e = build_within(&s.triangles, &opt, &Limits { triangles: 16, ..fits }).unwrap_err().to_string();
        assert!(e.contains("32 triangles exceed the 2^4"), "{e}");
        // One leaf of every triangle (depth 0) against a leaf limit of 7 = 2^3 - 1.
        let flat = BuildOptions { max_depth: Some(0), ..opt };
        let e = build_within(&s.triangles, &flat, &Limits { leaf_prims: 7, ..fits }).unwrap_err().to_string();
        assert_eq!(e, "scene too large for the kd-tree: a leaf of 32 triangles exceeds the 2^3 - 1 the 8-byte node format counts");
    }
}
