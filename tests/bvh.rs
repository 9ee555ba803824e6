//! The compressed wide BVH's builder: the structure the kernels trust (every triangle once,
//! child nodes after their parents, boxes that enclose what they hold, exactly as the kernels
//! reconstruct them, depth within the stack), on the built-in scenes and on inputs made to
//! break it (no triangles, one, thousands at one point, coordinates near the limits of `f32`,
//! a chain that a plain SAH builder would make deeper than the stack), and the traversal on
//! those against the oracle, natively and on the GPU. The oracle tests on the kd-tree's hard
//! cases (`kd_traversal.rs`) run the BVH too.
mod common;

use glam::Vec3;
use kdray::bvh::{self, BvhData};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Accel, Runtime, Scene, Tracer};
use kdray_shared::bvh::{Bvh, BvhNode, BVH_WIDTH, MAX_BVH_DEPTH};
use kdray_shared::query::{Closest, Query};
use kdray_shared::stats::NoStats;
use kdray_shared::{Hit, Ray};

/// Every slot's stored box (in `f32`, as the kernels compute it) encloses every triangle
/// beneath it; returns the triangles beneath node `i`.
fn enclosed(b: &BvhData, i: usize) -> Vec<usize> {
    let n: &BvhNode = &b.nodes[i];
    let mut all = Vec::new();
    let mut k = 0;
    for s in 0..BVH_WIDTH as u32 {
        let m = n.meta(s);
        if m == 0 {
            continue;
        }
        let below: Vec<usize> = if n.imask() >> s & 1 != 0 {
            let c = n.child_base() as usize + k;
            k += 1;
            enclosed(b, c)
        } else {
            let count = (m >> 5).count_ones() as usize;
            (0..count).map(|j| n.tri_base() as usize + (m & 0x1f) as usize + j).collect()
        };
        let (lo, hi) = n.child_box(s);
        for &t in &below {
            let tri = &b.tris[t];
            for v in [tri.v0, tri.v1, tri.v2] {
                for a in 0..3 {
                    assert!(lo[a] <= v[a] && v[a] <= hi[a], "node {i} slot {s}: box {lo:?}..{hi:?} misses vertex {v:?}");
                }
            }
        }
        all.extend(below);
    }
    all
}

fn check_structure(name: &str, s: &Scene) -> BvhData {
    check_tree(name, s, bvh::try_build(&s.triangles).unwrap())
}

/// `BvhData::validate`, every triangle in exactly one leaf under boxes that enclose it, each
/// leaf triangle the scene's, the depth within the stack.
fn check_tree(name: &str, s: &Scene, b: BvhData) -> BvhData {
    b.validate(s.triangles.len()).unwrap();
    let mut under = enclosed(&b, 0);
    under.sort();
    assert_eq!(under, (0..s.triangles.len()).collect::<Vec<_>>(), "{name}: every leaf triangle once");
    for (k, t) in b.tris.iter().enumerate() {
        let o = &s.triangles[t._pad as usize];
        assert_eq!((t.v0, t.v1, t.v2, t.material, t.face), (o.v0, o.v1, o.v2, o.material, o.face), "{name}: leaf triangle {k}");
    }
    assert!(b.depth <= MAX_BVH_DEPTH);
    println!("{name}: {} triangles, {} nodes, {} leaves, depth {}, SAH {:.1}, {} KiB", s.triangles.len(), b.nodes.len(), b.leaves, b.depth, b.sah_cost, b.bytes() / 1024);
    b
}

/// Random rays through the scene's box and from inside it.
fn rays_for(s: &Scene, n: usize, seed: u32) -> Vec<Ray> {
    let (lo, hi) = s.bounds();
    let ext = (hi - lo).max(Vec3::splat(1e-3));
    let mut rng = kdray_shared::rng::Rng::new(seed, 3);
    common::random_dirs(n, seed)
        .into_iter()
        .map(|d| {
            let p = lo - ext * 0.2 + ext * 1.4 * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(p.to_array(), d, 0.0, f32::INFINITY)
        })
        .collect()
}

