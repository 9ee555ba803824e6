//! The runtimes: where a pass runs. A pass is a `Kernel` value — one per-item function of
//! `kdray-shared` with named, typed buffers and its parameters — and both runtimes run the same
//! value: the wgpu runtime (`crate::gpu::Gpu`) dispatches the kernel's SPIR-V entry point, the
//! native runtime (`cpu::Cpu`) calls the kernel's per-item function for every item over all
//! cores. Integrators (`crate::integrator`) and the tracer (`crate::tracer`) are written once
//! against `dyn Runtime` and hold no wgpu type.
//!
//! Work is recorded into `Commands` and submitted; results come back through `Pending`
//! read-backs that are waited for separately, so a GPU keeps working on the next batch while
//! the host reads the last one. On the CPU every command runs when it is recorded.
pub mod cpu;
pub mod module;
pub mod reflect;

use crate::error::{bail, Result};
use bytemuck::Pod;
use kdray_shared::parts::{split_code, Parts, MAX_PARTS, SPLIT_BINDINGS};
use std::borrow::Cow;
use std::cell::UnsafeCell;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

pub use cpu::Cpu;

/// Where a buffer's memory lives.
pub(crate) enum Mem {
    /// `device`: the id of the `Gpu` that made it (buffers never cross devices).
    Gpu { buffer: wgpu::Buffer, dead: Arc<Mutex<Vec<u64>>>, device: u64 },
    /// Host memory in 4-byte words (every buffer element type is 4-byte aligned). Kernels
    /// running on the native runtime read and write it through raw pointers (see `HostStore`).
    Cpu(Box<[UnsafeCell<u32>]>),
}

/// A buffer of either runtime, untyped: identity (for caches), size and memory.
pub struct RawBuffer {
    id: u64,
    bytes: u64,
    label: String,
    pub(crate) mem: Mem,
    /// Host memory only: who uses it now (0: nobody, n: n readers, `WRITER`: one writer). The
    /// native runtime takes it for every dispatch, write, clear and read-back, so two threads
    /// that work on one buffer at once get an error, never a data race.
    borrow: AtomicU32,
}

const WRITER: u32 = u32::MAX;

// SAFETY: host memory is only read and written by the native runtime under `borrow` (shared for
// reading, exclusive for writing), and by kernels during a dispatch that holds those borrows,
// under the kernel contract (items write disjoint elements; see `Buffer::host_store`).
unsafe impl Sync for RawBuffer {}
unsafe impl Send for RawBuffer {}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

impl RawBuffer {
    pub(crate) fn new(label: &str, bytes: u64, mem: Mem) -> RawBuffer {
        RawBuffer { id: NEXT_ID.fetch_add(1, Ordering::Relaxed), bytes, label: label.to_string(), mem, borrow: AtomicU32::new(0) }
    }

    /// Takes the buffer for reading (shared) or writing (exclusive); fails if it is in use
    /// the other way.
    pub(crate) fn acquire(&self, write: bool) -> Result<()> {
        let ok = if write {
            self.borrow.compare_exchange(0, WRITER, Ordering::Acquire, Ordering::Relaxed).is_ok()
        } else {
            let mut n = self.borrow.load(Ordering::Relaxed);
            loop {
                if n >= WRITER - 1 {
                    break false;
                }
                match self.borrow.compare_exchange_weak(n, n + 1, Ordering::Acquire, Ordering::Relaxed) {
                    Ok(_) => break true,
                    Err(m) => n = m,
                }
            }
        };
        if !ok {
            bail!(InvalidInput: "buffer '{}' is in use by another operation of the native runtime", self.label);
        }
        Ok(())
    }

    pub(crate) fn release(&self, write: bool) {
        if write {
            self.borrow.store(0, Ordering::Release);
        } else {
            self.borrow.fetch_sub(1, Ordering::Release);
        }
    }

    /// The `Gpu` that made this buffer (`None`: host memory).
    pub(crate) fn device(&self) -> Option<u64> {
        match &self.mem {
            Mem::Gpu { device, .. } => Some(*device),
            Mem::Cpu(_) => None,
        }
    }
    /// Unique among the process's buffers (the GPU's bind-group cache keys on it).
    pub fn id(&self) -> u64 {
        self.id
    }
    /// Size in bytes (a GPU rounds the request up to a multiple of 4, at least 4).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
    /// The name given when the buffer was made (wgpu label, error messages).
    pub fn label(&self) -> &str {
        &self.label
    }
    pub(crate) fn gpu(&self) -> Option<&wgpu::Buffer> {
        match &self.mem {
            Mem::Gpu { buffer, .. } => Some(buffer),
            Mem::Cpu(_) => None,
        }
    }
    pub(crate) fn host_ptr(&self) -> Option<*mut u8> {
        match &self.mem {
            Mem::Cpu(words) => Some(words.as_ptr() as *mut u8),
            Mem::Gpu { .. } => None,
        }
    }
}

