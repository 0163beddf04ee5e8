"""Independent numpy re-implementation of the charting round trip (thesis eqs. 2.47-2.55, with the
departures listed in docs/reduce.md), used to cross-check crates/reduce/src/charting.rs on the
corpus: reads the PCA coordinates from a model file written by `reduce` and prints the
training round-trip error sqrt(sum|y^-y|^2 / sum|y-mean|^2) for d = 1..20.

usage: python3 tools/reduce/charting_numpy.py MODEL.bin [KC=45]
"""
import struct
import sys

import numpy as np
from scipy.special import logsumexp


def load_coords(path):
    with open(path, "rb") as f:
        head = f.read(12)
        if head[:8] != b"BRDFMODL":
            raise SystemExit("not a model file")
        (version,) = struct.unpack("<I", head[8:12])
        # log floor (f64), then in version 2 the mapping (u8 tag, f64 epsilon)
        f.read(8 if version == 1 else 17)
        dim, n, k = struct.unpack("<3Q", f.read(24))
        for _ in range(n):
            (length,) = struct.unpack("<I", f.read(4))
            f.read(length)
        f.read(8 * n)  # eigenvalues
        f.seek(4 * dim + 4 * dim * k, 1)  # mean and basis
        return np.frombuffer(f.read(8 * n * k), "<f8").reshape(n, k)


def sigma_default(P):
    D=np.sqrt(((P[:,None]-P[None])**2).sum(-1)); np.fill_diagonal(D,np.inf); return 0.5*D.min(1).mean()
def fit(P, sigma=None, floor=1e-6, broaden=1.0, mode='prev'):
    n,k=P.shape; s=sigma or sigma_default(P)
    D2=((P[:,None]-P[None])**2).sum(-1); W=np.exp(-D2/(2*s*s))
    a=W.sum(1); b=a-1
    if mode=='prev':
        S=np.diag(a+b)-(W-np.eye(n))
        R=np.stack([2*np.einsum('j,jp,jq->pq',W[i],P-P[i],P-P[i]) for i in range(n)])
        C=np.linalg.solve(S,R.reshape(n,-1)).reshape(n,k,k)
    elif mode=='local':  # plain weighted local scatter, no coupling
        C=np.stack([np.einsum('j,jp,jq->pq',W[i],P-P[i],P-P[i])/a[i] for i in range(n)])
    C=(C+C.transpose(0,2,1))/2
    vals,vecs=np.linalg.eigh(C); vals=vals[:,::-1]; vecs=vecs[:,:,::-1]
    vals=np.maximum(vals,vals[:,:1]*floor)+broaden*s*s
    return dict(P=P,s=s,vals=vals,vecs=vecs,C=C)
def post_y(ch,Y):
    P=ch['P'];diff=Y[:,None,:]-P[None]  # m,n,k
    proj=np.einsum('mnk,nkc->mnc',diff,ch['vecs'])
    L=-0.5*((proj**2/ch['vals'][None]).sum(-1)+np.log(ch['vals']).sum(-1)[None])
    return np.exp(L-logsumexp(L,1,keepdims=True))
def connect(ch,d):
    P=ch['P'];n=len(P)
    post=post_y(ch,P)  # i,k
    U=np.einsum('ikc->kic',np.einsum('ikq,kqc->ikc',P[:,None,:]-P[None],ch['vecs'][:,:,:d]))  # k,i,d
    Z=np.concatenate([U,np.ones((n,n,1))],2) # k,i,d+1
    Dk=np.einsum('ik,kia,kib->kab',post,Z,Z)
    Dk+=1e-9*np.trace(Dk,axis1=1,axis2=2)[:,None,None]/(d+1)*np.eye(d+1)
    Dinv=np.linalg.inv(Dk)
    Q=np.einsum('ik,kia->kai',post,Z)   # k,a,i  -> Q rows (k,a), col i
    M=np.einsum('kai,kab,kbj->ij',Q,Dinv,Q)
    mu,w=np.linalg.eigh(M); mu=mu[::-1]; w=w[:,::-1]
    ones=np.ones(n)/np.sqrt(n)
    triv=np.argmax(np.abs(w[:,:d+2].T@ones))
    ch_=[c for c in range(n) if c!=triv][:d]
    G=np.einsum('kab,kbi,ic->kca',Dinv,Q,w[:,ch_])/np.sqrt(mu[ch_])[None,:,None]  # k, d, d+1
    return dict(ch=ch,d=d,G=G,mu=mu[ch_],post=post,Z=Z)
def forward(c,Y):
    ch=c['ch'];d=c['d'];post=post_y(ch,Y)
    U=np.einsum('mkq,kqc->mkc',Y[:,None,:]-ch['P'][None],ch['vecs'][:,:,:d])
    Z=np.concatenate([U,np.ones(U.shape[:2]+(1,))],2)
    return np.einsum('mk,kca,mka->mc',post,c['G'],Z)
def backward(c,X,return_post=False):
    ch=c['ch'];d=c['d'];G=c['G'];A=G[:,:,:d];cc=G[:,:,d]
    lam=ch['vals'][:,:d]
    S=np.einsum('kab,kb,kcb->kac',A,lam,A)
    S+=1e-9*np.trace(S,axis1=1,axis2=2)[:,None,None]/d*np.eye(d)
    Si=np.linalg.inv(S); ld=np.linalg.slogdet(S)[1]
    diff=X[:,None,:]-cc[None]
    L=-0.5*(np.einsum('mka,kab,mkb->mk',diff,Si,diff)+ld[None])
    post=np.exp(L-logsumexp(L,1,keepdims=True))
    Ap=np.linalg.pinv(A,rcond=1e-12)
    loc=np.einsum('kab,mkb->mka',Ap,diff)
    Yk=ch['P'][None]+np.einsum('kqa,mka->mkq',ch['vecs'][:,:,:d],loc)
    Y=np.einsum('mk,mkq->mq',post,Yk)
    return (Y,post) if return_post else Y
def recon_err(c):
    P=c['ch']['P'];Yh=backward(c,forward(c,P))
    return np.sqrt(((Yh-P)**2).sum()/((P-P.mean(0))**2).sum()), Yh

if __name__ == "__main__":
    kc = int(sys.argv[2]) if len(sys.argv) > 2 else 45
    pts = load_coords(sys.argv[1])[:, :kc]
    charts = fit(pts)
    print(f"sigma = {charts['s']:.4f}")
    for d in range(1, 21):
        print(d, round(recon_err(connect(charts, d))[0], 5))
