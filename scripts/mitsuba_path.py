"""Mitsuba 3's path tracer on a scene that `kdray bench photons` exported (the same triangles,
materials, lights and camera), timed and scored against kdray's path-traced reference with the
bench's error measure: RMSE of the displayed images (clamped at 1) over the reference's mean.

Usage: python3 scripts/mitsuba_path.py BENCH_OUT SCENE VARIANT SPP [SPP ...]
  BENCH_OUT: the bench's --out folder (holds mitsuba-SCENE/ and reference-SCENE.pfm)
  VARIANT:   cuda_ad_rgb (OptiX) or llvm_ad_rgb (Embree)
Prints one line per sample count and appends it to BENCH_OUT/mitsuba-error.csv. Renders in
chunks of at most 1024 samples per pixel (different seeds) averaged; the first chunk size is
rendered once untimed so that kernel compilation is not counted.
"""
import os, sys, time
import numpy as np
import mitsuba as mi
import drjit as dr

out, scene_name, variant = sys.argv[1], sys.argv[2], sys.argv[3]
spps = [int(s) for s in sys.argv[4:]]
mi.set_variant(variant)


def read_pfm(p):
    with open(p, "rb") as f:
        assert f.readline().strip() == b"PF"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")[: w * h * 3].reshape(h, w, 3)
    return a[::-1]


def write_pfm(p, a):
    h, w, _ = a.shape
    with open(p, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        f.write(np.ascontiguousarray(a[::-1], dtype="<f4").tobytes())


ref = read_pfm(os.path.join(out, f"reference-{scene_name}.pfm"))
scene = mi.load_file(os.path.join(out, f"mitsuba-{scene_name}", "scene.xml"))


def error(img):
    a, b = np.clip(img, 0, 1), np.clip(ref, 0, 1)
    return float(np.sqrt(((a - b) ** 2).mean()) / b.mean()), float((((img - ref) ** 2) / (ref ** 2 + 0.01)).mean())


def render(spp):
    chunks, acc, left, seed = 0, None, spp, 1
    while left > 0:
        n = min(left, 1024)
        img = np.array(mi.render(scene, spp=n, seed=seed))[:, :, :3] * n
        acc = img if acc is None else acc + img
        left -= n
        seed += 1
    return acc / spp


render(min(spps[0], 1024))  # compile
dr.sync_thread()
csv = os.path.join(out, "mitsuba-error.csv")
new = not os.path.exists(csv)
with open(csv, "a") as f:
    if new:
        f.write("scene,variant,spp,seconds,rel RMSE %,relMSE\n")
    for spp in spps:
        t0 = time.perf_counter()
        img = render(spp)
        dr.sync_thread()
        secs = time.perf_counter() - t0
        e, m = error(img)
        line = f"{scene_name},{variant},{spp},{secs:.3f},{e * 100:.3f},{m:.3e}"
        print(line, flush=True)
        f.write(line + "\n")
    write_pfm(os.path.join(out, f"mitsuba-{scene_name}-{spps[-1]}spp.pfm"), img)