impl Drop for RawBuffer {
    fn drop(&mut self) {
        // Bind groups that name this buffer are dropped from the GPU's cache.
        if let Mem::Gpu { dead, .. } = &self.mem {
            if let Ok(mut d) = dead.lock() {
                d.push(self.id);
            }
        }
    }
}

/// A typed buffer of `len` elements of `T` on one runtime.
pub struct Buffer<T> {
    raw: RawBuffer,
    len: usize,
    _t: PhantomData<T>,
}

impl<T: Pod> Buffer<T> {
    pub(crate) fn from_raw(raw: RawBuffer, len: usize) -> Self {
        Buffer { raw, len, _t: PhantomData }
    }
    /// Elements asked for (the memory holds at least one: bindings cannot be empty).
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether `len` is 0.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The untyped buffer, for binding, clearing and read-backs.
    pub fn raw(&self) -> &RawBuffer {
        &self.raw
    }
    /// The untyped buffer (to keep for reuse).
    pub fn into_raw(self) -> RawBuffer {
        self.raw
    }

    /// The elements, for a kernel's native twin.
    ///
    /// # Safety
    /// Only inside `Kernel::run` of a dispatch on the native runtime that binds this buffer
    /// for reading (the runtime then holds a shared borrow of it, checked it is host memory,
    /// and nothing writes it until the dispatch ends).
    pub unsafe fn host(&self) -> &[T] {
        let p = self.raw.host_ptr().expect("Cpu::dispatch checks that every binding is host memory");
        // SAFETY: host memory of at least len·size_of::<T>() bytes (checked when made), 4-byte
        // aligned, T is Pod with alignment ≤ 4; not written meanwhile (the caller's contract).
        unsafe { std::slice::from_raw_parts(p as *const T, self.len) }
    }

    /// Element access for a kernel's native twin that writes this buffer.
    ///
    /// # Safety
    /// Only inside `Kernel::run` of a dispatch on the native runtime that binds this buffer for
    /// writing (the runtime then holds the exclusive borrow), and each item may read and write
    /// only elements no other item of the dispatch touches (the GPU's own contract), except
    /// through `AtomicStore::atomic_add`, which every item touching that element must use.
    pub unsafe fn host_store(&self) -> HostStore<'_, T> {
        let p = self.raw.host_ptr().expect("Cpu::dispatch checks that every binding is host memory");
        HostStore { ptr: p as *mut T, len: self.len, _buffer: PhantomData }
    }
}

/// The native form of a buffer a kernel writes: every thread of a dispatch holds one and writes
/// its own elements (the GPU's contract), through a raw pointer; it cannot outlive the buffer.
#[derive(Copy, Clone)]
pub struct HostStore<'a, T> {
    ptr: *mut T,
    len: usize,
    _buffer: PhantomData<&'a Buffer<T>>,
}

impl<T: Copy> kdray_shared::kernel::Store<T> for HostStore<'_, T> {
    #[inline(always)]
    fn load(&self, i: usize) -> T {
        assert!(i < self.len, "kernel read element {i} of {}", self.len);
        // SAFETY: in bounds; elements are only written by the item that owns them.
        unsafe { self.ptr.add(i).read() }
    }
    #[inline(always)]
    fn store(&mut self, i: usize, v: T) {
        assert!(i < self.len, "kernel wrote element {i} of {}", self.len);
        // SAFETY: in bounds; no other item reads or writes element i in this dispatch.
        unsafe { self.ptr.add(i).write(v) }
    }
    #[inline(always)]
    fn len(&self) -> usize {
        self.len
    }
}

impl kdray_shared::kernel::AtomicStore for HostStore<'_, u32> {
    #[inline(always)]
    fn atomic_add(&mut self, i: usize, v: u32) -> u32 {
        assert!(i < self.len, "kernel added to element {i} of {}", self.len);
        // SAFETY: in bounds, 4-byte aligned; every item of the dispatch that touches this
        // element does so atomically (the `AtomicStore` contract).
        unsafe { std::sync::atomic::AtomicU32::from_ptr(self.ptr.add(i)) }.fetch_add(v, Ordering::Relaxed)
    }
}

