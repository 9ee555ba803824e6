//! Bounds of a triangle clipped to a box ("perfect splits"), in f64, rounded outward to f32.

/// Box as (min, max) corners.
pub type Bounds = ([f32; 3], [f32; 3]);

/// A clipped polygon's vertices: a triangle cut by the six planes of a box has at most nine
/// (one more per plane); rounding can make a nearly flat one cross a plane more often, so
/// there is room for more, and `push` reports a polygon that would not fit.
struct Poly {
    v: [[f64; 3]; Poly::CAP],
    n: usize,
}

impl Poly {
    const CAP: usize = 12;

    fn push(&mut self, p: [f64; 3]) -> bool {
        if self.n == Poly::CAP {
            return false;
        }
        self.v[self.n] = p;
        self.n += 1;
        true
    }
}

/// What clipping a polygon by one plane left.
enum Cut {
    /// A polygon (possibly the same one).
    Kept,
    /// Nothing (numerically).
    Empty,
    /// More vertices than `Poly::CAP`: the caller falls back to the box overlap.
    Full,
}

/// Sutherland-Hodgman, plane by plane, between two polygons on the stack (a quarter of a
/// build's time was clipping, much of it allocating), taking turns: `polys[cur]` is the
/// polygon so far (swapping them instead copied 600 bytes a plane).
struct Clipper {
    polys: [Poly; 2],
    cur: usize,
}

impl Clipper {
    fn new(v: &[[f32; 3]; 3]) -> Clipper {
        let mut polys = [Poly { v: [[0.0; 3]; Poly::CAP], n: 3 }, Poly { v: [[0.0; 3]; Poly::CAP], n: 0 }];
        for (k, p) in v.iter().enumerate() {
            polys[0].v[k] = [p[0] as f64, p[1] as f64, p[2] as f64];
        }
        Clipper { polys, cur: 0 }
    }

    /// Starts again from triangle `v`.
    #[inline(always)]
    fn reset(&mut self, v: &[[f32; 3]; 3]) {
        for (k, p) in v.iter().enumerate() {
            self.polys[0].v[k] = [p[0] as f64, p[1] as f64, p[2] as f64];
        }
        self.polys[0].n = 3;
        self.cur = 0;
    }

    /// Makes `other` hold a copy of this one's polygon so far.
    #[inline(always)]
    fn fork_into(&self, other: &mut Clipper) {
        let p = &self.polys[self.cur];
        other.polys[0].v = p.v;
        other.polys[0].n = p.n;
        other.cur = 0;
    }

    /// Clips the polygon to the side of the plane at `bound` along `axis` (above it if
    /// `keep_above`, else below).
    #[inline(always)]
    fn plane(&mut self, axis: usize, bound: f64, keep_above: bool) -> Cut {
        let inside = |p: &[f64; 3]| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
        let [a, c] = &mut self.polys;
        let (poly, next) = if self.cur == 0 { (&*a, c) } else { (&*c, a) };
        // Most planes of a cell miss the triangle: the polygon stays as it is.
        if poly.v[..poly.n].iter().all(inside) {
            return Cut::Kept;
        }
        next.n = 0;
        for i in 0..poly.n {
            let here = poly.v[i];
            let there = poly.v[if i + 1 == poly.n { 0 } else { i + 1 }];
            let (hi, ti) = (inside(&here), inside(&there));
            if hi && !next.push(here) {
                return Cut::Full;
            }
            if hi != ti {
                let t = (bound - here[axis]) / (there[axis] - here[axis]);
                let mut p = [0.0; 3];
                for k in 0..3 {
                    p[k] = here[k] + t * (there[k] - here[k]);
                }
                p[axis] = bound;
                if !next.push(p) {
                    return Cut::Full;
                }
            }
        }
        if next.n == 0 {
            return Cut::Empty;
        }
        self.cur ^= 1;
        Cut::Kept
    }

