//! GPU entry points. Each kernel is a thin wrapper: it finds its work item, calls the one
//! implementation in `kdray-shared`, and stores the result. Binding 0 is always the
//! `FrameParams`; the host's kernel table (host/src/gpu/kernels.rs) mirrors these bindings.
//!
//! Work items are numbered over a 2D grid of 64-wide workgroups so a dispatch can exceed the
//! 65 535-workgroup limit of one dimension: `item = x + y · (groups_x · 64)`.
#![no_std]

use kdray_shared::{
    brute, camera, shade, FrameParams, Hit, Light, Material, Ray, ShadeTerms, Triangle,
};
use kdray_shared::rng::Rng;
use spirv_std::glam::UVec3;
use spirv_std::spirv;

pub const WORKGROUP: u32 = 64;

#[inline(always)]
fn item(id: UVec3, groups: UVec3) -> u32 {
    id.x + id.y * groups.x * WORKGROUP
}

#[spirv(compute(threads(64)))]
pub fn camera_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &mut [Ray],
) {
    let i = item(id, groups);
    if i < params.count {
        rays[i as usize] = camera::primary_ray(&params.camera, params.first + i);
    }
}

#[spirv(compute(threads(64)))]
pub fn closest_hit_brute(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] hits: &mut [Hit],
) {
    let i = item(id, groups);
    if i < params.count {
        hits[i as usize] = brute::closest_hit(&rays[i as usize], tris);
    }
}

#[spirv(compute(threads(64)))]
pub fn any_hit_brute(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] occluded: &mut [u32],
) {
    let i = item(id, groups);
    if i < params.count {
        occluded[i as usize] = brute::any_hit(&rays[i as usize], tris) as u32;
    }
}

#[spirv(compute(threads(64)))]
pub fn light_sample(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] shadow_rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] terms: &mut [ShadeTerms],
) {
    let i = item(id, groups);
    if i < params.count {
        let k = i as usize;
        let (ray, t) = shade::light_sample(
            params.seed,
            params.first + i,
            &rays[k],
            &hits[k],
            tris,
            materials,
            lights,
            params.light_count,
        );
        shadow_rays[k] = ray;
        terms[k] = t;
    }
}

#[spirv(compute(threads(64)))]
pub fn resolve(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] terms: &[ShadeTerms],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] occluded: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] radiance: &mut [[f32; 4]],
) {
    let i = item(id, groups);
    if i < params.count {
        let k = i as usize;
        radiance[k] = shade::resolve(&terms[k], occluded[k] != 0);
    }
}

/// Four numbers of the stream (seed, first + i) per item: checks CPU/GPU RNG identity.
#[spirv(compute(threads(64)))]
pub fn rng_fill(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] out: &mut [[u32; 4]],
) {
    let i = item(id, groups);
    if i < params.count {
        let mut rng = Rng::new(params.seed, params.first + i);
        out[i as usize] = [rng.next_u32(), rng.next_u32(), rng.next_u32(), rng.next_u32()];
    }
}
