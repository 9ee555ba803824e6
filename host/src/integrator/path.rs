//! Eye paths: the direct-lighting renderer, the path tracer, and the photon mapper's eye pass
//! are one schedule (`shade::path_step` decides per hit).
//!
//! Per batch of pixels and per sample: camera rays (through the pixel centre, or jittered);
//! per bounce a closest-hit query, a path step (specular bounce, or shade with one shadow ray
//! and continue / end / become a gather point), a shadow-ray any-hit query (only with lights)
//! and accumulation; then the film adds the sample (the photon mapper's gather does that
//! instead). Only what the scene needs runs: no bounces without specular surfaces or diffuse
//! bounces, no shadow queries without lights. Batches alternate between two sets of buffers,
//! so the GPU renders one while the host reads the last.
use super::{Progress, RenderOutput, SamplerKind};
use crate::accel::Accel;
use crate::kernels::{Accumulate, CameraRays, ContinuePaths, Film, PathStep, TracePaths};
use crate::runtime::{cast, Buffer, Commands, Kernel, Pending, Runtime};
use crate::tracer::{LeafLists, Tracer};
use crate::error::{bail, Result};
use kdray_shared::query::{AnyHit, Closest};
use kdray_shared::rng::pcg_hash;
use kdray_shared::{camera, raster, Camera, Hit, PathState, Ray, RenderParams, ShadeTerms, RENDER_CONTINUE, RENDER_JITTER, RENDER_PRIMARY_GIVEN};

/// What the eye paths do.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct PathOptions {
    /// Random stream of the first sample (later samples' streams derive from it).
    pub seed: u32,
    /// The last bounce (specular or diffuse) a path may take.
    pub bounces: u32,
    /// Diffuse bounces a path continues through: 0 is direct lighting.
    pub diffuse_bounces: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Camera rays through random points of their pixels (else the centres).
    pub jitter: bool,
    /// Whole paths in one kernel where there is one (else a pass per bounce and query).
    pub fused: bool,
    /// Where the paths' numbers come from.
    pub sampler: SamplerKind,
    /// Primary hits by rasterisation (`Tracer::raster_passes`; the BVH or the kd-tree's full
    /// stack traces where the rasteriser's answer is not trusted): each sample group is one
    /// dispatch over the whole image, every pixel sampled at the same point of its area (the
    /// centre, or with `jitter` the group's `raster::group_offset`), and the paths continue
    /// from the hits. The native runtime has no rasteriser and traces those rays instead
    /// (the same image up to `raster`'s tie rule).
    pub raster: bool,
    /// Samples per pixel per unit of work (`render_on`): a device renders a unit into films of
    /// its own, which are then read back and added to the image. Fixed by the render, not by
    /// the devices, so the image is the same on any number of them. `UNIT_SAMPLES` by default.
    pub unit_samples: u32,
}

impl PathOptions {
    /// Direct lighting: one sample through each pixel centre, `bounces` specular bounces.
    pub fn direct(seed: u32, bounces: u32) -> Self {
        PathOptions { seed, bounces, diffuse_bounces: 0, spp: 1, jitter: false, fused: true, sampler: SamplerKind::Sobol, raster: false, unit_samples: UNIT_SAMPLES }
    }
    /// Path tracing with next-event estimation: `spp` jittered samples, paths up to `bounces`
    /// long.
    pub fn path(seed: u32, bounces: u32, spp: u32) -> Self {
        PathOptions { seed, bounces, diffuse_bounces: bounces, spp, jitter: true, fused: true, sampler: SamplerKind::Sobol, raster: false, unit_samples: UNIT_SAMPLES }
    }
}

/// The random stream of sample `s` (sample 0 uses `seed` itself).
pub fn sample_seed(seed: u32, s: u32) -> u32 {
    if s == 0 {
        seed
    } else {
        pcg_hash(seed ^ pcg_hash(s.wrapping_add(0x5851_F42D)))
    }
}

