//! The eye-path entry points (`kdray_shared::render`).
use kdray_shared::render;
use kdray_shared::{Hit, ItemParams, Light, Material, PathState, Ray, RenderParams, ShadeTerms, Triangle};
use spirv_std::glam::UVec3;
use spirv_std::spirv;

#[spirv(compute(threads(64)))]
pub fn camera_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] paths: &mut [PathState],
) {
    render::camera_rays(crate::item(id, groups), params, rays, paths);
}

#[spirv(compute(threads(64)))]
pub fn path_step(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] shadow_rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] terms: &mut [ShadeTerms],
) {
    render::path_step(crate::item(id, groups), params, rays, tris, hits, materials, lights, paths, shadow_rays, terms);
}

#[spirv(compute(threads(64)))]
pub fn accumulate(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] terms: &[ShadeTerms],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] occluded: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] paths: &mut [PathState],
) {
    render::accumulate(crate::item(id, groups), params, terms, occluded, paths);
}

#[spirv(compute(threads(64)))]
pub fn film(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] paths: &[PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] radiance: &mut [[f32; 4]],
) {
    render::film(crate::item(id, groups), params, paths, radiance);
}

#[spirv(compute(threads(64)))]
pub fn rng_fill(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &ItemParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] out: &mut [[u32; 4]],
) {
    render::rng_fill(crate::item(id, groups), params, out);
}
