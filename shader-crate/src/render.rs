//! The eye-path entry points (`kdray_shared::render`).
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::{BvhNode, TriWords};
use kdray_shared::kdtree::{Full, KdNode, Short};
use kdray_shared::render;
use kdray_shared::trace::{Brute, Kd, Wide};
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
pub fn continue_paths(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] paths: &mut [PathState],
) {
    render::continue_paths(crate::item(id, groups), params, rays, paths);
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

/// One entry point running `render::trace_path::<$m>` (a pixel sample's path from the camera
/// to its end per thread). `scene_box` holds the traversals' root box: min in element 0, max in
/// element 1 (the push constants have no room left for it). `$a`, `$b` are the structure's two
/// buffers (kd: `nodes`, `prims`; BVH: `bvh`, `bvh_tris`) and `$view` makes its view of them.
macro_rules! eye_paths {
    ($name:ident, $m:ty, $a:ident: $at:ty, $b:ident: $bt:ty, $view:ident) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(push_constant)] params: &RenderParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] scene_box: &[[f32; 4]],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] $a: &[$at],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] $b: &[$bt],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] rays: &mut [Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] paths: &mut [PathState],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] primary_hits: &mut [Hit],
        ) {
            let (lo, hi) = (scene_box[0], scene_box[1]);
            let accel = crate::$view(Aabb { min: [lo[0], lo[1], lo[2]], max: [hi[0], hi[1], hi[2]] }, tris, $a, $b);
            render::trace_path::<$m, _, _, _>(crate::item(id, groups), params, &accel, tris, materials, lights, rays, paths, primary_hits);
        }
    };
}

eye_paths!(eye_paths_brute, Brute, nodes: KdNode, prims: u32, kd_view);
eye_paths!(eye_paths_stack, Kd<Full>, nodes: KdNode, prims: u32, kd_view);
eye_paths!(eye_paths_shortstack3, Kd<Short<3>>, nodes: KdNode, prims: u32, kd_view);
eye_paths!(eye_paths_bvh, Wide, bvh: BvhNode, bvh_tris: TriWords, bvh_view);
