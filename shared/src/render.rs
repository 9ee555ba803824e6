//! The eye-path kernels as per-item functions (entry points in the shader crate, the same
//! functions natively): camera rays, one path step per bounce (`shade::path_step`: specular
//! bounce, or shade with one shadow ray and continue / end / become a gather point),
//! accumulation once the shadow ray's answer is known, and the film that sums the samples.
use crate::camera;
use crate::query::{Answer, AnyHit, Closest, Query};
use crate::trace::Method;
use crate::kernel::Store;
use crate::math::{cosine_direction, scale3};
use crate::parts::Parts;
use crate::pod::{
    Hit, ItemParams, Light, Material, PathState, RenderParams, ShadeTerms, Triangle, PATH_ACTIVE, PATH_DIFFUSE_SHIFT, PATH_GATHER,
    RENDER_CONTINUE, RENDER_JITTER, RENDER_LEVEL_SHIFT, RENDER_PRIMARY_GIVEN,
};
use crate::ray::Ray;
use crate::rng::Rng;
use crate::sampler::{self, Sampler, DIM_CAMERA};
use crate::shade;

/// Path `i` of the batch (sample i / pixels of pixel i % pixels): its primary ray and a fresh
/// path state.
#[inline(always)]
pub fn camera_rays<R: Store<Ray> + ?Sized, P: Store<PathState> + ?Sized>(i: u32, p: &RenderParams, rays: &mut R, paths: &mut P) {
    if i < p.count {
        let (ray, path) = camera_sample(i, p);
        rays.store(i as usize, ray);
        paths.store(i as usize, path);
    }
}

/// The primary ray and fresh path state of path `i` of the batch.
#[inline(always)]
pub fn camera_sample(i: u32, p: &RenderParams) -> (Ray, PathState) {
    let b = p.pixels();
    let pixel = camera::pixel(&p.camera, p.first + i % b);
    let stream = pixel.wrapping_add((i / b).wrapping_mul(p.camera.width * p.camera.height));
    let ray = if p.flags & RENDER_JITTER != 0 {
        let u = Sampler::new(p, stream).get2(DIM_CAMERA);
        camera::jittered_ray(&p.camera, pixel, u[0], u[1])
    } else {
        camera::primary_ray(&p.camera, pixel)
    };
    (ray, PathState::start(stream))
}

/// The final gather's level of the paths of `p`: 0 if they are not resumed (`RENDER_CONTINUE`
/// off), else at least 1 (`RENDER_LEVEL_SHIFT`).
#[inline(always)]
pub fn resume_level(p: &RenderParams) -> u32 {
    if p.flags & RENDER_CONTINUE == 0 {
        0
    } else {
        (p.flags >> RENDER_LEVEL_SHIFT).max(1)
    }
}

/// A path at a gather point `point` (`shade::gather_point`) continued by one cosine-weighted
/// diffuse bounce from it: the final gather. Its throughput (which holds albedo/π there) times
/// π, the cosine and the pdf cos/π cancelling; the radiance it has gathered is kept. A path
/// that did not end at a gather point stays ended. Its direction takes the path's sampler's
/// dimension `sampler::resume_dim` of the level (the bounces after it have dimensions of their
/// own, `sampler::dim(_, _, level)`).
#[inline(always)]
pub fn resume(p: &RenderParams, point: &Ray, path: &PathState) -> (Ray, PathState) {
    if path.flags & PATH_GATHER == 0 {
        return (shade::NO_RAY, PathState { flags: 0, ..*path });
    }
    let u = Sampler::new(p, path.pixel).get2(sampler::resume_dim(resume_level(p)));
    let n = point.dir;
    let d = cosine_direction(n, u[0], u[1]);
    let next = PathState {
        throughput: scale3(path.throughput, core::f32::consts::PI),
        flags: PATH_ACTIVE | (1 << PATH_DIFFUSE_SHIFT),
        radiance: path.radiance,
        pixel: path.pixel,
    };
    (Ray::new(shade::offset(point.origin, n), d, 0.0, f32::INFINITY), next)
}

/// Path `i` resumes from its gather point (`resume`), for the per-bounce schedule.
#[inline(always)]
pub fn continue_paths<R: Store<Ray> + ?Sized, P: Store<PathState> + ?Sized>(i: u32, p: &RenderParams, rays: &mut R, paths: &mut P) {
    if i < p.count {
        let k = i as usize;
        let (ray, path) = resume(p, &rays.load(k), &paths.load(k));
        rays.store(k, ray);
        paths.store(k, path);
    }
}

/// One bounce of path `i`: reflect at a mirror (updating `rays[i]` in place) or shade.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step<R, P, SR, ST>(
    i: u32,
    p: &RenderParams,
    rays: &mut R,
    tris: &Parts<Triangle>,
    hits: &[Hit],
    materials: &[Material],
    lights: &[Light],
    paths: &mut P,
    shadow_rays: &mut SR,
    terms: &mut ST,
) where
    R: Store<Ray> + ?Sized,
    P: Store<PathState> + ?Sized,
    SR: Store<Ray> + ?Sized,
    ST: Store<ShadeTerms> + ?Sized,
{
    if i < p.count {
        let k = i as usize;
        let mut ray = rays.load(k);
        let mut path = paths.load(k);
        let (shadow, t) = shade::path_step(p, p.bounce, &mut ray, &hits[k], &mut path, tris, materials, lights);
        rays.store(k, ray);
        paths.store(k, path);
        shadow_rays.store(k, shadow);
        terms.store(k, t);
    }
}

