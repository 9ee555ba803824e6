//! Bounds of a triangle clipped to a box ("perfect splits"), in f64, rounded outward to f32.

/// Box as (min, max) corners.
pub type Bounds = ([f32; 3], [f32; 3]);

/// The bounds of the part of triangle `v` inside box `b`, or `None` if (numerically) empty.
/// The result always lies inside `b`.
pub fn clipped_bounds(v: [[f32; 3]; 3], b: Bounds) -> Option<Bounds> {
    let mut poly: Vec<[f64; 3]> = v.iter().map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect();
    let mut next = Vec::with_capacity(9);
    for axis in 0..3 {
        for (bound, keep_above) in [(b.0[axis] as f64, true), (b.1[axis] as f64, false)] {
            next.clear();
            let inside = |p: &[f64; 3]| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
            for i in 0..poly.len() {
                let cur = poly[i];
                let nxt = poly[(i + 1) % poly.len()];
                let (ci, ni) = (inside(&cur), inside(&nxt));
                if ci {
                    next.push(cur);
                }
                if ci != ni {
                    let t = (bound - cur[axis]) / (nxt[axis] - cur[axis]);
                    let mut p = [0.0; 3];
                    for k in 0..3 {
                        p[k] = cur[k] + t * (nxt[k] - cur[k]);
                    }
                    p[axis] = bound;
                    next.push(p);
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.is_empty() {
                return None;
            }
        }
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &poly {
        for k in 0..3 {
            lo[k] = lo[k].min(round_down(p[k]));
            hi[k] = hi[k].max(round_up(p[k]));
        }
    }
    for k in 0..3 {
        lo[k] = lo[k].max(b.0[k]);
        hi[k] = hi[k].min(b.1[k]);
        if lo[k] > hi[k] {
            return None;
        }
    }
    Some((lo, hi))
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
}
