//! Bad input gets one clear error line and a non-zero exit, never a panic.
mod common;

use kdray::scene;
use kdray::Runtime;
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

/// The built-in Cornell scenes are the files of `scenes/` (#11 item 6): the compiled-in copy
/// and the folder load the same scene, with the box's published layout.
#[test]
fn built_in_scenes_are_the_scene_files_of_the_scenes_folder() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    for name in scene::FILE_SCENES {
        let built_in = scene::load(name).unwrap();
        let file = root.join(format!("{name}.toml"));
        let from_disk = scene::load(file.to_str().unwrap()).unwrap();
        assert_eq!(built_in.name, *name);
        assert_eq!((&built_in.name, &built_in.camera, &built_in.material_names), (&from_disk.name, &from_disk.camera, &from_disk.material_names));
        assert_eq!(built_in.materials, from_disk.materials, "{name}");
        assert!(built_in.triangles == from_disk.triangles, "{name}: the compiled-in copy differs from {}", file.display());
    }
    let c = scene::load("cornell").unwrap();
    let material = |s: &scene::Scene, i: usize| s.material_names[s.triangles[i].material as usize].clone();
    assert_eq!(c.triangles.len(), 32);
    assert_eq!((material(&c, 0), material(&c, 2), material(&c, 8), material(&c, 10)), ("light".into(), "white".into(), "green".into(), "red".into()));
    assert_eq!(c.materials[c.triangles[0].material as usize].emission, [17.0, 12.0, 4.0]);
    let mirror = scene::load("cornell-mirror").unwrap();
    let mirrors: Vec<usize> = (0..32).filter(|&i| mirror.materials[mirror.triangles[i].material as usize].flags == kdray_shared::MAT_MIRROR).collect();
    assert_eq!(mirrors, [6, 7, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31], "back wall and tall block");
    let glass = scene::load("cornell-glass").unwrap();
    assert_eq!(glass.triangles.len(), 22 + 20_480, "the box without its short block, and the sphere");
}

/// A scene file picks objects from an OBJ file, and its materials override the MTL file's.
#[test]
fn scene_files_select_objects_and_override_mtl_materials() {
    let obj = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell.obj");
    let head = format!("[camera]\neye = [278, 273, -800]\nlook_at = [278, 273, 0]\n[materials.red]\ndiffuse = [0.9, 0.9, 0.9]\nmirror = true\n[[mesh]]\nfile = \"{}\"\n", obj.display());
    let p = tmp("objects.toml", &format!("{head}objects = [\"light\", \"left_wall\"]\n"));
    let s = scene::load(p.to_str().unwrap()).unwrap();
    assert_eq!(s.triangles.len(), 4);
    let red = s.materials[s.triangles[2].material as usize];
    assert_eq!((red.flags, red.diffuse), (kdray_shared::MAT_MIRROR, [0.9; 3]), "the file's [materials.red] wins over cornell.mtl's");
    let e = load_err("no-object.toml", &format!("{head}objects = [\"light\", \"window\"]\n"));
    assert!(e.contains("no object 'window'") && e.contains("short_block"), "{e}");
    let e = load_err("objects-builtin.toml", "[[mesh]]\nbuiltin = \"icosphere:2\"\nobjects = [\"a\"]\n");
    assert!(e.contains("'objects' selects objects of an OBJ 'file'"), "{e}");
    let e = load_err("icosphere.toml", "[[mesh]]\nbuiltin = \"icosphere:x\"\n");
    assert!(e.contains("icosphere:N"), "{e}");
}

#[test]
fn too_large_for_the_gpu_is_a_clear_error() {
    let Some(g) = common::gpu() else { return };
    let max = g.max_binding();
    let e = format!("{:#}", g.check_size("triangle", max + 1).unwrap_err());
    assert!(e.starts_with("scene too large for this GPU: the triangle buffer needs"), "{e}");
    assert!(g.check_size("triangle", max).is_ok());
}

