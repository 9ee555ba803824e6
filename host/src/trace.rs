//! What every runtime (native CPU, wgpu GPU) offers: batches of closest-hit and any-hit queries
//! and the direct-lighting render, all built from the same `kdray-shared` functions.
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::{Camera, Hit, Ray};

/// Result of `render`: per-pixel primary hit and linear RGB radiance (row-major, top row first).
#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub width: u32,
    pub height: u32,
    pub hits: Vec<Hit>,
    pub radiance: Vec<[f32; 4]>,
}

pub trait Tracer {
    /// Which device, for reports.
    fn device_name(&self) -> String;
    fn closest_hits(&self, rays: &[Ray]) -> Result<Vec<Hit>>;
    fn any_hits(&self, rays: &[Ray]) -> Result<Vec<bool>>;
    /// Primary rays through pixel centres, one shadow ray per pixel toward a sampled light
    /// point (random stream `seed`), Lambertian shading.
    fn render(&self, camera: &Camera, seed: u32, progress: &ProgressBar) -> Result<RenderOutput>;
}
