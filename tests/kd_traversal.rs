//! Every kd-tree traversal (full stack, kd-restart, push-down, short-stack 1..8; one ray at a
//! time and in packets of four), the decomposed pipeline and the compressed wide BVH against
//! the brute-force oracle, natively and on the GPU, on the hard cases of kd-tree traversal and
//! on random rays.
mod common;

use glam::Vec3;
use kdray::kdtree::{build, BuildOptions, KdTreeData};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Accel, Scene, Tracer};
use kdray_shared::kdtree::{Algorithm, MAX_SHORT_STACK};
use kdray_shared::rng::Rng;
use kdray_shared::{Hit, Ray};

fn cpu_algorithms() -> Vec<Algorithm> {
    let mut v = vec![Algorithm::Stack, Algorithm::Restart, Algorithm::PushDown];
    v.extend((1..=MAX_SHORT_STACK).map(Algorithm::ShortStack));
    v
}

/// Two hits agree: same triangle, or a tie (another triangle at the same point: a shared edge
/// or vertex, where the GPU's division may round t differently).
fn agree(a: &Hit, b: &Hit) -> bool {
    a.prim == b.prim || (a.is_hit() && b.is_hit() && (a.t - b.t).abs() <= 1e-6 * a.t.abs())
}

/// Packet traversals and decomposed pipelines checked natively (bit-identical to the oracle).
fn cpu_grouped() -> Vec<Accel> {
    let mut v: Vec<Accel> = [Algorithm::Stack, Algorithm::Restart, Algorithm::PushDown, Algorithm::ShortStack(1), Algorithm::ShortStack(2), Algorithm::ShortStack(3), Algorithm::ShortStack(8)]
        .into_iter()
        .map(Accel::packet)
        .collect();
    v.extend([1, 3, 16].map(Accel::decomposed));
    v
}

/// The same on the GPU (every packet kernel; leaf lists that overflow often and rarely).
fn gpu_grouped() -> Vec<Accel> {
    let mut v: Vec<Accel> = Accel::gpu_packets();
    v.extend([2, 16].map(Accel::decomposed));
    v
}

/// Ray order that groups rays by the signs of their direction (stable within an octant), so
/// that most groups of four are coherent packets even though their origins are scattered.
fn octant_order(rays: &[Ray]) -> Vec<usize> {
    let key = |r: &Ray| r.dir.iter().enumerate().map(|(a, d)| (d.is_sign_negative() as u32) << a).sum::<u32>();
    let mut order: Vec<usize> = (0..rays.len()).collect();
    order.sort_by_key(|&i| key(&rays[i]));
    order
}

/// GPU kernels that get every random ray; the others get `GPU_SAMPLE` of them (lavapipe in CI
/// runs on two CPU cores).
const GPU_FULL: [Accel; 3] = [Accel::kd(Algorithm::Stack), Accel::kd(Algorithm::ShortStack(3)), Accel::BVH];

/// Every one-ray GPU kernel but the oracle's: the kd traversals and the BVH.
fn gpu_single() -> Vec<Accel> {
    let mut v: Vec<Accel> = Accel::all().into_iter().skip(1).collect();
    v.push(Accel::BVH);
    v
}
const GPU_SAMPLE: usize = 1 << 16;

/// Checks every traversal against the oracle; `rays[..hard]` are hand-made hard cases, the
/// rest random. Natively the hits must be bit-identical (same triangle test, same inputs). On
/// the GPU a hit may differ only as a tie (the same point on two triangles), and on random rays
/// at most 1e-5 of the ids may differ. Returns the oracle's hits.
fn check(name: &str, scene: &Scene, tree: &KdTreeData, rays: &[Ray], hard: usize) -> Vec<Hit> {
    check_on(name, scene, tree, rays, hard, true)
}

