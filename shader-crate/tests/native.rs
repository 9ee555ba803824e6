//! The entry points compiled for the host and called as plain functions, the way a GPU calls
//! them: every invocation of a 2D grid of 64-wide workgroups. Checks the item numbering, that
//! invocations past the batch write nothing, and that an entry point stores what the
//! `kdray-shared` function it wraps computes.
use kdray_shader::{item, WORKGROUP};
use kdray_shared::parts::split_code;
use kdray_shared::{brute, camera, Camera, Hit, PathState, Ray, RenderParams, TraceParams, Triangle, ORDER_TILES};
use spirv_std::glam::UVec3;

/// Calls `f(id, groups)` for every invocation of a grid of `gx × gy` workgroups.
fn launch(gx: u32, gy: u32, mut f: impl FnMut(UVec3, UVec3)) {
    let groups = UVec3::new(gx, gy, 1);
    for y in 0..gy {
        for x in 0..gx * WORKGROUP {
            f(UVec3::new(x, y, 0), groups);
        }
    }
}

#[test]
fn a_2d_grid_numbers_every_item_once() {
    let (gx, gy) = (3, 5);
    let mut seen = vec![0u32; (gx * gy * WORKGROUP) as usize];
    launch(gx, gy, |id, groups| seen[item(id, groups) as usize] += 1);
    assert!(seen.iter().all(|&c| c == 1));
}

#[test]
fn camera_rays_entry_point_matches_the_shared_function() {
    let (w, h) = (37, 11);
    let camera = Camera {
        origin: [1.0, 2.0, -3.0],
        width: w,
        top_left: [-0.5, 0.4, 1.0],
        height: h,
        du: [1.0 / w as f32, 0.0, 0.0],
        order: ORDER_TILES,
        dv: [0.0, -0.8 / h as f32, 0.0],
        _pad1: 0,
    };
    let n = (w * h) as usize;
    let (first, count) = (5u32, n as u32 - 9);
    let params = RenderParams { count, first, camera, ..Default::default() };
    let sentinel = Ray::new([9.0; 3], [1.0, 0.0, 0.0], 0.0, 1.0);
    let mut rays = vec![sentinel; n];
    let mut paths = vec![PathState::default(); n];
    // Two rows of workgroups, more invocations than items.
    launch((count).div_ceil(2 * WORKGROUP), 2, |id, groups| kdray_shader::camera_rays(id, groups, &params, &mut rays, &mut paths));
    for i in 0..n as u32 {
        if i < count {
            let pixel = camera::pixel(&camera, first + i);
            assert_eq!(rays[i as usize], camera::primary_ray(&camera, pixel), "ray {i}");
            assert_eq!(paths[i as usize], PathState::start(pixel), "path {i}");
        } else {
            assert_eq!(rays[i as usize], sentinel, "item {i} is past the batch and must not be written");
        }
    }
}

#[test]
fn closest_and_any_brute_entry_points_match_the_oracle() {
    let tri = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| Triangle { v0: a, v1: b, v2: c, ..Default::default() };
    let tris = [tri([-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]), tri([-1.0, -1.0, 3.0], [1.0, -1.0, 3.0], [0.0, 1.0, 3.0])];
    let rays: Vec<Ray> = (0..200)
        .map(|i| {
            let x = (i % 20) as f32 / 10.0 - 1.0;
            let y = (i / 20) as f32 / 5.0 - 1.0;
            Ray::new([x, y, 0.0], [0.0, 0.0, 1.0], 0.0, if i % 3 == 0 { 2.5 } else { f32::INFINITY })
        })
        .collect();
    let params = TraceParams { count: rays.len() as u32, ..Default::default() };
    // The triangles whole (split code 0, one buffer bound thrice), and split into two parts of
    // one triangle (shift 0, two parts: `kdray_shared::parts::split_code`).
    let (t0, t1): (&[Triangle], &[Triangle]) = (&tris[..1], &tris[1..]);
    for (split, parts) in [(0, [&tris[..], &tris[..], &tris[..]]), (split_code(0, 2), [t0, t1, &[]])] {
        let mut hits = vec![Hit::NONE; rays.len()];
        let mut any = vec![7u32; rays.len()];
        let s = [split, 0, 0];
        launch(rays.len().div_ceil(64) as u32, 1, |id, g| kdray_shader::closest_brute(id, g, s, &params, &rays, parts[0], parts[1], parts[2], &[], &[], &[], &[], &[], &[], &mut hits));
        launch(rays.len().div_ceil(64) as u32, 1, |id, g| kdray_shader::any_brute(id, g, s, &params, &rays, parts[0], parts[1], parts[2], &[], &[], &[], &[], &[], &[], &mut any));
        let mut hit_count = 0;
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(hits[i], brute::closest_hit(r, &tris), "ray {i} (split {split})");
            assert_eq!(any[i], brute::any_hit(r, &tris) as u32, "ray {i} (split {split})");
            hit_count += hits[i].is_hit() as u32;
        }
        assert!(hit_count > 20 && hit_count < 200, "{hit_count} hits");
    }
}
