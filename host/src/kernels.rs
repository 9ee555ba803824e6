//! Every kernel family, declared once on the host: a struct of named, typed buffers and the
//! family's parameters, implementing `runtime::Kernel`. The same value runs on both runtimes:
//! its `entry` names the SPIR-V entry point (whose bindings the GPU runtime checks these against),
//! its `run` calls the `kdray-shared` per-item function that the entry point calls.
//!
//! Adding a kernel: a per-item function in `shared/src/<capability>.rs`, a thin entry point in
//! `shader-crate/src/<capability>.rs`, and a struct here with `entry`, `bindings` and `run`
//! (see `RngFill`, the smallest).
use crate::runtime::{read, read_split, write, Bind, Buffer, Draw, HostStore, Kernel, SplitBuffer};
use bytemuck::Pod;
use kdray_shared::kdtree::{KdNode, KdTree, LeafRef, PacketTraversal, Traversal, WithTraversal, PACKET};
use kdray_shared::query::{AnyHit, Answer, Closest, Query};
use kdray_shared::brute::BruteForce;
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::{Bvh, BvhNode, TriWords, BVH_PACKET};
use kdray_shared::parts;
use kdray_shared::trace::{self, Brute, Kd, Method, Wide};
use kdray_shared::photon::{self, HashGrid, KdCells, PhotonWord, SortedPhotons};
use kdray_shared::raster;
use kdray_shared::kernel::Alone;
use kdray_shared::{
    render, sort, Hit, IndexParams, ItemParams, LeafCells, Light, Material, PathState, Photon, PhotonParams, PhotonPath, RasterParams, Ray,
    RenderParams, ShadeTerms, RENDER_CONTINUE, RENDER_PRIMARY_GIVEN, SortParams, TraceParams, Triangle,
};
use std::borrow::Cow;
use std::marker::PhantomData;

/// A query whose answers a kernel stores: closest hit (`Hit`) or any hit (`u32` flags).
pub trait QueryKind: Query + BruteForce + Answer<Out: Pod + Send + Sync> + Copy + Sync + 'static {
    /// Entry-point prefix (`closest`, `any`).
    const PREFIX: &'static str;
}
impl QueryKind for Closest {
    const PREFIX: &'static str = "closest";
}
impl QueryKind for AnyHit {
    const PREFIX: &'static str = "any";
}

/// The scene as the ray-query kernels bind it: the triangles and the structure's two arrays,
/// each whole or split across bindings (`SplitBuffer`).
pub struct SceneBinds<'a> {
    /// The triangles (`Hit::prim` indexes them).
    pub tris: &'a SplitBuffer<Triangle>,
    /// The acceleration structure's arrays.
    pub structure: StructureBinds<'a>,
}

/// An acceleration structure's arrays as kernels bind them.
#[derive(Copy, Clone)]
pub enum StructureBinds<'a> {
    /// The kd-tree (bound as `nodes`, `prims`; brute force binds placeholders).
    Kd {
        /// The kd-tree's nodes (`nodes[0]` is the root).
        nodes: &'a SplitBuffer<KdNode>,
        /// The primitive index list: each leaf holds a range of it, each entry an index into `tris`.
        prims: &'a SplitBuffer<u32>,
    },
    /// The compressed wide BVH (bound as `bvh`, `bvh_tris`).
    Bvh {
        /// The BVH's nodes (`nodes[0]` is the root).
        nodes: &'a SplitBuffer<BvhNode>,
        /// The triangles in leaf order, each with its scene index in `_pad`.
        tris: &'a SplitBuffer<Triangle>,
    },
}

impl<'a> SceneBinds<'a> {
    /// The kd-tree as a kernel's native twin sees it.
    ///
    /// # Safety
    /// As `Buffer::host`: only inside `Kernel::run` of a native dispatch that binds these.
    unsafe fn tree(&self, p: &TraceParams) -> KdTree<'a> {
        // SAFETY: the caller's contract.
        unsafe { KdTree::view(self, Aabb { min: p.bounds_min, max: p.bounds_max }) }
    }

    /// The triangles' and the structure's bindings, each array in its parts.
    fn binds(&self) -> Vec<Bind<'a>> {
        let (a, b) = match self.structure {
            StructureBinds::Kd { nodes, prims } => (read_split(parts::KD_NODES, nodes), read_split(parts::KD_PRIMS, prims)),
            StructureBinds::Bvh { nodes, tris } => (read_split(parts::BVH_NODES, nodes), read_split(parts::BVH_TRIS, tris)),
        };
        read_split(parts::TRIS, self.tris).into_iter().chain(a).chain(b).collect()
    }
}

/// A structure's view (`Method::Accel`) as a kernel's native twin builds it from the bound
/// buffers.
trait View<'a>: Sized {
    /// # Safety
    /// As `Buffer::host`: only inside `Kernel::run` of a native dispatch that binds `s`.
    unsafe fn view(s: &SceneBinds<'a>, bounds: Aabb) -> Self;
}

impl<'a> View<'a> for KdTree<'a> {
    unsafe fn view(s: &SceneBinds<'a>, bounds: Aabb) -> Self {
        match s.structure {
            // SAFETY: the caller's contract.
            StructureBinds::Kd { nodes, prims } => unsafe { KdTree { nodes: nodes.host(), prims: prims.host(), tris: s.tris.host(), bounds } },
            StructureBinds::Bvh { .. } => panic!("a kd-tree or brute-force kernel bound to a BVH"),
        }
    }
}

impl<'a> View<'a> for Bvh<'a> {
    unsafe fn view(s: &SceneBinds<'a>, _bounds: Aabb) -> Self {
        match s.structure {
            // SAFETY: the caller's contract.
            StructureBinds::Bvh { nodes, tris } => unsafe { Bvh { nodes: nodes.host(), tris: TriWords::parts(tris.host()) } },
            StructureBinds::Kd { .. } => panic!("a BVH kernel bound to a kd-tree"),
        }
    }
}

/// How a trace kernel finds hits: brute force, a kd traversal one ray per thread or four, or
/// the wide BVH one ray per thread or four.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum TraceMethod {
    /// Every triangle for every ray (the tree is not used).
    Brute,
    /// Kd traversal of the given algorithm, one ray per thread.
    Single(kdray_shared::kdtree::Algorithm),
    /// The packet form of the given kd traversal: four rays per thread, traversed together where
    /// their direction signs agree, else one by one.
    Packet(kdray_shared::kdtree::Algorithm),
    /// The compressed 8-wide BVH, one ray per thread.
    Bvh,
    /// The compressed 8-wide BVH in packets: four rays per thread (natively
    /// `trace::trace_bvh_packet`, two threads' rays as one packet of eight; on the GPU one by one).
    BvhPacket,
}

/// Closest-hit or any-hit queries for `params.count` rays (`trace::trace` / `trace::trace_packet`).
pub struct Trace<'a, Q: QueryKind> {
    /// Ray count (`count`) and scene box.
    pub params: TraceParams,
    /// The rays to trace, one per work item (four per work item for packets).
    pub rays: &'a Buffer<Ray>,
    /// The scene the rays are traced against.
    pub scene: SceneBinds<'a>,
    /// Written: each ray's answer (`Hit` for closest hit, 1/0 for any hit).
    pub out: &'a Buffer<Q::Out>,
    entry: String,
    packet: bool,
    cpu: TraceRun<'a, Q>,
}

/// A trace kernel's native twin over threads `ts`, with the method's view of the scene.
type TraceRun<'a, Q> = fn(&Trace<'a, Q>, std::ops::Range<u32>);

fn run_trace<'a, M: Method, Q: QueryKind>(k: &Trace<'a, Q>, ts: std::ops::Range<u32>)
where
    M::Accel<'a>: View<'a>,
{
    // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
    // bindings; thread t writes only out[t].
    let (rays, view, mut out) = unsafe { (k.rays.host(), M::Accel::view(&k.scene, Aabb { min: k.params.bounds_min, max: k.params.bounds_max }), k.out.host_store()) };
    for t in ts {
        trace::trace::<M, Q, HostStore<'a, Q::Out>>(t, &k.params, rays, &view, &mut out)
    }
}

fn run_packets<'a, T: PacketTraversal, Q: QueryKind>(k: &Trace<'a, Q>, ts: std::ops::Range<u32>) {
    // SAFETY: as `run_trace`; thread t writes only out[4t..4t+4].
    let (rays, tree, mut out) = unsafe { (k.rays.host(), k.scene.tree(&k.params), k.out.host_store()) };
    for t in ts {
        trace::trace_packet::<T, Q, HostStore<'a, Q::Out>>(t, &k.params, rays, &tree, &mut out)
    }
}

