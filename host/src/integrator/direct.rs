//! Direct lighting: a primary ray per pixel centre, followed through up to `bounces` mirror
//! reflections, then one shadow ray toward a point sampled on the lights and Lambert shading.
//!
//! Per batch of pixels: camera rays; per bounce a closest-hit query, a path step (reflect or
//! shade), a shadow-ray any-hit query (only with lights) and accumulation. Only what the scene
//! needs runs: no reflection bounces without mirrors, no shadow queries without lights. Batches
//! alternate between two sets of buffers, so the GPU renders one while the host reads the last.
use super::RenderOutput;
use crate::accel::Accel;
use crate::kernels::{Accumulate, CameraRays, PathStep};
use crate::runtime::{cast, Buffer, Kernel};
use crate::tracer::{LeafLists, Tracer};
use anyhow::Result;
use indicatif::ProgressBar;
use kdray_shared::query::{AnyHit, Closest};
use kdray_shared::{camera, Camera, Hit, PathState, Ray, RenderParams, ShadeTerms};

/// The renderer's buffers for batches of up to `size` pixels.
pub struct FrameBuffers {
    rays: Buffer<Ray>,
    paths: Buffer<PathState>,
    hits: Buffer<Hit>,
    primary_hits: Buffer<Hit>,
    shadow: Buffer<Ray>,
    terms: Buffer<ShadeTerms>,
    /// Stays 0 in scenes without lights (no shadow pass writes it).
    occluded: Buffer<u32>,
    radiance: Buffer<[f32; 4]>,
    lists: Option<LeafLists>,
}

impl FrameBuffers {
    pub fn new(t: &Tracer, accel: Accel, size: usize) -> Result<Self> {
        let rt = t.rt;
        Ok(FrameBuffers {
            rays: rt.alloc("ray", size)?,
            paths: rt.alloc("path", size)?,
            hits: rt.alloc("hit", size)?,
            primary_hits: rt.alloc("primary hit", size)?,
            shadow: rt.alloc("shadow ray", size)?,
            terms: rt.alloc("shade terms", size)?,
            occluded: rt.alloc("occluded", size)?,
            radiance: rt.alloc("radiance", size)?,
            lists: t.leaf_lists(accel, size)?,
        })
    }
}

/// Parameters of the batch of pixels `first..first + count` (in the camera's ray order).
pub fn params(t: &Tracer, cam: &Camera, seed: u32, bounces: u32, first: usize, count: usize) -> RenderParams {
    RenderParams {
        count: count as u32,
        first: first as u32,
        seed,
        light_count: t.light_count,
        bounce: 0,
        max_bounces: if t.has_mirror { bounces } else { 0 },
        camera: *cam,
        ..Default::default()
    }
}

/// Every pass of one batch, in order. Bounce 0 writes its hits into `primary_hits`.
pub fn passes<'a>(t: &'a Tracer, accel: Accel, p: &RenderParams, fb: &'a FrameBuffers) -> Result<Vec<Box<dyn Kernel + 'a>>> {
    let n = p.count as usize;
    let mut v: Vec<Box<dyn Kernel + 'a>> = vec![Box::new(CameraRays { params: *p, rays: &fb.rays, paths: &fb.paths })];
    for bounce in 0..=p.max_bounces {
        let params = RenderParams { bounce, ..*p };
        let hits = if bounce == 0 { &fb.primary_hits } else { &fb.hits };
        v.extend(t.query_passes::<Closest>(accel, n, &fb.rays, hits, fb.lists.as_ref())?);
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
        v.push(Box::new(Accumulate { params, terms: &fb.terms, occluded: &fb.occluded, paths: &fb.paths, radiance: &fb.radiance }));
    }
    Ok(v)
}

/// Renders `cam`'s image with light samples from random stream `seed`.
pub fn render(t: &Tracer, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &ProgressBar) -> Result<RenderOutput> {
    t.check(accel)?;
    let rt = t.rt;
    let n = (cam.width * cam.height) as usize;
    let b = t.batch_size(accel, n);
    let sets = if n > b { 2 } else { 1 };
    let fbs: Vec<FrameBuffers> = (0..sets).map(|_| FrameBuffers::new(t, accel, b)).collect::<Result<_>>()?;
    let mut out = RenderOutput { width: cam.width, height: cam.height, hits: vec![Hit::NONE; n], radiance: vec![[0.0; 4]; n] };
    progress.set_length(n as u64);
    // Results come in tracing order: put each where its pixel is.
    let mut place = |first: usize, hits: Vec<Hit>, radiance: Vec<[f32; 4]>| {
        for (k, (h, r)) in hits.into_iter().zip(radiance).enumerate() {
            let px = camera::pixel(cam, (first + k) as u32) as usize;
            out.hits[px] = h;
            out.radiance[px] = r;
        }
        progress.inc(b.min(n - first) as u64);
    };
    let mut pending = None;
    let mut first = 0;
    let mut batch = 0;
    while first < n {
        let count = b.min(n - first);
        let fb = &fbs[batch % sets];
        let p = params(t, cam, seed, bounces, first, count);
        let mut c = rt.begin();
        for k in passes(t, accel, &p, fb)? {
            rt.dispatch(&mut c, k.as_ref())?;
        }
        let h = rt.read_back_of(&mut c, &fb.primary_hits, count)?;
        let r = rt.read_back_of(&mut c, &fb.radiance, count)?;
        rt.submit(c)?;
        if let Some((f, h, r)) = pending.replace((first, h, r)) {
            place(f, cast(rt.wait(h)?), cast(rt.wait(r)?));
        }
        first += count;
        batch += 1;
    }
    if let Some((f, h, r)) = pending {
        place(f, cast(rt.wait(h)?), cast(rt.wait(r)?));
    }
    Ok(out)
}
