//! Primary hits by rasterisation (`kdray_shared::raster`, `Tracer::raster_primary_hits`):
//! natively (no rasteriser: every ray traced) bit for bit the traversal's; on the GPU the
//! rasteriser's visibility buffer names the traversal's triangle at almost every pixel, and
//! every answer that differs from the traversal's is one the tie rule allows — the pixel's
//! centre within a sixteenth of a pixel of an edge of the triangle the traversal hits, or the
//! two hits at the same distance within the depth buffer's precision. Scenes: the Cornell box
//! and its chair, a closed sphere at the origin and the same sphere 10^5 away, the Stanford
//! bunny when `../shared/scenes/` holds it.
mod common;

use glam::{DVec3, Vec3};
use kdray::integrator::path::{self, PathOptions};
use kdray::kdtree::{build, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{Accel, Runtime, Scene, Tracer};
use kdray_shared::kdtree::Algorithm;
use kdray_shared::raster::{EMPTY, UNKNOWN};
use kdray_shared::{camera, Camera, Hit, RasterParams};

/// A sixteenth of a pixel: the rasterisers' sub-pixel precision is 1/256 (Vulkan
/// implementations commonly; llvmpipe's too), so a disagreement further from an edge than this
/// is an error.
const EDGE_PIXELS: f64 = 1.0 / 16.0;
/// Relative difference of two hits' distances that the depth buffer cannot order (24 bits of
/// mantissa, with room for the interpolation's rounding).
const DEPTH_TIE: f64 = 1e-5;

fn scenes() -> Vec<Scene> {
    let mut s = vec![kdray::scene::load("cornell").unwrap(), kdray::scene::load("cornell-chair").unwrap()];
    let (v, f) = common::icosphere(Vec3::ZERO, 1.0, 4);
    s.push(common::mesh_scene("sphere", &v, &f));
    let far = Vec3::new(1.5e5, 1.0e3, -2.2e5);
    let (v, f) = common::icosphere(far, 1.0, 4);
    let mut sphere = common::mesh_scene("far sphere", &v, &f);
    sphere.camera = kdray::scene::CameraSpec::framing(far - Vec3::ONE, far + Vec3::ONE);
    s.push(sphere);
    s.extend(common::shared_scene("stanford-bunny.obj"));
    s
}

/// Two hits of one triangle by one ray whose numbers agree up to the last bits (the same
/// watertight test, compiled into two kernels: a driver may contract its operations
/// differently in each).
fn same_numbers(a: &Hit, b: &Hit) -> bool {
    let t = (a.t == b.t) || ((a.t - b.t) as f64).abs() <= 4.0 * f32::EPSILON as f64 * a.t.abs() as f64;
    t && (a.b1 - b.b1).abs() <= 1e-6 && (a.b2 - b.b2).abs() <= 1e-6
}

/// Pixel coordinates (x, y) of the scene point `v` seen by `cam` (float64), or `None` behind
/// the eye.
fn project(cam: &Camera, v: [f32; 3]) -> Option<(f64, f64)> {
    let d = |a: [f32; 3]| DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    let (c0, c1, c2) = (d(cam.top_left), d(cam.du), d(cam.dv));
    let q = d(v) - d(cam.origin);
    let det = c0.dot(c1.cross(c2));
    let s = q.dot(c1.cross(c2)) / det;
    let b = c0.dot(q.cross(c2)) / det;
    let c = c0.dot(c1.cross(q)) / det;
    (s > 0.0).then(|| (b / s, c / s))
}

/// Distance in pixels from the centre of pixel `pixel` to the nearest edge line of triangle
/// `prim` (0 when a corner lies behind the eye: no bound is checked then).
fn edge_distance(scene: &Scene, cam: &Camera, pixel: u32, prim: u32) -> f64 {
    let t = &scene.triangles[prim as usize];
    let p = [t.v0, t.v1, t.v2].map(|v| project(cam, v));
    let (x, y) = ((pixel % cam.width) as f64 + 0.5, (pixel / cam.width) as f64 + 0.5);
    let mut best = f64::INFINITY;
    for k in 0..3 {
        let (Some(a), Some(b)) = (p[k], p[(k + 1) % 3]) else { return 0.0 };
        let (ex, ey) = (b.0 - a.0, b.1 - a.1);
        let len = (ex * ex + ey * ey).sqrt();
        let dist = if len > 0.0 { ((x - a.0) * ey - (y - a.1) * ex).abs() / len } else { ((x - a.0).powi(2) + (y - a.1).powi(2)).sqrt() };
        best = best.min(dist);
    }
    best
}

/// The visibility buffer and the hits of `t`'s rasterised primaries of `cam`.
fn raster(t: &Tracer, accel: Accel, cam: &Camera) -> (RasterParams, Vec<u32>, Vec<Hit>) {
    let rt = t.rt;
    let p = t.raster_params(cam).unwrap();
    let visible = rt.alloc::<u32>("visibility", p.row_words as usize * cam.height as usize).unwrap();
    let out = rt.alloc::<Hit>("primary hit", p.count as usize).unwrap();
    rt.run(&t.raster_passes(accel, &p, &visible, &out).unwrap().iter().map(|k| k.as_ref()).collect::<Vec<_>>()).unwrap();
    (p, rt.read(&visible, visible.len()).unwrap(), rt.read(&out, out.len()).unwrap())
}

/// The projection and the per-pixel resolve natively, on hand-made visibility buffers: points
/// along a pixel's primary ray land on its centre; an empty pixel is a miss, a right candidate
/// is its watertight hit, a wrong or unknown one is traced — in tiled order, 200 pixels wide
/// (rows padded to 256 words).
#[test]
fn projection_and_resolve_natively() {
    use kdray_shared::{raster, trace::Brute};
    let scene = kdray::scene::load("cornell-chair").unwrap();
    let mut cam = scene.camera.to_pod(200, 72);
    cam.order = kdray_shared::ORDER_TILES;
    let n = cam.width * cam.height;
    let p = RasterParams::new(&cam, scene.triangles.len() as u32, n, 1e-3);
    assert_eq!(p.row_words, 256);
    let mut rng = kdray_shared::rng::Rng::new(3, 4);
    for _ in 0..2000 {
        let pixel = rng.next_u32() % n;
        let r = camera::primary_ray(&cam, pixel);
        let t = 1.0 + 2000.0 * rng.next_f32();
        let c = p.clip([r.origin[0] + t * r.dir[0], r.origin[1] + t * r.dir[1], r.origin[2] + t * r.dir[2]]);
        // wgpu's NDC (y up) to framebuffer pixels (y down).
        let (x, y) = ((c[0] / c[3] + 1.0) * 0.5 * cam.width as f32, (1.0 - c[1] / c[3]) * 0.5 * cam.height as f32);
        let want = ((pixel % cam.width) as f32 + 0.5, (pixel / cam.width) as f32 + 0.5);
        assert!((x - want.0).abs() < 2e-3 && (y - want.1).abs() < 2e-3, "pixel {pixel} at t {t}: projected to ({x}, {y}), its centre is {want:?}");
        assert!(c[2] > 0.0 && c[2] <= c[3], "depth within [0, 1]");
    }
    let tree = build(&scene.triangles, &BuildOptions::default());
    let view = tree.view(&scene.triangles);
    let tris = kdray_shared::parts::Parts::one(&scene.triangles);
    let rays: Vec<_> = (0..n).map(|i| camera::primary_ray(&cam, camera::pixel(&cam, i))).collect();
    let want = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap().closest_hits(Accel::kd(Algorithm::Stack), &rays).unwrap();
    let resolve = |visible: &[u32]| {
        let mut out = vec![Hit::NONE; n as usize];
        for i in 0..n {
            raster::primary_hit::<Brute, _>(i, &p, &view, &tris, visible, out.as_mut_slice());
        }
        out
    };
    let slot = |i: u32| p.slot(camera::pixel(&cam, i));
    let mut right = vec![EMPTY; (p.row_words * cam.height) as usize];
    for i in 0..n {
        right[slot(i)] = if want[i as usize].is_hit() { want[i as usize].prim + 1 } else { EMPTY };
    }
    let differ = |got: Vec<Hit>| got.iter().zip(&want).filter(|(a, b)| a != b).count();
    assert_eq!(differ(resolve(&right)), 0, "right candidates: the watertight hits");
    assert_eq!(differ(resolve(&vec![UNKNOWN; right.len()])), 0, "unknown pixels: traced");
    // A wrong candidate: a triangle the pixel's ray misses (and an index past the triangles).
    let nt = scene.triangles.len() as u32;
    let mut wrong = right.clone();
    let mut tried = 0;
    for i in 0..n {
        let ray = &rays[i as usize];
        let miss = (1..nt).map(|k| (want[i as usize].prim.wrapping_add(k)) % nt).find(|&c| !kdray_shared::brute::closest_hit(ray, &scene.triangles[c as usize..c as usize + 1]).is_hit());
        wrong[slot(i)] = match (i % 2, miss) {
            (0, Some(c)) => c + 1,
            _ => nt + 1 + i,
        };
        tried += miss.is_some() as u32;
    }
    assert!(tried > n / 2);
    assert_eq!(differ(resolve(&wrong)), 0, "wrong candidates: traced");
    let empty = resolve(&vec![EMPTY; right.len()]);
    assert!(empty.iter().all(|h| !h.is_hit()), "empty pixels: misses");
}

/// `RENDER_PRIMARY_GIVEN`: the paths take bounce 0's hit from `primary_hits` (both schedules):
/// given misses everywhere, the image is black and the hits stay as given, where the traced
/// image is not.
#[test]
fn eye_paths_continue_from_the_given_hits() {
    use kdray::integrator::path::{eye_passes, params, FrameBuffers};
    use kdray::kernels::Film;
    let scene = kdray::scene::load("cornell").unwrap();
    let tree = build(&scene.triangles, &BuildOptions::default());
    let t = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap();
    // The kd full stack: it has whole-path kernels for given hits (`eye_paths_given_stack`).
    let accel = Accel::kd(Algorithm::Stack);
    let cam = scene.camera.to_pod(32, 24);
    let n = (cam.width * cam.height) as usize;
    let rt = t.rt;
    for fused in [true, false] {
        let o = PathOptions::direct(1, 2);
        let run = |given: bool| {
            let fb = FrameBuffers::new(&t, accel, n).unwrap();
            let mut p = params(&t, &cam, &o, 0, n, 0);
            if given {
                p.flags |= kdray_shared::RENDER_PRIMARY_GIVEN;
                rt.write(&fb.film.primary_hits, &vec![Hit::NONE; n]).unwrap();
            }
            let mut passes = eye_passes(&t, accel, &p, &fb, fused).unwrap();
            assert_eq!(passes.len(), if fused { 1 } else { passes.len().max(2) }, "fused: one whole-path kernel");
            passes.push(Box::new(Film { params: p, paths: &fb.paths, radiance: &fb.film.radiance }));
            rt.run(&passes.iter().map(|k| k.as_ref()).collect::<Vec<_>>()).unwrap();
            (rt.read(&fb.film.primary_hits, n).unwrap(), rt.read(&fb.film.radiance, n).unwrap())
        };
        let (hits, radiance) = run(false);
        assert!(hits.iter().any(|h| h.is_hit()) && radiance.iter().any(|c| c[0] + c[1] + c[2] > 0.0), "fused {fused}: traced");
        let (hits, radiance) = run(true);
        assert!(hits.iter().all(|h| *h == Hit::NONE), "fused {fused}: the given hits stay");
        assert!(radiance.iter().all(|c| c[0] + c[1] + c[2] == 0.0), "fused {fused}: no hit given, no light");
        let mut p = params(&t, &cam, &o, 0, n, 0);
        p.flags |= kdray_shared::RENDER_PRIMARY_GIVEN | kdray_shared::RENDER_JITTER;
        let fb = FrameBuffers::new(&t, accel, n).unwrap();
        assert!(eye_passes(&t, accel, &p, &fb, fused).is_err(), "given hits are for pixel centres");
    }
}

#[test]
fn natively_every_ray_is_traced_bit_for_bit() {
    for scene in scenes().into_iter().take(3) {
        let tree = build(&scene.triangles, &BuildOptions::default());
        let bvh = kdray::bvh::try_build(&scene.triangles).unwrap();
        let t = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
        let mut cam = scene.camera.to_pod(96, 64);
        cam.order = kdray_shared::ORDER_TILES;
        let rays: Vec<_> = (0..cam.width * cam.height).map(|i| camera::primary_ray(&cam, camera::pixel(&cam, i))).collect();
        let want = t.closest_hits(Accel::kd(Algorithm::Stack), &rays).unwrap();
        for accel in [Accel::BVH, Accel::kd(Algorithm::Stack)] {
            let (_, visible, got) = raster(&t, accel, &cam);
            assert!(visible.iter().all(|&v| v == UNKNOWN), "{}: the native twin marks every pixel unknown", scene.name);
            assert_eq!(got, want, "{} with {}: the traversal's hits", scene.name, accel.name());
        }
        let rt: &dyn Runtime = &NATIVE;
        let (visible, out) = (rt.alloc::<u32>("visibility", 1 << 14).unwrap(), rt.alloc::<Hit>("primary hit", 1 << 14).unwrap());
        let p = t.raster_params(&cam).unwrap();
        assert!(t.raster_passes(Accel::kd(Algorithm::Restart), &p, &visible, &out).is_err(), "kd-restart has no rasterised kernel");
        assert!(t.raster_passes(Accel::BVH, &p, &visible, &rt.alloc::<Hit>("primary hit", 10).unwrap()).is_err(), "too few results");
    }
}

#[test]
fn gpu_raster_names_the_traversals_triangle_up_to_the_tie_rule() {
    let Some(g) = common::gpu() else { return };
    for scene in scenes() {
        let tree = build(&scene.triangles, &BuildOptions::default());
        let bvh = kdray::bvh::try_build(&scene.triangles).unwrap();
        let native = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap();
        let t = Tracer::new(g, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
        // Not a multiple of 64 wide (padded rows), tiled order (rays not in pixel order).
        let mut cam = scene.camera.to_pod(200, 136);
        cam.order = kdray_shared::ORDER_TILES;
        let rays: Vec<_> = (0..cam.width * cam.height).map(|i| camera::primary_ray(&cam, camera::pixel(&cam, i))).collect();
        let oracle = native.closest_hits(Accel::kd(Algorithm::Stack), &rays).unwrap();
        for accel in [Accel::BVH, Accel::kd(Algorithm::Stack)] {
            let what = format!("{} with {}", scene.name, accel.name());
            // The same device's traversal: the candidate's test is the same code on the same
            // device, so its numbers agree up to how the driver compiled each kernel (on the
            // H200 the last bits of t and the barycentrics differed: `same_numbers`); the
            // native ones may differ in the last bits too (Vulkan's division is not correctly
            // rounded).
            let want = t.closest_hits(accel, &rays).unwrap();
            assert_eq!(want.iter().map(|h| h.prim).collect::<Vec<_>>(), oracle.iter().map(|h| h.prim).collect::<Vec<_>>(), "{what}: the GPU traversal");
            let (p, visible, got) = raster(&t, accel, &cam);
            let (mut named, mut hits, mut empty, mut misses) = (0, 0, 0, 0);
            let mut differ = 0;
            for (i, (w, h)) in want.iter().zip(&got).enumerate() {
                let pixel = camera::pixel(&cam, i as u32);
                let v = visible[p.slot(pixel)];
                if w.is_hit() {
                    hits += 1;
                    named += (v == w.prim + 1) as usize;
                } else {
                    misses += 1;
                    empty += (v == EMPTY) as usize;
                }
                if w.prim == h.prim {
                    assert!(same_numbers(w, h), "{what}: ray {i} hits its triangle {} with other numbers: {h:?} vs {w:?}", w.prim);
                    continue;
                }
                differ += 1;
                assert!(w.is_hit(), "{what}: ray {i} hits {} where the traversal misses", h.prim);
                let edge = edge_distance(&scene, &cam, pixel, w.prim);
                let tie = h.is_hit() && ((h.t - w.t) as f64).abs() <= DEPTH_TIE * w.t as f64;
                assert!(
                    edge <= EDGE_PIXELS || tie,
                    "{what}: ray {i} (pixel {pixel}) answers {h:?}, the traversal {w:?}: {edge:.4} pixels from its edges, not a tie"
                );
            }
            // The rasteriser does the work: the buffer names the traversal's triangle, or none,
            // almost everywhere (only edge pixels may differ).
            assert!(named as f64 >= 0.99 * hits as f64, "{what}: the buffer names the traversal's triangle at {named} of {hits} hit pixels");
            assert!(empty as f64 >= 0.99 * misses as f64, "{what}: the buffer is empty at {empty} of {misses} missed pixels");
            assert!(hits > 1000, "{what}: {hits} pixels hit: the camera sees the scene");
            eprintln!("{what}: {differ} of {} answers differ from the traversal's (each within the tie rule); buffer right at {named}/{hits} hits, {empty}/{misses} misses", got.len());
        }
    }
}

/// Renders `scene` with `o` on `t` (rasterised primaries or not, as `o` says).
fn render(t: &Tracer, accel: Accel, cam: &Camera, o: &PathOptions) -> kdray::integrator::RenderOutput {
    path::render(t, accel, cam, o, &()).unwrap()
}

#[test]
fn renders_continue_from_rasterised_hits() {
    let scene = kdray::scene::load("cornell-chair").unwrap();
    let tree = build(&scene.triangles, &BuildOptions::default());
    let bvh = kdray::bvh::try_build(&scene.triangles).unwrap();
    let cam = scene.camera.to_pod(120, 88);
    let mut tiled = cam;
    tiled.order = kdray_shared::ORDER_TILES;
    let native = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
    let direct = PathOptions::direct(3, 4);
    let raster_direct = PathOptions { raster: true, ..direct };
    // Natively every ray is traced: through the pixel centres, the same image bit for bit, in
    // both schedules (whole paths, a pass per bounce) and both pixel orders.
    for fused in [true, false] {
        for c in [&cam, &tiled] {
            let a = render(&native, Accel::BVH, c, &PathOptions { fused, ..direct });
            let b = render(&native, Accel::BVH, c, &PathOptions { fused, ..raster_direct });
            assert!(a.hits == b.hits && a.radiance == b.radiance, "natively (fused: {fused}, order {}): the rasterised render is the traced one", c.order);
        }
    }
    // Jittered samples: every pixel of a sample group at the group's point; the film converges
    // to the same image as the traced one's (means within 1 %).
    let path_o = PathOptions::path(5, 3, 16);
    let traced = render(&native, Accel::BVH, &cam, &path_o);
    let rastered = render(&native, Accel::BVH, &cam, &PathOptions { raster: true, ..path_o });
    let mean = |r: &kdray::integrator::RenderOutput| r.radiance.iter().map(|c| (c[0] + c[1] + c[2]) as f64).sum::<f64>() / r.radiance.len() as f64;
    let (m0, m1) = (mean(&traced), mean(&rastered));
    assert!((m0 - m1).abs() <= 0.01 * m0, "jittered groups: mean {m1} against the traced render's {m0}");
    assert!(traced.radiance != rastered.radiance, "the groups' points differ from the per-pixel jitter");

    let Some(g) = common::gpu() else { return };
    let gt = Tracer::new(g, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
    for (accel, c) in [(Accel::BVH, &cam), (Accel::kd(Algorithm::Stack), &tiled)] {
        for fused in [true, false] {
            let what = format!("{} (fused: {fused}, order {})", accel.name(), c.order);
            let traced = render(&gt, accel, c, &PathOptions { fused, ..direct });
            let rastered = render(&gt, accel, c, &PathOptions { fused, ..raster_direct });
            // The paths continue from the hits: where the primary hit is the traced one, so is
            // the pixel's colour, bit for bit (same device, same numbers).
            let mut differ = 0;
            for (k, (a, b)) in traced.hits.iter().zip(&rastered.hits).enumerate() {
                if a.prim == b.prim {
                    assert!(same_numbers(a, b), "{what}: pixel {k}: {a:?} traced, {b:?} rasterised");
                    let (x, y) = (traced.radiance[k], rastered.radiance[k]);
                    let close = (0..3).all(|c| (x[c] - y[c]).abs() <= 1e-4 * x[c].abs().max(1e-3));
                    assert!(close, "{what}: pixel {k}, same hit, other colour: {x:?} vs {y:?}");
                } else {
                    differ += 1;
                }
            }
            assert!(differ as f64 <= 0.005 * traced.hits.len() as f64, "{what}: {differ} primary hits differ from the traced ones");
            let hit = rastered.hits.iter().filter(|h| h.is_hit()).count();
            assert!(hit as f64 >= 0.5 * rastered.hits.len() as f64, "{what}: {hit} pixels hit");
        }
    }
    // Jittered on the GPU: the same groups as natively (up to the tie rule and rounding).
    let rastered_gpu = render(&gt, Accel::BVH, &cam, &PathOptions { raster: true, ..path_o });
    let m2 = mean(&rastered_gpu);
    assert!((m2 - m1).abs() <= 0.002 * m1, "jittered groups on the GPU: mean {m2}, natively {m1}");
    let same = rastered_gpu.hits.iter().zip(&rastered.hits).filter(|(a, b)| a.prim == b.prim).count();
    assert!(same as f64 >= 0.995 * rastered.hits.len() as f64, "the last group's primary hits: {same} of {} as natively", rastered.hits.len());
}

#[test]
fn cameras_that_cannot_be_drawn_are_refused() {
    let scene = kdray::scene::load("cornell").unwrap();
    let t = Tracer::new(&NATIVE, &scene, None).unwrap();
    let mut cam = scene.camera.to_pod(16, 16);
    cam.dv = cam.du;
    assert!(t.raster_params(&cam).is_err(), "axes that do not span space");
    let o = PathOptions { raster: true, ..PathOptions::direct(1, 1) };
    assert!(path::render(&t, Accel::BRUTE, &scene.camera.to_pod(16, 16), &o, &()).is_err(), "brute force has no rasterised kernel");
}
