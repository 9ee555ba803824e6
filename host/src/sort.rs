//! Counting sort by cell on either runtime, from the `kdray_shared::sort` kernels: count (each
//! item's rank among its key's), the keys' offsets, scatter. The offsets
//! come exact, in key order (sum chunks of 32 up the levels until at most 32 are left, scan
//! those in one item, turn the prefixes into each level's below them down to the cells'
//! offsets: 2 L + 1 dispatches for L = max(1, ⌈log32 cells⌉ − 1) levels), or by segments of
//! consecutive keys in one dispatch (`sort::segment_offsets`: each block of `sort::SEGMENT_BLOCK`
//! segments' range by one atomic addition, a subgroup's lanes scanning its counts; no scan over
//! every key). A sort needs no clearing: it leaves its buffers ready for the next (the
//! scatter zeroes the counts, each key's first item, `sort::release`; the count pass zeroes
//! the total, `sort::start`). The photon index sorts photons by cell with it (counting in its own key
//! pass and placing the photons themselves); the passes are recorded into the caller's
//! commands, so a schedule runs them with its other passes.
use crate::error::{bail, Result};
use crate::kernels::{ChunkSums, CountRank, ExclusiveLevel, ExclusiveOffsets, ScanTop, ScatterKeys, SegmentOffsets};
use crate::runtime::{Buffer, Commands, Runtime};
use kdray_shared::sort::CHUNK;
use kdray_shared::SortParams;

/// How a sort's offsets are made.
enum Offsets {
    /// Exact prefix sums: per level above the cells, its elements' sums and their exclusive
    /// prefix sums, one per element (level 1: the sums of chunks of counts; the last has at
    /// most `CHUNK` elements).
    Scan(Vec<(Buffer<u32>, Buffer<u32>)>),
    /// By segments of this many keys (the total placed so far after the segments' counts).
    Segments(u32),
}

/// The sort's working buffers for a fixed number of cells and items.
pub struct CountingSort<'r> {
    rt: &'r dyn Runtime,
    cells: u32,
    /// Items per cell; the count pass adds to them (zeroed again by the scatter).
    pub counts: Buffer<u32>,
    /// Per segment the keys it holds items of (added to by each key's first item, `sort::rank`)
    /// and the mark of written offsets, then the total placed so far (`sort::total_slot`); one
    /// unused word for exact offsets.
    pub segments: Buffer<u32>,
    /// Each counted item's rank among its cell's (as many as the sort's items).
    pub ranks: Buffer<u32>,
    how: Offsets,
    /// The cells' offsets: exact, `cells + 1` entries (the last: all items counted); by
    /// segments, `seg + 1` per segment of `seg` cells (key k's at `sort::segment_slot(k, seg)`).
    pub offsets: Buffer<u32>,
}

impl<'r> CountingSort<'r> {
    /// Working buffers on `rt` for up to `items` items with keys 0..`cells`, exact offsets;
    /// `cells` must be 1 to 2^32 − 65.
    pub fn new(rt: &'r dyn Runtime, cells: u32, items: u32) -> Result<Self> {
        // Chunk ends, (i + 1) · CHUNK, must not overflow.
        if cells == 0 || cells > u32::MAX - 2 * CHUNK {
            bail!(TooLarge: "a counting sort needs 1 to 2^32 - 65 cells, not {cells}");
        }
        let mut levels = Vec::new();
        let mut size = cells;
        loop {
            size = kdray_shared::sort::chunks(size);
            levels.push((rt.alloc("scan level sums", size as usize)?, rt.alloc("scan level prefixes", size as usize)?));
            if size <= CHUNK {
                break;
            }
        }
        Ok(CountingSort {
            rt,
            cells,
            counts: rt.alloc("cell counts", cells as usize)?,
            segments: rt.alloc("segment counts", 1)?,
            ranks: rt.alloc("cell ranks", items as usize)?,
            how: Offsets::Scan(levels),
            offsets: rt.alloc("cell offsets", cells as usize + 1)?,
        })
    }

    /// Working buffers on `rt` for up to `items` items with keys 0..`cells`, offsets by segments
    /// of `seg` keys (`cells` a multiple of `seg`; the offsets of all keys fit in 32 bits).
    pub fn segmented(rt: &'r dyn Runtime, cells: u32, seg: u32, items: u32) -> Result<Self> {
        if cells == 0 || seg == 0 || cells % seg != 0 {
            bail!(TooLarge: "a counting sort by segments needs a positive multiple of the {seg} keys of a segment, not {cells}");
        }
        let entries = cells as u64 / seg as u64 * (seg as u64 + 1);
        if entries > u32::MAX as u64 {
            bail!(TooLarge: "a counting sort by segments of {cells} keys: too many offsets");
        }
        Ok(CountingSort {
            rt,
            cells,
            counts: rt.alloc("cell counts", cells as usize)?,
            segments: rt.alloc("segment counts", (cells / seg) as usize + 1)?,
            ranks: rt.alloc("cell ranks", items as usize)?,
            how: Offsets::Segments(seg),
            offsets: rt.alloc("cell offsets", entries as usize)?,
        })
    }

    /// Keys per segment (0: exact offsets).
    pub fn segment(&self) -> u32 {
        match self.how {
            Offsets::Scan(_) => 0,
            Offsets::Segments(seg) => seg,
        }
    }

    /// Records clearing every working buffer: after counting without the scatter (which
    /// would leave the counts for the next sort to add to).
    pub fn record_reset(&self, c: &mut Commands) -> Result<()> {
        for b in [&self.counts, &self.segments, &self.offsets] {
            self.rt.clear(c, b.raw())?;
        }
        Ok(())
    }

