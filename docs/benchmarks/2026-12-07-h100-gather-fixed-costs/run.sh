#!/bin/bash
# r28: one binary N (main 67ba8ee); gather_grid variants as modules (KDRAY_SPIRV):
# G main; C run stores only for non-empty runs; S map-dependent values by selects (no run-time-indexed arrays) + gather_slack unrolled;
# K window constants 7/3 on the GPU (measurement only); CS = C+S; A = C+S+K.
# P = CS + HashGrid::with (production form of K: the default window as constants, code twice).
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w28; mkdir -p $W
gunzip -c $H/N.gz > $W/N; chmod +x $W/N
V="G C S K CS A P"
for v in $V; do gunzip -c $H/$v.spv.gz > $W/$v.spv; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
t0=$(date +%s)
echo "== pipeline statistics (photon::gather_grid)" >> $S
for v in $V; do
  echo "== $v" >> $S
  timeout 30 $H/pipeline_stats $W/$v.spv $W/ps-$v photon::gather_grid 2>&1 | grep -E "Register|Local|Binary|Shared" >> $S
done
b() { # variant tag
  rm -rf $W/b; KDRAY_SPIRV=$W/$1.spv KDRAY_PHOTONS_SPEED_ONLY=1 timeout 100 $W/N bench photons --size 1024 --scene cornell-glass --scene cornell --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/photons-$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
for v in $V; do b $v ${v}1; done
echo "round 1 done at $(( $(date +%s) - t0 )) s" >> $S
for v in P A CS K S C G; do b $v ${v}2; [ $(( $(date +%s) - t0 )) -gt 400 ] && break; done
echo "round 2 done at $(( $(date +%s) - t0 )) s" >> $S
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== renders: glass 1071 passes seed 1; 64-pass PFM md5" >> $S
for v in G P A G P A; do
  KDRAY_SPIRV=$W/$v.spv timeout 40 $W/N render --scene cornell-glass --passes 1071 --seed 1 --size 512 --device gpu -o $W/n-$v.png > $W/o.txt 2>&1
  echo "$v: $(grep -E '^rendered|rror' $W/o.txt | tr '\n' ' ')" >> $S
  [ $(( $(date +%s) - t0 )) -gt 520 ] && break
done
for v in $V; do
  KDRAY_SPIRV=$W/$v.spv timeout 20 $W/N render --scene cornell-glass --passes 64 --seed 1 --size 256 --device gpu -o $W/p-$v.png > $W/o.txt 2>&1
  echo "$v 64p: $(md5sum $W/p-$v.pfm 2>/dev/null | cut -c1-12) $(grep -E 'rror' $W/o.txt)" >> $S
  [ $(( $(date +%s) - t0 )) -gt 570 ] && break
done
echo "total $(( $(date +%s) - t0 )) s" >> $S
