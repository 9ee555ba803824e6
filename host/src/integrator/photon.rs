//! Progressive photon mapping (Knaus & Zwicker 2011) on either runtime, in passes of bounded
//! memory, after Frolov & Ignatenko's GPU scheme. Each pass, a function of its index and the
//! scene only:
//!
//! 1. **trace** — `photons` photons leave the lights (`photon::emit`), then per bounce a
//!    closest-hit query and `photon::bounce` (store at diffuse hits, Russian roulette);
//! 2. **index** — every stored photon's cell (hashed grid or kd leaves) and rank in it, the
//!    cells' offsets on the device (`sort::CountingSort`: by segments of a grid block's cells,
//!    or exact for the kd index's), the records placed in cell order;
//! 3. **eye** — one jittered sample per pixel through specular bounces to a diffuse gather
//!    point, direct light by a shadow ray (or from the photon map);
//! 4. **gather** — the photons within the pass's radius at each gather point, added to the
//!    film. With final gathering (`FinalGather`) the first gather point takes the caustic map
//!    only (everywhere, or near edges only); the paths then resume by one diffuse bounce to a
//!    second point, which takes direct light by a shadow ray and the rest from the maps.
//!
//! The radius shrinks from pass to pass, r²ᵢ₊₁ = r²ᵢ (i + α)/(i + 1), so the average of the
//! passes converges to the right answer; memory does not grow with the number of passes. A
//! pass is one submission; the record buffer is sized with a margin and grows should a pass
//! store more, which the host sees one pass late (the render then goes back to its last
//! checkpoint: passes are deterministic, so the image is the same).
use super::path::{self, FrameBuffers, PathOptions};
use super::{share, Progress, RenderOutput, SamplerKind};
use crate::accel::{Accel, Structure};
use crate::kdtree::KdTreeData;
use crate::kernels::{DispatchArgs, EmitPhotons, Film, Gather, IndexBinds, MarkEdges, PhotonBounce, PhotonKeys, PlacePhotons, TraceMethod, TracePhotons};
use crate::scene::{open_edges, Scene};
use crate::runtime::{cast, Buffer, Kernel, Pending, Runtime};
use crate::sort::CountingSort;
use crate::tracer::{LeafLists, Tracer};
use crate::error::{bail, err, Result};
use kdray_shared::kdtree::KdNode;
use kdray_shared::photon::PhotonWord;
use kdray_shared::query::Closest;
use kdray_shared::rng::pcg_hash;
use kdray_shared::{
    Camera, Hit, IndexParams, LeafCells, Light, Photon, PhotonParams, PhotonPath, Ray, RenderParams, FILTER_CONSTANT, GATHER_EDGES, INDEX_GRID, INDEX_KD, ORDER_TILES,
    GATHER_LISTED, PHOTON_SOBOL, PHOTON_STORE_DIRECT, RENDER_CONTINUE, RENDER_GATHER, RENDER_JITTER, RENDER_LEVEL_SHIFT, RENDER_PHOTON_DIRECT, RENDER_SOBOL,
};
use std::collections::VecDeque;
use std::time::Instant;

/// Which photon index: the paper's kd-tree leaves subdivided to about the radius, or a hashed
/// uniform grid of cells of about r or 2r (`PhotonOptions::grid_window`).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum IndexKind {
    /// Hashed uniform grid of cells of about r or 2r.
    Grid,
    /// The geometry kd-tree's leaves, each split into cells of about 2r (needs the tree).
    Kd,
}

/// The default spread of coherent photon groups: the 32 photons of a group leave from within
/// a tenth of the light's sample space of each other (a lattice scaled by 0.1, shifted
/// toroidally, so each photon's distribution is still exactly the light's), so a SIMD group
/// traces nearby rays. Measured on the H100 (512², 256 passes × 4 eye samples, one run): the
/// Cornell box in 1.53 s against 1.78 s with independent photons, the glass-sphere box in
/// 2.69 s against 2.85 s, at the same error; smaller spreads gain a little more speed and
/// lose accuracy in the glass-sphere box (caustic photons bunch up).
pub const COHERENT_SPREAD: f32 = 0.1;

/// Threads of a whole-path photon dispatch by default (`PhotonOptions::photon_threads`): 2^18,
/// four photons each in a pass of 2^20. On the H100 (2026-12-06, three runs each) 2^18 traced
/// the glass-sphere box's photon bounces 3–6 % faster than 2^17 (BVH 994–1 026 against 961–973
/// M/s) and rendered 2.3 % more passes in 4.85 s; the Cornell box within noise.
pub const PHOTON_THREADS: u32 = 1 << 18;

/// Where the eye paths' first diffuse points take their indirect light from.
///
/// A final gather takes, at the first diffuse point, direct light by a shadow ray and caustics
/// from the caustic map, then one cosine-weighted bounce to a second diffuse point, which takes
/// direct light by a shadow ray too and the rest from the photon maps: the density estimate's
/// bias, worst where the gather disc reaches past its surface at corners and edges, is
/// averaged over a hemisphere instead of seen directly, at the price of the bounce's noise and
/// an incoherent gather. (The maps hold no photons straight from the lights, as in every mode
/// but `photon_direct`: a second point's direct light by a shadow ray instead of direct
/// photons keeps the maps — and every gather's loop — to the indirect photons.)
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum FinalGather {
    /// The photon map read at the first diffuse point (direct visualisation, the paper's).
    Off,
    /// A final gather only where the first point's disc holds photons on surfaces of other
    /// orientations, normals more than 60° apart (a corner or an edge within the radius, but
    /// also the back of thin geometry or strongly curved surfaces: `GATHER_EDGES`); the photon
    /// map read directly everywhere else. Edges of less than 60° are not detected. A second
    /// point near an edge again bounces once more, up to `PhotonOptions::edge_levels`.
    Edges,
    /// A final gather at every first diffuse point.
    All,
}

/// What a photon-mapped render does.
#[derive(Clone, Debug)]
pub struct PhotonOptions {
    /// Photons emitted per pass.
    pub photons: u32,
    /// Passes (each: new photons, one eye sample per pixel, a smaller radius).
    pub passes: u32,
    /// Stop after the pass that ends past this many seconds (and the one already submitted
    /// behind it).
    pub time_limit: Option<f64>,
    /// Passes per unit of work (`render_on`): a device renders a unit's passes into a film of
    /// its own, which is then read back and added to the image. Fixed by the render, not by
    /// the devices, so the image is the same on any number of them; a failure loses at most
    /// the units in hand (another device renders them again). 0 (the default): `unit()`'s
    /// choice, at least `UNIT_PASSES` and at most 16 units a render.
    pub unit_passes: u32,
    /// The first pass's gather radius (scene units); default: about `PHOTONS_PER_GATHER` photons
    /// per gather.
    pub radius: Option<f32>,
    /// The caustic map's radius relative to the global map's.
    pub caustic_radius: f32,
    /// Knaus & Zwicker's α: 1 keeps the radius fixed.
    pub alpha: f32,
    /// Which photon index the passes build.
    pub index: IndexKind,
    /// The hashed grid's cells along x that a gather visits: 3 (cells of size r), 2 (cells
    /// of 2r), or 5, 7 (the default) or 9 (cells of r across x, of r/2, r/3 or r/4 along it);
    /// rows along x clipped to the query's sphere; see `kdray_shared::photon::HashGrid`.
    pub grid_window: u32,
    /// 0: independent photons; otherwise groups of 32 with lattice offsets of this spread
    /// (`COHERENT_SPREAD` by default).
    pub spread: f32,
    /// Everything from the photon map (the paper's way); otherwise direct light by shadow
    /// rays and only indirect light from the photon map. Needs `final_gather:
    /// FinalGather::Off` (a final gather takes direct light from shadow rays).
    pub photon_direct: bool,
    /// Final gathering, everywhere, near edges only, or not at all (`FinalGather`).
    pub final_gather: FinalGather,
    /// With `FinalGather::Edges`: the final gather's levels (1: one bounce from a first point
    /// near an edge to a second point, read there; 2 (the default): a second point near an
    /// edge again bounces once more, its photon estimate being as biased there as the first
    /// point's; and so on).
    pub edge_levels: u32,
    /// With `FinalGather::Edges`: each level's gather runs over a list of the points near edges
    /// (an indirect dispatch, `GatherPoints`) instead of over every eye path (the same image;
    /// off only to measure the difference).
    pub list_points: bool,
    /// `FILTER_*` of the gather.
    pub filter: u32,
    /// Photon bounces traced.
    pub photon_bounces: u32,
    /// Whole photon paths in one kernel where there is one (else a pass per bounce).
    pub fused: bool,
    /// Threads of a whole-path photon dispatch (`PhotonParams::stride`): each traces its share
    /// of the photons, the next as soon as one is absorbed (`PHOTON_THREADS` by default); 0:
    /// one photon per thread.
    pub photon_threads: u32,
    /// Specular bounces of eye paths.
    pub eye_bounces: u32,
    /// Eye samples per pixel and pass (all gather from the pass's photons).
    pub eye_samples: u32,
    /// `render` traces the pixels in 8×8 tiles (`ORDER_TILES`), whatever the camera's order: a
    /// subgroup's gathers then read nearly the same cells (the same image; H200, 512², 256
    /// passes: 7 % faster). Otherwise in the camera's order. (`eye_params` takes the camera as
    /// given.)
    pub tiles: bool,
    /// The render's seed: each pass's photons and eye samples derive from it and the pass index.
    pub seed: u32,
    /// Where the eye paths' numbers come from (each pixel's Sobol sequence runs on over the
    /// passes).
    pub sampler: SamplerKind,
    /// Where the photons' numbers come from (with `Sobol`, the coherent groups' emission
    /// samples and the photons' bounces run on over the passes as sequences of the render).
    /// Independent by default: Sobol photons gave no less error per pass and cost 15 % of the
    /// photon kernel's time (H200, docs/gpu-runs/2026-12-03-photon-direct-nee-h200.md).
    pub photon_sampler: SamplerKind,
}

