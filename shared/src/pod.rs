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
    /// First vertex.
    pub v0: [f32; 3],
    /// Index into the material buffer.
    pub material: u32,
    /// Second vertex.
    pub v1: [f32; 3],
    /// Index of the face in the source mesh.
    pub face: u32,
    /// Third vertex.
    pub v2: [f32; 3],
    /// Padding to a 16-byte multiple.
    pub _pad: u32,
}

/// Closest-hit result: distance, primitive index (`MISS` for none) and barycentrics of v1, v2.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct Hit {
    /// Ray parameter of the hit (`origin + t·dir`); infinity for a miss.
    pub t: f32,
    /// Index of the hit triangle, or `MISS`.
    pub prim: u32,
    /// Barycentric weight of `v1`.
    pub b1: f32,
    /// Barycentric weight of `v2`.
    pub b2: f32,
}

impl Hit {
    /// No hit: `t` infinite, `prim` = `MISS`.
    pub const NONE: Hit = Hit { t: f32::INFINITY, prim: MISS, b1: 0.0, b2: 0.0 };
    /// Whether a triangle was hit (`prim` is not `MISS`).
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

/// `Material::flags` bit: a perfect mirror (reflectance `diffuse`).
pub const MAT_MIRROR: u32 = 1;
/// `Material::flags` bit: a smooth dielectric that reflects or refracts (Fresnel, index `ior`).
pub const MAT_GLASS: u32 = 2;

/// A surface's material: Lambertian albedo, mirror / glass flags, emission, index of refraction.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Material {
    /// Lambertian albedo (RGB); a mirror's reflectance.
    pub diffuse: [f32; 3],
    /// `MAT_MIRROR`, `MAT_GLASS` bits.
    pub flags: u32,
    /// Radiance emitted from the triangle's front side (RGB).
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

/// `Light::kind`: an emissive triangle (front side only).
pub const LIGHT_TRIANGLE: u32 = 0;
/// `Light::kind`: a point light, emitting equally in every direction.
pub const LIGHT_POINT: u32 = 1;
/// `Light::kind`: a spot light, a point light limited to a cone.
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
    /// Triangle: its first vertex. Point and spot lights: the position.
    pub p0: [f32; 3],
    /// `LIGHT_TRIANGLE`, `LIGHT_POINT` or `LIGHT_SPOT`.
    pub kind: u32,
    /// Triangle: the edge v1 − v0. Spot light: the unit cone axis.
    pub e1: [f32; 3],
    /// Running sum of the direct-light selection probabilities, up to and including this light.
    pub cdf: f32,
    /// Triangle: the edge v2 − v0. Spot light: [cos of the cone's half angle, cos of the angle
    /// where the falloff starts, 0].
    pub e2: [f32; 3],
    /// Triangle: its area. Point and spot lights: unused (0).
    pub area: f32,
    /// Triangle: emitted radiance (RGB). Point light: intensity. Spot light: intensity on the axis.
    pub emission: [f32; 3],
    /// Running sum of the photon-emission selection probabilities (proportional to power).
    pub power_cdf: f32,
}

/// Pinhole camera: ray through pixel (x, y) has direction `top_left + (x+½)·du + (y+½)·dv`.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Camera {
    /// The eye: where every primary ray starts.
    pub origin: [f32; 3],
    /// Image width in pixels.
    pub width: u32,
    /// Direction from `origin` to the image's top-left corner (not normalised).
    pub top_left: [f32; 3],
    /// Image height in pixels.
    pub height: u32,
    /// Direction step from a pixel to its right neighbour.
    pub du: [f32; 3],
    /// The order in which pixels are traced: `ORDER_SCANLINE` or `ORDER_TILES`.
    pub order: u32,
    /// Direction step from a pixel to the one below it.
    pub dv: [f32; 3],
    /// Padding to a 16-byte multiple.
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
    /// Padding: aligns `bounds_min` to 16 bytes.
    pub _pad: [u32; 2],
    /// Minimum corner of the scene box.
    pub bounds_min: [f32; 3],
    /// Padding: aligns `bounds_max` to 16 bytes.
    pub _pad1: u32,
    /// Maximum corner of the scene box.
    pub bounds_max: [f32; 3],
    /// Padding to a 16-byte multiple.
    pub _pad2: u32,
}

