//! The counting sort's entry points (`kdray_shared::sort`).
use crate::Atomics;
use kdray_shared::sort;
use kdray_shared::SortParams;
use spirv_std::glam::UVec3;
use spirv_std::spirv;

#[spirv(compute(threads(64)))]
pub fn count_rank(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] keys: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] segments: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] ranks: &mut [u32],
) {
    sort::count_rank(crate::item(id, groups), params, keys, &mut Atomics(counts), &mut Atomics(segments), ranks);
}

#[spirv(compute(threads(64)))]
pub fn scan_top(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [u32],
) {
    sort::scan_top(crate::item(id, groups), params, input, output);
}

#[spirv(compute(threads(64)))]
pub fn exclusive_level(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] above: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] output: &mut [u32],
) {
    sort::exclusive_level(crate::item(id, groups), params, input, above, output);
}

#[spirv(compute(threads(64)))]
pub fn chunk_sums(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] sums: &mut [u32],
) {
    sort::chunk_sums(crate::item(id, groups), params, counts, sums);
}

#[spirv(compute(threads(64)))]
pub fn exclusive_offsets(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] above: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &mut [u32],
) {
    sort::exclusive(crate::item(id, groups), params, counts, above, offsets);
}

/// A subgroup's lanes take a block of segments together (`sort::segment_offsets`): its items are the
/// dispatch's subgroups, numbered over the 2D grid of workgroups.
#[spirv(compute(threads(64)))]
pub fn segment_offsets(
    #[spirv(workgroup_id)] group: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(subgroup_id)] sub: u32,
    #[spirv(num_subgroups)] subs: u32,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] counts: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] segments: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &mut [u32],
) {
    let g = (group.x + group.y * groups.x) * subs + sub;
    let lanes = crate::Subgroup::active();
    sort::segment_offsets(g, groups.x * groups.y * subs, &lanes, params, counts, &mut Atomics(segments), offsets);
}

#[spirv(compute(threads(64)))]
pub fn scatter_keys(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] keys: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] ranks: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] offsets: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] counts: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] order: &mut [u32],
) {
    sort::scatter(crate::item(id, groups), params, keys, ranks, offsets, counts, order);
}
