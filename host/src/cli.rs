//! The `kdray` command line.
use crate::gpu::{self, tracer::GpuTracer, Gpu};
use crate::image_out::{compare, write_png};
use crate::kdtree::{self, BuildOptions, KdTreeData};
use crate::trace::Accel;
use crate::{scene, CpuTracer, Tracer};
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
pub enum DeviceArg {
    Gpu,
    Cpu,
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
}

impl BuildArgs {
    pub fn options(&self) -> Result<BuildOptions> {
        if !(self.kt > 0.0 && self.ki > 0.0 && self.empty_bonus > 0.0 && self.empty_bonus <= 1.0) {
            bail!("--kt and --ki must be positive and --empty-bonus in (0, 1]");
        }
        Ok(BuildOptions {
            k_t: self.kt,
            k_i: self.ki,
            empty_bonus: self.empty_bonus,
            max_depth: self.max_depth,
            leaf_size: self.leaf_size,
            ..Default::default()
        })
    }
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a scene to PNG: primary rays, one shadow ray per pixel, Lambert shading.
    Render {
        /// `cornell` (built in), a .obj file or a .toml scene file.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// Where to trace; default: the GPU, or the CPU with a warning if there is no GPU.
        #[arg(long, value_enum)]
        device: Option<DeviceArg>,
        /// Image width and height in pixels.
        #[arg(long, default_value_t = 512)]
        size: u32,
        /// Radiance mapped to white.
        #[arg(long, default_value_t = 1.0)]
        exposure: f32,
        /// Random stream of the light samples.
        #[arg(long, default_value_t = 1)]
        seed: u32,
        #[arg(long, short, default_value = "render.png")]
        out: PathBuf,
        /// Also render on the other device, write `<out>-cpu.png`, and report how the two differ.
        #[arg(long)]
        compare: bool,
        /// How hits are found: brute (oracle), stack, restart, pushdown, shortstack[:N].
        #[arg(long, default_value = "shortstack")]
        traversal: String,
        /// Mirror reflections followed per pixel (only scenes with mirrors trace them).
        #[arg(long, default_value_t = 4)]
        bounces: u32,
        #[command(flatten)]
        build: BuildArgs,
    },
    /// List the GPU adapters wgpu sees.
    Adapters,
    /// Benchmarks; writes CSV and Markdown tables into --out.
    Bench {
        /// `traversals`: every kd traversal, primary and shadow rays, per scene.
        suite: String,
        /// Scenes (repeatable): `cornell`, a .obj or a .toml file.
        #[arg(long, default_values_t = vec!["cornell".to_string()])]
        scene: Vec<String>,
        #[arg(long, value_enum, default_value = "gpu")]
        device: DeviceArg,
        #[arg(long, default_value_t = 1024)]
        size: u32,
        /// Timed repetitions after one warm-up.
        #[arg(long, default_value_t = 5)]
        reps: usize,
        #[arg(long, default_value = "bench-out")]
        out: PathBuf,
        #[command(flatten)]
        build: BuildArgs,
    },
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
        Command::Adapters => {
            let list = gpu::adapters();
            if list.is_empty() {
                bail!("no GPU adapter: wgpu found no Vulkan device");
            }
            for a in list {
                println!("{}", gpu::describe(&a.get_info()));
            }
            Ok(())
        }
        Command::Bench { suite, scene: scenes, device, size, reps, out, build } => {
            let opts = build.options()?;
            if suite != "traversals" {
                bail!("unknown bench suite '{suite}' (known: traversals)");
            }
            if size == 0 || size > 4096 || reps == 0 {
                bail!("--size must be 1..=4096 and --reps at least 1");
            }
            let gpu = match device {
                DeviceArg::Gpu => Some(Gpu::new()?),
                DeviceArg::Cpu => None,
            };
            let dev = crate::bench::device_line(gpu.as_ref());
            println!("device: {dev}");
            let mut rows = Vec::new();
            for spec in &scenes {
                let scene = scene::load(spec)?;
                println!("scene {}: {} triangles", scene.name, scene.triangles.len());
                let tree = build_tree(&scene, &opts);
                let pb = progress(&scene.name);
                rows.extend(crate::bench::traversals(&scene, &tree, size, gpu.as_ref(), reps, &pb)?);
                pb.finish_and_clear();
            }
            let name = format!("traversals-{}", if gpu.is_some() { "gpu" } else { "cpu" });
            crate::bench::write_tables(&out, &name, &dev, &rows)?;
            print!("{}", std::fs::read_to_string(out.join(&name).with_extension("md"))?);
            println!("wrote {}.csv and .md", out.join(&name).display());
            Ok(())
        }
        Command::Render { scene, device, size, exposure, seed, out, compare: cmp, traversal, bounces, build } => {
            let opts = build.options()?;
            let accel = Accel::parse(&traversal)?;
            if bounces > 64 {
                bail!("--bounces must be at most 64, got {bounces}");
            }
            if size == 0 || size > 16384 {
                bail!("--size must be between 1 and 16384, got {size}");
            }
            if !(exposure.is_finite() && exposure > 0.0) {
                bail!("--exposure must be a positive number");
            }
            let scene = scene::load(&scene)?;
            println!(
                "scene {}: {} triangles ({} degenerate dropped), {} materials, {} lights",
                scene.name,
                scene.triangles.len(),
                scene.dropped_degenerate,
                scene.materials.len(),
                scene.lights().len()
            );
            let tree = match accel {
                Accel::Brute => None,
                Accel::Kd(_) => Some(build_tree(&scene, &opts)),
            };
            let tree = tree.as_ref();
            let cam = scene.camera.to_pod(size, size);
            let gpu = match device {
                Some(DeviceArg::Cpu) => None,
                Some(DeviceArg::Gpu) => Some(Gpu::new()?),
                None => match Gpu::new() {
                    Ok(g) => Some(g),
                    Err(e) => {
                        eprintln!("warning: {e:#}; rendering on the CPU");
                        None
                    }
                },
            };
            let cpu = CpuTracer::new(&scene, tree);
            let gpu_tracer = match &gpu {
                Some(g) => Some(GpuTracer::new(g, &scene, tree)?),
                None => None,
            };
            let primary: &dyn Tracer = match &gpu_tracer {
                Some(t) => t,
                None => &cpu,
            };
            let render = |t: &dyn Tracer| -> Result<crate::RenderOutput> {
                println!("device: {}, traversal {}", t.device_name(), accel.name());
                let pb = progress("render");
                let start = Instant::now();
                let r = t.render(accel, &cam, seed, bounces, &pb)?;
                pb.finish_and_clear();
                let secs = start.elapsed().as_secs_f64();
                println!(
                    "rendered {size}x{size} in {:.3} s ({:.2} M pixels/s, all passes and transfers)",
                    secs,
                    (size * size) as f64 / secs / 1e6
                );
                Ok(r)
            };
            let img = render(primary)?;
            write_png(&img, exposure, &out)?;
            println!("wrote {}", out.display());
            if cmp {
                if gpu_tracer.is_none() {
                    bail!("--compare needs a GPU adapter");
                }
                let other = render(&cpu)?;
                let stem = out.with_extension("");
                let cpu_path = PathBuf::from(format!("{}-cpu.png", stem.display()));
                write_png(&other, exposure, &cpu_path)?;
                println!("wrote {}", cpu_path.display());
                println!("GPU vs CPU: {}", compare(&img, &other, exposure));
            }
            Ok(())
        }
    }
}

/// Builds the kd-tree and prints what it cost.
pub fn build_tree(scene: &scene::Scene, opts: &BuildOptions) -> KdTreeData {
    let t = kdtree::build(&scene.triangles, opts);
    let s = &t.stats;
    println!(
        "kd-tree: {} nodes, {} leaves ({} empty), {:.2} triangles per leaf, depth {} (limit {}), SAH cost {:.1}, {:.2} MiB, built in {:.3} s",
        s.nodes,
        s.leaves,
        s.empty_leaves,
        s.avg_leaf_size,
        s.max_depth,
        s.depth_limit,
        s.sah_cost,
        s.bytes as f64 / 1048576.0,
        s.build_seconds
    );
    t
}
