//! The same rays through the native and the GPU runtime (lavapipe in CI): hit triangle ids,
//! distances, occlusion, RNG streams, camera rays and the rendered image must agree.
mod common;

use kdray::image_out::compare;
use kdray::integrator::direct;
use kdray::runtime::cpu::NATIVE;
use kdray::runtime::{Commands, Kernel, Pending, RawBuffer, Runtime};
use kdray::{scene, Accel, Tracer};
use kdray_shared::{camera, rng::Rng, shade, Hit, Ray};

/// Fraction of differing ids and the largest |Δt|/t where the ids agree.
fn diff(a: &[Hit], b: &[Hit]) -> (f64, f32) {
    let mut differ = 0;
    let mut max_rel = 0.0f32;
    for (x, y) in a.iter().zip(b) {
        if x.prim != y.prim {
            differ += 1;
        } else if x.is_hit() {
            max_rel = max_rel.max((x.t - y.t).abs() / x.t.abs());
        }
    }
    (differ as f64 / a.len() as f64, max_rel)
}

#[test]
fn cornell_256_closest_and_any_hit_cpu_vs_gpu() {
    let Some(g) = common::gpu() else { return };
    let scene = scene::load("cornell").unwrap();
    let cam = scene.camera.to_pod(256, 256);
    let rays: Vec<Ray> = (0..256 * 256).map(|i| camera::primary_ray(&cam, i)).collect();
    let cpu = Tracer::new(&NATIVE, &scene, None).unwrap();
    let gpu = Tracer::new(g, &scene, None).unwrap();
    let (ch, gh) = (cpu.closest_hits(Accel::BRUTE, &rays).unwrap(), gpu.closest_hits(Accel::BRUTE, &rays).unwrap());
    let (frac, max_rel) = diff(&ch, &gh);
    println!("Cornell 256² primary rays on {}: {:.5} % ids differ, max |Δt|/t = {:.2e}", gpu.device_name(), 100.0 * frac, max_rel);
    assert!(frac <= 1e-5, "{:.5} % of hit ids differ", 100.0 * frac);
    assert!(max_rel <= 1e-5, "max |Δt|/t = {max_rel:e}");
    assert!(ch.iter().filter(|h| h.is_hit()).count() > 60000, "the camera sees the box");

    // Shadow rays built on the CPU from the CPU hits, occlusion on both.
    let lights = scene.lights();
    let shadow: Vec<Ray> = rays
        .iter()
        .zip(&ch)
        .enumerate()
        .map(|(i, (r, h))| {
            let p = kdray_shared::RenderParams { seed: 5, light_count: lights.len() as u32, ..Default::default() };
            let (mut ray, mut path) = (*r, kdray_shared::PathState::start(i as u32));
            shade::path_step(&p, 0, &mut ray, h, &mut path, &kdray_shared::parts::Parts::one(&scene.triangles), &scene.materials, &lights).0
        })
        .collect();
    let (ca, ga) = (cpu.any_hits(Accel::BRUTE, &shadow).unwrap(), gpu.any_hits(Accel::BRUTE, &shadow).unwrap());
    let differ = ca.iter().zip(&ga).filter(|(a, b)| a != b).count();
    let occluded = ca.iter().filter(|o| **o).count();
    println!("shadow rays: {occluded} occluded, {differ} differ");
    assert!(differ as f64 <= 1e-5 * ca.len() as f64);
    assert!(occluded > 1000 && occluded < 50000, "the blocks cast shadows: {occluded}");
}

#[test]
fn random_rays_in_and_around_the_cornell_box() {
    let Some(g) = common::gpu() else { return };
    let scene = scene::load("cornell").unwrap();
    let n = 1 << 18;
    let mut rng = Rng::new(99, 1);
    let dirs = common::random_dirs(n, 3);
    let rays: Vec<Ray> = dirs
        .iter()
        .map(|d| {
            let o = [rng.next_f32() * 700.0 - 70.0, rng.next_f32() * 700.0 - 70.0, rng.next_f32() * 900.0 - 300.0];
            Ray::new(o, *d, 0.0, f32::INFINITY)
        })
        .collect();
    let ch = Tracer::new(&NATIVE, &scene, None).unwrap().closest_hits(Accel::BRUTE, &rays).unwrap();
    let gh = Tracer::new(g, &scene, None).unwrap().closest_hits(Accel::BRUTE, &rays).unwrap();
    let (frac, max_rel) = diff(&ch, &gh);
    // Rays starting next to a surface have tiny t, whose rounding error is relative to the
    // coordinates (t comes from a sum of terms of the size of the vertices): measure |Δt|
    // against t + |origin|.
    let max_scaled = rays
        .iter()
        .zip(ch.iter().zip(&gh))
        .filter(|(_, (a, b))| a.prim == b.prim && a.is_hit())
        .map(|(r, (a, b))| (a.t - b.t).abs() / (a.t + r.origin.iter().fold(0.0f32, |m, x| m.max(x.abs()))))
        .fold(0.0f32, f32::max);
    println!(
        "{n} random rays: {:.5} % ids differ, max |Δt|/t = {max_rel:.2e}, max |Δt|/(t + |o|) = {max_scaled:.2e}",
        100.0 * frac
    );
    assert!(frac <= 1e-5, "{:.5} % ids differ", 100.0 * frac);
    assert!(max_scaled <= 1e-5, "max |Δt|/(t + |o|) = {max_scaled:e}");
}

