"""The Python package against the Rust library and the command line, on the CPU and on the GPU
(lavapipe where there is no GPU: KDRAY_REQUIRE_GPU=1 makes a missing adapter a failure, as in
the Rust tests).

The command line's answers come from the `kdray` binary (KDRAY_BIN, else target/release/kdray;
with KDRAY_REQUIRE_BIN=1 a missing binary fails instead of skipping): `bench --dump-rays` writes
rays, the scene as OBJ and the native full-stack traversal's answers, and `render` writes PFM
images; the package must give the same answers on the same rays and the same image.
"""
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import kdray

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python" / "examples"))
from compare_trimesh import icosphere  # noqa: E402
REQUIRE_GPU = os.environ.get("KDRAY_REQUIRE_GPU") == "1"
KD_TRAVERSALS = ["stack", "restart", "pushdown", "shortstack", "shortstack:1", "shortstack+packets"]


def has_gpu():
    try:
        kdray.device_name("gpu")
        return True
    except kdray.NoGpuError:
        return False


DEVICES = ["cpu"] + (["gpu"] if REQUIRE_GPU or has_gpu() else [])


def kdray_bin():
    p = Path(os.environ.get("KDRAY_BIN", ROOT / "target" / "release" / "kdray"))
    if not p.exists():
        if os.environ.get("KDRAY_REQUIRE_BIN") == "1":
            pytest.fail(f"no kdray binary at {p} (KDRAY_REQUIRE_BIN=1)")
        pytest.skip(f"no kdray binary at {p}: build it with cargo build --release")
    return p


def cube():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [3, 7, 6], [3, 6, 2], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]])
    return v, f


def grid_rays(n=64, z=3.0):
    """n × n rays along −z from z, over [−0.5, 1.5]²: a quarter of them hit the unit cube."""
    x, y = np.meshgrid((np.arange(n) + 0.5) / n * 2 - 0.5, (np.arange(n) + 0.5) / n * 2 - 0.5)
    r = np.zeros((n, n, 6), np.float32)
    r[..., 0], r[..., 1], r[..., 2], r[..., 5] = x, y, z, -1
    return r


def sphere(subdivisions=3):
    """An icosphere of radius 1 (20 · 4^subdivisions faces), the example's."""
    v, f = icosphere(subdivisions)
    return v, f.astype(np.uint32)


def random_rays(n, seed=0, scale=2.0):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-scale, scale, (n, 3))
    target = rng.uniform(-0.8, 0.8, (n, 3))
    return np.concatenate([o, target - o], axis=1).astype(np.float32)


# Geometry whose answers are known.
@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("traversal", KD_TRAVERSALS + ["bvh", "bvh+packets", "auto", "brute"])
def test_cube_known_answers(device, traversal):
    scene = kdray.Scene(*cube())
    rays = grid_rays()
    hits = scene.cast_rays(rays, device=device, traversal=traversal)
    assert hits["t_hit"].shape == (64, 64) and hits["primitive_ids"].dtype == np.uint32
    assert hits["primitive_uvs"].shape == (64, 64, 2) and hits["primitive_normals"].shape == (64, 64, 3)
    inside = (rays[..., 0] > 0) & (rays[..., 0] < 1) & (rays[..., 1] > 0) & (rays[..., 1] < 1)
    hit = hits["primitive_ids"] != kdray.INVALID_ID
    np.testing.assert_array_equal(hit, inside)
    # The top face z = 1 (faces 2 and 3) at t = 2, normal +z.
    assert np.all(hits["t_hit"][hit] == 2.0) and np.all(np.isinf(hits["t_hit"][~hit]))
    assert set(np.unique(hits["primitive_ids"][hit])) == {2, 3}
    np.testing.assert_allclose(hits["primitive_normals"][hit], np.broadcast_to([0, 0, 1], (hit.sum(), 3)), atol=1e-7)
    np.testing.assert_array_equal(hits["primitive_normals"][~hit], 0)
    # Barycentrics put the hit point back together.
    v, f = cube()
    tri = v[f[hits["primitive_ids"][hit]]]
    uv = hits["primitive_uvs"][hit]
    p = tri[:, 0] * (1 - uv[:, :1] - uv[:, 1:]) + tri[:, 1] * uv[:, :1] + tri[:, 2] * uv[:, 1:]
    o = rays[hit][:, :3] + 2.0 * rays[hit][:, 3:]
    np.testing.assert_allclose(p, o, atol=1e-6)
    # Occlusion over [0, t_max]: the top face is 2 units away.
    np.testing.assert_array_equal(scene.test_occlusions(rays, device=device, traversal=traversal), inside)
    assert not scene.test_occlusions(rays, t_max=1.99, device=device, traversal=traversal).any()
    np.testing.assert_array_equal(scene.test_occlusions(rays, t_max=2.0, device=device, traversal=traversal), inside)


