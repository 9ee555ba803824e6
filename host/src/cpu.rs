//! The native runtime: the `kdray-shared` functions over all cores with rayon. Rays go through
//! in groups of four (`PACKET`), so the packet traversal and the single-ray ones share one
//! driver; groups past the end of a batch are padded with invalid rays (misses).
use crate::kdtree::KdTreeData;
use crate::scene::Scene;
use crate::trace::{Accel, RenderOutput, Tracer};
use anyhow::{anyhow, Result};
use indicatif::ProgressBar;
use kdray_shared::brute::BruteForce;
use kdray_shared::kdtree::{self, AnyHit, Closest, Counters, KdTree, NoStats, Query, Stats, PACKET};
use kdray_shared::{camera, shade, Camera, Hit, Light, Material, PathState, Ray, ShadeTerms, Triangle};
use rayon::prelude::*;

/// Borrows the scene and the tree: creating one copies nothing but the light list.
pub struct CpuTracer<'s> {
    tris: &'s [Triangle],
    materials: &'s [Material],
    lights: Vec<Light>,
    tree: Option<&'s KdTreeData>,
    has_mirror: bool,
}

/// Up to `PACKET` rays padded with invalid ones.
fn group(rays: &[Ray]) -> [Ray; PACKET] {
    let mut g = [Ray::default(); PACKET];
    g[..rays.len()].copy_from_slice(rays);
    g
}

impl<'s> CpuTracer<'s> {
    /// `tree` is needed only for the kd traversals.
    pub fn new(scene: &'s Scene, tree: Option<&'s KdTreeData>) -> Self {
        CpuTracer {
            tris: &scene.triangles,
            materials: &scene.materials,
            lights: scene.lights(),
            tree,
            has_mirror: scene.has_mirror(),
        }
    }

    fn tree(&self) -> Result<KdTree<'s>> {
        self.tree.map(|t| t.view(self.tris)).ok_or_else(|| anyhow!("no kd-tree was built for this scene"))
    }

    /// Answers `Q` for four rays with `accel`.
    fn trace4<Q: Query + BruteForce, S: Stats>(&self, accel: Accel, rays: &[Ray; PACKET], stats: &mut S) -> Result<[Q; PACKET]> {
        let mut q = rays.each_ref().map(Q::new);
        match accel {
            Accel::Brute => q.iter_mut().zip(rays).for_each(|(q, r)| q.brute(r, self.tris)),
            Accel::Kd(alg) => {
                let tree = self.tree()?;
                q.iter_mut().zip(rays).for_each(|(q, r)| kdtree::run(alg, &tree, r, q, stats));
            }
            Accel::Packet(alg) => {
                kdtree::run_packet(alg, &self.tree()?, rays, &mut q, stats);
            }
            Accel::Decomposed { capacity } => {
                let tree = self.tree()?;
                for (q, r) in q.iter_mut().zip(rays) {
                    let l = kdtree::record_leaves(&tree, r, capacity, stats);
                    if !kdtree::intersect_leaves(&tree, r, &l.entries, 0, l.status(), q, stats) {
                        // The list overflowed before the answer was settled: trace it whole.
                        *q = Q::new(r);
                        kdtree::run(kdtree::Algorithm::Stack, &tree, r, q, stats);
                    }
                }
            }
        }
        Ok(q)
    }

    fn closest4(&self, accel: Accel, rays: &[Ray; PACKET]) -> Result<[Hit; PACKET]> {
        Ok(self.trace4::<Closest, _>(accel, rays, &mut NoStats)?.map(|q| q.hit))
    }

    fn any4(&self, accel: Accel, rays: &[Ray; PACKET]) -> Result<[bool; PACKET]> {
        Ok(self.trace4::<AnyHit, _>(accel, rays, &mut NoStats)?.map(|q| q.found))
    }

    /// Traversal counters of `accel` (closest hit if `closest`, else any hit), one per group of
    /// four rays in order: a packet's node and leaf visits are counted once for its four rays.
    pub fn count(&self, accel: Accel, rays: &[Ray], closest: bool) -> Result<Vec<Counters>> {
        rays.par_chunks(PACKET)
            .map(|c| {
                let mut s = Counters::default();
                let g = group(c);
                if closest {
                    self.trace4::<Closest, _>(accel, &g, &mut s)?;
                } else {
                    self.trace4::<AnyHit, _>(accel, &g, &mut s)?;
                }
                Ok(s)
            })
            .collect()
    }

    /// How many rays the decomposed pipeline with `capacity` leaves per list must finish with
    /// the fallback traversal (their list overflowed before the query was settled).
    pub fn decomposed_fallbacks(&self, rays: &[Ray], capacity: u32, closest: bool) -> Result<usize> {
        let tree = self.tree()?;
        Ok(rays
            .par_iter()
            .filter(|r| {
                let l = kdtree::record_leaves(&tree, r, capacity, &mut NoStats);
                if closest {
                    !kdtree::intersect_leaves(&tree, r, &l.entries, 0, l.status(), &mut Closest::new(r), &mut NoStats)
                } else {
                    !kdtree::intersect_leaves(&tree, r, &l.entries, 0, l.status(), &mut AnyHit::new(r), &mut NoStats)
                }
            })
            .count())
    }

    /// How many of the groups of four rays the packet traversal takes together (the others go
    /// ray by ray because their direction signs differ).
    pub fn coherent_packets(&self, rays: &[Ray]) -> usize {
        rays.par_chunks(PACKET).filter(|c| kdtree::direction_signs(&group(c)).is_some()).count()
    }
}