#[test]
fn rng_streams_are_identical() {
    let Some(g) = common::gpu() else { return };
    let n = 100_000;
    let rt: &dyn kdray::Runtime = g;
    let out = rt.alloc::<[u32; 4]>("rng", n).unwrap();
    rt.run(&[&kdray::kernels::RngFill::new(n as u32, 0, 1234, &out)]).unwrap();
    let gpu = rt.read(&out, n).unwrap();
    for (i, got) in gpu.iter().enumerate() {
        let mut r = Rng::new(1234, i as u32);
        let want = [r.next_u32(), r.next_u32(), r.next_u32(), r.next_u32()];
        assert_eq!(*got, want, "stream {i}");
    }
    // And the numbers look uniform: mean of next_f32 over all streams ≈ 0.5.
    let mean = gpu.iter().flatten().map(|x| (x >> 8) as f64 / 16777216.0).sum::<f64>() / (4 * n) as f64;
    assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
}

#[test]
fn cornell_render_matches_pixel_for_pixel() {
    let Some(g) = common::gpu() else { return };
    let scene = scene::load("cornell").unwrap();
    let cam = scene.camera.to_pod(256, 256);
    let pb = ();
    let c = direct::render(&Tracer::new(&NATIVE, &scene, None).unwrap(), Accel::BRUTE, &cam, 7, 4, &pb).unwrap();
    let gt = Tracer::new(g, &scene, None).unwrap();
    let r = direct::render(&gt, Accel::BRUTE, &cam, 7, 4, &pb).unwrap();
    let cmp = compare(&c, &r, 1.0);
    println!("render GPU vs CPU: {cmp}");
    assert!(cmp.id_mismatches as f64 <= 1e-5 * cmp.pixels as f64);
    assert!(cmp.max_rel_dt <= 1e-5);
    // Same hit and same light sample: colours may differ only by float rounding (≤ 1 step).
    assert!(cmp.max_colour_diff <= 1, "{cmp}");
    assert!(cmp.colour_mismatches as f64 <= 1e-3 * cmp.pixels as f64, "{cmp}");
    // The picture is a lit Cornell box: red on the left, green on the right, a bright light.
    let px = |x: u32, y: u32| c.radiance[(y * 256 + x) as usize];
    let left = px(20, 128);
    let right = px(235, 128);
    assert!(left[0] > 2.0 * left[1], "left wall is red: {left:?}");
    assert!(right[1] > 2.0 * right[0], "right wall is green: {right:?}");
    assert!(px(128, 36)[0] > 5.0, "the light is visible near the top: {:?}", px(128, 36));
}

#[test]
fn gpu_camera_rays_match_cpu() {
    let Some(g) = common::gpu() else { return };
    // Rendering uses GPU-generated camera rays; their hits equal CPU camera rays' hits.
    let scene = scene::load("cornell").unwrap();
    let cam = scene.camera.to_pod(97, 61);
    let r = direct::render(&Tracer::new(g, &scene, None).unwrap(), Accel::BRUTE, &cam, 1, 4, &()).unwrap();
    let rays: Vec<Ray> = (0..97 * 61).map(|i| camera::primary_ray(&cam, i)).collect();
    let ch = Tracer::new(&NATIVE, &scene, None).unwrap().closest_hits(Accel::BRUTE, &rays).unwrap();
    let (frac, max_rel) = diff(&ch, &r.hits);
    assert!(frac <= 1e-3 && max_rel <= 1e-5, "{frac} {max_rel}");
}

/// Mirror reflections: the same image on both devices, and the mirrors show something else
/// than their diffuse colour would (the reflected room).
#[test]
fn mirror_reflections_match_and_reflect() {
    let Some(g) = common::gpu() else { return };
    let scene = scene::load("cornell-mirror").unwrap();
    assert!(scene.has_mirror());
    let cam = scene.camera.to_pod(128, 128);
    let pb = ();
    let gt = Tracer::new(g, &scene, None).unwrap();
    let c = direct::render(&Tracer::new(&NATIVE, &scene, None).unwrap(), Accel::BRUTE, &cam, 3, 4, &pb).unwrap();
    let r = direct::render(&gt, Accel::BRUTE, &cam, 3, 4, &pb).unwrap();
    let cmp = compare(&c, &r, 1.0);
    println!("mirror render GPU vs CPU: {cmp}");
    assert!(cmp.id_mismatches == 0 && cmp.max_colour_diff <= 1, "{cmp}");
    assert!(cmp.colour_mismatches as f64 <= 1e-3 * cmp.pixels as f64, "{cmp}");
    // Without bounces the mirrors are shaded as diffuse grey; with them they reflect.
    let flat = direct::render(&Tracer::new(&NATIVE, &scene, None).unwrap(), Accel::BRUTE, &cam, 3, 0, &pb).unwrap();
    let changed = c.radiance.iter().zip(&flat.radiance).filter(|(a, b)| a != b).count();
    assert!(changed > 2000, "only {changed} pixels changed with reflections");
    // A scene without mirrors traces no reflection: bounces change nothing.
    let plain = scene::load("cornell").unwrap();
    let a = direct::render(&Tracer::new(&NATIVE, &plain, None).unwrap(), Accel::BRUTE, &cam, 3, 0, &pb).unwrap();
    let b = direct::render(&Tracer::new(&NATIVE, &plain, None).unwrap(), Accel::BRUTE, &cam, 3, 4, &pb).unwrap();
    assert_eq!(a.radiance, b.radiance);
}

