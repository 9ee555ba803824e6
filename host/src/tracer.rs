//! Closest-hit and any-hit queries on one runtime: the scene's buffers, the acceleration
//! structures (the kd-tree or none, an enum that owns its arrays; the wide BVH beside it), and
//! the passes that answer a query with a given
//! `Accel` — one kernel, or the decomposed pipeline's three. Integrators build their schedules
//! from `query_passes`; nothing here knows which runtime it runs on.
use crate::accel::{Accel, Grouping, Pipeline, Structure};
use crate::kdtree::KdTreeData;
use crate::bvh::BvhData;
use crate::kernels::{Fallback, IntersectListed, QueryKind, RasterDraw, RasterHits, SceneBinds, StructureBinds, Trace, TraceMethod, TraverseLeaves};
use crate::runtime::{cast, Buffer, Kernel, RawBuffer, Runtime, SplitBuffer};
use crate::scene::Scene;
use crate::error::{bail, Result};
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::BvhNode;
use kdray_shared::kdtree::{KdNode, LeafRef};
use kdray_shared::query::{AnyHit, Closest};
use kdray_shared::{raster, Camera, Hit, Light, Material, RasterParams, Ray, TraceParams, Triangle};

/// Upper bound on ray-triangle tests of one brute-force submission.
const MAX_TESTS_PER_SUBMIT: u64 = 1 << 30;
/// Upper bound on rays of one kd-tree or BVH submission (each visits O(log N) nodes).
const MAX_TREE_RAYS_PER_SUBMIT: u64 = 1 << 22;
/// Rays per batch on the native runtime (bounds the decomposed pipeline's leaf lists).
const NATIVE_BATCH: u64 = 1 << 18;

/// An acceleration structure as a runtime holds it.
pub enum AccelStructure {
    /// None: only brute force.
    Triangles,
    /// The kd-tree's arrays (`KdTreeData`).
    KdTree {
        /// The tree's nodes.
        nodes: SplitBuffer<KdNode>,
        /// The leaves' triangle indices.
        prims: SplitBuffer<u32>,
        /// The tree's root cell.
        bounds: Aabb,
    },
}

/// The compressed wide BVH's arrays (`BvhData`) on a runtime.
pub struct BvhBuffers {
    /// The nodes.
    pub nodes: SplitBuffer<BvhNode>,
    /// The triangles in leaf order, each with its scene index in `_pad`.
    pub tris: SplitBuffer<Triangle>,
}

/// A fingerprint of `n` triangles' vertices, material and face ids, in order (`tri(i)` is
/// triangle i): FNV-1a over each triangle's words, the triangles' hashes folded the same way
/// chunk by chunk, chunks of a fixed size over the cores, and the chunks' hashes folded in
/// order (the same value on any machine, within one build of kdray). One FNV-1a chain over
/// every word took 55 ms for 1.5 M triangles on 2 cores; each triangle's own chain overlaps
/// the next ones'.
fn geometry_fingerprint<'a>(n: usize, tri: impl Fn(usize) -> &'a Triangle + Sync) -> u64 {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 14;
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0100_0000_01b3;
    let fold = |h: u64, w: u64| (h ^ w).wrapping_mul(PRIME);
    let chunk = |c: usize| {
        (c * CHUNK..((c + 1) * CHUNK).min(n)).fold(OFFSET, |h, i| {
            let t = tri(i);
            let words = t.v0.iter().chain(&t.v1).chain(&t.v2).map(|c| c.to_bits()).chain([t.material, t.face]);
            fold(h, words.fold(OFFSET, |th, w| fold(th, w as u64)))
        })
    };
    let chunks: Vec<u64> = (0..n.div_ceil(CHUNK)).into_par_iter().map(chunk).collect();
    chunks.into_iter().fold(fold(OFFSET, n as u64), fold)
}

