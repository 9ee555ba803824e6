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
    /// Decomposed pipeline: leaf lists, intersection over them (closest / any), fallback.
    TraverseLeaves,
    IntersectLeaves { closest: bool },
    Fallback { closest: bool },
}

/// Short-stack sizes with GPU kernels (`trace_kernels!` in shader-crate).
pub const GPU_SHORT_STACKS: [u32; 5] = [1, 2, 3, 4, 8];

/// Traversals with GPU packet kernels (`packet_kernels!`): Horn et al.'s rows.
pub const GPU_PACKETS: [Algorithm; 4] = [Algorithm::Stack, Algorithm::Restart, Algorithm::PushDown, Algorithm::ShortStack(3)];

/// Every entry point of the module.
pub const ENTRY_POINTS: &[&str] = &[
    "camera_rays", "path_step", "accumulate", "rng_fill",
    "closest_brute", "any_brute", "closest_stack", "any_stack", "closest_restart", "any_restart",
    "closest_pushdown", "any_pushdown", "closest_shortstack1", "any_shortstack1",
    "closest_shortstack2", "any_shortstack2", "closest_shortstack3", "any_shortstack3",
    "closest_shortstack4", "any_shortstack4", "closest_shortstack8", "any_shortstack8",
    "closest_packet_stack", "any_packet_stack", "closest_packet_restart", "any_packet_restart",
    "closest_packet_pushdown", "any_packet_pushdown", "closest_packet_shortstack3", "any_packet_shortstack3",
    "traverse_leaves", "closest_leaves", "any_leaves", "closest_fallback", "any_fallback",
];

fn accel_suffix(a: Accel) -> Result<&'static str> {
    Ok(match a {
        Accel::Brute => "brute",
        Accel::Packet(Algorithm::Stack) => "packet_stack",
        Accel::Packet(Algorithm::Restart) => "packet_restart",
        Accel::Packet(Algorithm::PushDown) => "packet_pushdown",
        Accel::Packet(Algorithm::ShortStack(3)) => "packet_shortstack3",
        Accel::Decomposed { .. } => bail!("the decomposed pipeline has no single kernel (traverse_leaves, *_leaves, *_fallback)"),
        Accel::Packet(_) => bail!("no GPU packet kernel for {}: built for stack, restart, pushdown, shortstack:3", a.name()),
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
            Kernel::TraverseLeaves => "traverse_leaves",
            Kernel::IntersectLeaves { closest: true } => "closest_leaves",
            Kernel::IntersectLeaves { closest: false } => "any_leaves",
            Kernel::Fallback { closest: true } => "closest_fallback",
            Kernel::Fallback { closest: false } => "any_fallback",
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
            Kernel::TraverseLeaves => &[true, true, true, true, false, false],
            Kernel::IntersectLeaves { .. } => &[true, true, true, true, true, false, false],
            Kernel::Fallback { .. } => &[true, true, true, true, true, false],
        }
    }

    /// Every kernel of the module (one per entry point).
    pub fn all() -> Vec<Kernel> {
        let mut v = vec![Kernel::CameraRays, Kernel::PathStep, Kernel::Accumulate, Kernel::RngFill, Kernel::TraverseLeaves];
        for closest in [true, false] {
            v.push(Kernel::IntersectLeaves { closest });
            v.push(Kernel::Fallback { closest });
        }
        let accels = Accel::all().into_iter().chain(GPU_PACKETS.map(Accel::Packet));
        for a in accels {
            v.push(Kernel::Closest(a));
            v.push(Kernel::Any(a));
        }
        v
    }

    /// Threads a dispatch over `count` work items launches: one per item, one per four rays
    /// for the packet kernels.
    pub fn threads(self, count: u32) -> u32 {
        match self {
            Kernel::Closest(Accel::Packet(_)) | Kernel::Any(Accel::Packet(_)) => count.div_ceil(kdray_shared::kdtree::PACKET as u32),
            _ => count,
        }
    }
}

/// Threads per workgroup of every kernel (`#[spirv(compute(threads(64)))]`).
pub const WORKGROUP: u32 = 64;
