#!/usr/bin/python3
"""Eight levels from three etch depths d1, d2, d3 (levels sum_i b_i d_i, the 3 masks of multi-step
lithography) that keep the mirror order dark over 0.40-0.70 um (normal light): random depths with
d1 + d2 + d3 <= 2 um, the shares of least worst mirror power by an LP (|.| approximated by 16
projections), the worst power then exact over 301 wavelengths. Prints the equal-step cases and the
15 best depth sets (worst power, depths, shares in the order of the levels sum_i b_i d_i with
(b1, b2, b3) in itertools.product order: 0, d3, d2, d2+d3, d1, d1+d3, d1+d2, d1+d2+d3)."""
import numpy as np, itertools
from scipy.optimize import linprog, minimize
lam=np.linspace(0.40,0.70,301); k=4*np.pi/lam
def worst_min_shares(h):
    # minimise t s.t. |sum s e^{-ikh}|^2 <= t approximated by max over polygon directions of Re/Im projection (LP), then report exact
    E=np.exp(-1j*np.outer(k,h))  # L x K
    # LP: min t, s>=0, sum s=1, for each lam and 16 directions d: Re(e^{-i d} E s) <= t
    K=len(h); D=np.linspace(0,2*np.pi,16,endpoint=False)
    A=[];b=[]
    for d in D:
        R=np.real(np.exp(-1j*d)*E)
        A.append(np.hstack([R,-np.ones((len(lam),1))]))
    A=np.vstack(A); b=np.zeros(A.shape[0])
    c=np.zeros(K+1);c[-1]=1
    res=linprog(c,A_ub=A,b_ub=b,A_eq=np.hstack([np.ones((1,K)),[[0]]]),b_eq=[1],bounds=[(0,None)]*K+[(None,None)])
    s=res.x[:K]; p=np.abs(E@s)**2
    return p.max(), s
for step in [0.153,0.165,0.2,0.286]:
    h=step*np.arange(8); print('equal',step,worst_min_shares(h)[0])
rng=np.random.default_rng(1)
best=[]
for trial in range(3000):
    d=np.sort(rng.uniform(0.05,1.4,3))
    if d.sum()>2.0: continue
    h=np.array([sum(b*dd for b,dd in zip(bits,d)) for bits in itertools.product([0,1],repeat=3)])
    w,s=worst_min_shares(h)
    best.append((w,tuple(np.round(d,4)),tuple(np.round(s,3))))
best.sort()
for b in best[:15]: print(b)