/// `check`, natively only when `on_gpu` is false.
fn check_on(name: &str, scene: &Scene, tree: &KdTreeData, rays: &[Ray], hard: usize, on_gpu: bool) -> Vec<Hit> {
    let bvh = kdray::bvh::build(&scene.triangles);
    let cpu = Tracer::new(&NATIVE, scene, Some(tree)).unwrap().with_bvh(&bvh).unwrap();
    let oracle = cpu.closest_hits(Accel::BRUTE, rays).unwrap();
    let oracle_any = cpu.any_hits(Accel::BRUTE, rays).unwrap();
    // The wide BVH, natively: bit-identical to the oracle, one ray at a time and in packets
    // (as given: packets of nearby origins go together; and every ray in a bundle of its own).
    common::assert_matches_oracle(&format!("{name}: CPU"), &cpu, Accel::BVH, rays, &oracle, &oracle_any);
    common::assert_matches_oracle(&format!("{name}: CPU"), &cpu, Accel::BVH_PACKETS, rays, &oracle, &oracle_any);
    common::assert_packets_match_single(&format!("{name}: CPU"), &cpu, rays);
    for alg in cpu_algorithms() {
        let hits = cpu.closest_hits(Accel::kd(alg), rays).unwrap();
        let bad: Vec<usize> = (0..rays.len()).filter(|&i| hits[i] != oracle[i]).collect();
        if let Some(&i) = bad.first() {
            panic!(
                "{name}: CPU {alg:?} differs from the oracle on {} of {} rays; first: {:?} gives {:?}, oracle {:?}",
                bad.len(), rays.len(), rays[i], hits[i], oracle[i]
            );
        }
        let any = cpu.any_hits(Accel::kd(alg), rays).unwrap();
        let bad = (0..rays.len()).filter(|&i| any[i] != oracle_any[i]).count();
        assert_eq!(bad, 0, "{name}: CPU {alg:?} any-hit differs on {bad} rays");
    }
    // Packets and the decomposed pipeline on the rays grouped by octant.
    let order = octant_order(rays);
    let grouped: Vec<Ray> = order.iter().map(|&i| rays[i]).collect();
    let coherent = kdray::analysis::coherent_packets(&grouped);
    println!("{name}: {coherent} of {} packets coherent", grouped.len().div_ceil(4));
    for accel in cpu_grouped() {
        let hits = cpu.closest_hits(accel, &grouped).unwrap();
        let bad: Vec<usize> = (0..rays.len()).filter(|&k| hits[k] != oracle[order[k]]).collect();
        if let Some(&k) = bad.first() {
            panic!(
                "{name}: CPU {} differs from the oracle on {} of {} rays; first: {:?} gives {:?}, oracle {:?}",
                accel.name(), bad.len(), rays.len(), grouped[k], hits[k], oracle[order[k]]
            );
        }
        let any = cpu.any_hits(accel, &grouped).unwrap();
        let bad = (0..rays.len()).filter(|&k| any[k] != oracle_any[order[k]]).count();
        assert_eq!(bad, 0, "{name}: CPU {} any-hit differs on {bad} rays", accel.name());
    }
    if let Some(g) = common::gpu().filter(|_| on_gpu) {
        let gpu = Tracer::new(g, scene, Some(tree)).unwrap().with_bvh(&bvh).unwrap();
        for accel in gpu_single() {
            let n = if GPU_FULL.contains(&accel) { rays.len() } else { (hard + GPU_SAMPLE).min(rays.len()) };
            let hits = gpu.closest_hits(accel, &rays[..n]).unwrap();
            let bad: Vec<usize> = (0..n).filter(|&i| !agree(&oracle[i], &hits[i])).collect();
            if let Some(&i) = bad.first() {
                panic!(
                    "{name}: GPU {} misses the oracle's hit on {} of {n} rays; first: {:?} gives {:?}, oracle {:?}",
                    accel.name(), bad.len(), rays[i], hits[i], oracle[i]
                );
            }
            let differ = (hard..n).filter(|&i| hits[i].prim != oracle[i].prim).count();
            let random = n - hard;
            assert!(differ as f64 <= 1e-5 * random as f64, "{name}: GPU {} ids differ on {differ} of {random} random rays", accel.name());
            let any = gpu.any_hits(accel, &rays[..n]).unwrap();
            let bad = (0..n).filter(|&i| any[i] != oracle_any[i]).count();
            assert!(bad as f64 <= 1e-5 * n as f64, "{name}: GPU {} any-hit differs on {bad} of {n} rays", accel.name());
            println!("{name}: GPU {} on {n} rays: {differ} ids differ on random rays", accel.name());
        }
        // Packets and decomposed pipelines must give exactly the GPU's single-ray results.
        let n = (hard + GPU_SAMPLE).min(rays.len());
        let sample: Vec<usize> = octant_order(&rays[..n]);
        let grouped: Vec<Ray> = sample.iter().map(|&i| rays[i]).collect();
        let single = gpu.closest_hits(Accel::kd(Algorithm::Stack), &grouped).unwrap();
        let single_any = gpu.any_hits(Accel::kd(Algorithm::Stack), &grouped).unwrap();
        // The BVH's packets: exactly the GPU's one-ray BVH walk.
        let wide = gpu.closest_hits(Accel::BVH, &grouped).unwrap();
        let wide_any = gpu.any_hits(Accel::BVH, &grouped).unwrap();
        let (packed, packed_any) = (gpu.closest_hits(Accel::BVH_PACKETS, &grouped).unwrap(), gpu.any_hits(Accel::BVH_PACKETS, &grouped).unwrap());
        let bad = (0..n).filter(|&k| packed[k] != wide[k]).count();
        assert_eq!(bad, 0, "{name}: GPU bvh+packets differs from the GPU BVH on {bad} of {n} rays");
        let bad = (0..n).filter(|&k| packed_any[k] != wide_any[k]).count();
        assert_eq!(bad, 0, "{name}: GPU bvh+packets any-hit differs from the GPU BVH on {bad} of {n} rays");
        for accel in gpu_grouped() {
            let hits = gpu.closest_hits(accel, &grouped).unwrap();
            let bad: Vec<usize> = (0..n).filter(|&k| hits[k] != single[k]).collect();
            if let Some(&k) = bad.first() {
                panic!(
                    "{name}: GPU {} differs from the GPU full stack on {} of {n} rays; first: {:?} gives {:?}, stack {:?}",
                    accel.name(), bad.len(), grouped[k], hits[k], single[k]
                );
            }
            let any = gpu.any_hits(accel, &grouped).unwrap();
            let bad = (0..n).filter(|&k| any[k] != single_any[k]).count();
            assert_eq!(bad, 0, "{name}: GPU {} any-hit differs from the full stack on {bad} of {n} rays", accel.name());
        }
    }
    oracle
}

/// Split planes of the tree: (axis, position) of every interior node.
fn split_planes(tree: &KdTreeData) -> Vec<(usize, f32)> {
    tree.nodes.iter().filter(|n| !n.is_leaf()).map(|n| (n.axis(), n.split())).collect()
}

