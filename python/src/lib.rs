//! `kdray._native`: the Rust half of the Python package. `kdray/__init__.py` checks every
//! argument (names, shapes, dtypes) and hands this module contiguous float32 and uint32 arrays;
//! this module runs the library's `Tracer` and integrators on them with the GIL released and
//! returns NumPy arrays that take over the vectors of results built here (no copy on the way
//! out).
//!
//! One device per process: the GPU a call names is opened once and kept (a leaked `Gpu`, so
//! tracers built on it live as long as their scene); each scene keeps its kd-tree, its BVH and
//! one tracer per device and structure, built on first use.
use kdray::bvh::BvhData;
use kdray::integrator::path::{self, PathOptions};
use kdray::integrator::Progress;
use kdray::integrator::photon::{self as pm, PhotonMap, PhotonOptions};
use kdray::kdtree::{self, KdTreeData};
use kdray::runtime::cpu::{check_cpu, NATIVE};
use kdray::shared::{Ray, MISS};
use kdray::{Accel, Error, Gpu, Runtime, Tracer};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyImportError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock, PoisonError};

pyo3::create_exception!(_native, NoGpuError, PyRuntimeError, "No usable Vulkan GPU adapter (or not the one asked for).");

/// A library error as the Python exception a caller expects, `what` (the argument or step to
/// blame) in front: bad arguments and scenes are `ValueError`, files `OSError`, a missing GPU
/// `NoGpuError` (a `RuntimeError`), device failures `RuntimeError`.
fn py_err(what: &str, e: Error) -> PyErr {
    let msg = if what.is_empty() { e.to_string() } else { format!("{what}: {e}") };
    match e.kind() {
        Error::NoAdapter(_) => NoGpuError::new_err(msg),
        Error::Io { .. } => PyOSError::new_err(msg),
        Error::InvalidInput(_) | Error::Scene(_) | Error::SceneFile { .. } | Error::TooLarge(_) => PyValueError::new_err(msg),
        _ => PyRuntimeError::new_err(msg),
    }
}

/// The lock, whether or not a thread panicked holding it (what it guards is only ever added to).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The GPUs opened so far, one device per adapter, and which adapter is the best one.
struct Gpus {
    open: Vec<&'static Gpu>,
    best: Option<usize>,
}
static GPUS: Mutex<Gpus> = Mutex::new(Gpus { open: Vec::new(), best: None });
/// What `device="auto"` resolved to: a hardware GPU, or `None` for the native runtime.
static AUTO: OnceLock<Option<&'static Gpu>> = OnceLock::new();

/// The GPU of adapter `index` (`None`: the best one), opened on first use and kept: `gpu` and
/// `gpu:N` naming the same adapter share one device.
fn gpu(index: Option<usize>) -> kdray::Result<&'static Gpu> {
    let mut g = lock(&GPUS);
    let known = |g: &Gpus, i: Option<usize>| i.and_then(|i| g.open.iter().copied().find(|d| d.index == i));
    if let Some(d) = known(&g, index.or(g.best)) {
        return Ok(d);
    }
    let opened = match index {
        None => Gpu::new()?,
        Some(i) => Gpu::open(i)?,
    };
    if index.is_none() {
        g.best = Some(opened.index);
        if let Some(d) = known(&g, g.best) {
            return Ok(d);
        }
    }
    let d: &'static Gpu = Box::leak(Box::new(opened));
    g.open.push(d);
    Ok(d)
}

/// The runtime a `device` argument names: `auto` (a hardware GPU when there is one, else the
/// CPU: a software Vulkan driver runs the same kernels slower than the native runtime), `cpu`,
/// `gpu` (the best adapter, software ones included) or `gpu:N` (adapter N of `devices()`).
fn runtime(device: &str) -> kdray::Result<&'static dyn Runtime> {
    let g = match device {
        "cpu" => return Ok(&NATIVE),
        "auto" => *AUTO.get_or_init(|| gpu(None).ok().filter(|g| !g.is_software())),
        "gpu" => Some(gpu(None)?),
        d => match d.strip_prefix("gpu:").map(str::parse::<usize>) {
            Some(Ok(i)) => Some(gpu(Some(i))?),
            _ => return Err(Error::InvalidInput(format!("unknown device '{d}': use auto, cpu, gpu or gpu:N"))),
        },
    };
    Ok(match g {
        Some(g) => g,
        None => &NATIVE,
    })
}

