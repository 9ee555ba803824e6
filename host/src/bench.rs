//! Benchmarks: tables (CSV + Markdown) with the machine, date, device and an error column next
//! to every speed. Timed runs carry no counters; node/leaf/triangle counts come from a separate
//! counting run (native: the same algorithm gives the same counts on every device).
use crate::gpu::{self, median, tracer::GpuTracer, Gpu};
use crate::kdtree::KdTreeData;
use crate::scene::Scene;
use crate::trace::Accel;
use crate::{CpuTracer, Tracer};
use anyhow::{Context, Result};
use indicatif::ProgressBar;
use kdray_shared::kdtree::{Algorithm, Counters};
use kdray_shared::rng::Rng;
use kdray_shared::{camera, shade, Hit, Ray};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

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

/// Primary rays of the scene camera at `size`², and the shadow rays of the pixels that hit.
pub fn ray_sets(scene: &Scene, tree: &KdTreeData, size: u32) -> Result<(Vec<Ray>, Vec<Ray>)> {
    let cam = scene.camera.to_pod(size, size);
    let primary: Vec<Ray> = (0..size * size).map(|i| camera::primary_ray(&cam, i)).collect();
    let cpu = CpuTracer::new(scene, Some(tree));
    let hits = cpu.closest_hits(Accel::Kd(Algorithm::Stack), &primary)?;
    let lights = scene.lights();
    let shadow = primary
        .iter()
        .zip(&hits)
        .enumerate()
        .filter(|(_, (_, h))| h.is_hit())
        .map(|(i, (r, h))| {
            shade::light_sample(1, i as u32, r, h, &scene.triangles, &scene.materials, &lights, lights.len() as u32).0
        })
        .filter(|r| r.is_valid())
        .collect();
    Ok((primary, shadow))
}

#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub triangles: usize,
    pub rays: usize,
    pub ray_type: &'static str,
    pub traversal: String,
    pub mrays_gpu: Option<f64>,
    pub mrays_wall: f64,
    pub nodes: f64,
    pub leaves: f64,
    pub tris: f64,
    pub restarts: f64,
    pub visits_vs_stack: f64,
    pub oracle_mismatch: f64,
    pub cpu_mismatch: Option<f64>,
}

fn mean(c: &[Counters], f: impl Fn(&Counters) -> u32) -> f64 {
    c.iter().map(|x| f(x) as f64).sum::<f64>() / c.len().max(1) as f64
}

/// Fraction of `a` and `b` that differ (hit ids for closest hit).
fn mismatch<T: PartialEq>(a: &[T], b: &[T]) -> f64 {
    a.iter().zip(b).filter(|(x, y)| x != y).count() as f64 / a.len().max(1) as f64
}

/// The traversal table: every kd traversal, primary and shadow rays, on one device.
pub fn traversals(
    scene: &Scene,
    tree: &KdTreeData,
    size: u32,
    gpu: Option<&Gpu>,
    reps: usize,
    progress: &ProgressBar,
) -> Result<Vec<Row>> {
    let (primary, shadow) = ray_sets(scene, tree, size)?;
    let cpu = CpuTracer::new(scene, Some(tree));
    let gt = match gpu {
        Some(g) => Some(GpuTracer::new(g, scene, Some(tree))?),
        None => None,
    };
    let accels: Vec<Accel> = Accel::all().into_iter().skip(1).collect();
    progress.set_length((2 * accels.len()) as u64);
    let mut rows = Vec::new();
    for (ray_type, rays) in [("primary", &primary), ("shadow", &shadow)] {
        let closest = ray_type == "primary";
        // A fixed random sample for the oracle.
        let mut rng = Rng::new(7, rays.len() as u32);
        let sample: Vec<Ray> = (0..ORACLE_SAMPLE.min(rays.len()))
            .map(|_| rays[(rng.next_u32() as usize) % rays.len()])
            .collect();
        let (oracle_h, oracle_a) = if closest {
            (cpu.closest_hits(Accel::Brute, &sample)?, Vec::new())
        } else {
            (Vec::new(), cpu.any_hits(Accel::Brute, &sample)?)
        };
        let mut stack_nodes = 0.0;
        for accel in &accels {
            let Accel::Kd(alg) = *accel else { unreachable!() };
            let counts = cpu.count(alg, rays, closest)?;
            let nodes = mean(&counts, |c| c.nodes);
            if alg == Algorithm::Stack {
                stack_nodes = nodes;
            }
            let (wall, gpu_t, oracle_mismatch, cpu_mismatch) = match &gt {
                Some(g) => {
                    let t = g.time(*accel, closest, rays, reps)?;
                    let (om, cm) = if closest {
                        let full = g.closest_hits(*accel, rays)?;
                        let reference = cpu.closest_hits(*accel, rays)?;
                        let ids = |h: &[Hit]| h.iter().map(|x| x.prim).collect::<Vec<_>>();
                        (mismatch(&ids(&g.closest_hits(*accel, &sample)?), &ids(&oracle_h)), Some(mismatch(&ids(&full), &ids(&reference))))
                    } else {
                        let full = g.any_hits(*accel, rays)?;
                        let reference = cpu.any_hits(*accel, rays)?;
                        (mismatch(&g.any_hits(*accel, &sample)?, &oracle_a), Some(mismatch(&full, &reference)))
                    };
                    (median(&t.wall_ms).unwrap_or(f64::NAN), median(&t.gpu_ms), om, cm)
                }
                None => {
                    let mut times = Vec::new();
                    for rep in 0..=reps {
                        let start = Instant::now();
                        if closest {
                            cpu.closest_hits(*accel, rays)?;
                        } else {
                            cpu.any_hits(*accel, rays)?;
                        }
                        if rep > 0 {
                            times.push(start.elapsed().as_secs_f64() * 1e3);
                        }
                    }
                    let om = if closest {
                        let ids = |h: &[Hit]| h.iter().map(|x| x.prim).collect::<Vec<_>>();
                        mismatch(&ids(&cpu.closest_hits(*accel, &sample)?), &ids(&oracle_h))
                    } else {
                        mismatch(&cpu.any_hits(*accel, &sample)?, &oracle_a)
                    };
                    (median(&times).unwrap_or(f64::NAN), None, om, None)
                }
            };
            let n = rays.len() as f64;
            rows.push(Row {
                scene: scene.name.clone(),
                triangles: scene.triangles.len(),
                rays: rays.len(),
                ray_type,
                traversal: accel.name(),
                mrays_gpu: gpu_t.map(|ms| n / (ms * 1e3)),
                mrays_wall: n / (wall * 1e3),
                nodes,
                leaves: mean(&counts, |c| c.leaves),
                tris: mean(&counts, |c| c.tris),
                restarts: mean(&counts, |c| c.restarts),
                visits_vs_stack: nodes / stack_nodes - 1.0,
                oracle_mismatch,
                cpu_mismatch,
            });
            progress.inc(1);
        }
    }
    Ok(rows)
}

