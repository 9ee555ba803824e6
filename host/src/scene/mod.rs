//! Scenes: triangles with materials, lights and a camera, validated on the way in.
pub mod file;
pub mod mitsuba;
pub mod obj;
pub mod procedural;

use rayon::prelude::*;
use crate::error::{bail, Context, Result};
use glam::Vec3;
use std::path::Path;
use kdray_shared::{Camera, Light, Material, Triangle, LIGHT_POINT, LIGHT_SPOT, LIGHT_TRIANGLE};

/// Where the camera is and what it sees; turned into the GPU `Camera` for a given resolution.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSpec {
    /// Position of the pinhole: where every camera ray starts.
    pub eye: Vec3,
    /// The point the camera looks at (the image centre).
    pub look_at: Vec3,
    /// Up direction: need not be unit length or perpendicular to the view, only not parallel to it.
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

/// A point light: emits `intensity` W/sr in every direction, or as a spot light inside a cone.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    /// Where the light is.
    pub position: Vec3,
    /// Radiant intensity per RGB channel (W/sr); a spot light's on its axis.
    pub intensity: Vec3,
    /// `Some` makes it a spot light, shining only inside the cone.
    pub spot: Option<Spot>,
}

/// A spot light's cone: unit axis, half angle and the angle where the falloff starts (degrees).
#[derive(Clone, Debug, PartialEq)]
pub struct Spot {
    /// The cone's axis, the direction the light shines (normalised when the lights are built).
    pub direction: Vec3,
    /// Half angle of the cone in degrees: no light beyond it.
    pub cone_deg: f32,
    /// Half angle in degrees within which the intensity is full; it falls smoothly to 0 at `cone_deg`.
    pub falloff_start_deg: f32,
}

/// A scene: triangles with materials, point and spot lights, and a camera. Emissive triangles
/// are lights too (see `lights`).
#[derive(Clone, Debug)]
pub struct Scene {
    /// Names the scene in error messages, warnings and reports.
    pub name: String,
    /// The triangles; `Hit::prim` indexes this list.
    pub triangles: Vec<Triangle>,
    /// The materials, indexed by `Triangle::material`.
    pub materials: Vec<Material>,
    /// Each material's name, in the order of `materials`.
    pub material_names: Vec<String>,
    /// Point and spot lights.
    pub point_lights: Vec<PointLight>,
    /// The camera.
    pub camera: CameraSpec,
    /// Zero-area triangles dropped while building (they can never be hit).
    pub dropped_degenerate: usize,
    /// What loading the scene let pass but a user should hear of (e.g. an MTL file that could
    /// not be read), without the `warning: ` prefix; the library prints nothing itself.
    pub warnings: Vec<String>,
}

impl Scene {
    /// An empty scene (no triangles, materials or lights) with this name and camera.
    pub fn new(name: impl Into<String>, camera: CameraSpec) -> Self {
        Scene {
            name: name.into(),
            triangles: Vec::new(),
            materials: Vec::new(),
            material_names: Vec::new(),
            point_lights: Vec::new(),
            camera,
            dropped_degenerate: 0,
            warnings: Vec::new(),
        }
    }

