//! Closest-hit, any-hit and rendering on the GPU: the scene lives in storage buffers, rays go
//! through in batches that respect both the device's binding-size limit and a bound on the work
//! of one submission (so no dispatch runs long enough to trip a driver watchdog).
use super::kernels::Kernel;
use super::{Gpu, Pass};
use crate::kdtree::KdTreeData;
use crate::scene::Scene;
use crate::trace::{Accel, RenderOutput, Tracer};
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::kdtree::LeafRef;
use kdray_shared::{camera, Camera, FrameParams, Hit, PathState, Ray, ShadeTerms};

/// Upper bound on ray-triangle tests of one brute-force submission.
const MAX_TESTS_PER_SUBMIT: u64 = 1 << 30;
/// Upper bound on rays of one kd-tree submission (each visits O(log N) nodes).
const MAX_KD_RAYS_PER_SUBMIT: u64 = 1 << 22;

pub struct GpuTracer<'g> {
    gpu: &'g Gpu,
    tris: wgpu::Buffer,
    materials: wgpu::Buffer,
    lights: wgpu::Buffer,
    nodes: wgpu::Buffer,
    prims: wgpu::Buffer,
    bounds: kdray_shared::aabb::Aabb,
    has_tree: bool,
    has_mirror: bool,
    tri_count: u64,
    light_count: u32,
}

/// The decomposed pipeline's per-batch buffers: leaf lists (`capacity` entries per ray) and
/// one status word per ray.
pub struct LeafLists {
    pub lists: wgpu::Buffer,
    pub status: wgpu::Buffer,
}

impl<'g> GpuTracer<'g> {
    /// `tree` is needed only for the kd traversals.
    pub fn new(gpu: &'g Gpu, scene: &Scene, tree: Option<&KdTreeData>) -> Result<Self> {
        let lights = scene.lights();
        let (lo, hi) = scene.bounds();
        Ok(GpuTracer {
            gpu,
            nodes: gpu.upload("kd-tree node", tree.map(|t| &t.nodes[..]).unwrap_or(&[]))?,
            prims: gpu.upload("kd-tree primitive index", tree.map(|t| &t.prims[..]).unwrap_or(&[]))?,
            bounds: tree.map(|t| t.bounds).unwrap_or(kdray_shared::aabb::Aabb { min: lo.to_array(), max: hi.to_array() }),
            has_tree: tree.is_some(),
            has_mirror: scene.has_mirror(),
            tris: gpu.upload("triangle", &scene.triangles)?,
            materials: gpu.upload("material", &scene.materials)?,
            lights: gpu.upload("light", &lights)?,
            tri_count: scene.triangles.len() as u64,
            light_count: lights.len() as u32,
        })
    }

    /// Items per batch: bounded by the binding limit (largest per-item record: 32 bytes, or
    /// the leaf list) and by the brute-force work per submission; a multiple of the workgroup
    /// size.
    fn batch_size(&self, accel: Accel, total: usize) -> usize {
        let record = match accel {
            Accel::Decomposed { capacity } => (capacity as u64 * std::mem::size_of::<LeafRef>() as u64).max(32),
            _ => 32,
        };
        let by_binding = self.gpu.max_binding() / record;
        let by_work = match accel {
            Accel::Brute => (MAX_TESTS_PER_SUBMIT / self.tri_count.max(1)).max(4096),
            _ => MAX_KD_RAYS_PER_SUBMIT,
        };
        let b = by_binding.min(by_work).min(total.max(1) as u64) as usize;
        if b >= total { total.max(1) } else { (b / 64).max(1) * 64 }
    }

    fn params(&self, first: usize, count: usize) -> FrameParams {
        FrameParams {
            count: count as u32,
            first: first as u32,
            light_count: self.light_count,
            bounds_min: self.bounds.min,
            bounds_max: self.bounds.max,
            ..Default::default()
        }
    }

    fn check(&self, accel: Accel) -> Result<()> {
        if accel.needs_tree() && !self.has_tree {
            anyhow::bail!("no kd-tree was built for this scene");
        }
        Ok(())
    }

    /// The leaf-list buffers `accel` needs for batches of `n` rays (none unless decomposed).
    pub fn leaf_lists(&self, accel: Accel, n: usize) -> Result<Option<LeafLists>> {
        Ok(match accel {
            Accel::Decomposed { capacity } => Some(LeafLists {
                lists: self.gpu.storage::<LeafRef>("leaf list", n * capacity as usize)?,
                status: self.gpu.storage::<u32>("leaf list status", n)?,
            }),
            _ => None,
        })
    }

