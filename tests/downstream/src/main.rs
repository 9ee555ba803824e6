//! Uses kdray as a library from another crate: a mesh and rays as arrays, hits on the GPU when
//! there is one (every adapter, lavapipe included) and natively, the answers compared, and the
//! typed errors matched. Exits non-zero on any disagreement.
use kdray::kdtree::{self, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{Accel, Error, Gpu, Ray, Runtime, Scene, Tracer};

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Error> {
    // A tetrahedron and rays from a grid of points toward its centre.
    let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let scene = Scene::from_mesh("tetrahedron", &vertices, &faces)?;
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default())?;
    let centre = [0.25f32, 0.25, 0.25];
    let rays: Vec<Ray> = (0..4096)
        .map(|i| {
            let o = [(i % 16) as f32 * 0.3 - 2.0, ((i / 16) % 16) as f32 * 0.3 - 2.0, (i / 256) as f32 * 0.3 - 2.0];
            let d = [centre[0] - o[0], centre[1] - o[1], centre[2] - o[2]];
            Ray::new(o, d, 0.0, f32::INFINITY)
        })
        .collect();

    let native = Tracer::new(&NATIVE, &scene, Some(&tree))?.closest_hits(Accel::parse("shortstack")?, &rays)?;
    // Every ray aims at a point inside the tetrahedron: it hits (rays starting inside hit too).
    let missed = native.iter().filter(|h| !h.is_hit()).count();
    if missed > 0 {
        return Err(Error::InvalidInput(format!("{missed} rays aimed at the centre missed")));
    }
    match Gpu::new() {
        Ok(gpu) => {
            let rt: &dyn Runtime = &gpu;
            let hits = Tracer::new(rt, &scene, Some(&tree))?.closest_hits(Accel::parse("shortstack")?, &rays)?;
            // Many of these rays pass through an edge or a vertex, where two triangles tie: the
            // distance must agree, the triangle may differ.
            let differ = hits.iter().zip(&native).filter(|(a, b)| a.is_hit() != b.is_hit() || (a.t - b.t).abs() > 1e-5 * b.t.abs()).count();
            let ties = hits.iter().zip(&native).filter(|(a, b)| a.prim != b.prim).count();
            println!("{} rays on {} and natively: {differ} distances differ ({ties} ties resolved to the other triangle)", rays.len(), gpu.adapter_line());
            if differ > 0 {
                return Err(Error::InvalidInput(format!("{differ} hits differ between the GPU and the CPU")));
            }
        }
        Err(Error::NoAdapter(why)) if std::env::var("KDRAY_REQUIRE_GPU").as_deref() != Ok("1") => println!("no GPU ({why}): native only"),
        Err(e) => return Err(e),
    }

    // Bad input gives a typed error a caller can match on.
    match Scene::from_mesh("nan", &[[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]) {
        Err(Error::Scene(msg)) => println!("a NaN vertex: {msg}"),
        other => return Err(Error::InvalidInput(format!("a NaN vertex gave {other:?}"))),
    }
    match kdray::scene::load("/no/such/scene.obj") {
        Err(e) if matches!(e.kind(), Error::Io { .. } | Error::SceneFile { .. }) => println!("a missing file: {e}"),
        other => return Err(Error::InvalidInput(format!("a missing file gave {:?}", other.map(|s| s.name)))),
    }
    println!("kdray as a dependency: ok");
    Ok(())
}
