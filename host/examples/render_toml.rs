//! Renders a TOML scene file by progressive photon mapping, reporting progress through the
//! library's callback, and writes a PNG preview and linear-radiance PFM.
//!
//! ```sh
//! cargo run --release --example render_toml -- scenes/room.toml room.png [SIZE] [PASSES]
//! ```
use kdray::image_out::{write_pfm, write_png};
use kdray::integrator::photon::{self, PhotonMap, PhotonOptions};
use kdray::integrator::Progress;
use kdray::kdtree::{self, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Accel, Gpu, Runtime, Tracer};
use std::cell::Cell;

/// Prints a line every quarter of the passes.
struct Quarters {
    total: Cell<u64>,
    done: Cell<u64>,
}

impl Progress for Quarters {
    fn start(&self, total: u64) {
        self.total.set(total);
    }
    fn advance(&self, n: u64) {
        let (before, total) = (self.done.get(), self.total.get().max(1));
        self.done.set(before + n);
        if (before * 4 / total) != (self.done.get() * 4 / total) {
            println!("  {} of {total} passes", self.done.get());
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (file, out) = match (args.get(1), args.get(2)) {
        (Some(f), Some(p)) => (f.as_str(), std::path::PathBuf::from(p)),
        _ => return Err("usage: render_toml FILE.toml OUT.png [SIZE] [PASSES]".into()),
    };
    let size: u32 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(256);
    let passes: u32 = args.get(4).map(|s| s.parse()).transpose()?.unwrap_or(16);

    let scene = scene::load(file)?;
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default())?;
    let gpu = Gpu::new().ok().filter(|g| !g.is_software());
    let rt: &dyn Runtime = match &gpu {
        Some(g) => g,
        None => &NATIVE,
    };
    let tracer = Tracer::new(rt, &scene, Some(&tree))?;
    let o = PhotonOptions { passes, photons: if rt.is_native() { 1 << 16 } else { 1 << 20 }, ..Default::default() };
    let mut map = PhotonMap::new(&tracer, Accel::parse("shortstack")?, Some(&tree), &scene, o)?;
    let cam = scene.camera.to_pod(size, size);
    let progress = Quarters { total: Cell::new(0), done: Cell::new(0) };
    let (img, stats) = photon::render(&mut map, &cam, &progress)?;
    write_png(&img, 1.0, &out)?;
    write_pfm(&img, &out.with_extension("pfm"))?;
    println!(
        "{}: {} passes, {:.1} M photons stored, {:.2} s on {}: wrote {}",
        scene.name,
        stats.passes,
        stats.stored as f64 / 1e6,
        stats.seconds,
        tracer.device_name(),
        out.display()
    );
    Ok(())
}