def test_primitive_ids_are_face_numbers_with_degenerate_faces_dropped():
    v, f = cube()
    f = np.concatenate([[[0, 0, 1], [1, 1, 1]], f])  # two zero-area faces first
    scene = kdray.Scene(v, f)
    assert scene.dropped_degenerate == 2 and scene.triangle_count == 12
    hits = scene.cast_rays(grid_rays())
    ids = hits["primitive_ids"][hits["primitive_ids"] != kdray.INVALID_ID]
    assert set(np.unique(ids)) == {4, 5}


def test_ray_layouts_and_intervals():
    scene = kdray.Scene(*cube())
    r6 = grid_rays(16).reshape(-1, 6)
    r8 = np.zeros((r6.shape[0], 8), np.float32)
    r8[:, :3], r8[:, 4:7], r8[:, 7] = r6[:, :3], r6[:, 3:], np.inf
    a, b = scene.cast_rays(r6), scene.cast_rays(r8)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    # t_min past the top face finds the bottom one at t = 3; per-ray t_max arrays broadcast.
    hit = a["primitive_ids"] != kdray.INVALID_ID
    np.testing.assert_array_equal(scene.cast_rays(r6, t_min=2.5)["t_hit"][hit], 3.0)
    r8[:, 3] = 2.5
    np.testing.assert_array_equal(scene.cast_rays(r8)["t_hit"][hit], 3.0)
    t_max = np.where(np.arange(len(r6)) % 2 == 0, 1.0, 10.0)
    np.testing.assert_array_equal(scene.test_occlusions(r6, t_max=t_max), hit & (t_max > 2))
    # float64, lists and non-contiguous arrays are converted; batch shapes are kept.
    np.testing.assert_array_equal(scene.cast_rays(r6.astype(np.float64))["t_hit"], a["t_hit"])
    np.testing.assert_array_equal(scene.cast_rays(r6.tolist())["t_hit"], a["t_hit"])
    wide = np.zeros((r6.shape[0], 12), np.float32)
    wide[:, ::2] = r6
    np.testing.assert_array_equal(scene.cast_rays(wide[:, ::2])["t_hit"], a["t_hit"])
    assert scene.cast_rays(r6.reshape(2, 8, 16, 6))["t_hit"].shape == (2, 8, 16)
    assert scene.cast_rays(r6[0])["t_hit"].shape == ()
    assert scene.cast_rays(np.zeros((0, 6), np.float32))["t_hit"].shape == (0,)
    # Integers are numbers too; misaligned buffers are copied; t_max broadcasts over a 2-D batch.
    np.testing.assert_array_equal(scene.test_occlusions(r6, t_max=4), hit)
    np.testing.assert_array_equal(kdray.Scene(v_int := cube()[0].astype(np.int64), cube()[1]).cast_rays(r6)["t_hit"], a["t_hit"])
    assert v_int.dtype == np.int64
    raw = np.zeros(r6.nbytes + 1, np.uint8)
    raw[1:] = r6.view(np.uint8).ravel()
    misaligned = np.frombuffer(raw.data, np.float32, offset=1).reshape(r6.shape)
    assert not misaligned.flags.aligned
    np.testing.assert_array_equal(scene.cast_rays(misaligned)["t_hit"], a["t_hit"])
    batch = r6.reshape(16, 16, 6)
    per_column = np.where(np.arange(16) < 8, 1.0, 10.0)
    np.testing.assert_array_equal(scene.test_occlusions(batch, t_max=per_column), hit.reshape(16, 16) & (per_column > 2))
    # Open3D's result keys; geometry 0 is the mesh.
    np.testing.assert_array_equal(a["geometry_ids"], np.where(hit, 0, kdray.INVALID_ID))


