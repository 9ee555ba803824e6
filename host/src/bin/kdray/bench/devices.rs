//! `bench devices`: one render and one batch of primary rays on the first device of
//! `--devices` alone, then on all of them (`kdray::integrator::share`): wall times, speed-up,
//! the units each device took, and the error of the shared result against the one-device
//! result (zero on devices of one kind: the units are summed in unit order). Writes
//! `devices.{csv,md}` and a speed-up plot.
use super::plot::{bar_chart, BarChart};
use super::{mismatch, rays, write_cells, Options, Scenes};
use kdray::accel::Accel;
use kdray::image_out::image_error;
use kdray::integrator::path::{self, PathOptions};
use kdray::integrator::photon::{self as pm, PhotonMap, PhotonOptions};
use kdray::integrator::share::closest_hits_on;
use kdray::integrator::RenderOutput;
use kdray::tracer::Tracer;
use anyhow::{bail, Result};
use std::path::PathBuf;
use std::time::Instant;

/// Rays per unit of a shared batch of primary rays.
const RAY_UNIT: usize = 1 << 18;

pub fn devices(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    if o.devices.is_empty() {
        bail!("bench devices needs --devices (e.g. --devices all, --devices 0,1 or --devices gpu:0,cpu)");
    }
    let names: Vec<String> = o.devices.iter().map(|d| d.name()).collect();
    let native = o.devices.iter().all(|d| d.is_native());
    let list = o.scenes.clone().unwrap_or_else(|| vec!["cornell".into()]);
    let header: Vec<String> = ["scene", "workload", "devices", "units per device", "seconds, first device", "seconds, all", "speed-up", "error vs first device"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let mut rows = Vec::new();
    let (mut labels, mut speedups) = (Vec::new(), Vec::new());
    let accel = Accel::BVH;
    for spec in &list {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let bvh = kdray::bvh::try_build(&scene.triangles)?;
        let tracers: Vec<Tracer> = o.devices.iter().map(|&rt| Tracer::new(rt, scene, Some(tree))?.with_bvh(&bvh)).collect::<kdray::Result<_>>()?;
        let all: Vec<&Tracer> = tracers.iter().collect();
        let one = &all[..1];
        let size = o.size;
        let cam = scene.camera.to_pod(size, size);
        let mut add = |workload: &str, per: &[u32], t1: f64, tn: f64, err: String| {
            println!("{}: {workload}: {t1:.3} s on one, {tn:.3} s on {} ({:.2}×), {err}", scene.name, all.len(), t1 / tn);
            labels.push(format!("{} {workload}", scene.name));
            speedups.push(t1 / tn);
            rows.push(vec![
                scene.name.clone(),
                workload.to_string(),
                names.join(" + "),
                per.iter().map(|u| u.to_string()).collect::<Vec<_>>().join(" / "),
                format!("{t1:.3}"),
                format!("{tn:.3}"),
                format!("{:.2}", t1 / tn),
                err,
            ]);
        };
        let rmse = |a: &RenderOutput, b: &RenderOutput| {
            let rgb = |r: &RenderOutput| r.radiance.iter().map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>();
            format!("{:.2e} rel. RMSE", image_error(&rgb(a), &rgb(b)).rel_rmse)
        };
        // Photon mapping: passes in units of four (the default's smallest).
        let po = PhotonOptions { photons: if native { 1 << 16 } else { 1 << 20 }, passes: if native { 16 } else { 128 }, unit_passes: 4, ..Default::default() };
        let photon = |ts: &[&Tracer]| -> Result<(RenderOutput, pm::PhotonStats)> {
            let mut maps: Vec<PhotonMap> = ts.iter().map(|&t| PhotonMap::new(t, accel, Some(tree), scene, po.clone())).collect::<kdray::Result<_>>()?;
            Ok(pm::render_on(&mut maps, &cam, &())?)
        };
        let (a, sa) = photon(one)?;
        let (b, sb) = photon(&all)?;
        add(&format!("photon mapping, {} passes × 2^{}", po.passes, po.photons.trailing_zeros()), &sb.per_device, sa.seconds, sb.seconds, rmse(&b, &a));
        o.progress.inc(1);
        // Path tracing: samples in units of 16 per pixel.
        let spp = if native { 32 } else { 256 };
        let pathed = |ts: &[&Tracer]| -> Result<(RenderOutput, path::PathStats)> { Ok(path::render_on(ts, accel, &cam, &PathOptions::path(1, 8, spp), &())?) };
        let (a, sa) = pathed(one)?;
        let (b, sb) = pathed(&all)?;
        add(&format!("path tracing, {spp} spp"), &sb.per_device, sa.seconds, sb.seconds, rmse(&b, &a));
        o.progress.inc(1);
        // Primary rays in units of 2^18, uploaded and read back with each unit.
        let primary = rays::primary(scene, size);
        let timed = |ts: &[&Tracer]| -> Result<(f64, Vec<kdray_shared::Hit>, Vec<u32>)> {
            let mut best = f64::INFINITY;
            let mut last = (Vec::new(), Vec::new());
            for _ in 0..o.reps.max(1) {
                let start = Instant::now();
                let (hits, per, failed) = closest_hits_on(ts, accel, &primary, RAY_UNIT)?;
                best = best.min(start.elapsed().as_secs_f64());
                if !failed.is_empty() {
                    bail!("a device failed: {}", failed.join("; "));
                }
                last = (hits, per);
            }
            Ok((best, last.0, last.1))
        };
        let (t1, h1, _) = timed(one)?;
        let (tn, hn, per) = timed(&all)?;
        let ids = |h: &[kdray_shared::Hit]| h.iter().map(|h| h.prim).collect::<Vec<_>>();
        add(&format!("primary rays {size}², units of 2^18 (with transfers)"), &per, t1, tn, format!("{:.2e} of hits differ", mismatch(&ids(&hn), &ids(&h1))));
        o.progress.inc(1);
    }
    let summary = format!(
        "First device: {}. All: {}. Work is handed out in units (photon passes in fours, path samples in sixteens, rays in 2^18s) to whichever device is free; \
         the units' films are summed exactly, so on devices of one kind the error is 0.\n\n",
        names[0],
        names.join(" + ")
    );
    write_cells(&o.out, "devices", "One render on several devices", &names.join(" + "), &summary, &header, &rows)?;
    let mut files = vec![o.out.join("devices.csv"), o.out.join("devices.md")];
    let png = o.out.join("devices.png");
    let chart = BarChart {
        title: format!("Speed-up on {} devices over the first alone", names.len()),
        y_label: "speed-up".into(),
        categories: labels,
        series: vec![(names.join(" + "), speedups)],
        stacked: false,
    };
    match bar_chart(&png, &chart) {
        Ok(()) => files.push(png),
        Err(e) => eprintln!("warning: no plot {}: {e:#}", png.display()),
    }
    Ok(files)
}
