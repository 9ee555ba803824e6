//! The host's view of the SPIR-V module built from `shader-crate/`: entry point names and
//! the binding list of each (binding 0 is always the read-only `FrameParams`). Keep in step
//! with the `#[spirv(...)]` attributes of the entry points.

#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    CameraRays,
    ClosestHitBrute,
    AnyHitBrute,
    LightSample,
    Resolve,
    RngFill,
}

/// `true` = read-only storage, `false` = read-write, for bindings 1.. of a kernel.
impl Kernel {
    pub const ALL: [Kernel; 6] = [
        Kernel::CameraRays,
        Kernel::ClosestHitBrute,
        Kernel::AnyHitBrute,
        Kernel::LightSample,
        Kernel::Resolve,
        Kernel::RngFill,
    ];

    pub fn entry_point(self) -> &'static str {
        match self {
            Kernel::CameraRays => "camera_rays",
            Kernel::ClosestHitBrute => "closest_hit_brute",
            Kernel::AnyHitBrute => "any_hit_brute",
            Kernel::LightSample => "light_sample",
            Kernel::Resolve => "resolve",
            Kernel::RngFill => "rng_fill",
        }
    }

    pub fn bindings(self) -> &'static [bool] {
        match self {
            Kernel::CameraRays => &[false],
            Kernel::ClosestHitBrute => &[true, true, false],
            Kernel::AnyHitBrute => &[true, true, false],
            Kernel::LightSample => &[true, true, true, true, true, false, false],
            Kernel::Resolve => &[true, true, false],
            Kernel::RngFill => &[false],
        }
    }
}

/// Threads per workgroup of every kernel (`#[spirv(compute(threads(64)))]`).
pub const WORKGROUP: u32 = 64;