/// `render --packets` and `render --pipeline decomposed` give the monolithic kernels' image
/// exactly, on each device: same primary hits, same radiance bits (mirrors, shadows and all).
#[test]
fn packets_and_decomposed_pipeline_render_the_same_image() {
    use kdray::kdtree::{build, BuildOptions};
    use kdray_shared::kdtree::Algorithm;
    let scene = scene::load("cornell-mirror").unwrap();
    let tree = build(&scene.triangles, &BuildOptions::default());
    let cam = scene.camera.to_pod(96, 96);
    let pb = ();
    for_each_runtime(&scene, &tree, |t| {
        let base = direct::render(&t, Accel::kd(Algorithm::Stack), &cam, 5, 4, &pb).unwrap();
        assert!(base.hits.iter().filter(|h| h.is_hit()).count() > 8000);
        let mut variants = vec![Accel::decomposed(1), Accel::decomposed(16)];
        variants.extend(Accel::gpu_packets());
        for accel in variants {
            let img = direct::render(&t, accel, &cam, 5, 4, &pb).unwrap();
            let cmp = compare(&base, &img, 1.0);
            println!("{} {}: {cmp}", t.device_name(), accel.name());
            assert_eq!(img.hits, base.hits, "{} {}: primary hits differ", t.device_name(), accel.name());
            assert_eq!(img.radiance, base.radiance, "{} {}: radiance differs", t.device_name(), accel.name());
        }
    });
}

/// `render --ray-order tiles`: the tile order is a bijection of the pixels for any image size,
/// groups of four rays are 2×2 quads, and the image equals the scanline image bit for bit.
#[test]
fn tiled_ray_order_renders_the_same_image() {
    use kdray::kdtree::{build, BuildOptions};
    use kdray_shared::kdtree::Algorithm;
    let scene = scene::load("cornell-mirror").unwrap();
    for (w, h) in [(1, 1), (7, 5), (8, 8), (13, 21), (64, 40), (100, 9)] {
        let mut cam = scene.camera.to_pod(w, h);
        cam.order = kdray_shared::ORDER_TILES;
        let mut seen = vec![false; (w * h) as usize];
        for i in 0..w * h {
            let p = camera::pixel(&cam, i) as usize;
            assert!(!seen[p], "{w}x{h}: pixel {p} twice");
            seen[p] = true;
        }
    }
    let mut cam = scene.camera.to_pod(16, 16);
    cam.order = kdray_shared::ORDER_TILES;
    let quad: Vec<u32> = (0..4).map(|i| camera::pixel(&cam, i)).collect();
    assert_eq!(quad, [0, 1, 16, 17], "the first four rays are a 2×2 quad");

    let tree = build(&scene.triangles, &BuildOptions::default());
    let scan = scene.camera.to_pod(90, 70);
    let tiles = kdray_shared::Camera { order: kdray_shared::ORDER_TILES, ..scan };
    let pb = ();
    for_each_runtime(&scene, &tree, |t| {
        for accel in [Accel::kd(Algorithm::ShortStack(3)), Accel::packet(Algorithm::ShortStack(3))] {
            let a = direct::render(&t, accel, &scan, 9, 4, &pb).unwrap();
            let b = direct::render(&t, accel, &tiles, 9, 4, &pb).unwrap();
            assert_eq!(a.hits, b.hits, "{} {}", t.device_name(), accel.name());
            assert_eq!(a.radiance, b.radiance, "{} {}", t.device_name(), accel.name());
        }
    });
}

/// Runs `f` on the native runtime and, where there is a GPU adapter, on the GPU runtime.
fn for_each_runtime(scene: &kdray::Scene, tree: &kdray::kdtree::KdTreeData, mut f: impl FnMut(&Tracer)) {
    f(&Tracer::new(&NATIVE, scene, Some(tree)).unwrap());
    if let Some(g) = common::gpu() {
        f(&Tracer::new(g, scene, Some(tree)).unwrap());
    }
}

/// Buffer clears and indirect dispatch, on each runtime: a dispatch whose workgroup count is
/// read from a buffer runs exactly that many workgroups, the same items on both.
#[test]
fn clear_and_indirect_dispatch_on_both_runtimes() {
    use kdray::kernels::RngFill;
    use kdray::Runtime;
    let n = 1000usize;
    let mut results = Vec::new();
    let mut runtimes: Vec<&dyn Runtime> = vec![&NATIVE];
    if let Some(g) = common::gpu() {
        runtimes.push(g);
    }
    for rt in runtimes {
        let out = rt.alloc::<[u32; 4]>("rng", n).unwrap();
        rt.run(&[&RngFill::new(n as u32, 0, 77, &out)]).unwrap();
        assert!(rt.read(&out, n).unwrap().iter().all(|v| *v != [0; 4]), "{}: filled", rt.name());
        // Clear, then 2 workgroups of 64 threads from an indirect-argument buffer.
        let args = rt.upload("indirect", &[[9u32, 9, 9], [2, 1, 1]]).unwrap();
        let mut c = rt.begin();
        rt.clear(&mut c, out.raw()).unwrap();
        rt.dispatch_indirect(&mut c, &RngFill::new(n as u32, 0, 77, &out), &args, 1).unwrap();
        let p = rt.read_back_of(&mut c, &out, n).unwrap();
        rt.submit(c).unwrap();
        let got: Vec<[u32; 4]> = kdray::runtime::cast(rt.wait(p).unwrap());
        let written = got.iter().filter(|v| **v != [0; 4]).count();
        assert_eq!(written, 128, "{}: an indirect dispatch of 2 workgroups of 64", rt.name());
        assert!(got[128..].iter().all(|v| *v == [0; 4]), "{}: the clear left the rest zero", rt.name());
        results.push(got);
    }
    assert!(results.windows(2).all(|w| w[0] == w[1]), "the runtimes disagree");
}

