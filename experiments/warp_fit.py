#!/usr/bin/env python3
"""How much of a recovery's height error is a smooth warp of the truth (issue 14, positions).

Usage: /usr/bin/python3 experiments/warp_fit.py RUN_DIR   (estimate_height.npy, truth_height.npy)
       /usr/bin/python3 experiments/warp_fit.py PREFIX    (recover_study save=PREFIX: PREFIX_estimate.npy,
                                                          PREFIX_truth.npy)
Fits a displacement field on k×k nodes (bilinear between them; k = 1 is a translation) that maps
the truth onto the estimate (bicubic), by least squares on the inner texels (3 texels of margin),
and prints height_rel_rmse (% of the truth's range, mean removed) before and after each fit with
the displacement's rms in texels. Position errors whose low-frequency part the data cannot pin
down show up as a warp that such a fit removes.
"""
import sys
import numpy as np
from scipy.ndimage import map_coordinates
from scipy.optimize import least_squares
d = sys.argv[1]
import os
if os.path.isdir(d):
    e = np.load(d + '/estimate_height.npy'); t = np.load(d + '/truth_height.npy')
else:
    e = np.load(d + '_estimate.npy'); t = np.load(d + '_truth.npy')
n = e.shape[0]; rng = t.max() - t.min()
def rel(a, b):
    r = (a - b); r = r - r.mean(); return np.sqrt((r**2).mean()) / rng * 100
m = 3  # margin texels excluded (interpolation at borders)
inner = (slice(m, n - m), slice(m, n - m))
print('plain', rel(e, t), 'inner', rel(e[inner], t[inner]))
yy, xx = np.mgrid[0:n, 0:n].astype(float)
for k in (1, 2, 3, 4, 6):
    def field(p):
        gx = p[:k*k].reshape(k, k); gy = p[k*k:].reshape(k, k)
        if k == 1: return np.full((n, n), gx[0, 0]), np.full((n, n), gy[0, 0])
        c = np.linspace(0, k - 1, n)
        cy, cx = np.meshgrid(c, c, indexing='ij')
        return (map_coordinates(gx, [cy, cx], order=1), map_coordinates(gy, [cy, cx], order=1))
    def res(p):
        dx, dy = field(p)
        w = map_coordinates(t, [yy + dy, xx + dx], order=3, mode='nearest')
        r = (e - w)[inner]; return (r - r.mean()).ravel()
    s = least_squares(res, np.zeros(2 * k * k))
    dx, dy = field(s.x)
    print(f'warp {k}x{k} nodes: rel {np.sqrt((s.fun**2).mean())/rng*100:.3f} %, |d| rms {np.sqrt((dx**2+dy**2).mean()):.3f} texel')
