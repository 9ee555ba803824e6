//! The native runtime: a pass runs by calling its kernel's per-item function (the one the SPIR-V
//! entry point calls) for every item, over all cores with rayon. Commands run as they are
//! recorded, so submitting and waiting cost nothing.
use super::{Access, Buffer, Commands, Kernel, Mem, Pending, PendingData, RawBuffer, Runtime};
use crate::error::{bail, Result};
use rayon::prelude::*;
use std::cell::UnsafeCell;

/// Whether this CPU runs the instructions this build of the native code was compiled for: with
/// the repository's `.cargo/config.toml`, x86-64 builds target FMA (`kdray_shared::math::fma` is
/// then the instruction). `Err` names what is missing and how to rebuild; the command line and
/// the Python module check it first and stop with that line instead of an illegal instruction.
/// Always `Ok` on builds that target no such feature. CPUID is asked itself:
/// `is_x86_feature_detected!` answers `true` without asking in a build that targets the feature.
pub fn check_cpu() -> Result<()> {
    #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
    {
        use std::arch::x86_64::{__cpuid, _xgetbv};
        // SAFETY: every x86-64 CPU has CPUID; XGETBV is run only where CPUID says the OS
        // enabled it (OSXSAVE).
        let runs_fma = unsafe {
            let c = __cpuid(1).ecx;
            let (fma, osxsave, avx) = (c & (1 << 12) != 0, c & (1 << 27) != 0, c & (1 << 28) != 0);
            fma && avx && osxsave && _xgetbv(0) & 6 == 6
        };
        if !runs_fma {
            bail!(InvalidInput: "this kdray was built for x86-64 CPUs with FMA and this one has none; rebuild it with RUSTFLAGS=\"-C target-feature=-fma\"");
        }
    }
    Ok(())
}

/// The native runtime over rayon's thread pool.
pub struct Cpu {
    /// Scene arrays larger than this are split across bindings (`with_split_limit`).
    split_limit: u64,
}

impl Default for Cpu {
    fn default() -> Self {
        Cpu::new()
    }
}

/// The kernels index with u32 elements of at most a few dozen bytes.
const MAX_BINDING: u64 = 1 << 36;

impl Cpu {
    /// The native runtime (`NATIVE` is the same value).
    pub const fn new() -> Cpu {
        Cpu { split_limit: MAX_BINDING }
    }

    /// The native runtime splitting scene arrays larger than `bytes` across bindings
    /// (`Runtime::upload_split`), as a GPU whose bindings hold at most `bytes` would. For tests
    /// of that path.
    pub const fn with_split_limit(bytes: u64) -> Cpu {
        Cpu { split_limit: if bytes < MAX_BINDING { bytes } else { MAX_BINDING } }
    }

    fn words(buf: &RawBuffer) -> Result<(*mut u8, usize)> {
        match buf.host_ptr() {
            Some(p) => Ok((p, buf.bytes() as usize)),
            None => bail!(InvalidInput: "buffer '{}' belongs to a GPU, not to the native runtime", buf.label()),
        }
    }

    /// Checks a pass before it runs natively: every buffer is host memory, and the declaration
    /// matches the kernel's SPIR-V entry point (`module::validate`, which also rejects a buffer
    /// bound twice where one binding writes it).
    fn check(k: &dyn Kernel) -> Result<()> {
        super::module::check_kernel(k)?;
        for b in k.bindings() {
            Self::words(b.buffer)?;
        }
        Ok(())
    }

    /// Runs `f` holding every binding of `k` (shared where read, exclusive where written).
    fn holding<R>(k: &dyn Kernel, f: impl FnOnce() -> Result<R>) -> Result<R> {
        let binds = k.bindings();
        for (i, b) in binds.iter().enumerate() {
            if let Err(e) = b.buffer.acquire(b.access == Access::Write) {
                for a in &binds[..i] {
                    a.buffer.release(a.access == Access::Write);
                }
                return Err(e.context(format!("kernel {}", k.entry())));
            }
        }
        let r = f();
        for b in &binds {
            b.buffer.release(b.access == Access::Write);
        }
        r
    }

    /// Runs `f` holding `buf` (exclusive if `write`).
    fn holding_one<R>(buf: &RawBuffer, write: bool, f: impl FnOnce() -> R) -> Result<R> {
        buf.acquire(write)?;
        let r = f();
        buf.release(write);
        Ok(r)
    }

    fn run_threads(k: &dyn Kernel, threads: u32) {
        // Chunks of consecutive items per task, like a GPU's workgroups.
        const CHUNK: u64 = 64;
        let n = threads as u64;
        (0..n.div_ceil(CHUNK)).into_par_iter().for_each(|c| k.run_many((c * CHUNK) as u32..n.min((c + 1) * CHUNK) as u32));
    }
}