/// A kernel declared on the host differently from its entry point in the SPIR-V module is an
/// error naming the kernel and the binding, on both runtimes (the native one checks the module
/// too), never a wrong binding.
#[test]
fn a_host_declaration_that_does_not_match_the_shader_is_an_error() {
    use kdray::runtime::{write, Bind, Buffer, Kernel};
    use kdray::Runtime;
    use std::borrow::Cow;
    /// `rng_fill` bound with 8-byte elements instead of [u32; 4].
    struct WrongElement<'a> {
        params: kdray_shared::ItemParams,
        out: &'a Buffer<[u32; 2]>,
    }
    impl Kernel for WrongElement<'_> {
        fn entry(&self) -> Cow<'static, str> {
            "rng_fill".into()
        }
        fn params(&self) -> &[u8] {
            bytemuck::bytes_of(&self.params)
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![write("out", self.out)]
        }
        fn threads(&self) -> u32 {
            self.params.count
        }
        fn run(&self, _t: u32) {
            unreachable!("never runs: the declaration is rejected")
        }
    }
    /// `rng_fill` with its buffer under another name.
    struct WrongName<'a>(WrongElement<'a>);
    impl Kernel for WrongName<'_> {
        fn entry(&self) -> Cow<'static, str> {
            self.0.entry()
        }
        fn params(&self) -> &[u8] {
            self.0.params()
        }
        fn bindings(&self) -> Vec<Bind<'_>> {
            vec![write("output", self.0.out)]
        }
        fn threads(&self) -> u32 {
            self.0.threads()
        }
        fn run(&self, _t: u32) {
            unreachable!()
        }
    }
    let mut runtimes: Vec<&dyn Runtime> = vec![&NATIVE];
    if let Some(g) = common::gpu() {
        runtimes.push(g);
    }
    for rt in runtimes {
        let out = rt.alloc::<[u32; 2]>("rng", 64).unwrap();
        let k = WrongElement { params: kdray_shared::ItemParams { count: 64, ..Default::default() }, out: &out };
        let e = format!("{:#}", rt.run(&[&k]).unwrap_err());
        assert!(e.contains("kernel rng_fill") && e.contains("'out'") && e.contains("16 bytes"), "{}: {e}", rt.name());
        let e = format!("{:#}", rt.run(&[&WrongName(k)]).unwrap_err());
        assert!(e.contains("kernel rng_fill") && e.contains("'out'"), "{}: {e}", rt.name());
    }
}

/// Every adapter the machine has, opened at once (a runtime per device): each renders the image
/// the native runtime renders.
#[test]
fn every_adapter_renders_the_native_image() {
    if common::gpu().is_none() {
        return;
    }
    let scene = scene::load("cornell-mirror").unwrap();
    let cam = scene.camera.to_pod(48, 40);
    let pb = ();
    let native = direct::render(&Tracer::new(&NATIVE, &scene, None).unwrap(), Accel::BRUTE, &cam, 2, 4, &pb).unwrap();
    let gpus = kdray::Gpu::open_all().unwrap();
    assert!(!gpus.is_empty());
    for g in &gpus {
        let img = direct::render(&Tracer::new(g, &scene, None).unwrap(), Accel::BRUTE, &cam, 2, 4, &pb).unwrap();
        let cmp = compare(&native, &img, 1.0);
        println!("gpu:{} {}: {cmp}", g.index, g.adapter_line());
        assert!(cmp.id_mismatches == 0 && cmp.max_colour_diff <= 1, "{cmp}");
    }
    // A buffer of one runtime is refused by another, with an error, not a panic.
    let rt: &dyn kdray::Runtime = &gpus[0];
    let host = (&NATIVE as &dyn kdray::Runtime).alloc::<[u32; 4]>("host", 8).unwrap();
    let e = format!("{:#}", rt.run(&[&kdray::kernels::RngFill::new(8, 0, 1, &host)]).unwrap_err());
    assert!(e.contains("native runtime"), "{e}");
}

