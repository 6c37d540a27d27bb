#!/usr/bin/python3
"""Upper bounds on the anti-mirror's region fraction, over the band at every wavelength and on the band
mean, for every relief of K equally spaced levels (step D) on an N^2 tile of square texels of a um
under normal light that keeps the limits (cone <= 0.2 % and uniformity <= 0.25 at every wavelength):
the dual of the level masks' Gram relaxation, checked without the solver.

The model is exact scalar diffraction as src/design/exact.cpp scores it. Level masks chi_k (sum 1
per texel) have DFTs F_k(b) = (1/N^2) sum_x chi_k(x) e^{-2 pi i b.x/N}. At wavelength lam the order
of spatial frequency f + (i, j)/a (bin b = f N a, alias (i, j)) has amplitude
sinc(f_x a + i) sinc(f_y a + j) sum_k F_k(b) exp(-i k_lam h_k q), q = 1 + cos t_o, flux
|amplitude|^2 cos t_o, and a metric is a sum of fluxes divided by the propagating total P_lam. So every
flux sum is sum_b tr(W(b) G(b)) with G(b) = Re F(b) F(b)^H (bins b and -b pair up; their weights
are equal) and W(b) real 8 x 8 weights that depend on f = b/(N a) alone, not on N.
A relief gives: G(b) >= 0 and G(b) 1 = 0 for b != 0 (the masks sum to one), sum_b G(b) = diag(s)
(Parseval; s the level shares), and G(0) = s s^T, so Z = [1; s][1; s]^T >= 0 with Z E = 0,
E = (-1, 1, ..., 1). The relaxation keeps those and forgets the rank and the masks' 0/1 values.
Uniformity: the 4 rings' totals T (each the mean of its 4 bins, times 4) spread no more than the 16
bins, so std/mean <= u over the bins gives |T - mean T| / 2 <= u mean T, a second-order cone.

Every wavelength: R_lam - rho P_lam >= 0 at every lam is linear; a dual value < 0 proves no relief
reaches rho at every wavelength. Band mean: r_lam = 1 - O_lam / P_lam <= 1 - O_lam / Pbar_lam,
O = P - region flux, for Pbar_lam >= P_lam of every relief in the limits (itself bounded here,
maximising P_lam), so the mean is at most 1 + max Phi(G), Phi = -mean_lam O_lam / Pbar_lam.
Weak duality: for multipliers z in their cones and any symmetric Y, V(b) = V_base(b) + sum z_j A_j(b):
    Phi(G) <= delta+ + t,   delta = max over bins b != 0 of lambda_max(B^T (V(b) - Y) B)
                            t = max over lifts Z of tr(M Z), M = [[0, diag(Y)^T / 2], [diag(Y) / 2, V(0) - Y]]
(B an orthonormal basis of the complement of 1; sum_b tr G(b) <= 1). The solver only proposes
(Y, z); `certify` evaluates delta on every bin of the checked grid by eigenvalues and t in closed
form, so the number holds for that grid whatever the solver did. A tile of N texels uses the bins
f = (m, n)/(N a): a certificate checked on N^2 covers N^2 and every tile that divides it. Solve
and check on the same grid: a certificate solved on a coarser grid loosens by tens of points on a
finer one (V jumps at the rings' edges).

Usage: antimirror_gram_bound.py [--solve-size N] [--check-size N] [--steps 0.165,...] [--no-mean]
           [--no-every] [--bracket lo,hi] [--json OUT]
"""
import argparse
import json
import sys
import time

import numpy as np

LAMBDAS = 0.40 + (np.arange(16) + 0.5) * 0.30 / 16  # the --spectral 16 band samples of 0.40-0.70 um
TEXEL = 0.5
LEVELS = 8
CONE, R1, R2, CONE_LIMIT, UNIFORMITY = 0.05, 0.1, 0.5, 0.002, 0.25


def basis_perp_ones(K):
    """Orthonormal K x (K-1) basis of the complement of the all-ones vector."""
    return np.linalg.qr(np.c_[np.ones(K), np.eye(K)[:, :K - 1]])[0][:, 1:]


