//! Primary rays of the pinhole camera.
use crate::math::{add3, normalize3, scale3};
use crate::pod::{Camera, ORDER_TILES};
use crate::ray::Ray;

/// Ray through the centre of pixel `index` (row-major, row 0 at the top).
#[inline(always)]
pub fn primary_ray(cam: &Camera, index: u32) -> Ray {
    let x = (index % cam.width) as f32 + 0.5;
    let y = (index / cam.width) as f32 + 0.5;
    let d = add3(add3(cam.top_left, scale3(cam.du, x)), scale3(cam.dv, y));
    Ray::new(cam.origin, normalize3(d), 0.0, f32::INFINITY)
}

/// Ray through point (x + u, y + v) of pixel `index` (u, v in [0, 1)).
#[inline(always)]
pub fn jittered_ray(cam: &Camera, index: u32, u: f32, v: f32) -> Ray {
    let x = (index % cam.width) as f32 + u;
    let y = (index / cam.width) as f32 + v;
    let d = add3(add3(cam.top_left, scale3(cam.du, x)), scale3(cam.dv, y));
    Ray::new(cam.origin, normalize3(d), 0.0, f32::INFINITY)
}

/// The pixel traced as the `index`-th ray of a frame, in the camera's order (a bijection of
/// 0..width·height). Tiles: the largest region of whole 8×8 tiles first, tile by tile in rows,
/// Morton order inside each tile; then the pixels right of it (rows), then those below (rows).
#[inline(always)]
pub fn pixel(cam: &Camera, index: u32) -> u32 {
    if cam.order != ORDER_TILES {
        return index;
    }
    let (w, h) = (cam.width, cam.height);
    let (core_w, core_h) = (w / 8 * 8, h / 8 * 8);
    let core = core_w * core_h;
    if index < core {
        let tile = index / 64;
        let m = index % 64;
        // De-interleave the 6 Morton bits: x from the even bits, y from the odd ones.
        let x = (m & 1) | ((m >> 1) & 2) | ((m >> 2) & 4);
        let y = ((m >> 1) & 1) | ((m >> 2) & 2) | ((m >> 3) & 4);
        let tiles_x = core_w / 8;
        return ((tile / tiles_x) * 8 + y) * w + (tile % tiles_x) * 8 + x;
    }
    let r = index - core;
    let side = w - core_w;
    if r < side * core_h {
        (r / side) * w + core_w + r % side
    } else {
        let r = r - side * core_h;
        (core_h + r / w) * w + r % w
    }
}
