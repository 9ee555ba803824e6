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
    /// Index of refraction of a `MAT_GLASS` material (0: the default, 1.5).
    pub ior: f32,
}

impl Material {
    /// The index of refraction glass uses: `ior`, or 1.5 when unset.
    #[inline(always)]
    pub fn ior(&self) -> f32 {
        if self.ior > 0.0 {
            self.ior
        } else {
            1.5
        }
    }
}

pub const LIGHT_TRIANGLE: u32 = 0;
pub const LIGHT_POINT: u32 = 1;
pub const LIGHT_SPOT: u32 = 2;

/// A light to sample for direct illumination and to emit photons from. Triangle lights: `p0`,
/// edges `e1`, `e2`, emitted radiance (front side: e1 × e2), `area`. Point lights: position `p0`,
/// intensity in `emission`. Spot lights: position `p0`, unit axis `e1`, `e2` = [cos of the
/// cone's half angle, cos of the angle where the falloff starts, 0], intensity on the axis in
/// `emission` (falling off smoothly to 0 at the cone's edge, as pbrt-v4's spot light).
/// `cdf` is the running sum of the direct-light selection probabilities (last light: 1),
/// `power_cdf` that of photon emission, proportional to power.
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
    pub power_cdf: f32,
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

/// `RenderParams::flags`: camera rays through a random point of the pixel, not its centre.
pub const RENDER_JITTER: u32 = 1;
/// Paths end at their first diffuse hit as a gather point for the photon map (`shade`).
pub const RENDER_GATHER: u32 = 2;
/// With `RENDER_GATHER`: no shadow ray; the photon map gives direct light too.
pub const RENDER_PHOTON_DIRECT: u32 = 4;

/// Push constants of the renderer's kernels (camera rays, path steps, accumulation).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RenderParams {
    /// Paths in this dispatch.
    pub count: u32,
    /// Index (in the camera's ray order) of the batch's first path.
    pub first: u32,
    /// Random stream of this sample (each sample of a pixel has its own).
    pub seed: u32,
    pub light_count: u32,
    /// Which bounce of the paths this dispatch shades (0 = primary hits).
    pub bounce: u32,
    /// The last bounce: a path still going then is shaded as if diffuse and ends.
    pub max_bounces: u32,
    /// Diffuse bounces a path continues through (0: direct lighting only).
    pub diffuse_bounces: u32,
    /// `RENDER_*` bits.
    pub flags: u32,
    pub camera: Camera,
    /// Which group of samples this is (0 writes the film, later ones add to it).
    pub sample: u32,
    /// Samples per pixel in this dispatch: `count` = pixels × `samples`, path i being sample
    /// i / pixels of pixel i % pixels (0 counts as 1).
    pub samples: u32,
    pub _pad: [u32; 2],
}

impl RenderParams {
    /// Samples per pixel of the dispatch (at least 1).
    #[inline(always)]
    pub fn samples(&self) -> u32 {
        if self.samples == 0 {
            1
        } else {
            self.samples
        }
    }
    /// Pixels of the dispatch.
    #[inline(always)]
    pub fn pixels(&self) -> u32 {
        self.count / self.samples()
    }
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

/// `PathState::flags`: the path continues.
pub const PATH_ACTIVE: u32 = 1;
/// The path's last vertex was specular (or the camera): emission it hits counts (after a
/// diffuse vertex the shadow ray has counted it).
pub const PATH_SPECULAR: u32 = 2;
/// The path ended at a gather point, left in its ray slot (`shade::gather_point`).
pub const PATH_GATHER: u32 = 4;
/// Diffuse bounces so far, from this bit up.
pub const PATH_DIFFUSE_SHIFT: u32 = 8;

/// A pixel sample's path: what its next hit is worth (`throughput`), the radiance gathered so
/// far, and its state (`PATH_*` bits).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PathState {
    pub throughput: [f32; 3],
    pub flags: u32,
    pub radiance: [f32; 3],
    /// The path's random stream: its pixel, plus the sample within the dispatch times the
    /// image's pixel count.
    pub pixel: u32,
}

impl PathState {
    pub const fn start(pixel: u32) -> PathState {
        PathState { throughput: [1.0; 3], flags: PATH_ACTIVE | PATH_SPECULAR, radiance: [0.0; 3], pixel }
    }
    #[inline(always)]
    pub fn is_active(&self) -> bool {
        self.flags & PATH_ACTIVE != 0
    }
}