/// The BVH's packets natively: the rays of work items 2k and 2k + 1 (`BVH_PACKET` each) as one
/// packet of eight lanes (one AVX register) where both are in `ts`, else an item's alone (so
/// packets are rays 8k..8k + 8 of the batch, whatever the split).
fn run_bvh_packets<'a, Q: QueryKind>(k: &Trace<'a, Q>, ts: std::ops::Range<u32>) {
    const W: u32 = BVH_PACKET as u32;
    // SAFETY: as `run_trace`; item t writes only out[4t..4t+4] (a pair t, t + 1 of `ts`:
    // out[4t..4t+8]).
    let (rays, bvh, mut out) = unsafe { (k.rays.host(), Bvh::view(&k.scene, Aabb { min: k.params.bounds_min, max: k.params.bounds_max }), k.out.host_store()) };
    let mut t = ts.start;
    while t < ts.end {
        if t % 2 == 0 && t + 1 < ts.end {
            trace::trace_bvh_packet::<Q, HostStore<'a, Q::Out>, { 2 * BVH_PACKET }>(t * W, &k.params, rays, &bvh, &mut out);
            t += 2;
        } else {
            trace::trace_bvh_packet::<Q, HostStore<'a, Q::Out>, BVH_PACKET>(t * W, &k.params, rays, &bvh, &mut out);
            t += 1;
        }
    }
}

struct Pick<'s, Q>(bool, PhantomData<&'s Q>);
impl<'s, Q: QueryKind> WithTraversal for Pick<'s, Q> {
    type Out = TraceRun<'s, Q>;
    fn call<T: Traversal + PacketTraversal>(self) -> TraceRun<'s, Q> {
        if self.0 {
            run_packets::<T, Q>
        } else {
            run_trace::<Kd<T>, Q>
        }
    }
}

impl<'a, Q: QueryKind> Trace<'a, Q> {
    /// The kernel for query `Q` found by `method`: entry point `<Q::PREFIX>_<method.suffix()>`
    /// (e.g. `closest_stack`) and the matching native function.
    pub fn new(method: TraceMethod, params: TraceParams, rays: &'a Buffer<Ray>, scene: SceneBinds<'a>, out: &'a Buffer<Q::Out>) -> Self {
        use kdray_shared::kdtree::with_traversal;
        let (packet, cpu): (bool, TraceRun<'a, Q>) = match method {
            TraceMethod::Brute => (false, run_trace::<Brute, Q>),
            TraceMethod::Single(a) => (false, with_traversal(a, Pick::<'a, Q>(false, PhantomData))),
            TraceMethod::Packet(a) => (true, with_traversal(a, Pick::<'a, Q>(true, PhantomData))),
            TraceMethod::Bvh => (false, run_trace::<Wide, Q>),
            TraceMethod::BvhPacket => (true, run_bvh_packets::<Q>),
        };
        Trace { params, rays, scene, out, entry: format!("{}_{}", Q::PREFIX, method.suffix()), packet, cpu }
    }
}

impl TraceMethod {
    /// The entry-point suffix (`brute`, `stack`, …, `packet_shortstack3`).
    pub fn suffix(self) -> String {
        match self {
            TraceMethod::Brute => "brute".into(),
            TraceMethod::Single(a) => kernel_suffix(a),
            TraceMethod::Packet(a) => format!("packet_{}", kernel_suffix(a)),
            TraceMethod::Bvh => "bvh".into(),
            TraceMethod::BvhPacket => "packet_bvh".into(),
        }
    }
}

/// The entry-point suffix of a kd traversal (`stack`, `restart`, `pushdown`, `shortstackN`).
pub fn kernel_suffix(a: kdray_shared::kdtree::Algorithm) -> String {
    use kdray_shared::kdtree::Algorithm::*;
    match a {
        Stack => "stack".into(),
        Restart => "restart".into(),
        PushDown => "pushdown".into(),
        ShortStack(n) => format!("shortstack{n}"),
    }
}

impl<Q: QueryKind> Kernel for Trace<'_, Q> {
    fn entry(&self) -> Cow<'static, str> {
        self.entry.clone().into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("rays", self.rays)];
        b.extend(self.scene.binds());
        b.push(write("out", self.out));
        b
    }
    fn threads(&self) -> u32 {
        if self.packet {
            // Four rays per item for either structure's packets.
            const _: () = assert!(PACKET == BVH_PACKET);
            self.params.count.div_ceil(PACKET as u32)
        } else {
            self.params.count
        }
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        (self.cpu)(self, ts)
    }
}

/// Decomposed pipeline, step 1: leaf lists (`trace::traverse_leaves`).
pub struct TraverseLeaves<'a> {
    /// Ray count, leaf-list capacity (`leaf_capacity`) and scene box.
    pub params: TraceParams,
    /// The rays, one per work item.
    pub rays: &'a Buffer<Ray>,
    /// The scene the rays traverse.
    pub scene: SceneBinds<'a>,
    /// Written: each ray's non-empty leaves in traversal order, `params.leaf_capacity` entries
    /// per ray (ray i's from `i · leaf_capacity`).
    pub lists: &'a Buffer<LeafRef>,
    /// Written: each ray's entry count, plus `LEAF_OVERFLOW` if its list is incomplete.
    pub status: &'a Buffer<u32>,
}

impl Kernel for TraverseLeaves<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "traverse_leaves".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("rays", self.rays)];
        b.extend(self.scene.binds());
        b.extend([write("lists", self.lists), write("status", self.status)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            let tree = self.scene.tree(&self.params);
            trace::traverse_leaves(t, &self.params, self.rays.host(), &tree, &mut self.lists.host_store(), &mut self.status.host_store())
        }
    }
}

/// Decomposed pipeline, step 2: the listed leaves (`trace::intersect_listed`).
pub struct IntersectListed<'a, Q: QueryKind> {
    /// Ray count, leaf-list capacity and scene box (as for `TraverseLeaves`).
    pub params: TraceParams,
    /// The rays, one per work item.
    pub rays: &'a Buffer<Ray>,
    /// The scene whose listed leaves are tested.
    pub scene: SceneBinds<'a>,
    /// The leaf lists `TraverseLeaves` wrote.
    pub lists: &'a Buffer<LeafRef>,
    /// Read and written: `TraverseLeaves`' status in; out 1 where the list overflowed without
    /// settling the query (for `Fallback`), else 0.
    pub status: &'a Buffer<u32>,
    /// Written: each ray's answer (`Hit` or 1/0) over its listed leaves.
    pub out: &'a Buffer<Q::Out>,
}

impl<Q: QueryKind> Kernel for IntersectListed<'_, Q> {
    fn entry(&self) -> Cow<'static, str> {
        format!("{}_leaves", Q::PREFIX).into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("rays", self.rays)];
        b.extend(self.scene.binds());
        b.extend([read("lists", self.lists), write("status", self.status), write("out", self.out)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            let tree = self.scene.tree(&self.params);
            trace::intersect_listed::<Q, _, _>(t, &self.params, self.rays.host(), &tree.prims(), self.lists.host(), &mut self.status.host_store(), &mut self.out.host_store())
        }
    }
}

/// Decomposed pipeline, step 3: rays whose list overflowed unsettled (`trace::fallback`).
pub struct Fallback<'a, Q: QueryKind> {
    /// Ray count and scene box.
    pub params: TraceParams,
    /// The rays, one per work item.
    pub rays: &'a Buffer<Ray>,
    /// The scene the rays are traced against again.
    pub scene: SceneBinds<'a>,
    /// The statuses `IntersectListed` left: non-zero for the rays to trace again.
    pub status: &'a Buffer<u32>,
    /// Written: the answer of each ray traced again (full-stack traversal); other rays' answers
    /// are left as they are.
    pub out: &'a Buffer<Q::Out>,
}

impl<Q: QueryKind> Kernel for Fallback<'_, Q> {
    fn entry(&self) -> Cow<'static, str> {
        format!("{}_fallback", Q::PREFIX).into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("rays", self.rays)];
        b.extend(self.scene.binds());
        b.extend([read("status", self.status), write("out", self.out)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            let tree = self.scene.tree(&self.params);
            trace::fallback::<Q, _>(t, &self.params, self.rays.host(), &tree, self.status.host(), &mut self.out.host_store())
        }
    }
}

/// Primary rays and fresh paths (`render::camera_rays`).
pub struct CameraRays<'a> {
    /// The batch (`count` paths from `first`), camera, seed and flags.
    pub params: RenderParams,
    /// Written: each path's primary ray.
    pub rays: &'a Buffer<Ray>,
    /// Written: each path's fresh state.
    pub paths: &'a Buffer<PathState>,
}

