#!/usr/bin/python3
"""Does the masks' Gram relaxation of exact scalar diffraction allow the anti-mirror's 90 %?

For a relief of 8 levels of heights h_l on N^2 texels of a um (normal light), the amplitude of an
order g is F(bin) . w_g, F(bin) in C^8 the level masks' FFT at the order's bin, w_g the phasors
exp(-i k h_l (1 + cos theta_g)) (one per order: the per-order obliquity phase, exactly as
exact.cpp), times the texel's sinc. So every order's power is tr(Q(bin) W_g), Q = F F^H, and a
relief gives Q(bin) >= 0 (PSD), Q(bin) 1 = 0 off the mirror bin, sum over bins of Q = diag(s) - s s^T
(s the levels' shares; Q(0) = s s^T, relaxed by the lift [[1, s^T], [s, Q(0)]] >= 0, Q(0) 1 = s,
Q(0) >= 0). Real masks let Q be real (pair bin and -bin); bins with equal weights share one Q.
This relaxation is solved (cvxopt) for:
    maximise tau  subject to, at every wavelength of the band,
      region - RHO * propagating >= tau,   cone <= 0.2 % of propagating,
      four ring totals R: ||R - mean R|| <= 0.5 mean R  (implied by 16 bins' std/mean <= 0.25).
tau >= 0 means the relaxation admits a region fraction >= RHO at every wavelength together, so it
cannot prove the band mean below RHO: on this tile, and (the tile embeds in any multiple of it)
on every multiple of it, such as 256^2 for N = 32.
Usage: am5_gram_sdp.py N STEP_UM [RHO]   (levels l * STEP, l = 0..7)
       am5_gram_sdp.py check N STEP_UM     (the weights against am3_band on a random relief)"""
import sys

import numpy as np
from cvxopt import matrix, solvers, spmatrix
from scipy.sparse import coo_matrix

LAMBDAS = 0.40 + (np.arange(16) + 0.5) * 0.30 / 16


def weights(N, texel, lam, h):
    """Per bin (N, N): real 8x8 weights of the cone, the 4 rings, the rest, summed over copies."""
    L = N * texel
    k = 2 * np.pi / lam
    reach = int(np.ceil(L / lam / N)) + 1
    W = np.zeros((6, N, N, 8, 8))
    edges = (0.01, 0.25)
    for i in range(-reach, reach + 1):
        for j in range(-reach, reach + 1):
            m = np.arange(N)[:, None] + N * i + 0 * np.arange(N)[None, :]
            n = np.arange(N)[None, :] + N * j + 0 * np.arange(N)[:, None]
            # signed representatives: bins 0..N-1, copies m + N i
            dx, dy = lam * m / L, lam * n / L
            r2 = dx * dx + dy * dy
            prop = r2 < 1
            if not prop.any():
                continue
            cos_o = np.sqrt(np.clip(1 - r2, 0, None))
            env = np.where(prop, np.sinc(m / N) ** 2 * np.sinc(n / N) ** 2 * cos_o, 0.0)
            ph = k * h[None, None, :] * (1 + cos_o)[..., None]  # (N, N, 8)
            wr = np.cos(ph[..., :, None] - ph[..., None, :])  # Re(w w^H)
            cls = np.full((N, N), 5)
            cls[r2 <= 0.0025] = 0
            reg = (r2 >= edges[0]) & (r2 <= edges[1])
            ring = np.clip(np.floor(4 * (r2 - edges[0]) / (edges[1] - edges[0])).astype(int), 0, 3)
            cls[reg] = 1 + ring[reg]
            for c in range(6):
                sel = prop & (cls == c)
                W[c][sel] += env[sel][:, None, None] * wr[sel]
    return W


