//! The wgpu runtime: adapter choice, device limits, SPIR-V pipelines, buffers, bounded
//! dispatches. Kernels are loaded as passthrough SPIR-V (no WGSL, no naga translation); what
//! each entry point declares — workgroup size, bindings by name with element size and
//! read-only flag, push-constant size — is read from the module itself (`reflect`), and every
//! pass is checked against it before it is recorded: a mismatch between a host kernel
//! declaration and the shader is an error naming the kernel and the binding, never a wrong
//! binding. Pipelines and bind groups are cached; read-backs go through reused staging buffers
//! and are waited for apart from submission.
use crate::runtime::module::{find_entry, module_info, short_name, specialize, spirv_words, splits, validate, Slot, Splits};
use crate::runtime::{reflect, Bind, Buffer, Commands, Draw, Kernel, Mem, Pending, PendingData, RawBuffer, Runtime};
use crate::error::{bail, err, Result};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

static NEXT_GPU: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// Longest a single submission may run before we report it as hung. Work is split so that a
/// submission is far below this on any real device.
const SUBMIT_TIMEOUT: Duration = Duration::from_secs(600);

/// Work of a measurement run before it is timed (caches).
const WARM_UP: Duration = Duration::from_millis(100);

/// An idle GPU longer than this is warmed up for a second before the next measurement.
const IDLE: Duration = Duration::from_millis(250);

/// The kernels' module on `device`: `spirv` is the module's words (`spirv_words`), or those with
/// other defaults for its specialization constants (`specialize`).
fn shader_module(device: &wgpu::Device, spirv: Vec<u32>, label: &str) -> Result<wgpu::ShaderModule> {
    let entry_points: Vec<wgpu::PassthroughShaderEntryPoint> = module_info()?
        .entry_points
        .iter()
        .map(|e| wgpu::PassthroughShaderEntryPoint { name: e.name.clone().into(), workgroup_size: (e.workgroup_size[0], e.workgroup_size[1], e.workgroup_size[2]) })
        .collect();
    // SAFETY: the module is the rust-gpu output of shader-crate (built in, or the file
    // `KDRAY_SPIRV` names for kernel development), validated by spirv-val at build time, with
    // at most the default values of its specialization constants changed (the split codes the
    // kernels are written for); its entry points are the ones it declares (reflected), and
    // every pipeline layout is made from the bindings it declares.
    Ok(unsafe {
        device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
            label: Some(label),
            entry_points: entry_points.into(),
            spirv: Some(spirv.into()),
            ..Default::default()
        })
    })
}

/// Environment variable: every GPU splits scene arrays larger than this many bytes across
/// bindings (`Gpu::split_arrays_above`), as a device with that binding limit would. For
/// measuring the split path (`kdray bench …` with it set).
pub const MAX_BINDING_OVERRIDE: &str = "KDRAY_MAX_BINDING";

/// Environment variable: set (to anything but `0`), every pass recorded through
/// `Runtime::dispatch` carries GPU timestamps, and when the `Gpu` is dropped a table of GPU
/// time per entry point (dispatches, total and mean) goes to stderr. For finding where a
/// schedule's time goes; the timestamps themselves cost a little per pass.
pub const PROFILE_ENV: &str = "KDRAY_PROFILE";

/// Passes timed per submission under `PROFILE_ENV` (wgpu's query sets hold 4 096 queries).
const PROFILE_PASSES: u32 = 2048;

/// The timestamps of one submission under `PROFILE_ENV`: a query set and the entry point of
/// each timed pass.
pub(crate) struct ProfileRecording {
    set: wgpu::QuerySet,
    names: Vec<String>,
}

/// GPU time per entry point under `PROFILE_ENV`: submissions not yet read, and the totals.
#[derive(Default)]
struct Profile {
    pending: Vec<(wgpu::Buffer, Vec<String>)>,
    totals: HashMap<String, (u64, f64)>,
    /// Profiled submissions read, the ms from each one's first timed pass's start to its last
    /// one's end (summed), and the ms from one's end to the next one's start (summed).
    submissions: (u64, f64, f64),
    /// The end of the last submission read (ticks).
    last_end: Option<u64>,
}

/// Largest push-constant block a kernel family may use (Vulkan guarantees 128 bytes).
const MAX_PARAMS: u32 = 128;

struct Pipeline {
    pipeline: Pipe,
    layout: wgpu::BindGroupLayout,
    info: reflect::EntryPoint,
}

/// A compute pipeline, or the render pipeline of a drawing pass (`Kernel::draw`).
enum Pipe {
    Compute(wgpu::ComputePipeline),
    Render(wgpu::RenderPipeline),
}

