//! GPU entry points. Each is a thin wrapper: it declares its bindings, finds its work item and
//! calls the per-item function in `kdray-shared` (`trace`, `render`), which the host's native
//! runtime calls too. Parameters are push constants (render) or a small read-only storage
//! buffer named `params` (trace; measured faster there). The host reads every entry point's
//! name, workgroup size and bindings (number, name, element size, read-only or not) from the
//! SPIR-V module itself and checks its typed passes against them, so nothing here is listed
//! again on the host.
//!
//! Arrays of the scene that may exceed one storage binding (`kdray_shared::parts::SPLIT_BINDINGS`:
//! triangles, kd-tree nodes and primitive indices, BVH nodes and triangles) are bound as three
//! parts each (`tris`, `tris1`, `tris2`, …) with a specialization constant saying how they are
//! split; the host binds one buffer thrice for a scene that fits.
//!
//! Work items are numbered over a 2D grid of workgroups so a dispatch can exceed the 65 535-
//! workgroup limit of one dimension: `item = x + y · (groups_x · WORKGROUP)`.
//!
//! Kernel families are cargo features (`trace`, `render`, `sort`, `photon`, `raster`, `build`; all on by default), so a user can
//! build a module with only what they need. The crate also builds for the host (as a normal
//! library), where the entry points are plain functions that unit tests call.
#![cfg_attr(target_arch = "spirv", no_std)]

#[cfg(feature = "trace")]
mod trace;
#[cfg(feature = "render")]
mod render;
#[cfg(feature = "sort")]
mod sort;
#[cfg(feature = "photon")]
mod photon;
#[cfg(feature = "raster")]
mod raster;
#[cfg(feature = "build")]
mod build;

#[cfg(feature = "trace")]
pub use trace::*;
#[cfg(feature = "render")]
pub use render::*;
#[cfg(feature = "sort")]
pub use sort::*;
#[cfg(feature = "photon")]
pub use photon::*;
#[cfg(feature = "raster")]
pub use raster::*;
#[cfg(feature = "build")]
pub use build::*;

use kdray_shared::kernel::{AtomicStore, Lanes, Store};
use kdray_shared::parts::Parts;
use spirv_std::glam::UVec3;

/// An array bound as up to three parts (`kdray_shared::parts`): `split` is the array's
/// specialization constant, whose default 0 (one part) the driver folds.
#[inline(always)]
pub fn parts<'a, T: Copy>(split: u32, p0: &'a [T], p1: &'a [T], p2: &'a [T]) -> Parts<'a, T> {
    Parts::new(split, p0, p1, p2)
}

/// The kd-tree (or, for brute force, the triangles) as the whole-path kernels see it.
#[inline(always)]
pub fn kd_view<'a>(bounds: kdray_shared::aabb::Aabb, tris: Parts<'a, kdray_shared::Triangle>, nodes: Parts<'a, kdray_shared::kdtree::KdNode>, prims: Parts<'a, u32>) -> kdray_shared::kdtree::KdTree<'a> {
    kdray_shared::kdtree::KdTree { nodes, prims, tris, bounds }
}

/// The wide BVH as the whole-path kernels see it (its nodes and leaf-ordered triangles; the
/// scene's box and triangles are not part of it).
#[inline(always)]
pub fn bvh_view<'a>(_bounds: kdray_shared::aabb::Aabb, _tris: Parts<'a, kdray_shared::Triangle>, bvh: Parts<'a, kdray_shared::bvh::BvhNode>, bvh_tris: Parts<'a, kdray_shared::bvh::TriWords>) -> kdray_shared::bvh::Bvh<'a> {
    kdray_shared::bvh::Bvh { nodes: bvh, tris: bvh_tris }
}

/// Threads per workgroup (`#[spirv(compute(threads(64)))]` on every entry point).
pub use kdray_shared::kernel::WORKGROUP;

/// The work item of invocation `id` in a grid of `groups` workgroups.
#[inline(always)]
pub fn item(id: UVec3, groups: UVec3) -> u32 {
    id.x + id.y * groups.x * WORKGROUP
}

/// The invocation's subgroup as `Lanes` (the subgroup operations over its active lanes). Built
/// for the host, it is a subgroup of one lane, as the native runtime runs such kernels.
pub struct Subgroup {
    /// The lane's index among the subgroup's active lanes.
    lane: u32,
    /// The subgroup's active lanes.
    size: u32,
}

