//! Buffer layouts shared by host and kernels: `#[repr(C)]`, `Pod`, scalars and scalar arrays
//! only (std430-compatible, no padding surprises). Sizes are compile-time assertions (`sizes`).
use bytemuck::{Pod, Zeroable};

/// `Hit::prim` of a ray that hit nothing.
pub const MISS: u32 = u32::MAX;

/// A triangle as stored for intersection: three vertices, its material id and the index of the
/// face in the source mesh (after degenerate triangles were dropped).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Triangle {
    pub v0: [f32; 3],
    pub material: u32,
    pub v1: [f32; 3],
    pub face: u32,
    pub v2: [f32; 3],
    pub _pad: u32,
}

/// Closest-hit result: distance, primitive index (`MISS` for none) and barycentrics of v1, v2.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub b1: f32,
    pub b2: f32,
}

impl Hit {
    pub const NONE: Hit = Hit { t: f32::INFINITY, prim: MISS, b1: 0.0, b2: 0.0 };
    #[inline(always)]
    pub fn is_hit(&self) -> bool {
        self.prim != MISS
    }
}

impl Default for Hit {
    fn default() -> Self {
        Self::NONE
    }
}

pub const MAT_MIRROR: u32 = 1;
pub const MAT_GLASS: u32 = 2;

#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Material {
    pub diffuse: [f32; 3],
    /// `MAT_MIRROR`, `MAT_GLASS` bits.
    pub flags: u32,
    pub emission: [f32; 3],
    pub _pad: u32,
}

pub const LIGHT_TRIANGLE: u32 = 0;
pub const LIGHT_POINT: u32 = 1;

/// A light to sample for direct illumination. Triangle lights: `p0`, edges `e1`, `e2`,
/// emitted radiance (two-sided). Point lights: position `p0`, intensity in `emission`.
/// `cdf` is the running sum of selection probabilities (last light: 1).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Light {
    pub p0: [f32; 3],
    pub kind: u32,
    pub e1: [f32; 3],
    pub cdf: f32,
    pub e2: [f32; 3],
    pub area: f32,
    pub emission: [f32; 3],
    pub _pad: u32,
}

/// Pinhole camera: ray through pixel (x, y) has direction `top_left + (x+½)·du + (y+½)·dv`.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Camera {
    pub origin: [f32; 3],
    pub width: u32,
    pub top_left: [f32; 3],
    pub height: u32,
    pub du: [f32; 3],
    /// The order in which pixels are traced: `ORDER_SCANLINE` or `ORDER_TILES`.
    pub order: u32,
    pub dv: [f32; 3],
    pub _pad1: u32,
}

/// Pixels in rows, top row first.
pub const ORDER_SCANLINE: u32 = 0;
/// 8×8 tiles in rows, Morton (Z-curve) order inside a tile: 4 consecutive rays form a 2×2 quad,
/// 32 an 8×4 half tile (see `camera::pixel`).
pub const ORDER_TILES: u32 = 1;

/// Parameters of the ray-query kernels (closest / any hit, packets, the decomposed pipeline;
/// a small storage buffer, binding `params`): how many rays, the scene box (the structure's root cell) and the leaf-list
/// capacity of the decomposed pipeline.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TraceParams {
    /// Rays in this dispatch.
    pub count: u32,
    /// Entries per ray of the decomposed pipeline's leaf lists.
    pub leaf_capacity: u32,
    pub _pad: [u32; 2],
    pub bounds_min: [f32; 3],
    pub _pad1: u32,
    pub bounds_max: [f32; 3],
    pub _pad2: u32,
}

/// Push constants of the renderer's kernels (camera rays, path steps, accumulation).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RenderParams {
    /// Paths in this dispatch.
    pub count: u32,
    /// Index (in the camera's ray order) of the batch's first path.
    pub first: u32,
    pub seed: u32,
    pub light_count: u32,
    /// Which bounce of the paths this dispatch shades (0 = primary hits).
    pub bounce: u32,
    /// Mirror reflections followed before a path is shaded as diffuse.
    pub max_bounces: u32,
    pub _pad: [u32; 2],
    pub camera: Camera,
}

/// Push constants of the counting sort's kernels (`sort`): items, cells, and the distance of a
/// scan step.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SortParams {
    pub count: u32,
    pub cells: u32,
    pub step: u32,
    pub _pad: u32,
}

/// Push constants of simple per-item kernels (`rng_fill`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ItemParams {
    pub count: u32,
    pub first: u32,
    pub seed: u32,
    pub _pad: u32,
}

/// What shading needs after the shadow ray: radiance reaching the eye regardless of the shadow
/// ray (`base`: emission) and the direct light if the shadow ray is unoccluded (`direct`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadeTerms {
    pub base: [f32; 3],
    pub _pad0: u32,
    pub direct: [f32; 3],
    pub _pad1: u32,
}

/// A pixel's path through mirrors: what its next hit is worth (`throughput`), the radiance
/// gathered so far, and whether it still continues.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PathState {
    pub throughput: [f32; 3],
    pub active: u32,
    pub radiance: [f32; 3],
    /// The pixel this path belongs to (its random stream).
    pub pixel: u32,
}

impl PathState {
    pub const fn start(pixel: u32) -> PathState {
        PathState { throughput: [1.0; 3], active: 1, radiance: [0.0; 3], pixel }
    }
}
