//! Images: linear radiance to a PNG preview, PFM, and OpenEXR with the primary hits' AOVs
//! (depth, normal, albedo, triangle id) as named channels; pixel-by-pixel comparison of two
//! renders.
use crate::error::{err, Context, Result};
use crate::integrator::RenderOutput;
use crate::scene::Scene;
use kdray_shared::math::{dot3, length3, scale3, sub3};
use kdray_shared::{shade, Camera, Ray, MISS};
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

/// The tonemapped preview: radiance ÷ `exposure`, clamped, sRGB-encoded 8 bits, as PNG (or
/// the 8-bit format `path`'s extension names, e.g. `.jpg`).
pub fn write_png(out: &RenderOutput, exposure: f32, path: &Path) -> Result<()> {
    write_rgb8(&to_rgb8(out, exposure), path)
}

/// Writes an 8-bit RGB image (atomically, `files::write`) as PNG, or in the format `path`'s
/// extension names when the `image` crate knows it.
pub fn write_rgb8(img: &image::RgbImage, path: &Path) -> Result<()> {
    let format = image::ImageFormat::from_path(path).unwrap_or(image::ImageFormat::Png);
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), format).map_err(|e| err!(InvalidInput: "{}: cannot encode the image: {e}", path.display()))?;
    crate::files::write(path, bytes)
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
    crate::files::write(path, bytes)
}

