//! The wgpu runtime: adapter choice, device limits, SPIR-V pipelines, buffers and bounded
//! dispatches. Kernels are loaded as passthrough SPIR-V (no WGSL, no naga translation).
pub mod kernels;
pub mod tracer;

use anyhow::{anyhow, bail, Context, Result};
use bytemuck::Pod;
use kdray_shared::FrameParams;
use kernels::{Kernel, WORKGROUP};
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;

static SPIRV: &[u8] = include_bytes!(env!("kdray_shader.spv"));

/// Longest a single submission may run before we report it as hung. Work is split so that a
/// submission is far below this on any real device.
const SUBMIT_TIMEOUT: Duration = Duration::from_secs(600);

/// Work of a measurement run before it is timed (caches).
const WARM_UP: Duration = Duration::from_millis(100);

/// An idle GPU longer than this is warmed up for a second before the next measurement.
const IDLE: Duration = Duration::from_millis(250);

pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Whether passes can carry timestamp queries (GPU-side kernel times).
    pub timestamps: bool,
    module: wgpu::ShaderModule,
    /// Created on first use: drivers compile each entry point when its pipeline is made.
    pipelines: Mutex<HashMap<Kernel, (wgpu::ComputePipeline, wgpu::BindGroupLayout)>>,
    /// When a timed measurement last finished (to tell how long the GPU has idled).
    last_timed: Mutex<Option<std::time::Instant>>,
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

pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.backend, info.device_type, info.driver, info.driver_info
    )
}

impl Gpu {
    /// Opens the best Vulkan adapter. Fails with a clear message when there is none.
    pub fn new() -> Result<Gpu> {
        let adapter = adapters()
            .into_iter()
            .next()
            .ok_or_else(|| anyhow!("no GPU adapter: wgpu found no Vulkan device (install a Vulkan driver, e.g. Mesa's lavapipe: apt-get install mesa-vulkan-drivers)"))?;
        Self::with_adapter(adapter)
    }

