//! One source for CPU and GPU: everything here compiles natively and, through rust-gpu,
//! to SPIR-V. Buffer types are `#[repr(C)]` + `Pod` built from `f32`/`u32` arrays only, so the
//! byte layout is identical on both sides (no `Vec3` in buffers).
#![no_std]
// Fused multiply-add and square root: `core::f32::math` (a nightly feature) in the shader build,
// `libm` on the host (hardware FMA and SSE square root where the CPU has them, both correctly
// rounded), so the crate builds on stable Rust everywhere but in the shader build.
#![cfg_attr(target_arch = "spirv", feature(core_float_math))]

pub mod aabb;
pub mod brute;
pub mod camera;
pub mod kdtree;
pub mod kernel;
pub mod math;
pub mod photon;
pub mod pod;
pub mod query;
pub mod ray;
pub mod render;
pub mod rng;
pub mod shade;
mod sizes;
pub mod sort;
pub mod stats;
pub mod trace;
pub mod triangle;

pub use pod::*;
pub use ray::Ray;
