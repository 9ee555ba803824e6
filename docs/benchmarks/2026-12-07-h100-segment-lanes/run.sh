#!/bin/bash
# The prepared measurement of segment-lanes.diff (README.md beside it). Put beside this script, in a
# git-ignored folder carried to the device (e.g. carry/rNN/): B.gz (main's stripped `kdray`,
# gzipped), N.gz (the same with the patch applied and `bash scripts/kernels.sh` run BEFORE the
# build: the library embeds the module), difftest.gz and phototest.gz (the patched `differential`
# and `photon` test binaries, built after kernels.sh too: `cargo test --release -p kdray --test
# differential --test photon --no-run`, stripped, gzipped), and sum.py, cmp.py,
# pfm.py from ../2026-12-06-h100-one-index/. Run with .gl's Vulkan loader (the device README).
# B against N (the segment offsets by a subgroup's lanes): the two tests on NVIDIA's subgroups of
# 32 first, then profiled renders and bench photons, alternating, then the photon test suite.
H=$(cd "$(dirname "$0")" && pwd); W=/tmp/w; mkdir -p $W
for v in B N difftest phototest; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader > $S
t0=$(date +%s)
KDRAY_REQUIRE_GPU=1 timeout 120 $W/difftest counting_sort segment_offsets > $OUT/difftest.txt 2>&1; echo "difftest rc=$?" >> $S
grep -E "^test |test result" $OUT/difftest.txt >> $S
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
for v in B N; do p $v warm$v cornell; done
# A patched module that hangs or fails stops the run here, leaving time for the tests' report.
grep -q "^rendered" <(sed -n '/== warmN cornell/,$p' $S) || { echo "N's warm-up render failed: stopping" >> $S; exit 0; }
for r in 1 2; do
  if [ $r = 1 ]; then vs="B N"; else vs="N B"; fi
  for v in $vs; do p $v $v$r cornell-glass; p $v $v$r cornell; done
  echo "round $r profiles done at $(( $(date +%s) - t0 )) s" >> $S
  for v in $vs; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 330 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
(cd $W && md5sum *.pfm) >> $S
for s in cornell-glass cornell; do python3 $H/cmp.py $W/B1-$s.pfm $W/N1-$s.pfm $W/B2-$s.pfm $W/N2-$s.pfm >> $S 2>&1; done
echo "== photon tests at $(( $(date +%s) - t0 )) s" >> $S
left=$(( 560 - ($(date +%s) - t0) ))
if [ $left -gt 30 ]; then
  KDRAY_REQUIRE_GPU=1 timeout $left $W/phototest > $OUT/phototest.txt 2>&1; echo "phototest rc=$?" >> $S
else
  echo "no time left for the photon tests" >> $S
fi
grep -E "test result|FAILED|panicked" $OUT/phototest.txt >> $S
echo "total $(( $(date +%s) - t0 )) s" >> $S
