#!/bin/bash
# r24: D = main (8afb62b); G = df9ca57 (multiplicative block hash, unchecked offset loads); W = G with the grid query's run list in workgroup memory (a column per invocation, GroupRuns) instead of private memory
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w24; mkdir -p $W
for v in D G W; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
echo "(D = main 8afb62b; G = df9ca57; W = G + run lists in workgroup memory. Profiles: render --scene S --integrator photon --size 512 --passes 64, KDRAY_PROFILE=1)" >> $S
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $W/$1 render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|gather_grid|error|Error" $W/o.txt >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $W/$1 bench photons --size 1024 --scene cornell-glass --scene cornell --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
t0=$(date +%s)
for v in D G W; do p $v warm$v cornell-glass; done
for r in 1 2; do
  for v in D G W; do p $v $v$r cornell-glass; done
  for v in D G W; do p $v $v$r cornell; done
  echo "round $r profiles done at $(( $(date +%s) - t0 )) s" >> $S
  for v in D G W; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 260 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
python3 $H/cmp.py $W/D1-cornell-glass.pfm $W/G1-cornell-glass.pfm $W/W1-cornell-glass.pfm >> $S 2>&1
python3 $H/cmp.py $W/D1-cornell.pfm $W/G1-cornell.pfm $W/W1-cornell.pfm >> $S 2>&1
echo "== whole commands at main's measured pass counts (seed 1: 429 and 1 071 passes)" >> $S
for v in D G W; do
  for sp in "cornell 429" "cornell-glass 1071"; do set -- $sp
    a=$(date +%s.%N); timeout 60 $W/$v render --scene $1 --passes $2 --seed 1 --size 512 --device gpu -o $W/n-$v-$1.png > $W/o.txt 2>&1; b=$(date +%s.%N)
    echo "$v $1 $2 passes: command $(python3 -c "print(f'{$b-$a:.3f}')") s; $(grep -E '^rendered|rror' $W/o.txt | tr '\n' ' ')" >> $S
  done
  [ $(( $(date +%s) - t0 )) -gt 520 ] && break
done
echo "total $(( $(date +%s) - t0 )) s" >> $S
