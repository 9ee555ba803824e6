//! Shared by the test suites: the GPU (once per test binary) and closed meshes.
#![allow(dead_code)]
use glam::Vec3;
use kdray::scene::{CameraSpec, Scene};
use kdray::Gpu;
use kdray_shared::Material;
use std::sync::OnceLock;

/// The GPU, or `None` (with a message) when there is no adapter. With `KDRAY_REQUIRE_GPU=1`
/// (set by the README's test command, and so in CI) a missing adapter fails the test instead.
pub fn gpu() -> Option<&'static Gpu> {
    static GPU: OnceLock<Result<Gpu, String>> = OnceLock::new();
    match GPU.get_or_init(|| Gpu::new().map_err(|e| format!("{e:#}"))) {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("KDRAY_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("KDRAY_REQUIRE_GPU=1 but no GPU: {e}");
            }
            eprintln!("skipped: GPU part of this test needs a Vulkan adapter ({e})");
            None
        }
    }
}

/// Icosphere of `subdiv` subdivisions: closed, every edge shared by exactly two triangles with
/// bit-identical vertex coordinates.
pub fn icosphere(center: Vec3, radius: f32, subdiv: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<glam::DVec3> = [
        (-1.0, t, 0.0), (1.0, t, 0.0), (-1.0, -t, 0.0), (1.0, -t, 0.0),
        (0.0, -1.0, t), (0.0, 1.0, t), (0.0, -1.0, -t), (0.0, 1.0, -t),
        (t, 0.0, -1.0), (t, 0.0, 1.0), (-t, 0.0, -1.0), (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| glam::DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..subdiv {
        let mut mid = std::collections::HashMap::new();
        let mut nf = Vec::new();
        for tri in &f {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *mid.entry(key).or_insert_with(|| {
                    v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                    (v.len() - 1) as u32
                });
            }
            nf.push([tri[0], m[0], m[2]]);
            nf.push([tri[1], m[1], m[0]]);
            nf.push([tri[2], m[2], m[1]]);
            nf.push([m[0], m[1], m[2]]);
        }
        f = nf;
    }
    let c = center.as_dvec3();
    let verts = v.iter().map(|p| (c + *p * radius as f64).as_vec3().to_array()).collect();
    (verts, f)
}

pub fn mesh_scene(name: &str, verts: &[[f32; 3]], faces: &[[u32; 3]]) -> Scene {
    let mut s = Scene::new(name, CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let m = s.add_material("white", Material { diffuse: [0.8; 3], ..Default::default() });
    for f in faces {
        let v = f.map(|i| Vec3::from(verts[i as usize]));
        s.add_triangle(v, m, &|| name.to_string()).unwrap();
    }
    s
}

/// Uniformly distributed unit vectors (deterministic).
pub fn random_dirs(n: usize, seed: u32) -> Vec<[f32; 3]> {
    let mut rng = kdray_shared::rng::Rng::new(seed, 0);
    (0..n)
        .map(|_| {
            let z = 2.0 * rng.next_f32() - 1.0;
            let phi = std::f32::consts::TAU * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

/// Each ray followed by seven more from its origin (in random directions within its interval):
/// groups of eight that `bvh+packets` traces together natively (nearby origins), so the packet
/// walk meets every ray of `rays`, hard cases included, in a packet of its own.
pub fn bundles(rays: &[kdray::Ray], seed: u32) -> Vec<kdray::Ray> {
    let dirs = random_dirs(rays.len() * 7, seed);
    let dirs = &dirs;
    rays.iter()
        .enumerate()
        .flat_map(|(i, r)| std::iter::once(*r).chain((0..7).map(move |k| kdray::Ray::new(r.origin, dirs[i * 7 + k], r.t_min, r.t_max))))
        .collect()
}

/// `bvh+packets` gives the one-ray BVH walk's answers bit for bit on `rays` in bundles (each
/// ray in a packet of its own: `bundles`), natively.
pub fn assert_packets_match_single(what: &str, t: &kdray::Tracer, rays: &[kdray::Ray]) {
    let b = bundles(rays, 77);
    let (single, packed) = (t.closest_hits(kdray::Accel::BVH, &b).unwrap(), t.closest_hits(kdray::Accel::BVH_PACKETS, &b).unwrap());
    if let Some(i) = (0..b.len()).find(|&i| single[i] != packed[i]) {
        panic!("{what}: bvh+packets differs from bvh on {} of {} bundled rays; first: {:?} gives {:?}, bvh {:?}", (0..b.len()).filter(|&i| single[i] != packed[i]).count(), b.len(), b[i], packed[i], single[i]);
    }
    let (single, packed) = (t.any_hits(kdray::Accel::BVH, &b).unwrap(), t.any_hits(kdray::Accel::BVH_PACKETS, &b).unwrap());
    let bad = (0..b.len()).filter(|&i| single[i] != packed[i]).count();
    assert_eq!(bad, 0, "{what}: bvh+packets any-hit differs from bvh on {bad} of {} bundled rays", b.len());
}

/// `accel` on `t` gives the oracle's answers bit for bit (closest and any hit); the panic names
/// the first ray that differs.
pub fn assert_matches_oracle(what: &str, t: &kdray::Tracer, accel: kdray::Accel, rays: &[kdray::Ray], oracle: &[kdray::Hit], oracle_any: &[bool]) {
    let hits = t.closest_hits(accel, rays).unwrap();
    let bad: Vec<usize> = (0..rays.len()).filter(|&i| hits[i] != oracle[i]).collect();
    if let Some(&i) = bad.first() {
        panic!("{what}: {} differs from the oracle on {} of {} rays; first: {:?} gives {:?}, oracle {:?}", accel.name(), bad.len(), rays.len(), rays[i], hits[i], oracle[i]);
    }
    let any = t.any_hits(accel, rays).unwrap();
    let bad = (0..rays.len()).filter(|&i| any[i] != oracle_any[i]).count();
    assert_eq!(bad, 0, "{what}: {} any-hit differs from the oracle on {bad} of {} rays", accel.name(), rays.len());
}

/// A mesh from `../shared/scenes/` (beside the checkout), or `None` with a message when that
/// folder or file is absent: the tests that need one skip.
pub fn shared_scene(file: &str) -> Option<Scene> {
    let path = format!("{}/../../shared/scenes/{file}", env!("CARGO_MANIFEST_DIR"));
    if !std::path::Path::new(&path).exists() {
        eprintln!("skipped: {path} not present (the shared scenes folder lies beside the checkout)");
        return None;
    }
    Some(kdray::scene::load(&path).unwrap())
}