/// The image format of a drawing pass's target (one `u32` per pixel) and of its depth buffer.
const DRAW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A drawing pass's render targets of one size: the `u32` image and its depth buffer.
struct DrawTargets {
    image: wgpu::Texture,
    image_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

/// A recorded copy into a staging buffer and the submission that carries it.
pub(crate) struct Readback {
    device: u64,
    staging: wgpu::Buffer,
    bytes: u64,
    submission: Mutex<Option<wgpu::SubmissionIndex>>,
}

/// The wgpu runtime on one Vulkan adapter: its device and queue, the SPIR-V module, and the
/// caches of pipelines, bind groups, staging and parameter buffers.
pub struct Gpu {
    /// The device opened on the adapter.
    pub device: wgpu::Device,
    /// The device's queue: every submission and buffer write goes through it.
    pub queue: wgpu::Queue,
    /// The adapter's name, backend, device type and driver.
    pub info: wgpu::AdapterInfo,
    /// The limits the device was opened with: the adapter's own for storage buffers and
    /// workgroup counts, `MAX_PARAMS` bytes of push constants.
    pub limits: wgpu::Limits,
    /// Position of the adapter in `adapters()`.
    pub index: usize,
    /// Unique among the `Gpu`s of the process: buffers and commands carry it.
    id: u64,
    /// Whether passes can carry timestamp queries (GPU-side kernel times).
    pub timestamps: bool,
    module: wgpu::ShaderModule,
    /// The module specialized for scenes whose arrays are split across bindings, by split
    /// (made on first use; `module` is the one for whole arrays).
    split_modules: Mutex<HashMap<Splits, wgpu::ShaderModule>>,
    /// Created on first use: drivers compile each entry point when its pipeline is made; by
    /// entry point and the splits it is specialized for.
    pipelines: Mutex<HashMap<(String, Splits), Arc<Pipeline>>>,
    /// Render targets of drawing passes by (width in words, height), made on first use.
    draw_targets: Mutex<HashMap<(u32, u32), Arc<DrawTargets>>>,
    /// Bind groups by entry point, splits and buffer ids (dropped with their buffers).
    bind_groups: Mutex<HashMap<(String, Vec<u64>), wgpu::BindGroup>>,
    /// A limit below `max_binding` for splitting scene arrays (`split_arrays_above`), 0 if none.
    binding_cap: std::sync::atomic::AtomicU64,
    /// Ids of dropped buffers not yet purged from `bind_groups`.
    dead: Arc<Mutex<Vec<u64>>>,
    /// Staging buffers for read-backs, reused.
    staging: Mutex<Vec<wgpu::Buffer>>,
    /// Parameter buffers of kernels that take their parameters from a buffer, by value.
    params: Mutex<HashMap<Vec<u8>, RawBuffer>>,
    /// When a timed measurement last finished (to tell how long the GPU has idled).
    last_timed: Mutex<Option<std::time::Instant>>,
    /// What the device reported outside calls that return errors.
    faults: Arc<Faults>,
    /// GPU time per entry point, under `PROFILE_ENV` on an adapter with timestamps.
    profile: Option<Mutex<Profile>>,
}

/// A lost device's reason, and the first error raised outside an error scope.
#[derive(Default)]
struct Faults {
    lost: Mutex<Option<String>>,
    error: Mutex<Option<String>>,
}

fn device_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

/// Adapters wgpu can see through Vulkan, best first.
pub fn adapters() -> Vec<wgpu::Adapter> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let mut list = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
    list.sort_by_key(|a| device_rank(a.get_info().device_type));
    list
}

/// One line naming an adapter: name, backend, device type, driver.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?}, driver {} {})", info.name, info.backend, info.device_type, info.driver, info.driver_info)
}

/// A wgpu error (whose text spans lines: the error and its causes) as one line.
fn one_line(e: &wgpu::Error) -> String {
    e.to_string().split('\n').map(|l| l.trim().trim_end_matches(':')).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(": ")
}

const NO_ADAPTER: &str =
    "no GPU adapter: wgpu found no Vulkan device (install a Vulkan driver, e.g. Mesa's lavapipe: apt-get install mesa-vulkan-drivers)";