impl Default for PhotonOptions {
    fn default() -> Self {
        PhotonOptions {
            photons: 1 << 20,
            passes: 16,
            time_limit: None,
            unit_passes: 0,
            radius: None,
            caustic_radius: 0.5,
            alpha: 2.0 / 3.0,
            index: IndexKind::Grid,
            grid_window: 7,
            spread: COHERENT_SPREAD,
            photon_direct: false,
            final_gather: FinalGather::Edges,
            edge_levels: 2,
            list_points: true,
            filter: FILTER_CONSTANT,
            photon_bounces: 16,
            fused: true,
            photon_threads: PHOTON_THREADS,
            eye_bounces: 16,
            eye_samples: 4,
            tiles: true,
            seed: 1,
            sampler: SamplerKind::Sobol,
            photon_sampler: SamplerKind::Independent,
        }
    }
}

/// What one render did.
#[derive(Clone, Debug, Default)]
pub struct PhotonStats {
    /// Passes run (fewer than asked when `time_limit` ended the render, or the caller through
    /// `Progress::cancelled`).
    pub passes: u32,
    /// Photons emitted, over all passes.
    pub emitted: u64,
    /// Photons stored in the map, over all passes.
    pub stored: u64,
    /// The last pass's gather radius (global map; 0 when no pass was rendered).
    pub last_radius: f32,
    /// Wall time from the first pass to the image read back, in seconds.
    pub seconds: f64,
    /// Why the render stopped early, if every device failed with units of passes still to
    /// render: what failed, and how. The image is then that of the units delivered (`passes`).
    pub interrupted: Option<String>,
    /// Each device that failed (its name and the error): its units were rendered by the
    /// others, or are missing (`interrupted`).
    pub failed: Vec<String>,
    /// Units of passes each device rendered (`render_on`'s order).
    pub per_device: Vec<u32>,
}

/// The seed of pass `pass`.
pub fn pass_seed(seed: u32, pass: u32) -> u32 {
    pcg_hash(seed.wrapping_mul(0x2545_F491) ^ pcg_hash(pass))
}

/// The global radius of pass `pass` (0-based) from the first pass's `r0`.
pub fn pass_radius(r0: f32, alpha: f32, pass: u32) -> f32 {
    let mut r2 = (r0 as f64).powi(2);
    for i in 1..=pass {
        r2 *= (i as f64 + alpha as f64) / (i as f64 + 1.0);
    }
    r2.sqrt() as f32
}

/// Photons a first pass's gather finds on average where they spread evenly over the scene's
/// surface: the default radius. 85 since the edges are found from the geometry (H200, 512²,
/// equal time, radius 7 against 5.4 (50 photons): Cornell box 0.985 → 0.840 %, glass sphere
/// 0.978 → 0.936 %; `docs/gpu-runs/2026-12-03-edge-geometry-h200.md`).
pub const PHOTONS_PER_GATHER: f64 = 85.0;

/// The kd index's data: each kd-tree node's box if it is a leaf, the leaves' cells on the
/// device, the tree's nodes on the device.
type KdIndexData<'t> = (Vec<Option<([f32; 3], [f32; 3])>>, Buffer<LeafCells>, &'t Buffer<KdNode>);

/// The photon map's device buffers and the scene-derived sizes.
pub struct PhotonMap<'t> {
    t: &'t Tracer<'t>,
    accel: Accel,
    /// The options the map was made with.
    pub o: PhotonOptions,
    batch: usize,
    rays: Buffer<Ray>,
    paths: Buffer<PhotonPath>,
    hits: Buffer<Hit>,
    lists: Option<LeafLists>,
    /// The last traced pass's stored photons, in slot order (`capacity` slots).
    pub records: Buffer<Photon>,
    /// The records' words (`PhotonWord`: position, normal, power) in cell order, after
    /// `record_index`.
    pub sorted: Buffer<PhotonWord>,
    /// One word: the photons the last trace stored, including those past `capacity` (counted,
    /// not stored).
    pub counter: Buffer<u32>,
    keys: Buffer<u32>,
    sort: CountingSort<'t>,
    /// Photon slots in `records`, `sorted` and the index (grown when a pass stores more).
    pub capacity: u32,
    /// Cells per map.
    cells: u32,
    maps: u32,
    bounds: ([f32; 3], [f32; 3]),
    /// The kd-tree's root cell (the traversals' scene box).
    tree_bounds: ([f32; 3], [f32; 3]),
    /// The kd index: each leaf's box (host), the cell table, the tree's nodes on the device.
    kd: Option<KdIndexData<'t>>,
    r0: f32,
    /// `IndexParams::power_top` (`power_top`).
    power_top: i32,
    /// Each triangle's open edges (`scene::open_edges`), with `FinalGather::Edges`.
    open_edges: Option<Buffer<u32>>,
}

/// `IndexParams::power_top` for passes of `emitted` photons from `lights`: two binades above
/// the largest channel of a photon's power as it leaves a light (`photon::emit_photon`: the
/// light's emission times its emitting factor, over its selection probability, power / total,
/// times `emitted`). A diffuse bounce does not raise a photon's largest channel (Russian
/// roulette by the largest albedo, at most 1), a mirror or glass neither, a spot light's
/// falloff not past 1; a spot light's solid angle may exceed the one its power counts (by less
/// than 2). So the words hold every photon's power (`photon::word_power`), 29 binades below it
/// at full precision. 0 without lights. (A material of albedo above 1 raises a photon's power,
/// and lights chosen uniformly, where their powers are unusable (`Scene::lights`), need not
/// follow their power: such photons may be clamped to the words' largest power.)
pub fn power_top(lights: &[Light], emitted: u32) -> i32 {
    use std::f64::consts::PI;
    let total: f64 = lights.iter().map(crate::scene::power).sum();
    let mut most = 0.0f64;
    for l in lights {
        let w = crate::scene::power(l);
        let factor = match l.kind {
            kdray_shared::LIGHT_POINT => 4.0 * PI,
            kdray_shared::LIGHT_SPOT => 2.0 * PI * (1.0 - l.e2[0] as f64),
            _ => PI * l.area as f64,
        };
        let m = l.emission.iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
        if w > 0.0 {
            most = most.max(m * factor * total / (w * emitted.max(1) as f64));
        }
    }
    if !(most > 0.0 && most.is_finite()) {
        return 0;
    }
    (most.log2().ceil() as i32 + 2).clamp(kdray_shared::photon::POWER_TOP[0], kdray_shared::photon::POWER_TOP[1])
}

/// Every node's box if it is a leaf (walking from the root cell).
fn leaf_boxes(nodes: &[KdNode], lo: [f32; 3], hi: [f32; 3]) -> Vec<Option<([f32; 3], [f32; 3])>> {
    let mut out = vec![None; nodes.len()];
    let mut stack = vec![(0usize, lo, hi)];
    while let Some((i, lo, hi)) = stack.pop() {
        let n = nodes[i];
        if n.is_leaf() {
            out[i] = Some((lo, hi));
            continue;
        }
        let (a, s, c) = (n.axis(), n.split(), n.first_child() as usize);
        let (mut hi_below, mut lo_above) = (hi, lo);
        hi_below[a] = s;
        lo_above[a] = s;
        stack.push((c, lo, hi_below));
        stack.push((c + 1, lo_above, hi));
    }
    out
}

