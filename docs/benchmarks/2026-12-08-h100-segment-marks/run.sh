#!/bin/bash
# N8 (41a0acf, landed) against M (its offsets pass reading a block's marks first, side by side,
# and only the counts of segments that hold items): sort tests on the GPU, profiled renders of
# the four bench scenes alternating, image checksums, the photon suite with M. One output file.
H=$(cd "$(dirname "$0")" && pwd); W=/tmp/w; mkdir -p $W
for v in N8 M difftestM phototestM; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/all.txt
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader > $S
t0=$(date +%s)
KDRAY_REQUIRE_GPU=1 timeout 120 $W/difftestM counting_sort segment_offsets >> $S 2>&1; echo "difftestM rc=$?" >> $S
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $W/$1 render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|segment_offsets|photon_keys_grid|place_photons|error|Error" $W/o.txt >> $S
}
for v in N8 M; do p $v warm$v cornell; done
for r in 1 2; do
  if [ $r = 1 ]; then vs="N8 M"; else vs="M N8"; fi
  for v in $vs; do for s in cornell-chair conference cornell cornell-glass; do p $v $v-$r $s; done; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
done
echo "== images" >> $S
ls $W >> $S
md5sum $W/*.pfm >> $S 2>&1
left=$(( ${PT_LEFT:-400} - ($(date +%s) - t0) ))
if [ $left -gt 30 ]; then
  KDRAY_REQUIRE_GPU=1 timeout $left $W/phototestM > $W/pt.txt 2>&1; echo "phototestM rc=$?" >> $S
  grep -E "test result|FAILED|panicked" $W/pt.txt >> $S
else
  echo "photon suite not run (PT_LEFT)" >> $S
fi
echo "total $(( $(date +%s) - t0 )) s" >> $S
