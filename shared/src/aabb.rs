//! Ray / axis-aligned box slab test.
//!
//! A direction component of +0, −0 or one so small that its reciprocal overflows is treated as
//! parallel to that slab: the ray is inside the slab iff its origin is (bounds inclusive), and
//! the slab does not constrain t. No 0·∞ NaN ever reaches a comparison. The far distance is
//! widened by 2γ(3) as in pbrt so rounding never loses a hit on the box boundary.
use crate::math::gamma;

/// An axis-aligned box given by its minimum and maximum corners.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: [f32; 3],
    /// Maximum corner.
    pub max: [f32; 3],
}

/// Reciprocal direction, computed once per ray.
#[inline(always)]
pub fn inv_dir(d: [f32; 3]) -> [f32; 3] {
    [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]]
}

/// The parametric interval where the ray overlaps the box, clipped to [t0, t1]; `None` if empty.
#[inline(always)]
pub fn intersect_box(
    origin: [f32; 3],
    inv_d: [f32; 3],
    b: &Aabb,
    t0: f32,
    t1: f32,
) -> Option<(f32, f32)> {
    let mut t0 = t0;
    let mut t1 = t1;
    let mut a = 0;
    while a < 3 {
        let o = origin[a];
        if inv_d[a].is_infinite() {
            if o < b.min[a] || o > b.max[a] {
                return None;
            }
        } else {
            let mut near = (b.min[a] - o) * inv_d[a];
            let mut far = (b.max[a] - o) * inv_d[a];
            if near > far {
                let s = near;
                near = far;
                far = s;
            }
            far *= 1.0 + 2.0 * gamma(3);
            if near > t0 {
                t0 = near;
            }
            if far < t1 {
                t1 = far;
            }
            if t0 > t1 {
                return None;
            }
        }
        a += 1;
    }
    Some((t0, t1))
}