    /// The passes that answer closest-hit (`closest`) or any-hit queries for `rays` into `out`
    /// (`Hit`s or u32 flags): one kernel, or the decomposed pipeline's traverse → intersect →
    /// fallback.
    pub fn trace_passes<'a>(
        &'a self,
        accel: Accel,
        closest: bool,
        p: &FrameParams,
        rays: &'a wgpu::Buffer,
        out: &'a wgpu::Buffer,
        lists: Option<&'a LeafLists>,
    ) -> Result<Vec<Pass<'a>>> {
        let scene = [&self.tris, &self.nodes, &self.prims];
        Ok(match (accel, lists) {
            (Accel::Decomposed { capacity }, Some(l)) => {
                let params = FrameParams { leaf_capacity: capacity, ..*p };
                let with = |extra: &[&'a wgpu::Buffer]| [&[rays][..], &scene[..], extra].concat();
                vec![
                    Pass { kernel: Kernel::TraverseLeaves, params, buffers: with(&[&l.lists, &l.status]) },
                    Pass { kernel: Kernel::IntersectLeaves { closest }, params, buffers: with(&[&l.lists, &l.status, out]) },
                    Pass { kernel: Kernel::Fallback { closest }, params, buffers: with(&[&l.status, out]) },
                ]
            }
            (Accel::Decomposed { .. }, None) => anyhow::bail!("the decomposed pipeline needs leaf-list buffers"),
            _ => {
                let kernel = if closest { Kernel::Closest(accel) } else { Kernel::Any(accel) };
                vec![Pass { kernel, params: *p, buffers: vec![rays, scene[0], scene[1], scene[2], out] }]
            }
        })
    }

    fn query<T: bytemuck::Pod>(&self, accel: Accel, closest: bool, rays: &[Ray]) -> Result<Vec<T>> {
        let mut out = Vec::with_capacity(rays.len());
        let b = self.batch_size(accel, rays.len());
        let lists = self.leaf_lists(accel, b)?;
        for (i, batch) in rays.chunks(b).enumerate() {
            let rbuf = self.gpu.upload("ray", batch)?;
            let obuf = self.gpu.storage::<T>("result", batch.len())?;
            let mut enc = self.gpu.encoder();
            let p = self.params(i * b, batch.len());
            self.gpu.record_passes(&mut enc, &self.trace_passes(accel, closest, &p, &rbuf, &obuf, lists.as_ref())?)?;
            self.gpu.submit_wait(enc)?;
            out.extend(self.gpu.read::<T>(&obuf, batch.len())?);
        }
        Ok(out)
    }
}

impl Tracer for GpuTracer<'_> {
    fn device_name(&self) -> String {
        self.gpu.adapter_line()
    }

    fn closest_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Hit>> {
        self.check(accel)?;
        self.query::<Hit>(accel, true, rays)
    }

    fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>> {
        self.check(accel)?;
        Ok(self.query::<u32>(accel, false, rays)?.into_iter().map(|o| o != 0).collect())
    }

    fn render(&self, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        self.check(accel)?;
        let g = self.gpu;
        let n = (cam.width * cam.height) as usize;
        let b = self.batch_size(accel, n);
        let fb = self.frame_buffers(accel, b)?;
        let mut out = RenderOutput { width: cam.width, height: cam.height, hits: vec![Hit::NONE; n], radiance: vec![[0.0; 4]; n] };
        progress.set_length(n as u64);
        let mut first = 0;
        while first < n {
            let count = b.min(n - first);
            let p = self.frame_params(cam, seed, bounces, first, count);
            let mut enc = g.encoder();
            g.record_passes(&mut enc, &self.frame_passes(accel, &p, &fb)?)?;
            g.submit_wait(enc)?;
            // Results come in tracing order: put each where its pixel is.
            let hits = g.read::<Hit>(&fb.primary_hits, count)?;
            let radiance = g.read::<[f32; 4]>(&fb.radiance, count)?;
            for (k, (h, r)) in hits.into_iter().zip(radiance).enumerate() {
                let px = camera::pixel(cam, (first + k) as u32) as usize;
                out.hits[px] = h;
                out.radiance[px] = r;
            }
            first += count;
            progress.inc(count as u64);
        }
        Ok(out)
    }
}

/// The renderer's buffers for batches of up to `size` pixels.
pub struct FrameBuffers {
    rays: wgpu::Buffer,
    paths: wgpu::Buffer,
    hits: wgpu::Buffer,
    primary_hits: wgpu::Buffer,
    shadow: wgpu::Buffer,
    terms: wgpu::Buffer,
    occluded: wgpu::Buffer,
    radiance: wgpu::Buffer,
    lists: Option<LeafLists>,
}

