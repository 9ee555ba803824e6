//! Wavefront OBJ/MTL input through `tobj`, with a line-by-line validation pass first so that a
//! malformed file is reported as one line naming the file and the offending line.
use super::{CameraSpec, Files, PointLight, Scene};
use crate::error::{bail, err, Result};
use glam::Vec3;
use kdray_shared::{Material, MAT_GLASS, MAT_MIRROR};
use std::path::Path;

/// Checks what tobj does not report by line: every `v` has three finite numbers, every `f` has
/// ≥ 3 vertex references to vertices defined before it, and there is at least one face.
pub fn validate_obj_text(name: &str, text: &str) -> Result<()> {
    let mut vertices = 0i64;
    let mut faces = 0usize;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let nums: Vec<&str> = it.collect();
                if nums.len() < 3 {
                    bail!(SceneFile(name, Some(line_no)): "vertex needs 3 coordinates: '{line}'");
                }
                for n in &nums[..3] {
                    let x: f32 = n
                        .parse()
                        .map_err(|_| err!(SceneFile(name, Some(line_no)): "cannot parse vertex coordinate '{n}'"))?;
                    if !x.is_finite() {
                        bail!(SceneFile(name, Some(line_no)): "vertex {} has a non-finite coordinate '{n}'", vertices + 1);
                    }
                }
                vertices += 1;
            }
            Some("f") => {
                faces += 1;
                let refs: Vec<&str> = it.collect();
                if refs.len() < 3 {
                    bail!(SceneFile(name, Some(line_no)): "face {faces} has {} vertices, needs at least 3", refs.len());
                }
                for r in refs {
                    let idx = r.split('/').next().unwrap_or("");
                    let k: i64 = idx
                        .parse()
                        .map_err(|_| err!(SceneFile(name, Some(line_no)): "face {faces}: cannot parse vertex index '{r}'"))?;
                    let resolved = if k < 0 { vertices + 1 + k } else { k };
                    if k == 0 || resolved < 1 || resolved > vertices {
                        bail!(SceneFile(name, Some(line_no)): "face {faces} refers to vertex {k}, but only {vertices} vertices are defined before it"
                        );
                    }
                }
            }
            _ => {}
        }
    }
    if faces == 0 {
        bail!(SceneFile(name, None): "no faces: the mesh is empty");
    }
    Ok(())
}

