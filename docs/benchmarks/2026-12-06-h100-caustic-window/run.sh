#!/bin/bash
# r20: D = main (530dc96); C = the caustic map's own grid window (default 2: 2x2 rows of cubes of 2r_c), c7104a7; C7 = C with --caustic-window 7 (main's window for both maps), C3 likewise 3; M = C plus both maps' runs listed first and walked in one photon loop
# (sum.py, cmp.py and pfm.py: those of ../2026-12-06-h100-one-index/, copied beside it on the device)
H=$(cd "$(dirname "$0")" && pwd)
W=/tmp/w; mkdir -p $W
for v in D C M; do gunzip -c $H/$v.gz > $W/$v; chmod +x $W/$v; done
S=$OUT/sum.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $S
echo "(D = 530dc96; C = caustic map's own window, default 2; C7 = C --caustic-window 7; C3 = C --caustic-window 3; M = C + both maps in one loop. Profiles: render --scene S --integrator photon --size 512 --passes 64, KDRAY_PROFILE=1)" >> $S
bin() { case $1 in C7|C3) echo "$W/C";; *) echo "$W/$1";; esac; }
arg() { case $1 in C7) echo "--caustic-window 7";; C3) echo "--caustic-window 3";; *) echo "";; esac; }
p() { # variant tag scene
  echo "== $2 $3" >> $S
  KDRAY_PROFILE=1 timeout 120 $(bin $1) render --scene $3 --integrator photon --size 512 --passes 64 $(arg $1) --device gpu -o $W/$2-$3.png > $W/o.txt 2>&1
  grep -E "^rendered|gather_grid|place_photons|photon_keys_grid|segment_offsets|error|Error" $W/o.txt >> $S
}
b() { # variant tag
  rm -rf $W/b; KDRAY_PHOTONS_SPEED_ONLY=1 timeout 200 $(bin $1) bench photons --size 1024 --out $W/b > $W/bo.txt 2>&1 || tail -3 $W/bo.txt >> $S
  f=$(ls $W/b/photons-*.md | grep -v error | head -1); cp $f $OUT/$2.md 2>/dev/null
  python3 $H/sum.py $2 $f >> $W/bsum.txt
}
t0=$(date +%s)
for v in D C M; do p $v warm$v cornell-glass; done
for r in 1 2; do
  for v in D C M C7 C3; do p $v $v$r cornell-glass; done
  for v in D C M; do p $v $v$r cornell; done
  echo "round $r profiles done at $(( $(date +%s) - t0 )) s" >> $S
  for v in D C M; do b $v $v$r; done
  echo "round $r done at $(( $(date +%s) - t0 )) s" >> $S
  [ $(( $(date +%s) - t0 )) -gt 240 ] && break
done
python3 $H/sum.py HDR $(ls $W/b/photons-*.md | grep -v error | head -1) >> $S 2>/dev/null
cat $W/bsum.txt >> $S
echo "== images" >> $S
python3 $H/cmp.py $W/D1-cornell-glass.pfm $W/C71-cornell-glass.pfm $W/C1-cornell-glass.pfm $W/M1-cornell-glass.pfm $W/D2-cornell-glass.pfm $W/C2-cornell-glass.pfm >> $S 2>&1
python3 $H/cmp.py $W/D1-cornell.pfm $W/C1-cornell.pfm $W/M1-cornell.pfm $W/D2-cornell.pfm >> $S 2>&1
echo "== whole commands at main's measured pass counts (seed 1; 2026-12-06 error run: 429 and 1 071 passes)" >> $S
for r in 1; do for v in D C M; do
  for sp in "cornell 429" "cornell-glass 1071"; do set -- $sp
    a=$(date +%s.%N); timeout 60 $(bin $v) render --scene $1 --passes $2 --seed 1 --size 512 --device gpu -o $W/n-$v$r-$1.png > $W/o.txt 2>&1; b=$(date +%s.%N)
    echo "$v$r $1 $2 passes: command $(python3 -c "print(f'{$b-$a:.3f}')") s; $(grep -E '^rendered|rror' $W/o.txt | tr '\n' ' ')" >> $S
  done
done; done
for sc in cornell cornell-glass; do python3 $H/cmp.py $W/n-D1-$sc.pfm $W/n-C1-$sc.pfm $W/n-M1-$sc.pfm >> $S 2>&1; done
echo "total $(( $(date +%s) - t0 )) s" >> $S
