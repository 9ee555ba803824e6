"""Casts the same rays with kdray (GPU and CPU) and with the tracers a Python user would
otherwise reach for — trimesh (with embreex when installed, else its pure-NumPy intersector
over an R-tree) and Open3D's RaycastingScene when installed — and prints how their answers
agree and how fast each is.

    python examples/compare_trimesh.py [MESH.obj] [--rays N] [--reps K]

Without a mesh: the Stanford bunny from the shared scenes folder (KDRAY_SHARED_SCENES, else
../shared/scenes beside the repository) when it is there, else an icosphere of 20 480 faces.
With --require-agreement P it fails (status 1) when two tracers agree on hit or miss for fewer
than P % of the rays. Rays: N primary rays of a camera framing the mesh (a square grid), and N rays between random
points of the mesh's bounding box. Times are the best of K calls after one warm-up call (the
warm-up builds kdray's acceleration structures and copies the scene to the device); trimesh's
pure-NumPy intersector is slow, so it gets fewer rays (--trimesh-rays).
"""
import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

import kdray


def icosphere(subdivisions):
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        mid, nf = {}, []
        for a, b, c in f:
            def m(i, j):
                k = (min(i, j), max(i, j))
                if k not in mid:
                    p = v[i] + v[j]
                    v.append(p / np.linalg.norm(p))
                    mid[k] = len(v) - 1
                return mid[k]
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    return np.array(v, np.float32), np.array(f, np.int64)


def read_obj(path):
    """Vertices and triangulated faces of an OBJ file (positions only)."""
    v, f = [], []
    with open(path) as fh:
        for line in fh:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                v.append([float(x) for x in p[1:4]])
            elif p[0] == "f":
                idx = [int(x.split("/")[0]) for x in p[1:]]
                idx = [i - 1 if i > 0 else len(v) + i for i in idx]
                f += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(v, np.float32), np.array(f, np.int64)


def rays_for(v, n, seed=0):
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    side = int(round(n**0.5))
    # Primary rays: a pinhole camera on +z, 40 degrees, framing the bounding sphere.
    eye = centre + np.array([0, 0, radius / np.sin(np.radians(20))])
    s = np.tan(np.radians(20))
    x, y = np.meshgrid((np.arange(side) + 0.5) / side * 2 - 1, 1 - (np.arange(side) + 0.5) / side * 2)
    d = np.stack([x * s, y * s, -np.ones_like(x)], axis=-1).reshape(-1, 3)
    primary = np.concatenate([np.broadcast_to(eye, d.shape), d / np.linalg.norm(d, axis=1, keepdims=True)], axis=1)
    # Incoherent rays: between random points of the box, normalised.
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(lo, hi, (side * side, 3)), rng.uniform(lo, hi, (side * side, 3))
    random = np.concatenate([a, (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)], axis=1)
    return {"primary": primary.astype(np.float32), "random": random.astype(np.float32)}


def best_of(f, reps, warm_up=True):
    out = f() if warm_up else None
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return out, min(times)


WORST = [100.0]  # the lowest hit/miss agreement seen, in percent


