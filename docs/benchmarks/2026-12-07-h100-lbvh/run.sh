#!/bin/bash
# r32: the kernels' LBVH (cubic 60-bit Morton, refine 128) on the device: builds, traversal
# (GPU time of closest_bvh with each tree), bench build --device gpu; then r27 (peers).
O=$OUT; mkdir -p $O/l $O/bench $O/b
D=carry/r32
nvidia-smi --query-gpu=name,driver_version --format=csv > $O/l/gpu.txt 2>&1
timeout 150 $D/zz_lbvh conference $D/stanford-bunny.obj chairs:64 chairs:1024 > $O/l/build.txt 2>&1; echo "rc=$?" >> $O/l/build.txt
for sc in conference $D/stanford-bunny.obj chairs:1024; do
  for w in host kernels; do
    KDRAY_PROFILE=1 timeout 60 $D/zz_lbvh trace $w $sc > $O/l/trace-$w-$(basename $sc .obj).txt 2>&1
  done
done
KDRAY_SHARED_SCENES=$D timeout 200 $D/kdray bench build --device gpu --scene conference --scene $D/stanford-bunny.obj --scene chairs:64 --scene chairs:1024 --out $O/bench > $O/l/bench.txt 2>&1; echo "bench rc=$?" >> $O/l/bench.txt
{ cat $O/l/gpu.txt $O/l/build.txt; for f in $O/l/trace-*.txt; do echo "== $f"; grep -E "^trace|closest_bvh|lbvh_|^entry" $f; done; tail -2 $O/l/bench.txt; cat $O/bench/build-gpu.md; } > $O/sum.txt
# (r27 separately)

