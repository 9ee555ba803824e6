//! The host's view of the SPIR-V module built from `shader-crate/`: entry point names and the
//! binding list of each (binding 0 is always the read-only `FrameParams`). Keep in step with the
//! `#[spirv(...)]` attributes of the entry points.
use crate::trace::Accel;
use anyhow::{bail, Result};
use kdray_shared::kdtree::Algorithm;

#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    CameraRays,
    Closest(Accel),
    Any(Accel),
    PathStep,
    Accumulate,
    RngFill,
}

/// Short-stack sizes with GPU kernels (`trace_kernels!` in shader-crate).
pub const GPU_SHORT_STACKS: [u32; 5] = [1, 2, 3, 4, 8];

/// Every entry point of the module.
pub const ENTRY_POINTS: &[&str] = &[
    "camera_rays", "path_step", "accumulate", "rng_fill",
    "closest_brute", "any_brute", "closest_stack", "any_stack", "closest_restart", "any_restart",
    "closest_pushdown", "any_pushdown", "closest_shortstack1", "any_shortstack1",
    "closest_shortstack2", "any_shortstack2", "closest_shortstack3", "any_shortstack3",
    "closest_shortstack4", "any_shortstack4", "closest_shortstack8", "any_shortstack8",
];

fn accel_suffix(a: Accel) -> Result<&'static str> {
    Ok(match a {
        Accel::Brute => "brute",
        Accel::Kd(Algorithm::Stack) => "stack",
        Accel::Kd(Algorithm::Restart) => "restart",
        Accel::Kd(Algorithm::PushDown) => "pushdown",
        Accel::Kd(Algorithm::ShortStack(1)) => "shortstack1",
        Accel::Kd(Algorithm::ShortStack(2)) => "shortstack2",
        Accel::Kd(Algorithm::ShortStack(3)) => "shortstack3",
        Accel::Kd(Algorithm::ShortStack(4)) => "shortstack4",
        Accel::Kd(Algorithm::ShortStack(8)) => "shortstack8",
        Accel::Kd(Algorithm::ShortStack(n)) => {
            bail!("no GPU kernel for a short stack of {n}: built for {GPU_SHORT_STACKS:?} (the CPU runs 1..=8)")
        }
    })
}

impl Kernel {
    pub fn entry_point(self) -> Result<&'static str> {
        let name = match self {
            Kernel::CameraRays => "camera_rays",
            Kernel::PathStep => "path_step",
            Kernel::Accumulate => "accumulate",
            Kernel::RngFill => "rng_fill",
            Kernel::Closest(a) | Kernel::Any(a) => {
                let prefix = if matches!(self, Kernel::Closest(_)) { "closest_" } else { "any_" };
                let full = format!("{prefix}{}", accel_suffix(a)?);
                *ENTRY_POINTS.iter().find(|e| **e == full).expect("entry point listed")
            }
        };
        Ok(name)
    }

    /// `true` = read-only storage, `false` = read-write, for bindings 1.. of a kernel.
    pub fn bindings(self) -> &'static [bool] {
        match self {
            Kernel::CameraRays => &[false, false],
            Kernel::Closest(_) | Kernel::Any(_) => &[true, true, true, true, false],
            Kernel::PathStep => &[false, true, true, true, true, false, false, false],
            Kernel::Accumulate => &[true, true, false, false],
            Kernel::RngFill => &[false],
        }
    }
}

/// Threads per workgroup of every kernel (`#[spirv(compute(threads(64)))]`).
pub const WORKGROUP: u32 = 64;
