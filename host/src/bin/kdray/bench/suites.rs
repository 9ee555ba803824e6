//! The benchmark suites: each reproduces one table or figure of the papers this project comes
//! from, on whatever device it runs, and writes `<suite>-<gpu|cpu>.{csv,md}` and its plots.
use super::plot::{bar_chart, line_chart, BarChart, LineChart, Series};
use super::table::{markdown, write_cells, write_rows, Row};
use super::{answers, device_line, dump, mismatch, rays, Bed, RaySet};
use kdray::gpu::{median, Gpu};
use kdray::kdtree::{self, BuildOptions, KdTreeData};
use kdray::scene::{self, Scene};
use kdray::accel::Accel;
use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use kdray_shared::kdtree::Algorithm;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub const SUITES: &[&str] = &["horn", "bounces", "scaling", "breakdown", "build", "visits", "order", "traversals", "photons", "devices"];

/// What every suite needs.
pub struct Options<'g> {
    pub gpu: Option<&'g Gpu>,
    /// `--devices`: the runtimes of `bench devices` (empty without it).
    pub devices: Vec<&'g dyn kdray::runtime::Runtime>,
    /// Scenes instead of the suite's own list (`scaling` always measures `chairs:K`).
    pub scenes: Option<Vec<String>>,
    pub size: u32,
    pub reps: usize,
    pub build: BuildOptions,
    pub out: PathBuf,
    /// Also write every ray batch measured with its answers (see `dump`).
    pub dump_rays: Option<PathBuf>,
    /// horn: a peer tracer's command, run on the dumped rays (see `peer_rows`).
    pub peer: Option<String>,
    /// Largest K of `chairs:K` in `scaling`.
    pub max_chairs: u32,
    /// Only these methods' rows in `horn` (by `Accel::name`).
    pub methods: Option<Vec<String>>,
    /// `photons`: threads of the whole-path photon kernel (`PhotonOptions::photon_threads`).
    pub photon_threads: u32,
    pub progress: ProgressBar,
}

/// Scenes and their trees, built once per run.
#[derive(Default)]
pub struct Scenes {
    loaded: HashMap<String, (Scene, KdTreeData)>,
}

impl Scenes {
    pub fn get(&mut self, spec: &str, opts: &BuildOptions) -> Result<&(Scene, KdTreeData)> {
        if !self.loaded.contains_key(spec) {
            let s = scene::load(spec)?;
            let t = kdtree::try_build(&s.triangles, opts)?;
            self.loaded.insert(spec.to_string(), (s, t));
        }
        Ok(&self.loaded[spec])
    }
}

/// The Stanford bunny from the shared scenes folder (`KDRAY_SHARED_SCENES`, else
/// `../shared/scenes`), or `chairs:64` with a message when it is absent.
fn bunny_or_chairs() -> String {
    let dir = std::env::var("KDRAY_SHARED_SCENES").unwrap_or_else(|_| "../shared/scenes".into());
    let p = Path::new(&dir).join("stanford-bunny.obj");
    if p.exists() {
        p.display().to_string()
    } else {
        eprintln!("note: {} not present: chairs:64 instead of the Stanford bunny", p.display());
        "chairs:64".into()
    }
}

/// Horn et al.'s four scenes: Cornell box, Cornell box with a chair, conference room, bunny.
fn horn_scenes(o: &Options) -> Vec<String> {
    o.scenes.clone().unwrap_or_else(|| vec!["cornell".into(), "cornell-chair".into(), "conference".into(), bunny_or_chairs()])
}

/// Runs `suite` (or every suite for `all`); returns the files written.
pub fn run_suite(suite: &str, o: &Options) -> Result<Vec<PathBuf>> {
    let mut scenes = Scenes::default();
    // `all` runs `devices` only with --devices.
    let list: Vec<&str> = if suite == "all" { SUITES.iter().copied().filter(|&s| s != "devices" || !o.devices.is_empty()).collect() } else { vec![suite] };
    let mut files = Vec::new();
    for s in list {
        let start = std::time::Instant::now();
        let written = match s {
            "horn" => horn(o, &mut scenes)?,
            "bounces" => bounces(o, &mut scenes)?,
            "scaling" => scaling(o, &mut scenes)?,
            "breakdown" => breakdown(o, &mut scenes)?,
            "build" => build(o, &mut scenes)?,
            "visits" => visits(o, &mut scenes)?,
            "order" => order(o, &mut scenes)?,
            "traversals" => traversals(o, &mut scenes)?,
            "photons" => super::photons::photons(o, &mut scenes)?,
            "devices" => super::devices::devices(o, &mut scenes)?,
            _ => bail!("unknown bench suite '{s}' (known: {}, all)", SUITES.join(", ")),
        };
        println!("suite {s}: {:.1} s", start.elapsed().as_secs_f64());
        files.extend(written);
    }
    Ok(files)
}

/// The adapter's name (or the CPU) for plot titles.
fn short_device(o: &Options) -> String {
    match o.gpu {
        Some(g) => g.info.name.clone(),
        None => format!("CPU, {} threads", rayon::current_num_threads()),
    }
}

pub(super) fn short_device_name(o: &Options) -> String {
    short_device(o)
}

pub(super) fn dev_name(o: &Options) -> &'static str {
    dev(o)
}

fn dev(o: &Options) -> &'static str {
    if o.gpu.is_some() { "gpu" } else { "cpu" }
}

/// Writes the rows and summary of a suite; returns the two table files.
fn finish(o: &Options, suite: &str, title: &str, summary: &str, rows: &[Row]) -> Result<Vec<PathBuf>> {
    let name = format!("{suite}-{}", dev(o));
    write_rows(&o.out, &name, title, &device_line(o.gpu), summary, rows)?;
    Ok(vec![o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))])
}

