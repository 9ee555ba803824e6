//! Benchmarks: every suite writes a CSV and a Markdown table (and PNG plots) with the date,
//! the machine, the device and an error column next to every speed. Timed runs carry no
//! counters; node/leaf/triangle counts come from a separate counting run (natively: the same
//! algorithm visits the same nodes on every device).
//!
//! Error columns: `oracle mismatch` = fraction of a fixed sample of `ORACLE_SAMPLE` rays whose
//! answer (hit triangle id, or occluded or not) differs from the brute-force oracle;
//! `vs reference` = fraction of all rays whose answer differs from the native full-stack
//! traversal (itself bit-identical to the oracle in the tests).
pub mod devices;
pub mod dump;
pub mod photons;
pub mod plot;
pub mod rays;
mod suites;
mod table;

pub use suites::{run_suite, Options, Scenes, SUITES};
pub use table::{write_cells, Row};

use kdray::accel::{Accel, Pipeline};
use kdray::gpu::{self, median, Gpu};
use kdray::kdtree::KdTreeData;
use kdray::runtime::cpu::NATIVE;
use kdray::scene::Scene;
use kdray::tracer::Tracer;
use kdray::analysis;
use anyhow::Result;
use kdray_shared::kdtree::Algorithm;
use kdray_shared::query::{AnyHit, Closest};
use kdray_shared::stats::Counters;
use kdray_shared::rng::Rng;
use kdray_shared::Ray;
use std::time::Instant;

/// Timing attempts per GPU row (fresh buffers each; the fastest median is reported).
pub const ATTEMPTS: usize = 3;

/// Rays checked against the brute-force oracle per row (the oracle is O(N) per ray).
pub const ORACLE_SAMPLE: usize = 4096;

/// UTC date (YYYY-MM-DD) of now.
pub fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() / 86400)
        .unwrap_or(0) as i64;
    // Civil-from-days (H. Hinnant).
    let z = days + 719468;
    let era = z.div_euclid(146097);
    let doe = z - era * 146097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (m <= 2) as i64;
    format!("{y:04}-{m:02}-{d:02}")
}

/// CPU model and core count of this machine.
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string()))
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!("{model} ×{}", std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1))
}

/// The adapter line, or the CPU.
pub fn device_line(g: Option<&Gpu>) -> String {
    match g {
        Some(g) => gpu::describe(&g.info),
        None => format!("CPU ({} threads)", rayon::current_num_threads()),
    }
}

/// One scene ready to be measured: its tree and both runtimes.
pub struct Bed<'a> {
    pub scene: &'a Scene,
    pub tree: &'a KdTreeData,
    pub bvh: kdray::bvh::BvhData,
    /// Seconds the BVH took to build (`bvh::try_build`).
    pub bvh_seconds: f64,
    pub cpu: Tracer<'a>,
    pub gpu: Option<(&'a Gpu, Tracer<'a>)>,
    pub size: u32,
    pub reps: usize,
}

impl<'a> Bed<'a> {
    pub fn new(scene: &'a Scene, tree: &'a KdTreeData, gpu: Option<&'a Gpu>, size: u32, reps: usize) -> Result<Self> {
        let start = Instant::now();
        let bvh = kdray::bvh::try_build(&scene.triangles)?;
        let bvh_seconds = start.elapsed().as_secs_f64();
        Ok(Bed {
            bvh_seconds,
            scene,
            tree,
            cpu: Tracer::new(&NATIVE, scene, Some(tree))?.with_bvh(&bvh)?,
            gpu: match gpu {
                Some(g) => Some((g, Tracer::new(g, scene, Some(tree))?.with_bvh(&bvh)?)),
                None => None,
            },
            bvh,
            size,
            reps,
        })
    }

