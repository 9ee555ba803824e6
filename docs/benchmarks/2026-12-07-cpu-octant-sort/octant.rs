// Scratch: bvh+packets natively on dumped rays, in their order and sorted by direction octant
// (stable). Usage: zz_octant SCENE.obj RAYS.npy closest|any REPS
use kdray::runtime::cpu::NATIVE;
use kdray::{Accel, Tracer};
use kdray_shared::Ray;
use std::time::Instant;

fn read_rays(p: &str) -> Vec<Ray> {
    let b = std::fs::read(p).unwrap();
    let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
    let data = &b[10 + hl..];
    let f: Vec<f32> = data.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    f.chunks_exact(8).map(|r| Ray { origin: [r[0], r[1], r[2]], t_min: r[3], dir: [r[4], r[5], r[6]], t_max: r[7] }).collect()
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let s = kdray::scene::load(&a[1]).unwrap();
    let rays = read_rays(&a[2]);
    let any = a[3] == "any";
    let reps: usize = a[4].parse().unwrap();
    let bvh = kdray::bvh::try_build(&s.triangles).unwrap();
    let t = Tracer::new(&NATIVE, &s, None).unwrap().with_bvh(&bvh).unwrap();
    let oct = |r: &Ray| ((r.dir[0] < 0.0) as usize) << 2 | ((r.dir[1] < 0.0) as usize) << 1 | (r.dir[2] < 0.0) as usize;
    let mut order: Vec<usize> = (0..rays.len()).collect();
    order.sort_by_key(|&i| oct(&rays[i]));
    let sorted: Vec<Ray> = order.iter().map(|&i| rays[i]).collect();
    let run = |r: &[Ray]| -> (f64, Vec<u32>) {
        let t0 = Instant::now();
        let out: Vec<u32> = if any { t.any_hits(Accel::BVH_PACKETS, r).unwrap().into_iter().map(|b| b as u32).collect() } else { t.closest_hits(Accel::BVH_PACKETS, r).unwrap().into_iter().map(|h| h.prim).collect() };
        (r.len() as f64 / t0.elapsed().as_secs_f64() / 1e6, out)
    };
    let (_, base) = run(&rays);
    let (_, so) = run(&sorted);
    let same = order.iter().enumerate().all(|(j, &i)| so[j] == base[i]);
    let mix = rays.chunks(8).filter(|c| c.iter().any(|r| oct(r) != oct(&c[0]))).count();
    let mix_s = sorted.chunks(8).filter(|c| c.iter().any(|r| oct(r) != oct(&c[0]))).count();
    let sum = |r: &[Ray]| {
        let c = kdray::analysis::bvh_counts(&bvh, r, !any, true);
        let n = r.len() as f64;
        let (nodes, tris) = c.iter().fold((0u64, 0u64), |(a, b), x| (a + x.nodes as u64, b + x.tris as u64));
        (nodes as f64 / n, tris as f64 / n)
    };
    let (c1, c2) = (sum(&rays), sum(&sorted));
    println!("counts per ray (packet node visits count once for the packet's rays): nodes {:.3} -> {:.3}, triangles {:.3} -> {:.3}", c1.0, c2.0, c1.1, c2.1);
    let (mut a1, mut a2) = (vec![], vec![]);
    for _ in 0..reps {
        a1.push(run(&rays).0);
        a2.push(run(&sorted).0);
    }
    a1.sort_by(|x, y| x.partial_cmp(y).unwrap());
    a2.sort_by(|x, y| x.partial_cmp(y).unwrap());
    println!("{} {}: same answers {same}; mixed-octant packets of 8 {mix} -> {mix_s} of {}; Mrays/s median/max as is {:.2}/{:.2} sorted {:.2}/{:.2}", a[2].rsplit('/').next().unwrap(), a[3], rays.len() / 8, a1[reps / 2], a1[reps - 1], a2[reps / 2], a2[reps - 1]);
}