    /// Records the offsets from the counts (after counting).
    pub fn record_offsets(&self, c: &mut Commands) -> Result<()> {
        let rt = self.rt;
        let p = SortParams { count: 0, cells: self.cells, segment: 0, _pad: 0 };
        match &self.how {
            Offsets::Segments(seg) => {
                let k = SegmentOffsets { params: SortParams { segment: *seg, ..p }, counts: &self.counts, segments: &self.segments, offsets: &self.offsets };
                rt.dispatch(c, &k)
            }
            Offsets::Scan(levels) => {
                // Up: each level the sums of chunks of the one below.
                let cells = |b: &Buffer<u32>| SortParams { cells: b.len() as u32, ..p };
                let mut below = &self.counts;
                for (sums, _) in levels {
                    rt.dispatch(c, &ChunkSums { params: cells(below), counts: below, sums })?;
                    below = sums;
                }
                // The top in one item, then down: each level's prefixes from those of the one above.
                let (top_sums, top_ex) = levels.last().expect("at least one level");
                rt.dispatch(c, &ScanTop { params: cells(top_sums), input: top_sums, output: top_ex })?;
                for w in levels.windows(2).rev() {
                    let ((sums, ex), (_, above)) = (&w[0], &w[1]);
                    rt.dispatch(c, &ExclusiveLevel { params: cells(sums), input: sums, above, output: ex })?;
                }
                rt.dispatch(c, &ExclusiveOffsets { params: p, counts: &self.counts, above: &levels[0].1, offsets: &self.offsets })
            }
        }
    }

    /// Records sorting the first `n` of `keys` by cell: the item indices into `order`, each
    /// cell's from `offsets[s]` to `offsets[s + 1]` for its slot s (the key itself, or
    /// `sort::segment_slot` of it). Keys ≥ `cells` are left out.
    pub fn record(&self, c: &mut Commands, keys: &Buffer<u32>, n: u32, order: &Buffer<u32>) -> Result<()> {
        if n as usize > keys.len() || n as usize > order.len() || n as usize > self.ranks.len() {
            bail!(TooLarge: "a counting sort of {n} items with {} keys, room for {} and {} ranks", keys.len(), order.len(), self.ranks.len());
        }
        let p = SortParams { count: n, cells: self.cells, segment: self.segment(), _pad: 0 };
        self.rt.dispatch(c, &CountRank { params: p, keys, counts: &self.counts, segments: &self.segments, ranks: &self.ranks })?;
        self.record_offsets(c)?;
        self.rt.dispatch(c, &ScatterKeys { params: p, keys, ranks: &self.ranks, offsets: &self.offsets, counts: &self.counts, order })
    }

    /// Items placed by the last sort (after it ran).
    pub fn placed(&self) -> Result<u32> {
        match &self.how {
            Offsets::Scan(_) => Ok(self.rt.read(&self.offsets, self.cells as usize + 1)?[self.cells as usize]),
            Offsets::Segments(seg) => {
                let slot = kdray_shared::sort::total_slot(&SortParams { count: 0, cells: self.cells, segment: *seg, _pad: 0 });
                Ok(self.rt.read(&self.segments, slot + 1)?[slot])
            }
        }
    }
}

/// Sorts `keys` (< `cells`; others are left out) on `rt`, exact offsets or by segments of
/// `seg` keys (`Some(seg)`): the offsets buffer as the sort leaves it (`CountingSort::offsets`)
/// and the items in key order, `order[offsets[s]..offsets[s + 1]]` those of cell c for its slot
/// s (c, or `sort::segment_slot(c, seg)`).
pub fn counting_sort(rt: &dyn Runtime, keys: &[u32], cells: u32, seg: Option<u32>) -> Result<(Vec<u32>, Vec<u32>)> {
    counting_sorts(rt, &[keys], cells, seg)
}

/// `counting_sort` of each of `key_sets` in turn (all of one length) with the same buffers,
/// the last one's result: a sort must leave its buffers ready for the next (by segments it
/// cleans up behind itself).
pub fn counting_sorts(rt: &dyn Runtime, key_sets: &[&[u32]], cells: u32, seg: Option<u32>) -> Result<(Vec<u32>, Vec<u32>)> {
    let Some(keys) = key_sets.last() else {
        bail!(InvalidInput: "counting_sorts: no keys to sort");
    };
    if key_sets.iter().any(|k| k.len() != keys.len()) {
        bail!(InvalidInput: "counting_sorts: key sets of different lengths");
    }
    let n = keys.len() as u32;
    let s = match seg {
        None => CountingSort::new(rt, cells, n)?,
        Some(seg) => CountingSort::segmented(rt, cells, seg, n)?,
    };
    let order = rt.alloc::<u32>("order", keys.len())?;
    let mut c = rt.begin();
    let kbufs = key_sets.iter().map(|k| rt.upload("keys", k)).collect::<Result<Vec<_>>>()?;
    for kbuf in &kbufs {
        s.record(&mut c, kbuf, n, &order)?;
    }
    let po = rt.read_back_of(&mut c, &s.offsets, s.offsets.len())?;
    let pr = rt.read_back_of(&mut c, &order, keys.len())?;
    rt.submit(c)?;
    let offsets: Vec<u32> = crate::runtime::cast(rt.wait(po)?);
    let mut placed: Vec<u32> = crate::runtime::cast(rt.wait(pr)?);
    placed.truncate(s.placed()? as usize);
    Ok((offsets, placed))
}