/// How a kernel uses one of its buffers.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Access {
    /// Only read.
    Read,
    /// Written (and possibly read back at the item's own elements).
    Write,
}

/// One named buffer of a pass. The GPU runtime checks every binding against the entry point's
/// bindings in the SPIR-V module: same name, same element size, read-only where read.
pub struct Bind<'a> {
    /// The binding's name in the kernel's entry point (matched against the module's debug names).
    pub name: &'static str,
    /// The buffer bound.
    pub buffer: &'a RawBuffer,
    /// Whether the kernel reads or writes it.
    pub access: Access,
    /// Bytes per element on the host (`size_of::<T>()`).
    pub elem: u32,
    /// For one part of an array split across bindings (`SplitBuffer`), how it is split
    /// (`kdray_shared::parts::split_code`; the GPU runtime makes it the binding's specialization
    /// constant); 0 for a buffer bound whole.
    pub split: u32,
}

/// A buffer the kernel only reads.
pub fn read<'a, T: Pod>(name: &'static str, b: &'a Buffer<T>) -> Bind<'a> {
    Bind { name, buffer: b.raw(), access: Access::Read, elem: std::mem::size_of::<T>() as u32, split: 0 }
}

/// A buffer the kernel writes.
pub fn write<'a, T: Pod>(name: &'static str, b: &'a Buffer<T>) -> Bind<'a> {
    Bind { name, buffer: b.raw(), access: Access::Write, elem: std::mem::size_of::<T>() as u32, split: 0 }
}

/// Array `array` of `kdray_shared::parts::SPLIT_BINDINGS` (`parts::TRIS`, …), which the kernel
/// reads in parts (`SplitBuffer`): bound under its parts' names (the one buffer thrice when it
/// is whole).
pub fn read_split<T: Pod>(array: usize, b: &SplitBuffer<T>) -> [Bind<'_>; MAX_PARTS] {
    let part = |i: usize| Bind {
        name: SPLIT_BINDINGS[array][i],
        buffer: b.parts[i.min(b.parts.len() - 1)].raw(),
        access: Access::Read,
        elem: std::mem::size_of::<T>() as u32,
        split: b.split(),
    };
    [part(0), part(1), part(2)]
}

/// A read-only array of the scene (triangles, a structure's nodes and indices) as one buffer,
/// or, when larger than the runtime's `max_binding`, as up to `MAX_PARTS` buffers of 2^shift
/// elements each, which kernels bind side by side (`kdray_shared::parts`).
pub struct SplitBuffer<T> {
    parts: Vec<Buffer<T>>,
    shift: u32,
    len: usize,
}

impl<T: Pod> SplitBuffer<T> {
    /// Elements in all parts.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The buffers (one, unless the array is larger than one binding).
    pub fn parts(&self) -> &[Buffer<T>] {
        &self.parts
    }
    /// The buffer holding the whole array, if it is not split.
    pub fn whole(&self) -> Option<&Buffer<T>> {
        match self.parts.as_slice() {
            [b] => Some(b),
            _ => None,
        }
    }
    /// How it is split (`kdray_shared::parts::split_code`: 0 when whole).
    pub fn split(&self) -> u32 {
        split_code(self.shift, self.parts.len() as u32)
    }
    /// The first `len` elements of `buf` as an array bound whole (the buffer may hold more: a
    /// tree built into buffers kept for larger trees, `Tracer::build_bvh`).
    pub fn whole_of(buf: Buffer<T>, len: usize) -> Result<Self> {
        if len > buf.len() {
            bail!(InvalidInput: "{}: {len} elements of a buffer of {}", buf.raw().label(), buf.len());
        }
        Ok(SplitBuffer { parts: vec![buf], shift: 0, len })
    }
    /// The one buffer of an array bound whole (`None`, the parts dropped, if it is split).
    pub fn into_whole(self) -> Option<Buffer<T>> {
        let mut parts = self.parts;
        (parts.len() == 1).then(|| parts.remove(0))
    }
    /// The parts as a kernel's native twin reads them.
    ///
    /// # Safety
    /// As `Buffer::host`, for every part.
    pub unsafe fn host(&self) -> Parts<'_, T> {
        let p = |i: usize| unsafe { self.parts[i.min(self.parts.len() - 1)].host() };
        Parts::new(self.split(), p(0), p(1), p(2))
    }
}

