"""The cone bound (experiments/cone_bound.py) against independent evaluations: every relief maps to
a feasible point of its programme with the cone power of a direct sum over texels; on a 3 x 3 tile
no relief of all 3^9 beats it; the design runs' own cone light (design.json, exact scalar
diffraction in incident power) never exceeds it at its own chromaticity."""
import itertools
import os
import sys

import numpy as np
import pytest

pytest.importorskip("scipy.optimize")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "experiments"))
import cone_bound as cb  # noqa: E402


def _weights(lambdas):
    import wavebrdf as wb
    xyz = np.array([wb.cie1931_xyz(l) for l in lambdas]).T  # 3 x W, unnormalised: only ratios and order matter
    return xyz / xyz[1].sum()


def _direct_cone_power(levels_map, step, texel, cone, lambdas):
    """sum over the orders in the cone of |(1/L^2) integral e^{-i k h q} e^{-2 pi i f.x}|^2 cos t_o, texel by texel."""
    N = levels_map.shape[0]
    L = N * texel
    out = []
    for lam in lambdas:
        k = 2 * np.pi / lam
        R = int(cone * L / lam) + 1
        total = 0.0
        for m in range(-R, R + 1):
            for n in range(-R, R + 1):
                dx, dy = lam * m / L, lam * n / L
                if dx * dx + dy * dy > cone * cone:
                    continue
                cos_o = np.sqrt(1 - dx * dx - dy * dy)
                a = 0j
                for i in range(N):
                    for j in range(N):
                        ph = -k * levels_map[i, j] * step * (1 + cos_o)
                        ix = texel if m == 0 else (np.exp(-2j * np.pi * m * (i + 1) * texel / L) - np.exp(-2j * np.pi * m * i * texel / L)) / (-2j * np.pi * m / L)
                        iy = texel if n == 0 else (np.exp(-2j * np.pi * n * (j + 1) * texel / L) - np.exp(-2j * np.pi * n * j * texel / L)) / (-2j * np.pi * n / L)
                        a += np.exp(1j * ph) * ix * iy
                total += abs(a / L ** 2) ** 2 * cos_o
        out.append(total)
    return np.array(out)


