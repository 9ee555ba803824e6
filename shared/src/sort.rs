//! Counting sort of items by a small integer key (a cell), as per-item kernels: the photon
//! index sorts photons by cell with it. Four kinds of pass, each one item per thread:
//!
//! 1. `count_keys`: `counts[key[i]] += 1` (atomic);
//! 2. `scan_step`, ⌈log2 cells⌉ times (Hillis & Steele): an inclusive prefix sum of the counts,
//!    `out[i] = in[i] + in[i − d]` for d = 1, 2, 4, …, ping-ponging between two buffers;
//! 3. `exclusive`: `offsets[c]` = items with a smaller key (offsets[cells] = all counted), and a
//!    copy of it as the scatter cursors;
//! 4. `scatter`: item i goes to `order[cursor[key[i]]++]` (atomic).
//!
//! Items with a key ≥ `cells` are left out (not counted, not placed). Within a cell the order
//! of items is whatever order the atomic increments happened in (on a GPU, not deterministic);
//! the offsets are exact.
use crate::kernel::{AtomicStore, Store};
use crate::pod::SortParams;

#[inline(always)]
pub fn count_keys<C: AtomicStore + ?Sized>(i: u32, p: &SortParams, keys: &[u32], counts: &mut C) {
    if i < p.count {
        let k = keys[i as usize];
        if k < p.cells {
            counts.atomic_add(k as usize, 1);
        }
    }
}

/// One step of the inclusive scan over `p.cells` elements with distance `p.step` (0: copy).
#[inline(always)]
pub fn scan_step<O: Store<u32> + ?Sized>(i: u32, p: &SortParams, input: &[u32], out: &mut O) {
    if i < p.cells {
        let mut v = input[i as usize];
        if p.step > 0 && i >= p.step {
            v = v.wrapping_add(input[(i - p.step) as usize]);
        }
        out.store(i as usize, v);
    }
}

/// Offsets (`cells + 1` entries) and scatter cursors (`cells` entries) from the inclusive scan.
#[inline(always)]
pub fn exclusive<O: Store<u32> + ?Sized, C: Store<u32> + ?Sized>(i: u32, p: &SortParams, inclusive: &[u32], offsets: &mut O, cursor: &mut C) {
    if i <= p.cells {
        let v = if i == 0 { 0 } else { inclusive[(i - 1) as usize] };
        offsets.store(i as usize, v);
        if i < p.cells {
            cursor.store(i as usize, v);
        }
    }
}

#[inline(always)]
pub fn scatter<C: AtomicStore + ?Sized, O: Store<u32> + ?Sized>(i: u32, p: &SortParams, keys: &[u32], cursor: &mut C, order: &mut O) {
    if i < p.count {
        let k = keys[i as usize];
        if k < p.cells {
            let slot = cursor.atomic_add(k as usize, 1);
            order.store(slot as usize, i);
        }
    }
}
