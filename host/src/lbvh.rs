//! The linear BVH build on either runtime (`kdray_shared::bvh::build`): Morton codes, the
//! counting sort by their top bits (`crate::sort`), the order within small cells by the full
//! codes, Karras's binary tree, its boxes from a range tree, and the collapse to the compressed
//! wide BVH level by level, all as kernels, so a GPU builds the tree that its trace kernels
//! (and the native ones) traverse. The host only uploads the triangles, records the passes
//! and reads the tree back (`LbvhBuilder::build`: a `BvhData`, as `crate::bvh::try_build`
//! returns it), or builds from a tracer's triangles into the tracer's own buffers and reads
//! back only the build's state (`Tracer::build_bvh`).
//!
//! Quality: Morton order instead of the SAH, then `TREELET_ROUNDS` rounds of treelet
//! restructuring (`build::treelet`), which bring the binary tree's SAH cost to about the host's
//! binned SAH build's; `LbvhData::sah_cost` reports it as `BvhData::sah_cost` does the host's,
//! and `build_with` takes another number of rounds (0: Karras's tree as it comes).
use crate::bvh::BvhData;
use crate::error::{bail, Result};
use crate::kernels::lbvh::{Bounds, Boxes, Collapse, Depths, Hierarchy, Level, Morton, Reduce, Refine, Treelet};
use crate::runtime::{cast, Buffer, Commands, Runtime};
use crate::sort::CountingSort;
use kdray_shared::bvh::build::{self, range_level, range_tree_shape, LEAF_BIT, STATE_WORDS};
use kdray_shared::bvh::{BvhNode, MAX_BVH_DEPTH, MAX_LEAF_TRIS};
use kdray_shared::{BuildBox, LbvhParams, Triangle};
use std::time::Instant;

/// Triangles the build takes at most (Karras's search keeps positions below 2^29).
pub const MAX_TRIANGLES: usize = 1 << 29;

/// Bits of the Morton code the counting sort sorts by for `n` triangles: a multiple of three
/// (whole levels of the octree), about 64 n cells (a mesh fills few of them), from 12 to 24
/// (16.7 M cells).
pub fn cell_bits(n: usize) -> u32 {
    let log = usize::BITS - n.max(2).next_power_of_two().leading_zeros() - 1;
    (((log + 6).div_ceil(3)) * 3).clamp(12, 24)
}

/// Rounds of treelet restructuring `build_on` runs (`build::treelet`; three phases each, by
/// depth modulo 3, so that about every inner node is a treelet's root once a round: depths
/// change between phases).
pub const TREELET_ROUNDS: u32 = 3;
/// Rounds `build_with` takes at most.
pub const MAX_TREELET_ROUNDS: u32 = 16;

/// A BVH built by the kernels, with where the time went.
#[derive(Clone, Debug)]
pub struct LbvhData {
    /// The tree, as the host's builder returns it (`sah_cost`: the binary tree's, below).
    pub bvh: BvhData,
    /// Seconds from submitting the build's passes to their end (the build itself, on the
    /// device; the triangles already there).
    pub build_s: f64,
    /// Seconds to upload the triangles and to allocate the working buffers (where a builder's
    /// kept buffers did not fit: `LbvhBuilder`).
    pub setup_s: f64,
    /// Seconds to read the tree back.
    pub read_s: f64,
    /// Rounds of treelet restructuring in this tree: those asked for, or 0 where they made a
    /// tree deeper than `MAX_BVH_DEPTH` levels and the build was made again without them
    /// (`build_s` then counts both builds).
    pub rounds: u32,
}

/// What a build left in its output buffers, from the build's state words (read back alone).
struct Tree {
    nodes: usize,
    leaves: usize,
    depth: usize,
}

/// A build's outcome: a tree, or one deeper than `MAX_BVH_DEPTH` levels.
enum Ran {
    Tree(Tree),
    TooDeep,
}

/// Where a build reads its `n` triangles and writes its tree (buffers of at least `n`
/// elements each).
struct Io<'a> {
    tris: &'a Buffer<Triangle>,
    bvh: &'a Buffer<BvhNode>,
    bvh_tris: &'a Buffer<Triangle>,
}

/// The buffers a build that reads the triangles from the host (`LbvhBuilder::build`) uploads
/// them to and writes its tree into, before reading it back.
struct Own {
    tris: Buffer<Triangle>,
    bvh: Buffer<BvhNode>,
    bvh_tris: Buffer<Triangle>,
}

