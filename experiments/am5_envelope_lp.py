#!/usr/bin/python3
"""Upper bound on the anti-mirror's region fraction per wavelength from the texel envelope alone
(normal light, N^2 texels of a um, exact.cpp's normalisation).

Model ('envelope model'): the field's FFT over the N^2 bins has powers p(bin) >= 0 (Parseval:
they sum to 1); every propagating order g = bin + N (i, j) carries p(bin) sinc^2(m/N) sinc^2(n/N)
cos theta_o. This is exact scalar diffraction when all copies of a bin share one obliquity phase
(exp(-i k h (1 + cos theta_o)) with one cos theta_o per bin); see the write-up for how the designs'
own obliquity differences move their scores (< 1 point). For each wavelength, over all p:
    maximise  region power / propagating power
    subject to  cone power <= 0.2 % of propagating power,
                16 equal-area bins' std/mean <= 0.25.
Linear-fractional; Charnes-Cooper makes it an LP (HiGHS). The uniformity cone is averaged over the
quarter turns (a relaxation: any feasible p's quarter-turn average is feasible, has the same ring
totals, and its four quadrant bins in each ring are equal, so std/mean <= 0.25 becomes
||R - mean(R)|| <= 0.5 mean(R) on the four ring totals R), and enforced by tangent cuts
v.(R - mean R) <= 0.5 mean R, added until the ring totals satisfy it to 1e-6: every cut is implied
by the constraint, so every LP value is an upper bound.

Usage: am5_envelope_lp.py [N [TEXEL_UM [CONE [UNIF [LAMBDA,LAMBDA,...]]]]]
       (default 256 0.5 0.002 0.25, the 16 samples of 0.40-0.70 um)"""
import sys

import numpy as np
from scipy.optimize import linprog

LAMBDAS = 0.40 + (np.arange(16) + 0.5) * 0.30 / 16
R1, R2 = 0.1, 0.5


def bin_vectors(N, texel, lam, cone_r=0.05):
    """Per FFT bin (row-major, index m0 * N + n0 with m0, n0 in 0..N-1): the envelope weight its
    copies put into the cone, each of the 4 equal-area rings, the rest inside/beyond, and in all."""
    L = N * texel
    k0 = np.arange(N)
    reach = int(np.ceil(L / lam / N)) + 1
    out = np.zeros((7, N, N))  # cone, ring0..3, other, total
    edges = np.linspace(R1 ** 2, R2 ** 2, 5)
    for i in range(-reach, reach + 1):
        m = k0 + N * i
        for j in range(-reach, reach + 1):
            n = k0 + N * j
            dx = lam * m[:, None] / L
            dy = lam * n[None, :] / L
            r2 = dx * dx + dy * dy
            prop = r2 < 1.0
            if not prop.any():
                continue
            w = np.where(prop, np.sinc(m[:, None] / N) ** 2 * np.sinc(n[None, :] / N) ** 2
                         * np.sqrt(np.clip(1 - r2, 0, None)), 0.0)
            cone = r2 <= cone_r ** 2
            reg = (r2 >= edges[0]) & (r2 <= edges[-1])
            ring = np.clip(np.floor(4 * (r2 - edges[0]) / (edges[-1] - edges[0])).astype(int), 0, 3)
            out[0] += np.where(cone, w, 0)
            for q in range(4):
                out[1 + q] += np.where(reg & (ring == q), w, 0)
            out[5] += np.where(~cone & ~reg, w, 0)
            out[6] += w
    return out.reshape(7, N * N)


def bound_one(V, cone=0.002, unif=0.25, tol=1e-6, max_cuts=200):
    """max sum(rings . p) / (total . p) under the cone and ring constraints; returns (value,
    ring totals / total, cone / total, p normalised to sum 1)."""
    n = V.shape[1]
    c = -(V[1:5].sum(0))
    A_eq = V[6][None, :]
    b_eq = [1.0]
    cuts = []
    Rm = V[1:5]
    while True:
        rows = [V[0]]
        rhs = [cone]
        for v in cuts:  # v.(R - mean R) - unif*2 mean R <= 0
            vv = v - v.mean()
            rows.append(vv @ Rm - 2 * unif * Rm.mean(0))
            rhs.append(0.0)
        res = linprog(c, A_ub=np.array(rows), b_ub=rhs, A_eq=A_eq, b_eq=b_eq, bounds=(0, None),
                      method="highs")
        if res.status != 0:
            raise RuntimeError(res.message)
        p = res.x
        R = Rm @ p
        d = R - R.mean()
        viol = np.linalg.norm(d) - 2 * unif * R.mean()
        if viol <= tol or len(cuts) >= max_cuts:
            return -res.fun, R, V[0] @ p, p / p.sum(), viol
        cuts.append(d / np.linalg.norm(d))


def main():
    N = int(sys.argv[1]) if len(sys.argv) > 1 else 256
    texel = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
    cone = float(sys.argv[3]) if len(sys.argv) > 3 else 0.002
    unif = float(sys.argv[4]) if len(sys.argv) > 4 else 0.25
    lams = [float(x) for x in sys.argv[5].split(",")] if len(sys.argv) > 5 else LAMBDAS
    print(f"envelope-model bound, {N}^2 texels of {texel} um, cone <= {cone}, uniformity <= {unif}")
    print("lambda  bound  | free  (no cone/uniformity)")
    vals = []
    free = []
    for lam in lams:
        V = bin_vectors(N, texel, lam)
        val, R, cn, p, viol = bound_one(V, cone, unif)
        ratio = V[1:5].sum(0) / np.where(V[6] > 0, V[6], np.inf)
        vals.append(val)
        free.append(ratio.max())
        print(f"{lam:.4f} {100 * val:6.2f} | {100 * ratio.max():6.2f}   rings {np.round(R / R.sum(), 3)} "
              f"cone {cn:.2e} viol {viol:.1e}", flush=True)
    print(f"mean   {100 * np.mean(vals):6.2f} | {100 * np.mean(free):6.2f}")


if __name__ == "__main__":
    main()
