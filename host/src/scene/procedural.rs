//! Scenes the project generates itself: a tessellated chair (~1 464 triangles), `chairs:K` (a
//! square grid of K chairs seen from above: the scaling scene of the photon-mapping paper), the
//! Cornell box with a chair, and a conference room of about 280 000 triangles standing in for
//! Greg Ward's Conference scene, and `soup:N` (random triangles). All closed meshes are built
//! from shared vertex positions.
use super::{CameraSpec, PointLight, Scene};
use crate::error::{bail, Result};
use glam::{Mat3, Vec3};
use kdray_shared::Material;

/// A triangle soup being assembled: positions and index triples.
#[derive(Default, Clone)]
pub struct Mesh {
    /// Vertex positions.
    pub v: Vec<Vec3>,
    /// Triangles as three indices into `v`.
    pub f: Vec<[u32; 3]>,
}

impl Mesh {
    fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.f.push([a, b, c]);
        self.f.push([a, c, d]);
    }

    /// Rounded box centred at the origin: half extents `h`, edge radius `r`, each cube face
    /// subdivided n × n (12 n² triangles).
    pub fn rounded_box(h: Vec3, r: f32, n: u32) -> Mesh {
        let mut m = Mesh::default();
        let inner = (h - Vec3::splat(r)).max(Vec3::ZERO);
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let base = m.v.len() as u32;
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                for j in 0..=n {
                    for i in 0..=n {
                        let mut c = Vec3::ZERO;
                        c[axis] = sign;
                        c[u] = -1.0 + 2.0 * i as f32 / n as f32;
                        c[v] = -1.0 + 2.0 * j as f32 / n as f32;
                        let p = c * h;
                        let q = p.clamp(-inner, inner);
                        let d = p - q;
                        m.v.push(if d.length_squared() > 0.0 { q + d.normalize() * r } else { p });
                    }
                }
                for j in 0..n {
                    for i in 0..n {
                        let a = base + j * (n + 1) + i;
                        let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
                        if sign > 0.0 { m.quad(a, b, c, d) } else { m.quad(a, d, c, b) }
                    }
                }
            }
        }
        m
    }

    /// Closed cylinder along +y from the origin: radius, height, `seg` segments (4·seg triangles).
    pub fn cylinder(radius: f32, height: f32, seg: u32) -> Mesh {
        let mut m = Mesh::default();
        for k in 0..seg {
            let a = k as f32 / seg as f32 * std::f32::consts::TAU;
            let (x, z) = (a.cos() * radius, a.sin() * radius);
            m.v.push(Vec3::new(x, 0.0, z));
            m.v.push(Vec3::new(x, height, z));
        }
        let bottom = m.v.len() as u32;
        m.v.push(Vec3::ZERO);
        m.v.push(Vec3::new(0.0, height, 0.0));
        for k in 0..seg {
            let (a, b) = (2 * k, 2 * ((k + 1) % seg));
            m.quad(a, a + 1, b + 1, b);
            m.f.push([bottom, a, b]);
            m.f.push([bottom + 1, b + 1, a + 1]);
        }
        m
    }

    /// Appends `o` rotated about +y by `yaw`, scaled, then moved by `at`.
    pub fn add(&mut self, o: &Mesh, at: Vec3, yaw: f32, scale: f32) {
        let base = self.v.len() as u32;
        let rot = Mat3::from_rotation_y(yaw);
        self.v.extend(o.v.iter().map(|p| rot * (*p * scale) + at));
        self.f.extend(o.f.iter().map(|t| t.map(|i| i + base)));
    }

    /// Adds every triangle to `scene` with `material` through `Scene::add_triangle` (errors name
    /// `what`; zero-area triangles are dropped and counted). Panics on an index outside `v`.
    pub fn into_scene(&self, scene: &mut Scene, material: u32, what: &str) -> Result<()> {
        for t in &self.f {
            let v = t.map(|i| self.v[i as usize]);
            scene.add_triangle(v, material, &|| format!("{what} (generated)"))?;
        }
        Ok(())
    }
}

/// A chair 0.9 high standing (2 mm above) y = 0, seat centred on the origin, back toward −z:
/// four cylindrical legs, a rounded seat, a rounded back and a cross bar (1 468 triangles).
pub fn chair() -> Mesh {
    let mut m = Mesh::default();
    // Legs stand 2 mm above y = 0 and reach 1 cm into the seat: no face of the chair is
    // coplanar with another one or with a floor (coplanar overlaps make "the" hit ambiguous).
    let leg = Mesh::cylinder(0.02, 0.438, 16);
    for (x, z) in [(-0.19, -0.19), (0.19, -0.19), (-0.19, 0.19), (0.19, 0.19)] {
        m.add(&leg, Vec3::new(x, 0.002, z), 0.0, 1.0);
    }
    m.add(&Mesh::rounded_box(Vec3::new(0.23, 0.025, 0.23), 0.02, 8), Vec3::new(0.0, 0.455, 0.0), 0.0, 1.0);
    m.add(&Mesh::rounded_box(Vec3::new(0.23, 0.2, 0.02), 0.015, 6), Vec3::new(0.0, 0.7, -0.21), 0.0, 1.0);
    m.add(&Mesh::rounded_box(Vec3::new(0.19, 0.01, 0.01), 0.0, 1), Vec3::new(0.0, 0.15, 0.19), 0.0, 1.0);
    m
}

