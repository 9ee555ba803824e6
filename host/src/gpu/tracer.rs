//! Closest-hit, any-hit and rendering on the GPU: the scene lives in storage buffers, rays go
//! through in batches that respect both the device's binding-size limit and a bound on the work
//! of one submission (so no dispatch runs long enough to trip a driver watchdog).
use super::kernels::Kernel;
use super::Gpu;
use crate::kdtree::KdTreeData;
use crate::scene::Scene;
use crate::trace::{Accel, RenderOutput, Tracer};
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::{Camera, FrameParams, Hit, PathState, Ray, ShadeTerms};

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

    /// Items per batch: bounded by the binding limit (largest per-item record: 32 bytes) and by
    /// the brute-force work per submission; a multiple of the workgroup size.
    fn batch_size(&self, accel: Accel, total: usize) -> usize {
        let by_binding = self.gpu.max_binding() / 32;
        let by_work = match accel {
            Accel::Brute => (MAX_TESTS_PER_SUBMIT / self.tri_count.max(1)).max(4096),
            Accel::Kd(_) => MAX_KD_RAYS_PER_SUBMIT,
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
        if matches!(accel, Accel::Kd(_)) && !self.has_tree {
            anyhow::bail!("no kd-tree was built for this scene");
        }
        Ok(())
    }

    fn query<T: bytemuck::Pod>(&self, accel: Accel, kernel: Kernel, rays: &[Ray]) -> Result<Vec<T>> {
        let mut out = Vec::with_capacity(rays.len());
        let b = self.batch_size(accel, rays.len());
        for (i, batch) in rays.chunks(b).enumerate() {
            let rbuf = self.gpu.upload("ray", batch)?;
            let obuf = self.gpu.storage::<T>("result", batch.len())?;
            let mut enc = self.gpu.encoder();
            let p = self.params(i * b, batch.len());
            self.gpu.record(&mut enc, kernel, &p, &[&rbuf, &self.tris, &self.nodes, &self.prims, &obuf])?;
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
        self.query::<Hit>(accel, Kernel::Closest(accel), rays)
    }

    fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>> {
        self.check(accel)?;
        Ok(self.query::<u32>(accel, Kernel::Any(accel), rays)?.into_iter().map(|o| o != 0).collect())
    }

    fn render(&self, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        self.check(accel)?;
        let g = self.gpu;
        let n = (cam.width * cam.height) as usize;
        let b = self.batch_size(accel, n);
        // Only what the scene needs: no reflection passes without mirrors, no shadow rays
        // without lights (their occlusion flags then stay 0).
        let max_bounces = if self.has_mirror { bounces } else { 0 };
        let rays = g.storage::<Ray>("ray", b)?;
        let paths = g.storage::<PathState>("path", b)?;
        let hits = g.storage::<Hit>("hit", b)?;
        let primary_hits = g.storage::<Hit>("primary hit", b)?;
        let shadow = g.storage::<Ray>("shadow ray", b)?;
        let terms = g.storage::<ShadeTerms>("shade terms", b)?;
        let occluded = g.upload("occluded", &vec![0u32; b])?;
        let radiance = g.storage::<[f32; 4]>("radiance", b)?;
        let mut out = RenderOutput { width: cam.width, height: cam.height, hits: Vec::with_capacity(n), radiance: Vec::with_capacity(n) };
        progress.set_length(n as u64);
        let mut first = 0;
        while first < n {
            let count = b.min(n - first);
            let p = FrameParams { seed, camera: *cam, max_bounces, ..self.params(first, count) };
            let mut enc = g.encoder();
            g.record(&mut enc, Kernel::CameraRays, &p, &[&rays, &paths])?;
            for bounce in 0..=max_bounces {
                let p = FrameParams { bounce, ..p };
                g.record(&mut enc, Kernel::Closest(accel), &p, &[&rays, &self.tris, &self.nodes, &self.prims, &hits])?;
                if bounce == 0 {
                    enc.copy_buffer_to_buffer(&hits, 0, &primary_hits, 0, (count * std::mem::size_of::<Hit>()) as u64);
                }
                g.record(
                    &mut enc,
                    Kernel::PathStep,
                    &p,
                    &[&rays, &self.tris, &hits, &self.materials, &self.lights, &paths, &shadow, &terms],
                )?;
                if self.light_count > 0 {
                    g.record(&mut enc, Kernel::Any(accel), &p, &[&shadow, &self.tris, &self.nodes, &self.prims, &occluded])?;
                }
                g.record(&mut enc, Kernel::Accumulate, &p, &[&terms, &occluded, &paths, &radiance])?;
            }
            g.submit_wait(enc)?;
            out.hits.extend(g.read::<Hit>(&primary_hits, count)?);
            out.radiance.extend(g.read::<[f32; 4]>(&radiance, count)?);
            first += count;
            progress.inc(count as u64);
        }
        Ok(out)
    }
}

impl GpuTracer<'_> {
    /// Times closest-hit (or any-hit) kernels of `accel` over `rays` (one batch).
    pub fn time(&self, accel: Accel, closest: bool, rays: &[Ray], reps: usize) -> Result<super::Timing> {
        self.check(accel)?;
        if self.batch_size(accel, rays.len()) < rays.len() {
            anyhow::bail!("{} rays do not fit one GPU batch", rays.len());
        }
        let rbuf = self.gpu.upload("ray", rays)?;
        let obuf = self.gpu.storage::<Hit>("result", rays.len())?;
        let k = if closest { Kernel::Closest(accel) } else { Kernel::Any(accel) };
        let p = self.params(0, rays.len());
        self.gpu.time_kernel(k, &p, &[&rbuf, &self.tris, &self.nodes, &self.prims, &obuf], reps)
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
