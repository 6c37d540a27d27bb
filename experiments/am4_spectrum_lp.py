#!/usr/bin/python3
"""The anti-mirror over a band in a second-order (power-spectrum) model of an 8-level relief: can
the spectrum's wavelength dependence, as equally spaced levels allow it, hold the light in the
annulus at every wavelength with even bins? An LP (scipy HiGHS).

Model (normal light; continuum and isotropic: radial frequency bins of width DF up to 1/lambda_max,
no texel aliasing, no obliquity, phase factor 1 + cos theta_o taken as 2):
  - the relief's field at wavelength lambda is sum_l M_l z^l with z = exp(-i phi),
    phi = 4 pi Delta / lambda (levels l Delta); the power of a frequency bin i is therefore
    G_i(phi) = |sum_l M_l(f) z^l|^2 summed over the bin: a nonnegative trigonometric polynomial
    of degree K - 1 in phi (imposed on a grid of NPHI phases: a relaxation);
  - Parseval: sum_i G_i(phi) = 1 for every phi (coefficientwise);
  - sum_l M_l(f) = 0 for f != 0 (the masks partition the tile): G_i(0) = 0; the mirror order
    G_0(0) = 1 (the shares sum to 1);
  - per wavelength: power within sin 0.05 (mirror order and the bins landing there) <= CONE;
    the 4 equal-area rings of the annulus within +-2 U of their mean (implied by the 16 bins'
    std/mean <= U when the bins of a ring are equal, as an isotropic design makes them);
  - maximise the band-mean fraction in the annulus (all power propagates, so the fractions'
    denominators are 1).
Every 8-level relief's power spectrum (isotropised) satisfies these, so a value below the target
would rule the target out in this model; a value of 1 says only that second-order physics does
not. Usage: am4_spectrum_lp.py STEP_UM [STEP_UM ...]
"""
import sys

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import lil_matrix, vstack


def solve(step, K=8, lam0=0.40, lam1=0.70, nl=16, df=0.01, cone=0.002, cone_r=0.05, u=0.25, r1=0.1, r2=0.5,
          uni=True, nphi=96):
    lams = lam0 + (np.arange(nl) + 0.5) * (lam1 - lam0) / nl
    f = (np.arange(int(round(1.0 / lam1 / df))) + 0.5) * df
    nb, nc = len(f) + 1, 2 * K - 1  # bin 0: the mirror order; c0, a_1..a_{K-1}, b_1..b_{K-1}
    nv = nb * nc

    def row(phi):
        return np.concatenate([[1.0], np.cos(np.arange(1, K) * phi), np.sin(np.arange(1, K) * phi)])

    B = np.array([row(p) for p in np.linspace(0, 2 * np.pi, nphi, endpoint=False)])
    nonneg = lil_matrix((nb * nphi, nv))
    for i in range(nb):
        nonneg[i * nphi:(i + 1) * nphi, i * nc:(i + 1) * nc] = -B
    aub, bub = [nonneg.tocsr()], [np.zeros(nb * nphi)]
    parseval = lil_matrix((nc, nv))
    at_zero = lil_matrix((nb, nv))
    for i in range(nb):
        for c in range(nc):
            parseval[c, i * nc + c] = 1.0
        at_zero[i, i * nc:(i + 1) * nc] = row(0.0)
    aeq = [parseval.tocsr(), at_zero.tocsr()]
    beq = [np.r_[1.0, np.zeros(nc - 1)], np.r_[1.0, np.zeros(nb - 1)]]
    objective = np.zeros(nv)
    edges = np.sqrt(np.linspace(r1 ** 2, r2 ** 2, 5))
    for lam in lams:
        rb = row(4 * np.pi * step / lam)
        s = lam * f
        rings = [lil_matrix((1, nv)) for _ in range(4)]
        in_cone = lil_matrix((1, nv))
        in_cone[0, 0:nc] = rb
        for i, si in enumerate(s, start=1):
            if si <= cone_r:
                in_cone[0, i * nc:(i + 1) * nc] = rb
            if r1 <= si <= r2:
                rings[min(3, int(np.searchsorted(edges, si) - 1))][0, i * nc:(i + 1) * nc] = rb
                objective[i * nc:(i + 1) * nc] -= rb / nl
        aub.append(in_cone.tocsr())
        bub.append([cone])
        if uni:
            total = sum(r.tocsr() for r in rings)
            for r in rings:
                aub += [r.tocsr() - total / 4 - 2 * u * total / 4, -(r.tocsr() - total / 4) - 2 * u * total / 4]
                bub += [[0.0], [0.0]]
    res = linprog(objective, A_ub=vstack(aub).tocsr(), b_ub=np.concatenate([np.atleast_1d(b) for b in bub]),
                  A_eq=vstack(aeq).tocsr(), b_eq=np.concatenate(beq), bounds=(None, None), method="highs")
    if res.status != 0:
        return None, res.message
    x = res.x.reshape(nb, nc)
    per = []
    for lam in lams:
        s = lam * f
        per.append((x[1:] @ row(4 * np.pi * step / lam))[(s >= r1) & (s <= r2)].sum())
    return -res.fun, np.array(per)


if __name__ == "__main__":
    for step in map(float, sys.argv[1:]):
        for uni in (False, True):
            value, per = solve(step, uni=uni)
            label = "uniformity <= 0.25" if uni else "no uniformity"
            if value is None:
                print(f"step {step} um, {label}: {per}")
            else:
                print(f"step {step} um, {label}: band-mean region {100 * value:.1f} %; per wavelength "
                      + " ".join(f"{100 * p:.0f}" for p in per))
