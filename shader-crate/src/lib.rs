//! GPU entry points. Each is a thin wrapper: it declares its bindings, finds its work item and
//! calls the per-item function in `kdray-shared` (`trace`, `render`), which the host's native
//! runtime calls too. Parameters are push constants (render) or a small read-only storage
//! buffer named `params` (trace; measured faster there). The host reads every entry point's
//! name, workgroup size and bindings (number, name, element size, read-only or not) from the
//! SPIR-V module itself and checks its typed passes against them, so nothing here is listed
//! again on the host.
//!
//! Work items are numbered over a 2D grid of workgroups so a dispatch can exceed the 65 535-
//! workgroup limit of one dimension: `item = x + y · (groups_x · WORKGROUP)`.
//!
//! Kernel families are cargo features (`trace`, `render`, `sort`; all on by default), so a user can
//! build a module with only what they need. The crate also builds for the host (as a normal
//! library), where the entry points are plain functions that unit tests call.
#![cfg_attr(target_arch = "spirv", no_std)]

#[cfg(feature = "trace")]
mod trace;
#[cfg(feature = "render")]
mod render;
#[cfg(feature = "sort")]
mod sort;

#[cfg(feature = "trace")]
pub use trace::*;
#[cfg(feature = "render")]
pub use render::*;
#[cfg(feature = "sort")]
pub use sort::*;

use spirv_std::glam::UVec3;

/// Threads per workgroup (`#[spirv(compute(threads(64)))]` on every entry point).
pub const WORKGROUP: u32 = 64;

/// The work item of invocation `id` in a grid of `groups` workgroups.
#[inline(always)]
pub fn item(id: UVec3, groups: UVec3) -> u32 {
    id.x + id.y * groups.x * WORKGROUP
}
