//! Shading of eye paths, written once for the direct-lighting renderer, the path tracer and the
//! photon mapper's eye pass: Lambertian surfaces, perfect mirrors and smooth dielectrics
//! (Fresnel), area / point / spot lights. Emissive triangles emit from their front side, the
//! side (v1 − v0) × (v2 − v0) points to (as in pbrt and Mitsuba; OBJ winding).
//!
//! A pixel's path follows specular bounces (mirrors reflect; glass reflects or refracts with
//! the Fresnel probability) until it meets a diffuse surface, where `light_sample` turns the hit
//! into a shadow ray toward one sampled light point and the radiance that arrives if that ray is
//! unoccluded (next-event estimation); `accumulate` adds it once the any-hit result is known.
//! Then the path ends (direct lighting, `diffuse_bounces` 0), continues in a cosine-weighted
//! direction with Russian roulette by albedo (path tracing), or ends as a gather point for the
//! photon map (`RENDER_GATHER`). Emission a path hits counts after the camera or a specular
//! vertex only; after a diffuse vertex the shadow ray has counted it. A final gather resumes a
//! path from its gather point (`render::resume`, `RENDER_CONTINUE`) to a second one, which
//! takes direct light by its own shadow ray and the rest from the photon maps; emission it
//! meets counts nowhere on the way (direct light and caustics were counted at the first
//! point). The split lets each query run as its own kernel.
//!
//! Glass is colourless and the radiance scaling by η² at refraction is left out (it cancels
//! for paths that enter and leave a closed object).
use crate::math::{add3, cosine_direction, cross3, dot3, length3, mul3, normalize3, scale3, sqrt, sub3};
use crate::parts::Parts;
use crate::pod::{
    Hit, Light, Material, PathState, RenderParams, ShadeTerms, Triangle, LIGHT_POINT, LIGHT_SPOT, MAT_GLASS, MAT_MIRROR,
    PATH_ACTIVE, PATH_DIFFUSE_SHIFT, PATH_GATHER, PATH_SPECULAR, RENDER_CONTINUE, RENDER_GATHER, RENDER_PHOTON_DIRECT,
};
use crate::ray::Ray;
use crate::sampler::{self, Sampler};

/// 1/π: the Lambertian BRDF per unit albedo.
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;
/// Shadow rays stop this fraction short of the light point so they never hit the light itself.
pub const SHADOW_END: f32 = 1.0 - 1.0 / 4096.0;

/// An interval that every query rejects: the "no shadow ray needed" marker.
pub const NO_RAY: Ray = Ray { origin: [0.0; 3], t_min: 1.0, dir: [0.0, 0.0, 1.0], t_max: 0.0 };

/// Offset along the normal that moves a hit point off its surface, relative to its magnitude
/// (a few dozen ulps: the barycentric point's rounding error is below γ(7)·|p|).
#[inline(always)]
pub fn offset_scale(p: [f32; 3]) -> f32 {
    let m = p[0].abs().max(p[1].abs()).max(p[2].abs());
    (1.0 + m) * (64.0 * f32::EPSILON)
}

/// `p` moved off its surface to the side `n` points to.
#[inline(always)]
pub fn offset(p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
    add3(p, scale3(n, offset_scale(p)))
}

/// The unit geometric normal (v1 − v0) × (v2 − v0) of a triangle.
#[inline(always)]
pub fn geometric_normal(tri: &Triangle) -> [f32; 3] {
    normalize3(cross3(sub3(tri.v1, tri.v0), sub3(tri.v2, tri.v0)))
}

/// The hit point (from barycentrics, not o + t·d) and the geometric normal facing the ray.
#[inline(always)]
pub fn surface_point(tri: &Triangle, hit: &Hit, ray: &Ray) -> ([f32; 3], [f32; 3]) {
    let b0 = 1.0 - hit.b1 - hit.b2;
    let p = add3(add3(scale3(tri.v0, b0), scale3(tri.v1, hit.b1)), scale3(tri.v2, hit.b2));
    let n = geometric_normal(tri);
    (p, if dot3(n, ray.dir) > 0.0 { scale3(n, -1.0) } else { n })
}

/// The light of selection number `u` for the running sums `cdf_of(i)` (last: 1).
#[inline(always)]
fn pick_light(lights: &[Light], n: usize, u: f32, power: bool) -> usize {
    let mut i = 0;
    while i + 1 < n && (if power { lights[i].power_cdf } else { lights[i].cdf }) <= u {
        i += 1;
    }
    i
}

