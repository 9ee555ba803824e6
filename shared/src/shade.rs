//! Direct lighting with one shadow ray per pixel, Lambertian surfaces and perfect mirrors.
//!
//! A pixel's path follows mirror reflections (up to `max_bounces`) until it meets a diffuse
//! surface, where `light_sample` turns the hit into a shadow ray toward one sampled light point
//! and the radiance that arrives if that ray is unoccluded; `accumulate` adds it once the
//! any-hit result is known. The split lets each query run as its own kernel.
use crate::math::{add3, cross3, dot3, length3, mul3, normalize3, scale3, sub3};
use crate::pod::{Hit, Light, Material, PathState, ShadeTerms, Triangle, LIGHT_POINT, MAT_MIRROR};
use crate::ray::Ray;
use crate::rng::Rng;

const INV_PI: f32 = core::f32::consts::FRAC_1_PI;
/// Shadow rays stop this fraction short of the light point so they never hit the light itself.
pub const SHADOW_END: f32 = 1.0 - 1.0 / 4096.0;

/// An interval that every query rejects: the "no shadow ray needed" marker.
pub const NO_RAY: Ray = Ray { origin: [0.0; 3], t_min: 1.0, dir: [0.0, 0.0, 1.0], t_max: 0.0 };

/// Offset along the normal that moves a hit point off its surface, relative to its magnitude
/// (a few dozen ulps: the barycentric point's rounding error is below γ(7)·|p|).
#[inline(always)]
fn offset_scale(p: [f32; 3]) -> f32 {
    let m = p[0].abs().max(p[1].abs()).max(p[2].abs());
    (1.0 + m) * (64.0 * f32::EPSILON)
}

/// The hit point (from barycentrics, not o + t·d) and the geometric normal facing the ray.
#[inline(always)]
fn surface_point(tri: &Triangle, hit: &Hit, ray: &Ray) -> ([f32; 3], [f32; 3]) {
    let b0 = 1.0 - hit.b1 - hit.b2;
    let p = add3(add3(scale3(tri.v0, b0), scale3(tri.v1, hit.b1)), scale3(tri.v2, hit.b2));
    let n = normalize3(cross3(sub3(tri.v1, tri.v0), sub3(tri.v2, tri.v0)));
    (p, if dot3(n, ray.dir) > 0.0 { scale3(n, -1.0) } else { n })
}

#[inline(always)]
fn pick_light(lights: &[Light], n: usize, u: f32) -> usize {
    let mut i = 0;
    while i + 1 < n && lights[i].cdf <= u {
        i += 1;
    }
    i
}

#[inline(always)]
pub fn light_sample(
    seed: u32,
    pixel: u32,
    ray: &Ray,
    hit: &Hit,
    tris: &[Triangle],
    materials: &[Material],
    lights: &[Light],
    light_count: u32,
) -> (Ray, ShadeTerms) {
    let mut terms = ShadeTerms::default();
    if !hit.is_hit() {
        return (NO_RAY, terms);
    }
    let tri = &tris[hit.prim as usize];
    let mat = &materials[tri.material as usize];
    terms.base = mat.emission;
    if light_count == 0 {
        return (NO_RAY, terms);
    }
    let (p, n) = surface_point(tri, hit, ray);
    let mut rng = Rng::new(seed, pixel);
    let li = pick_light(lights, light_count as usize, rng.next_f32());
    let light = &lights[li];
    let prev = if li == 0 { 0.0 } else { lights[li - 1].cdf };
    let p_select = light.cdf - prev;
    let u1 = rng.next_f32();
    let u2 = rng.next_f32();
    let (target, radiance_geom) = if light.kind == LIGHT_POINT {
        (light.p0, scale3(light.emission, 1.0 / p_select))
    } else {
        let s = crate::math::sqrt(u1);
        let q = add3(add3(light.p0, scale3(light.e1, 1.0 - s)), scale3(light.e2, u2 * s));
        let nl = normalize3(cross3(light.e1, light.e2));
        let w = normalize3(sub3(p, q));
        let cos_l = dot3(nl, w).abs();
        (q, scale3(light.emission, cos_l * light.area / p_select))
    };
    let origin = add3(p, scale3(n, offset_scale(p)));
    let to_light = sub3(target, origin);
    let dist = length3(to_light);
    let cos_s = dot3(n, to_light) / dist;
    if !(cos_s > 0.0) || !(dist > 0.0) {
        return (NO_RAY, terms);
    }
    let f = scale3(mat.diffuse, INV_PI * cos_s / (dist * dist));
    terms.direct = mul3(f, radiance_geom);
    (Ray::new(origin, to_light, 0.0, SHADOW_END), terms)
}

/// One step of a pixel's path at its `bounce`-th hit: a mirror (before the last bounce)
/// reflects `ray` in place and scales the throughput by its colour; anything else is shaded
/// (emission + one shadow ray) and ends the path. Returns the shadow ray (`NO_RAY` if none) and
/// the terms to `accumulate`, already weighted by the path's throughput. A path that ends
/// leaves `NO_RAY` in `ray`, so later bounces trace nothing for it. The light sample is drawn
/// from the random stream of the path's pixel.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step(
    seed: u32,
    bounce: u32,
    max_bounces: u32,
    ray: &mut Ray,
    hit: &Hit,
    path: &mut PathState,
    tris: &[Triangle],
    materials: &[Material],
    lights: &[Light],
    light_count: u32,
) -> (Ray, ShadeTerms) {
    let mut terms = ShadeTerms::default();
    if path.active == 0 {
        return (NO_RAY, terms);
    }
    if !hit.is_hit() {
        path.active = 0;
        *ray = NO_RAY;
        return (NO_RAY, terms);
    }
    let tri = &tris[hit.prim as usize];
    let mat = &materials[tri.material as usize];
    if mat.flags & MAT_MIRROR != 0 && bounce < max_bounces {
        terms.base = mul3(path.throughput, mat.emission);
        let (p, n) = surface_point(tri, hit, ray);
        let d = sub3(ray.dir, scale3(n, 2.0 * dot3(ray.dir, n)));
        *ray = Ray::new(add3(p, scale3(n, offset_scale(p))), d, 0.0, f32::INFINITY);
        path.throughput = mul3(path.throughput, mat.diffuse);
        return (NO_RAY, terms);
    }
    // Each bounce draws from its own random stream.
    let stream = seed ^ bounce.wrapping_mul(0x9E37_79B9);
    let (shadow, t) = light_sample(stream, path.pixel, ray, hit, tris, materials, lights, light_count);
    terms.base = mul3(path.throughput, t.base);
    terms.direct = mul3(path.throughput, t.direct);
    path.active = 0;
    *ray = NO_RAY;
    (shadow, terms)
}

/// Adds a step's radiance to its path: `base`, plus `direct` unless the shadow ray was blocked.
#[inline(always)]
pub fn accumulate(path: &mut PathState, terms: &ShadeTerms, occluded: bool) {
    let c = if occluded { terms.base } else { add3(terms.base, terms.direct) };
    path.radiance = add3(path.radiance, c);
}
