//! Traversal cost counters, shared by every acceleration structure: a traversal calls a `Stats`
//! sink at each node, leaf, triangle test and restart; `NoStats` compiles to nothing and
//! `Counters` is also the GPU buffer layout of the counting kernels.
use bytemuck::{Pod, Zeroable};

/// Traversal cost counters; `NoStats` compiles to nothing.
pub trait Stats {
    fn node(&mut self);
    fn leaf(&mut self);
    fn tri(&mut self);
    fn restart(&mut self);
}

pub struct NoStats;
impl Stats for NoStats {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tri(&mut self) {}
    #[inline(always)]
    fn restart(&mut self) {}
}

/// Per-ray counts: nodes visited (interior and leaf), leaves visited, triangles tested,
/// restarts. Also the GPU buffer layout of the counting kernels.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct Counters {
    pub nodes: u32,
    pub leaves: u32,
    pub tris: u32,
    pub restarts: u32,
}
impl Stats for Counters {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    #[inline(always)]
    fn tri(&mut self) {
        self.tris += 1;
    }
    #[inline(always)]
    fn restart(&mut self) {
        self.restarts += 1;
    }
}

