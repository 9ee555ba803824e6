#!/bin/bash
# r27: the same rays through kdray (main 2129b5c's kernels: N = 2eda5c8's binary, the same SPIR-V), Mitsuba 3.9.1 cuda_ad_rgb (OptiX) and tinybvh's CWBVH; joined by scripts/peers_table.py
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w27; mkdir -p $W/scenes
gunzip -c $H/N.gz > $W/N; chmod +x $W/N
gunzip -c $H/bunny.obj.gz > $W/scenes/stanford-bunny.obj
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
export KDRAY_SHARED_SCENES=$W/scenes
timeout 400 bash $H/peers/same_rays_gpu.sh $W/N $H/mi $OUT/h --method bvh --method stack --method shortstack:3 --size 1024 > $OUT/peers.log 2>&1
cat $OUT/peers.log >> $S
python3 scripts/peers_table.py $OUT/h/horn-gpu.csv $OUT/peers.log $OUT/peers >> $S 2>&1
cat $OUT/peers.md >> $S 2>/dev/null