/// The kd index's cell table for radius `r`: each leaf split into cells of about 2r (at least
/// one, at most 1023 per axis), coarser everywhere if that would exceed `budget` cells.
fn leaf_cells(boxes: &[Option<([f32; 3], [f32; 3])>], r: f32, budget: u64) -> Vec<LeafCells> {
    let mut size = 2.0 * r as f64;
    loop {
        let mut table = vec![LeafCells::default(); boxes.len()];
        let mut total: u64 = 0;
        for (e, b) in table.iter_mut().zip(boxes) {
            if let Some((lo, hi)) = b {
                let d: Vec<u32> = (0..3).map(|a| (((hi[a] - lo[a]) as f64 / size).ceil() as u32).clamp(1, 1023)).collect();
                *e = LeafCells { lo: *lo, base: total as u32, hi: *hi, dims: d[0] | (d[1] << 10) | (d[2] << 20) };
                total += d[0] as u64 * d[1] as u64 * d[2] as u64;
            }
        }
        if total <= budget || size > 1e30 {
            return table;
        }
        size *= ((total as f64 / budget as f64).cbrt()).max(1.05);
    }
}

impl<'t> PhotonMap<'t> {
    /// Buffers for `o.photons` photons per pass over `scene` (the one `t` was made with); `tree`
    /// is needed for the kd index.
    pub fn new(t: &'t Tracer<'t>, accel: Accel, tree: Option<&KdTreeData>, scene: &Scene, o: PhotonOptions) -> Result<Self> {
        t.check(accel)?;
        if !t.holds(scene) {
            bail!(InvalidInput: "the photon map's scene '{}' is not the one its tracer was made with", scene.name);
        }
        if o.photons == 0 || o.eye_samples == 0 || o.passes == 0 {
            bail!(InvalidInput: "photon mapping needs at least one photon, pass and eye sample per pass");
        }
        if !(o.alpha > 0.0 && o.alpha <= 1.0) {
            bail!(InvalidInput: "the radius reduction alpha must be in (0, 1], got {}", o.alpha);
        }
        if o.final_gather != FinalGather::Off && o.photon_direct {
            bail!(InvalidInput: "final gathering takes direct light from shadow rays: it cannot be combined with direct light from photons");
        }
        if o.final_gather == FinalGather::Edges && !(1..=8).contains(&o.edge_levels) {
            bail!(InvalidInput: "the final gather's levels must be between 1 and 8, got {}", o.edge_levels);
        }
        if !kdray_shared::photon::GRID_WINDOWS.contains(&o.grid_window) {
            bail!(InvalidInput: "the photon grid's window must be one of {:?} cells, got {}", kdray_shared::photon::GRID_WINDOWS, o.grid_window);
        }
        if let Some(r) = o.radius {
            if !(r.is_finite() && r > 0.0) {
                bail!(InvalidInput: "--radius must be a positive number, got {r}");
            }
        }
        let rt = t.rt;
        let batch = t.batch_size(accel, o.photons as usize);
        // The per-bounce schedule's buffers only where it runs (no whole-path kernel).
        let split = if o.fused && t.whole_path_method(accel, TracePhotons::PREFIX).is_some() { 1 } else { batch };
        // Stored photons per emitted one: about the number of diffuse bounces; sized up after
        // the first pass if needed.
        let capacity = o.photons.saturating_mul(2).max(1024);
        let maps = if t.has_specular { 2 } else { 1 };
        let (lo, hi) = t.bounds();
        let r0 = o.radius.unwrap_or_else(|| ((PHOTONS_PER_GATHER * scene.surface_area()) / (std::f64::consts::PI * o.photons as f64)).sqrt() as f32);
        // The open edges only where the final gather looks for edges.
        let open_edges = match o.final_gather {
            FinalGather::Edges => Some(rt.upload("open edges", &open_edges(&scene.triangles))?),
            _ => None,
        };
        let kd = match o.index {
            IndexKind::Grid => None,
            IndexKind::Kd => {
                let tree = tree.ok_or_else(|| err!(InvalidInput: "the kd photon index needs the scene's kd-tree (a kd traversal)"))?;
                let nodes = match &t.structure {
                    crate::tracer::AccelStructure::KdTree { nodes, .. } => nodes.whole().ok_or_else(|| {
                        err!(TooLarge: "the kd photon index needs the kd-tree's nodes in one storage buffer, and this scene's are split across {} (use the grid index)", nodes.parts().len())
                    })?,
                    _ => bail!(InvalidInput: "the kd photon index needs the kd-tree on the device: make the tracer with the scene's kd-tree"),
                };
                Some((leaf_boxes(&tree.nodes, tree.bounds.min, tree.bounds.max), rt.alloc("kd leaf cells", tree.nodes.len())?, nodes))
            }
        };
        let cells = Self::cells_for(o.index, capacity, o.grid_window, Self::leaf_count(&kd))?;
        let sort = Self::sort_for(rt, o.index, o.grid_window, cells, maps, capacity)?;
        Ok(PhotonMap {
            t,
            accel,
            batch,
            rays: rt.alloc("photon ray", split)?,
            paths: rt.alloc("photon path", split)?,
            hits: rt.alloc("photon hit", split)?,
            lists: t.leaf_lists(accel, split)?,
            records: rt.alloc("photon", capacity as usize)?,
            sorted: rt.alloc("sorted photon", capacity as usize)?,
            counter: rt.alloc("photon counter", 1)?,
            keys: rt.alloc("photon cell", capacity as usize)?,
            sort,
            capacity,
            cells,
            maps,
            bounds: (lo, hi),
            tree_bounds: t.trace_bounds(),
            kd,
            r0,
            power_top: power_top(&scene.lights(), o.photons),
            open_edges,
            o,
        })
    }

    /// Cells per map: the grid's buckets (a power of two of blocks of wx·w² cells,
    /// `grid_windows`, about the photon count), or the kd index's budget: twice the photons,
    /// and at least a cell per leaf of the tree (`leaves`; `leaf_cells` gives every leaf one at
    /// the least, so with fewer cells than leaves the leaves' cells would run past the
    /// offsets).
    fn cells_for(kind: IndexKind, capacity: u32, window: u32, leaves: u32) -> Result<u32> {
        Ok(match kind {
            IndexKind::Grid => {
                let [wx, w] = kdray_shared::photon::grid_windows(window);
                let block = wx * w * w;
                capacity.div_ceil(block).next_power_of_two().min(1 << 25) * block
            }
            IndexKind::Kd => {
                const MAX: u32 = 1 << 30;
                if leaves > MAX {
                    bail!(TooLarge: "the kd photon index needs a cell per leaf of the kd-tree, and its {leaves} leaves are more than {MAX} (use the grid index)");
                }
                capacity.saturating_mul(2).max(leaves).min(MAX)
            }
        })
    }

    /// The kd index's leaves (each takes at least one of its cells): the tree's leaves that
    /// hold a box; none for the grid.
    fn leaf_count(kd: &Option<KdIndexData<'_>>) -> u32 {
        kd.as_ref().map_or(0, |(boxes, _, _)| boxes.iter().filter(|b| b.is_some()).count() as u32)
    }