/// The counting sort (ranks from a histogram with atomics, offsets, scatter by rank) on both
/// runtimes, exact offsets and by segments: exact offsets equal to the histogram's prefix sum;
/// by segments, each segment's keys' offsets its prefix sum from a start of its own, segments
/// that hold items not overlapping and covering every item; every item in its cell exactly
/// once, keys out of range left out; the same exact offsets on both.
#[test]
fn counting_sort_on_both_runtimes() {
    use kdray::sort::counting_sorts;
    use kdray::Runtime;
    use kdray_shared::sort::segment_slot;
    let mut runtimes: Vec<&dyn Runtime> = vec![&NATIVE];
    if let Some(g) = common::gpu() {
        runtimes.push(g);
    }
    // Cell counts at and around the scan's chunk and level sizes (32, 32², 32³).
    for (n, cells) in [(200_003usize, 1000u32), (5000, 1), (3000, 70_000), (0, 7), (10_000, 32), (10_000, 33), (20_000, 1024), (20_000, 1025), (100_000, 32 * 32 * 32 + 1), (60_000, 27 * 1500), (60_000, 63 * 640), (500, 27)] {
        let mut rng = Rng::new(41, n as u32);
        // Skewed keys (many in few cells), and one in a hundred out of range.
        let keys: Vec<u32> = (0..n)
            .map(|_| {
                let u = rng.next_f32();
                if rng.next_f32() < 0.01 { cells + rng.next_u32() % 5 } else { ((u * u * cells as f32) as u32).min(cells - 1) }
            })
            .collect();
        let mut want = vec![Vec::new(); cells as usize];
        for (i, k) in keys.iter().enumerate() {
            if *k < cells {
                want[*k as usize].push(i as u32);
            }
        }
        let mut want_offsets = vec![0u32];
        for c in &want {
            want_offsets.push(want_offsets.last().unwrap() + c.len() as u32);
        }
        // Each sort runs after one of the mirrored keys (k → cells − 1 − k) with the same
        // buffers: a sort must leave them ready for the next.
        let mirrored: Vec<u32> = keys.iter().map(|&k| if k < cells { cells - 1 - k } else { k }).collect();
        let counting_sort = |rt: &dyn Runtime, seg| counting_sorts(rt, &[&mirrored, &keys], cells, seg);
        let mut all = Vec::new();
        for rt in &runtimes {
            let (offsets, order) = counting_sort(*rt, None).unwrap();
            assert_eq!(offsets, want_offsets, "{}: {n} keys, {cells} cells: offsets", rt.name());
            assert_eq!(order.len(), *want_offsets.last().unwrap() as usize);
            for (c, items) in want.iter().enumerate() {
                let mut got = order[offsets[c] as usize..offsets[c + 1] as usize].to_vec();
                got.sort_unstable();
                assert_eq!(&got, items, "{}: cell {c}", rt.name());
            }
            all.push(offsets);
            // By segments (of sizes that divide the cells).
            for seg in [1u32, 8, 27, 32, 63].into_iter().filter(|s| cells % s == 0) {
                let what = format!("{}: {n} keys, {cells} cells, segments of {seg}", rt.name());
                let (offsets, order) = counting_sort(*rt, Some(seg)).unwrap();
                assert_eq!(offsets.len() as u32, cells / seg * (seg + 1), "{what}: offsets");
                assert_eq!(order.len(), *want_offsets.last().unwrap() as usize, "{what}: items placed");
                let mut ranges = Vec::new();
                for s in 0..cells / seg {
                    let o = &offsets[(s * (seg + 1)) as usize..((s + 1) * (seg + 1)) as usize];
                    for k in 0..seg {
                        assert_eq!(o[k as usize + 1] - o[k as usize], want[(s * seg + k) as usize].len() as u32, "{what}: segment {s}, key {k}");
                    }
                    if o[seg as usize] > o[0] {
                        ranges.push((o[0], o[seg as usize]));
                    }
                }
                assert_ranges_tile(ranges, order.len() as u32, &what);
                for (c, items) in want.iter().enumerate() {
                    let sl = segment_slot(c as u32, seg) as usize;
                    let mut got = order[offsets[sl] as usize..offsets[sl + 1] as usize].to_vec();
                    got.sort_unstable();
                    assert_eq!(&got, items, "{what}: cell {c}");
                }
            }
        }
        assert!(all.windows(2).all(|w| w[0] == w[1]));
    }
}

/// The segments' ranges of slots `(start, end)`, in any order, tile `0..total`.
fn assert_ranges_tile(mut ranges: Vec<(u32, u32)>, total: u32, what: &str) {
    ranges.sort_unstable();
    let mut end = 0;
    for (a, b) in ranges {
        assert_eq!(a, end, "{what}: segments overlap or leave a gap");
        end = b;
    }
    assert_eq!(end, total, "{what}: segments cover the items");
}

/// A barrier for lane threads that fails instead of waiting forever: when a lane panicked
/// (`LaneGuard`) or after 20 s (lanes that never meet: a cross-lane operation under control
/// flow that differs between lanes).
#[derive(Default)]
struct LaneBarrier {
    lanes: u32,
    arrived: std::sync::atomic::AtomicU32,
    generation: std::sync::atomic::AtomicU32,
    poisoned: std::sync::atomic::AtomicBool,
}

impl LaneBarrier {
    fn wait(&self) {
        use std::sync::atomic::Ordering::SeqCst;
        let generation = self.generation.load(SeqCst);
        if self.arrived.fetch_add(1, SeqCst) + 1 == self.lanes {
            self.arrived.store(0, SeqCst);
            self.generation.fetch_add(1, SeqCst);
            return;
        }
        let t0 = std::time::Instant::now();
        while self.generation.load(SeqCst) == generation {
            assert!(!self.poisoned.load(SeqCst), "another lane of the subgroup panicked");
            assert!(t0.elapsed().as_secs() < 20, "the lanes did not meet at a cross-lane operation");
            std::thread::yield_now();
        }
    }
}

/// Marks the barrier poisoned when its lane's thread panics.
struct LaneGuard<'a>(&'a LaneBarrier);

impl Drop for LaneGuard<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.poisoned.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }
}

/// Lanes run as threads in lockstep at every cross-lane operation (`Lanes`), for checking a
/// kernel written for subgroups natively with subgroups of any size.
struct SimLanes<'a> {
    lane: u32,
    count: u32,
    barrier: &'a LaneBarrier,
    slots: &'a [std::sync::atomic::AtomicU32],
}

impl SimLanes<'_> {
    /// Every lane's `v`, once all have given theirs (and before any gives its next); every
    /// lane must be at the same operation `op` (`slots`: the values, then the operations).
    fn exchange(&self, op: u32, v: u32) -> Vec<u32> {
        use std::sync::atomic::Ordering::SeqCst;
        let n = self.count as usize;
        self.slots[self.lane as usize].store(v, SeqCst);
        self.slots[n + self.lane as usize].store(op, SeqCst);
        self.barrier.wait();
        let all: Vec<u32> = self.slots[..n].iter().map(|s| s.load(SeqCst)).collect();
        let ops: Vec<u32> = self.slots[n..].iter().map(|s| s.load(SeqCst)).collect();
        self.barrier.wait();
        assert!(ops.iter().all(|&o| o == op), "lane {} at operation {op} while the lanes are at {ops:?}", self.lane);
        all
    }
}

