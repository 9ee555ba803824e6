//! SAH kd-tree construction: O(N log N) below the upper levels (Wald & Havran 2006): per-axis
//! event lists sorted once, a sweep per node that evaluates every candidate plane exactly,
//! "perfect splits" (triangles straddling a plane are clipped to each child and only their new
//! events are sorted and merged), and an empty-space bonus. Nodes above
//! `BuildOptions::binned_above` triangles choose their plane by binned SAH instead (no event
//! lists there; the plane moved into a gap as below), and nodes of at most `SMALL` triangles
//! sort their events afresh on the stack (`Ctx::build_small`: the same tree).
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
use super::clip::{overlap, tri_bounds, Bounds, ClipScratch};
use crate::error::{bail, Result};
use kdray_shared::aabb::Aabb;
use kdray_shared::kdtree::{KdNode, KdTree, MAX_DEPTH};
use kdray_shared::parts::Parts;
use kdray_shared::Triangle;
use std::sync::atomic::{AtomicUsize, Ordering};
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
    /// Nodes with more triangles than this choose their plane by binned SAH (`BINS` − 1
    /// candidate planes per axis, the chosen one moved into the gap between the triangles'
    /// bounds around it, where the exact sweep would put a plane) instead of the exact sweep;
    /// `None`: the exact sweep everywhere (Wald & Havran's build). Binned nodes skip the sorted
    /// event lists. Below 32 it acts as 32 (smaller nodes are always swept exactly).
    pub binned_above: Option<usize>,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            k_t: 15.0,
            k_i: 20.0,
            empty_bonus: 0.8,
            max_depth: None,
            leaf_size: 1,
            parallel_threshold: 8192,
            max_duplication: DEFAULT_MAX_DUPLICATION,
            binned_above: Some(DEFAULT_BINNED_ABOVE),
        }
    }
}

/// `BuildOptions::binned_above` by default: the upper levels only. Binning from 4 096 on built
/// the conference room 17 % faster with a 3 % lower SAH cost, yet its primary rays tested 23 %
/// more triangles and its shadow rays entered 9 % more nodes (natively, the full stack); from
/// 65 536 on the rays do the exact sweep's work (−1 % and +1 % by nodes and tests weighted as
/// the SAH weighs them) and the build is 7 % faster (a million small triangles: 20 %).
pub const DEFAULT_BINNED_ABOVE: usize = 65_536;

/// Candidate planes per axis of a binned node (`BuildOptions::binned_above`), less one.
pub const BINS: usize = 128;

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
    /// Nodes that chose their plane by binned SAH (`BuildOptions::binned_above`), and of them
    /// those whose binned plane found no gap to go into, broke the budget or cost more than a
    /// leaf, which the exact sweep then decided.
    pub binned_nodes: usize,
    /// See `binned_nodes`.
    pub binned_fallbacks: usize,
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

/// Sorts events by position (`f32::total_cmp`), then kind; the order of a triangle's equal
/// events among others' is free (nothing reads it). As integers (position, kind, triangle)
/// where the triangle ids fit 30 bits: sorted faster than the structs by comparator.
fn sort_events(e: &mut [Event]) {
    const TRI_BITS: u32 = 30;
    if e.len() < 2 || e.len() >= 1 << TRI_BITS || e.iter().any(|x| x.tri >> TRI_BITS != 0) {
        e.sort_unstable_by(|a, b| a.pos.total_cmp(&b.pos).then(a.kind.cmp(&b.kind)));
        return;
    }
    let mut keys: Vec<u64> = e.iter().map(|x| ordered_key(x.pos, x.kind) << TRI_BITS | x.tri as u64).collect();
    keys.sort_unstable();
    for (x, &key) in e.iter_mut().zip(&keys) {
        *x = Event { tri: (key & ((1 << TRI_BITS) - 1)) as u32, ..key_event(key >> TRI_BITS) };
    }
}

/// An event at `pos` of `kind` as 34 bits whose order is `f32::total_cmp` on the position,
/// then the kind.
fn ordered_key(pos: f32, kind: u8) -> u64 {
    let b = pos.to_bits();
    let ordered = if b >> 31 != 0 { !b } else { b | 1 << 31 };
    (ordered as u64) << 2 | kind as u64
}

/// An event at `pos` of `kind` as an integer whose order is `sort_events`'s (`f32::total_cmp`
/// on the position, then the kind).
/// -0 is written as 0: the sweep treats them as one position, wherever their events sort (the
/// counts at the end of a run, the planes between runs, are the same).
fn event_key(pos: f32, kind: u8) -> u64 {
    ordered_key(pos + 0.0, kind)
}

