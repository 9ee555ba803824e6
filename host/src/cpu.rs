//! The native runtime: the `kdray-shared` functions over all cores with rayon.
use crate::kdtree::KdTreeData;
use crate::scene::Scene;
use crate::trace::{Accel, RenderOutput, Tracer};
use anyhow::{anyhow, Result};
use indicatif::ProgressBar;
use kdray_shared::kdtree::{self, Algorithm, Counters, NoStats, Stats};
use kdray_shared::{brute, camera, shade, Camera, Hit, Light, Material, PathState, Ray, Triangle};
use rayon::prelude::*;

/// Borrows the scene and the tree: creating one copies nothing but the light list.
pub struct CpuTracer<'s> {
    tris: &'s [Triangle],
    materials: &'s [Material],
    lights: Vec<Light>,
    tree: Option<&'s KdTreeData>,
    has_mirror: bool,
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

    fn tree(&self) -> Result<kdtree::KdTree<'s>> {
        self.tree.map(|t| t.view(self.tris)).ok_or_else(|| anyhow!("no kd-tree was built for this scene"))
    }

    fn closest<S: Stats>(&self, accel: Accel, ray: &Ray, stats: &mut S) -> Result<Hit> {
        Ok(match accel {
            Accel::Brute => brute::closest_hit(ray, self.tris),
            Accel::Kd(alg) => kdtree::closest_hit(alg, &self.tree()?, ray, stats),
        })
    }

    fn any<S: Stats>(&self, accel: Accel, ray: &Ray, stats: &mut S) -> Result<bool> {
        Ok(match accel {
            Accel::Brute => brute::any_hit(ray, self.tris),
            Accel::Kd(alg) => kdtree::any_hit(alg, &self.tree()?, ray, stats),
        })
    }

    /// Per-ray traversal counters of `alg` (closest hit if `closest`, else any hit).
    pub fn count(&self, alg: Algorithm, rays: &[Ray], closest: bool) -> Result<Vec<Counters>> {
        let tree = self.tree()?;
        Ok(rays
            .par_iter()
            .map(|r| {
                let mut c = Counters::default();
                if closest {
                    kdtree::closest_hit(alg, &tree, r, &mut c);
                } else {
                    kdtree::any_hit(alg, &tree, r, &mut c);
                }
                c
            })
            .collect())
    }
}

/// Rows per parallel work item of the renderer (also the progress granularity).
const ROWS_PER_TASK: u32 = 4;

impl Tracer for CpuTracer<'_> {
    fn device_name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn closest_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<Hit>> {
        rays.par_iter().map(|r| self.closest(accel, r, &mut NoStats)).collect()
    }

    fn any_hits(&self, accel: Accel, rays: &[Ray]) -> Result<Vec<bool>> {
        rays.par_iter().map(|r| self.any(accel, r, &mut NoStats)).collect()
    }

    fn render(&self, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput> {
        if let Accel::Kd(_) = accel {
            self.tree()?;
        }
        let max_bounces = if self.has_mirror { bounces } else { 0 };
        let (w, h) = (cam.width, cam.height);
        let n = (w * h) as usize;
        let mut hits = vec![Hit::NONE; n];
        let mut radiance = vec![[0.0f32; 4]; n];
        let chunk = (w * ROWS_PER_TASK) as usize;
        progress.set_length(n as u64);
        hits.par_chunks_mut(chunk).zip(radiance.par_chunks_mut(chunk)).enumerate().try_for_each(
            |(c, (hs, rs))| -> Result<()> {
                for (k, (primary, rad)) in hs.iter_mut().zip(rs.iter_mut()).enumerate() {
                    let pixel = (c * chunk + k) as u32;
                    let mut ray = camera::primary_ray(cam, pixel);
                    let mut path = PathState::START;
                    for bounce in 0..=max_bounces {
                        let hit = self.closest(accel, &ray, &mut NoStats)?;
                        if bounce == 0 {
                            *primary = hit;
                        }
                        let (shadow, terms) = shade::path_step(
                            seed,
                            pixel,
                            bounce,
                            max_bounces,
                            &mut ray,
                            &hit,
                            &mut path,
                            self.tris,
                            self.materials,
                            &self.lights,
                            self.lights.len() as u32,
                        );
                        let occluded = !self.lights.is_empty() && self.any(accel, &shadow, &mut NoStats)?;
                        shade::accumulate(&mut path, &terms, occluded);
                        if path.active == 0 {
                            break;
                        }
                    }
                    *rad = [path.radiance[0], path.radiance[1], path.radiance[2], 1.0];
                }
                progress.inc(hs.len() as u64);
                Ok(())
            },
        )?;
        Ok(RenderOutput { width: w, height: h, hits, radiance })
    }
}
