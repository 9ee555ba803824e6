//! The direct-lighting renderer's kernels as per-item functions (entry points in the shader
//! crate, the same functions natively): camera rays, one path step per bounce (reflect at a
//! mirror, or shade with one shadow ray), and accumulation once the shadow ray's answer is known.
use crate::camera;
use crate::kernel::Store;
use crate::pod::{Hit, ItemParams, Light, Material, PathState, RenderParams, ShadeTerms, Triangle};
use crate::ray::Ray;
use crate::rng::Rng;
use crate::shade;

/// Path `i` of the batch: its primary ray and a fresh path state.
#[inline(always)]
pub fn camera_rays<R: Store<Ray> + ?Sized, P: Store<PathState> + ?Sized>(i: u32, p: &RenderParams, rays: &mut R, paths: &mut P) {
    if i < p.count {
        let pixel = camera::pixel(&p.camera, p.first + i);
        rays.store(i as usize, camera::primary_ray(&p.camera, pixel));
        paths.store(i as usize, PathState::start(pixel));
    }
}

/// One bounce of path `i`: reflect at a mirror (updating `rays[i]` in place) or shade.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step<R, P, SR, ST>(
    i: u32,
    p: &RenderParams,
    rays: &mut R,
    tris: &[Triangle],
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
        let (shadow, t) =
            shade::path_step(p.seed, p.bounce, p.max_bounces, &mut ray, &hits[k], &mut path, tris, materials, lights, p.light_count);
        rays.store(k, ray);
        paths.store(k, path);
        shadow_rays.store(k, shadow);
        terms.store(k, t);
    }
}

/// Adds path `i`'s shaded terms; writes the pixel's radiance so far.
#[inline(always)]
pub fn accumulate<P: Store<PathState> + ?Sized, O: Store<[f32; 4]> + ?Sized>(
    i: u32,
    p: &RenderParams,
    terms: &[ShadeTerms],
    occluded: &[u32],
    paths: &mut P,
    radiance: &mut O,
) {
    if i < p.count {
        let k = i as usize;
        let mut path = paths.load(k);
        shade::accumulate(&mut path, &terms[k], occluded[k] != 0);
        paths.store(k, path);
        radiance.store(k, [path.radiance[0], path.radiance[1], path.radiance[2], 1.0]);
    }
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
