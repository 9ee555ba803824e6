#!/bin/bash
# r21: D = main (530dc96); N = main's kernels with bench photons' caustic columns (host only); A = ablation: the gather sums the global map alone (no caustic gather); B = ablation: the caustic map alone (images differ)
# (sum.py, cmp.py and pfm.py: those of ../2026-12-06-h100-one-index/, copied beside it on the device)
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w21; mkdir -p $W
for v in D N A B; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
echo "(D = 530dc96; N = D's kernels, bench photons with the caustic map's found/tested and balance; A = no caustic gather; B = the caustic gather alone. Profiles: render --scene S --integrator photon --size 512 --passes 64, KDRAY_PROFILE=1)" >> $S
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $W/$1 render --scene $3 --integrator photon --size 512 --passes 64 --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|gather_grid|error|Error" $W/o.txt >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $W/$1 bench photons --size 1024 --scene cornell-glass --scene cornell --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); case $2 in D*|N*) cp $f $OUT/$2.md;; esac
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
t0=$(date +%s)
for v in D A; do p $v warm$v cornell-glass; done
for r in 1 2; do
  for v in D A B N; do p $v $v$r cornell-glass; done
  p D D$r cornell
  for v in D A B N; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 200 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
python3 $H/cmp.py $W/D1-cornell-glass.pfm $W/N1-cornell-glass.pfm $W/A1-cornell-glass.pfm >> $S 2>&1
echo "total $(( $(date +%s) - t0 )) s" >> $S
