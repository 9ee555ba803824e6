// Treelet rounds on the device: GPU build time (min of 7), SAH; `trace R scene`: closest_bvh on 1024^2 primary rays with the tree of R rounds (R = host: the host's SAH build).
use kdray::Runtime;
use kdray_shared::camera;
fn trace(which: &str, spec: &str) {
    let g = kdray::gpu::Gpu::new().unwrap();
    let s = kdray::scene::load(spec).unwrap();
    let b = if which == "host" { kdray::bvh::try_build(&s.triangles).unwrap() } else { kdray::lbvh::build_with(&g, &s.triangles, which.parse().unwrap()).unwrap().bvh };
    let t = kdray::Tracer::new(&g, &s, None).unwrap().with_bvh(&b).unwrap();
    let cam = s.camera.to_pod(1024, 1024);
    let rays: Vec<kdray::Ray> = (0..1024 * 1024).map(|i| camera::primary_ray(&cam, i)).collect();
    let mut hits = 0;
    for _ in 0..10 {
        hits = t.closest_hits(kdray::Accel::BVH, &rays).unwrap().iter().filter(|h| h.is_hit()).count();
    }
    println!("trace {which} {spec}: SAH {:.1} {hits} hits of {} (10 runs of closest_bvh; GPU times below)", b.sah_cost, rays.len());
}
fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(|a| a.as_str()) == Some("repeat") {
        let g = kdray::gpu::Gpu::new().unwrap();
        let s = kdray::scene::load(&args[3]).unwrap();
        let rounds: u32 = args[2].parse().unwrap();
        let t: Vec<String> = (0..24).map(|_| { let b = kdray::lbvh::build_with(&g as &dyn Runtime, &s.triangles, rounds).unwrap(); format!("{:.1}/{:.1}", b.setup_s * 1e3, b.build_s * 1e3) }).collect();
        println!("repeat {} rounds {rounds}: 24 builds in one process, setup/build ms: {}", args[3], t.join(" "));
        return;
    }
    if args.get(1).map(|a| a.as_str()) == Some("once") {
        let g = kdray::gpu::Gpu::new().unwrap();
        let s = kdray::scene::load(&args[3]).unwrap();
        let rounds: u32 = args[2].parse().unwrap();
        // Pipelines made on a tiny scene first.
        kdray::lbvh::build_with(&g as &dyn Runtime, &kdray::scene::load("cornell").unwrap().triangles, rounds).unwrap();
        let t: Vec<String> = (0..3).map(|_| format!("{:.2}", kdray::lbvh::build_with(&g as &dyn Runtime, &s.triangles, rounds).unwrap().build_s * 1e3)).collect();
        println!("once {} rounds {rounds}: builds in a fresh process {} ms", args[3], t.join(", "));
        return;
    }
    if args.get(1).map(|a| a.as_str()) == Some("trace") {
        trace(&args[2], &args[3]);
        return;
    }
    let g = kdray::gpu::Gpu::new().unwrap();
    println!("device: {}", g.name());
    for spec in std::env::args().skip(1) {
        let s = kdray::scene::load(&spec).unwrap();
        for rounds in [0u32, 1, 2, 3] {
            let mut best = f64::MAX; let mut last = None;
            for _ in 0..7 { let b = kdray::lbvh::build_with(&g as &dyn Runtime, &s.triangles, rounds).unwrap(); best = best.min(b.build_s); last = Some(b); }
            let b = last.unwrap();
            b.bvh.validate(s.triangles.len()).unwrap();
            println!("{spec} ({} tris) rounds {rounds}: gpu build min of 7 {:.2} ms, setup {:.1} ms, read {:.1} ms, SAH {:.2}", s.triangles.len(), best * 1e3, b.setup_s * 1e3, b.read_s * 1e3, b.bvh.sah_cost);
        }
    }
}