/// What the sweep reads of an event: `Event`s, or `event_key`s (`Ctx::build_small`).
trait SweepEvent: Copy {
    fn pos(&self) -> f32;
    fn kind(&self) -> u8;
    /// Whether the two lie at the same position (`==`: 0 and -0 are the same).
    fn same_pos(&self, other: &Self) -> bool;
}

impl SweepEvent for Event {
    #[inline(always)]
    fn pos(&self) -> f32 {
        self.pos
    }
    #[inline(always)]
    fn kind(&self) -> u8 {
        self.kind
    }
    #[inline(always)]
    fn same_pos(&self, other: &Self) -> bool {
        self.pos == other.pos
    }
}

impl SweepEvent for u64 {
    #[inline(always)]
    fn pos(&self) -> f32 {
        key_event(*self).pos
    }
    #[inline(always)]
    fn kind(&self) -> u8 {
        (*self & 3) as u8
    }
    /// The same bits (`event_key` writes -0 as 0).
    #[inline(always)]
    fn same_pos(&self, other: &Self) -> bool {
        *self >> 2 == *other >> 2
    }
}

/// The event of `event_key` or `ordered_key` (its triangle unknown: 0).
fn key_event(key: u64) -> Event {
    let ordered = (key >> 2) as u32;
    let b = if ordered >> 31 != 0 { ordered & !(1 << 31) } else { !ordered };
    Event { pos: f32::from_bits(b), kind: (key & 3) as u8, tri: 0 }
}

