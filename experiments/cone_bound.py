"""The cone bound: the largest luminous efficiency Y, counted in incident power, that any relief on
K equally spaced levels can send into the mirror direction's view cone at a given chromaticity
(normal light). A linear programme; run as a script it prints the six sRGB primaries and
secondaries for the colour acceptance's tile.

Why it is a bound. With F_l(b) the DFT of level l's mask (divided by N^2), the order (m, n) in the
cone carries the flux env(m, n) |sum_l F_l(b) e^{-i l nu}|^2 with nu = (2 pi / lambda) step
(cos t_i + cos t_o) and env = sinc^2(m/N) sinc^2(n/N) cos t_o / cos t_i. Group the orders in the
largest cone into classes {(+-m, +-n), (+-n, +-m)}: one |f|, so one nu and one env per
wavelength. A class's sum S_c(nu) = sum_b |sum_l F_l(b) e^{-i l nu}|^2 is a cosine polynomial of
degree K - 1 (the class is closed under negation and the masks are real), non-negative; summed
over every bin of the tile it is 1 at every nu (Parseval at a fixed nu); the mirror order's
S_0 = |sum_l p_l e^{-i l nu}|^2 has autocorrelation coefficients r_m >= 0, r_m <= r_0,
S_0(0) = 1. Every relief gives a point of that set with its own cone power P_lambda =
sum_c env_c S_c(nu_c), so the largest Y over the set at a chromaticity bounds every relief's Y (in
incident power) at that chromaticity. Non-negativity is imposed on a grid (a relaxation: still a
bound).

What it does not cover: the metrics' normalisation by the reflected propagating power (orders far
outside the cone, at their own nu, which can be dark at one wavelength and not at another);
oblique light (the classes' nu is no longer shared).
"""
import sys

import numpy as np

M_SRGB = np.array([[0.4124564, 0.3575761, 0.1804375],
                   [0.2126729, 0.7151522, 0.0721750],
                   [0.0193339, 0.1191920, 0.9503041]])


def xyz_to_uv(X):
    d = X[0] + 15 * X[1] + 3 * X[2]
    return np.array([4 * X[0] / d, 9 * X[1] / d])


def cone_classes(size, texel_um, cone, lambdas_um):
    """The classes of orders in the largest cone: (m, n) keys with 0 <= n <= m, each with its members."""
    L = size * texel_um
    lmin = float(np.min(lambdas_um))
    R = int(np.ceil(cone * L / lmin)) + 1
    cl = {}
    for m in range(-R, R + 1):
        for n in range(-R, R + 1):
            if (lmin * m / L) ** 2 + (lmin * n / L) ** 2 > cone * cone:
                continue
            cl.setdefault(tuple(sorted((abs(m), abs(n)), reverse=True)), []).append((m, n))
    keys = sorted(cl, key=lambda k: (k[0] ** 2 + k[1] ** 2, k))
    return keys, cl


def cone_matrix(size, texel_um, cone, lambdas_um, step_um, levels):
    """P = A @ g: the cone power per wavelength from the classes' cosine coefficients g (class-major,
    K per class; the last K for the rest of the tile, which never enters the cone)."""
    keys, _ = cone_classes(size, texel_um, cone, lambdas_um)
    L, K, W = size * texel_um, levels, len(lambdas_um)
    A = np.zeros((W, (len(keys) + 1) * K))
    for c, (m, n) in enumerate(keys):
        for w, lam in enumerate(lambdas_um):
            dx, dy = lam * m / L, lam * n / L
            if dx * dx + dy * dy > cone * cone:
                continue
            cos_o = np.sqrt(1 - dx * dx - dy * dy)
            env = np.sinc(m / size) ** 2 * np.sinc(n / size) ** 2 * cos_o
            nu = 2 * np.pi / lam * step_um * (1 + cos_o)
            A[w, c * K] += env
            A[w, c * K + 1:(c + 1) * K] += env * 2 * np.cos(np.arange(1, K) * nu)
    return keys, A


def programme(size, texel_um, cone, lambdas_um, step_um, levels, xyz_weights, grid=64, mirror_at_most_one=False):
    """The linear programme's pieces: objective rows X (3 x vars), inequality and equality rows, bounds.
    mirror_at_most_one: S_0(0) <= 1 instead of = 1 (the relaxation the library's semidefinite dual solves)."""
    keys, A = cone_matrix(size, texel_um, cone, lambdas_um, step_um, levels)
    if 2 * keys[-1][0] >= size:
        raise ValueError("the cone reaches order %d of a %d-texel tile; expected below half the tile" % (keys[-1][0], size))
    K, C = levels, len(keys) + 1
    nv = C * K
    nus = np.linspace(0, np.pi, grid)
    basis = 2 * np.cos(np.outer(nus, np.arange(K)))
    basis[:, 0] = 1
    A_ub = np.zeros((C * grid + K - 1, nv))
    for c in range(C):
        A_ub[c * grid:(c + 1) * grid, c * K:(c + 1) * K] = -basis
    for m in range(1, K):  # the mirror order's r_m <= r_0
        A_ub[C * grid + m - 1, 0] = -1
        A_ub[C * grid + m - 1, m] = 1
    A_eq = np.zeros((K + 1, nv))
    A_eq[0, 0] = 1
    A_eq[0, 1:K] = 2  # S_0(0) = 1
    for m in range(K):  # sum over the classes and the rest: S = 1 at every nu
        A_eq[1 + m, m::K] = 1
    b_eq = np.zeros(K + 1)
    b_eq[0] = b_eq[1] = 1
    bounds = [(0, None) if (c == 0 or m == 0) else (None, None) for c in range(C) for m in range(K)]
    if mirror_at_most_one:
        A_ub = np.vstack([A_ub, A_eq[:1]])
        A_eq, b_eq = A_eq[1:], b_eq[1:]
        b_ub = np.concatenate([np.zeros(len(A_ub) - 1), [1.0]])
        return dict(keys=keys, A=A, X=np.asarray(xyz_weights).reshape(3, -1) @ A, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq,
                    b_eq=b_eq, bounds=bounds)
    X = np.asarray(xyz_weights).reshape(3, -1) @ A
    return dict(keys=keys, A=A, X=X, A_ub=A_ub, b_ub=np.zeros(len(A_ub)), A_eq=A_eq, b_eq=b_eq, bounds=bounds)