/// Saves a plot next to the tables; a missing font costs the plot, not the run.
fn plot(o: &Options, files: &mut Vec<PathBuf>, name: &str, draw: impl FnOnce(&Path) -> Result<()>) {
    let path = o.out.join(format!("{name}-{}.png", dev(o)));
    match draw(&path) {
        Ok(()) => files.push(path),
        Err(e) => eprintln!("warning: no plot {}: {e:#}", path.display()),
    }
}

/// The primary rays (closest hit) and shadow rays (any hit) of a scene, dumped if asked.
fn primary_and_shadow(o: &Options, bed: &Bed) -> Result<(RaySet, RaySet)> {
    let (b, shadow, _) = rays::bounces(bed.scene, bed.tree, o.size, 0)?;
    let primary = bed.ray_set("primary", b.into_iter().next().unwrap_or_default(), true)?;
    let shadow = bed.ray_set("shadow", shadow, false)?;
    for set in [&primary, &shadow] {
        dump_set(o, bed, set)?;
    }
    Ok((primary, shadow))
}

/// Runs a peer tracer's command on the dumped rays in `dir` and adds a row (method
/// `peer:NAME`) for each of its result lines, `SCENE-RAYS: peer=NAME rays=N Mrays/s=X
/// same-answer=A/B` (`../shared/peers/mitsuba_same_rays.py` prints them) whose scene and ray type
/// were measured here: its speed, and as "vs reference" the fraction of rays whose answer
/// differs from the dumped one. Returns the peers' names. A command that fails, or prints no
/// such line, is an error.
fn peer_rows(cmd: &str, dir: &Path, rows: &mut Vec<Row>) -> Result<Vec<String>> {
    println!("peer: {cmd} {}", dir.display());
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("{cmd} \"$0\""))
        .arg(dir)
        .stderr(std::process::Stdio::inherit())
        .output()
        .with_context(|| format!("--peer: cannot run '{cmd}'"))?;
    if !out.status.success() {
        bail!("--peer '{cmd}' failed ({})", out.status);
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let mut names: Vec<String> = Vec::new();
    for line in text.lines() {
        let Some((label, rest)) = line.split_once(": peer=") else { continue };
        let field = |key: &str| rest.split_whitespace().find_map(|f| f.strip_prefix(key));
        let (Some(name), Some(rays), Some(mrays), Some(same)) = (rest.split_whitespace().next(), field("rays="), field("Mrays/s="), field("same-answer=")) else {
            continue;
        };
        let parsed = (rays.parse::<usize>(), mrays.parse::<f64>(), same.split_once('/').map(|(a, b)| (a.parse::<usize>(), b.parse::<usize>())));
        let (Ok(rays), Ok(mrays), Some((Ok(same), Ok(total)))) = parsed else {
            bail!("--peer: cannot read '{line}'");
        };
        let Some(ours) = rows.iter().find(|r| !r.method.starts_with("peer:") && dump::stem(&r.scene, &r.ray_type) == label) else {
            continue;
        };
        let row = Row {
            method: format!("peer:{name}"),
            rays,
            mrays_gpu: None,
            mrays_wall: mrays,
            nodes: f64::NAN,
            leaves: f64::NAN,
            tris: f64::NAN,
            restarts: f64::NAN,
            vs_stack: None,
            oracle_mismatch: f64::NAN,
            reference_mismatch: 1.0 - same as f64 / total.max(1) as f64,
            fallbacks: None,
            notes: format!("run by --peer on the dumped rays; {same}/{total} answers as the full stack's"),
            ..ours.clone()
        };
        if !names.iter().any(|n| n == name) {
            names.push(name.to_string());
        }
        rows.push(row);
    }
    if names.is_empty() {
        bail!("--peer '{cmd}' printed no result line for the scenes measured ('SCENE-RAYS: peer=NAME rays=N Mrays/s=X same-answer=A/B')");
    }
    Ok(names)
}

fn dump_set(o: &Options, bed: &Bed, set: &RaySet) -> Result<()> {
    let Some(dir) = &o.dump_rays else { return Ok(()) };
    let accel = Accel::kd(Algorithm::Stack);
    if set.closest {
        dump::write_batch(dir, bed.scene, &set.kind, &set.rays, Some(&bed.cpu.closest_hits(accel, &set.rays)?), None)
    } else {
        dump::write_batch(dir, bed.scene, &set.kind, &set.rays, None, Some(&bed.cpu.any_hits(accel, &set.rays)?))
    }
}

const HORN_ROWS: [(&str, Accel); 9] = [
    ("full stack (baseline)", Accel::kd(Algorithm::Stack)),
    ("kd-restart", Accel::kd(Algorithm::Restart)),
    ("+ packets", Accel::packet(Algorithm::Restart)),
    ("+ push-down", Accel::packet(Algorithm::PushDown)),
    ("+ short-stack (3)", Accel::packet(Algorithm::ShortStack(3))),
    ("push-down, single rays", Accel::kd(Algorithm::PushDown)),
    ("short-stack (3), single rays", Accel::kd(Algorithm::ShortStack(3))),
    ("compressed 8-wide BVH", Accel::BVH),
    ("compressed 8-wide BVH, packets", Accel::BVH_PACKETS),
];

/// Primary hits by rasterisation (Horn et al. §5), traced by this structure where needed:
/// a row of primary rays only (`Bed::measure_raster`; method `raster+NAME`).
const RASTER_ROW: (&str, Accel) = ("rasterised primaries, BVH where needed", Accel::BVH);

