#!/bin/bash
# usage: ab.sh rounds threads bin1 bin2 ... ; prints per-bin per-scene min wall s/M and min cpu s/M
R=$1; T=$2; shift 2
SC="${SCENES:-conference /work/shared/scenes/stanford-bunny.obj}"
for r in $(seq $R); do for b in "$@"; do
  RAYON_NUM_THREADS=$T REPS=${REPS:-2} ${KDHASH_DIR:-/tmp}/kdhash-$b $SC | sed "s/^/$b /"
done; done > /tmp/kb/ab.out
python3 - <<'P'
import re,collections
d=collections.defaultdict(lambda:[[],[],set()])
for l in open('/tmp/kb/ab.out'):
    b,sc=l.split()[:2]
    w=re.search(r'all \[([^\]]*)\]',l).group(1); c=re.search(r'cpu-s/M \[([^\]]*)\]',l).group(1)
    h=re.search(r'nodes (\d+) refs (\d+) sah ([\d.]+) hash (\w+)',l).groups()
    d[(sc,b)][0]+= [float(x) for x in w.split(',')]; d[(sc,b)][1]+= [float(x) for x in c.split(',')]; d[(sc,b)][2].add(h)
for k,v in sorted(d.items()):
    w=sorted(v[0]); c=sorted(v[1])
    print(f"{k[0]:<15} {k[1]:<10} wall min {w[0]:.3f} med {w[len(w)//2]:.3f}  cpu min {c[0]:.3f} med {c[len(c)//2]:.3f}  {v[2]}")
P