def max_y(prog, uv, delta=0.0):
    """The largest Y (incident power) at chromaticity uv (delta 0) or within a 32-gon circumscribing
    the disk of radius delta about it; 0 when the set holds no such colour (HiGHS: infeasible)."""
    from scipy.optimize import linprog
    X = prog["X"]
    d = X[0] + 15 * X[1] + 3 * X[2]
    cu, cv = 4 * X[0] - uv[0] * d, 9 * X[1] - uv[1] * d
    A_ub, b_ub, A_eq, b_eq = prog["A_ub"], prog["b_ub"], prog["A_eq"], prog["b_eq"]
    if delta == 0.0:
        A_eq, b_eq = np.vstack([A_eq, cu, cv]), np.concatenate([b_eq, [0, 0]])
    else:
        th = 2 * np.pi * np.arange(32) / 32
        poly = np.cos(th)[:, None] * cu + np.sin(th)[:, None] * cv - delta * d
        A_ub, b_ub = np.vstack([A_ub, poly]), np.concatenate([b_ub, np.zeros(32)])
    r = linprog(-X[1], A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=prog["bounds"], method="highs")
    if r.status == 2:  # infeasible: no point of the set has this colour
        return 0.0
    if r.status != 0:
        raise RuntimeError("the linear programme did not solve: " + r.message)
    return max(0.0, -r.fun)


def min_delta_uv(prog, uv, min_y=0.05):
    """The least Δu′v′ (a lower bound: the polygon circumscribes the disk) at which Y >= min_y."""
    lo, hi = 0.0, 0.5
    if max_y(prog, uv, hi) < min_y:
        return float("inf")
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        if max_y(prog, uv, mid) >= min_y:
            hi = mid
        else:
            lo = mid
    return lo


def relief_point(levels_map, levels, keys):
    """A relief's point in the programme: each class's cosine coefficients from its masks' DFTs."""
    N = levels_map.shape[0]
    F = np.stack([np.fft.fft2((levels_map == l).astype(float)) / N ** 2 for l in range(levels)])
    g = np.zeros((len(keys) + 1, levels))
    used = np.zeros((N, N), bool)
    for c, (m, n) in enumerate(keys):
        members = {(a, b) for a in (m, -m) for b in (n, -n)} | {(b, a) for a in (m, -m) for b in (n, -n)}
        for (a, b) in members:
            f = F[:, a % N, b % N]
            for k in range(levels):
                g[c, k] += np.real(np.sum(f[:levels - k] * np.conj(f[k:])))
            used[a % N, b % N] = True
    rest = F[:, ~used]
    for k in range(levels):
        g[-1, k] = np.real(np.sum(rest[:levels - k] * np.conj(rest[k:])))
    return g.ravel()


if __name__ == "__main__":
    import json
    doc = json.load(open(sys.argv[1]))  # any colour run's design.json on the tile (for weights, levels)
    mb = doc["mixture_bound"]
    lam = np.asarray(doc["light"]["lambdas_um"])
    o = doc["options"] if "options" in doc else {}
    size = int(sys.argv[2]) if len(sys.argv) > 2 else 128
    texel = float(sys.argv[3]) if len(sys.argv) > 3 else 0.5
    cone = float(sys.argv[4]) if len(sys.argv) > 4 else 0.05
    prog = programme(size, texel, cone, lam, mb["level_step_um"], mb["levels"], mb["xyz_weights"])
    print(f"{len(prog['keys'])} classes in the cone at {lam.min():.3f} um")
    for name, rgb in [("#FF0000", (1, 0, 0)), ("#00FF00", (0, 1, 0)), ("#0000FF", (0, 0, 1)),
                      ("#00FFFF", (0, 1, 1)), ("#FF00FF", (1, 0, 1)), ("#FFFF00", (1, 1, 0))]:
        uv = xyz_to_uv(M_SRGB @ np.array(rgb, float))
        y = max_y(prog, uv)
        dmin = min_delta_uv(prog, uv) if y < 0.05 else 0.0
        print(f"{name} Y_max {100 * y:.3f} %  least delta u'v' at Y >= 5 %: {dmin:.4f}", flush=True)
