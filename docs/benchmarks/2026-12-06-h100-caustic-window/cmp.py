# cmp.py A B...: means, relative RMSE of each against the first
import sys, numpy as np
sys.path.insert(0, __file__.rsplit('/',1)[0]); from pfm import read
a=read(sys.argv[1])
for b in sys.argv[2:]:
    x=read(b)
    print(f"{b.split('/')[-1]} vs {sys.argv[1].split('/')[-1]}: means {a.mean():.7g} {x.mean():.7g}, rel RMSE {np.sqrt(((a-x)**2).mean())/a.mean():.3e}")