impl kdray_shared::kernel::Lanes for SimLanes<'_> {
    fn lane(&self) -> u32 {
        self.lane
    }
    fn count(&self) -> u32 {
        self.count
    }
    fn exclusive_add(&self, v: u32) -> u32 {
        self.exchange(0, v)[..self.lane as usize].iter().fold(0, |a, b| a.wrapping_add(*b))
    }
    fn add(&self, v: u32) -> u32 {
        self.exchange(1, v).iter().fold(0, |a, b| a.wrapping_add(*b))
    }
    fn first(&self, v: u32) -> u32 {
        self.exchange(2, v)[0]
    }
}

/// A buffer that lane threads share (plain stores to disjoint elements, atomic additions).
struct SharedWords<'a>(&'a [std::sync::atomic::AtomicU32]);

impl kdray_shared::kernel::Store<u32> for SharedWords<'_> {
    fn load(&self, i: usize) -> u32 {
        self.0[i].load(std::sync::atomic::Ordering::SeqCst)
    }
    fn store(&mut self, i: usize, v: u32) {
        self.0[i].store(v, std::sync::atomic::Ordering::SeqCst)
    }
    fn len(&self) -> usize {
        self.0.len()
    }
}

impl kdray_shared::kernel::AtomicStore for SharedWords<'_> {
    fn atomic_add(&mut self, i: usize, v: u32) -> u32 {
        self.0[i].fetch_add(v, std::sync::atomic::Ordering::SeqCst)
    }
}

/// `sort::segment_offsets` in one lane and by subgroups of 1 to 33 lanes (threads in lockstep)
/// and 1 to 5 subgroups: a segment with items gets its keys' prefix sums from a range of slots,
/// the ranges tile the total, and it is marked written; a segment emptied since an earlier
/// sort gets empty ranges and its mark cleared; one never written is left as it was. (On the
/// GPU, CI's lavapipe runs subgroups of 8, the H100 32.)
#[test]
fn segment_offsets_by_lanes_match_one_lane() {
    use kdray_shared::kernel::Alone;
    use kdray_shared::sort::{segment_offsets, total_slot, SEGMENT_BLOCK, SEGMENT_WRITTEN};
    use kdray_shared::SortParams;
    use std::sync::atomic::AtomicU32;
    let words = |v: &[u32]| v.iter().map(|&x| AtomicU32::new(x)).collect::<Vec<_>>();
    let plain = |v: &[AtomicU32]| v.iter().map(|x| x.load(std::sync::atomic::Ordering::SeqCst)).collect::<Vec<u32>>();
    for seg in [1u32, 5, 8, 31, 32, 33, 63, 64, 100] {
        // Two whole blocks and a part; the second block's segments without items.
        let n_seg = 2 * SEGMENT_BLOCK + 3;
        let p = SortParams { count: 0, cells: seg * n_seg, segment: seg, _pad: 0 };
        let mut rng = Rng::new(7, seg);
        // Per segment: items (0: counts, its marked keys), emptied since a sort (1), or never
        // written (2); each with its expected mark and offsets relative to its first.
        let mut counts = vec![0u32; p.cells as usize];
        let mut segments = vec![0u32; total_slot(&p) + 1];
        let mut offsets = vec![0u32; (n_seg * (seg + 1)) as usize];
        let (mut kinds, mut want_marks, mut want_rel, mut total) = (Vec::new(), Vec::new(), Vec::new(), 0);
        for s in 0..n_seg {
            let kind = if s < 3 {
                s
            } else if (SEGMENT_BLOCK..2 * SEGMENT_BLOCK).contains(&s) {
                1 + s % 2
            } else {
                rng.next_u32() % 3
            };
            let range = (s * (seg + 1)) as usize..((s + 1) * (seg + 1)) as usize;
            let mut rel = vec![0u32];
            if kind == 0 {
                let mut keys = 0;
                for k in 0..seg {
                    let c = if rng.next_f32() < 0.4 { 0 } else { rng.next_u32() % 9 };
                    counts[(s * seg + k) as usize] = c;
                    keys += (c > 0) as u32;
                }
                if keys == 0 {
                    counts[(s * seg) as usize] = 1;
                    keys = 1;
                }
                for k in 0..seg {
                    rel.push(rel[k as usize] + counts[(s * seg + k) as usize]);
                }
                total += rel[seg as usize];
                segments[s as usize] = keys | if rng.next_f32() < 0.5 { SEGMENT_WRITTEN } else { 0 };
                offsets[range].fill(777);
            } else {
                if kind == 1 {
                    segments[s as usize] = SEGMENT_WRITTEN;
                }
                offsets[range.clone()].fill(if kind == 1 { 555 } else { 333 });
                rel = if kind == 1 { vec![0; seg as usize + 1] } else { offsets[range].to_vec() };
            }
            kinds.push(kind);
            want_marks.push(if kind == 0 { SEGMENT_WRITTEN } else { 0 });
            want_rel.push(rel);
        }
        let check = |sg: &[u32], of: &[u32], what: &str| {
            assert_eq!(sg[..n_seg as usize], want_marks[..], "{what}: marks");
            assert_eq!(sg[total_slot(&p)], total, "{what}: total");
            let mut ranges = Vec::new();
            for s in 0..n_seg as usize {
                let o = &of[s * (seg as usize + 1)..(s + 1) * (seg as usize + 1)];
                let base = if kinds[s] == 0 { o[0] } else { 0 };
                assert_eq!(o.iter().map(|x| x.wrapping_sub(base)).collect::<Vec<_>>(), want_rel[s], "{what}: segment {s}'s offsets (kind {})", kinds[s]);
                if kinds[s] == 0 {
                    ranges.push((o[0], o[seg as usize]));
                }
            }
            assert_ranges_tile(ranges, total, what);
        };
        let (mut sg, mut of) = (segments.clone(), offsets.clone());
        segment_offsets(0, 1, &Alone, &p, &counts, sg.as_mut_slice(), of.as_mut_slice());
        check(&sg, &of, &format!("segments of {seg}, one lane"));
        for lanes in [1u32, 2, 3, 8, 32, 33] {
            for groups in [1u32, 2, 5] {
                let (sg, of) = (words(&segments), words(&offsets));
                std::thread::scope(|scope| {
                    for g in 0..groups {
                        let barrier = std::sync::Arc::new(LaneBarrier { lanes, ..Default::default() });
                        let slots = std::sync::Arc::new(words(&vec![0; 2 * lanes as usize]));
                        for lane in 0..lanes {
                            let (barrier, slots, counts, sg, of, p) = (barrier.clone(), slots.clone(), &counts, &sg, &of, &p);
                            scope.spawn(move || {
                                let _guard = LaneGuard(&barrier);
                                let l = SimLanes { lane, count: lanes, barrier: &barrier, slots: &slots };
                                segment_offsets(g, groups, &l, p, counts, &mut SharedWords(sg), &mut SharedWords(of));
                            });
                        }
                    }
                });
                check(&plain(&sg), &plain(&of), &format!("segments of {seg}, {lanes} lanes, {groups} subgroups"));
            }
        }
    }
}