/// The acceleration structure a tracer holds.
#[derive(Copy, Clone, PartialEq, Eq, Debug)]
enum Structure {
    None,
    KdTree,
    Bvh,
}

/// A scene and what was built for it on demand.
#[pyclass(module = "kdray._native", frozen)]
struct Scene {
    scene: kdray::Scene,
    tree: Mutex<Option<Arc<KdTreeData>>>,
    bvh: Mutex<Option<Arc<BvhData>>>,
    /// One tracer per (runtime, structure): the runtime's address names it.
    tracers: Mutex<Vec<(usize, Structure, Arc<Tracer<'static>>)>>,
}

impl Scene {
    fn new(scene: kdray::Scene) -> Self {
        Scene { scene, tree: Mutex::new(None), bvh: Mutex::new(None), tracers: Mutex::new(Vec::new()) }
    }

    fn tree(&self) -> kdray::Result<Arc<KdTreeData>> {
        let mut t = lock(&self.tree);
        if t.is_none() {
            *t = Some(Arc::new(kdtree::try_build(&self.scene.triangles, &Default::default())?));
        }
        Ok(t.as_ref().expect("built").clone())
    }

    fn bvh(&self) -> kdray::Result<Arc<BvhData>> {
        let mut b = lock(&self.bvh);
        if b.is_none() {
            *b = Some(Arc::new(kdray::bvh::try_build(&self.scene.triangles)?));
        }
        Ok(b.as_ref().expect("built").clone())
    }

    /// The tracer for `device` holding what `accel` traverses, built on first use.
    fn tracer(&self, device: &str, accel: Accel) -> PyResult<Arc<Tracer<'static>>> {
        let rt = runtime(device).map_err(|e| py_err("device", e))?;
        let structure = if accel.needs_bvh() {
            Structure::Bvh
        } else if accel.needs_tree() {
            Structure::KdTree
        } else {
            Structure::None
        };
        let key = rt as *const dyn Runtime as *const u8 as usize;
        let find = |list: &[(usize, Structure, Arc<Tracer<'static>>)]| list.iter().find(|(k, s, _)| *k == key && *s == structure).map(|(_, _, t)| t.clone());
        if let Some(t) = find(&lock(&self.tracers)) {
            return Ok(t);
        }
        // The structure first, under its own lock (a build takes seconds per million
        // triangles): calls on other devices and structures go on meanwhile.
        let ctx = |e| py_err(&self.scene.name, e);
        let tree = if structure == Structure::KdTree { Some(self.tree().map_err(ctx)?) } else { None };
        let bvh = if structure == Structure::Bvh { Some(self.bvh().map_err(ctx)?) } else { None };
        let mut list = lock(&self.tracers);
        if let Some(t) = find(&list) {
            return Ok(t);
        }
        let mut t = Tracer::new(rt, &self.scene, tree.as_deref()).map_err(ctx)?;
        if let Some(b) = bvh {
            t = t.with_bvh(&b).map_err(ctx)?;
        }
        let t = Arc::new(t);
        list.push((key, structure, t.clone()));
        Ok(t)
    }
}

/// Rays from an (N, 6) or (N, 8) float32 array (origin, direction; or origin, t_min,
/// direction, t_max), the interval replaced where `t_min` / `t_max` are given.
fn rays_from(data: &[f32], cols: usize, t_min: Option<&[f32]>, t_max: Option<&[f32]>) -> Vec<Ray> {
    (0..data.len() / cols)
        .map(|i| {
            let r = &data[i * cols..(i + 1) * cols];
            let (o, d, lo, hi) = match cols {
                8 => ([r[0], r[1], r[2]], [r[4], r[5], r[6]], r[3], r[7]),
                _ => ([r[0], r[1], r[2]], [r[3], r[4], r[5]], 0.0, f32::INFINITY),
            };
            Ray::new(o, d, t_min.map_or(lo, |t| t[i]), t_max.map_or(hi, |t| t[i]))
        })
        .collect()
}

/// A render's progress for Python: calls `callback(done, total)` as work completes, and stops
/// the render (`Progress::cancelled`) when the callback raises or a signal handler does
/// (Ctrl-C: `KeyboardInterrupt`), keeping the exception for the caller.
struct PyProgress {
    callback: Option<Py<PyAny>>,
    total: AtomicU64,
    done: AtomicU64,
    error: Mutex<Option<PyErr>>,
}

impl PyProgress {
    fn keep(&self, e: PyErr) {
        lock(&self.error).get_or_insert(e);
    }
}

impl Progress for PyProgress {
    fn start(&self, total: u64) {
        self.total.store(total, Ordering::Relaxed);
    }