/// Horn et al. 2007, Table 1: Mrays/s of the cumulative variants for primary (PS) and shadow
/// (SS) rays on four scenes, and primary hits by rasterisation.
fn horn(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let specs = horn_scenes(o);
    let raster_name = format!("raster+{}", RASTER_ROW.1.name());
    let (horn_rows, raster): (Vec<(&str, Accel)>, bool) = match &o.methods {
        None => (HORN_ROWS.to_vec(), true),
        Some(m) => {
            let mut known: Vec<String> = HORN_ROWS.iter().map(|(_, a)| a.name()).collect();
            known.push(raster_name.clone());
            if let Some(bad) = m.iter().find(|x| !known.contains(x)) {
                bail!("--method {bad}: not a row of the horn suite (its methods: {})", known.join(", "));
            }
            (HORN_ROWS.iter().copied().filter(|(_, a)| m.contains(&a.name())).collect(), m.contains(&raster_name))
        }
    };
    o.progress.set_length((specs.len() * (horn_rows.len() * 2 + raster as usize)) as u64);
    let mut rows = Vec::new();
    let mut names = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        names.push(scene.name.clone());
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (primary, shadow) = primary_and_shadow(o, &bed)?;
        for set in [&primary, &shadow] {
            for (_, accel) in &horn_rows {
                rows.push(bed.measure(set, *accel)?);
                o.progress.inc(1);
            }
        }
        if raster {
            rows.push(bed.measure_raster(&primary, RASTER_ROW.1)?);
            o.progress.inc(1);
        }
    }
    let peers = match (&o.peer, &o.dump_rays) {
        (Some(cmd), Some(dir)) => peer_rows(cmd, dir, &mut rows)?,
        _ => Vec::new(),
    };
    let find = |scene: &str, kind: &str, m: &str| rows.iter().find(|r| r.scene == scene && r.ray_type == kind && r.method == m);
    let mut header = vec!["Mrays/s".to_string()];
    for n in &names {
        header.push(format!("{n} PS"));
        header.push(format!("{n} SS"));
    }
    let mut labelled: Vec<(&str, String)> = horn_rows.iter().map(|(label, accel)| (*label, accel.name())).collect();
    if raster {
        labelled.push((RASTER_ROW.0, raster_name.clone()));
    }
    let mut cells: Vec<Vec<String>> = labelled
        .iter()
        .map(|(label, method)| {
            let mut r = vec![format!("{label} (`{method}`)")];
            for n in &names {
                for kind in ["primary", "shadow"] {
                    r.push(find(n, kind, method).map(|x| format!("{:.1}", x.mrays())).unwrap_or_default());
                }
            }
            r
        })
        .collect();
    // Each peer, and the fastest kdray row over it (same rays, same machine, same run).
    for peer in &peers {
        let method = format!("peer:{peer}");
        let mut own = vec![format!("peer: {peer}, same rays")];
        let mut ratio = vec![format!("fastest kdray ÷ {peer}")];
        for n in &names {
            for kind in ["primary", "shadow"] {
                let theirs = find(n, kind, &method).map(|x| x.mrays());
                let ours = rows.iter().filter(|r| r.scene == *n && r.ray_type == kind && !r.method.starts_with("peer:")).map(|r| r.mrays()).fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
                own.push(theirs.map(|v| format!("{v:.1}")).unwrap_or_default());
                ratio.push(match (ours, theirs) {
                    (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
                    _ => String::new(),
                });
            }
        }
        cells.push(own);
        cells.push(ratio);
    }
    let summary = format!(
        "## Horn et al. 2007, Table 1 layout\n\nPS = primary rays (closest hit), SS = shadow rays (any hit), {}² pixels; Mrays/s from GPU time where available. \
         Horn's rows are cumulative: kd-restart, then packets of four, then push-down, then a short stack of 3.\n\n{}",
        o.size,
        markdown(&header, &cells)
    );
    let mut files = finish(o, "horn", "Horn et al. Table 1: kd-restart, packets, push-down, short-stack", &summary, &rows)?;
    plot(o, &mut files, "horn", |p| {
        let categories: Vec<String> = names.iter().flat_map(|n| [format!("{n} PS"), format!("{n} SS")]).collect();
        let series = labelled
            .iter()
            .map(|(label, method)| {
                let v = names.iter().flat_map(|n| ["primary", "shadow"].map(|k| find(n, k, method).map(|x| x.mrays()).unwrap_or(0.0))).collect();
                (label.to_string(), v)
            })
            .collect();
        bar_chart(p, &BarChart { title: format!("Mrays/s, {}² ({})", o.size, short_device(o)), y_label: "Mrays/s".into(), categories, series, stacked: false })
    });
    Ok(files)
}