/// One pass: a kernel with its buffers and parameters, runnable on either runtime. Declared once
/// per kernel family (`crate::kernels`); the SPIR-V entry point and the native twin call the same
/// `kdray-shared` function.
pub trait Kernel: Sync {
    /// The SPIR-V entry point.
    fn entry(&self) -> Cow<'static, str>;
    /// The family's parameter struct as bytes (push constants, or the `params` buffer where the
    /// entry point takes one).
    fn params(&self) -> &[u8];
    /// The buffers, by name.
    fn bindings(&self) -> Vec<Bind<'_>>;
    /// Threads (work items) of a direct dispatch.
    fn threads(&self) -> u32;
    /// Threads per workgroup of the entry point (checked against the module).
    fn workgroup(&self) -> u32 {
        64
    }
    /// The native twin: runs thread `t` (reading and writing host memory through
    /// `Buffer::host` / `Buffer::host_store`, whose contracts the implementation keeps).
    fn run(&self, t: u32);
    /// Runs threads `ts` (one dynamic call per chunk of threads on the native runtime).
    fn run_many(&self, ts: std::ops::Range<u32>) {
        for t in ts {
            self.run(t);
        }
    }
    /// A pass that draws instead of dispatching (the rasterised primary hits): on a GPU,
    /// `entry()` is the vertex shader, run for `Draw::vertices` vertices, and the fragment
    /// shader's one `u32` output, kept where the depth test passes, lands in the binding
    /// `Draw::target`. Natively the pass runs its threads like any other (`run`).
    fn draw(&self) -> Option<Draw> {
        None
    }
}

/// What a drawing pass draws (`Kernel::draw`): a triangle list of `vertices` vertices through
/// the vertex shader `Kernel::entry` and the fragment shader `fragment`, with a depth test
/// (reversed depth: nearer is larger, cleared to 0), into a `width` × `height` image of `u32`
/// cleared to 0, which is then copied into the pass's binding named `target` in rows of
/// `row_words` words (a multiple of 64, at least `width`).
#[derive(Copy, Clone, Debug)]
pub struct Draw {
    /// Vertices drawn (three per triangle).
    pub vertices: u32,
    /// The fragment shader's entry point.
    pub fragment: &'static str,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Words per row of the target.
    pub row_words: u32,
    /// The binding that receives the image (written by the copy, not by the shaders).
    pub target: &'static str,
}

/// Recorded work of one submission.
pub struct Commands {
    /// The `Gpu` these were recorded for (`None`: the native runtime).
    pub(crate) device: Option<u64>,
    pub(crate) encoder: Option<wgpu::CommandEncoder>,
    pub(crate) readbacks: Vec<Arc<crate::gpu::Readback>>,
    /// Timestamps of the passes under `gpu::PROFILE_ENV`.
    pub(crate) profile: Option<crate::gpu::ProfileRecording>,
}

/// A read-back that was recorded; `Runtime::wait` returns its bytes once the work before it is
/// done.
pub struct Pending {
    pub(crate) bytes: u64,
    pub(crate) data: PendingData,
}

pub(crate) enum PendingData {
    Ready(Vec<u32>),
    Gpu(Arc<crate::gpu::Readback>),
}

