//! Scenes: triangles with materials, lights and a camera, validated on the way in.
pub mod cornell;
pub mod file;
pub mod obj;
pub mod procedural;

use anyhow::{bail, Result};
use glam::Vec3;
use kdray_shared::{Camera, Light, Material, Triangle, LIGHT_POINT, LIGHT_TRIANGLE};

/// Where the camera is and what it sees; turned into the GPU `Camera` for a given resolution.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSpec {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
}

impl CameraSpec {
    /// Pinhole camera for a `width` × `height` image (square pixels, row 0 at the top).
    pub fn to_pod(&self, width: u32, height: u32) -> Camera {
        let forward = (self.look_at - self.eye).normalize();
        // Right-handed: with +y up and looking along +z, screen-right is −x.
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        let half_h = (self.fov_y_deg.to_radians() * 0.5).tan();
        let half_w = half_h * width as f32 / height as f32;
        let du = right * (2.0 * half_w / width as f32);
        let dv = -up * (2.0 * half_h / height as f32);
        let top_left = forward - right * half_w + up * half_h;
        Camera {
            origin: self.eye.to_array(),
            width,
            top_left: top_left.to_array(),
            height,
            du: du.to_array(),
            order: kdray_shared::ORDER_SCANLINE,
            dv: dv.to_array(),
            _pad1: 0,
        }
    }

    /// A camera looking at the box from the +z side, far enough to see all of it.
    pub fn framing(min: Vec3, max: Vec3) -> Self {
        let center = (min + max) * 0.5;
        let radius = ((max - min).length() * 0.5).max(1e-3);
        let fov_y_deg: f32 = 40.0;
        let dist = radius / (fov_y_deg.to_radians() * 0.5).sin();
        CameraSpec { eye: center + Vec3::new(0.0, 0.0, dist), look_at: center, up: Vec3::Y, fov_y_deg }
    }
}

/// A point light (emits `intensity` W/sr in every direction).
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    pub position: Vec3,
    pub intensity: Vec3,
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    pub point_lights: Vec<PointLight>,
    pub camera: CameraSpec,
    /// Zero-area triangles dropped while building (they can never be hit).
    pub dropped_degenerate: usize,
}

impl Scene {
    pub fn new(name: impl Into<String>, camera: CameraSpec) -> Self {
        Scene {
            name: name.into(),
            triangles: Vec::new(),
            materials: Vec::new(),
            material_names: Vec::new(),
            point_lights: Vec::new(),
            camera,
            dropped_degenerate: 0,
        }
    }

    /// Material id by name, adding it if new.
    pub fn add_material(&mut self, name: &str, m: Material) -> u32 {
        if let Some(i) = self.material_names.iter().position(|n| n == name) {
            self.materials[i] = m;
            return i as u32;
        }
        self.materials.push(m);
        self.material_names.push(name.to_string());
        (self.materials.len() - 1) as u32
    }

    pub fn material_id(&self, name: &str) -> Option<u32> {
        self.material_names.iter().position(|n| n == name).map(|i| i as u32)
    }

    /// Adds a triangle. Non-finite coordinates are an error (`what` names the source, e.g.
    /// "scene.obj: face 12"); a triangle of exactly zero area is dropped and counted.
    pub fn add_triangle(&mut self, v: [Vec3; 3], material: u32, what: &dyn Fn() -> String) -> Result<()> {
        if !v.iter().all(|p| p.is_finite()) {
            bail!("{}: vertex coordinates are not finite ({:?}, {:?}, {:?})", what(), v[0], v[1], v[2]);
        }
        if (material as usize) >= self.materials.len() {
            bail!("{}: material id {} does not exist", what(), material);
        }
        let (a, b, c) = (v[0].as_dvec3(), v[1].as_dvec3(), v[2].as_dvec3());
        if (b - a).cross(c - a) == glam::DVec3::ZERO {
            self.dropped_degenerate += 1;
            return Ok(());
        }
        let face = self.triangles.len() as u32 + self.dropped_degenerate as u32;
        self.triangles.push(Triangle {
            v0: v[0].to_array(),
            material,
            v1: v[1].to_array(),
            face,
            v2: v[2].to_array(),
            _pad: 0,
        });
        Ok(())
    }