/// The BVH against the oracle: natively bit for bit, on the GPU up to ties (the same point on
/// two triangles).
fn check_hits(name: &str, s: &Scene, b: &BvhData, rays: &[Ray]) {
    let cpu = Tracer::new(&NATIVE, s, None).unwrap().with_bvh(b).unwrap();
    let oracle = cpu.closest_hits(Accel::BRUTE, rays).unwrap();
    let oracle_any = cpu.any_hits(Accel::BRUTE, rays).unwrap();
    common::assert_matches_oracle(&format!("{name}: native"), &cpu, Accel::BVH, rays, &oracle, &oracle_any);
    common::assert_matches_oracle(&format!("{name}: native"), &cpu, Accel::BVH_PACKETS, rays, &oracle, &oracle_any);
    common::assert_packets_match_single(&format!("{name}: native"), &cpu, rays);
    if let Some(g) = common::gpu() {
        let gpu = Tracer::new(g, s, None).unwrap().with_bvh(b).unwrap();
        // The packets: exactly the GPU's one-ray walk.
        let hits = gpu.closest_hits(Accel::BVH, rays).unwrap();
        let packed = gpu.closest_hits(Accel::BVH_PACKETS, rays).unwrap();
        let bad: Vec<usize> = (0..rays.len()).filter(|&i| packed[i] != hits[i]).collect();
        if let Some(&i) = bad.first() {
            panic!("{name}: GPU bvh+packets differs from the GPU BVH on {} of {} rays; first: {:?} gives {:?}, BVH {:?}, oracle {:?}", bad.len(), rays.len(), rays[i], packed[i], hits[i], oracle[i]);
        }
        assert_eq!(gpu.any_hits(Accel::BVH_PACKETS, rays).unwrap(), gpu.any_hits(Accel::BVH, rays).unwrap(), "{name}: GPU bvh+packets any-hit differs from the GPU BVH");
        let agree = |a: &Hit, b: &Hit| a.prim == b.prim || (a.is_hit() && b.is_hit() && (a.t - b.t).abs() <= 1e-6 * a.t.abs());
        let bad: Vec<usize> = (0..rays.len()).filter(|&i| !agree(&hits[i], &oracle[i])).collect();
        if let Some(&i) = bad.first() {
            let brute = gpu.closest_hits(Accel::BRUTE, &rays[i..i + 1]).unwrap()[0];
            panic!("{name}: GPU BVH differs from the oracle on {} of {} rays; first: {:?} gives {:?}, oracle {:?}, GPU brute force {brute:?}", bad.len(), rays.len(), rays[i], hits[i], oracle[i]);
        }
        let any = gpu.any_hits(Accel::BVH, rays).unwrap();
        let bad = (0..rays.len()).filter(|&i| any[i] != oracle_any[i]).count();
        assert!(bad as f64 <= 1e-4 * rays.len() as f64, "{name}: GPU BVH any-hit differs on {bad} of {} rays", rays.len());
        println!("{name}: {} on {} rays agrees with the oracle", g.name(), rays.len());
    }
}

#[test]
fn built_in_scenes_build_valid_trees_that_find_the_oracles_hits() {
    for name in ["cornell", "cornell-glass", "cornell-chair", "chairs:16"] {
        let s = scene::load(name).unwrap();
        let b = check_structure(name, &s);
        check_hits(name, &s, &b, &rays_for(&s, 50_000, 7));
    }
}

#[test]
fn no_triangles_one_triangle_and_many_at_one_point() {
    // No triangles (a scene refuses that; the builder and the traversal must not break).
    let b = bvh::try_build(&[]).unwrap();
    b.validate(0).unwrap();
    assert_eq!((b.nodes.len(), b.tris.len()), (1, 0));
    let ray = Ray::new([0.0; 3], [0.0, 0.0, 1.0], 0.0, f32::INFINITY);
    let mut q = Closest::new(&ray);
    kdray_shared::bvh::traverse(&Bvh { nodes: (&b.nodes[..]).into(), tris: kdray_shared::bvh::TriWords::cast(&b.tris).into() }, &ray, &mut q, &mut NoStats);
    assert!(!q.hit.is_hit());

    let one = common::mesh_scene("one", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]);
    let b = check_structure("one", &one);
    check_hits("one", &one, &b, &rays_for(&one, 4_000, 3));

    // 3 000 copies of two triangles: every centroid at one of two points, so the SAH finds
    // nothing and object medians must split (and stay within the depth limit).
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let f: Vec<[u32; 3]> = (0..3000).flat_map(|_| [[0, 1, 2], [0, 1, 3]]).collect();
    let stacked = common::mesh_scene("stacked", &v, &f);
    let b = check_structure("stacked", &stacked);
    check_hits("stacked", &stacked, &b, &rays_for(&stacked, 4_000, 5));
}

/// `n` triangles in the plane z = 0, the k-th at x = `ratio`^k and of that size times 0.2 (with
/// `ratio` < 0.83 each clear of the next; above, overlapping it).
fn chain(ratio: f32, n: i32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    let mut f = Vec::new();
    for k in 0..n {
        let x = ratio.powi(k);
        let s = x * 0.2;
        let i = v.len() as u32;
        v.extend([[x, 0.0, 0.0], [x + s, 0.0, 0.0], [x, s, 0.0]]);
        f.push([i, i + 1, i + 2]);
    }
    (v, f)
}