/// Parameters of the rasterised primary hits (`raster`): the camera, its projection and the
/// visibility buffer's layout.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RasterParams {
    /// The camera whose primary rays are resolved (and whose image is drawn).
    pub camera: Camera,
    /// The projection (`RasterParams::new`): rows giving, for a point q relative to the eye,
    /// its distance along the camera's axis and its pixel coordinates times 2 / size, times
    /// that distance (the fourth components are 0).
    pub rows: [[f32; 4]; 3],
    /// Rays to resolve in this dispatch (the camera's first `count`, in its order).
    pub count: u32,
    /// Triangles drawn (the draw has three vertices per triangle).
    pub triangles: u32,
    /// Words per row of the visibility buffer (`raster::row_words`).
    pub row_words: u32,
    /// Depth of the near clipping plane along the camera's axis, in units of `top_left`.
    pub near: f32,
}

/// `RenderParams::flags`: camera rays through a random point of the pixel, not its centre.
pub const RENDER_JITTER: u32 = 1;
/// Paths end at their first diffuse hit as a gather point for the photon map (`shade`).
pub const RENDER_GATHER: u32 = 2;
/// With `RENDER_GATHER`: no shadow ray; the photon map gives direct light too.
pub const RENDER_PHOTON_DIRECT: u32 = 4;
/// The paths resume from their gather points (`render::resume`: one cosine-weighted diffuse
/// bounce, the final gather) instead of leaving the camera; emission they hit does not count
/// (shadow rays and the caustic map at the first gather point have counted it).
pub const RENDER_CONTINUE: u32 = 8;
/// Each pixel's numbers come from its own scrambled Sobol sequence (`sampler`), sample
/// `sample_base + s` for the dispatch's sample s, instead of independent random numbers.
pub const RENDER_SOBOL: u32 = 16;
/// The paths' camera rays are through the pixel centres of `camera` (no `RENDER_JITTER`) and
/// their closest hits are given: the whole-path kernels read bounce 0's hit from
/// `primary_hits` (written by the rasterised primary hits, `raster`) instead of tracing it.
pub const RENDER_PRIMARY_GIVEN: u32 = 32;
/// With `RENDER_CONTINUE`: the flags' bits from here up hold the final gather's level, the
/// bounces from the eye path's first gather point (1, or more where a resumed path's gather
/// point was near an edge again and resumed once more: `render::resume_level`). Each level
/// draws from sampler dimensions of its own.
pub const RENDER_LEVEL_SHIFT: u32 = 8;

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
    /// Lights in the light buffer.
    pub light_count: u32,
    /// Which bounce of the paths this dispatch shades (0 = primary hits).
    pub bounce: u32,
    /// The last bounce: a path still going then is shaded as if diffuse and ends.
    pub max_bounces: u32,
    /// Diffuse bounces a path continues through (0: direct lighting only).
    pub diffuse_bounces: u32,
    /// `RENDER_*` bits.
    pub flags: u32,
    /// The camera the primary rays come from.
    pub camera: Camera,
    /// Which group of samples this is (0 writes the film, later ones add to it).
    pub sample: u32,
    /// Samples per pixel in this dispatch: `count` = pixels × `samples`, path i being sample
    /// i / pixels of pixel i % pixels (0 counts as 1).
    pub samples: u32,
    /// With `RENDER_SOBOL`: the index, in each pixel's sequence, of the dispatch's first
    /// sample (e.g. pass × eye samples per pass).
    pub sample_base: u32,
    /// With `RENDER_SOBOL`: the seed of the pixels' scrambles, the same for every dispatch of
    /// one render (so that its samples continue one sequence per pixel).
    pub sequence: u32,
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
    /// Items to sort (keys).
    pub count: u32,
    /// Cells: keys below it are sorted, others left out. For the passes over a level of the
    /// scan, the level's elements.
    pub cells: u32,
    /// Keys per segment when the offsets come by segments (`sort::segment_offsets`), else 0.
    pub segment: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

/// Push constants of the linear BVH build's kernels (`bvh::build`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LbvhParams {
    /// Triangles.
    pub count: u32,
    /// The range tree's level (`reduce`) or the wide tree's (`collapse`).
    pub level: u32,
    /// Bits of the Morton code that the counting sort sorts by (its top ones; at most 30).
    pub cell_bits: u32,
    /// The range tree's root entry (the scene's box).
    pub root: u32,
}

