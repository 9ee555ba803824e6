//! Counting sorts of items by a small integer key (a cell), as per-item kernels; the photon
//! index sorts photons by cell with them. Every item first takes its place among its key's:
//!
//! 1. `count_rank`: `ranks[i] = counts[key[i]]++` (atomic; keys ≥ `cells` are left out), and
//!    with segments, `segments[key[i] / seg]++` by the first item of each key (rank 0): a
//!    segment counts the keys it holds items of, not its items (item 0 also zeroes the total,
//!    `start`).
//!
//! Then the keys' offsets, one of two ways:
//!
//! * exact, in key order: up the levels, `chunk_sums`, the sum of every chunk of `CHUNK`
//!   consecutive elements of the level below (the counts, then the sums), until a level has at
//!   most `CHUNK` elements (3.5 M cells: 110 592, 3 456, 108, 4); `scan_top`, one item, the
//!   exclusive prefix sum of the top level; down the levels, `exclusive_level`, one item per
//!   element: the element's chunk's prefix plus the elements before it in the chunk; at the
//!   bottom `exclusive` writes `offsets[k]` = items with a smaller key (`offsets[cells]` = all
//!   counted). 2 L + 1 dispatches for L levels (3.5 M cells: 9).
//! * by segments, in one dispatch: keys come in segments of `seg` consecutive keys (a photon
//!   grid's block of cells); `segment_offsets` gives each block of `SEGMENT_BLOCK` segments a
//!   range of slots (its keys' counts summed) by one atomic addition to a total (the word
//!   after the segments' counts, `total_slot`) and writes the keys' offsets within it, segment
//!   by segment in key order (a subgroup's lanes a block together, `Lanes`; it zeroes the
//!   offsets of a segment emptied since an earlier sort; never-written segments stay 0).
//!   Blocks lie in whatever order their additions happened, so a key's offset is at
//!   `segment_slot(key, seg)` (`seg + 1` entries per segment, the last its end) and only keys
//!   of one segment are contiguous — all a query of runs inside segments needs, without a
//!   scan over every key.
//!
//! 2. `scatter`: item i goes to `order[offsets[slot] + ranks[i]]` (no atomics; `slot` the key,
//!    or `segment_slot` of it). A caller can place its own records there instead (the photon
//!    index writes the photons themselves). The item of rank 0 zeroes its key's count
//!    (`release`): every key counted has one, and nothing reads the counts after the offsets,
//!    so a sort leaves its counts zeroed for the next without a pass over all of them.
//!
//! So a sort needs no clearing before it: its buffers start zeroed (as allocated) and every
//! sort leaves them ready for the next (a caller that counts without scattering clears them).
//!
//! Within a key the order of items is whatever order the atomic increments happened in (on a
//! GPU, not deterministic), and so is the order of blocks of segments (within a block, segments
//! in key order); each key's range holds exactly its items.
use crate::kernel::{AtomicStore, Lanes, Store};
use crate::pod::SortParams;

/// Counts per chunk of the two-level scan.
pub const CHUNK: u32 = 32;

/// Chunks of `cells` counts.
#[inline(always)]
pub fn chunks(cells: u32) -> u32 {
    cells.div_ceil(CHUNK)
}

/// The place of an item of key `key` among its key's items (its key's count so far, added to
/// atomically); when keys come by segments (`p.segment` > 0) the first item of a key (rank 0)
/// counts the key in its segment's keys with items, so a segment takes one atomic addition
/// per key held instead of one per item (photons arrive in coherent groups, so a subgroup's
/// additions went mostly to one segment: the photon index's count pass 53.8 → 45.6 µs a pass
/// of 2^20 photons, Cornell box, H100). Keys ≥ `p.cells` are left out (rank 0, nothing
/// counted).
#[inline(always)]
pub fn rank<C: AtomicStore + ?Sized, S: AtomicStore + ?Sized>(key: u32, p: &SortParams, counts: &mut C, segments: &mut S) -> u32 {
    if key >= p.cells {
        return 0;
    }
    let r = counts.atomic_add(key as usize, 1);
    // A segment counts the keys it holds items of (each key's first item), not its items.
    if p.segment > 0 && r == 0 {
        segments.atomic_add((key / p.segment) as usize, 1);
    }
    r
}

