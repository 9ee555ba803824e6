#!/bin/bash
# r43: the bvh tests but the render one (it runs the build tree's binary) with the GPU required, then bench build (frame: read back / in place (update)); after the review fixes (finish sends queued writes).
O=$OUT; D=carry/r43; mkdir -p $O/bench
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv
nvidia-smi --query-gpu=timestamp,clocks.sm,power.draw,utilization.gpu --format=csv,noheader -lms 50 > $O/smi.txt 2>&1 &
SMI=$!
KDRAY_REQUIRE_GPU=1 timeout 300 $D/bvhtest --test-threads 1 --skip a_render_with > $O/tests.txt 2>&1; echo "tests rc=$?" >> $O/tests.txt
grep -E "^test |test result|rc=|panicked" $O/tests.txt
KDRAY_SHARED_SCENES=$D timeout 280 $D/kdray bench build --device gpu --scene conference --scene $D/stanford-bunny.obj --scene chairs:64 --scene chairs:1024 --out $O/bench > $O/bench.txt 2>&1; echo "bench rc=$?" >> $O/bench.txt
kill $SMI
tail -3 $O/bench.txt; cut -d"|" -f2,3,18- $O/bench/build-gpu.md | tail -6
awk -F', ' '{print $2}' $O/smi.txt | sort | uniq -c | sort -rn | head -5
