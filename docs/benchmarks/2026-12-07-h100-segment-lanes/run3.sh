#!/bin/bash
# B (911bff1) against N8 (41a0acf's kernels): profiled renders of all four bench scenes, two
# rounds alternating, each render's whole profile table kept; one output file.
H=$(cd "$(dirname "$0")" && pwd); W=/tmp/w; mkdir -p $W
for v in B N8; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/all.txt
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader > $S
t0=$(date +%s)
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $W/$1 render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -vE "^\s*$" $W/o.txt | grep -v "^\[" >> $S
}
for v in B N8; do p $v warm$v cornell; done
for r in 1 2; do
  if [ $r = 1 ]; then vs="B N8"; else vs="N8 B"; fi
  for v in $vs; do for s in cornell-chair conference cornell cornell-glass; do p $v $v-$r $s; done; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 400 ] && break
done
echo "== images" >> $S
(cd $W && md5sum *.pfm) >> $S
echo "total $(( $(date +%s) - t0 )) s" >> $S