impl Own {
    /// The build's input and output: these buffers.
    fn io(&self) -> Io<'_> {
        Io { tris: &self.tris, bvh: &self.bvh, bvh_tris: &self.bvh_tris }
    }
}

/// The working buffers of a build, for up to `capacity` triangles whose Morton codes are sorted
/// by `bits` bits (`cell_bits`).
struct Work<'r> {
    capacity: usize,
    bits: u32,
    /// Made by the first build from the host (`LbvhBuilder::build`); a build into a tracer's
    /// buffers (`LbvhBuilder::build_into`) needs none.
    own: Option<Own>,
    list: Buffer<BuildBox>,
    tree: Buffer<BuildBox>,
    codes: Buffer<[u32; 2]>,
    keys: Buffer<u32>,
    order: Buffer<u32>,
    sort: CountingSort<'r>,
    sorted: Buffer<u32>,
    sorted_codes: Buffer<[u32; 2]>,
    nodes2: Buffer<[u32; 4]>,
    boxes2: Buffer<BuildBox>,
    counts: Buffer<u32>,
    parents: Buffer<u32>,
    depths: Buffer<u32>,
    state: Buffer<u32>,
    args: Buffer<[u32; 3]>,
    pending: Buffer<u32>,
}

impl<'r> Work<'r> {
    /// Buffers for `n` (at least one) triangles.
    fn new(rt: &'r dyn Runtime, n: usize) -> Result<Self> {
        let nu = n as u32;
        let bits = cell_bits(n);
        let inner = (n - 1).max(1);
        Ok(Work {
            capacity: n,
            bits,
            own: None,
            list: rt.alloc("BVH build boxes", n)?,
            tree: rt.alloc("BVH build range tree", range_tree_shape(nu).1 as usize)?,
            codes: rt.alloc("BVH build codes", n)?,
            keys: rt.alloc("BVH build keys", n)?,
            order: rt.alloc("BVH build order", n)?,
            sort: CountingSort::new(rt, 1 << bits, nu)?,
            sorted: rt.alloc("BVH build sorted", n)?,
            sorted_codes: rt.alloc("BVH build sorted codes", n)?,
            nodes2: rt.alloc("BVH build binary nodes", inner)?,
            boxes2: rt.alloc("BVH build binary boxes", inner)?,
            counts: rt.alloc("BVH build binary counts", inner)?,
            parents: rt.alloc("BVH build binary parents", inner)?,
            depths: rt.alloc("BVH build binary depths", inner)?,
            state: rt.alloc("BVH build state", STATE_WORDS)?,
            args: rt.alloc("BVH build dispatch", 1)?,
            // Every wide node but the root stands for a distinct inner node of more than
            // MAX_LEAF_TRIS triangles: fewer than n.
            pending: rt.alloc("BVH build pending", n)?,
        })
    }

    /// Whether a build of `n` triangles can use these buffers: no more triangles, and the sort
    /// by the same bits (its cells are fixed). The kernels read only the first `n` elements, or
    /// what the build itself wrote, so larger buffers hold the same tree.
    fn fits(&self, n: usize) -> bool {
        n <= self.capacity && cell_bits(n) == self.bits
    }
}

/// Output buffers for a tree of `n` triangles: its nodes (fewer than `n`: see `Work::new`'s
/// `pending`) and its triangles in leaf order.
pub(crate) fn tree_buffers(rt: &dyn Runtime, n: usize) -> Result<(Buffer<BvhNode>, Buffer<Triangle>)> {
    Ok((rt.alloc("BVH nodes", n)?, rt.alloc("BVH triangles", n)?))
}