/// A device that runs passes: the wgpu runtime or the native one.
pub trait Runtime: Sync {
    /// Which device, for reports.
    fn name(&self) -> String;
    /// Whether this is the native runtime.
    fn is_native(&self) -> bool;
    /// Whether this is a software Vulkan driver (lavapipe, SwiftShader) rather than a GPU.
    /// Lavapipe's code generator ends an invocation silently after about 65 535 loop
    /// iterations in all (gallivm's loop limiter), so long-running items are avoided there.
    fn is_software(&self) -> bool;
    /// Largest buffer a kernel can bind, in bytes.
    fn max_binding(&self) -> u64;
    /// How a read-only scene array of `len` elements of `elem` bytes is split across bindings
    /// (`Runtime::upload_split`): `None` for one buffer, else `Some(shift)`, parts of 2^shift
    /// elements (at most `MAX_PARTS` of them). The default: one buffer when it fits in
    /// `max_binding`, else parts of the largest power of two of elements that fits (and at
    /// most 2^29, which keeps every index within 31 bits); more than `MAX_PARTS` parts is an
    /// error naming `label`, the size and the limit.
    fn split_shift(&self, label: &str, len: usize, elem: usize) -> Result<Option<u32>> {
        split_at(label, len, elem, self.max_binding(), || (self.name(), self.is_native()))
    }
    /// A zero-filled buffer of `bytes` bytes (never empty: at least 4).
    fn alloc_raw(&self, label: &str, bytes: u64) -> Result<RawBuffer>;
    /// Copies `data` into `buf` at byte 0. On a GPU the copy lands before every command of
    /// the next submission (also ones recorded before the call); natively at once: write
    /// between submissions, not between recording and submitting.
    fn write_raw(&self, buf: &RawBuffer, data: &[u8]) -> Result<()>;
    /// Starts recording commands for this runtime.
    fn begin(&self) -> Commands;
    /// Records zero-filling `buf`.
    fn clear(&self, c: &mut Commands, buf: &RawBuffer) -> Result<()>;
    /// Records one pass over `k.threads()` threads.
    fn dispatch(&self, c: &mut Commands, k: &dyn Kernel) -> Result<()>;
    /// Records one pass whose workgroup counts (x, y, z) are read from `args` at `index` when it
    /// runs (written by an earlier pass: e.g. a count of survivors). Kernels number their items
    /// over x and y: z must be 1, and x and y within the device's workgroup limit.
    fn dispatch_indirect(&self, c: &mut Commands, k: &dyn Kernel, args: &Buffer<[u32; 3]>, index: usize) -> Result<()>;
    /// Records copying the first `bytes` bytes of `buf` back to the host.
    fn read_back(&self, c: &mut Commands, buf: &RawBuffer, bytes: u64) -> Result<Pending>;
    /// Submits the recorded work (on the GPU it runs while the host goes on).
    fn submit(&self, c: Commands) -> Result<()>;
    /// Waits for a read-back and returns its contents as 4-byte words (`cast` types them).
    fn wait(&self, p: Pending) -> Result<Vec<u32>>;
    /// Waits until everything submitted, and every write (`write`, `write_raw`), has run.
    fn finish(&self) -> Result<()>;
}

impl dyn Runtime + '_ {
    /// A zero-filled buffer of `n` elements (at least one: bindings cannot be empty). Fails with
    /// a clear message when it exceeds the device's binding limit.
    pub fn alloc<T: Pod>(&self, label: &str, n: usize) -> Result<Buffer<T>> {
        if std::mem::align_of::<T>() > 4 {
            bail!(InvalidInput: "{label}: element type aligned to more than 4 bytes");
        }
        let Some(bytes) = n.max(1).checked_mul(std::mem::size_of::<T>()) else {
            bail!(TooLarge: "{label}: {n} elements do not fit in memory");
        };
        let bytes = bytes.max(4) as u64;
        self.check_size(label, bytes)?;
        Ok(Buffer::from_raw(self.alloc_raw(label, bytes)?, n))
    }

    /// A buffer holding `data` (one zeroed element if empty).
    pub fn upload<T: Pod>(&self, label: &str, data: &[T]) -> Result<Buffer<T>> {
        let b = self.alloc::<T>(label, data.len())?;
        if !data.is_empty() {
            self.write_raw(b.raw(), bytemuck::cast_slice(data))?;
        }
        Ok(b)
    }

    /// A read-only scene array holding `data`, in one buffer or in parts as `split_shift`
    /// says (the kernels that read it bind every part: `read_split`).
    pub fn upload_split<T: Pod>(&self, label: &str, data: &[T]) -> Result<SplitBuffer<T>> {
        let Some(shift) = self.split_shift(label, data.len(), std::mem::size_of::<T>())? else {
            return Ok(SplitBuffer { parts: vec![self.upload(label, data)?], shift: 0, len: data.len() });
        };
        let n = data.len().div_ceil(1 << shift);
        if !(1..=29).contains(&shift) || !(2..=MAX_PARTS).contains(&n) {
            bail!(InvalidInput: "{label}: {} elements cannot be split into parts of 2^{shift} (2 to {MAX_PARTS} parts of 2 to 2^29 elements)", data.len());
        }
        let parts = data
            .chunks(1 << shift)
            .enumerate()
            .map(|(i, c)| self.upload(&format!("{label} (part {} of {n})", i + 1), c))
            .collect::<Result<Vec<_>>>()?;
        Ok(SplitBuffer { parts, shift, len: data.len() })
    }

    /// Copies `data` into the start of `buf`.
    pub fn write<T: Pod>(&self, buf: &Buffer<T>, data: &[T]) -> Result<()> {
        if data.len() > buf.len().max(1) {
            bail!(InvalidInput: "{}: {} elements written into a buffer of {}", buf.raw().label(), data.len(), buf.len());
        }
        self.write_raw(buf.raw(), bytemuck::cast_slice(data))
    }

    /// Copies `data` over a split array of as many elements, part by part.
    pub fn write_split<T: Pod>(&self, buf: &SplitBuffer<T>, data: &[T]) -> Result<()> {
        if data.len() != buf.len() {
            bail!(InvalidInput: "{} elements written over an array of {}", data.len(), buf.len());
        }
        match buf.parts.as_slice() {
            [one] => self.write(one, data),
            parts => parts.iter().zip(data.chunks(1 << buf.shift)).try_for_each(|(p, c)| self.write(p, c)),
        }
    }

    /// Records the passes `ks` in order; returns how many.
    pub fn dispatch_all<'k>(&self, c: &mut Commands, ks: Vec<Box<dyn Kernel + 'k>>) -> Result<usize> {
        for k in &ks {
            self.dispatch(c, k.as_ref())?;
        }
        Ok(ks.len())
    }

    /// Records reading the first `n` elements of `buf` back.
    pub fn read_back_of<T: Pod>(&self, c: &mut Commands, buf: &Buffer<T>, n: usize) -> Result<Pending> {
        self.read_back(c, buf.raw(), (n.min(buf.len()) * std::mem::size_of::<T>()) as u64)
    }

    /// The first `n` elements of `buf`, now (submits and waits).
    pub fn read<T: Pod>(&self, buf: &Buffer<T>, n: usize) -> Result<Vec<T>> {
        let mut c = self.begin();
        let p = self.read_back_of(&mut c, buf, n)?;
        self.submit(c)?;
        Ok(cast(self.wait(p)?))
    }

    /// Runs passes in order, now, and waits for them.
    pub fn run(&self, passes: &[&dyn Kernel]) -> Result<()> {
        let mut c = self.begin();
        for k in passes {
            self.dispatch(&mut c, *k)?;
        }
        self.submit(c)?;
        self.finish()
    }

    /// Fails (`TooLarge`, naming `label` and the device) when a buffer of `bytes` bytes exceeds
    /// `max_binding`.
    pub fn check_size(&self, label: &str, bytes: u64) -> Result<()> {
        let max = self.max_binding();
        if bytes > max {
            let what = if self.is_native() { "machine" } else { "GPU" };
            bail!(TooLarge:
                "scene too large for this {what}: the {label} buffer needs {:.1} MiB but {} allows at most {:.1} MiB per storage buffer",
                bytes as f64 / 1048576.0,
                self.name(),
                max as f64 / 1048576.0
            );
        }
        Ok(())
    }
}

