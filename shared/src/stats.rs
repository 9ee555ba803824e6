//! Traversal cost counters, shared by every acceleration structure: a traversal calls a `Stats`
//! sink at each node, leaf, triangle test and restart; `NoStats` compiles to nothing and
//! `Counters` is also the GPU buffer layout of the counting kernels.
use bytemuck::{Pod, Zeroable};

/// Traversal cost counters; `NoStats` compiles to nothing.
pub trait Stats {
    /// A node visited (interior or leaf).
    fn node(&mut self);
    /// A leaf visited.
    fn leaf(&mut self);
    /// A triangle tested.
    fn tri(&mut self);
    /// A restart.
    fn restart(&mut self);
}

/// Counts nothing.
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
    /// Nodes visited, interior and leaf.
    pub nodes: u32,
    /// Leaves visited.
    pub leaves: u32,
    /// Triangles tested.
    pub tris: u32,
    /// Restarts.
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