/// Builds BVHs with the kernels on one runtime and keeps the working buffers from one build to
/// the next, so a scene rebuilt every frame (its triangles moved) allocates them once:
/// `build_with` is one builder's one build. A build of more triangles than the kept buffers
/// hold, or of a count whose Morton sort takes other bits (`cell_bits`, three more each time
/// the count grows eightfold), allocates new ones; a build that fails drops them (one that
/// fails only for a tree too deep for the traversal keeps them).
///
/// `build` uploads the triangles and reads the tree back (`BvhData`: its SAH cost, and a tree
/// any runtime can load). A frame loop on a GPU would rather leave the tree where it is:
/// `Tracer::build_bvh` builds from the tracer's triangles into its own BVH buffers, with
/// nothing uploaded and only the build's state read back (`Tracer::update` writes the moved
/// triangles first). A builder used both ways keeps `build`'s triangle and tree buffers too
/// (about 176 bytes a triangle).
///
/// ```no_run
/// # fn main() -> kdray::Result<()> {
/// # let gpu = kdray::gpu::Gpu::new()?;
/// # let frames: Vec<kdray::Scene> = Vec::new();
/// let mut builder = kdray::lbvh::LbvhBuilder::new(&gpu);
/// for scene in &frames {
///     let bvh = builder.build(&scene.triangles, kdray::lbvh::TREELET_ROUNDS)?.bvh;
///     # let _ = bvh;
/// }
/// # Ok(())
/// # }
/// ```
pub struct LbvhBuilder<'r> {
    rt: &'r dyn Runtime,
    work: Option<Work<'r>>,
}

impl<'r> LbvhBuilder<'r> {
    /// A builder on `rt`, with no buffers yet.
    pub fn new(rt: &'r dyn Runtime) -> Self {
        LbvhBuilder { rt, work: None }
    }

