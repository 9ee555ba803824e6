//! The linear BVH build's entry points (`kdray_shared::bvh::build`).
use crate::Atomics;
use kdray_shared::bvh::build;
use kdray_shared::bvh::BvhNode;
use kdray_shared::{BuildBox, LbvhParams, Triangle};
use spirv_std::glam::UVec3;
use spirv_std::spirv;

#[spirv(compute(threads(64)))]
pub fn lbvh_boxes(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] list: &mut [BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tree: &mut [BuildBox],
) {
    build::boxes(crate::item(id, groups), params, tris, list, tree);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_reduce(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] tree: &mut [BuildBox],
) {
    build::reduce(crate::item(id, groups), params, tree);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_morton(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] list: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tree: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] codes: &mut [[u32; 2]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] keys: &mut [u32],
) {
    build::morton(crate::item(id, groups), params, list, tree, codes, keys);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_refine(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] order: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] codes: &[[u32; 2]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] list: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] sorted: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] sorted_codes: &mut [[u32; 2]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] tree: &mut [BuildBox],
) {
    build::refine(crate::item(id, groups), params, order, offsets, codes, list, sorted, sorted_codes, tree);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_hierarchy(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] sorted_codes: &[[u32; 2]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes2: &mut [[u32; 4]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] parents: &mut [u32],
) {
    build::hierarchy(crate::item(id, groups), params, sorted_codes, nodes2, counts, parents);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_bounds(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] nodes2: &[[u32; 4]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tree: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] boxes2: &mut [BuildBox],
) {
    build::bounds(crate::item(id, groups), params, nodes2, tree, boxes2);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_depths(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] parents: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] depths: &mut [u32],
) {
    build::depths(crate::item(id, groups), params, parents, depths);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_treelet(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] depths: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tree: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes2: &mut [[u32; 4]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] boxes2: &mut [BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] parents: &mut [u32],
) {
    build::treelet(crate::item(id, groups), params, depths, tree, nodes2, boxes2, counts, parents);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_level(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] state: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] args: &mut [[u32; 3]],
) {
    build::level(crate::item(id, groups), state, args);
}

#[spirv(compute(threads(64)))]
pub fn lbvh_collapse(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &LbvhParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] sorted: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] nodes2: &[[u32; 4]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] boxes2: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] tree: &[BuildBox],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] state: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] pending: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] bvh: &mut [BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] bvh_tris: &mut [Triangle],
) {
    build::collapse(crate::item(id, groups), params, tris, sorted, nodes2, boxes2, counts, tree, &mut Atomics(state), pending, bvh, bvh_tris);
}
