//! Renders an OBJ file (materials from its MTL) with the path tracer, on a hardware GPU when
//! there is one and natively otherwise, and writes a PNG preview and linear-radiance PFM.
//!
//! ```sh
//! cargo run --release --example render_obj -- scenes/room.obj room.png [SIZE] [SPP]
//! ```
use kdray::image_out::{write_pfm, write_png};
use kdray::integrator::path::{self, PathOptions};
use kdray::kdtree::{self, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Accel, Gpu, Runtime, Tracer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (obj, out) = match (args.get(1), args.get(2)) {
        (Some(o), Some(p)) => (o.as_str(), std::path::PathBuf::from(p)),
        _ => return Err("usage: render_obj FILE.obj OUT.png [SIZE] [SPP]".into()),
    };
    let size: u32 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(256);
    let spp: u32 = args.get(4).map(|s| s.parse()).transpose()?.unwrap_or(64);

    let scene = scene::load(obj)?;
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default())?;
    // A software Vulkan driver (lavapipe) runs the kernels slower than the native runtime.
    let gpu = Gpu::new().ok().filter(|g| !g.is_software());
    let rt: &dyn Runtime = match &gpu {
        Some(g) => g,
        None => &NATIVE,
    };
    let tracer = Tracer::new(rt, &scene, Some(&tree))?;
    let cam = scene.camera.to_pod(size, size);
    let img = path::render(&tracer, Accel::parse("shortstack")?, &cam, &PathOptions::path(1, 32, spp), &())?;
    write_png(&img, 1.0, &out)?;
    write_pfm(&img, &out.with_extension("pfm"))?;
    let mean = img.radiance.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / img.radiance.len() as f64;
    println!("{}: {} triangles, {size}² × {spp} spp on {}, mean radiance {mean:.4}: wrote {}", scene.name, scene.triangles.len(), tracer.device_name(), out.display());
    if !(mean.is_finite() && mean > 0.0) {
        return Err("the image is black or not finite".into());
    }
    Ok(())
}
