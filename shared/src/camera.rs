//! Primary rays of the pinhole camera.
use crate::math::{add3, normalize3, scale3};
use crate::pod::Camera;
use crate::ray::Ray;

/// Ray through the centre of pixel `index` (row-major, row 0 at the top).
#[inline(always)]
pub fn primary_ray(cam: &Camera, index: u32) -> Ray {
    let x = (index % cam.width) as f32 + 0.5;
    let y = (index / cam.width) as f32 + 0.5;
    let d = add3(add3(cam.top_left, scale3(cam.du, x)), scale3(cam.dv, y));
    Ray::new(cam.origin, normalize3(d), 0.0, f32::INFINITY)
}