/// A film: what the paths of a batch of pixels leave behind over the sample groups.
pub struct FilmBuffers {
    /// Per path of a dispatch: the closest hit of its camera ray (bounce 0).
    pub primary_hits: Buffer<Hit>,
    /// Per pixel: the sum of its samples' radiance, and their number in the fourth component.
    pub radiance: Buffer<[f32; 4]>,
}

impl FilmBuffers {
    /// A film for dispatches of up to `paths` paths over `pixels` pixels.
    pub fn new(t: &Tracer, paths: usize, pixels: usize) -> Result<Self> {
        Ok(FilmBuffers { primary_hits: t.rt.alloc("primary hit", paths)?, radiance: t.rt.alloc("radiance", pixels)? })
    }
}

/// The renderer's buffers for batches of up to `size` paths: the paths' state from bounce to
/// bounce, and a film (`film`, unless made by `work`: then each batch brings its own).
pub struct FrameBuffers {
    /// Per path: its current ray (the camera ray, then each bounce's).
    pub rays: Buffer<Ray>,
    /// Per path: its state (throughput, radiance so far, `PATH_*` flags).
    pub paths: Buffer<PathState>,
    hits: Buffer<Hit>,
    shadow: Buffer<Ray>,
    terms: Buffer<ShadeTerms>,
    /// Stays 0 in scenes without lights (no shadow pass writes it).
    occluded: Buffer<u32>,
    lists: Option<LeafLists>,
    /// The film the passes of `eye_passes` and `passes` write.
    pub film: FilmBuffers,
}

impl FrameBuffers {
    /// Allocates them on `t`'s runtime for up to `size` paths (and a film of as many pixels),
    /// with the leaf lists that `accel`'s decomposed pipeline needs.
    pub fn new(t: &Tracer, accel: Accel, size: usize) -> Result<Self> {
        Self::with_film(t, accel, size, FilmBuffers::new(t, size, size)?)
    }

    /// The paths' buffers for up to `size` paths, with a film of one element: for schedules
    /// that give each batch a film of its own (`eye_passes_into`).
    pub fn work(t: &Tracer, accel: Accel, size: usize) -> Result<Self> {
        Self::with_film(t, accel, size, FilmBuffers::new(t, 1, 1)?)
    }

    fn with_film(t: &Tracer, accel: Accel, size: usize, film: FilmBuffers) -> Result<Self> {
        let rt = t.rt;
        Ok(FrameBuffers {
            rays: rt.alloc("ray", size)?,
            paths: rt.alloc("path", size)?,
            hits: rt.alloc("hit", size)?,
            shadow: rt.alloc("shadow ray", size)?,
            terms: rt.alloc("shade terms", size)?,
            occluded: rt.alloc("occluded", size)?,
            lists: t.leaf_lists(accel, size)?,
            film,
        })
    }
}

/// Parameters of sample group `sample` (one sample per pixel, the pixels' `sample`-th) of the
/// batch of pixels `first..first + count` (in the camera's ray order); `with_samples` makes it
/// several (then set `sample_base`).
pub fn params(t: &Tracer, cam: &Camera, o: &PathOptions, first: usize, count: usize, sample: u32) -> RenderParams {
    let bounces_needed = t.has_specular || o.diffuse_bounces > 0;
    RenderParams {
        count: count as u32,
        first: first as u32,
        seed: sample_seed(o.seed, sample),
        light_count: t.light_count,
        bounce: 0,
        max_bounces: if bounces_needed { o.bounces } else { 0 },
        diffuse_bounces: o.diffuse_bounces,
        flags: if o.jitter { RENDER_JITTER } else { 0 } | o.sampler.flags(),
        camera: *cam,
        sample,
        samples: 1,
        sample_base: sample,
        sequence: pcg_hash(o.seed ^ 0x5EC0_5EC0),
    }
}

/// `p` with `samples` samples per pixel in one dispatch.
pub fn with_samples(p: RenderParams, samples: u32) -> RenderParams {
    RenderParams { count: p.count * samples, samples, ..p }
}