/// A runtime that splits every scene array into two or three parts (`Runtime::split_shift`),
/// whatever its size; otherwise `rt` itself.
struct SplitAll<'a>(&'a dyn Runtime);

impl Runtime for SplitAll<'_> {
    fn split_shift(&self, _label: &str, len: usize, _elem: usize) -> kdray::Result<Option<u32>> {
        Ok((len >= 2).then(|| (1..30).find(|s| len.div_ceil(1 << s) <= 3).unwrap()))
    }
    fn name(&self) -> String {
        format!("{} (arrays split)", self.0.name())
    }
    fn is_native(&self) -> bool {
        self.0.is_native()
    }
    fn is_software(&self) -> bool {
        self.0.is_software()
    }
    fn max_binding(&self) -> u64 {
        self.0.max_binding()
    }
    fn alloc_raw(&self, label: &str, bytes: u64) -> kdray::Result<RawBuffer> {
        self.0.alloc_raw(label, bytes)
    }
    fn write_raw(&self, buf: &RawBuffer, data: &[u8]) -> kdray::Result<()> {
        self.0.write_raw(buf, data)
    }
    fn begin(&self) -> Commands {
        self.0.begin()
    }
    fn clear(&self, c: &mut Commands, buf: &RawBuffer) -> kdray::Result<()> {
        self.0.clear(c, buf)
    }
    fn dispatch(&self, c: &mut Commands, k: &dyn Kernel) -> kdray::Result<()> {
        self.0.dispatch(c, k)
    }
    fn dispatch_indirect(&self, c: &mut Commands, k: &dyn Kernel, args: &kdray::runtime::Buffer<[u32; 3]>, index: usize) -> kdray::Result<()> {
        self.0.dispatch_indirect(c, k, args, index)
    }
    fn read_back(&self, c: &mut Commands, buf: &RawBuffer, bytes: u64) -> kdray::Result<Pending> {
        self.0.read_back(c, buf, bytes)
    }
    fn submit(&self, c: Commands) -> kdray::Result<()> {
        self.0.submit(c)
    }
    fn wait(&self, p: Pending) -> kdray::Result<Vec<u32>> {
        self.0.wait(p)
    }
    fn finish(&self) -> kdray::Result<()> {
        self.0.finish()
    }
}