    pub fn with_adapter(adapter: wgpu::Adapter) -> Result<Gpu> {
        let info = adapter.get_info();
        let mut features = wgpu::Features::PASSTHROUGH_SHADERS;
        if !adapter.features().contains(features) {
            bail!("GPU adapter {} does not accept SPIR-V passthrough shaders", describe(&info));
        }
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // Ask for everything the adapter offers for storage buffers: scenes are limited by the
        // device, not by wgpu's conservative defaults.
        let a = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: a.max_storage_buffer_binding_size,
            max_buffer_size: a.max_buffer_size,
            max_storage_buffers_per_shader_stage: a.max_storage_buffers_per_shader_stage.min(16),
            max_compute_workgroups_per_dimension: a.max_compute_workgroups_per_dimension,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("kdray"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .with_context(|| format!("cannot open GPU device {}", describe(&info)))?;
        let spirv: Vec<u32> = SPIRV
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        let entry_points: Vec<wgpu::PassthroughShaderEntryPoint> = kernels::ENTRY_POINTS
            .iter()
            .map(|name| wgpu::PassthroughShaderEntryPoint {
                name: (*name).into(),
                workgroup_size: (WORKGROUP, 1, 1),
            })
            .collect();
        // SAFETY: the module is the rust-gpu output of shader-crate, validated by spirv-val at
        // build time; its entry points and bindings are the ones listed in `kernels`.
        let module = unsafe {
            device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                label: Some("kdray-shader"),
                entry_points: entry_points.into(),
                spirv: Some(spirv.into()),
                ..Default::default()
            })
        };
        Ok(Gpu { device, queue, info, limits, timestamps, module, pipelines: Mutex::new(HashMap::new()), last_timed: Mutex::new(None) })
    }

    fn pipeline(&self, k: Kernel) -> Result<(wgpu::ComputePipeline, wgpu::BindGroupLayout)> {
        let mut cache = self.pipelines.lock().expect("pipeline cache");
        if let Some(p) = cache.get(&k) {
            return Ok(p.clone());
        }
        let name = k.entry_point()?;
        let mut entries = vec![storage_entry(0, true)];
        entries.extend(k.bindings().iter().enumerate().map(|(i, ro)| storage_entry(i as u32 + 1, *ro)));
        let bgl = self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(name),
            entries: &entries,
        });
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let pipeline = self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&layout),
            module: &self.module,
            entry_point: Some(name),
            compilation_options: Default::default(),
            cache: None,
        });
        cache.insert(k, (pipeline.clone(), bgl.clone()));
        Ok((pipeline, bgl))
    }

    /// Creates the pipeline of `kernel` now (the driver compiles it), instead of on first use.
    pub fn compile(&self, kernel: Kernel) -> Result<()> {
        self.pipeline(kernel).map(|_| ())
    }

    pub fn adapter_line(&self) -> String {
        describe(&self.info)
    }

    /// Largest buffer a kernel can bind, in bytes.
    pub fn max_binding(&self) -> u64 {
        self.limits.max_storage_buffer_binding_size.min(self.limits.max_buffer_size)
    }

    /// A storage buffer holding `data` (one zeroed element if empty: bindings cannot be empty).
    /// Fails with a clear message when it exceeds the device's binding limit.
    pub fn upload<T: Pod + Default>(&self, label: &str, data: &[T]) -> Result<wgpu::Buffer> {
        let one = [T::default()];
        let data = if data.is_empty() { &one[..] } else { data };
        let bytes: &[u8] = bytemuck::cast_slice(data);
        self.check_size(label, bytes.len() as u64)?;
        let buf = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        self.queue.write_buffer(&buf, 0, bytes);
        Ok(buf)
    }

    /// An uninitialised storage buffer of `n` elements of `T`.
    pub fn storage<T: Pod>(&self, label: &str, n: usize) -> Result<wgpu::Buffer> {
        let size = (n.max(1) * std::mem::size_of::<T>()) as u64;
        self.check_size(label, size)?;
        Ok(self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        }))
    }

    pub fn check_size(&self, label: &str, bytes: u64) -> Result<()> {
        let max = self.max_binding();
        if bytes > max {
            bail!(
                "scene too large for this GPU: the {label} buffer needs {:.1} MiB but {} allows at most {:.1} MiB per storage buffer",
                bytes as f64 / 1048576.0,
                self.info.name,
                max as f64 / 1048576.0
            );
        }
        Ok(())
    }

    /// Records one dispatch of `kernel` over `params.count` items into `encoder`.
    /// The items are laid out on a 2D grid of workgroups so no dimension exceeds the limit.
    pub fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        kernel: Kernel,
        params: &FrameParams,
        buffers: &[&wgpu::Buffer],
    ) -> Result<()> {
        self.record_pass(encoder, &Pass { kernel, params: *params, buffers: buffers.to_vec() }, None)
    }

    /// Records `pass`, writing timestamps at its start and end into queries `2i` and `2i + 1` of
    /// `timer = (queries, i)`.
    fn record_pass(&self, encoder: &mut wgpu::CommandEncoder, pass: &Pass, timer: Option<(&wgpu::QuerySet, u32)>) -> Result<()> {
        let Pass { kernel, params, buffers } = pass;
        let kernel = *kernel;
        let (pipeline, bgl) = &self.pipeline(kernel)?;
        assert_eq!(buffers.len(), kernel.bindings().len(), "binding count of {kernel:?}");
        let pbuf = self.upload("params", std::slice::from_ref(params))?;
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: pbuf.as_entire_binding() }];
        entries.extend(
            buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32 + 1, resource: b.as_entire_binding() }),
        );
        let bg = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(kernel.entry_point()?),
            layout: bgl,
            entries: &entries,
        });
        let (gx, gy) = self.grid(kernel.threads(params.count))?;
        let mut cpass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(kernel.entry_point()?),
            timestamp_writes: timer.map(|(q, i)| wgpu::ComputePassTimestampWrites {
                query_set: q,
                beginning_of_pass_write_index: Some(2 * i),
                end_of_pass_write_index: Some(2 * i + 1),
            }),
        });
        cpass.set_pipeline(pipeline);
        cpass.set_bind_group(0, &bg, &[]);
        if gx > 0 {
            cpass.dispatch_workgroups(gx, gy, 1);
        }
        Ok(())
    }

    /// Records a sequence of passes.
    pub fn record_passes(&self, encoder: &mut wgpu::CommandEncoder, passes: &[Pass]) -> Result<()> {
        passes.iter().try_for_each(|p| self.record_pass(encoder, p, None))
    }

    /// Workgroup grid (x, y) covering `count` items.
    pub fn grid(&self, count: u32) -> Result<(u32, u32)> {
        let groups = count.div_ceil(WORKGROUP);
        let max = self.limits.max_compute_workgroups_per_dimension;
        let gx = groups.min(max);
        let gy = if gx == 0 { 0 } else { groups.div_ceil(gx) };
        if gy > max {
            bail!("dispatch of {count} items exceeds the device's workgroup grid");
        }
        Ok((gx, gy.max(if gx == 0 { 0 } else { 1 })))
    }

    /// Runs a sequence of passes `reps` times after a warm-up (`WARM_UP`). Per run: the wall time from
    /// submit to completion and, where the adapter has timestamp queries, the GPU time from the
    /// start of the first pass to the end of the last and the GPU time of each pass (ms).
    pub fn time_passes(&self, passes: &[Pass], reps: usize) -> Result<Timing> {
        let n = passes.len() as u32;
        let qs = self.timestamps.then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timer"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * n,
            })
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
            self.warm_up(Duration::from_secs(1))?;
        }
        // Warm-up: at least WARM_UP of this work (and 3 runs), so caches are filled before
        // anything is timed; bounded in runs.
        let warm = std::time::Instant::now();
        let mut runs = 0;
        while runs < 3 || (warm.elapsed() < WARM_UP && runs < 1000) {
            let mut enc = self.encoder();
            for p in passes {
                self.record_pass(&mut enc, p, None)?;
            }
            self.submit_wait(enc)?;
            runs += 1;
        }
        for _ in 0..reps {
            let mut enc = self.encoder();
            for (i, p) in passes.iter().enumerate() {
                self.record_pass(&mut enc, p, qs.as_ref().map(|q| (q, i as u32)))?;
            }
            if let Some(q) = &qs {
                enc.resolve_query_set(q, 0..2 * n, &resolve, 0);
            }
            let start = std::time::Instant::now();
            self.submit_wait(enc)?;
            t.wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            if qs.is_some() {
                let ticks: Vec<u64> = self.read(&resolve, 2 * n as usize)?;
                t.gpu_ms.push(ticks[2 * n as usize - 1].wrapping_sub(ticks[0]) as f64 * period);
                for (i, part) in t.parts_ms.iter_mut().enumerate() {
                    part.push(ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) as f64 * period);
                }
            }
        }
        *self.last_timed.lock().expect("timer") = Some(std::time::Instant::now());
        Ok(t)
    }

    /// Keeps the GPU busy for `d` (bounded kernels of 1 M items each), so that clocks and
    /// power states have settled before a series of measurements: on the H100 the first
    /// seconds of a process ran the same kernels up to 5× slower.
    pub fn warm_up(&self, d: Duration) -> Result<()> {
        let n = 1usize << 20;
        let out = self.storage::<[u32; 4]>("warm-up", n)?;
        let start = std::time::Instant::now();
        let mut seed = 0;
        while start.elapsed() < d && seed < 100_000 {
            let mut enc = self.encoder();
            let p = FrameParams { count: n as u32, seed, ..Default::default() };
            for _ in 0..4 {
                self.record(&mut enc, Kernel::RngFill, &p, &[&out])?;
            }
            self.submit_wait(enc)?;
            seed += 1;
        }
        Ok(())
    }

    pub fn encoder(&self) -> wgpu::CommandEncoder {
        self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None })
    }

    /// Submits and waits, with an upper bound on the wait.
    pub fn submit_wait(&self, encoder: wgpu::CommandEncoder) -> Result<()> {
        let idx = self.queue.submit([encoder.finish()]);
        self.device
            .poll(wgpu::PollType::Wait { submission_index: Some(idx), timeout: Some(SUBMIT_TIMEOUT) })
            .map_err(|e| anyhow!("GPU did not finish: {e}"))?;
        Ok(())
    }

    /// Copies the first `n` elements of `buf` back to the host.
    pub fn read<T: Pod>(&self, buf: &wgpu::Buffer, n: usize) -> Result<Vec<T>> {
        let size = (n * std::mem::size_of::<T>()) as u64;
        if size == 0 {
            return Ok(Vec::new());
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.encoder();
        enc.copy_buffer_to_buffer(buf, 0, &staging, 0, size);
        self.submit_wait(enc)?;
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(SUBMIT_TIMEOUT) })
            .map_err(|e| anyhow!("GPU did not finish: {e}"))?;
        rx.recv()?.map_err(|e| anyhow!("cannot read GPU buffer: {e}"))?;
        let view = slice.get_mapped_range().map_err(|e| anyhow!("cannot map GPU buffer: {e:?}"))?;
        let out = bytemuck::cast_slice::<u8, T>(&view).to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// One dispatch: a kernel, its parameters and its buffers (bindings 1..).
#[derive(Clone)]
pub struct Pass<'a> {
    pub kernel: Kernel,
    pub params: FrameParams,
    pub buffers: Vec<&'a wgpu::Buffer>,
}

/// Repeated measurements of a sequence of dispatches, in milliseconds: wall time, GPU time of
/// the whole sequence, and GPU time of each pass (empty without timestamp queries).
#[derive(Clone, Debug, Default)]
pub struct Timing {
    pub wall_ms: Vec<f64>,
    pub gpu_ms: Vec<f64>,
    pub parts_ms: Vec<Vec<f64>>,
}

pub fn median(v: &[f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    Some(s[s.len() / 2])
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}