def lift_basis(K):
    """Orthonormal (K+1) x K basis of the complement of E = (-1, 1, ..., 1)."""
    E = np.r_[-1.0, np.ones(K)]
    return np.linalg.qr(np.c_[E, np.eye(K + 1)[:, :K]])[0][:, 1:]


def grid_bins(N, texel=TEXEL):
    """Representatives under the square's 8 symmetries of the N x N tile's bins, as frequencies
    (cycles/um), with their multiplicities; bin 0 first."""
    reps, mult = [], []
    h = N // 2
    for m in range(0, h + 1):
        for n in range(0, m + 1):
            orbit = {(s1 * a % N, s2 * b % N) for a, b in ((m, n), (n, m)) for s1 in (1, -1) for s2 in (1, -1)}
            reps.append((m, n))
            mult.append(len(orbit))
    f = np.array(reps, float) / (N * texel)
    return f, np.array(mult)


def class_weights(f, lam, h, texel=TEXEL):
    """(6, n, K, K) real weights of the cone, the region's 4 equal-area rings and the rest of the
    propagating orders (inside the region or beyond it) for bins at frequencies f (n, 2), summed over
    each bin's aliases (an alias at a multiple of 1/a has sinc 0 and no flux)."""
    k = 2 * np.pi / lam
    reach = int(np.ceil(texel / lam)) + 2
    K = len(h)
    W = np.zeros((6, len(f), K, K))
    dh = h[:, None] - h[None, :]
    a, b = R1 * R1, R2 * R2
    for i in range(-reach, reach + 1):
        for j in range(-reach, reach + 1):
            fx, fy = f[:, 0] + i / texel, f[:, 1] + j / texel
            ox, oy = lam * fx, lam * fy
            r2 = ox * ox + oy * oy
            prop = r2 < 1.0
            if not prop.any():
                continue
            cos_o = np.sqrt(np.clip(1.0 - r2, 0.0, None))
            env = np.sinc(fx * texel) ** 2 * np.sinc(fy * texel) ** 2 * cos_o
            cls = np.full(len(f), 5)
            cls[r2 <= CONE * CONE] = 0
            reg = (r2 >= a) & (r2 <= b)
            ring = np.clip((4.0 * (r2 - a) / (b - a)).astype(int), 0, 3)
            cls[reg] = 1 + ring[reg]
            sel = np.nonzero(prop & (env > 0))[0]
            if not len(sel):
                continue
            wr = np.cos(k * (1.0 + cos_o[sel])[:, None, None] * dh[None]) * env[sel][:, None, None]
            np.add.at(W, (cls[sel], sel), wr)
    return W


def problem(f, h, lambdas, kind, u=UNIFORMITY, texel=TEXEL):
    """V_base (n, K, K), the multipliers' weights A (J, n, K, K), how many lead z (z >= 0) and the
    sets that sum to one; the last 5 L multipliers are one second-order cone per wavelength (the
    rings' uniformity), for V(b) = V_base(b) + sum_j z_j A_j(b):
      ('power', w): Phi = P at lambdas[w];
      ('every', rho): Phi = sum alpha_lam (R_lam - rho P_lam), alpha in the simplex: a bound < 0 proves
                      that no relief has R >= rho P at every wavelength within the limits;
      ('mean', pbar): Phi = -mean O_lam / pbar_lam: the band mean is at most 1 + the bound;
      ('cone', w): Phi = the cone's flux at lambdas[w], without the limits (a check with a known optimum);
    every kind with the limits: -mu_lam (cone_lam - c P_lam) and the rings' uniformity, ring totals
    T_lam: |T - mean T| / 2 <= u mean T (implied by std/mean <= u over the 16 bins), as
    gamma_lam u/2 sum T + eta_lam . (T - mean T), |eta| <= gamma."""
    n, K, L = len(f), len(h), len(lambdas)
    name = kind[0]
    if name == "cone":  # the cone's flux at lambdas[w], no limits: a flat relief's 1 where the cone holds one order
        return class_weights(f, lambdas[kind[1]], h, texel)[0], np.zeros((0, n, K, K)), 0, []
    lead = L + (L if name == "every" else 0)
    V = np.zeros((n, K, K))
    A = np.zeros((lead + 5 * L, n, K, K))
    for w, lam in enumerate(lambdas):
        Wc = class_weights(f, lam, h, texel)
        P = Wc.sum(0)
        A[w] = -(Wc[0] - CONE_LIMIT * P)
        rings = Wc[1:5]
        o = lead + 5 * w
        A[o] = 0.5 * u * rings.sum(0)
        A[o + 1:o + 5] = rings - rings.mean(0)
        if name == "every":
            A[L + w] = rings.sum(0) - kind[1] * P
        elif name == "mean":
            V -= (Wc[0] + Wc[5]) / (kind[1][w] * L)
        elif w == kind[1]:
            V += P
    return V, A, lead, ([np.arange(L, 2 * L)] if name == "every" else [])


