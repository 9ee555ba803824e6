//! Primary hits by rasterisation (Horn et al. 2007, §5): the GPU's rasteriser draws every
//! triangle of the scene with a depth test into a visibility buffer that holds, per pixel, the
//! triangle seen through the pixel's centre; one kernel then turns each pixel's candidate into
//! the hit the pixel's primary ray would have found, with the same watertight triangle test as
//! every traversal, and traces the ray through the structure where the candidate cannot be
//! trusted.
//!
//! The projection (`RasterParams::clip`) is the pinhole camera's own: a point's framebuffer
//! coordinates are exactly the continuous pixel coordinates (x, y) whose ray
//! `camera::primary_ray` would point at it, and its depth is `near / s`, with s the point's
//! distance along the camera's `top_left` axis (reversed depth: nearer is larger, compared with
//! `Greater`; the float depth keeps 24 bits of relative precision at every distance).
//!
//! What the answers are (the tie rule, tested in `tests/raster.rs`):
//! * a pixel whose candidate the ray hits gets that hit from the watertight test (the same
//!   operations as the traversals'; a driver may compile them differently in two kernels: on
//!   the H200 the last bits of `t` and the barycentrics differed from the BVH kernel's);
//! * a pixel whose candidate the ray misses (the rasteriser's coverage and the watertight test
//!   disagree within its sub-pixel precision, near an edge) is traced through the structure:
//!   its answer is the traversal's;
//! * a pixel the rasteriser left empty is a miss.
//!
//! So an answer differs from the traversal's only where the rasteriser's fixed-point coverage
//! or its depth test decided differently within their precision: the ray passes within a
//! fraction of a pixel's width (1/256 on common hardware) of an edge of the triangle the
//! traversal hits, or the two triangles' distances agree within the depth buffer's precision
//! (including exact ties, which the traversal breaks by the lower index). Triangles nearer to
//! the eye than `near` along its axis are clipped by the rasteriser.
//!
//! Natively there is no rasteriser: the native twin of the drawing pass marks every pixel
//! `UNKNOWN`, and the resolve kernel traces every ray — the traversal's answers exactly.
use crate::camera;
use crate::kernel::Store;
use crate::math::{cross3, dot3, scale3, sub3};
use crate::parts::Parts;
use crate::pod::{Camera, Hit, RasterParams, Triangle};
use crate::query::{Answer, Closest, Query};
use crate::stats::NoStats;
use crate::trace::Method;
use crate::triangle::ShearedRay;

/// A pixel of the visibility buffer that no triangle covered (its clear value).
pub const EMPTY: u32 = 0;
/// A pixel whose triangle is not known (the native twin's): its ray is traced. Any value above
/// the triangle count means the same.
pub const UNKNOWN: u32 = u32::MAX;

/// Words per row of the visibility buffer for images `width` pixels wide: a multiple of 64, so
/// that a row is a whole number of 256-byte blocks (the GPU's image-to-buffer copies need it).
#[inline(always)]
pub const fn row_words(width: u32) -> u32 {
    width.div_ceil(64) * 64
}

/// A pixel's value in the visibility buffer: `prim + 1` (0 is `EMPTY`).
#[inline(always)]
pub fn visible_value(prim: u32) -> u32 {
    prim.wrapping_add(1)
}

impl RasterParams {
    /// The parameters that draw the camera `cam`'s image of `triangles` triangles and resolve
    /// its `count` primary rays (in the camera's order), clipping at `near` along the camera's
    /// `top_left` axis (in units of that vector's length). The rows are the inverse of the
    /// matrix whose columns are `top_left`, `du`, `dv`, the second and third scaled by 2 /
    /// width and 2 / height; a camera whose vectors are linearly dependent gets rows of zeros
    /// (the rasteriser then draws nothing, and every pixel is `EMPTY`).
    pub fn new(cam: &Camera, triangles: u32, count: u32, near: f32) -> RasterParams {
        let (c0, c1, c2) = (cam.top_left, cam.du, cam.dv);
        let (x12, x20, x01) = (cross3(c1, c2), cross3(c2, c0), cross3(c0, c1));
        let det = dot3(c0, x12);
        let inv = if det.is_finite() && det != 0.0 { 1.0 / det } else { 0.0 };
        let row = |v: [f32; 3], s: f32| {
            let r = scale3(v, inv * s);
            [r[0], r[1], r[2], 0.0]
        };
        RasterParams {
            camera: *cam,
            rows: [row(x12, 1.0), row(x20, 2.0 / cam.width as f32), row(x01, 2.0 / cam.height as f32)],
            count,
            triangles,
            row_words: row_words(cam.width),
            near,
        }
    }

    /// Where pixel `pixel` (row-major, row 0 at the top) is in the visibility buffer (rows of
    /// `row_words`).
    #[inline(always)]
    pub fn slot(&self, pixel: u32) -> usize {
        ((pixel / self.camera.width) * self.row_words + pixel % self.camera.width) as usize
    }