impl GpuTracer<'_> {
    fn frame_buffers(&self, accel: Accel, b: usize) -> Result<FrameBuffers> {
        let g = self.gpu;
        Ok(FrameBuffers {
            rays: g.storage::<Ray>("ray", b)?,
            paths: g.storage::<PathState>("path", b)?,
            hits: g.storage::<Hit>("hit", b)?,
            primary_hits: g.storage::<Hit>("primary hit", b)?,
            shadow: g.storage::<Ray>("shadow ray", b)?,
            terms: g.storage::<ShadeTerms>("shade terms", b)?,
            // Stays 0 in scenes without lights (no shadow pass writes it).
            occluded: g.upload("occluded", &vec![0u32; b])?,
            radiance: g.storage::<[f32; 4]>("radiance", b)?,
            lists: self.leaf_lists(accel, b)?,
        })
    }

    /// Parameters of the batch of pixels `first..first + count`. Only what the scene needs: no
    /// reflection passes without mirrors.
    fn frame_params(&self, cam: &Camera, seed: u32, bounces: u32, first: usize, count: usize) -> FrameParams {
        let max_bounces = if self.has_mirror { bounces } else { 0 };
        FrameParams { seed, camera: *cam, max_bounces, ..self.params(first, count) }
    }

    /// Every pass of one batch of the renderer: camera rays; per bounce closest hit, path step
    /// (reflect or shade), shadow rays (only with lights) and accumulation. Bounce 0 writes its
    /// hits into `primary_hits`.
    pub fn frame_passes<'a>(&'a self, accel: Accel, p: &FrameParams, fb: &'a FrameBuffers) -> Result<Vec<Pass<'a>>> {
        let mut passes = vec![Pass { kernel: Kernel::CameraRays, params: *p, buffers: vec![&fb.rays, &fb.paths] }];
        for bounce in 0..=p.max_bounces {
            let p = FrameParams { bounce, ..*p };
            let hits = if bounce == 0 { &fb.primary_hits } else { &fb.hits };
            passes.extend(self.trace_passes(accel, true, &p, &fb.rays, hits, fb.lists.as_ref())?);
            passes.push(Pass {
                kernel: Kernel::PathStep,
                params: p,
                buffers: vec![&fb.rays, &self.tris, hits, &self.materials, &self.lights, &fb.paths, &fb.shadow, &fb.terms],
            });
            if self.light_count > 0 {
                passes.extend(self.trace_passes(accel, false, &p, &fb.shadow, &fb.occluded, fb.lists.as_ref())?);
            }
            passes.push(Pass { kernel: Kernel::Accumulate, params: p, buffers: vec![&fb.terms, &fb.occluded, &fb.paths, &fb.radiance] });
        }
        Ok(passes)
    }

    /// Times every pass of a whole frame (which must fit one batch): the kernels in order and
    /// their timings (`Timing::parts_ms`).
    pub fn time_frame(&self, accel: Accel, cam: &Camera, seed: u32, bounces: u32, reps: usize) -> Result<(Vec<Kernel>, super::Timing)> {
        self.check(accel)?;
        let n = (cam.width * cam.height) as usize;
        if self.batch_size(accel, n) < n {
            anyhow::bail!("a {}x{} frame does not fit one GPU batch", cam.width, cam.height);
        }
        let fb = self.frame_buffers(accel, n)?;
        let passes = self.frame_passes(accel, &self.frame_params(cam, seed, bounces, 0, n), &fb)?;
        let t = self.gpu.time_passes(&passes, reps)?;
        Ok((passes.iter().map(|p| p.kernel).collect(), t))
    }
}

impl GpuTracer<'_> {
    /// Times the closest-hit (or any-hit) passes of `accel` over `rays` (one batch); with the
    /// decomposed pipeline `Timing::parts_ms` holds traverse, intersect and fallback.
    pub fn time(&self, accel: Accel, closest: bool, rays: &[Ray], reps: usize) -> Result<super::Timing> {
        self.check(accel)?;
        if self.batch_size(accel, rays.len()) < rays.len() {
            anyhow::bail!("{} rays do not fit one GPU batch", rays.len());
        }
        let rbuf = self.gpu.upload("ray", rays)?;
        let obuf = self.gpu.storage::<Hit>("result", rays.len())?;
        let lists = self.leaf_lists(accel, rays.len())?;
        let p = self.params(0, rays.len());
        self.gpu.time_passes(&self.trace_passes(accel, closest, &p, &rbuf, &obuf, lists.as_ref())?, reps)
    }
}

/// Four numbers of each RNG stream (seed, index) for `count` indices, generated on the GPU.
pub fn rng_streams(gpu: &Gpu, seed: u32, count: usize) -> Result<Vec<[u32; 4]>> {
    let out = gpu.storage::<[u32; 4]>("rng", count)?;
    let mut enc = gpu.encoder();
    let p = FrameParams { count: count as u32, seed, ..Default::default() };
    gpu.record(&mut enc, Kernel::RngFill, &p, &[&out])?;
    gpu.submit_wait(enc)?;
    gpu.read(&out, count)
}
