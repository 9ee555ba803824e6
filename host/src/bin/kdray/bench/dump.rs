//! `bench --dump-rays DIR`: the exact rays of a benchmark row and this project's answers as
//! NumPy `.npy` files (format version 1.0, little-endian), and the scene's triangles as an OBJ
//! in the same coordinates, so other ray tracers can be run on the same rays and compared:
//!
//! * `<scene>.obj`: `v` lines (three per triangle, in triangle order) and `f` lines; face k is
//!   triangle id k;
//! * `<scene>-<rays>-rays.npy`: float32 (N, 8): origin x y z, t_min, direction x y z, t_max
//!   (directions are not normalised for shadow rays: they end at t = 1 − 1/4096, just before the light);
//! * `<scene>-<rays>-hit-id.npy`: uint32 (N,): closest-hit triangle id, 4294967295 = miss;
//!   for shadow rays (any-hit queries) 1 = occluded, 0 = not;
//! * `<scene>-<rays>-hit-t.npy`: float32 (N,): distance along the ray (closest hit; +inf for a
//!   miss and for any-hit queries).
use kdray::scene::Scene;
use anyhow::{Context, Result};
use kdray_shared::{Hit, Ray};
use std::fmt::Write as _;
use std::path::Path;

/// Element types of the `.npy` files.
pub trait NpyElem: bytemuck::Pod {
    const DESCR: &'static str;
}
impl NpyElem for f32 {
    const DESCR: &'static str = "<f4";
}
impl NpyElem for u32 {
    const DESCR: &'static str = "<u4";
}

/// Writes `data` as a C-order `.npy` array of `shape`.
pub fn write_npy<T: NpyElem>(path: &Path, shape: &[usize], data: &[T]) -> Result<()> {
    if shape.iter().product::<usize>() != data.len() {
        anyhow::bail!("{}: shape {shape:?} does not hold {} elements", path.display(), data.len());
    }
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '{}', 'fortran_order': False, 'shape': {dims}, }}", T::DESCR);
    // Magic (6) + version (2) + length (2) + header + '\n' is padded to a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(bytemuck::cast_slice(data));
    Ok(kdray::files::write(path, bytes)?)
}

/// The scene's triangles as OBJ, face k = triangle id k.
pub fn write_obj(path: &Path, scene: &Scene) -> Result<()> {
    let mut s = format!("# {}: {} triangles, written by kdray; face k is triangle id k\n", scene.name, scene.triangles.len());
    for t in &scene.triangles {
        for v in [t.v0, t.v1, t.v2] {
            writeln!(s, "v {:e} {:e} {:e}", v[0], v[1], v[2])?;
        }
    }
    for k in 0..scene.triangles.len() {
        writeln!(s, "f {} {} {}", 3 * k + 1, 3 * k + 2, 3 * k + 3)?;
    }
    Ok(kdray::files::write(path, s)?)
}

/// The files of ray batch `label` of scene `scene` start with this: `SCENE-LABEL`, spaces as
/// dashes (`conference-reflection-2`); peers name their results by it.
pub fn stem(scene: &str, label: &str) -> String {
    format!("{scene}-{}", label.replace(' ', "-"))
}

/// Writes one ray batch and its answers (`hits` for closest-hit batches, `occluded` for
/// any-hit ones) as described in the module notes.
pub fn write_batch(dir: &Path, scene: &Scene, label: &str, rays: &[Ray], hits: Option<&[Hit]>, occluded: Option<&[bool]>) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let obj = dir.join(format!("{}.obj", scene.name));
    if !obj.exists() {
        write_obj(&obj, scene)?;
    }
    let stem = stem(&scene.name, label);
    let flat: Vec<f32> = rays.iter().flat_map(|r| [r.origin[0], r.origin[1], r.origin[2], r.t_min, r.dir[0], r.dir[1], r.dir[2], r.t_max]).collect();
    write_npy(&dir.join(format!("{stem}-rays.npy")), &[rays.len(), 8], &flat)?;
    let (ids, ts): (Vec<u32>, Vec<f32>) = match (hits, occluded) {
        (Some(h), _) => h.iter().map(|h| (h.prim, h.t)).unzip(),
        (None, Some(o)) => o.iter().map(|o| (*o as u32, f32::INFINITY)).unzip(),
        (None, None) => anyhow::bail!("a ray batch needs its answers"),
    };
    write_npy(&dir.join(format!("{stem}-hit-id.npy")), &[ids.len()], &ids)?;
    write_npy(&dir.join(format!("{stem}-hit-t.npy")), &[ts.len()], &ts)
}
