//! The `photons` suite: photon mapping's speed and its error against a path-traced reference,
//! on the device the run is given.
//!
//! Table 1 (`photons-speed`): per scene, one pass of 2^20 photons — photon rays and bounces
//! (from a separate counting run), the trace's time and photon bounces per second, the photon
//! index's build time (hashed grid and kd leaves), and the eye pass and the gather at the
//! benchmark's resolution. Times are wall time per pass of several passes recorded into one
//! submission (launch overhead amortised, every clear and dispatch included).
//!
//! Table 2 (`photons-error`): per scene at 512² (or `--size` if smaller), the error of
//! progressive photon mapping (default, fixed radius, kd index, independent photons, direct
//! light from photons) and of the path tracer against a path-traced reference of many
//! samples, against wall time (whole renders: every pass and transfer). Error: RMSE of the
//! displayed images (clamped at 1) over the reference's mean (the measure), and relMSE.
//! The reference is written as `reference-SCENE.pfm` and the scene for Mitsuba as
//! `mitsuba-SCENE/` beside the tables.
use super::plot::{line_chart, LineChart, Series};
use super::suites::{dev_name, short_device_name};
use super::{device_line, write_cells, Options, Scenes};
use crate::accel::Accel;
use crate::image_out::{image_error, write_pfm};
use crate::integrator::path::{self, FrameBuffers, PathOptions};
use crate::integrator::photon::{self as pm, IndexKind, PhotonMap, PhotonOptions};
use crate::integrator::RenderOutput;
use crate::runtime::cpu::NATIVE;
use crate::runtime::{Commands, Runtime};
use crate::tracer::Tracer;
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::kdtree::Algorithm;
use std::path::PathBuf;
use std::time::Instant;

/// Photon mapping's scenes: the Cornell box, with a chair, the conference room, with a glass
/// sphere (caustics).
fn scenes(o: &Options) -> Vec<String> {
    o.scenes.clone().unwrap_or_else(|| ["cornell", "cornell-chair", "conference", "cornell-glass"].map(String::from).to_vec())
}

