//! Scene arrays larger than one storage binding. A GPU binds at most a few GiB per storage
//! buffer (wgpu: 2 GiB − 1), far less than its memory: a scene whose triangles, kd-tree or BVH
//! exceed that is uploaded in up to `MAX_PARTS` buffers of 2^shift elements each (the last
//! shorter), bound side by side, and element `i` lies in part `i >> shift` at `i & (2^shift − 1)`.
//! Three parts keep every kernel within 16 storage buffers (the whole-path kernels bind a
//! kd-tree's three arrays, in nine bindings, and six more buffers), which every desktop Vulkan driver offers.
//!
//! How an array is split reaches the kernels as a SPIR-V specialization constant (one per
//! splittable binding, `SPLIT_BINDINGS`), whose default 0 means one buffer. The host sets it in
//! the module it builds a pipeline from, so the driver compiles a kernel for a scene that fits
//! with the split path folded away: it costs such scenes nothing. Natively the same code runs
//! with the value given at run time.

/// Most parts an array is split into (each a binding of every kernel that reads the array).
pub const MAX_PARTS: usize = 3;

/// The arrays that may be split, by specialization-constant id (the index), each with the
/// binding names of its parts: the entry points declare `#[spirv(spec_constant(id = N))]` for
/// array N and bind its parts under these names. The host derives every constant from the
/// bindings of a pass.
pub const SPLIT_BINDINGS: [[&str; MAX_PARTS]; 5] = [
    ["tris", "tris1", "tris2"],
    ["nodes", "nodes1", "nodes2"],
    ["prims", "prims1", "prims2"],
    ["bvh", "bvh1", "bvh2"],
    ["bvh_tris", "bvh_tris1", "bvh_tris2"],
];
/// The scene's triangles (`SPLIT_BINDINGS[TRIS]`).
pub const TRIS: usize = 0;
/// The kd-tree's nodes.
pub const KD_NODES: usize = 1;
/// The kd-tree's primitive index list.
pub const KD_PRIMS: usize = 2;
/// The wide BVH's nodes.
pub const BVH_NODES: usize = 3;
/// The wide BVH's triangles in leaf order.
pub const BVH_TRIS: usize = 4;

/// A split code: 0 for one buffer, else `shift | (parts − 1) << 8` (2 ≤ parts ≤ `MAX_PARTS`,
/// 1 ≤ shift ≤ 29).
#[inline(always)]
pub const fn split_code(shift: u32, parts: u32) -> u32 {
    if parts <= 1 {
        0
    } else {
        shift | (parts - 1) << 8
    }
}

/// An array as a kernel reads it: one slice, or up to three parts of 2^shift elements.
#[derive(Copy, Clone)]
pub struct Parts<'a, T> {
    p0: &'a [T],
    p1: &'a [T],
    p2: &'a [T],
    /// `split_code` (0: everything is in `p0`).
    split: u32,
}

impl<'a, T: Copy> Parts<'a, T> {
    /// One slice: the array whole.
    #[inline(always)]
    pub const fn one(s: &'a [T]) -> Self {
        Parts { p0: s, p1: s, p2: s, split: 0 }
    }

    /// The array split as `split` (`split_code`) over `p0`, `p1`, `p2` (parts past the count
    /// are not read; bind anything there). With `split` = 0 it is `p0`.
    #[inline(always)]
    pub const fn new(split: u32, p0: &'a [T], p1: &'a [T], p2: &'a [T]) -> Self {
        Parts { p0, p1, p2, split }
    }

    /// Elements in all parts.
    #[inline(always)]
    pub fn len(&self) -> usize {
        if self.split == 0 {
            self.p0.len()
        } else {
            let shift = self.split & 31;
            let last = self.split >> 8;
            let n = if last == 1 { self.p1.len() } else { self.p2.len() };
            ((last as usize) << shift) + n
        }
    }

    /// Whether there are no elements.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Element `i` (bounds-checked: a panic natively, the GPU's bounds check in a kernel).
    #[inline(always)]
    pub fn get(&self, i: usize) -> T {
        if self.split == 0 {
            self.p0[i]
        } else {
            let shift = self.split & 31;
            let j = i & ((1usize << shift) - 1);
            // Past the last part, the index stays past the end of the last part (checked).
            match i >> shift {
                0 => self.p0[j],
                1 => self.p1[j],
                k => self.p2[j + ((k - 2) << shift)],
            }
        }
    }

    /// Element `i` without the bounds check (`kernel::at`).
    ///
    /// # Safety
    /// `i < self.len()`.
    #[inline(always)]
    pub unsafe fn get_unchecked(&self, i: usize) -> T {
        use crate::kernel::at;
        // SAFETY (all arms): i < len, so its part exists and holds index j (the caller's
        // contract; parts before the last are full).
        if self.split == 0 {
            unsafe { *at(self.p0, i) }
        } else {
            let shift = self.split & 31;
            let j = i & ((1usize << shift) - 1);
            unsafe {
                match i >> shift {
                    0 => *at(self.p0, j),
                    1 => *at(self.p1, j),
                    _ => *at(self.p2, j),
                }
            }
        }
    }

    /// The first part (the whole array when it is not split).
    #[inline(always)]
    pub fn first(&self) -> &'a [T] {
        self.p0
    }

    /// The same parts seen through `f` (e.g. a cast to another element type of the same size:
    /// the split is by element index).
    #[inline(always)]
    pub fn map<U: Copy>(self, f: impl Fn(&'a [T]) -> &'a [U]) -> Parts<'a, U> {
        Parts { p0: f(self.p0), p1: f(self.p1), p2: f(self.p2), split: self.split }
    }

    /// The split code (`split_code`).
    #[inline(always)]
    pub fn split(&self) -> u32 {
        self.split
    }
}

impl<'a, T: Copy> From<&'a [T]> for Parts<'a, T> {
    #[inline(always)]
    fn from(s: &'a [T]) -> Self {
        Parts::one(s)
    }
}