/// Paths resume from their gather points by one diffuse bounce, the final gather
/// (`render::continue_paths`), for the per-bounce schedule.
pub struct ContinuePaths<'a> {
    /// The batch and the continuation's seed.
    pub params: RenderParams,
    /// Read and written: each path's gather point, replaced by its next ray.
    pub rays: &'a Buffer<Ray>,
    /// Read and written: each path's state.
    pub paths: &'a Buffer<PathState>,
}

impl Kernel for ContinuePaths<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "continue_paths".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![write("rays", self.rays), write("paths", self.paths)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements.
        unsafe { render::continue_paths(t, &self.params, &mut self.rays.host_store(), &mut self.paths.host_store()) }
    }
}

impl Kernel for CameraRays<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "camera_rays".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![write("rays", self.rays), write("paths", self.paths)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            render::camera_rays(t, &self.params, &mut self.rays.host_store(), &mut self.paths.host_store())
        }
    }
}

/// One bounce of every path: reflect or shade (`render::path_step`).
pub struct PathStep<'a> {
    /// The batch and the bounce being shaded (`bounce`).
    pub params: RenderParams,
    /// Read and written: each active path's ray; replaced by its next ray, its gather point, or no ray
    /// when the path ends.
    pub rays: &'a Buffer<Ray>,
    /// The scene's triangles.
    pub tris: &'a SplitBuffer<Triangle>,
    /// Each path's closest hit at this bounce.
    pub hits: &'a Buffer<Hit>,
    /// The materials (`Triangle::material` indexes them).
    pub materials: &'a Buffer<Material>,
    /// The lights to sample (`params.light_count` of them).
    pub lights: &'a Buffer<Light>,
    /// Read and written: each path's state.
    pub paths: &'a Buffer<PathState>,
    /// Written: each path's shadow ray (no ray if none).
    pub shadow_rays: &'a Buffer<Ray>,
    /// Written: each path's shaded terms, to add once the shadow ray's answer is known.
    pub terms: &'a Buffer<ShadeTerms>,
}

impl Kernel for PathStep<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "path_step".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![write("rays", self.rays)];
        b.extend(read_split(parts::TRIS, self.tris));
        b.extend([
            read("hits", self.hits),
            read("materials", self.materials),
            read("lights", self.lights),
            write("paths", self.paths),
            write("shadow_rays", self.shadow_rays),
            write("terms", self.terms),
        ]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            render::path_step(
                t,
                &self.params,
                &mut self.rays.host_store(),
                &self.tris.host(),
                self.hits.host(),
                self.materials.host(),
                self.lights.host(),
                &mut self.paths.host_store(),
                &mut self.shadow_rays.host_store(),
                &mut self.terms.host_store(),
            )
        }
    }
}

/// Adds the shaded terms of every path (`render::accumulate`).
pub struct Accumulate<'a> {
    /// The batch (`count` paths).
    pub params: RenderParams,
    /// Each path's shaded terms (`PathStep`).
    pub terms: &'a Buffer<ShadeTerms>,
    /// Each shadow ray's any-hit answer: non-zero if blocked.
    pub occluded: &'a Buffer<u32>,
    /// Read and written: each path's state; its radiance gains `base`, plus `direct` unless occluded.
    pub paths: &'a Buffer<PathState>,
}

impl Kernel for Accumulate<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "accumulate".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("terms", self.terms), read("occluded", self.occluded), write("paths", self.paths)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            render::accumulate(t, &self.params, self.terms.host(), self.occluded.host(), &mut self.paths.host_store())
        }
    }
}

/// Adds every path's radiance to the film (`render::film`).
pub struct Film<'a> {
    /// The batch: pixels, samples per pixel, and the sample group (`sample`: 0 writes the film,
    /// later groups add to it).
    pub params: RenderParams,
    /// The batch's paths: sample s of pixel i at `s · pixels + i`.
    pub paths: &'a Buffer<PathState>,
    /// Written: each pixel's radiance sum (RGB) and, fourth, its sample count.
    pub radiance: &'a Buffer<[f32; 4]>,
}

impl Kernel for Film<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "film".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("paths", self.paths), write("radiance", self.radiance)]
    }
    fn threads(&self) -> u32 {
        self.params.pixels()
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes radiance[t] only.
        unsafe { render::film(t, &self.params, self.paths.host(), &mut self.radiance.host_store()) }
    }
}

/// Four numbers of each random stream (`render::rng_fill`).
pub struct RngFill<'a> {
    /// Items (`count`), first stream (`first`) and seed.
    pub params: ItemParams,
    /// Written: four numbers of stream `first + i` for item i.
    pub out: &'a Buffer<[u32; 4]>,
}

impl<'a> RngFill<'a> {
    /// `count` items: the streams `first..first + count` of `seed`.
    pub fn new(count: u32, first: u32, seed: u32, out: &'a Buffer<[u32; 4]>) -> Self {
        RngFill { params: ItemParams { count, first, seed, _pad: 0 }, out }
    }
}

impl Kernel for RngFill<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "rng_fill".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![write("out", self.out)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t reads and writes only its own elements of what it writes.
        unsafe {
            render::rng_fill(t, &self.params, &mut self.out.host_store())
        }
    }
}

/// Counting sort, pass 1: each item's rank among its key's, by the histogram of keys
/// (`sort::count_rank`).
pub struct CountRank<'a> {
    /// Items (`count`) and cells (`cells`).
    pub params: SortParams,
    /// Each item's key (cell).
    pub keys: &'a Buffer<u32>,
    /// Added to atomically: items per key (keys ≥ `params.cells` are left out).
    pub counts: &'a Buffer<u32>,
    /// Added to atomically when keys come by segments (`params.segment` > 0): keys per segment
    /// that hold items (`sort::rank`).
    pub segments: &'a Buffer<u32>,
    /// Written: each counted item's rank among its key's.
    pub ranks: &'a Buffer<u32>,
}

impl Kernel for CountRank<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "count_rank".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("keys", self.keys), write("counts", self.counts), write("segments", self.segments), write("ranks", self.ranks)]
    }
    fn threads(&self) -> u32 {
        // Item 0 runs even without items: it zeroes the total (`sort::start`).
        self.params.count.max(1)
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; items add to `counts` and `segments` atomically and write ranks[t]
        // only, and item 0 the total (a word of `segments` no item adds to in this pass).
        unsafe {
            let (mut counts, mut segments) = (self.counts.host_store(), self.segments.host_store());
            sort::count_rank(t, &self.params, self.keys.host(), &mut counts, &mut segments, &mut self.ranks.host_store())
        }
    }
}

/// Counting sort, pass 3: the exclusive prefix sums of the top level, by one item
/// (`sort::scan_top`).
pub struct ScanTop<'a> {
    /// The level's elements (`cells`).
    pub params: SortParams,
    /// The top level's sums.
    pub input: &'a Buffer<u32>,
    /// Written: their exclusive prefix sums.
    pub output: &'a Buffer<u32>,
}

impl Kernel for ScanTop<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "scan_top".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("input", self.input), write("output", self.output)]
    }
    fn threads(&self) -> u32 {
        1
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; only item 0 writes.
        unsafe { sort::scan_top(t, &self.params, self.input.host(), &mut self.output.host_store()) }
    }
}

/// Counting sort, pass 4: one level down, each element gets its exclusive prefix sum
/// (`sort::exclusive_level`).
pub struct ExclusiveLevel<'a> {
    /// The level's elements (`cells`).
    pub params: SortParams,
    /// The level's sums.
    pub input: &'a Buffer<u32>,
    /// The exclusive prefix sums of the level above (one per chunk of this level).
    pub above: &'a Buffer<u32>,
    /// Written: this level's exclusive prefix sums.
    pub output: &'a Buffer<u32>,
}

impl Kernel for ExclusiveLevel<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "exclusive_level".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("input", self.input), read("above", self.above), write("output", self.output)]
    }
    fn threads(&self) -> u32 {
        self.params.cells
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes output[t] only.
        unsafe { sort::exclusive_level(t, &self.params, self.input.host(), self.above.host(), &mut self.output.host_store()) }
    }
}

/// Counting sort, pass 2: one level up, the sums of chunks of a level (`sort::chunk_sums`).
pub struct ChunkSums<'a> {
    /// Elements (`cells`) of the level summed.
    pub params: SortParams,
    /// The level: items per cell (`CountKeys`), or the sums of the level below.
    pub counts: &'a Buffer<u32>,
    /// Written: the sum of each chunk of `CHUNK` consecutive elements.
    pub sums: &'a Buffer<u32>,
}

impl Kernel for ChunkSums<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "chunk_sums".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("counts", self.counts), write("sums", self.sums)]
    }
    fn threads(&self) -> u32 {
        sort::chunks(self.params.cells)
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes sums[t] only.
        unsafe { sort::chunk_sums(t, &self.params, self.counts.host(), &mut self.sums.host_store()) }
    }
}