    /// The runtime it builds on.
    pub fn runtime(&self) -> &'r dyn Runtime {
        self.rt
    }

    /// Triangles the kept buffers hold (0: none kept).
    pub fn capacity(&self) -> usize {
        self.work.as_ref().map_or(0, |w| w.capacity)
    }

    /// `build_with` on the kept buffers where they fit.
    pub fn build(&mut self, tris: &[Triangle], rounds: u32) -> Result<LbvhData> {
        check_rounds(rounds)?;
        let rt = self.rt;
        let n = tris.len();
        check_count(n)?;
        if let Some(i) = tris.iter().position(|t| [t.v0, t.v1, t.v2].iter().flatten().any(|c| !c.is_finite())) {
            bail!(InvalidInput: "triangle {i} has a vertex that is not a finite number");
        }
        if n == 0 {
            let bvh = crate::bvh::try_build(tris)?;
            return Ok(LbvhData { bvh, build_s: 0.0, setup_s: 0.0, read_s: 0.0, rounds });
        }
        let t0 = Instant::now();
        let mut w = self.work_for(n)?;
        let own = match w.own.take() {
            Some(o) => o,
            None => {
                let (bvh, bvh_tris) = tree_buffers(rt, w.capacity)?;
                Own { tris: rt.alloc("BVH build triangles", w.capacity)?, bvh, bvh_tris }
            }
        };
        rt.write(&own.tris, tris)?;
        rt.finish()?;
        let setup_s = t0.elapsed().as_secs_f64();
        let Some((tree, build_s, rounds)) = run_rounds(rt, &w, &own.io(), n, rounds)? else {
            w.own = Some(own);
            self.work = Some(w);
            bail!(TooLarge: "{}", too_deep());
        };

        let inner = (n - 1).max(1);
        let t2 = Instant::now();
        let mut c = rt.begin();
        let pn = rt.read_back_of(&mut c, &own.bvh, tree.nodes)?;
        let pt = rt.read_back_of(&mut c, &own.bvh_tris, n)?;
        let p2 = rt.read_back_of(&mut c, &w.nodes2, inner)?;
        let pb = rt.read_back_of(&mut c, &w.boxes2, inner)?;
        let pl = rt.read_back_of(&mut c, &w.tree, n)?;
        let pc = rt.read_back_of(&mut c, &w.counts, inner)?;
        rt.submit(c)?;
        let nodes: Vec<BvhNode> = cast(rt.wait(pn)?);
        let out_tris: Vec<Triangle> = cast(rt.wait(pt)?);
        let read_s = t2.elapsed().as_secs_f64();
        let nodes2: Vec<[u32; 4]> = cast(rt.wait(p2)?);
        let boxes2: Vec<BuildBox> = cast(rt.wait(pb)?);
        let leaf_boxes: Vec<BuildBox> = cast(rt.wait(pl)?);
        let counts: Vec<u32> = cast(rt.wait(pc)?);
        let sah_cost = binary_sah(n, &nodes2, &boxes2, &counts, &leaf_boxes);
        let bvh = BvhData { nodes, tris: out_tris, depth: tree.depth, leaves: tree.leaves, sah_cost };
        w.own = Some(own);
        self.work = Some(w);
        Ok(LbvhData { bvh, build_s, setup_s, read_s, rounds })
    }

    /// Builds over the first `n` (at least one) triangles of `tris`, already on the device,
    /// into `out` (nodes and triangles in leaf order, `tree_buffers`, at least `n` elements
    /// each), on the kept buffers where they fit, and reads back only the build's state. The
    /// triangles' vertices must be finite (`Scene::validate`; the tracer's are).
    pub(crate) fn build_into(&mut self, tris: &Buffer<Triangle>, n: usize, out: &(Buffer<BvhNode>, Buffer<Triangle>), rounds: u32) -> Result<LbvhBuild> {
        check_rounds(rounds)?;
        check_count(n)?;
        if n == 0 || tris.len() < n || out.0.len() < n || out.1.len() < n {
            bail!(InvalidInput: "a BVH build of {n} triangles from a buffer of {} into buffers of {} and {}", tris.len(), out.0.len(), out.1.len());
        }
        let t0 = Instant::now();
        let w = self.work_for(n)?;
        let setup_s = t0.elapsed().as_secs_f64();
        let io = Io { tris, bvh: &out.0, bvh_tris: &out.1 };
        let ran = run_rounds(self.rt, &w, &io, n, rounds)?;
        self.work = Some(w);
        let Some((tree, build_s, rounds)) = ran else { bail!(TooLarge: "{}", too_deep()) };
        Ok(LbvhBuild { nodes: tree.nodes, leaves: tree.leaves, depth: tree.depth, build_s, setup_s, rounds })
    }

    /// The kept working buffers if they fit `n` triangles, else new ones (the old ones freed
    /// first, so that growing needs no room for both). Taken out of the builder: a build that
    /// fails drops them.
    fn work_for(&mut self, n: usize) -> Result<Work<'r>> {
        if !self.work.as_ref().is_some_and(|w| w.fits(n)) {
            self.work = None;
        }
        match self.work.take() {
            Some(w) => Ok(w),
            None => Work::new(self.rt, n),
        }
    }

    /// Fills every kept buffer with other bytes than a fresh one's zeros, as if left by an
    /// unknown earlier use (the counting sort's counts excepted: a sort leaves them zero, and
    /// `CountingSort` is built on that). For tests: a build after this must be the same. The
    /// bytes 0x7f make every index and count far out of range and every coordinate about
    /// 3.4e38, so a box united with one that was never written grows to nearly all of `f32`.
    #[doc(hidden)]
    pub fn scribble(&self) -> Result<()> {
        let Some(w) = &self.work else { return Ok(()) };
        let mut raws = vec![
            w.list.raw(), w.tree.raw(), w.codes.raw(), w.keys.raw(), w.order.raw(), w.sort.ranks.raw(), w.sort.offsets.raw(), w.sorted.raw(), w.sorted_codes.raw(),
            w.nodes2.raw(), w.boxes2.raw(), w.counts.raw(), w.parents.raw(), w.depths.raw(), w.state.raw(), w.args.raw(), w.pending.raw(),
        ];
        if let Some(o) = &w.own {
            raws.extend([o.tris.raw(), o.bvh.raw(), o.bvh_tris.raw()]);
        }
        for b in raws {
            self.rt.write_raw(b, &vec![0x7f; b.bytes() as usize])?;
        }
        self.rt.finish()
    }
}

/// A BVH the kernels built and left on the device (`Tracer::build_bvh`), as its build reports
/// it: no SAH cost (that needs the binary tree on the host: `LbvhBuilder::build`).
#[derive(Clone, Debug)]
pub struct LbvhBuild {
    /// Wide nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Depth in wide nodes.
    pub depth: usize,
    /// As `LbvhData::build_s`.
    pub build_s: f64,
    /// Seconds to allocate the working buffers, and the tracer's BVH buffers, where the kept
    /// ones did not fit (nothing is uploaded: the triangles are the tracer's).
    pub setup_s: f64,
    /// As `LbvhData::rounds`.
    pub rounds: u32,
}

pub(crate) fn check_rounds(rounds: u32) -> Result<()> {
    if rounds > MAX_TREELET_ROUNDS {
        bail!(InvalidInput: "{rounds} rounds of treelet restructuring: at most {MAX_TREELET_ROUNDS} (a fourth changed the SAH cost by under 1 % on the bench scenes)");
    }
    Ok(())
}