/// The decomposed pipeline's per-batch buffers: leaf lists (`capacity` entries per ray) and
/// one status word per ray.
pub struct LeafLists {
    /// Each ray's non-empty leaves in traversal order: ray i's `capacity` entries start at `i * capacity`.
    pub lists: Buffer<LeafRef>,
    /// Per ray: after `TraverseLeaves`, the number of entries with `LEAF_OVERFLOW` set if the
    /// list overflowed; `IntersectListed` then overwrites it with 1 (to trace again) or 0.
    pub status: Buffer<u32>,
}

/// A scene's buffers and acceleration structure on one runtime, and the closest-hit and
/// any-hit queries over them.
pub struct Tracer<'r> {
    /// The runtime that holds the buffers and runs the passes.
    pub rt: &'r dyn Runtime,
    /// The scene's triangles, in `Scene::triangles` order (`Hit::prim` indexes them); split
    /// across bindings when larger than one (as are the structures' arrays).
    pub tris: SplitBuffer<Triangle>,
    /// The scene's materials.
    pub materials: Buffer<Material>,
    /// `Scene::lights` (one zeroed entry if there are none: see `light_count`).
    pub lights: Buffer<Light>,
    /// A kd-tree if `new` was given one, else only brute force.
    pub structure: AccelStructure,
    /// The wide BVH, if `with_bvh` or `build_bvh` added one.
    pub bvh: Option<BvhBuffers>,
    /// A BVH's buffers that `update` dropped (no longer this scene's), for `build_bvh` to
    /// reuse.
    bvh_spare: Option<(Buffer<BvhNode>, Buffer<Triangle>)>,
    /// The traversals' root box (min, max; `trace_bounds`) for the whole-path kernels.
    pub scene_box: Buffer<[f32; 4]>,
    /// Bound in place of the tree's arrays by kernels that do not use them (brute force).
    no_nodes: SplitBuffer<KdNode>,
    no_prims: SplitBuffer<u32>,
    scene_bounds: Aabb,
    /// Number of lights in `lights`.
    pub light_count: u32,
    /// Any mirror or glass: only then are specular bounces traced.
    pub has_specular: bool,
    tri_count: u64,
    /// `geometry_fingerprint` of the scene's triangles (a BVH must hold the same ones).
    tri_fingerprint: u64,
    /// Buffers of earlier queries, reused by later ones (by label and size).
    pool: std::sync::Mutex<Vec<(&'static str, RawBuffer)>>,
}

impl<'r> Tracer<'r> {
    /// The scene on `rt`; `tree` is needed only for the kd traversals. The scene is validated
    /// (`Scene::validate`: material ids, finite vertices, colours, lights, camera) and the tree
    /// must index its triangles: the kernels trust both, so a scene edited through its public
    /// fields, or a tree of another scene, is an error here rather than an out-of-range read on
    /// the device or a panic natively.
    pub fn new(rt: &'r dyn Runtime, scene: &Scene, tree: Option<&KdTreeData>) -> Result<Self> {
        scene.validate()?;
        if let Some(t) = tree {
            let n = scene.triangles.len();
            if let Some(&p) = t.prims.iter().find(|&&p| p as usize >= n) {
                bail!(InvalidInput: "the kd-tree does not belong to scene '{}': it names triangle {p} of {n}", scene.name);
            }
        }
        let lights = scene.lights();
        let (lo, hi) = scene.bounds();
        let structure = match tree {
            Some(t) => AccelStructure::KdTree { nodes: rt.upload_split("kd-tree node", &t.nodes)?, prims: rt.upload_split("kd-tree primitive index", &t.prims)?, bounds: t.bounds },
            None => AccelStructure::Triangles,
        };
        let root = match &structure {
            AccelStructure::KdTree { bounds, .. } => *bounds,
            AccelStructure::Triangles => Aabb { min: lo.to_array(), max: hi.to_array() },
        };
        let scene_box = rt.upload("scene box", &[[root.min[0], root.min[1], root.min[2], 0.0], [root.max[0], root.max[1], root.max[2], 0.0]])?;
        Ok(Tracer {
            scene_box,
            rt,
            tris: rt.upload_split("triangle", &scene.triangles)?,
            materials: rt.upload("material", &scene.materials)?,
            lights: rt.upload("light", &lights)?,
            structure,
            bvh: None,
            bvh_spare: None,
            no_nodes: rt.upload_split("no kd-tree nodes", &[KdNode::default()])?,
            no_prims: rt.upload_split("no kd-tree primitives", &[0])?,
            scene_bounds: Aabb { min: lo.to_array(), max: hi.to_array() },
            light_count: lights.len() as u32,
            has_specular: scene.has_specular(),
            tri_count: scene.triangles.len() as u64,
            tri_fingerprint: geometry_fingerprint(scene.triangles.len(), |i| &scene.triangles[i]),
            pool: std::sync::Mutex::new(Vec::new()),
        })
    }

