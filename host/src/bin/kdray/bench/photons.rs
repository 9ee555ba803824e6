//! The `photons` suite: photon mapping's speed and its error against a path-traced reference,
//! on the device the run is given.
//!
//! Table 1 (`photons`): per scene, one pass of 2^20 photons — photon rays and bounces
//! (from a separate counting run), the trace's time and photon bounces per second (whole
//! paths, the per-bounce passes, and the whole-path kernel without lights, stopped at the
//! first hit and storing nothing: where its time goes), the photon index's build time (hashed
//! grid and kd leaves), and the eye pass and the gather at the benchmark's resolution (grid of
//! cells r and of 2r, kd leaves; what a gather finds and tests per point, and the grid's gather
//! again at the radius that finds about 50 photons a point — there also the caustic map's
//! photons found and tested per point and its subgroup balance, where the scene has one — and
//! over eye paths in 8×8 tiles of pixels instead of rows), and a final gather's eye pass (eye
//! paths, resumed to a second point with its shadow ray, gathered there: BVH, grid). Times are
//! wall time per pass of several passes recorded into one submission (launch overhead
//! amortised, every clear and dispatch included); on a GPU the first scene's row is measured
//! twice, the first time discarded (a warm-up).
//!
//! Table 2 (`photons-error`): per scene at 512² (or `--size` if smaller), the error of
//! progressive photon mapping (default, fixed radius, kd index, independent photons, direct
//! light from photons, final gathering; `KDRAY_PHOTONS_VARIANTS` picks some) and of the path tracer against a path-traced reference of many
//! samples, against wall time (whole renders: every pass and transfer). Error: RMSE of the
//! displayed images (clamped at 1) over the reference's mean (the measure), and relMSE.
//! The reference is written as `reference-SCENE.pfm` and the scene for Mitsuba as
//! `mitsuba-SCENE/` beside the tables.
use super::plot::{line_chart, LineChart, Series};
use super::suites::{dev_name, short_device_name};
use super::{device_line, write_cells, Options, Scenes};
use kdray::accel::Accel;
use kdray::image_out::{image_error, write_pfm};
use kdray::integrator::path::{self, FrameBuffers, PathOptions};
use kdray::integrator::photon::{self as pm, FinalGather, IndexKind, PhotonMap, PhotonOptions};
use kdray::integrator::{RenderOutput, SamplerKind};
use kdray::kernels::TracePhotons;
use kdray_shared::PhotonParams;
use kdray::runtime::cpu::NATIVE;
use kdray::runtime::{Commands, Runtime};
use kdray::tracer::Tracer;
use anyhow::{Context, Result};
use kdray_shared::kdtree::Algorithm;
use std::path::PathBuf;
use std::time::Instant;

/// Photon mapping's scenes: the Cornell box, with a chair, the conference room, with a glass
/// sphere (caustics).
fn scenes(o: &Options) -> Vec<String> {
    o.scenes.clone().unwrap_or_else(|| ["cornell", "cornell-chair", "conference", "cornell-glass"].map(String::from).to_vec())
}

/// Milliseconds per copy of what `record` records: `copies` copies in one submission, the
/// median of 3 attempts after one warm-up attempt. On a GPU from submission to completion; the
/// native runtime runs passes as they are recorded, so there the recording is timed too.
fn time_recorded(rt: &dyn Runtime, copies: u32, record: &dyn Fn(&mut Commands) -> kdray::Result<()>) -> Result<f64> {
    let mut ms = Vec::new();
    for attempt in 0..4 {
        rt.finish()?;
        let native_start = Instant::now();
        let mut c = rt.begin();
        for _ in 0..copies {
            record(&mut c)?;
        }
        let start = if rt.is_native() { native_start } else { Instant::now() };
        rt.submit(c)?;
        rt.finish()?;
        if attempt > 0 {
            ms.push(start.elapsed().as_secs_f64() * 1e3 / copies as f64);
        }
    }
    Ok(kdray::gpu::median(&ms).unwrap_or(f64::NAN))
}

fn error_of(img: &RenderOutput, reference: &RenderOutput) -> (f64, f64) {
    let f = |o: &RenderOutput| o.radiance.iter().map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>();
    let e = image_error(&f(img), &f(reference));
    (e.rel_rmse, e.rel_mse)
}

