// Repeated kernel BVH builds in one process: fresh buffers (build_with) or kept ones (LbvhBuilder).
// Usage: zz_repeat fresh|kept ROUNDS SCENE N
use kdray::Runtime;
use std::time::{SystemTime, UNIX_EPOCH};
fn now_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
        * 1e3
}
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let (mode, rounds, spec, n): (&str, u32, &str, usize) =
        (&a[1], a[2].parse().unwrap(), &a[3], a[4].parse().unwrap());
    let g = kdray::gpu::Gpu::new().unwrap();
    let rt = &g as &dyn Runtime;
    let s = kdray::scene::load(spec).unwrap();
    // Pipelines made on a tiny scene first.
    kdray::lbvh::build_with(
        rt,
        &kdray::scene::load("cornell").unwrap().triangles,
        rounds,
    )
    .unwrap();
    let mut builder = kdray::lbvh::LbvhBuilder::new(rt);

    let t0 = now_ms();
    let gap: u64 = std::env::var("GAP_MS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let warm_ms: u64 = std::env::var("WARM_MS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let host = kdray::bvh::try_build(&s.triangles).unwrap();
    let t = kdray::Tracer::new(&g, &s, None)
        .unwrap()
        .with_bvh(&host)
        .unwrap();
    let cam = s.camera.to_pod(512, 512);
    let rays: Vec<kdray::Ray> = (0..512 * 512)
        .map(|i| kdray_shared::camera::primary_ray(&cam, i))
        .collect();
    let rbuf = rt.upload("ray", &rays).unwrap();
    let out = rt.alloc::<kdray_shared::Hit>("result", rays.len()).unwrap();
    let passes = t
        .query_passes::<kdray_shared::query::Closest>(
            kdray::Accel::BVH,
            rays.len(),
            &rbuf,
            &out,
            None,
        )
        .unwrap();
    let passes: Vec<&dyn kdray::runtime::Kernel> = passes.iter().map(|k| k.as_ref()).collect();
    for i in 0..n {
        std::thread::sleep(std::time::Duration::from_millis(gap));
        if warm_ms > 0 {
            g.warm_up(&passes, std::time::Duration::from_millis(warm_ms))
                .unwrap();
        }
        let start = now_ms();
        let b = if mode == "kept" {
            builder.build(&s.triangles, rounds).unwrap()
        } else {
            kdray::lbvh::build_with(rt, &s.triangles, rounds).unwrap()
        };
        let end = now_ms();
        println!("BUILD {mode} {rounds} {spec} {i} start_ms={:.3} end_ms={:.3} epoch_start={start:.1} epoch_end={end:.1} setup={:.2} build={:.2} read={:.2} sah={:.2}", start - t0, end - t0, b.setup_s * 1e3, b.build_s * 1e3, b.read_s * 1e3, b.bvh.sah_cost);
    }
}