fn check_count(n: usize) -> Result<()> {
    if n > MAX_TRIANGLES {
        bail!(TooLarge: "{n} triangles: the kernels' BVH build takes at most 2^29");
    }
    Ok(())
}

/// A build with `rounds` rounds of treelet restructuring, and again without them where that
/// made a tree deeper than `MAX_BVH_DEPTH` levels: the tree, the seconds of both builds, and
/// the rounds of the tree; `None` where even the tree without them is too deep (`too_deep`).
fn run_rounds(rt: &dyn Runtime, w: &Work, io: &Io, n: usize, rounds: u32) -> Result<Option<(Tree, f64, u32)>> {
    let (ran, build_s) = run(rt, w, io, n, rounds)?;
    Ok(match ran {
        Ran::Tree(t) => Some((t, build_s, rounds)),
        Ran::TooDeep if rounds > 0 => match run(rt, w, io, n, 0)? {
            (Ran::Tree(t), again) => Some((t, build_s + again, 0)),
            (Ran::TooDeep, _) => None,
        },
        Ran::TooDeep => None,
    })
}

/// Why a build of a scene the kernels cannot build shallow enough fails (its buffers are
/// kept: nothing went wrong with them).
fn too_deep() -> String {
    format!("the kernels' BVH build made a tree deeper than {MAX_BVH_DEPTH} levels (the host's builder balances such scenes)")
}

/// One build of `n` (at least one) triangles with `rounds` rounds of treelet restructuring
/// (`build_with`): its outcome and seconds, from submitting the passes to their end.
fn run(rt: &dyn Runtime, w: &Work, io: &Io, n: usize, rounds: u32) -> Result<(Ran, f64)> {
    let nu = n as u32;
    let bits = cell_bits(n);
    let mut state = [0u32; STATE_WORDS];
    state[build::STATE_NODES] = 1;
    rt.write(&w.state, &state)?;
    // The root: inner node 0, or the one triangle.
    rt.write(&w.pending, &[if n == 1 { LEAF_BIT } else { 0 }])?;
    rt.finish()?;

    let t1 = Instant::now();
    let mut c = rt.begin();
    let (top, _) = range_level(nu, range_tree_shape(nu).0);
    let p = LbvhParams { count: nu, level: 0, cell_bits: bits, root: top };
    rt.dispatch(&mut c, &Boxes { params: p, tris: io.tris, list: &w.list, tree: &w.tree })?;
    record_reduce(rt, &mut c, nu, &w.tree)?;
    rt.dispatch(&mut c, &Morton { params: p, list: &w.list, tree: &w.tree, codes: &w.codes, keys: &w.keys })?;
    w.sort.record(&mut c, &w.keys, nu, &w.order)?;
    rt.dispatch(
        &mut c,
        &Refine { params: p, order: &w.order, offsets: &w.sort.offsets, codes: &w.codes, list: &w.list, sorted: &w.sorted, sorted_codes: &w.sorted_codes, tree: &w.tree },
    )?;
    record_reduce(rt, &mut c, nu, &w.tree)?;
    if n > 1 {
        rt.dispatch(&mut c, &Hierarchy { params: p, sorted_codes: &w.sorted_codes, nodes2: &w.nodes2, counts: &w.counts, parents: &w.parents })?;
        rt.dispatch(&mut c, &Bounds { params: p, nodes2: &w.nodes2, tree: &w.tree, boxes2: &w.boxes2 })?;
        for _ in 0..rounds {
            for phase in 0..3 {
                rt.dispatch(&mut c, &Depths { params: p, parents: &w.parents, depths: &w.depths })?;
                let k = Treelet {
                    params: LbvhParams { level: phase, ..p },
                    depths: &w.depths,
                    tree: &w.tree,
                    nodes2: &w.nodes2,
                    boxes2: &w.boxes2,
                    counts: &w.counts,
                    parents: &w.parents,
                };
                rt.dispatch(&mut c, &k)?;
            }
        }
    }
    for level in 0..MAX_BVH_DEPTH as u32 {
        rt.dispatch(&mut c, &Level { state: &w.state, args: &w.args })?;
        let k = Collapse {
            params: LbvhParams { level, ..p },
            tris: io.tris,
            sorted: &w.sorted,
            nodes2: &w.nodes2,
            boxes2: &w.boxes2,
            counts: &w.counts,
            tree: &w.tree,
            state: &w.state,
            pending: &w.pending,
            bvh: io.bvh,
            bvh_tris: io.bvh_tris,
        };
        rt.dispatch_indirect(&mut c, &k, &w.args, 0)?;
    }
    let ps = rt.read_back_of(&mut c, &w.state, STATE_WORDS)?;
    rt.submit(c)?;
    let st: Vec<u32> = cast(rt.wait(ps)?);
    let build_s = t1.elapsed().as_secs_f64();
    if st[build::STATE_ERROR_DEPTH] != 0 {
        return Ok((Ran::TooDeep, build_s));
    }
    if st[build::STATE_ERROR_QUANTISE] != 0 {
        bail!(TooLarge: "a BVH node of the kernels' build is too large to quantise");
    }
    if st[build::STATE_ERROR_NODES] != 0 {
        bail!(TooLarge: "the kernels' BVH build made more nodes than it allocated");
    }
    let (count, placed) = (st[build::STATE_NODES] as usize, st[build::STATE_TRIS] as usize);
    if placed != n || count > n {
        bail!(InvalidInput: "the kernels' BVH build placed {placed} of {n} triangles in {count} nodes");
    }
    Ok((Ran::Tree(Tree { nodes: count, leaves: st[build::STATE_LEAVES] as usize, depth: st[build::STATE_DEPTH] as usize }), build_s))
}