/// Horn et al.'s Diagram 1: Mrays/s of the rays of the n-th mirror reflection, with and without
/// packets (coherence falls bounce after bounce).
fn bounces(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    const MAX: u32 = 4;
    let methods = [Accel::kd(Algorithm::ShortStack(3)), Accel::packet(Algorithm::ShortStack(3)), Accel::kd(Algorithm::Stack), Accel::packet(Algorithm::Stack)];
    let specs = o.scenes.clone().unwrap_or_else(|| vec!["cornell-mirrors".into()]);
    o.progress.set_length((specs.len() * (MAX as usize + 1) * methods.len()) as u64);
    let mut rows = Vec::new();
    let mut summary = String::from("## Rays of the n-th reflection\n\nBounce 0 = primary rays; bounce n = the reflected rays of the paths still bouncing after n mirror hits (closest hit).\n\n");
    let mut curves: Vec<Series> = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (sets, _, _) = rays::bounces(scene, tree, o.size, MAX)?;
        let mut header = vec!["bounce".to_string(), "rays".into(), "coherent packets".into()];
        header.extend(methods.iter().map(|m| format!("`{}` Mrays/s", m.name())));
        let mut cells = Vec::new();
        let mut points = vec![Vec::new(); methods.len()];
        for (n, r) in sets.into_iter().enumerate() {
            if r.is_empty() {
                break;
            }
            let set = bed.ray_set(format!("reflection {n}"), r, true)?;
            dump_set(o, &bed, &set)?;
            let coherent = kdray::analysis::coherent_packets(&set.rays) as f64 / set.rays.len().div_ceil(4) as f64;
            let mut line = vec![n.to_string(), set.rays.len().to_string(), format!("{:.1} %", 100.0 * coherent)];
            for (m, accel) in methods.iter().enumerate() {
                let row = bed.measure(&set, *accel)?;
                line.push(format!("{:.1}", row.mrays()));
                points[m].push((n as f64, row.mrays()));
                rows.push(row);
                o.progress.inc(1);
            }
            cells.push(line);
        }
        summary += &format!("### {}\n\n{}\n", scene.name, markdown(&header, &cells));
        for (m, accel) in methods.iter().enumerate() {
            curves.push(Series { name: format!("{} {}", scene.name, accel.name()), points: points[m].clone(), dashed: !accel.is_packet() });
        }
    }
    let mut files = finish(o, "bounces", "Reflection rays with and without packets (Horn et al., Diagram 1)", &summary, &rows)?;
    plot(o, &mut files, "bounces", |p| {
        line_chart(p, &LineChart { title: format!("Reflection rays, {}² ({})", o.size, short_device(o)), x_label: "bounce".into(), y_label: "Mrays/s".into(), x_log: false, y_log: false, series: curves })
    });
    Ok(files)
}

/// The photon-mapping paper's Fig. 7: primary-ray speed against scene size on `chairs:K`, with
/// c/log N and c/log² N through the first point; build time and memory per N.
fn scaling(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let methods = [Accel::kd(Algorithm::Stack), Accel::kd(Algorithm::ShortStack(3)), Accel::BVH];
    let ks: Vec<u32> = std::iter::successors(Some(1u32), |k| Some(k * 4)).take_while(|k| *k <= o.max_chairs).collect();
    o.progress.set_length((ks.len() * methods.len()) as u64);
    let mut rows = Vec::new();
    let mut cells = Vec::new();
    let mut points = vec![Vec::new(); methods.len()];
    for k in &ks {
        let spec = format!("chairs:{k}");
        let (scene, tree) = scenes.get(&spec, &o.build)?;
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (primary, _) = primary_and_shadow(o, &bed)?;
        let n = scene.triangles.len() as f64;
        let bvh_bytes = bed.bvh.nodes.len() * std::mem::size_of::<kdray_shared::bvh::BvhNode>() + bed.bvh.tris.len() * std::mem::size_of::<kdray_shared::Triangle>();
        let mut line = vec![
            k.to_string(),
            scene.triangles.len().to_string(),
            format!("{:.3}", tree.stats.build_seconds),
            format!("{:.1}", tree.stats.bytes as f64 / 1048576.0),
            format!("{:.3}", bed.bvh_seconds),
            format!("{:.1}", bvh_bytes as f64 / 1048576.0),
        ];
        for (m, accel) in methods.iter().enumerate() {
            let row = bed.measure(&primary, *accel)?;
            line.push(format!("{:.1}", row.mrays()));
            points[m].push((n, row.mrays()));
            rows.push(row);
            o.progress.inc(1);
        }
        cells.push(line);
    }
    // Fits through the first point of the short-stack curve: c / log N and c / log² N.
    let ss = &points[1];
    let mut series: Vec<Series> = methods.iter().zip(&points).map(|(a, p)| Series { name: a.name(), points: p.clone(), dashed: false }).collect();
    if let Some(&(n0, v0)) = ss.first() {
        let fit = |p: i32| ss.iter().map(|&(n, _)| (n, v0 * (n0.ln() / n.ln()).powi(p))).collect::<Vec<_>>();
        for (line, (n, _)) in cells.iter_mut().zip(ss) {
            line.push(format!("{:.1}", v0 * n0.ln() / n.ln()));
            line.push(format!("{:.1}", v0 * (n0.ln() / n.ln()).powi(2)));
        }
        series.push(Series { name: "c / log N".into(), points: fit(1), dashed: true });
        series.push(Series { name: "c / log² N".into(), points: fit(2), dashed: true });
    }
    let header: Vec<String> =
        ["K chairs", "triangles", "kd build s", "kd-tree MiB", "BVH build s", "BVH MiB", "`stack` Mrays/s", "`shortstack:3` Mrays/s", "`bvh` Mrays/s", "c / log N", "c / log² N"].map(String::from).to_vec();
    let summary = format!(
        "## Primary rays against scene size\n\n`chairs:K` (K chairs of 1 468 triangles and a floor), {}² primary rays: the kd-tree (full stack, short stack of 3) and the compressed wide BVH side by side; build times on the host (the BVH's includes its collapse to 8 wide and quantisation). The fitted curves pass through the first short-stack point.\n\n{}",
        o.size,
        markdown(&header, &cells)
    );
    let mut files = finish(o, "scaling", "Speed against scene size (chairs:K)", &summary, &rows)?;
    plot(o, &mut files, "scaling", |p| {
        line_chart(p, &LineChart { title: format!("Primary rays, {}² ({})", o.size, short_device(o)), x_label: "triangles".into(), y_label: "Mrays/s".into(), x_log: true, y_log: false, series })
    });
    Ok(files)
}

