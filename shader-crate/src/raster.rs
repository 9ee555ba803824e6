//! Rasterised primary hits (`kdray_shared::raster`): the vertex and fragment shaders that draw
//! the scene's triangle ids into the visibility buffer (wgpu's render pipeline, a depth test),
//! and the kernels that resolve each pixel's primary hit from it, tracing with the BVH or the
//! kd-tree's full stack where the candidate cannot be trusted. Bindings as the trace kernels':
//! `params`, the scene's `tris` in three parts, the structure's arrays, `visible`, `out`.
use kdray_shared::aabb::Aabb;
use kdray_shared::bvh::{BvhNode, TriWords};
use kdray_shared::kdtree::{Full, KdNode};
use kdray_shared::raster;
use kdray_shared::trace::{Kd, Wide};
use kdray_shared::{Hit, RasterParams, Triangle};
use crate::parts;
use spirv_std::glam::{UVec3, Vec4};
use spirv_std::spirv;

/// Vertex `vertex_index` of the draw: a corner of triangle `vertex_index / 3`, projected by the
/// camera (`RasterParams::clip`), with the pixel value of its triangle.
#[spirv(vertex)]
pub fn raster_vertex(
    #[spirv(vertex_index)] vertex_index: u32,
    #[spirv(spec_constant(id = 0))] split: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RasterParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris2: &[Triangle],
    #[spirv(position)] position: &mut Vec4,
    #[spirv(flat)] value: &mut u32,
) {
    let (c, v) = raster::vertex(params, &parts(split, tris, tris1, tris2), vertex_index);
    *position = Vec4::new(c[0], c[1], c[2], c[3]);
    *value = v;
}

/// The nearest fragment's triangle (the depth test chose it) into the visibility buffer.
#[spirv(fragment)]
pub fn raster_fragment(#[spirv(flat)] value: u32, out: &mut u32) {
    *out = value;
}

/// The primary hits from the visibility buffer, tracing through the BVH where needed.
#[spirv(compute(threads(64)))]
pub fn primary_raster_bvh(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(spec_constant(id = 0))] split_tris: u32,
    #[spirv(spec_constant(id = 3))] split: [u32; 2],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RasterParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris2: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] bvh: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] bvh1: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] bvh2: &[BvhNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] bvh_tris: &[TriWords],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] bvh_tris1: &[TriWords],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] bvh_tris2: &[TriWords],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] visible: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] out: &mut [Hit],
) {
    let tris = parts(split_tris, tris, tris1, tris2);
    let bvh = crate::bvh_view(Aabb { min: [0.0; 3], max: [0.0; 3] }, tris, parts(split[0], bvh, bvh1, bvh2), parts(split[1], bvh_tris, bvh_tris1, bvh_tris2));
    raster::primary_hit::<Wide, _>(crate::item(id, groups), params, &bvh, &tris, visible, out);
}

/// The primary hits from the visibility buffer, tracing with the kd-tree's full stack where
/// needed. `scene_box`: the tree's root box (min in element 0, max in element 1).
#[spirv(compute(threads(64)))]
pub fn primary_raster_stack(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(spec_constant(id = 0))] split: [u32; 3],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RasterParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris2: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] nodes1: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] nodes2: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] prims: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] prims1: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] prims2: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] scene_box: &[[f32; 4]],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] visible: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] out: &mut [Hit],
) {
    let (lo, hi) = (scene_box[0], scene_box[1]);
    let tris = parts(split[0], tris, tris1, tris2);
    let tree = crate::kd_view(Aabb { min: [lo[0], lo[1], lo[2]], max: [hi[0], hi[1], hi[2]] }, tris, parts(split[1], nodes, nodes1, nodes2), parts(split[2], prims, prims1, prims2));
    raster::primary_hit::<Kd<Full>, _>(crate::item(id, groups), params, &tree, &tris, visible, out);
}