def test_rays_that_cannot_be_traced_are_misses_when_asked():
    scene = kdray.Scene(*cube())
    rays = grid_rays(8).reshape(-1, 6)
    want = scene.cast_rays(rays)
    bad = rays.copy()
    bad[::3, 0] = np.nan
    bad[1::3, 3:] = 0
    hits = scene.cast_rays(bad, invalid="miss")
    ok = np.arange(len(rays)) % 3 == 2
    np.testing.assert_array_equal(hits["primitive_ids"][ok], want["primitive_ids"][ok])
    assert (hits["primitive_ids"][~ok] == kdray.INVALID_ID).all() and np.isinf(hits["t_hit"][~ok]).all()
    occluded = scene.test_occlusions(bad, invalid="miss")
    np.testing.assert_array_equal(occluded, ok & (want["primitive_ids"] != kdray.INVALID_ID))
    with pytest.raises(ValueError, match="rays: ray 0 cannot be traced"):
        scene.test_occlusions(bad)


def test_triangles_and_files(tmp_path):
    v, f = cube()
    scene = kdray.Scene(v, np.concatenate([[[0, 0, 1]], f]))
    np.testing.assert_array_equal(scene.triangles, v[f])
    np.testing.assert_array_equal(scene.triangle_faces, np.arange(1, 13))
    # An OBJ file, its extension in capitals, its path as bytes: the same triangles.
    p = tmp_path / "CUBE.OBJ"
    p.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
    for path in (p, str(p), bytes(p)):
        s = kdray.Scene.from_obj(path)
        np.testing.assert_array_equal(s.triangles, v[f])
        np.testing.assert_array_equal(s.cast_rays(grid_rays(8))["t_hit"], scene.cast_rays(grid_rays(8))["t_hit"])


@pytest.mark.parametrize("device", DEVICES)
def test_traversals_agree_on_a_sphere(device):
    scene = kdray.Scene(*sphere(4))
    rays = random_rays(20000)
    ref = scene.cast_rays(rays, device="cpu", traversal="brute")
    hit = ref["primitive_ids"] != kdray.INVALID_ID
    assert 5000 < hit.sum() < 20000
    for traversal in KD_TRAVERSALS + ["bvh", "bvh+packets"]:
        got = scene.cast_rays(rays, device=device, traversal=traversal)
        differ = (got["primitive_ids"] != ref["primitive_ids"]).sum()
        assert differ <= 2, f"{traversal} on {device}: {differ} ids differ"  # ties at shared edges
        both = hit & (got["primitive_ids"] == ref["primitive_ids"])
        np.testing.assert_allclose(got["t_hit"][both], ref["t_hit"][both], rtol=1e-5, atol=1e-6)  # t near 0: origins on the sphere
        np.testing.assert_array_equal(scene.test_occlusions(rays, device=device, traversal=traversal), hit)


# The Rust library's answers, through the command line's --dump-rays files.
@pytest.fixture(scope="module")
def dumped(tmp_path_factory):
    d = tmp_path_factory.mktemp("dump")
    subprocess.run([str(kdray_bin()), "bench", "horn", "--scene", "cornell-chair", "--device", "cpu", "--size", "128", "--reps", "1",
                    "--method", "shortstack:3", "--dump-rays", str(d), "--out", str(d / "bench")], check=True, capture_output=True)
    return d


@pytest.mark.parametrize("device", DEVICES)
def test_same_answers_as_the_rust_library_on_dumped_rays(dumped, device):
    scene = kdray.Scene.from_obj(dumped / "cornell-chair.obj")
    rays = np.load(dumped / "cornell-chair-primary-rays.npy")
    ids, t = np.load(dumped / "cornell-chair-primary-hit-id.npy"), np.load(dumped / "cornell-chair-primary-hit-t.npy")
    assert rays.shape == (128 * 128, 8) and (ids != kdray.INVALID_ID).sum() > 10000
    # The dump's answers are the native full-stack traversal's: the same call here gives them
    # bit for bit (the OBJ holds the same floats, so the kd-tree is the same).
    if device == "cpu":
        got = scene.cast_rays(rays, device="cpu", traversal="stack")
        np.testing.assert_array_equal(got["primitive_ids"], ids)
        np.testing.assert_array_equal(got["t_hit"], t)
    for traversal in KD_TRAVERSALS + ["bvh", "bvh+packets"]:
        got = scene.cast_rays(rays, device=device, traversal=traversal)
        differ = (got["primitive_ids"] != ids).sum()
        assert differ <= 2, f"{traversal} on {device}: {differ} of {len(ids)} ids differ"
        same = got["primitive_ids"] == ids
        np.testing.assert_allclose(got["t_hit"][same], t[same], rtol=1e-5)
    shadow = np.load(dumped / "cornell-chair-shadow-rays.npy")
    occluded = np.load(dumped / "cornell-chair-shadow-hit-id.npy") == 1
    assert 100 < occluded.sum() < len(occluded)
    for traversal in ["stack", "shortstack", "bvh"]:
        got = scene.test_occlusions(shadow, device=device, traversal=traversal)
        assert (got != occluded).sum() <= 2, traversal