/// A buffer the device refuses (past its largest buffer, taken below the size check that
/// `alloc` makes) is an error of the allocation, not a panic in wgpu's error handler; the
/// device goes on working.
#[test]
fn a_buffer_the_gpu_refuses_is_an_error_not_a_panic() {
    let Some(g) = common::gpu() else { return };
    let e = g.alloc_raw("huge", 1 << 50).err().expect("a 1 PiB buffer is refused");
    let msg = format!("{e:#}");
    assert!(matches!(e.kind(), kdray::Error::TooLarge(_)), "{msg}");
    assert!(msg.contains("huge") && !msg.contains('\n'), "{msg}");
    let rt: &dyn Runtime = g;
    let b = rt.upload("after", &[1u32, 2, 3]).unwrap();
    assert_eq!(rt.read(&b, 3).unwrap(), vec![1, 2, 3]);
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

/// The command line prints a library error's chain once: context, then the cause, nothing
/// repeated (the typed error holds the chain in its message).
#[test]
fn cli_prints_an_error_chain_once() {
    let (code, _, err) = kdray(&["render", "--device", "cpu", "--scene", "/nonexistent/dir/missing.obj"], &[]);
    assert_eq!(code, 1);
    let line = err.trim_end();
    assert!(line.starts_with("error: cannot read /nonexistent/dir/missing.obj: "), "{line}");
    let cause = line.rsplit_once(": ").unwrap().1;
    assert_eq!(line.matches(cause).count(), 1, "the cause is repeated: {line}");
    let (code, _, err) = kdray(&["error", "/nonexistent/a.pfm", "/nonexistent/b.pfm"], &[]);
    assert_eq!(code, 1);
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
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
    // Rasterised primaries: not with the photon integrator, nor with a traversal that has no
    // rasterised kernel.
    let (code, _, err) = kdray(&["render", "--device", "cpu", "--primary", "raster"], &[]);
    assert_eq!((code, err.lines().count()), (1, 1), "{err}");
    assert!(err.starts_with("error: --primary raster is for the direct and path integrators"), "{err}");
    let args = ["render", "--device", "cpu", "--size", "8", "--integrator", "direct", "--primary", "raster", "--traversal", "restart", "--out", "/dev/null"];
    let (code, _, err) = kdray(&args, &[]);
    assert_eq!((code, err.lines().count()), (1, 1), "{err}");
    assert!(err.contains("rasterised primary hits trace with the BVH or the kd-tree's full stack"), "{err}");
    // An option that bench would ignore is refused.
    let (code, _, err) = kdray(&["bench", "build", "--device", "cpu", "--bvh-build", "kernels", "--out", "/dev/null"], &[]);
    assert_eq!((code, err.lines().count()), (1, 1), "{err}");
    assert!(err.starts_with("error: --bvh-build is render's"), "{err}");
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

/// A scene file `name` with a camera and a square (in an OBJ file of its own, so that tests
/// running in parallel never read a file another one is writing) but no light, plus `extra`.
fn plain_scene(name: &str, extra: &str) -> PathBuf {
    let obj = format!("{name}.obj");
    tmp(&obj, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    tmp(name, &format!("[camera]\neye = [0.5, 0.5, 3]\nlook_at = [0.5, 0.5, 0]\n[[mesh]]\nfile = \"{obj}\"\n{extra}"))
}

fn scene_err(name: &str, extra: &str) -> String {
    let p = plain_scene(name, extra);
    match scene::load(p.to_str().unwrap()) {
        Ok(_) => panic!("{name} should not load"),
        Err(e) => format!("{e:#}"),
    }
}

#[test]
fn non_finite_or_negative_quad_light_emission_names_the_light() {
    let quad = |e: &str| format!("[[light]]\npoint = [0, 0, 2]\n[[light]]\ncorner = [0, 0, 1]\nedge1 = [1, 0, 0]\nedge2 = [0, 1, 0]\nemission = {e}\n");
    let e = scene_err("quad-nan.toml", &quad("[nan, 1, 1]"));
    assert!(e.contains("quad-nan.toml: light 2 emission is not finite: [NaN, 1.0, 1.0]"), "{e}");
    let e = scene_err("quad-inf.toml", &quad("[1, inf, 1]"));
    assert!(e.contains("quad-inf.toml: light 2 emission is not finite"), "{e}");
    let e = scene_err("quad-neg.toml", &quad("[1, -1, 1]"));
    assert!(e.contains("quad-neg.toml: light 2 emission is negative: [1.0, -1.0, 1.0]"), "{e}");
    let e = scene_err("quad-flat.toml", "[[light]]\ncorner = [0, 0, 1]\nedge1 = [1, 0, 0]\nedge2 = [2, 0, 0]\n");
    assert!(e.contains("quad-flat.toml: light 1: edge1 [1, 0, 0] and edge2 [2, 0, 0] span no area"), "{e}");
    let e = scene_err("quad-edge.toml", "[[light]]\ncorner = [0, 0, 1]\nedge1 = [1, nan, 0]\nedge2 = [0, 1, 0]\n");
    assert!(e.contains("quad-edge.toml: light 1 edge1 is not finite"), "{e}");
    let e = scene_err("mixed.toml", "[[light]]\npoint = [0, 0, 2]\nemission = [5, 5, 5]\n");
    assert!(e.contains("mixed.toml: light 1: a point light takes 'intensity', not 'edge1', 'edge2' or 'emission'"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn non_finite_point_lights_materials_and_cameras_are_rejected() {
    let e = scene_err("point-inf.toml", "[[light]]\npoint = [0, 0, 2]\nintensity = [inf, 1, 1]\n");
    assert!(e.contains("point-inf.toml: light 1 intensity is not finite: [inf, 1.0, 1.0]"), "{e}");
    let e = scene_err("point-neg.toml", "[[light]]\npoint = [0, 0, 2]\nintensity = [1, 1, -0.5]\n");
    assert!(e.contains("point-neg.toml: light 1 intensity is negative"), "{e}");
    let e = scene_err("point-pos.toml", "[[light]]\npoint = [0, nan, 2]\n");
    assert!(e.contains("point-pos.toml: light 1 point is not finite"), "{e}");
    let e = scene_err("mat-nan.toml", "[materials.white]\ndiffuse = [0.5, 0.5, 0.5]\nemission = [0, nan, 0]\n");
    assert!(e.contains("mat-nan.toml: material 'white' emission is not finite"), "{e}");
    let e = scene_err("mat-neg.toml", "[materials.white]\ndiffuse = [0.5, -0.5, 0.5]\n");
    assert!(e.contains("mat-neg.toml: material 'white' diffuse is negative"), "{e}");
    tmp("camera-tests.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    let cam = |c: &str| format!("[camera]\n{c}\n[[mesh]]\nfile = \"camera-tests.obj\"\n");
    let e = load_err("fov.toml", &cam("eye = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov_y = nan"));
    assert!(e.contains("fov.toml: camera fov_y must be between 0 and 180 degrees"), "{e}");
    let e = load_err("fov0.toml", &cam("eye = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov_y = 0"));
    assert!(e.contains("fov0.toml: camera fov_y must be between 0 and 180 degrees (exclusive), got 0"), "{e}");
    let e = load_err("sameeye.toml", &cam("eye = [0, 0, 1]\nlook_at = [0, 0, 1]"));
    assert!(e.contains("sameeye.toml: camera eye and look_at must be distinct points"), "{e}");
    let e = load_err("camup.toml", &cam("eye = [0, 0, 1]\nlook_at = [0, 0, 0]\nup = [0, 0, 2]"));
    assert!(e.contains("camup.toml: camera up [0, 0, 2] is zero or parallel to the view direction"), "{e}");
}

#[test]
fn non_finite_or_negative_mtl_colours_name_file_line_and_material() {
    let mtl_err = |stem: &str, mtl: &str| {
        tmp(&format!("{stem}.mtl"), mtl);
        load_err(&format!("{stem}.obj"), &format!("mtllib {stem}.mtl\n{TRI}usemtl m\nf 1 2 3\n"))
    };
    let e = mtl_err("kd-nan", "newmtl m\nKd nan 0.5 0.5\n");
    assert!(e.contains("kd-nan.mtl:2: material 'm' Kd has a non-finite value 'nan'"), "{e}");
    let e = mtl_err("kd-huge", "newmtl m\nKd 0.5 1e39 0.5\n");
    assert!(e.contains("kd-huge.mtl:2: material 'm' Kd has a non-finite value '1e39'"), "{e}");
    let e = mtl_err("ke-inf", "newmtl m\nKd 0.5 0.5 0.5\nKe 1 1 inf\n");
    assert!(e.contains("ke-inf.mtl:3: material 'm' Ke has a non-finite value 'inf'"), "{e}");
    let e = mtl_err("ke-neg", "newmtl m\nKe -2 1 1\n");
    assert!(e.contains("ke-neg.mtl:2: material 'm' Ke has a negative value '-2'"), "{e}");
    // tobj panics on fewer than three numbers.
    let e = mtl_err("kd-short", "newmtl m\nKd 0.5\n");
    assert!(e.contains("kd-short.mtl:2: material 'm' Kd needs 3 numbers (r g b): 'Kd 0.5'"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn light_powers_that_overflow_are_rejected() {
    let huge = "[[light]]\ncorner = [-1.5e38, 0, 0]\nedge1 = [3e38, 0, 0]\nedge2 = [0, 0, 3e38]\nemission = [1, 1, 1]\n";
    let e = scene_err("light-huge.toml", huge);
    assert!(e.contains("(material 'light1') has a non-finite power: area inf"), "{e}");
    let bright = "[[light]]\ncorner = [0, 0, 1]\nedge1 = [10, 0, 0]\nedge2 = [0, 10, 0]\nemission = [1e38, 1, 1]\n";
    let e = scene_err("light-bright.toml", bright);
    assert!(e.contains("(material 'light1') has a non-finite power: area 5e1 × emission [1e38, 1.0, 1.0] overflows f32"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn zero_power_lights_are_skipped_and_the_cdf_is_never_nan() {
    use glam::Vec3;
    use kdray::scene::{CameraSpec, PointLight, Scene};
    use kdray_shared::{Light, Material};
    let cdf_ok = |ls: &[Light]| {
        ls.iter().all(|l| l.cdf.is_finite() && l.cdf >= 0.0 && l.cdf <= 1.0)
            && ls.windows(2).all(|w| w[0].cdf <= w[1].cdf)
            && ls.last().is_none_or(|l| l.cdf == 1.0)
    };
    // Black lights in a scene file load, and are not lights.
    let black = "[[light]]\npoint = [0, 0, 2]\nintensity = [0, 0, 0]\n[[light]]\ncorner = [0, 0, 1]\nedge1 = [1, 0, 0]\nedge2 = [0, 1, 0]\nemission = [0, 0, 0]\n";
    let p = plain_scene("black.toml", black);
    let s = scene::load(p.to_str().unwrap()).unwrap();
    assert!(s.lights().is_empty(), "{:?}", s.lights());
    // With one bright light beside them, only it is sampled.
    let p = plain_scene("one-bright.toml", &format!("{black}[[light]]\npoint = [0, 1, 2]\nintensity = [0, 0, 3]\n"));
    let s = scene::load(p.to_str().unwrap()).unwrap();
    let ls = s.lights();
    assert_eq!(ls.len(), 1, "{ls:?}");
    assert_eq!((ls[0].emission, ls[0].cdf), ([0.0, 0.0, 3.0], 1.0), "blue only has a positive luminance");

    // Scenes built in code: NaN / infinite / negative emission never gives a NaN cdf (uniform
    // selection instead), and `validate` names the problem.
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let scene_with = |emission: [f32; 3], intensity: Vec3| {
        let mut s = Scene::new("coded", CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
        let m = s.add_material("glow", Material { diffuse: [0.5; 3], emission, ..Default::default() });
        let w = s.add_material("white", Material { diffuse: [0.5; 3], ..Default::default() });
        s.add_triangle(tri, m, &|| "tri".into()).unwrap();
        s.add_triangle(tri.map(|v| v + Vec3::Z), w, &|| "tri".into()).unwrap();
        s.point_lights.push(PointLight { position: Vec3::new(0.0, 0.0, 2.0), intensity, spot: None });
        s
    };
    for (emission, intensity, expect) in [
        ([f32::NAN, 1.0, 1.0], Vec3::ONE, "coded: material 'glow' emission is not finite"),
        ([f32::INFINITY, 1.0, 1.0], Vec3::ONE, "coded: material 'glow' emission is not finite"),
        ([1.0, 1.0, 1.0], Vec3::new(-5.0, 0.0, 0.0), "coded: point light 1 intensity is negative"),
        ([f32::MAX; 3], Vec3::splat(f32::MAX), "coded: the lights' total power"),
    ] {
        let s = scene_with(emission, intensity);
        let ls = s.lights();
        assert_eq!(ls.len(), 2, "{ls:?}");
        assert!(cdf_ok(&ls), "{emission:?} {intensity}: {ls:?}");
        let e = format!("{:#}", s.validate().unwrap_err());
        assert!(e.starts_with(expect), "{e}");
    }
    // The largest finite inputs: weights are computed in f64, so the cdf stays finite.
    let mut s = scene_with([f32::MAX; 3], Vec3::splat(f32::MAX));
    let big = [Vec3::new(-f32::MAX, -f32::MAX, 0.0), Vec3::new(f32::MAX, -f32::MAX, 0.0), Vec3::new(0.0, f32::MAX, 0.0)];
    s.add_triangle(big, 0, &|| "big".into()).unwrap();
    let ls = s.lights();
    assert_eq!(ls.len(), 3);
    assert!(cdf_ok(&ls), "{ls:?}");
    assert!(ls[0].cdf < ls[1].cdf, "proportional, not uniform: {ls:?}");
    assert!(s.validate().is_err());
}

fn render_warnings(scene: &std::path::Path) -> (i32, Vec<String>, String) {
    let out = scene.with_extension("png");
    let (code, _, err) =
        kdray(&["render", "--device", "cpu", "--size", "8", "--scene", scene.to_str().unwrap(), "--out", out.to_str().unwrap()], &[]);
    let warnings = err.lines().filter(|l| l.starts_with("warning:")).map(String::from).collect();
    (code, warnings, err)
}

#[test]
fn glass_is_a_dielectric_with_its_index_and_renders_without_warnings() {
    tmp("glass.mtl", "newmtl clear\nKd 0.9 0.9 0.9\nillum 7\nNi 1.33\nnewmtl frosted\nKd 0.9 0.9 0.9\nillum 4\nnewmtl unused\nillum 6\n");
    let obj = tmp(
        "glass.obj",
        "mtllib glass.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl clear\nf 1 2 3\nusemtl frosted\nf 1 3 4\n",
    );
    let s = scene::load(obj.to_str().unwrap()).unwrap();
    let m = s.materials[s.triangles[0].material as usize];
    assert_eq!(m.flags, kdray_shared::MAT_GLASS, "the flag is kept");
    assert_eq!(m.ior(), 1.33, "Ni is the index of refraction");
    assert_eq!(s.materials[s.triangles[1].material as usize].ior(), 1.5, "default index");
    let (code, warnings, err) = render_warnings(&obj);
    assert_eq!(code, 0, "{err}");
    assert!(warnings.is_empty(), "{err}");

    let toml = tmp(
        "glass.toml",
        "[materials.pane]\ndiffuse = [0.8, 0.8, 0.8]\nglass = true\nior = 1.7\n[[mesh]]\nfile = \"glass.obj\"\n[[mesh]]\nfile = \"glass.obj\"\nmaterial = \"pane\"\ntranslate = [0, 0, -1]\n[[light]]\npoint = [0, 0, 3]\n",
    );
    let (code, warnings, err) = render_warnings(&toml);
    assert_eq!(code, 0, "{err}");
    assert!(warnings.is_empty(), "{err}");
    let s = scene::load(toml.to_str().unwrap()).unwrap();
    assert_eq!(s.materials[s.material_id("pane").unwrap() as usize].ior(), 1.7);

    // An index below 1 (or not finite) is an error naming the material.
    tmp("badni.mtl", "newmtl clear\nillum 7\nNi 0.5\n");
    let bad = tmp("badni.obj", "mtllib badni.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl clear\nf 1 2 3\n");
    let e = format!("{:#}", scene::load(bad.to_str().unwrap()).unwrap_err());
    assert!(e.contains("'clear' Ni") && e.contains("0.5"), "{e}");
    let bad = tmp("badior.toml", "[materials.pane]\ndiffuse = [0.8, 0.8, 0.8]\nglass = true\nior = 0.2\n[[mesh]]\nfile = \"glass.obj\"\nmaterial = \"pane\"\n");
    let e = format!("{:#}", scene::load(bad.to_str().unwrap()).unwrap_err());
    assert!(e.contains("'pane' ior"), "{e}");
}

#[test]
fn spot_lights_need_a_direction_and_a_cone() {
    let obj = tmp("spotmesh.obj", &format!("{TRI}f 1 2 3\n"));
    let _ = obj;
    for (light, want) in [
        ("point = [0, 0, 3]\ndirection = [0, 0, -1]\n", "needs both 'direction' and 'cone'"),
        ("point = [0, 0, 3]\ndirection = [0, 0, -1]\ncone = 120.0\n", "cone must be in (0, 90]"),
        ("point = [0, 0, 3]\ndirection = [0, 0, -1]\ncone = 30.0\nfalloff_start = 40.0\n", "falloff_start in [0, cone]"),
        ("point = [0, 0, 3]\ndirection = [0, 0, 0]\ncone = 30.0\n", "direction is zero"),
    ] {
        let f = tmp("spot.toml", &format!("[[mesh]]\nfile = \"spotmesh.obj\"\n[[light]]\n{light}"));
        let e = format!("{:#}", scene::load(f.to_str().unwrap()).unwrap_err());
        assert!(e.contains("light 1") && e.contains(want), "{light}: {e}");
    }
    let f = tmp("spot.toml", "[[mesh]]\nfile = \"spotmesh.obj\"\n[[light]]\npoint = [0, 0, 3]\ndirection = [0, 0, -2]\ncone = 30.0\nfalloff_start = 20.0\n");
    let s = scene::load(f.to_str().unwrap()).unwrap();
    let l = s.lights();
    assert_eq!(l[0].kind, kdray_shared::LIGHT_SPOT);
    assert!((l[0].e1[2] + 1.0).abs() < 1e-6, "the axis is normalised: {:?}", l[0].e1);
}

#[test]
fn bad_photon_options_are_one_error_line() {
    for (args, want) in [
        (vec!["--emission", "sideways"], "--emission must be"),
        (vec!["--emission", "coherent:2"], "--emission must be"),
        (vec!["--passes", "0"], "--passes must be at least 1"),
        (vec!["--photons", "0"], "at least one photon"),
        (vec!["--radius=-1"], "--radius must be a positive number"),
        (vec!["--alpha", "0"], "alpha must be in (0, 1]"),
        (vec!["--time-limit=-3"], "--time-limit must be"),
        (vec!["--spp", "0"], "--spp must be"),
    ] {
        let mut a = vec!["render", "--device", "cpu", "--size", "8", "--out", "/dev/null"];
        a.extend(args.iter().copied());
        let (code, _, err) = kdray(&a, &[]);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error:")).count(), 1, "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn a_tracer_refuses_an_edited_scene_or_another_scenes_tree() {
    use kdray::{kdtree, runtime::cpu::NATIVE, Scene, Tracer};
    // Library users can edit a scene's public fields after loading: the tracer validates
    // before any kernel reads them (natively, indexing past the materials would panic).
    let mut s = Scene::from_mesh("square", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2], [0, 2, 3]]).unwrap();
    let tree = kdtree::try_build(&s.triangles, &Default::default()).unwrap();
    s.triangles[1].material = 7;
    let e = Tracer::new(&NATIVE, &s, Some(&tree)).err().expect("an error");
    assert!(e.to_string().contains("material id 7 does not exist"), "{e}");
    s.triangles[1].material = 0;
    s.triangles[0].v1[2] = f32::NAN;
    assert!(Tracer::new(&NATIVE, &s, None).is_err());
    // A tree built for a larger scene names triangles this one lacks.
    let big = kdray::scene::load("cornell").unwrap();
    let big_tree = kdtree::try_build(&big.triangles, &Default::default()).unwrap();
    let small = Scene::from_mesh("triangle", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]).unwrap();
    let e = Tracer::new(&NATIVE, &small, Some(&big_tree)).err().expect("an error");
    assert!(matches!(e.kind(), kdray::Error::InvalidInput(_)) && e.to_string().contains("does not belong"), "{e}");
}