    /// The index's counting sort, as the kernels expect it (`photon::sort_params`: by segments
    /// of a grid block's wx·w² cells, each row of a gather's window within a block then one
    /// run; exact offsets for the kd index).
    fn sort_for(rt: &'t dyn Runtime, kind: IndexKind, window: u32, cells: u32, maps: u32, capacity: u32) -> Result<CountingSort<'t>> {
        let keys = cells.checked_mul(maps).ok_or_else(|| err!(TooLarge: "too many photon cells"))?;
        let kind = if kind == IndexKind::Kd { INDEX_KD } else { INDEX_GRID };
        match kdray_shared::photon::sort_params(&IndexParams { kind, grid: window, cells, maps, ..Default::default() }).segment {
            0 => CountingSort::new(rt, keys, capacity),
            seg => CountingSort::segmented(rt, keys, seg, capacity),
        }
    }

    fn grow(&mut self, stored: u32) -> Result<()> {
        let rt = self.t.rt;
        let capacity = (stored as u64 * 5 / 4).min(u32::MAX as u64 / 2) as u32;
        self.records = rt.alloc("photon", capacity as usize)?;
        self.sorted = rt.alloc("sorted photon", capacity as usize)?;
        self.keys = rt.alloc("photon cell", capacity as usize)?;
        self.capacity = capacity;
        self.cells = Self::cells_for(self.o.index, capacity, self.o.grid_window, Self::leaf_count(&self.kd))?;
        self.sort = Self::sort_for(rt, self.o.index, self.o.grid_window, self.cells, self.maps, capacity)?;
        Ok(())
    }

    /// Photons a pass's records hold room for (grown when a pass stores more).
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// The first pass's global radius.
    pub fn initial_radius(&self) -> f32 {
        self.r0
    }

    /// The photon-tracing parameters of pass `pass`; `count` and `first` are 0 (each dispatch
    /// sets its own).
    pub fn photon_params(&self, pass: u32) -> PhotonParams {
        PhotonParams {
            count: 0,
            first: 0,
            emitted: self.o.photons,
            seed: pass_seed(self.o.seed, pass),
            light_count: self.t.light_count,
            bounce: 0,
            max_bounces: self.o.photon_bounces,
            flags: if self.o.photon_direct { PHOTON_STORE_DIRECT } else { 0 }
                | if self.o.photon_sampler == SamplerKind::Sobol { PHOTON_SOBOL } else { 0 },
            pass,
            sequence: pcg_hash(self.o.seed ^ 0x9407_0145),
            capacity: self.capacity,
            spread: self.o.spread,
            caustic_map: (self.maps > 1) as u32,
            bounds_min: self.tree_bounds.0,
            bounds_max: self.tree_bounds.1,
            ..Default::default()
        }
    }

    /// The threads of a whole-path dispatch of `count` photons (`PhotonParams::stride`):
    /// `photon_threads`, at most one per photon; on a software driver at most 64 photons per
    /// thread (lavapipe ends an item silently after about 65 535 loop iterations in all).
    pub fn stride(&self, count: u32) -> u32 {
        let threads = match self.o.photon_threads {
            0 => count,
            t if self.t.rt.is_software() => t.max(count.div_ceil(64)),
            t => t,
        };
        threads.min(count)
    }

    /// The whole-path photon kernel for `p`, when `fused` is on and there is one
    /// (`Tracer::whole_path_method`).
    fn fused(&self, p: PhotonParams) -> Option<TracePhotons<'_>> {
        if !self.o.fused {
            return None;
        }
        let t = self.t;
        let method = t.whole_path_method(self.accel, TracePhotons::PREFIX)?;
        TracePhotons::new(method, p, &t.lights, t.scene_binds(self.accel), &t.materials, &self.records, &self.counter)
    }