    /// The runtime being measured.
    pub fn tracer(&self) -> &Tracer<'a> {
        match &self.gpu {
            Some((_, t)) => t,
            None => &self.cpu,
        }
    }

    /// Times the passes that answer queries for `rays` with `accel` on the GPU (one batch).
    pub fn time(&self, g: &Gpu, t: &Tracer, accel: Accel, closest: bool, rays: &[Ray], reps: usize) -> Result<kdray::gpu::Timing> {
        t.check(accel)?;
        if t.batch_size(accel, rays.len()) < rays.len() {
            anyhow::bail!("{} rays do not fit one GPU batch", rays.len());
        }
        let rt: &dyn kdray::Runtime = g;
        let rbuf = rt.upload("ray", rays)?;
        let lists = t.leaf_lists(accel, rays.len())?;
        if closest {
            let out = rt.alloc::<kdray_shared::Hit>("result", rays.len())?;
            let passes = t.query_passes::<Closest>(accel, rays.len(), &rbuf, &out, lists.as_ref())?;
            Ok(g.time_passes(&passes.iter().map(|k| k.as_ref()).collect::<Vec<_>>(), reps)?)
        } else {
            let out = rt.alloc::<u32>("result", rays.len())?;
            let passes = t.query_passes::<AnyHit>(accel, rays.len(), &rbuf, &out, lists.as_ref())?;
            Ok(g.time_passes(&passes.iter().map(|k| k.as_ref()).collect::<Vec<_>>(), reps)?)
        }
    }

    /// A ray set with its oracle sample and native full-stack reference answers.
    pub fn ray_set(&self, kind: impl Into<String>, rays: Vec<Ray>, closest: bool) -> Result<RaySet> {
        let sample: Vec<Ray> = sample_indices(rays.len()).into_iter().map(|i| rays[i]).collect();
        Ok(RaySet {
            kind: kind.into(),
            oracle: answers(&self.cpu, Accel::BRUTE, &sample, closest)?,
            reference: answers(&self.cpu, Accel::kd(Algorithm::Stack), &rays, closest)?,
            rays,
            sample,
            closest,
        })
    }

    /// Times `accel` on `set` (median of `reps` runs after a warm-up), counts its work per ray
    /// natively, and checks its answers against the oracle sample and the reference.
    pub fn measure(&self, set: &RaySet, accel: Accel) -> Result<Row> {
        let counts = if accel.needs_bvh() {
            analysis::bvh_counts(&self.bvh, &set.rays, set.closest, accel.is_packet())
        } else {
            analysis::counts(&self.scene.triangles, self.tree, accel, &set.rays, set.closest)?
        };
        let spread_text;
        let (wall, gpu_ms, parts, got) = match &self.gpu {
            Some((g, gt)) => {
                // Three attempts, each with fresh ray and result buffers, the lowest median
                // kept: on the H100 the same kernel on the same rays ran up to 5× slower in
                // some attempts than in others, steadily within an attempt (see
                // docs/benchmarks/README.md).
                let (t, medians) = best_of_attempts(|| self.time(g, gt, accel, set.closest, &set.rays, self.reps))?;
                let attempts = medians.len();
                let parts = t.parts_ms.iter().map(|p| median(p).unwrap_or(f64::NAN)).collect::<Vec<_>>();
                spread_text = format!(
                    "{}; attempt medians {:.3}–{:.3} ms",
                    spread_note(if t.gpu_ms.is_empty() { &t.wall_ms } else { &t.gpu_ms }, attempts),
                    medians.iter().copied().fold(f64::INFINITY, f64::min),
                    medians.iter().copied().fold(0.0, f64::max)
                );
                (median(&t.wall_ms).unwrap_or(f64::NAN), median(&t.gpu_ms), parts, answers(gt, accel, &set.rays, set.closest)?)
            }
            None => {
                let mut times = Vec::new();
                let mut got = Vec::new();
                for rep in 0..=self.reps {
                    let start = Instant::now();
                    got = answers(&self.cpu, accel, &set.rays, set.closest)?;
                    if rep > 0 {
                        times.push(start.elapsed().as_secs_f64() * 1e3);
                    }
                }
                spread_text = spread_note(&times, 1);
                (median(&times).unwrap_or(f64::NAN), None, Vec::new(), got)
            }
        };
        let sample = answers(self.tracer(), accel, &set.sample, set.closest)?;
        let n = set.rays.len();
        let per_ray = |f: fn(&Counters) -> u32| counts.iter().map(|c| f(c) as f64).sum::<f64>() / n.max(1) as f64;
        let mut notes = vec![spread_text];
        if accel.is_packet() && accel.needs_tree() {
            let coherent = analysis::coherent_packets(&set.rays);
            notes.push(format!("{:.1} % of packets coherent", 100.0 * coherent as f64 / n.div_ceil(4).max(1) as f64));
        }
        let mut fallbacks = None;
        if let Pipeline::Decomposed { capacity } = accel.pipeline {
            let f = analysis::decomposed_fallbacks(&self.scene.triangles, self.tree, &set.rays, capacity, set.closest);
            fallbacks = Some(f);
            notes.push(format!(
                "fallback {f} rays ({:.2} %), leaf lists {:.1} MiB",
                100.0 * f as f64 / n.max(1) as f64,
                leaf_list_mib(n, capacity)
            ));
            if parts.len() == 3 {
                notes.push(format!("GPU ms traverse {:.3} / intersect {:.3} / fallback {:.3}", parts[0], parts[1], parts[2]));
            }
        }
        Ok(Row {
            scene: self.scene.name.clone(),
            triangles: self.scene.triangles.len(),
            resolution: self.size,
            ray_type: set.kind.clone(),
            rays: n,
            method: accel.name(),
            mrays_gpu: gpu_ms.map(|ms| n as f64 / (ms * 1e3)),
            mrays_wall: n as f64 / (wall * 1e3),
            nodes: per_ray(|c| c.nodes),
            leaves: per_ray(|c| c.leaves),
            tris: per_ray(|c| c.tris),
            restarts: per_ray(|c| c.restarts),
            vs_stack: None,
            oracle_mismatch: mismatch(&sample, &set.oracle),
            reference_mismatch: mismatch(&got, &set.reference),
            fallbacks,
            notes: notes.join("; "),
        })
    }
}

