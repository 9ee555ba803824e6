//! The Cornell box from the Cornell Program of Computer Graphics' published measurements
//! ("Cornell Box Data": millimetres, camera at (278, 273, −800) looking +z, 35 mm focal length
//! on a 25 mm × 25 mm film). Reflectances are the RGB approximations of the measured spectra
//! that RGB renderers commonly use, the light's radiance (17, 12, 4) likewise. The light quad is
//! lowered by 0.1 mm below the ceiling so the emitter and the ceiling are not coplanar.
use super::{CameraSpec, Scene};
use glam::Vec3;
use kdray_shared::Material;

fn quad(s: &mut Scene, pts: [[f32; 3]; 4], m: u32) {
    s.add_quad(pts.map(Vec3::from), m).expect("built-in Cornell box geometry is valid");
}

/// The Cornell box (module docs): walls, floor, ceiling, light and two blocks in 32 triangles
/// of four diffuse materials (the light's emissive), no point lights.
pub fn cornell_box() -> Scene {
    let fov = 2.0 * (12.5f32 / 35.0).atan().to_degrees();
    let mut s = Scene::new(
        "cornell",
        CameraSpec {
            eye: Vec3::new(278.0, 273.0, -800.0),
            look_at: Vec3::new(278.0, 273.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: fov,
        },
    );
    let diffuse = |c: [f32; 3]| Material { diffuse: c, ..Default::default() };
    let white = s.add_material("white", diffuse([0.725, 0.71, 0.68]));
    let red = s.add_material("red", diffuse([0.63, 0.065, 0.05]));
    let green = s.add_material("green", diffuse([0.14, 0.45, 0.091]));
    let light = s.add_material(
        "light",
        Material { diffuse: [0.78, 0.78, 0.78], emission: [17.0, 12.0, 4.0], ..Default::default() },
    );
    // Light (y lowered 0.1 mm from 548.8).
    quad(&mut s, [[343.0, 548.7, 227.0], [343.0, 548.7, 332.0], [213.0, 548.7, 332.0], [213.0, 548.7, 227.0]], light);
    // Floor, ceiling, back wall.
    quad(&mut s, [[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]], white);
    quad(&mut s, [[556.0, 548.8, 0.0], [556.0, 548.8, 559.2], [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]], white);
    quad(&mut s, [[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2], [556.0, 548.8, 559.2]], white);
    // Right wall (green, x = 0) and left wall (red, x ≈ 550).
    quad(&mut s, [[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]], green);
    quad(&mut s, [[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2], [556.0, 548.8, 0.0]], red);
    // Short block.
    for q in [
        [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
        [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
        [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
        [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
        [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
    ] {
        quad(&mut s, q, white);
    }
    // Tall block.
    for q in [
        [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
        [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
        [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
        [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
        [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
    ] {
        quad(&mut s, q, white);
    }
    s
}

/// The Cornell box with a mirror tall block and a mirror back wall (for reflection rays).
pub fn cornell_mirror() -> Scene {
    with_mirrors("cornell-mirror", |i, n| (6..8).contains(&i) || i >= n - 10)
}

/// The Cornell box with mirror walls (back, left, right) and mirror blocks: most paths reflect
/// several times (the reflection-ray benchmark: rays diverge bounce after bounce).
pub fn cornell_mirrors() -> Scene {
    with_mirrors("cornell-mirrors", |i, _| i >= 6)
}

/// The Cornell box with the triangles `mirror(index, count)` made mirrors.
fn with_mirrors(name: &str, is_mirror: impl Fn(usize, usize) -> bool) -> Scene {
    let mut s = cornell_box();
    s.name = name.into();
    let mirror = s.add_material(
        "mirror",
        Material { diffuse: [0.9, 0.9, 0.9], flags: kdray_shared::MAT_MIRROR, ..Default::default() },
    );
    // Triangles 0..2 are the light, 2..4 the floor, 4..6 the ceiling, 6..8 the back wall,
    // 8..12 the side walls, then the short and the tall block (10 each).
    let n = s.triangles.len();
    for (i, t) in s.triangles.iter_mut().enumerate() {
        if is_mirror(i, n) {
            t.material = mirror;
        }
    }
    s
}

/// The Cornell box with a glass sphere (index 1.5, radius 82.5 mm, 20 480 triangles) in place
/// of the short block: caustics on the floor, light through glass.
pub fn cornell_glass() -> Scene {
    let mut s = cornell_box();
    s.name = "cornell-glass".into();
    // Triangles 12..22 are the short block (see `with_mirrors`).
    s.triangles.drain(12..22);
    let glass = s.add_material(
        "glass",
        Material { diffuse: [1.0; 3], flags: kdray_shared::MAT_GLASS, ior: 1.5, ..Default::default() },
    );
    let mut ball = super::procedural::sphere(82.5, 5);
    for v in &mut ball.v {
        *v += Vec3::new(186.0, 83.0, 169.0);
    }
    ball.into_scene(&mut s, glass, "glass sphere").expect("the generated sphere is valid");
    s
}
