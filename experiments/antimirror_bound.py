#!/usr/bin/python3
"""Upper bound on the anti-mirror's region fraction at one wavelength for any relief of square
texels on K given levels, given a uniformity std/mean <= u over the region's 16 equal-area bins.

Why it bounds: the orders that read one FFT bin b != 0 of the tile have amplitudes
sqrt(env_o) * v_o . F_b, v_o[l] = exp(-i k h_l q_o), F_b the K level masks' spectra at b, which sum to
zero over the levels (the masks sum to one per texel). Write y = D^(1/2) V^H F_b for the bin's
order amplitudes; y ranges over a subspace S_b. Every fraction is a ratio of sums over bins of
y^H G y (G diagonal: 1 on the orders of a group) to y^H y. The bin 0 (the mirror order) adds to the
total only. For a multiplier vector mu in the dual cone of the uniformity cone
C = {x in R^16: |x - mean 1| <= u * |mean 1| * ...} (region bins x), region <= region + mu.x on C, and
region + mu.x = sum_b y_b^H W y_b with W = diag(1 + mu_q on region bin q's orders), so
region / total <= max_b lambda_max(P_b W P_b) for ANY such mu (weak duality). The script
minimises that over mu; whatever mu it stops at, the number is a valid bound.

The cone: x in R^16, e = 1/4 (unit vector along 1), x_par = x.e, x_perp = x - x_par e;
std/mean <= u  <=>  |x_perp| <= u x_par. Dual cone: |mu_perp| <= mu_par / u. Taking mu_par at its
least, u |mu_perp|.

Usage: antimirror_bound.py --size 128 --texel 0.5 --levels-um 0,0.132,... --lambda 0.55 --u 0.25
       antimirror_bound.py ... --check heights.exr-derived .npy (heights in um) to compare
"""
import argparse
import json
import sys

import numpy as np
from scipy.optimize import minimize


def orders(size, texel, lam, cone=0.05, r1=0.1, r2=0.5):
    """Propagating orders at normal light, as make_order_set and AntiMirror::assign build them."""
    L = size * texel
    M = int(np.floor(L / lam))
    m, n = np.meshgrid(np.arange(-M, M + 1), np.arange(-M, M + 1), indexing="ij")
    m, n = m.ravel(), n.ravel()
    dx, dy = lam * m / L, lam * n / L
    rr = dx * dx + dy * dy
    keep = rr < 1.0
    keep &= ~((m % size == 0) & (m != 0)) & ~((n % size == 0) & (n != 0))
    m, n, dx, dy, rr = m[keep], n[keep], dx[keep], dy[keep], rr[keep]
    cos_o = np.sqrt(1.0 - rr)
    q = 1.0 + cos_o
    env = np.sinc(m / size) ** 2 * np.sinc(n / size) ** 2 * cos_o
    group = np.full(m.shape, -1)
    group[rr <= cone * cone] = 0
    a, b = r1 * r1, r2 * r2
    inreg = (rr >= a) & (rr <= b)
    ring = np.minimum(3, (4.0 * (rr - a) / (b - a)).astype(int))
    ang = np.arctan2(dy, dx) + np.pi
    quad = np.minimum(3, (ang / (0.5 * np.pi)).astype(int))
    group[inreg] = 1 + (ring * 4 + quad)[inreg]
    bins = (m % size) * size + (n % size)
    return dict(m=m, n=n, q=q, env=env, group=group, bin=bins, k=2 * np.pi / lam)