/// Records the range tree's levels above level 0.
fn record_reduce(rt: &dyn Runtime, c: &mut Commands, n: u32, tree: &Buffer<BuildBox>) -> Result<()> {
    for level in 1..=range_tree_shape(n).0 {
        let (_, size) = range_level(n, level);
        rt.dispatch(c, &Reduce { params: LbvhParams { count: n, level, cell_bits: 0, root: 0 }, threads: size, tree })?;
    }
    Ok(())
}

/// Builds the compressed wide BVH over `tris` with the kernels on `rt`. Fails on a vertex that
/// is not finite, more than `MAX_TRIANGLES` triangles, a tree deeper than `MAX_BVH_DEPTH`
/// levels or a box too large to quantise (`crate::bvh::try_build` builds those it can), or
/// buffers larger than the device allows.
pub fn build_on(rt: &dyn Runtime, tris: &[Triangle]) -> Result<LbvhData> {
    build_with(rt, tris, TREELET_ROUNDS)
}

/// `build_on` with `rounds` rounds of treelet restructuring (`build_on`'s default:
/// `TREELET_ROUNDS`; 0: Karras's tree as it is; at most `MAX_TREELET_ROUNDS`, more are refused),
/// to weigh tree quality against build time.
/// The cheapest topology over a run of ever smaller boxes is a chain: on such input the treelets
/// can make the tree deeper than `MAX_BVH_DEPTH` levels (a chain of 4 000 triangles shrinking by
/// 2 % each: the wide tree's depth 11 without them, more than 32 after three rounds), and the
/// build is then made again without them (`LbvhData::rounds` says so).
pub fn build_with(rt: &dyn Runtime, tris: &[Triangle], rounds: u32) -> Result<LbvhData> {
    LbvhBuilder::new(rt).build(tris, rounds)
}

/// The SAH cost of the binary tree as the collapse reads it (inner nodes of more than
/// `MAX_LEAF_TRIS` triangles cost 1 a visit, the others are leaves costing their triangles),
/// relative to the root's area, in `f64` as `crate::bvh` reports the host's.
fn binary_sah(n: usize, nodes2: &[[u32; 4]], boxes2: &[BuildBox], counts: &[u32], leaf_boxes: &[BuildBox]) -> f64 {
    let area = |b: &BuildBox| crate::bvh::surface_area(b.lo, b.hi);
    let of = |r: u32| -> (usize, BuildBox) {
        if r & LEAF_BIT != 0 {
            (1, leaf_boxes[(r & !LEAF_BIT) as usize])
        } else {
            (counts[r as usize] as usize, boxes2[r as usize])
        }
    };
    if n < 2 {
        return n as f64;
    }
    let root = area(&boxes2[0]).max(f64::MIN_POSITIVE);
    let mut cost = 0.0;
    let mut stack = vec![0u32];
    while let Some(r) = stack.pop() {
        let (s, b) = of(r);
        if s <= MAX_LEAF_TRIS {
            cost += area(&b) * s as f64;
        } else {
            cost += area(&b);
            let nd = nodes2[r as usize];
            stack.extend([nd[0], nd[1]]);
        }
    }
    cost / root
}

