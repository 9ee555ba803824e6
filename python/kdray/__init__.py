"""kdray: ray casting and photon mapping written once in Rust, run on any Vulkan GPU or natively.

NumPy rays in, hits out::

    import numpy as np, kdray
    scene = kdray.Scene(vertices, faces)            # (V, 3) float, (F, 3) int
    rays = np.array([[0.2, 0.3, 5, 0, 0, -1]], np.float32)   # origin xyz, direction xyz
    hits = scene.cast_rays(rays)                   # dict of arrays, one entry per ray
    hits["t_hit"], hits["primitive_ids"], hits["primitive_uvs"], hits["primitive_normals"]
    blocked = scene.test_occlusions(rays, t_max=4.0)

The same kernels run on the GPU (any Vulkan device, through wgpu) and on the CPU (all cores):
``device="gpu"`` or ``"cpu"``; ``"auto"`` (the default) takes a hardware GPU when there is one.
C-contiguous float32 (uint32 for faces) arrays are read where NumPy holds them (rays of 8
columns are the library's own ray layout and are handed to it as they are), the result arrays
take over the vectors the library's answers are written to, and the GIL is released while a
call traces, builds or renders.
"""
from __future__ import annotations

import math
import os
from typing import Dict, Optional, Sequence, Tuple, Union

import numpy as np

# Mesa's Vulkan drivers probe Wayland while enumerating adapters, and libwayland prints an
# "error:" line when XDG_RUNTIME_DIR is unset (headless machines, CI).
if "XDG_RUNTIME_DIR" not in os.environ:
    import tempfile

    os.environ["XDG_RUNTIME_DIR"] = tempfile.gettempdir()

from . import _native  # noqa: E402
from ._native import NoGpuError

__all__ = ["Scene", "NoGpuError", "INVALID_ID", "devices", "device_name", "TRAVERSALS"]

#: The ``primitive_ids`` of a ray that hits nothing (as Open3D's ``INVALID_ID``).
INVALID_ID: int = _native.MISS

#: The traversals ``cast_rays`` and ``test_occlusions`` take (``shortstack:N``, N = 1..8,
#: and ``+packets`` after a kd traversal or ``bvh`` also work). ``auto``, the default: the
#: BVH, natively in eight-ray SIMD packets (``bvh+packets``), on a GPU one ray per thread.
TRAVERSALS = ("auto", "shortstack", "stack", "restart", "pushdown", "bvh", "bvh+packets", "brute")

ArrayLike = Union[np.ndarray, Sequence]


def devices() -> list:
    """Every Vulkan adapter, best first; ``device="gpu:N"`` names entry N."""
    return _native.devices()


def device_name(device: str = "auto") -> str:
    """What ``device`` resolves to here: the Vulkan adapter's description, or ``"CPU (16
    threads)"``. Raises ``NoGpuError`` when it names a GPU there is not."""
    return _native.device_name(_device(device))


def _device(device) -> str:
    if not isinstance(device, str):
        raise TypeError(f"device: expected a str (auto, cpu, gpu or gpu:N), got {type(device).__name__}")
    return device


def _traversal(traversal) -> str:
    if not isinstance(traversal, str):
        raise TypeError(f"traversal: expected a str such as 'shortstack' or 'bvh', got {type(traversal).__name__}")
    return traversal


def _array(value, name: str, kind: str) -> np.ndarray:
    """``value`` as an ndarray of real numbers (kind "f": floating point or integers, converted
    to float32) or of integers (kind "i"), with a TypeError naming the argument otherwise."""
    try:
        a = np.asarray(value)
    except Exception as e:  # ragged lists and the like
        raise TypeError(f"{name}: cannot be read as an array ({e})") from None
    if kind == "f" and a.dtype.kind not in "fiu":
        raise TypeError(f"{name}: dtype {a.dtype}, expected real numbers (float32 is used as it is, other types are converted)")
    if kind == "i" and a.dtype.kind not in "iu":
        raise TypeError(f"{name}: dtype {a.dtype}, expected integers (uint32 is used as it is, other widths are converted)")
    return a


def _contiguous(a: np.ndarray, dtype) -> np.ndarray:
    # No copy when it already is C-contiguous and aligned, of this dtype.
    return np.require(a, dtype=dtype, requirements=["C", "A"])


