//! GPU entry points. Each kernel is a thin wrapper: it finds its work item, calls the one
//! implementation in `kdray-shared`, and stores the result. Binding 0 is always the
//! `FrameParams`; the host's kernel table (host/src/gpu/kernels.rs) mirrors these bindings.
//!
//! Work items are numbered over a 2D grid of 64-wide workgroups so a dispatch can exceed the
//! 65 535-workgroup limit of one dimension: `item = x + y · (groups_x · 64)`.
#![no_std]

use kdray_shared::aabb::Aabb;
use kdray_shared::kdtree::{
    intersect_leaves, packet_or_single, record_leaves, traverse, AnyHit, Closest, Entry, FullStack, KdNode,
    KdTree, LeafRef, NoStack, NoStats, PacketEntry, Query, ShortStack, MAX_DEPTH, PACKET,
};
use kdray_shared::brute::BruteForce;
use kdray_shared::{
    camera, shade, FrameParams, Hit, Light, Material, PathState, Ray, ShadeTerms, Triangle,
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
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] paths: &mut [PathState],
) {
    let i = item(id, groups);
    if i < params.count {
        let pixel = camera::pixel(&params.camera, params.first + i);
        rays[i as usize] = camera::primary_ray(&params.camera, pixel);
        paths[i as usize] = PathState::start(pixel);
    }
}

/// What a query stores per ray: the hit (closest hit) or 1/0 (any hit).
trait Answer {
    type Out;
    fn answer(&self) -> Self::Out;
}
impl Answer for Closest {
    type Out = Hit;
    #[inline(always)]
    fn answer(&self) -> Hit {
        self.hit
    }
}
impl Answer for AnyHit {
    type Out = u32;
    #[inline(always)]
    fn answer(&self) -> u32 {
        self.found as u32
    }
}

/// Closest-hit and any-hit entry points for one way of finding hits. All of them share one
/// binding layout: 1 rays, 2 triangles, 3 kd-tree nodes, 4 primitive indices, 5 results
/// (brute force leaves 3 and 4 unused).
macro_rules! trace_kernel {
    ($name:ident, $query:ident, $out:ty, |$tree:ident, $ray:ident, $q:ident| $run:expr) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] out: &mut [$out],
        ) {
            let i = item(id, groups);
            if i < params.count {
                let $tree = tree(params, tris, nodes, prims);
                let $ray = &rays[i as usize];
                let mut $q = $query::new($ray);
                $run;
                out[i as usize] = $q.answer();
            }
        }
    };
}

macro_rules! trace_kernels {
    ($closest:ident, $any:ident, |$tree:ident, $ray:ident, $q:ident| $run:expr) => {
        trace_kernel!($closest, Closest, Hit, |$tree, $ray, $q| $run);
        trace_kernel!($any, AnyHit, u32, |$tree, $ray, $q| $run);
    };
}

#[inline(always)]
fn tree<'a>(params: &FrameParams, tris: &'a [Triangle], nodes: &'a [KdNode], prims: &'a [u32]) -> KdTree<'a> {
    KdTree { nodes, prims, tris, bounds: Aabb { min: params.bounds_min, max: params.bounds_max } }
}

trace_kernels!(closest_brute, any_brute, |t, r, q| q.brute(r, t.tris));
trace_kernels!(closest_stack, any_stack, |t, r, q| traverse::<_, _, _, false>(&t, r, &mut q, &mut FullStack::new(), &mut NoStats));
trace_kernels!(closest_restart, any_restart, |t, r, q| traverse::<_, _, _, false>(&t, r, &mut q, &mut NoStack::new(), &mut NoStats));
trace_kernels!(closest_pushdown, any_pushdown, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut NoStack::new(), &mut NoStats));
trace_kernels!(closest_shortstack1, any_shortstack1, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<Entry, 1>::new(), &mut NoStats));
trace_kernels!(closest_shortstack2, any_shortstack2, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<Entry, 2>::new(), &mut NoStats));
trace_kernels!(closest_shortstack3, any_shortstack3, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<Entry, 3>::new(), &mut NoStats));
trace_kernels!(closest_shortstack4, any_shortstack4, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<Entry, 4>::new(), &mut NoStats));
trace_kernels!(closest_shortstack8, any_shortstack8, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<Entry, 8>::new(), &mut NoStats));

/// Four rays per thread (Horn et al.'s packets): thread `i` traces rays 4i..4i+3 together when
/// their direction signs agree, else one by one. `$kp`/`$k` are the packet and single-ray stacks.
macro_rules! packet_kernel {
    ($name:ident, $query:ident, $out:ty, $kp:ty, $k:ty, $pushdown:expr) => {
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] out: &mut [$out],
        ) {
            let first = item(id, groups) * PACKET as u32;
            if first < params.count {
                let t = tree(params, tris, nodes, prims);
                let r = packet_rays(params, rays, first);
                let mut qs = [$query::new(&r[0]), $query::new(&r[1]), $query::new(&r[2]), $query::new(&r[3])];
                packet_or_single::<_, $kp, $k, _, $pushdown>(&t, &r, &mut qs, &mut NoStats);
                let mut l = 0;
                while l < PACKET as u32 {
                    if first + l < params.count {
                        out[(first + l) as usize] = qs[l as usize].answer();
                    }
                    l += 1;
                }
            }
        }
    };
}