/// Counting sort, exact offsets at the bottom level (`sort::exclusive`).
pub struct ExclusiveOffsets<'a> {
    /// Cells (`cells`).
    pub params: SortParams,
    /// Items per cell (`CountRank`).
    pub counts: &'a Buffer<u32>,
    /// The exclusive prefix sums of the chunks of counts (`ExclusiveLevel` or `ScanTop`).
    pub above: &'a Buffer<u32>,
    /// Written: each cell's first slot (`cells + 1` entries; the last is every item counted).
    pub offsets: &'a Buffer<u32>,
}

impl Kernel for ExclusiveOffsets<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "exclusive_offsets".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("counts", self.counts), read("above", self.above), write("offsets", self.offsets)]
    }
    fn threads(&self) -> u32 {
        self.params.cells + 1
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes offsets[t] only.
        unsafe { sort::exclusive(t, &self.params, self.counts.host(), self.above.host(), &mut self.offsets.host_store()) }
    }
}

/// Counting sort, offsets by segments of `params.segment` keys (`sort::segment_offsets`).
pub struct SegmentOffsets<'a> {
    /// Keys (`cells`, a multiple of `segment`) and keys per segment (`segment`).
    pub params: SortParams,
    /// Items per key (`CountRank`).
    pub counts: &'a Buffer<u32>,
    /// Keys per segment that hold items (`CountRank`), marked as the offsets are written; then the total
    /// (`sort::total_slot`), added to atomically: the items of the segments placed so far.
    pub segments: &'a Buffer<u32>,
    /// Written: `segment + 1` offsets per segment that holds items (`sort::segment_slot`), and
    /// zeroed for one that held items in an earlier sort but none now.
    pub offsets: &'a Buffer<u32>,
}

impl Kernel for SegmentOffsets<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "segment_offsets".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("counts", self.counts), write("segments", self.segments), write("offsets", self.offsets)]
    }
    /// `SEGMENT_LANES` a block of segments (on the GPU a subgroup takes a block; natively an
    /// item, the other items have none).
    fn threads(&self) -> u32 {
        sort::segment_blocks(&self.params).saturating_mul(sort::SEGMENT_LANES)
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t, a subgroup of one lane, writes its blocks' segments' marks and offsets
        // only and adds to the total atomically.
        unsafe { sort::segment_offsets(t, self.threads(), &Alone, &self.params, self.counts.host(), &mut self.segments.host_store(), &mut self.offsets.host_store()) }
    }
}

/// Counting sort, last pass: every item to its slot, its key's offset plus its rank
/// (`sort::scatter`).
pub struct ScatterKeys<'a> {
    /// Items (`count`), cells (`cells`) and keys per segment (`segment`, 0 for exact offsets).
    pub params: SortParams,
    /// Each item's key (cell).
    pub keys: &'a Buffer<u32>,
    /// Each counted item's rank among its key's (`CountRank`).
    pub ranks: &'a Buffer<u32>,
    /// The keys' offsets (`ExclusiveOffsets` or `SegmentOffsets`).
    pub offsets: &'a Buffer<u32>,
    /// Items per key (`CountRank`): zeroed for the next sort, each by its key's first item.
    pub counts: &'a Buffer<u32>,
    /// Written: the item indices in key order.
    pub order: &'a Buffer<u32>,
}

impl Kernel for ScatterKeys<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "scatter_keys".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("keys", self.keys), read("ranks", self.ranks), read("offsets", self.offsets), write("counts", self.counts), write("order", self.order)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; ranks make every item's slot its own, and only a key's item of rank
        // 0 writes its count.
        unsafe { sort::scatter(t, &self.params, self.keys.host(), self.ranks.host(), self.offsets.host(), &mut self.counts.host_store(), &mut self.order.host_store()) }
    }
}

/// Photons leave the lights (`photon::emit`).
pub struct EmitPhotons<'a> {
    /// The dispatch's photons (`count` from `first` of the pass), photons per pass (`emitted`),
    /// seed, spread and light count.
    pub params: PhotonParams,
    /// The lights to emit from (`params.light_count` of them).
    pub lights: &'a Buffer<Light>,
    /// Written: each photon's ray.
    pub rays: &'a Buffer<Ray>,
    /// Written: each photon's power and state.
    pub paths: &'a Buffer<PhotonPath>,
}

impl Kernel for EmitPhotons<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "emit_photons".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("lights", self.lights), write("rays", self.rays), write("paths", self.paths)]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes rays[t] and paths[t] only.
        unsafe { photon::emit(t, &self.params, self.lights.host(), &mut self.rays.host_store(), &mut self.paths.host_store()) }
    }
}

/// One bounce of every photon: store, continue or absorb (`photon::bounce`).
pub struct PhotonBounce<'a> {
    /// The dispatch's photons, the bounce (`bounce`), record capacity (`capacity`), seed and flags.
    pub params: PhotonParams,
    /// Read and written: each active photon's ray; replaced by its next ray, or no ray when absorbed.
    pub rays: &'a Buffer<Ray>,
    /// Each photon's closest hit at this bounce.
    pub hits: &'a Buffer<Hit>,
    /// The scene's triangles.
    pub tris: &'a SplitBuffer<Triangle>,
    /// The materials (`Triangle::material` indexes them).
    pub materials: &'a Buffer<Material>,
    /// Read and written: each photon's power and state.
    pub paths: &'a Buffer<PhotonPath>,
    /// Written: the stored photon records, each in a slot taken from `counter`.
    pub photons: &'a Buffer<Photon>,
    /// Added to atomically: `counter[0]` counts every photon to store, including those past
    /// `params.capacity` (which are not stored).
    pub counter: &'a Buffer<u32>,
}

impl Kernel for PhotonBounce<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "photon_bounce".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![write("rays", self.rays), read("hits", self.hits)];
        b.extend(read_split(parts::TRIS, self.tris));
        b.extend([read("materials", self.materials), write("paths", self.paths), write("photons", self.photons), write("counter", self.counter)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes its own ray and path, the photon slot it took from the
        // counter atomically, and adds to the counter atomically.
        unsafe {
            photon::bounce(
                t,
                &self.params,
                &mut self.rays.host_store(),
                self.hits.host(),
                &self.tris.host(),
                self.materials.host(),
                &mut self.paths.host_store(),
                &mut self.photons.host_store(),
                &mut self.counter.host_store(),
            )
        }
    }
}

/// Which photon index the index and gather kernels use: the hashed grid, or the kd-tree's
/// leaves (its nodes and per-node cell table).
#[derive(Copy, Clone)]
pub enum IndexBinds<'a> {
    /// The hashed uniform grid (no buffers).
    Grid,
    /// The geometry kd-tree's leaves, subdivided into cells.
    Kd {
        /// The geometry kd-tree's nodes.
        nodes: &'a Buffer<kdray_shared::kdtree::KdNode>,
        /// Each node's cells, indexed like `nodes` (interior nodes' have `dims` 0).
        leaves: &'a Buffer<LeafCells>,
    },
}

impl<'a> IndexBinds<'a> {
    fn suffix(&self) -> &'static str {
        match self {
            IndexBinds::Grid => "grid",
            IndexBinds::Kd { .. } => "kd",
        }
    }
    fn binds(&self) -> Vec<Bind<'a>> {
        match *self {
            IndexBinds::Grid => vec![],
            IndexBinds::Kd { nodes, leaves } => vec![read("nodes", nodes), read("leaves", leaves)],
        }
    }
}

/// The cell of every stored photon and its rank in the cell (`photon::keys`).
pub struct PhotonKeys<'a> {
    /// Photon slots (`count`), cells per map, maps, gather radii and scene box.
    pub params: IndexParams,
    /// The photon index whose cells the keys name.
    pub index: IndexBinds<'a>,
    /// The stored photon records.
    pub photons: &'a Buffer<Photon>,
    /// `counter[0]`: photons to store (`PhotonBounce`); slots from `min(counter[0], count)` on
    /// are empty.
    pub counter: &'a Buffer<u32>,
    /// Written: each slot's cell (`NO_CELL` for empty slots).
    pub keys: &'a Buffer<u32>,
    /// Added to atomically: photons per cell (zeroed by the last index's placing).
    pub counts: &'a Buffer<u32>,
    /// Added to atomically for the hashed grid: photons per block of cells (marked by the last
    /// index's offsets), then the total, which item 0 zeroes (`sort::start`).
    pub segments: &'a Buffer<u32>,
    /// Written: each placed photon's rank among its cell's.
    pub ranks: &'a Buffer<u32>,
}