def _finite_rows(a: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(a).all(axis=-1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: row {i} is not finite ({a[i].tolist()})")


class Scene:
    """Triangles to cast rays at (and, from a scene file, materials, lights and a camera to
    render). Acceleration structures are built on first use and kept: the kd-tree (SAH, on the
    CPU) for the kd traversals, the compressed wide BVH for ``bvh``, ``bvh+packets`` and
    ``auto`` (the default traversal); each device gets its own copy of the scene on first use.

    ``Scene(vertices, faces)``: vertices (V, 3) floating point, faces (F, 3) integers indexing
    them. Faces of zero area are dropped (they can never be hit; see ``dropped_degenerate``);
    ``primitive_ids`` are always face numbers of the mesh given.
    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike, name: str = "mesh"):
        v = _array(vertices, "vertices", "f")
        f = _array(faces, "faces", "i")
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices: shape {v.shape}, expected (V, 3)")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces: shape {f.shape}, expected (F, 3)")
        if v.shape[0] == 0 or f.shape[0] == 0:
            raise ValueError(f"empty mesh: {v.shape[0]} vertices, {f.shape[0]} faces")
        _finite_rows(v, "vertices")
        if f.shape[0] >= 2**32 - 1:
            raise ValueError(f"faces: {f.shape[0]} faces; face numbers are uint32 (at most 2^32 - 2 faces)")
        if f.size and (f.min() < 0 or f.max() >= v.shape[0]):
            bad = int(np.flatnonzero(((f < 0) | (f >= v.shape[0])).any(axis=1))[0])
            raise ValueError(f"faces: face {bad} ({f[bad].tolist()}) indexes a vertex outside 0..{v.shape[0] - 1}")
        if not isinstance(name, str):
            raise TypeError(f"name: expected a str, got {type(name).__name__}")
        self._s = _native.Scene.from_arrays(name, _contiguous(v, np.float32), _contiguous(f, np.uint32))

    @classmethod
    def from_obj(cls, path: Union[str, os.PathLike]) -> "Scene":
        """A Wavefront OBJ file (with its MTL materials when there are any). Its polygons are
        fanned into triangles: ``primitive_ids`` number the triangles in file order."""
        p = os.fsdecode(path)
        if not p.lower().endswith(".obj"):
            raise ValueError(f"path: '{p}' is not an .obj file (Scene.from_file reads .toml scenes)")
        return cls._wrap(_native.Scene.load(p))

    @classmethod
    def from_file(cls, path: Union[str, os.PathLike]) -> "Scene":
        """A scene file (``.toml``: triangles, materials, lights, camera; or ``.obj``) or a
        built-in scene: ``cornell``, ``cornell-glass``, ``cornell-chair``, ``conference``, …"""
        return cls._wrap(_native.Scene.load(os.fsdecode(path)))

    @classmethod
    def _wrap(cls, native) -> "Scene":
        s = cls.__new__(cls)
        s._s = native
        return s

    # What the scene holds.
    @property
    def name(self) -> str:
        return self._s.name

    @property
    def triangle_count(self) -> int:
        """Triangles kept (faces of zero area dropped)."""
        return self._s.triangle_count

    @property
    def dropped_degenerate(self) -> int:
        """Faces of zero area dropped while loading."""
        return self._s.dropped_degenerate

    @property
    def light_count(self) -> int:
        return self._s.light_count

    @property
    def warnings(self) -> list:
        """What loading let pass but a user should hear of (e.g. an unreadable MTL file)."""
        return self._s.warnings

    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """(min, max) corners of the triangles' bounding box."""
        lo, hi = self._s.bounds
        return np.array(lo, np.float32), np.array(hi, np.float32)

    @property
    def triangles(self) -> np.ndarray:
        """The triangles traced, (T, 3, 3) float32 vertices (faces of zero area dropped)."""
        return self._s.triangle_vertices().reshape(-1, 3, 3)

    @property
    def triangle_faces(self) -> np.ndarray:
        """Each of ``triangles``' face number: what ``primitive_ids`` report for it."""
        return self._s.faces()

    @property
    def camera(self) -> dict:
        """The scene's camera: eye, look_at, up, fov (vertical, degrees)."""
        eye, look_at, up, fov = self._s.camera
        return {"eye": eye, "look_at": look_at, "up": up, "fov": fov}

    def __repr__(self) -> str:
        return f"kdray.Scene('{self.name}', {self.triangle_count} triangles, {self.light_count} lights)"

    # Ray casting.
    def _rays(self, rays, t_min, t_max):
        r = _array(rays, "rays", "f")
        if r.ndim < 1 or r.shape[-1] not in (6, 8):
            raise ValueError(f"rays: shape {r.shape}, expected (..., 6) (origin, direction) or (..., 8) (origin, t_min, direction, t_max)")
        batch = r.shape[:-1]
        flat = _contiguous(r, np.float32).reshape(-1, r.shape[-1])
        n = flat.shape[0]

        def interval(value, name):
            if value is None:
                return None
            a = _array(value, name, "f")
            try:
                a = np.broadcast_to(a, batch)
            except ValueError:
                raise ValueError(f"{name}: shape {a.shape} does not broadcast to the rays' {batch}") from None
            return _contiguous(a, np.float32).reshape(n)

        lo, hi = interval(t_min, "t_min"), interval(t_max, "t_max")
        return flat, batch, lo, hi

    def cast_rays(self, rays: ArrayLike, *, device: str = "auto", traversal: str = "auto",
                  t_min=None, t_max=None, invalid: str = "raise") -> Dict[str, np.ndarray]:
        """The closest hit of every ray.

        ``rays``: (..., 6) origin xyz, direction xyz (any length, not zero), traced over
        t in [0, inf); or (..., 8) origin xyz, t_min, direction xyz, t_max (the layout of
        ``kdray bench --dump-rays``). ``t_min`` / ``t_max``, when given, replace the interval
        (scalars or arrays broadcasting to the rays' batch shape). A ray that cannot be traced
        (a coordinate not finite, a zero direction, not 0 <= t_min <= t_max) raises
        ``ValueError`` naming it, or with ``invalid="miss"`` is a miss (rays from depth images
        with holes). ``traversal``: one of ``TRAVERSALS``; ``auto`` picks the BVH, natively
        in eight-ray SIMD packets.

        Returns arrays of the rays' batch shape: ``t_hit`` (float32, inf for a miss; the hit is
        origin + t_hit · direction), ``primitive_ids`` (uint32 face numbers, ``INVALID_ID`` for
        a miss), ``geometry_ids`` (0, the one mesh, or ``INVALID_ID``), ``primitive_uvs``
        (..., 2) (barycentric weights of the face's second and third vertex),
        ``primitive_normals`` (..., 3) (unit geometric normal, right-hand rule over the face's
        vertex order; zeros for a miss).
        """
        flat, batch, lo, hi = self._rays(rays, t_min, t_max)
        check = _invalid(invalid)
        if flat.shape[0] == 0:
            return {"t_hit": np.zeros(batch, np.float32), "primitive_ids": np.zeros(batch, np.uint32),
                    "geometry_ids": np.zeros(batch, np.uint32), "primitive_uvs": np.zeros(batch + (2,), np.float32),
                    "primitive_normals": np.zeros(batch + (3,), np.float32)}
        t, ids, uv, normals = self._s.cast(flat, lo, hi, _device(device), _traversal(traversal), False, check)
        ids = ids.reshape(batch)
        return {
            "t_hit": t.reshape(batch),
            "primitive_ids": ids,
            "geometry_ids": np.where(ids == INVALID_ID, np.uint32(INVALID_ID), np.uint32(0)),
            "primitive_uvs": uv.reshape(batch + (2,)),
            "primitive_normals": normals.reshape(batch + (3,)),
        }

    def test_occlusions(self, rays: ArrayLike, t_max=None, *, device: str = "auto",
                        traversal: str = "auto", t_min=None, invalid: str = "raise") -> np.ndarray:
        """Whether each ray hits anything for t in [t_min, t_max] (defaults: the rays' own
        interval with 8 columns, [0, inf) with 6): a bool array of the rays' batch shape. Any
        hit ends a ray's search, so this is faster than ``cast_rays``. ``invalid`` as there."""
        flat, batch, lo, hi = self._rays(rays, t_min, t_max)
        check = _invalid(invalid)
        if flat.shape[0] == 0:
            return np.zeros(batch, bool)
        return self._s.cast(flat, lo, hi, _device(device), _traversal(traversal), True, check).reshape(batch)

    # Images.
    def render(self, width: int = 512, height: Optional[int] = None, *, integrator: str = "photon",
               spp: Optional[int] = None, passes: int = 16, photons: Optional[int] = None,
               bounces: Optional[int] = None, seed: int = 1, device: str = "auto",
               traversal: str = "bvh", camera: Optional[dict] = None,
               time_limit: Optional[float] = None, progress=None) -> np.ndarray:
        """The scene seen by its camera (or ``camera``: a dict of eye, look_at, up and fov,
        vertical in degrees; missing entries from the scene's) as (height, width, 3) float32
        linear RGB radiance, top row first.

        ``integrator``: ``"photon"`` (progressive photon mapping: ``passes`` passes of
        ``photons`` photons each, default 2^20 on a GPU and 2^18 on the CPU; ``spp`` eye paths
        per pixel and pass, default 4; stops early after ``time_limit`` seconds), ``"path"``
        (path tracing with next-event estimation, ``spp`` samples, default 64) or ``"direct"``
        (direct light only). ``bounces`` caps eye paths (defaults: 16, 32, 4). The scene needs
        a light (emissive triangles or point lights): a mesh made from arrays has none.

        ``progress``, when given, is called as ``progress(done, total)`` as the render goes
        (photon passes, or path samples over all pixels); an exception it raises stops the
        render and propagates, and so does Ctrl-C (``KeyboardInterrupt``), checked after every
        pass or sample group.
        """
        height = width if height is None else height
        for name, value, lo, hi in (("width", width, 1, 16384), ("height", height, 1, 16384), ("passes", passes, 1, 1 << 20),
                                    ("seed", seed, 0, 2**32 - 1)):
            _int_in(name, value, lo, hi)
        if integrator not in ("photon", "path", "direct"):
            raise ValueError(f"integrator: unknown '{integrator}': use photon, path or direct")
        spp = (64 if integrator == "path" else 4) if spp is None else spp
        bounces = {"photon": 16, "path": 32, "direct": 4}[integrator] if bounces is None else bounces
        _int_in("spp", spp, 1, 1 << 20)
        _int_in("bounces", bounces, 0, 64)
        if photons is not None:
            _int_in("photons", photons, 1, 1 << 30)
        if time_limit is not None and not (isinstance(time_limit, (int, float)) and math.isfinite(time_limit) and time_limit > 0):
            raise ValueError(f"time_limit: expected a positive number of seconds, got {time_limit!r}")
        if self.light_count == 0:
            raise ValueError(f"scene '{self.name}' has no lights (emissive triangles or point lights): there is nothing to render; "
                             "load a scene file with lights, or cast rays instead")
        cam = None
        if camera is not None:
            if not isinstance(camera, dict) or not set(camera) <= {"eye", "look_at", "up", "fov"}:
                raise ValueError("camera: expected a dict with some of eye, look_at, up, fov")
            c = {**self.camera, **camera}
            vecs = []
            for key in ("eye", "look_at", "up"):
                with np.errstate(over="ignore"):
                    a = _contiguous(_array(c[key], f"camera['{key}']", "f"), np.float32)
                if a.shape != (3,) or not np.isfinite(a).all():
                    raise ValueError(f"camera['{key}']: expected 3 finite float32 numbers, got {c[key]!r}")
                vecs.append(a)
            fov = c["fov"]
            if not (isinstance(fov, (int, float, np.integer, np.floating)) and 0 < fov < 180):
                raise ValueError(f"camera['fov']: expected degrees in (0, 180), got {fov!r}")
            # As the library computes the view (float32): a direction it can normalise.
            with np.errstate(all="ignore"):
                forward = vecs[1] - vecs[0]
                right = np.cross(forward / np.linalg.norm(forward), vecs[2])
                ok = np.isfinite(forward).all() and np.linalg.norm(forward) > 0 and np.isfinite(right).all() and np.linalg.norm(right) > 1e-6 * np.linalg.norm(vecs[2])
            if not ok:
                raise ValueError("camera: eye and look_at must differ, and up must not be parallel to the view")
            cam = tuple(tuple(float(x) for x in v) for v in vecs) + (float(fov),)
        if progress is not None and not callable(progress):
            raise TypeError(f"progress: expected a callable progress(done, total), got {type(progress).__name__}")
        img, note = self._s.render(int(width), int(height), integrator, int(spp), int(passes),
                                   None if photons is None else int(photons), int(bounces), int(seed),
                                   _device(device), _traversal(traversal), cam, None if time_limit is None else float(time_limit),
                                   progress)
        if note is not None:
            import warnings
            warnings.warn(note, RuntimeWarning, stacklevel=2)
        return img.reshape(int(height), int(width), 3)


def _invalid(invalid) -> bool:
    if invalid not in ("raise", "miss"):
        raise ValueError(f"invalid: expected 'raise' or 'miss', got {invalid!r}")
    return invalid == "raise"


def _int_in(name: str, value, lo: int, hi: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    if not lo <= value <= hi:
        raise ValueError(f"{name}: {value} is outside {lo}..{hi}")
