//! Counting sort of items by a small integer key (a cell), as per-item kernels: the photon
//! index sorts photons by cell with it. The passes, each one item per thread:
//!
//! 1. `count_keys`: `counts[key[i]] += 1` (atomic);
//! 2. up the levels, `chunk_sums`: the sum of every chunk of `CHUNK` consecutive elements of
//!    the level below (the counts, then the sums), until a level has at most `CHUNK` elements
//!    (3.5 M cells: 110 592, 3 456, 108, 4);
//! 3. `scan_top`: one item, the exclusive prefix sum of the top level (at most `CHUNK` elements);
//! 4. down the levels, `exclusive_level`, one item per element: the element's chunk's prefix
//!    plus the elements before it in the chunk; at the bottom `exclusive` writes `offsets[c]` =
//!    items with a smaller key (`offsets[cells]` = all counted) and a copy as the scatter cursors;
//! 5. `scatter`: item i goes to `order[cursor[key[i]]++]` (atomic).
//!
//! The dispatches grow with log32 of the cells: 2 L + 3 for L levels (3.5 M cells: 11, against
//! 21 with a Hillis–Steele scan of the chunk sums), the histogram's clear aside. Items with a key ≥ `cells` are left out (not counted, not placed). Within a cell the
//! order of items is whatever order the atomic increments happened in (on a GPU, not
//! deterministic); the offsets are exact.
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

/// Chunk `i`'s sum of the `p.cells` elements of `counts` (`chunks(p.cells)` items).
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

/// The top level: one item writes the exclusive prefix sums of the `p.cells` elements of
/// `input` (at most `CHUNK` where the sort calls it) to `out`.
#[inline(always)]
pub fn scan_top<O: Store<u32> + ?Sized>(i: u32, p: &SortParams, input: &[u32], out: &mut O) {
    if i == 0 {
        let mut v = 0u32;
        let mut c = 0;
        while c < p.cells {
            out.store(c as usize, v);
            v = v.wrapping_add(input[c as usize]);
            c += 1;
        }
    }
}

/// The exclusive prefix sum at element `i` of a level of `cells` (≥ 1) elements `input`: its
/// chunk's prefix `above[chunk]` plus the elements of the chunk before it; `i == cells` gives
/// the total. (One item per element: the items of a chunk read the same few words, which a
/// GPU serves to a whole subgroup at once, and write side by side.)
#[inline(always)]
fn prefix_at(i: u32, cells: u32, input: &[u32], above: &[u32]) -> u32 {
    let chunk = if i == cells { (cells - 1) / CHUNK } else { i / CHUNK };
    let mut v = above[chunk as usize];
    let mut c = chunk * CHUNK;
    while c < i {
        v = v.wrapping_add(input[c as usize]);
        c += 1;
    }
    v
}

/// Element `i` of the `p.cells` elements of `input`, down one level: its exclusive prefix sum
/// from the chunks' prefixes `above` (`prefix_at`).
#[inline(always)]
pub fn exclusive_level<O: Store<u32> + ?Sized>(i: u32, p: &SortParams, input: &[u32], above: &[u32], out: &mut O) {
    if i < p.cells {
        out.store(i as usize, prefix_at(i, p.cells, input, above));
    }
}

/// Cell `i`, the bottom level: its offset (`cells + 1` entries: item `cells` writes the total)
/// and scatter cursor (`cells` entries) from the counts and the chunks' prefixes `above`.
#[inline(always)]
pub fn exclusive<O: Store<u32> + ?Sized, C: Store<u32> + ?Sized>(
    i: u32,
    p: &SortParams,
    counts: &[u32],
    above: &[u32],
    offsets: &mut O,
    cursor: &mut C,
) {
    if i <= p.cells {
        let v = prefix_at(i, p.cells, counts, above);
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
