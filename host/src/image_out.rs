//! From linear radiance to PNG, and pixel-by-pixel comparison of two renders.
use crate::integrator::RenderOutput;
use anyhow::{Context, Result};
use std::path::Path;

/// Linear → sRGB-encoded 8-bit (clamped).
pub fn to_srgb8(c: f32) -> u8 {
    let c = if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 };
    let s = if c <= 0.0031308 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Radiance is divided by `exposure` before encoding.
pub fn to_rgb8(out: &RenderOutput, exposure: f32) -> image::RgbImage {
    image::RgbImage::from_fn(out.width, out.height, |x, y| {
        let c = out.radiance[(y * out.width + x) as usize];
        image::Rgb([to_srgb8(c[0] / exposure), to_srgb8(c[1] / exposure), to_srgb8(c[2] / exposure)])
    })
}

pub fn write_png(out: &RenderOutput, exposure: f32, path: &Path) -> Result<()> {
    to_rgb8(out, exposure).save(path).with_context(|| format!("cannot write {}", path.display()))
}

/// How two renders of the same camera differ.
#[derive(Clone, Debug, Default)]
pub struct Comparison {
    pub pixels: usize,
    /// Pixels whose primary hit triangle differs.
    pub id_mismatches: usize,
    /// Largest |Δt|/t over pixels hitting the same triangle.
    pub max_rel_dt: f32,
    /// Pixels with the same primary hit whose 8-bit colours differ, and the largest difference.
    pub colour_mismatches: usize,
    pub max_colour_diff: u8,
}

pub fn compare(a: &RenderOutput, b: &RenderOutput, exposure: f32) -> Comparison {
    let (ia, ib) = (to_rgb8(a, exposure), to_rgb8(b, exposure));
    let mut c = Comparison { pixels: a.hits.len(), ..Default::default() };
    for (i, (ha, hb)) in a.hits.iter().zip(&b.hits).enumerate() {
        if ha.prim != hb.prim {
            c.id_mismatches += 1;
            continue;
        }
        if ha.is_hit() {
            let rel = (ha.t - hb.t).abs() / ha.t.abs().max(f32::MIN_POSITIVE);
            c.max_rel_dt = c.max_rel_dt.max(rel);
        }
        let (x, y) = (i as u32 % a.width, i as u32 / a.width);
        let d = ia.get_pixel(x, y).0.iter().zip(ib.get_pixel(x, y).0).map(|(p, q)| p.abs_diff(q)).max().unwrap_or(0);
        if d > 0 {
            c.colour_mismatches += 1;
            c.max_colour_diff = c.max_colour_diff.max(d);
        }
    }
    c
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} pixels: {} with different hit triangle ({:.5} %), max |Δt|/t {:.2e}; of the rest {} differ in 8-bit colour (max difference {})",
            self.pixels,
            self.id_mismatches,
            100.0 * self.id_mismatches as f64 / self.pixels.max(1) as f64,
            self.max_rel_dt,
            self.colour_mismatches,
            self.max_colour_diff
        )
    }
}
