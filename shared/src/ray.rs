//! Rays as they live in buffers (`Ray`, 32 bytes) and the validity rule every query applies
//! first: a ray with a non-finite or zero direction, a non-finite origin or a NaN / inverted
//! interval is a miss, never a hang.
use bytemuck::{Pod, Zeroable};

/// A ray with its parametric interval [t_min, t_max]; `dir` need not be normalised.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Ray {
    /// Start point.
    pub origin: [f32; 3],
    /// Start of the parametric interval.
    pub t_min: f32,
    /// Direction (need not be normalised).
    pub dir: [f32; 3],
    /// End of the parametric interval (may be +inf).
    pub t_max: f32,
}

impl Ray {
    /// The ray `origin + t·dir` for t in [`t_min`, `t_max`].
    pub fn new(origin: [f32; 3], dir: [f32; 3], t_min: f32, t_max: f32) -> Self {
        Self { origin, t_min, dir, t_max }
    }

    /// Finite origin, finite non-zero direction whose largest component can be normalised
    /// exactly, and `0 <= t_min <= t_max` with `t_max` possibly +inf.
    #[inline(always)]
    pub fn is_valid(&self) -> bool {
        let o = self.origin;
        let d = self.dir;
        let finite = o[0].is_finite()
            && o[1].is_finite()
            && o[2].is_finite()
            && d[0].is_finite()
            && d[1].is_finite()
            && d[2].is_finite();
        let m = d[0].abs().max(d[1].abs()).max(d[2].abs());
        finite
            && crate::math::pow2_normaliser(m).is_some()
            && self.t_min >= 0.0
            && self.t_min <= self.t_max
    }

    /// The point at parameter `t`: `origin + t·dir`.
    #[inline(always)]
    pub fn at(&self, t: f32) -> [f32; 3] {
        crate::math::add3(self.origin, crate::math::scale3(self.dir, t))
    }
}
