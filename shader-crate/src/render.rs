//! The eye-path entry points (`kdray_shared::render`).
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::{BvhNode, TriWords};
use kdray_shared::kdtree::{Full, KdNode, Short};
use crate::parts;
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
    #[spirv(spec_constant(id = 0))] split: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris2: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] shadow_rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] terms: &mut [ShadeTerms],
) {
    let tris = parts(split, tris, tris1, tris2);
    render::path_step(crate::item(id, groups), params, rays, &tris, hits, materials, lights, paths, shadow_rays, terms);
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
    ($name:ident, $given:literal, $m:ty, $id:literal, $a:ident, $a1:ident, $a2:ident: $at:ty, $b:ident, $b1:ident, $b2:ident: $bt:ty, $view:ident) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(push_constant)] params: &RenderParams,
            #[spirv(spec_constant(id = 0))] split_tris: u32,
            #[spirv(spec_constant(id = $id))] split: [u32; 2],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] scene_box: &[[f32; 4]],
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
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] rays: &mut [Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] paths: &mut [PathState],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 14)] primary_hits: &mut [Hit],
        ) {
            let (lo, hi) = (scene_box[0], scene_box[1]);
            let tris = parts(split_tris, tris, tris1, tris2);
            let (a, b) = (parts(split[0], $a, $a1, $a2), parts(split[1], $b, $b1, $b2));
            let accel = crate::$view(Aabb { min: [lo[0], lo[1], lo[2]], max: [hi[0], hi[1], hi[2]] }, tris, a, b);
            render::trace_path::<$m, _, _, _, $given>(crate::item(id, groups), params, &accel, &tris, materials, lights, rays, paths, primary_hits);
        }
    };
}

eye_paths!(eye_paths_brute, false, Brute, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
eye_paths!(eye_paths_stack, false, Kd<Full>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
eye_paths!(eye_paths_shortstack3, false, Kd<Short<3>>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
eye_paths!(eye_paths_bvh, false, Wide, 3, bvh, bvh1, bvh2: BvhNode, bvh_tris, bvh_tris1, bvh_tris2: TriWords, bvh_view);
// Paths from given primary hits (`RENDER_PRIMARY_GIVEN`: the rasterised primaries' structures).
eye_paths!(eye_paths_given_stack, true, Kd<Full>, 1, nodes, nodes1, nodes2: KdNode, prims, prims1, prims2: u32, kd_view);
eye_paths!(eye_paths_given_bvh, true, Wide, 3, bvh, bvh1, bvh2: BvhNode, bvh_tris, bvh_tris1, bvh_tris2: TriWords, bvh_view);