/// The events of triangles with bounds `bounds` (triangle i at index i), sorted per axis.
fn sorted_events(bounds: &[Bounds]) -> [Vec<Event>; 3] {
    let mut events: [Vec<Event>; 3] = Default::default();
    for (i, b) in bounds.iter().enumerate() {
        push_events(&mut events, b, i as u32);
    }
    for e in events.iter_mut() {
        sort_events(e);
    }
    events
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
/// each axis (events refer to positions in `tris`; none where the node will not sweep them:
/// below a binned parent, for a binned or small node, a leaf).
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
    /// Makes slot `idx` the leaf of `tris`.
    fn leaf(&mut self, idx: usize, tris: &[u32]) {
        self.nodes[idx] = KdNode::leaf(self.prims.len() as u32, tris.len() as u32);
        self.prims.extend_from_slice(tris);
        self.largest_leaf = self.largest_leaf.max(tris.len());
    }

    /// Makes slot `idx` an interior node split at `pos` along `axis`, allocating its two
    /// children's slots; returns the first's.
    fn interior(&mut self, idx: usize, axis: usize, pos: f32) -> usize {
        let c = self.nodes.len();
        self.nodes.extend([KdNode::default(); 2]);
        self.nodes[idx] = KdNode::interior(axis as u32, pos, c as u32);
        c
    }

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

/// The SAH cost of planes along one axis of a cell, times half the cell's area (`Split::cost`).
struct AxisCost {
    lo: f32,
    hi: f32,
    /// A child's half area is `cross` + its extent along the axis times `perim` (the cell's
    /// other two extents d1, d2: cross = d1 d2, perim = d1 + d2).
    cross: f64,
    perim: f64,
    k_t: f64,
    k_i: f64,
    bonus: f64,
}

impl AxisCost {
    fn new(ctx: &Ctx, cell: &Bounds, k: usize, half_area: f64) -> AxisCost {
        let (d1, d2) = (extent(cell, (k + 1) % 3), extent(cell, (k + 2) % 3));
        let o = ctx.opt;
        AxisCost { lo: cell.0[k], hi: cell.1[k], cross: d1 * d2, perim: d1 + d2, k_t: o.k_t as f64 * half_area, k_i: o.k_i as f64, bonus: o.empty_bonus as f64 }
    }

    /// The cost of a plane at `pos` with `nl` triangles left of it and `nr` right.
    #[inline(always)]
    fn at(&self, pos: f32, nl: usize, nr: usize) -> f64 {
        let (al, ar) = (self.cross + (pos - self.lo) as f64 * self.perim, self.cross + (self.hi - pos) as f64 * self.perim);
        let c = self.k_t + self.k_i * (al * nl as f64 + ar * nr as f64);
        if nl == 0 || nr == 0 {
            c * self.bonus
        } else {
            c
        }
    }
}

/// A box's extent along axis `k`, in f64.
fn extent(b: &Bounds, k: usize) -> f64 {
    (b.1[k] - b.0[k]) as f64
}

fn area(b: &Bounds) -> f64 {
    let d = [(b.1[0] - b.0[0]) as f64, (b.1[1] - b.0[1]) as f64, (b.1[2] - b.0[2]) as f64];
    2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

#[derive(Copy, Clone, Debug)]
struct Split {
    /// The SAH cost times half the cell's area (no division per candidate).
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
    /// Nodes that looked for their plane by binned SAH, and those of them that fell back to
    /// the exact sweep (`TreeStats`).
    binned_nodes: AtomicUsize,
    binned_fallbacks: AtomicUsize,
}

/// Planes go only into gaps between event positions of at least this fraction of the scene's
/// extent: geometry closer together than that — a face that is axis-aligned up to rounding
/// noise — is not cut apart. Not for correctness (the traversals resolve cells of any
/// thinness: the rules in `kdray_shared::kdtree`) but for speed: a ray meeting a cell thinner than the
/// rounding of its t is traversed again with the full stack. Relative to the extent, not to
/// the coordinates, so a scene far from the origin gets the tree it gets at the origin.
const MIN_GAP: f32 = 1.0 / 262_144.0;

/// `Ctx::build_small`'s stack of its nodes' triangles and bounds, and one axis's event keys.
#[derive(Default)]
struct Small {
    tris: Vec<u32>,
    bounds: Vec<Bounds>,
    keys: Vec<u64>,
    clip: ClipScratch,
}

thread_local! {
    static SMALL_STACK: std::cell::RefCell<Small> = std::cell::RefCell::new(Small::default());
}

/// Nodes of at most this many triangles are built by `Ctx::build_small`.
const SMALL: usize = 32;

impl Ctx<'_> {
    /// The sweep: every event position strictly inside the cell is a candidate plane, if its
    /// children's references fit the node's budget.
    fn best_split(&self, w: &Work) -> Option<Split> {
        let half_area = area(&w.cell) * 0.5;
        if half_area <= 0.0 {
            return None;
        }
        let mut best = None;
        for k in 0..3 {
            self.sweep_axis(&w.events[k], k, w.tris.len(), &w.cell, half_area, w.budget, &mut best);
        }
        best
    }

    /// The sweep along axis `k` over its events `ev` (sorted by `sort_events`) of a node of `n`
    /// triangles: `best` becomes the cheapest candidate plane so far (the first of equal costs).
    #[allow(clippy::too_many_arguments)]
    fn sweep_axis<E: SweepEvent>(&self, ev: &[E], k: usize, n: usize, cell: &Bounds, half_area: f64, budget: f64, best: &mut Option<Split>) {
        let (lo, hi) = (cell.0[k], cell.1[k]);
        let (mut nl, mut nr) = (0usize, n);
        let cost = AxisCost::new(self, cell, k, half_area);
        // Candidate planes lie strictly between consecutive event positions (and between
        // the cell's faces and the geometry): left = triangles starting at or before the
        // lower position, right = those ending at or after the upper one.
        let consider = |pos: f32, cl: usize, cr: usize, best: &mut Option<Split>| {
            if pos > lo && pos < hi && (cl + cr) as f64 <= budget {
                let cost = cost.at(pos, cl, cr);
                if best.is_none_or(|b| cost < b.cost) {
                    *best = Some(Split { cost, axis: k, pos });
                }
            }
        };
        if let Some(first) = ev.first() {
            // Empty space below the geometry: keep the cut close to it.
            let first = first.pos();
            let pos = lo + (first - lo) * (1.0 - EMPTY_MARGIN);
            if pos < first && first - lo >= self.min_gap {
                consider(pos, 0, n, best);
            }
        }
        // Event by event (the counts at the end of a run of equal positions are those after
        // all its ends, planars and starts, whatever their order): a candidate after each run.
        // Positions are read (decoded, for keys) only at the ends of runs.
        for i in 0..ev.len() {
            let e = ev[i];
            let kind = e.kind();
            nl += (kind != END) as usize;
            nr -= (kind != START) as usize;
            let next = ev.get(i + 1);
            if next.is_some_and(|n| n.same_pos(&e)) {
                continue;
            }
            let p = e.pos();
            let (upper, pos) = match next {
                Some(next) => {
                    let next = next.pos();
                    (next, p + (next - p) * 0.5)
                }
                // Empty space above the geometry.
                None => (hi, p + (hi - p) * EMPTY_MARGIN),
            };
            if pos > p && pos < upper && upper - p >= self.min_gap {
                consider(pos, nl, nr, best);
            }
        }
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
    fn build(&self, mut w: Work, out: &mut Flat, idx: usize) {
        let n = w.tris.len();
        if self.leaf_at_once(n, w.depth) {
            return out.leaf(idx, &w.tris);
        }
        if n <= SMALL {
            return self.build_small(&w.tris, &w.bounds, w.cell, w.depth, w.budget, out, idx);
        }
        let half_area = area(&w.cell) * 0.5;
        if half_area <= 0.0 {
            // No plane can split a flat cell (neither search would find one).
            return out.leaf(idx, &w.tris);
        }
        let leaf_cost = self.opt.k_i as f64 * n as f64 * half_area;
        let mut binned = self.binned(n);
        let mut best = None;
        if binned {
            self.binned_nodes.fetch_add(1, Ordering::Relaxed);
            best = self.binned_split(&w).filter(|s| s.cost < leaf_cost);
            if best.is_none() {
                // The binned plane found no gap to go into, broke the budget or costs more
                // than a leaf: the exact sweep decides, over every candidate.
                self.binned_fallbacks.fetch_add(1, Ordering::Relaxed);
                binned = false;
            }
        }
        if !binned {
            if w.events[0].is_empty() {
                w.events = sorted_events(&w.bounds);
            }
            best = self.best_split(&w);
        }
        let split = match best {
            Some(s) if s.cost < leaf_cost => s,
            _ => return out.leaf(idx, &w.tris),
        };
        let (mut left, mut right) = self.split(w, split, !binned);
        let whole = left.tris.len() + right.tris.len();
        for c in [&mut left, &mut right] {
            c.budget = share(c.budget, c.tris.len(), whole);
        }
        let c = out.interior(idx, split.axis, split.pos);
        if n > self.opt.parallel_threshold {
            // The left subtree straight into `out` (the nodes and order `append` gave it), the
            // right one on its own, to be appended (copied) after.
            let ((), r) = rayon::join(|| self.build(left, out, c), || self.subtree(right));
            out.append(r, c + 1);
        } else {
            self.build(left, out, c);
            self.build(right, out, c + 1);
        }
    }

    /// Distributes the triangles: one-sided ones keep their (already sorted) events, straddlers
    /// are clipped to each child and their new events sorted and merged in.
    fn split(&self, w: Work, s: Split, carry_events: bool) -> (Work, Work) {
        let k = s.axis;
        let p = s.pos;
        let mut lcell = w.cell;
        let mut rcell = w.cell;
        lcell.1[k] = p;
        rcell.0[k] = p;
        let n = w.tris.len();
        // Side of each triangle: bit 0 = left, bit 1 = right.
        let side: Vec<u8> = w.bounds.iter().map(|b| side(b, k, p)).collect();
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
        // A small child sorts its own events (`build_small`).
        // A binned parent has no events to carry: its children sort their own (`build`); and
        // a child that will be binned needs none.
        let wants = |leaf: bool, c: usize| carry_events && !leaf && c > SMALL && !self.binned(c);
        let (l_events, r_events) = (wants(l_leaf, nl), wants(r_leaf, nr));
        let mut lw = Work { tris: Vec::with_capacity(nl), bounds: Vec::with_capacity(if l_leaf { 0 } else { nl }), events: Default::default(), cell: lcell, depth: w.depth + 1, budget: w.budget };
        let mut rw = Work { tris: Vec::with_capacity(nr), bounds: Vec::with_capacity(if r_leaf { 0 } else { nr }), events: Default::default(), cell: rcell, depth: w.depth + 1, budget: w.budget };
        // A one-sided triangle's index in its child; the straddlers are clipped into both and
        // listed (their indices in each child) for their new events.
        let mut local = vec![0u32; n];
        let mut straddlers: Vec<[u32; 2]> = Vec::with_capacity(ns);
        let mut clip = ClipScratch::default();
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
                    let ids = [lw.tris.len() as u32, rw.tris.len() as u32];
                    lw.tris.push(g);
                    rw.tris.push(g);
                    let [lb, rb] = self.clip_both(&mut clip, g, &w.bounds[i], &w.cell, k, p, [!l_leaf, !r_leaf]);
                    if !l_leaf {
                        lw.bounds.push(lb);
                    }
                    if !r_leaf {
                        rw.bounds.push(rb);
                    }
                    straddlers.push(ids);
                }
            }
        }
        // Per axis and child: the one-sided triangles' events in their (sorted) order, then the
        // straddlers' new events sorted and merged in, in the one array the child keeps.
        let mut new = Vec::with_capacity(2 * ns);
        for a in 0..3 {
            let mut le = Vec::with_capacity(if l_events { el[a] + 2 * ns } else { 0 });
            let mut re = Vec::with_capacity(if r_events { er[a] + 2 * ns } else { 0 });
            if l_events || r_events {
                for e in &w.events[a] {
                    let i = e.tri as usize;
                    match side[i] {
                        1 if l_events => le.push(Event { tri: local[i], ..*e }),
                        2 if r_events => re.push(Event { tri: local[i], ..*e }),
                        _ => {}
                    }
                }
            }
            for (c, (cw, events, wanted)) in [(&lw, &mut le, l_events), (&rw, &mut re, r_events)].into_iter().enumerate() {
                if !wanted {
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

impl Ctx<'_> {
    /// Whether a node of `n` triangles chooses its plane by binned SAH.
    fn binned(&self, n: usize) -> bool {
        self.opt.binned_above.is_some_and(|m| n > m)
    }

    /// Binned SAH: per axis, the triangles' clipped bounds counted into `BINS` equal bins of the
    /// cell and the planes between bins costed from the counts; the cheapest is moved into the
    /// gap between the bounds' positions around it (halfway, or 1/64 of an empty gap from the
    /// geometry: where the exact sweep puts its planes, so no plane passes through a vertex) and
    /// costed again from exact counts. `None` if the chosen plane has no gap wide enough or
    /// breaks the node's budget (`build` then sweeps, as it does where the plane costs more
    /// than a leaf).
    fn binned_split(&self, w: &Work) -> Option<Split> {
        let n = w.tris.len();
        let half_area = area(&w.cell) * 0.5;
        if half_area <= 0.0 {
            return None;
        }
        let mut best: Option<Split> = None;
        for k in 0..3 {
            let (lo, hi) = (w.cell.0[k], w.cell.1[k]);
            if !(hi > lo) {
                continue;
            }
            let scale = BINS as f32 / (hi - lo);
            let bin = |x: f32| (((x - lo) * scale) as usize).min(BINS - 1);
            let (mut starts, mut ends) = ([0u32; BINS], [0u32; BINS]);
            for b in &w.bounds {
                starts[bin(b.0[k])] += 1;
                ends[bin(b.1[k])] += 1;
            }
            let cost = AxisCost::new(self, &w.cell, k, half_area);
            let (mut nl, mut nr) = (0usize, n);
            for j in 1..BINS {
                nl += starts[j - 1] as usize;
                nr -= ends[j - 1] as usize;
                let pos = lo + (hi - lo) * (j as f32 / BINS as f32);
                if pos > lo && pos < hi && (nl + nr) as f64 <= w.budget {
                    let c = cost.at(pos, nl, nr);
                    if best.is_none_or(|b| c < b.cost) {
                        best = Some(Split { cost: c, axis: k, pos });
                    }
                }
            }
        }
        let b = best?;
        self.into_gap(w, b.axis, b.pos, half_area)
    }

    /// The plane nearest `pos` along axis `k` that lies in a gap between the node's bounds'
    /// positions, as the exact sweep places it, with its exact cost; `None` where that gap is
    /// narrower than `min_gap` or the children's references break the node's budget.
    fn into_gap(&self, w: &Work, k: usize, pos: f32, half_area: f64) -> Option<Split> {
        let (lo, hi) = (w.cell.0[k], w.cell.1[k]);
        let (mut below, mut above) = (f32::NEG_INFINITY, f32::INFINITY);
        for b in &w.bounds {
            for x in [b.0[k], b.1[k]] {
                if x < pos {
                    below = below.max(x);
                } else {
                    above = above.min(x);
                }
            }
        }
        let (p, gap) = if below == f32::NEG_INFINITY {
            (lo + (above - lo) * (1.0 - EMPTY_MARGIN), above - lo)
        } else if above == f32::INFINITY {
            (below + (hi - below) * EMPTY_MARGIN, hi - below)
        } else {
            (below + (above - below) * 0.5, above - below)
        };
        let (floor, ceil) = (below.max(lo), above.min(hi));
        let p = if p > floor && p < ceil && gap >= self.min_gap {
            p
        } else if below > f32::NEG_INFINITY && above < f32::INFINITY {
            // Positions too close together there (a dense mesh's upper nodes hold more
            // positions than `MIN_GAP` allows gaps): the nearest wide enough gap within a
            // bin's width either side.
            self.nearest_gap(w, k, pos, (hi - lo) / BINS as f32)?
        } else {
            return None;
        };
        let (mut nl, mut nr) = (0usize, 0usize);
        for b in &w.bounds {
            let sd = side(b, k, p);
            nl += (sd & 1) as usize;
            nr += (sd >> 1) as usize;
        }
        if (nl + nr) as f64 > w.budget {
            return None;
        }
        Some(Split { cost: AxisCost::new(self, &w.cell, k, half_area).at(p, nl, nr), axis: k, pos: p })
    }

    /// The plane halfway across the gap of at least `min_gap` between consecutive bounds
    /// positions along axis `k` (both within `reach` of `pos`) whose plane lies nearest `pos`,
    /// as the exact sweep places it; `None` if there is none.
    fn nearest_gap(&self, w: &Work, k: usize, pos: f32, reach: f32) -> Option<f32> {
        let mut xs: Vec<f32> = Vec::new();
        for b in &w.bounds {
            for x in [b.0[k], b.1[k]] {
                if (x - pos).abs() <= reach {
                    xs.push(x);
                }
            }
        }
        xs.sort_unstable_by(f32::total_cmp);
        let mut best: Option<f32> = None;
        for pair in xs.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let p = a + (b - a) * 0.5;
            if b - a >= self.min_gap && p > a && p < b && best.is_none_or(|q| (p - pos).abs() < (q - pos).abs()) {
                best = Some(p);
            }
        }
        best
    }

    /// `build` for a node of at most `SMALL` triangles (`tris`, their clipped `bounds`): the
    /// same tree, with each axis's events sorted afresh per node instead of carried down. Most
    /// nodes are this small (2.3 of the conference's 2.6 million split nodes hold under 8
    /// triangles), and there the lists' allocation and upkeep cost more than sorting a few
    /// events. The subtree's triangles and bounds live on one stack per thread (`Small`), no
    /// arrays zeroed or allocated per node.
    #[allow(clippy::too_many_arguments)]
    fn build_small(&self, tris: &[u32], bounds: &[Bounds], cell: Bounds, depth: u32, budget: f64, out: &mut Flat, idx: usize) {
        // The borrow lasts the whole subtree: nothing under `build_small_at` may reach rayon
        // (a `join` or parallel sort there could run another `build_small` on this thread
        // while it is held, and `borrow_mut` would panic) or call `build`.
        SMALL_STACK.with(|s| {
            let mut s = s.borrow_mut();
            s.tris.clear();
            s.bounds.clear();
            s.tris.extend_from_slice(tris);
            s.bounds.extend_from_slice(bounds);
            self.build_small_at(&mut s, 0, tris.len(), !bounds.is_empty(), cell, depth, budget, out, idx);
        })
    }

    /// `build_small` of the node whose triangles are `s.tris[at..at + n]` (and bounds, unless
    /// it is a leaf at once, `s.bounds[at..at + n]`); its children go on top of the stack, and
    /// the stack is back as it was on return.
    #[allow(clippy::too_many_arguments)]
    fn build_small_at(&self, s: &mut Small, at: usize, n: usize, has_bounds: bool, cell: Bounds, depth: u32, budget: f64, out: &mut Flat, idx: usize) {
        debug_assert!(n <= SMALL);
        if self.leaf_at_once(n, depth) {
            return out.leaf(idx, &s.tris[at..at + n]);
        }
        debug_assert!(has_bounds);
        let half_area = area(&cell) * 0.5;
        let mut best = None;
        if half_area > 0.0 {
            // Events as integers in `sort_events`'s order (sorted faster than the structs).
            for k in 0..3 {
                s.keys.clear();
                for b in &s.bounds[at..at + n] {
                    if b.0[k] == b.1[k] {
                        s.keys.push(event_key(b.0[k], PLANAR));
                    } else {
                        s.keys.push(event_key(b.0[k], START));
                        s.keys.push(event_key(b.1[k], END));
                    }
                }
                s.keys.sort_unstable();
                self.sweep_axis(&s.keys, k, n, &cell, half_area, budget, &mut best);
            }
        }
        let split = match best {
            Some(sp) if sp.cost < self.opt.k_i as f64 * n as f64 * half_area => sp,
            _ => return out.leaf(idx, &s.tris[at..at + n]),
        };
        let (k, p) = (split.axis, split.pos);
        let (mut lcell, mut rcell) = (cell, cell);
        lcell.1[k] = p;
        rcell.0[k] = p;
        let (mut nl, mut nr) = (0usize, 0usize);
        for b in &s.bounds[at..at + n] {
            let sd = side(b, k, p);
            nl += (sd & 1) as usize;
            nr += (sd >> 1) as usize;
        }
        let (l_leaf, r_leaf) = (self.leaf_at_once(nl, depth + 1), self.leaf_at_once(nr, depth + 1));
        // The children on top of the stack: left at `base`, right at `base + nl`.
        let base = s.tris.len();
        let empty: Bounds = ([0.0; 3], [0.0; 3]);
        s.tris.resize(base + nl + nr, 0);
        s.bounds.resize(base + nl + nr, empty);
        let (mut il, mut ir) = (base, base + nl);
        for i in at..at + n {
            let (g, b) = (s.tris[i], s.bounds[i]);
            let sd = side(&b, k, p);
            let [cl, cr] = if sd == 3 { self.clip_both(&mut s.clip, g, &b, &cell, k, p, [!l_leaf, !r_leaf]) } else { [b, b] };
            if sd & 1 != 0 {
                s.tris[il] = g;
                s.bounds[il] = cl;
                il += 1;
            }
            if sd & 2 != 0 {
                s.tris[ir] = g;
                s.bounds[ir] = cr;
                ir += 1;
            }
        }
        let c = out.interior(idx, k, p);
        self.build_small_at(s, base, nl, !l_leaf, lcell, depth + 1, share(budget, nl, nl + nr), out, c);
        self.build_small_at(s, base + nl, nr, !r_leaf, rcell, depth + 1, share(budget, nr, nl + nr), out, c + 1);
        s.tris.truncate(base);
        s.bounds.truncate(base);
    }

    /// The bounds of straddling triangle `g` (bounds `b`) clipped into the children of `cell`
    /// split at `p` along axis `k` that `want` them (left, right; the others' entries are
    /// `b`), the planes they share clipped once where both do; where clipping leaves nothing
    /// (numerically), the box overlap instead (conservative).
    #[allow(clippy::too_many_arguments)]
    fn clip_both(&self, c: &mut ClipScratch, g: u32, b: &Bounds, cell: &Bounds, k: usize, p: f32, want: [bool; 2]) -> [Bounds; 2] {
        let (mut lcell, mut rcell) = (*cell, *cell);
        lcell.1[k] = p;
        rcell.0[k] = p;
        let t = &self.tris[g as usize];
        let v = [t.v0, t.v1, t.v2];
        match want {
            [true, true] => {
                let [l, r] = c.split(v, *cell, k, p);
                [l.unwrap_or_else(|| overlap(*b, lcell)), r.unwrap_or_else(|| overlap(*b, rcell))]
            }
            [true, false] => [c.bounds(v, lcell).unwrap_or_else(|| overlap(*b, lcell)), *b],
            [false, true] => [*b, c.bounds(v, rcell).unwrap_or_else(|| overlap(*b, rcell))],
            [false, false] => [*b, *b],
        }
    }
}

/// Which children of a split at `p` along axis `k` a triangle of bounds `b` goes to: bit 0 the
/// left, bit 1 the right (a triangle flat in the plane goes left).
fn side(b: &Bounds, k: usize, p: f32) -> u8 {
    if b.0[k] == p && b.1[k] == p {
        1
    } else if b.1[k] <= p {
        1
    } else if b.0[k] >= p {
        2
    } else {
        3
    }
}

/// A child's share of its parent's reference `budget`: in proportion to its `n` of the
/// children's `whole` triangles, and at least its own count (up to rounding, hence the max),
/// so that together they keep the parent's.
fn share(budget: f64, n: usize, whole: usize) -> f64 {
    if n == 0 {
        0.0
    } else {
        (budget * (n as f64 / whole as f64)).max(n as f64)
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
    let mut scene: Bounds = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for t in tris {
        let b = tri_bounds([t.v0, t.v1, t.v2]);
        for k in 0..3 {
            scene.0[k] = scene.0[k].min(b.0[k]);
            scene.1[k] = scene.1[k].max(b.1[k]);
        }
        bounds.push(b);
    }
    // The root's events, unless it is binned (`Ctx::build` sorts them where they are missing).
    let events = if opt.binned_above.is_some_and(|m| n > m) { Default::default() } else { sorted_events(&bounds) };
    let extent = (0..3).fold(0.0f32, |m, k| m.max(scene.1[k] - scene.0[k]));
    let ctx = Ctx { tris, opt, depth_limit, min_gap: extent * MIN_GAP, binned_nodes: AtomicUsize::new(0), binned_fallbacks: AtomicUsize::new(0) };
    let budget = opt.max_duplication.max(1.0) as f64 * n as f64;
    let Flat { nodes, prims, largest_leaf } = ctx.subtree(Work { tris: (0..n as u32).collect(), bounds, events, cell: scene, depth: 0, budget });
    check_counts(&TreeCounts { nodes: nodes.len() as u64, largest_leaf: largest_leaf as u64, prim_refs: prims.len() as u64 }, limits)?;

    let mut st = TreeStats {
        triangles: n,
        depth_limit,
        binned_nodes: ctx.binned_nodes.load(Ordering::Relaxed),
        binned_fallbacks: ctx.binned_fallbacks.load(Ordering::Relaxed),
        ..Default::default()
    };
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

    /// `sort_events` as integers orders events as the comparator does (position by
    /// `total_cmp`, then kind), -0 and 0 and equal positions included.
    #[test]
    fn event_sort_matches_the_comparator() {
        let pos = [0.5f32, -0.0, 0.0, 1.0, -2.5, 0.5, 1e-30, -1e-30, 3.0];
        let mut ev: Vec<Event> = (0..90u32).map(|i| Event { pos: pos[(i * 7 % 9) as usize], kind: (i % 3) as u8, tri: i }).collect();
        let mut want = ev.clone();
        want.sort_by(|a, b| a.pos.total_cmp(&b.pos).then(a.kind.cmp(&b.kind)));
        sort_events(&mut ev);
        let key = |e: &Event| (e.pos.to_bits(), e.kind);
        assert_eq!(ev.iter().map(key).collect::<Vec<_>>(), want.iter().map(key).collect::<Vec<_>>());
        let mut tris: Vec<u32> = ev.iter().map(|e| e.tri).collect();
        tris.sort_unstable();
        assert_eq!(tris, (0..90).collect::<Vec<_>>());
    }

    /// The exact sweep's trees stay as they were (a regression pin: 9461bea built these, before
    /// the small-node builder and the division-free costs, which must not change them).
    #[test]
    fn exact_trees_are_pinned() {
        for (spec, nodes, refs, sah) in [("cornell", 107, 98, 429.5), ("cornell-chair", 12091, 9203, 412.2)] {
            let s = crate::scene::load(spec).unwrap();
            let t = build(&s.triangles, &BuildOptions { binned_above: None, ..Default::default() });
            assert_eq!((t.nodes.len(), t.prims.len()), (nodes, refs), "{spec}");
            assert!((t.stats.sah_cost - sah).abs() < 0.05, "{spec}: SAH cost {}", t.stats.sah_cost);
        }
    }

    /// A binned plane whose own gap is too narrow moves to the nearest wide enough gap within
    /// a bin's width (a dense mesh's upper nodes), strictly between two bounds positions, with
    /// its exact counts; with none within reach, or over the budget, the node sweeps (`None`).
    #[test]
    fn binned_planes_go_into_the_nearest_wide_gap() {
        let opt = BuildOptions::default();
        let ctx = Ctx { tris: &[], opt: &opt, depth_limit: 20, min_gap: 0.01, binned_nodes: AtomicUsize::new(0), binned_fallbacks: AtomicUsize::new(0) };
        // Flat boxes along x: a dense run 0.500, 0.501, … 0.539 (gaps 0.001 < min_gap), then a
        // gap to 0.56, and boxes spanning [0.56, 0.6] and [0.1, 0.2].
        let mut bounds: Vec<Bounds> = (0..40).map(|i| ([0.5 + i as f32 * 0.001, 0.0, 0.0], [0.5 + i as f32 * 0.001, 1.0, 1.0])).collect();
        bounds.push(([0.56, 0.0, 0.0], [0.6, 1.0, 1.0]));
        bounds.push(([0.1, 0.0, 0.0], [0.2, 1.0, 1.0]));
        let n = bounds.len();
        let work = |budget: f64| Work { tris: (0..n as u32).collect(), bounds: bounds.clone(), events: Default::default(), cell: ([0.0; 3], [4.0, 1.0, 1.0]), depth: 0, budget };
        let w = work(1e9);
        let half_area = area(&w.cell) * 0.5;
        // Inside the dense run: the gap 0.539 .. 0.56 is the nearest wide one within a bin's
        // width (4/128) of 0.535 (0.2 .. 0.5 lies beyond it).
        let s = ctx.into_gap(&w, 0, 0.535, half_area).unwrap();
        let p = 0.539f32 + (0.56f32 - 0.539f32) * 0.5;
        assert_eq!(s.pos, p);
        assert!(bounds.iter().all(|b| b.0[0] != s.pos && b.1[0] != s.pos));
        assert_eq!(s.cost, AxisCost::new(&ctx, &w.cell, 0, half_area).at(p, 41, 1));
        // From a plane whose neighbours are far enough apart, that gap itself.
        assert_eq!(ctx.into_gap(&w, 0, 0.3, half_area).unwrap().pos, 0.2 + (0.5 - 0.2) * 0.5);
        // No wide gap within a bin's width: the sweep decides.
        let dense: Vec<Bounds> = (0..40).map(|i| ([0.5 + i as f32 * 0.001, 0.0, 0.0], [0.5 + i as f32 * 0.001, 1.0, 1.0])).collect();
        let far = Work { tris: (0..40).collect(), bounds: dense.clone(), events: Default::default(), cell: ([0.4, 0.0, 0.0], [0.6, 1.0, 1.0]), depth: 0, budget: 1e9 };
        assert!(ctx.nearest_gap(&far, 0, 0.52, 0.015).is_none());
        // Over the budget (the straddling box [0.56, 0.6] counts twice for a plane inside it).
        let tight = work(n as f64);
        assert!(ctx.into_gap(&tight, 0, 0.58, half_area).is_none());
        assert!(ctx.into_gap(&tight, 0, 0.535, half_area).is_some());
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