/// An axis-aligned box of the BVH build (`bvh::build`): 24 bytes.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BuildBox {
    /// Lower corner.
    pub lo: [f32; 3],
    /// Upper corner.
    pub hi: [f32; 3],
}

/// Push constants of simple per-item kernels (`rng_fill`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ItemParams {
    /// Items in this dispatch.
    pub count: u32,
    /// Index of the dispatch's first item.
    pub first: u32,
    /// Seed of the random streams.
    pub seed: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

/// What shading needs after the shadow ray: radiance reaching the eye regardless of the shadow
/// ray (`base`: emission) and the direct light if the shadow ray is unoccluded (`direct`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadeTerms {
    /// Radiance reaching the eye whatever the shadow ray finds (emission hit), times the path's
    /// throughput (RGB).
    pub base: [f32; 3],
    /// Padding: aligns `direct` to 16 bytes.
    pub _pad0: u32,
    /// Direct light the shadow ray brings if unoccluded, times the path's throughput (RGB).
    pub direct: [f32; 3],
    /// Padding to a 16-byte multiple.
    pub _pad1: u32,
}

/// `PathState::flags`: the path continues.
pub const PATH_ACTIVE: u32 = 1;
/// The path's last vertex was specular (or the camera): emission it hits counts (after a
/// diffuse vertex the shadow ray has counted it).
pub const PATH_SPECULAR: u32 = 2;
/// The path ended at a gather point, left in its ray slot (`shade::gather_point`).
pub const PATH_GATHER: u32 = 4;
/// `PathState::flags`: the gather point's disc reaches past its surface (`photon::mark_edges`).
pub const PATH_NEAR_EDGE: u32 = 16;
/// Diffuse bounces so far, from this bit up.
pub const PATH_DIFFUSE_SHIFT: u32 = 8;

/// A pixel sample's path: what its next hit is worth (`throughput`), the radiance gathered so
/// far, and its state (`PATH_*` bits).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PathState {
    /// RGB factor on the radiance that the path's next hit sends back along it.
    pub throughput: [f32; 3],
    /// `PATH_*` bits; the diffuse bounces so far from `PATH_DIFFUSE_SHIFT` up.
    pub flags: u32,
    /// Radiance gathered so far (RGB).
    pub radiance: [f32; 3],
    /// The path's random stream: its pixel, plus the sample within the dispatch times the
    /// image's pixel count.
    pub pixel: u32,
}

impl PathState {
    /// A new path of random stream `pixel`: throughput 1, active and specular (the camera), no
    /// radiance.
    pub const fn start(pixel: u32) -> PathState {
        PathState { throughput: [1.0; 3], flags: PATH_ACTIVE | PATH_SPECULAR, radiance: [0.0; 3], pixel }
    }
    /// Whether the path continues (`PATH_ACTIVE`).
    #[inline(always)]
    pub fn is_active(&self) -> bool {
        self.flags & PATH_ACTIVE != 0
    }
}

/// `PhotonParams::flags`: photons that reach a diffuse surface straight from a light are stored
/// (everything from the photon map); otherwise only those that bounced before (shadow rays
/// give direct light).
pub const PHOTON_STORE_DIRECT: u32 = 1;
/// `PhotonParams::flags`: photons draw from the render's scrambled Sobol sequences
/// (`sampler::Sampler::photon`, `photon_group`) instead of independent random numbers.
pub const PHOTON_SOBOL: u32 = 2;

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
    /// Lights in the light buffer.
    pub light_count: u32,
    /// Which bounce this dispatch handles (0: hits of emitted photons).
    pub bounce: u32,
    /// The last bounce: a photon is still stored there (at a diffuse surface) but not continued.
    pub max_bounces: u32,
    /// `PHOTON_*` bits.
    pub flags: u32,
    /// Room in the photon records (photons past it are counted, not stored).
    pub capacity: u32,
    /// 0: every photon draws its own samples. Otherwise photons come in groups of 32 that
    /// share one sample, each shifted by its lane's point of a rank-1 lattice scaled by
    /// `spread` (modulo 1): every photon's marginal distribution is still exactly the lights'.
    pub spread: f32,
    /// Photons that reached a diffuse surface through specular bounces only go to the caustic
    /// map (1) or to the global one (0).
    pub caustic_map: u32,
    /// The pass's index (with `PHOTON_SOBOL`: where its photons start in the sequences).
    pub pass: u32,
    /// The scene box (the kd-tree's root cell) for `photon::trace_photons`.
    pub bounds_min: [f32; 3],
    /// With `PHOTON_SOBOL`: the seed of the render's photon sequences' scrambles (the same for
    /// every pass).
    pub sequence: u32,
    /// Maximum corner of the scene box.
    pub bounds_max: [f32; 3],
    /// Items of a whole-path dispatch (`photon::trace_photons`): item i traces photons i,
    /// i + stride, … of the dispatch; 0: one photon per item (`count` items).
    pub stride: u32,
}