macro_rules! packet_kernels {
    ($closest:ident, $any:ident, $kp:ty, $k:ty, $pushdown:expr) => {
        packet_kernel!($closest, Closest, Hit, $kp, $k, $pushdown);
        packet_kernel!($any, AnyHit, u32, $kp, $k, $pushdown);
    };
}

/// Rays `first..first + 4`; past the end of the batch, invalid rays (misses, never written).
#[inline(always)]
fn packet_rays(params: &FrameParams, rays: &[Ray], first: u32) -> [Ray; PACKET] {
    let mut r = [Ray::default(); PACKET];
    let mut l = 0;
    while l < PACKET as u32 {
        if first + l < params.count {
            r[l as usize] = rays[(first + l) as usize];
        }
        l += 1;
    }
    r
}

packet_kernels!(closest_packet_stack, any_packet_stack, ShortStack<PacketEntry, MAX_DEPTH>, FullStack, false);
packet_kernels!(closest_packet_restart, any_packet_restart, NoStack, NoStack, false);
packet_kernels!(closest_packet_pushdown, any_packet_pushdown, NoStack, NoStack, true);
packet_kernels!(closest_packet_shortstack3, any_packet_shortstack3, ShortStack<PacketEntry, 3>, ShortStack<Entry, 3>, true);

/// Decomposed pipeline, step 1: each ray's non-empty leaves (full-stack traversal) into
/// `lists[i · cap ..]`, the count and overflow bit into `status[i]`.
#[spirv(compute(threads(64)))]
pub fn traverse_leaves(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lists: &mut [LeafRef],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] status: &mut [u32],
) {
    let i = item(id, groups);
    if i < params.count {
        let t = tree(params, tris, nodes, prims);
        let cap = params.leaf_capacity;
        let l = record_leaves(&t, &rays[i as usize], cap, &mut NoStats);
        let base = (i * cap) as usize;
        let mut k = 0;
        while k < l.len {
            lists[base + k as usize] = l.entries[k as usize];
            k += 1;
        }
        status[i as usize] = l.status();
    }
}

/// Decomposed pipeline, step 2 (closest / any hit over the listed leaves) and its fallback:
/// step 2 leaves `status[i]` = 1 where the list overflowed without settling the query (0
/// elsewhere); the fallback kernel traces exactly those rays with the full-stack traversal.
macro_rules! leaf_kernels {
    ($intersect:ident, $fallback:ident, $query:ident, $out:ty) => {
        #[spirv(compute(threads(64)))]
        pub fn $intersect(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lists: &[LeafRef],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] status: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] out: &mut [$out],
        ) {
            let i = item(id, groups);
            if i < params.count {
                let k = i as usize;
                let t = tree(params, tris, nodes, prims);
                let ray = &rays[k];
                let mut q = $query::new(ray);
                let settled = intersect_leaves(&t, ray, lists, k * params.leaf_capacity as usize, status[k], &mut q, &mut NoStats);
                status[k] = !settled as u32;
                out[k] = q.answer();
            }
        }

        #[spirv(compute(threads(64)))]
        pub fn $fallback(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] status: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] out: &mut [$out],
        ) {
            let i = item(id, groups);
            if i < params.count && status[i as usize] != 0 {
                let t = tree(params, tris, nodes, prims);
                let ray = &rays[i as usize];
                let mut q = $query::new(ray);
                traverse::<_, _, _, false>(&t, ray, &mut q, &mut FullStack::new(), &mut NoStats);
                out[i as usize] = q.answer();
            }
        }
    };
}

leaf_kernels!(closest_leaves, closest_fallback, Closest, Hit);
leaf_kernels!(any_leaves, any_fallback, AnyHit, u32);

/// One bounce of every path: reflect at mirrors (updating `rays` in place) or shade.
#[spirv(compute(threads(64)))]
pub fn path_step(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] hits: &[Hit],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] shadow_rays: &mut [Ray],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] terms: &mut [ShadeTerms],
) {
    let i = item(id, groups);
    if i < params.count {
        let k = i as usize;
        let mut ray = rays[k];
        let mut path = paths[k];
        let (shadow, t) = shade::path_step(
            params.seed,
            params.bounce,
            params.max_bounces,
            &mut ray,
            &hits[k],
            &mut path,
            tris,
            materials,
            lights,
            params.light_count,
        );
        rays[k] = ray;
        paths[k] = path;
        shadow_rays[k] = shadow;
        terms[k] = t;
    }
}

/// Adds each path's shaded terms; writes the pixel's radiance so far.
#[spirv(compute(threads(64)))]
pub fn accumulate(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] terms: &[ShadeTerms],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] occluded: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] paths: &mut [PathState],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] radiance: &mut [[f32; 4]],
) {
    let i = item(id, groups);
    if i < params.count {
        let k = i as usize;
        let mut path = paths[k];
        shade::accumulate(&mut path, &terms[k], occluded[k] != 0);
        paths[k] = path;
        radiance[k] = [path.radiance[0], path.radiance[1], path.radiance[2], 1.0];
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
