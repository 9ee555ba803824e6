//! What every kernel body is written against, so that one per-item function runs both as a
//! SPIR-V compute entry point (`shader-crate`) and natively (the host's CPU runtime calls it for
//! every item, in parallel).
//!
//! A kernel reads whole buffers through plain slices and writes through `Store`: on the GPU a
//! storage-buffer slice, on the CPU a view that the runtime's threads share. The contract that
//! makes the native twin safe is the GPU's own: within one dispatch, items write disjoint
//! elements (item `i` writes element `i`, or its own range, or elements it alone owns in the
//! dispatch, as a treelet's nodes in `bvh::build::treelet`), reads through `Store` only
//! elements it writes itself or that no item of the dispatch writes, and no buffer is both read
//! as a slice and written.

/// `s[i]` without the bounds check that rust-gpu puts on every slice index (`IndexUnchecked`
/// on the GPU, `get_unchecked` natively).
///
/// # Safety
/// `i < s.len()`: the caller proves it (e.g. for a structure the host validated before upload).
#[inline(always)]
pub unsafe fn at<T>(s: &[T], i: usize) -> &T {
    #[cfg(target_arch = "spirv")]
    {
        use spirv_std::arch::IndexUnchecked;
        // SAFETY: the caller's contract.
        unsafe { s.index_unchecked(i) }
    }
    #[cfg(not(target_arch = "spirv"))]
    {
        // SAFETY: the caller's contract.
        unsafe { s.get_unchecked(i) }
    }
}

/// Element access to a buffer that a kernel writes (and may read back at its own elements).
pub trait Store<T: Copy> {
    /// Element `i`.
    fn load(&self, i: usize) -> T;
    /// Writes `v` to element `i`.
    fn store(&mut self, i: usize, v: T);
    /// Number of elements.
    fn len(&self) -> usize;
    /// Whether there are no elements.
    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl<T: Copy> Store<T> for [T] {
    #[inline(always)]
    fn load(&self, i: usize) -> T {
        self[i]
    }
    #[inline(always)]
    fn store(&mut self, i: usize, v: T) {
        self[i] = v;
    }
    #[inline(always)]
    fn len(&self) -> usize {
        <[T]>::len(self)
    }
}

/// Atomic addition on a buffer's elements, for counters that many items share (a counting
/// sort's histogram and cursors). The shader crate implements it with `OpAtomicIAdd`, the
/// native runtime with `AtomicU32`; a plain `&mut [u32]` (one thread owns it) adds directly.
pub trait AtomicStore {
    /// Adds `v` to element `i` and returns the value before, atomically.
    fn atomic_add(&mut self, i: usize, v: u32) -> u32;
    /// `atomic_add` where every caller adds to the same element `i` (a total that items take
    /// ranges of slots from): each caller's value before its addition, as if the additions
    /// came one at a time in some order. A GPU's store may add a subgroup's values in one
    /// atomic addition (`Atomics` in the shader crate); by default, `atomic_add`.
    #[inline(always)]
    fn atomic_add_shared(&mut self, i: usize, v: u32) -> u32 {
        self.atomic_add(i, v)
    }
}

#[cfg(not(target_arch = "spirv"))]
impl AtomicStore for [u32] {
    #[inline(always)]
    fn atomic_add(&mut self, i: usize, v: u32) -> u32 {
        let old = self[i];
        self[i] = old.wrapping_add(v);
        old
    }
}

/// The lanes of a subgroup that work on one thing together, for a kernel whose items are
/// subgroups rather than threads (`sort::segment_offsets`). Every active lane of the subgroup
/// calls each method at the same point (control flow uniform over the subgroup). On the GPU
/// the shader crate's `Subgroup` (the subgroup operations over the active lanes); natively
/// each item is a subgroup of one lane (`Alone`), so the kernel's loops over lanes become its
/// plain loops. A value that lane 0 alone computes under an `if` and hands on with `first`
/// assumes the lane rejoins the others after the `if`, as `AtomicStore::atomic_add_shared`
/// does on the GPU (every driver that has run them does; Vulkan promises it only with
/// VK_KHR_shader_maximal_reconvergence).
pub trait Lanes {
    /// This lane's index, `0..count()`.
    fn lane(&self) -> u32;
    /// Lanes in the subgroup (at least 1).
    fn count(&self) -> u32;
    /// The sum of `v` over the lanes below this one (wrapping).
    fn exclusive_add(&self, v: u32) -> u32;
    /// The sum of `v` over every lane (wrapping).
    fn add(&self, v: u32) -> u32;
    /// `v` of lane 0 (the lowest active lane).
    fn first(&self, v: u32) -> u32;
}

/// A subgroup of one lane: natively, every item.
pub struct Alone;

impl Lanes for Alone {
    #[inline(always)]
    fn lane(&self) -> u32 {
        0
    }
    #[inline(always)]
    fn count(&self) -> u32 {
        1
    }
    #[inline(always)]
    fn exclusive_add(&self, _: u32) -> u32 {
        0
    }
    #[inline(always)]
    fn add(&self, v: u32) -> u32 {
        v
    }
    #[inline(always)]
    fn first(&self, v: u32) -> u32 {
        v
    }
}

/// Threads per workgroup of every entry point (`#[spirv(compute(threads(64)))]`).
pub const WORKGROUP: u32 = 64;
/// Workgroups per grid dimension that every Vulkan device offers (and wgpu's default limit).
pub const MAX_GROUPS: u32 = 65_535;

/// The workgroup counts (x, y, 1) of an indirect dispatch of `items` items, as the host
/// dispatches directly: up to `MAX_GROUPS` along x, then rows along y (items are numbered
/// x + y · width). `[0, 0, 1]` for none.
#[inline(always)]
pub fn dispatch_args(items: u32) -> [u32; 3] {
    let groups = items.div_ceil(WORKGROUP);
    let x = if groups < MAX_GROUPS { groups } else { MAX_GROUPS };
    let y = if x == 0 { 0 } else { groups.div_ceil(x) };
    [x, y, 1]
}
