#!/usr/bin/python3
"""How dark the mirror order of K equally spaced levels (step Δ) can be over a band, for any shares
a ≥ 0 (Σ a = 1) of the levels: P(λ) = Σ_ℓ a_ℓ e^{−i 4π Δ ℓ / λ} (normal light).

Per step: the minimax power (an LP: Re(P e^{−iφ_j}) ≤ t for 32 directions φ_j; t² is a lower bound
on the least worst-case |P|², the LP's shares' worst |P|² an upper one) and the worst |P|² of the
shares with least mean |P|² (every subset of levels tried), which is what the design's rule uses.
Usage: am2_mirror_shares.py [--band A B] [--levels K]"""
import argparse, itertools
import numpy as np
from scipy.optimize import linprog

ap = argparse.ArgumentParser()
ap.add_argument("--band", type=float, nargs=2, default=[0.409375, 0.690625])
ap.add_argument("--levels", type=int, default=8)
a = ap.parse_args()
K, J = a.levels, 32
lam = a.band[0] + (a.band[1] - a.band[0]) * np.arange(129) / 128


def phasors(step):
    return np.exp(-1j * np.outer(4 * np.pi * step / lam, np.arange(K)))


def minimax(step):
    z = phasors(step)
    A = np.vstack([np.real(z * np.exp(-2j * np.pi * j / J)) for j in range(J)])
    r = linprog(np.r_[np.zeros(K), 1], A_ub=np.hstack([A, -np.ones((len(A), 1))]), b_ub=np.zeros(len(A)),
                A_eq=np.r_[np.ones(K), 0][None], b_eq=[1], bounds=[(0, None)] * (K + 1), method="highs")
    return r.fun ** 2, (np.abs(z @ r.x[:K]) ** 2).max()


def least_mean(step):
    z = phasors(step)
    G = np.real(z.conj().T @ z) / len(lam)
    best = None
    for n in range(1, K + 1):
        for S in itertools.combinations(range(K), n):
            x = np.linalg.solve(G[np.ix_(S, S)] + 1e-13 * np.eye(n), np.ones(n))
            s = x / x.sum()
            if (s < 0).any():
                continue
            v = s @ G[np.ix_(S, S)] @ s
            if best is None or v < best[0]:
                full = np.zeros(K)
                full[list(S)] = s
                best = (v, full)
    return (np.abs(z @ best[1]) ** 2).max()


print("step_um  minimax_lower  minimax_upper  least_mean_shares_worst  binomial_worst")
for step in [0.132, 0.138, 0.14, 0.145, 0.15, 0.153, 0.155, 0.16, 0.165, 0.17, 0.175, 0.18]:
    lo, hi = minimax(step)
    c = np.cos(2 * np.pi * step / lam)
    print(f"{step:.3f}  {lo:.2e}  {hi:.2e}  {least_mean(step):.2e}  {((c * c) ** (K - 1)).max():.2e}")