impl Gpu {
    /// Opens the best Vulkan adapter that can run the kernels (trying them best first). Fails
    /// with a clear message when there is none.
    pub fn new() -> Result<Gpu> {
        let list = adapters();
        if list.is_empty() {
            bail!(NoAdapter: "{NO_ADAPTER}");
        }
        let mut first_error = None;
        for (i, a) in list.into_iter().enumerate() {
            match Self::with_adapter(a, i) {
                Ok(g) => return Ok(g),
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        Err(first_error.expect("one adapter was tried"))
    }

    /// Opens adapter `index` of `adapters()` (best first).
    pub fn open(index: usize) -> Result<Gpu> {
        let list = adapters();
        if list.is_empty() {
            bail!(NoAdapter: "{NO_ADAPTER}");
        }
        let n = list.len();
        let adapter = list.into_iter().nth(index).ok_or_else(|| err!(NoAdapter: "no GPU adapter {index}: there are {n} (see `kdray adapters`)"))?;
        Self::with_adapter(adapter, index)
    }

    /// Opens every adapter that can run the kernels (one runtime per device), best first;
    /// adapters that cannot (no SPIR-V passthrough, push constants or subgroup operations) are
    /// skipped with a warning.
    pub fn open_all() -> Result<Vec<Gpu>> {
        let list = adapters();
        if list.is_empty() {
            bail!(NoAdapter: "{NO_ADAPTER}");
        }
        let mut out = Vec::new();
        for (i, a) in list.into_iter().enumerate() {
            match Self::with_adapter(a, i) {
                Ok(g) => out.push(g),
                Err(e) => eprintln!("warning: GPU adapter {i} skipped: {e:#}"),
            }
        }
        if out.is_empty() {
            bail!(NoAdapter: "no GPU adapter can run the kernels");
        }
        Ok(out)
    }

    /// Opens `adapter`, which is entry `index` of `adapters()`. Fails (`NoAdapter`) when it has no
    /// SPIR-V passthrough, fewer than `MAX_PARAMS` bytes of push constants or no subgroup
    /// operations, or the device cannot be opened.
    pub fn with_adapter(adapter: wgpu::Adapter, index: usize) -> Result<Gpu> {
        let info = adapter.get_info();
        let mut features = wgpu::Features::PASSTHROUGH_SHADERS | wgpu::Features::IMMEDIATES;
        if !adapter.features().contains(features) {
            bail!(NoAdapter: "GPU adapter {} does not accept SPIR-V passthrough shaders with push constants", describe(&info));
        }
        // The kernels use subgroup arithmetic and ballots (the photon index's sort). wgpu's flag
        // asks for more: votes, shuffles and quads, in fragment shaders too, and Vulkan 1.3 or
        // VK_EXT_subgroup_size_control; every adapter that has run these kernels (NVIDIA,
        // lavapipe) offers it. Passthrough shaders need no feature enabled for them.
        if !adapter.features().contains(wgpu::Features::SUBGROUP) {
            bail!(NoAdapter: "GPU adapter {} does not offer subgroup operations in compute shaders", describe(&info));
        }
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // Ask for everything the adapter offers for storage buffers: scenes are limited by the
        // device, not by wgpu's conservative defaults.
        let a = adapter.limits();
        if a.max_immediate_size < MAX_PARAMS {
            bail!(NoAdapter: "GPU adapter {} offers {} bytes of push constants, the kernels need {MAX_PARAMS}", describe(&info), a.max_immediate_size);
        }
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: a.max_storage_buffer_binding_size,
            max_buffer_size: a.max_buffer_size,
            max_storage_buffers_per_shader_stage: a.max_storage_buffers_per_shader_stage.min(16),
            max_compute_workgroups_per_dimension: a.max_compute_workgroups_per_dimension,
            max_immediate_size: MAX_PARAMS,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("kdray"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| err!(NoAdapter: "cannot open GPU device {}: {e}", describe(&info)))?;
        // Errors outside an error scope and a lost device are recorded here and reported by
        // the next submission or wait, instead of panicking in wgpu's default handler (or
        // waiting out `SUBMIT_TIMEOUT` for a device that will never answer).
        let faults = Arc::new(Faults::default());
        let f = faults.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            f.error.lock().expect("GPU faults").get_or_insert_with(|| one_line(&e));
        }));
        let f = faults.clone();
        device.set_device_lost_callback(move |reason, message| {
            let m = message.trim().to_string();
            let what = if m.is_empty() { format!("{reason:?}") } else { format!("{reason:?}: {m}") };
            f.lost.lock().expect("GPU faults").get_or_insert(what);
        });
        let module = shader_module(&device, spirv_words()?, "kdray-shader")?;
        let cap = match std::env::var(MAX_BINDING_OVERRIDE) {
            Err(_) => 0,
            Ok(v) => v.trim().parse::<u64>().ok().filter(|&b| b >= 4).ok_or_else(|| err!(InvalidInput: "{MAX_BINDING_OVERRIDE}={v}: expected a number of bytes (at least 4)"))?,
        };
        Ok(Gpu {
            device,
            queue,
            info,
            limits,
            index,
            id: NEXT_GPU.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            timestamps,
            module,
            split_modules: Mutex::new(HashMap::new()),
            pipelines: Mutex::new(HashMap::new()),
            draw_targets: Mutex::new(HashMap::new()),
            binding_cap: std::sync::atomic::AtomicU64::new(cap),
            bind_groups: Mutex::new(HashMap::new()),
            dead: Arc::new(Mutex::new(Vec::new())),
            staging: Mutex::new(Vec::new()),
            params: Mutex::new(HashMap::new()),
            last_timed: Mutex::new(None),
            faults,
            profile: (timestamps && std::env::var(PROFILE_ENV).is_ok_and(|v| v != "0")).then(|| Mutex::new(Profile::default())),
        })
    }

    /// A fault the device reported since the last call: a lost device (every later call
    /// reports it too) or an error outside an error scope (reported once).
    fn fault(&self) -> Result<()> {
        if let Some(m) = self.faults.lost.lock().expect("GPU faults").as_ref() {
            bail!(DeviceLost: "the GPU device was lost ({m})");
        }
        if let Some(m) = self.faults.error.lock().expect("GPU faults").take() {
            bail!(Gpu: "the GPU reported an error: {m}");
        }
        Ok(())
    }

    /// The shader module specialized for `splits` (the built one when nothing is split).
    fn module_for(&self, splits: &Splits) -> Result<wgpu::ShaderModule> {
        if splits.iter().all(|&s| s == 0) {
            return Ok(self.module.clone());
        }
        let mut cache = self.split_modules.lock().expect("module cache");
        if let Some(m) = cache.get(splits) {
            return Ok(m.clone());
        }
        let module = shader_module(&self.device, specialize(&spirv_words()?, splits), "kdray-shader (split scene arrays)")?;
        cache.insert(*splits, module.clone());
        Ok(module)
    }

    fn pipeline(&self, name: &str, splits: &Splits, draw: Option<&Draw>) -> Result<Arc<Pipeline>> {
        let mut cache = self.pipelines.lock().expect("pipeline cache");
        let key = (name.to_string(), *splits);
        if let Some(p) = cache.get(&key) {
            return Ok(p.clone());
        }
        let m = module_info()?;
        let info = find_entry(m, name).cloned().ok_or_else(|| {
            let stem = name.split('_').next().unwrap_or(name);
            let similar: Vec<&str> = m.entry_points.iter().map(|e| short_name(&e.name)).filter(|e| e.starts_with(stem)).collect();
            err!(Gpu: "the SPIR-V module has no kernel '{name}' (kernels like it: {})", similar.join(", "))
        })?;
        let want = if draw.is_some() { reflect::Stage::Vertex } else { reflect::Stage::Compute };
        if info.stage != want {
            bail!(Gpu: "entry point '{name}' is a {:?} shader, not a {want:?} one", info.stage);
        }
        let visibility = if draw.is_some() { wgpu::ShaderStages::VERTEX } else { wgpu::ShaderStages::COMPUTE };
        let entries: Vec<wgpu::BindGroupLayoutEntry> = info
            .bindings
            .iter()
            .map(|b| wgpu::BindGroupLayoutEntry {
                binding: b.binding,
                visibility,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: b.read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        let layout = self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(name), entries: &entries });
        let pl = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: info.push_constant_size,
        });
        let module = self.module_for(splits)?;
        let pipeline = match draw {
            None => Pipe::Compute(self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(&info.name),
                compilation_options: Default::default(),
                cache: None,
            })),
            Some(d) => {
                let fragment = find_entry(m, d.fragment)
                    .filter(|f| f.stage == reflect::Stage::Fragment)
                    .ok_or_else(|| err!(Gpu: "the SPIR-V module has no fragment shader '{}'", d.fragment))?;
                Pipe::Render(self.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(name),
                    layout: Some(&pl),
                    vertex: wgpu::VertexState { module: &module, entry_point: Some(&info.name), compilation_options: Default::default(), buffers: &[] },
                    primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleList, cull_mode: None, ..Default::default() },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_FORMAT,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Greater),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(&fragment.name),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState { format: DRAW_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL })],
                    }),
                    multiview_mask: None,
                    cache: None,
                }))
            }
        };
        let p = Arc::new(Pipeline { pipeline, layout, info });
        cache.insert(key, p.clone());
        Ok(p)
    }

    /// Creates the pipeline of entry point `name` now (the driver compiles it).
    pub fn compile(&self, name: &str) -> Result<()> {
        self.pipeline(name, &Splits::default(), None).map(|_| ())
    }

    /// This GPU's adapter in one line (`describe`).
    pub fn adapter_line(&self) -> String {
        describe(&self.info)
    }

    /// Largest buffer a kernel can bind, in bytes.
    pub fn max_binding(&self) -> u64 {
        self.limits.max_storage_buffer_binding_size.min(self.limits.max_buffer_size)
    }

    /// Splits scene arrays larger than `bytes` (when below `max_binding`) across bindings from
    /// now on, as a device whose bindings hold at most `bytes` would; other buffers keep the
    /// device's limit. For tests and measurements of that path; 0 lifts it.
    pub fn split_arrays_above(&self, bytes: u64) {
        self.binding_cap.store(bytes, std::sync::atomic::Ordering::Relaxed);
    }

    /// Fails with "scene too large for this device" when a buffer of `bytes` cannot be bound.
    pub fn check_size(&self, label: &str, bytes: u64) -> Result<()> {
        (self as &dyn Runtime).check_size(label, bytes)
    }

    /// The buffer holding parameters `bytes` (made once per distinct value, then reused): its
    /// id and the buffer.
    fn params_buffer(&self, bytes: &[u8]) -> Result<(u64, wgpu::Buffer)> {
        let mut cache = self.params.lock().expect("params cache");
        if let Some(b) = cache.get(bytes) {
            return Ok((b.id(), b.gpu().expect("a GPU buffer").clone()));
        }
        if cache.len() >= 1024 {
            // Dropped buffers stay alive while submitted work uses them (wgpu tracks that).
            cache.clear();
        }
        let b = self.alloc_raw("params", bytes.len() as u64)?;
        self.write_raw(&b, bytes)?;
        let out = (b.id(), b.gpu().expect("a GPU buffer").clone());
        cache.insert(bytes.to_vec(), b);
        Ok(out)
    }

    /// The encoder of commands recorded for this GPU.
    fn commands<'c>(&self, c: &'c mut Commands) -> Result<&'c mut wgpu::CommandEncoder> {
        if c.device != Some(self.id) {
            bail!(InvalidInput: "commands of another runtime recorded on {}", self.info.name);
        }
        c.encoder.as_mut().ok_or_else(|| err!(Gpu: "commands already submitted"))
    }

    /// This GPU's buffer of `buf`, or an error naming it.
    fn own<'b>(&self, buf: &'b RawBuffer) -> Result<&'b wgpu::Buffer> {
        match (buf.gpu(), buf.device()) {
            (Some(b), Some(d)) if d == self.id => Ok(b),
            (Some(_), _) => bail!(InvalidInput: "buffer '{}' belongs to another GPU", buf.label()),
            _ => bail!(InvalidInput: "buffer '{}' is host memory, not this GPU's", buf.label()),
        }
    }

    /// Drops cached bind groups that name dropped buffers (so their memory is freed).
    fn purge_dead(&self, cache: &mut HashMap<(String, Vec<u64>), wgpu::BindGroup>) {
        let dead: Vec<u64> = std::mem::take(&mut *self.dead.lock().expect("dead buffers"));
        if !dead.is_empty() {
            cache.retain(|(_, key), _| !key.iter().any(|id| dead.contains(id)));
        }
    }

    /// The pass's bind group (cached by entry point and buffers), its buffers checked against
    /// the module.
    fn bind_group(&self, p: &Pipeline, k: &dyn Kernel, host: &[Bind]) -> Result<wgpu::BindGroup> {
        let order = validate(k, host, &p.info)?;
        let name = k.entry();
        for h in host {
            if h.buffer.device() != Some(self.id) {
                bail!(Gpu: "kernel {name}: buffer '{}' belongs to {}, not to this GPU", h.buffer.label(), if h.buffer.device().is_some() { "another GPU" } else { "the native runtime" });
            }
        }
        let params = if order.contains(&Slot::Params) { Some(self.params_buffer(k.params())?) } else { None };
        // Buffer ids in binding order: the cache key.
        let ids: Vec<u64> = order
            .iter()
            .map(|s| match s {
                Slot::Host(i) => host[*i].buffer.id(),
                Slot::Params => params.as_ref().map_or(0, |p| p.0),
            })
            .collect();
        let mut cache = self.bind_groups.lock().expect("bind group cache");
        self.purge_dead(&mut cache);
        let key = (p.info.name.clone(), ids);
        if let Some(bg) = cache.get(&key) {
            return Ok(bg.clone());
        }
        let mut buffers = Vec::with_capacity(order.len());
        for s in &order {
            buffers.push(match s {
                Slot::Host(i) => host[*i].buffer.gpu().ok_or_else(|| err!(Gpu: "kernel {name}: buffer '{}' is host memory, not this GPU's", host[*i].buffer.label()))?,
                Slot::Params => &params.as_ref().ok_or_else(|| err!(Gpu: "kernel {name}: parameter buffer missing"))?.1,
            });
        }
        let entries: Vec<wgpu::BindGroupEntry> = p
            .info
            .bindings
            .iter()
            .zip(&buffers)
            .map(|(b, buf)| wgpu::BindGroupEntry { binding: b.binding, resource: buf.as_entire_binding() })
            .collect();
        let bg = self.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(&name), layout: &p.layout, entries: &entries });
        cache.insert(key, bg.clone());
        Ok(bg)
    }

    /// Records one pass, direct (`threads`) or indirect (`(args, byte offset)`), with
    /// timestamps at its start and end into queries `2i`, `2i + 1` of `timer = (queries, i)`.
    fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        k: &dyn Kernel,
        indirect: Option<(&wgpu::Buffer, u64)>,
        timer: Option<(&wgpu::QuerySet, u32)>,
    ) -> Result<()> {
        let name = k.entry();
        let host = k.bindings();
        let draw = k.draw();
        let p = self.pipeline(&name, &splits(&host), draw.as_ref())?;
        let bg = self.bind_group(&p, k, &host)?;
        let pipeline = match (&p.pipeline, draw) {
            (Pipe::Compute(c), None) => c,
            (Pipe::Render(r), Some(d)) => return self.record_draw(enc, k, &d, r, &bg, &host, timer),
            _ => bail!(Gpu: "kernel {name}: drawn and dispatched both"),
        };
        let grid = match indirect {
            None => Some(self.grid(k.threads(), k.workgroup())?),
            Some(_) => None,
        };
        let mut cpass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(&name),
            timestamp_writes: timer.map(|(q, i)| wgpu::ComputePassTimestampWrites {
                query_set: q,
                beginning_of_pass_write_index: Some(2 * i),
                end_of_pass_write_index: Some(2 * i + 1),
            }),
        });
        cpass.set_pipeline(pipeline);
        cpass.set_bind_group(0, &bg, &[]);
        if p.info.push_constant_size > 0 {
            cpass.set_immediates(0, k.params());
        }
        match (indirect, grid) {
            (Some((buf, off)), _) => cpass.dispatch_workgroups_indirect(buf, off),
            (None, Some((gx, gy))) if gx > 0 => cpass.dispatch_workgroups(gx, gy, 1),
            _ => {}
        }
        Ok(())
    }

    /// Records a drawing pass (`Kernel::draw`): the draw into render targets of the pass's size,
    /// then the copy of its image into the target binding.
    #[allow(clippy::too_many_arguments)]
    fn record_draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        k: &dyn Kernel,
        d: &Draw,
        pipeline: &wgpu::RenderPipeline,
        bg: &wgpu::BindGroup,
        host: &[Bind],
        timer: Option<(&wgpu::QuerySet, u32)>,
    ) -> Result<()> {
        let name = k.entry();
        let target = host.iter().find(|h| h.name == d.target).ok_or_else(|| err!(Gpu: "kernel {name}: no binding '{}' for its image", d.target))?;
        let max = self.limits.max_texture_dimension_2d;
        if d.width == 0 || d.height == 0 || d.row_words < d.width || d.row_words % 64 != 0 || d.row_words > max || d.height > max {
            bail!(TooLarge: "kernel {name}: an image of {} x {} pixels in rows of {} words cannot be drawn (this GPU draws at most {max} x {max})", d.width, d.height, d.row_words);
        }
        let bytes = 4 * d.row_words as u64 * d.height as u64;
        if target.elem != 4 || target.buffer.bytes() < bytes {
            bail!(Gpu: "kernel {name}: '{}' holds {} bytes of {}-byte elements, the image {bytes} bytes of u32", d.target, target.buffer.bytes(), target.elem);
        }
        let dest = self.own(target.buffer)?;
        let t = self.draw_targets(d.row_words, d.height);
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some(&name),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &t.image_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &t.depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: timer.map(|(q, i)| wgpu::RenderPassTimestampWrites {
                    query_set: q,
                    beginning_of_pass_write_index: Some(2 * i),
                    end_of_pass_write_index: Some(2 * i + 1),
                }),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bg, &[]);
            // The image's own pixels only: the viewport maps the camera's frame onto them
            // whatever the padding of the rows.
            pass.set_viewport(0.0, 0.0, d.width as f32, d.height as f32, 0.0, 1.0);
            pass.set_scissor_rect(0, 0, d.width, d.height);
            if d.vertices > 0 {
                pass.draw(0..d.vertices, 0..1);
            }
        }
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo { texture: &t.image, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            wgpu::TexelCopyBufferInfo {
                buffer: dest,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * d.row_words), rows_per_image: Some(d.height) },
            },
            wgpu::Extent3d { width: d.row_words, height: d.height, depth_or_array_layers: 1 },
        );
        Ok(())
    }

    /// The render targets of drawing passes `width` × `height` pixels (made once per size).
    fn draw_targets(&self, width: u32, height: u32) -> Arc<DrawTargets> {
        let mut cache = self.draw_targets.lock().expect("draw targets");
        cache
            .entry((width, height))
            .or_insert_with(|| {
                let texture = |label, format, usage| {
                    self.device.create_texture(&wgpu::TextureDescriptor {
                        label: Some(label),
                        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format,
                        usage,
                        view_formats: &[],
                    })
                };
                let image = texture("visibility", DRAW_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
                let depth = texture("depth", DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
                Arc::new(DrawTargets { image_view: image.create_view(&Default::default()), image, depth_view: depth.create_view(&Default::default()) })
            })
            .clone()
    }

    /// Workgroup grid (x, y) covering `threads` threads in groups of `wg`.
    pub fn grid(&self, threads: u32, wg: u32) -> Result<(u32, u32)> {
        let groups = threads.div_ceil(wg);
        let max = self.limits.max_compute_workgroups_per_dimension;
        let gx = groups.min(max);
        let gy = if gx == 0 { 0 } else { groups.div_ceil(gx) };
        if gy > max {
            bail!(Gpu: "dispatch of {threads} threads exceeds the device's workgroup grid");
        }
        Ok((gx, gy))
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None })
    }

    /// Submits and waits, with an upper bound on the wait.
    fn submit_wait(&self, encoder: wgpu::CommandEncoder) -> Result<()> {
        let idx = self.queue.submit([encoder.finish()]);
        self.poll(Some(idx))
    }

    fn poll(&self, idx: Option<wgpu::SubmissionIndex>) -> Result<()> {
        self.fault()?;
        let polled = self.device.poll(wgpu::PollType::Wait { submission_index: idx, timeout: Some(SUBMIT_TIMEOUT) });
        // A fault explains a failed wait better than the wait's own error.
        self.fault()?;
        polled.map_err(|e| err!(DeviceLost: "the GPU did not finish: {e}"))?;
        Ok(())
    }

    /// A staging buffer of at least `bytes` bytes from the pool, or a new one.
    fn take_staging(&self, bytes: u64) -> wgpu::Buffer {
        let mut pool = self.staging.lock().expect("staging pool");
        if let Some(i) = pool.iter().position(|b| b.size() >= bytes && b.size() <= bytes.max(1 << 16) * 4) {
            return pool.swap_remove(i);
        }
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: bytes.max(4).next_multiple_of(4),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    fn return_staging(&self, b: wgpu::Buffer) {
        let mut pool = self.staging.lock().expect("staging pool");
        // A few buffers are enough for double-buffered batches.
        if pool.len() < 8 {
            pool.push(b);
        }
    }

    /// Whether the adapter is a CPU driver (lavapipe, SwiftShader) rather than a GPU.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Runs a sequence of passes `reps` times after a warm-up (`WARM_UP`). Per run: the wall time from
    /// submit to completion and, where the adapter has timestamp queries, the GPU time from the
    /// start of the first pass to the end of the last and the GPU time of each pass (ms).
    pub fn time_passes(&self, passes: &[&dyn Kernel], reps: usize) -> Result<Timing> {
        let n = passes.len() as u32;
        let qs = self.timestamps.then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("pass timer"), ty: wgpu::QueryType::Timestamp, count: 2 * n })
        });
        let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamps"),
            size: 16 * n as u64,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut t = Timing { parts_ms: vec![Vec::new(); passes.len()], ..Default::default() };
        let period = self.queue.get_timestamp_period() as f64 * 1e-6;
        // After an idle spell (or at the first measurement) the GPU needs a second of work
        // before it runs at full speed again (measured on the H100: up to 5× slower before).
        let idle = self.last_timed.lock().expect("timer").is_none_or(|t| t.elapsed() > IDLE);
        if idle && self.info.device_type != wgpu::DeviceType::Cpu {
            self.warm_up(passes, Duration::from_secs(1))?;
        }
        // Warm-up: at least WARM_UP of this work (and 3 runs), so caches are filled before
        // anything is timed; bounded in runs.
        let warm = std::time::Instant::now();
        let mut runs = 0;
        while runs < 3 || (warm.elapsed() < WARM_UP && runs < 1000) {
            let mut enc = self.encoder();
            for p in passes {
                self.record(&mut enc, *p, None, None)?;
            }
            self.submit_wait(enc)?;
            runs += 1;
        }
        for _ in 0..reps {
            let mut enc = self.encoder();
            for (i, p) in passes.iter().enumerate() {
                self.record(&mut enc, *p, None, qs.as_ref().map(|q| (q, i as u32)))?;
            }
            if let Some(q) = &qs {
                enc.resolve_query_set(q, 0..2 * n, &resolve, 0);
            }
            let start = std::time::Instant::now();
            self.submit_wait(enc)?;
            t.wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            if qs.is_some() {
                let ticks: Vec<u64> = self.read_plain(&resolve, 16 * n as u64)?;
                t.gpu_ms.push(ticks[2 * n as usize - 1].wrapping_sub(ticks[0]) as f64 * period);
                for (i, part) in t.parts_ms.iter_mut().enumerate() {
                    part.push(ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) as f64 * period);
                }
            }
        }
        *self.last_timed.lock().expect("timer") = Some(std::time::Instant::now());
        Ok(t)
    }

    /// Keeps the GPU busy for `d` with `passes` (bounded in runs), so that clocks and power
    /// states have settled before a series of measurements: on the H100 the first seconds of a
    /// process ran the same kernels up to 5× slower.
    pub fn warm_up(&self, passes: &[&dyn Kernel], d: Duration) -> Result<()> {
        let start = std::time::Instant::now();
        let mut runs = 0;
        while start.elapsed() < d && runs < 100_000 {
            let mut enc = self.encoder();
            for p in passes {
                self.record(&mut enc, *p, None, None)?;
            }
            self.submit_wait(enc)?;
            runs += 1;
        }
        Ok(())
    }

    /// Copies a non-storage buffer (timestamps) back.
    fn read_plain<T: bytemuck::Pod>(&self, buf: &wgpu::Buffer, bytes: u64) -> Result<Vec<T>> {
        let staging = self.take_staging(bytes);
        let mut enc = self.encoder();
        enc.copy_buffer_to_buffer(buf, 0, &staging, 0, bytes);
        let idx = self.queue.submit([enc.finish()]);
        let r = Readback { device: self.id, staging, bytes, submission: Mutex::new(Some(idx)) };
        Ok(bytemuck::pod_collect_to_vec(&self.map(&r)?))
    }

    fn map(&self, r: &Readback) -> Result<Vec<u32>> {
        if r.bytes == 0 {
            return Ok(Vec::new());
        }
        let idx = r.submission.lock().expect("read-back").clone();
        if idx.is_none() {
            bail!(Gpu: "a read-back was waited for before its commands were submitted");
        }
        let slice = r.staging.slice(..r.bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |res| {
            let _ = tx.send(res);
        });
        self.poll(idx)?;
        rx.recv_timeout(SUBMIT_TIMEOUT)
            .map_err(|_| err!(DeviceLost: "a GPU read-back did not complete"))?
            .map_err(|e| err!(Gpu: "cannot read GPU buffer: {e}"))?;
        let view = slice.get_mapped_range().map_err(|e| err!(Gpu: "cannot map GPU buffer: {e:?}"))?;
        let out: Vec<u32> = bytemuck::pod_collect_to_vec(&view);
        drop(view);
        r.staging.unmap();
        Ok(out)
    }
}