    fn advance(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        if let Some(cb) = &self.callback {
            let total = self.total.load(Ordering::Relaxed);
            if let Err(e) = Python::attach(|py| cb.call1(py, (done, total)).map(drop)) {
                self.keep(e);
            }
        }
    }

    fn cancelled(&self) -> bool {
        if let Err(e) = Python::attach(|py| py.check_signals()) {
            self.keep(e);
        }
        lock(&self.error).is_some()
    }
}

/// The unit normal of triangle (a, b, c) by the right-hand rule (computed in f64: exact to
/// float32 rounding however thin the triangle).
fn unit_normal(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [f32; 3] {
    let e1 = [0, 1, 2].map(|k| b[k] as f64 - a[k] as f64);
    let e2 = [0, 1, 2].map(|k| c[k] as f64 - a[k] as f64);
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 0.0 {
        n.map(|x| (x / len) as f32)
    } else {
        [0.0; 3]
    }
}

#[pymethods]
impl Scene {
    /// One indexed triangle mesh: vertices (V, 3) float32, faces (F, 3) uint32, both C-contiguous.
    #[staticmethod]
    fn from_arrays(py: Python<'_>, name: &str, vertices: PyReadonlyArray2<'_, f32>, faces: PyReadonlyArray2<'_, u32>) -> PyResult<Self> {
        if vertices.shape()[1] != 3 || faces.shape()[1] != 3 {
            return Err(PyValueError::new_err("vertices and faces must have 3 columns"));
        }
        let v: &[[f32; 3]] = bytemuck::cast_slice(vertices.as_slice()?);
        let f: &[[u32; 3]] = bytemuck::cast_slice(faces.as_slice()?);
        let s = py.detach(|| kdray::Scene::from_mesh(name, v, f)).map_err(|e| py_err("", e))?;
        Ok(Scene::new(s))
    }

    /// A scene file (`.obj` with its MTL, `.toml`) or a built-in scene name.
    #[staticmethod]
    fn load(py: Python<'_>, spec: &str) -> PyResult<Self> {
        let spec = spec.to_string();
        let s = py.detach(move || kdray::scene::load(&spec)).map_err(|e| py_err("", e))?;
        Ok(Scene::new(s))
    }

    #[getter]
    fn name(&self) -> &str {
        &self.scene.name
    }

    /// Triangles kept (faces of zero area are dropped).
    #[getter]
    fn triangle_count(&self) -> usize {
        self.scene.triangles.len()
    }

    #[getter]
    fn dropped_degenerate(&self) -> usize {
        self.scene.dropped_degenerate
    }

    #[getter]
    fn light_count(&self) -> usize {
        self.scene.lights().len()
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scene.warnings.clone()
    }

    /// (min, max) corners of the triangles' bounding box.
    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let (lo, hi) = self.scene.bounds();
        (lo.to_array(), hi.to_array())
    }

    /// (eye, look_at, up, vertical field of view in degrees).
    #[getter]
    fn camera(&self) -> ([f32; 3], [f32; 3], [f32; 3], f32) {
        let c = &self.scene.camera;
        (c.eye.to_array(), c.look_at.to_array(), c.up.to_array(), c.fov_y_deg)
    }

    /// Each triangle's face number in the source mesh (`primitive_ids` are these).
    fn faces<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        self.scene.triangles.iter().map(|t| t.face).collect::<Vec<u32>>().into_pyarray(py)
    }

