//! Integrators: what is computed per pixel, each a schedule of passes written once against
//! `tracer::Tracer` and `runtime::Runtime` (pbrt-v4 keeps aggregates and integrators apart the
//! same way). They hold no wgpu type and no runtime-specific code: the same schedule runs on
//! the GPU and natively.
pub mod direct;

use kdray_shared::Hit;

/// Result of a render: per-pixel primary hit and linear RGB radiance (row-major, top row first).
#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub width: u32,
    pub height: u32,
    pub hits: Vec<Hit>,
    pub radiance: Vec<[f32; 4]>,
}