/// `PhotonPath::flags`: the photon is still travelling.
pub const PHOTON_ACTIVE: u32 = 1;
/// Every bounce so far was specular (a caustic photon once it bounced at all).
pub const PHOTON_SPECULAR_ONLY: u32 = 2;

/// A photon in flight: its power (RGB, watts) and state.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PhotonPath {
    /// Power carried (RGB, watts).
    pub power: [f32; 3],
    /// `PHOTON_*` bits.
    pub flags: u32,
}

/// A stored photon, 20 bytes: position, power as shared-exponent RGB (RGB9E5), and `packed` =
/// the surface normal on the side the photon arrived from (octahedral, 2 × 8 bits), the
/// direction it came from (octahedral, 2 × 7 bits, bits 16..30), whether it is a caustic
/// photon (bit 30) and whether it came straight from a light (bit 31).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Photon {
    /// Where the photon landed.
    pub position: [f32; 3],
    /// Power (RGB) as RGB9E5 (`photon::encode_rgb9e5`).
    pub power: u32,
    /// Normal, incoming direction, caustic and direct bits (layout in the struct's description).
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
    /// The hashed grid's window (`photon::HashGrid`, `photon::grid_windows`): 3 (cells of size
    /// r), 2 (cells of 2r), or 5, 7 or 9 (cells of r across the rows, r/2, r/3 or r/4 along
    /// them).
    pub grid: u32,
    /// The scene box (the grid's origin, the kd-tree's root cell).
    pub bounds_min: [f32; 3],
    /// The first map a gather sums (maps `first_map..maps`): 0 for all, 1 for the caustic map
    /// alone.
    pub first_map: u32,
    /// Maximum corner of the scene box.
    pub bounds_max: [f32; 3],
    /// `GATHER_*` bits.
    pub gather_flags: u32,
    /// The photon words' power range (`photon::word_power`): powers below 2^`power_top` (and
    /// down to 2^(`power_top` − 31)) are held with 6 or 5 bits of mantissa a channel, smaller
    /// ones are dithered to 0 or the smallest. Clamped to `photon::POWER_TOP` (default 0:
    /// powers below 1). The host sets it from the lights' power per emitted photon.
    pub power_top: i32,
    /// Padding to a 16-byte multiple.
    pub _pad: [u32; 3],
}

/// `IndexParams::gather_flags`: final gathering near edges only. A gather point marked
/// `PATH_NEAR_EDGE` (`photon::mark_edges`: its disc reaches a surface of another orientation, a
/// corner or a crease, or an open edge, where the disc reaches past its surface and the
/// estimate is biased low) takes only the caustic map and stays a gather point, to be resumed
/// by the final gather; any other takes every map and ends.
pub const GATHER_EDGES: u32 = 2;
/// `IndexParams::gather_flags`: the gather's items are the paths listed in its `points`
/// buffer (item i gathers for path `points[1 + i]`, i < `points[0]`), as the first gather of
/// `GATHER_EDGES` listed them: the final gather's second gathers run as a dense dispatch of the
/// points near edges (an indirect one, `kernel::dispatch_args`) instead of over every path.
pub const GATHER_LISTED: u32 = 4;

/// A kd-tree leaf's cells in the photon index (`INDEX_KD`), one per node (interior nodes'
/// have `dims` 0): the leaf's box, its first cell and its subdivision (`dims` = nx | ny << 10 |
/// nz << 20, each 1..1023).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LeafCells {
    /// Minimum corner of the leaf's box.
    pub lo: [f32; 3],
    /// Number of the leaf's first cell in a map; its cells follow, x fastest, then y, then z.
    pub base: u32,
    /// Maximum corner of the leaf's box.
    pub hi: [f32; 3],
    /// Cells along x, y and z: nx | ny << 10 | nz << 20 (0 for interior nodes).
    pub dims: u32,
}