/// Light `i` chosen by selection number `u` (by the running sums `cdf`, or `power_cdf` for
/// emission by power), its selection probability, and `u` rescaled to [0, 1) within the
/// light's share, (u − before) / probability: a number as uniform as `u` and independent of the
/// choice, so one stratified number both chooses the light and goes on to place the point.
#[inline(always)]
pub fn choose_light(lights: &[Light], n: u32, u: f32, power: bool) -> (usize, f32, f32) {
    let i = pick_light(lights, n as usize, u, power);
    let (cur, prev) = if power {
        (lights[i].power_cdf, if i == 0 { 0.0 } else { lights[i - 1].power_cdf })
    } else {
        (lights[i].cdf, if i == 0 { 0.0 } else { lights[i - 1].cdf })
    };
    let p = cur - prev;
    // Below 1: the quotient may round up to it.
    let rest = if p > 0.0 { ((u - prev) / p).max(0.0).min(0.999_999_94) } else { 0.0 };
    (i, p, rest)
}

/// A spot light's intensity factor toward unit direction `w` (leaving the light): 1 inside the
/// falloff start, 0 outside the cone, smoothstep between (pbrt-v4).
#[inline(always)]
pub fn spot_falloff(light: &Light, w: [f32; 3]) -> f32 {
    let c = dot3(light.e1, w);
    let (c_end, c_start) = (light.e2[0], light.e2[1]);
    if c >= c_start {
        1.0
    } else if c <= c_end {
        0.0
    } else {
        let t = (c - c_end) / (c_start - c_end);
        t * t * (3.0 - 2.0 * t)
    }
}

/// Next-event estimation at diffuse point `p` (normal `n` facing the arriving ray, albedo
/// `albedo`): a shadow ray toward a point on one light, chosen and placed by the two numbers
/// `u` (the first picks the light and, rescaled to its share, goes on to place the point, so
/// stratified numbers stay stratified on each light), and the reflected radiance it brings if
/// unoccluded. `NO_RAY` and 0 when nothing can arrive.
#[inline(always)]
pub fn light_sample(u: [f32; 2], p: [f32; 3], n: [f32; 3], albedo: [f32; 3], lights: &[Light], light_count: u32) -> (Ray, [f32; 3]) {
    if light_count == 0 {
        return (NO_RAY, [0.0; 3]);
    }
    let (li, p_select, u1) = choose_light(lights, light_count, u[0], false);
    let light = &lights[li];
    let u2 = u[1];
    let (target, radiance_geom) = if light.kind == LIGHT_POINT {
        (light.p0, scale3(light.emission, 1.0 / p_select))
    } else if light.kind == LIGHT_SPOT {
        let f = spot_falloff(light, normalize3(sub3(p, light.p0)));
        (light.p0, scale3(light.emission, f / p_select))
    } else {
        let s = sqrt(u1);
        let q = add3(add3(light.p0, scale3(light.e1, 1.0 - s)), scale3(light.e2, u2 * s));
        let nl = normalize3(cross3(light.e1, light.e2));
        let w = normalize3(sub3(p, q));
        // One-sided: only the front, (v1 − v0) × (v2 − v0), emits.
        let cos_l = dot3(nl, w).max(0.0);
        (q, scale3(light.emission, cos_l * light.area / p_select))
    };
    let origin = offset(p, n);
    let to_light = sub3(target, origin);
    let dist = length3(to_light);
    let cos_s = dot3(n, to_light) / dist;
    if !(cos_s > 0.0) || !(dist > 0.0) {
        return (NO_RAY, [0.0; 3]);
    }
    let f = scale3(albedo, INV_PI * cos_s / (dist * dist));
    (Ray::new(origin, to_light, 0.0, SHADOW_END), mul3(f, radiance_geom))
}

/// Fresnel reflectance of a smooth dielectric for relative index `eta` = n_incident / n_other,
/// incident cosine `cos_i` and transmitted cosine `cos_t`.
#[inline(always)]
pub fn fresnel(cos_i: f32, cos_t: f32, eta: f32) -> f32 {
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// The ray leaving a specular surface at `p` for unit direction `d` arriving: a mirror
/// reflects; glass (index `mat.ior()`, the triangle's geometric normal pointing outside)
/// reflects with the Fresnel probability (or under total internal reflection) and refracts
/// otherwise, decided by `u`.
#[inline(always)]
pub fn specular_bounce(mat: &Material, tri: &Triangle, p: [f32; 3], d: [f32; 3], u: f32) -> Ray {
    let ng = geometric_normal(tri);
    let entering = dot3(ng, d) < 0.0;
    let n = if entering { ng } else { scale3(ng, -1.0) };
    let cos_i = -dot3(d, n);
    let reflect = add3(d, scale3(n, 2.0 * cos_i));
    if mat.flags & MAT_MIRROR != 0 || mat.flags & MAT_GLASS == 0 {
        return Ray::new(offset(p, n), reflect, 0.0, f32::INFINITY);
    }
    let eta = if entering { 1.0 / mat.ior() } else { mat.ior() };
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return Ray::new(offset(p, n), reflect, 0.0, f32::INFINITY);
    }
    let cos_t = sqrt(1.0 - sin2_t);
    if u < fresnel(cos_i, cos_t, eta) {
        return Ray::new(offset(p, n), reflect, 0.0, f32::INFINITY);
    }
    let t = add3(scale3(d, eta), scale3(n, eta * cos_i - cos_t));
    Ray::new(offset(p, scale3(n, -1.0)), normalize3(t), 0.0, f32::INFINITY)
}