def read_pfm(path):
    with open(path, "rb") as fh:
        kind = fh.readline().strip()
        w, h = map(int, fh.readline().split())
        scale = float(fh.readline())
        data = np.fromfile(fh, "<f4" if scale < 0 else ">f4")
    assert kind == b"PF"
    return data.reshape(h, w, 3)[::-1]  # PFM rows run bottom to top


def test_render_matches_the_command_line(tmp_path):
    out = tmp_path / "cornell.png"
    subprocess.run([str(kdray_bin()), "render", "--scene", "cornell", "--device", "cpu", "--size", "48", "--integrator", "path",
                    "--spp", "4", "--seed", "7", "--out", str(out)], check=True, capture_output=True)
    want = read_pfm(out.with_suffix(".pfm"))
    scene = kdray.Scene.from_file("cornell")
    img = scene.render(48, integrator="path", spp=4, seed=7, device="cpu")
    assert img.shape == (48, 48, 3) and img.dtype == np.float32
    np.testing.assert_array_equal(img, want)


@pytest.mark.parametrize("device", DEVICES)
def test_photon_render_gpu_and_cpu(device):
    scene = kdray.Scene.from_file("cornell")
    img = scene.render(40, 32, passes=2, photons=1 << 15, device=device)
    assert img.shape == (32, 40, 3) and np.isfinite(img).all() and (img >= 0).all()
    # The box is square: black beside it; its red wall on the left, the green one on the right.
    assert (img[:, :3] == 0).all() and (img[:, -3:] == 0).all()
    left, right = img[8:24, 5:9].mean(axis=(0, 1)), img[8:24, -9:-5].mean(axis=(0, 1))
    assert left[0] > 2 * left[1] and right[1] > 2 * right[0], (left, right)
    if device != "cpu":
        cpu = scene.render(40, 32, passes=2, photons=1 << 15, device="cpu")
        assert abs(img.mean() / cpu.mean() - 1) < 0.05


def test_render_with_a_camera():
    scene = kdray.Scene.from_file("cornell")
    c = scene.camera
    a = scene.render(16, integrator="direct", device="cpu")
    b = scene.render(16, integrator="direct", device="cpu", camera={"fov": c["fov"]})
    np.testing.assert_array_equal(a, b)
    zoomed = scene.render(16, integrator="direct", device="cpu", camera={"fov": c["fov"] / 2})
    rolled = scene.render(16, integrator="direct", device="cpu", camera={"up": [1, 0, 0]})
    assert not np.allclose(zoomed, a)
    np.testing.assert_allclose(rolled.mean(axis=(0, 1)), a.mean(axis=(0, 1)), rtol=0.05)
    assert not np.allclose(rolled, a)


# Threads: the GIL is released while tracing, and calls from several threads are safe.
def test_threads_get_the_same_answers():
    scene = kdray.Scene(*sphere(3))
    rays = random_rays(5000, seed=3)
    want = scene.cast_rays(rays, device="cpu")
    results = [None] * 4

    def work(i):
        results[i] = scene.cast_rays(rays, device=DEVICES[i % len(DEVICES)])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        assert (r["primitive_ids"] != want["primitive_ids"]).sum() <= 2


def count_until(done):
    n = 0
    while not done.is_set():
        n += 1
    return n


def test_the_gil_is_released_while_tracing():
    scene = kdray.Scene(*sphere(4))
    rays = random_rays(200000, seed=5)
    scene.cast_rays(rays[:10], device="cpu", traversal="brute")  # the scene on the device
    # How fast this thread counts in 0.2 s while another thread sleeps (no GIL held).
    done = threading.Event()
    timer = threading.Timer(0.2, done.set)
    timer.start()
    rate = count_until(done) / 0.2
    done = threading.Event()
    elapsed = []

    def trace():
        t0 = time.perf_counter()
        scene.cast_rays(rays, device="cpu", traversal="brute")  # 5120 triangles per ray
        elapsed.append(time.perf_counter() - t0)
        done.set()

    th = threading.Thread(target=trace)
    th.start()
    counted = count_until(done)
    th.join()
    # Holding the GIL, the trace would let this loop run only around the call (and the
    # trace's threads share the cores with it: a fraction of the rate).
    assert elapsed[0] > 0.1, "the trace is long enough to tell"
    assert counted > 0.1 * rate * elapsed[0], (counted, rate, elapsed)