/// Every pass of one sample group of one batch, in order, up to the paths' last bounce (the
/// caller adds the film or the gather). Bounce 0 writes its hits into `primary_hits`
/// (with `RENDER_PRIMARY_GIVEN` it reads them from there instead). With
/// `RENDER_CONTINUE` the paths resume from their gather points (`ContinuePaths`) instead of
/// leaving the camera, and `primary_hits` stays as it is. The film is `film`.
pub fn path_passes<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers, film: &'a FilmBuffers) -> Result<Vec<Box<dyn Kernel + 'a>>> {
    check_given(p)?;
    let n = p.count as usize;
    let resuming = p.flags & RENDER_CONTINUE != 0;
    let mut v: Vec<Box<dyn Kernel + 'a>> = if resuming {
        vec![Box::new(ContinuePaths { params: *p, rays: &fb.rays, paths: &fb.paths })]
    } else {
        vec![Box::new(CameraRays { params: *p, rays: &fb.rays, paths: &fb.paths })]
    };
    for bounce in 0..=p.max_bounces {
        let params = RenderParams { bounce, ..*p };
        let hits = if bounce == 0 && !resuming { &film.primary_hits } else { &fb.hits };
        if !(bounce == 0 && !resuming && p.flags & RENDER_PRIMARY_GIVEN != 0) {
            v.extend(t.query_passes::<Closest>(accel, n, &fb.rays, hits, fb.lists.as_ref())?);
        }
        v.push(Box::new(PathStep {
            params,
            rays: &fb.rays,
            tris: &t.tris,
            hits,
            materials: &t.materials,
            lights: &t.lights,
            paths: &fb.paths,
            shadow_rays: &fb.shadow,
            terms: &fb.terms,
        }));
        if t.light_count > 0 {
            v.extend(t.query_passes::<AnyHit>(accel, n, &fb.shadow, &fb.occluded, fb.lists.as_ref())?);
        }
        v.push(Box::new(Accumulate { params, terms: &fb.terms, occluded: &fb.occluded, paths: &fb.paths }));
    }
    Ok(v)
}

/// Given primary hits (`RENDER_PRIMARY_GIVEN`) are those of the camera's rays through pixel
/// centres of one batch from the first pixel, one sample each: anything else is an error.
fn check_given(p: &RenderParams) -> Result<()> {
    if p.flags & RENDER_PRIMARY_GIVEN != 0 && (p.first != 0 || p.samples != 1 || p.flags & RENDER_JITTER != 0) {
        bail!(InvalidInput: "given primary hits are for one sample through the pixel centres of a batch from pixel 0 (first {}, {} samples, jitter {})", p.first, p.samples, p.flags & RENDER_JITTER != 0);
    }
    Ok(())
}

/// The whole-path kernel for `p` (camera to end in one thread), when the module has one for
/// this way of finding hits on this runtime (`Tracer::whole_path_method`).
pub fn fused_pass<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers, film: &'a FilmBuffers) -> Option<TracePaths<'a>> {
    let method = t.whole_path_method(accel, TracePaths::PREFIX)?;
    TracePaths::new(method, *p, &t.scene_box, t.scene_binds(accel), &t.materials, &t.lights, &fb.rays, &fb.paths, &film.primary_hits)
}

/// The eye paths of `p` up to their ends, into `fb`'s film: the whole-path kernel if `fused`
/// and there is one, else `path_passes`.
pub fn eye_passes<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers, fused: bool) -> Result<Vec<Box<dyn Kernel + 'a>>> {
    eye_passes_into(t, accel, p, fb, &fb.film, fused)
}

/// `eye_passes` into the film `film`.
pub fn eye_passes_into<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers, film: &'a FilmBuffers, fused: bool) -> Result<Vec<Box<dyn Kernel + 'a>>> {
    check_given(p)?;
    if fused {
        if let Some(k) = fused_pass(t, accel, p, fb, film) {
            return Ok(vec![Box::new(k)]);
        }
    }
    path_passes(t, accel, p, fb, film)
}

/// `path_passes` and the film.
pub fn passes<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers) -> Result<Vec<Box<dyn Kernel + 'a>>> {
    let mut v = path_passes(t, accel, p, fb, &fb.film)?;
    v.push(Box::new(Film { params: *p, paths: &fb.paths, radiance: &fb.film.radiance }));
    Ok(v)
}