/// The render as one OpenEXR file (32-bit float channels, ZIP-compressed, one layer):
/// linear radiance `R`, `G`, `B`, and for each pixel's primary hit (one eye sample of the last
/// pass) the AOVs `depth.Z` (distance from the eye; +inf where the ray missed),
/// `normal.X`/`.Y`/`.Z` (unit geometric normal facing the eye; 0 on a miss), `albedo.R`/`.G`/`.B`
/// (the material's diffuse reflectance; 0 on a miss) and `id` (32-bit unsigned: the triangle,
/// `Hit::prim`; `u32::MAX` on a miss, or where the id is not a triangle of `scene`). `cam` and
/// `scene` must be those of the render.
pub fn write_exr(out: &RenderOutput, scene: &Scene, cam: &Camera, path: &Path) -> Result<()> {
    use exr::prelude::*;
    let n = (out.width * out.height) as usize;
    if out.radiance.len() != n || out.hits.len() != n {
        return Err(err!(InvalidInput: "write_exr: {}×{} image with {} pixels and {} hits", out.width, out.height, out.radiance.len(), out.hits.len()));
    }
    let mut f = vec![Vec::with_capacity(n); 10];
    let mut id = Vec::with_capacity(n);
    for (c, h) in out.radiance.iter().zip(&out.hits) {
        let tri = scene.triangles.get(h.prim as usize).filter(|_| h.prim != MISS);
        let aov = match tri {
            Some(tri) => {
                // The surface point and geometric normal, the normal then turned to the eye.
                let (p, n) = shade::surface_point(tri, h, &Ray::new(cam.origin, [0.0, 0.0, 1.0], 0.0, 1.0));
                let to_eye = sub3(cam.origin, p);
                let normal = if dot3(n, to_eye) < 0.0 { scale3(n, -1.0) } else { n };
                let albedo = scene.materials.get(tri.material as usize).map_or([0.0; 3], |m| m.diffuse);
                [length3(to_eye), normal[0], normal[1], normal[2], albedo[0], albedo[1], albedo[2]]
            }
            None => [f32::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        for (k, v) in [c[0], c[1], c[2]].into_iter().chain(aov).enumerate() {
            f[k].push(v);
        }
        id.push(if tri.is_some() { h.prim } else { u32::MAX });
    }
    let names = ["R", "G", "B", "depth.Z", "normal.X", "normal.Y", "normal.Z", "albedo.R", "albedo.G", "albedo.B"];
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = names.iter().zip(f).map(|(name, v)| AnyChannel::new(*name, FlatSamples::F32(v))).collect();
    list.push(AnyChannel::new("id", FlatSamples::U32(id)));
    let layer = Layer::new((out.width as usize, out.height as usize), LayerAttributes::named("kdray"), Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut bytes).map_err(|e| match e {
        exr::error::Error::Io(io) => crate::Error::io(path, io),
        e => err!(InvalidInput: "{}: cannot write OpenEXR: {e}", path.display()),
    })?;
    crate::files::write(path, bytes.into_inner())
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
    /// Mean of the displayed (clamped) image.
    pub mean: f64,
    /// Mean of the displayed (clamped) reference.
    pub reference_mean: f64,
}

/// The error of linear image `a` against `reference` (same size, rows alike).
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
    /// Pixels compared.
    pub pixels: usize,
    /// Pixels whose primary hit triangle differs.
    pub id_mismatches: usize,
    /// Largest |Δt|/t over pixels hitting the same triangle.
    pub max_rel_dt: f32,
    /// Pixels with the same primary hit whose 8-bit colours differ, and the largest difference.
    pub colour_mismatches: usize,
    /// The largest difference of an 8-bit channel among them.
    pub max_colour_diff: u8,
}

/// Compares two renders of one camera pixel by pixel: primary hits, then 8-bit colours at
/// `exposure`.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::path::{self, PathOptions};
    use crate::runtime::cpu::NATIVE;
    use crate::{scene, Accel, Tracer};

    /// Every channel of the EXR reads back as written: radiance as the PFM's, the id as the
    /// primary hit's triangle, depth as the distance to the hit point, unit normals facing the
    /// eye, albedo as the material's.
    #[test]
    fn exr_holds_radiance_and_the_primary_hits_aovs() {
        use exr::prelude::*;
        let scene = scene::load("cornell").unwrap();
        let cam = scene.camera.to_pod(24, 16);
        let t = Tracer::new(&NATIVE, &scene, None).unwrap();
        let img = path::render(&t, Accel::BRUTE, &cam, &PathOptions::path(3, 4, 2), &()).unwrap();
        let dir = std::env::temp_dir().join(format!("kdray-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("aov.exr");
        write_exr(&img, &scene, &cam, &path).unwrap();
        let read = read_all_flat_layers_from_file(&path).unwrap();
        let layer = &read.layer_data[0];
        assert_eq!((layer.size.0, layer.size.1), (24, 16));
        let ch = |name: &str| &layer.channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap_or_else(|| panic!("no channel {name}")).sample_data;
        let f = |name: &str| match ch(name) {
            FlatSamples::F32(v) => v.clone(),
            _ => panic!("{name} is not f32"),
        };
        let ids = match ch("id") {
            FlatSamples::U32(v) => v.clone(),
            _ => panic!("id is not u32"),
        };
        let (r, depth, nx, ny, nz, ar) = (f("R"), f("depth.Z"), f("normal.X"), f("normal.Y"), f("normal.Z"), f("albedo.R"));
        let mut hits = 0;
        for (i, h) in img.hits.iter().enumerate() {
            assert_eq!(r[i], img.radiance[i][0]);
            if !h.is_hit() {
                assert_eq!(ids[i], u32::MAX);
                assert!(depth[i].is_infinite());
                continue;
            }
            hits += 1;
            assert_eq!(ids[i], h.prim);
            let tri = &scene.triangles[h.prim as usize];
            assert_eq!(ar[i], scene.materials[tri.material as usize].diffuse[0]);
            let len = (nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i]).sqrt();
            assert!((len - 1.0).abs() < 1e-5, "unit normal: {len}");
            let b0 = 1.0 - h.b1 - h.b2;
            let p: Vec<f32> = (0..3).map(|k| tri.v0[k] * b0 + tri.v1[k] * h.b1 + tri.v2[k] * h.b2).collect();
            let to_eye: Vec<f32> = (0..3).map(|k| cam.origin[k] - p[k]).collect();
            let dist = (to_eye[0] * to_eye[0] + to_eye[1] * to_eye[1] + to_eye[2] * to_eye[2]).sqrt();
            assert!((depth[i] - dist).abs() <= 1e-4 * dist && depth[i] > 500.0, "depth {} against {dist}", depth[i]);
            assert!(nx[i] * to_eye[0] + ny[i] * to_eye[1] + nz[i] * to_eye[2] > 0.0);
        }
        assert!(hits > 200, "{hits} of {} pixels hit", img.hits.len());
        std::fs::remove_dir_all(&dir).ok();
    }
}