/// Milliseconds per copy of what `record` records: `copies` copies in one submission, the
/// median of 3 attempts after one warm-up attempt.
fn time_recorded(rt: &dyn Runtime, copies: u32, record: &dyn Fn(&mut Commands) -> Result<()>) -> Result<f64> {
    let mut ms = Vec::new();
    for attempt in 0..4 {
        let mut c = rt.begin();
        for _ in 0..copies {
            record(&mut c)?;
        }
        rt.finish()?;
        let start = Instant::now();
        rt.submit(c)?;
        rt.finish()?;
        if attempt > 0 {
            ms.push(start.elapsed().as_secs_f64() * 1e3 / copies as f64);
        }
    }
    Ok(crate::gpu::median(&ms).unwrap_or(f64::NAN))
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
    let accel = Accel::kd(Algorithm::ShortStack(3));
    let photons: u32 = if rt.is_native() { 1 << 18 } else { 1 << 20 };
    let copies = if rt.is_native() { 1 } else { 5 };
    o.progress.set_length(specs.len() as u64 * 2);
    let speed_header: Vec<String> = [
        "scene", "triangles", "photons", "rays traced", "bounces", "bounces/photon", "stored", "trace ms", "G bounces/s",
        "index grid ms", "index kd ms", "eye ms", "gather grid ms", "gather kd ms", "image",
    ]
    .map(String::from)
    .to_vec();
    let mut speed = Vec::new();
    let err_size = o.size.min(512);
    let err_header: Vec<String> = ["scene", "method", "passes or spp", "photons/pass", "seconds", "rel RMSE %", "relMSE", "reference spp"].map(String::from).to_vec();
    let mut errors = Vec::new();
    let mut files = Vec::new();
    for spec in &specs {
        let (scene, tree) = all.get(spec, &o.build)?;
        let t = Tracer::new(rt, scene, Some(tree))?;
        let area = scene.surface_area();
        // Speed: one pass of `photons` photons, both indices.
        let mut row = vec![scene.name.clone(), scene.triangles.len().to_string(), photons.to_string()];
        let base = PhotonOptions { photons, passes: 1, ..Default::default() };
        let mut grid = PhotonMap::new(&t, accel, Some(tree), area, base.clone())?;
        let (rays, bounces) = grid.count_bounces(0)?;
        let stored = grid.trace_and_index(0)?;
        let trace_ms = time_recorded(rt, copies, &|c| grid.record_trace(c, 0))?;
        let index_grid = time_recorded(rt, copies, &|c| grid.record_index(c, 0))?;
        let mut kd = PhotonMap::new(&t, accel, Some(tree), area, PhotonOptions { index: IndexKind::Kd, ..base.clone() })?;
        kd.trace_and_index(0)?;
        let index_kd = time_recorded(rt, copies, &|c| kd.record_index(c, 0))?;
        let cam = scene.camera.to_pod(o.size, o.size);
        let n = (o.size * o.size) as usize;
        let (eye_ms, gather_grid, gather_kd) = if t.batch_size(accel, n) >= n {
            let fb = FrameBuffers::new(&t, accel, n)?;
            let po = PathOptions { seed: 1, bounces: 16, diffuse_bounces: 0, spp: 1, jitter: true };
            let mut p = path::params(&t, &cam, &po, 0, n, 0);
            p.flags |= kdray_shared::RENDER_GATHER;
            let eye = time_recorded(rt, copies, &|c| {
                for k in path::path_passes(&t, accel, &p, &fb)? {
                    rt.dispatch(c, k.as_ref())?;
                }
                Ok(())
            })?;
            let g = time_recorded(rt, copies, &|c| rt.dispatch(c, &grid.gather(0, 0, n as u32, &fb)))?;
            let k = time_recorded(rt, copies, &|c| rt.dispatch(c, &kd.gather(0, 0, n as u32, &fb)))?;
            (format!("{eye:.3}"), format!("{g:.3}"), format!("{k:.3}"))
        } else {
            ("–".into(), "–".into(), "–".into())
        };
        row.extend([
            rays.to_string(),
            bounces.to_string(),
            format!("{:.2}", bounces as f64 / photons as f64),
            stored.to_string(),
            format!("{trace_ms:.3}"),
            format!("{:.2}", bounces as f64 / trace_ms / 1e6),
            format!("{index_grid:.3}"),
            format!("{index_kd:.3}"),
            eye_ms,
            gather_grid,
            gather_kd,
            format!("{}²", o.size),
        ]);
        speed.push(row);
        drop(kd);
        drop(grid);
        o.progress.inc(1);

        // Error against time at err_size².
        let cam = scene.camera.to_pod(err_size, err_size);
        let hidden = ProgressBar::hidden();
        let ref_spp: u32 = std::env::var("KDRAY_REFERENCE_SPP").ok().and_then(|v| v.parse().ok()).unwrap_or(if rt.is_native() { 256 } else { 8192 });
        let reference = path::render(&t, accel, &cam, &PathOptions::path(0x5EED, 64, ref_spp), &hidden)?;
        let ref_path = o.out.join(format!("reference-{}.pfm", scene.name));
        write_pfm(&reference, &ref_path)?;
        files.push(ref_path);
        let _ = crate::scene::mitsuba::export(scene, &o.out.join(format!("mitsuba-{}", scene.name)), err_size, err_size, 65);
        let mut series: Vec<Series> = Vec::new();
        let pass_counts: Vec<u32> = if rt.is_native() { vec![1, 4, 16] } else { vec![1, 4, 16, 64, 256] };
        let variants: Vec<(&str, PhotonOptions)> = vec![
            ("ppm", PhotonOptions { photons, ..Default::default() }),
            ("ppm fixed radius", PhotonOptions { photons, alpha: 1.0, ..Default::default() }),
            ("ppm kd index", PhotonOptions { photons, index: IndexKind::Kd, ..Default::default() }),
            ("ppm independent photons", PhotonOptions { photons, spread: 0.0, ..Default::default() }),
            ("ppm direct from photons", PhotonOptions { photons, photon_direct: true, ..Default::default() }),
            ("ppm 4 eye samples/pass", PhotonOptions { photons, eye_samples: 4, ..Default::default() }),
        ];
        for (name, v) in variants {
            let mut pts = Vec::new();
            for &passes in &pass_counts {
                let start = Instant::now();
                let mut map = PhotonMap::new(&t, accel, Some(tree), area, PhotonOptions { passes, ..v.clone() })?;
                let (img, _) = pm::render(&mut map, &cam, &hidden)?;
                let secs = start.elapsed().as_secs_f64();
                let (e, m) = error_of(&img, &reference);
                pts.push((secs, e * 100.0));
                errors.push(vec![scene.name.clone(), name.into(), passes.to_string(), photons.to_string(), format!("{secs:.3}"), format!("{:.3}", e * 100.0), format!("{m:.3e}"), ref_spp.to_string()]);
            }
            series.push(Series { name: name.into(), points: pts, dashed: false });
        }
        let spps: Vec<u32> = if rt.is_native() { vec![4, 16, 64] } else { vec![16, 64, 256, 1024] };
        let mut pts = Vec::new();
        for &spp in &spps {
            let start = Instant::now();
            let img = path::render(&t, accel, &cam, &PathOptions::path(0xA11CE, 64, spp), &hidden)?;
            let secs = start.elapsed().as_secs_f64();
            let (e, m) = error_of(&img, &reference);
            pts.push((secs, e * 100.0));
            errors.push(vec![scene.name.clone(), "path tracer".into(), spp.to_string(), "–".into(), format!("{secs:.3}"), format!("{:.3}", e * 100.0), format!("{m:.3e}"), ref_spp.to_string()]);
        }
        series.push(Series { name: "path tracer (NEE)".into(), points: pts, dashed: true });
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
    let name = format!("photons-speed-{}", dev_name(o));
    write_cells(&o.out, &name, "Photon mapping: tracing, index, gather", &device_line(o.gpu), "", &speed_header, &speed)?;
    files.extend([o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))]);
    let name = format!("photons-error-{}", dev_name(o));
    write_cells(&o.out, &name, "Photon mapping: error against a path-traced reference vs time", &device_line(o.gpu), "", &err_header, &errors)?;
    files.extend([o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))]);
    Ok(files)
}