/// Whether a material scatters specularly (mirror or glass).
#[inline(always)]
pub fn is_specular(mat: &Material) -> bool {
    mat.flags & (MAT_MIRROR | MAT_GLASS) != 0
}

/// A gather point in a ray slot: the point as origin, the normal (facing the eye path) as
/// direction, an interval every query rejects, so nothing traces it.
#[inline(always)]
pub fn gather_point(p: [f32; 3], n: [f32; 3]) -> Ray {
    Ray { origin: p, t_min: 1.0, dir: n, t_max: 0.0 }
}

#[inline(always)]
fn end(path: &mut PathState, ray: &mut Ray) {
    path.flags = 0;
    *ray = NO_RAY;
}

/// One step of a pixel's path at its `bounce`-th hit (see the module notes). A specular
/// bounce before `p.max_bounces` replaces `ray` in place; a diffuse hit (or any hit at the last
/// bounce) is shaded with one shadow ray and then continues, ends, or becomes a gather point.
/// Returns the shadow ray (`NO_RAY` if none) and the terms to `accumulate`, weighted by the
/// path's throughput. A path that ends leaves `NO_RAY` in `ray` (a gather point, see
/// `gather_point`), so later bounces trace nothing for it. Numbers come from the path's
/// `Sampler`, dimensions of their own per bounce and use (`sampler::dim`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step(
    p: &RenderParams,
    bounce: u32,
    ray: &mut Ray,
    hit: &Hit,
    path: &mut PathState,
    tris: &Parts<Triangle>,
    materials: &[Material],
    lights: &[Light],
) -> (Ray, ShadeTerms) {
    let mut terms = ShadeTerms::default();
    if !path.is_active() {
        return (NO_RAY, terms);
    }
    if !hit.is_hit() {
        end(path, ray);
        return (NO_RAY, terms);
    }
    let tri = &tris.get(hit.prim as usize);
    let mat = &materials[tri.material as usize];
    // Emitters emit from their front side only; a final-gather path (`RENDER_CONTINUE`) left
    // a diffuse point whose direct light and caustics are counted already.
    if path.flags & PATH_SPECULAR != 0 && p.flags & RENDER_CONTINUE == 0 && dot3(geometric_normal(tri), ray.dir) < 0.0 {
        terms.base = mul3(path.throughput, mat.emission);
    }
    // Each bounce draws from dimensions of its own.
    let smp = Sampler::new(p, path.pixel);
    let level = crate::render::resume_level(p);
    let (pt, n) = surface_point(tri, hit, ray);
    if is_specular(mat) && bounce < p.max_bounces {
        *ray = specular_bounce(mat, tri, pt, ray.dir, smp.get1(sampler::dim(bounce, sampler::FRESNEL, level)));
        if mat.flags & MAT_MIRROR != 0 {
            path.throughput = mul3(path.throughput, mat.diffuse);
        }
        path.flags |= PATH_SPECULAR;
        return (NO_RAY, terms);
    }
    let gather = p.flags & RENDER_GATHER != 0;
    let mut shadow = NO_RAY;
    if !(gather && p.flags & RENDER_PHOTON_DIRECT != 0) {
        let u = smp.get2(sampler::dim(bounce, sampler::LIGHT, level));
        let (s, direct) = light_sample(u, pt, n, mat.diffuse, lights, p.light_count);
        shadow = s;
        terms.direct = mul3(path.throughput, direct);
    }
    let diffuse = path.flags >> PATH_DIFFUSE_SHIFT;
    if gather {
        path.throughput = scale3(mul3(path.throughput, mat.diffuse), INV_PI);
        path.flags = PATH_GATHER;
        *ray = gather_point(pt, n);
    } else if diffuse < p.diffuse_bounces && bounce < p.max_bounces {
        let a = mat.diffuse;
        let q = a[0].max(a[1]).max(a[2]).min(1.0);
        if smp.get1(sampler::dim(bounce, sampler::ROULETTE, level)) < q {
            let u = smp.get2(sampler::dim(bounce, sampler::BOUNCE, level));
            let d = cosine_direction(n, u[0], u[1]);
            *ray = Ray::new(offset(pt, n), d, 0.0, f32::INFINITY);
            path.throughput = mul3(path.throughput, scale3(a, 1.0 / q));
            path.flags = PATH_ACTIVE | ((diffuse + 1) << PATH_DIFFUSE_SHIFT);
        } else {
            end(path, ray);
        }
    } else {
        end(path, ray);
    }
    (shadow, terms)
}

/// Adds a step's radiance to its path: `base`, plus `direct` unless the shadow ray was blocked.
#[inline(always)]
pub fn accumulate(path: &mut PathState, terms: &ShadeTerms, occluded: bool) {
    let c = if occluded { terms.base } else { add3(terms.base, terms.direct) };
    path.radiance = add3(path.radiance, c);
}