/// The hard cases of kd-tree traversal for a scene, then `n_random` random rays; returns the
/// rays and the number of hard cases.
fn hard_rays(scene: &Scene, tree: &KdTreeData, n_random: usize, seed: u32) -> (Vec<Ray>, usize) {
    let (lo, hi) = scene.bounds();
    let ext = hi - lo;
    let mut rng = Rng::new(seed, 17);
    let point = |rng: &mut Rng| lo - ext * 0.1 + ext * 1.2 * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    let mut rays = Vec::new();
    let dirs = common::random_dirs(n_random + 4096, seed);
    for (k, p) in split_planes(tree).into_iter().take(400) {
        for j in 0..6 {
            // Axis-aligned rays lying exactly in the split plane (direction component ±0).
            let mut o = point(&mut rng);
            o[k] = p;
            let mut d = [0.0f32; 3];
            let a = (k + 1 + j % 2) % 3;
            d[a] = if j < 3 { 1.0 } else { -1.0 };
            d[k] = if j % 3 == 0 { -0.0 } else { 0.0 };
            rays.push(Ray::new(o.to_array(), d, 0.0, f32::INFINITY));
            // Parallel to the plane but in general direction.
            let mut d2 = Vec3::from(dirs[rays.len() % dirs.len()]);
            d2[k] = 0.0;
            rays.push(Ray::new(o.to_array(), d2.to_array(), 0.0, f32::INFINITY));
            // Starting exactly on the plane in a random direction.
            rays.push(Ray::new(o.to_array(), dirs[(rays.len() * 7) % dirs.len()], 0.0, f32::INFINITY));
        }
    }
    // Degenerate intervals and invalid rays.
    let c = ((lo + hi) * 0.5).to_array();
    for d in [[1.0, 0.0, 0.0], [0.3, -0.5, 0.2]] {
        rays.push(Ray::new(c, d, 0.0, 0.0));
        rays.push(Ray::new(c, d, 5.0, 1.0));
        rays.push(Ray::new([f32::NAN, 0.0, 0.0], d, 0.0, f32::INFINITY));
        rays.push(Ray::new(c, [f32::INFINITY, 0.0, 1.0], 0.0, f32::INFINITY));
        rays.push(Ray::new(c, d, 0.0, f32::NAN));
    }
    let hard = rays.len();
    // Random rays from around the scene.
    for d in dirs.iter().take(n_random) {
        rays.push(Ray::new(point(&mut rng).to_array(), *d, 0.0, f32::INFINITY));
    }
    (rays, hard)
}

/// A flat cell: a 24 × 24 grid of quads in the plane z = 1 (many coplanar triangles in a split
/// plane) inside a second grid folded along x = 0.5 (shared edges).
fn grid_scene() -> Scene {
    let mut v = Vec::new();
    let mut f = Vec::new();
    let n = 24u32;
    for plane in 0..2 {
        let base = v.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                v.push(if plane == 0 { [x, y, 1.0] } else { [0.5, x, y * 2.0] });
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = base + j * (n + 1) + i;
                f.push([a, a + 1, a + n + 2]);
                f.push([a, a + n + 2, a + n + 1]);
            }
        }
    }
    common::mesh_scene("grid", &v, &f)
}

fn run_scene(name: &str, scene: &Scene, n_random: usize) {
    let tree = build(&scene.triangles, &BuildOptions::default());
    assert!(tree.stats.nodes > 1, "{name}: the tree splits");
    let (rays, hard) = hard_rays(scene, &tree, n_random, 11);
    let hits = check(name, scene, &tree, &rays, hard);
    let grouped: Vec<Ray> = octant_order(&rays[hard..]).into_iter().map(|i| rays[hard + i]).collect();
    let coherent = kdray::analysis::coherent_packets(&grouped);
    assert!(4 * coherent >= grouped.len() * 9 / 10, "{name}: only {coherent} of the random rays' packets are coherent");
    let hit_frac = hits.iter().filter(|h| h.is_hit()).count() as f64 / hits.len() as f64;
    println!("{name}: {} rays, {:.1} % hit, tree {:?}", rays.len(), 100.0 * hit_frac, tree.stats);
    assert!(hit_frac > 0.05, "{name}: the rays must hit something");
}

#[test]
fn cornell_box_hard_cases_and_random_rays() {
    run_scene("cornell", &scene::load("cornell").unwrap(), 1_000_000);
}

#[test]
fn flat_cells_and_coplanar_grids() {
    run_scene("grid", &grid_scene(), 1_000_000);
}

/// A triangle soup (#11 item 2): large overlapping triangles make perfect splits duplicate
/// references without end (here 54 per triangle unbounded). `max_duplication` bounds them,
/// by default and when asked for less, and the bounded trees still answer exactly.
#[test]
fn triangle_soup_with_bounded_duplication() {
    let scene = scene::load("soup:4000:0.4").unwrap();
    let n = scene.triangles.len();
    let unbounded = build(&scene.triangles, &BuildOptions { max_duplication: f32::INFINITY, ..Default::default() });
    let refs = |t: &KdTreeData| t.stats.references as f64 / n as f64;
    assert!(refs(&unbounded) > 32.0, "the soup duplicates: {:.2} references per triangle", refs(&unbounded));
    for cap in [kdray::kdtree::DEFAULT_MAX_DUPLICATION, 4.0, 2.0] {
        let tree = build(&scene.triangles, &BuildOptions { max_duplication: cap, ..Default::default() });
        let r = refs(&tree);
        println!("soup, at most {cap} references per triangle: {r:.2}, {:?}", tree.stats);
        assert!(r <= cap as f64 && tree.stats.references == tree.prims.len(), "{r:.2} references per triangle over the bound {cap}");
        assert!(tree.stats.nodes > 1, "the bounded tree still splits");
        let (rays, hard) = hard_rays(&scene, &tree, 20_000, 29);
        // At 2 the leaves hold ~330 triangles: a packet's walk outruns lavapipe's loop limit
        // (`Runtime::is_software`) and loses hits there, so on a software driver that tree is
        // checked natively only; a hardware GPU checks it too.
        let on_gpu = cap >= 4.0 || common::gpu().is_some_and(|g| !g.is_software());
        check_on(&format!("soup, duplication {cap}"), &scene, &tree, &rays, hard, on_gpu);
    }
}

