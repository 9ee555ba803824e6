//! The native runtime: a pass runs by calling its kernel's per-item function (the one the SPIR-V
//! entry point calls) for every item, over all cores with rayon. Commands run as they are
//! recorded, so submitting and waiting cost nothing.
use super::{Access, Buffer, Commands, Kernel, Mem, Pending, PendingData, RawBuffer, Runtime};
use anyhow::{bail, Result};
use rayon::prelude::*;
use std::cell::UnsafeCell;

/// The native runtime over rayon's thread pool.
#[derive(Default)]
pub struct Cpu;

impl Cpu {
    pub fn new() -> Cpu {
        Cpu
    }

    fn words(buf: &RawBuffer) -> Result<(*mut u8, usize)> {
        match buf.host_ptr() {
            Some(p) => Ok((p, buf.bytes() as usize)),
            None => bail!("buffer '{}' belongs to a GPU, not to the native runtime", buf.label()),
        }
    }

    /// Checks a pass before it runs natively: every buffer is host memory, and no buffer is
    /// bound twice where one binding writes it (the kernel contract the GPU has too), and the
    /// declaration matches the kernel's SPIR-V entry point.
    fn check(k: &dyn Kernel) -> Result<()> {
        // The declaration must match the SPIR-V entry point, as on a GPU.
        crate::gpu::check_kernel(k)?;
        let b = k.bindings();
        for (i, x) in b.iter().enumerate() {
            Self::words(x.buffer)?;
            for y in &b[i + 1..] {
                if x.buffer.id() == y.buffer.id() && (x.access == Access::Write || y.access == Access::Write) {
                    bail!("{}: buffer '{}' is bound as both '{}' and '{}' and written", k.entry(), x.buffer.label(), x.name, y.name);
                }
            }
        }
        Ok(())
    }

    fn run_threads(k: &dyn Kernel, threads: u32) {
        // Chunks of consecutive items per task, like a GPU's workgroups.
        const CHUNK: u32 = 64;
        (0..threads.div_ceil(CHUNK)).into_par_iter().for_each(|c| k.run_many(c * CHUNK..threads.min((c + 1) * CHUNK)));
    }
}

impl Runtime for Cpu {
    fn name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn is_native(&self) -> bool {
        true
    }

    fn max_binding(&self) -> u64 {
        // The kernels index with u32 elements of at most a few dozen bytes.
        1 << 36
    }

    fn alloc_raw(&self, label: &str, bytes: u64) -> Result<RawBuffer> {
        let words = bytes.div_ceil(4) as usize;
        let mut v: Vec<UnsafeCell<u32>> = Vec::new();
        if v.try_reserve_exact(words).is_err() {
            bail!("out of memory: the {label} buffer needs {:.1} MiB", bytes as f64 / 1048576.0);
        }
        v.resize_with(words, || UnsafeCell::new(0));
        Ok(RawBuffer::new(label, bytes, Mem::Cpu(v.into_boxed_slice())))
    }

    fn write_raw(&self, buf: &RawBuffer, data: &[u8]) -> Result<()> {
        let (p, n) = Self::words(buf)?;
        if data.len() > n {
            bail!("{}: {} bytes written into a buffer of {}", buf.label(), data.len(), n);
        }
        // SAFETY: in bounds; no dispatch runs while the native runtime is called.
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len()) };
        Ok(())
    }

    fn begin(&self) -> Commands {
        Commands { encoder: None, readbacks: Vec::new() }
    }

    fn clear(&self, _c: &mut Commands, buf: &RawBuffer) -> Result<()> {
        let (p, n) = Self::words(buf)?;
        // SAFETY: in bounds; no dispatch runs.
        unsafe { std::ptr::write_bytes(p, 0, n) };
        Ok(())
    }

    fn dispatch(&self, _c: &mut Commands, k: &dyn Kernel) -> Result<()> {
        Self::check(k)?;
        Self::run_threads(k, k.threads());
        Ok(())
    }

    fn dispatch_indirect(&self, _c: &mut Commands, k: &dyn Kernel, args: &Buffer<[u32; 3]>, index: usize) -> Result<()> {
        Self::check(k)?;
        let Some(g) = args.host().get(index).copied() else {
            bail!("{}: indirect arguments {index} of {}", k.entry(), args.len());
        };
        let threads = g[0] as u64 * g[1] as u64 * g[2] as u64 * k.workgroup() as u64;
        if threads > u32::MAX as u64 {
            bail!("{}: indirect dispatch of {threads} threads", k.entry());
        }
        Self::run_threads(k, threads as u32);
        Ok(())
    }

    fn read_back(&self, _c: &mut Commands, buf: &RawBuffer, bytes: u64) -> Result<Pending> {
        let (p, n) = Self::words(buf)?;
        let m = (bytes as usize).min(n) / 4;
        // SAFETY: in bounds, 4-byte aligned words; no dispatch runs.
        let data = unsafe { std::slice::from_raw_parts(p as *const u32, m) }.to_vec();
        Ok(Pending { bytes: 4 * m as u64, data: PendingData::Ready(data) })
    }

    fn submit(&self, _c: Commands) -> Result<()> {
        Ok(())
    }

    fn wait(&self, p: Pending) -> Result<Vec<u32>> {
        match p.data {
            PendingData::Ready(v) => Ok(v),
            PendingData::Gpu(_) => bail!("a GPU read-back waited for on the native runtime"),
        }
    }

    fn finish(&self) -> Result<()> {
        Ok(())
    }
}

/// The native runtime (it has no state: one value serves every caller).
pub static NATIVE: Cpu = Cpu;
