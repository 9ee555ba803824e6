//! kdray: ray casting (a compressed wide BVH, kd-tree traversals) and photon mapping written
//! once in Rust (`kdray-shared`), run
//! natively on the CPU and as SPIR-V compute kernels on any Vulkan GPU through wgpu. The
//! kernels come compiled (the committed SPIR-V in `kernels/`), so the library builds on stable
//! Rust.
//!
//! ```
//! use kdray::{kdtree, runtime::cpu::NATIVE, Accel, Gpu, Ray, Runtime, Scene, Tracer};
//!
//! // A mesh as arrays: a square of two triangles in the plane z = 0.
//! let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
//! let scene = Scene::from_mesh("square", &vertices, &[[0, 1, 2], [0, 2, 3]])?;
//! let tree = kdtree::try_build(&scene.triangles, &Default::default())?;
//! let rays = [
//!     Ray::new([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
//!     Ray::new([3.0, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
//! ];
//! // On the GPU when there is one, natively otherwise: the same kernels either way.
//! let gpu = Gpu::new().ok();
//! let rt: &dyn Runtime = match &gpu { Some(g) => g, None => &NATIVE };
//! let hits = Tracer::new(rt, &scene, Some(&tree))?.closest_hits(Accel::parse("shortstack")?, &rays)?;
//! assert_eq!((hits[0].prim, hits[0].t), (1, 2.0)); // the second triangle, 2 units away
//! assert!(!hits[1].is_hit());
//! # Ok::<(), kdray::Error>(())
//! ```
//!
//! Layers (docs/architecture.md): `runtime` (where passes run: `gpu::Gpu`, `runtime::Cpu`),
//! `kernels` (every kernel family declared once), `tracer` (closest/any-hit queries over an
//! acceleration structure), `integrator` (what a pixel computes, as schedules of passes:
//! direct light, path tracing, progressive photon mapping), `scene` (OBJ/MTL, TOML, built-in
//! and procedural scenes, meshes as arrays), `kdtree` (the SAH builder), `bvh` (the compressed
//! wide BVH's builder), `image_out` (PNG,
//! PFM, OpenEXR with AOVs), `files` (outputs written atomically), `error` (`kdray::Error`).
//! The command line and the benchmarks are the `kdray` binary (feature `cli`, on by default;
//! `default-features = false` leaves out its dependencies).
#![warn(missing_docs)]
pub mod accel;
pub mod error;
pub mod files;
pub mod analysis;
pub mod gpu;
pub mod image_out;
pub mod integrator;
pub mod bvh;
pub mod kdtree;
pub mod kernels;
pub mod lbvh;
#[cfg(feature = "mpi")]
pub mod mpi;
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