    /// The bounce pass of the photons of dispatch `p` at bounce `bounce`.
    fn bounce_pass(&self, p: PhotonParams, bounce: u32) -> PhotonBounce<'_> {
        let t = self.t;
        PhotonBounce {
            params: PhotonParams { bounce, ..p },
            rays: &self.rays,
            hits: &self.hits,
            tris: &t.tris,
            materials: &t.materials,
            paths: &self.paths,
            photons: &self.records,
            counter: &self.counter,
        }
    }

    /// Records tracing pass `pass`'s photons into `c`: records and counter filled. One kernel
    /// per batch of photons where there is a whole-path kernel (`fused`), else the emission
    /// and per bounce the closest-hit query passes and the bounce.
    pub fn record_trace(&self, c: &mut crate::runtime::Commands, pass: u32) -> Result<()> {
        let t = self.t;
        let rt = t.rt;
        rt.clear(c, self.counter.raw())?;
        let base = self.photon_params(pass);
        let mut first = 0u32;
        while first < self.o.photons {
            let count = (self.batch as u32).min(self.o.photons - first);
            let p = PhotonParams { count, first, ..base };
            if let Some(k) = self.fused(PhotonParams { stride: self.stride(count), ..p }) {
                rt.dispatch(c, &k)?;
                first += count;
                continue;
            }
            rt.dispatch(c, &EmitPhotons { params: p, lights: &t.lights, rays: &self.rays, paths: &self.paths })?;
            for bounce in 0..=self.o.photon_bounces {
                rt.dispatch_all(c, t.query_passes::<Closest>(self.accel, count as usize, &self.rays, &self.hits, self.lists.as_ref())?)?;
                rt.dispatch(c, &self.bounce_pass(p, bounce))?;
            }
            first += count;
        }
        Ok(())
    }

    /// The index parameters of pass `pass` for `count` items.
    pub fn index_params(&self, pass: u32, count: u32) -> IndexParams {
        let r = pass_radius(self.r0, self.o.alpha, pass);
        IndexParams {
            count,
            cells: self.cells,
            kind: if self.kd.is_some() { INDEX_KD } else { INDEX_GRID },
            maps: self.maps,
            radius: [r, r * self.o.caustic_radius],
            filter: self.o.filter,
            grid: self.o.grid_window,
            bounds_min: self.bounds.0,
            bounds_max: self.bounds.1,
            power_top: self.power_top,
            ..Default::default()
        }
    }

    fn index_binds(&self) -> IndexBinds<'_> {
        match &self.kd {
            Some((_, leaves, nodes)) => IndexBinds::Kd { nodes, leaves },
            None => IndexBinds::Grid,
        }
    }

    /// Updates the kd index's cell table for pass `pass`'s radius (host: a function of the
    /// tree and the radius only).
    fn prepare_index(&mut self, pass: u32) -> Result<()> {
        if let (Some(table), Some((_, buf, _))) = (self.leaf_table(pass), &self.kd) {
            self.t.rt.write(buf, &table)?;
        }
        Ok(())
    }

    /// The kd index's cell table of pass `pass` (`None` for the grid).
    pub fn leaf_table(&self, pass: u32) -> Option<Vec<LeafCells>> {
        let (boxes, _, _) = self.kd.as_ref()?;
        Some(leaf_cells(boxes, pass_radius(self.r0, self.o.alpha, pass), self.cells as u64))
    }

    /// Records building the index of the stored photons into `c`: keys and ranks, the cells'
    /// offsets, the photons placed into `sorted` in cell order.
    pub fn record_index(&self, c: &mut crate::runtime::Commands, pass: u32) -> Result<()> {
        self.record_index_steps(c, pass, 3)
    }

    /// Records clearing every working buffer of the index's sort (as allocated).
    pub fn record_index_reset(&self, c: &mut crate::runtime::Commands) -> Result<()> {
        self.sort.record_reset(c)
    }

    /// The first `steps` of the index build (1: keys and ranks; 2: + the cells'
    /// offsets; 3: + the photons placed, which zeroes the counts again), for timing the parts;
    /// fewer than 3 end with a reset of the sort's buffers for the next index
    /// (`record_index_reset`) and leave the index unfinished: by segments, the offsets need
    /// not match the photons placed before.
    pub fn record_index_steps(&self, c: &mut crate::runtime::Commands, pass: u32, steps: u32) -> Result<()> {
        let rt = self.t.rt;
        let p = self.index_params(pass, self.capacity);
        let s = &self.sort;
        rt.dispatch(c, &PhotonKeys { params: p, index: self.index_binds(), photons: &self.records, counter: &self.counter, keys: &self.keys, counts: &s.counts, segments: &s.segments, ranks: &s.ranks })?;
        if steps > 1 {
            s.record_offsets(c)?;
        }
        if steps > 2 {
            let k = PlacePhotons { params: p, photons: &self.records, keys: &self.keys, ranks: &s.ranks, offsets: &s.offsets, counts: &s.counts, words: &self.sorted };
            rt.dispatch(c, &k)
        } else {
            // Counts left for the next index to add to: cleared (`record_reset`).
            s.record_reset(c)
        }
    }

    /// What the gathers of each map (0 global, 1 caustic; a map the index lacks has none) at
    /// every `stride`-th of the first `count` paths of `fb` visit and find, from the index as
    /// it stands (after `record_index` ran) and the paths as the eye pass left them: computed
    /// natively by the shared index over buffers read back once (`photon::Disc::test`: the
    /// photons a gather counts). Grid or kd index alike.
    pub fn query_stats(&self, pass: u32, fb: &FrameBuffers, count: u32, stride: u32) -> Result<[QueryStats; 2]> {
        use kdray_shared::photon::SortedPhotons;
        let rt = self.t.rt;
        let p = self.index_params(pass, count);
        let (words, offsets) = (rt.read(&self.sorted, self.sorted.len())?, rt.read(&self.sort.offsets, self.sort.offsets.len())?);
        let sorted = SortedPhotons { words: &words, offsets: &offsets };
        let (rays, paths) = (rt.read(&fb.rays, count as usize)?, rt.read(&fb.paths, count as usize)?);
        let kd = match &self.kd {
            None => None,
            Some((_, leaves, nodes)) => Some((rt.read(nodes, nodes.len())?, rt.read(leaves, leaves.len())?)),
        };
        // A map the index lacks: no gathers.
        Ok(core::array::from_fn(|map| if map < p.maps as usize { Self::map_stats(&p, map as u32, &sorted, kd.as_ref(), &rays, &paths, count, stride) } else { QueryStats::default() }))
    }

    /// `query_stats` of map `map`, over read-back buffers (`kd`: the kd index's nodes
    /// and leaves, for a kd index).
    #[allow(clippy::too_many_arguments)]
    fn map_stats(p: &IndexParams, map: u32, sorted: &kdray_shared::photon::SortedPhotons, kd: Option<&(Vec<KdNode>, Vec<LeafCells>)>, rays: &[Ray], paths: &[kdray_shared::PathState], count: u32, stride: u32) -> QueryStats {
        use kdray_shared::photon::{CellVisitor, Disc, HashGrid, KdCells, PhotonIndex, SortedPhotons};
        struct Count {
            disc: Disc,
            visited: u64,
            found: u64,
            /// Words passed, padding included (the grid's `GRID_STEP` a step).
            words: u64,
        }
        impl CellVisitor for Count {
            fn word(&mut self, w: glam::UVec4, real: bool, _sorted: &SortedPhotons) {
                self.words += 1;
                if !real {
                    return;
                }
                self.visited += 1;
                self.found += self.disc.test(w).0 as u64;
            }
        }
        let r = p.radius[map as usize];
        let mut s = QueryStats::default();
        // `per_step`: words a gather step takes (the grid's `HashGrid::visit`: `GRID_STEP`, padding
        // included; the kd index's leaves: one).
        let mut run = |per_step: u64, index: &dyn Fn(&mut Count)| {
            let gather = |k: usize| {
                (paths[k].flags & kdray_shared::PATH_GATHER != 0).then(|| {
                    let mut c = Count { disc: Disc::new(p, rays[k].origin, rays[k].dir, r), visited: 0, found: 0, words: 0 };
                    index(&mut c);
                    c
                })
            };
            for k in (0..count as usize).step_by(stride.max(1) as usize) {
                if let Some(c) = gather(k) {
                    s.points += 1;
                    s.visited += c.visited;
                    s.found += c.found;
                }
            }
            // Groups of 32 consecutive paths, every `stride`-th.
            for g in (0..count as usize / 32).step_by(stride.max(1) as usize) {
                let (mut lanes, mut most) = (0u64, 0u64);
                for k in g * 32..g * 32 + 32 {
                    if let Some(c) = gather(k) {
                        let steps = c.words.div_ceil(per_step);
                        lanes += 1;
                        most = most.max(steps);
                        s.lane_steps += steps;
                    }
                }
                s.group_steps += lanes * most;
            }
        };
        match kd {
            None => {
                let grid = HashGrid::new(p);
                run(kdray_shared::photon::GRID_STEP as u64, &|c| grid.visit(c.disc.x, r, map, sorted, c));
            }
            Some((nodes, leaves)) => {
                let kd = KdCells::new(p, nodes, leaves);
                run(1, &|c| kd.visit(c.disc.x, r, map, sorted, c));
            }
        }
        s
    }

    /// Cells per map and slots (capacity) of the index.
    pub fn index_size(&self) -> (u32, u32) {
        (self.cells, self.capacity)
    }

    /// The gather pass of pass `pass` over `count` eye paths, every map.
    pub fn gather<'a>(&'a self, pass: u32, count: u32, fb: &'a FrameBuffers, gp: &'a GatherPoints) -> Gather<'a> {
        self.gather_maps(pass, count, fb, gp, 0)
    }

    /// The gather pass of pass `pass` over `count` eye paths, maps `first_map..` (1: the
    /// caustic map alone).
    pub fn gather_maps<'a>(&'a self, pass: u32, count: u32, fb: &'a FrameBuffers, gp: &'a GatherPoints, first_map: u32) -> Gather<'a> {
        self.gather_with(IndexParams { first_map, ..self.index_params(pass, count) }, fb, gp, 0)
    }

    /// Marks the gather points of pass `pass`'s `count` paths in `fb` whose global-map disc
    /// reaches past their surface (`photon::mark_edges`), for the next gather's `GATHER_EDGES`.
    pub fn mark_edges<'a>(&'a self, pass: u32, count: u32, fb: &'a FrameBuffers) -> Result<MarkEdges<'a>> {
        let open_edges = self.open_edges.as_ref().ok_or_else(|| err!(InvalidInput: "edges are marked only for the final gather near edges"))?;
        let method = match self.accel.structure {
            Structure::Brute => TraceMethod::Brute,
            Structure::KdTree => TraceMethod::Single(self.accel.traversal),
            Structure::Bvh => TraceMethod::Bvh,
        };
        Ok(MarkEdges::new(method, self.index_params(pass, count), self.t.scene_binds(self.accel), open_edges, &fb.rays, &fb.paths))
    }

    /// The first gather of `FinalGather::Edges`: every map, the points near edges kept for the
    /// final gather (`GATHER_EDGES`) and listed in `gp.list(0)` (cleared before).
    pub fn gather_edges<'a>(&'a self, pass: u32, count: u32, fb: &'a FrameBuffers, gp: &'a GatherPoints) -> Gather<'a> {
        self.gather_level(pass, count, fb, gp, 0, false, true)
    }

    /// The gather at the final gather's level `level` (every map; 0: the eye paths' first
    /// points), over the points the level before listed in `gp.list(level - 1)` (`listed`:
    /// dispatched indirectly, `GatherPoints::record_args` before) or over every path; with
    /// `edges`, the points near edges kept for the next level and listed in `gp.list(level)`
    /// (cleared before).
    #[allow(clippy::too_many_arguments)]
    pub fn gather_level<'a>(&'a self, pass: u32, count: u32, fb: &'a FrameBuffers, gp: &'a GatherPoints, level: u32, listed: bool, edges: bool) -> Gather<'a> {
        let flags = if listed { GATHER_LISTED } else { 0 } | if edges { GATHER_EDGES } else { 0 };
        self.gather_with(IndexParams { gather_flags: flags, ..self.index_params(pass, count) }, fb, gp, level)
    }

    /// A gather at level `level` (0: the eye paths' first points): reads `gp.list(level - 1)`,
    /// writes `gp.list(level)`.
    fn gather_with<'a>(&'a self, params: IndexParams, fb: &'a FrameBuffers, gp: &'a GatherPoints, level: u32) -> Gather<'a> {
        Gather {
            params,
            index: self.index_binds(),
            rays: &fb.rays,
            words: &self.sorted,
            offsets: &self.sort.offsets,
            paths: &fb.paths,
            points: gp.list(level.wrapping_sub(1)),
            next_points: gp.list(level),
        }
    }

    /// Traces pass `pass`'s photons and indexes them (growing the records and tracing again if
    /// they did not fit); returns the photons stored.
    pub fn trace_and_index(&mut self, pass: u32) -> Result<u32> {
        let rt: &dyn Runtime = self.t.rt;
        loop {
            self.prepare_index(pass)?;
            let mut c = rt.begin();
            self.record_trace(&mut c, pass)?;
            let pc = rt.read_back_of(&mut c, &self.counter, 1)?;
            rt.submit(c)?;
            let stored: Vec<u32> = cast(rt.wait(pc)?);
            if stored[0] > self.capacity {
                self.grow(stored[0])?;
                continue;
            }
            let mut c = rt.begin();
            self.record_index(&mut c, pass)?;
            rt.submit(c)?;
            return Ok(stored[0]);
        }
    }

    /// Photon rays traced and photon bounces (hits) of pass `pass`, counted from the hits of
    /// every bounce of the per-bounce schedule (a separate counting run: the timed runs read
    /// nothing back).
    pub fn count_bounces(&self, pass: u32) -> Result<(u64, u64)> {
        let t = self.t;
        let rt = t.rt;
        if self.rays.len() < self.batch {
            bail!(InvalidInput: "counting photon bounces needs the per-bounce schedule (PhotonOptions::fused off)");
        }
        let (mut rays, mut hits) = (0u64, 0u64);
        rt.finish()?;
        let mut c = rt.begin();
        rt.clear(&mut c, self.counter.raw())?;
        rt.submit(c)?;
        let base = self.photon_params(pass);
        let mut first = 0u32;
        while first < self.o.photons {
            let count = (self.batch as u32).min(self.o.photons - first);
            let p = PhotonParams { count, first, ..base };
            let mut c = rt.begin();
            rt.dispatch(&mut c, &EmitPhotons { params: p, lights: &t.lights, rays: &self.rays, paths: &self.paths })?;
            rt.submit(c)?;
            for bounce in 0..=self.o.photon_bounces {
                let mut c = rt.begin();
                rt.dispatch_all(&mut c, t.query_passes::<Closest>(self.accel, count as usize, &self.rays, &self.hits, self.lists.as_ref())?)?;
                let pr = rt.read_back_of(&mut c, &self.rays, count as usize)?;
                let ph = rt.read_back_of(&mut c, &self.hits, count as usize)?;
                rt.dispatch(&mut c, &self.bounce_pass(p, bounce))?;
                rt.submit(c)?;
                let rs: Vec<Ray> = cast(rt.wait(pr)?);
                let hs: Vec<Hit> = cast(rt.wait(ph)?);
                rays += rs.iter().filter(|r| r.is_valid()).count() as u64;
                hits += hs.iter().filter(|h| h.is_hit()).count() as u64;
            }
            first += count;
        }
        Ok((rays, hits))
    }

    /// The stored photons of the last traced pass, in slot order (tests, diagnostics).
    pub fn read_records(&self) -> Result<Vec<Photon>> {
        let n = self.t.rt.read(&self.counter, 1)?[0].min(self.capacity) as usize;
        self.t.rt.read(&self.records, n)
    }

    /// The sorted photons' words and the cell offsets of the last index (tests, diagnostics;
    /// cell c's photons: `photon::cell_range`).
    pub fn read_index(&self) -> Result<(Vec<PhotonWord>, Vec<u32>)> {
        let offsets = self.t.rt.read(&self.sort.offsets, self.sort.offsets.len())?;
        let n = self.sort.placed()? as usize;
        Ok((self.t.rt.read(&self.sorted, n)?, offsets))
    }
}