    /// Two triangles (a, b, c) and (a, c, d) of a planar quad a-b-c-d.
    pub fn add_quad(&mut self, q: [Vec3; 4], material: u32) -> Result<()> {
        let name = self.name.clone();
        self.add_triangle([q[0], q[1], q[2]], material, &|| format!("{name}: quad"))?;
        self.add_triangle([q[0], q[2], q[3]], material, &|| format!("{name}: quad"))
    }

    /// Whether any triangle is a mirror (only then are reflection rays traced).
    pub fn has_mirror(&self) -> bool {
        self.triangles.iter().any(|t| self.materials[t.material as usize].flags & kdray_shared::MAT_MIRROR != 0)
    }

    /// Fails on a scene with nothing to trace.
    pub fn validate(&self) -> Result<()> {
        if self.triangles.is_empty() {
            bail!("{}: the scene has no triangles", self.name);
        }
        Ok(())
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for v in [t.v0, t.v1, t.v2] {
                lo = lo.min(Vec3::from(v));
                hi = hi.max(Vec3::from(v));
            }
        }
        (lo, hi)
    }

    /// Lights to sample: every emissive triangle (chosen with probability ∝ area · luminance)
    /// and every point light (∝ luminance of intensity), with the running `cdf` filled in.
    pub fn lights(&self) -> Vec<Light> {
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mut lights = Vec::new();
        let mut weights = Vec::new();
        for t in &self.triangles {
            let e = self.materials[t.material as usize].emission;
            if lum(e) <= 0.0 {
                continue;
            }
            let (v0, v1, v2) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
            let area = 0.5 * (v1 - v0).cross(v2 - v0).length();
            lights.push(Light {
                p0: t.v0,
                kind: LIGHT_TRIANGLE,
                e1: (v1 - v0).to_array(),
                cdf: 0.0,
                e2: (v2 - v0).to_array(),
                area,
                emission: e,
                _pad: 0,
            });
            weights.push(area as f64 * lum(e) as f64);
        }
        for p in &self.point_lights {
            lights.push(Light {
                p0: p.position.to_array(),
                kind: LIGHT_POINT,
                emission: p.intensity.to_array(),
                ..Default::default()
            });
            weights.push(lum(p.intensity.to_array()) as f64);
        }
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0;
        for (l, w) in lights.iter_mut().zip(&weights) {
            acc += w;
            l.cdf = (acc / total) as f32;
        }
        if let Some(last) = lights.last_mut() {
            last.cdf = 1.0;
        }
        lights
    }
}

/// Loads a scene by name: a built-in one (`cornell`, `cornell-chair`, `chairs:K`,
/// `conference`), a `.obj` file or a `.toml` scene file.
pub fn load(spec: &str) -> Result<Scene> {
    let scene = match spec {
        "cornell" => cornell::cornell_box(),
        "cornell-mirror" => cornell::cornell_mirror(),
        "cornell-mirrors" => cornell::cornell_mirrors(),
        "cornell-chair" => procedural::cornell_chair()?,
        "conference" => procedural::conference()?,
        s if s.starts_with("chairs:") => match s["chairs:".len()..].parse::<u32>() {
            Ok(k) => procedural::chairs(k)?,
            Err(_) => bail!("'{s}': use chairs:K with K = 1, 4, 16, …, 4096"),
        },
        s if s.ends_with(".obj") => obj::load_obj_scene(std::path::Path::new(s))?,
        s if s.ends_with(".toml") => file::load_scene_file(std::path::Path::new(s))?,
        s => bail!("unknown scene '{s}': use cornell, cornell-mirror, cornell-mirrors, cornell-chair, chairs:K, conference, a .obj file or a .toml scene file"),
    };
    scene.validate()?;
    Ok(scene)
}
