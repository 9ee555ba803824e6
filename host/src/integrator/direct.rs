//! Direct lighting: a primary ray per pixel centre, followed through up to `bounces` specular
//! bounces, then one shadow ray toward a point sampled on the lights and Lambert shading — the
//! eye-path schedule (`path`) with no diffuse bounce and one sample.
use super::path::{self, PathOptions};
use super::{Progress, RenderOutput};
use crate::accel::Accel;
use crate::tracer::Tracer;
use crate::error::Result;
use kdray_shared::Camera;

/// Renders `cam`'s image with light samples from random stream `seed`.
pub fn render(t: &Tracer, accel: Accel, cam: &Camera, seed: u32, bounces: u32, progress: &dyn Progress) -> Result<RenderOutput> {
    path::render(t, accel, cam, &PathOptions::direct(seed, bounces), progress)
}
