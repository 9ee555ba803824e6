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

/// The bounds of the part of triangle `v` inside box `b`, or `None` if (numerically) empty.
/// The result always lies inside `b`.
pub fn clipped_bounds(v: [[f32; 3]; 3], b: Bounds) -> Option<Bounds> {
    // Sutherland-Hodgman, plane by plane, between two polygons on the stack (a quarter of a
    // build's time was clipping, much of it allocating), taking turns: `polys[cur]` is the
    // polygon so far (swapping them instead copied 600 bytes a plane).
    let mut polys = [Poly { v: [[0.0; 3]; Poly::CAP], n: 3 }, Poly { v: [[0.0; 3]; Poly::CAP], n: 0 }];
    for (k, p) in v.iter().enumerate() {
        polys[0].v[k] = [p[0] as f64, p[1] as f64, p[2] as f64];
    }
    let mut cur = 0;
    for axis in 0..3 {
        for (bound, keep_above) in [(b.0[axis] as f64, true), (b.1[axis] as f64, false)] {
            let inside = |p: &[f64; 3]| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
            let [a, c] = &mut polys;
            let (poly, next) = if cur == 0 { (&*a, c) } else { (&*c, a) };
            // Most planes of a cell miss the triangle: the polygon stays as it is.
            if poly.v[..poly.n].iter().all(inside) {
                continue;
            }
            next.n = 0;
            for i in 0..poly.n {
                let here = poly.v[i];
                let there = poly.v[if i + 1 == poly.n { 0 } else { i + 1 }];
                let (hi, ti) = (inside(&here), inside(&there));
                if hi && !next.push(here) {
                    return Some(overlap(tri_bounds(v), b));
                }
                if hi != ti {
                    let t = (bound - here[axis]) / (there[axis] - here[axis]);
                    let mut p = [0.0; 3];
                    for k in 0..3 {
                        p[k] = here[k] + t * (there[k] - here[k]);
                    }
                    p[axis] = bound;
                    if !next.push(p) {
                        return Some(overlap(tri_bounds(v), b));
                    }
                }
            }
            if next.n == 0 {
                return None;
            }
            cur ^= 1;
        }
    }
    // The polygon's bounds in f64, rounded outward once per axis (rounding is monotonic: the
    // same as rounding every vertex).
    let poly = &polys[cur].v[..polys[cur].n];
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
}
