//! Hand-made hard cases for the box and triangle tests, each checked natively and, through the
//! same rays, on the GPU (the results must be identical).
mod common;

use glam::Vec3;
use kdray::runtime::cpu::NATIVE;
use kdray::{Accel, Tracer};
use kdray_shared::aabb::{intersect_box, inv_dir, Aabb};
use kdray_shared::triangle::{intersect_triangle, ShearedRay};
use kdray_shared::{brute, Hit, Ray, Triangle};

fn tri(v0: [f32; 3], v1: [f32; 3], v2: [f32; 3]) -> Triangle {
    Triangle { v0, v1, v2, ..Default::default() }
}

fn hit1(ray: &Ray, t: &Triangle) -> Option<f32> {
    let r = ShearedRay::new(ray)?;
    intersect_triangle(&r, t.v0, t.v1, t.v2, ray.t_min, ray.t_max).map(|h| h.t)
}

/// Runs `rays` against `tris` on the GPU too and requires the same hits (ids and t within
/// 1e-6 relative) and the same any-hit answers as on the CPU; returns the CPU hits.
fn both(tris: &[Triangle], rays: &[Ray]) -> Vec<Hit> {
    let scene = kdray::Scene {
        triangles: tris.to_vec(),
        materials: vec![Default::default()],
        material_names: vec!["m".into()],
        ..kdray::Scene::new("hard", kdray::scene::CameraSpec::framing(Vec3::ZERO, Vec3::ONE))
    };
    let cpu = Tracer::new(&NATIVE, &scene, None).unwrap();
    let ch = cpu.closest_hits(Accel::BRUTE, rays).unwrap();
    let ca = cpu.any_hits(Accel::BRUTE, rays).unwrap();
    for (r, h) in rays.iter().zip(&ch) {
        assert_eq!(*h, brute::closest_hit(r, tris));
    }
    if let Some(g) = common::gpu() {
        let gt = Tracer::new(g, &scene, None).unwrap();
        let gh = gt.closest_hits(Accel::BRUTE, rays).unwrap();
        let ga = gt.any_hits(Accel::BRUTE, rays).unwrap();
        for (i, (c, g)) in ch.iter().zip(&gh).enumerate() {
            // A different triangle is only acceptable as a tie: two triangles meeting at the hit
            // point whose t differ in the last bits (the GPU's division may round differently).
            let tie = c.is_hit() && g.is_hit() && (c.t - g.t).abs() <= 1e-6 * c.t.abs();
            assert!(c.prim == g.prim || tie, "ray {i} {:?}: CPU {c:?} GPU {g:?}", rays[i]);
            if c.is_hit() {
                assert!((c.t - g.t).abs() <= 1e-6 * c.t.abs().max(1e-30), "ray {i}: t {} vs {}", c.t, g.t);
            }
        }
        assert_eq!(ca, ga, "any-hit CPU vs GPU");
    }
    ch
}

#[test]
fn zero_and_negative_zero_direction_components() {
    let t = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
    let mut rays = Vec::new();
    for dx in [0.0f32, -0.0] {
        for dy in [0.0f32, -0.0] {
            rays.push(Ray::new([0.0, 0.0, 5.0], [dx, dy, -1.0], 0.0, f32::INFINITY));
            rays.push(Ray::new([0.0, 0.0, -5.0], [dx, dy, 2.0], 0.0, f32::INFINITY));
        }
    }
    let hits = both(&[t], &rays);
    for (r, h) in rays.iter().zip(&hits) {
        assert_eq!(h.prim, 0, "{r:?}");
        assert_eq!(h.t, 5.0 / r.dir[2].abs(), "{r:?}");
    }
    // Box: origin exactly on a slab plane with a ±0 component inside the box for both signs.
    let b = Aabb { min: [0.0, 0.0, 0.0], max: [1.0, 1.0, 1.0] };
    for dx in [0.0f32, -0.0] {
        let o = [0.0, 0.5, -1.0];
        let r = intersect_box(o, inv_dir([dx, 0.0, 1.0]), &b, 0.0, f32::INFINITY);
        let (t0, t1) = r.expect("ray in the x = 0 face plane overlaps the closed box");
        assert_eq!(t0, 1.0);
        assert!(t1 >= 2.0 && t1 < 2.0 + 1e-5);
        let o = [1.0, 0.5, -1.0];
        assert!(intersect_box(o, inv_dir([dx, 0.0, 1.0]), &b, 0.0, f32::INFINITY).is_some());
        let o = [1.0000001, 0.5, -1.0];
        assert!(intersect_box(o, inv_dir([dx, 0.0, 1.0]), &b, 0.0, f32::INFINITY).is_none());
        // Tiny (denormal) components are parallel too: no NaN, same answer.
        let r = intersect_box([0.5, 0.5, -1.0], inv_dir([1e-45 * dx.signum(), 0.0, 1.0]), &b, 0.0, 9.0);
        assert!(r.is_some());
    }
}

