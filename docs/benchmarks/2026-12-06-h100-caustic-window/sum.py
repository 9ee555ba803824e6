# sum.py TAG photons-*.md: one line of the chosen columns per scene
import sys
tag=sys.argv[1]; rows=[l for l in open(sys.argv[2]) if l.startswith('|')]
hdr=[c.strip() for c in rows[0].strip().strip('|').split('|')]
want=["M bounces/s","BVH M bounces/s","index grid ms","grid keys+ranks / offsets / place ms","gather grid ms","gather grid: found / tested per point","gather grid at ~50 found ms (found / tested)","gather grid, 8×8 tiles: default / ~50 found ms (subgroup balance)"]
idx=[hdr.index(w) for w in want if w in hdr]
if tag=="HDR": print("| " + " | ".join(["run","scene"]+[hdr[i] for i in idx])+" |"); sys.exit()
for r in rows[2:]:
    c=[x.strip() for x in r.strip().strip('|').split('|')]
    print("| " + " | ".join([tag,c[0]]+[c[i] for i in idx])+" |")