/// Where a kernel's time goes in the breakdown, by entry point.
fn stage(entry: &str) -> &'static str {
    if entry == "traverse_leaves" {
        "traverse"
    } else if entry.ends_with("_leaves") {
        "intersect"
    } else if entry.ends_with("_fallback") {
        "fallback"
    } else if entry.starts_with("closest_") || entry.starts_with("any_") {
        "trace"
    } else {
        "shade"
    }
}

/// Times every pass of a whole `direct` frame (which must fit one batch): the kernels' entry
/// points in order and their timings.
fn time_frame(g: &kdray::Gpu, t: &kdray::Tracer, accel: Accel, cam: &kdray_shared::Camera, reps: usize) -> Result<(Vec<String>, kdray::gpu::Timing)> {
    use kdray::integrator::path;
    t.check(accel)?;
    let n = (cam.width * cam.height) as usize;
    if t.batch_size(accel, n) < n {
        anyhow::bail!("a {}x{} frame does not fit one GPU batch", cam.width, cam.height);
    }
    let fb = path::FrameBuffers::new(t, accel, n)?;
    let passes = path::passes(t, accel, &path::params(t, cam, &path::PathOptions::direct(1, 4), 0, n, 0), &fb)?;
    let timing = g.time_passes(&passes.iter().map(|k| k.as_ref()).collect::<Vec<_>>(), reps)?;
    Ok((passes.iter().map(|k| k.entry().into_owned()).collect(), timing))
}

const STAGES: [&str; 5] = ["traverse", "intersect", "fallback", "trace", "shade"];

/// Frolov & Ignatenko's split: share of a frame's GPU time in traverse / intersect / shade for
/// the decomposed pipeline, next to the monolithic short-stack kernels, with the image
/// difference between the two (0 expected), fallback rays and leaf-list memory.
fn breakdown(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let capacity = kdray::accel::DEFAULT_LEAF_CAPACITY;
    let decomposed = Accel::decomposed(capacity);
    let monolithic = Accel::kd(Algorithm::ShortStack(3));
    let mut specs = horn_scenes(o);
    if o.scenes.is_none() {
        specs.push("chairs:1024".into());
    }
    o.progress.set_length((specs.len() * 4) as u64);
    let mut rows = Vec::new();
    let mut cells = Vec::new();
    let mut shares: Vec<(String, [f64; 5])> = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (primary, shadow) = primary_and_shadow(o, &bed)?;
        let mut fallbacks = 0;
        for set in [&primary, &shadow] {
            for accel in [decomposed, monolithic] {
                let row = bed.measure(set, accel)?;
                fallbacks += row.fallbacks.unwrap_or(0);
                rows.push(row);
                o.progress.inc(1);
            }
        }
        let cam = scene.camera.to_pod(o.size, o.size);
        let pb = ();
        let a = kdray::integrator::direct::render(bed.tracer(), decomposed, &cam, 1, 4, &pb)?;
        let b = kdray::integrator::direct::render(bed.tracer(), monolithic, &cam, 1, 4, &pb)?;
        let differ = a.radiance.iter().zip(&b.radiance).zip(a.hits.iter().zip(&b.hits)).filter(|((x, y), (h, k))| x != y || h.prim != k.prim).count();
        let list_mib = super::leaf_list_mib(primary.rays.len(), capacity);
        let Some((g, gt)) = &bed.gpu else {
            cells.push(vec![scene.name.clone(), scene.triangles.len().to_string(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), "–".into(), fallbacks.to_string(), format!("{list_mib:.1}"), differ.to_string()]);
            continue;
        };
        for accel in [decomposed, monolithic] {
            let (kernels, t) = time_frame(g, gt, accel, &cam, o.reps)?;
            let mut ms = [0.0f64; 5];
            for (k, part) in kernels.iter().zip(&t.parts_ms) {
                let i = STAGES.iter().position(|s| *s == stage(k)).expect("known stage");
                ms[i] += median(part).unwrap_or(0.0);
            }
            let total: f64 = ms.iter().sum();
            let pct = |i: usize| if total > 0.0 { format!("{:.0} %", 100.0 * ms[i] / total) } else { "–".into() };
            cells.push(vec![
                scene.name.clone(),
                scene.triangles.len().to_string(),
                format!("`{}`", accel.name()),
                format!("{total:.2}"),
                pct(0),
                pct(1),
                pct(2),
                pct(3),
                pct(4),
                if accel == decomposed { fallbacks.to_string() } else { "–".into() },
                if accel == decomposed { format!("{list_mib:.1}") } else { "–".into() },
                differ.to_string(),
            ]);
            if accel == decomposed && total > 0.0 {
                shares.push((scene.name.clone(), ms.map(|x| 100.0 * x / total)));
            }
        }
    }
    let header: Vec<String> = ["scene", "triangles", "pipeline", "frame GPU ms", "traverse", "intersect", "fallback", "trace (monolithic)", "shade", "fallback rays", "leaf lists MiB", "pixels differing"].map(String::from).to_vec();
    let summary = format!(
        "## Time per stage of a frame\n\nOne {}² frame as `render` traces it (primary rays, mirror bounces where the scene has mirrors, one shadow ray per pixel), GPU time per pass from timestamp queries, summed per stage \
         (shade = camera rays, path step and accumulation). The decomposed pipeline lists up to {} leaves per ray; rays whose list overflows before their answer is settled are finished by the full-stack kernel (fallback). \
         Pixels differing: hit id or radiance different from the monolithic render (0 expected). Frolov & Ignatenko measured 15 % / 74 % / 11 % (traverse / intersect / shade) on their conference scene and 46 % / 45 % traverse / intersect on 1.5 M triangles.\n\n{}",
        o.size,
        capacity,
        markdown(&header, &cells)
    );
    let mut files = finish(o, "breakdown", "Decomposed pipeline: traverse / intersect / shade", &summary, &rows)?;
    if !shares.is_empty() {
        plot(o, &mut files, "breakdown", |p| {
            let series = [0usize, 1, 2, 4].iter().map(|&i| (STAGES[i].to_string(), shares.iter().map(|s| s.1[i]).collect())).collect();
            bar_chart(p, &BarChart { title: format!("Decomposed pipeline, share of frame time ({})", short_device(o)), y_label: "% of frame GPU time".into(), categories: shares.iter().map(|s| s.0.clone()).collect(), series, stacked: true })
        });
    }
    Ok(files)
}

