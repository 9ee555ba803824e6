//! The ray batches of the benchmarks, generated natively with the renderer's own functions:
//! primary rays through pixel centres, the shadow rays of the pixels that hit, and the rays of
//! the n-th mirror reflection.
use kdray::kdtree::KdTreeData;
use kdray::scene::Scene;
use kdray::accel::Accel;
use kdray::runtime::cpu::NATIVE;
use kdray::tracer::Tracer;
use anyhow::Result;
use kdray_shared::kdtree::Algorithm;
use kdray_shared::{camera, shade, PathState, Ray};

/// Seed of the light samples of benchmark shadow rays.
const SEED: u32 = 1;

pub fn primary(scene: &Scene, size: u32) -> Vec<Ray> {
    let cam = scene.camera.to_pod(size, size);
    (0..size * size).map(|i| camera::primary_ray(&cam, i)).collect()
}

/// The pixels of a `size`² image in the renderer's tiled order (8×8 tiles, Morton order inside;
/// `camera::pixel`).
pub fn tiled_order(scene: &Scene, size: u32) -> Vec<u32> {
    let mut cam = scene.camera.to_pod(size, size);
    cam.order = kdray_shared::ORDER_TILES;
    (0..size * size).map(|i| camera::pixel(&cam, i)).collect()
}

/// Rays of every bounce 0..=max_bounces of the renderer's paths (bounce 0: primary rays;
/// bounce n: rays of paths reflected n times by mirrors), the shadow rays of bounce 0 and the
/// pixel of each shadow ray.
pub fn bounces(scene: &Scene, tree: &KdTreeData, size: u32, max_bounces: u32) -> Result<(Vec<Vec<Ray>>, Vec<Ray>, Vec<u32>)> {
    let cpu = Tracer::new(&NATIVE, scene, Some(tree))?;
    let lights = scene.lights();
    let mut rays = primary(scene, size);
    let mut paths: Vec<PathState> = (0..rays.len() as u32).map(PathState::start).collect();
    let mut out = vec![rays.clone()];
    let mut shadow = Vec::new();
    let mut shadow_pixels = Vec::new();
    for bounce in 0..=max_bounces {
        let hits = cpu.closest_hits(Accel::kd(Algorithm::Stack), &rays)?;
        let mut next = (Vec::new(), Vec::new());
        for (k, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
            let mut ray = *ray;
            let mut path = paths[k];
            let p = kdray_shared::RenderParams { seed: SEED, bounce, max_bounces, light_count: lights.len() as u32, ..Default::default() };
            let (s, _) = shade::path_step(&p, bounce, &mut ray, hit, &mut path, &kdray_shared::parts::Parts::one(&scene.triangles), &scene.materials, &lights);
            if bounce == 0 && s.is_valid() {
                shadow.push(s);
                shadow_pixels.push(path.pixel);
            }
            if path.is_active() {
                next.0.push(ray);
                next.1.push(path);
            }
        }
        (rays, paths) = next;
        if bounce < max_bounces {
            out.push(rays.clone());
        }
    }
    Ok((out, shadow, shadow_pixels))
}