/// Adds path `i`'s shaded terms.
#[inline(always)]
pub fn accumulate<P: Store<PathState> + ?Sized>(i: u32, p: &RenderParams, terms: &[ShadeTerms], occluded: &[u32], paths: &mut P) {
    if i < p.count {
        let k = i as usize;
        let mut path = paths.load(k);
        shade::accumulate(&mut path, &terms[k], occluded[k] != 0);
        paths.store(k, path);
    }
}

/// The film: pixel `i` of the batch sums its samples' radiance; sample group 0 writes it, later
/// groups add theirs (the fourth component counts the samples; the host divides by it).
#[inline(always)]
pub fn film<O: Store<[f32; 4]> + ?Sized>(i: u32, p: &RenderParams, paths: &[PathState], radiance: &mut O) {
    let b = p.pixels();
    if i < b {
        let mut c = [0.0f32; 3];
        let mut s = 0;
        while s < p.samples() {
            let r = paths[(s * b + i) as usize].radiance;
            c = [c[0] + r[0], c[1] + r[1], c[2] + r[2]];
            s += 1;
        }
        film_add(i as usize, p.sample, c, p.samples() as f32, radiance);
    }
}

/// Writes (sample group 0) or adds `c`, the sum of `n` samples, to element `k` of the film.
#[inline(always)]
pub fn film_add<O: Store<[f32; 4]> + ?Sized>(k: usize, sample: u32, c: [f32; 3], n: f32, radiance: &mut O) {
    let v = if sample == 0 { [c[0], c[1], c[2], n] } else {
        let o = radiance.load(k);
        [o[0] + c[0], o[1] + c[1], o[2] + c[2], o[3] + n]
    };
    radiance.store(k, v);
}

/// Four numbers of the stream (seed, first + i): checks CPU/GPU RNG identity (and keeps a GPU
/// busy for warm-ups).
#[inline(always)]
pub fn rng_fill<O: Store<[u32; 4]> + ?Sized>(i: u32, p: &ItemParams, out: &mut O) {
    if i < p.count {
        let mut rng = Rng::new(p.seed, p.first + i);
        out.store(i as usize, [rng.next_u32(), rng.next_u32(), rng.next_u32(), rng.next_u32()]);
    }
}

/// Path `i` of the batch from the camera (or, with `RENDER_CONTINUE`, from its gather point by
/// `resume`, leaving `primary_hits` alone; where `GIVEN` and `RENDER_PRIMARY_GIVEN`, its first
/// hit read from `primary_hits[i]`: the rasterised primaries' kernels, so that the others
/// carry no trace of it) to its end in one item: `camera_rays`, then per
/// bounce (up to `p.max_bounces`) a closest-hit query by `M`, `shade::path_step`, the shadow
/// ray's any-hit query and `shade::accumulate` — the same paths as the schedule of separate
/// passes, without a dispatch per bounce. Leaves the path (and its gather point, if any, in
/// `rays[i]`) for the gather and the film; the primary hit goes to `primary_hits[i]`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn trace_path<M: Method, R, P, H, const GIVEN: bool>(
    i: u32,
    p: &RenderParams,
    accel: &M::Accel<'_>,
    tris: &Parts<Triangle>,
    materials: &[Material],
    lights: &[Light],
    rays: &mut R,
    paths: &mut P,
    primary_hits: &mut H,
) where
    R: Store<Ray> + ?Sized,
    P: Store<PathState> + ?Sized,
    H: Store<Hit> + ?Sized,
{
    if i >= p.count {
        return;
    }
    let k = i as usize;
    // The camera sample in registers: writing it to `rays`/`paths` and reading it back in the
    // same invocation read zeros on NVIDIA's driver 580 (lavapipe read the values written).
    let resuming = p.flags & RENDER_CONTINUE != 0;
    let (mut ray, mut path) = if resuming { resume(p, &rays.load(k), &paths.load(k)) } else { camera_sample(i, p) };
    let given = GIVEN && !resuming && p.flags & RENDER_PRIMARY_GIVEN != 0;
    let mut bounce = 0;
    while bounce <= p.max_bounces && path.is_active() {
        let hit = if bounce == 0 && given {
            primary_hits.load(k)
        } else {
            let mut q = Closest::new(&ray);
            M::find(accel, &ray, &mut q);
            q.answer()
        };
        if bounce == 0 && !resuming && !given {
            primary_hits.store(k, hit);
        }
        let (shadow, terms) = shade::path_step(p, bounce, &mut ray, &hit, &mut path, tris, materials, lights);
        let mut occluded = false;
        if shadow.is_valid() {
            let mut s = AnyHit::new(&shadow);
            M::find(accel, &shadow, &mut s);
            occluded = s.answer() != 0;
        }
        shade::accumulate(&mut path, &terms, occluded);
        bounce += 1;
    }
    rays.store(k, ray);
    paths.store(k, path);
}