/// Binned SAH (`BuildOptions::binned_above`) all the way down to nodes of 48 triangles: the
/// planes it chooses are moved into gaps between the triangles' bounds as the exact sweep's
/// are, so the hard cases (rays in, along and starting on every split plane) and random rays
/// get the oracle's hits from every traversal; the trees differ from the exact build's, keep
/// the reference budget, and cost within 10 % of it under the SAH.
#[test]
fn binned_builds_answer_exactly() {
    let scenes = [("grid", grid_scene()), ("rotated-chairs", rotated_chairs()), ("soup", scene::load("soup:4000:0.4").unwrap())];
    for (name, scene) in scenes {
        let n = scene.triangles.len();
        let exact = build(&scene.triangles, &BuildOptions { binned_above: None, max_duplication: 4.0, ..Default::default() });
        let binned = build(&scene.triangles, &BuildOptions { binned_above: Some(48), max_duplication: 4.0, ..Default::default() });
        let (se, sb) = (exact.stats.sah_cost, binned.stats.sah_cost);
        let st = &binned.stats;
        println!("{name}: SAH cost exact {se:.1}, binned {sb:.1}; nodes {} and {}; {} nodes binned, {} of them swept", exact.stats.nodes, st.nodes, st.binned_nodes, st.binned_fallbacks);
        assert!(binned.nodes != exact.nodes && st.binned_nodes > 0, "{name}: binning changed nothing");
        assert_eq!((exact.stats.binned_nodes, exact.stats.binned_fallbacks), (0, 0));
        assert!(sb <= 1.1 * se, "{name}: binned SAH cost {sb:.1} over 1.1 × the exact build's {se:.1}");
        assert!(binned.prims.len() as f64 <= 4.0 * n as f64, "{name}: {} references over the budget", binned.prims.len());
        let (rays, hard) = hard_rays(&scene, &binned, 20_000, 23);
        check(&format!("{name}, binned"), &scene, &binned, &rays, hard);
    }
}

