//! Photon mapping's entry points (`kdray_shared::photon`): emission, one bounce, whole photon
//! paths (emission to absorption in one thread, for brute force, two kd traversals and the BVH), the
//! index's keys and permutation, and the gather, for both photon indices (hashed grid, kd
//! leaves).
use crate::Atomics;
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
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] paths: &mut [PhotonPath],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] photons: &mut [Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] counter: &mut [u32],
) {
    photon::bounce(crate::item(id, groups), params, rays, hits, tris, materials, paths, photons, &mut Atomics(counter));
}

#[spirv(compute(threads(64)))]
pub fn photon_keys_grid(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] photons: &[Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] counter: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] keys: &mut [u32],
) {
    photon::keys(crate::item(id, groups), params, &HashGrid::new(params), photons, counter, keys);
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
) {
    let index = KdCells { nodes, leaves, cells: params.cells };
    photon::keys(crate::item(id, groups), params, &index, photons, counter, keys);
}

#[spirv(compute(threads(64)))]
pub fn permute_photons(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] photons: &[Photon],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] order: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] words: &mut [PhotonWord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] powers: &mut [u32],
) {
    photon::permute(crate::item(id, groups), params, photons, order, offsets, words, powers);
}

#[spirv(compute(threads(64)))]
pub fn gather_grid(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] words: &[PhotonWord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] powers: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] paths: &mut [PathState],
) {
    let sorted = SortedPhotons { words, powers, offsets };
    photon::gather(crate::item(id, groups), params, &HashGrid::new(params), rays, &sorted, paths);
}

#[spirv(compute(threads(64)))]
pub fn gather_kd(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &IndexParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] words: &[PhotonWord],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] powers: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] leaves: &[LeafCells],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] paths: &mut [PathState],
) {
    let index = KdCells { nodes, leaves, cells: params.cells };
    let sorted = SortedPhotons { words, powers, offsets };
    photon::gather(crate::item(id, groups), params, &index, rays, &sorted, paths);
}

/// One entry point running `photon::trace_photon::<$m>` (a photon from the light to its
/// absorption per thread); `$a`, `$b` are the structure's two buffers (kd: `nodes`, `prims`;
/// BVH: `bvh`, `bvh_tris`) and `$view` makes the structure's view of them.
macro_rules! photon_paths {
    ($name:ident, $m:ty, $a:ident: $at:ty, $b:ident: $bt:ty, $view:ident) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(push_constant)] params: &PhotonParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] $a: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] $b: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] photons: &mut [Photon],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] counter: &mut [u32],
        ) {
            let accel = crate::$view(Aabb { min: params.bounds_min, max: params.bounds_max }, tris, $a, $b);
            photon::trace_photon::<$m, _, _>(crate::item(id, groups), params, &accel, tris, lights, materials, photons, &mut Atomics(counter));
        }
    };
}

photon_paths!(photon_paths_brute, Brute, nodes: KdNode, prims: u32, kd_view);
photon_paths!(photon_paths_stack, Kd<Full>, nodes: KdNode, prims: u32, kd_view);
photon_paths!(photon_paths_shortstack3, Kd<Short<3>>, nodes: KdNode, prims: u32, kd_view);
photon_paths!(photon_paths_bvh, Wide, bvh: BvhNode, bvh_tris: TriWords, bvh_view);