def check(N, step, seed=1):
    """The weights against am3_band's exact orders on a random 8-level relief: region and cone
    fractions from sum over bins of tr(Re(F F^H) W) must equal the direct scoring."""
    import os
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import am3_band as am
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, 8, (N, N))
    h = np.arange(8) * step
    F = np.stack([np.fft.fft2((idx == l).astype(float)) / N ** 2 for l in range(8)], -1)
    Q = np.real(F[..., :, None] * np.conj(F[..., None, :]))
    worst = 0.0
    for lam in LAMBDAS[::5]:
        W = weights(N, 0.5, lam, h)
        P = np.einsum("abij,cabij->c", Q, W)
        o = am.orders(idx * step, 0.5, lam)
        rr = o["r"] ** 2
        reg = o["P"][(rr >= 0.01) & (rr <= 0.25)].sum()
        cone = o["P"][rr <= 0.0025].sum()
        a, b = P[1:5].sum() / P.sum(), P[0] / P.sum()
        worst = max(worst, abs(a - reg), abs(b - cone), abs(P.sum() - o["kirchhoff"]))
        print(f"  check {lam:.4f}: region {a:.6f} vs {reg:.6f}, cone {b:.2e} vs {cone:.2e}, "
              f"propagating {P.sum():.6f} vs {o['kirchhoff']:.6f}")
    print(f"  largest difference {worst:.1e}")


