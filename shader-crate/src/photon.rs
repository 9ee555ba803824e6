//! Photon mapping's entry points (`kdray_shared::photon`): emission, one bounce, whole photon
//! paths (emission to absorption in one thread, for brute force, two kd traversals and the BVH), the
//! index's keys and placement, and the gather, for both photon indices (hashed grid, kd
//! leaves).
use crate::{parts, Atomics};
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::{BvhNode, TriWords};
use kdray_shared::kdtree::{Full, KdNode, Short};
use kdray_shared::trace::{Brute, Kd, Wide};
use kdray_shared::photon::{self, HashGrid, KdCells, PhotonWord, SortedPhotons};
use kdray_shared::{Hit, IndexParams, LeafCells, Light, Material, PathState, Photon, PhotonParams, PhotonPath, Ray, Triangle};
use spirv_std::glam::UVec3;
use spirv_std::spirv;

#[spirv(compute(threads(64)))]
pub fn emit_photons(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &PhotonParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] paths: &mut [PhotonPath],
) {
    photon::emit(crate::item(id, groups), params, lights, rays, paths);
}

#[spirv(compute(threads(64)))]
pub fn photon_bounce(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &PhotonParams,
    #[spirv(spec_constant(id = 0))] split: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] tris2: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] paths: &mut [PhotonPath],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] photons: &mut [Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] counter: &mut [u32],
) {
    let tris = parts(split, tris, tris1, tris2);
    photon::bounce(crate::item(id, groups), params, rays, hits, &tris, materials, paths, photons, &mut Atomics(counter));
}

#[spirv(compute(threads(64)))]
pub fn photon_keys_grid(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] photons: &[Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] counter: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] keys: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] segments: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] ranks: &mut [u32],
) {
    let grid = HashGrid::new(params);
    photon::keys(crate::item(id, groups), params, &grid, photons, counter, keys, &mut Atomics(counts), &mut Atomics(segments), ranks);
}

#[spirv(compute(threads(64)))]
pub fn photon_keys_kd(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] photons: &[Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] counter: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] leaves: &[LeafCells],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] keys: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] segments: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] ranks: &mut [u32],
) {
    let index = KdCells::new(params, nodes, leaves);
    photon::keys(crate::item(id, groups), params, &index, photons, counter, keys, &mut Atomics(counts), &mut Atomics(segments), ranks);
}

#[spirv(compute(threads(64)))]
pub fn place_photons(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] photons: &[Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] keys: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] ranks: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] words: &mut [PhotonWord],
) {
    photon::place(crate::item(id, groups), params, photons, keys, ranks, offsets, counts, words);
}

#[spirv(compute(threads(64)))]
pub fn gather_grid(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] words: &[PhotonWord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] points: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] next_points: &mut [u32],
) {
    let sorted = SortedPhotons { words, offsets };
    photon::gather(crate::item(id, groups), params, &HashGrid::new(params), rays, &sorted, paths, points, &mut Atomics(next_points));
}

#[spirv(compute(threads(64)))]
pub fn gather_kd(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] words: &[PhotonWord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] leaves: &[LeafCells],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] points: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] next_points: &mut [u32],
) {
    let index = KdCells::new(params, nodes, leaves);
    let sorted = SortedPhotons { words, offsets };
    photon::gather(crate::item(id, groups), params, &index, rays, &sorted, paths, points, &mut Atomics(next_points));
}

/// The workgroup counts of an indirect dispatch over the `counts[0]` items a pass before
/// counted (`kernel::dispatch_args`; one item).
#[spirv(compute(threads(64)))]
pub fn dispatch_args(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] args: &mut [[u32; 3]],
) {
    if id.x == 0 && id.y == 0 {
        args[0] = kdray_shared::kernel::dispatch_args(counts[0]);
    }
}

/// One entry point running `photon::trace_photons::<$m>` (photons from the light to their
/// absorption per thread); `$a`, `$b` are the structure's two buffers (kd: `nodes`, `prims`;
/// BVH: `bvh`, `bvh_tris`) and `$view` makes the structure's view of them.
macro_rules! photon_paths {
    ($name:ident, $m:ty, $id:literal, $a:ident, $a1:ident, $a2:ident: $at:ty, $b:ident, $b1:ident, $b2:ident: $bt:ty, $view:ident) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(push_constant)] params: &PhotonParams,
            #[spirv(spec_constant(id = 0))] split_tris: u32,
            #[spirv(spec_constant(id = $id))] split: [u32; 2],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris1: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris2: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] $a: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] $a1: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] $a2: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] $b: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] $b1: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] $b2: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] photons: &mut [Photon],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] counter: &mut [u32],
        ) {
            let tris = parts(split_tris, tris, tris1, tris2);
            let (a, b) = (parts(split[0], $a, $a1, $a2), parts(split[1], $b, $b1, $b2));
            let accel = crate::$view(Aabb { min: params.bounds_min, max: params.bounds_max }, tris, a, b);
            photon::trace_photons::<$m, _, _>(crate::item(id, groups), params, &accel, &tris, lights, materials, photons, &mut Atomics(counter));
        }
    };
}

photon_paths!(photon_paths_brute, Brute, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
photon_paths!(photon_paths_stack, Kd<Full>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
photon_paths!(photon_paths_shortstack3, Kd<Short<3>>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
photon_paths!(photon_paths_bvh, Wide, 3, bvh, bvh1, bvh2: BvhNode, bvh_tris, bvh_tris1, bvh_tris2: TriWords, bvh_view);

/// One entry point running `photon::mark_edges::<$m>` (which gather points' discs reach past
/// their surface); `$a`, `$b` are the structure's two buffers (kd: `nodes`, `prims`; BVH:
/// `bvh`, `bvh_tris`) and `$view` makes the structure's view of them. Every kd traversal shares
/// the kd-tree's one (`kdtree::near`).
macro_rules! edge_points {
    ($name:ident, $m:ty, $id:literal, $a:ident, $a1:ident, $a2:ident: $at:ty, $b:ident, $b1:ident, $b2:ident: $bt:ty, $view:ident) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(push_constant)] params: &IndexParams,
            #[spirv(spec_constant(id = 0))] split_tris: u32,
            #[spirv(spec_constant(id = $id))] split: [u32; 2],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris1: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris2: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] $a: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] $a1: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] $a2: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] $b: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] $b1: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] $b2: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] open_edges: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] paths: &mut [PathState],
        ) {
            let tris = parts(split_tris, tris, tris1, tris2);
            // Nothing is near an edge in a scene without triangles. (Also keeps the BVH entry's
            // triangle bindings, which its search does not read: without them, the first three,
            // lavapipe ran the entry point as a no-op — 2026-12-03, Mesa 22.3.6.)
            if tris.is_empty() {
                return;
            }
            let (a, b) = (parts(split[0], $a, $a1, $a2), parts(split[1], $b, $b1, $b2));
            let accel = crate::$view(Aabb { min: params.bounds_min, max: params.bounds_max }, tris, a, b);
            photon::mark_edges::<$m, _>(crate::item(id, groups), params, &accel, open_edges, rays, paths);
        }
    };
}

edge_points!(edge_points_brute, Brute, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
edge_points!(edge_points_kd, Kd<Full>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
edge_points!(edge_points_bvh, Wide, 3, bvh, bvh1, bvh2: BvhNode, bvh_tris, bvh_tris1, bvh_tris2: TriWords, bvh_view);
