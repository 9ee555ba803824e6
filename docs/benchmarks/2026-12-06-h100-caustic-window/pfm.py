import numpy as np, sys
def read(p):
    with open(p,'rb') as f:
        h=f.readline().strip(); w,hh=map(int,f.readline().split()); s=float(f.readline())
        d=np.fromfile(f, '<f4' if s<0 else '>f4')
    c=3 if h==b'PF' else 1
    return d.reshape(hh,w,c)[::-1].astype(np.float64)