pub fn photons(o: &Options, all: &mut Scenes) -> Result<Vec<PathBuf>> {
    let rt: &dyn Runtime = match o.gpu {
        Some(g) => g,
        None => &NATIVE,
    };
    let specs = scenes(o);
    std::fs::create_dir_all(&o.out).with_context(|| format!("cannot create {}", o.out.display()))?;
    let accel = Accel::kd(Algorithm::ShortStack(3));
    // A software device (the native runtime, lavapipe) gets small workloads: CI runs every
    // suite at tiny sizes there.
    let software = rt.is_native() || o.gpu.is_some_and(|g| g.is_software());
    let photons: u32 = if software { (o.size * o.size * 4).clamp(1 << 12, 1 << 18) } else { (o.size * o.size * 4).clamp(1 << 16, 1 << 20) };
    let copies = if software { 1 } else { 5 };
    o.progress.set_length(specs.len() as u64 * 2);
    let speed_header: Vec<String> = [
        "scene", "triangles", "photons", "rays traced", "bounces", "bounces/photon", "stored", "trace ms", "M bounces/s", "BVH trace ms", "BVH M bounces/s",
        "split trace ms", "trace parts: emit only / first hit only / no stores ms", "index grid ms", "grid keys+ranks / offsets / place ms", "cells, slots", "index kd ms", "eye ms", "BVH eye ms", "gather grid ms", "gather grid: found / tested per point", "gather grid at ~50 found ms (found / tested)", "gather grid, 8×8 tiles: default / ~50 found ms (subgroup balance)", "gather grid 2r ms", "gather kd ms", "BVH eye + final gather + gather ms", "image",
    ]
    .map(String::from)
    .to_vec();
    let mut speed = Vec::new();
    let err_size = o.size.min(512);
    let err_header: Vec<String> =
        ["scene", "method", "passes or spp", "photons/pass", "seconds", "rel RMSE %", "noise-corrected %", "relMSE", "reference spp"].map(String::from).to_vec();
    let mut errors = Vec::new();
    let mut ref_notes: Vec<String> = Vec::new();
    let mut files = Vec::new();
    // On a GPU the first scene's speed row is measured twice and the first discarded: measured
    // once, its eye passes and gathers ran 3-6× slow (H200: whichever scene came first, in
    // every attempt of its timings), the next scenes' not.
    let mut runs: Vec<(&String, bool)> = specs.iter().map(|s| (s, false)).collect();
    if !software {
        runs.insert(0, (&specs[0], true));
    }
    for (spec, warm_up) in runs {
        let (scene, tree) = all.get(spec, &o.build)?;
        let bvh = kdray::bvh::try_build(&scene.triangles)?;
        let t = Tracer::new(rt, scene, Some(tree))?.with_bvh(&bvh)?;
        let speed_only = std::env::var("KDRAY_PHOTONS_SPEED_ONLY").is_ok_and(|v| v == "1");
        // Speed: one pass of `photons` photons, both indices.
        let mut row = vec![scene.name.clone(), scene.triangles.len().to_string(), photons.to_string()];
        let base = PhotonOptions { photons, passes: 1, final_gather: FinalGather::Off, photon_threads: o.photon_threads, ..Default::default() };
        let split = PhotonMap::new(&t, accel, Some(tree), &scene, PhotonOptions { fused: false, ..base.clone() })?;
        let (rays, bounces) = split.count_bounces(0)?;
        let split_ms = time_recorded(rt, copies, &|c| split.record_trace(c, 0))?;
        drop(split);
        let mut grid = PhotonMap::new(&t, accel, Some(tree), &scene, base.clone())?;
        let stored = grid.trace_and_index(0)?;
        let trace_ms = time_recorded(rt, copies, &|c| grid.record_trace(c, 0))?;
        // The same photons through the wide BVH (the same bounces: it finds the kd-tree's hits).
        let mut wide_map = PhotonMap::new(&t, Accel::BVH, Some(tree), &scene, base.clone())?;
        wide_map.trace_and_index(0)?;
        let bvh_trace_ms = time_recorded(rt, copies, &|c| wide_map.record_trace(c, 0))?;
        drop(wide_map);
        // Where the whole-path kernel's time goes: the same dispatch with no lights (launch and
        // emission only), stopping at the first hit (max_bounces 0), and storing nothing
        // (capacity 0: slots are still taken).
        let method = t.whole_path_method(accel, TracePhotons::PREFIX).context("no whole-path photon kernel")?;
        let part = |p: PhotonParams| -> Result<f64> {
            let k = TracePhotons::new(method, PhotonParams { count: photons, ..p }, &t.lights, t.scene_binds(accel), &t.materials, &grid.records, &grid.counter)
                .context("no whole-path photon kernel")?;
            time_recorded(rt, copies, &|c| {
                rt.clear(c, grid.counter.raw())?;
                rt.dispatch(c, &k)
            })
        };
        let p0 = PhotonParams { stride: grid.stride(photons), ..grid.photon_params(0) };
        let parts = [part(PhotonParams { light_count: 0, ..p0 })?, part(PhotonParams { max_bounces: 0, ..p0 })?, part(PhotonParams { capacity: 0, ..p0 })?];
        let mut wide = PhotonMap::new(&t, accel, Some(tree), &scene, PhotonOptions { grid_window: 2, ..base.clone() })?;
        wide.trace_and_index(0)?;
        // The first steps alone, then the whole index: the gathers below read the index as the
        // last of these left it, and by segments a rerun of the offsets alone need not give
        // the blocks the places the photons were put at.
        let steps: Vec<f64> = (1..=2).map(|s| time_recorded(rt, copies, &|c| grid.record_index_steps(c, 0, s))).collect::<Result<_>>()?;
        // Steps 1 and 2 reset the sort's buffers after them (the next index would add to its
        // counts): not part of an index.
        let reset = time_recorded(rt, copies, &|c| grid.record_index_reset(c))?;
        let index_grid = time_recorded(rt, copies, &|c| grid.record_index(c, 0))?;
        let (cells, slots) = grid.index_size();
        let mut kd = PhotonMap::new(&t, accel, Some(tree), &scene, PhotonOptions { index: IndexKind::Kd, ..base.clone() })?;
        kd.trace_and_index(0)?;
        let index_kd = time_recorded(rt, copies, &|c| kd.record_index(c, 0))?;
        let cam = scene.camera.to_pod(o.size, o.size);
        let n = (o.size * o.size) as usize;
        let mut fg_map = PhotonMap::new(&t, Accel::BVH, Some(tree), &scene, PhotonOptions { final_gather: FinalGather::All, ..base.clone() })?;
        fg_map.trace_and_index(0)?;
        let (eye_ms, bvh_eye_ms, gather_grid, per_point, at50, gather_tiles, gather_wide, gather_kd, fg_ms) = if t.batch_size(accel, n) >= n {
            let fb = FrameBuffers::new(&t, accel, n)?;
            let gp = pm::GatherPoints::new(&t, 0)?;
            let po = PathOptions { seed: 1, bounces: 16, diffuse_bounces: 0, spp: 1, jitter: true, fused: true, sampler: SamplerKind::Sobol, raster: false, unit_samples: 1 };
            let mut p = path::params(&t, &cam, &po, 0, n, 0);
            p.flags |= kdray_shared::RENDER_GATHER;
            let eye = time_recorded(rt, copies, &|c| rt.dispatch_all(c, path::eye_passes(&t, accel, &p, &fb, true)?).map(drop))?;
            let bvh_eye = time_recorded(rt, copies, &|c| rt.dispatch_all(c, path::eye_passes(&t, Accel::BVH, &p, &fb, true)?).map(drop))?;
            let g = time_recorded(rt, copies, &|c| rt.dispatch(c, &grid.gather(0, n as u32, &fb, &gp)))?;
            // What a gather reads: photons found and tested per point (global map, every 61st
            // path), and the gather again at the radius that finds about 50 per point.
            let [qs, _] = grid.query_stats(0, &fb, n as u32, 61)?;
            let r50 = grid.index_params(0, 1).radius[0] * (50.0 / qs.found_per_point().max(1.0)).sqrt() as f32;
            let mut m50 = PhotonMap::new(&t, accel, Some(tree), &scene, PhotonOptions { radius: Some(r50), ..base.clone() })?;
            m50.trace_and_index(0)?;
            let g50 = time_recorded(rt, copies, &|c| rt.dispatch(c, &m50.gather(0, n as u32, &fb, &gp)))?;
            // With the caustic map's gathers at the same points (its radius `caustic_radius` of
            // the global map's), where the scene has one.
            let [qs50, qc50] = m50.query_stats(0, &fb, n as u32, 61)?;
            let per_point = format!("{:.1} / {:.1}", qs.found_per_point(), qs.visited_per_point());
            let mut at50 = format!("{g50:.3} ({:.1} / {:.1})", qs50.found_per_point(), qs50.visited_per_point());
            if qc50.points > 0 {
                at50 += &format!(", caustic {:.1} / {:.1}", qc50.found_per_point(), qc50.visited_per_point());
            }
            let w = time_recorded(rt, copies, &|c| rt.dispatch(c, &wide.gather(0, n as u32, &fb, &gp)))?;
            let k = time_recorded(rt, copies, &|c| rt.dispatch(c, &kd.gather(0, n as u32, &fb, &gp)))?;
            // The gather over eye paths in 8×8 tiles of pixels (Morton order inside a tile)
            // instead of rows: a subgroup's points lie close together.
            let cam_tiles = kdray_shared::Camera { order: kdray_shared::ORDER_TILES, ..cam };
            let mut pt = path::params(&t, &cam_tiles, &po, 0, n, 0);
            pt.flags |= kdray_shared::RENDER_GATHER;
            let mut c = rt.begin();
            rt.dispatch_all(&mut c, path::eye_passes(&t, accel, &pt, &fb, true)?)?;
            rt.submit(c)?;
            let gt = time_recorded(rt, copies, &|c| rt.dispatch(c, &grid.gather(0, n as u32, &fb, &gp)))?;
            let g50t = time_recorded(rt, copies, &|c| rt.dispatch(c, &m50.gather(0, n as u32, &fb, &gp)))?;
            // How evenly a subgroup's 32 gathers (8 × 4 pixels) share its time at ~50 found.
            let [qs50t, qc50t] = m50.query_stats(0, &fb, n as u32, 61)?;
            let balance = qs50t.group_balance();
            drop(m50);
            let mut gt = format!("{gt:.3} / {g50t:.3} ({balance:.2}");
            if qc50t.points > 0 {
                gt += &format!(", caustic {:.2}", qc50t.group_balance());
            }
            gt += ")";
            // Eye paths to their first points, resumed to the second, the gather there (no
            // caustic gather at the first point: the whole final gather but that).
            let fg = time_recorded(rt, copies, &|c| {
                rt.dispatch_all(c, path::eye_passes(&t, Accel::BVH, &p, &fb, true)?)?;
                rt.dispatch_all(c, path::eye_passes(&t, Accel::BVH, &pm::final_gather_params(&p, 1), &fb, true)?)?;
                rt.dispatch(c, &fg_map.gather(0, n as u32, &fb, &gp))
            })?;
            (format!("{eye:.3}"), format!("{bvh_eye:.3}"), format!("{g:.3}"), per_point, at50, gt, format!("{w:.3}"), format!("{k:.3}"), format!("{fg:.3}"))
        } else {
            ("–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into())
        };
        drop(fg_map);
        row.extend([
            rays.to_string(),
            bounces.to_string(),
            format!("{:.2}", bounces as f64 / photons as f64),
            stored.to_string(),
            format!("{trace_ms:.3}"),
            format!("{:.1}", bounces as f64 / trace_ms / 1e3),
            format!("{bvh_trace_ms:.3}"),
            format!("{:.1}", bounces as f64 / bvh_trace_ms / 1e3),
            format!("{split_ms:.3}"),
            format!("{:.3} / {:.3} / {:.3}", parts[0], parts[1], parts[2]),
            format!("{index_grid:.3}"),
            format!("{:.3} / {:.3} / {:.3}", steps[0] - reset, steps[1] - steps[0], index_grid - steps[1] + reset),
            format!("{cells}, {slots}"),
            format!("{index_kd:.3}"),
            eye_ms,
            bvh_eye_ms,
            gather_grid,
            per_point,
            at50,
            gather_tiles,
            gather_wide,
            gather_kd,
            fg_ms,
            format!("{}²", o.size),
        ]);
        if warm_up {
            continue;
        }
        speed.push(row);
        drop(kd);
        drop(wide);
        drop(grid);
        o.progress.inc(1);

        if speed_only {
            o.progress.inc(1);
            continue;
        }
        // Error against time at err_size², with the renderer's default traversal (the BVH).
        let err_accel = Accel::BVH;
        let cam = scene.camera.to_pod(err_size, err_size);
        let hidden = ();
        let ref_spp: u32 = std::env::var("KDRAY_REFERENCE_SPP").ok().and_then(|v| v.parse().ok()).unwrap_or(if software { 256 } else { 8192 });
        // The reference: `KDRAY_REFERENCE_DIR/reference-SCENE.pfm` if there is one (with its own
        // error in `reference-SCENE.err`, e.g. from scripts/mitsuba_path.py --reference), else
        // our path tracer's, as two independent halves whose difference gives the reference's
        // own error (half of theirs). The table subtracts it in quadrature ("noise-corrected").
        let given = std::env::var("KDRAY_REFERENCE_DIR").ok().map(PathBuf::from).map(|d| (d.join(format!("reference-{}.pfm", scene.name)), d.join(format!("reference-{}.err", scene.name))));
        let (reference, ref_err, ref_what) = match given.filter(|(p, _)| p.exists()) {
            Some((p, e)) => {
                let (w, h, px) = kdray::image_out::read_pfm(&p)?;
                anyhow::ensure!(w == err_size && h == err_size, "{} is {w}x{h}, not {err_size}²", p.display());
                let mut r = RenderOutput::new(w, h);
                for (d, s) in r.radiance.iter_mut().zip(px) {
                    *d = [s[0], s[1], s[2], 1.0];
                }
                let err: f64 = std::fs::read_to_string(&e).ok().and_then(|s| s.trim().parse().ok()).unwrap_or(0.0);
                (r, err, format!("{} (given)", p.display()))
            }
            None => {
                let start = Instant::now();
                let half_a = path::render(&t, err_accel, &cam, &PathOptions::path(0x5EED, 64, ref_spp / 2), &hidden)?;
                let half_b = path::render(&t, err_accel, &cam, &PathOptions::path(0xFACADE, 64, ref_spp / 2), &hidden)?;
                let ref_secs = start.elapsed().as_secs_f64();
                let mut reference = half_a.clone();
                for (r, b) in reference.radiance.iter_mut().zip(&half_b.radiance) {
                    for c in 0..3 {
                        r[c] = 0.5 * (r[c] + b[c]);
                    }
                }
                let ref_path = o.out.join(format!("reference-{}.pfm", scene.name));
                write_pfm(&reference, &ref_path)?;
                files.push(ref_path);
                let err = error_of(&half_a, &half_b).0 / 2.0;
                (reference, err, format!("our path tracer, {ref_spp} spp ({ref_secs:.1} s)"))
            }
        };
        ref_notes.push(format!("{}: reference {ref_what}, its own error {:.3} %", scene.name, ref_err * 100.0));
        let corrected = |e: f64| (e * e - ref_err * ref_err).max(0.0).sqrt();
        let _ = kdray::scene::mitsuba::export(scene, &o.out.join(format!("mitsuba-{}", scene.name)), err_size, err_size, 65);
        let mut series: Vec<Series> = Vec::new();
        let pass_counts: Vec<u32> = if software { vec![1, 4] } else { vec![1, 4, 16, 64, 256] };
        // The baseline reads the photon map at the first diffuse point (direct visualisation).
        let d = PhotonOptions { photons, eye_samples: 4, final_gather: FinalGather::Off, ..Default::default() };
        let variants: Vec<(String, PhotonOptions)> = vec![
            (format!("ppm direct visualisation, 1 eye sample/pass"), PhotonOptions { eye_samples: 1, ..d.clone() }),
            (format!("ppm direct visualisation, 4 eye samples/pass"), d.clone()),
            (format!("ppm direct visualisation, 16 eye samples/pass"), PhotonOptions { eye_samples: 16, ..d.clone() }),
            (format!("ppm direct visualisation, {}k photons, 16 eye samples/pass", photons / 4096), PhotonOptions { photons: photons / 4, eye_samples: 16, ..d.clone() }),
            ("ppm fixed radius (4 eye)".into(), PhotonOptions { alpha: 1.0, ..d.clone() }),
            ("ppm kd index (4 eye)".into(), PhotonOptions { index: IndexKind::Kd, ..d.clone() }),
            ("ppm independent photons (4 eye)".into(), PhotonOptions { spread: 0.0, ..d.clone() }),
            ("ppm direct from photons (4 eye)".into(), PhotonOptions { photon_direct: true, ..d.clone() }),
            ("ppm final gather, 4 eye samples/pass".into(), PhotonOptions { final_gather: FinalGather::All, ..d.clone() }),
            ("ppm final gather, 16 eye samples/pass".into(), PhotonOptions { final_gather: FinalGather::All, eye_samples: 16, ..d.clone() }),
            ("ppm final gather near edges, 4 eye samples/pass".into(), PhotonOptions { final_gather: FinalGather::Edges, ..d.clone() }),
            ("ppm final gather near edges, 16 eye samples/pass".into(), PhotonOptions { final_gather: FinalGather::Edges, eye_samples: 16, ..d.clone() }),
            (
                "ppm final gather near edges, 4 eye samples/pass, independent numbers".into(),
                PhotonOptions { final_gather: FinalGather::Edges, sampler: SamplerKind::Independent, photon_sampler: SamplerKind::Independent, ..d.clone() },
            ),
        ];
        // KDRAY_PHOTONS_VARIANTS="a;b": only the variants whose names contain one of them.
        let only: Option<Vec<String>> = std::env::var("KDRAY_PHOTONS_VARIANTS").ok().map(|v| v.split(';').map(String::from).collect());
        let variants: Vec<_> = variants.into_iter().filter(|(n, _)| only.as_ref().is_none_or(|o| o.iter().any(|w| n.contains(w.as_str())))).collect();
        for (name, v) in variants {
            let mut pts = Vec::new();
            for &passes in &pass_counts {
                let start = Instant::now();
                let mut map = PhotonMap::new(&t, err_accel, Some(tree), &scene, PhotonOptions { passes, ..v.clone() })?;
                let (img, _) = pm::render(&mut map, &cam, &hidden)?;
                let secs = start.elapsed().as_secs_f64();
                let (e, m) = error_of(&img, &reference);
                pts.push((secs, e * 100.0));
                errors.push(vec![scene.name.clone(), name.clone(), passes.to_string(), map.o.photons.to_string(), format!("{secs:.3}"), format!("{:.3}", e * 100.0), format!("{:.3}", corrected(e) * 100.0), format!("{m:.3e}"), ref_spp.to_string()]);
            }
            series.push(Series { name, points: pts, dashed: false });
        }
        let spps: Vec<u32> = if software { vec![4, 16] } else { vec![16, 64, 256, 1024] };
        for (name, sampler) in [("path tracer", SamplerKind::Sobol), ("path tracer, independent numbers", SamplerKind::Independent)] {
            let mut pts = Vec::new();
            for &spp in &spps {
                let start = Instant::now();
                let img = path::render(&t, err_accel, &cam, &PathOptions { sampler, ..PathOptions::path(0xA11CE, 64, spp) }, &hidden)?;
                let secs = start.elapsed().as_secs_f64();
                let (e, m) = error_of(&img, &reference);
                pts.push((secs, e * 100.0));
                errors.push(vec![scene.name.clone(), name.into(), spp.to_string(), "–".into(), format!("{secs:.3}"), format!("{:.3}", e * 100.0), format!("{:.3}", corrected(e) * 100.0), format!("{m:.3e}"), ref_spp.to_string()]);
            }
            series.push(Series { name: format!("{name} (NEE)"), points: pts, dashed: true });
        }
        let plot_path = o.out.join(format!("photons-error-{}-{}.png", scene.name, dev_name(o)));
        let chart = LineChart {
            title: format!("{}: error vs time, {err_size}² ({})", scene.name, short_device_name(o)),
            x_label: "seconds (whole render)".into(),
            y_label: "relative RMSE % (clamped at 1)".into(),
            x_log: true,
            y_log: true,
            series,
        };
        match line_chart(&plot_path, &chart) {
            Ok(()) => files.push(plot_path),
            Err(e) => eprintln!("warning: no plot {}: {e:#}", plot_path.display()),
        }
        o.progress.inc(1);
    }
    let name = format!("photons-{}", dev_name(o));
    write_cells(&o.out, &name, "Photon mapping: tracing, index, gather", &device_line(o.gpu), "", &speed_header, &speed)?;
    files.extend([o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))]);
    let name = format!("photons-error-{}", dev_name(o));
    let summary = format!(
        "Error: RMSE of the displayed images (clamped at 1) over the reference's mean; noise-corrected: with the reference's own error \
         (from its two independent halves) subtracted in quadrature. Seconds: whole renders, every pass and transfer, {err_size}².\n\n{}\n\n",
        ref_notes.iter().map(|n| format!("* {n}")).collect::<Vec<_>>().join("\n")
    );
    write_cells(&o.out, &name, "Photon mapping: error against a path-traced reference vs time", &device_line(o.gpu), &summary, &err_header, &errors)?;
    files.extend([o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))]);
    Ok(files)
}