/// Where the total of a sort by segments is (the items given slots so far by
/// `segment_offsets`): the word after the segments' counts, `segments[p.cells / p.segment]`.
#[inline(always)]
pub fn total_slot(p: &SortParams) -> usize {
    (p.cells / p.segment) as usize
}

/// The count pass's item `i`: item 0 of a sort by segments zeroes the total for the offsets
/// pass that follows (nothing reads or adds to it during counting).
#[inline(always)]
pub fn start<S: Store<u32> + ?Sized>(i: u32, p: &SortParams, segments: &mut S) {
    if i == 0 && p.segment > 0 {
        segments.store(total_slot(p), 0);
    }
}

/// Item `i` takes its place among the items of its key: `ranks[i]` (`rank`; keys ≥ `p.cells`
/// are left out, their rank 0 and never used); `start`.
#[inline(always)]
pub fn count_rank<C: AtomicStore + ?Sized, S: AtomicStore + Store<u32> + ?Sized, R: Store<u32> + ?Sized>(
    i: u32,
    p: &SortParams,
    keys: &[u32],
    counts: &mut C,
    segments: &mut S,
    ranks: &mut R,
) {
    start(i, p, segments);
    if i < p.count {
        ranks.store(i as usize, rank(keys[i as usize], p, counts, segments));
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
/// from the counts and the chunks' prefixes `above`.
#[inline(always)]
pub fn exclusive<O: Store<u32> + ?Sized>(i: u32, p: &SortParams, counts: &[u32], above: &[u32], offsets: &mut O) {
    if i <= p.cells {
        offsets.store(i as usize, prefix_at(i, p.cells, counts, above));
    }
}

/// Where key `key`'s offset is when keys are sorted by segments of `seg` keys: its segment's
/// `seg + 1` entries, then its place in the segment. The end of keys `key..key + n` of one
/// segment is at `segment_slot(key, seg) + n`.
#[inline(always)]
pub fn segment_slot(key: u32, seg: u32) -> u32 {
    key / seg * (seg + 1) + key % seg
}

/// Where key `key`'s offset is: at the key itself, or at `segment_slot` of it when keys come
/// by segments (`p.segment` > 0).
#[inline(always)]
pub fn offset_slot(key: u32, p: &SortParams) -> u32 {
    if p.segment > 0 {
        segment_slot(key, p.segment)
    } else {
        key
    }
}

/// `segments[s]`'s high bit after `segment_offsets`: the segment's offsets hold a sort's values
/// (the counts that later sorts add go to the low bits).
pub const SEGMENT_WRITTEN: u32 = 1 << 31;

/// Lanes a subgroup of `segment_offsets` has on the GPU (NVIDIA's subgroups of 32; a
/// subgroup of another size still gets every block, by the kernel's loop over blocks): the
/// host dispatches this many threads per block of `SEGMENT_BLOCK` segments.
pub const SEGMENT_LANES: u32 = 32;

/// Consecutive segments that `segment_offsets` places by one atomic addition: a subgroup takes a
/// block of them together.
pub const SEGMENT_BLOCK: u32 = 8;

/// Blocks of `SEGMENT_BLOCK` segments that `segment_offsets` places (the last may hold fewer).
#[inline(always)]
pub fn segment_blocks(p: &SortParams) -> u32 {
    if p.segment == 0 {
        return 0;
    }
    (p.cells / p.segment).div_ceil(SEGMENT_BLOCK)
}

/// The offsets of the blocks of subgroup `group` of `groups` (blocks `group`, `group + groups`,
/// … of `segment_blocks`, each `SEGMENT_BLOCK` consecutive segments of the `p.cells / seg`;
/// `p.cells` keys in segments of `seg = p.segment`, segment s holding items of `segments[s]`
/// keys, `rank`), each by all the subgroup's `lanes` together. A block takes a range of slots
/// (its keys' counts summed: a segment without items has counts of 0) by one atomic addition
/// to the total (`segments[total_slot]`, zeroed by the count pass, `start`), and each of its
/// segments that holds items gets its `seg + 1` offsets (`segment_slot`) from that range in
/// segment order. The lanes read the counts side by side and scan them
/// (`Lanes::exclusive_add`). Natively each item is a subgroup of one lane (`Alone`). The sort
/// cleans up behind itself, so that nothing needs clearing before the next (the buffers are as
/// large as the keys: clearing them took about a quarter of the photon index's time): the
/// segment is marked `SEGMENT_WRITTEN` (its counts are zeroed by the scatter, `release`); a
/// segment without items whose offsets were written by an earlier sort zeroes them (empty
/// ranges) and its mark, and one never written writes nothing.
#[inline(always)]
pub fn segment_offsets<L: Lanes, S: Store<u32> + AtomicStore + ?Sized, O: Store<u32> + ?Sized>(group: u32, groups: u32, lanes: &L, p: &SortParams, counts: &[u32], segments: &mut S, offsets: &mut O) {
    let seg = p.segment;
    if seg == 0 {
        return;
    }
    let (n_seg, blocks, lane, step) = (p.cells / seg, segment_blocks(p), lanes.lane(), lanes.count());
    let mut b = group;
    // At most ⌈blocks / groups⌉ blocks a subgroup (`groups` ≥ 1).
    while b < blocks {
        let s0 = b * SEGMENT_BLOCK;
        let s1 = if n_seg - s0 < SEGMENT_BLOCK { n_seg } else { s0 + SEGMENT_BLOCK };
        // The block's items: every count of its keys, side by side.
        let mut n = 0u32;
        let mut k = s0 * seg + lane;
        while k < s1 * seg {
            n = n.wrapping_add(counts[k as usize]);
            k += step;
        }
        let n = lanes.add(n);
        let mut base = 0;
        if lane == 0 && n > 0 {
            base = segments.atomic_add(total_slot(p), n);
        }
        let mut v = lanes.first(base);
        let mut s = s0;
        while s < s1 {
            // Lane 0's load for all: the lanes may not all have loaded the mark before lane 0
            // stores the new one.
            let tagged = lanes.first(segments.load(s as usize));
            let (first, out) = (s * seg, s * (seg + 1));
            if tagged & !SEGMENT_WRITTEN == 0 {
                if tagged != 0 {
                    let mut k = lane;
                    while k <= seg {
                        offsets.store((out + k) as usize, 0);
                        k += step;
                    }
                    if lane == 0 {
                        segments.store(s as usize, 0);
                    }
                }
            } else {
                // The keys' offsets in key order: chunks of `step` keys, each lane one key.
                let mut k0 = 0;
                while k0 < seg {
                    let k = k0 + lane;
                    let c = if k < seg { counts[(first + k) as usize] } else { 0 };
                    let before = lanes.exclusive_add(c);
                    if k < seg {
                        offsets.store((out + k) as usize, v.wrapping_add(before));
                    }
                    v = v.wrapping_add(lanes.add(c));
                    k0 += step;
                }
                if lane == 0 {
                    offsets.store((out + seg) as usize, v);
                    segments.store(s as usize, SEGMENT_WRITTEN);
                }
            }
            s += 1;
        }
        if groups > blocks - b {
            break;
        }
        b += groups.max(1);
    }
}

/// After the offsets: the item of rank `rank` among key `key`'s zeroes the key's count if it
/// is the first (rank 0), so that the sort leaves every count zeroed for the next (a key that
/// was counted has exactly one such item; nothing reads the counts after the offsets).
#[inline(always)]
pub fn release<C: Store<u32> + ?Sized>(key: u32, rank: u32, counts: &mut C) {
    if rank == 0 {
        counts.store(key as usize, 0);
    }
}

/// Item `i` to its slot: `order[offsets[offset_slot(key)] + ranks[i]] = i` (keys ≥ `p.cells`
/// are left out); the first of a key zeroes its count (`release`).
#[inline(always)]
pub fn scatter<C: Store<u32> + ?Sized, O: Store<u32> + ?Sized>(i: u32, p: &SortParams, keys: &[u32], ranks: &[u32], offsets: &[u32], counts: &mut C, order: &mut O) {
    if i < p.count {
        let k = keys[i as usize];
        if k < p.cells {
            let rank = ranks[i as usize];
            order.store((offsets[offset_slot(k, p) as usize] + rank) as usize, i);
            release(k, rank, counts);
        }
    }
}
