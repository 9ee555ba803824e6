//! What a traversal does at a leaf, for every acceleration structure (kd-tree, brute force,
//! and any structure that ends in leaves holding a range of a primitive index list).
//! `Visitor` is what a traversal calls; every `Query` (closest hit, any hit) is a visitor that
//! tests the leaf's triangles one by one, and the decomposed pipeline's leaf recorder
//! (`kdtree::leaf_list`) is a visitor that tests nothing.
use crate::parts::Parts;
use crate::pod::{Hit, Triangle};
use crate::ray::Ray;
use crate::stats::Stats;
use crate::triangle::{intersect_triangle, ShearedRay, TriHit};

/// What leaves refer to: a primitive index list (a leaf holds `prims[first..first + count]`)
/// and the triangles those indices name.
#[derive(Copy, Clone)]
pub struct Prims<'a> {
    /// The primitive index list.
    pub index: Parts<'a, u32>,
    /// The triangles the indices name.
    pub tris: Parts<'a, Triangle>,
}

/// Called by the traversals for each leaf whose cell the ray's interval overlaps.
pub trait Visitor {
    /// The leaf holding primitives `g.index[first..first + count]` covers the ray's interval up
    /// to `t_far`.
    #[allow(clippy::too_many_arguments)]
    fn leaf<S: Stats>(&mut self, g: &Prims, first: u32, count: u32, r: &ShearedRay, t_min: f32, t_far: f32, stats: &mut S);
    /// Whether nothing beyond `t` (the end of the leaf just visited) can change the answer.
    fn done(&self, t: f32) -> bool;
}

/// A hit query, one triangle at a time (the packet traversal fetches each triangle once and
/// offers it to every active ray of the packet).
pub trait Query {
    /// Nothing found yet on `ray`.
    fn new(ray: &Ray) -> Self;
    /// Tests triangle `prim`: the watertight test over [`t_min`, `bound()`], then `accept`.
    #[inline(always)]
    fn test<S: Stats>(&mut self, prim: u32, tri: &Triangle, r: &ShearedRay, t_min: f32, stats: &mut S) {
        stats.tri();
        if let Some(h) = intersect_triangle(r, tri.v0, tri.v1, tri.v2, t_min, self.bound()) {
            self.accept(prim, h);
        }
    }
    /// Takes `h`, the test's hit of triangle `prim` within [t_min, `bound()`], into the answer
    /// (`test`'s second half; packets test a triangle for all lanes at once and call it).
    fn accept(&mut self, prim: u32, h: TriHit);
    /// Whether a further triangle can still change the answer.
    fn open(&self) -> bool;
    /// Whether nothing beyond `t` can change the answer.
    fn finished(&self, t: f32) -> bool;
    /// The end of the interval still searched: a primitive whose hits all lie beyond it cannot
    /// change the answer (one at exactly this distance still can: the tie rule).
    fn bound(&self) -> f32;
    /// Whether the first hit found answers the query (any hit), so that rays go apart in the
    /// BVH's packets (`bvh::packet::SOLO`) and nothing else changes.
    const ANY_HIT: bool = false;
}

impl<Q: Query> Visitor for Q {
    #[inline(always)]
    fn leaf<S: Stats>(&mut self, g: &Prims, first: u32, count: u32, r: &ShearedRay, t_min: f32, _t_far: f32, stats: &mut S) {
        let off = first as usize;
        let n = count as usize;
        let mut j = 0;
        while j < n && self.open() {
            let p = g.index.get(off + j);
            self.test(p, &g.tris.get(p as usize), r, t_min, stats);
            j += 1;
        }
    }
    #[inline(always)]
    fn done(&self, t: f32) -> bool {
        self.finished(t)
    }
}

/// Closest-hit query: the nearest hit in the ray's interval (ties keep the lower primitive
/// index).
#[derive(Copy, Clone)]
pub struct Closest {
    /// Best hit so far (`Hit::NONE` if none).
    pub hit: Hit,
    /// End of the interval still searched: the best hit's `t`, or the ray's `t_max`.
    pub t_max: f32,
}

impl Query for Closest {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        Closest { hit: Hit::NONE, t_max: ray.t_max }
    }
    #[inline(always)]
    fn accept(&mut self, p: u32, h: TriHit) {
        // Ties in t keep the lower primitive index, as the brute-force oracle does.
        if !self.hit.is_hit() || h.t < self.hit.t || (h.t == self.hit.t && p < self.hit.prim) {
            self.hit = Hit { t: h.t, prim: p, b1: h.b1, b2: h.b2 };
            self.t_max = h.t;
        }
    }
    #[inline(always)]
    fn open(&self) -> bool {
        true
    }
    #[inline(always)]
    fn finished(&self, t: f32) -> bool {
        self.hit.is_hit() && self.hit.t <= t
    }
    #[inline(always)]
    fn bound(&self) -> f32 {
        self.t_max
    }
}

/// Any-hit query: whether the ray hits any triangle in its interval.
#[derive(Copy, Clone)]
pub struct AnyHit {
    /// Whether a hit was found.
    pub found: bool,
    /// End of the ray's interval.
    pub t_max: f32,
}

impl Query for AnyHit {
    const ANY_HIT: bool = true;
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        AnyHit { found: false, t_max: ray.t_max }
    }
    #[inline(always)]
    fn accept(&mut self, _p: u32, _h: TriHit) {
        self.found = true;
    }
    #[inline(always)]
    fn open(&self) -> bool {
        !self.found
    }
    #[inline(always)]
    fn finished(&self, _t: f32) -> bool {
        self.found
    }
    #[inline(always)]
    fn bound(&self) -> f32 {
        self.t_max
    }
}

/// A search of the triangles near a point rather than along a ray (`Method::near`): the
/// structure offers it every triangle whose leaf (kd cell, BVH leaf box) overlaps the box
/// `lo`..`hi` it was asked about — possibly more, never fewer — and reports whether any
/// answered yes. The test reads the query and changes nothing (an immutable query holding a
/// buffer: the NVIDIA driver 580's compiler crashed on a mutable one, lavapipe lost its
/// answer), and the search does not end early.
pub trait Near {
    /// Whether triangle `prim` (its index in the scene) answers the query.
    fn test(&self, prim: u32, tri: &Triangle) -> bool;
}

/// What a query stores per ray in a result buffer: the hit (closest hit) or 1/0 (any hit).
pub trait Answer {
    /// The value stored per ray.
    type Out: Copy;
    /// The query's answer, as stored in the result buffer.
    fn answer(&self) -> Self::Out;
}
impl Answer for Closest {
    type Out = Hit;
    #[inline(always)]
    fn answer(&self) -> Hit {
        self.hit
    }
}
impl Answer for AnyHit {
    type Out = u32;
    #[inline(always)]
    fn answer(&self) -> u32 {
        self.found as u32
    }
}