fn diffuse(c: [f32; 3]) -> Material {
    Material { diffuse: c, ..Default::default() }
}

/// `chairs:K`: K chairs (K = 4^i, 1 ≤ K ≤ 4096) on a floor, in a square grid seen from above.
pub fn chairs(k: u32) -> Result<Scene> {
    let side = (k as f64).sqrt().round() as u32;
    if k == 0 || side * side != k || !side.is_power_of_two() || k > 4096 {
        bail!(Scene: "chairs:{k}: K must be 1, 4, 16, … (a power of 4) up to 4096");
    }
    let spacing = 0.8;
    let half = side as f32 * spacing * 0.5;
    let height = half * 1.15 / (20f32.to_radians()).tan() + 1.0;
    let mut s = Scene::new(
        format!("chairs-{k}"),
        CameraSpec { eye: Vec3::new(0.0, height, 0.0), look_at: Vec3::ZERO, up: Vec3::NEG_Z, fov_y_deg: 40.0 },
    );
    let wood = s.add_material("wood", diffuse([0.55, 0.35, 0.2]));
    let floor = s.add_material("floor", diffuse([0.6, 0.6, 0.6]));
    let c = chair();
    let mut all = Mesh::default();
    for j in 0..side {
        for i in 0..side {
            let at = Vec3::new((i as f32 + 0.5) * spacing - half, 0.0, (j as f32 + 0.5) * spacing - half);
            all.add(&c, at, ((i * 7 + j * 3) % 8) as f32 * 0.4, 1.0);
        }
    }
    all.into_scene(&mut s, wood, "chair")?;
    let e = half + 0.5;
    s.add_quad([Vec3::new(-e, 0.0, -e), Vec3::new(-e, 0.0, e), Vec3::new(e, 0.0, e), Vec3::new(e, 0.0, -e)], floor)?;
    s.point_lights.push(PointLight { position: Vec3::new(half * 0.3, height * 0.8, half * 0.5), intensity: Vec3::splat(0.6 * height * height), spot: None });
    Ok(s)
}

/// The Cornell box with a chair (scaled ×300) in place of the two blocks.
pub fn cornell_chair() -> Result<Scene> {
    let base = super::load("cornell")?;
    let mut s = Scene::new("cornell-chair", base.camera.clone());
    for (name, m) in base.material_names.iter().zip(&base.materials) {
        s.add_material(name, *m);
    }
    // Walls and light: the first 12 triangles (light, floor, ceiling, back, right, left).
    for t in base.triangles.iter().take(12) {
        s.add_triangle([t.v0, t.v1, t.v2].map(Vec3::from), t.material, &|| "cornell wall".into())?;
    }
    let white = s.material_id("white").expect("cornell has white");
    let mut m = Mesh::default();
    m.add(&chair(), Vec3::new(278.0, 0.0, 300.0), 0.5, 300.0);
    m.into_scene(&mut s, white, "chair")?;
    Ok(s)
}