# Bad input: one clear exception naming the argument, never a crash.
def test_bad_input():
    v, f = cube()
    scene = kdray.Scene(v, f)
    rays = grid_rays(4)
    cases = [
        (lambda: kdray.Scene(v[:, :2], f), ValueError, "vertices: shape"),
        (lambda: kdray.Scene(v, f[:, :2]), ValueError, "faces: shape"),
        (lambda: kdray.Scene(v.astype(np.complex64), f), TypeError, "vertices: dtype"),
        (lambda: kdray.Scene(v, np.where(f == 7, 2**32 + 7, f)), ValueError, "faces: face 3 ([4, 6, 4294967303])"),
        (lambda: kdray.Scene(v, f.astype(np.float32)), TypeError, "faces: dtype"),
        (lambda: kdray.Scene(np.where(np.arange(8)[:, None] == 3, np.nan, v), f), ValueError, "vertices: row 3 is not finite"),
        (lambda: kdray.Scene(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)), ValueError, "empty mesh"),
        (lambda: kdray.Scene(v, f + 1), ValueError, "faces: face"),
        (lambda: kdray.Scene(v, -f), ValueError, "faces: face"),
        (lambda: kdray.Scene(np.zeros((3, 3), np.float32), [[0, 1, 2]]), ValueError, "no triangle of non-zero area"),
        (lambda: kdray.Scene([[1, 2], [3]], f), TypeError, "vertices"),
        (lambda: kdray.Scene.from_obj("missing.obj"), OSError, "missing.obj"),
        (lambda: kdray.Scene.from_obj("scene.toml"), ValueError, "not an .obj file"),
        (lambda: kdray.Scene.from_file("nonsense"), ValueError, "unknown scene"),
        (lambda: scene.cast_rays(rays[..., :5]), ValueError, "rays: shape"),
        (lambda: scene.cast_rays(rays.astype(str)), TypeError, "rays: dtype"),
        (lambda: scene.cast_rays(rays, invalid="skip"), ValueError, "invalid: expected"),
        (lambda: scene.cast_rays(rays, 0.0), TypeError, "positional"),
        (lambda: scene.cast_rays(np.where(np.arange(6) == 4, np.inf, rays)), ValueError, "rays: ray 0 cannot be traced"),
        (lambda: scene.cast_rays(np.where(np.arange(6) >= 3, 0.0, rays)), ValueError, "a finite non-zero direction"),
        (lambda: scene.test_occlusions(rays, t_min=5.0, t_max=1.0), ValueError, "0 <= t_min <= t_max"),
        (lambda: scene.cast_rays(rays, t_min=-1.0), ValueError, "interval [-1, inf]"),
        (lambda: scene.cast_rays(rays, t_max=np.ones(3)), ValueError, "t_max: shape"),
        (lambda: scene.cast_rays(rays, device="tpu"), ValueError, "unknown device 'tpu'"),
        (lambda: scene.cast_rays(rays, device=0), TypeError, "device"),
        (lambda: scene.cast_rays(rays, device="gpu:99"), kdray.NoGpuError, "no GPU adapter"),
        (lambda: scene.cast_rays(rays, traversal="octree"), ValueError, "traversal: unknown traversal 'octree'"),
        (lambda: scene.test_occlusions(rays, traversal="brute+packets"), ValueError, "traversal"),
        (lambda: scene.render(16), ValueError, "no lights"),
        (lambda: kdray.Scene.from_file("cornell").render(0), ValueError, "width: 0"),
        (lambda: kdray.Scene.from_file("cornell").render(16, integrator="radiosity"), ValueError, "integrator"),
        (lambda: kdray.Scene.from_file("cornell").render(16, spp=1.5), TypeError, "spp"),
        (lambda: kdray.Scene.from_file("cornell").render(16, camera={"up": [0, 0, 0]}), ValueError, "camera"),
        (lambda: kdray.Scene.from_file("cornell").render(16, camera={"look_at": [278, 273, -800 + 1e-12]}), ValueError, "camera"),
        (lambda: kdray.Scene.from_file("cornell").render(16, camera={"eye": [0, 0, 1e39]}), ValueError, "camera['eye']"),
    ]
    for call, exc, text in cases:
        with pytest.raises(exc, match=None) as e:
            call()
        assert text in str(e.value), (text, str(e.value))
    assert issubclass(kdray.NoGpuError, RuntimeError)


