//! From linear radiance to PNG, and pixel-by-pixel comparison of two renders.
use crate::integrator::RenderOutput;
use crate::error::{err, Context, Result};
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

/// Linear radiance as a PFM (portable float map: little-endian RGB f32, bottom row first).
pub fn write_pfm(out: &RenderOutput, path: &Path) -> Result<()> {
    let mut bytes = format!("PF\n{} {}\n-1.0\n", out.width, out.height).into_bytes();
    for y in (0..out.height).rev() {
        for x in 0..out.width {
            let c = out.radiance[(y * out.width + x) as usize];
            for v in &c[..3] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// Reads a PFM written by `write_pfm` (3 channels, little-endian): width, height, rows top first.
pub fn read_pfm(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let data = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 && pos < data.len() {
        while pos < data.len() && data[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < data.len() && !data[pos].is_ascii_whitespace() {
            pos += 1;
        }
        fields.push(String::from_utf8_lossy(&data[start..pos]).into_owned());
    }
    pos += 1;
    let bad = || err!(InvalidInput: "{}: not a little-endian RGB PFM file", path.display());
    if fields.len() < 4 || fields[0] != "PF" || !fields[3].starts_with('-') {
        return Err(bad());
    }
    let (w, h): (u32, u32) = (fields[1].parse().map_err(|_| bad())?, fields[2].parse().map_err(|_| bad())?);
    let n = w as usize * h as usize;
    if data.len() < pos + n * 12 {
        return Err(bad());
    }
    let mut px = vec![[0.0f32; 3]; n];
    for y in 0..h as usize {
        for x in 0..w as usize {
            let o = pos + ((h as usize - 1 - y) * w as usize + x) * 12;
            let f = |k: usize| f32::from_le_bytes(data[o + 4 * k..o + 4 * k + 4].try_into().unwrap());
            px[y * w as usize + x] = [f(0), f(1), f(2)];
        }
    }
    Ok((w, h, px))
}

/// Error of an image against a reference.
#[derive(Copy, Clone, Debug, Default)]
pub struct ImageError {
    /// RMSE of the displayed images (each channel clamped to [0, 1]) divided by the reference's
    /// displayed mean: the measure the photon-mapping issue and its Mitsuba anchor use.
    pub rel_rmse: f64,
    /// Mean over channels of (a − b)² / (b² + 0.01), unclamped.
    pub rel_mse: f64,
    pub mean: f64,
    pub reference_mean: f64,
}

pub fn image_error(a: &[[f32; 3]], reference: &[[f32; 3]]) -> ImageError {
    let clamp = |v: f32| if v.is_finite() { v.clamp(0.0, 1.0) as f64 } else { 0.0 };
    let (mut se, mut rel, mut ma, mut mb) = (0.0, 0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(reference) {
        for c in 0..3 {
            let (p, q) = (clamp(x[c]), clamp(y[c]));
            se += (p - q).powi(2);
            ma += p;
            mb += q;
            let (u, v) = (x[c] as f64, y[c] as f64);
            rel += (u - v).powi(2) / (v * v + 0.01);
        }
    }
    let n = (a.len() * 3).max(1) as f64;
    let (ma, mb) = (ma / n, mb / n);
    ImageError { rel_rmse: (se / n).sqrt() / mb.max(1e-12), rel_mse: rel / n, mean: ma, reference_mean: mb }
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