/// `PhotonParams::flags`: photons that reach a diffuse surface straight from a light are stored
/// (everything from the photon map); otherwise only those that bounced before (shadow rays
/// give direct light).
pub const PHOTON_STORE_DIRECT: u32 = 1;

/// Push constants of the photon tracing kernels (`photon`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PhotonParams {
    /// Photons in this dispatch.
    pub count: u32,
    /// Index in the pass of the dispatch's first photon.
    pub first: u32,
    /// Photons emitted in the whole pass (each carries 1/emitted of the lights' power).
    pub emitted: u32,
    /// Random stream of the pass (a function of the render's seed and the pass index only).
    pub seed: u32,
    pub light_count: u32,
    /// Which bounce this dispatch handles (0: hits of emitted photons).
    pub bounce: u32,
    pub max_bounces: u32,
    /// `PHOTON_*` bits.
    pub flags: u32,
    /// Room in the photon records (photons past it are counted, not stored).
    pub capacity: u32,
    /// 0: every photon draws its own samples. Otherwise photons come in groups of 32 that
    /// share one sample, each shifted by its lane's point of a rank-1 lattice scaled by
    /// `spread` (modulo 1): every photon's marginal distribution is still exactly the lights'.
    pub spread: f32,
    /// The specular materials' photons go to the caustic map (1) or the global one (0).
    pub caustic_map: u32,
    pub _pad: u32,
    /// The scene box (the kd-tree's root cell) for `photon::trace_photon`.
    pub bounds_min: [f32; 3],
    pub _pad1: u32,
    pub bounds_max: [f32; 3],
    pub _pad2: u32,
}

/// `PhotonPath::flags`: the photon is still travelling.
pub const PHOTON_ACTIVE: u32 = 1;
/// Every bounce so far was specular (a caustic photon once it bounced at all).
pub const PHOTON_SPECULAR_ONLY: u32 = 2;

/// A photon in flight: its power (RGB, watts) and state.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PhotonPath {
    pub power: [f32; 3],
    pub flags: u32,
}

/// A stored photon, 20 bytes: position, power as shared-exponent RGB (RGB9E5), and `packed` =
/// the surface normal on the side the photon arrived from (octahedral, 2 × 8 bits), the
/// direction it came from (octahedral, 2 × 7 bits, bits 16..30) and whether it is a caustic
/// photon (bit 30).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Photon {
    pub position: [f32; 3],
    pub power: u32,
    pub packed: u32,
}

/// `IndexParams::kind`: hashed uniform grid of cell size 2r.
pub const INDEX_GRID: u32 = 0;
/// Cells from the geometry kd-tree's leaves, each subdivided to about 2r.
pub const INDEX_KD: u32 = 1;

/// `IndexParams::filter`: constant kernel 1/(πr²).
pub const FILTER_CONSTANT: u32 = 0;
/// Cone filter (Jensen, k = 1): weight 1 − d/r, normalised by 3/(πr²).
pub const FILTER_CONE: u32 = 1;
/// Epanechnikov: weight 1 − d²/r², normalised by 2/(πr²).
pub const FILTER_EPANECHNIKOV: u32 = 2;

/// Push constants of the photon index and gather kernels.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct IndexParams {
    /// Items of this dispatch: photon slots (index) or paths (gather).
    pub count: u32,
    /// Cells of one map; the caustic map's cells follow the global map's.
    pub cells: u32,
    /// `INDEX_GRID` or `INDEX_KD`.
    pub kind: u32,
    /// Maps: 1 (global) or 2 (global and caustic).
    pub maps: u32,
    /// Gather radius of the global and the caustic map.
    pub radius: [f32; 2],
    /// `FILTER_*`.
    pub filter: u32,
    pub _pad: u32,
    /// The scene box (the grid's origin, the kd-tree's root cell).
    pub bounds_min: [f32; 3],
    pub _pad0: u32,
    pub bounds_max: [f32; 3],
    pub _pad1: u32,
}

/// A kd-tree leaf's cells in the photon index (`INDEX_KD`), one per node (interior nodes'
/// have `dims` 0): the leaf's box, its first cell and its subdivision (`dims` = nx | ny << 10 |
/// nz << 20, each 1..1023).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LeafCells {
    pub lo: [f32; 3],
    pub base: u32,
    pub hi: [f32; 3],
    pub dims: u32,
}