#[cfg(test)]
mod tests {
    use kdray_shared::bvh::build::{cheapest_topology, grid_area, table_part, AreaGrid, GridBox, TREELET_GRID_BITS, TREELET_LEAVES};
    use kdray_shared::BuildBox;

    /// `AreaGrid::snap` rounds outwards onto the grid (in f64, each snapped box holds the box),
    /// within one step, and snapping a union is the union of the snapped boxes (so a treelet's
    /// cost now equals the sum over its snapped leaves); subnormal differences snap as zero,
    /// as a GPU that flushes them computes; boxes of no extent or not finite have no grid.
    #[test]
    fn area_grids_round_outwards_and_keep_unions() {
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        for case in 0..2000 {
            let (o, size) = ([next() * 200.0 - 100.0, next() * 1e-3, -next() * 1e6], [next() * 50.0 + 1e-3, next() * 1e-4 + 1e-9, next() * 3e5 + 1.0]);
            let root = BuildBox { lo: o, hi: [o[0] + size[0], o[1] + size[1], o[2] + size[2]] };
            let g = AreaGrid::new(&root).unwrap();
            let mut inner = || {
                let (a, b) = ([next(), next(), next()], [next(), next(), next()]);
                let lo = [0, 1, 2].map(|k| root.lo[k] + (root.hi[k] - root.lo[k]) * a[k].min(b[k]));
                let hi = [0, 1, 2].map(|k| (root.lo[k] + (root.hi[k] - root.lo[k]) * a[k].max(b[k])).min(root.hi[k]));
                BuildBox { lo, hi }
            };
            let (x, y) = (inner(), inner());
            let (sx, sy, su) = (g.snap(&x), g.snap(&y), g.snap(&x.union(&y)));
            let union: GridBox = [[0, 1, 2].map(|k| sx[0][k].min(sy[0][k])), [0, 1, 2].map(|k| sx[1][k].max(sy[1][k]))];
            assert_eq!(su, union, "case {case}");
            // The grid's step: the power of two that puts the longest side within 2^bits steps.
            let m = (0..3).map(|k| root.hi[k] - root.lo[k]).fold(0.0f32, f32::max) as f64;
            let step = 2f64.powi(m.log2().ceil() as i32 - TREELET_GRID_BITS);
            assert_eq!(g.snap(&root)[0], [0; 3], "case {case}");
            for k in 0..3 {
                let (l, h) = ((x.lo[k] as f64 - root.lo[k] as f64) / step, (x.hi[k] as f64 - root.lo[k] as f64) / step);
                assert!(sx[0][k] as f64 <= l + 1e-3 && l < sx[0][k] as f64 + 1.0 + 1e-3, "case {case} axis {k}: lo {l} snapped {}", sx[0][k]);
                assert!(sx[1][k] as f64 + 1e-3 >= h && (sx[1][k] as f64) < h + 1.0 + 1e-3, "case {case} axis {k}: hi {h} snapped {}", sx[1][k]);
                assert!(sx[1][k] <= 1 << TREELET_GRID_BITS);
            }
        }
        // A subnormal difference (from a root at 0) snaps as zero; a huge root's tiny product too.
        let root = BuildBox { lo: [0.0; 3], hi: [1e-30, 1e-30, 1e-30] };
        let g = AreaGrid::new(&root).unwrap();
        let sub = f32::from_bits(5);
        assert_eq!(g.snap(&BuildBox { lo: [sub; 3], hi: [sub; 3] }), [[0; 3]; 2]);
        let root = BuildBox { lo: [-3e38; 3], hi: [3e38; 3] };
        assert!(AreaGrid::new(&root).is_none(), "an extent past f32::MAX");
        let root = BuildBox { lo: [0.0; 3], hi: [1e38; 3] };
        let g = AreaGrid::new(&root).unwrap();
        assert_eq!(g.snap(&BuildBox { lo: [0.0; 3], hi: [1e-4; 3] }), [[0; 3], [0; 3]], "a subnormal product");
        assert_eq!(g.snap(&BuildBox { lo: [0.0; 3], hi: [1e36; 3] }), [[0; 3], [13; 3]], "1e36 is 12.04 steps of 2^116");
        assert!(AreaGrid::new(&BuildBox { lo: [1.0; 3], hi: [1.0; 3] }).is_none());
        assert!(AreaGrid::new(&BuildBox { lo: [0.0; 3], hi: [sub; 3] }).is_none());
    }