/// Embree's watertightness test through every traversal: a closed sphere translated far from
/// the origin, 10^6 rays from its centre, no misses.
#[test]
fn closed_sphere_far_from_origin_every_traversal() {
    let center = Vec3::new(148376.0, 1234.0, -223423.0);
    let (v, f) = common::icosphere(center, 1000.0, 4);
    let scene = common::mesh_scene("sphere", &v, &f);
    let tree = build(&scene.triangles, &BuildOptions::default());
    let rays: Vec<Ray> = common::random_dirs(1_000_000, 5)
        .into_iter()
        .map(|d| Ray::new(center.to_array(), d, 0.0, f32::INFINITY))
        .collect();
    let bvh = kdray::bvh::build(&scene.triangles);
    let cpu = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
    let misses = cpu.closest_hits(Accel::BVH, &rays).unwrap().iter().filter(|h| !h.is_hit()).count();
    assert_eq!(misses, 0, "CPU BVH: {misses} of 10^6 rays leaked");
    let misses = cpu.any_hits(Accel::BVH, &rays).unwrap().iter().filter(|h| !**h).count();
    assert_eq!(misses, 0, "CPU BVH any-hit: {misses} of 10^6 rays leaked");
    for alg in cpu_algorithms() {
        let misses = cpu.closest_hits(Accel::kd(alg), &rays).unwrap().iter().filter(|h| !h.is_hit()).count();
        assert_eq!(misses, 0, "CPU {alg:?}: {misses} of 10^6 rays leaked");
        let misses = cpu.any_hits(Accel::kd(alg), &rays).unwrap().iter().filter(|h| !**h).count();
        assert_eq!(misses, 0, "CPU {alg:?} any-hit: {misses} of 10^6 rays leaked");
    }
    let grouped: Vec<Ray> = octant_order(&rays).into_iter().map(|i| rays[i]).collect();
    for accel in cpu_grouped() {
        let misses = cpu.closest_hits(accel, &grouped).unwrap().iter().filter(|h| !h.is_hit()).count();
        assert_eq!(misses, 0, "CPU {}: {misses} of 10^6 rays leaked", accel.name());
        let misses = cpu.any_hits(accel, &grouped).unwrap().iter().filter(|h| !**h).count();
        assert_eq!(misses, 0, "CPU {} any-hit: {misses} of 10^6 rays leaked", accel.name());
    }
    if let Some(g) = common::gpu() {
        let gpu = Tracer::new(g, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
        for accel in gpu_single() {
            let rays = if GPU_FULL.contains(&accel) { &rays[..] } else { &rays[..GPU_SAMPLE] };
            let misses = gpu.closest_hits(accel, &rays).unwrap().iter().filter(|h| !h.is_hit()).count();
            assert_eq!(misses, 0, "GPU {}: {misses} of {} rays leaked", accel.name(), rays.len());
            let misses = gpu.any_hits(accel, &rays).unwrap().iter().filter(|h| !**h).count();
            assert_eq!(misses, 0, "GPU {} any-hit: {misses} of {} rays leaked", accel.name(), rays.len());
        }
        for accel in gpu_grouped() {
            let rays = &grouped[..GPU_SAMPLE];
            let misses = gpu.closest_hits(accel, rays).unwrap().iter().filter(|h| !h.is_hit()).count();
            assert_eq!(misses, 0, "GPU {}: {misses} of {} rays leaked", accel.name(), rays.len());
            let misses = gpu.any_hits(accel, rays).unwrap().iter().filter(|h| !**h).count();
            assert_eq!(misses, 0, "GPU {} any-hit: {misses} of {} rays leaked", accel.name(), rays.len());
        }
    }
    // And the hard cases on the same sphere, checked against the oracle, with rays grazing
    // shared edges: from outside, aimed exactly at every vertex and edge midpoint.
    let (base, base_hard) = hard_rays(&scene, &tree, 20_000, 3);
    let mut rays = base[..base_hard].to_vec();
    let mut tangent = Vec::new();
    for tri in f.iter().take(2000) {
        for k in 0..3 {
            let a = Vec3::from(v[tri[k] as usize]);
            let b = Vec3::from(v[tri[(k + 1) % 3] as usize]);
            for target in [a, (a + b) * 0.5] {
                let from = center + (target - center) * 3.0 + Vec3::new(0.0, 700.0, 0.0);
                rays.push(Ray::new(from.to_array(), (target - from).to_array(), 0.0, f32::INFINITY));
            }
            tangent.push(Ray::new((a - (b - a)).to_array(), (b - a).to_array(), 0.0, f32::INFINITY));
        }
    }
    let hard = rays.len();
    rays.extend_from_slice(&base[base_hard..]);
    check("sphere", &scene, &tree, &rays, hard);
    // Rays along an edge touch the surface only there: hit or miss is a convention of the
    // triangle test in a measure-zero case (a GPU compiler may rearrange it), so these are
    // checked natively, where every traversal must still agree with the oracle bit for bit.
    let n = tangent.len();
    check_on("sphere tangents", &scene, &tree, &tangent, n, false);
}

#[test]
fn stanford_bunny_from_shared_scenes() {
    let Some(scene) = common::shared_scene("stanford-bunny.obj") else { return };
    run_scene("bunny", &scene, 50_000);
}

/// `bench all` at a small size: every suite writes its CSV and Markdown tables, every timed
/// row carries a speed and an error column that is zero (every method is exact), and the
/// dumped rays read back as the batch that was measured.
#[test]
fn bench_all_suites_write_rows_with_speed_and_error() {
    let dir = std::env::temp_dir().join(format!("kdray-bench-{}", std::process::id()));
    let dev = if common::gpu().is_some() { "gpu" } else { "cpu" };
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_kdray"))
        .args(["bench", "all", "--device", dev, "--scene", "cornell-mirror", "--size", "24", "--reps", "1", "--max-chairs", "4"])
        .arg("--out")
        .arg(&dir)
        .arg("--dump-rays")
        .arg(dir.join("rays"))
        .status()
        .unwrap();
    assert!(status.success(), "kdray bench all: {status}");
    for suite in ["horn", "bounces", "scaling", "breakdown", "build", "visits", "order", "traversals", "photons"] {
        for ext in ["csv", "md"] {
            let f = dir.join(format!("{suite}-{dev}.{ext}"));
            assert!(f.is_file(), "{suite}: {} not written", f.display());
        }
        let csv = std::fs::read_to_string(dir.join(format!("{suite}-{dev}.csv"))).unwrap();
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(&header[..3], ["date", "machine", "device"], "{suite}");
        let rows: Vec<&str> = lines.collect();
        assert!(!rows.is_empty(), "{suite}: no rows");
        // Timed suites: speed and both error columns; every method is exact on the CPU
        // reference (ties between GPU and CPU aside: none in this small batch).
        if let Some(k) = header.iter().position(|h| *h == "reference_mismatch_rate") {
            let speed = header.iter().position(|h| *h == "mrays_s_wall").unwrap();
            for r in &rows {
                let cells = split_csv(r);
                assert!(cells[speed].parse::<f64>().unwrap() > 0.0, "{suite}: {r}");
                assert_eq!(cells[k].parse::<f64>().unwrap(), 0.0, "{suite}: {r}");
                assert_eq!(cells[k - 1].parse::<f64>().unwrap(), 0.0, "{suite}: {r}");
            }
        }
    }
    let horn = std::fs::read_to_string(dir.join(format!("horn-{dev}.md"))).unwrap();
    assert!(horn.contains("| + short-stack (3) (`shortstack:3+packets`) |"), "{horn}");
    let breakdown = std::fs::read_to_string(dir.join(format!("breakdown-{dev}.md"))).unwrap();
    assert!(breakdown.contains("decomposed:16"));
    // The dumped primary rays of cornell-mirror are the camera's rays, answers included.
    let rays = read_npy_f32(&dir.join("rays/cornell-mirror-primary-rays.npy"));
    assert_eq!(rays.len(), 24 * 24 * 8);
    let scene = scene::load("cornell-mirror").unwrap();
    let cam = scene.camera.to_pod(24, 24);
    let r7 = kdray_shared::camera::primary_ray(&cam, 7);
    assert_eq!(&rays[56..64], &[r7.origin[0], r7.origin[1], r7.origin[2], r7.t_min, r7.dir[0], r7.dir[1], r7.dir[2], r7.t_max]);
    let obj = scene::load(dir.join("rays/cornell-mirror.obj").to_str().unwrap()).unwrap();
    assert_eq!(obj.triangles.len(), scene.triangles.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench horn --peer CMD`: the command runs on the dumped rays, its result lines become rows
/// (speed, and answers differing from the dump's as "vs reference"), and the table gains the
/// fastest kdray row over each peer; a failing or silent peer is one error line.
#[test]
fn bench_horn_adds_a_peer_run_on_the_same_rays() {
    let dir = std::env::temp_dir().join(format!("kdray-peer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A peer that answers for every batch it finds, at 2.5 Mrays/s, 99 of 100 as the dump.
    let peer = dir.join("peer.sh");
    std::fs::write(&peer, "for f in \"$1\"/*-rays.npy; do b=$(basename \"$f\" -rays.npy); echo \"$b: peer=fake rays=100 Mrays/s=2.5 same-answer=99/100\"; done\necho unrelated line\n").unwrap();
    let run = |peer_cmd: &str, dump: bool| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_kdray"));
        c.args(["bench", "horn", "--device", "cpu", "--scene", "cornell", "--size", "16", "--reps", "1", "--method", "bvh", "--method", "stack", "--peer", peer_cmd]);
        c.arg("--out").arg(dir.join("out"));
        if dump {
            c.arg("--dump-rays").arg(dir.join("rays"));
        }
        c.output().unwrap()
    };
    let out = run(&format!("sh {}", peer.display()), true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("out/horn-cpu.csv")).unwrap();
    let peer_rows: Vec<Vec<String>> = csv.lines().filter(|l| l.contains(",peer:fake,")).map(split_csv).collect();
    assert_eq!(peer_rows.len(), 2, "{csv}");
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for r in &peer_rows {
        assert_eq!(r[col("mrays_s_wall")].parse::<f64>().unwrap(), 2.5);
        assert_eq!(r[col("reference_mismatch_rate")].parse::<f64>().unwrap(), 0.01);
        assert_eq!(r[col("rays")], "100");
    }
    let md = std::fs::read_to_string(dir.join("out/horn-cpu.md")).unwrap();
    let ratio = md.lines().find(|l| l.starts_with("| fastest kdray ÷ fake |")).unwrap_or_else(|| panic!("{md}"));
    let fastest: f64 = csv
        .lines()
        .filter(|l| l.contains(",cornell,") && l.contains(",primary,") && !l.contains("peer:"))
        .map(|l| split_csv(l)[col("mrays_s_wall")].parse::<f64>().unwrap())
        .fold(0.0, f64::max);
    let shown: f64 = ratio.split('|').nth(2).unwrap().trim().parse().unwrap();
    assert!((shown - fastest / 2.5).abs() <= 0.005 + 1e-9, "{ratio} vs {fastest}");
    // A peer that fails, one that prints nothing useful, and --peer without --dump-rays.
    for (cmd, dump, says) in [("false", true, "failed"), ("echo nothing", true, "no result line"), ("true", false, "--dump-rays")] {
        let out = run(cmd, dump);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{cmd}: {err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error:")).count(), 1, "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// CSV cells (quoted cells may hold commas).
fn split_csv(line: &str) -> Vec<String> {
    let mut cells = vec![String::new()];
    let mut quoted = false;
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => cells.push(String::new()),
            c => cells.last_mut().unwrap().push(c),
        }
    }
    cells
}

/// A float32 `.npy` file's data (header checked).
fn read_npy_f32(path: &std::path::Path) -> Vec<f32> {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + len]).unwrap();
    assert!(header.contains("'descr': '<f4'") && (10 + len) % 64 == 0, "{header}");
    b[10 + len..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

#[test]
fn cornell_box_with_a_chair() {
    run_scene("cornell-chair", &scene::load("cornell-chair").unwrap(), 1_000_000);
}

#[test]
fn generated_scenes_have_the_published_sizes() {
    let chair = kdray::scene::procedural::chair();
    assert_eq!(chair.f.len(), 1468, "one chair");
    for k in [1u32, 4, 16] {
        let s = scene::load(&format!("chairs:{k}")).unwrap();
        assert_eq!(s.triangles.len(), 1468 * k as usize + 2, "chairs:{k} (+ floor)");
        assert_eq!(s.dropped_degenerate, 0);
    }
    let c = scene::load("conference").unwrap();
    assert!((270_000..300_000).contains(&c.triangles.len()), "conference: {}", c.triangles.len());
    assert_eq!(c.lights().len(), 24, "12 lamp panels");
    for bad in ["chairs:0", "chairs:5", "chairs:8", "chairs:x", "chairs:16384"] {
        let e = format!("{:#}", scene::load(bad).unwrap_err());
        assert!(e.contains("power of 4") || e.contains("use chairs:K"), "{bad}: {e}");
    }
}

/// The chair's surface is closed: every edge, by position, is shared by exactly two triangles.
#[test]
fn chair_parts_are_closed() {
    use std::collections::HashMap;
    let m = kdray::scene::procedural::chair();
    let key = |p: Vec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let mut edges: HashMap<_, i32> = HashMap::new();
    for t in &m.f {
        for k in 0..3 {
            let (a, b) = (key(m.v[t[k] as usize]), key(m.v[t[(k + 1) % 3] as usize]));
            if a == b {
                continue;
            }
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let open = edges.values().filter(|c| **c != 2).count();
    assert_eq!(open, 0, "{open} edges are not shared by exactly two triangles");
}

/// Chairs turned by π and π/2: their axis-aligned faces become planar only up to rounding noise
/// (sin π ≠ 0 in f32), vertices a few ulps apart. The builder must not cut such geometry into
/// cells thinner than the rounding of t (a traversal would skip them: the conference room's
/// audience once lost 0.3 % of its primary hits that way).
#[test]
fn rotated_chairs_with_rounding_noise() {
    run_scene("rotated-chairs", &rotated_chairs(), 50_000);
}

/// Eight chairs, four turned by π and four by π/2 (faces planar up to rounding noise).
fn rotated_chairs() -> Scene {
    use kdray::scene::procedural::{chair, Mesh};
    let mut m = Mesh::default();
    for i in 0..4 {
        for j in 0..2 {
            let yaw = [std::f32::consts::PI, std::f32::consts::FRAC_PI_2][j];
            m.add(&chair(), Vec3::new(i as f32 * 0.7, 0.0, j as f32 * 0.7), yaw, 1.0);
        }
    }
    let mut s = Scene::new("rotated-chairs", kdray::scene::CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let mat = s.add_material("wood", Default::default());
    m.into_scene(&mut s, mat, "chair").unwrap();
    s
}

/// A scene and the same scene moved far from the origin (#11 item 1): the kd-tree of the moved
/// one is as good (nodes and triangle tests per ray within 1.5× on the same rays, moved, a
/// deterministic count), and every traversal still returns the oracle's hits there, on the
/// hard cases, on random rays from around the scene and on rays from the world's origin aimed
/// at its vertices, edges and faces (t rounds to about 10^-2 there: cells of an ulp of the
/// moved coordinates are thinner than that).
#[test]
fn scenes_far_from_the_origin_keep_their_trees_and_hits() {
    use kdray::scene::procedural::{chair, Mesh};
    let shift = Vec3::new(148376.0, 1234.0, -223423.0);
    let mut m = Mesh::default();
    for i in 0..4 {
        for j in 0..2 {
            let yaw = [std::f32::consts::PI, std::f32::consts::FRAC_PI_2][j];
            m.add(&chair(), Vec3::new(i as f32 * 0.7, 0.0, j as f32 * 0.7), yaw, 1.0);
        }
    }
    let mut chairs = Scene::new("chairs", kdray::scene::CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let mat = chairs.add_material("wood", Default::default());
    m.into_scene(&mut chairs, mat, "chair").unwrap();
    for (name, small) in [("chairs", chairs), ("grid", grid_scene())] {
        // At a scale where the moved coordinates still resolve the geometry (an ulp there is
        // 0.016; the chairs' finest detail is about 1 at this scale).
        let scaled = |s: &Scene, by: f32, at: Vec3, label: &str| {
            let mut out = Scene::new(label, kdray::scene::CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
            let mat = out.add_material("white", Default::default());
            for t in &s.triangles {
                let v = [t.v0, t.v1, t.v2].map(|p| Vec3::from(p) * by + at);
                out.add_triangle(v, mat, &|| label.to_string()).unwrap();
            }
            out
        };
        let scene = scaled(&small, 100.0, Vec3::ZERO, name);
        let moved = scaled(&small, 100.0, shift, &format!("{name}-moved"));
        let tree = build(&scene.triangles, &BuildOptions::default());
        let far = build(&moved.triangles, &BuildOptions::default());
        // The same rays, moved: from around the scene in random directions.
        let (rays, hard) = hard_rays(&scene, &tree, 20_000, 5);
        let random: Vec<Ray> = rays[hard..].to_vec();
        let moved_rays: Vec<Ray> = random.iter().map(|r| Ray::new((Vec3::from(r.origin) + shift).to_array(), r.dir, r.t_min, r.t_max)).collect();
        let per_ray = |tris: &[kdray_shared::Triangle], t: &KdTreeData, rays: &[Ray]| {
            let c = kdray::analysis::counts(tris, t, Accel::kd(Algorithm::Stack), rays, true).unwrap();
            let (nodes, tests): (u64, u64) = c.iter().fold((0, 0), |a, c| (a.0 + c.nodes as u64, a.1 + c.tris as u64));
            (nodes as f64 / rays.len() as f64, tests as f64 / rays.len() as f64)
        };
        let (n0, t0) = per_ray(&scene.triangles, &tree, &random);
        let (n1, t1) = per_ray(&moved.triangles, &far, &moved_rays);
        println!("{name}: at the origin {n0:.1} nodes, {t0:.1} triangle tests per ray ({} nodes); moved {n1:.1}, {t1:.1} ({} nodes)", tree.stats.nodes, far.stats.nodes);
        assert!(n1 <= 1.5 * n0 && n0 <= 1.5 * n1, "{name}: nodes per ray {n0:.1} at the origin, {n1:.1} moved");
        assert!(t1 <= 1.5 * t0 && t0 <= 1.5 * t1, "{name}: triangle tests per ray {t0:.1} at the origin, {t1:.1} moved");
        // The hard cases of the moved scene and the moved random rays: natively against the
        // oracle, on the GPU against the GPU's brute force (rays starting exactly on the moved
        // planes meet the triangle test's rounding there).
        let (mut all, hard) = hard_rays(&moved, &far, 0, 7);
        all.extend_from_slice(&moved_rays);
        check_on(&format!("{name} moved"), &moved, &far, &all, hard, false);
        check_gpu_against_gpu_brute(&format!("{name} moved"), &moved, &far, &all);
        // Rays from the world's origin at its vertices, edge midpoints and centroids: natively
        // (a ray through a vertex or an edge is a convention of the triangle test, which a GPU
        // compiler may round otherwise).
        let mut aimed = Vec::new();
        for t in moved.triangles.iter().take(4000) {
            let (a, b, c) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
            for target in [a, (a + b) * 0.5, (a + b + c) / 3.0] {
                aimed.push(Ray::new([0.0; 3], target.to_array(), 0.0, f32::INFINITY));
            }
        }
        let n = aimed.len();
        let hits = check_on(&format!("{name} moved, aimed from the origin"), &moved, &far, &aimed, n, false);
        let aimed_hits = hits.iter().filter(|h| h.is_hit()).count();
        assert!(aimed_hits * 10 >= n * 9, "{name}: only {aimed_hits} of {n} aimed rays hit");
    }
}

/// Thin cells far from the origin: flat quads stacked an ulp or two apart in z at
/// z ≈ −223 323 (where an ulp is 1/64), the kd-tree free to put planes between them, and rays
/// from the world's origin through them, whose t at those planes rounds by more than the
/// cells are thick. Every traversal must still find the oracle's hits.
#[test]
fn cells_thinner_than_the_rounding_of_t() {
    let z0 = -223323.0f32;
    let mut v = Vec::new();
    let mut f = Vec::new();
    let mut z = z0;
    for k in 0..12u32 {
        // Quads of 60 × 60, the odd ones a little smaller: only planes in z separate them.
        let (x, y) = if k % 2 == 0 { (148300.0, 1200.0) } else { (148310.0, 1210.0) };
        let b = v.len() as u32;
        let w = if k % 2 == 0 { 60.0 } else { 40.0 };
        v.extend([[x, y, z], [x + w, y, z], [x + w, y + w, z], [x, y + w, z]]);
        f.push([b, b + 1, b + 2]);
        f.push([b, b + 2, b + 3]);
        // The next z two ulps further (room for one plane between).
        z = f32::from_bits(z.to_bits() + 2);
    }
    let scene = common::mesh_scene("thin", &v, &f);
    let tree = build(&scene.triangles, &BuildOptions::default());
    let thin_planes = tree.nodes.iter().filter(|n| !n.is_leaf() && n.axis() == 2 && (n.split() - z0).abs() < 1.0).count();
    println!("thin: {:?}, {thin_planes} planes between the quads", tree.stats);
    let mut rng = Rng::new(3, 9);
    let mut rays = Vec::new();
    for _ in 0..20_000 {
        // Inside the quads, off their outer edges (a ray along an edge is a convention of the
        // triangle test, which a GPU compiler may round otherwise).
        let target = [148301.0 + 58.0 * rng.next_f32(), 1201.0 + 58.0 * rng.next_f32(), z0];
        rays.push(Ray::new([0.0; 3], target, 0.0, f32::INFINITY));
        let from = [target[0] + 40.0 * (rng.next_f32() - 0.5), target[1] + 40.0 * (rng.next_f32() - 0.5), z0 + 3000.0];
        let d = [target[0] - from[0], target[1] - from[1], target[2] - from[2]];
        rays.push(Ray::new(from, d, 0.0, f32::INFINITY));
    }
    let n = rays.len();
    let hits = check("thin", &scene, &tree, &rays, n);
    assert!(hits.iter().filter(|h| h.is_hit()).count() * 2 > n, "most rays hit a quad");
}

/// Rays from far away (2·10^5 from a scene 3 units across): their t at the planes rounds by
/// about 0.02, far more than the thinnest cells of the rotated chairs (planes a few hundred
/// ulps apart around their rounding noise), so cells come out empty or inverted in t. Every
/// traversal must still find the oracle's hits.
#[test]
fn rays_from_far_away() {
    let s = rotated_chairs();
    let tree = build(&s.triangles, &BuildOptions::default());
    let dirs = common::random_dirs(64, 21);
    let mut rays = Vec::new();
    for (k, t) in s.triangles.iter().enumerate() {
        let (a, b, c) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
        let from = Vec3::from(dirs[k % dirs.len()]) * 2.0e5;
        for target in [a, (a + b) * 0.5, (a + b + c) / 3.0] {
            rays.push(Ray::new(from.to_array(), (target - from).to_array(), 0.0, f32::INFINITY));
        }
    }
    // At vertices, edge midpoints and centroids: natively (a ray through a vertex or along an
    // edge is a convention of the triangle test, which a GPU compiler may round otherwise).
    let n = rays.len();
    let hits = check_on("rays from far away, aimed", &s, &tree, &rays, n, false);
    assert!(hits.iter().filter(|h| h.is_hit()).count() * 10 > n * 9);
    // From far away at random points of the scene box, natively and on the GPU.
    let (lo, hi) = s.bounds();
    let mut rng = Rng::new(8, 2);
    let far: Vec<Ray> = (0..40_000)
        .map(|k| {
            let from = Vec3::from(dirs[k % dirs.len()]) * 2.0e5;
            let target = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(from.to_array(), (target - from).to_array(), 0.0, f32::INFINITY)
        })
        .collect();
    let hits = check_on("rays from far away", &s, &tree, &far, 0, false);
    assert!(hits.iter().filter(|h| h.is_hit()).count() * 20 > far.len(), "some of the rays hit");
    // On the GPU against the GPU's own brute force: rays from that far cross edges and
    // vertices often (their directions round to a coarse grid), where the GPU's triangle test
    // may round otherwise than the native one. The first 10 000 (every direction, about 150
    // rays each): on lavapipe all 40 000 took three minutes of the CI's 2 cores.
    check_gpu_against_gpu_brute("rays from far away", &s, &tree, &far[..10_000]);
}

/// Every GPU traversal against the GPU's brute force on `rays` (ties allowed): for rays whose
/// triangle tests the GPU rounds otherwise than the native code (edges and vertices of
/// coordinates far from the origin), the traversals must still find exactly what brute force
/// finds with the same triangle test.
fn check_gpu_against_gpu_brute(name: &str, scene: &Scene, tree: &KdTreeData, rays: &[Ray]) {
    let Some(g) = common::gpu() else { return };
    let bvh = kdray::bvh::build(&scene.triangles);
    let gpu = Tracer::new(g, scene, Some(tree)).unwrap().with_bvh(&bvh).unwrap();
    let brute = gpu.closest_hits(Accel::BRUTE, rays).unwrap();
    let brute_any = gpu.any_hits(Accel::BRUTE, rays).unwrap();
    for accel in gpu_single().into_iter().chain(gpu_grouped()) {
        let hits = gpu.closest_hits(accel, rays).unwrap();
        let bad = (0..rays.len()).filter(|&i| !agree(&brute[i], &hits[i])).count();
        assert_eq!(bad, 0, "{name}: GPU {}: {bad} of {} rays differ from the GPU's brute force", accel.name(), rays.len());
        let any = gpu.any_hits(accel, rays).unwrap();
        let bad = (0..rays.len()).filter(|&i| any[i] != brute_any[i]).count();
        assert_eq!(bad, 0, "{name}: GPU {} any-hit: {bad} of {} rays differ from the GPU's brute force", accel.name(), rays.len());
    }
}
