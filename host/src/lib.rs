//! kdray: kd-tree ray casting and photon mapping written once in Rust (`kdray-shared`), run
//! natively on the CPU and as SPIR-V compute kernels on any Vulkan GPU through wgpu.
pub mod bench;
pub mod cli;
pub mod cpu;
pub mod gpu;
pub mod image_out;
pub mod kdtree;
pub mod scene;
pub mod trace;

pub use cpu::CpuTracer;
pub use gpu::tracer::GpuTracer;
pub use gpu::Gpu;
pub use scene::Scene;
pub use trace::{Accel, RenderOutput, Tracer};
