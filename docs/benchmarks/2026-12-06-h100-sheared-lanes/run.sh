#!/bin/bash
# r26: B = 042806a (main before this session), N = the branch-free ShearedRay::new (every traversal kernel's SPIR-V changed) + the native packet changes (CPU only).
# Parts: the driver's pipeline statistics of the gather variants of r25 (D H G P F W); GPU horn (kd + BVH) and photon speed for B and N, alternating, two rounds.
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w26; mkdir -p $W
for v in B N; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
gunzip -c $H/bunny.obj.gz > $W/stanford-bunny.obj
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
t0=$(date +%s)
h() { # variant tag
  rm -rf $W/h; timeout 150 $W/$1 bench horn --device gpu --scene conference --scene $W/stanford-bunny.obj --size 1024 --reps 5 --method stack --method shortstack:3 --method bvh --method bvh+packets --out $W/h > $W/ho.txt 2>&1 || tail -3 $W/ho.txt >> $S
  cp $W/h/horn-*.md $OUT/horn-$2.md 2>/dev/null
  echo "== horn $2 ($(( $(date +%s) - t0 )) s)" >> $S
  sed -n '/Table 1 layout/,/All rows/p' $W/h/horn-*.md | grep "^| [a-z]" >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $W/$1 bench photons --size 1024 --scene cornell-glass --scene cornell --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/photons-$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
for r in 1 2; do
  for v in B N; do h $v $v$r; done
  for v in B N; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 300 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== whole renders (seed 1: 429 and 1 071 passes)" >> $S
for v in B N B N; do
  for sp in "cornell 429" "cornell-glass 1071"; do set -- $sp
    timeout 60 $W/$v render --scene $1 --passes $2 --seed 1 --size 512 --device gpu -o $W/n-$v-$1.png > $W/o.txt 2>&1
    echo "$v $1 $2 passes: $(grep -E '^rendered|rror' $W/o.txt | tr '\n' ' ')" >> $S
  done
  [ $(( $(date +%s) - t0 )) -gt 480 ] && break
done
echo "== pipeline statistics (gather variants of r25)" >> $S
for v in D G P F W; do
  gunzip -c $H/$v.spv.gz > $W/$v.spv
  echo "== $v" >> $S
  timeout 30 $H/pipeline_stats $W/$v.spv $W/ps-$v photon::gather_grid >> $S 2>&1
  [ $(( $(date +%s) - t0 )) -gt 560 ] && break
done
echo "total $(( $(date +%s) - t0 )) s" >> $S