impl Bed<'_> {
    /// The camera's primary rays of `set` (`rays::primary`: pixel centres in scanline order)
    /// found by rasterisation (`Tracer::raster_passes`), traced by `accel` where the
    /// rasteriser's answer is not trusted: timed like `measure` (draw, image copy and resolve
    /// together), its answers checked against the oracle sample and the reference, and how
    /// many differ from the reference (the tie rule of `kdray_shared::raster`) in the notes.
    /// Natively every ray is traced (there is no rasteriser).
    pub fn measure_raster(&self, set: &RaySet, accel: Accel) -> Result<Row> {
        let cam = self.scene.camera.to_pod(self.size, self.size);
        if set.rays.len() != (cam.width * cam.height) as usize {
            anyhow::bail!("rasterised primaries: {} rays are not the camera's {}² primary rays", set.rays.len(), self.size);
        }
        let t = self.tracer();
        let p = t.raster_params(&cam)?;
        let rt = t.rt;
        let visible = rt.alloc::<u32>("visibility", p.row_words as usize * cam.height as usize)?;
        let out = rt.alloc::<kdray_shared::Hit>("primary hit", p.count as usize)?;
        let passes = t.raster_passes(accel, &p, &visible, &out)?;
        let passes: Vec<&dyn kdray::runtime::Kernel> = passes.iter().map(|k| k.as_ref()).collect();
        let n = set.rays.len();
        let (wall, gpu_ms, spread_text) = match &self.gpu {
            Some((g, _)) => {
                let (t, medians) = best_of_attempts(|| Ok(g.time_passes(&passes, self.reps)?))?;
                let parts: Vec<f64> = t.parts_ms.iter().map(|p| median(p).unwrap_or(f64::NAN)).collect();
                let text = format!(
                    "{}; GPU ms draw {:.3} / resolve {:.3} (the image copy between them)",
                    spread_note(if t.gpu_ms.is_empty() { &t.wall_ms } else { &t.gpu_ms }, medians.len()),
                    parts.first().copied().unwrap_or(f64::NAN),
                    parts.get(1).copied().unwrap_or(f64::NAN)
                );
                (median(&t.wall_ms).unwrap_or(f64::NAN), median(&t.gpu_ms), text)
            }
            None => {
                let mut times = Vec::new();
                for rep in 0..=self.reps {
                    let start = Instant::now();
                    rt.run(&passes)?;
                    if rep > 0 {
                        times.push(start.elapsed().as_secs_f64() * 1e3);
                    }
                }
                (median(&times).unwrap_or(f64::NAN), None, spread_note(&times, 1))
            }
        };
        rt.run(&passes)?;
        let hits = rt.read(&out, n)?;
        let visible = rt.read(&visible, visible.len())?;
        let got: Vec<u32> = hits.iter().map(|h| h.prim).collect();
        let sample: Vec<u32> = sample_indices(n).into_iter().map(|i| got[i]).collect();
        let differ = got.iter().zip(&set.reference).filter(|(a, b)| a != b).count();
        // Pixels whose candidate the rasteriser named and the ray confirmed: resolved without a
        // traversal.
        let confirmed = hits
            .iter()
            .enumerate()
            .filter(|(i, h)| h.is_hit() && visible[p.slot(*i as u32)] == h.prim + 1)
            .count();
        let empty = (0..n).filter(|&i| visible[p.slot(i as u32)] == kdray_shared::raster::EMPTY).count();
        let notes = [
            spread_text,
            format!("{differ} of {n} answers differ from the full stack's (raster tie rule)"),
            format!("{:.2} % of rays resolved by their pixel's triangle, {:.2} % empty pixels, the rest traced", 100.0 * confirmed as f64 / n.max(1) as f64, 100.0 * empty as f64 / n.max(1) as f64),
        ];
        Ok(Row {
            scene: self.scene.name.clone(),
            triangles: self.scene.triangles.len(),
            resolution: self.size,
            ray_type: set.kind.clone(),
            rays: n,
            method: format!("raster+{}", accel.name()),
            mrays_gpu: gpu_ms.map(|ms| n as f64 / (ms * 1e3)),
            mrays_wall: n as f64 / (wall * 1e3),
            nodes: f64::NAN,
            leaves: f64::NAN,
            tris: f64::NAN,
            restarts: f64::NAN,
            vs_stack: None,
            oracle_mismatch: mismatch(&sample, &set.oracle),
            reference_mismatch: mismatch(&got, &set.reference),
            fallbacks: None,
            notes: notes.join("; "),
        })
    }
}

