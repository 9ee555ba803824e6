#!/bin/bash
# r29: one binary N (main 67ba8ee); gather_grid modules via KDRAY_SPIRV:
# G = main; L0 = the lanes of a subgroup walk the union of their windows row by row, each loading the same word at once (visit_lanes); L = L0 walking only the stream positions some lane counts.
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w29; mkdir -p $W
gunzip -c $H/N.gz > $W/N; chmod +x $W/N
V="G L0 L"
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
for v in G L0 L; do b $v ${v}1; done
echo "round 1 done at $(( $(date +%s) - t0 )) s" >> $S
for v in L G; do b $v ${v}2; done
echo "round 2 done at $(( $(date +%s) - t0 )) s" >> $S
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== renders: 1071 / 429 passes seed 1 (rendered in)" >> $S
for v in G L; do
  for sp in "cornell-glass 1071" "cornell 429"; do set -- $sp
    KDRAY_SPIRV=$W/$v.spv timeout 40 $W/N render --scene $1 --passes $2 --seed 1 --size 512 --device gpu -o $W/n-$v-$1.png > $W/o.txt 2>&1
    echo "$v $1 $2: $(grep -E '^rendered|rror' $W/o.txt | tr '\n' ' ')" >> $S
  done
  [ $(( $(date +%s) - t0 )) -gt 200 ] && break
done
echo "== 64-pass 512² PFMs (md5) and KDRAY_PROFILE gather" >> $S
for v in G L; do
  for sc in cornell-glass cornell; do
    KDRAY_PROFILE=1 KDRAY_SPIRV=$W/$v.spv timeout 25 $W/N render --scene $sc --passes 64 --seed 1 --size 512 --device gpu -o $W/p-$v-$sc.png > $W/o.txt 2>&1
    echo "$v $sc 64p: $(md5sum $W/p-$v-$sc.pfm 2>/dev/null | cut -c1-12) $(grep -iE 'gather' $W/o.txt | head -3 | tr '\n' ' ') $(grep rror $W/o.txt)" >> $S
  done
  [ $(( $(date +%s) - t0 )) -gt 260 ] && break
done
echo "total $(( $(date +%s) - t0 )) s" >> $S