    /// Clips by box `b`'s planes of axes `from..3` (lower plane first), then the polygon's
    /// bounds within `b`: `clipped_bounds`'s answer once the axes before `from` are clipped.
    #[inline(always)]
    fn finish(&mut self, v: &[[f32; 3]; 3], b: Bounds, from: usize) -> Option<Bounds> {
        for axis in from..3 {
            for (bound, keep_above) in [(b.0[axis] as f64, true), (b.1[axis] as f64, false)] {
                match self.plane(axis, bound, keep_above) {
                    Cut::Kept => {}
                    Cut::Empty => return None,
                    Cut::Full => return Some(overlap(tri_bounds(*v), b)),
                }
            }
        }
        self.bounds(b)
    }

    /// The polygon's bounds in f64, rounded outward once per axis (rounding is monotonic: the
    /// same as rounding every vertex), within `b`.
    fn bounds(&self, b: Bounds) -> Option<Bounds> {
        let poly = &self.polys[self.cur].v[..self.polys[self.cur].n];
        let (mut lo64, mut hi64) = (poly[0], poly[0]);
        for p in &poly[1..] {
            for k in 0..3 {
                lo64[k] = if p[k] < lo64[k] { p[k] } else { lo64[k] };
                hi64[k] = if p[k] > hi64[k] { p[k] } else { hi64[k] };
            }
        }
        let mut lo = [0.0f32; 3];
        let mut hi = [0.0f32; 3];
        for k in 0..3 {
            lo[k] = round_down(lo64[k]).max(b.0[k]);
            hi[k] = round_up(hi64[k]).min(b.1[k]);
            if lo[k] > hi[k] {
                return None;
            }
        }
        Some((lo, hi))
    }
}

/// The bounds of the part of triangle `v` inside box `b`, or `None` if (numerically) empty.
/// The result always lies inside `b`.
pub fn clipped_bounds(v: [[f32; 3]; 3], b: Bounds) -> Option<Bounds> {
    Clipper::new(&v).finish(&v, b, 0)
}

/// Polygons for clipping one triangle after another, set up once (`clipped_bounds` zeroes its
/// every call).
pub struct ClipScratch {
    left: Clipper,
    right: Clipper,
}

impl Default for ClipScratch {
    fn default() -> Self {
        ClipScratch { left: Clipper::new(&[[0.0; 3]; 3]), right: Clipper::new(&[[0.0; 3]; 3]) }
    }
}

impl ClipScratch {
    /// `clipped_bounds`.
    pub fn bounds(&mut self, v: [[f32; 3]; 3], b: Bounds) -> Option<Bounds> {
        self.left.reset(&v);
        self.left.finish(&v, b, 0)
    }

    /// `clipped_bounds` of triangle `v` in both children of box `b` split at `p` along axis
    /// `k` (left, right), the same bit for bit: the planes of the axes before `k`, which both
    /// children share and clip first, are clipped once.
    pub fn split(&mut self, v: [[f32; 3]; 3], b: Bounds, k: usize, p: f32) -> [Option<Bounds>; 2] {
        let (mut l, mut r) = (b, b);
        l.1[k] = p;
        r.0[k] = p;
        let c = &mut self.left;
        c.reset(&v);
        for axis in 0..k {
            for (bound, keep_above) in [(b.0[axis] as f64, true), (b.1[axis] as f64, false)] {
                match c.plane(axis, bound, keep_above) {
                    Cut::Kept => {}
                    Cut::Empty => return [None, None],
                    Cut::Full => return [Some(overlap(tri_bounds(v), l)), Some(overlap(tri_bounds(v), r))],
                }
            }
        }
        c.fork_into(&mut self.right);
        [self.left.finish(&v, l, k), self.right.finish(&v, r, k)]
    }
}

/// The part of box `a` inside box `b` (conservative bounds of a triangle whose clipping
/// rounding made degenerate; `a` must overlap `b`).
pub fn overlap(a: Bounds, b: Bounds) -> Bounds {
    let mut o = a;
    for k in 0..3 {
        o.0[k] = a.0[k].max(b.0[k]);
        o.1[k] = a.1[k].min(b.1[k]).max(o.0[k]);
    }
    o
}

fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x { f.next_down() } else { f }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

/// Plain bounds of a triangle.
pub fn tri_bounds(v: [[f32; 3]; 3]) -> Bounds {
    let mut lo = v[0];
    let mut hi = v[0];
    for p in &v[1..] {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_a_triangle_to_half_its_box() {
        let v = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let (lo, hi) = clipped_bounds(v, ([1.0, 0.0, 0.0], [2.0, 2.0, 0.0])).unwrap();
        assert_eq!((lo, hi), ([1.0, 0.0, 0.0], [2.0, 1.0, 0.0]));
        assert!(clipped_bounds(v, ([1.5, 1.5, 0.0], [2.0, 2.0, 0.0])).is_none());
        // Touching the box in one point.
        let (lo, hi) = clipped_bounds(v, ([2.0, -1.0, -1.0], [3.0, 1.0, 1.0])).unwrap();
        assert_eq!((lo, hi), ([2.0, 0.0, 0.0], [2.0, 0.0, 0.0]));
    }

    /// Several planes in turn: a box inside a large triangle clips it to the box's own face; a
    /// box over its hypotenuse to the corner the triangle keeps; a tilted triangle through a
    /// box to the exact (outward rounded) bounds of its part inside.
    #[test]
    fn clipping_by_several_planes() {
        let v = [[0.0, 0.0, 0.0], [8.0, 0.0, 0.0], [0.0, 8.0, 0.0]];
        let inner = ([1.0, 1.0, -1.0], [2.0, 3.0, 1.0]);
        assert_eq!(clipped_bounds(v, inner).unwrap(), ([1.0, 1.0, 0.0], [2.0, 3.0, 0.0]));
        // x + y <= 8 inside [5, 7] × [2, 6]: x from 5 to 6 (at y = 2), y from 2 to 3 (at x = 5).
        let corner = ([5.0, 2.0, -1.0], [7.0, 6.0, 1.0]);
        assert_eq!(clipped_bounds(v, corner).unwrap(), ([5.0, 2.0, 0.0], [6.0, 3.0, 0.0]));
        // z = x / 4 over the same triangle, in a box cut at z <= 0.5 (x <= 2) and y >= 1.
        let tilted = [[0.0, 0.0, 0.0], [8.0, 0.0, 2.0], [0.0, 8.0, 0.0]];
        let (lo, hi) = clipped_bounds(tilted, ([0.0, 1.0, 0.0], [8.0, 8.0, 0.5])).unwrap();
        assert_eq!((lo, hi), ([0.0, 1.0, 0.0], [2.0, 8.0, 0.5]));
        // Outside every face: nothing.
        assert!(clipped_bounds(v, ([6.0, 6.0, -1.0], [7.0, 7.0, 1.0])).is_none());
    }

    /// The reused polygons give `clipped_bounds`'s answers bit for bit, in both children of
    /// every axis's split (pseudo-random triangles through a box, some cut away entirely).
    #[test]
    fn clip_scratch_matches_clipped_bounds() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut r = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32 * 3.0 - 1.0
        };
        let mut c = ClipScratch::default();
        let b = ([0.0f32, 0.1, 0.2], [1.0f32, 0.9, 1.1]);
        for _ in 0..2000 {
            let v = [[r(), r(), r()], [r(), r(), r()], [r(), r(), r()]];
            for k in 0..3 {
                let p = b.0[k] + (b.1[k] - b.0[k]) * (0.5 + 0.4 * r() / 2.0);
                let (mut l, mut rt) = (b, b);
                l.1[k] = p;
                rt.0[k] = p;
                assert_eq!(c.split(v, b, k, p), [clipped_bounds(v, l), clipped_bounds(v, rt)]);
                assert_eq!(c.bounds(v, l), clipped_bounds(v, l));
            }
        }
    }
}
