//! What every runtime (native CPU, wgpu GPU) offers: batches of closest-hit and any-hit queries
//! and the direct-lighting render, all built from the same `kdray-shared` functions, with the
//! hit-finding method (`Accel`) chosen per call.
use anyhow::{bail, Result};
use indicatif::ProgressBar;
use kdray_shared::kdtree::{Algorithm, MAX_SHORT_STACK};
use kdray_shared::{Camera, Hit, Ray};

/// How hits are found: the brute-force oracle or a kd-tree traversal.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Accel {
    Brute,
    Kd(Algorithm),
}

impl Accel {
    /// `brute`, `stack`, `restart`, `pushdown`, `shortstack` (= `shortstack:3`) or `shortstack:N`.
    pub fn parse(s: &str) -> Result<Accel> {
        Ok(match s {
            "brute" => Accel::Brute,
            "stack" => Accel::Kd(Algorithm::Stack),
            "restart" => Accel::Kd(Algorithm::Restart),
            "pushdown" => Accel::Kd(Algorithm::PushDown),
            "shortstack" => Accel::Kd(Algorithm::ShortStack(3)),
            s => match s.strip_prefix("shortstack:").map(str::parse::<u32>) {
                Some(Ok(n)) if (1..=MAX_SHORT_STACK).contains(&n) => Accel::Kd(Algorithm::ShortStack(n)),
                _ => bail!(
                    "unknown traversal '{s}': use brute, stack, restart, pushdown, shortstack or shortstack:N (N = 1..={MAX_SHORT_STACK})"
                ),
            },
        })
    }

    pub fn name(&self) -> String {
        match self {
            Accel::Brute => "brute".into(),
            Accel::Kd(Algorithm::Stack) => "stack".into(),
            Accel::Kd(Algorithm::Restart) => "restart".into(),
            Accel::Kd(Algorithm::PushDown) => "pushdown".into(),
            Accel::Kd(Algorithm::ShortStack(n)) => format!("shortstack:{n}"),
        }
    }

    /// Every kd traversal with a GPU kernel, the oracle first.
    pub fn all() -> Vec<Accel> {
        let mut v = vec![
            Accel::Brute,
            Accel::Kd(Algorithm::Stack),
            Accel::Kd(Algorithm::Restart),
            Accel::Kd(Algorithm::PushDown),
        ];
        v.extend(crate::gpu::kernels::GPU_SHORT_STACKS.iter().map(|n| Accel::Kd(Algorithm::ShortStack(*n))));
        v
    }
}

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
    fn closest_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Hit>>;
    fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>>;
    /// Primary rays through pixel centres, reflected at mirrors up to `bounces` times, then one
    /// shadow ray per pixel toward a sampled light point (random stream `seed`), Lambertian
    /// shading; every ray type through `accel`. `RenderOutput::hits` are the primary hits.
    fn render(&self, accel: Accel, camera: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput>;
}