/// Puts a batch's results (in tracing order) where their pixels are, the film divided by its
/// sample count.
pub fn place(out: &mut RenderOutput, cam: &Camera, first: usize, hits: Vec<Hit>, film: Vec<[f32; 4]>) {
    for (k, (h, r)) in hits.into_iter().zip(film).enumerate() {
        let px = camera::pixel(cam, (first + k) as u32) as usize;
        out.hits[px] = h;
        let s = if r[3] > 0.0 { 1.0 / r[3] } else { 0.0 };
        out.radiance[px] = [r[0] * s, r[1] * s, r[2] * s, 1.0];
    }
}

/// What a path-traced render did.
#[derive(Clone, Debug, Default)]
pub struct PathStats {
    /// Samples per pixel in the image (fewer than asked when a failure interrupted it, or the
    /// caller through `Progress::cancelled`).
    pub samples: u32,
    /// Wall time of the render, in seconds.
    pub seconds: f64,
    /// Why the render stopped early: what failed, and how (`render_on`).
    pub interrupted: Option<String>,
    /// Each device that failed (its name and the error): its units were rendered by the
    /// others, or are missing (`interrupted`).
    pub failed: Vec<String>,
    /// Units of samples each device rendered (`render_on`'s order).
    pub per_device: Vec<u32>,
}

/// Samples per pixel per unit of work by default (`PathOptions::unit_samples`).
pub const UNIT_SAMPLES: u32 = 16;

/// Renders `cam`'s image: `o.spp` samples per pixel, as many per dispatch as the batch size
/// and the unit allow (fewer, larger dispatches). An error if anything fails
/// (`render_checkpointed` keeps what was done).
pub fn render(t: &Tracer, accel: Accel, cam: &Camera, o: &PathOptions, progress: &dyn Progress) -> Result<RenderOutput> {
    let (out, stats) = render_on(&[t], accel, cam, o, progress)?;
    match stats.interrupted {
        Some(why) => bail!(DeviceLost: "{why}"),
        None => Ok(out),
    }
}

/// `render`, keeping what was done: if the device fails after a unit of samples was read
/// back, the render returns the image of the units before (fewer samples per pixel), with the
/// error in `PathStats::interrupted`; a failure in the first unit is an error.
pub fn render_checkpointed(t: &Tracer, accel: Accel, cam: &Camera, o: &PathOptions, progress: &dyn Progress) -> Result<(RenderOutput, PathStats)> {
    render_on(&[t], accel, cam, o, progress)
}

/// Renders `cam`'s image on every tracer's runtime at once (one tracer per device, all made
/// over the same scene). The samples go in units of `PathOptions::unit_samples` per pixel
/// (`share`): a device takes the next unit when it is free and renders its samples, batch
/// by batch of pixels (each batch its own film, the paths' buffers shared), into its films
/// from zero, then reads them back; the films are summed exactly (`share::FilmSum`), so the image is the
/// same, bit for bit, on one device or several of one kind. A device that fails gives its
/// units to the others (`PathStats::failed`); with none left, the render returns the image of
/// the units delivered, with the error in `PathStats::interrupted` (none delivered: the
/// error). `progress` counts samples (a pixel's each).
pub fn render_on(ts: &[&Tracer], accel: Accel, cam: &Camera, o: &PathOptions, progress: &dyn Progress) -> Result<(RenderOutput, PathStats)> {
    let Some(&first) = ts.first() else { bail!(InvalidInput: "a render needs at least one device") };
    if o.spp == 0 {
        bail!(InvalidInput: "at least one sample per pixel is needed");
    }
    if o.unit_samples == 0 {
        bail!(InvalidInput: "a unit of work needs at least one sample per pixel");
    }
    for t in ts {
        t.check(accel)?;
        if o.raster {
            t.raster_method(accel)?;
        }
        if !t.holds_same(first) {
            bail!(InvalidInput: "the devices of a render need tracers over the same scene");
        }
    }
    let start = std::time::Instant::now();
    let n = (cam.width * cam.height) as usize;
    let mut devices: Vec<(&Tracer, PathBuffers)> = ts.iter().map(|&t| Ok((t, PathBuffers::new(t, accel, cam, o)?))).collect::<Result<_>>()?;
    let names: Vec<String> = ts.iter().map(|t| t.rt.name()).collect();
    progress.start(n as u64 * o.spp as u64);
    let mut shared = super::share::share(&mut devices, o.spp.div_ceil(o.unit_samples), super::share::Part::WHOLE, n, |(t, b), hand| path_worker(t, accel, cam, o, b, hand), |k| {
        progress.advance(k);
        progress.cancelled()
    })?;
    let samples = shared.stats.iter().map(|s| s.1).sum();
    let (failed, interrupted) = shared.failures(&names, || format!("the image holds {samples} of the {} samples per pixel", o.spp))?;
    if shared.stats.is_empty() {
        bail!(InvalidInput: "the render stopped before its first sample");
    }
    let mut out = RenderOutput::new(cam.width, cam.height);
    place(&mut out, cam, 0, shared.hits.unwrap_or_else(|| vec![Hit::NONE; n]), shared.sum.film());
    Ok((out, PathStats { samples, seconds: start.elapsed().as_secs_f64(), interrupted, failed, per_device: shared.per_device }))
}