def main():
    if sys.argv[1] == "check":
        check(int(sys.argv[2]), float(sys.argv[3]))
        return
    N, step = int(sys.argv[1]), float(sys.argv[2])
    rho = float(sys.argv[3]) if len(sys.argv) > 3 else 0.9
    texel = 0.5
    h = np.arange(8) * step
    K = 8
    # basis of the complement of 1
    B = np.linalg.qr(np.c_[np.ones(K), np.eye(K)[:, :K - 1]])[0][:, 1:]  # 8x7 orthonormal, _|_ 1
    Ws = [weights(N, texel, lam, h) for lam in LAMBDAS]  # each (6, N, N, 8, 8)
    # group bins (other than 0) with identical weights at every wavelength
    sig = {}
    groups = []
    for a in range(N):
        for b in range(N):
            if a == 0 and b == 0:
                continue
            key = tuple(np.round(np.concatenate([W[:, a, b].ravel() for W in Ws]), 9))
            key = hash(key)
            if key not in sig:
                sig[key] = len(groups)
                groups.append([])
            groups[sig[key]].append((a, b))
    G = len(groups)
    print(f"N {N}, step {step}, rho {rho}: {G} bin groups", flush=True)
    nt = 28  # 7x7 sym
    iu = np.triu_indices(7)
    # variable layout: X_g (28 each), Q0 (36, 8x8 sym), s (8), tau (1)
    i8 = np.triu_indices(8)
    nx = G * nt + 36 + 8 + 1
    oQ0, os_, ot = G * nt, G * nt + 36, G * nt + 44

    def symvec_coeffs(M, idx):  # tr(X M) for X sym given by its upper entries
        c = M[idx] * 1.0
        off = idx[0] != idx[1]
        c[off] = M[idx][off] + M.T[idx][off]
        return c

    # linear functionals per wavelength: cone, rings 0..3, other -> rows over x
    def functional(Wl, c):
        row = np.zeros(nx)
        for g, members in enumerate(groups):
            a, b = members[0]
            M = B.T @ Wl[c, a, b] @ B * len(members)
            row[g * nt:(g + 1) * nt] = symvec_coeffs(M, iu)
        row[oQ0:oQ0 + 36] = symvec_coeffs(Wl[c, 0, 0], i8)  # the mirror bin's own copies
        return row

    Gl, hl = [], []  # linear inequalities  G x <= h
    soc_G, soc_h = [], []
    for Wl in Ws:
        F = [functional(Wl, c) for c in range(6)]
        A = F[1] + F[2] + F[3] + F[4]
        T = A + F[0] + F[5]
        r = -(A - rho * T)
        r[ot] = 1.0  # tau - (A - rho T) <= 0
        Gl.append(r); hl.append(0.0)
        Gl.append(F[0] - 0.002 * T); hl.append(0.0)
        R = np.array(F[1:5])
        P = np.eye(4) - 0.25
        # SOC: t = 0.125 * sum R >= || P R ||   -> s = h - G x in SOC: s0 = 0.125 sum R, s1.. = P R
        soc_G.append(-np.vstack([0.125 * R.sum(0), P @ R]))
        soc_h.append(np.zeros(5))
    # s >= 0, Q0 >= 0 entrywise
    for l in range(8):
        r = np.zeros(nx); r[os_ + l] = -1; Gl.append(r); hl.append(0.0)
    for q in range(36):
        r = np.zeros(nx); r[oQ0 + q] = -1; Gl.append(r); hl.append(0.0)
    # PSD blocks: each X_g (7x7), the lift [[1, s^T], [s, Q0]] (9x9)
    psd_G, psd_h = [], []
    for g in range(G):
        Gb = np.zeros((49, nx))
        for t, (i, j) in enumerate(zip(*iu)):
            Gb[i * 7 + j, g * nt + t] -= 1
            if i != j:
                Gb[j * 7 + i, g * nt + t] -= 1
        psd_G.append(Gb); psd_h.append(np.zeros(49))
    Gb = np.zeros((81, nx)); hb = np.zeros(81)
    hb[0] = 1.0
    for l in range(8):
        Gb[(l + 1) * 9 + 0, os_ + l] -= 1; Gb[0 * 9 + l + 1, os_ + l] -= 1
    for t, (i, j) in enumerate(zip(*i8)):
        Gb[(i + 1) * 9 + j + 1, oQ0 + t] -= 1
        if i != j:
            Gb[(j + 1) * 9 + i + 1, oQ0 + t] -= 1
    psd_G.append(Gb); psd_h.append(hb)
    # equalities: sum_g B X_g B^T + Q0 - diag(s) = 0 (upper entries), Q0 1 - s = 0, 1^T s = 1
    Ae, be = [], []
    for t8, (p, q) in enumerate(zip(*i8)):
        r = np.zeros(nx)
        for g, members in enumerate(groups):
            for t, (i, j) in enumerate(zip(*iu)):
                v = B[p, i] * B[q, j] + (B[p, j] * B[q, i] if i != j else 0.0)
                r[g * nt + t] += v * len(members)
        r[oQ0 + t8] += 1
        if p == q:
            r[os_ + p] -= 1
        Ae.append(r); be.append(0.0)
    for p in range(8):
        r = np.zeros(nx)
        for t8, (i, j) in enumerate(zip(*i8)):
            if i == p: r[oQ0 + t8] += 1
            elif j == p: r[oQ0 + t8] += 1
        r[os_ + p] -= 1
        Ae.append(r); be.append(0.0)
    r = np.zeros(nx); r[os_:os_ + 8] = 1; Ae.append(r); be.append(1.0)
    Gall = np.vstack(Gl + soc_G + psd_G)
    hall = np.concatenate([hl] + soc_h + psd_h)
    dims = {"l": len(Gl), "q": [5] * len(soc_G), "s": [7] * G + [9]}
    c = np.zeros(nx); c[ot] = -1.0
    Ae = np.array(Ae)
    # drop dependent equality rows (rank)
    U, S, Vt = np.linalg.svd(Ae, full_matrices=False)
    keep = S > 1e-9 * S[0]
    Ae2, be2 = (U[:, keep].T @ Ae), U[:, keep].T @ np.array(be)
    solvers.options["show_progress"] = False
    solvers.options["maxiters"] = 200
    Gs = coo_matrix(Gall)  # the PSD blocks touch only their own group's entries
    Gsp = spmatrix(Gs.data.tolist(), Gs.row.tolist(), Gs.col.tolist(), Gall.shape)
    sol = solvers.conelp(matrix(c), Gsp, matrix(hall), dims, matrix(Ae2), matrix(be2))
    x = np.array(sol["x"]).ravel()
    print(f"status {sol['status']}  tau {x[ot]:.4g}  primal obj {sol['primal objective']:.4g} dual obj "
          f"{sol['dual objective']:.4g}  shares {np.round(x[os_:os_ + 8], 3)}")
    # per wavelength ratios of the relaxed point
    out = []
    for Wl in Ws:
        F = [functional(Wl, c) @ x for c in range(6)]
        A = sum(F[1:5]); T = A + F[0] + F[5]
        out.append((A / T, F[0] / T))
    print("region % per wavelength: " + " ".join(f"{100 * a:.1f}" for a, _ in out))
    print("cone % per wavelength:   " + " ".join(f"{100 * b:.3f}" for _, b in out))


if __name__ == "__main__":
    main()