/// kd-tree build statistics per scene.
fn build(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let mut specs = horn_scenes(o);
    if o.scenes.is_none() {
        specs.extend(["chairs:64".to_string(), "chairs:1024".to_string()]);
    }
    o.progress.set_length(specs.len() as u64);
    let header: Vec<String> = [
        "scene",
        "triangles",
        "build s",
        "s per M triangles",
        "exact sweep s per M",
        "nodes",
        "leaves",
        "empty leaves",
        "triangles/leaf",
        "references/triangle",
        "depth",
        "SAH cost",
        "SAH ÷ exact sweep's",
        "binned nodes (swept)",
        "MiB",
        "oracle mismatch",
        "BVH s per M",
        "BVH SAH cost",
        "kernels' BVH ms",
        "kernels' BVH SAH cost",
        "primary ray visits: BVH / kernels' BVH",
        "kernels' BVH frame ms: read back / in place (its update)",
    ]
    .map(String::from)
    .to_vec();
    let mut cells = Vec::new();
    let mut bars = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let s = &tree.stats;
        // The same options with the exact sweep at every node (Wald & Havran): what binning
        // the upper levels costs in tree quality, and saves in time.
        let exact = match o.build.binned_above {
            Some(_) => kdtree::try_build(&scene.triangles, &BuildOptions { binned_above: None, ..o.build.clone() })?.stats,
            None => s.clone(),
        };
        let t0 = std::time::Instant::now();
        let bvh = kdray::bvh::try_build(&scene.triangles)?;
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let per_million = |seconds: f64| seconds / (scene.triangles.len() as f64 / 1e6);
        // The tree answers like the oracle (a sample of primary rays, full stack, natively).
        let bed = Bed::new(scene, tree, None, 64, 1)?;
        let set = bed.ray_set("primary", rays::primary(scene, 64), true)?;
        let got = answers(&bed.cpu, Accel::kd(Algorithm::Stack), &set.sample, true)?;
        let per_m = per_million(s.build_seconds);
        // The kernels' linear BVH on the suite's device: the fastest of the repetitions (from
        // submitting its passes to their end) on one builder's kept buffers, as a scene rebuilt
        // every frame is, its SAH cost, and node visits plus triangle tests per primary ray
        // (64², natively) of both BVHs.
        let rt: &dyn kdray::runtime::Runtime = match o.gpu {
            Some(g) => g,
            None => &kdray::runtime::cpu::NATIVE,
        };
        let mut builder = kdray::lbvh::LbvhBuilder::new(rt);
        let mut lbvh = builder.build(&scene.triangles, kdray::lbvh::TREELET_ROUNDS)?;
        // On a GPU each timed build follows a second of tracing (the scene's primary rays, the
        // host's BVH): on the H100 a process ran at 1 980 MHz for its first 3-4 s, then at 345,
        // and builds alone (a tenth of the GPU's time or less; the rest is upload and
        // read-back) did not raise the clock again, builds up to four times slower
        // (docs/benchmarks/2026-12-07-h100-build-clocks/). A frame loop that renders keeps it up.
        // (Not on a CPU driver, which has no clocks to raise.)
        let warm = match o.gpu {
            Some(g) if !g.is_software() => {
                let t = kdray::Tracer::new(g, scene, Some(tree))?.with_bvh(&bed.bvh)?;
                let rays = rays::primary(scene, 512);
                let rt: &dyn kdray::runtime::Runtime = g;
                let rbuf = rt.upload("ray", &rays)?;
                let out = rt.alloc::<kdray_shared::Hit>("result", rays.len())?;
                Some((g, t, rbuf, out, rays.len()))
            }
            _ => None,
        };
        let warm_up = || -> Result<()> {
            if let Some((g, t, rbuf, out, n)) = &warm {
                let passes = t.query_passes::<kdray_shared::query::Closest>(Accel::BVH, *n, rbuf, out, None)?;
                g.warm_up(&passes.iter().map(|k| k.as_ref()).collect::<Vec<_>>(), std::time::Duration::from_secs(1))?;
            }
            Ok(())
        };
        // A frame of a scene rebuilt every frame, wall time to a BVH the tracer can use: the
        // build read back and a tracer made with it (`LbvhBuilder::build`, `Tracer::new`,
        // `with_bvh`), against the tracer's triangles written over and the BVH built where
        // they are (`Tracer::update`, `Tracer::build_bvh`). The fastest of the repetitions.
        let mut in_place = kdray::Tracer::new(rt, scene, None)?;
        let mut in_place_builder = kdray::lbvh::LbvhBuilder::new(rt);
        in_place.build_bvh(&mut in_place_builder, kdray::lbvh::TREELET_ROUNDS)?;
        let (mut frame_read, mut frame_in_place, mut frame_update) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for _ in 1..o.reps.max(3) {
            warm_up()?;
            let again = builder.build(&scene.triangles, kdray::lbvh::TREELET_ROUNDS)?;
            if again.build_s < lbvh.build_s {
                lbvh = again;
            }
            warm_up()?;
            let t0 = std::time::Instant::now();
            let read = builder.build(&scene.triangles, kdray::lbvh::TREELET_ROUNDS)?;
            let tracer = kdray::Tracer::new(rt, scene, None)?.with_bvh(&read.bvh)?;
            rt.finish()?;
            frame_read = frame_read.min(t0.elapsed().as_secs_f64());
            drop(tracer);
            warm_up()?;
            let t0 = std::time::Instant::now();
            in_place.update(scene)?;
            rt.finish()?;
            let updated = t0.elapsed().as_secs_f64();
            in_place.build_bvh(&mut in_place_builder, kdray::lbvh::TREELET_ROUNDS)?;
            rt.finish()?;
            if t0.elapsed().as_secs_f64() < frame_in_place {
                (frame_in_place, frame_update) = (t0.elapsed().as_secs_f64(), updated);
            }
        }
        let visits = |b: &kdray::bvh::BvhData| kdray::analysis::bvh_counts(b, &set.sample, true, false).iter().map(|c| (c.nodes + c.tris) as f64).sum::<f64>();
        cells.push(vec![
            scene.name.clone(),
            scene.triangles.len().to_string(),
            format!("{:.3}", s.build_seconds),
            format!("{per_m:.2}"),
            format!("{:.2}", per_million(exact.build_seconds)),
            s.nodes.to_string(),
            s.leaves.to_string(),
            s.empty_leaves.to_string(),
            format!("{:.2}", s.avg_leaf_size),
            format!("{:.2}", s.references as f64 / s.triangles.max(1) as f64),
            s.max_depth.to_string(),
            format!("{:.1}", s.sah_cost),
            format!("{:.3}", s.sah_cost / exact.sah_cost),
            format!("{} ({})", s.binned_nodes, s.binned_fallbacks),
            format!("{:.2}", s.bytes as f64 / 1048576.0),
            format!("{:.1e}", mismatch(&got, &set.oracle)),
            format!("{:.2}", per_million(bvh_seconds)),
            format!("{:.1}", bvh.sah_cost),
            format!("{:.2}", lbvh.build_s * 1e3),
            format!("{:.1}", lbvh.bvh.sah_cost),
            format!("{:.2}", visits(&bvh) / visits(&lbvh.bvh).max(1.0)),
            format!("{:.1} / {:.1} ({:.1})", frame_read * 1e3, frame_in_place * 1e3, frame_update * 1e3),
        ]);
        bars.push((scene.name.clone(), per_m, per_million(bvh_seconds)));
        o.progress.inc(1);
    }
    let name = format!("build-{}", dev(o));
    let how = match o.build.binned_above {
        Some(m) => format!("binned SAH ({} planes per axis) above {m} triangles, the exact sweep below", kdtree::BINS - 1),
        None => "the exact sweep everywhere".into(),
    };
    let kernels_on = o.gpu.map(|g| device_line(Some(g))).unwrap_or_else(|| device_line(None));
    write_cells(&o.out, &name, &format!("kd-tree build (SAH: {how}; and the BVH's: the host's binned SAH build, and the kernels' linear BVH on {kernels_on})"), &device_line(None), "", &header, &cells)?;
    let mut files = vec![o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))];
    plot(o, &mut files, "build", |p| {
        bar_chart(p, &BarChart { title: format!("build time per million triangles ({})", super::machine()), y_label: "s per 10^6 triangles".into(), categories: bars.iter().map(|b| b.0.clone()).collect(), series: vec![("kd-tree".into(), bars.iter().map(|b| b.1).collect()), ("BVH".into(), bars.iter().map(|b| b.2).collect())], stacked: false })
    });
    Ok(files)
}