def test_every_relief_is_a_point_of_its_programme_with_the_direct_sums_cone_power():
    rng = np.random.default_rng(5)
    lambdas, K, N, texel, cone, step = np.array([0.41, 0.52, 0.66]), 4, 12, 0.5, 0.3, 0.21
    prog = cb.programme(N, texel, cone, lambdas, step, K, _weights(lambdas), grid=64)
    for trial in range(3):
        relief = rng.integers(0, K, size=(N, N))
        if trial == 2:
            relief = (np.add.outer(np.arange(N), np.arange(N)) // 3) % K  # a coarse staircase: light in the cone
        g = cb.relief_point(relief, K, prog["keys"])
        assert prog["A"] @ g == pytest.approx(_direct_cone_power(relief, step, texel, cone, lambdas), rel=1e-9, abs=1e-12)
        assert np.max(prog["A_ub"] @ g) <= 1e-12
        assert prog["A_eq"] @ g == pytest.approx(prog["b_eq"], abs=1e-12)
        for value, (lo, hi) in zip(g, prog["bounds"]):
            assert lo is None or value >= lo - 1e-15


def test_no_relief_on_a_small_tile_beats_the_bound():
    lambdas, K, N, texel, cone, step = np.array([0.42, 0.55, 0.68]), 3, 3, 0.5, 0.2, 0.3
    w = _weights(lambdas)
    prog = cb.programme(N, texel, cone, lambdas, step, K, w, grid=64)
    P = []
    for levels in itertools.product(range(K), repeat=N * N):
        g = cb.relief_point(np.array(levels).reshape(N, N), K, prog["keys"])
        P.append(prog["A"] @ g)
    P = np.array(P)
    # the direct sum on a few of them, so that the brute force rests on the independent evaluation too
    for i in (1, 4000, 19000):
        relief = np.array(list(itertools.product(range(K), repeat=N * N))[i]).reshape(N, N)
        assert P[i] == pytest.approx(_direct_cone_power(relief, step, texel, cone, lambdas), rel=1e-9)
    X = P @ w.T
    uv = np.array([cb.xyz_to_uv(x) for x in X])
    centres = uv[np.argsort(-X[:, 1])[:: len(uv) // 12]][:12]  # chromaticities spread over the reliefs
    delta = 0.02
    some_bound_is_tight = False
    for c in centres:
        near = np.hypot(*(uv - c).T) <= delta
        best = X[near, 1].max()
        bound = cb.max_y(prog, c, delta)
        assert best <= bound + 1e-9
        some_bound_is_tight |= best >= 0.5 * bound
    assert some_bound_is_tight


@pytest.mark.parametrize("colour", ["#FF0000", "#FFFF00", "#0000FF"])
def test_a_designs_own_cone_light_is_within_the_bound(colour):
    import wavebrdf as wb
    r = wb.design(target="colour:" + colour, size=16, spectral=8, band_um=(0.4, 0.7), levels=8,
                  height_range_um=1.5, view_cone=0.2, iterations=20, refine_passes=2, seed=11)
    doc = r["design"]
    m = doc["mixture_bound"]
    lam = np.asarray(doc["light"]["lambdas_um"])
    prog = cb.programme(16, 0.5, 0.2, lam, m["level_step_um"], m["levels"], m["xyz_weights"])
    own = m["design_check"]["absolute"]
    assert own["y"] <= cb.max_y(prog, own["uv"]) + 1e-7


def _cvxopt_dual(doc, uv, size, texel_um, cone):
    """The semidefinite dual of design.json's cone bound, solved by cvxopt from the definition."""
    cvx = pytest.importorskip("cvxopt")
    from cvxopt import matrix, solvers
    solvers.options["show_progress"] = False
    lam = np.asarray(doc["light"]["lambdas_um"])
    cbj = doc["cone_bound"]
    K = cbj["levels"]
    keys, A = cb.cone_matrix(size, texel_um, cone, lam, cbj["level_step_um"], K)
    C = len(keys)
    w = np.asarray(doc["mixture_bound"]["xyz_weights"]).reshape(3, -1)
    X = np.einsum("xw,wcm->xcm", w, A[:, :C * K].reshape(len(lam), C, K))

    def T(v):
        i, j = np.indices((K, K))
        d = np.abs(i - j)
        return np.where(d == 0, v[0], 0.5 * np.asarray(v)[d])

    dd = X[0] + 15 * X[1] + 3 * X[2]
    G = [4 * X[0] - uv[0] * dd, 9 * X[1] - uv[1] * dd]
    n = K + 1 + 2 + 2 * (K - 1)
    ip, ir, ig, ia, ib = 0, K, K + 1, K + 3, 2 * K + 2
    ones2 = np.full(K, 2.0)
    ones2[0] = 1
    Gs, hs = [], []
    for c in range(C + 1):
        base, J = np.zeros(K), np.zeros((K, n))
        J[np.arange(K), ip + np.arange(K)] = 1
        if c < C:
            base = -X[1][c]
            for g in range(2):
                J[:, ig + g] = G[g][c]
        if c == 0:
            J[:, ir] = ones2
            for m in range(1, K):
                J[m, ia + m - 1], J[m, ib + m - 1], J[0, ib + m - 1] = -1, 1, -1
        hs.append(matrix(T(base)))
        Gs.append(matrix(np.column_stack([-T(J[:, i]).ravel() for i in range(n)])))
    pos = [ir] + list(range(ia, n))
    Gl = np.zeros((len(pos), n))
    Gl[np.arange(len(pos)), pos] = -1
    cobj = np.zeros(n)
    cobj[ip] = cobj[ir] = 1
    r = solvers.sdp(matrix(cobj), Gl=matrix(Gl), hl=matrix(np.zeros(len(pos))), Gs=Gs, hs=hs)
    assert r["status"] == "optimal"
    return r["primal objective"]


@pytest.mark.parametrize("colour", ["#FF0000", "#00FF00"])
def test_design_json_cone_bound_holds_for_the_run_and_matches_an_independent_solver(colour):
    import wavebrdf as wb
    r = wb.design(target="colour:" + colour, size=16, spectral=8, band_um=(0.4, 0.7), levels=8,
                  height_range_um=1.5, view_cone=0.2, iterations=20, refine_passes=2, seed=11)
    doc = r["design"]
    c = doc["cone_bound"]
    # the run's own cone light in incident power: the exact metrics' reflectance (per unit incident
    # power) and their Y; divided by kirchhoff_total, the share of the reflected power
    w = np.asarray(doc["mixture_bound"]["xyz_weights"]).reshape(3, -1)
    refl = np.asarray(doc["metrics"]["exact"]["reflectance"])
    X = w @ refl
    own = c["design_check"]["absolute"]
    assert own["y"] == pytest.approx(X[1], rel=1e-9)
    assert doc["metrics"]["exact"]["luminous_efficiency"] == pytest.approx(X[1], rel=1e-9)
    share = (w @ (refl / np.asarray(doc["metrics"]["kirchhoff_total"])))[1]
    assert doc["metrics"]["exact"]["luminous_efficiency_share_of_reflected"] == pytest.approx(share, rel=1e-9)
    assert c["design_check"]["normalised"]["y"] == pytest.approx(share, rel=1e-9)
    assert own["within"] and X[1] <= own["bound_y_at_its_chromaticity"]
    # the same programme by HiGHS on a grid (a weaker relaxation) and by cvxopt (the exact dual)
    lam = np.asarray(doc["light"]["lambdas_um"])
    prog = cb.programme(16, 0.5, 0.2, lam, c["level_step_um"], c["levels"], doc["mixture_bound"]["xyz_weights"], grid=256,
                        mirror_at_most_one=True)
    target = doc["metrics"]["exact"]["target_uv"]
    exact = _cvxopt_dual(doc, target, 16, 0.5, 0.2)
    assert c["y_at_target"] >= exact - 1e-6          # a bound: never below the optimum
    assert c["y_at_target"] <= exact + 0.01 + 0.05 * exact  # and near it
    assert exact <= cb.max_y(prog, target) + 1e-6    # the grid's relaxation is weaker
    assert c["out_of_reach_at_target"] == (c["y_at_target"] < 0.05)
