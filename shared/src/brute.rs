//! Brute-force closest-hit and any-hit over a triangle list: the oracle every accelerated
//! traversal is checked against. Ties in t keep the lower primitive index.
use crate::parts::Parts;
use crate::query::{AnyHit, Closest};
use crate::pod::{Hit, Triangle};
use crate::ray::Ray;
use crate::triangle::{intersect_triangle, ShearedRay};

/// The closest hit of `ray` among all of `tris` (`Hit::NONE` if none, or if the ray is
/// invalid); ties in t keep the lower index.
#[inline(always)]
pub fn closest_hit(ray: &Ray, tris: &[Triangle]) -> Hit {
    closest_hit_in(ray, &Parts::one(tris))
}

/// `closest_hit` over an array that may be split across bindings.
#[inline(always)]
pub fn closest_hit_in(ray: &Ray, tris: &Parts<Triangle>) -> Hit {
    let mut best = Hit::NONE;
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return best,
    };
    let mut t_max = ray.t_max;
    let n = tris.len();
    let mut i = 0;
    while i < n {
        let tri = &tris.get(i);
        if let Some(h) = intersect_triangle(&r, tri.v0, tri.v1, tri.v2, ray.t_min, t_max) {
            if !best.is_hit() || h.t < best.t {
                best = Hit { t: h.t, prim: i as u32, b1: h.b1, b2: h.b2 };
                t_max = h.t;
            }
        }
        i += 1;
    }
    best
}

/// Whether `ray` hits any of `tris` in its interval (`false` for an invalid ray).
#[inline(always)]
pub fn any_hit(ray: &Ray, tris: &[Triangle]) -> bool {
    any_hit_in(ray, &Parts::one(tris))
}

/// `any_hit` over an array that may be split across bindings.
#[inline(always)]
pub fn any_hit_in(ray: &Ray, tris: &Parts<Triangle>) -> bool {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return false,
    };
    let n = tris.len();
    let mut i = 0;
    while i < n {
        let tri = &tris.get(i);
        if intersect_triangle(&r, tri.v0, tri.v1, tri.v2, ray.t_min, ray.t_max).is_some() {
            return true;
        }
        i += 1;
    }
    false
}

/// A hit query answered by the oracle (the brute-force kernels and the CPU runtime).
pub trait BruteForce {
    /// Answers the query for `ray` by testing every triangle of `tris`.
    fn brute(&mut self, ray: &Ray, tris: &Parts<Triangle>);
}
impl BruteForce for Closest {
    #[inline(always)]
    fn brute(&mut self, ray: &Ray, tris: &Parts<Triangle>) {
        self.hit = closest_hit_in(ray, tris);
    }
}
impl BruteForce for AnyHit {
    #[inline(always)]
    fn brute(&mut self, ray: &Ray, tris: &Parts<Triangle>) {
        self.found = any_hit_in(ray, tris);
    }
}
