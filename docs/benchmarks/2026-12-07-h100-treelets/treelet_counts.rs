// Treelet rounds: native LBVH build time, binary SAH, primary-ray nodes/tris per ray, vs the host build.
use kdray::runtime::cpu::NATIVE;
use kdray_shared::camera;
fn counts(b: &kdray::bvh::BvhData, rays: &[kdray::Ray], shadow: bool) -> (f64, f64) {
    let c = kdray::analysis::bvh_counts(b, rays, !shadow, false);
    let n = c.len() as f64;
    (c.iter().map(|c| c.nodes as f64).sum::<f64>() / n, c.iter().map(|c| c.tris as f64).sum::<f64>() / n)
}
fn main() {
    for spec in std::env::args().skip(1) {
        let s = kdray::scene::load(&spec).unwrap();
        let cam = s.camera.to_pod(256, 256);
        let rays: Vec<kdray::Ray> = (0..256 * 256).map(|i| camera::primary_ray(&cam, i)).collect();
        let h = kdray::bvh::try_build(&s.triangles).unwrap();
        let (hn, ht) = counts(&h, &rays, false);
        println!("{spec}: {} tris | host SAH {:.1} nodes/ray {:.2} tris/ray {:.2}", s.triangles.len(), h.sah_cost, hn, ht);
        for rounds in [0u32, 1, 2, 3] {
            let g = kdray::lbvh::build_with(&NATIVE, &s.triangles, rounds).unwrap();
            g.bvh.validate(s.triangles.len()).unwrap();
            let (ln, lt) = counts(&g.bvh, &rays, false);
            println!("  rounds {rounds}: native {:.3}s SAH {:.1} nodes/ray {:.2} tris/ray {:.2} depth {} nodes {}", g.build_s, g.bvh.sah_cost, ln, lt, g.bvh.depth, g.bvh.nodes.len());
        }
    }
}