impl Kernel for PhotonKeys<'_> {
    fn entry(&self) -> Cow<'static, str> {
        format!("photon_keys_{}", self.index.suffix()).into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("photons", self.photons), read("counter", self.counter)];
        b.extend(self.index.binds());
        b.extend([write("keys", self.keys), write("counts", self.counts), write("segments", self.segments), write("ranks", self.ranks)]);
        b
    }
    fn threads(&self) -> u32 {
        // Item 0 runs even without slots: it zeroes the sort's total (`sort::start`).
        self.params.count.max(1)
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes keys[t] and ranks[t] only, and adds to the counts
        // atomically; item 0 writes the total (a word of `segments` no item adds to here).
        unsafe {
            let (photons, counter, mut keys) = (self.photons.host(), self.counter.host(), self.keys.host_store());
            let (mut counts, mut segments, mut ranks) = (self.counts.host_store(), self.segments.host_store(), self.ranks.host_store());
            match self.index {
                IndexBinds::Grid => {
                    photon::keys(t, &self.params, &HashGrid::new(&self.params), photons, counter, &mut keys, &mut counts, &mut segments, &mut ranks)
                }
                IndexBinds::Kd { nodes, leaves } => {
                    let index = KdCells::new(&self.params, nodes.host(), leaves.host());
                    photon::keys(t, &self.params, &index, photons, counter, &mut keys, &mut counts, &mut segments, &mut ranks)
                }
            }
        }
    }
}

/// The stored photons in cell order (`photon::place`): each at its cell's offset plus its rank.
pub struct PlacePhotons<'a> {
    /// Photon slots (`count`), the index's kind, cells per map and maps.
    pub params: IndexParams,
    /// The stored photon records.
    pub photons: &'a Buffer<Photon>,
    /// Each slot's cell (`PhotonKeys`).
    pub keys: &'a Buffer<u32>,
    /// Each placed photon's rank among its cell's (`PhotonKeys`).
    pub ranks: &'a Buffer<u32>,
    /// The cells' offsets (`photon::offset_slot`).
    pub offsets: &'a Buffer<u32>,
    /// The sort's counts per cell: zeroed for the next index, each by its cell's first photon.
    pub counts: &'a Buffer<u32>,
    /// Written: the placed records' words (`PhotonWord`: position, normal, power) in cell
    /// order.
    pub words: &'a Buffer<PhotonWord>,
}

impl Kernel for PlacePhotons<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "place_photons".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![
            read("photons", self.photons),
            read("keys", self.keys),
            read("ranks", self.ranks),
            read("offsets", self.offsets),
            write("counts", self.counts),
            write("words", self.words),
        ]
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; ranks make every placed photon's slot its own, and only a cell's
        // photon of rank 0 writes its count.
        unsafe {
            let (mut counts, mut words) = (self.counts.host_store(), self.words.host_store());
            photon::place(t, &self.params, self.photons.host(), self.keys.host(), self.ranks.host(), self.offsets.host(), &mut counts, &mut words)
        }
    }
}

/// The photon-map estimate at every gather point, added to the path's radiance
/// (`photon::gather`).
pub struct Gather<'a> {
    /// Paths (`count`), cells per map, maps, gather radii, filter and scene box.
    pub params: IndexParams,
    /// The photon index whose cells are searched.
    pub index: IndexBinds<'a>,
    /// Each path's ray slot; at a gather point, the point (origin) and its normal (direction).
    pub rays: &'a Buffer<Ray>,
    /// The photons' words in cell order (`PlacePhotons`).
    pub words: &'a Buffer<PhotonWord>,
    /// Cell offsets into `words` (`photon::cell_range`: cell c's from its
    /// `offset_slot` s, `offsets[s]..offsets[s + 1]`).
    pub offsets: &'a Buffer<u32>,
    /// Read and written: each path's state; a path at a gather point gains the photons' radiance.
    pub paths: &'a Buffer<PathState>,
    /// The final gather's points a gather under `GATHER_LISTED` runs over (`photon::gather`;
    /// element 0 their count, then the paths).
    pub points: &'a Buffer<u32>,
    /// Written (appended to, element 0 their count, cleared before) by a gather under
    /// `GATHER_EDGES`: the points near edges, for the next level of the final gather. `count +
    /// 1` elements to list them, or one (none listed).
    pub next_points: &'a Buffer<u32>,
}

impl Kernel for Gather<'_> {
    fn entry(&self) -> Cow<'static, str> {
        format!("gather_{}", self.index.suffix()).into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("rays", self.rays), read("words", self.words), read("offsets", self.offsets)];
        b.extend(self.index.binds());
        b.extend([write("paths", self.paths), read("points", self.points), write("next_points", self.next_points)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; item t writes the path it gathers for only (paths[t], or under
        // `GATHER_LISTED` the t-th listed one: listed once each), adds to next_points[0]
        // atomically and writes the slot that returned.
        unsafe {
            let (rays, mut paths, points, mut next) = (self.rays.host(), self.paths.host_store(), self.points.host(), self.next_points.host_store());
            let sorted = SortedPhotons { words: self.words.host(), offsets: self.offsets.host() };
            match self.index {
                IndexBinds::Grid => photon::gather(t, &self.params, &HashGrid::new(&self.params), rays, &sorted, &mut paths, points, &mut next),
                IndexBinds::Kd { nodes, leaves } => {
                    let index = KdCells::new(&self.params, nodes.host(), leaves.host());
                    photon::gather(t, &self.params, &index, rays, &sorted, &mut paths, points, &mut next)
                }
            }
        }
    }
}

/// The workgroup counts of an indirect dispatch over the `counts[0]` items an earlier pass
/// counted (`kernel::dispatch_args`), for `Runtime::dispatch_indirect`; one item.
pub struct DispatchArgs<'a> {
    /// Element 0: the items.
    pub counts: &'a Buffer<u32>,
    /// Written: element 0, the workgroup counts (x, y, 1).
    pub args: &'a Buffer<[u32; 3]>,
}

impl Kernel for DispatchArgs<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "dispatch_args".into()
    }
    fn params(&self) -> &[u8] {
        &[]
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        vec![read("counts", self.counts), write("args", self.args)]
    }
    fn threads(&self) -> u32 {
        1
    }
    fn run(&self, t: u32) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds
        // its bindings; its one item writes args[0].
        unsafe {
            if t == 0 {
                kdray_shared::kernel::Store::store(&mut self.args.host_store(), 0, kdray_shared::kernel::dispatch_args(self.counts.host()[0]));
            }
        }
    }
}

/// A whole-path photon kernel's native twin over threads `ts`.
type PhotonRun<'a> = fn(&TracePhotons<'a>, std::ops::Range<u32>);

fn run_photons<'a, M: Method>(k: &TracePhotons<'a>, ts: std::ops::Range<u32>)
where
    M::Accel<'a>: View<'a>,
{
    // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
    // bindings; items write only the photon slots they take from the counter atomically.
    unsafe {
        let p = &k.params;
        let accel = M::Accel::view(&k.scene, Aabb { min: p.bounds_min, max: p.bounds_max });
        let (tris, lights, materials) = (k.scene.tris.host(), k.lights.host(), k.materials.host());
        let (mut photons, mut counter) = (k.photons.host_store(), k.counter.host_store());
        for t in ts {
            photon::trace_photons::<M, HostStore<'a, Photon>, HostStore<'a, u32>>(t, p, &accel, &tris, lights, materials, &mut photons, &mut counter)
        }
    }
}

struct PickPhotons<'s>(PhantomData<&'s ()>);
impl<'s> WithTraversal for PickPhotons<'s> {
    type Out = PhotonRun<'s>;
    fn call<T: Traversal + PacketTraversal>(self) -> PhotonRun<'s> {
        run_photons::<Kd<T>>
    }
}

/// Whole photon paths, emission to absorption (`photon::trace_photons`): one photon per thread,
/// or `params.stride` threads each tracing its share, a new photon as soon as one is absorbed;
/// brute force, a kd traversal or the BVH, one ray at a time.
pub struct TracePhotons<'a> {
    /// The dispatch's photons, photons per pass, seed, lights, bounce limit, record capacity and
    /// scene box.
    pub params: PhotonParams,
    /// The lights to emit from (`params.light_count` of them).
    pub lights: &'a Buffer<Light>,
    /// The scene the photons are traced against.
    pub scene: SceneBinds<'a>,
    /// The materials (`Triangle::material` indexes them).
    pub materials: &'a Buffer<Material>,
    /// Written: the stored photon records, each in a slot taken from `counter`.
    pub photons: &'a Buffer<Photon>,
    /// Added to atomically: `counter[0]` counts every photon to store, including those past
    /// `params.capacity` (which are not stored).
    pub counter: &'a Buffer<u32>,
    entry: String,
    cpu: PhotonRun<'a>,
}

impl<'a> TracePhotons<'a> {
    /// Entry-point prefix (`photon_paths_<method>`).
    pub const PREFIX: &'static str = "photon_paths";

