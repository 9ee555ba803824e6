#!/bin/bash
# r19: error against time on the H100 (F = the committed candidate): path-traced references in parts, then timed renders of two seeds
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w19; mkdir -p $W; gunzip -c $H/D.gz > $W/F; chmod +x $W/F
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
t0=$(date +%s)
ref() { # scene spp seconds
  local k=0 st=$(date +%s)
  while [ $(( $(date +%s) - st )) -lt $3 ]; do k=$((k+1))
    timeout 200 $W/F render --scene $1 --integrator path --spp $2 --seed $((1000+k)) --size 512 --device gpu -o $W/ref-$1-$k.png > $W/o.txt 2>&1
    grep "^rendered" $W/o.txt | sed "s/^/ref $1 part $k ($2 spp): /" >> $S
  done
}
timed() { # scene limit
  for s in 1 2; do
    timeout 60 $W/F render --scene $1 --time-limit $2 --passes 100000 --seed $s --size 512 --device gpu -o $W/r-$1-$s.png > $W/o.txt 2>&1
    grep -E "photon mapping|^rendered" $W/o.txt | tr '\n' ' ' | sed "s/^/$1 seed $s, limit $2: /" >> $S; echo >> $S
  done
}
ref cornell 4096 70
ref cornell-glass 4096 150
timed cornell 0.93; timed cornell-glass 4.85
for sc in cornell cornell-glass; do python3 $H/err.py $sc $W/ref-$sc-[0-9]*.pfm -- $W/r-$sc-1.pfm $W/r-$sc-2.pfm >> $S 2>&1; done
echo "total $(( $(date +%s) - t0 )) s" >> $S