def test_bad_files(tmp_path):
    p = tmp_path / "broken.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(ValueError, match="broken.obj:3"):
        kdray.Scene.from_obj(p)
    p = tmp_path / "nan.obj"
    p.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="nan.obj"):
        kdray.Scene.from_obj(p)
    p = tmp_path / "bad.toml"
    p.write_text("[camera\n")
    with pytest.raises(ValueError, match="bad.toml"):
        kdray.Scene.from_file(p)


def test_devices():
    names = kdray.devices()
    assert isinstance(names, list)
    assert "CPU" in kdray.device_name("cpu")
    if REQUIRE_GPU:
        assert names and kdray.device_name("gpu") == kdray.device_name("gpu:0")


def test_the_readme_example():
    text = (ROOT / "python" / "README.md").read_text()
    code = text.split("## Casting rays")[1].split("```python")[1].split("```")[0]
    env = {}
    exec(code, env)
    hits = env["hits"]
    np.testing.assert_array_equal(hits["t_hit"], [2.0, np.inf])
    np.testing.assert_array_equal(hits["primitive_ids"], [1, kdray.INVALID_ID])
    np.testing.assert_allclose(hits["primitive_normals"], [[0, 0, 1], [0, 0, 0]])
    np.testing.assert_array_equal(env["scene"].test_occlusions(env["rays"], t_max=1.5), [False, False])
    np.testing.assert_array_equal(env["scene"].test_occlusions(env["rays"]), [True, False])


def test_without_a_gpu():
    """With no Vulkan driver: device="gpu" is one clear error, "auto" and "cpu" trace natively."""
    code = (
        "import kdray, numpy as np\n"
        "s = kdray.Scene(np.eye(3, dtype=np.float32), [[0, 1, 2]])\n"
        "r = np.array([[0.2, 0.2, 1, 0, 0, -1]], np.float32)\n"
        "assert kdray.devices() == []\n"
        "assert s.cast_rays(r)['primitive_ids'][0] == 0 and 'CPU' in kdray.device_name()\n"
        "try:\n"
        "    s.cast_rays(r, device='gpu')\n"
        "except kdray.NoGpuError as e:\n"
        "    print(e)\n"
    )
    env = {**os.environ, "VK_DRIVER_FILES": "/nonexistent.json", "VK_ICD_FILENAMES": "/nonexistent.json"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("device: no GPU adapter"), out.stdout


def test_render_progress_and_stopping_it():
    scene = kdray.Scene.from_file("cornell")
    seen = []
    img = scene.render(16, passes=4, photons=1 << 12, device="cpu", progress=lambda done, total: seen.append((done, total)))
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)] and img.shape == (16, 16, 3)
    seen = []
    scene.render(16, integrator="path", spp=8, device="cpu", progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (16 * 16 * 8, 16 * 16 * 8) and all(a[0] < b[0] for a, b in zip(seen, seen[1:]))

    class Enough(Exception):
        pass

    def stop(done, total):
        if done >= 2:
            raise Enough(done)

    calls = []
    with pytest.raises(Enough):
        scene.render(16, passes=1000, photons=1 << 12, device="cpu", progress=lambda d, t: (calls.append(d), stop(d, t)))
    assert len(calls) < 10, "the render stopped soon after the callback raised"
    with pytest.raises(TypeError, match="progress"):
        scene.render(16, progress=3)


def test_ctrl_c_stops_a_render():
    import _thread
    import signal

    scene = kdray.Scene.from_file("cornell")
    scene.render(16, passes=1, photons=1 << 12, device="cpu")  # the tracer built
    # Python's own Ctrl-C handler (a process started in the background ignores SIGINT, and
    # then Python installs none).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.3, _thread.interrupt_main)
        timer.start()
        t0 = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            # The time limit ends it if the interrupt is not heard (the test then fails).
            scene.render(64, passes=100000, photons=1 << 14, device="cpu", time_limit=20)
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert time.perf_counter() - t0 < 15