impl Runtime for Gpu {
    fn name(&self) -> String {
        self.adapter_line()
    }

    fn is_native(&self) -> bool {
        false
    }

    fn is_software(&self) -> bool {
        Gpu::is_software(self)
    }

    fn max_binding(&self) -> u64 {
        Gpu::max_binding(self)
    }

    fn split_shift(&self, label: &str, len: usize, elem: usize) -> Result<Option<u32>> {
        let max = match self.binding_cap.load(std::sync::atomic::Ordering::Relaxed) {
            0 => self.max_binding(),
            cap => cap.min(self.max_binding()),
        };
        crate::runtime::split_at(label, len, elem, max, || (Runtime::name(self), false))
    }

    fn alloc_raw(&self, label: &str, bytes: u64) -> Result<RawBuffer> {
        let size = bytes.max(4).next_multiple_of(4);
        // A buffer the device cannot hold (out of memory) or refuses (past its limits) is an
        // error of this call: caught in error scopes instead of reaching wgpu's handler of
        // uncaptured errors, which panics.
        let out_of_memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let invalid = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::INDIRECT,
            // wgpu zero-initialises new buffers.
            mapped_at_creation: false,
        });
        let refused = pollster::block_on(invalid.pop());
        let no_memory = pollster::block_on(out_of_memory.pop());
        let mib = size as f64 / 1048576.0;
        if let Some(e) = no_memory {
            bail!(TooLarge: "out of GPU memory: the {label} buffer ({mib:.1} MiB) does not fit on {}: {}", self.info.name, one_line(&e));
        }
        if let Some(e) = refused {
            bail!(TooLarge: "the GPU refuses the {label} buffer ({mib:.1} MiB) on {}: {}", self.info.name, one_line(&e));
        }
        // Bind groups of dropped buffers go first, so their memory is freed before more is taken.
        self.purge_dead(&mut self.bind_groups.lock().expect("bind group cache"));
        Ok(RawBuffer::new(label, size, Mem::Gpu { buffer, dead: self.dead.clone(), device: self.id }))
    }

    fn write_raw(&self, buf: &RawBuffer, data: &[u8]) -> Result<()> {
        let b = self.own(buf)?;
        if data.len() as u64 > buf.bytes() {
            bail!(Gpu: "{}: {} bytes written into a buffer of {}", buf.label(), data.len(), buf.bytes());
        }
        if data.len() % 4 != 0 {
            let mut padded = data.to_vec();
            padded.resize(data.len().next_multiple_of(4), 0);
            self.queue.write_buffer(b, 0, &padded);
        } else if !data.is_empty() {
            self.queue.write_buffer(b, 0, data);
        }
        Ok(())
    }

    fn begin(&self) -> Commands {
        let profile = self.profile.as_ref().map(|_| ProfileRecording {
            set: self.device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("profile"), ty: wgpu::QueryType::Timestamp, count: 2 * PROFILE_PASSES }),
            names: Vec::new(),
        });
        Commands { device: Some(self.id), encoder: Some(self.encoder()), readbacks: Vec::new(), profile }
    }

    fn clear(&self, c: &mut Commands, buf: &RawBuffer) -> Result<()> {
        let b = self.own(buf)?;
        self.commands(c)?.clear_buffer(b, 0, None);
        Ok(())
    }

    fn dispatch(&self, c: &mut Commands, k: &dyn Kernel) -> Result<()> {
        self.commands(c)?;
        let enc = c.encoder.as_mut().expect("checked");
        self.record(enc, k, None, profile_slot(&mut c.profile, k))
    }

    fn dispatch_indirect(&self, c: &mut Commands, k: &dyn Kernel, args: &Buffer<[u32; 3]>, index: usize) -> Result<()> {
        let b = self.own(args.raw())?;
        if index >= args.len() {
            bail!(InvalidInput: "{}: indirect arguments {index} of {}", k.entry(), args.len());
        }
        self.commands(c)?;
        let enc = c.encoder.as_mut().expect("checked");
        self.record(enc, k, Some((b, 12 * index as u64)), profile_slot(&mut c.profile, k))
    }

    fn read_back(&self, c: &mut Commands, buf: &RawBuffer, bytes: u64) -> Result<Pending> {
        let b = self.own(buf)?;
        let bytes = bytes.min(buf.bytes()).next_multiple_of(4).min(buf.bytes());
        let staging = self.take_staging(bytes);
        if bytes > 0 {
            self.commands(c)?.copy_buffer_to_buffer(b, 0, &staging, 0, bytes);
        }
        let r = Arc::new(Readback { device: self.id, staging, bytes, submission: Mutex::new(None) });
        c.readbacks.push(r.clone());
        Ok(Pending { bytes, data: PendingData::Gpu(r) })
    }

    fn submit(&self, mut c: Commands) -> Result<()> {
        self.commands(&mut c)?;
        let mut enc = c.encoder.take().ok_or_else(|| err!(InvalidInput: "commands of another runtime"))?;
        self.fault()?;
        let timed = c.profile.take().filter(|r| !r.names.is_empty()).map(|r| {
            let bytes = 16 * r.names.len() as u64;
            let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("profile timestamps"),
                size: bytes,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("profile read-back"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            enc.resolve_query_set(&r.set, 0..2 * r.names.len() as u32, &resolve, 0);
            enc.copy_buffer_to_buffer(&resolve, 0, &staging, 0, bytes);
            (staging, r.names)
        });
        let idx = self.queue.submit([enc.finish()]);
        if let (Some(t), Some(p)) = (timed, &self.profile) {
            let full = {
                let mut p = p.lock().expect("profile");
                p.pending.push(t);
                p.pending.len() > 16
            };
            if full {
                self.collect_profile();
            }
        }
        for r in &c.readbacks {
            *r.submission.lock().expect("read-back") = Some(idx.clone());
        }
        self.fault()
    }

    fn wait(&self, p: Pending) -> Result<Vec<u32>> {
        let r = match p.data {
            PendingData::Gpu(r) => r,
            PendingData::Ready(_) => bail!(Gpu: "a read-back of the native runtime waited for on a GPU"),
        };
        if r.device != self.id {
            bail!(Gpu: "a read-back of another GPU waited for on this one");
        }
        let mut out = self.map(&r)?;
        out.truncate(p.bytes as usize / 4);
        if let Ok(r) = Arc::try_unwrap(r) {
            self.return_staging(r.staging);
        }
        Ok(out)
    }

    fn finish(&self) -> Result<()> {
        // Queued writes reach the device with the next submission: an empty one sends them,
        // so that a caller timing an upload (`LbvhData::setup_s`) times its transfer.
        self.queue.submit(std::iter::empty());
        self.poll(None)?;
        self.collect_profile();
        Ok(())
    }
}