#[test]
fn box_with_nan_and_empty_intervals() {
    let b = Aabb { min: [0.0; 3], max: [1.0; 3] };
    let o = [0.5, 0.5, -1.0];
    let id = inv_dir([0.0, 0.0, 1.0]);
    assert!(intersect_box(o, id, &b, 0.0, 0.5).is_none(), "box beyond t_max");
    assert!(intersect_box(o, id, &b, 3.0, 4.0).is_none(), "box before t_min");
    assert!(intersect_box(o, id, &b, 1.0, 1.0).is_some(), "interval touching the box");
    assert!(intersect_box(o, inv_dir([0.0, 0.0, -1.0]), &b, 0.0, f32::INFINITY).is_none());
}

#[test]
fn shared_edge_and_vertex_are_watertight() {
    // A planar fan of 6 triangles around the origin (shared vertex) and their shared edges:
    // every ray crossing the plane inside the hexagon must hit one of them. (A non-planar fold
    // would not do: a ray grazing the ridge may pass just above it, a legitimate miss.)
    let mut tris = Vec::new();
    let ring: Vec<[f32; 3]> = (0..6)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / 6.0;
            [a.cos() * 3.0, a.sin() * 3.0, 0.0]
        })
        .collect();
    for k in 0..6 {
        tris.push(tri([0.0, 0.0, 0.0], ring[k], ring[(k + 1) % 6]));
    }
    let mut rays = vec![
        Ray::new([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        Ray::new([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY),
        Ray::new([1.0, 2.0, 5.0], [-1.0, -2.0, -5.0], 0.0, f32::INFINITY),
    ];
    // Through points on every shared edge, from many directions.
    for k in 0..6 {
        for s in [0.1f32, 0.37, 0.5, 0.93] {
            let p = Vec3::from(ring[k]) * s;
            for d in common::random_dirs(8, k as u32 * 31 + (s * 100.0) as u32) {
                let d = Vec3::from(d);
                if d.z.abs() < 0.05 {
                    continue;
                }
                rays.push(Ray::new((p - d * 4.0).to_array(), d.to_array(), 0.0, f32::INFINITY));
            }
        }
    }
    let hits = both(&tris, &rays);
    for (r, h) in rays.iter().zip(&hits) {
        assert!(h.is_hit(), "leak through a shared edge/vertex: {r:?}");
    }
}

#[test]
fn ray_along_an_edge_and_parallel_to_a_face() {
    let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let rays = [
        // In the triangle's plane, along the edge v0-v1 and through its interior: parallel.
        Ray::new([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, f32::INFINITY),
        Ray::new([-1.0, 0.25, 0.0], [1.0, 0.0, 0.0], 0.0, f32::INFINITY),
        // Parallel, just above the plane.
        Ray::new([-1.0, 0.25, 1e-6], [1.0, 0.0, 0.0], 0.0, f32::INFINITY),
        // Perpendicular through the middle of an edge and through a vertex: on the boundary.
        Ray::new([0.5, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
    ];
    let hits = both(&[t], &rays);
    assert!(!hits[0].is_hit() && !hits[1].is_hit() && !hits[2].is_hit());
    assert_eq!(hits[3].t, 1.0);
    assert_eq!(hits[4].t, 1.0);
}

#[test]
fn origin_on_the_triangle() {
    let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let rays = [
        Ray::new([0.25, 0.25, 0.0], [0.3, 0.1, 1.0], 0.0, f32::INFINITY),
        Ray::new([0.25, 0.25, 0.0], [0.3, 0.1, 1.0], 1e-6, f32::INFINITY),
        Ray::new([0.25, 0.25, 0.0], [0.0, 0.0, -1.0], 0.0, 0.0),
    ];
    let hits = both(&[t], &rays);
    assert_eq!((hits[0].prim, hits[0].t), (0, 0.0));
    assert!(!hits[1].is_hit(), "t_min > 0 excludes the origin");
    assert_eq!((hits[2].prim, hits[2].t), (0, 0.0), "t_max = 0 still admits t = 0");
}

#[test]
fn degenerate_triangles_never_hit() {
    let tris = [
        tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]), // collinear
        tri([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]), // two equal vertices
        tri([0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.5, 0.5, 0.0]), // a point
    ];
    let mut rays = Vec::new();
    for p in [[0.0f32, 0.0], [0.5, 0.0], [1.0, 0.0], [0.0, 0.5], [0.5, 0.5], [1.5, 0.0]] {
        for d in [[0.0f32, 0.0, -1.0], [0.1, -0.2, -1.0], [-0.0, 0.0, -1.0]] {
            rays.push(Ray::new([p[0], p[1], 1.0], d, 0.0, f32::INFINITY));
        }
    }
    for h in both(&tris, &rays) {
        assert!(!h.is_hit(), "{h:?}");
    }
    // The scene builder drops them.
    let mut s = common::mesh_scene("degenerate", &[[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2], [0, 1, 3]]);
    assert_eq!(s.dropped_degenerate, 1);
    assert_eq!(s.triangles.len(), 1);
    assert_eq!(s.triangles[0].face, 1, "face keeps its index in the source mesh");
    s.triangles.clear();
    assert!(s.validate().is_err());
}

#[test]
fn nan_and_inf_rays_miss() {
    let t = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
    let (n, i) = (f32::NAN, f32::INFINITY);
    let rays = [
        Ray::new([n, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, i),
        Ray::new([0.0, 0.0, 1.0], [0.0, n, -1.0], 0.0, i),
        Ray::new([i, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, i),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -i], 0.0, i),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 0.0, i),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], n, i),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, n),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 2.0, 1.0),
        Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1e-39], 0.0, i),
    ];
    for h in both(&[t], &rays) {
        assert!(!h.is_hit());
    }
    assert!(hit1(&Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, i), &t).is_some());
}

