//! Scene files (TOML): meshes, camera, materials and lights.
//!
//! ```toml
//! [camera]                       # optional: default frames the scene
//! eye = [0.0, 0.1, 0.4]
//! look_at = [0.0, 0.1, 0.0]
//! up = [0.0, 1.0, 0.0]           # optional
//! fov_y = 40.0                   # degrees, optional
//!
//! [materials.white]              # defines a material, or overrides one of an MTL file by name
//! diffuse = [0.8, 0.8, 0.8]
//! emission = [0.0, 0.0, 0.0]     # optional
//! mirror = false                 # optional
//! glass = false                  # optional: a smooth dielectric (colourless)
//! ior = 1.5                      # optional: glass's index of refraction
//!
//! [[mesh]]
//! file = "bunny.obj"             # relative to this file; or builtin = "cornell" (the box of
//!                                # scenes/cornell.toml) or "icosphere:N" (radius 1, 20·4^N faces)
//! objects = ["body", "ears"]     # optional: only these objects (`o`/`g`) of the OBJ file
//! material = "white"             # optional: every face gets this material
//! scale = 1.0                    # optional
//! translate = [0.0, 0.0, 0.0]    # optional
//!
//! [[light]]
//! point = [0.0, 1.0, 1.0]
//! intensity = [10.0, 10.0, 10.0]
//!
//! [[light]]                      # a spot light: a point light with a direction and a cone
//! point = [0.0, 1.0, 0.0]
//! intensity = [10.0, 10.0, 10.0] # on the axis
//! direction = [0.0, -1.0, 0.0]
//! cone = 30.0                    # half angle in degrees, (0, 90]
//! falloff_start = 25.0           # optional, degrees (default: cone, a hard edge)
//!
//! [[light]]                      # an emissive quad corner, corner+edge1(+edge2)
//! corner = [-0.1, 0.3, -0.1]
//! edge1 = [0.2, 0.0, 0.0]
//! edge2 = [0.0, 0.0, 0.2]
//! emission = [10.0, 10.0, 10.0]
//! ```
//!
//! Every number must be finite; colours (`diffuse`, `emission`, `intensity`) must also be
//! non-negative, `fov_y` lie strictly between 0 and 180, and a quad light span some area: an
//! error names the file and the material, light or camera field otherwise.
use super::{check_color, check_finite, obj, procedural, CameraSpec, Files, PointLight, Scene};
use crate::error::{bail, err, Result};
use glam::Vec3;
use kdray_shared::{Material, MAT_GLASS, MAT_MIRROR};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCamera {
    eye: [f32; 3],
    look_at: [f32; 3],
    up: Option<[f32; 3]>,
    fov_y: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMaterial {
    diffuse: [f32; 3],
    emission: Option<[f32; 3]>,
    mirror: Option<bool>,
    glass: Option<bool>,
    ior: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMesh {
    file: Option<String>,
    builtin: Option<String>,
    objects: Option<Vec<String>>,
    material: Option<String>,
    scale: Option<f32>,
    translate: Option<[f32; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileLight {
    point: Option<[f32; 3]>,
    intensity: Option<[f32; 3]>,
    corner: Option<[f32; 3]>,
    edge1: Option<[f32; 3]>,
    edge2: Option<[f32; 3]>,
    emission: Option<[f32; 3]>,
    direction: Option<[f32; 3]>,
    cone: Option<f32>,
    falloff_start: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: Option<FileCamera>,
    #[serde(default)]
    materials: BTreeMap<String, FileMaterial>,
    #[serde(default)]
    mesh: Vec<FileMesh>,
    #[serde(default)]
    light: Vec<FileLight>,
}

fn finite(name: &str, what: &str, v: [f32; 3]) -> Result<Vec3> {
    check_finite(name, what, v)
}

/// Loads the scene file at `path` (format in the module docs), named after the file's stem;
/// mesh files are relative to its directory. Errors name the file, and the line where known.
pub fn load_scene_file(path: &Path) -> Result<Scene> {
    let dir = path.parent().unwrap_or(Path::new(""));
    load_scene(Files::Dir(dir), Path::new(path.file_name().unwrap_or_default()))
}

/// Loads the scene file `path` of `files` (a folder's, or the built-in scenes'); its mesh files
/// are read from `files` too.
pub fn load_scene(files: Files, path: &Path) -> Result<Scene> {
    let name = files.name(path);
    let text = String::from_utf8(files.read(path)?).map_err(|_| err!(SceneFile(name, None): "not UTF-8 text"))?;
    let file: SceneFile = toml::from_str(&text).map_err(|e| {
        let msg = e.message().to_string();
        match e.span() {
            Some(span) => {
                let line = text[..span.start].matches('\n').count() + 1;
                err!(SceneFile(name, Some(line)): "{msg}")
            }
            None => err!(SceneFile(name, None): "{msg}"),
        }
    })?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut scene = Scene::new(stem, CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let mut materials = Vec::new();
    for (mname, m) in &file.materials {
        let flags = if m.mirror.unwrap_or(false) { MAT_MIRROR } else { 0 }
            | if m.glass.unwrap_or(false) { MAT_GLASS } else { 0 };
        let diffuse = check_color(&name, &format!("material '{mname}' diffuse"), m.diffuse)?;
        let emission = check_color(&name, &format!("material '{mname}' emission"), m.emission.unwrap_or([0.0; 3]))?;
        let ior = m.ior.unwrap_or(1.5);
        if !(ior.is_finite() && ior >= 1.0 && ior <= 10.0) {
            bail!(SceneFile(name, None): "material '{mname}' ior must be between 1 and 10, got {ior}");
        }
        let material = Material { diffuse, flags, emission, ior };
        scene.add_material(mname, material);
        materials.push((mname, material));
    }
    if file.mesh.is_empty() {
        bail!(SceneFile(name, None): "no [[mesh]] entries: the scene is empty");
    }
    for (i, m) in file.mesh.iter().enumerate() {
        let mat = match &m.material {
            Some(mn) => Some(
                scene
                    .material_id(mn)
                    .ok_or_else(|| err!(SceneFile(name, None): "mesh {}: unknown material '{mn}'", i + 1))?,
            ),
            None => None,
        };
        let translate = finite(&name, &format!("mesh {} translate", i + 1), m.translate.unwrap_or([0.0; 3]))?;
        let scale = m.scale.unwrap_or(1.0);
        if !scale.is_finite() || scale == 0.0 {
            bail!(SceneFile(name, None): "mesh {}: scale must be finite and non-zero", i + 1);
        }
        if m.objects.is_some() && m.file.is_none() {
            bail!(SceneFile(name, None): "mesh {}: 'objects' selects objects of an OBJ 'file'", i + 1);
        }
        match (&m.file, &m.builtin) {
            (Some(f), None) => obj::add_obj(&mut scene, files, &path.with_file_name(f), scale, translate, mat, m.objects.as_deref())?,
            (None, Some(b)) if b.starts_with("icosphere:") => {
                let n = b["icosphere:".len()..].parse::<u32>().ok().filter(|&n| n <= 8);
                let Some(n) = n else { bail!(SceneFile(name, None): "mesh {}: use builtin = \"icosphere:N\" with N = 0..8 subdivisions", i + 1) };
                let id = match mat {
                    Some(id) => id,
                    None => scene.add_material("default", Material { diffuse: [0.8; 3], ..Default::default() }),
                };
                let mut ball = procedural::sphere(1.0, n);
                for v in &mut ball.v {
                    *v = *v * scale + translate;
                }
                ball.into_scene(&mut scene, id, &format!("{name}: builtin {b}"))?;
            }
            (None, Some(b)) if b == "cornell" => {
                let c = super::load("cornell")?;
                for t in &c.triangles {
                    let cm = &c.material_names[t.material as usize];
                    let id = mat.unwrap_or_else(|| scene.add_material(cm, c.materials[t.material as usize]));
                    let v = [t.v0, t.v1, t.v2].map(|p| Vec3::from(p) * scale + translate);
                    scene.add_triangle(v, id, &|| format!("{name}: builtin cornell"))?;
                }
                if file.camera.is_none() {
                    scene.camera = c.camera.clone();
                }
            }
            (None, Some(b)) => bail!(SceneFile(name, None): "mesh {}: unknown builtin '{b}' (known: cornell, icosphere:N)", i + 1),
            _ => bail!(SceneFile(name, None): "mesh {}: give exactly one of 'file' or 'builtin'", i + 1),
        }
    }
    // The file's materials override those of its meshes' MTL files of the same name.
    for (mname, m) in materials {
        scene.add_material(mname, m);
    }
    for (i, l) in file.light.iter().enumerate() {
        let what = |field: &str| format!("light {} {field}", i + 1);
        match (l.point, l.corner) {
            (Some(p), None) => {
                if l.edge1.is_some() || l.edge2.is_some() || l.emission.is_some() {
                    bail!(SceneFile(name, None): "light {}: a point light takes 'intensity', not 'edge1', 'edge2' or 'emission'", i + 1);
                }
                let position = finite(&name, &what("point"), p)?;
                let intensity = Vec3::from(check_color(&name, &what("intensity"), l.intensity.unwrap_or([1.0; 3]))?);
                let spot = match (l.direction, l.cone) {
                    (None, None) if l.falloff_start.is_none() => None,
                    (Some(d), Some(cone)) => {
                        let d = finite(&name, &what("direction"), d)?;
                        if d.length_squared() == 0.0 {
                            bail!(SceneFile(name, None): "light {}: direction is zero", i + 1);
                        }
                        let start = l.falloff_start.unwrap_or(cone);
                        if !(cone > 0.0 && cone <= 90.0) || !(start >= 0.0 && start <= cone) {
                            bail!(SceneFile(name, None): "light {}: cone must be in (0, 90] degrees and falloff_start in [0, cone], got {cone} and {start}", i + 1);
                        }
                        Some(super::Spot { direction: d.normalize(), cone_deg: cone, falloff_start_deg: start })
                    }
                    _ => bail!(SceneFile(name, None): "light {}: a spot light needs both 'direction' and 'cone'", i + 1),
                };
                scene.point_lights.push(PointLight { position, intensity, spot });
            }
            (None, Some(c)) => {
                if l.intensity.is_some() {
                    bail!(SceneFile(name, None): "light {}: a quad light takes 'emission', not 'intensity'", i + 1);
                }
                let c = finite(&name, &what("corner"), c)?;
                let (e1, e2) = match (l.edge1, l.edge2) {
                    (Some(a), Some(b)) => (finite(&name, &what("edge1"), a)?, finite(&name, &what("edge2"), b)?),
                    _ => bail!(SceneFile(name, None): "light {}: a quad light needs edge1 and edge2", i + 1),
                };
                if e1.as_dvec3().cross(e2.as_dvec3()) == glam::DVec3::ZERO {
                    bail!(SceneFile(name, None): "light {}: edge1 {e1} and edge2 {e2} span no area", i + 1);
                }
                if !(c + e1 + e2).is_finite() {
                    bail!(SceneFile(name, None): "light {}: corner + edge1 + edge2 is not finite in f32", i + 1);
                }
                let emission = check_color(&name, &what("emission"), l.emission.unwrap_or([1.0; 3]))?;
                let id = scene.add_material(
                    &format!("light{}", i + 1),
                    Material { diffuse: [0.0; 3], emission, ..Default::default() },
                );
                scene.add_quad([c, c + e1, c + e1 + e2, c + e2], id)?;
            }
            _ => bail!(SceneFile(name, None): "light {}: give exactly one of 'point' or 'corner'", i + 1),
        }
    }
    match file.camera {
        Some(c) => {
            scene.camera = CameraSpec {
                eye: finite(&name, "camera eye", c.eye)?,
                look_at: finite(&name, "camera look_at", c.look_at)?,
                up: finite(&name, "camera up", c.up.unwrap_or([0.0, 1.0, 0.0]))?,
                fov_y_deg: c.fov_y.unwrap_or(40.0),
            };
            scene.camera.check(&name)?;
        }
        None if !file.mesh.iter().any(|m| m.builtin.is_some()) => {
            let (lo, hi) = scene.bounds();
            scene.camera = CameraSpec::framing(lo, hi);
        }
        None => {}
    }
    Ok(scene)
}