def bin_subspaces(o, levels_um):
    """Per bin != 0: an orthonormal basis Q (n_max x r) of the order-amplitude subspace S_b, the
    group of each padded row (-2: padding)."""
    K = len(levels_um)
    h = np.asarray(levels_um)
    sel = o["bin"] != 0
    bins, q, env, grp = o["bin"][sel], o["q"][sel], o["env"][sel], o["group"][sel]
    order = np.argsort(bins, kind="stable")
    bins, q, env, grp = bins[order], q[order], env[order], grp[order]
    ub, start, count = np.unique(bins, return_index=True, return_counts=True)
    nmax = count.max()
    nb = len(ub)
    slot = np.arange(len(bins)) - np.repeat(start, count)
    row = np.repeat(np.arange(nb), count)
    # basis of {F: sum_l F_l = 0}: Helmert-like via QR of the centring matrix
    C = np.eye(K) - 1.0 / K
    U = np.linalg.qr(C)[0][:, : K - 1]
    V = np.exp(-1j * o["k"] * q[:, None] * h[None, :])  # n x K, amplitude = sqrt(env) V F
    Bo = np.sqrt(env)[:, None] * (V @ U)  # n x (K-1)
    B = np.zeros((nb, nmax, K - 1), complex)
    B[row, slot] = Bo
    G = np.full((nb, nmax), -2)
    G[row, slot] = grp
    # orthonormal basis of the column space (rank cut)
    Uu, s, _ = np.linalg.svd(B, full_matrices=False)
    tol = s[:, :1] * 1e-10
    Uu = Uu * (s > tol)[:, None, :]
    return Uu, G


def bound_value(Q, G, mu_perp, u):
    """max over bins of lambda_max(Q^H W Q), W = diag over orders."""
    mu_par = u * np.linalg.norm(mu_perp)
    w_region = 1.0 + mu_par / 4.0  # mu_par e . x = mu_par/4 * sum x
    wq = np.zeros(18)
    wq[1:17] = w_region + mu_perp
    W = np.where(G >= 1, wq[np.clip(G, 0, 16)], 0.0)  # region bin q (1..16): wq[q]; else 0
    A = np.einsum("bnr,bn,bns->brs", Q.conj(), W, Q)
    ev = np.linalg.eigvalsh(A)
    return ev[:, -1].max()


def perp_basis():
    e = np.full(16, 0.25)
    Bp = np.linalg.qr(np.column_stack([e, np.eye(16)[:, :15]]))[0][:, 1:16]
    return Bp  # 16 x 15, orthonormal, orthogonal to e


def region_bound(size, texel, lam, levels_um, u, iters=400, seed=0):
    o = orders(size, texel, lam)
    Q, G = bin_subspaces(o, levels_um)
    Bp = perp_basis()
    f = lambda z: bound_value(Q, G, Bp @ z, u)
    best = (f(np.zeros(15)), np.zeros(15))
    rng = np.random.default_rng(seed)
    for start in range(3):
        z0 = np.zeros(15) if start == 0 else 0.1 * rng.standard_normal(15)
        r = minimize(f, z0, method="Powell", options={"maxfev": iters, "xtol": 1e-4, "ftol": 1e-6})
        if r.fun < best[0]:
            best = (r.fun, r.x)
    value = f(best[1])  # recomputed: the bound is this number for this mu
    return value, Bp @ best[1], f(np.zeros(15))


def exact_fractions(heights_um, size, texel, lam):
    """Region/cone fractions and uniformity of a relief by the K-level identity (as exact.cpp)."""
    o = orders(size, texel, lam)
    hs = np.unique(heights_um)
    H = heights_um.reshape(size, size)
    A = np.zeros(len(o["m"]), complex)
    for h in hs:
        F = np.fft.fft2((H == h).astype(float)) / size**2
        A += np.exp(-1j * o["k"] * h * o["q"]) * F.ravel()[o["bin"]]
    flux = o["env"] * np.abs(A) ** 2
    tot = flux.sum()
    g = o["group"]
    bins = np.array([flux[g == 1 + q].sum() for q in range(16)]) / tot
    return dict(cone=flux[g == 0].sum() / tot, region=bins.sum(), uniformity=bins.std() / bins.mean())


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--texel", type=float, default=0.5)
    ap.add_argument("--levels", type=int, default=8)
    ap.add_argument("--step", type=float, default=0.132)
    ap.add_argument("--lambdas", type=float, nargs="+", default=[0.55])
    ap.add_argument("--u", type=float, nargs="+", default=[0.25])
    ap.add_argument("--iters", type=int, default=400)
    a = ap.parse_args()
    levels = [a.step * l for l in range(a.levels)]
    out = []
    for lam in a.lambdas:
        for u in a.u:
            v, mu, v0 = region_bound(a.size, a.texel, lam, levels, u, a.iters)
            out.append(dict(lambda_um=lam, u=u, bound=v, bound_mu0=v0))
            print(json.dumps(out[-1]), flush=True)