/// Writes `name.csv` and `name.md` into `dir`.
pub fn write_tables(dir: &Path, name: &str, device: &str, rows: &[Row]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let date = today();
    let machine = machine();
    let mut csv = String::from(
        "date,machine,device,scene,triangles,rays,ray_type,traversal,mrays_s_gpu_timestamps,mrays_s_wall,nodes_per_ray,leaves_per_ray,tris_per_ray,restarts_per_ray,node_visits_vs_stack,oracle_mismatch_rate,gpu_vs_cpu_mismatch_rate\n",
    );
    let opt = |v: Option<f64>, p: usize| v.map(|x| format!("{x:.p$}")).unwrap_or_default();
    for r in rows {
        writeln!(
            csv,
            "{date},\"{machine}\",\"{device}\",{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{:.3e},{}",
            r.scene, r.triangles, r.rays, r.ray_type, r.traversal, opt(r.mrays_gpu, 3), r.mrays_wall, r.nodes, r.leaves,
            r.tris, r.restarts, r.visits_vs_stack, r.oracle_mismatch, r.cpu_mismatch.map(|x| format!("{x:.3e}")).unwrap_or_default()
        )?;
    }
    let mut md = format!(
        "# {name}\n\nDate {date}; machine {machine}; device {device}.\n\n\
         Mrays/s: median of the timed repetitions after a warm-up, from GPU timestamps where the adapter has them, and wall time (submit to completion) always. \
         Counts per ray come from a separate counting run. Oracle mismatch: fraction of {ORACLE_SAMPLE} sampled rays whose hit differs from the brute-force oracle; GPU vs CPU: fraction of all rays whose hit differs from the native run of the same traversal.\n\n\
         | scene | tris | ray type | rays | traversal | Mrays/s (GPU time) | Mrays/s (wall) | nodes/ray | vs stack | leaves/ray | tris/ray | restarts/ray | oracle mismatch | GPU vs CPU |\n\
         |---|---:|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    );
    for r in rows {
        writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {:.1} | {:.1} | {:+.1} % | {:.2} | {:.2} | {:.2} | {:.2e} | {} |",
            r.scene, r.triangles, r.ray_type, r.rays, r.traversal, opt(r.mrays_gpu, 1), r.mrays_wall, r.nodes,
            100.0 * r.visits_vs_stack, r.leaves, r.tris, r.restarts, r.oracle_mismatch,
            r.cpu_mismatch.map(|x| format!("{x:.2e}")).unwrap_or_else(|| "–".into())
        )?;
    }
    let base = dir.join(name);
    std::fs::write(base.with_extension("csv"), csv)?;
    std::fs::write(base.with_extension("md"), md)?;
    Ok(())
}

/// The adapter line, or the CPU.
pub fn device_line(g: Option<&Gpu>) -> String {
    match g {
        Some(g) => gpu::describe(&g.info),
        None => format!("CPU ({} threads)", rayon::current_num_threads()),
    }
}