    /// `None` for packets (photon paths are traced one ray at a time).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        method: TraceMethod,
        params: PhotonParams,
        lights: &'a Buffer<Light>,
        scene: SceneBinds<'a>,
        materials: &'a Buffer<Material>,
        photons: &'a Buffer<Photon>,
        counter: &'a Buffer<u32>,
    ) -> Option<Self> {
        let cpu: PhotonRun<'a> = match method {
            TraceMethod::Brute => run_photons::<Brute>,
            TraceMethod::Single(a) => kdray_shared::kdtree::with_traversal(a, PickPhotons(PhantomData)),
            TraceMethod::Bvh => run_photons::<Wide>,
            TraceMethod::Packet(_) | TraceMethod::BvhPacket => return None,
        };
        Some(TracePhotons { params, lights, scene, materials, photons, counter, entry: format!("{}_{}", Self::PREFIX, method.suffix()), cpu })
    }
}

impl Kernel for TracePhotons<'_> {
    fn entry(&self) -> Cow<'static, str> {
        self.entry.clone().into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("lights", self.lights)];
        b.extend(self.scene.binds());
        b.extend([read("materials", self.materials), write("photons", self.photons), write("counter", self.counter)]);
        b
    }
    fn threads(&self) -> u32 {
        match self.params.stride {
            0 => self.params.count,
            s => s.min(self.params.count),
        }
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        (self.cpu)(self, ts)
    }
}

/// A whole-path eye kernel's native twin over threads `ts`.
type PathRun<'a> = fn(&TracePaths<'a>, std::ops::Range<u32>);

fn run_paths<'a, M: Method, const GIVEN: bool>(k: &TracePaths<'a>, ts: std::ops::Range<u32>)
where
    M::Accel<'a>: View<'a>,
{
    // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
    // bindings; item t writes rays[t], paths[t] and primary_hits[t] only.
    unsafe {
        let b = k.scene_box.host();
        let accel = M::Accel::view(&k.scene, Aabb { min: [b[0][0], b[0][1], b[0][2]], max: [b[1][0], b[1][1], b[1][2]] });
        let (tris, materials, lights) = (k.scene.tris.host(), k.materials.host(), k.lights.host());
        let (mut rays, mut paths, mut hits) = (k.rays.host_store(), k.paths.host_store(), k.primary_hits.host_store());
        for t in ts {
            render::trace_path::<M, HostStore<'a, Ray>, HostStore<'a, PathState>, HostStore<'a, Hit>, GIVEN>(t, &k.params, &accel, &tris, materials, lights, &mut rays, &mut paths, &mut hits)
        }
    }
}

struct PickPaths<'s>(PhantomData<&'s ()>);
impl<'s> WithTraversal for PickPaths<'s> {
    type Out = PathRun<'s>;
    fn call<T: Traversal + PacketTraversal>(self) -> PathRun<'s> {
        run_paths::<Kd<T>, false>
    }
}

/// Whole eye paths, camera to end, one pixel sample per thread (`render::trace_path`): brute
/// force, a kd traversal or the BVH, one ray at a time.
pub struct TracePaths<'a> {
    /// The batch, camera, seed, lights, bounce limits and flags.
    pub params: RenderParams,
    /// The traversals' root box: min, max (`[f32; 4]` each).
    pub scene_box: &'a Buffer<[f32; 4]>,
    /// The scene the paths are traced against.
    pub scene: SceneBinds<'a>,
    /// The materials (`Triangle::material` indexes them).
    pub materials: &'a Buffer<Material>,
    /// The lights to sample (`params.light_count` of them).
    pub lights: &'a Buffer<Light>,
    /// Written: each path's last ray (its gather point, if it ended at one); with
    /// `RENDER_CONTINUE` also read first (the gather point it resumes from).
    pub rays: &'a Buffer<Ray>,
    /// Written: each path's final state (read first with `RENDER_CONTINUE`).
    pub paths: &'a Buffer<PathState>,
    /// Written: each path's closest hit at bounce 0 (not with `RENDER_CONTINUE`).
    pub primary_hits: &'a Buffer<Hit>,
    entry: String,
    cpu: PathRun<'a>,
}

impl<'a> TracePaths<'a> {
    /// Entry-point prefix (`eye_paths_<method>`).
    pub const PREFIX: &'static str = "eye_paths";
    /// Entry-point prefix of the paths from given primary hits (`RENDER_PRIMARY_GIVEN`:
    /// `eye_paths_given_<method>`, for the BVH and the kd full stack).
    pub const GIVEN_PREFIX: &'static str = "eye_paths_given";

    /// `None` for packets (paths are traced one ray at a time), and for given primary hits
    /// (`RENDER_PRIMARY_GIVEN` without `RENDER_CONTINUE`) with a method other than the BVH or
    /// the kd full stack (their paths then go pass by pass).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        method: TraceMethod,
        params: RenderParams,
        scene_box: &'a Buffer<[f32; 4]>,
        scene: SceneBinds<'a>,
        materials: &'a Buffer<Material>,
        lights: &'a Buffer<Light>,
        rays: &'a Buffer<Ray>,
        paths: &'a Buffer<PathState>,
        primary_hits: &'a Buffer<Hit>,
    ) -> Option<Self> {
        let given = params.flags & RENDER_PRIMARY_GIVEN != 0 && params.flags & RENDER_CONTINUE == 0;
        let cpu: PathRun<'a> = match (method, given) {
            (TraceMethod::Bvh, true) => run_paths::<Wide, true>,
            (TraceMethod::Single(kdray_shared::kdtree::Algorithm::Stack), true) => run_paths::<Kd<kdray_shared::kdtree::Full>, true>,
            (_, true) => return None,
            (TraceMethod::Brute, false) => run_paths::<Brute, false>,
            (TraceMethod::Single(a), false) => kdray_shared::kdtree::with_traversal(a, PickPaths(PhantomData)),
            (TraceMethod::Bvh, false) => run_paths::<Wide, false>,
            (TraceMethod::Packet(_) | TraceMethod::BvhPacket, false) => return None,
        };
        let prefix = if given { Self::GIVEN_PREFIX } else { Self::PREFIX };
        Some(TracePaths { params, scene_box, scene, materials, lights, rays, paths, primary_hits, entry: format!("{prefix}_{}", method.suffix()), cpu })
    }
}

impl Kernel for TracePaths<'_> {
    fn entry(&self) -> Cow<'static, str> {
        self.entry.clone().into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("scene_box", self.scene_box)];
        b.extend(self.scene.binds());
        b.extend([
            read("materials", self.materials),
            read("lights", self.lights),
            write("rays", self.rays),
            write("paths", self.paths),
            write("primary_hits", self.primary_hits),
        ]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        (self.cpu)(self, ts)
    }
}

/// A gather-point marking kernel's native twin over items `ts`.
type MarkRun<'a> = fn(&MarkEdges<'a>, std::ops::Range<u32>);

fn run_marks<'a, M: Method>(k: &MarkEdges<'a>, ts: std::ops::Range<u32>)
where
    M::Accel<'a>: View<'a>,
{
    // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
    // bindings; item t writes paths[t] only.
    unsafe {
        let p = &k.params;
        let accel = M::Accel::view(&k.scene, Aabb { min: p.bounds_min, max: p.bounds_max });
        let (open_edges, rays, mut paths) = (k.open_edges.host(), k.rays.host(), k.paths.host_store());
        for t in ts {
            photon::mark_edges::<M, HostStore<'a, PathState>>(t, p, &accel, open_edges, rays, &mut paths)
        }
    }
}

/// Marks the gather points whose global-map disc (radius `params.radius[0]`) reaches past
/// their surface (`photon::mark_edges`): triangles found by brute force, the kd-tree (one walk
/// for every kd traversal) or the BVH.
pub struct MarkEdges<'a> {
    /// The paths (`count`), the radius, the scene box.
    pub params: IndexParams,
    /// The scene searched.
    pub scene: SceneBinds<'a>,
    /// Each triangle's open edges (`photon::EdgeProbe`).
    pub open_edges: &'a Buffer<u32>,
    /// The paths' gather points.
    pub rays: &'a Buffer<Ray>,
    /// The paths, whose `PATH_NEAR_EDGE` bit is set or cleared.
    pub paths: &'a Buffer<PathState>,
    entry: &'static str,
    cpu: MarkRun<'a>,
}

