import sys, datetime, statistics
builds, smi = sys.argv[1], sys.argv[2]
samples = []
for l in open(smi):
    p = [x.strip() for x in l.split(',')]
    try:
        t = datetime.datetime.strptime(p[0], "%Y/%m/%d %H:%M:%S.%f").timestamp() * 1e3
        samples.append((t, float(p[1].split()[0]), float(p[3].split()[0]) if p[3][0].isdigit() else 0.0))
    except Exception:
        pass
print("smi samples", len(samples))
cur = None
rows = []
def flush():
    if cur and rows:
        b = [r[0] for r in rows]
        print(cur, "| build ms:", " ".join("%.1f@%d" % (r[0], r[1]) for r in rows))
        print("   setup ms:", " ".join("%.1f" % r[2] for r in rows))
        print("   median build first10 %.2f last10 %.2f; median MHz first10 %d last10 %d" % (statistics.median(b[:10]), statistics.median(b[-10:]), statistics.median([r[1] for r in rows[:10]]), statistics.median([r[1] for r in rows[-10:]])))
for l in open(builds):
    if l.startswith("=="):
        flush(); cur = l.strip(); rows = []
    elif l.startswith("BUILD"):
        kv = dict(x.split('=') for x in l.split() if '=' in x)
        s, e = float(kv['epoch_start']), float(kv['epoch_end'])
        clk = [c for (t, c, w) in samples if s - 10 <= t <= e + 10]
        rows.append((float(kv['build']), statistics.median(clk) if clk else -1, float(kv['setup'])))
    else:
        print("  ", l.rstrip()[:200])
flush()
