#!/bin/bash
# r41: kept against fresh buffers at working clocks (each build after WARM_MS of tracing), SM clock sampled; then bench build.
O=$OUT; D=carry/r41; mkdir -p $O/bench
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv; nvidia-smi --query-gpu=timestamp,clocks.sm,clocks.mem,power.draw,pstate,utilization.gpu,temperature.gpu,clocks_event_reasons.active --format=csv,noheader -lms 20 > $O/smi.txt 2>&1 &
SMI=$!
run() { echo "== $*" >> $O/builds.txt; env $1 timeout 120 $D/zz_repeat $2 $3 $4 $5 >> $O/builds.txt 2>&1; }
run X=0 fresh 3 chairs:1024 20
run X=0 kept 3 chairs:1024 20
run WARM_MS=1000 kept 3 chairs:1024 12
run WARM_MS=1000 fresh 3 chairs:1024 10
run WARM_MS=300 kept 3 chairs:1024 12
run WARM_MS=1000 kept 0 chairs:1024 10
run WARM_MS=1000 fresh 0 chairs:1024 10
run WARM_MS=1000 kept 3 conference 10
run WARM_MS=1000 kept 3 $D/stanford-bunny.obj 10
KDRAY_SHARED_SCENES=$D timeout 300 $D/kdray bench build --device gpu --scene conference --scene $D/stanford-bunny.obj --scene chairs:64 --scene chairs:1024 --out $O/bench > $O/bench.txt 2>&1; echo "bench rc=$?" >> $O/bench.txt
kill $SMI
python3 $D/summ.py $O/builds.txt $O/smi.txt
tail -3 $O/bench.txt; tail -8 $O/bench/build-gpu.md
awk -F, '{print $8}' $O/smi.txt | sort | uniq -c
