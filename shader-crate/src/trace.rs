//! Closest-hit and any-hit entry points: one per way of finding hits (brute force, each kd
//! traversal, four-ray packets, the decomposed pipeline's three steps, the wide BVH). All share
//! the binding names `params`, `rays`, `tris`, `nodes`, `prims` and (but `traverse_leaves`)
//! `out`; the decomposed pipeline adds `lists` and `status`; brute force does not use
//! `nodes`/`prims`; the BVH binds `bvh` and `bvh_tris` instead of `tris`, `nodes`, `prims`. The parameters come in a small storage buffer, not as push constants: on
//! the H100 the packet kernels' shadow rays ran 7–17 % slower with push constants (same
//! SPIR-V otherwise), the other kernels the same.
use kdray_shared::kdtree::{Full, KdNode, LeafRef, PushDown, Restart, Short};
use kdray_shared::query::{AnyHit, Closest};
use kdray_shared::bvh::{Bvh, BvhNode, TriWords};
use kdray_shared::trace::{self, Brute, Kd, Wide};
use kdray_shared::{Hit, Ray, TraceParams, Triangle};
use spirv_std::glam::UVec3;
use spirv_std::spirv;

/// One entry point running `trace::$f::<$t, $query>` (one ray, or one packet, per thread).
macro_rules! trace_kernel {
    ($name:ident, $query:ident, $out:ty, $f:ident, $t:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] out: &mut [$out],
        ) {
            trace::$f::<$t, $query, _>(crate::item(id, groups), params, rays, &trace::tree(params, tris, nodes, prims), out);
        }
    };
}

/// The BVH's entry point for `$query` (`trace::trace::<Wide, $query>`).
macro_rules! bvh_kernel {
    ($name:ident, $query:ident, $out:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] bvh: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] bvh_tris: &[TriWords],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] out: &mut [$out],
        ) {
            trace::trace::<Wide, $query, _>(crate::item(id, groups), params, rays, &Bvh { nodes: bvh, tris: bvh_tris }, out);
        }
    };
}

/// The closest-hit and any-hit entry points of one method.
macro_rules! trace_kernels {
    ($closest:ident, $any:ident, trace_wide) => {
        bvh_kernel!($closest, Closest, Hit);
        bvh_kernel!($any, AnyHit, u32);
    };
    ($closest:ident, $any:ident, $f:ident, $t:ty) => {
        trace_kernel!($closest, Closest, Hit, $f, $t);
        trace_kernel!($any, AnyHit, u32, $f, $t);
    };
}

trace_kernels!(closest_brute, any_brute, trace, Brute);
trace_kernels!(closest_stack, any_stack, trace, Kd<Full>);
trace_kernels!(closest_restart, any_restart, trace, Kd<Restart>);
trace_kernels!(closest_pushdown, any_pushdown, trace, Kd<PushDown>);
trace_kernels!(closest_shortstack1, any_shortstack1, trace, Kd<Short<1>>);
trace_kernels!(closest_shortstack2, any_shortstack2, trace, Kd<Short<2>>);
trace_kernels!(closest_shortstack3, any_shortstack3, trace, Kd<Short<3>>);
trace_kernels!(closest_shortstack4, any_shortstack4, trace, Kd<Short<4>>);
trace_kernels!(closest_shortstack8, any_shortstack8, trace, Kd<Short<8>>);
// The compressed 8-wide BVH: `bvh` holds its nodes and `bvh_tris` the triangles in leaf
// order (each with its scene index); the scene's `tris` are not needed. (Its bindings have no
// gap: with binding numbers 0, 1, 3, 4, 5 lavapipe 22.3 ran the kernel without writing `out`.)
trace_kernels!(closest_bvh, any_bvh, trace_wide);
// Four rays per thread (Horn et al.'s packets).
trace_kernels!(closest_packet_stack, any_packet_stack, trace_packet, Full);
trace_kernels!(closest_packet_restart, any_packet_restart, trace_packet, Restart);
trace_kernels!(closest_packet_pushdown, any_packet_pushdown, trace_packet, PushDown);
trace_kernels!(closest_packet_shortstack3, any_packet_shortstack3, trace_packet, Short<3>);

/// Decomposed pipeline, step 1 (`trace::traverse_leaves`).
#[spirv(compute(threads(64)))]
pub fn traverse_leaves(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lists: &mut [LeafRef],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] status: &mut [u32],
) {
    trace::traverse_leaves(crate::item(id, groups), params, rays, &trace::tree(params, tris, nodes, prims), lists, status);
}

/// Decomposed pipeline, steps 2 (`trace::intersect_listed`) and 3 (`trace::fallback`).
macro_rules! leaf_kernels {
    ($intersect:ident, $fallback:ident, $query:ident, $out:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $intersect(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lists: &[LeafRef],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] status: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] out: &mut [$out],
        ) {
            trace::intersect_listed::<$query, _, _>(crate::item(id, groups), params, rays, &trace::tree(params, tris, nodes, prims), lists, status, out);
        }

        #[spirv(compute(threads(64)))]
        pub fn $fallback(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] status: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] out: &mut [$out],
        ) {
            trace::fallback::<$query, _>(crate::item(id, groups), params, rays, &trace::tree(params, tris, nodes, prims), status, out);
        }
    };
}

leaf_kernels!(closest_leaves, closest_fallback, Closest, Hit);
leaf_kernels!(any_leaves, any_fallback, AnyHit, u32);