    /// A scene of one indexed triangle mesh (grey diffuse, no lights, a camera framing it):
    /// what a user tracing rays at their own geometry starts from. `faces` index `vertices`;
    /// an index out of range, a non-finite vertex or a mesh with no triangle of non-zero area
    /// is an error naming the face. Faces of zero area are dropped (counted in
    /// `dropped_degenerate`); `Hit::prim` indexes `triangles`, whose `face` is the face number.
    ///
    /// ```
    /// let s = kdray::Scene::from_mesh("quad", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2], [0, 2, 3]]).unwrap();
    /// assert_eq!(s.triangles.len(), 2);
    /// assert!(kdray::Scene::from_mesh("bad", &[[0.0; 3]; 3], &[[0, 1, 3]]).is_err());
    /// ```
    pub fn from_mesh(name: &str, vertices: &[[f32; 3]], faces: &[[u32; 3]]) -> Result<Scene> {
        let mut s = Scene::new(name, CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
        let grey = s.add_material("default", Material { diffuse: [0.8; 3], ..Default::default() });
        for (i, f) in faces.iter().enumerate() {
            let mut v = [Vec3::ZERO; 3];
            for k in 0..3 {
                let Some(p) = vertices.get(f[k] as usize) else {
                    bail!(Scene: "{name}: face {i}: vertex index {} out of range ({} vertices)", f[k], vertices.len());
                };
                v[k] = Vec3::from_array(*p);
            }
            s.add_triangle(v, grey, &|| format!("{name}: face {i}"))?;
        }
        if s.triangles.is_empty() {
            bail!(Scene: "{name}: no triangle of non-zero area among {} faces", faces.len());
        }
        let (lo, hi) = s.bounds();
        s.camera = CameraSpec::framing(lo, hi);
        Ok(s)
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

    /// Material id of the material named `name`, if there is one.
    pub fn material_id(&self, name: &str) -> Option<u32> {
        self.material_names.iter().position(|n| n == name).map(|i| i as u32)
    }

    /// Adds a triangle. Non-finite coordinates are an error (`what` names the source, e.g.
    /// "scene.obj: face 12"); a triangle of exactly zero area is dropped and counted.
    pub fn add_triangle(&mut self, v: [Vec3; 3], material: u32, what: &dyn Fn() -> String) -> Result<()> {
        if !v.iter().all(|p| p.is_finite()) {
            bail!(Scene: "{}: vertex coordinates are not finite ({:?}, {:?}, {:?})", what(), v[0], v[1], v[2]);
        }
        if (material as usize) >= self.materials.len() {
            bail!(Scene: "{}: material id {} does not exist", what(), material);
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

    /// Whether any triangle is a mirror.
    pub fn has_mirror(&self) -> bool {
        self.triangles.iter().any(|t| self.materials[t.material as usize].flags & kdray_shared::MAT_MIRROR != 0)
    }

    /// Whether any triangle is a mirror or glass (only then are specular bounces traced).
    pub fn has_specular(&self) -> bool {
        self.triangles.iter().any(|t| kdray_shared::shade::is_specular(&self.materials[t.material as usize]))
    }

    /// Fails on a scene with nothing to trace or with inputs that would make the renderer
    /// produce NaN or infinity: non-finite or negative material colours, point lights or camera
    /// values, a degenerate camera, and lights whose power overflows f32. The loaders report
    /// the same problems earlier, naming the file; this catches scenes built in code.
    pub fn validate(&self) -> Result<()> {
        let name = &self.name;
        if self.triangles.is_empty() {
            bail!(Scene: "{name}: the scene has no triangles");
        }
        if self.material_names.len() != self.materials.len() {
            bail!(Scene: "{name}: {} materials but {} material names", self.materials.len(), self.material_names.len());
        }
        // Triangles pushed directly (the field is public) get the checks `add_triangle` makes.
        for t in &self.triangles {
            if t.material as usize >= self.materials.len() {
                bail!(Scene: "{name}: face {}: material id {} does not exist", t.face, t.material);
            }
            if ![t.v0, t.v1, t.v2].iter().flatten().all(|c| c.is_finite()) {
                bail!(Scene: "{name}: face {}: vertex coordinates are not finite ({:?}, {:?}, {:?})", t.face, t.v0, t.v1, t.v2);
            }
        }
        for (m, mname) in self.materials.iter().zip(&self.material_names) {
            check_color(name, &format!("material '{mname}' diffuse"), m.diffuse)?;
            check_color(name, &format!("material '{mname}' emission"), m.emission)?;
        }
        for (i, p) in self.point_lights.iter().enumerate() {
            check_finite(name, &format!("point light {} position", i + 1), p.position.to_array())?;
            check_color(name, &format!("point light {} intensity", i + 1), p.intensity.to_array())?;
        }
        self.camera.check(name)?;
        self.check_light_powers()
    }

    /// Every light's power as the renderer computes it (f32: emission × area for emissive
    /// triangles, intensity for point lights) and the lights' total power must be finite.
    fn check_light_powers(&self) -> Result<()> {
        let name = &self.name;
        let mut total = 0.0f64;
        for (light, weight, source) in self.light_entries() {
            let power = light.emission.map(|e| e * if light.kind == LIGHT_TRIANGLE { light.area } else { 1.0 });
            if !(light.area.is_finite() && power.iter().all(|p| p.is_finite()) && weight.is_finite()) {
                let what = match source {
                    LightSource::Triangle(i) => {
                        let t = &self.triangles[i];
                        format!(
                            "emissive triangle {} (material '{}') has a non-finite power: area {:e} × emission {:?} overflows f32",
                            t.face, self.material_names[t.material as usize], light.area, light.emission
                        )
                    }
                    LightSource::Point(i) => {
                        format!("point light {} has a non-finite power: intensity {:?}", i + 1, light.emission)
                    }
                };
                bail!(Scene: "{name}: {what}");
            }
            total += weight;
        }
        if !(total as f32).is_finite() {
            bail!(Scene: "{name}: the lights' total power {total:e} (area × luminance) overflows f32");
        }
        Ok(())
    }


    /// The area of the surfaces photons land on (every non-emissive triangle), in f64.
    pub fn surface_area(&self) -> f64 {
        self.triangles
            .iter()
            .filter(|t| self.materials[t.material as usize].emission == [0.0; 3])
            .map(|t| {
                let (a, b, c) = (Vec3::from(t.v0).as_dvec3(), Vec3::from(t.v1).as_dvec3(), Vec3::from(t.v2).as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// The box (min, max) around every triangle's vertices; (+∞, −∞) when there are no triangles.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        // In chunks over the cores (minima and maxima: the same box in any order).
        let empty = || (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        self.triangles
            .par_chunks(1 << 14)
            .map(|c| {
                let (mut lo, mut hi) = empty();
                for t in c {
                    for v in [t.v0, t.v1, t.v2] {
                        lo = lo.min(Vec3::from(v));
                        hi = hi.max(Vec3::from(v));
                    }
                }
                (lo, hi)
            })
            .reduce(empty, |a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Lights to sample: every emissive triangle (chosen with probability ∝ area · luminance)
    /// and every point light (∝ luminance of intensity), with the running `cdf` filled in.
    ///
    /// A light that emits nothing is not a light and is skipped: zero luminance (black: with
    /// negative components rejected at load time, and the luminance taken in f64, any positive
    /// component gives a positive luminance), or an emissive triangle so small that its normal
    /// underflows in f32 (its samples would be NaN). So every light returned has a positive
    /// weight, and a scene whose lights all emit nothing has none (no shadow rays; the image is
    /// the same). The weights are computed in f64 from f32 inputs: finite inputs give finite
    /// weights and a finite, positive total. Should the weights still be unusable (a scene
    /// built in code with NaN, infinite or negative emission, which `validate` rejects, or a
    /// total of 0), the lights are chosen uniformly instead, so the `cdf` is never NaN.
    /// (A light's f32 `area` or power may still overflow for finite but huge inputs;
    /// `validate` rejects those.)
    pub fn lights(&self) -> Vec<Light> {
        let entries = self.light_entries();
        let weights: Vec<f64> = entries.iter().map(|e| e.1).collect();
        let mut lights: Vec<Light> = entries.into_iter().map(|e| e.0).collect();
        fill_cdf(&mut lights, &weights);
        let powers: Vec<f64> = lights.iter().map(power).collect();
        let mut cdf: Vec<Light> = lights.clone();
        fill_cdf(&mut cdf, &powers);
        for (l, c) in lights.iter_mut().zip(&cdf) {
            l.power_cdf = c.cdf;
        }
        lights
    }

    /// The lights with their selection weights (area · luminance, or luminance) and where each
    /// comes from; `cdf` is left at 0.
    fn light_entries(&self) -> Vec<(Light, f64, LightSource)> {
        let mut out = Vec::new();
        let lums: Vec<f64> = self.materials.iter().map(|m| luminance(m.emission)).collect();
        for (i, t) in self.triangles.iter().enumerate() {
            let lum = lums[t.material as usize];
            if lum == 0.0 {
                continue;
            }
            let e = self.materials[t.material as usize].emission;
            let (v0, v1, v2) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
            let cross = (v1 - v0).cross(v2 - v0);
            if cross.length_squared() == 0.0 {
                continue;
            }
            let area = 0.5 * cross.length();
            let (d0, d1, d2) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
            let area64 = 0.5 * (d1 - d0).cross(d2 - d0).length();
            let light = Light {
                p0: t.v0,
                kind: LIGHT_TRIANGLE,
                e1: (v1 - v0).to_array(),
                cdf: 0.0,
                e2: (v2 - v0).to_array(),
                area,
                emission: e,
                power_cdf: 0.0,
            };
            out.push((light, weight(area, area64, e), LightSource::Triangle(i)));
        }
        for (i, p) in self.point_lights.iter().enumerate() {
            let lum = luminance(p.intensity.to_array());
            if lum == 0.0 {
                continue;
            }
            let mut light = Light {
                p0: p.position.to_array(),
                kind: LIGHT_POINT,
                emission: p.intensity.to_array(),
                ..Default::default()
            };
            if let Some(s) = &p.spot {
                light.kind = LIGHT_SPOT;
                light.e1 = s.direction.normalize().to_array();
                light.e2 = [s.cone_deg.to_radians().cos(), s.falloff_start_deg.to_radians().cos(), 0.0];
            }
            out.push((light, weight(1.0, 1.0, p.intensity.to_array()), LightSource::Point(i)));
        }
        out
    }
}

/// Where a light of `Scene::light_entries` comes from (an index into `triangles` or
/// `point_lights`), for error messages.
#[derive(Copy, Clone, Debug)]
enum LightSource {
    Triangle(usize),
    Point(usize),
}

/// A light's selection weight, area · luminance: computed in f32 as the renderer always has
/// (the same weights, so the same light samples and images as before), and in f64 only where
/// the f32 product is not positive and finite (tiny or huge lights).
fn weight(area: f32, area64: f64, c: [f32; 3]) -> f64 {
    let lum32 = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let w = area as f64 * lum32 as f64;
    if w > 0.0 && w.is_finite() {
        w
    } else {
        area64 * luminance(c)
    }
}

/// A light's emitted power (luminance, watts), the weight of photon emission: π·area·L for
/// an emissive triangle (front side), 4π·I for a point light, 2π·I·(1 − (cos start + cos end)/2)
/// for a spot light (pbrt-v4's).
pub fn power(l: &Light) -> f64 {
    use std::f64::consts::PI;
    let lum = luminance(l.emission);
    match l.kind {
        LIGHT_POINT => 4.0 * PI * lum,
        LIGHT_SPOT => 2.0 * PI * lum * (1.0 - 0.5 * (l.e2[0] as f64 + l.e2[1] as f64)),
        _ => PI * l.area as f64 * lum,
    }
}

/// Rec. 709 luminance, in f64 so that no positive component rounds away.
fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Fills the running `cdf` of `lights` from their `weights`: proportional when every weight is
/// finite and non-negative and the total is positive and finite, uniform otherwise; the last
/// light's is 1.
pub(crate) fn fill_cdf(lights: &mut [Light], weights: &[f64]) {
    let n = lights.len();
    let total: f64 = weights.iter().sum();
    let proportional = total > 0.0 && total.is_finite() && weights.iter().all(|w| w.is_finite() && *w >= 0.0);
    let mut acc = 0.0;
    for (i, (l, w)) in lights.iter_mut().zip(weights).enumerate() {
        l.cdf = if proportional {
            acc += w;
            (acc / total) as f32
        } else {
            ((i + 1) as f64 / n as f64) as f32
        };
    }
    if let Some(last) = lights.last_mut() {
        last.cdf = 1.0;
    }
}

/// `v` must be finite: an error naming `what` of `name` otherwise.
pub(crate) fn check_finite(name: &str, what: &str, v: [f32; 3]) -> Result<Vec3> {
    if !v.iter().all(|x| x.is_finite()) {
        bail!(Scene: "{name}: {what} is not finite: {v:?}");
    }
    Ok(Vec3::from(v))
}

/// A colour (reflectance, emission, intensity) must be finite and non-negative.
pub(crate) fn check_color(name: &str, what: &str, v: [f32; 3]) -> Result<[f32; 3]> {
    check_finite(name, what, v)?;
    if v.iter().any(|x| *x < 0.0) {
        bail!(Scene: "{name}: {what} is negative: {v:?}");
    }
    Ok(v)
}

impl CameraSpec {
    /// Finite eye, look_at and up, a field of view strictly between 0 and 180 degrees, and a
    /// view direction that exists and is not parallel to `up` (else every ray is NaN).
    pub fn check(&self, name: &str) -> Result<()> {
        check_finite(name, "camera eye", self.eye.to_array())?;
        check_finite(name, "camera look_at", self.look_at.to_array())?;
        check_finite(name, "camera up", self.up.to_array())?;
        let fov = self.fov_y_deg;
        if !(fov > 0.0 && fov < 180.0) {
            bail!(Scene: "{name}: camera fov_y must be between 0 and 180 degrees (exclusive), got {fov}");
        }
        let forward = (self.look_at - self.eye).normalize_or_zero();
        if forward == Vec3::ZERO || !forward.is_finite() {
            bail!(Scene: "{name}: camera eye and look_at must be distinct points, got {} and {}", self.eye, self.look_at);
        }
        let right = forward.cross(self.up).normalize_or_zero();
        if right == Vec3::ZERO || !right.is_finite() {
            bail!(Scene: "{name}: camera up {} is zero or parallel to the view direction {}", self.up, forward);
        }
        Ok(())
    }
}

/// The scene files of the repository's `scenes/` folder that are built-in scenes, compiled in
/// (`host/scenes` links to that folder, so the published crate carries them too).
const BUILTIN_FILES: &[(&str, &str)] = &[
    ("cornell.toml", include_str!("../../scenes/cornell.toml")),
    ("cornell-mirror.toml", include_str!("../../scenes/cornell-mirror.toml")),
    ("cornell-mirrors.toml", include_str!("../../scenes/cornell-mirrors.toml")),
    ("cornell-glass.toml", include_str!("../../scenes/cornell-glass.toml")),
    ("cornell.obj", include_str!("../../scenes/cornell.obj")),
    ("cornell.mtl", include_str!("../../scenes/cornell.mtl")),
];

/// Where a scene file's own file references (meshes, `mtllib`) are read from: a folder, or the
/// built-in copy of `scenes/`.
#[derive(Copy, Clone, Debug)]
pub enum Files<'a> {
    /// Relative to this folder.
    Dir(&'a Path),
    /// The built-in scene files (`scenes/` as compiled in).
    Builtin,
}

impl Files<'_> {
    /// The name of `file` in messages: its path, or `scenes/…` (built in).
    pub fn name(&self, file: &Path) -> String {
        match self {
            Files::Dir(d) => d.join(file).display().to_string(),
            Files::Builtin => Path::new("scenes").join(file).display().to_string(),
        }
    }

    /// The bytes of `file`.
    pub fn read(&self, file: &Path) -> Result<Vec<u8>> {
        match self {
            Files::Dir(d) => std::fs::read(d.join(file)).with_context(|| format!("cannot read {}", self.name(file))),
            Files::Builtin => match BUILTIN_FILES.iter().find(|(n, _)| Path::new(n) == file) {
                Some((_, text)) => Ok(text.as_bytes().to_vec()),
                None => bail!(Scene: "{}: not a built-in scene file", self.name(file)),
            },
        }
    }
}

/// The built-in scenes that are scene files in `scenes/` (`NAME.toml`, compiled in).
pub const FILE_SCENES: &[&str] = &["cornell", "cornell-mirror", "cornell-mirrors", "cornell-glass"];

/// Loads a scene by name: a built-in one (`cornell`, `cornell-mirror`, `cornell-mirrors`,
/// `cornell-glass` — the scene files of `scenes/`, compiled in — and the generated
/// `cornell-chair`, `chairs:K`, `conference`, `soup:N[:S]`), a `.obj` file or a `.toml` scene
/// file.
pub fn load(spec: &str) -> Result<Scene> {
    let scene = match spec {
        s if FILE_SCENES.contains(&s) => file::load_scene(Files::Builtin, Path::new(&format!("{s}.toml")))?,
        "cornell-chair" => procedural::cornell_chair()?,
        "conference" => procedural::conference()?,
        s if s.starts_with("chairs:") => match s["chairs:".len()..].parse::<u32>() {
            Ok(k) => procedural::chairs(k)?,
            Err(_) => bail!(Scene: "'{s}': use chairs:K with K = 1, 4, 16, …, 4096"),
        },
        s if s.starts_with("soup:") => {
            let mut args = s["soup:".len()..].splitn(2, ':');
            match (args.next().map(str::parse::<u32>), args.next().map(str::parse::<f32>)) {
                (Some(Ok(n)), None) => procedural::soup(n, 1.0)?,
                (Some(Ok(n)), Some(Ok(size))) => procedural::soup(n, size)?,
                _ => bail!(Scene: "'{s}': use soup:N or soup:N:S (N random triangles of size S in the unit cube)"),
            }
        }
        s if has_extension(s, "obj") => in_file(s, obj::load_obj_scene(Path::new(s)))?,
        s if has_extension(s, "toml") => in_file(s, file::load_scene_file(Path::new(s)))?,
        s => bail!(Scene: "unknown scene '{s}': use cornell, cornell-mirror, cornell-mirrors, cornell-glass, cornell-chair, chairs:K, conference, soup:N[:S], a .obj file or a .toml scene file"),
    };
    in_file(spec, scene.validate().map(|_| scene))
}

/// Whether the file `spec` names ends in `.ext`, in any case (`X.OBJ` is an OBJ file).
fn has_extension(spec: &str, ext: &str) -> bool {
    Path::new(spec).extension().is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// A scene file's content errors as `Error::SceneFile` of that file (the generic checks —
/// colours, finiteness, the camera — report `Error::Scene` with the file's name in front).
fn in_file(spec: &str, r: Result<Scene>) -> Result<Scene> {
    match r {
        Err(crate::Error::Scene(msg)) if has_extension(spec, "obj") || has_extension(spec, "toml") => {
            let message = msg.strip_prefix(&format!("{spec}: ")).unwrap_or(&msg).to_string();
            Err(crate::Error::SceneFile { file: spec.to_string(), line: None, message })
        }
        r => r,
    }
}

/// Each triangle's open edges: bit k set where its edge from vertex k to vertex k + 1 (mod 3)
/// is shared by no other triangle (vertices compared by position, exactly, in either
/// direction; −0 as 0): where a surface ends. The final gather near edges looks for them
/// (`kdray_shared::photon::EdgeProbe`): a gather disc that reaches past one counts photons over
/// less than its area.
pub fn open_edges(triangles: &[Triangle]) -> Vec<u32> {
    let point = |v: [f32; 3]| v.map(|c| (c + 0.0).to_bits());
    let mut edges: Vec<([u32; 3], [u32; 3], u32)> = Vec::with_capacity(triangles.len() * 3);
    for (i, t) in triangles.iter().enumerate() {
        let v = [point(t.v0), point(t.v1), point(t.v2)];
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            let (a, b) = if a <= b { (a, b) } else { (b, a) };
            edges.push((a, b, (i * 3 + k) as u32));
        }
    }
    edges.par_sort_unstable_by(|x, y| (x.0, x.1).cmp(&(y.0, y.1)));
    let mut open = vec![0u32; triangles.len()];
    for run in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        if let [(_, _, e)] = run {
            open[(e / 3) as usize] |= 1 << (e % 3);
        }
    }
    open
}
