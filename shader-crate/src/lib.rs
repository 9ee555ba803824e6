//! GPU entry points. Each kernel is a thin wrapper: it finds its work item, calls the one
//! implementation in `kdray-shared`, and stores the result. Binding 0 is always the
//! `FrameParams`; the host's kernel table (host/src/gpu/kernels.rs) mirrors these bindings.
//!
//! Work items are numbered over a 2D grid of 64-wide workgroups so a dispatch can exceed the
//! 65 535-workgroup limit of one dimension: `item = x + y · (groups_x · 64)`.
#![no_std]

use kdray_shared::aabb::Aabb;
use kdray_shared::kdtree::{
    traverse, AnyHit, Closest, FullStack, KdNode, KdTree, NoStack, NoStats, ShortStack,
};
use kdray_shared::{
    brute, camera, shade, FrameParams, Hit, Light, Material, PathState, Ray, ShadeTerms, Triangle,
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
        rays[i as usize] = camera::primary_ray(&params.camera, params.first + i);
        paths[i as usize] = PathState::START;
    }
}

/// Closest-hit and any-hit entry points for one way of finding hits. All of them share one
/// binding layout: 1 rays, 2 triangles, 3 kd-tree nodes, 4 primitive indices, 5 results
/// (brute force leaves 3 and 4 unused).
macro_rules! trace_kernels {
    ($closest:ident, $any:ident, |$tree:ident, $ray:ident, $q:ident| $run:expr) => {
        #[spirv(compute(threads(64)))]
        pub fn $closest(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] hits: &mut [Hit],
        ) {
            let i = item(id, groups);
            if i < params.count {
                let $tree = tree(params, tris, nodes, prims);
                let $ray = &rays[i as usize];
                let mut $q = Closest::new($ray);
                $run;
                hits[i as usize] = $q.hit;
            }
        }

        #[spirv(compute(threads(64)))]
        pub fn $any(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(num_workgroups)] groups: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] rays: &[Ray],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] tris: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[KdNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] prims: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] occluded: &mut [u32],
        ) {
            let i = item(id, groups);
            if i < params.count {
                let $tree = tree(params, tris, nodes, prims);
                let $ray = &rays[i as usize];
                let mut $q = AnyHit::new($ray);
                $run;
                occluded[i as usize] = $q.found as u32;
            }
        }
    };
}

#[inline(always)]
fn tree<'a>(params: &FrameParams, tris: &'a [Triangle], nodes: &'a [KdNode], prims: &'a [u32]) -> KdTree<'a> {
    KdTree { nodes, prims, tris, bounds: Aabb { min: params.bounds_min, max: params.bounds_max } }
}

/// The oracle: every triangle, no tree.
trait BruteQuery {
    fn brute(&mut self, tree: &KdTree, ray: &Ray);
}
impl BruteQuery for Closest {
    #[inline(always)]
    fn brute(&mut self, tree: &KdTree, ray: &Ray) {
        self.hit = brute::closest_hit(ray, tree.tris);
    }
}
impl BruteQuery for AnyHit {
    #[inline(always)]
    fn brute(&mut self, tree: &KdTree, ray: &Ray) {
        self.found = brute::any_hit(ray, tree.tris);
    }
}

trace_kernels!(closest_brute, any_brute, |t, r, q| q.brute(&t, r));
trace_kernels!(closest_stack, any_stack, |t, r, q| traverse::<_, _, _, false>(&t, r, &mut q, &mut FullStack::new(), &mut NoStats));
trace_kernels!(closest_restart, any_restart, |t, r, q| traverse::<_, _, _, false>(&t, r, &mut q, &mut NoStack::new(), &mut NoStats));
trace_kernels!(closest_pushdown, any_pushdown, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut NoStack::new(), &mut NoStats));
trace_kernels!(closest_shortstack1, any_shortstack1, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<1>::new(), &mut NoStats));
trace_kernels!(closest_shortstack2, any_shortstack2, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<2>::new(), &mut NoStats));
trace_kernels!(closest_shortstack3, any_shortstack3, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<3>::new(), &mut NoStats));
trace_kernels!(closest_shortstack4, any_shortstack4, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<4>::new(), &mut NoStats));
trace_kernels!(closest_shortstack8, any_shortstack8, |t, r, q| traverse::<_, _, _, true>(&t, r, &mut q, &mut ShortStack::<8>::new(), &mut NoStats));

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
            params.first + i,
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
