#!/bin/bash
# B (main) against N8 and N32 (segment offsets by a subgroup's lanes, blocks of 8 or 32 segments
# placed by one atomic addition): the segment tests on the GPU, profiled renders and bench
# photons alternating, images compared, then the photon suite with N8.
H=$(cd "$(dirname "$0")" && pwd); W=/tmp/w; mkdir -p $W
for v in B N8 N32 difftest8 difftest32 phototest8; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader > $S
t0=$(date +%s)
for b in 8 32; do
  KDRAY_REQUIRE_GPU=1 timeout 120 $W/difftest$b counting_sort segment_offsets > $OUT/difftest$b.txt 2>&1; echo "difftest$b rc=$?" >> $S
  grep -E "^test |test result" $OUT/difftest$b.txt >> $S
done
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $W/$1 render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|gather_grid|place_photons|photon_keys_grid|segment_offsets|error|Error" $W/o.txt >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $W/$1 bench photons --size 1024 --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
for v in B N8 N32; do p $v warm$v cornell; done
for r in 1 2; do
  if [ $r = 1 ]; then vs="B N8 N32"; else vs="N32 N8 B"; fi
  for v in $vs; do p $v $v-$r cornell-glass; p $v $v-$r cornell; done
  echo "round $r profiles done at $(( $(date +%s) - t0 )) s" >> $S
  for v in $vs; do b $v $v-$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 330 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
(cd $W && md5sum *.pfm) >> $S
for s in cornell-glass cornell; do python3 $H/cmp.py $W/B-1-$s.pfm $W/N8-1-$s.pfm $W/N32-1-$s.pfm $W/N8-2-$s.pfm $W/N32-2-$s.pfm >> $S 2>&1; done
echo "== photon tests at $(( $(date +%s) - t0 )) s" >> $S
left=$(( 560 - ($(date +%s) - t0) ))
if [ $left -gt 30 ]; then
  KDRAY_REQUIRE_GPU=1 timeout $left $W/phototest8 > $OUT/phototest8.txt 2>&1; echo "phototest8 rc=$?" >> $S
else
  echo "no time left for the photon tests" >> $S
fi
grep -E "test result|FAILED|panicked" $OUT/phototest8.txt >> $S
echo "total $(( $(date +%s) - t0 )) s" >> $S