/// `ATTEMPTS` timings by `time` (each with fresh buffers where `time` makes them): the one with
/// the lowest median (GPU time where there is one), and every attempt's median.
fn best_of_attempts(mut time: impl FnMut() -> Result<kdray::gpu::Timing>) -> Result<(kdray::gpu::Timing, Vec<f64>)> {
    let mut best: Option<kdray::gpu::Timing> = None;
    let mut medians = Vec::new();
    for _ in 0..ATTEMPTS {
        let t = time()?;
        let m = median(if t.gpu_ms.is_empty() { &t.wall_ms } else { &t.gpu_ms }).unwrap_or(f64::NAN);
        if medians.iter().all(|b| m < *b) {
            best = Some(t);
        }
        medians.push(m);
    }
    Ok((best.expect("one attempt"), medians))
}

/// The indices of a batch of `n` rays checked against the oracle (`ORACLE_SAMPLE` of them,
/// drawn with a fixed seed; the same for every method).
pub fn sample_indices(n: usize) -> Vec<usize> {
    if n == 0 {
        return Vec::new();
    }
    let mut rng = Rng::new(7, n as u32);
    (0..ORACLE_SAMPLE.min(n)).map(|_| (rng.next_u32() as usize) % n).collect()
}

/// The spread of the timed runs: "ms min / max of N" and the attempts it took.
fn spread_note(ms: &[f64], attempts: usize) -> String {
    let min = ms.iter().copied().fold(f64::INFINITY, f64::min);
    let max = ms.iter().copied().fold(0.0, f64::max);
    let retried = if attempts > 1 { format!(" (best of {attempts} attempts)") } else { String::new() };
    format!("ms min {min:.3} / max {max:.3} of {}{retried}", ms.len())
}

/// GPU memory of the leaf lists of `rays` rays with `capacity` entries each, in MiB.
pub fn leaf_list_mib(rays: usize, capacity: u32) -> f64 {
    (rays * capacity as usize * std::mem::size_of::<kdray_shared::kdtree::LeafRef>()) as f64 / 1048576.0
}

/// Rays of one type with what their answers are checked against.
pub struct RaySet {
    /// `primary`, `shadow`, `reflection N`.
    pub kind: String,
    pub rays: Vec<Ray>,
    pub closest: bool,
    pub sample: Vec<Ray>,
    pub oracle: Vec<u32>,
    pub reference: Vec<u32>,
}

/// Answers as numbers: the hit triangle id (closest hit) or 1/0 (any hit).
pub fn answers(t: &Tracer, accel: Accel, rays: &[Ray], closest: bool) -> Result<Vec<u32>> {
    Ok(if closest {
        t.closest_hits(accel, rays)?.iter().map(|h| h.prim).collect()
    } else {
        t.any_hits(accel, rays)?.iter().map(|o| *o as u32).collect()
    })
}

/// Fraction of `a` and `b` that differ.
pub fn mismatch<T: PartialEq>(a: &[T], b: &[T]) -> f64 {
    a.iter().zip(b).filter(|(x, y)| x != y).count() as f64 / a.len().max(1) as f64
}
