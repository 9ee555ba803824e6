#!/bin/bash
# r40: repeated kernel BVH builds in one process, fresh buffers against kept ones (LbvhBuilder), with the SM clock sampled.
O=$OUT; D=carry/r40
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.applications.graphics --format=csv > $O/gpu.txt 2>&1
nvidia-smi --query-gpu=timestamp,clocks.sm,clocks.mem,power.draw,pstate,utilization.gpu,temperature.gpu --format=csv,noheader -lms 20 > $O/smi.txt 2>&1 &
SMI=$!
run() { echo "== $*" >> $O/builds.txt; env $1 timeout 120 $D/zz_repeat $2 $3 $4 $5 >> $O/builds.txt 2>&1; }
run X=0 fresh 3 chairs:1024 30
run X=0 kept 3 chairs:1024 30
run X=0 fresh 0 chairs:1024 30
run X=0 kept 0 chairs:1024 30
run GAP_MS=300 kept 3 chairs:1024 20
run GAP_MS=300 fresh 3 chairs:1024 20
run X=0 kept 3 conference 30
kill $SMI
cat $O/gpu.txt
python3 $D/summ.py $O/builds.txt $O/smi.txt