impl Subgroup {
    /// The active lanes of the invocation's subgroup, numbered by ballot: no assumption that
    /// subgroups are full or that `SubgroupSize` is the lanes that run (Vulkan promises full
    /// subgroups only where a pipeline requires them, which wgpu does not ask). Lane 0 is the
    /// lowest active one, whose value `subgroup_broadcast_first` hands on.
    #[inline(always)]
    pub fn active() -> Self {
        #[cfg(target_arch = "spirv")]
        {
            use spirv_std::arch::{subgroup_ballot, subgroup_ballot_bit_count, subgroup_ballot_exclusive_bit_count};
            let all = subgroup_ballot(true);
            Subgroup { lane: subgroup_ballot_exclusive_bit_count(all), size: subgroup_ballot_bit_count(all) }
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            Subgroup { lane: 0, size: 1 }
        }
    }
}

impl Lanes for Subgroup {
    #[inline(always)]
    fn lane(&self) -> u32 {
        self.lane
    }
    #[inline(always)]
    fn count(&self) -> u32 {
        self.size
    }
    #[inline(always)]
    fn exclusive_add(&self, v: u32) -> u32 {
        #[cfg(target_arch = "spirv")]
        {
            spirv_std::arch::subgroup_exclusive_i_add(v)
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            kdray_shared::kernel::Alone.exclusive_add(v)
        }
    }
    #[inline(always)]
    fn add(&self, v: u32) -> u32 {
        #[cfg(target_arch = "spirv")]
        {
            spirv_std::arch::subgroup_i_add(v)
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            kdray_shared::kernel::Alone.add(v)
        }
    }
    #[inline(always)]
    fn first(&self, v: u32) -> u32 {
        #[cfg(target_arch = "spirv")]
        {
            spirv_std::arch::subgroup_broadcast_first(v)
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            kdray_shared::kernel::Alone.first(v)
        }
    }
}

/// A storage buffer whose elements many invocations add to (`OpAtomicIAdd`, queue-family scope:
/// every invocation of a dispatch; device scope would need an extra Vulkan memory-model
/// capability).
pub struct Atomics<'a>(pub &'a mut [u32]);

/// Plain loads and stores at elements no other item adds to (a list whose count the items
/// take slots from atomically: `photon::gather`'s points).
impl Store<u32> for Atomics<'_> {
    #[inline(always)]
    fn load(&self, i: usize) -> u32 {
        self.0[i]
    }
    #[inline(always)]
    fn store(&mut self, i: usize, v: u32) {
        self.0[i] = v;
    }
    #[inline(always)]
    fn len(&self) -> usize {
        self.0.len()
    }
}

impl AtomicStore for Atomics<'_> {
    #[inline(always)]
    fn atomic_add(&mut self, i: usize, v: u32) -> u32 {
        #[cfg(target_arch = "spirv")]
        {
            use spirv_std::memory::{Scope, Semantics};
            // SAFETY: an in-bounds element of a storage buffer (the index is checked).
            unsafe { spirv_std::arch::atomic_i_add::<u32, { Scope::QueueFamily as u32 }, { Semantics::NONE.bits() }>(&mut self.0[i], v) }
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            self.0.atomic_add(i, v)
        }
    }
    /// One atomic addition per subgroup: the active lanes' values summed, each lane's value
    /// before it the sum of the lanes' below it (an exclusive scan) after the subgroup's base,
    /// which the lowest active lane takes and hands on. The broadcast after the `if` assumes
    /// the elected lane rejoins the others there, as every driver that has run it does (NVIDIA,
    /// lavapipe); Vulkan promises it only with VK_KHR_shader_maximal_reconvergence.
    #[inline(always)]
    fn atomic_add_shared(&mut self, i: usize, v: u32) -> u32 {
        #[cfg(target_arch = "spirv")]
        {
            use spirv_std::arch::{subgroup_broadcast_first, subgroup_elect, subgroup_exclusive_i_add, subgroup_i_add};
            let (before, total) = (subgroup_exclusive_i_add(v), subgroup_i_add(v));
            let mut base = 0;
            if subgroup_elect() {
                base = self.atomic_add(i, total);
            }
            subgroup_broadcast_first(base).wrapping_add(before)
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            self.atomic_add(i, v)
        }
    }
}