/// Node visits per ray of every traversal relative to the full stack (Horn: kd-restart
/// +166 %, short-stack(1) +25 %, short-stack(3) +3 %). Counted natively: the counts are a
/// property of the algorithm, identical on every device.
fn visits(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let mut algs = vec![Algorithm::Stack, Algorithm::Restart, Algorithm::PushDown];
    algs.extend((1..=kdray_shared::kdtree::MAX_SHORT_STACK).map(Algorithm::ShortStack));
    let specs = horn_scenes(o);
    o.progress.set_length((specs.len() * 2) as u64);
    let header: Vec<String> = ["scene", "ray type", "traversal", "nodes/ray", "vs stack", "leaves/ray", "tris/ray", "restarts/ray", "oracle mismatch"].map(String::from).to_vec();
    let mut cells = Vec::new();
    let mut series = Vec::new();
    let mut summary_cells: Vec<Vec<String>> = algs.iter().map(|a| vec![format!("`{}`", Accel::kd(*a).name())]).collect();
    let mut names = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        names.push(scene.name.clone());
        let bed = Bed::new(scene, tree, None, o.size, 1)?;
        let (primary, shadow) = primary_and_shadow(o, &bed)?;
        for set in [&primary, &shadow] {
            let mut stack_nodes = 0.0;
            let mut curve = Vec::new();
            for (i, alg) in algs.iter().enumerate() {
                let accel = Accel::kd(*alg);
                let c = kdray::analysis::counts(&scene.triangles, tree, accel, &set.rays, set.closest)?;
                let n = set.rays.len().max(1) as f64;
                let sum = |f: fn(&kdray_shared::stats::Counters) -> u32| c.iter().map(|x| f(x) as f64).sum::<f64>() / n;
                let nodes = sum(|x| x.nodes);
                if *alg == Algorithm::Stack {
                    stack_nodes = nodes;
                }
                let vs = nodes / stack_nodes - 1.0;
                let sample = answers(&bed.cpu, accel, &set.sample, set.closest)?;
                cells.push(vec![
                    scene.name.clone(),
                    set.kind.clone(),
                    accel.name(),
                    format!("{nodes:.2}"),
                    format!("{:+.1} %", 100.0 * vs),
                    format!("{:.2}", sum(|x| x.leaves)),
                    format!("{:.2}", sum(|x| x.tris)),
                    format!("{:.3}", sum(|x| x.restarts)),
                    format!("{:.1e}", mismatch(&sample, &set.oracle)),
                ]);
                if set.closest {
                    summary_cells[i].push(format!("{:+.1} %", 100.0 * vs));
                }
                if let Algorithm::ShortStack(k) = alg {
                    curve.push((*k as f64, 100.0 * vs));
                }
            }
            if set.closest {
                series.push(Series { name: scene.name.clone(), points: curve, dashed: false });
            }
            o.progress.inc(1);
        }
    }
    let mut sh = vec!["primary rays".to_string()];
    sh.extend(names.iter().cloned());
    let name = format!("visits-{}", dev(o));
    let title = "Node visits relative to the full stack (Horn et al.: kd-restart +166 %, short-stack(1) +25 %, short-stack(3) +3 %)";
    let summary = format!("## Summary ({}² primary rays)\n\n{}\n", o.size, markdown(&sh, &summary_cells));
    write_cells(&o.out, &name, title, "native counting run (device independent)", &summary, &header, &cells)?;
    let mut files = vec![o.out.join(format!("{name}.csv")), o.out.join(format!("{name}.md"))];
    plot(o, &mut files, "visits", |p| {
        line_chart(p, &LineChart { title: "Short-stack size against extra node visits (primary rays)".into(), x_label: "short-stack entries".into(), y_label: "% more node visits than the full stack".into(), x_log: false, y_log: false, series })
    });
    Ok(files)
}

