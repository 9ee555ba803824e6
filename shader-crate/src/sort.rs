//! The counting sort's entry points (`kdray_shared::sort`); the GPU's atomic addition for its
//! shared counters.
use kdray_shared::kernel::AtomicStore;
use kdray_shared::sort;
use kdray_shared::SortParams;
use spirv_std::glam::UVec3;
use spirv_std::spirv;

/// A storage buffer whose elements many invocations add to (`OpAtomicIAdd`, queue-family scope:
/// every invocation of a dispatch; device scope would need an extra Vulkan memory-model
/// capability).
pub struct Atomics<'a>(pub &'a mut [u32]);

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
}

#[spirv(compute(threads(64)))]
pub fn count_keys(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] keys: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] counts: &mut [u32],
) {
    sort::count_keys(crate::item(id, groups), params, keys, &mut Atomics(counts));
}

#[spirv(compute(threads(64)))]
pub fn scan_step(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [u32],
) {
    sort::scan_step(crate::item(id, groups), params, input, output);
}

#[spirv(compute(threads(64)))]
pub fn exclusive_offsets(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] inclusive: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] offsets: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] cursor: &mut [u32],
) {
    sort::exclusive(crate::item(id, groups), params, inclusive, offsets, cursor);
}

#[spirv(compute(threads(64)))]
pub fn scatter_keys(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(push_constant)] params: &SortParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] keys: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] cursor: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] order: &mut [u32],
) {
    sort::scatter(crate::item(id, groups), params, keys, &mut Atomics(cursor), order);
}
