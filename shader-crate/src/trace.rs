//! Closest-hit and any-hit entry points: one per way of finding hits (brute force, each kd
//! traversal, four-ray packets, the decomposed pipeline's three steps, the wide BVH one ray or
//! four per thread). All share
//! the binding names `params`, `rays`, `tris`, `nodes`, `prims` and (but `traverse_leaves`)
//! `out`; the decomposed pipeline adds `lists` and `status`; brute force does not use
//! `nodes`/`prims`; the BVH binds `bvh` and `bvh_tris` instead of `tris`, `nodes`, `prims`.
//! The scene's arrays come in three parts each (`tris`, `tris1`, `tris2`, …: see the crate's
//! docs). The parameters come in a small storage buffer, not as push constants: on
//! the H100 the packet kernels' shadow rays ran 7–17 % slower with push constants (same
//! SPIR-V otherwise), the other kernels the same.
use kdray_shared::kdtree::{Full, KdNode, LeafRef, PushDown, Restart, Short};
use kdray_shared::query::{AnyHit, Closest, Prims};
use kdray_shared::bvh::{Bvh, BvhNode, TriWords, BVH_PACKET};
use kdray_shared::trace::{self, Brute, Kd, Wide};
use kdray_shared::{Hit, Ray, TraceParams, Triangle};
use crate::parts;
use spirv_std::glam::UVec3;
use spirv_std::spirv;

/// The kd-tree of a trace entry point's bindings: `split` holds the specialization constants of
/// `tris`, `nodes`, `prims` (ids 0, 1, 2), each bound as three parts.
macro_rules! kd_tree {
    ($params:ident, $split:ident, $t0:ident, $t1:ident, $t2:ident, $n0:ident, $n1:ident, $n2:ident, $p0:ident, $p1:ident, $p2:ident) => {
        trace::tree($params, parts($split[0], $t0, $t1, $t2), parts($split[1], $n0, $n1, $n2), parts($split[2], $p0, $p1, $p2))
    };
}

/// One entry point running `trace::$f::<$t, $query>` (one ray, or one packet, per thread).
macro_rules! trace_kernel {
    ($name:ident, $query:ident, $out:ty, $f:ident, $t:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(spec_constant(id = 0))] split: [u32; 3],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris1: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] tris2: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] nodes1: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] nodes2: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] prims1: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] prims2: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] out: &mut [$out],
        ) {
            let tree = kd_tree!(params, split, tris, tris1, tris2, nodes, nodes1, nodes2, prims, prims1, prims2);
            trace::$f::<$t, $query, _>(crate::item(id, groups), params, rays, &tree, out);
        }
    };
}

/// The BVH's entry point for `$query`: `trace::trace::<Wide, $query>` for one ray per thread,
/// or for each of four (the GPU side of `bvh+packets`).
macro_rules! bvh_kernel {
    ($name:ident, $query:ident, $out:ty, $packet:literal) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(spec_constant(id = 3))] split: [u32; 2],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] bvh: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] bvh1: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] bvh2: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] bvh_tris: &[TriWords],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] bvh_tris1: &[TriWords],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] bvh_tris2: &[TriWords],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] out: &mut [$out],
        ) {
            let bvh = Bvh { nodes: parts(split[0], bvh, bvh1, bvh2), tris: parts(split[1], bvh_tris, bvh_tris1, bvh_tris2) };
            if $packet {
                // A thread's four rays one by one: the packet walk is the CPU's (see
                // `Accel::BVH_PACKETS`).
                let first = crate::item(id, groups) * BVH_PACKET as u32;
                let mut l = 0;
                while l < BVH_PACKET as u32 {
                    trace::trace::<Wide, $query, _>(first + l, params, rays, &bvh, out);
                    l += 1;
                }
            } else {
                trace::trace::<Wide, $query, _>(crate::item(id, groups), params, rays, &bvh, out);
            }
        }
    };
}

/// The closest-hit and any-hit entry points of one method.
macro_rules! trace_kernels {
    ($closest:ident, $any:ident, trace_wide) => {
        bvh_kernel!($closest, Closest, Hit, false);
        bvh_kernel!($any, AnyHit, u32, false);
    };
    ($closest:ident, $any:ident, trace_wide_packet) => {
        bvh_kernel!($closest, Closest, Hit, true);
        bvh_kernel!($any, AnyHit, u32, true);
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
// The BVH, four rays per thread (natively, `bvh::traverse_packet`'s packets).
trace_kernels!(closest_packet_bvh, any_packet_bvh, trace_wide_packet);

/// Decomposed pipeline, step 1 (`trace::traverse_leaves`).
#[spirv(compute(threads(64)))]
pub fn traverse_leaves(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(spec_constant(id = 0))] split: [u32; 3],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris1: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] tris2: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] nodes1: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] nodes2: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] prims: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] prims1: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] prims2: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] lists: &mut [LeafRef],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] status: &mut [u32],
) {
    let tree = kd_tree!(params, split, tris, tris1, tris2, nodes, nodes1, nodes2, prims, prims1, prims2);
    trace::traverse_leaves(crate::item(id, groups), params, rays, &tree, lists, status);
}

/// Decomposed pipeline, steps 2 (`trace::intersect_listed`) and 3 (`trace::fallback`).
macro_rules! leaf_kernels {
    ($intersect:ident, $fallback:ident, $query:ident, $out:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $intersect(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(spec_constant(id = 0))] split_tris: u32,
            #[spirv(spec_constant(id = 2))] split_prims: u32,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris1: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] tris2: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] prims1: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] prims2: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] lists: &[LeafRef],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] status: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] out: &mut [$out],
        ) {
            // The leaves' primitives only: the nodes are not bound.
            let g = Prims { index: parts(split_prims, prims, prims1, prims2), tris: parts(split_tris, tris, tris1, tris2) };
            trace::intersect_listed::<$query, _, _>(crate::item(id, groups), params, rays, &g, lists, status, out);
        }

        #[spirv(compute(threads(64)))]
        pub fn $fallback(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(spec_constant(id = 0))] split: [u32; 3],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &TraceParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] tris1: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] tris2: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] nodes1: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] nodes2: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] prims1: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] prims2: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] status: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] out: &mut [$out],
        ) {
            let tree = kd_tree!(params, split, tris, tris1, tris2, nodes, nodes1, nodes2, prims, prims1, prims2);
            trace::fallback::<$query, _>(crate::item(id, groups), params, rays, &tree, status, out);
        }
    };
}

leaf_kernels!(closest_leaves, closest_fallback, Closest, Hit);
leaf_kernels!(any_leaves, any_fallback, AnyHit, u32);
