"""Mitsuba 3's path tracer on a scene that `kdray bench photons` exported (the same triangles,
materials, lights and camera), timed and scored against kdray's path-traced reference with the
bench's error measure: RMSE of the displayed images (clamped at 1) over the reference's mean.

Usage: python3 scripts/mitsuba_path.py DIR SCENE VARIANT SPP [SPP ...]
       python3 scripts/mitsuba_path.py DIR SCENE VARIANT --reference SPP
  DIR:     holds mitsuba-SCENE/ (`kdray export --mitsuba DIR/mitsuba-SCENE`) and, in the first
           form, reference-SCENE.pfm
  VARIANT: cuda_ad_rgb (OptiX) or llvm_ad_rgb (Embree)
First form: prints one line per sample count and appends it to DIR/mitsuba-error.csv. Second
form: renders a reference of SPP samples as two independent halves and writes
DIR/reference-SCENE.pfm (their mean) and DIR/reference-SCENE.err (its own error: half the
halves' difference, same measure), which `kdray bench photons` reads with KDRAY_REFERENCE_DIR.
Renders in chunks of at most 1024 samples per pixel (different seeds) averaged; the first chunk
size is rendered once untimed so that kernel compilation is not counted.
"""
import os, sys, time
import numpy as np
import mitsuba as mi
import drjit as dr

out, scene_name, variant = sys.argv[1], sys.argv[2], sys.argv[3]
reference_mode = sys.argv[4] == "--reference"
spps = [int(s) for s in sys.argv[5:]] if reference_mode else [int(s) for s in sys.argv[4:]]
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


scene = mi.load_file(os.path.join(out, f"mitsuba-{scene_name}", "scene.xml"))


def rel_rmse(img, ref):
    a, b = np.clip(img, 0, 1), np.clip(ref, 0, 1)
    return float(np.sqrt(((a - b) ** 2).mean()) / b.mean())


def error(img):
    a, b = np.clip(img, 0, 1), np.clip(ref, 0, 1)
    return float(np.sqrt(((a - b) ** 2).mean()) / b.mean()), float((((img - ref) ** 2) / (ref ** 2 + 0.01)).mean())


def render(spp, seed=1):
    acc, left = None, spp
    while left > 0:
        n = min(left, 1024)
        img = np.array(mi.render(scene, spp=n, seed=seed))[:, :, :3] * n
        acc = img if acc is None else acc + img
        left -= n
        seed += 1
    return acc / spp


render(min(spps[0], 1024))  # compile
dr.sync_thread()
if reference_mode:
    t0 = time.perf_counter()
    a = render(spps[0] // 2, seed=1)
    b = render(spps[0] // 2, seed=1 << 20)
    dr.sync_thread()
    own = rel_rmse(a, b) / 2
    write_pfm(os.path.join(out, f"reference-{scene_name}.pfm"), (a + b) / 2)
    with open(os.path.join(out, f"reference-{scene_name}.err"), "w") as f:
        f.write(f"{own}\n")
    print(f"{scene_name}: reference {spps[0]} spp in {time.perf_counter() - t0:.1f} s, own error {own * 100:.3f} %", flush=True)
    sys.exit(0)
ref = read_pfm(os.path.join(out, f"reference-{scene_name}.pfm"))
csv = os.path.join(out, "mitsuba-error.csv")
new = not os.path.exists(csv)
with open(csv, "a") as f:
    if new:
        f.write("scene,variant,spp,seconds,rel RMSE %,relMSE\n")
    for spp in spps:
        t0 = time.perf_counter()
        img = render(spp, seed=1 << 24)  # seeds apart from the reference's
        dr.sync_thread()
        secs = time.perf_counter() - t0
        e, m = error(img)
        line = f"{scene_name},{variant},{spp},{secs:.3f},{e * 100:.3f},{m:.3e}"
        print(line, flush=True)
        f.write(line + "\n")
    write_pfm(os.path.join(out, f"mitsuba-{scene_name}-{spps[-1]}spp.pfm"), img)