/// Checks what tobj does not, by line, in an MTL file: the colour statements (`Ka`, `Kd`,
/// `Ks`, `Ke`) have three numbers (tobj panics on fewer), and `Kd` and `Ke` (the ones used) are
/// finite and non-negative. Numbers that do not parse are left to tobj, whose failure to load
/// the materials is a warning.
pub fn validate_mtl_text(name: &str, text: &str) -> Result<()> {
    let mut material = String::new();
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        let mut it = line.split_whitespace();
        let key = it.next();
        match key {
            Some("newmtl") => material = line["newmtl".len()..].trim().to_string(),
            Some(k @ ("Ka" | "Kd" | "Ks" | "Ke")) => {
                let nums: Vec<&str> = it.take(3).collect();
                let what = if material.is_empty() { k.to_string() } else { format!("material '{material}' {k}") };
                if nums.len() < 3 {
                    bail!(SceneFile(name, Some(line_no)): "{what} needs 3 numbers (r g b): '{line}'");
                }
                if k == "Ka" || k == "Ks" {
                    continue;
                }
                for n in nums {
                    let Ok(x) = n.parse::<f32>() else { continue };
                    if !x.is_finite() {
                        bail!(SceneFile(name, Some(line_no)): "{what} has a non-finite value '{n}'");
                    }
                    if x < 0.0 {
                        bail!(SceneFile(name, Some(line_no)): "{what} has a negative value '{n}'");
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Validates the MTL files an OBJ file names (`mtllib`, resolved as tobj does: relative to
/// the OBJ file's directory). Files that cannot be read are left to the loader (a warning).
fn validate_mtllibs(files: Files, obj: &Path, text: &str) -> Result<()> {
    for raw in text.lines() {
        let line = raw.trim();
        if line.split_whitespace().next() != Some("mtllib") {
            continue;
        }
        let file = line.split_once(' ').unwrap_or_default().1.trim();
        let mtl = beside(obj, Path::new(file));
        // Lossily: tobj reads the lines before a byte that is not UTF-8, so those must be
        // checked too (found by tests/fuzz.rs).
        if let Ok(bytes) = files.read(&mtl) {
            validate_mtl_text(&files.name(&mtl), &String::from_utf8_lossy(&bytes))?;
        }
    }
    Ok(())
}

/// `file` named in `obj` (an `mtllib`): relative to the OBJ file's directory.
fn beside(obj: &Path, file: &Path) -> std::path::PathBuf {
    match obj.parent() {
        Some(dir) => dir.join(file),
        None => file.to_path_buf(),
    }
}

/// A material from an MTL entry; `name` (the OBJ file) is for errors that `validate_mtl_text`
/// should already have caught.
fn material_from_mtl(name: &str, m: &tobj::Material) -> Result<Material> {
    let what = |k: &str| format!("material '{}' {k}", m.name);
    let diffuse = super::check_color(name, &what("Kd"), m.diffuse.unwrap_or([0.8, 0.8, 0.8]))?;
    let emission = super::check_color(name, &what("Ke"), m.emissive.unwrap_or([0.0; 3]))?;
    let flags = match m.illumination_model {
        Some(3) | Some(5) => MAT_MIRROR,
        // Glass: a smooth dielectric of index `Ni` (default 1.5).
        Some(4) | Some(6) | Some(7) | Some(9) => MAT_GLASS,
        _ => 0,
    };
    let ior = match m.optical_density {
        Some(n) if n.is_finite() && (1.0..=10.0).contains(&n) => n,
        Some(n) if flags & MAT_GLASS != 0 => bail!(SceneFile(name, None): "{} must be between 1 and 10, got {n}", what("Ni")),
        _ => 1.5,
    };
    Ok(Material { diffuse, flags, emission, ior })
}

/// Which objects (`o`/`g` names) of an OBJ file to add, in the file's order: all, or those named.
pub type Objects<'a> = Option<&'a [String]>;

/// Adds the meshes of the OBJ file `path` (read through `files`) to `scene`, transformed by
/// `scale` then `translate`; only the `objects` named, if given (each must exist).
/// `material_override` replaces every face's material.
pub fn add_obj(
    scene: &mut Scene,
    files: Files,
    path: &Path,
    scale: f32,
    translate: Vec3,
    material_override: Option<u32>,
    objects: Objects,
) -> Result<()> {
    let name = files.name(path);
    let bytes = files.read(path)?;
    let text = String::from_utf8(bytes).map_err(|_| err!(SceneFile(name, None): "not UTF-8 text"))?;
    validate_obj_text(&name, &text)?;
    validate_mtllibs(files, path, &text)?;
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, mtls) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |mtl| match files.read(&beside(path, mtl)) {
        Ok(b) => tobj::load_mtl_buf(&mut b.as_slice()),
        Err(_) => Err(tobj::LoadError::OpenFileFailed),
    })
    .map_err(|e| err!(SceneFile(name, None): "{e}"))?;
    if let Some(wanted) = objects {
        if let Some(o) = wanted.iter().find(|o| !models.iter().any(|m| &m.name == *o)) {
            bail!(SceneFile(name, None): "no object '{o}' (objects: {})", models.iter().map(|m| m.name.as_str()).collect::<Vec<_>>().join(", "));
        }
    }
    // A missing or broken .mtl is not fatal: faces fall back to the default material.
    let mtls = mtls.unwrap_or_else(|e| {
        scene.warnings.push(format!("{name}: materials not loaded ({e}); using a grey default"));
        Vec::new()
    });
    let default = scene.add_material("default", Material { diffuse: [0.8; 3], ..Default::default() });
    let mut mtl_ids = Vec::with_capacity(mtls.len());
    for m in &mtls {
        let mat = material_from_mtl(&name, m)?;
        mtl_ids.push(scene.add_material(&m.name, mat));
    }
    let mut face_no = 0usize;
    for model in &models {
        if objects.is_some_and(|o| !o.contains(&model.name)) {
            continue;
        }
        let mesh = &model.mesh;
        let mat = material_override
            .or_else(|| mesh.material_id.and_then(|i| mtl_ids.get(i).copied()))
            .unwrap_or(default);
        let pos = |i: u32| -> Vec3 {
            let i = i as usize * 3;
            Vec3::new(mesh.positions[i], mesh.positions[i + 1], mesh.positions[i + 2]) * scale + translate
        };
        for tri in mesh.indices.chunks_exact(3) {
            face_no += 1;
            let f = face_no;
            scene.add_triangle([pos(tri[0]), pos(tri[1]), pos(tri[2])], mat, &|| {
                format!("{name}: triangle {f} of object '{}'", model.name)
            })?;
        }
    }
    if face_no == 0 {
        bail!(SceneFile(name, None): "no triangles: the mesh is empty");
    }
    Ok(())
}

/// An OBJ file on its own: framed by an automatic camera and lit by a light at the camera
/// (plus any emissive MTL materials).
pub fn load_obj_scene(path: &Path) -> Result<Scene> {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut scene = Scene::new(stem, CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let dir = path.parent().unwrap_or(Path::new(""));
    let file = Path::new(path.file_name().unwrap_or_default());
    add_obj(&mut scene, Files::Dir(dir), file, 1.0, Vec3::ZERO, None, None)?;
    let (lo, hi) = scene.bounds();
    scene.camera = CameraSpec::framing(lo, hi);
    let d = (scene.camera.eye - scene.camera.look_at).length();
    scene.point_lights.push(PointLight {
        position: scene.camera.eye + Vec3::new(0.3, 0.5, 0.0) * d,
        intensity: Vec3::splat(1.2 * d * d),
        spot: None,
    });
    Ok(scene)
}