/// The default split (`Runtime::split_shift`) of an array of `len` elements of `elem` bytes
/// for bindings of at most `max` bytes; `device` names the runtime and says whether it is the
/// native one, for the error.
pub fn split_at(label: &str, len: usize, elem: usize, max: u64, device: impl Fn() -> (String, bool)) -> Result<Option<u32>> {
    let size = elem.max(1) as u64;
    let bytes = (len as u64).max(1) * size;
    if bytes <= max {
        return Ok(None);
    }
    let per = (max / size).max(1);
    let shift = (63 - per.leading_zeros()).min(29);
    if len.div_ceil(1 << shift) > MAX_PARTS {
        let (name, native) = device();
        bail!(TooLarge:
            "scene too large for this {}: the {label} buffer needs {}, more than {MAX_PARTS} storage buffers of {} ({name} allows at most {} per storage buffer)",
            if native { "machine" } else { "GPU" },
            human_bytes(bytes),
            human_bytes((1u64 << shift) * size),
            human_bytes(max)
        );
    }
    Ok(Some(shift))
}

/// `bytes` in GiB, MiB or KiB (one decimal), or in bytes below 1 KiB.
pub fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1024 => format!("{bytes} bytes"),
        1024..1048576 => format!("{:.1} KiB", b / 1024.0),
        1048576..1073741824 => format!("{:.1} MiB", b / 1048576.0),
        _ => format!("{:.1} GiB", b / 1073741824.0),
    }
}

/// Typed elements of a read-back (without a copy where the words fit `T` exactly).
pub fn cast<T: Pod>(words: Vec<u32>) -> Vec<T> {
    let n = words.len() * 4 / std::mem::size_of::<T>().max(1);
    let mut words = words;
    words.truncate(n * std::mem::size_of::<T>() / 4);
    words.shrink_to_fit();
    match bytemuck::allocation::try_cast_vec::<u32, T>(words) {
        Ok(v) => v,
        Err((_, words)) => bytemuck::pod_collect_to_vec(&words),
    }
}