    /// Adds the compressed wide BVH `bvh` (built by `bvh::try_build` over this scene's
    /// triangles): `Accel::BVH` then runs. It is checked first (`BvhData::validate`), since
    /// the kernels trust it.
    pub fn with_bvh(mut self, bvh: &BvhData) -> Result<Self> {
        bvh.validate(self.tri_count as usize)?;
        // Its triangles are copies: they must be this scene's (a BVH of another scene with as
        // many triangles, or of this one before an edit, would find hits on other geometry).
        let mut order: Vec<&Triangle> = bvh.tris.iter().collect();
        order.sort_by_key(|t| t._pad);
        if geometry_fingerprint(order.len(), |i| order[i]) != self.tri_fingerprint {
            bail!(InvalidInput: "the BVH was built over other triangles than this scene's");
        }
        self.bvh = Some(BvhBuffers { nodes: self.rt.upload_split("BVH node", &bvh.nodes)?, tris: self.rt.upload_split("BVH triangle", &bvh.tris)? });
        Ok(self)
    }

    /// Builds the wide BVH over this tracer's triangles with the kernels on its runtime
    /// (`crate::lbvh`, `rounds` rounds of treelet restructuring: `lbvh::build_with`), on
    /// `builder`'s kept working buffers, into buffers that stay on the device: `Accel::BVH` then
    /// runs on it. Nothing is uploaded and only the build's state is read back, where
    /// `LbvhBuilder::build` uploads the triangles and reads the tree back (on the H100 for 1.5 M
    /// triangles: about 100 ms of read-back against 18 ms of build). For a scene that changes
    /// every frame: `update`, then this, then the frame's queries; the BVH buffers of the last
    /// build are reused where they hold the triangles. The tree is not checked on the host
    /// (`BvhData::validate`) as `with_bvh` checks one: it is the kernels' own, from triangles
    /// this tracer validated. Fails, changing nothing, where `builder` is on another runtime,
    /// `rounds` is more than `lbvh::MAX_TREELET_ROUNDS`, or the triangles are split across
    /// bindings (the build reads one); where the build itself fails (as `LbvhBuilder::build`),
    /// the tracer is left without a BVH.
    ///
    /// ```no_run
    /// # fn main() -> kdray::Result<()> {
    /// # let gpu = kdray::gpu::Gpu::new()?;
    /// # let (first, frames): (kdray::Scene, Vec<kdray::Scene>) = (kdray::scene::load("cornell")?, Vec::new());
    /// # let rays: Vec<kdray::Ray> = Vec::new();
    /// let mut builder = kdray::lbvh::LbvhBuilder::new(&gpu);
    /// let mut tracer = kdray::Tracer::new(&gpu, &first, None)?;
    /// for scene in &frames {
    ///     tracer.update(scene)?;
    ///     tracer.build_bvh(&mut builder, kdray::lbvh::TREELET_ROUNDS)?;
    ///     let hits = tracer.closest_hits(kdray::Accel::BVH, &rays)?;
    ///     # let _ = hits;
    /// }
    /// # Ok(())
    /// # }
    /// ```
    pub fn build_bvh(&mut self, builder: &mut crate::lbvh::LbvhBuilder, rounds: u32) -> Result<crate::lbvh::LbvhBuild> {
        let n = self.tri_count as usize;
        if !std::ptr::addr_eq(builder.runtime() as *const dyn Runtime, self.rt as *const dyn Runtime) {
            bail!(InvalidInput: "the BVH builder runs on {}, the tracer on {}", builder.runtime().name(), self.rt.name());
        }
        crate::lbvh::check_rounds(rounds)?;
        // A tracer holds at least one triangle (`Scene::validate`).
        let Some(tris) = self.tris.whole() else {
            bail!(TooLarge: "the kernels' BVH build reads the triangles from one binding; these are split across {} (build on the host: bvh::try_build and with_bvh)", self.tris.parts().len());
        };
        // The buffers of the last BVH (or of the one `update` dropped) where they hold n
        // triangles; the others are freed before new ones are made.
        let fits = |o: &(Buffer<BvhNode>, Buffer<Triangle>)| o.0.len() >= n && o.1.len() >= n;
        let last = self.bvh.take().and_then(|b| b.nodes.into_whole().zip(b.tris.into_whole()));
        let spare = self.bvh_spare.take();
        let old = match (last, spare) {
            (Some(o), _) if fits(&o) => Some(o),
            (_, Some(o)) if fits(&o) => Some(o),
            _ => None,
        };
        let t0 = std::time::Instant::now();
        let out = match old {
            Some(o) => o,
            None => crate::lbvh::tree_buffers(self.rt, n)?,
        };
        let allocated_s = t0.elapsed().as_secs_f64();
        let mut r = builder.build_into(tris, n, &out, rounds)?;
        r.setup_s += allocated_s;
        self.bvh = Some(BvhBuffers { nodes: SplitBuffer::whole_of(out.0, r.nodes)?, tris: SplitBuffer::whole_of(out.1, n)? });
        Ok(r)
    }

