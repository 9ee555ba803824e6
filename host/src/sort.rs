//! Counting sort by cell on either runtime, from the `kdray_shared::sort` kernels: clear the
//! histogram, count, sum chunks of 32 up the levels until at most 32 are left, scan those in one
//! item, turn the prefixes into each level's below them down to the cells' offsets and cursors,
//! scatter (2 L + 3 dispatches for L = max(1, ⌈log32 cells⌉ − 1) levels). The photon index sorts photons by cell with it;
//! the passes are recorded into the caller's commands, so a schedule runs them with its other
//! passes.
use crate::kernels::{ChunkSums, CountKeys, ExclusiveLevel, ExclusiveOffsets, ScanTop, ScatterKeys};
use crate::runtime::{Buffer, Commands, Runtime};
use crate::error::{bail, Result};
use kdray_shared::SortParams;

/// The sort's working buffers for a fixed number of cells.
pub struct CountingSort<'r> {
    rt: &'r dyn Runtime,
    cells: u32,
    counts: Buffer<u32>,
    /// Per level above the cells: its elements' sums and their exclusive prefix sums, one per
    /// element (level 1: the sums of chunks of counts; the last has at most `CHUNK` elements).
    levels: Vec<(Buffer<u32>, Buffer<u32>)>,
    /// `cells + 1` entries: items with a smaller key; the last, all items placed.
    pub offsets: Buffer<u32>,
    cursor: Buffer<u32>,
}

impl<'r> CountingSort<'r> {
    /// Working buffers on `rt` for keys 0..`cells`; `cells` must be 1 to 2^32 − 65.
    pub fn new(rt: &'r dyn Runtime, cells: u32) -> Result<Self> {
        // Chunk ends, (i + 1) · CHUNK, must not overflow.
        if cells == 0 || cells > u32::MAX - 2 * kdray_shared::sort::CHUNK {
            bail!(TooLarge: "a counting sort needs 1 to 2^32 - 65 cells, not {cells}");
        }
        let n = cells as usize;
        let mut levels = Vec::new();
        let mut size = cells;
        loop {
            size = kdray_shared::sort::chunks(size);
            levels.push((rt.alloc("scan level sums", size as usize)?, rt.alloc("scan level prefixes", size as usize)?));
            if size <= kdray_shared::sort::CHUNK {
                break;
            }
        }
        Ok(CountingSort {
            rt,
            cells,
            counts: rt.alloc("cell counts", n)?,
            levels,
            offsets: rt.alloc("cell offsets", n + 1)?,
            cursor: rt.alloc("cell cursors", n)?,
        })
    }

    /// Records sorting the first `n` of `keys` by cell: `order[offsets[c]..offsets[c + 1]]`
    /// are the items of cell `c`. Keys ≥ `cells` are left out.
    pub fn record(&self, c: &mut Commands, keys: &Buffer<u32>, n: u32, order: &Buffer<u32>) -> Result<()> {
        if n as usize > keys.len() || n as usize > order.len() {
            bail!(TooLarge: "a counting sort of {n} items with {} keys and room for {}", keys.len(), order.len());
        }
        let rt = self.rt;
        let p = SortParams { count: n, cells: self.cells, _pad: [0; 2] };
        rt.clear(c, self.counts.raw())?;
        rt.dispatch(c, &CountKeys { params: p, keys, counts: &self.counts })?;
        // Up: each level the sums of chunks of the one below.
        let cells = |b: &Buffer<u32>| SortParams { cells: b.len() as u32, ..p };
        let mut below = &self.counts;
        for (sums, _) in &self.levels {
            rt.dispatch(c, &ChunkSums { params: cells(below), counts: below, sums })?;
            below = sums;
        }
        // The top in one item, then down: each level's prefixes from those of the one above.
        let (top_sums, top_ex) = self.levels.last().expect("at least one level");
        rt.dispatch(c, &ScanTop { params: cells(top_sums), input: top_sums, output: top_ex })?;
        for w in self.levels.windows(2).rev() {
            let ((sums, ex), (_, above)) = (&w[0], &w[1]);
            rt.dispatch(c, &ExclusiveLevel { params: cells(sums), input: sums, above, output: ex })?;
        }
        rt.dispatch(c, &ExclusiveOffsets { params: p, counts: &self.counts, above: &self.levels[0].1, offsets: &self.offsets, cursor: &self.cursor })?;
        rt.dispatch(c, &ScatterKeys { params: p, keys, cursor: &self.cursor, order })
    }
}

/// Sorts `keys` (< `cells`; others are left out) into cell offsets (`cells + 1` entries) and
/// the items of each cell in turn, on `rt`.
pub fn counting_sort(rt: &dyn Runtime, keys: &[u32], cells: u32) -> Result<(Vec<u32>, Vec<u32>)> {
    let s = CountingSort::new(rt, cells)?;
    let kbuf = rt.upload("keys", keys)?;
    let order = rt.alloc::<u32>("order", keys.len())?;
    let mut c = rt.begin();
    s.record(&mut c, &kbuf, keys.len() as u32, &order)?;
    let po = rt.read_back_of(&mut c, &s.offsets, cells as usize + 1)?;
    let pr = rt.read_back_of(&mut c, &order, keys.len())?;
    rt.submit(c)?;
    let offsets: Vec<u32> = crate::runtime::cast(rt.wait(po)?);
    let mut placed: Vec<u32> = crate::runtime::cast(rt.wait(pr)?);
    placed.truncate(offsets[cells as usize] as usize);
    Ok((offsets, placed))
}