/// One device's buffers of a path-traced render: the pixels in batches (each with its film),
/// the paths' buffers (shared by the batches), and the samples of a dispatch.
struct PathBuffers {
    batches: Vec<(usize, usize)>,
    per_dispatch: u32,
    work: FrameBuffers,
    films: Vec<FilmBuffers>,
    raster_visible: Option<Buffer<u32>>,
}

impl PathBuffers {
    fn new(t: &Tracer, accel: Accel, cam: &Camera, o: &PathOptions) -> Result<Self> {
        let rt = t.rt;
        let n = (cam.width * cam.height) as usize;
        // Rasterised primaries: one batch of the whole image, one sample per pixel a dispatch.
        let b = if o.raster { n } else { t.batch_size(accel, n) };
        if o.raster && (n as u64 * std::mem::size_of::<ShadeTerms>() as u64 > rt.max_binding() || n > t.batch_size(accel, n).max(1 << 22)) {
            bail!(TooLarge: "--primary raster renders the whole image in one batch: {} x {} pixels are too many for {}", cam.width, cam.height, rt.name());
        }
        let unit = o.unit_samples.min(o.spp);
        let per_dispatch = if o.raster { 1 } else { (t.batch_size(accel, b * unit as usize) / b).clamp(1, unit as usize) as u32 };
        let raster_visible = if o.raster { Some(rt.alloc::<u32>("visibility", t.raster_params(cam)?.row_words as usize * cam.height as usize)?) } else { None };
        let batches: Vec<(usize, usize)> = (0..n).step_by(b).map(|f| (f, b.min(n - f))).collect();
        let work = FrameBuffers::work(t, accel, b * per_dispatch as usize)?;
        let films = batches.iter().map(|&(_, c)| FilmBuffers::new(t, c * per_dispatch as usize, c)).collect::<Result<_>>()?;
        Ok(PathBuffers { batches, per_dispatch, work, films, raster_visible })
    }
}

