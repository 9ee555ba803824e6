//! The SAH kd-tree over a scene's triangles, built on the host and traversed by the
//! `kdray_shared::kdtree` algorithms on CPU and GPU.
pub mod sah;
pub mod clip;

pub use sah::{build, check_limits, try_build, BuildOptions, KdTreeData, TreeStats, BINS, DEFAULT_BINNED_ABOVE, DEFAULT_MAX_DUPLICATION};