/// Triangles at positions 0.8^k (k = 0..120; sizes stay far from f32's subnormals, which GPUs
/// flush to zero): the SAH peels one off per level, a chain far
/// deeper than the traversal stack; the builder balances the rest once the depth runs out.
#[test]
fn a_chain_deeper_than_the_stack_is_balanced() {
    let (v, f) = chain(0.8, 120);
    let chain = common::mesh_scene("chain", &v, &f);
    let b = check_structure("chain", &chain);
    let rays: Vec<Ray> = (0..120).map(|k| {
        let x = (0.8f32).powi(k);
        Ray::new([x + x * 0.05, x * 0.05, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
    }).collect();
    check_hits("chain", &chain, &b, &rays);
    let t = Tracer::new(&NATIVE, &chain, None).unwrap().with_bvh(&b).unwrap();
    let hits = t.closest_hits(Accel::BVH, &rays).unwrap();
    assert_eq!(hits.iter().filter(|h| h.is_hit()).count(), 120, "every triangle of the chain is hit");
}

/// Coordinates far from 1 and from the origin (as far as the triangle test's products stay in
/// `f32`'s range: ~1e±19), and a triangle spanning nearly all of `f32`: the quantisation grid
/// stays exact (no subnormal coordinate, no overflow) and no hit is lost.
#[test]
fn huge_tiny_and_far_coordinates() {
    for (name, center, radius) in [("huge", Vec3::splat(1e17), 3e16), ("tiny", Vec3::splat(3e-8), 1e-8), ("far", Vec3::new(-3.0e7, 1.0e5, 7.0e6), 0.5)] {
        let (v, f) = common::icosphere(center, radius, 3);
        let s = common::mesh_scene(name, &v, &f);
        let b = check_structure(name, &s);
        let rays: Vec<Ray> = common::random_dirs(20_000, 9).into_iter().map(|d| Ray::new(center.to_array(), d, 0.0, f32::INFINITY)).collect();
        check_hits(name, &s, &b, &rays);
        let t = Tracer::new(&NATIVE, &s, None).unwrap().with_bvh(&b).unwrap();
        let misses = t.closest_hits(Accel::BVH, &rays).unwrap().iter().filter(|h| !h.is_hit()).count();
        assert_eq!(misses, 0, "{name}: {misses} rays from the centre leaked");
    }
    let mut big = Vec::new();
    big.extend([[-3e38f32, 0.0, 0.0], [3e38, 0.0, 0.0], [0.0, 3e38, 1.0]]);
    let s = common::mesh_scene("limits", &big, &[[0, 1, 2]]);
    match bvh::try_build(&s.triangles) {
        Ok(b) => check_hits("limits", &s, &b, &[Ray::new([0.0, 1.0, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)]),
        Err(e) => assert!(e.to_string().contains("quantise"), "{e}"),
    }
}

/// A BVH that does not belong to the scene, or whose nodes were edited, is an error from
/// `Tracer::with_bvh`, never an out-of-range read in a kernel.
#[test]
fn foreign_or_corrupt_trees_are_refused() {
    let cornell = scene::load("cornell").unwrap();
    let chair = scene::load("cornell-chair").unwrap();
    let b = bvh::build(&chair.triangles);
    let e = Tracer::new(&NATIVE, &cornell, None).unwrap().with_bvh(&b).err().expect("a foreign BVH");
    assert!(e.to_string().contains("BVH"), "{e}");
    // The same scene edited after the build: as many triangles, one vertex moved.
    let good = bvh::build(&cornell.triangles);
    let mut edited = cornell.clone();
    edited.triangles[5].v1[1] += 1.0;
    let e = Tracer::new(&NATIVE, &edited, None).unwrap().with_bvh(&good).err().expect("a stale BVH");
    assert!(e.to_string().contains("other triangles"), "{e}");
    let corrupt: [(&str, fn(&mut BvhData)); 9] = [
        ("shared triangles", |b| {
            let n = b.nodes.len() - 1;
            b.nodes[n].bases_meta[1] = b.nodes[0].bases_meta[1];
        }),
        ("grid step", |b| b.nodes[0].origin_exp[3] = (b.nodes[0].origin_exp[3] & !0xff) | 3),
        ("child index", |b| b.nodes[0].bases_meta[0] = u32::MAX - 4),
        ("triangle index", |b| b.tris[0]._pad = 1 << 30),
        ("backwards child", |b| {
            let last = b.nodes.len() - 1;
            b.nodes[last].origin_exp[3] |= 1 << 24;
            b.nodes[last].bases_meta[2] = (b.nodes[last].bases_meta[2] & !0xff) | 0b001_11000;
            b.nodes[last].bases_meta[0] = 0;
        }),
        ("meta byte", |b| b.nodes[0].bases_meta[2] ^= 0b101_00000),
        // Beyond the traversal's once-per-ray bound (`tame`): a grid far from the root's, a
        // step four times the root's.
        ("grid origin", |b| {
            let last = b.nodes.len() - 1;
            b.nodes[last].origin_exp[0] = 1.0e6f32.to_bits();
        }),
        ("NaN grid origin", |b| {
            let last = b.nodes.len() - 1;
            b.nodes[last].origin_exp[1] = f32::NAN.to_bits();
        }),
        ("grid step above the root's", |b| {
            let last = b.nodes.len() - 1;
            b.nodes[last].origin_exp[3] = (b.nodes[last].origin_exp[3] & !0xff) | ((b.nodes[0].origin_exp[3] & 0xff) + 2);
        }),
    ];
    for (what, f) in corrupt {
        let mut b = good.clone();
        f(&mut b);
        assert!(Tracer::new(&NATIVE, &cornell, None).unwrap().with_bvh(&b).is_err(), "{what}: accepted");
    }
    assert!(Tracer::new(&NATIVE, &cornell, None).unwrap().closest_hits(Accel::BVH, &[]).is_err(), "no BVH built");
}

#[test]
fn stanford_bunny_from_shared_scenes() {
    let Some(s) = common::shared_scene("stanford-bunny.obj") else { return };
    let b = check_structure("bunny", &s);
    check_hits("bunny", &s, &b, &rays_for(&s, 50_000, 13));
}

/// `bvh::traverse_packet` itself: packets of rays from one point go together (it returns
/// `true`, so the packet walk is what answers) and every lane gets the one-ray walk's answer bit
/// for bit, closest and any hit, with eight lanes and four, invalid lanes mixed in (the first
/// among them), and intervals that differ from lane to lane (some starting or ending inside the
/// sphere); every other packet's lanes from points a little apart. The lanes fan out from their point, so any-hit lanes part and go on alone
/// (`bvh::packet::SOLO`): the test fails without that walk. Packets from scattered origins are
/// declined.
#[test]
fn packets_go_together_and_answer_as_one_ray_each() {
    use kdray_shared::bvh::{traverse_packet, TriWords};
    use kdray_shared::query::AnyHit;
    let c = Vec3::new(1.0, 2.0, 3.0);
    let (v, f) = common::icosphere(c, 1.5, 4);
    let s = common::mesh_scene("sphere", &v, &f);
    let b = bvh::try_build(&s.triangles).unwrap();
    let view = Bvh { nodes: (&b.nodes[..]).into(), tris: TriWords::cast(&b.tris).into() };
    let dirs = common::random_dirs(8 * 3000 + 3000, 21);
    fn check<const W: usize>(view: &Bvh, rays: &[Ray; W]) -> bool {
        let mut qc = rays.map(|r| Closest::new(&r));
        let mut qa = rays.map(|r| AnyHit::new(&r));
        let went = traverse_packet(view, rays, &mut qc, &mut NoStats);
        assert_eq!(traverse_packet(view, rays, &mut qa, &mut NoStats), went);
        for (l, r) in rays.iter().enumerate() {
            let (mut c1, mut a1) = (Closest::new(r), AnyHit::new(r));
            kdray_shared::bvh::traverse(view, r, &mut c1, &mut NoStats);
            kdray_shared::bvh::traverse(view, r, &mut a1, &mut NoStats);
            if went {
                assert_eq!(qc[l].hit, c1.hit, "lane {l} of {rays:?}");
                assert_eq!(qa[l].found, a1.found, "lane {l} of {rays:?}");
            }
        }
        went
    }
    let mut hits = 0;
    for k in 0..3000 {
        let o = (c + Vec3::from(dirs[8 * 3000 + k]) * 4.0).to_array();
        let mut rays = [Ray::default(); 8];
        for (l, r) in rays.iter_mut().enumerate() {
            // Every other packet's lanes from points up to 0.05 apart along each axis (a
            // packet goes together within a sixteenth of the scene, here 0.19).
            let o = if k % 2 == 1 { (Vec3::from(o) + Vec3::from(dirs[(8 * k + l + 7) % (8 * 3000)]) * 0.05).to_array() } else { o };
            let target = c + Vec3::from(dirs[8 * k + l]) * 1.6 - Vec3::from(o);
            let (t_min, t_max) = match (k + l) % 4 {
                0 => (0.0, f32::INFINITY),
                1 => (0.5, 0.9),
                2 => (0.0, 0.85),
                _ => (0.95, 3.0),
            };
            *r = Ray::new(o, target.to_array(), t_min, t_max);
        }
        if k % 5 == 0 {
            rays[k / 5 % 8] = Ray::new(o, [0.0; 3], 0.0, f32::INFINITY); // invalid: no direction
        }
        assert!(check(&view, &rays), "packet {k} from one point was declined");
        let four: [Ray; 4] = rays[..4].try_into().unwrap();
        assert!(check(&view, &four), "packet {k} of four was declined");
        hits += rays.iter().filter(|r| { let mut q = Closest::new(r); kdray_shared::bvh::traverse(&view, r, &mut q, &mut NoStats); q.hit.is_hit() }).count();
    }
    assert!(hits > 3000 && hits < 20000, "{hits} hits");
    // Scattered origins: declined (the caller traces the rays one by one).
    let rays: [Ray; 8] = std::array::from_fn(|l| Ray::new((c + Vec3::from(dirs[l]) * 4.0).to_array(), (-Vec3::from(dirs[l])).to_array(), 0.0, f32::INFINITY));
    assert!(!check(&view, &rays));
}

/// The builder's trees stay as they were (a regression pin): sizes and a checksum of every node
/// and triangle word (`chairs:64`: more triangles than a node bins in one thread). The binary
/// trees and their collapse are 9461bea's (the parallel bins and the collapse without
/// allocations left them unchanged); the quantised grids are those of origins on the finest
/// exact power of two (a node's lower bound rounded down to it, not to a multiple of the step).
#[test]
fn bvh_trees_are_pinned() {
    let mut built = Vec::new();
    let mut pinned = Vec::new();
    for (spec, nodes, leaves, depth, sum) in [("cornell", 4usize, 17usize, 2usize, 0xd9ac4ab58dc3dc87u64), ("cornell-chair", 216, 734, 5, 0xcd93b8eabdececa0), ("chairs:64", 14288, 47405, 8, 0xeaf1c762c30f1fae)] {
        let s = kdray::scene::load(spec).unwrap();
        let b = kdray::bvh::try_build(&s.triangles).unwrap();
        let words: &[u32] = bytemuck::cast_slice(&b.nodes);
        let tri_words: &[u32] = bytemuck::cast_slice(&b.tris);
        let check = words.iter().chain(tri_words).fold(0u64, |h, &w| h.wrapping_mul(0x100000001b3).wrapping_add(w as u64));
        println!("{spec}: {} nodes, {} leaves, depth {}, SAH {:.4}, checksum {check:#x}", b.nodes.len(), b.leaves, b.depth, b.sah_cost);
        built.push((spec, b.nodes.len(), b.leaves, b.depth, check));
        pinned.push((spec, nodes, leaves, depth, sum));
    }
    assert_eq!(built, pinned);
}

/// The kernels' linear BVH build (`kdray::lbvh`), natively and on the GPU: valid trees (the
/// checks above) that find the oracle's hits, on the built-in scenes and the inputs made to
/// break a builder; the two runtimes build the same binary tree (the same SAH cost) wherever
/// no Morton cell holds more than `REFINE` triangles.
#[test]
fn the_kernels_build_valid_trees_that_find_the_oracles_hits() {
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let f: Vec<[u32; 3]> = (0..3000).flat_map(|_| [[0, 1, 2], [0, 1, 3]]).collect();
    let mut scenes: Vec<(String, Scene, Option<Vec3>)> = ["cornell", "cornell-glass", "cornell-chair", "chairs:16"].iter().map(|n| (n.to_string(), scene::load(n).unwrap(), None)).collect();
    scenes.push(("one".into(), common::mesh_scene("one", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]), None));
    scenes.push(("two".into(), common::mesh_scene("two", &v, &[[0, 1, 2], [0, 1, 3]]), None));
    scenes.push(("stacked".into(), common::mesh_scene("stacked", &v, &f), None));
    // The chain of `a_chain_deeper_than_the_stack_is_balanced`: positions 0.8^k, most of them
    // in one Morton cell.
    let (cv, cf) = chain(0.8, 120);
    scenes.push(("chain".into(), common::mesh_scene("chain", &cv, &cf), None));
    // Rays from the centre (elsewhere the triangle test's products leave f32's range).
    for (name, center, radius) in [("huge", Vec3::splat(1e17), 3e16), ("tiny", Vec3::splat(3e-8), 1e-8), ("far", Vec3::new(-3.0e7, 1.0e5, 7.0e6), 0.5)] {
        let (v, f) = common::icosphere(center, radius, 3);
        scenes.push((name.into(), common::mesh_scene(name, &v, &f), Some(center)));
    }
    let gpu = common::gpu();
    for (name, s, center) in &scenes {
        let rays = match center {
            None => rays_for(s, 20_000, 13),
            Some(c) => common::random_dirs(20_000, 9).into_iter().map(|d| Ray::new(c.to_array(), d, 0.0, f32::INFINITY)).collect(),
        };
        let native = kdray::lbvh::build_on(&NATIVE, &s.triangles).unwrap();
        let b = check_tree(&format!("{name} (kernels, native)"), s, native.bvh);
        check_hits(&format!("{name} (kernels, native)"), s, &b, &rays);
        if let Some(g) = gpu {
            let built = kdray::lbvh::build_on(g, &s.triangles).unwrap();
            let c = check_tree(&format!("{name} (kernels, {})", g.name()), s, built.bvh);
            check_hits(&format!("{name} (kernels, {})", g.name()), s, &c, &rays);
            if *name != "stacked" && *name != "chain" {
                assert_eq!((c.sah_cost, c.leaves, c.nodes.len(), c.depth), (b.sah_cost, b.leaves, b.nodes.len(), b.depth), "{name}: the GPU's tree differs from the native one");
            }
        }
    }
    // A triangle spanning nearly all of f32: a tree, or the quantisation's error (as the host's
    // builder); a vertex that is not finite: an error, never a tree.
    let big = common::mesh_scene("limits", &[[-3e38f32, 0.0, 0.0], [3e38, 0.0, 0.0], [0.0, 3e38, 1.0]], &[[0, 1, 2]]);
    for rt in std::iter::once(&NATIVE as &dyn Runtime).chain(gpu.map(|g| g as &dyn Runtime)) {
        match kdray::lbvh::build_on(rt, &big.triangles) {
            Ok(b) => check_hits("limits (kernels)", &big, &b.bvh, &[Ray::new([0.0, 1.0, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)]),
            Err(e) => assert!(e.to_string().contains("quantise"), "{e}"),
        }
        let mut bad = scene::load("cornell").unwrap().triangles;
        bad[5].v1[2] = f32::NAN;
        let e = kdray::lbvh::build_on(rt, &bad).unwrap_err().to_string();
        assert!(e.contains("triangle 5") && e.contains("finite"), "{e}");
    }
}

/// Treelet restructuring of the kernels' binary tree (`build::treelet`), natively (the test
/// above checks that the GPU builds the same trees): every round's tree is valid and finds the
/// oracle's hits, and `build_on`'s (`TREELET_ROUNDS`) costs clearly less than Karras's tree as
/// it comes (no rounds) and no more than about the host's SAH build. A chain of ever smaller
/// triangles, which the treelets would make deeper than the traversal's stack, is built again
/// without them.
#[test]
fn treelets_bring_the_kernels_tree_to_the_hosts_cost() {
    for spec in ["cornell-glass", "cornell-chair", "chairs:16"] {
        let s = scene::load(spec).unwrap();
        let rays = rays_for(&s, 5_000, 21);
        let host = kdray::bvh::try_build(&s.triangles).unwrap().sah_cost;
        let karras = kdray::lbvh::build_with(&NATIVE, &s.triangles, 0).unwrap().bvh.sah_cost;
        for rounds in 1..=3 {
            let b = kdray::lbvh::build_with(&NATIVE, &s.triangles, rounds).unwrap().bvh;
            let cost = b.sah_cost;
            let b = check_tree(&format!("{spec} (kernels, {rounds} rounds)"), &s, b);
            check_hits(&format!("{spec} (kernels, {rounds} rounds)"), &s, &b, &rays);
            println!("{spec}: {rounds} rounds, SAH {cost:.2} (Karras's {karras:.2}, the host's {host:.2})");
            assert!(cost < karras, "{spec}: {rounds} rounds cost {cost} against Karras's {karras}");
        }
        let built = kdray::lbvh::build_on(&NATIVE, &s.triangles).unwrap();
        assert_eq!(built.rounds, kdray::lbvh::TREELET_ROUNDS);
        let cost = built.bvh.sah_cost;
        assert!(cost <= 0.92 * karras && cost <= 1.05 * host, "{spec}: SAH {cost}: Karras's {karras}, the host's {host}");
    }
    // Each triangle 2 % smaller than the last, overlapping it.
    let (cv, cf) = chain(0.98, 4000);
    // Most of its triangles share one Morton cell, so the sort's order within it (and the
    // tree) varies from run to run: three rounds made it 29 levels deep or more than 32; with
    // sixteen, always more.
    let chain = Scene::from_mesh("chain", &cv, &cf).unwrap();
    for rounds in [1, kdray::lbvh::TREELET_ROUNDS, kdray::lbvh::MAX_TREELET_ROUNDS] {
        let built = kdray::lbvh::build_with(&NATIVE, &chain.triangles, rounds).unwrap();
        println!("chain: {rounds} rounds asked, {} kept, depth {}", built.rounds, built.bvh.depth);
        assert!(built.rounds == rounds || built.rounds == 0);
        assert!(rounds < kdray::lbvh::MAX_TREELET_ROUNDS || built.rounds == 0, "the chain's tree kept its treelets (depth {})", built.bvh.depth);
        // (Its hits are not compared with the oracle's: overlapping coplanar triangles tie.)
        check_tree(&format!("chain (kernels, {rounds} rounds asked)"), &chain, built.bvh);
    }
    let e = kdray::lbvh::build_with(&NATIVE, &scene::load("cornell").unwrap().triangles, kdray::lbvh::MAX_TREELET_ROUNDS + 1).unwrap_err();
    assert!(matches!(e, kdray::Error::InvalidInput(_)) && e.to_string().contains("rounds"), "{e}");
}

/// A builder that keeps its buffers (`lbvh::LbvhBuilder`, a scene rebuilt every frame) builds
/// the trees of fresh buffers: on buffers that held a larger scene, on buffers filled with
/// other bytes than a fresh one's zeros (so no kernel reads what the build did not write), and
/// on new ones where a scene needs more; natively and on the GPU.
#[test]
fn a_builder_that_keeps_its_buffers_builds_the_same_trees() {
    let large = scene::load("chairs:16").unwrap();
    let small = scene::load("chairs:4").unwrap();
    let larger = scene::load("chairs:64").unwrap();
    let (nl, ns) = (large.triangles.len(), small.triangles.len());
    // The small scene's sort takes the large one's bits (else its build would allocate anew).
    assert!(ns < nl && kdray::lbvh::cell_bits(ns) == kdray::lbvh::cell_bits(nl));
    assert!(larger.triangles.len() > nl);
    let shape = |b: &BvhData| (b.sah_cost, b.leaves, b.nodes.len(), b.depth);
    let gpu = common::gpu();
    for rt in std::iter::once(&NATIVE as &dyn Runtime).chain(gpu.map(|g| g as &dyn Runtime)) {
        let name = rt.name();
        let fresh_small = kdray::lbvh::build_on(rt, &small.triangles).unwrap().bvh;
        let mut builder = kdray::lbvh::LbvhBuilder::new(rt);
        assert_eq!(builder.capacity(), 0);
        let b = builder.build(&large.triangles, kdray::lbvh::TREELET_ROUNDS).unwrap().bvh;
        assert_eq!(shape(&b), shape(&kdray::lbvh::build_on(rt, &large.triangles).unwrap().bvh), "{name}: chairs:16");
        assert_eq!(builder.capacity(), nl);
        for scribbled in [false, true] {
            if scribbled {
                builder.scribble().unwrap();
            }
            let b = builder.build(&small.triangles, kdray::lbvh::TREELET_ROUNDS).unwrap().bvh;
            assert_eq!(builder.capacity(), nl, "{name}: the small scene's build allocated anew");
            assert_eq!(shape(&b), shape(&fresh_small), "{name}: chairs:4 on kept buffers (scribbled over: {scribbled})");
            let b = check_tree(&format!("chairs:4 (kept buffers, {name})"), &small, b);
            check_hits(&format!("chairs:4 (kept buffers, {name})"), &small, &b, &rays_for(&small, 3_000, 5));
        }
        // Refused input leaves the buffers; more triangles take new ones.
        let mut bad = small.triangles.clone();
        bad[7].v2[0] = f32::INFINITY;
        assert!(builder.build(&bad, kdray::lbvh::TREELET_ROUNDS).is_err());
        assert_eq!(builder.capacity(), nl);
        let b = builder.build(&larger.triangles, kdray::lbvh::TREELET_ROUNDS).unwrap().bvh;
        assert_eq!(builder.capacity(), larger.triangles.len());
        assert_eq!(shape(&b), shape(&kdray::lbvh::build_on(rt, &larger.triangles).unwrap().bvh), "{name}: chairs:64");
    }
}

/// A tracer's BVH built by the kernels in place (`Tracer::build_bvh`: from the triangles on the
/// device, into buffers that stay there) is the tree `LbvhBuilder::build` reads back, and gives
/// its answers (natively, the oracle's bit for bit); after `Tracer::update` moved the
/// triangles and edited the materials (a floor become a light: more lights), a build on the
/// same builder (once on scribbled buffers) and the dropped BVH's buffers follows them, the
/// tracer's boxes, lights and image are a fresh tracer's, and the kd-tree given to `new` is
/// gone; other counts are refused and change nothing. Natively and on the GPU.
#[test]
fn a_tracer_builds_its_bvh_in_place_and_follows_moved_triangles() {
    let a = scene::load("chairs:16").unwrap();
    // The same chairs sheared and lifted (every vertex moved), as a frame of an animation.
    let mut b = a.clone();
    for t in &mut b.triangles {
        for v in [&mut t.v0, &mut t.v1, &mut t.v2] {
            *v = [v[0] + 0.3 * v[1], v[1] + 0.05 * v[2] + 0.2, v[2] - 0.1 * v[0]];
        }
    }
    let floor = b.material_id("floor").unwrap() as usize;
    b.materials[floor].emission = [0.4, 0.3, 0.2];
    let wood = b.material_id("wood").unwrap() as usize;
    b.materials[wood].diffuse = [0.2, 0.5, 0.3];
    assert!(b.lights().len() > a.lights().len());
    // b moved on: as many lights, elsewhere.
    let mut b2 = b.clone();
    for t in &mut b2.triangles {
        for v in [&mut t.v0, &mut t.v1, &mut t.v2] {
            *v = [v[0] + 0.05, v[1] + 0.1, v[2]];
        }
    }
    let other = scene::load("chairs:4").unwrap();
    let tree = kdray::kdtree::try_build(&a.triangles, &Default::default()).unwrap();
    let gpu = common::gpu();
    for rt in std::iter::once(&NATIVE as &dyn Runtime).chain(gpu.map(|g| g as &dyn Runtime)) {
        let name = rt.name();
        let mut builder = kdray::lbvh::LbvhBuilder::new(rt);
        let mut t = Tracer::new(rt, &a, Some(&tree)).unwrap();
        for (frame, s) in [(0, &a), (1, &b), (2, &b2), (3, &a)] {
            if frame > 0 {
                if frame == 2 {
                    builder.scribble().unwrap();
                }
                t.update(s).unwrap();
                assert!(t.check(Accel::BVH).is_err(), "{name}: frame {frame}: the BVH of the last frame is still there");
                assert!(t.check(Accel::kd(kdray_shared::kdtree::Algorithm::Stack)).is_err(), "{name}: frame {frame}: the kd-tree is still there");
            }
            let built = t.build_bvh(&mut builder, kdray::lbvh::TREELET_ROUNDS).unwrap();
            let read = kdray::lbvh::build_on(rt, &s.triangles).unwrap().bvh;
            assert_eq!((built.nodes, built.leaves, built.depth), (read.nodes.len(), read.leaves, read.depth), "{name}: frame {frame}: another tree than the read-back build's");
            let rays = rays_for(s, 3_000, 11 + frame);
            let there = t.closest_hits(Accel::BVH, &rays).unwrap();
            let back = Tracer::new(rt, s, None).unwrap().with_bvh(&read).unwrap();
            let here = back.closest_hits(Accel::BVH, &rays).unwrap();
            assert!(there == here, "{name}: frame {frame}: the in-place BVH answers {} of {} rays otherwise", (0..rays.len()).filter(|&i| there[i] != here[i]).count(), rays.len());
            assert_eq!(t.any_hits(Accel::BVH, &rays).unwrap(), back.any_hits(Accel::BVH, &rays).unwrap(), "{name}: frame {frame}: any-hit");
            let brute = Tracer::new(&NATIVE, s, None).unwrap();
            let oracle = brute.closest_hits(Accel::BRUTE, &rays).unwrap();
            assert!(there.iter().zip(&oracle).filter(|(h, o)| h.is_hit() != o.is_hit()).count() <= 2, "{name}: frame {frame}: hits where the oracle misses or the other way");
            if rt.name() == NATIVE.name() {
                common::assert_matches_oracle(&format!("{name}: frame {frame}"), &t, Accel::BVH, &rays, &oracle, &brute.any_hits(Accel::BRUTE, &rays).unwrap());
            }
            assert!(t.holds(s), "{name}: frame {frame}");
            // Everything else `update` writes: as a tracer made for this frame.
            assert_eq!((t.bounds(), t.trace_bounds(), t.light_count, t.has_specular), (back.bounds(), back.trace_bounds(), back.light_count, back.has_specular), "{name}: frame {frame}");
            let cam = s.camera.to_pod(48, 48);
            let (mine, fresh) = (kdray::integrator::direct::render(&t, Accel::BVH, &cam, 3, 2, &()).unwrap(), kdray::integrator::direct::render(&back, Accel::BVH, &cam, 3, 2, &()).unwrap());
            assert!(mine.radiance == fresh.radiance, "{name}: frame {frame}: another image than a fresh tracer's");
            if rt.name() == NATIVE.name() {
                // Brute force's whole paths start from the tracer's box.
                let o = kdray::integrator::path::PathOptions::path(3, 3, 1);
                let cam = s.camera.to_pod(16, 16);
                let (mine, fresh) = (kdray::integrator::path::render(&t, Accel::BRUTE, &cam, &o, &()).unwrap(), kdray::integrator::path::render(&back, Accel::BRUTE, &cam, &o, &()).unwrap());
                assert!(mine.radiance == fresh.radiance, "{name}: frame {frame}: brute force renders another image than a fresh tracer's");
            }
        }
        // Other counts: refused, the tracer as it was.
        let mut fewer = a.clone();
        fewer.triangles.pop();
        for bad in [&other, &fewer] {
            assert!(t.update(bad).is_err(), "{name}: an update with other counts was taken");
        }
        let mut nan = a.clone();
        nan.triangles[5].v1[2] = f32::NAN;
        assert!(t.update(&nan).is_err(), "{name}: a vertex that is not a number was taken");
        assert!(t.holds(&a) && t.check(Accel::BVH).is_ok(), "{name}: a refused update changed the tracer");
        // A builder of another runtime is refused.
        if gpu.is_some() {
            let other_rt: &dyn Runtime = if rt.name() == NATIVE.name() { gpu.unwrap() } else { &NATIVE };
            assert!(t.build_bvh(&mut kdray::lbvh::LbvhBuilder::new(other_rt), 0).is_err(), "{name}: a builder on another runtime");
        }
    }
}

/// `render --bvh-build kernels`: the same image as the host's BVH (the traversal is exact, so
/// the tree that finds the hits does not change them), natively and on the GPU.
#[test]
fn a_render_with_the_kernels_bvh_is_the_hosts_image() {
    let dir = std::env::temp_dir().join(format!("kdray-lbvh-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut devices = vec!["cpu"];
    if common::gpu().is_some() {
        devices.push("gpu");
    }
    for device in devices {
        let mut images = Vec::new();
        for how in ["host", "kernels"] {
            let out = dir.join(format!("{device}-{how}.png"));
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_kdray"))
                .args(["render", "--scene", "cornell-chair", "--size", "64", "--passes", "2", "--device", device, "--bvh-build", how, "--out"])
                .arg(&out)
                .output()
                .unwrap();
            let said = String::from_utf8_lossy(&o.stdout).to_string();
            assert!(o.status.success(), "{device} {how}: {said}{}", String::from_utf8_lossy(&o.stderr));
            assert!(said.contains(if how == "host" { "by the host's binned SAH" } else { "by the kernels' linear build" }), "{said}");
            images.push(std::fs::read(out.with_extension("pfm")).unwrap());
        }
        assert!(images[0] == images[1], "{device}: the kernels' BVH rendered another image");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