    /// Puts `scene`'s new state into this tracer's buffers, for a scene that changes from
    /// frame to frame with as many triangles and materials (its vertices moved, its materials
    /// edited): triangles, materials, lights (reallocated if their number changed) and the
    /// scene's box are written over. The kd-tree given to `new` no longer fits and is dropped
    /// (the kd traversals then fail, as for a tracer made without one), and so is the BVH,
    /// whose buffers the next `build_bvh` reuses. The scene is validated as by `new`; a scene
    /// that fails that or has other counts, or whose lights' new buffer cannot be made,
    /// changes nothing.
    pub fn update(&mut self, scene: &Scene) -> Result<()> {
        scene.validate()?;
        if scene.triangles.len() as u64 != self.tri_count || scene.materials.len() != self.materials.len() {
            bail!(InvalidInput: "scene '{}' has {} triangles and {} materials, the tracer {} and {}: make a new tracer", scene.name, scene.triangles.len(), scene.materials.len(), self.tri_count, self.materials.len());
        }
        let lights = scene.lights();
        let (lo, hi) = scene.bounds();
        // The one allocation first: past it, writes fail only on a lost device.
        if lights.len() == self.lights.len() {
            self.rt.write(&self.lights, &lights)?;
        } else {
            self.lights = self.rt.upload("light", &lights)?;
        }
        self.rt.write_split(&self.tris, &scene.triangles)?;
        self.rt.write(&self.materials, &scene.materials)?;
        self.rt.write(&self.scene_box, &[[lo.x, lo.y, lo.z, 0.0], [hi.x, hi.y, hi.z, 0.0]])?;
        self.structure = AccelStructure::Triangles;
        if let Some(b) = self.bvh.take() {
            self.bvh_spare = b.nodes.into_whole().zip(b.tris.into_whole());
        }
        self.scene_bounds = Aabb { min: lo.to_array(), max: hi.to_array() };
        self.light_count = lights.len() as u32;
        self.has_specular = scene.has_specular();
        self.tri_fingerprint = geometry_fingerprint(scene.triangles.len(), |i| &scene.triangles[i]);
        Ok(())
    }

    /// Whether `scene` has the triangles this tracer was made with (vertices, materials and
    /// faces, in order).
    pub fn holds(&self, scene: &Scene) -> bool {
        scene.triangles.len() as u64 == self.tri_count && geometry_fingerprint(scene.triangles.len(), |i| &scene.triangles[i]) == self.tri_fingerprint
    }