/// The timestamp slot of a pass of `k` under `PROFILE_ENV` (none past `PROFILE_PASSES`).
fn profile_slot<'a>(r: &'a mut Option<ProfileRecording>, k: &dyn Kernel) -> Option<(&'a wgpu::QuerySet, u32)> {
    let r = r.as_mut()?;
    let i = r.names.len() as u32;
    if i >= PROFILE_PASSES {
        return None;
    }
    r.names.push(k.entry().into_owned());
    Some((&r.set, i))
}

impl Gpu {
    /// Reads the timestamps of profiled submissions (waiting for them) into the totals.
    fn collect_profile(&self) {
        let Some(p) = &self.profile else { return };
        let pending = std::mem::take(&mut p.lock().expect("profile").pending);
        let period = self.queue.get_timestamp_period() as f64 * 1e-6;
        for (staging, names) in pending {
            let slice = staging.slice(..);
            slice.map_async(wgpu::MapMode::Read, |_| {});
            if self.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(SUBMIT_TIMEOUT) }).is_err() {
                return;
            }
            let Ok(view) = slice.get_mapped_range() else { return };
            let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&view);
            drop(view);
            let mut p = p.lock().expect("profile");
            let passes = names.len();
            for (i, n) in names.into_iter().enumerate() {
                let e = p.totals.entry(n).or_default();
                e.0 += 1;
                e.1 += ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) as f64 * period;
            }
            if passes > 0 {
                let (start, end) = (ticks[0], ticks[2 * passes - 1]);
                let idle = p.last_end.map_or(0.0, |e| start.saturating_sub(e) as f64 * period);
                p.submissions.0 += 1;
                p.submissions.1 += end.wrapping_sub(start) as f64 * period;
                p.submissions.2 += idle;
                p.last_end = Some(end);
            }
        }
    }

    /// Under `PROFILE_ENV`: GPU time per entry point so far, most first (entry point,
    /// dispatches, total ms).
    pub fn profile(&self) -> Option<Vec<(String, u64, f64)>> {
        self.profile.as_ref()?;
        self.collect_profile();
        let p = self.profile.as_ref()?.lock().expect("profile");
        let mut rows: Vec<_> = p.totals.iter().map(|(k, &(n, ms))| (k.clone(), n, ms)).collect();
        rows.sort_by(|a, b| b.2.total_cmp(&a.2));
        Some(rows)
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        let Some(rows) = self.profile() else { return };
        let total: f64 = rows.iter().map(|r| r.2).sum();
        eprintln!("GPU time per entry point ({PROFILE_ENV}, {}; timestamps at every pass):", describe(&self.info));
        eprintln!("{:<34} {:>10} {:>12} {:>10} {:>7}", "entry point", "dispatches", "total ms", "mean us", "share");
        for (name, n, ms) in rows {
            eprintln!("{name:<34} {n:>10} {ms:>12.3} {:>10.2} {:>6.1}%", ms * 1e3 / n as f64, 100.0 * ms / total.max(1e-12));
        }
        if let Some(p) = &self.profile {
            let (n, span, idle) = p.lock().expect("profile").submissions;
            eprintln!(
                "{n} submissions: {span:.3} ms from each one's first pass to its last ({:.3} ms of it between passes), {idle:.3} ms between submissions",
                span - total
            );
        }
    }
}

/// Repeated measurements of a sequence of dispatches, in milliseconds: wall time, GPU time of
/// the whole sequence, and GPU time of each pass (empty without timestamp queries).
#[derive(Clone, Debug, Default)]
pub struct Timing {
    /// Per run: host time from submit to completion.
    pub wall_ms: Vec<f64>,
    /// Per run: GPU time from the start of the first pass to the end of the last.
    pub gpu_ms: Vec<f64>,
    /// Per pass: its GPU time in each run.
    pub parts_ms: Vec<Vec<f64>>,
}

/// The middle value of `v` (the upper of the two middle ones for an even count); `None` if
/// `v` is empty.
pub fn median(v: &[f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    Some(s[s.len() / 2])
}