impl<'a> MarkEdges<'a> {
    /// The kernel searching the structure `scene` binds with `method`'s structure (brute
    /// force, the kd-tree whatever its traversal, or the BVH).
    pub fn new(method: TraceMethod, params: IndexParams, scene: SceneBinds<'a>, open_edges: &'a Buffer<u32>, rays: &'a Buffer<Ray>, paths: &'a Buffer<PathState>) -> Self {
        let (entry, cpu): (&'static str, MarkRun<'a>) = match method {
            TraceMethod::Brute => ("edge_points_brute", run_marks::<Brute>),
            TraceMethod::Single(_) | TraceMethod::Packet(_) => ("edge_points_kd", run_marks::<Kd<kdray_shared::kdtree::Full>>),
            TraceMethod::Bvh | TraceMethod::BvhPacket => ("edge_points_bvh", run_marks::<Wide>),
        };
        MarkEdges { params, scene, open_edges, rays, paths, entry, cpu }
    }
}

impl Kernel for MarkEdges<'_> {
    fn entry(&self) -> Cow<'static, str> {
        self.entry.into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = self.scene.binds();
        b.extend([read("open_edges", self.open_edges), read("rays", self.rays), write("paths", self.paths)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        (self.cpu)(self, ts)
    }
}

/// Draws the camera's image of the scene's triangles with a depth test into `visible`
/// (`raster::vertex`, `raster_fragment`): per pixel, `raster::visible_value` of the triangle
/// seen through its centre, `raster::EMPTY` where none is. The native runtime has no
/// rasteriser: its twin marks every pixel `raster::UNKNOWN`, so that `RasterHits` traces every
/// ray.
pub struct RasterDraw<'a> {
    /// The camera, its projection, the triangle count and the buffer's row length.
    pub params: RasterParams,
    /// The scene's triangles.
    pub tris: &'a SplitBuffer<Triangle>,
    /// Written: the visibility buffer, `params.row_words` × the camera's height.
    pub visible: &'a Buffer<u32>,
}

impl Kernel for RasterDraw<'_> {
    fn entry(&self) -> Cow<'static, str> {
        "raster_vertex".into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b: Vec<Bind> = read_split(parts::TRIS, self.tris).into();
        b.push(write("visible", self.visible));
        b
    }
    fn threads(&self) -> u32 {
        self.params.row_words * self.params.camera.height
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
        // bindings; thread t writes visible[t] only.
        let mut out = unsafe { self.visible.host_store() };
        for t in ts {
            raster::unknown(t, &self.params, &mut out);
        }
    }
    fn draw(&self) -> Option<Draw> {
        let cam = &self.params.camera;
        Some(Draw {
            vertices: self.params.triangles * 3,
            fragment: "raster_fragment",
            width: cam.width,
            height: cam.height,
            row_words: self.params.row_words,
            target: "visible",
        })
    }
}

/// A rasterised primary-hit kernel's native twin over threads `ts`.
type RasterRun<'a> = fn(&RasterHits<'a>, std::ops::Range<u32>);

fn run_raster_hits<'a, M: Method>(k: &RasterHits<'a>, ts: std::ops::Range<u32>)
where
    M::Accel<'a>: View<'a>,
{
    // SAFETY: called by the native runtime during the dispatch of this pass, which holds its
    // bindings; thread t writes out[t] only.
    unsafe {
        let b = k.scene_box.host();
        let accel = M::Accel::view(&k.scene, Aabb { min: [b[0][0], b[0][1], b[0][2]], max: [b[1][0], b[1][1], b[1][2]] });
        let (tris, visible, mut out) = (k.scene.tris.host(), k.visible.host(), k.out.host_store());
        for t in ts {
            raster::primary_hit::<M, HostStore<'a, Hit>>(t, &k.params, &accel, &tris, visible, &mut out)
        }
    }
}

/// The closest hits of the camera's primary rays from the visibility buffer `RasterDraw` drew
/// (`raster::primary_hit`): each pixel's candidate tested, rays without a trusted one traced by
/// the BVH or the kd-tree's full stack.
pub struct RasterHits<'a> {
    /// The camera, the number of rays and the buffer's row length (as `RasterDraw`'s).
    pub params: RasterParams,
    /// The kd-tree's root box: min, max (`[f32; 4]` each).
    pub scene_box: &'a Buffer<[f32; 4]>,
    /// The scene the rays are traced against where needed.
    pub scene: SceneBinds<'a>,
    /// The visibility buffer.
    pub visible: &'a Buffer<u32>,
    /// Written: ray i's closest hit (the camera's i-th pixel, in its order).
    pub out: &'a Buffer<Hit>,
    entry: &'static str,
    cpu: RasterRun<'a>,
}

impl<'a> RasterHits<'a> {
    /// `None` for methods without a rasterised entry point (the BVH and the kd full stack
    /// have one).
    pub fn new(method: TraceMethod, params: RasterParams, scene_box: &'a Buffer<[f32; 4]>, scene: SceneBinds<'a>, visible: &'a Buffer<u32>, out: &'a Buffer<Hit>) -> Option<Self> {
        let (entry, cpu): (&'static str, RasterRun<'a>) = match method {
            TraceMethod::Bvh | TraceMethod::BvhPacket => ("primary_raster_bvh", run_raster_hits::<Wide>),
            TraceMethod::Single(kdray_shared::kdtree::Algorithm::Stack) => ("primary_raster_stack", run_raster_hits::<Kd<kdray_shared::kdtree::Full>>),
            _ => return None,
        };
        Some(RasterHits { params, scene_box, scene, visible, out, entry, cpu })
    }
}

impl Kernel for RasterHits<'_> {
    fn entry(&self) -> Cow<'static, str> {
        self.entry.into()
    }
    fn params(&self) -> &[u8] {
        bytemuck::bytes_of(&self.params)
    }
    fn bindings(&self) -> Vec<Bind<'_>> {
        let mut b = vec![read("scene_box", self.scene_box)];
        b.extend(self.scene.binds());
        b.extend([read("visible", self.visible), write("out", self.out)]);
        b
    }
    fn threads(&self) -> u32 {
        self.params.count
    }
    fn run(&self, t: u32) {
        self.run_many(t..t + 1)
    }
    fn run_many(&self, ts: std::ops::Range<u32>) {
        (self.cpu)(self, ts)
    }
}

/// The linear BVH build's kernels (`kdray_shared::bvh::build`), each over its `threads` items;
/// `crate::lbvh` records them.
pub mod lbvh {
    use super::*;
    use kdray_shared::bvh::build;
    use kdray_shared::{BuildBox, LbvhParams};

