//! Rays as they live in buffers (`Ray`, 32 bytes) and the validity rule every query applies
//! first: a ray with a non-finite or zero direction, a non-finite origin or a NaN / inverted
//! interval is a miss, never a hang.
use bytemuck::{Pod, Zeroable};

/// A ray with its parametric interval [t_min, t_max]; `dir` need not be normalised.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Ray {
    pub origin: [f32; 3],
    pub t_min: f32,
    pub dir: [f32; 3],
    pub t_max: f32,
}

impl Ray {
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

    #[inline(always)]
    pub fn at(&self, t: f32) -> [f32; 3] {
        crate::math::add3(self.origin, crate::math::scale3(self.dir, t))
    }
}
