//! What every runtime (native CPU, wgpu GPU) offers: batches of closest-hit and any-hit queries
//! and the direct-lighting render, all built from the same `kdray-shared` functions, with the
//! hit-finding method (`Accel`) chosen per call.
use anyhow::{bail, Result};
use indicatif::ProgressBar;
use kdray_shared::kdtree::{Algorithm, MAX_SHORT_STACK};
use kdray_shared::{Camera, Hit, Ray};

/// How hits are found: the brute-force oracle, a kd-tree traversal one ray at a time or in
/// packets of four, or the decomposed pipeline (leaf lists of `capacity` entries per ray, then
/// intersection, then a full-stack fallback for rays whose list overflowed).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Accel {
    Brute,
    Kd(Algorithm),
    Packet(Algorithm),
    Decomposed { capacity: u32 },
}

/// Default leaf-list capacity of the decomposed pipeline.
pub const DEFAULT_LEAF_CAPACITY: u32 = 16;
/// Largest leaf-list capacity accepted.
pub const MAX_LEAF_CAPACITY: u32 = kdray_shared::kdtree::MAX_LEAF_LIST as u32;

impl Accel {
    /// `brute`, `stack`, `restart`, `pushdown`, `shortstack` (= `shortstack:3`), `shortstack:N`,
    /// any kd traversal followed by `+packets`, or `decomposed[:CAPACITY]`.
    pub fn parse(s: &str) -> Result<Accel> {
        if let Some(alg) = s.strip_suffix("+packets") {
            return match Accel::parse(alg)? {
                Accel::Kd(a) => Ok(Accel::Packet(a)),
                _ => bail!("'+packets' applies to the kd traversals (stack, restart, pushdown, shortstack[:N]), not '{alg}'"),
            };
        }
        if let Some(rest) = s.strip_prefix("decomposed") {
            let capacity = match rest.strip_prefix(':').map(str::parse::<u32>) {
                None if rest.is_empty() => DEFAULT_LEAF_CAPACITY,
                Some(Ok(c)) if (1..=MAX_LEAF_CAPACITY).contains(&c) => c,
                _ => bail!("unknown pipeline '{s}': use decomposed or decomposed:CAPACITY (1..={MAX_LEAF_CAPACITY} leaves per ray)"),
            };
            return Ok(Accel::Decomposed { capacity });
        }
        Ok(match s {
            "brute" => Accel::Brute,
            "stack" => Accel::Kd(Algorithm::Stack),
            "restart" => Accel::Kd(Algorithm::Restart),
            "pushdown" => Accel::Kd(Algorithm::PushDown),
            "shortstack" => Accel::Kd(Algorithm::ShortStack(3)),
            s => match s.strip_prefix("shortstack:").map(str::parse::<u32>) {
                Some(Ok(n)) if (1..=MAX_SHORT_STACK).contains(&n) => Accel::Kd(Algorithm::ShortStack(n)),
                _ => bail!(
                    "unknown traversal '{s}': use brute, stack, restart, pushdown, shortstack or shortstack:N (N = 1..={MAX_SHORT_STACK}), optionally +packets, or decomposed[:CAPACITY]"
                ),
            },
        })
    }

    pub fn name(&self) -> String {
        match self {
            Accel::Brute => "brute".into(),
            Accel::Kd(a) => alg_name(*a),
            Accel::Packet(a) => format!("{}+packets", alg_name(*a)),
            Accel::Decomposed { capacity } => format!("decomposed:{capacity}"),
        }
    }

    /// The same traversal with 4-ray packets (`None` for brute force and the decomposed pipeline).
    pub fn with_packets(self) -> Option<Accel> {
        match self {
            Accel::Kd(a) | Accel::Packet(a) => Some(Accel::Packet(a)),
            _ => None,
        }
    }

    /// Whether a kd-tree is needed.
    pub fn needs_tree(self) -> bool {
        !matches!(self, Accel::Brute)
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

fn alg_name(a: Algorithm) -> String {
    match a {
        Algorithm::Stack => "stack".into(),
        Algorithm::Restart => "restart".into(),
        Algorithm::PushDown => "pushdown".into(),
        Algorithm::ShortStack(n) => format!("shortstack:{n}"),
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