    /// Each triangle's box into the list and level 0 of the range tree (`build::boxes`).
    pub struct Boxes<'a> {
        /// Triangles (`count`).
        pub params: LbvhParams,
        /// The scene's triangles.
        pub tris: &'a Buffer<Triangle>,
        /// Written: their boxes in scene order.
        pub list: &'a Buffer<BuildBox>,
        /// Written: level 0 of the range tree (the same boxes).
        pub tree: &'a Buffer<BuildBox>,
    }

    impl Kernel for Boxes<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_boxes".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![read("tris", self.tris), write("list", self.list), write("tree", self.tree)]
        }
        fn threads(&self) -> u32 {
            self.params.count
        }
        fn run(&self, t: u32) {
            // SAFETY: the native runtime's dispatch of this pass holds its bindings; item t
            // writes element t of each output.
            unsafe { build::boxes(t, &self.params, self.tris.host(), &mut self.list.host_store(), &mut self.tree.host_store()) }
        }
    }

    /// One level of the range tree from the level below (`build::reduce`, `params.level` ≥ 1).
    pub struct Reduce<'a> {
        /// Triangles (`count`), the level, and its size as `threads`.
        pub params: LbvhParams,
        /// Items: the level's entries.
        pub threads: u32,
        /// The range tree: read below, written at the level.
        pub tree: &'a Buffer<BuildBox>,
    }

    impl Kernel for Reduce<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_reduce".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![write("tree", self.tree)]
        }
        fn threads(&self) -> u32 {
            self.threads
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; item t writes its entry of the level and reads two of the
            // level below, which no item of this dispatch writes.
            unsafe { build::reduce(t, &self.params, &mut self.tree.host_store()) }
        }
    }

    /// Morton codes and sort keys (`build::morton`).
    pub struct Morton<'a> {
        /// Triangles, the key's bits, the range tree's root.
        pub params: LbvhParams,
        /// The boxes in scene order.
        pub list: &'a Buffer<BuildBox>,
        /// The range tree (its root: the scene's box).
        pub tree: &'a Buffer<BuildBox>,
        /// Written: each triangle's 60-bit code (two halves).
        pub codes: &'a Buffer<[u32; 2]>,
        /// Written: each triangle's sort key.
        pub keys: &'a Buffer<u32>,
    }

    impl Kernel for Morton<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_morton".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![read("list", self.list), read("tree", self.tree), write("codes", self.codes), write("keys", self.keys)]
        }
        fn threads(&self) -> u32 {
            self.params.count
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`.
            unsafe { build::morton(t, &self.params, self.list.host(), self.tree.host(), &mut self.codes.host_store(), &mut self.keys.host_store()) }
        }
    }

    /// The sorted order by full codes within small cells, and level 0 of the range tree in it
    /// (`build::refine`).
    pub struct Refine<'a> {
        /// Triangles and the key's bits.
        pub params: LbvhParams,
        /// The counting sort's order (by key).
        pub order: &'a Buffer<u32>,
        /// The counting sort's offsets (exact).
        pub offsets: &'a Buffer<u32>,
        /// Each triangle's code.
        pub codes: &'a Buffer<[u32; 2]>,
        /// The boxes in scene order.
        pub list: &'a Buffer<BuildBox>,
        /// Written: the triangles in sorted order.
        pub sorted: &'a Buffer<u32>,
        /// Written: their codes.
        pub sorted_codes: &'a Buffer<[u32; 2]>,
        /// Written: level 0 of the range tree, in sorted order.
        pub tree: &'a Buffer<BuildBox>,
    }

    impl Kernel for Refine<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_refine".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![
                read("order", self.order),
                read("offsets", self.offsets),
                read("codes", self.codes),
                read("list", self.list),
                write("sorted", self.sorted),
                write("sorted_codes", self.sorted_codes),
                write("tree", self.tree),
            ]
        }
        fn threads(&self) -> u32 {
            self.params.count
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; the items of a cell take distinct ranks, so each position is
            // written once.
            unsafe {
                build::refine(
                    t,
                    &self.params,
                    self.order.host(),
                    self.offsets.host(),
                    self.codes.host(),
                    self.list.host(),
                    &mut self.sorted.host_store(),
                    &mut self.sorted_codes.host_store(),
                    &mut self.tree.host_store(),
                )
            }
        }
    }

    /// Karras's inner nodes (`build::hierarchy`).
    pub struct Hierarchy<'a> {
        /// Triangles.
        pub params: LbvhParams,
        /// The sorted codes.
        pub sorted_codes: &'a Buffer<[u32; 2]>,
        /// Written: the inner nodes.
        pub nodes2: &'a Buffer<[u32; 4]>,
        /// Written: their triangles' counts.
        pub counts: &'a Buffer<u32>,
        /// Written: each inner node's parent (the root's is not written).
        pub parents: &'a Buffer<u32>,
    }

    impl Kernel for Hierarchy<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_hierarchy".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![read("sorted_codes", self.sorted_codes), write("nodes2", self.nodes2), write("counts", self.counts), write("parents", self.parents)]
        }
        fn threads(&self) -> u32 {
            self.params.count.saturating_sub(1)
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; item t writes its node, its count and its inner children's
            // parents (each node has one parent).
            unsafe {
                build::hierarchy(
                    t,
                    &self.params,
                    self.sorted_codes.host(),
                    &mut self.nodes2.host_store(),
                    &mut self.counts.host_store(),
                    &mut self.parents.host_store(),
                )
            }
        }
    }

    /// The inner nodes' boxes (`build::bounds`).
    pub struct Bounds<'a> {
        /// Triangles.
        pub params: LbvhParams,
        /// The inner nodes.
        pub nodes2: &'a Buffer<[u32; 4]>,
        /// The range tree over the sorted boxes.
        pub tree: &'a Buffer<BuildBox>,
        /// Written: each inner node's box.
        pub boxes2: &'a Buffer<BuildBox>,
    }

    impl Kernel for Bounds<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_bounds".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![read("nodes2", self.nodes2), read("tree", self.tree), write("boxes2", self.boxes2)]
        }
        fn threads(&self) -> u32 {
            self.params.count.saturating_sub(1)
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`.
            unsafe { build::bounds(t, &self.params, self.nodes2.host(), self.tree.host(), &mut self.boxes2.host_store()) }
        }
    }

    /// Each inner node's depth in the binary tree (`build::depths`).
    pub struct Depths<'a> {
        /// Triangles.
        pub params: LbvhParams,
        /// The inner nodes' parents.
        pub parents: &'a Buffer<u32>,
        /// Written: their depths.
        pub depths: &'a Buffer<u32>,
    }

    impl Kernel for Depths<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_depths".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![read("parents", self.parents), write("depths", self.depths)]
        }
        fn threads(&self) -> u32 {
            self.params.count.saturating_sub(1)
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`.
            unsafe { build::depths(t, &self.params, self.parents.host(), &mut self.depths.host_store()) }
        }
    }

    /// One phase of treelet restructuring (`build::treelet`, the phase as `params.level`).
    pub struct Treelet<'a> {
        /// Triangles and the phase.
        pub params: LbvhParams,
        /// The inner nodes' depths.
        pub depths: &'a Buffer<u32>,
        /// The range tree (level 0: the sorted triangles' boxes).
        pub tree: &'a Buffer<BuildBox>,
        /// The inner nodes (rewired).
        pub nodes2: &'a Buffer<[u32; 4]>,
        /// Their boxes (rewritten where rebuilt).
        pub boxes2: &'a Buffer<BuildBox>,
        /// Their triangles' counts (rewritten where rebuilt).
        pub counts: &'a Buffer<u32>,
        /// Their parents (rewritten where moved).
        pub parents: &'a Buffer<u32>,
    }

    impl Kernel for Treelet<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_treelet".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![
                read("depths", self.depths),
                read("tree", self.tree),
                write("nodes2", self.nodes2),
                write("boxes2", self.boxes2),
                write("counts", self.counts),
                write("parents", self.parents),
            ]
        }
        fn threads(&self) -> u32 {
            self.params.count.saturating_sub(1)
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; the items of a phase write disjoint nodes and read only their
            // own and nodes no item of the phase writes (`build::treelet`).
            unsafe {
                build::treelet(
                    t,
                    &self.params,
                    self.depths.host(),
                    self.tree.host(),
                    &mut self.nodes2.host_store(),
                    &mut self.boxes2.host_store(),
                    &mut self.counts.host_store(),
                    &mut self.parents.host_store(),
                )
            }
        }
    }

    /// The next level's items and indirect workgroup counts (`build::level`; one item).
    pub struct Level<'a> {
        /// The build's state words.
        pub state: &'a Buffer<u32>,
        /// Written: element 0, the collapse's workgroup counts.
        pub args: &'a Buffer<[u32; 3]>,
    }

    impl Kernel for Level<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_level".into()
        }
        fn params(&self) -> &[u8] {
            &[]
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![write("state", self.state), write("args", self.args)]
        }
        fn threads(&self) -> u32 {
            1
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; one item.
            unsafe { build::level(t, &mut self.state.host_store(), &mut self.args.host_store()) }
        }
    }

    /// One level of wide nodes (`build::collapse`), dispatched indirectly.
    pub struct Collapse<'a> {
        /// Triangles and the level.
        pub params: LbvhParams,
        /// The scene's triangles.
        pub tris: &'a Buffer<Triangle>,
        /// The triangles in sorted order.
        pub sorted: &'a Buffer<u32>,
        /// The inner nodes.
        pub nodes2: &'a Buffer<[u32; 4]>,
        /// Their boxes.
        pub boxes2: &'a Buffer<BuildBox>,
        /// Their triangles' counts.
        pub counts: &'a Buffer<u32>,
        /// The range tree (level 0: the sorted triangles' boxes).
        pub tree: &'a Buffer<BuildBox>,
        /// The build's state words (added to atomically).
        pub state: &'a Buffer<u32>,
        /// Each wide node's binary node (read at the level's, written at their children's).
        pub pending: &'a Buffer<u32>,
        /// Written: the wide nodes.
        pub bvh: &'a Buffer<BvhNode>,
        /// Written: the leaf triangles.
        pub bvh_tris: &'a Buffer<Triangle>,
    }

    impl Kernel for Collapse<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "lbvh_collapse".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![
                read("tris", self.tris),
                read("sorted", self.sorted),
                read("nodes2", self.nodes2),
                read("boxes2", self.boxes2),
                read("counts", self.counts),
                read("tree", self.tree),
                write("state", self.state),
                write("pending", self.pending),
                write("bvh", self.bvh),
                write("bvh_tris", self.bvh_tris),
            ]
        }
        fn threads(&self) -> u32 {
            // Dispatched indirectly (`Level`).
            0
        }
        fn run(&self, t: u32) {
            // SAFETY: as `Boxes`; item t writes its own node and the places it took atomically.
            unsafe {
                build::collapse(
                    t,
                    &self.params,
                    self.tris.host(),
                    self.sorted.host(),
                    self.nodes2.host(),
                    self.boxes2.host(),
                    self.counts.host(),
                    self.tree.host(),
                    &mut self.state.host_store(),
                    &mut self.pending.host_store(),
                    &mut self.bvh.host_store(),
                    &mut self.bvh_tris.host_store(),
                )
            }
        }
    }
}