/// What sampled gathers visited and found (`PhotonMap::query_stats`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QueryStats {
    /// Gather points sampled.
    pub points: u64,
    /// Photons their gathers tested (read from the index's cells).
    pub visited: u64,
    /// Photons that counted (within the radius, on the point's side).
    pub found: u64,
    /// Steps (the grid's `GRID_STEP` photons each, `HashGrid::visit`'s; the kd index's one) of the
    /// gather points of sampled groups of 32 consecutive paths (a subgroup's, on the GPU), summed over those points.
    pub lane_steps: u64,
    /// The same groups' longest gathers: per group, its gather points times the most steps any
    /// of them took (a subgroup takes as long as its longest lane), summed.
    pub group_steps: u64,
}

impl QueryStats {
    /// Photons found per gather point.
    pub fn found_per_point(&self) -> f64 {
        self.found as f64 / self.points.max(1) as f64
    }
    /// Photons tested per gather point.
    pub fn visited_per_point(&self) -> f64 {
        self.visited as f64 / self.points.max(1) as f64
    }
    /// How evenly the gathers of a group of 32 paths share its time: the steps they take over
    /// those of the longest, times the group's gather points (1: every lane busy to the end).
    pub fn group_balance(&self) -> f64 {
        self.lane_steps as f64 / self.group_steps.max(1) as f64
    }
}

/// The gather points near edges of a batch of eye paths (`FinalGather::Edges`), level by level
/// of the final gather: the first gather lists them, the next level's gather runs over the list
/// alone — a dense, indirect dispatch instead of one over every path, most of whose lanes
/// would idle — and lists those near edges again for the level after it. Two lists, used in
/// turn.
pub struct GatherPoints {
    /// Element 0: the points listed; then the paths' indices.
    lists: [Buffer<u32>; 2],
    /// The workgroup counts of a dispatch over a list (`DispatchArgs`).
    pub args: Buffer<[u32; 3]>,
}

impl GatherPoints {
    /// Room for every path of a batch of `paths` (0: lists that list none).
    pub fn new(t: &Tracer, paths: usize) -> Result<Self> {
        let rt = t.rt;
        Ok(GatherPoints { lists: [rt.alloc("gather points", paths + 1)?, rt.alloc("gather points", paths + 1)?], args: rt.alloc("gather point dispatch", 1)? })
    }

    /// The list of the points near edges at final-gather level `level` (0: of the first gather).
    pub fn list(&self, level: u32) -> &Buffer<u32> {
        &self.lists[(level % 2) as usize]
    }

    /// Records clearing level `level`'s list (before the gather that fills it).
    pub fn record_clear(&self, rt: &dyn Runtime, c: &mut crate::runtime::Commands, level: u32) -> Result<()> {
        rt.clear(c, self.list(level).raw())
    }

    /// Records the workgroup counts of a dispatch over level `level`'s list.
    pub fn record_args(&self, rt: &dyn Runtime, c: &mut crate::runtime::Commands, level: u32) -> Result<()> {
        rt.dispatch(c, &DispatchArgs { counts: self.list(level), args: &self.args })
    }
}

/// Eye-path parameters of pass `pass`: `o.eye_samples` jittered samples per pixel, ending at
/// gather points.
pub fn eye_params(t: &Tracer, cam: &Camera, o: &PhotonOptions, first: usize, count: usize, pass: u32) -> RenderParams {
    let po = PathOptions { seed: pass_seed(o.seed ^ 0x0E7E_0E7E, pass), bounces: o.eye_bounces, diffuse_bounces: 0, spp: 1, jitter: true, fused: o.fused, sampler: o.sampler, raster: false, unit_samples: 1 };
    let mut p = path::params(t, cam, &po, first, count, 0);
    p.seed = po.seed;
    p.sample = pass;
    // One sequence per pixel over the whole render: pass k's samples follow pass k − 1's.
    p.sample_base = pass.wrapping_mul(o.eye_samples);
    p.sequence = pcg_hash(o.seed ^ 0x0E7E_5EC0);
    p.flags = RENDER_JITTER | RENDER_GATHER | if o.photon_direct { RENDER_PHOTON_DIRECT } else { 0 } | o.sampler.flags();
    path::with_samples(p, o.eye_samples)
}

/// The final gather's parameters for the eye paths of `eye` (`eye_params`) at level `level` ≥ 1:
/// resume from the gather points, the eye paths' kind of numbers with random streams and
/// sampler dimensions of the level's own;
/// at the next diffuse point direct light by a shadow ray, the rest from the photon maps.
pub fn final_gather_params(eye: &RenderParams, level: u32) -> RenderParams {
    // The eye pass's other flags (jitter) concern the camera rays, which a resumed path has
    // left behind.
    let seed = pcg_hash(eye.seed ^ 0xF17A_16A7 ^ (level - 1).wrapping_mul(0x9E37_79B9));
    // Sobol numbers (`RENDER_SOBOL`) go on: until 2026-12-03 resumed paths drew independent
    // ones (the flags were replaced), which natively cost 3–4 % more error at equal passes
    // (Cornell box, 128², 48 passes, four seeds).
    RenderParams { seed, flags: RENDER_GATHER | RENDER_CONTINUE | (eye.flags & RENDER_SOBOL) | (level << RENDER_LEVEL_SHIFT), ..*eye }
}

/// The eye passes and gathers of pass `pass` for the paths of `p` (`eye_params`), up to the
/// film: eye paths to their first diffuse points and the gather there; with final gathering,
/// the caustic map at the first point (near edges only: every map elsewhere), the paths
/// resumed to a second point, and every map there — near edges, level by level
/// (`PhotonOptions::edge_levels`): a point of the level before the last near an edge again
/// takes the caustic map and is resumed once more.
fn record_eye<'a>(c: &mut crate::runtime::Commands, map: &'a PhotonMap, p: &RenderParams, pass: u32, fb: &'a FrameBuffers, gp: &'a GatherPoints) -> Result<()> {
    let (t, rt) = (map.t, map.t.rt);
    rt.dispatch_all(c, path::eye_passes(t, map.accel, p, fb, map.o.fused)?)?;
    let edges = map.o.final_gather == FinalGather::Edges;
    match map.o.final_gather {
        FinalGather::Off => return rt.dispatch(c, &map.gather(pass, p.count, fb, gp) as &dyn Kernel),
        FinalGather::Edges => {
            gp.record_clear(rt, c, 0)?;
            rt.dispatch(c, &map.mark_edges(pass, p.count, fb)?)?;
            rt.dispatch(c, &map.gather_edges(pass, p.count, fb, gp) as &dyn Kernel)?;
        }
        FinalGather::All if map.maps > 1 => rt.dispatch(c, &map.gather_maps(pass, p.count, fb, gp, 1) as &dyn Kernel)?,
        FinalGather::All => {}
    }
    let levels = if edges { map.o.edge_levels.max(1) } else { 1 };
    for level in 1..=levels {
        rt.dispatch_all(c, path::eye_passes(t, map.accel, &final_gather_params(p, level), fb, map.o.fused)?)?;
        if !edges {
            rt.dispatch(c, &map.gather(pass, p.count, fb, gp) as &dyn Kernel)?;
            continue;
        }
        let again = level < levels;
        if again {
            gp.record_clear(rt, c, level)?;
            rt.dispatch(c, &map.mark_edges(pass, p.count, fb)?)?;
        }
        let k = map.gather_level(pass, p.count, fb, gp, level, map.o.list_points, again);
        if map.o.list_points {
            gp.record_args(rt, c, level - 1)?;
            rt.dispatch_indirect(c, &k, &gp.args, 0)?;
        } else {
            rt.dispatch(c, &k)?;
        }
    }
    Ok(())
}

