//! The `kdray` command line.
use kdray::accel::Accel;
use kdray::gpu::{self, Gpu};
use kdray::image_out::{compare, write_png};
use kdray::integrator::path::{self, PathOptions};
use kdray::integrator::SamplerKind;
use kdray::integrator::photon::{self as pm, FinalGather, IndexKind, PhotonMap, PhotonOptions};
use kdray::kdtree::{self, BuildOptions, KdTreeData};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Runtime, Tracer};
use anyhow::{bail, Result};
use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "kdray", version, about = "kd-tree ray casting on CPU and Vulkan GPUs")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum RayOrderArg {
    Scanline,
    Tiles,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrimaryArg {
    /// Camera rays traced like every other ray.
    Trace,
    /// Primary hits by rasterisation (Horn et al.): the GPU draws the triangles' ids with a
    /// depth test, each pixel's candidate is checked by the watertight test and the ray traced
    /// where it fails (the BVH or the kd-tree's full stack); every pixel of a sample is
    /// sampled at the same point of its area.
    Raster,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum IntegratorArg {
    /// One shadow ray per pixel centre (no indirect light).
    Direct,
    /// Path tracing with next-event estimation (the reference).
    Path,
    /// Progressive photon mapping: direct light by shadow rays, indirect from photons.
    Photon,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum IndexArg {
    /// Hashed uniform grid of cell size 2r.
    Grid,
    /// The geometry kd-tree's leaves subdivided to about 2r (Frolov & Ignatenko).
    Kd,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum SamplerArg {
    /// Each pixel's own Owen-scrambled Sobol sequence, over samples and passes.
    Sobol,
    /// Independent random numbers.
    Independent,
}

impl SamplerArg {
    fn kind(self) -> SamplerKind {
        match self {
            SamplerArg::Sobol => SamplerKind::Sobol,
            SamplerArg::Independent => SamplerKind::Independent,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum FinalGatherArg {
    Off,
    Edges,
    All,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum FilterArg {
    Constant,
    Cone,
    Epanechnikov,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PipelineArg {
    Monolithic,
    Decomposed,
}

/// `gpu` (the best adapter), `gpu:N` (adapter N of `kdray adapters`) or `cpu`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DeviceArg {
    Gpu(usize),
    Cpu,
}

impl std::str::FromStr for DeviceArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cpu" => Ok(DeviceArg::Cpu),
            "gpu" => Ok(DeviceArg::Gpu(0)),
            s => match s.strip_prefix("gpu:").map(str::parse::<usize>) {
                Some(Ok(n)) => Ok(DeviceArg::Gpu(n)),
                _ => Err(format!("unknown device '{s}': use gpu, gpu:N (see `kdray adapters`) or cpu")),
            },
        }
    }
}

/// `--devices`: `all` (every GPU adapter that can run the kernels) or a comma-separated list
/// of `gpu`, `gpu:N`, `N` (adapter N) and `cpu` (the native runtime).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DevicesArg {
    All,
    List(Vec<DeviceArg>),
}

impl std::str::FromStr for DevicesArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "all" {
            return Ok(DevicesArg::All);
        }
        let list = s
            .split(',')
            .map(|d| match d.trim().parse::<usize>() {
                Ok(n) => Ok(DeviceArg::Gpu(n)),
                Err(_) => d.trim().parse::<DeviceArg>().map_err(|_| format!("unknown device '{d}' in --devices: use all, or a list of gpu, gpu:N, N and cpu")),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(DevicesArg::List(list))
    }
}

/// Opens the runtimes of `--devices`, in the order given.
fn open_devices(d: &DevicesArg) -> Result<Vec<Box<dyn Runtime>>> {
    Ok(match d {
        DevicesArg::All => Gpu::open_all()?.into_iter().map(|g| Box::new(g) as Box<dyn Runtime>).collect(),
        DevicesArg::List(l) => l
            .iter()
            .map(|d| {
                Ok(match d {
                    DeviceArg::Gpu(i) => Box::new(Gpu::open(*i)?) as Box<dyn Runtime>,
                    DeviceArg::Cpu => Box::new(kdray::runtime::Cpu::new()),
                })
            })
            .collect::<Result<_>>()?,
    })
}

/// kd-tree build options (SAH constants and limits).
#[derive(clap::Args, Clone, Debug)]
pub struct BuildArgs {
    /// SAH cost of a traversal step.
    #[arg(long, default_value_t = 15.0)]
    pub kt: f32,
    /// SAH cost of a triangle test.
    #[arg(long, default_value_t = 20.0)]
    pub ki: f32,
    /// SAH cost factor of a split that cuts off empty space.
    #[arg(long, default_value_t = 0.8)]
    pub empty_bonus: f32,
    /// Maximum tree depth (default 8 + 1.3·log2 N).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Nodes with at most this many triangles become leaves.
    #[arg(long, default_value_t = 1)]
    pub leaf_size: usize,
    /// Most triangle references in the kd-tree's leaves per triangle (at least 1; splits that
    /// clip triangles into both children duplicate them).
    #[arg(long, default_value_t = kdray::kdtree::DEFAULT_MAX_DUPLICATION)]
    pub max_duplication: f32,
    /// Nodes with more triangles than this choose their split plane by binned SAH; the exact
    /// sweep below.
    #[arg(long, default_value_t = kdray::kdtree::DEFAULT_BINNED_ABOVE)]
    pub binned_above: usize,
    /// The exact SAH sweep at every node (Wald & Havran's build; slower, not better).
    #[arg(long)]
    pub exact_sah: bool,
    /// Who builds the BVH: `host` (binned SAH on the CPU's cores) or `kernels` (the linear BVH
    /// of `kdray::lbvh` on the render's first device: milliseconds on a GPU, a tree of higher
    /// SAH cost).
    #[arg(long, value_enum, default_value_t = BvhBuildArg::Host)]
    pub bvh_build: BvhBuildArg,
}

/// `--bvh-build`.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BvhBuildArg {
    /// Binned SAH on the host (`kdray::bvh`).
    Host,
    /// The linear BVH by the kernels (`kdray::lbvh`) on the device.
    Kernels,
}

impl BuildArgs {
    pub fn options(&self) -> Result<BuildOptions> {
        if !(self.kt > 0.0 && self.ki > 0.0 && self.empty_bonus > 0.0 && self.empty_bonus <= 1.0) {
            bail!("--kt and --ki must be positive and --empty-bonus in (0, 1]");
        }
        if !(self.max_duplication >= 1.0) {
            bail!("--max-duplication must be at least 1");
        }
        Ok(BuildOptions {
            k_t: self.kt,
            k_i: self.ki,
            empty_bonus: self.empty_bonus,
            max_depth: self.max_depth,
            leaf_size: self.leaf_size,
            max_duplication: self.max_duplication,
            binned_above: (!self.exact_sah).then_some(self.binned_above),
            ..Default::default()
        })
    }
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a scene to PNG (and PFM, linear HDR): progressive photon mapping by default,
    /// path tracing or direct lighting on request.
    Render {
        /// A built-in scene (`cornell`, `cornell-glass`, … — see the README), a .obj file or a
        /// .toml scene file.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// Where to trace: gpu, gpu:N (adapter N of `kdray adapters`) or cpu; default: the
        /// best GPU, or the CPU with a warning if there is no GPU.
        #[arg(long)]
        device: Option<DeviceArg>,
        /// Render on several devices at once: `all` (every GPU adapter) or a list such as
        /// `0,1` or `gpu:0,cpu` (an adapter listed twice is opened twice). Photon passes and
        /// path samples are handed out in units (a faster device takes more) and summed in
        /// unit order: the image is the same, bit for bit, as on one device of the kind. A
        /// device that fails hands its units to the others.
        #[arg(long, conflicts_with_all = ["device", "compare"])]
        devices: Option<DevicesArg>,
        /// One photon render over the ranks of an MPI job (`mpirun -n N kdray render --mpi …`;
        /// built with `--features mpi`): rank r renders unit r of the units of passes, then
        /// every N-th, on its devices; the ranks' sums are added up to rank 0, which writes
        /// the image (the same, bit for bit, as one process's).
        #[arg(long)]
        mpi: bool,
        /// The unit of work: passes (photon; default: at least 4, at most 16 units a render)
        /// or samples per pixel (path; default 16) a device renders into a film of its own before it is read back and added to
        /// the image. Part of the render: another unit sums in another order (the last bits).
        #[arg(long)]
        unit: Option<u32>,
        /// Image width and height in pixels.
        #[arg(long, default_value_t = 512)]
        size: u32,
        /// Radiance mapped to white.
        #[arg(long, default_value_t = 1.0)]
        exposure: f32,
        /// Random stream of the light samples.
        #[arg(long, default_value_t = 1)]
        seed: u32,
        /// Where the eye paths' numbers come from (path, photon, direct): `sobol` (each
        /// pixel's scrambled Sobol sequence, continued over samples and passes: stratified)
        /// or `independent` (plain Monte Carlo).
        #[arg(long, value_enum, default_value = "sobol")]
        sampler: SamplerArg,
        /// Where the photons' numbers come from (photon): `independent` (the default: as
        /// accurate per pass as Sobol's and cheaper, docs/gpu-runs/2026-12-03-photon-direct-nee-h200.md)
        /// or `sobol` (the render's scrambled Sobol sequences over the coherent groups'
        /// emission and the photons' bounces, continued over the passes).
        #[arg(long, value_enum, default_value = "independent")]
        photon_sampler: SamplerArg,
        #[arg(long, short, default_value = "render.png")]
        out: PathBuf,
        /// Also render on the other device, write `<out>-cpu.png`, and report how the two differ.
        #[arg(long)]
        compare: bool,
        /// How hits are found: bvh (compressed 8-wide BVH, the default), brute (oracle), or a
        /// kd-tree traversal: stack, restart, pushdown, shortstack[:N] (shortstack =
        /// shortstack:3, the default with --packets).
        #[arg(long)]
        traversal: Option<String>,
        /// Trace rays in packets (bvh: eight natively, on the GPU four rays per thread one by
        /// one; kd traversals: four, incoherent packets ray by ray).
        #[arg(long)]
        packets: bool,
        /// `monolithic` (one kernel per query) or `decomposed` (traverse → leaf lists →
        /// intersect, full-stack traversal, overflowing lists finished by the monolithic kernel).
        #[arg(long, value_enum, default_value = "monolithic")]
        pipeline: PipelineArg,
        /// Pixel order of the rays: `scanline`, or `tiles` (8×8 tiles, Morton order inside:
        /// neighbouring rays run together). Same image either way. Default: tiles for the
        /// photon integrator (its gathers read fewer cells per subgroup: 256 passes 7 % faster
        /// on an H200), scanline otherwise.
        #[arg(long, value_enum)]
        ray_order: Option<RayOrderArg>,
        /// How the camera rays' first hits are found (direct and path integrators): `trace`,
        /// or `raster` (rasterised, then the paths continue from the hits; natively, where
        /// there is no rasteriser, traced).
        #[arg(long, value_enum, default_value = "trace")]
        primary: PrimaryArg,
        /// Leaf-list entries per ray of the decomposed pipeline.
        #[arg(long, default_value_t = kdray::accel::DEFAULT_LEAF_CAPACITY)]
        leaf_capacity: u32,
        /// Bounces of eye paths (specular ones for direct and photon; all for path); default
        /// 4 (direct), 16 (photon), 32 (path).
        #[arg(long)]
        bounces: Option<u32>,
        /// How light is computed.
        #[arg(long, value_enum, default_value = "photon")]
        integrator: IntegratorArg,
        /// Samples per pixel (path; default 64), or eye samples per pixel and pass (photon;
        /// default 4).
        #[arg(long)]
        spp: Option<u32>,
        /// Photons per pass (photon); default 2^20 on a GPU, 2^18 on the CPU.
        #[arg(long)]
        photons: Option<u32>,
        /// Passes (photon): each traces new photons and `--spp` eye samples per pixel.
        #[arg(long, default_value_t = 16)]
        passes: u32,
        /// Stop after the pass that ends past this many seconds (photon).
        #[arg(long)]
        time_limit: Option<f64>,
        /// The first pass's gather radius in scene units (photon); default: about 85 photons
        /// per gather.
        #[arg(long)]
        radius: Option<f32>,
        /// Radius reduction per pass, r²ᵢ₊₁ = r²ᵢ (i + α)/(i + 1) (photon); 1 keeps it fixed.
        #[arg(long, default_value_t = 2.0 / 3.0)]
        alpha: f32,
        /// The photon index (photon).
        #[arg(long, value_enum, default_value = "grid")]
        photon_index: IndexArg,
        /// Photon emission (photon): `coherent` (groups of 32 sharing one sample, lattice
        /// offsets scaled by 0.1), `coherent:S` (offsets scaled by S in (0, 1]) or
        /// `independent`.
        #[arg(long, default_value = "coherent")]
        emission: String,
        /// Direct light from the photon map too (the paper's way), not by shadow rays.
        #[arg(long)]
        photon_direct: bool,
        /// Final gathering (photon): one diffuse bounce from an eye path's first diffuse point,
        /// the photon map read at the second (direct light by shadow rays and caustics from the
        /// caustic map at the first) — `edges`: only where the first point is within the
        /// radius of a corner or edge (photons of other orientations in its disc), `all`:
        /// everywhere, `off`: the photon map read at the first point (direct visualisation).
        /// Default: edges, or off with `--photon-direct` (the paper's way).
        #[arg(long, value_enum)]
        final_gather: Option<FinalGatherArg>,
        /// Gather kernel (photon).
        #[arg(long, value_enum, default_value = "constant")]
        filter: FilterArg,
        /// The hashed photon grid's cells along x a gather visits (photon): 3 (cells of the
        /// radius), 2 (cells of twice the radius), or 5, 7 or 9 (cells of the radius across x,
        /// of a half, a third or a quarter of it along x).
        #[arg(long, default_value_t = 7)]
        grid_window: u32,
        /// A pass per bounce and query (camera or emission, then closest-hit query, shading,
        /// shadow query per bounce: the wavefront schedule) instead of whole photon and eye
        /// paths in one kernel each (path, photon; the same paths).
        #[arg(long)]
        split_passes: bool,
        /// Threads of the whole-path photon kernel (photon): each traces its share of a
        /// pass's photons, starting the next as soon as one is absorbed; 0: one photon per
        /// thread.
        #[arg(long, default_value_t = pm::PHOTON_THREADS)]
        photon_threads: u32,
        /// With `--final-gather edges`: the second gather over every eye path instead of a
        /// list of the points near edges (the same image; for measuring the difference).
        #[arg(long, hide = true)]
        gather_every_path: bool,
        /// Levels of the final gather near edges (photon, `--final-gather edges`): a point it
        /// reaches near an edge again bounces once more, up to this many bounces.
        #[arg(long, default_value_t = 2)]
        final_gather_levels: u32,
        #[command(flatten)]
        build: BuildArgs,
    },
    /// Write the scene for another renderer: `--mitsuba DIR` (Mitsuba 3 XML + PLY meshes).
    Export {
        #[arg(long, default_value = "cornell")]
        scene: String,
        #[arg(long)]
        mitsuba: PathBuf,
        /// Image width and height in pixels.
        #[arg(long, default_value_t = 512)]
        size: u32,
        /// Mitsuba's max_depth (path vertices; 65 as in the anchor).
        #[arg(long, default_value_t = 65)]
        max_depth: u32,
    },
    /// Error-vs-time plots from a `bench photons` error table (and Mitsuba's, if given).
    PlotPhotons {
        table: PathBuf,
        #[arg(long)]
        mitsuba: Option<PathBuf>,
        #[arg(long, default_value = ".")]
        out: PathBuf,
        /// The device named in the titles.
        #[arg(long, default_value = "")]
        device: String,
    },
    /// Error of an image against a reference (PFM files): RMSE of the displayed images
    /// (radiance clamped at 1) divided by the reference's mean, and relMSE.
    Error {
        image: PathBuf,
        reference: PathBuf,
    },
    /// List the GPU adapters wgpu sees.
    Adapters {
        /// Also compile every kernel on the best adapter, naming each before its compilation.
        #[arg(long)]
        compile: bool,
        /// With --compile: only the entry points whose names contain one of these.
        only: Vec<String>,
    },
    /// Benchmarks: writes CSV and Markdown tables and PNG plots into --out.
    Bench {
        /// horn, bounces, scaling, breakdown, build, visits, order, traversals, photons,
        /// devices (with --devices), or all.
        suite: String,
        /// Scenes (repeatable) instead of the suite's own: built-in names, .obj or .toml files.
        #[arg(long)]
        scene: Vec<String>,
        /// gpu, gpu:N or cpu.
        #[arg(long, default_value = "gpu")]
        device: DeviceArg,
        /// `bench devices`: the devices to share the work over (as `render --devices`); the
        /// first alone is the baseline.
        #[arg(long)]
        devices: Option<DevicesArg>,
        /// Image width and height of the ray batches.
        #[arg(long, default_value_t = 1024)]
        size: u32,
        /// Timed repetitions after one warm-up (at least 5 for published numbers).
        #[arg(long, default_value_t = 5)]
        reps: usize,
        #[arg(long, default_value = "bench-out")]
        out: PathBuf,
        /// Also write every ray batch measured (.npy) with this project's answers and the
        /// scene as OBJ into this folder (format: README, "Same rays for other systems").
        #[arg(long)]
        dump_rays: Option<PathBuf>,
        /// horn: a command run on the dumped rays (needs --dump-rays; the folder is appended as
        /// its last argument), e.g. Mitsuba's Embree: "python3 ../shared/peers/mitsuba_same_rays.py
        /// llvm_ad_rgb". Each line `SCENE-RAYS: peer=NAME rays=N Mrays/s=X same-answer=A/B` it
        /// prints becomes a row (method peer:NAME), and the table gains the fastest kdray row
        /// over it: the ratio measured in the same run on the same rays.
        #[arg(long)]
        peer: Option<String>,
        /// Largest K of chairs:K in the scaling suite (1, 4, …, 4096).
        #[arg(long, default_value_t = 1024)]
        max_chairs: u32,
        /// Only these rows of the horn suite (repeatable), by the method names of its tables:
        /// bvh, stack, restart, pushdown, shortstack:3, restart+packets, …
        #[arg(long)]
        method: Vec<String>,
        /// photons: threads of the whole-path photon kernel (as `render --photon-threads`).
        #[arg(long, default_value_t = pm::PHOTON_THREADS)]
        photon_threads: u32,
        #[command(flatten)]
        build: BuildArgs,
    },
}

/// A terminal progress bar for the library's integrators.
pub struct Bar(pub ProgressBar);

impl kdray::integrator::Progress for Bar {
    fn start(&self, total: u64) {
        self.0.set_length(total);
    }
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
    fn status(&self, text: &str) {
        self.0.set_message(text.to_string());
    }
}

fn progress(label: &str) -> ProgressBar {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{prefix:>8} [{bar:40}] {percent:>3}% {elapsed_precise}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_prefix(label.to_string());
    pb
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Export { scene, mitsuba, size, max_depth } => {
            if size == 0 || size > 16384 {
                bail!("--size must be between 1 and 16384, got {size}");
            }
            let s = scene::load(&scene)?;
            let p = scene::mitsuba::export(&s, &mitsuba, size, size, max_depth)?;
            println!("wrote {}", p.display());
            Ok(())
        }
        Command::PlotPhotons { table, mitsuba, out, device } => {
            for f in crate::bench::photons::plot_error_table(&table, mitsuba.as_deref(), &out, &device)? {
                println!("wrote {}", f.display());
            }
            Ok(())
        }
        Command::Error { image, reference } => {
            let (w, h, a) = kdray::image_out::read_pfm(&image)?;
            let (w2, h2, b) = kdray::image_out::read_pfm(&reference)?;
            if (w, h) != (w2, h2) {
                bail!("{} is {w}x{h} but {} is {w2}x{h2}", image.display(), reference.display());
            }
            let e = kdray::image_out::image_error(&a, &b);
            println!("relative RMSE {:.4} % (clamped at 1, / reference mean), relMSE {:.3e}, mean {:.5} vs {:.5}", e.rel_rmse * 100.0, e.rel_mse, e.mean, e.reference_mean);
            Ok(())
        }
        Command::Adapters { compile, only } => {
            let list = gpu::adapters();
            if list.is_empty() {
                bail!("no GPU adapter: wgpu found no Vulkan device");
            }
            for (i, a) in list.iter().enumerate() {
                println!("gpu:{i}  {}", gpu::describe(&a.get_info()));
            }
            if compile {
                let g = Gpu::new()?;
                for e in &kdray::runtime::module::module_info()?.entry_points {
                    if !only.is_empty() && !only.iter().any(|o| e.name.contains(o.as_str())) {
                        continue;
                    }
                    use std::io::Write as _;
                    print!("compiling {} ... ", kdray::runtime::module::short_name(&e.name));
                    std::io::stdout().flush()?;
                    let start = Instant::now();
                    g.compile(&e.name)?;
                    println!("{:.2} s", start.elapsed().as_secs_f64());
                }
            }
            Ok(())
        }
        Command::Bench { suite, scene: scenes, device, devices, size, reps, out, dump_rays, peer, max_chairs, method, photon_threads, build } => {
            if size == 0 || size > 4096 || reps == 0 {
                bail!("--size must be 1..=4096 and --reps at least 1");
            }
            if !(1..=4096).contains(&max_chairs) {
                bail!("--max-chairs must be 1..=4096");
            }
            if peer.is_some() && (suite != "horn" || dump_rays.is_none()) {
                bail!("--peer runs on the rays of bench horn: use it with the horn suite and --dump-rays DIR");
            }
            if suite != "all" && !crate::bench::SUITES.contains(&suite.as_str()) {
                bail!("unknown bench suite '{suite}' (known: {}, all)", crate::bench::SUITES.join(", "));
            }
            let several = match &devices {
                Some(d) => open_devices(d)?,
                None => Vec::new(),
            };
            let gpu = match device {
                // With --devices the other suites run natively (--devices is for `devices`).
                _ if devices.is_some() => None,
                DeviceArg::Gpu(i) => Some(Gpu::open(i)?),
                DeviceArg::Cpu => None,
            };
            println!("device: {}", crate::bench::device_line(gpu.as_ref()));
            if build.bvh_build != BvhBuildArg::Host {
                bail!("--bvh-build is render's: `bench build` measures both BVH builds, the other suites the host's");
            }
            let opts = crate::bench::Options {
                devices: several.iter().map(|b| b.as_ref()).collect(),
                gpu: gpu.as_ref(),
                scenes: (!scenes.is_empty()).then_some(scenes),
                size,
                reps,
                build: build.options()?,
                out,
                dump_rays,
                peer,
                max_chairs,
                methods: (!method.is_empty()).then_some(method),
                photon_threads,
                progress: progress("bench"),
            };
            let start = Instant::now();
            let files = crate::bench::run_suite(&suite, &opts)?;
            opts.progress.finish_and_clear();
            for f in files {
                println!("wrote {}", f.display());
            }
            println!("bench {suite}: {:.1} s", start.elapsed().as_secs_f64());
            Ok(())
        }
        Command::Render {
            scene,
            device,
            devices,
            unit,
            mpi,
            size,
            exposure,
            seed,
            out,
            compare: cmp,
            traversal,
            packets,
            pipeline,
            ray_order,
            primary,
            leaf_capacity,
            bounces,
            integrator,
            spp,
            photons,
            passes,
            time_limit,
            radius,
            alpha,
            photon_index,
            emission,
            photon_direct,
            final_gather,
            filter,
            grid_window,
            split_passes,
            photon_threads,
            gather_every_path,
            final_gather_levels,
            sampler,
            photon_sampler,
            build,
        } => {
            let opts = build.options()?;
            let accel = render_accel(traversal.as_deref(), packets, pipeline, leaf_capacity)?;
            let bounces = bounces.unwrap_or(match integrator {
                IntegratorArg::Direct => 4,
                IntegratorArg::Photon => 16,
                IntegratorArg::Path => 32,
            });
            if bounces > 64 {
                bail!("--bounces must be at most 64, got {bounces}");
            }
            let spp = spp.unwrap_or(if integrator == IntegratorArg::Path { 64 } else { 4 });
            if spp == 0 || spp > 1 << 20 {
                bail!("--spp must be between 1 and 2^20, got {spp}");
            }
            if passes == 0 {
                bail!("--passes must be at least 1");
            }
            if unit == Some(0) {
                bail!("--unit must be at least 1");
            }
            if let Some(l) = time_limit {
                if !(l.is_finite() && l > 0.0) {
                    bail!("--time-limit must be a positive number of seconds");
                }
            }
            let spread = parse_emission(&emission)?;
            if primary == PrimaryArg::Raster && integrator == IntegratorArg::Photon {
                bail!("--primary raster is for the direct and path integrators (--integrator direct|path)");
            }
            if size == 0 || size > 16384 {
                bail!("--size must be between 1 and 16384, got {size}");
            }
            if !(exposure.is_finite() && exposure > 0.0) {
                bail!("--exposure must be a positive number");
            }
            let job = open_job(mpi)?;
            if job.is_some() && integrator != IntegratorArg::Photon {
                bail!("--mpi renders photon mapping (--integrator photon)");
            }
            // Rank 0 of an MPI job speaks for it; the others say only what goes wrong.
            let loud = job.as_ref().is_none_or(|j| j.rank() == 0);
            let scene = scene::load(&scene)?;
            for w in &scene.warnings {
                eprintln!("warning: {w}");
            }
            if loud {
                println!(
                    "scene {}: {} triangles ({} degenerate dropped), {} materials, {} lights",
                    scene.name,
                    scene.triangles.len(),
                    scene.dropped_degenerate,
                    scene.materials.len(),
                    scene.lights().len()
                );
            }
            let needs_tree = accel.needs_tree() || (integrator == IntegratorArg::Photon && photon_index == IndexArg::Kd);
            let tree = if needs_tree { Some(build_tree(&scene, &opts)?) } else { None };
            let tree = tree.as_ref();
            let mut cam = scene.camera.to_pod(size, size);
            // The photon integrator traces tiles unless told otherwise (`PhotonOptions::tiles`).
            if ray_order == Some(RayOrderArg::Tiles) {
                cam.order = kdray_shared::ORDER_TILES;
            }
            // The photon render's options (photons a pass: fewer natively).
            let photon_options = |native: bool| PhotonOptions {
                photons: photons.unwrap_or(if native { 1 << 18 } else { 1 << 20 }),
                passes,
                time_limit,
                radius,
                alpha,
                index: if photon_index == IndexArg::Kd { IndexKind::Kd } else { IndexKind::Grid },
                spread,
                photon_direct,
                final_gather: match final_gather {
                    Some(FinalGatherArg::Off) => FinalGather::Off,
                    Some(FinalGatherArg::Edges) => FinalGather::Edges,
                    Some(FinalGatherArg::All) => FinalGather::All,
                    None if photon_direct => FinalGather::Off,
                    None => FinalGather::Edges,
                },
                filter: match filter {
                    FilterArg::Constant => kdray_shared::FILTER_CONSTANT,
                    FilterArg::Cone => kdray_shared::FILTER_CONE,
                    FilterArg::Epanechnikov => kdray_shared::FILTER_EPANECHNIKOV,
                },
                photon_bounces: 16,
                fused: !split_passes,
                photon_threads,
                list_points: !gather_every_path,
                edge_levels: final_gather_levels,
                grid_window,
                caustic_radius: 0.5,
                eye_bounces: bounces,
                eye_samples: spp,
                tiles: ray_order != Some(RayOrderArg::Scanline),
                seed,
                sampler: sampler.kind(),
                photon_sampler: photon_sampler.kind(),
                unit_passes: unit.unwrap_or(0),
                ..Default::default()
            };
            let opened = (|| -> Result<(Option<Gpu>, Vec<Box<dyn Runtime>>)> {
            let gpu = match device {
                _ if devices.is_some() => None,
                Some(DeviceArg::Cpu) => None,
                Some(DeviceArg::Gpu(i)) => Some(Gpu::open(i)?),
                None => match Gpu::new() {
                    // A software Vulkan driver runs the same kernels slower than the native
                    // runtime does (lavapipe: 40 s against 15 s for the default render on 2
                    // cores), so without --device it renders natively (--compare keeps it).
                    Ok(g) if g.is_software() && !cmp => {
                        eprintln!("note: the only Vulkan adapter is a CPU driver ({}); rendering with the native runtime (--device gpu uses the driver)", g.info.name);
                        None
                    }
                    Ok(g) => Some(g),
                    Err(e) => {
                        eprintln!("warning: {e:#}; rendering on the CPU");
                        None
                    }
                },
            };
            let several = match &devices {
                Some(d) => open_devices(d)?,
                None => Vec::new(),
            };
            Ok((gpu, several))
            })();
            // A rank of an MPI job that cannot open its devices still takes part (with its error).
            let (gpu, several) = match (opened, &job) {
                (Ok(o), _) => o,
                (Err(e), Some(j)) => {
                    j.reduce_photons(Err(kdray::Error::InvalidInput(format!("{e:#}"))), &photon_options(false), &cam)?;
                    return handed_over(j, e);
                }
                (Err(e), None) => return Err(e),
            };
            let rts: Vec<&dyn Runtime> = match &gpu {
                _ if !several.is_empty() => several.iter().map(|b| b.as_ref()).collect(),
                Some(g) => vec![g],
                None => vec![&NATIVE],
            };
            let bvh = if accel.needs_bvh() { Some(build_bvh(&scene, build.bvh_build, rts[0])?) } else { None };
            // The image, and why it holds fewer passes than asked (every device failed), if
            // it does.
            let reduced = std::cell::Cell::new(false);
            let render = |rts: &[&dyn Runtime]| -> Result<Option<(kdray::RenderOutput, Option<String>)>> {
                let tracers: Vec<Tracer> = rts
                    .iter()
                    .map(|&rt| {
                        let t = Tracer::new(rt, &scene, tree)?;
                        let t = match &bvh {
                            Some(b) => t.with_bvh(b)?,
                            None => t,
                        };
                        if loud {
                            println!("device: {}, traversal {}", t.device_name(), accel.name());
                            if let Some(s) = t.split_summary() {
                                println!("scene split across bindings: {s}");
                            }
                        }
                        Ok(t)
                    })
                    .collect::<Result<_>>()?;
                let ts: Vec<&Tracer> = tracers.iter().collect();
                let rt = rts[0];
                let start = Instant::now();
                let (r, interrupted) = match integrator {
                    IntegratorArg::Direct | IntegratorArg::Path => {
                        let mut o = if integrator == IntegratorArg::Direct {
                            PathOptions::direct(seed, bounces)
                        } else {
                            PathOptions::path(seed, bounces, spp)
                        };
                        o.fused = !split_passes;
                        o.sampler = sampler.kind();
                        o.raster = primary == PrimaryArg::Raster;
                        o.unit_samples = unit.unwrap_or(path::UNIT_SAMPLES);
                        let pb = progress("render");
                        let (r, s) = path::render_on(&ts, accel, &cam, &o, &Bar(pb.clone()))?;
                        pb.finish_and_clear();
                        for f in &s.failed {
                            eprintln!("warning: device {f}; its samples went to the other devices");
                        }
                        (r, s.interrupted)
                    }
                    IntegratorArg::Photon => {
                        let o = photon_options(rt.is_native());
                        let mut maps: Vec<PhotonMap> = ts.iter().map(|&t| PhotonMap::new(t, accel, tree, &scene, o.clone())).collect::<Result<_, kdray::Error>>()?;
                        let pb = if loud { progress_passes() } else { ProgressBar::hidden() };
                        let (r, s) = match &job {
                            Some(j) => {
                                reduced.set(true);
                                let part = pm::render_part(&mut maps, &cam, &Bar(pb.clone()), j.part());
                                pb.finish_and_clear();
                                if let Err(e) = &part {
                                    eprintln!("error: rank {}: {e}", j.rank());
                                }
                                match j.reduce_photons(part, &o, &cam)? {
                                    Some(whole) => (whole.image(), whole.stats),
                                    None => return Ok(None),
                                }
                            }
                            None => pm::render_on(&mut maps, &cam, &Bar(pb.clone()))?,
                        };
                        pb.finish_and_clear();
                        for f in &s.failed {
                            eprintln!("warning: device {f}; its passes went to the other devices");
                        }
                        let map = &maps[0];
                        println!(
                            "photon mapping: {} passes × {} photons, {:.1} M photons stored, radius {:.4} → {:.4}, {:.1} M photons/s",
                            s.passes,
                            map.o.photons,
                            s.stored as f64 / 1e6,
                            map.initial_radius(),
                            s.last_radius,
                            s.emitted as f64 / s.seconds / 1e6
                        );
                        (r, s.interrupted)
                    }
                };
                let secs = start.elapsed().as_secs_f64();
                println!(
                    "rendered {size}x{size} in {:.3} s ({:.2} M pixels/s, all passes and transfers)",
                    secs,
                    (size * size) as f64 / secs / 1e6
                );
                Ok(Some((r, interrupted)))
            };
            let (img, interrupted) = match (render(&rts), &job) {
                (Ok(Some(r)), _) => r,
                // Another rank of the MPI job writes the image.
                (Ok(None), _) => return Ok(()),
                (Err(e), Some(j)) if !reduced.get() => {
                    j.reduce_photons(Err(kdray::Error::InvalidInput(format!("{e:#}"))), &photon_options(false), &cam)?;
                    return handed_over(j, e);
                }
                (Err(e), _) => return Err(e),
            };
            write_png(&img, exposure, &out)?;
            println!("wrote {}", out.display());
            if integrator != IntegratorArg::Direct {
                let pfm = out.with_extension("pfm");
                kdray::image_out::write_pfm(&img, &pfm)?;
                println!("wrote {} (linear radiance)", pfm.display());
            }
            let exr = out.with_extension("exr");
            kdray::image_out::write_exr(&img, &scene, &cam, &exr)?;
            println!("wrote {} (linear radiance, depth, normal, albedo, triangle id)", exr.display());
            if cmp {
                if gpu.is_none() {
                    bail!("--compare needs a GPU adapter");
                }
                let (other, _) = render(&[&NATIVE])?.expect("not an MPI job");
                let stem = out.with_extension("");
                let cpu_path = PathBuf::from(format!("{}-cpu.png", stem.display()));
                write_png(&other, exposure, &cpu_path)?;
                println!("wrote {}", cpu_path.display());
                println!("GPU vs CPU: {}", compare(&img, &other, exposure));
            }
            if let Some(e) = interrupted {
                bail!("{e}");
            }
            Ok(())
        }
    }
}

/// The MPI job of `render --mpi` (feature `mpi`).
#[cfg(feature = "mpi")]
type Job = kdray::mpi::Job;

/// Without the feature there is no job (`--mpi` is refused).
#[cfg(not(feature = "mpi"))]
enum Job {}

#[cfg(not(feature = "mpi"))]
impl Job {
    fn rank(&self) -> u32 {
        match *self {}
    }
    fn part(&self) -> kdray::integrator::share::Part {
        match *self {}
    }
    fn reduce_photons(&self, _: kdray::Result<pm::PhotonPart>, _: &PhotonOptions, _: &kdray_shared::Camera) -> kdray::Result<Option<pm::PhotonPart>> {
        match *self {}
    }
}

/// How a rank ends that handed its error `e` to the reduction: rank 0 fails with it; another
/// rank says so and ends successfully, as rank 0 reports the failure and exits non-zero once it
/// has written the image of the other ranks' units (`mpirun` aborts the whole job when a rank
/// exits non-zero, which could kill rank 0 before that: the passes done would be lost).
fn handed_over(j: &Job, e: anyhow::Error) -> Result<()> {
    if j.rank() == 0 {
        return Err(e);
    }
    eprintln!("error: rank {}: {e:#} (rank 0 reports it and writes the other ranks' image)", j.rank());
    Ok(())
}

/// The MPI job, with `--mpi`.
fn open_job(mpi: bool) -> Result<Option<Job>> {
    if !mpi {
        return Ok(None);
    }
    #[cfg(feature = "mpi")]
    return Ok(Some(kdray::mpi::Job::init()?));
    #[cfg(not(feature = "mpi"))]
    bail!("--mpi: this kdray was built without MPI (cargo build --release --features mpi, with Open MPI and libclang installed: scripts/setup.sh --mpi)")
}

/// The spread of `--emission`: 0 for independent photons.
fn parse_emission(s: &str) -> Result<f32> {
    match s {
        "independent" => Ok(0.0),
        "coherent" => Ok(kdray::integrator::photon::COHERENT_SPREAD),
        s => match s.strip_prefix("coherent:").map(str::parse::<f32>) {
            Some(Ok(v)) if v > 0.0 && v <= 1.0 => Ok(v),
            _ => bail!("--emission must be independent, coherent or coherent:S with S in (0, 1], got '{s}'"),
        },
    }
}

fn progress_passes() -> ProgressBar {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{prefix:>8} [{bar:40}] pass {pos}/{len} {elapsed_precise} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_prefix("photons");
    pb
}

/// The hit-finding method of `render` from its options.
fn render_accel(traversal: Option<&str>, packets: bool, pipeline: PipelineArg, leaf_capacity: u32) -> Result<Accel> {
    match pipeline {
        PipelineArg::Decomposed => {
            if traversal.is_some() || packets {
                bail!("--pipeline decomposed traverses with the full stack, one ray per thread: drop --traversal and --packets");
            }
            Ok(Accel::parse(&format!("decomposed:{leaf_capacity}"))?)
        }
        PipelineArg::Monolithic => {
            // The BVH by default (on the H200 1.5-3.4x the kd kernels' rays, the photon-mapped
            // Cornell box in half the time; natively no slower); packets are the kd-tree's.
            let accel = Accel::parse(traversal.unwrap_or(if packets { "shortstack" } else { "bvh" }))?;
            if !packets {
                return Ok(accel);
            }
            accel.with_packets().ok_or_else(|| anyhow::anyhow!("--packets applies to bvh and the kd traversals, not '{}'", accel.name()))
        }
    }
}

/// Builds the compressed wide BVH (on the host, or by the kernels on `rt`) and prints what it
/// cost.
pub fn build_bvh(scene: &scene::Scene, how: BvhBuildArg, rt: &dyn Runtime) -> Result<kdray::bvh::BvhData> {
    let start = Instant::now();
    let (b, by) = match how {
        BvhBuildArg::Host => (kdray::bvh::try_build(&scene.triangles)?, "the host's binned SAH".to_string()),
        BvhBuildArg::Kernels => {
            let l = kdray::lbvh::build_on(rt, &scene.triangles)?;
            let by = format!("the kernels' linear build on {} ({:.1} ms of it on the device)", rt.name(), l.build_s * 1e3);
            (l.bvh, by)
        }
    };
    println!(
        "BVH: {} nodes of 8, {} leaves, depth {}, SAH cost {:.1}, {:.2} MiB, built in {:.3} s by {by}",
        b.nodes.len(),
        b.leaves,
        b.depth,
        b.sah_cost,
        b.bytes() as f64 / 1048576.0,
        start.elapsed().as_secs_f64()
    );
    Ok(b)
}

/// Builds the kd-tree and prints what it cost.
pub fn build_tree(scene: &scene::Scene, opts: &BuildOptions) -> Result<KdTreeData> {
    let t = kdtree::try_build(&scene.triangles, opts)?;
    let s = &t.stats;
    println!(
        "kd-tree: {} nodes, {} leaves ({} empty), {:.2} triangles per leaf, {:.2} references per triangle, depth {} (limit {}), SAH cost {:.1}, {:.2} MiB, built in {:.3} s",
        s.nodes,
        s.leaves,
        s.empty_leaves,
        s.avg_leaf_size,
        s.references as f64 / s.triangles.max(1) as f64,
        s.max_depth,
        s.depth_limit,
        s.sah_cost,
        s.bytes as f64 / 1048576.0,
        s.build_seconds
    );
    Ok(t)
}
