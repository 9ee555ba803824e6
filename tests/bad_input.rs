//! Bad input gets one clear error line and a non-zero exit, never a panic.
mod common;

use kdray::scene;
use std::path::PathBuf;
use std::process::Command;

fn tmp(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdray-bad-input-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn load_err(name: &str, text: &str) -> String {
    let p = tmp(name, text);
    match scene::load(p.to_str().unwrap()) {
        Ok(_) => panic!("{name} should not load"),
        Err(e) => format!("{e:#}"),
    }
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn malformed_obj_names_file_and_line() {
    let e = load_err("malformed.obj", "v 0 0 0\nv 1.0 abc 2.0\nv 0 1 0\nf 1 2 3\n");
    assert!(e.contains("malformed.obj:2: cannot parse vertex coordinate 'abc'"), "{e}");
    let e = load_err("short.obj", "v 0 0\n");
    assert!(e.contains("short.obj:1: vertex needs 3 coordinates"), "{e}");
    let e = load_err("badface.obj", &format!("{TRI}f 1 x 3\n"));
    assert!(e.contains("badface.obj:4: face 1: cannot parse vertex index 'x'"), "{e}");
    let e = load_err("twoverts.obj", &format!("{TRI}f 1 2\n"));
    assert!(e.contains("twoverts.obj:4: face 1 has 2 vertices, needs at least 3"), "{e}");
}

#[test]
fn non_finite_vertices_are_rejected() {
    let e = load_err("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    assert!(e.contains("nan.obj:2: vertex 2 has a non-finite coordinate 'nan'"), "{e}");
    let e = load_err("inf.obj", "v 0 0 0\nv 1 inf 0\nv 0 1 0\nf 1 2 3\n");
    assert!(e.contains("inf.obj:2: vertex 2 has a non-finite coordinate 'inf'"), "{e}");
    let e = load_err("huge.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
    assert!(e.contains("huge.obj:2: vertex 2 has a non-finite coordinate '1e39'"), "{e}");
}

#[test]
fn out_of_range_indices_are_rejected() {
    let e = load_err("range.obj", &format!("{TRI}f 1 2 9\n"));
    assert!(e.contains("range.obj:4: face 1 refers to vertex 9, but only 3 vertices are defined before it"), "{e}");
    let e = load_err("neg.obj", &format!("{TRI}f -1 -2 -4\n"));
    assert!(e.contains("neg.obj:4: face 1 refers to vertex -4"), "{e}");
    let e = load_err("zero.obj", &format!("{TRI}f 0 1 2\n"));
    assert!(e.contains("zero.obj:4: face 1 refers to vertex 0"), "{e}");
}

#[test]
fn empty_meshes_and_scenes_are_rejected() {
    let e = load_err("empty.obj", TRI);
    assert!(e.contains("empty.obj: no faces: the mesh is empty"), "{e}");
    let e = load_err("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    assert!(e.contains("flat: the scene has no triangles"), "{e}");
    let e = load_err("nomesh.toml", "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\n");
    assert!(e.contains("nomesh.toml: no [[mesh]] entries: the scene is empty"), "{e}");
}

#[test]
fn missing_files_are_named() {
    let e = format!("{:#}", scene::load("/nonexistent/dir/missing.obj").unwrap_err());
    assert!(e.starts_with("cannot read /nonexistent/dir/missing.obj"), "{e}");
    let p = tmp("refs-missing.toml", "[[mesh]]\nfile = \"gone.obj\"\n");
    let e = format!("{:#}", scene::load(p.to_str().unwrap()).unwrap_err());
    assert!(e.contains("cannot read") && e.contains("gone.obj"), "{e}");
    let e = format!("{:#}", scene::load("scene.ply").unwrap_err());
    assert!(e.contains("unknown scene 'scene.ply'"), "{e}");
}

#[test]
fn malformed_scene_files_name_the_line() {
    let e = load_err("syntax.toml", "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0,\n");
    assert!(e.contains("syntax.toml:3:"), "{e}");
    let e = load_err("unknown-key.toml", "[[mesh]]\nbuiltin = \"cornell\"\ncolour = 3\n");
    assert!(e.contains("unknown-key.toml:3:") && e.contains("colour"), "{e}");
    let e = load_err("unknown-mat.toml", "[[mesh]]\nbuiltin = \"cornell\"\nmaterial = \"gold\"\n");
    assert!(e.contains("mesh 1: unknown material 'gold'"), "{e}");
    let e = load_err("quad.toml", "[[mesh]]\nbuiltin = \"cornell\"\n[[light]]\ncorner = [0, 0, 0]\n");
    assert!(e.contains("light 1: a quad light needs edge1 and edge2"), "{e}");
    let e = load_err("nancam.toml", "[camera]\neye = [nan, 0, 1]\nlook_at = [0, 0, 0]\n[[mesh]]\nbuiltin = \"cornell\"\n");
    assert!(e.contains("camera eye is not finite"), "{e}");
}

#[test]
fn scene_file_with_obj_and_lights_loads() {
    let obj = tmp("quad.obj", "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl glow\nf 1 2 3 4\n");
    tmp("quad.mtl", "newmtl glow\nKd 0.5 0.5 0.5\nKe 2 2 2\nillum 3\n");
    let p = tmp(
        "ok.toml",
        "[camera]\neye = [0.5, 0.5, 3]\nlook_at = [0.5, 0.5, 0]\n[[mesh]]\nfile = \"quad.obj\"\n[[light]]\npoint = [0, 0, 2]\nintensity = [5, 5, 5]\n",
    );
    let s = scene::load(p.to_str().unwrap()).unwrap();
    assert_eq!(s.triangles.len(), 2);
    let m = s.materials[s.triangles[0].material as usize];
    assert_eq!(m.emission, [2.0; 3]);
    assert_eq!(m.flags, kdray_shared::MAT_MIRROR);
    assert_eq!(s.lights().len(), 3, "two emissive triangles and a point light");
    assert_eq!(s.lights().last().unwrap().cdf, 1.0);
    let _ = obj;
}

#[test]
fn too_large_for_the_gpu_is_a_clear_error() {
    let Some(g) = common::gpu() else { return };
    let max = g.max_binding();
    let e = format!("{:#}", g.check_size("triangle", max + 1).unwrap_err());
    assert!(e.starts_with("scene too large for this GPU: the triangle buffer needs"), "{e}");
    assert!(g.check_size("triangle", max).is_ok());
}

fn kdray(args: &[&str], envs: &[(&str, &str)]) -> (i32, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_kdray"));
    c.args(args);
    for (k, v) in envs {
        c.env(k, v);
    }
    let o = c.output().unwrap();
    (o.status.code().unwrap_or(-1), String::from_utf8_lossy(&o.stdout).into(), String::from_utf8_lossy(&o.stderr).into())
}

#[test]
fn cli_reports_one_error_line_and_exits_non_zero() {
    let bad = tmp("cli-bad.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
    let (code, _, err) = kdray(&["render", "--device", "cpu", "--scene", bad.to_str().unwrap()], &[]);
    assert_eq!(code, 1);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: ") && err.contains("cli-bad.obj:2:"), "{err}");
    let (code, _, err) = kdray(&["render", "--size", "0"], &[]);
    assert_eq!(code, 1);
    assert!(err.starts_with("error: --size"), "{err}");
}

#[test]
fn no_gpu_adapter() {
    // Point the Vulkan loader at no driver at all.
    let none = [("VK_DRIVER_FILES", "/nonexistent/icd.json"), ("VK_ICD_FILENAMES", "/nonexistent/icd.json")];
    let out = std::env::temp_dir().join(format!("kdray-fallback-{}.png", std::process::id()));
    let (code, _, err) = kdray(&["render", "--device", "gpu", "--size", "8"], &none);
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: no GPU adapter"), "{err}");
    // Without --device the render falls back to the CPU with a warning.
    let (code, stdout, err) = kdray(&["render", "--size", "8", "--out", out.to_str().unwrap()], &none);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning: no GPU adapter"), "{err}");
    assert!(stdout.contains("device: CPU"), "{stdout}");
    assert!(out.exists());
}