/// Rows per parallel work item of the renderer (also the progress granularity).
const ROWS_PER_TASK: u32 = 4;

impl Tracer for CpuTracer<'_> {
    fn device_name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn closest_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Hit>> {
        let groups: Vec<[Hit; PACKET]> = rays.par_chunks(PACKET).map(|c| self.closest4(accel, &group(c))).collect::<Result<_>>()?;
        Ok(groups.into_iter().flatten().take(rays.len()).collect())
    }

    fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>> {
        let groups: Vec<[bool; PACKET]> = rays.par_chunks(PACKET).map(|c| self.any4(accel, &group(c))).collect::<Result<_>>()?;
        Ok(groups.into_iter().flatten().take(rays.len()).collect())
    }

    fn render(&self, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        if accel.needs_tree() {
            self.tree()?;
        }
        let max_bounces = if self.has_mirror { bounces } else { 0 };
        let (w, h) = (cam.width, cam.height);
        let n = (w * h) as usize;
        // Results in tracing order (the camera's pixel order), then put in place.
        let mut traced = vec![(Hit::NONE, [0.0f32; 4]); n];
        let chunk = (w * ROWS_PER_TASK) as usize;
        progress.set_length(n as u64);
        traced.par_chunks_mut(chunk).enumerate().try_for_each(|(c, items)| -> Result<()> {
            for (g, items) in items.chunks_mut(PACKET).enumerate() {
                // Four consecutive rays at a time, exactly as the GPU kernels group them.
                let first = (c * chunk + g * PACKET) as u32;
                let m = items.len();
                let mut rays = [Ray::default(); PACKET];
                let mut paths = [PathState::start(0); PACKET];
                for l in 0..PACKET {
                    if l < m {
                        let pixel = camera::pixel(cam, first + l as u32);
                        rays[l] = camera::primary_ray(cam, pixel);
                        paths[l] = PathState::start(pixel);
                    } else {
                        paths[l].active = 0;
                    }
                }
                for bounce in 0..=max_bounces {
                    let hit = self.closest4(accel, &rays)?;
                    if bounce == 0 {
                        for (item, h) in items.iter_mut().zip(hit) {
                            item.0 = h;
                        }
                    }
                    let mut shadow = [Ray::default(); PACKET];
                    let mut terms = [ShadeTerms::default(); PACKET];
                    for l in 0..m {
                        (shadow[l], terms[l]) = shade::path_step(
                            seed,
                            bounce,
                            max_bounces,
                            &mut rays[l],
                            &hit[l],
                            &mut paths[l],
                            self.tris,
                            self.materials,
                            &self.lights,
                            self.lights.len() as u32,
                        );
                    }
                    let occluded = if self.lights.is_empty() { [false; PACKET] } else { self.any4(accel, &shadow)? };
                    for l in 0..m {
                        shade::accumulate(&mut paths[l], &terms[l], occluded[l]);
                    }
                    if paths.iter().all(|p| p.active == 0) {
                        break;
                    }
                }
                for (item, p) in items.iter_mut().zip(&paths) {
                    item.1 = [p.radiance[0], p.radiance[1], p.radiance[2], 1.0];
                }
            }
            progress.inc(items.len() as u64);
            Ok(())
        })?;
        let mut hits = vec![Hit::NONE; n];
        let mut radiance = vec![[0.0f32; 4]; n];
        for (k, (hit, rad)) in traced.into_iter().enumerate() {
            let px = camera::pixel(cam, k as u32) as usize;
            hits[px] = hit;
            radiance[px] = rad;
        }
        Ok(RenderOutput { width: w, height: h, hits, radiance })
    }
}
