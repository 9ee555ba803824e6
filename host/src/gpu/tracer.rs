//! Closest-hit, any-hit and rendering on the GPU: the scene lives in storage buffers, rays go
//! through in batches that respect both the device's binding-size limit and a bound on the work
//! of one submission (so no dispatch runs long enough to trip a driver watchdog).
use super::kernels::Kernel;
use super::Gpu;
use crate::scene::Scene;
use crate::trace::{RenderOutput, Tracer};
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::{Camera, FrameParams, Hit, Ray, ShadeTerms};

/// Upper bound on ray-triangle tests of one brute-force submission.
const MAX_TESTS_PER_SUBMIT: u64 = 1 << 30;

pub struct GpuTracer<'g> {
    gpu: &'g Gpu,
    tris: wgpu::Buffer,
    materials: wgpu::Buffer,
    lights: wgpu::Buffer,
    tri_count: u64,
    light_count: u32,
}

impl<'g> GpuTracer<'g> {
    pub fn new(gpu: &'g Gpu, scene: &Scene) -> Result<Self> {
        let lights = scene.lights();
        Ok(GpuTracer {
            gpu,
            tris: gpu.upload("triangle", &scene.triangles)?,
            materials: gpu.upload("material", &scene.materials)?,
            lights: gpu.upload("light", &lights)?,
            tri_count: scene.triangles.len() as u64,
            light_count: lights.len() as u32,
        })
    }

    /// Items per batch: bounded by the binding limit (largest per-item record: 32 bytes) and by
    /// the brute-force work per submission; a multiple of the workgroup size.
    fn batch_size(&self, total: usize) -> usize {
        let by_binding = self.gpu.max_binding() / 32;
        let by_work = (MAX_TESTS_PER_SUBMIT / self.tri_count.max(1)).max(4096);
        let b = by_binding.min(by_work).min(total.max(1) as u64) as usize;
        if b >= total { total.max(1) } else { (b / 64).max(1) * 64 }
    }

    fn params(&self, first: usize, count: usize) -> FrameParams {
        FrameParams { count: count as u32, first: first as u32, light_count: self.light_count, ..Default::default() }
    }

    fn query<T: bytemuck::Pod>(&self, kernel: Kernel, rays: &[Ray]) -> Result<Vec<T>> {
        let mut out = Vec::with_capacity(rays.len());
        let b = self.batch_size(rays.len());
        for (i, batch) in rays.chunks(b).enumerate() {
            let rbuf = self.gpu.upload("ray", batch)?;
            let obuf = self.gpu.storage::<T>("result", batch.len())?;
            let mut enc = self.gpu.encoder();
            self.gpu.record(&mut enc, kernel, &self.params(i * b, batch.len()), &[&rbuf, &self.tris, &obuf])?;
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

    fn closest_hits(&self, rays: &[Ray]) -> Result<Vec<Hit>> {
        self.query::<Hit>(Kernel::ClosestHitBrute, rays)
    }

    fn any_hits(&self, rays: &[Ray]) -> Result<Vec<bool>> {
        Ok(self.query::<u32>(Kernel::AnyHitBrute, rays)?.into_iter().map(|o| o != 0).collect())
    }

    fn render(&self, cam: &Camera, seed: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        let g = self.gpu;
        let n = (cam.width * cam.height) as usize;
        let b = self.batch_size(n);
        let rays = g.storage::<Ray>("primary ray", b)?;
        let hits = g.storage::<Hit>("hit", b)?;
        let shadow = g.storage::<Ray>("shadow ray", b)?;
        let terms = g.storage::<ShadeTerms>("shade terms", b)?;
        let occluded = g.storage::<u32>("occluded", b)?;
        let radiance = g.storage::<[f32; 4]>("radiance", b)?;
        let mut out = RenderOutput { width: cam.width, height: cam.height, hits: Vec::with_capacity(n), radiance: Vec::with_capacity(n) };
        progress.set_length(n as u64);
        let mut first = 0;
        while first < n {
            let count = b.min(n - first);
            let p = FrameParams { seed, camera: *cam, ..self.params(first, count) };
            let mut enc = g.encoder();
            g.record(&mut enc, Kernel::CameraRays, &p, &[&rays])?;
            g.record(&mut enc, Kernel::ClosestHitBrute, &p, &[&rays, &self.tris, &hits])?;
            g.record(
                &mut enc,
                Kernel::LightSample,
                &p,
                &[&rays, &self.tris, &hits, &self.materials, &self.lights, &shadow, &terms],
            )?;
            g.record(&mut enc, Kernel::AnyHitBrute, &p, &[&shadow, &self.tris, &occluded])?;
            g.record(&mut enc, Kernel::Resolve, &p, &[&terms, &occluded, &radiance])?;
            g.submit_wait(enc)?;
            out.hits.extend(g.read::<Hit>(&hits, count)?);
            out.radiance.extend(g.read::<[f32; 4]>(&radiance, count)?);
            first += count;
            progress.inc(count as u64);
        }
        Ok(out)
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
