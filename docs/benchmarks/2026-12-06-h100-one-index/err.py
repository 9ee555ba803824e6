# err.py NAME REFPARTS... -- RENDER1 RENDER2: the error measure (RMSE of the displayed
# image, clamped at 1, over the reference's mean), the reference's own error from its parts'
# spread subtracted in quadrature; noise from the two renders of different seeds; bias the rest.
import sys, numpy as np
sys.path.insert(0, __file__.rsplit('/',1)[0]); from pfm import read
a=sys.argv[2:]; k=a.index('--'); parts=[np.clip(read(p),0,1) for p in a[:k]]; r1,r2=[np.clip(read(p),0,1) for p in a[k+1:]]
ref=np.mean(parts,axis=0); m=ref.mean(); K=len(parts)
own=np.sqrt((np.var(parts,axis=0,ddof=1)/K).mean())/m if K>1 else 0.0
noise=np.sqrt(((r1-r2)**2).mean()/2)/m
for i,x in enumerate([r1,r2]):
    e=np.sqrt(((x-ref)**2).mean())/m; c=np.sqrt(max(e*e-own*own,0)); b=np.sqrt(max(c*c-noise*noise,0))
    print(f"{sys.argv[1]} render {i+1}: reference {K} parts, own error {own*100:.3f} %; error {e*100:.3f} %, corrected {c*100:.3f} %, noise per render {noise*100:.3f} %, bias {b*100:.3f} %")