    /// Whether `other` was made over the same triangles (the devices of one render).
    pub fn holds_same(&self, other: &Tracer) -> bool {
        (self.tri_count, self.tri_fingerprint) == (other.tri_count, other.tri_fingerprint)
    }

    /// The scene arrays held in more than one buffer (larger than one storage binding), with
    /// their part counts: e.g. `triangles in 2 buffers, kd-tree nodes in 3`; `None` if all are
    /// whole.
    pub fn split_summary(&self) -> Option<String> {
        let mut v = vec![("triangles", self.tris.parts().len())];
        if let AccelStructure::KdTree { nodes, prims, .. } = &self.structure {
            v.extend([("kd-tree nodes", nodes.parts().len()), ("kd-tree primitive indices", prims.parts().len())]);
        }
        if let Some(b) = &self.bvh {
            v.extend([("BVH nodes", b.nodes.parts().len()), ("BVH triangles", b.tris.parts().len())]);
        }
        let split: Vec<String> = v.into_iter().filter(|(_, n)| *n > 1).map(|(what, n)| format!("{what} in {n} buffers")).collect();
        (!split.is_empty()).then(|| split.join(", "))
    }

    /// The box the traversals start from (the kd-tree's root cell, else the scene's box).
    pub fn trace_bounds(&self) -> ([f32; 3], [f32; 3]) {
        let p = self.params(crate::accel::Accel::BRUTE, 0);
        match &self.structure {
            AccelStructure::KdTree { bounds, .. } => (bounds.min, bounds.max),
            AccelStructure::Triangles => (p.bounds_min, p.bounds_max),
        }
    }