    /// Clip-space position of the scene point `v` (wgpu's conventions: x right, y up, depth
    /// z / w in [0, 1]); after the perspective division and the viewport transform, x and y
    /// are the point's pixel coordinates as `camera::jittered_ray` takes them.
    #[inline(always)]
    pub fn clip(&self, v: [f32; 3]) -> [f32; 4] {
        let q = sub3(v, self.camera.origin);
        let r = &self.rows;
        let s = dot3([r[0][0], r[0][1], r[0][2]], q);
        let x = dot3([r[1][0], r[1][1], r[1][2]], q);
        let y = dot3([r[2][0], r[2][1], r[2][2]], q);
        [x - s, s - y, self.near, s]
    }
}

/// The vertex shader's work: vertex `vertex` of the draw is corner `vertex % 3` of triangle
/// `vertex / 3`; returns its clip-space position and the value its pixels get.
#[inline(always)]
pub fn vertex(p: &RasterParams, tris: &Parts<Triangle>, vertex: u32) -> ([f32; 4], u32) {
    let prim = vertex / 3;
    let t = tris.get(prim as usize);
    let corner = vertex % 3;
    let v = if corner == 0 { t.v0 } else if corner == 1 { t.v1 } else { t.v2 };
    (p.clip(v), visible_value(prim))
}

/// The closest hit of the camera's primary ray `i` (pixel `camera::pixel(i)`, through its
/// centre) from the visibility buffer `visible` (rows of `p.row_words`): the watertight test of
/// the pixel's candidate, or `M`'s traversal when there is none to trust (see the module's
/// tie rule).
#[inline(always)]
pub fn primary_hit<M: Method, O: Store<Hit> + ?Sized>(
    i: u32,
    p: &RasterParams,
    accel: &M::Accel<'_>,
    tris: &Parts<Triangle>,
    visible: &[u32],
    out: &mut O,
) {
    if i >= p.count {
        return;
    }
    let cam = &p.camera;
    let pixel = camera::pixel(cam, i);
    let ray = camera::primary_ray(cam, pixel);
    let v = visible[p.slot(pixel)];
    let mut q = Closest::new(&ray);
    let mut settled = v == EMPTY;
    let prim = v.wrapping_sub(1);
    if !settled && (prim as usize) < tris.len() {
        if let Some(r) = ShearedRay::new(&ray) {
            q.test(prim, &tris.get(prim as usize), &r, ray.t_min, &mut NoStats);
            settled = q.hit.is_hit();
        }
    }
    if !settled {
        M::find(accel, &ray, &mut q);
    }
    out.store(i as usize, q.answer());
}

/// The native twin of the drawing pass: pixel `i` of the buffer is `UNKNOWN`.
#[inline(always)]
pub fn unknown<O: Store<u32> + ?Sized>(i: u32, p: &RasterParams, visible: &mut O) {
    if i < p.row_words * p.camera.height {
        visible.store(i as usize, UNKNOWN);
    }
}

/// The sub-pixel offset (in [0, 1)²) of sample group `sample` of a rasterised render: every
/// pixel of the group is sampled at the same point of its area (the rasteriser samples pixel
/// centres, so the group's camera is shifted, `shifted`), the points of successive groups
/// the Halton sequence in bases 2 and 3 (the first the centre, (1/2, 1/2) after the shift by
/// one half), so the film's average converges to the pixel-box-filtered image.
pub fn group_offset(sample: u32) -> [f32; 2] {
    let h = |mut i: u32, b: u32| {
        let (mut f, mut r) = (1.0f32, 0.5f32);
        while i > 0 {
            f /= b as f32;
            r += f * (i % b) as f32;
            i /= b;
        }
        if r >= 1.0 { r - 1.0 } else { r }
    };
    [h(sample, 2), h(sample, 3)]
}

/// `cam` with every pixel's centre moved to point `offset` of its area: its primary rays
/// (`camera::primary_ray`) are `cam`'s rays through that point of each pixel (up to rounding).
pub fn shifted(cam: &Camera, offset: [f32; 2]) -> Camera {
    let (u, v) = (offset[0] - 0.5, offset[1] - 0.5);
    let t = cam.top_left;
    Camera { top_left: [t[0] + cam.du[0] * u + cam.dv[0] * v, t[1] + cam.du[1] * u + cam.dv[1] * v, t[2] + cam.du[2] * u + cam.dv[2] * v], ..*cam }
}

/// Whether `cam` may be rasterised: its image has pixels and its axes span space.
pub fn can_draw(cam: &Camera) -> bool {
    let det = dot3(cam.top_left, cross3(cam.du, cam.dv));
    cam.width > 0 && cam.height > 0 && det.is_finite() && det != 0.0
}
