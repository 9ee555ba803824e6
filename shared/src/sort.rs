//! Counting sort of items by a small integer key (a cell), as per-item kernels: the photon
//! index sorts photons by cell with it. Four kinds of pass, each one item per thread:
//!
//! 1. `count_keys`: `counts[key[i]] += 1` (atomic);
//! 2. `chunk_sums`: the sum of every chunk of `CHUNK` consecutive counts;
//! 3. `scan_step`, ⌈log2 chunks⌉ times (Hillis & Steele): an inclusive prefix sum of the chunk
//!    sums, `out[i] = in[i] + in[i − d]` for d = 1, 2, 4, …, ping-ponging between two buffers
//!    (over cells / 32 elements: 5 dispatches fewer and 32× less traffic than over the cells);
//! 4. `exclusive`: `offsets[c]` = items with a smaller key (`offsets[cells]` = all counted) — the
//!    chunks before c's plus the counts before c in its chunk — and a copy of it as the scatter
//!    cursors;
//! 5. `scatter`: item i goes to `order[cursor[key[i]]++]` (atomic).
//!
//! Items with a key ≥ `cells` are left out (not counted, not placed). Within a cell the order
//! of items is whatever order the atomic increments happened in (on a GPU, not deterministic);
//! the offsets are exact.
use crate::kernel::{AtomicStore, Store};
use crate::pod::SortParams;

/// Counts per chunk of the two-level scan.
pub const CHUNK: u32 = 32;

/// Chunks of `cells` counts.
#[inline(always)]
pub fn chunks(cells: u32) -> u32 {
    cells.div_ceil(CHUNK)
}

/// Pass 1: item `i` adds 1 to its key's count (keys ≥ `p.cells` are left out).
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

/// Chunk `i`'s sum of counts (`chunks(p.cells)` items).
#[inline(always)]
pub fn chunk_sums<O: Store<u32> + ?Sized>(i: u32, p: &SortParams, counts: &[u32], sums: &mut O) {
    if i < chunks(p.cells) {
        let end = ((i + 1) * CHUNK).min(p.cells);
        let mut s = 0u32;
        let mut c = i * CHUNK;
        while c < end {
            s = s.wrapping_add(counts[c as usize]);
            c += 1;
        }
        sums.store(i as usize, s);
    }
}

/// Offsets (`cells + 1` entries) and scatter cursors (`cells` entries) from the counts and the
/// inclusive scan of the chunk sums.
#[inline(always)]
pub fn exclusive<O: Store<u32> + ?Sized, C: Store<u32> + ?Sized>(
    i: u32,
    p: &SortParams,
    counts: &[u32],
    chunk_inclusive: &[u32],
    offsets: &mut O,
    cursor: &mut C,
) {
    if i <= p.cells {
        let chunk = i / CHUNK;
        let mut v = if chunk == 0 { 0 } else { chunk_inclusive[(chunk - 1) as usize] };
        let mut c = chunk * CHUNK;
        while c < i {
            v = v.wrapping_add(counts[c as usize]);
            c += 1;
        }
        offsets.store(i as usize, v);
        if i < p.cells {
            cursor.store(i as usize, v);
        }
    }
}

/// Pass 5: item `i` takes the next slot of its key's cursor and writes its index there (keys
/// ≥ `p.cells` are left out).
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
