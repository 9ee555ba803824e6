//! The ray-query kernels (closest hit, any hit) as per-item functions, generic over how hits
//! are found (`Method`: brute force, a kd-tree traversal or the wide BVH's), over the query, and over the
//! grouping (one ray per item, or four per item as a packet) and pipeline (one kernel, or the
//! decomposed traverse → intersect → fallback). The shader crate instantiates each as an entry
//! point; the host's native runtime calls the very same functions.
use crate::aabb::Aabb;
use crate::brute::BruteForce;
use crate::bvh::Bvh;
use crate::kdtree::{intersect_leaves, record_leaves, Full, KdNode, KdTree, LeafRef, PacketTraversal, Traversal, PACKET};
use crate::kernel::Store;
use crate::parts::Parts;
use crate::pod::{TraceParams, Triangle};
use crate::query::{Answer, Near, Prims, Query};
use crate::ray::Ray;
use crate::stats::NoStats;
use core::marker::PhantomData;

/// How one ray's query is answered over the scene: the structure it searches, as the kernels
/// see it (`Accel`), and the search.
pub trait Method {
    /// The structure searched (brute force: the kd-tree view, of which it uses the triangles).
    type Accel<'a>: Copy;
    /// Answers `q` for `ray` over `accel`.
    fn find<Q: Query + BruteForce>(accel: &Self::Accel<'_>, ray: &Ray, q: &mut Q);
    /// Whether any triangle near the box `lo`..`hi` (`query::Near`: at least those whose
    /// leaves overlap it) answers `q`.
    fn near<N: Near>(accel: &Self::Accel<'_>, lo: [f32; 3], hi: [f32; 3], q: &N) -> bool;
}

/// The brute-force oracle (every triangle; the tree is not used).
pub struct Brute;
impl Method for Brute {
    type Accel<'a> = KdTree<'a>;
    #[inline(always)]
    fn find<Q: Query + BruteForce>(tree: &KdTree, ray: &Ray, q: &mut Q) {
        q.brute(ray, &tree.tris)
    }
    #[inline(always)]
    fn near<N: Near>(tree: &KdTree, _lo: [f32; 3], _hi: [f32; 3], q: &N) -> bool {
        let mut found = false;
        let mut j = 0;
        while j < tree.tris.len() {
            found |= q.test(j as u32, &tree.tris.get(j));
            j += 1;
        }
        found
    }
}

/// A kd-tree traversal.
pub struct Kd<T>(PhantomData<T>);
impl<T: Traversal> Method for Kd<T> {
    type Accel<'a> = KdTree<'a>;
    #[inline(always)]
    fn find<Q: Query + BruteForce>(tree: &KdTree, ray: &Ray, q: &mut Q) {
        T::run(tree, ray, q, &mut NoStats)
    }
    #[inline(always)]
    fn near<N: Near>(tree: &KdTree, lo: [f32; 3], hi: [f32; 3], q: &N) -> bool {
        crate::kdtree::near(tree, lo, hi, q)
    }
}

/// The compressed 8-wide BVH's traversal (`bvh::traverse`).
pub struct Wide;
impl Method for Wide {
    type Accel<'a> = Bvh<'a>;
    #[inline(always)]
    fn find<Q: Query + BruteForce>(bvh: &Bvh, ray: &Ray, q: &mut Q) {
        crate::bvh::traverse(bvh, ray, q, &mut NoStats)
    }
    #[inline(always)]
    fn near<N: Near>(bvh: &Bvh, lo: [f32; 3], hi: [f32; 3], q: &N) -> bool {
        crate::bvh::near(bvh, lo, hi, q)
    }
}

/// The scene as the kernels see it: the entry points build it from their bindings and the
/// parameters' scene box, and pass it to the per-item functions below.
#[inline(always)]
pub fn tree<'a>(p: &TraceParams, tris: Parts<'a, Triangle>, nodes: Parts<'a, KdNode>, prims: Parts<'a, u32>) -> KdTree<'a> {
    KdTree { nodes, prims, tris, bounds: Aabb { min: p.bounds_min, max: p.bounds_max } }
}

/// Ray `i`: answers `Q` with `M` into `out[i]`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn trace<M: Method, Q: Query + BruteForce + Answer, O: Store<Q::Out> + ?Sized>(
    i: u32,
    p: &TraceParams,
    rays: &[Ray],
    t: &M::Accel<'_>,
    out: &mut O,
) {
    if i < p.count {
        let ray = &rays[i as usize];
        let mut q = Q::new(ray);
        M::find(t, ray, &mut q);
        out.store(i as usize, q.answer());
    }
}