/// Embree's watertightness test: rays from the centre of a closed sphere far from the origin
/// must all hit it.
#[test]
fn closed_sphere_far_from_origin_has_no_leaks() {
    let center = Vec3::new(148376.0, 1234.0, -223423.0);
    let (v, f) = common::icosphere(center, 1000.0, 3);
    let scene = common::mesh_scene("sphere", &v, &f);
    assert_eq!(scene.triangles.len(), 1280);
    let n = 1_000_000;
    let rays: Vec<Ray> = common::random_dirs(n, 7)
        .into_iter()
        .map(|d| Ray::new(center.to_array(), d, 0.0, f32::INFINITY))
        .collect();
    let cpu = Tracer::new(&NATIVE, &scene, None).unwrap().closest_hits(Accel::BRUTE, &rays).unwrap();
    let misses = cpu.iter().filter(|h| !h.is_hit()).count();
    assert_eq!(misses, 0, "{misses} of {n} rays leaked out of the closed sphere (CPU)");
    // Also aimed exactly at every vertex and edge midpoint.
    let mut aimed = Vec::new();
    for tri in &f {
        for k in 0..3 {
            let a = Vec3::from(v[tri[k] as usize]);
            let b = Vec3::from(v[tri[(k + 1) % 3] as usize]);
            aimed.push(Ray::new(center.to_array(), (a - center).to_array(), 0.0, f32::INFINITY));
            aimed.push(Ray::new(center.to_array(), ((a + b) * 0.5 - center).to_array(), 0.0, f32::INFINITY));
        }
    }
    let hits = both(&scene.triangles, &aimed);
    assert!(hits.iter().all(|h| h.is_hit()), "a ray aimed at a vertex or an edge leaked");
    if let Some(g) = common::gpu() {
        let gpu = Tracer::new(g, &scene, None).unwrap().closest_hits(Accel::BRUTE, &rays).unwrap();
        let misses = gpu.iter().filter(|h| !h.is_hit()).count();
        assert_eq!(misses, 0, "{misses} of {n} rays leaked out of the closed sphere (GPU)");
        let differ = cpu.iter().zip(&gpu).filter(|(a, b)| a.prim != b.prim).count();
        assert_eq!(differ, 0, "CPU and GPU disagree on {differ} of {n} sphere rays");
    }
}
