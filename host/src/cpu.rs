//! The native runtime: the `kdray-shared` functions over all cores with rayon.
use crate::scene::Scene;
use crate::trace::{RenderOutput, Tracer};
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::{brute, camera, shade, Camera, Hit, Light, Material, Ray, Triangle};
use rayon::prelude::*;

pub struct CpuTracer {
    tris: Vec<Triangle>,
    materials: Vec<Material>,
    lights: Vec<Light>,
}

impl CpuTracer {
    pub fn new(scene: &Scene) -> Self {
        CpuTracer { tris: scene.triangles.clone(), materials: scene.materials.clone(), lights: scene.lights() }
    }
}

/// Rows per parallel work item of the renderer (also the progress granularity).
const ROWS_PER_TASK: u32 = 4;

impl Tracer for CpuTracer {
    fn device_name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn closest_hits(&self, rays: &[Ray]) -> Result<Vec<Hit>> {
        Ok(rays.par_iter().map(|r| brute::closest_hit(r, &self.tris)).collect())
    }

    fn any_hits(&self, rays: &[Ray]) -> Result<Vec<bool>> {
        Ok(rays.par_iter().map(|r| brute::any_hit(r, &self.tris)).collect())
    }

    fn render(&self, cam: &Camera, seed: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        let (w, h) = (cam.width, cam.height);
        let n = (w * h) as usize;
        let mut hits = vec![Hit::NONE; n];
        let mut radiance = vec![[0.0f32; 4]; n];
        let chunk = (w * ROWS_PER_TASK) as usize;
        progress.set_length(n as u64);
        hits.par_chunks_mut(chunk)
            .zip(radiance.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(c, (hs, rs))| {
                for (k, (hit, rad)) in hs.iter_mut().zip(rs.iter_mut()).enumerate() {
                    let pixel = (c * chunk + k) as u32;
                    let ray = camera::primary_ray(cam, pixel);
                    *hit = brute::closest_hit(&ray, &self.tris);
                    let (shadow, terms) = shade::light_sample(
                        seed,
                        pixel,
                        &ray,
                        hit,
                        &self.tris,
                        &self.materials,
                        &self.lights,
                        self.lights.len() as u32,
                    );
                    *rad = shade::resolve(&terms, brute::any_hit(&shadow, &self.tris));
                }
                progress.inc(hs.len() as u64);
            });
        Ok(RenderOutput { width: w, height: h, hits, radiance })
    }
}