/// One device's share of a path-traced render (`render_on`): takes units of samples and
/// renders them, a group of `per_dispatch` samples per pixel at a time, every batch in turn.
fn path_worker(t: &Tracer, accel: Accel, cam: &Camera, o: &PathOptions, b: &PathBuffers, hand: &mut super::share::Hand<'_, u32>) -> Result<()> {
    let rt = t.rt;
    let n = (cam.width * cam.height) as u64;
    while let Some(u) = hand.take() {
        let (first_sample, end) = (u * o.unit_samples, ((u + 1) * o.unit_samples).min(o.spp));
        let mut s0 = first_sample;
        while s0 < end && !(s0 > first_sample && hand.stopping()) {
            let s = b.per_dispatch.min(end - s0);
            let submitted = (|| -> Result<()> {
                let mut c = rt.begin();
                let mut recorded = 0;
                for (&(first, count), film) in b.batches.iter().zip(&b.films) {
                    if s0 == first_sample {
                        rt.clear(&mut c, film.radiance.raw())?;
                    }
                    let mut p = with_samples(params(t, cam, o, first, count, s0), s);
                    if let Some(visible) = &b.raster_visible {
                        // The group's camera: every pixel's centre moved to the group's point.
                        p.camera = raster::shifted(cam, if o.jitter { raster::group_offset(s0) } else { [0.5, 0.5] });
                        p.flags = (p.flags & !RENDER_JITTER) | RENDER_PRIMARY_GIVEN;
                        recorded += rt.dispatch_all(&mut c, t.raster_passes(accel, &t.raster_params(&p.camera)?, visible, &film.primary_hits)?)?;
                    }
                    recorded += rt.dispatch_all(&mut c, eye_passes_into(t, accel, &p, &b.work, film, o.fused)?)?;
                    rt.dispatch(&mut c, &Film { params: p, paths: &b.work.paths, radiance: &film.radiance })?;
                    if recorded >= DISPATCHES_PER_SUBMIT {
                        rt.submit(std::mem::replace(&mut c, rt.begin()))?;
                        recorded = 0;
                    }
                }
                rt.submit(c)
            })();
            submitted.map_err(|e| e.context(format!("samples {s0}..{} failed", s0 + s)))?;
            s0 += s;
            hand.advance(n * s as u64);
        }
        let film_refs: Vec<&FilmBuffers> = b.films.iter().collect();
        let (film, hits) = read_raw_films(t, &b.batches, &film_refs, u == 0).map_err(|e| e.context("reading back the image failed"))?;
        hand.deliver(super::share::Unit { index: u, film, hits, stats: s0 - first_sample });
        if hand.stopping() {
            return Ok(());
        }
    }
    Ok(())
}

/// Dispatches recorded into one submission (bounds the size of a command buffer).
const DISPATCHES_PER_SUBMIT: usize = 2048;

/// Records the read-backs of the films of `batches` (and, with `hits`, their primary hits),
/// to be waited for by `wait_film_reads`.
pub(crate) fn record_film_reads(t: &Tracer, batches: &[(usize, usize)], films: &[&FilmBuffers], hits: bool, c: &mut Commands) -> Result<(Vec<Pending>, Vec<Pending>)> {
    let mut radiance = Vec::new();
    let mut hit = Vec::new();
    for (&(_, count), f) in batches.iter().zip(films) {
        radiance.push(t.rt.read_back_of(c, &f.radiance, count)?);
        if hits {
            hit.push(t.rt.read_back_of(c, &f.primary_hits, count)?);
        }
    }
    Ok((radiance, hit))
}

/// The films (and hits) `record_film_reads` recorded, per pixel in ray order.
pub(crate) fn wait_film_reads(rt: &dyn Runtime, films: Vec<Pending>, hits: Vec<Pending>) -> Result<(Vec<[f32; 4]>, Option<Vec<Hit>>)> {
    let mut film = Vec::new();
    for p in films {
        film.extend(cast::<[f32; 4]>(rt.wait(p)?));
    }
    let hit = if hits.is_empty() {
        None
    } else {
        let mut v = Vec::new();
        for p in hits {
            v.extend(cast::<Hit>(rt.wait(p)?));
        }
        Some(v)
    };
    Ok((film, hit))
}

/// The films of `batches`, per pixel in ray order, and (with `hits`) their primary hits, read
/// back now.
pub fn read_raw_films(t: &Tracer, batches: &[(usize, usize)], films: &[&FilmBuffers], hits: bool) -> Result<(Vec<[f32; 4]>, Option<Vec<Hit>>)> {
    let mut c = t.rt.begin();
    let (radiance, hit) = record_film_reads(t, batches, films, hits, &mut c)?;
    t.rt.submit(c)?;
    wait_film_reads(t.rt, radiance, hit)
}