impl Runtime for Cpu {
    fn name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn is_native(&self) -> bool {
        true
    }

    fn is_software(&self) -> bool {
        false
    }

    fn max_binding(&self) -> u64 {
        MAX_BINDING
    }

    fn split_shift(&self, label: &str, len: usize, elem: usize) -> Result<Option<u32>> {
        super::split_at(label, len, elem, self.split_limit, || (self.name(), true))
    }

    fn alloc_raw(&self, label: &str, bytes: u64) -> Result<RawBuffer> {
        let words = bytes.div_ceil(4) as usize;
        let mut v: Vec<UnsafeCell<u32>> = Vec::new();
        if v.try_reserve_exact(words).is_err() {
            bail!(TooLarge: "out of memory: the {label} buffer needs {:.1} MiB", bytes as f64 / 1048576.0);
        }
        v.resize_with(words, || UnsafeCell::new(0));
        Ok(RawBuffer::new(label, bytes, Mem::Cpu(v.into_boxed_slice())))
    }

    fn write_raw(&self, buf: &RawBuffer, data: &[u8]) -> Result<()> {
        let (p, n) = Self::words(buf)?;
        if data.len() > n {
            bail!(InvalidInput: "{}: {} bytes written into a buffer of {}", buf.label(), data.len(), n);
        }
        // SAFETY: in bounds; the exclusive borrow keeps every other access out.
        Self::holding_one(buf, true, || unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len()) })
    }

    fn begin(&self) -> Commands {
        Commands { device: None, encoder: None, readbacks: Vec::new(), profile: None }
    }

    fn clear(&self, _c: &mut Commands, buf: &RawBuffer) -> Result<()> {
        let (p, n) = Self::words(buf)?;
        // SAFETY: in bounds; the exclusive borrow keeps every other access out.
        Self::holding_one(buf, true, || unsafe { std::ptr::write_bytes(p, 0, n) })
    }

    fn dispatch(&self, c: &mut Commands, k: &dyn Kernel) -> Result<()> {
        if c.device.is_some() {
            bail!(InvalidInput: "commands of a GPU recorded on the native runtime");
        }
        Self::check(k)?;
        Self::holding(k, || {
            Self::run_threads(k, k.threads());
            Ok(())
        })
    }

    fn dispatch_indirect(&self, c: &mut Commands, k: &dyn Kernel, args: &Buffer<[u32; 3]>, index: usize) -> Result<()> {
        if c.device.is_some() {
            bail!(InvalidInput: "commands of a GPU recorded on the native runtime");
        }
        Self::check(k)?;
        let (p, n) = Self::words(args.raw())?;
        if (index + 1) * 12 > n {
            bail!(InvalidInput: "{}: indirect arguments {index} of {}", k.entry(), args.len());
        }
        // SAFETY: in bounds, 4-byte aligned words, read under a shared borrow.
        let g = Self::holding_one(args.raw(), false, || unsafe { *(p as *const [u32; 3]).add(index) })?;
        if g[2] != 1 || g[0] > u16::MAX as u32 || g[1] > u16::MAX as u32 {
            bail!(InvalidInput: "{}: indirect workgroup counts {g:?}: z must be 1 and x, y at most 65535", k.entry());
        }
        let threads = g[0] as u64 * g[1] as u64 * k.workgroup() as u64;
        if threads > u32::MAX as u64 {
            bail!(InvalidInput: "{}: indirect dispatch of {threads} threads", k.entry());
        }
        Self::holding(k, || {
            Self::run_threads(k, threads as u32);
            Ok(())
        })
    }

    fn read_back(&self, _c: &mut Commands, buf: &RawBuffer, bytes: u64) -> Result<Pending> {
        let (p, n) = Self::words(buf)?;
        let m = (bytes as usize).min(n) / 4;
        // SAFETY: in bounds, 4-byte aligned words, read under a shared borrow.
        let data = Self::holding_one(buf, false, || unsafe { std::slice::from_raw_parts(p as *const u32, m) }.to_vec())?;
        Ok(Pending { bytes: 4 * m as u64, data: PendingData::Ready(data) })
    }

    fn submit(&self, _c: Commands) -> Result<()> {
        Ok(())
    }

    fn wait(&self, p: Pending) -> Result<Vec<u32>> {
        match p.data {
            PendingData::Ready(v) => Ok(v),
            PendingData::Gpu(_) => bail!(InvalidInput: "a GPU read-back waited for on the native runtime"),
        }
    }

    fn finish(&self) -> Result<()> {
        Ok(())
    }
}

/// The native runtime (it has no state: one value serves every caller).
pub static NATIVE: Cpu = Cpu::new();
