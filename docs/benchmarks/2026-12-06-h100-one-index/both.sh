#!/bin/bash
# r18 (one index against main), then r19 (error against time) in what is left of the call
H=$(cd "$(dirname "$0")" && pwd)
t0=$(date +%s)
bash $H/r18/run.sh
left=$(( 560 - ($(date +%s) - t0) ))
echo "r18 took $(( $(date +%s) - t0 )) s; $left s left" >> $OUT/sum.txt
if [ $left -gt 200 ]; then
  CSEC=$(( (left - 90) * 2 / 5 )) GSEC=$(( (left - 90) * 3 / 5 )) timeout $left bash $H/r19/run.sh
fi
