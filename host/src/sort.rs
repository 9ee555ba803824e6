//! Counting sort by cell on either runtime, from the `kdray_shared::sort` kernels: clear the
//! histogram, count, sum chunks of 32 counts, prefix-sum the chunk sums (⌈log2 chunks⌉ scan
//! steps), turn them and the counts into offsets and cursors, scatter. The photon index sorts photons by cell with it; the passes are recorded into the
//! caller's commands, so a schedule runs them with its other passes.
use crate::kernels::{ChunkSums, CountKeys, ExclusiveOffsets, ScanStep, ScatterKeys};
use crate::runtime::{Buffer, Commands, Runtime};
use crate::error::{bail, Result};
use kdray_shared::SortParams;

/// The sort's working buffers for a fixed number of cells.
pub struct CountingSort<'r> {
    rt: &'r dyn Runtime,
    cells: u32,
    counts: Buffer<u32>,
    scan: [Buffer<u32>; 2],
    /// `cells + 1` entries: items with a smaller key; the last, all items placed.
    pub offsets: Buffer<u32>,
    cursor: Buffer<u32>,
}

impl<'r> CountingSort<'r> {
    /// Working buffers on `rt` for keys 0..`cells`; `cells` must be 1 to 2^32 - 2.
    pub fn new(rt: &'r dyn Runtime, cells: u32) -> Result<Self> {
        if cells == 0 || cells == u32::MAX {
            bail!(TooLarge: "a counting sort needs 1 to 2^32 - 2 cells, not {cells}");
        }
        let n = cells as usize;
        let chunks = kdray_shared::sort::chunks(cells) as usize;
        Ok(CountingSort {
            rt,
            cells,
            counts: rt.alloc("cell counts", n)?,
            scan: [rt.alloc("chunk scan", chunks)?, rt.alloc("chunk scan", chunks)?],
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
        let p = SortParams { count: n, cells: self.cells, step: 0, _pad: 0 };
        rt.clear(c, self.counts.raw())?;
        rt.dispatch(c, &CountKeys { params: p, keys, counts: &self.counts })?;
        rt.dispatch(c, &ChunkSums { params: p, counts: &self.counts, sums: &self.scan[0] })?;
        let chunks = kdray_shared::sort::chunks(self.cells);
        let mut src = &self.scan[0];
        let mut step = 1u32;
        let mut k = 1;
        while step < chunks {
            let dst = &self.scan[k % 2];
            rt.dispatch(c, &ScanStep { params: SortParams { cells: chunks, step, ..p }, input: src, output: dst })?;
            src = dst;
            k += 1;
            step = step.saturating_mul(2);
        }
        rt.dispatch(c, &ExclusiveOffsets { params: p, counts: &self.counts, inclusive: src, offsets: &self.offsets, cursor: &self.cursor })?;
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