def sym_basis(K):
    """Y = B S B^T, S symmetric (K-1) x (K-1): adding 1 v^T + v 1^T to Y changes no bound (the
    bins see B^T Y B only; in the lift d.s and -s^T Y s change by 2 v.s and -2 v.s), so this is
    without loss and leaves the solver no flat directions."""
    B = basis_perp_ones(K)
    iu = np.triu_indices(K - 1)
    E = np.zeros((len(iu[0]), K, K))
    for t, (p, q) in enumerate(zip(*iu)):
        e = np.zeros((K - 1, K - 1))
        e[p, q] = e[q, p] = 1.0
        E[t] = B @ e @ B.T
    return E


def unpack(x, K, J):
    E = sym_basis(K)
    nY = len(E)
    Y = np.tensordot(x[:nY], E, 1)
    return Y, x[nY:nY + J], x[nY + J]


def lift_matrix(V0, Y):
    K = len(Y)
    M = np.zeros((K + 1, K + 1))
    M[0, 1:] = M[1:, 0] = 0.5 * np.diag(Y)
    M[1:, 1:] = V0 - Y
    return M


def lift_max(V0, Y):
    """max over Z >= 0, Z E = 0, Z_00 = 1 of tr(M Z): rank one at the optimum, w^T Mt w over u.w = 1."""
    K = len(Y)
    U = lift_basis(K)
    Mt = U.T @ lift_matrix(V0, Y) @ U
    u = U[0]
    uu = u @ u
    Nb = np.linalg.qr(np.c_[u, np.eye(K)[:, :K - 1]])[0][:, 1:]
    w0 = u / uu
    a = w0 @ Mt @ w0
    g = Nb.T @ Mt @ w0
    Q = Nb.T @ Mt @ Nb
    top = np.linalg.eigvalsh(Q).max()
    if top >= -1e-12:
        return np.inf
    return a - g @ np.linalg.solve(Q, g)


def certify(Y, z, kind, h, lambdas, fc, chunk=1024):
    """The bound Phi <= delta+ + t at (Y, z), by numpy alone: delta = max over the bins fc (bin 0
    first, skipped) of lambda_max(B^T (V(b) - Y) B), t = the lift's max at bin 0. z must lie in its
    cones (the solver's z is projected onto them first: any z there gives a valid bound). The solver's
    Y often leaves the lift's LMI singular (t infinite in closed form), so Y + eps B B^T is tried for a
    few eps and the least delta+ + t kept (each one a valid bound)."""
    K = len(Y)
    B = basis_perp_ones(K)
    V0 = None
    top = -np.inf
    for c0 in range(0, len(fc), chunk):
        V, A, _, _ = problem(fc[c0:c0 + chunk], h, lambdas, kind)
        V = V + np.tensordot(z, A, 1)
        if c0 == 0:
            V0, V = V[0], V[1:]
        S = np.einsum("ki,nkl,lj->nij", B, V - Y[None], B)
        top = max(top, np.linalg.eigvalsh(S)[:, -1].max())
    best = (np.inf, top, np.inf)
    for eps in (0.0, 1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4):
        d = top - eps
        t = lift_max(V0, Y + eps * B @ B.T)
        if max(d, 0.0) + t < best[0]:
            best = (max(d, 0.0) + t, d, t)
    return best


