//! A scene as a Mitsuba 3 scene (XML and one binary PLY per material), for side-by-side runs
//! of Mitsuba's path tracer on exactly this scene and camera: diffuse → `diffuse`, mirror →
//! `conductor` (material `none`, the mirror colour as specular reflectance), glass →
//! `dielectric`, emissive triangles → `area` emitters (one-sided, on the same side as here),
//! point lights → `point`, spot lights → `spot`; a perspective sensor with a box filter.
use super::Scene;
use crate::error::{Context, Result};
use kdray_shared::{MAT_GLASS, MAT_MIRROR};
use std::fmt::Write as _;
use std::path::Path;

fn rgb(c: [f32; 3]) -> String {
    format!("{}, {}, {}", c[0], c[1], c[2])
}

fn v3(c: glam::Vec3) -> String {
    format!("{}, {}, {}", c.x, c.y, c.z)
}

/// Writes `dir/scene.xml` and `dir/mesh-K.ply` for a `width` × `height` image with paths of at
/// most `max_depth` vertices; returns the XML's path.
pub fn export(scene: &Scene, dir: &Path, width: u32, height: u32, max_depth: u32) -> Result<std::path::PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let c = &scene.camera;
    let mut x = String::new();
    writeln!(x, "<scene version=\"3.0.0\">")?;
    writeln!(x, "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"{max_depth}\"/></integrator>")?;
    writeln!(x, "  <sensor type=\"perspective\">")?;
    writeln!(x, "    <float name=\"fov\" value=\"{}\"/><string name=\"fov_axis\" value=\"y\"/>", c.fov_y_deg)?;
    writeln!(x, "    <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>", v3(c.eye), v3(c.look_at), v3(c.up))?;
    writeln!(x, "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\"64\"/></sampler>")?;
    writeln!(x, "    <film type=\"hdrfilm\"><integer name=\"width\" value=\"{width}\"/><integer name=\"height\" value=\"{height}\"/><rfilter type=\"box\"/><string name=\"pixel_format\" value=\"rgb\"/></film>")?;
    writeln!(x, "  </sensor>")?;
    for (k, m) in scene.materials.iter().enumerate() {
        let tris: Vec<_> = scene.triangles.iter().filter(|t| t.material as usize == k).collect();
        if tris.is_empty() {
            continue;
        }
        let file = format!("mesh-{k}.ply");
        let mut ply = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            3 * tris.len(),
            tris.len()
        )
        .into_bytes();
        for t in &tris {
            for v in [t.v0, t.v1, t.v2] {
                for c in v {
                    ply.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        for i in 0..tris.len() as i32 {
            ply.push(3);
            for j in 0..3 {
                ply.extend_from_slice(&(3 * i + j).to_le_bytes());
            }
        }
        crate::files::write(&dir.join(&file), ply)?;
        writeln!(x, "  <shape type=\"ply\"><string name=\"filename\" value=\"{file}\"/><boolean name=\"face_normals\" value=\"true\"/>")?;
        if m.flags & MAT_MIRROR != 0 {
            writeln!(x, "    <bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/><rgb name=\"specular_reflectance\" value=\"{}\"/></bsdf>", rgb(m.diffuse))?;
        } else if m.flags & MAT_GLASS != 0 {
            writeln!(x, "    <bsdf type=\"dielectric\"><float name=\"int_ior\" value=\"{}\"/><float name=\"ext_ior\" value=\"1.0\"/></bsdf>", m.ior())?;
        } else {
            writeln!(x, "    <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"{}\"/></bsdf>", rgb(m.diffuse))?;
        }
        if m.emission != [0.0; 3] {
            writeln!(x, "    <emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>", rgb(m.emission))?;
        }
        writeln!(x, "  </shape>")?;
    }
    for p in &scene.point_lights {
        match &p.spot {
            None => writeln!(x, "  <emitter type=\"point\"><point name=\"position\" value=\"{}\"/><rgb name=\"intensity\" value=\"{}\"/></emitter>", v3(p.position), rgb(p.intensity.to_array()))?,
            Some(s) => {
                let up = if s.direction.y.abs() > 0.9 { glam::Vec3::X } else { glam::Vec3::Y };
                writeln!(
                    x,
                    "  <emitter type=\"spot\"><transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform><rgb name=\"intensity\" value=\"{}\"/><float name=\"cutoff_angle\" value=\"{}\"/><float name=\"beam_width\" value=\"{}\"/></emitter>",
                    v3(p.position),
                    v3(p.position + s.direction),
                    v3(up),
                    rgb(p.intensity.to_array()),
                    s.cone_deg,
                    s.falloff_start_deg
                )?
            }
        }
    }
    writeln!(x, "</scene>")?;
    let path = dir.join("scene.xml");
    crate::files::write(&path, x)?;
    Ok(path)
}