def agreement(ids, t, ref_ids, ref_t):
    hit, ref_hit = ids != kdray.INVALID_ID, ref_ids != kdray.INVALID_ID
    both = hit & ref_hit
    dt = np.abs(t[both] - ref_t[both]) / np.maximum(ref_t[both], 1e-30)
    agree = np.mean(hit == ref_hit) * 100
    WORST[0] = min(WORST[0], agree)
    return f"hit/miss agree {agree:.3f} %, same face {np.mean(ids == ref_ids) * 100:.3f} %, max |dt|/t {dt.max() if dt.size else 0:.1e}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh", nargs="?")
    ap.add_argument("--rays", type=int, default=1 << 20)
    ap.add_argument("--trimesh-rays", type=int, default=1 << 14)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--require-agreement", type=float, metavar="PERCENT",
                    help="exit with status 1 when any two tracers agree on hit or miss for fewer rays than this")
    a = ap.parse_args()

    if a.mesh:
        path = Path(a.mesh)
    else:
        path = Path(os.environ.get("KDRAY_SHARED_SCENES", Path(__file__).resolve().parents[3] / "shared" / "scenes")) / "stanford-bunny.obj"
    if path.exists():
        v, f = read_obj(path)
        name = path.name
    else:
        if a.mesh:
            sys.exit(f"error: {path}: no such file")
        print(f"note: {path} not found: an icosphere instead")
        v, f = icosphere(5)
        name = "icosphere"
    print(f"{name}: {len(v)} vertices, {len(f)} faces")

    scene = kdray.Scene(v, f)
    devices = ["cpu"]
    try:
        devices.insert(0, "gpu")
        print(f"kdray gpu: {kdray.device_name('gpu')}")
    except kdray.NoGpuError as e:
        devices.remove("gpu")
        print(f"kdray: no GPU ({e}): the CPU only")
    print(f"kdray cpu: {kdray.device_name('cpu')}")

    peers = {}
    try:
        import trimesh

        mesh = trimesh.Trimesh(v, f, process=False)
        backend = type(mesh.ray).__module__.split(".")[-1]

        def trimesh_cast(r):
            o, d = r[:, :3].astype(np.float64), r[:, 3:].astype(np.float64)
            tri, ray, loc = mesh.ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
            ids = np.full(len(r), kdray.INVALID_ID, np.uint32)
            t = np.full(len(r), np.inf, np.float32)
            ids[ray] = tri
            loc = np.asarray(loc, np.float64).reshape(-1, 3)
            t[ray] = np.linalg.norm(loc - o[ray], axis=1) / np.linalg.norm(d[ray], axis=1)
            return ids, t

        peers[f"trimesh ({backend})"] = (trimesh_cast, a.rays if backend == "ray_pyembree" else a.trimesh_rays)
    except ImportError:
        print("note: trimesh is not installed (pip install trimesh rtree): skipped")
    try:
        import open3d as o3d

        rs = o3d.t.geometry.RaycastingScene()
        rs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f.astype(np.uint32)))

        def open3d_cast(r):
            ans = rs.cast_rays(o3d.core.Tensor(r))
            return ans["primitive_ids"].numpy().astype(np.uint32), ans["t_hit"].numpy()

        peers["Open3D (Embree)"] = (open3d_cast, a.rays)
    except ImportError:
        print("note: Open3D is not installed: skipped")

    for kind, rays in rays_for(v, a.rays).items():
        print(f"\n{kind} rays: {len(rays)}")
        ref = None
        for device in devices:
            for traversal in ["bvh", "bvh+packets", "shortstack"] if device == "cpu" else ["bvh", "shortstack"]:
                hits, secs = best_of(lambda: scene.cast_rays(rays, device=device, traversal=traversal), a.reps)
                ids, t = hits["primitive_ids"], hits["t_hit"]
                line = f"  {'kdray ' + device + ' ' + traversal:<24} {len(rays) / secs / 1e6:9.3g} Mrays/s"
                if ref is None:
                    ref = (ids, t)
                    print(line + f"  ({(ids != kdray.INVALID_ID).mean() * 100:.1f} % hit; the reference below)")
                else:
                    print(line + "  " + agreement(ids, t, *ref))
        for peer, (cast, n) in peers.items():
            every = max(1, len(rays) // n)  # a subset spread over all of them
            sub = rays[::every]
            (ids, t), secs = best_of(lambda: cast(sub), 1, warm_up=False) if every > 1 else best_of(lambda: cast(sub), a.reps)
            some = f" (every {every}th ray)" if every > 1 else ""
            print(f"  {peer:<24} {len(sub) / secs / 1e6:9.3g} Mrays/s  {agreement(ids, t, ref[0][::every], ref[1][::every])}{some}")
    if a.require_agreement is not None and WORST[0] < a.require_agreement:
        sys.exit(f"error: hit/miss agreement {WORST[0]:.3f} % is below --require-agreement {a.require_agreement} %")


if __name__ == "__main__":
    main()
