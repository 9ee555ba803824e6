//! Rays given as arrays against a mesh given as arrays: closest hits and occlusion on the GPU
//! (the native runtime when there is none), checked against the native runtime.
//!
//! ```sh
//! cargo run --release --example trace_arrays
//! ```
use kdray::kdtree::{self, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{Accel, Error, Gpu, Hit, Ray, Runtime, Scene, Tracer};

fn main() -> Result<(), Error> {
    // A unit cube: 8 vertices, 12 triangles.
    let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]];
    let faces = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [3, 7, 6], [3, 6, 2], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]];
    let scene = Scene::from_mesh("cube", &vertices, &faces)?;
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default())?;

    // A 64 × 64 grid of rays along −z from z = 3, three quarters of them passing beside the cube.
    let n = 64;
    let rays: Vec<Ray> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32 / n as f32 * 2.0 - 0.5, (i / n) as f32 / n as f32 * 2.0 - 0.5);
            Ray::new([x, y, 3.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
        })
        .collect();

    let gpu = match Gpu::new() {
        Ok(g) => Some(g),
        Err(Error::NoAdapter(why)) => {
            println!("no GPU ({why}): the native runtime only");
            None
        }
        Err(e) => return Err(e),
    };
    let rt: &dyn Runtime = match &gpu {
        Some(g) => g,
        None => &NATIVE,
    };
    let accel = Accel::parse("shortstack")?;
    let tracer = Tracer::new(rt, &scene, Some(&tree))?;
    let hits: Vec<Hit> = tracer.closest_hits(accel, &rays)?;
    let occluded: Vec<bool> = tracer.any_hits(accel, &rays)?;

    let reference = Tracer::new(&NATIVE, &scene, Some(&tree))?.closest_hits(Accel::BRUTE, &rays)?;
    let agree = hits.iter().zip(&reference).filter(|(a, b)| a.prim == b.prim).count();
    let hit = hits.iter().filter(|h| h.is_hit()).count();
    println!("{} rays on {}: {hit} hit the cube, {} occluded, {agree} agree with brute force on the CPU", rays.len(), tracer.device_name(), occluded.iter().filter(|o| **o).count());
    // Every ray that hits meets the front face z = 1 at t = 2.
    assert!(hits.iter().filter(|h| h.is_hit()).all(|h| (h.t - 2.0).abs() < 1e-6));
    assert_eq!(hit, occluded.iter().filter(|o| **o).count());
    assert_eq!(agree, rays.len());
    Ok(())
}