    /// The scene's box (min, max).
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        (self.scene_bounds.min, self.scene_bounds.max)
    }

    /// The runtime's name, for reports.
    pub fn device_name(&self) -> String {
        self.rt.name()
    }

    /// Fails unless the structure `accel` searches was built.
    pub fn check(&self, accel: Accel) -> Result<()> {
        if accel.structure == Structure::KdTree && matches!(self.structure, AccelStructure::Triangles) {
            bail!(InvalidInput: "no kd-tree was built for this scene");
        }
        if accel.structure == Structure::Bvh && self.bvh.is_none() {
            bail!(InvalidInput: "no BVH was built for this scene");
        }
        Ok(())
    }

    /// The scene's buffers as the ray-query kernels of `accel` bind them (brute force binds
    /// placeholders for the kd-tree's; `check(accel)` first: a structure that was not built
    /// binds placeholders too).
    pub fn scene_binds(&self, accel: Accel) -> SceneBinds<'_> {
        let structure = match (accel.structure, &self.structure, &self.bvh) {
            (Structure::Bvh, _, Some(b)) => StructureBinds::Bvh { nodes: &b.nodes, tris: &b.tris },
            (Structure::KdTree, AccelStructure::KdTree { nodes, prims, .. }, _) => StructureBinds::Kd { nodes, prims },
            _ => StructureBinds::Kd { nodes: &self.no_nodes, prims: &self.no_prims },
        };
        SceneBinds { tris: &self.tris, structure }
    }

    /// The method of `accel`'s whole-path kernel family `prefix` on this runtime
    /// (`Accel::whole_path_method`), or `None` where whole paths must be traced pass by pass:
    /// brute force on a software Vulkan driver, where an item testing every triangle at every
    /// bounce outruns lavapipe's loop limit and loses its work silently (measured: a fifth of
    /// the photons of the 20 502-triangle glass-sphere box).
    pub fn whole_path_method(&self, accel: Accel, prefix: &str) -> Option<crate::kernels::TraceMethod> {
        if self.rt.is_software() && accel.structure == Structure::Brute {
            return None;
        }
        accel.whole_path_method(prefix)
    }

    /// Parameters of a query over `count` rays.
    pub fn params(&self, accel: Accel, count: usize) -> TraceParams {
        let b = match &self.structure {
            AccelStructure::KdTree { bounds, .. } => *bounds,
            AccelStructure::Triangles => self.scene_bounds,
        };
        let leaf_capacity = match accel.pipeline {
            Pipeline::Decomposed { capacity } => capacity,
            Pipeline::Monolithic => 0,
        };
        TraceParams { count: count as u32, leaf_capacity, bounds_min: b.min, bounds_max: b.max, ..Default::default() }
    }

    /// Items per batch: bounded by the binding limit (largest per-item record: 32 bytes, or
    /// the leaf list), by the brute-force work per submission, and natively by memory; a
    /// multiple of 64.
    pub fn batch_size(&self, accel: Accel, total: usize) -> usize {
        let record = match accel.pipeline {
            Pipeline::Decomposed { capacity } => (capacity as u64 * std::mem::size_of::<LeafRef>() as u64).max(32),
            Pipeline::Monolithic => 32,
        };
        let by_binding = self.rt.max_binding() / record;
        let mut by_work = match accel.structure {
            Structure::Brute => (MAX_TESTS_PER_SUBMIT / self.tri_count.max(1)).max(4096),
            Structure::KdTree | Structure::Bvh => MAX_TREE_RAYS_PER_SUBMIT,
        };
        if self.rt.is_native() {
            by_work = by_work.min(NATIVE_BATCH);
        }
        let b = by_binding.min(by_work).min(total.max(1) as u64) as usize;
        if b >= total {
            total.max(1)
        } else {
            (b / 64).max(1) * 64
        }
    }

    /// The leaf-list buffers `accel` needs for batches of `n` rays (none unless decomposed).
    pub fn leaf_lists(&self, accel: Accel, n: usize) -> Result<Option<LeafLists>> {
        Ok(match accel.pipeline {
            Pipeline::Decomposed { capacity } => {
                Some(LeafLists { lists: self.rt.alloc("leaf list", n * capacity as usize)?, status: self.rt.alloc("leaf list status", n)? })
            }
            Pipeline::Monolithic => None,
        })
    }

    /// The passes that answer query `Q` for the first `count` rays of `rays` into `out`: one
    /// kernel, or the decomposed pipeline's traverse → intersect → fallback.
    pub fn query_passes<'a, Q: QueryKind>(
        &'a self,
        accel: Accel,
        count: usize,
        rays: &'a Buffer<Ray>,
        out: &'a Buffer<Q::Out>,
        lists: Option<&'a LeafLists>,
    ) -> Result<Vec<Box<dyn Kernel + 'a>>> {
        self.check(accel)?;
        if count > rays.len() || count > out.len() || count > u32::MAX as usize {
            bail!(InvalidInput: "a query over {count} rays with {} rays and {} results in its buffers", rays.len(), out.len());
        }
        if let (Pipeline::Decomposed { capacity }, Some(l)) = (accel.pipeline, lists) {
            if l.status.len() < count || l.lists.len() < count * capacity as usize {
                bail!(InvalidInput: "leaf-list buffers for {} rays, a query over {count}", l.status.len());
            }
        }
        let params = self.params(accel, count);
        let scene = || self.scene_binds(accel);
        Ok(match (accel.structure, accel.grouping, accel.pipeline) {
            (Structure::KdTree, _, Pipeline::Decomposed { .. }) => {
                let Some(l) = lists else { bail!(InvalidInput: "the decomposed pipeline needs leaf-list buffers") };
                vec![
                    Box::new(TraverseLeaves { params, rays, scene: scene(), lists: &l.lists, status: &l.status }),
                    Box::new(IntersectListed::<Q> { params, rays, scene: scene(), lists: &l.lists, status: &l.status, out }),
                    Box::new(Fallback::<Q> { params, rays, scene: scene(), status: &l.status, out }),
                ]
            }
            (Structure::Brute, _, _) => vec![Box::new(Trace::<Q>::new(TraceMethod::Brute, params, rays, scene(), out))],
            (Structure::Bvh, Grouping::Single, _) => vec![Box::new(Trace::<Q>::new(TraceMethod::Bvh, params, rays, scene(), out))],
            (Structure::Bvh, Grouping::Packet4, _) => vec![Box::new(Trace::<Q>::new(TraceMethod::BvhPacket, params, rays, scene(), out))],
            (Structure::KdTree, Grouping::Single, _) => vec![Box::new(Trace::<Q>::new(TraceMethod::Single(accel.traversal), params, rays, scene(), out))],
            (Structure::KdTree, Grouping::Packet4, _) => vec![Box::new(Trace::<Q>::new(TraceMethod::Packet(accel.traversal), params, rays, scene(), out))],
        })
    }

    /// Answers `Q` for every ray, batch by batch; the next batch is uploaded and submitted
    /// before the last one's answers are read.
    fn query<Q: QueryKind>(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Q::Out>> {
        self.check(accel)?;
        let rt = self.rt;
        let b = self.batch_size(accel, rays.len());
        let lists = self.leaf_lists(accel, b)?;
        // Two sets of buffers, used in turn.
        let sets = if rays.len() > b { 2 } else { 1 };
        let bufs: Vec<(Buffer<Ray>, Buffer<Q::Out>)> =
            (0..sets).map(|_| Ok((self.scratch::<Ray>("ray", b)?, self.scratch::<Q::Out>("result", b)?))).collect::<Result<_>>()?;
        let mut out = Vec::with_capacity(rays.len());
        let mut pending = None;
        for (i, batch) in rays.chunks(b).enumerate() {
            let (rbuf, obuf) = &bufs[i % sets];
            rt.write(rbuf, batch)?;
            let mut c = rt.begin();
            rt.dispatch_all(&mut c, self.query_passes::<Q>(accel, batch.len(), rbuf, obuf, lists.as_ref())?)?;
            let p = rt.read_back_of(&mut c, obuf, batch.len())?;
            rt.submit(c)?;
            if let Some(prev) = pending.replace(p) {
                out.extend(cast::<Q::Out>(rt.wait(prev)?));
            }
        }
        if let Some(p) = pending {
            let last = cast::<Q::Out>(rt.wait(p)?);
            if out.is_empty() {
                out = last;
            } else {
                out.extend(last);
            }
        }
        let mut pool = self.pool.lock().expect("buffer pool");
        for (r, o) in bufs {
            pool.push(("ray", r.into_raw()));
            pool.push(("result", o.into_raw()));
        }
        // Keep the newest few.
        let old = pool.len().saturating_sub(8);
        pool.drain(..old);
        Ok(out)
    }

    /// A buffer of `n` elements from the pool of earlier queries' buffers, or a new one.
    /// (Its contents are whatever the last query left: every query writes what it reads.)
    fn scratch<T: bytemuck::Pod>(&self, label: &'static str, n: usize) -> Result<Buffer<T>> {
        let bytes = (n.max(1) * std::mem::size_of::<T>()).max(4) as u64;
        let mut pool = self.pool.lock().expect("buffer pool");
        if let Some(i) = pool.iter().position(|(l, r)| *l == label && r.bytes() == bytes.next_multiple_of(4)) {
            let (_, raw) = pool.swap_remove(i);
            return Ok(Buffer::from_raw(raw, n));
        }
        drop(pool);
        self.rt.alloc::<T>(label, n)
    }

    /// How rasterised primary hits trace where the rasteriser's answer is not trusted: the
    /// BVH or the kd-tree's full stack, one ray per thread, one kernel (`accel` says which);
    /// an error for any other `accel`, or a structure that was not built.
    pub fn raster_method(&self, accel: Accel) -> Result<TraceMethod> {
        self.check(accel)?;
        match (accel.structure, accel.traversal, accel.grouping, accel.pipeline) {
            (Structure::Bvh, _, _, Pipeline::Monolithic) => Ok(TraceMethod::Bvh),
            (Structure::KdTree, kdray_shared::kdtree::Algorithm::Stack, Grouping::Single, Pipeline::Monolithic) => Ok(TraceMethod::Single(kdray_shared::kdtree::Algorithm::Stack)),
            _ => bail!(InvalidInput: "rasterised primary hits trace with the BVH or the kd-tree's full stack (one kernel), not '{}'", accel.name()),
        }
    }

    /// Parameters of the rasterised primary hits of camera `cam` (`raster`): its projection,
    /// clipping at 10^-6 of the scene's diagonal from the eye along its axis. Fails for a
    /// camera without pixels or whose axes do not span space.
    pub fn raster_params(&self, cam: &Camera) -> Result<RasterParams> {
        if !raster::can_draw(cam) {
            bail!(InvalidInput: "the camera cannot be rasterised: a {} x {} image whose axes do not span space", cam.width, cam.height);
        }
        let pixels = cam.width as u64 * cam.height as u64;
        if raster::row_words(cam.width) as u64 * cam.height as u64 > u32::MAX as u64 || self.tri_count * 3 > u32::MAX as u64 {
            bail!(TooLarge: "an image of {} x {} pixels of {} triangles is too large to rasterise", cam.width, cam.height, self.tri_count);
        }
        let b = self.scene_bounds;
        let diagonal = (0..3).map(|k| (b.max[k] - b.min[k]) as f64).map(|e| e * e).sum::<f64>().sqrt();
        let axis = cam.top_left.iter().map(|&c| (c as f64) * (c as f64)).sum::<f64>().sqrt();
        let near = (1e-6 * diagonal / axis) as f32;
        let near = if near.is_finite() && near > 0.0 { near } else { f32::MIN_POSITIVE };
        Ok(RasterParams::new(cam, self.tri_count as u32, pixels as u32, near))
    }

    /// The passes that find camera `cam`'s primary hits by rasterisation (Horn et al. 2007):
    /// draw the visibility buffer `visible` (`RasterDraw`; natively: every pixel unknown), then
    /// each ray's hit from it into `out`, traced by `accel`'s structure where needed
    /// (`RasterHits`: the BVH, or the kd-tree's full stack). `out[i]` is the camera's i-th
    /// pixel in its order; the answers are the traversal's up to `raster`'s tie rule.
    pub fn raster_passes<'a>(&'a self, accel: Accel, p: &RasterParams, visible: &'a Buffer<u32>, out: &'a Buffer<Hit>) -> Result<Vec<Box<dyn Kernel + 'a>>> {
        let method = self.raster_method(accel)?;
        let need = p.row_words as usize * p.camera.height as usize;
        if visible.len() < need || out.len() < p.count as usize {
            bail!(InvalidInput: "rasterised primary hits of {} rays need {need} visibility words and as many results; the buffers hold {} and {}", p.count, visible.len(), out.len());
        }
        let hits = RasterHits::new(method, *p, &self.scene_box, self.scene_binds(accel), visible, out).expect("raster_method checked it");
        Ok(vec![Box::new(RasterDraw { params: *p, tris: &self.tris, visible }), Box::new(hits)])
    }

    /// Camera `cam`'s primary hits (through pixel centres, in the camera's order) by
    /// rasterisation, traced by `accel` where the rasteriser's answer cannot be trusted
    /// (`raster_passes`).
    pub fn raster_primary_hits(&self, accel: Accel, cam: &Camera) -> Result<Vec<Hit>> {
        let p = self.raster_params(cam)?;
        let visible = self.rt.alloc::<u32>("visibility", p.row_words as usize * cam.height as usize)?;
        let out = self.rt.alloc::<Hit>("primary hit", p.count as usize)?;
        let passes = self.raster_passes(accel, &p, &visible, &out)?;
        let mut c = self.rt.begin();
        self.rt.dispatch_all(&mut c, passes)?;
        let pending = self.rt.read_back_of(&mut c, &out, p.count as usize)?;
        self.rt.submit(c)?;
        Ok(cast::<Hit>(self.rt.wait(pending)?))
    }

    /// The closest hit of each ray in its interval (`Hit::NONE` for a miss), found with
    /// `accel`; fails if `accel` needs a kd-tree and none was built.
    pub fn closest_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Hit>> {
        self.query::<Closest>(accel, rays)
    }

    /// Whether each ray hits any triangle in its interval, found with `accel`; fails if
    /// `accel` needs a kd-tree and none was built.
    pub fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>> {
        Ok(self.query::<AnyHit>(accel, rays)?.into_iter().map(|o| o != 0).collect())
    }
}