/// Scenes larger than one storage binding (#11): the triangles and the kd-tree's and the BVH's
/// arrays are uploaded in up to three parts, bound side by side, and read through a
/// specialization constant. With every array split (`SplitAll`), every traversal gives the
/// answers it gives with the arrays whole, bit for bit, natively and on the GPU, and so do the
/// path tracer and photon mapping; the kd photon index over split nodes is one clear error.
#[test]
fn scene_arrays_split_across_bindings_give_the_same_answers() {
    use kdray::integrator::path::{self, PathOptions};
    use kdray::integrator::photon::{self as pm, FinalGather, IndexKind, PhotonMap, PhotonOptions};
    use kdray::kdtree::{build, BuildOptions};
    use kdray_shared::kdtree::Algorithm;
    let scene = scene::load("cornell-glass").unwrap();
    let tree = build(&scene.triangles, &BuildOptions::default());
    let bvh = kdray::bvh::build(&scene.triangles);
    let mut rays: Vec<Ray> = common::random_dirs(900, 11).iter().map(|d| Ray::new([278.0, 300.0, 279.5], *d, 0.0, f32::INFINITY)).collect();
    // Rays from outside the box, through the sphere, at the light.
    rays.extend(common::random_dirs(300, 12).iter().map(|d| Ray::new([278.0 + 900.0 * d[0], 273.0 + 900.0 * d[1], 279.5 + 900.0 * d[2]], [-d[0], -d[1], -d[2]], 0.0, f32::INFINITY)));
    let mut accels = Accel::all();
    accels.extend(Accel::gpu_packets());
    accels.extend([Accel::decomposed(4), Accel::BVH, Accel::BVH_PACKETS]);
    let cam = scene.camera.to_pod(24, 24);
    let mut runtimes: Vec<&dyn Runtime> = vec![&NATIVE];
    if let Some(g) = common::gpu() {
        runtimes.push(g);
    }
    for whole_rt in runtimes {
        let split_rt = SplitAll(whole_rt);
        let whole = Tracer::new(whole_rt, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
        let split = Tracer::new(&split_rt, &scene, Some(&tree)).unwrap().with_bvh(&bvh).unwrap();
        let name = split_rt.name();
        let kdray::tracer::AccelStructure::KdTree { nodes, prims, .. } = &split.structure else { panic!("a kd-tree was given") };
        let b = split.bvh.as_ref().unwrap();
        let parts = [split.tris.parts().len(), nodes.parts().len(), prims.parts().len(), b.nodes.parts().len(), b.tris.parts().len()];
        assert!(parts.iter().all(|&n| n >= 2), "{name}: {parts:?}");
        assert_eq!(whole.tris.parts().len(), 1);
        for &accel in &accels {
            let (h0, h1) = (whole.closest_hits(accel, &rays).unwrap(), split.closest_hits(accel, &rays).unwrap());
            let differ = (0..rays.len()).filter(|&i| h0[i] != h1[i]).count();
            assert_eq!(differ, 0, "{name} {}: {differ} of {} closest hits differ with the arrays split", accel.name(), rays.len());
            let hit = h0.iter().filter(|h| h.is_hit()).count();
            assert!(hit > 900, "{name} {}: {hit} of {} rays hit the box", accel.name(), rays.len());
            assert_eq!(whole.any_hits(accel, &rays).unwrap(), split.any_hits(accel, &rays).unwrap(), "{name} {}: any hits differ", accel.name());
        }
        for accel in [Accel::kd(Algorithm::ShortStack(3)), Accel::BVH, Accel::BRUTE] {
            for fused in [true, false] {
                let o = PathOptions { fused, ..PathOptions::path(5, 4, 2) };
                let (a, b) = (path::render(&whole, accel, &cam, &o, &()).unwrap(), path::render(&split, accel, &cam, &o, &()).unwrap());
                assert!(a.radiance == b.radiance && a.hits == b.hits, "{name} {} (fused: {fused}): the path-traced image differs", accel.name());
            }
            for fused in [true, false] {
                let o = PhotonOptions { photons: 2000, passes: 2, index: IndexKind::Grid, final_gather: FinalGather::Off, fused, ..Default::default() };
                let render = |t: &Tracer| {
                    let mut map = PhotonMap::new(t, accel, Some(&tree), &scene, o.clone()).unwrap();
                    pm::render(&mut map, &cam, &()).unwrap().0
                };
                let (a, b) = (render(&whole), render(&split));
                assert!(a.radiance == b.radiance, "{name} {} (fused: {fused}): the photon-mapped image differs", accel.name());
            }
        }
        let o = PhotonOptions { photons: 4000, passes: 1, index: IndexKind::Kd, ..Default::default() };
        let e = PhotonMap::new(&split, Accel::kd(Algorithm::Stack), Some(&tree), &scene, o).err().expect("the kd index over split nodes is refused");
        assert!(format!("{e:#}").contains("use the grid index"), "{e:#}");
    }
}

/// The default split (`Runtime::split_shift`) follows the binding limit: on a runtime whose
/// limit is lowered — natively (`Cpu::with_split_limit`) and on the GPU
/// (`Gpu::split_arrays_above`) — the glass-sphere box's triangles go into three parts of 2^13 and
/// its kd nodes into two of 2^16, and hits are unchanged; an array past three parts is one
/// error naming the buffer and the limit.
#[test]
fn scene_arrays_split_at_the_binding_limit() {
    use kdray::kdtree::{build, BuildOptions};
    use kdray::runtime::Cpu;
    use kdray_shared::kdtree::Algorithm;
    let scene = scene::load("cornell-glass").unwrap();
    let tree = build(&scene.triangles, &BuildOptions::default());
    let rays: Vec<Ray> = common::random_dirs(2000, 13).iter().map(|d| Ray::new([278.0, 300.0, 279.5], *d, 0.0, f32::INFINITY)).collect();
    let limit = 512 << 10;
    let native = Cpu::with_split_limit(limit);
    let gpu = common::gpu().map(|_| {
        let g = kdray::Gpu::new().unwrap();
        g.split_arrays_above(limit);
        g
    });
    let mut pairs: Vec<(&dyn Runtime, &dyn Runtime)> = vec![(&NATIVE, &native)];
    if let (Some(g), Some(s)) = (common::gpu(), gpu.as_ref()) {
        pairs.push((g, s));
    }
    for (whole_rt, split_rt) in pairs {
        let t = Tracer::new(split_rt, &scene, Some(&tree)).unwrap();
        let kdray::tracer::AccelStructure::KdTree { nodes, prims, .. } = &t.structure else { panic!("a kd-tree was given") };
        assert_eq!([t.tris.parts().len(), nodes.parts().len(), prims.parts().len()], [3, 2, 1], "{}", split_rt.name());
        let w = Tracer::new(whole_rt, &scene, Some(&tree)).unwrap();
        for accel in [Accel::kd(Algorithm::ShortStack(3)), Accel::BRUTE] {
            assert_eq!(t.closest_hits(accel, &rays).unwrap(), w.closest_hits(accel, &rays).unwrap(), "{} {}", split_rt.name(), accel.name());
        }
    }
    let e = Tracer::new(&Cpu::with_split_limit(64 << 10), &scene, None).err().expect("20 502 triangles in parts of 64 KiB are refused");
    let msg = format!("{e:#}");
    assert_eq!(msg, "scene too large for this machine: the triangle buffer needs 961.0 KiB, more than 3 storage buffers of 48.0 KiB (CPU (2 threads) allows at most 64.0 KiB per storage buffer)".replace("2 threads", &format!("{} threads", rayon::current_num_threads())));
}