    /// Each triangle's vertices, T·9 float32 (`faces` gives their face numbers).
    fn triangle_vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.scene.triangles.iter().flat_map(|t| [t.v0, t.v1, t.v2]).flatten().collect::<Vec<f32>>().into_pyarray(py)
    }

    /// Closest hits (`any_hit` false) or occlusion of rays (N, 6 or 8) float32: (t, face ids,
    /// barycentrics (2N), unit geometric normals (3N)), or a bool array. With `check`, a ray
    /// the kernels cannot trace is a `ValueError`; without, it is a miss.
    #[pyo3(signature = (rays, t_min, t_max, device, traversal, any_hit, check))]
    #[allow(clippy::too_many_arguments)]
    fn cast<'py>(
        &self,
        py: Python<'py>,
        rays: PyReadonlyArray2<'py, f32>,
        t_min: Option<PyReadonlyArray1<'py, f32>>,
        t_max: Option<PyReadonlyArray1<'py, f32>>,
        device: &str,
        traversal: &str,
        any_hit: bool,
        check: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let cols = rays.shape()[1];
        if cols != 6 && cols != 8 {
            return Err(PyValueError::new_err(format!("rays: {cols} columns, expected 6 or 8")));
        }
        let n = rays.shape()[0];
        let data = rays.as_slice()?;
        let lo = t_min.as_ref().map(|t| t.as_slice()).transpose()?;
        let hi = t_max.as_ref().map(|t| t.as_slice()).transpose()?;
        if lo.is_some_and(|t| t.len() != n) || hi.is_some_and(|t| t.len() != n) {
            return Err(PyValueError::new_err("t_min and t_max must hold one value per ray"));
        }
        let parsed = match traversal {
            "auto" => None,
            t => Some(Accel::parse(t).map_err(|e| py_err("traversal", e))?),
        };
        let tris = &self.scene.triangles;
        py.detach(|| -> PyResult<_> {
            // `auto`: the fastest for the device (opened here, without the GIL): natively the
            // BVH's eight-ray SIMD packets, on a GPU the BVH one ray per thread.
            let accel = match parsed {
                Some(a) => a,
                None if runtime(device).map_err(|e| py_err("device", e))?.is_native() => Accel::BVH_PACKETS,
                None => Accel::BVH,
            };
            let tracer = self.tracer(device, accel)?;
            // (N, 8) float32 is the library's ray layout: traced where NumPy holds it.
            let owned;
            let rays: &[Ray] = if cols == 8 && lo.is_none() && hi.is_none() {
                bytemuck::cast_slice(data)
            } else {
                owned = rays_from(data, cols, lo, hi);
                &owned
            };
            // The kernels answer "no hit" for a ray they cannot trace; a caller hears why.
            if let Some(i) = check.then(|| rays.iter().position(|r| !r.is_valid())).flatten() {
                let r = &rays[i];
                return Err(PyValueError::new_err(format!(
                    "rays: ray {i} cannot be traced (origin {:?}, direction {:?}, interval [{}, {}]): it needs a finite origin, a finite non-zero direction and 0 <= t_min <= t_max",
                    r.origin, r.dir, r.t_min, r.t_max
                )));
            }
            if any_hit {
                return Ok(Err(tracer.any_hits(accel, rays).map_err(|e| py_err("rays", e))?));
            }
            let hits = tracer.closest_hits(accel, rays).map_err(|e| py_err("rays", e))?;
            let (mut t, mut ids) = (Vec::with_capacity(n), Vec::with_capacity(n));
            let (mut uv, mut normals) = (Vec::with_capacity(2 * n), Vec::with_capacity(3 * n));
            for h in &hits {
                t.push(h.t);
                match tris.get(h.prim as usize) {
                    Some(tri) if h.is_hit() => {
                        ids.push(tri.face);
                        uv.extend([h.b1, h.b2]);
                        normals.extend(unit_normal(tri.v0, tri.v1, tri.v2));
                    }
                    _ => {
                        ids.push(MISS);
                        uv.extend([0.0; 2]);
                        normals.extend([0.0; 3]);
                    }
                }
            }
            Ok(Ok((t, ids, uv, normals)))
        })
        .map(|r| match r {
            Err(occluded) => occluded.into_pyarray(py).into_any(),
            Ok((t, ids, uv, normals)) => {
                (t.into_pyarray(py), ids.into_pyarray(py), uv.into_pyarray(py), normals.into_pyarray(py)).into_pyobject(py).expect("tuple").into_any()
            }
        })
    }

    /// Renders the scene's camera view (or the camera given): linear RGB radiance, H·W·3
    /// float32, rows top first, and a warning line when fewer passes ran than asked (a pass
    /// failed after a checkpoint; the image holds those before it).
    #[pyo3(signature = (width, height, integrator, spp, passes, photons, bounces, seed, device, traversal, camera, time_limit, progress))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        integrator: &str,
        spp: u32,
        passes: u32,
        photons: Option<u32>,
        bounces: u32,
        seed: u32,
        device: &str,
        traversal: &str,
        camera: Option<([f32; 3], [f32; 3], [f32; 3], f32)>,
        time_limit: Option<f64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, Option<String>)> {
        let accel = Accel::parse(traversal).map_err(|e| py_err("traversal", e))?;
        let mut spec = self.scene.camera.clone();
        if let Some((eye, look_at, up, fov)) = camera {
            spec = kdray::scene::CameraSpec { eye: eye.into(), look_at: look_at.into(), up: up.into(), fov_y_deg: fov };
        }
        let cam = spec.to_pod(width, height);
        let integrator = integrator.to_string();
        let report = PyProgress { callback: progress, total: AtomicU64::new(0), done: AtomicU64::new(0), error: Mutex::new(None) };
        let rendered = py.detach(|| -> PyResult<_> {
            let t = self.tracer(device, accel)?;
            let ctx = |e| py_err(&self.scene.name, e);
            let paths = |o: &PathOptions| path::render_checkpointed(&t, accel, &cam, o, &report).map(|(out, _)| (out, None)).map_err(ctx);
            let (out, note) = match integrator.as_str() {
                "direct" => paths(&PathOptions::direct(seed, bounces))?,
                "path" => paths(&PathOptions::path(seed, bounces, spp))?,
                "photon" => {
                    let o = PhotonOptions {
                        photons: photons.unwrap_or(if t.rt.is_native() { 1 << 18 } else { 1 << 20 }),
                        passes,
                        time_limit,
                        eye_bounces: bounces,
                        eye_samples: spp,
                        seed,
                        ..Default::default()
                    };
                    let mut map = PhotonMap::new(&t, accel, None, &self.scene, o).map_err(ctx)?;
                    let (out, s) = pm::render(&mut map, &cam, &report).map_err(ctx)?;
                    (out, s.interrupted)
                }
                other => return Err(PyValueError::new_err(format!("integrator: unknown '{other}': use photon, path or direct"))),
            };
            Ok((out.radiance.iter().flat_map(|p| [p[0], p[1], p[2]]).collect::<Vec<f32>>(), note))
        });
        // Stopped by the callback or a signal: its exception, not the partial image.
        if let Some(e) = lock(&report.error).take() {
            return Err(e);
        }
        let (radiance, note) = rendered?;
        Ok((radiance.into_pyarray(py), note))
    }
}

/// The name of the device `device` resolves to (opening it if needed).
#[pyfunction]
fn device_name(py: Python<'_>, device: &str) -> PyResult<String> {
    py.detach(|| runtime(device).map(|rt| rt.name())).map_err(|e| py_err("device", e))
}

/// Every Vulkan adapter, best first: `gpu:N` names entry N.
#[pyfunction]
fn devices(py: Python<'_>) -> Vec<String> {
    py.detach(|| kdray::gpu::adapters().iter().map(|a| kdray::gpu::describe(&a.get_info())).collect())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    check_cpu().map_err(|e| PyImportError::new_err(e.to_string()))?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(device_name, m)?)?;
    m.add_function(wrap_pyfunction!(devices, m)?)?;
    m.add("NoGpuError", m.py().get_type::<NoGpuError>())?;
    m.add("MISS", MISS)?;
    Ok(())
}
