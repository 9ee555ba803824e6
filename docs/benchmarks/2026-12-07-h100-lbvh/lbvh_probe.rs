// LBVH (kernels) vs host SAH build: build times (native, GPU if present), SAH, and per-ray
// node/triangle counts of primary rays (512^2) on both trees.
use kdray::runtime::cpu::NATIVE;
use kdray::Runtime;
use kdray_shared::camera;
fn counts(b: &kdray::bvh::BvhData, rays: &[kdray::Ray]) -> (f64, f64) {
    let c = kdray::analysis::bvh_counts(b, rays, true, false);
    let n = c.len() as f64;
    (c.iter().map(|c| c.nodes as f64).sum::<f64>() / n, c.iter().map(|c| c.tris as f64).sum::<f64>() / n)
}
fn trace(which: &str, spec: &str) {
    let g = kdray::gpu::Gpu::new().unwrap();
    let s = kdray::scene::load(spec).unwrap();
    let b = if which == "host" { kdray::bvh::try_build(&s.triangles).unwrap() } else { kdray::lbvh::build_on(&g, &s.triangles).unwrap().bvh };
    let t = kdray::Tracer::new(&g, &s, None).unwrap().with_bvh(&b).unwrap();
    let cam = s.camera.to_pod(1024, 1024);
    let rays: Vec<kdray::Ray> = (0..1024 * 1024).map(|i| camera::primary_ray(&cam, i)).collect();
    let mut hits = 0;
    for _ in 0..10 {
        hits = t.closest_hits(kdray::Accel::BVH, &rays).unwrap().iter().filter(|h| h.is_hit()).count();
    }
    println!("trace {which} {spec}: {hits} hits of {} (10 runs of closest_bvh; GPU times below)", rays.len());
}
fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(|a| a.as_str()) == Some("trace") {
        trace(&args[2], &args[3]);
        return;
    }
    let gpu = kdray::gpu::Gpu::new().ok();
    if let Some(g) = &gpu { println!("device: {}", g.name()); }
    for spec in std::env::args().skip(1) {
        let s = kdray::scene::load(&spec).unwrap();
        let mut th = f64::MAX;
        let mut h = None;
        for _ in 0..3 { let t = std::time::Instant::now(); h = Some(kdray::bvh::try_build(&s.triangles).unwrap()); th = th.min(t.elapsed().as_secs_f64()); }
        let h = h.unwrap();
        let mut nb = f64::MAX; let mut g0 = None;
        for _ in 0..3 { let g = kdray::lbvh::build_on(&NATIVE, &s.triangles).unwrap(); nb = nb.min(g.build_s); g0 = Some(g); }
        let g0 = g0.unwrap();
        g0.bvh.validate(s.triangles.len()).unwrap();
        let cam = s.camera.to_pod(512, 512);
        let rays: Vec<kdray::Ray> = (0..512 * 512).map(|i| camera::primary_ray(&cam, i)).collect();
        let (hn, ht) = counts(&h, &rays);
        let (ln, lt) = counts(&g0.bvh, &rays);
        println!("{spec}: {} tris | host SAH build {:.3}s SAH {:.1} nodes/ray {:.2} tris/ray {:.2} | kernels native {:.3}s SAH {:.1} nodes/ray {:.2} tris/ray {:.2}",
            s.triangles.len(), th, h.sah_cost, hn, ht, nb, g0.bvh.sah_cost, ln, lt);
        if let Some(g) = &gpu {
            let mut best = f64::MAX; let mut last = None;
            for _ in 0..7 { let b = kdray::lbvh::build_on(g as &dyn Runtime, &s.triangles).unwrap(); best = best.min(b.build_s); last = Some(b); }
            let b = last.unwrap();
            b.bvh.validate(s.triangles.len()).unwrap();
            println!("  gpu build min of 7: {:.2} ms (submit to done, incl. one read-back of 32 B), setup {:.1} ms, read {:.1} ms, SAH {:.1}, same SAH as native: {}",
                best * 1e3, b.setup_s * 1e3, b.read_s * 1e3, b.bvh.sah_cost, b.bvh.sah_cost == g0.bvh.sah_cost);
            if let Ok(p) = std::env::var("KDRAY_PROFILE") { let _ = p; }
        }
    }
}
