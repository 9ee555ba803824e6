//! One source for CPU and GPU: everything here compiles natively and, through rust-gpu,
//! to SPIR-V. Buffer types are `#[repr(C)]` + `Pod` built from `f32`/`u32` arrays only, so the
//! byte layout is identical on both sides (no `Vec3` in buffers).
#![no_std]
#![feature(core_float_math)]

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