def project_cones(z, lead, sums):
    """z onto its cones: the lead entries >= 0 (a simplex set rescaled to sum one), each trailing
    block of 5 a second-order cone (gamma raised to |eta|)."""
    z = z.copy()
    z[:lead] = np.maximum(z[:lead], 0.0)
    for idx in sums:
        z[idx] /= z[idx].sum()
    for o in range(lead, len(z), 5):
        z[o] = max(z[o], np.linalg.norm(z[o + 1:o + 5]))
    return z


def solve_dual(V, A, V0, A0, lead, sums):
    """cvxopt: minimise t over (Y = B S B^T, z, t) with B^T (V(b) + sum z_j A_j(b) - Y) B <= 0 at
    every bin given and the lift's LMI U^T (t e0 e0^T - M) U >= 0; z[:lead] >= 0, the rest second-
    order cones of 5; sum z over each of `sums` = 1. V, A exclude bin 0; V0, A0 (J, K, K) are bin 0's."""
    from cvxopt import matrix, solvers
    n, K = V.shape[0], V.shape[2]
    J = A.shape[0]
    E = sym_basis(K)
    nY = len(E)
    nx = nY + J + 1
    B = basis_perp_ones(K)
    U = lift_basis(K)
    k1 = K - 1
    Gb = np.zeros((n, k1 * k1, nx))
    for t in range(nY):
        Gb[:, :, t] = -np.broadcast_to((B.T @ E[t] @ B).ravel(), (n, k1 * k1))
    for j in range(J):
        Gb[:, :, nY + j] = np.einsum("ki,nkl,lj->nij", B, A[j], B).reshape(n, -1)
    hb = -np.einsum("ki,nkl,lj->nij", B, V, B).reshape(n, -1)

    def lift_s(x):
        Y, z, t = unpack(x, K, J)
        V0m = V0 + (np.tensordot(z, A0, 1) if J else 0.0)
        e00 = np.zeros((K + 1, K + 1)); e00[0, 0] = t
        return (U.T @ (e00 - lift_matrix(V0m, Y)) @ U).ravel()
    s0 = lift_s(np.zeros(nx))
    Gl = np.stack([-(lift_s(np.eye(nx)[i]) - s0) for i in range(nx)], 1)
    Gz = np.zeros((J, nx)); Gz[:, nY:nY + J] = -np.eye(J)
    Gall = np.vstack([Gz, Gb.reshape(-1, nx), Gl])
    hall = np.concatenate([np.zeros(J), hb.ravel(), s0])
    dims = {"l": lead, "q": [5] * ((J - lead) // 5), "s": [k1] * n + [K]}
    c = np.zeros(nx); c[-1] = 1.0
    Ae = np.zeros((len(sums), nx))
    for i, idx in enumerate(sums):
        Ae[i, nY + idx] = 1.0
    args = (matrix(Ae), matrix(np.ones(len(sums)))) if sums else ()
    for tol in (1e-9, 1e-7, 1e-6):  # the solver may stall at the tightest tolerance; any point is certified
        solvers.options.update(show_progress=False, maxiters=100, abstol=tol, reltol=tol * 10, feastol=tol)
        try:
            sol = solvers.conelp(matrix(c), matrix(Gall), matrix(hall), dims, *args)
        except (ZeroDivisionError, ArithmeticError, ValueError):
            continue
        if sol["x"] is not None:
            solve_dual.last_z = (np.array(sol["z"]).ravel(), J, n, k1)
            return np.array(sol["x"]).ravel(), sol["status"]
    raise RuntimeError("cvxopt failed at every tolerance")


def relaxed_point(kind, h, lambdas, f):
    """Solve on the bins f (bin 0 first) and read the relaxation's own optimum from the multipliers
    of the LMIs: per bin orbit the Gram matrix B X B^T, the lift Z = U W U^T / (U W U^T)_00 (its
    corner G(0), its row s), each bin's Gram scaled alike; per wavelength the fractions (cone, rings,
    the rest) of the propagating flux, with the mirror bin's; and how far Parseval is off."""
    K = len(h)
    V, A, lead, sums = problem(f, h, lambdas, kind)
    solve_dual(V[1:], A[:, 1:], V[0], A[:, 0], lead, sums)
    z, J, n, k1 = solve_dual.last_z
    X = z[J:J + n * k1 * k1].reshape(n, k1, k1)
    W = z[J + n * k1 * k1:].reshape(K, K)
    U = lift_basis(K)
    Z = U @ W @ U.T
    scale = Z[0, 0]
    Z = Z / scale
    B = basis_perp_ones(K)
    G = np.concatenate([Z[None, 1:, 1:], np.einsum("ki,nij,lj->nkl", B, X, B) / scale])
    s = Z[0, 1:]
    parseval = np.abs(G.sum(0) - np.diag(s)).max()
    frac = []
    for lam in lambdas:
        fl = np.einsum("cnij,nij->c", class_weights(f, lam, h), G)
        frac.append(fl / fl.sum())
    return G, s, np.array(frac), parseval


def certified(kind, h, lambdas, fs, fc):
    """Solve on the bins fs, certify on the bins fc (both with bin 0 first): (bound, solver's, z, status)."""
    K = len(h)
    Vs, As, lead, sums = problem(fs, h, lambdas, kind)
    x, st = solve_dual(Vs[1:], As[:, 1:], Vs[0], As[:, 0], lead, sums)
    Y, z, t_solver = unpack(x, K, len(As))
    z = project_cones(z, lead, sums)
    b, d, t = certify(Y, z, kind, h, lambdas, fc)
    return b, t_solver, z, st


def bound_at(step, solve_size, check_size, lambdas=LAMBDAS, mean=True, every=True, bracket=(0.5, 1.0), log=print):
    """Certified bounds at one level step: Pbar per wavelength, the band mean, the every-wavelength rho
    (bisection within bracket: hi is certified only where a certificate < 0 was found there)."""
    h = np.arange(LEVELS) * step
    fs, _ = grid_bins(solve_size)
    fc, _ = grid_bins(check_size)
    out = dict(step=step, solve_size=solve_size, check_size=check_size)
    if every:
        lo, hi = bracket  # every wavelength: bisection on rho, a certificate < 0 moves hi down
        proved = None
        while hi - lo > 2e-3:
            rho = 0.5 * (lo + hi)
            b, sb, *_ = certified(("every", rho), h, lambdas, fs, fc)
            log(f"  every {rho:.4f}: certified {b:.3e} (solver {sb:.3e})", flush=True)
            lo, hi = (lo, rho) if b < 0 else (rho, hi)
            proved = rho if b < 0 else proved
        out["every_bound"] = proved  # None: no rho in the bracket was ruled out
    if mean:
        pbar = np.array([certified(("power", w), h, lambdas, fs, fc)[0] for w in range(len(lambdas))])
        bm, sm, z, st = certified(("mean", pbar), h, lambdas, fs, fc)
        out.update(mean_bound=1.0 + bm, mean_solver=1.0 + sm, status=st, pbar=pbar.tolist())
    return out


def relief_gram(levels_map, K=LEVELS):
    """A relief's bins (all N^2, as frequencies) and Gram matrices G(b) = Re F(b) F(b)^H, G(0) = s s^T."""
    N = levels_map.shape[0]
    F = np.stack([np.fft.fft2((levels_map == l).astype(float)) / N ** 2 for l in range(K)], -1)
    G = np.real(F[..., :, None] * np.conj(F[..., None, :])).reshape(N * N, K, K)
    m = np.fft.fftfreq(N, 1.0 / N)
    mm, nn = np.meshgrid(m, m, indexing="ij")
    return np.c_[mm.ravel(), nn.ravel()] / (N * TEXEL), G


def lagrangian(levels_map, step, Y, z, kind, lambdas=LAMBDAS):
    """sum over all bins of tr((V(b) + sum z_j A_j(b)) G(b)) at a relief's own Gram matrices: weak
    duality says it is at most certify's bound on any grid that holds the relief's bins."""
    f, G = relief_gram(levels_map, len(Y))
    V, A, _, _ = problem(f, np.arange(len(Y)) * step, lambdas, kind)
    if len(z):
        V = V + np.tensordot(z, A, 1)
    return float(np.einsum("nij,nij->", V, G))


def relief_metrics(levels_map, step, lambdas=LAMBDAS):
    """Per wavelength from the same weights at a relief's own G: region, cone and ring fractions of
    the propagating flux P, and P itself (exact scalar diffraction as src/design/exact.cpp scores it)."""
    f, G = relief_gram(levels_map)
    out = {"region": [], "cone": [], "rings": [], "P": [], "other": []}
    for lam in lambdas:
        fl = np.einsum("cnij,nij->c", class_weights(f, lam, np.arange(LEVELS) * step), G)
        tot = fl.sum()
        out["region"].append(fl[1:5].sum() / tot); out["cone"].append(fl[0] / tot)
        out["rings"].append(fl[1:5] / tot); out["other"].append(fl[5] / tot); out["P"].append(tot)
    return {k: np.array(v) for k, v in out.items()}


def print_relaxed_point(a):
    """The relaxation's optimum of the mean programme on the solve grid, read back and checked: PSD,
    Parseval, the cone and the rings' uniformity at every wavelength; its true band-mean region
    fraction is a value the relaxation reaches, so no bound from it can be lower."""
    step = float(a.steps.split(",")[0])
    h = np.arange(LEVELS) * step
    f, _ = grid_bins(a.solve_size)
    pbar = np.array(json.load(open(a.json))[0]["pbar"])
    G, s, fr, parseval = relaxed_point(("mean", pbar), h, LAMBDAS, f)
    rings = fr[:, 1:5]
    u = rings.std(1) / rings.mean(1)
    print(f"step {step}, {a.solve_size}^2: shares {np.round(s, 3)}; least eigenvalue {np.linalg.eigvalsh(G).min():.1e}, "
          f"Parseval off by {parseval:.1e}")
    for lam, r, uu in zip(LAMBDAS, fr, u):
        print(f"  {lam:.3f} um: region {100 * r[1:5].sum():.1f} %, cone {100 * r[0]:.3f} %, rings' std/mean {uu:.3f}, "
              f"the rest {100 * r[5]:.1f} %")
    print(f"band mean {100 * fr[:, 1:5].sum(1).mean():.2f} %, cone <= {100 * fr[:, 0].max():.4f} %, "
          f"rings' std/mean <= {u.max():.4f}")
    tr = np.trace(G[1:], axis1=1, axis2=2)
    hist, edges = np.histogram(np.linalg.norm(f[1:], axis=1), bins=np.arange(0, 1.3, 0.1), weights=tr)
    print("trace by |f| (cycles/um): " + ", ".join(f"{e:.1f}: {v:.3f}" for e, v in zip(edges, hist)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--solve-size", type=int, default=64)
    ap.add_argument("--check-size", type=int, default=256)
    ap.add_argument("--steps", default="0.165")
    ap.add_argument("--json")
    ap.add_argument("--no-mean", action="store_true")
    ap.add_argument("--no-every", action="store_true")
    ap.add_argument("--bracket", default="0.5,1.0", help="the every-wavelength bisection's start (lo,hi)")
    ap.add_argument("--relaxed-point", action="store_true",
                    help="the relaxation's own optimum of the mean programme (Pbar from --json's file) and its metrics")
    a = ap.parse_args()
    if a.relaxed_point:
        return print_relaxed_point(a)
    out = []
    for s in [float(v) for v in a.steps.split(",")]:
        t0 = time.process_time()
        r = bound_at(s, a.solve_size, a.check_size, mean=not a.no_mean, every=not a.no_every,
                     bracket=tuple(float(v) for v in a.bracket.split(",")))
        r["cpu_s"] = time.process_time() - t0
        line = f"step {s:.4f}, solved on {a.solve_size}^2, certified on {a.check_size}^2:"
        if "every_bound" in r:
            line += (f" every wavelength <= {100 * r['every_bound']:.1f} %;" if r["every_bound"] else
                     " every wavelength: nothing in the bracket ruled out;")
        if "mean_bound" in r:
            line += (f" band mean <= {100 * r['mean_bound']:.2f} % (solver {100 * r['mean_solver']:.2f}, {r['status']}),"
                     f" Pbar {min(r['pbar']):.4f}-{max(r['pbar']):.4f};")
        print(line + f" {r['cpu_s']:.0f} CPU-s", flush=True)
        out.append(r)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    sys.exit(main())