/// Ray order: the same rays in scanline order and in the renderer's tile order (8×8 tiles,
/// Morton order inside: `render --ray-order tiles`).
fn order(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let methods = [
        Accel::kd(Algorithm::Stack),
        Accel::kd(Algorithm::ShortStack(3)),
        Accel::packet(Algorithm::ShortStack(3)),
    ];
    let specs = horn_scenes(o);
    o.progress.set_length((specs.len() * 4 * methods.len()) as u64);
    let mut rows = Vec::new();
    let mut header = vec!["method".to_string()];
    let mut cells: Vec<Vec<String>> = methods.iter().map(|m| vec![format!("`{}`", m.name())]).collect();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (b, shadow, pixels) = rays::bounces(scene, tree, o.size, 0)?;
        let morton = rays::tiled_order(scene, o.size);
        let mut rank = vec![0u32; morton.len()];
        for (k, p) in morton.iter().enumerate() {
            rank[*p as usize] = k as u32;
        }
        let primary = b.into_iter().next().unwrap_or_default();
        let primary_m: Vec<_> = morton.iter().map(|&p| primary[p as usize]).collect();
        let mut by_pixel: Vec<usize> = (0..shadow.len()).collect();
        by_pixel.sort_by_key(|&k| rank[pixels[k] as usize]);
        let shadow_m: Vec<_> = by_pixel.iter().map(|&k| shadow[k]).collect();
        let sets = [
            bed.ray_set("primary", primary, true)?,
            bed.ray_set("primary in tile order", primary_m, true)?,
            bed.ray_set("shadow", shadow, false)?,
            bed.ray_set("shadow in tile order", shadow_m, false)?,
        ];
        for set in &sets {
            header.push(format!("{} {}", scene.name, set.kind));
            for (m, accel) in methods.iter().enumerate() {
                let row = bed.measure(set, *accel)?;
                cells[m].push(format!("{:.1}", row.mrays()));
                rows.push(row);
                o.progress.inc(1);
            }
        }
    }
    let summary = format!(
        "## Ray order (Mrays/s)\n\n{}² pixels. Tile order: the same rays in the order `render --ray-order tiles` traces them (8×8 tiles in rows, Morton order inside a tile: 2×2 quads, 8×4 half tiles).\n\n{}",
        o.size,
        markdown(&header, &cells)
    );
    finish(o, "order", "Ray order", &summary, &rows)
}

/// Every traversal with a GPU kernel, primary and shadow rays, per scene.
fn traversals(o: &Options, scenes: &mut Scenes) -> Result<Vec<PathBuf>> {
    let specs = horn_scenes(o);
    let accels: Vec<Accel> = Accel::all().into_iter().skip(1).collect();
    o.progress.set_length((specs.len() * accels.len() * 2) as u64);
    let mut rows = Vec::new();
    for spec in &specs {
        let (scene, tree) = scenes.get(spec, &o.build)?;
        let bed = Bed::new(scene, tree, o.gpu, o.size, o.reps)?;
        let (primary, shadow) = primary_and_shadow(o, &bed)?;
        for set in [&primary, &shadow] {
            let mut stack_nodes = None;
            for accel in &accels {
                let mut row = bed.measure(set, *accel)?;
                let base = *stack_nodes.get_or_insert(row.nodes);
                row.vs_stack = Some(row.nodes / base - 1.0);
                rows.push(row);
                o.progress.inc(1);
            }
        }
    }
    finish(o, "traversals", "Every kd traversal", "", &rows)
}