    /// Every rooted binary tree over `m` leaves, built by inserting the leaves one at a time on
    /// every edge ((2m − 3)!! trees), each as the leaf sets of its inner nodes.
    fn all_trees(m: usize) -> Vec<Vec<u32>> {
        #[derive(Clone)]
        enum T {
            Leaf(usize),
            Node(Box<T>, Box<T>),
        }
        fn insert(t: &T, k: usize) -> Vec<T> {
            let mut out = vec![T::Node(Box::new(t.clone()), Box::new(T::Leaf(k)))];
            if let T::Node(a, b) = t {
                for x in insert(a, k) {
                    out.push(T::Node(Box::new(x), b.clone()));
                }
                for x in insert(b, k) {
                    out.push(T::Node(a.clone(), Box::new(x)));
                }
            }
            out
        }
        fn sets(t: &T, out: &mut Vec<u32>) -> u32 {
            match t {
                T::Leaf(k) => 1 << k,
                T::Node(a, b) => {
                    let s = sets(a, out) | sets(b, out);
                    out.push(s);
                    s
                }
            }
        }
        let mut trees = vec![T::Leaf(0)];
        for k in 1..m {
            trees = trees.iter().flat_map(|t| insert(t, k)).collect();
        }
        trees
            .iter()
            .map(|t| {
                let mut v = Vec::new();
                sets(t, &mut v);
                v
            })
            .collect()
    }

    /// `cheapest_topology` finds the least cost of all (2m − 3)!! binary trees over 2 to 5
    /// random grid boxes (many of them ties: boxes nested or equal), and its partitions rebuild
    /// a tree of that cost.
    #[test]
    fn the_treelet_topology_is_the_cheapest_of_all_trees() {
        let mut seed = 0x9e37_79b9u32;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % n
        };
        for m in 2..=TREELET_LEAVES {
            let trees = all_trees(m);
            let expected = (1..2 * m as u64 - 2).step_by(2).product::<u64>();
            assert_eq!(trees.len() as u64, expected.max(1));
            for case in 0..60 {
                let mut boxes: [GridBox; TREELET_LEAVES] = [[[0; 3]; 2]; TREELET_LEAVES];
                for b in boxes.iter_mut().take(m) {
                    // Small coordinates for many ties; every tenth case spans the grid.
                    let top = if case % 10 == 0 { 1 << TREELET_GRID_BITS } else { 6 };
                    for a in 0..3 {
                        let (x, y) = (next(top + 1), next(top + 1));
                        *b = { let mut c = *b; c[0][a] = x.min(y); c[1][a] = x.max(y); c };
                    }
                }
                let area = |set: u32| {
                    let mut u: GridBox = [[u32::MAX; 3], [0; 3]];
                    for k in 0..m {
                        if set >> k & 1 != 0 {
                            for a in 0..3 {
                                u[0][a] = u[0][a].min(boxes[k][0][a]);
                                u[1][a] = u[1][a].max(boxes[k][1][a]);
                            }
                        }
                    }
                    grid_area(&u)
                };
                let best = trees.iter().map(|t| t.iter().map(|&s| area(s)).sum::<u32>()).min().unwrap();
                let mut table = [0u32; 1 << TREELET_LEAVES];
                let cost = cheapest_topology(&boxes, m, &mut table);
                assert_eq!(cost, best, "{m} boxes, case {case}");
                // The tree the partitions make.
                let mut rebuilt = 0u32;
                let mut todo = vec![(1u32 << m) - 1];
                while let Some(s) = todo.pop() {
                    rebuilt += area(s);
                    let p = table_part(&table, s);
                    assert!(p != 0 && p & s == p && p != s && p & (s & s.wrapping_neg()) != 0, "{m} boxes, case {case}: part {p:b} of {s:b}");
                    for h in [p, s ^ p] {
                        if h.count_ones() > 1 {
                            todo.push(h);
                        }
                    }
                }
                assert_eq!(rebuilt, cost, "{m} boxes, case {case}");
            }
        }
    }
}
