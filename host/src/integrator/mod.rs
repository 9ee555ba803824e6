//! Integrators: what is computed per pixel, each a schedule of passes written once against
//! `tracer::Tracer` and `runtime::Runtime` (pbrt-v4 keeps aggregates and integrators apart the
//! same way). They hold no wgpu type and no runtime-specific code: the same schedule runs on
//! the GPU and natively.
pub mod direct;
pub mod path;
pub mod photon;
pub mod share;

use kdray_shared::Hit;

/// What a long render reports as it goes. The command line draws a progress bar from it;
/// `&()` reports nothing.
pub trait Progress {
    /// The amount of work, in the integrator's units (path samples, photon passes).
    fn start(&self, _total: u64) {}
    /// `n` more units done.
    fn advance(&self, _n: u64) {}
    /// A short status line, e.g. `"12.3 M photons/s"`.
    fn status(&self, _text: &str) {}
    /// Whether the caller wants the render to stop (asked after each photon pass or path
    /// sample group): the render then returns the image of the work done so far, like a time
    /// limit (`PhotonStats::passes`, `PathStats::samples` say how much), not an error.
    fn cancelled(&self) -> bool {
        false
    }
}

impl Progress for () {}

/// Where an eye path's numbers (pixel jitter, light samples, bounce directions, Russian
/// roulette, glass) come from (`kdray_shared::sampler`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum SamplerKind {
    /// Independent random numbers: plain Monte Carlo.
    Independent,
    /// Each pixel's own Owen-scrambled Sobol sequence, continued over samples and passes:
    /// the same expectation, with the samples of a pixel stratified in every pair of
    /// dimensions (lower error at equal samples wherever the integrand is not noise-like:
    /// edges, soft shadows, smooth indirect light).
    #[default]
    Sobol,
}

impl SamplerKind {
    /// The `RENDER_*` flag it sets.
    pub fn flags(self) -> u32 {
        match self {
            SamplerKind::Independent => 0,
            SamplerKind::Sobol => kdray_shared::RENDER_SOBOL,
        }
    }
}

/// Result of a render: per-pixel primary hit and linear RGB radiance (row-major, top row first).
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Per pixel: the closest hit of one of its camera rays (jittered where the integrator
    /// jitters; from the last sample group rendered), `Hit::NONE` where it hit nothing.
    pub hits: Vec<Hit>,
    /// Per pixel: the average of its samples' radiance; the fourth component is 1.
    pub radiance: Vec<[f32; 4]>,
}

impl RenderOutput {
    /// A black image with no hits.
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        RenderOutput { width, height, hits: vec![Hit::NONE; n], radiance: vec![[0.0, 0.0, 0.0, 1.0]; n] }
    }
}
