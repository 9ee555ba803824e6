//! One source for CPU and GPU: everything here compiles natively and, through rust-gpu,
//! to SPIR-V. Buffer types are `#[repr(C)]` + `Pod` built from `f32`/`u32` arrays only, so the
//! byte layout is identical on both sides (no `Vec3` in buffers); the one exception, the BVH
//! node, is five `UVec4` at offsets that are multiples of 16, the same on both sides.
//!
//! ```
//! use kdray_shared::{brute, Ray, Triangle};
//! let tri = Triangle { v0: [0.0, 0.0, 0.0], v1: [1.0, 0.0, 0.0], v2: [0.0, 1.0, 0.0], material: 0, face: 7, _pad: 0 };
//! // Watertight: a ray through the triangle's edge or vertex never slips through a closed mesh.
//! let hit = brute::closest_hit(&Ray::new([0.25, 0.25, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY), &[tri]);
//! assert_eq!((hit.prim, hit.t), (0, 1.0));
//! assert_eq!((hit.b1, hit.b2), (0.25, 0.25)); // barycentrics of v1 and v2
//! ```
#![no_std]
#![warn(missing_docs)]
// Fused multiply-add and square root: `core::f32::math` (a nightly feature) in the shader build;
// on the host, multiply-adds are the FMA instruction inline where the build targets it
// (`math::fma`), else `libm::fmaf`, and square roots `libm::sqrtf` (SSE), all correctly rounded,
// so the crate builds on stable Rust everywhere but in the shader build.
#![cfg_attr(target_arch = "spirv", feature(core_float_math))]

pub mod aabb;
pub mod brute;
pub mod bvh;
pub mod camera;
pub mod kdtree;
pub mod kernel;
pub mod math;
pub mod parts;
pub mod photon;
pub mod pod;
pub mod query;
pub mod raster;
pub mod ray;
pub mod render;
pub mod rng;
pub mod sampler;
pub mod shade;
mod sizes;
pub mod sort;
pub mod stats;
pub mod trace;
pub mod triangle;

pub use pod::*;
pub use ray::Ray;