/// Passes submitted ahead of the host's check of their photon counts: three measured 1 %
/// faster than two (H200, Cornell box 256 × 4 passes: 0.94 → 0.93 s; four: 0.92 s, and an
/// overflow found one pass later still).
const IN_FLIGHT: usize = 3;

/// The fewest passes of a unit of work chosen by default (`PhotonOptions::unit`).
pub const UNIT_PASSES: u32 = 4;

/// The most units of work a render is cut into by default (`PhotonOptions::unit`): each unit's
/// film is read back and summed on the host. (With the film waited for after the next passes
/// are submitted, 1 to 64 units cost the same on an H100: Cornell box 512², 256 passes,
/// 0.88–0.92 s; waited for at once, 64 units had cost 22 % on an H200.)
pub const DEFAULT_UNITS: u32 = 16;

impl PhotonOptions {
    /// The passes of a unit of work: `unit_passes`, or by default as many as cut the render
    /// into at most `DEFAULT_UNITS` units, at least `UNIT_PASSES` — a function of the
    /// options alone, never of the devices, so the image is the same on any number of them.
    pub fn unit(&self) -> u32 {
        match self.unit_passes {
            0 => self.passes.div_ceil(DEFAULT_UNITS).max(UNIT_PASSES),
            n => n,
        }
    }
}

/// Renders `cam`'s image by progressive photon mapping on `map`'s runtime; `progress` counts
/// passes. `render_on` with one device.
pub fn render(map: &mut PhotonMap, cam: &Camera, progress: &dyn Progress) -> Result<(RenderOutput, PhotonStats)> {
    render_on(std::slice::from_mut(map), cam, progress)
}

/// Renders `cam`'s image by progressive photon mapping on every map's runtime at once (one map
/// per device, all made with the same options over the same scene); `progress` counts passes.
///
/// The passes go in units of `PhotonOptions::unit()` (`share`): a device takes the next
/// unit when it is free, renders its passes into its film from zero and hands the film over;
/// the films are summed exactly (`share::FilmSum`), so the image is the same, bit for bit, on one device or
/// several of one kind. Each pass is one submission: its photons traced and indexed, its eye
/// samples gathered into the film, its photon count read back (a unit's last pass reads the
/// film back too). The count is checked while the next passes run, so a device never waits
/// for the host between passes. A pass whose photons did not fit the records (rare: the
/// records are sized from the first pass with a margin) lost photons: the records grow and
/// the device renders its units in hand again from their first passes — passes are
/// deterministic, so the image is the same as if they had fit.
///
/// A device that fails gives its units to the others (`PhotonStats::failed` says which and
/// why). With none left, the render returns the image of the units delivered, with the error
/// in `PhotonStats::interrupted`; with none delivered, the error.
pub fn render_on(maps: &mut [PhotonMap], cam: &Camera, progress: &dyn Progress) -> Result<(RenderOutput, PhotonStats)> {
    let part = render_part(maps, cam, progress, share::Part::WHOLE)?;
    Ok((part.image(), part.stats))
}

/// One process's share of a photon render (`render_part`): the exact sum of its units'
/// films, unit 0's primary hits (the first part's), its counts, and the camera in the order
/// the rays were traced. Parts of one render add up (`add`) to the whole render's.
pub struct PhotonPart {
    /// The films of the part's units, summed.
    pub sum: share::FilmSum,
    /// Unit 0's primary hits, where this part rendered it.
    pub hits: Option<Vec<Hit>>,
    /// The part's counts (`seconds`: its own wall time).
    pub stats: PhotonStats,
    /// The camera the rays were traced with (`PhotonOptions::tiles` orders them).
    pub camera: Camera,
    /// The render's passes (to report a part that failed).
    pub passes: u32,
}

impl PhotonPart {
    /// Adds another part of the same render.
    pub fn add(&mut self, other: &PhotonPart) {
        self.sum.add_sums(&other.sum);
        if self.hits.is_none() {
            self.hits = other.hits.clone();
        }
        let (a, b) = (&mut self.stats, &other.stats);
        a.passes += b.passes;
        a.emitted += b.emitted;
        a.stored += b.stored;
        // The radius shrinks pass by pass: the last pass's is the smallest (0: no pass).
        if b.last_radius > 0.0 && (a.last_radius == 0.0 || b.last_radius < a.last_radius) {
            a.last_radius = b.last_radius;
        }
        a.seconds = a.seconds.max(b.seconds);
        a.failed.extend(b.failed.iter().cloned());
        a.per_device.extend(b.per_device.iter().copied());
        a.interrupted = match (a.interrupted.take(), &b.interrupted) {
            (Some(x), Some(y)) => Some(format!("{x}; {y}")),
            (x, y) => x.or(y.clone()),
        };
    }

    /// The image of the units summed.
    pub fn image(&self) -> RenderOutput {
        let cam = &self.camera;
        let n = (cam.width * cam.height) as usize;
        let mut out = RenderOutput::new(cam.width, cam.height);
        path::place(&mut out, cam, 0, self.hits.clone().unwrap_or_else(|| vec![Hit::NONE; n]), self.sum.film());
        out
    }
}

/// `render_on` for the units of `part` only (an MPI rank's share: unit `part.rank`, then every
/// `part.ranks`-th): the parts of all ranks, added, are the whole render, bit for bit. A part
/// with no unit is an empty one, not an error.
pub fn render_part(maps: &mut [PhotonMap], cam: &Camera, progress: &dyn Progress, part: share::Part) -> Result<PhotonPart> {
    let Some(first) = maps.first() else { bail!(InvalidInput: "a render needs at least one device") };
    let o = first.o.clone();
    for m in &maps[1..] {
        let same = (m.o.passes, m.o.unit(), m.o.photons, m.o.seed, m.o.alpha, m.o.eye_samples) == (o.passes, o.unit(), o.photons, o.seed, o.alpha, o.eye_samples);
        if !same || m.r0 != first.r0 || !m.t.holds_same(first.t) {
            bail!(InvalidInput: "the devices of a render need photon maps made with the same options over the same scene");
        }
    }
    let per = o.unit();
    let r0 = first.r0;
    let cam = &ray_camera(&o, cam);
    let n = (cam.width * cam.height) as usize;
    let names: Vec<String> = maps.iter().map(|m| m.t.rt.name()).collect();
    // Each device's buffers and its first pipelines (before the clock starts).
    let mut devices: Vec<(&mut PhotonMap, Option<EyeBuffers>)> = maps.iter_mut().map(|m| (m, None)).collect();
    let ready: Vec<Result<()>> = std::thread::scope(|s| {
        let jobs: Vec<_> = devices.iter_mut().map(|(m, b)| s.spawn(move || EyeBuffers::new(m, cam).map(|e| *b = Some(e)))).collect();
        jobs.into_iter().map(|j| j.join().expect("setting up a device's buffers panicked")).collect()
    });
    for r in ready {
        r?;
    }
    let units = o.passes.div_ceil(per);
    // The part's passes (all of them in one process).
    let mine: u32 = (0..units).filter(|&u| part.holds(u)).map(|u| (o.passes - u * per).min(per)).sum();
    progress.start(mine as u64);
    let start = Instant::now();
    let mut stats = PhotonStats::default();
    let mut shared = share::share(
        &mut devices,
        units,
        part,
        n,
        |(map, eye), hand| photon_worker(map, cam, eye.as_ref().expect("buffers made"), hand),
        |k| {
            stats.passes += k as u32;
            stats.emitted += k * o.photons as u64;
            progress.advance(k);
            let secs = start.elapsed().as_secs_f64();
            progress.status(&format!("{:.1} M photons/s", stats.emitted as f64 / secs / 1e6));
            o.time_limit.is_some_and(|l| secs >= l) || progress.cancelled()
        },
    )?;
    let mut stats = PhotonStats { seconds: start.elapsed().as_secs_f64(), ..Default::default() };
    let mut last_pass = None;
    for (_, u) in &shared.stats {
        stats.passes += u.passes;
        stats.emitted += u.emitted;
        stats.stored += u.stored;
        last_pass = last_pass.max(Some(u.last_pass));
    }
    stats.last_radius = last_pass.map_or(0.0, |p| pass_radius(r0, o.alpha, p));
    let passes = stats.passes;
    (stats.failed, stats.interrupted) = shared.failures(&names, || format!("the image holds {passes} of the {} passes", o.passes))?;
    stats.per_device = std::mem::take(&mut shared.per_device);
    Ok(PhotonPart { sum: shared.sum, hits: shared.hits, stats, camera: *cam, passes: o.passes })
}