/// Error-vs-time plots (one per scene) from a `photons-error-*.csv` table, with the rows of
/// `scripts/mitsuba_path.py`'s `mitsuba-error.csv` added as dashed lines when given (for runs
/// on machines without a plot font). Returns the files written.
pub fn plot_error_table(table: &std::path::Path, mitsuba: Option<&std::path::Path>, out: &std::path::Path, device: &str) -> Result<Vec<PathBuf>> {
    let read = |p: &std::path::Path| -> Result<Vec<std::collections::HashMap<String, String>>> {
        let mut r = csv_rows(&std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?);
        anyhow::ensure!(!r.is_empty(), "{}: no header", p.display());
        let header = r.remove(0);
        Ok(r.into_iter().map(|row| header.iter().cloned().zip(row).collect()).collect())
    };
    let rows = read(table)?;
    let extra = match mitsuba {
        Some(m) => read(m)?,
        None => Vec::new(),
    };
    let mut scenes: Vec<String> = rows.iter().map(|r| r["scene"].clone()).collect();
    scenes.dedup();
    let mut files = Vec::new();
    for scene in scenes {
        let mut series: Vec<Series> = Vec::new();
        for r in rows.iter().filter(|r| r["scene"] == scene) {
            let name = if r["method"].starts_with("path tracer") { format!("kdray {} (NEE)", r["method"]) } else { r["method"].clone() };
            let pt = (r["seconds"].parse::<f64>().unwrap_or(f64::NAN), r["noise-corrected %"].parse::<f64>().unwrap_or(f64::NAN));
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(pt),
                None => series.push(Series { dashed: name.contains("path tracer"), name, points: vec![pt] }),
            }
        }
        let m: Vec<(f64, f64)> = extra
            .iter()
            .filter(|r| r["scene"] == scene)
            .map(|r| (r["seconds"].parse().unwrap_or(f64::NAN), r["rel RMSE %"].parse().unwrap_or(f64::NAN)))
            .collect();
        if !m.is_empty() {
            series.push(Series { name: "Mitsuba 3 path tracer (cuda_ad_rgb)".into(), points: m, dashed: true });
        }
        let path = out.join(format!("photons-error-{scene}.png"));
        line_chart(
            &path,
            &LineChart {
                title: format!("{scene}: error vs time, 512² ({device})"),
                x_label: "seconds (whole render)".into(),
                y_label: "relative RMSE % (clamped at 1), reference noise removed".into(),
                x_log: true,
                y_log: true,
                series,
            },
        )?;
        files.push(path);
    }
    Ok(files)
}

/// Rows of a CSV file as written by `write_cells` (fields quoted with "" when needed).
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for line in text.lines().filter(|l| !l.is_empty()) {
        let mut row = Vec::new();
        let mut cell = String::new();
        let mut quoted = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '"' if quoted && chars.peek() == Some(&'"') => {
                    cell.push('"');
                    chars.next();
                }
                '"' => quoted = !quoted,
                ',' if !quoted => row.push(std::mem::take(&mut cell)),
                c => cell.push(c),
            }
        }
        row.push(cell);
        rows.push(row);
    }
    rows
}
