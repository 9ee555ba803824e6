#!/bin/bash
# r18: D = main (931866d); F = both maps' photons in one index (one visit a gather point)
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w; mkdir -p $W
for v in D F; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
echo "(D = 931866d; F = both maps' photons in one index, a word's map in a bit, one visit a gather point. Profiles: render --scene S --integrator photon --size 512 --passes 64, KDRAY_PROFILE=1: kernel, dispatches, total ms, us per dispatch, share)" >> $S
bin() { echo "$W/$1"; }
mer() { case $1 in G1) echo 1;; *) echo 0;; esac; }
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_MERGED=$(mer $1) KDRAY_PROFILE=1 timeout 120 $(bin $1) render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|gather_grid|place_photons|photon_keys_grid|segment_offsets|error|Error" $W/o.txt >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_MERGED=$(mer $1) KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $(bin $1) bench photons --size 1024 --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
t0=$(date +%s)
for v in D F; do p $v warm$v cornell; done
for r in 1 2; do
  for v in D F; do p $v $v$r cornell-glass; p $v $v$r cornell; done
  echo "round $r profiles done at $(( $(date +%s) - t0 )) s" >> $S
  for v in D F; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 330 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
for s in cornell-glass cornell; do python3 $H/cmp.py $W/D1-$s.pfm $W/F1-$s.pfm $W/D2-$s.pfm $W/F2-$s.pfm >> $S 2>&1; done
echo "== path tracer probe" >> $S
( time timeout 60 $W/D render --scene cornell-glass --integrator path --spp 1024 --size 512 --device gpu -o $W/pt.png ) >> $S 2>&1
echo "total $(( $(date +%s) - t0 )) s" >> $S