/// The camera as a photon render traces it: in tiles (`PhotonOptions::tiles`) or as given.
pub fn ray_camera(o: &PhotonOptions, cam: &Camera) -> Camera {
    Camera { order: if o.tiles { ORDER_TILES } else { cam.order }, ..*cam }
}

/// The counts of one unit of passes.
#[derive(Clone, Copy, Default)]
struct UnitStats {
    passes: u32,
    emitted: u64,
    stored: u64,
    last_pass: u32,
}

/// One device's eye buffers: the pixels in batches (each with its paths and film).
struct EyeBuffers {
    batches: Vec<(usize, usize)>,
    fbs: Vec<FrameBuffers>,
    gps: Vec<GatherPoints>,
}

impl EyeBuffers {
    /// The batches' films.
    fn films(&self) -> Vec<&path::FilmBuffers> {
        self.fbs.iter().map(|f| &f.film).collect()
    }

    fn new(map: &mut PhotonMap, cam: &Camera) -> Result<Self> {
        let t = map.t;
        let e = map.o.eye_samples as usize;
        let n = (cam.width * cam.height) as usize;
        let b = (t.batch_size(map.accel, n * e) / e).max(1);
        let batches: Vec<(usize, usize)> = (0..n).step_by(b).map(|f| (f, b.min(n - f))).collect();
        let fbs: Vec<FrameBuffers> = batches.iter().map(|&(_, c)| FrameBuffers::new(t, map.accel, c * e)).collect::<Result<_>>()?;
        let gps: Vec<GatherPoints> = match map.o.final_gather {
            FinalGather::Edges if map.o.list_points => batches.iter().map(|&(_, c)| GatherPoints::new(t, c * e)).collect::<Result<_>>()?,
            _ => (0..batches.len()).map(|_| GatherPoints::new(t, 0)).collect::<Result<_>>()?,
        };
        let eye = EyeBuffers { batches, fbs, gps };
        if !t.rt.is_native() {
            // A device creates a kernel's pipeline when a pass first records it (the driver
            // compiles: 0.12–0.13 s for a pass's eight kernels on the H200, cached or not).
            // Pass 0 recorded once and dropped unsubmitted makes them ready before the
            // render's clock (and its time limit) starts; the caller's own clock still sees
            // the cost. (Natively, recording runs the kernels.)
            let mut c = t.rt.begin();
            record_pass(map, cam, 0, &eye, &mut c)?;
        }
        Ok(eye)
    }
}

/// A pass submitted and not yet checked: its unit's place among the device's units in hand,
/// its photon count, and (a unit's last pass) the film's and hits' read-backs.
struct Flight {
    pass: u32,
    count: Pending,
    film: Option<(Vec<Pending>, Vec<Pending>)>,
}

/// One device's share of a photon render (`render_on`): takes units of passes and renders
/// them, `IN_FLIGHT` passes ahead of the checks.
fn photon_worker(map: &mut PhotonMap, cam: &Camera, eye: &EyeBuffers, hand: &mut share::Hand<'_, UnitStats>) -> Result<()> {
    let rt = map.t.rt;
    let (per, passes) = (map.o.unit(), map.o.passes);
    let range = |u: u32| (u * per, ((u + 1) * per).min(passes));
    // Units in hand, oldest first (the first is the one being checked), the next of them to
    // submit passes of, and its next pass.
    let mut hold: VecDeque<u32> = VecDeque::new();
    let mut sub = 0usize;
    let mut next = 0u32;
    let mut flight: VecDeque<Flight> = VecDeque::new();
    let mut counts = UnitStats::default();
    // A unit whose passes are all checked, its film's read-back not yet waited for.
    let mut reading: Option<(u32, Vec<Pending>, Vec<Pending>, UnitStats)> = None;
    loop {
        if flight.len() < IN_FLIGHT && !hand.stopping() {
            if sub == hold.len() {
                if let Some(u) = hand.take() {
                    hold.push_back(u);
                    next = range(u).0;
                }
            }
            if sub < hold.len() {
                let u = hold[sub];
                let (a, b) = range(u);
                let pass = next;
                let mut c = rt.begin();
                let submitted = (|| {
                    if pass == a {
                        for fb in &eye.fbs {
                            rt.clear(&mut c, fb.film.radiance.raw())?;
                        }
                    }
                    let count = record_pass(map, cam, pass, eye, &mut c)?;
                    let film = if pass + 1 == b { Some(path::record_film_reads(map.t, &eye.batches, &eye.films(), u == 0, &mut c)?) } else { None };
                    rt.submit(c)?;
                    Ok::<_, crate::Error>(Flight { pass, count, film })
                })();
                flight.push_back(submitted.map_err(|e| e.context(format!("pass {pass} failed")))?);
                if pass + 1 == b {
                    sub += 1;
                    if let Some(&u) = hold.get(sub) {
                        next = range(u).0;
                    }
                } else {
                    next += 1;
                }
                if flight.len() < IN_FLIGHT {
                    continue;
                }
            }
        }
        // A finished unit's film, read back in its last pass's submission, is taken once the
        // passes after it are submitted (the device works on while the host copies it).
        if let Some((u, film, hits, stats)) = reading.take() {
            let (film, hits) = path::wait_film_reads(rt, film, hits).map_err(|e| e.context("reading back the image failed"))?;
            hand.deliver(share::Unit { index: u, film, hits, stats });
        }
        let Some(f) = flight.pop_front() else {
            // Nothing in flight: every unit in hand is delivered, or the render stops and the
            // one begun goes as far as it got.
            if counts.passes > 0 {
                let u = hold.pop_front().expect("a unit begun");
                let (film, hits) = path::read_raw_films(map.t, &eye.batches, &eye.films(), u == 0).map_err(|e| e.context("reading back the image failed"))?;
                hand.deliver(share::Unit { index: u, film, hits, stats: counts });
            }
            return Ok(());
        };
        let stored = rt.wait(f.count).map_err(|e| e.context(format!("pass {} failed", f.pass)))?[0];
        if stored > map.capacity {
            // The pass lost photons (those after it may have too): grow the records and render
            // the units in hand again from their first passes.
            flight.clear();
            rt.finish().and_then(|_| map.grow(stored)).map_err(|e| e.context(format!("growing the photon records after pass {} failed", f.pass)))?;
            sub = 0;
            next = range(hold[0]).0;
            counts = UnitStats::default();
            continue;
        }
        counts.passes += 1;
        counts.emitted += map.o.photons as u64;
        counts.stored += stored as u64;
        counts.last_pass = f.pass;
        hand.advance(1);
        if let Some((film, hits)) = f.film {
            let u = hold.pop_front().expect("a unit in hand");
            sub -= 1;
            reading = Some((u, film, hits, std::mem::take(&mut counts)));
        }
    }
}


/// Records pass `pass` whole into `c`: photons traced and indexed, every batch's eye samples
/// gathered into its film, and the photons stored read back (to check against the records'
/// capacity).
fn record_pass(map: &mut PhotonMap, cam: &Camera, pass: u32, eye: &EyeBuffers, c: &mut crate::runtime::Commands) -> Result<Pending> {
    let (t, rt) = (map.t, map.t.rt);
    map.prepare_index(pass)?;
    map.record_trace(c, pass)?;
    map.record_index(c, pass)?;
    for ((&(first, count), fb), gp) in eye.batches.iter().zip(&eye.fbs).zip(&eye.gps) {
        let p = eye_params(t, cam, &map.o, first, count, pass);
        record_eye(c, map, &p, pass, fb, gp)?;
        rt.dispatch(c, &Film { params: p, paths: &fb.paths, radiance: &fb.film.radiance })?;
    }
    rt.read_back_of(c, &map.counter, 1)
}
