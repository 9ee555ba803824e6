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

/// One slab of a box along one axis: the parametric distances where the ray (origin `o`,
/// reciprocal direction `inv`, `neg` when the direction is negative) crosses the near and the
/// far plane of [`lo`, `hi`], the far one widened by 2γ(3). A direction too small to invert is
/// parallel: (−∞, ∞) when the origin lies in the slab (bounds inclusive), else (∞, −∞); no
/// 0·∞ NaN is formed (drivers need not honour NaN comparisons).
#[inline(always)]
pub fn slab(o: f32, inv: f32, lo: f32, hi: f32, neg: bool) -> (f32, f32) {
    if inv.is_infinite() {
        if o < lo || o > hi {
            (f32::INFINITY, f32::NEG_INFINITY)
        } else {
            (f32::NEG_INFINITY, f32::INFINITY)
        }
    } else {
        let (a, b) = if neg { (hi, lo) } else { (lo, hi) };
        let near = (a - o) * inv;
        let far = (b - o) * inv;
        (near, far * (1.0 + 2.0 * gamma(3)))
    }
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
        let (near, far) = slab(origin[a], inv_d[a], b.min[a], b.max[a], inv_d[a] < 0.0);
        if near > t0 {
            t0 = near;
        }
        if far < t1 {
            t1 = far;
        }
        if t0 > t1 {
            return None;
        }
        a += 1;
    }
    Some((t0, t1))
}