/// A closed conference room (24 × 3.2 × 12): a long table with 24 chairs, 160 audience chairs
/// in 8 rows, 12 ceiling lamps (emissive panels under spheres) — about 280 000 triangles.
pub fn conference() -> Result<Scene> {
    let (w, h, d) = (24.0f32, 3.2f32, 12.0f32);
    let mut s = Scene::new(
        "conference",
        CameraSpec { eye: Vec3::new(-11.0, 2.4, 5.2), look_at: Vec3::new(2.0, 0.6, -1.0), up: Vec3::Y, fov_y_deg: 55.0 },
    );
    let wall = s.add_material("wall", diffuse([0.7, 0.68, 0.62]));
    let floor = s.add_material("carpet", diffuse([0.25, 0.22, 0.3]));
    let wood = s.add_material("wood", diffuse([0.5, 0.3, 0.15]));
    let seat = s.add_material("seat", diffuse([0.15, 0.2, 0.45]));
    let lamp = s.add_material("lamp", diffuse([0.8, 0.8, 0.8]));
    let light = s.add_material("light", Material { diffuse: [0.8; 3], emission: [40.0, 37.0, 33.0], ..Default::default() });
    let (x0, x1, z0, z1) = (-w / 2.0, w / 2.0, -d / 2.0, d / 2.0);
    let p = |x, y, z| Vec3::new(x, y, z);
    s.add_quad([p(x0, 0.0, z0), p(x1, 0.0, z0), p(x1, 0.0, z1), p(x0, 0.0, z1)], floor)?;
    s.add_quad([p(x0, h, z0), p(x0, h, z1), p(x1, h, z1), p(x1, h, z0)], wall)?;
    s.add_quad([p(x0, 0.0, z0), p(x0, h, z0), p(x1, h, z0), p(x1, 0.0, z0)], wall)?;
    s.add_quad([p(x0, 0.0, z1), p(x1, 0.0, z1), p(x1, h, z1), p(x0, h, z1)], wall)?;
    s.add_quad([p(x0, 0.0, z0), p(x0, 0.0, z1), p(x0, h, z1), p(x0, h, z0)], wall)?;
    s.add_quad([p(x1, 0.0, z0), p(x1, h, z0), p(x1, h, z1), p(x1, 0.0, z1)], wall)?;
    // The table: a rounded top on four legs, at x in [-5, 5], z in [-2.6, -1.4].
    let mut table = Mesh::default();
    table.add(&Mesh::rounded_box(Vec3::new(5.0, 0.04, 0.6), 0.03, 16), p(0.0, 0.74, -2.0), 0.0, 1.0);
    for (x, z) in [(-4.7, -2.4), (4.7, -2.4), (-4.7, -1.6), (4.7, -1.6)] {
        table.add(&Mesh::cylinder(0.05, 0.708, 24), p(x, 0.002, z), 0.0, 1.0);
    }
    table.into_scene(&mut s, wood, "table")?;
    let c = chair();
    let mut chairs = Mesh::default();
    for i in 0..12 {
        let x = -4.4 + i as f32 * 0.8;
        chairs.add(&c, p(x, 0.0, -2.95), 0.0, 1.0);
        chairs.add(&c, p(x, 0.0, -1.05), std::f32::consts::PI, 1.0);
    }
    for row in 0..8 {
        for i in 0..20 {
            chairs.add(&c, p(-9.5 + i as f32 * 1.0, 0.0, 0.4 + row as f32 * 0.7), std::f32::consts::PI, 1.0);
        }
    }
    chairs.into_scene(&mut s, seat, "chair")?;
    let mut lamps = Mesh::default();
    let shade = sphere(0.25, 3);
    for j in 0..2 {
        for i in 0..6 {
            let (x, z) = (-9.0 + i as f32 * 3.6, -3.0 + j as f32 * 4.0);
            lamps.add(&shade, p(x, h - 0.45, z), 0.0, 1.0);
            let y = h - 0.72;
            s.add_quad([p(x - 0.2, y, z - 0.2), p(x + 0.2, y, z - 0.2), p(x + 0.2, y, z + 0.2), p(x - 0.2, y, z + 0.2)], light)?;
        }
    }
    lamps.into_scene(&mut s, lamp, "lamp")?;
    Ok(s)
}

/// `soup:N[:S]`: N random triangles in the unit cube (a fixed seed), each with its vertices
/// uniform in a cube of side S (default 1: the whole cube) around a uniform centre: large
/// overlapping triangles, the worst case for a kd-tree's reference duplication and the BVH's
/// kind of scene. A point light above and a camera in front.
pub fn soup(n: u32, size: f32) -> Result<Scene> {
    if n == 0 || n > 1 << 24 {
        bail!(Scene: "soup:{n}: N must be between 1 and 16 777 216");
    }
    if !(size > 0.0 && size <= 1.0) {
        bail!(Scene: "soup:{n}:{size}: the triangles' size S must be in (0, 1]");
    }
    let mut s = Scene::new(
        if size == 1.0 { format!("soup-{n}") } else { format!("soup-{n}-{size}") },
        CameraSpec { eye: Vec3::new(0.5, 0.6, -1.6), look_at: Vec3::splat(0.5), up: Vec3::Y, fov_y_deg: 40.0 },
    );
    let grey = s.add_material("grey", diffuse([0.6, 0.6, 0.6]));
    let mut rng = kdray_shared::rng::Rng::new(0x50C9_5EED, 0);
    let mut unit = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    for _ in 0..n {
        // The centre keeps the whole triangle inside the unit cube.
        let c = Vec3::splat(size * 0.5) + unit() * (1.0 - size);
        let v = [0, 1, 2].map(|_| c + (unit() - Vec3::splat(0.5)) * size);
        s.add_triangle(v, grey, &|| "soup triangle (generated)".into())?;
    }
    s.point_lights.push(PointLight { position: Vec3::new(0.3, 2.0, -0.8), intensity: Vec3::splat(4.0), spot: None });
    Ok(s)
}

/// Icosphere of `subdiv` subdivisions (20·4^subdiv triangles) centred at the origin.
pub fn sphere(radius: f32, subdiv: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        (-1.0, t, 0.0), (1.0, t, 0.0), (-1.0, -t, 0.0), (1.0, -t, 0.0),
        (0.0, -1.0, t), (0.0, 1.0, t), (0.0, -1.0, -t), (0.0, 1.0, -t),
        (t, 0.0, -1.0), (t, 0.0, 1.0), (-t, 0.0, -1.0), (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
        [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
        [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..subdiv {
        let mut mid = std::collections::HashMap::new();
        let mut nf = Vec::with_capacity(f.len() * 4);
        for tri in &f {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                    (v.len() - 1) as u32
                });
            }
            nf.extend([[tri[0], m[0], m[2]], [tri[1], m[1], m[0]], [tri[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        f = nf;
    }
    Mesh { v: v.into_iter().map(|p| p * radius).collect(), f }
}
