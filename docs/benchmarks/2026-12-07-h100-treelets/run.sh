#!/bin/bash
# r38: the final treelet code (five leaves, packed table, exact collapse areas): builds in fresh processes, traces, repeated builds in one process, bench build.
O=$OUT; D=carry/r38; mkdir -p $O/bench
nvidia-smi --query-gpu=name,driver_version --format=csv > $O/gpu.txt 2>&1
for rep in 1 2 3; do for sc in chairs:1024 conference $D/stanford-bunny.obj chairs:64; do for r in 0 3; do
  timeout 60 $D/zz_tprobe once $r $sc >> $O/once.txt 2>&1
done; done; done
for sc in chairs:1024 conference $D/stanford-bunny.obj; do for w in host 0 3; do
  KDRAY_PROFILE=1 timeout 60 $D/zz_tprobe trace $w $sc > $O/trace-$w-$(basename $sc .obj | tr : -).txt 2>&1
done; done
for r in 0 3; do timeout 120 $D/zz_tprobe repeat $r chairs:1024 >> $O/repeat.txt 2>&1; done
KDRAY_SHARED_SCENES=$D timeout 200 $D/kdray bench build --device gpu --scene conference --scene $D/stanford-bunny.obj --scene chairs:64 --scene chairs:1024 --out $O/bench > $O/bench.txt 2>&1; echo "bench rc=$?" >> $O/bench.txt
cat $O/gpu.txt $O/once.txt $O/repeat.txt; for f in $O/trace-*.txt; do echo "== $f"; grep -E "^trace|closest_bvh|lbvh_treelet|submissions" $f; done; tail -7 $O/bench/build-gpu.md
