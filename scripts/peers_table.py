"""One table of kdray against the peers on the same rays: reads `kdray bench horn`'s CSV and the
output of `../shared/peers/same_rays_gpu.sh` (Mitsuba 3 and tinybvh's CWBVH on the rays that
bench dumped, in the same run) and writes OUT.csv and OUT.md with every tracer's Mrays/s, the
ratios, and how far the answers agree.

Usage: python3 scripts/peers_table.py HORN.csv PEERS.log OUT
  kdray: the BVH row and the fastest kd-tree row per scene and ray type (GPU timestamps), and
  the rasterised primaries' row (`raster+bvh`) where the bench measured one;
  OptiX: Mitsuba's `cuda_ad_rgb` (wall time per launch); CWBVH: the better of tinybvh's two
  builds and, for shadow rays, of its occlusion and closest-hit kernels (CUDA events).
Only the standard library: it runs wherever the tables are.
"""
import csv, re, sys

horn, log, out = sys.argv[1], sys.argv[2], sys.argv[3]
rows = list(csv.DictReader(open(horn)))
text = open(log).read()

kd, bvh, raster, meta = {}, {}, {}, {}
for r in rows:
    key = (r["scene"], r["ray_type"])
    v = float(r["mrays_s_gpu_timestamps"] or r["mrays_s_wall"])
    if not r["method"].startswith("raster+"):
        meta[key] = (r["rays"], r["device"], r["date"], r["oracle_mismatch_rate"])
    if r["method"] == "bvh":
        bvh[key] = v
    elif r["method"].startswith("raster+"):
        raster[key] = v
    elif r["method"] != "brute" and v > kd.get(key, (0.0, ""))[0]:
        kd[key] = (v, r["method"])

optix, agree = {}, {}
for m in re.finditer(r"^(\S+)-(primary|shadow): peer=cuda_ad_rgb rays=\d+ Mrays/s=([\d.]+) same-answer=(\d+)/(\d+)", text, re.M):
    optix[(m[1], m[2])] = float(m[3])
    agree[(m[1], m[2])] = f"{m[4]}/{m[5]}"

cwbvh = {}
for m in re.finditer(r"^(\S+)-(primary|shadow)-rays\s+rays\s+\d+ \| closest:\s+([\d.]+) Mrays/s.*?\| occluded:\s+([\d.]+) Mrays/s", text, re.M):
    key = (m[1], m[2])
    v = float(m[3]) if m[2] == "primary" else max(float(m[3]), float(m[4]))
    cwbvh[key] = max(cwbvh.get(key, 0.0), v)

same = {}
for m in re.finditer(r"^(\S+)-(primary|shadow)-rays\s+(\d+)\s+(\d+)\s", text, re.M):
    same[(m[1], m[2])] = f"{m[4]}/{m[3]}"

header = ["scene", "ray type", "rays", "kd fastest (method)", "BVH", "OptiX (Mitsuba 3)", "CWBVH (tinybvh)",
          "BVH / OptiX", "BVH / CWBVH", "kd / OptiX", "kd / CWBVH", "kdray oracle mismatch", "Mitsuba same answer", "CWBVH same hit/miss (closest-hit kernel)"]
if raster:
    header[7:7] = ["rasterised primaries", "raster / BVH"]
table = []
for key in sorted(bvh, key=lambda k: (list(bvh).index(k))):
    k, b, o, c = kd.get(key, (float("nan"), "")), bvh[key], optix.get(key, float("nan")), cwbvh.get(key, float("nan"))
    row = [key[0], key[1], meta[key][0], f"{k[0]:.0f} ({k[1]})", f"{b:.0f}", f"{o:.0f}", f"{c:.0f}",
           f"{b / o:.2f}", f"{b / c:.2f}", f"{k[0] / o:.2f}", f"{k[0] / c:.2f}", meta[key][3], agree.get(key, ""), same.get(key, "")]
    if raster:
        row[7:7] = [f"{raster[key]:.0f}", f"{raster[key] / b:.2f}"] if key in raster else ["", ""]
    table.append(row)

with open(out + ".csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["date", "device"] + header)
    for t in table:
        key = (t[0], t[1])
        w.writerow([meta[key][2], meta[key][1]] + t)
with open(out + ".md", "w") as f:
    first = next(iter(meta.values()))
    f.write(f"# kdray and the peers on the same rays\n\nDate {first[2]}; device {first[1]}. Mrays/s.\n\n")
    f.write("| " + " | ".join(header) + " |\n|" + "---|" * len(header) + "\n")
    for t in table:
        f.write("| " + " | ".join(t) + " |\n")
print(f"wrote {out}.csv and {out}.md ({len(table)} rows)")
