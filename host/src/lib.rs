//! kdray: kd-tree ray casting and photon mapping written once in Rust (`kdray-shared`), run
//! natively on the CPU and as SPIR-V compute kernels on any Vulkan GPU through wgpu.
//!
//! Layers (docs/architecture.md): `runtime` (where passes run: `gpu::Gpu`, `runtime::Cpu`),
//! `kernels` (every kernel family declared once), `tracer` (closest/any-hit queries over an
//! acceleration structure), `integrator` (what a pixel computes, as schedules of passes).
pub mod accel;
pub mod error;
pub mod analysis;
pub mod gpu;
pub mod image_out;
pub mod integrator;
pub mod kdtree;
pub mod kernels;
pub mod runtime;
pub mod scene;
pub mod sort;
pub mod tracer;

pub use accel::Accel;
pub use error::{Error, Result};
pub use gpu::Gpu;
pub use integrator::RenderOutput;
pub use runtime::{Cpu, Runtime};
pub use scene::Scene;
pub use tracer::Tracer;
/// The `no_std` crate every kernel is written in (ray and hit layouts, traversals, shading).
pub use kdray_shared as shared;
pub use kdray_shared::{Hit, Ray};