/// Thread `i` traces rays 4i..4i+3 as a packet (Horn et al.) when their direction signs agree,
/// else one by one. Rays past the end of the batch are invalid (misses, never written).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn trace_packet<T: PacketTraversal, Q: Query + Answer, O: Store<Q::Out> + ?Sized>(
    i: u32,
    p: &TraceParams,
    rays: &[Ray],
    t: &KdTree,
    out: &mut O,
) {
    let first = i * PACKET as u32;
    if first < p.count {
        let r = packet_rays::<PACKET>(p, rays, first);
        let mut qs = [Q::new(&r[0]), Q::new(&r[1]), Q::new(&r[2]), Q::new(&r[3])];
        T::run_packet(t, &r, &mut qs, &mut NoStats);
        let mut l = 0;
        while l < PACKET as u32 {
            if first + l < p.count {
                out.store((first + l) as usize, qs[l as usize].answer());
            }
            l += 1;
        }
    }
}

/// Rays `first..first + W` as one packet through the wide BVH (`bvh::traverse_packet`), or one
/// by one where it declines them; rays past the end of the batch are invalid (misses, never
/// written). The native runtime's `bvh+packets`: eight rays (two work items) where it has both
/// items, else four (the GPU kernel traces each item's four rays one by one).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn trace_bvh_packet<Q: Query + Answer + Copy, O: Store<Q::Out> + ?Sized, const W: usize>(
    first: u32,
    p: &TraceParams,
    rays: &[Ray],
    bvh: &Bvh,
    out: &mut O,
) {
    if first < p.count {
        let r = packet_rays::<W>(p, rays, first);
        let mut qs = [Q::new(&r[0]); W];
        let mut l = 1;
        while l < W {
            qs[l] = Q::new(&r[l]);
            l += 1;
        }
        crate::bvh::packet_or_single(bvh, &r, &mut qs, &mut NoStats);
        let mut l = 0;
        while l < W as u32 {
            if first + l < p.count {
                out.store((first + l) as usize, qs[l as usize].answer());
            }
            l += 1;
        }
    }
}

/// Rays `first..first + W`; past the end of the batch, invalid rays (misses, never written).
/// (A function returning the array: written inline, the packet kernels' closest-hit primary
/// rays ran 5–7 % slower on the H100 — one local copy fewer in the SPIR-V, otherwise the same.)
#[inline(always)]
fn packet_rays<const W: usize>(p: &TraceParams, rays: &[Ray], first: u32) -> [Ray; W] {
    let mut r = [Ray::default(); W];
    let mut l = 0;
    while l < W as u32 {
        if first + l < p.count {
            r[l as usize] = rays[(first + l) as usize];
        }
        l += 1;
    }
    r
}

/// Decomposed pipeline, step 1: ray `i`'s non-empty leaves (full-stack traversal) into
/// `lists[i · cap ..]`, the count and overflow bit into `status[i]`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn traverse_leaves<L: Store<LeafRef> + ?Sized, St: Store<u32> + ?Sized>(
    i: u32,
    p: &TraceParams,
    rays: &[Ray],
    t: &KdTree,
    lists: &mut L,
    status: &mut St,
) {
    if i < p.count {
        let cap = p.leaf_capacity;
        let l = record_leaves(t, &rays[i as usize], cap, &mut NoStats);
        let base = (i * cap) as usize;
        let mut k = 0;
        while k < l.len {
            lists.store(base + k as usize, l.entries[k as usize]);
            k += 1;
        }
        status.store(i as usize, l.status());
    }
}

/// Decomposed pipeline, step 2: `Q` over ray `i`'s listed leaves (the tree's primitive index
/// list and triangles `g`). Leaves `status[i]` = 1 where
/// the list overflowed without settling the query (0 elsewhere) for `fallback`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn intersect_listed<Q: Query + Answer, St: Store<u32> + ?Sized, O: Store<Q::Out> + ?Sized>(
    i: u32,
    p: &TraceParams,
    rays: &[Ray],
    g: &Prims,
    lists: &[LeafRef],
    status: &mut St,
    out: &mut O,
) {
    if i < p.count {
        let k = i as usize;
        let ray = &rays[k];
        let mut q = Q::new(ray);
        let settled = intersect_leaves(g, ray, lists, k * p.leaf_capacity as usize, status.load(k), &mut q, &mut NoStats);
        status.store(k, !settled as u32);
        out.store(k, q.answer());
    }
}

/// Decomposed pipeline, step 3: rays whose list overflowed unsettled (`status[i]` ≠ 0) are
/// traced whole with the full-stack traversal; never dropped.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn fallback<Q: Query + Answer, O: Store<Q::Out> + ?Sized>(
    i: u32,
    p: &TraceParams,
    rays: &[Ray],
    t: &KdTree,
    status: &[u32],
    out: &mut O,
) {
    if i < p.count && status[i as usize] != 0 {
        let ray = &rays[i as usize];
        let mut q = Q::new(ray);
        Full::run(t, ray, &mut q, &mut NoStats);
        out.store(i as usize, q.answer());
    }
}
