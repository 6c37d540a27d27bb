"""The mixture bound in design.json against SciPy's HiGHS linear programme, built here from its
definition (the recorded phase steps and XYZ weights), and the run's own level shares against it."""
import numpy as np
import pytest

import wavebrdf as wb

linprog = pytest.importorskip("scipy.optimize").linprog


def _programme(doc):
    m = doc["mixture_bound"]
    K = m["levels"]
    nu = np.asarray(m["phase_step_rad"])
    w = np.asarray(m["xyz_weights"]).reshape(3, -1)
    grid = np.concatenate([np.pi * np.arange(m["grid"]) / (m["grid"] - 1), nu])

    def basis(v):  # R(v) = basis(v) @ r
        a = 2.0 * np.cos(np.outer(v, np.arange(K)))
        a[:, 0] = 1.0
        return a

    S = basis(nu)  # samples x K
    X, Y, Z = (w[c] @ S for c in range(3))
    D = X + 15 * Y + 3 * Z
    rows = [-basis(grid)]
    for k in range(1, K):  # r_k <= r_0
        e = np.zeros(K)
        e[0], e[k] = -1.0, 1.0
        rows.append(e[None, :])
    A_ub = np.vstack(rows)
    norm = np.full(K, 2.0)
    norm[0] = 1.0
    return K, nu, w, Y, X, D, A_ub, norm


def _max_y(prog, uv, delta=0.0):
    K, nu, w, Y, X, D, A_ub, norm = prog
    cu, cv = 4 * X - uv[0] * D, 9 * Y - uv[1] * D
    if delta == 0.0:
        A_eq, b_eq = np.vstack([cu, cv, norm]), [0.0, 0.0, 1.0]
        A, b = A_ub, np.zeros(len(A_ub))
    else:
        th = 2 * np.pi * np.arange(32) / 32
        poly = np.cos(th)[:, None] * cu + np.sin(th)[:, None] * cv - delta * D
        A, b = np.vstack([A_ub, poly]), np.zeros(len(A_ub) + 32)
        A_eq, b_eq = norm[None, :], [1.0]
    res = linprog(-Y, A_ub=A, b_ub=b, A_eq=A_eq, b_eq=b_eq, bounds=(0, None), method="highs")
    return -res.fun if res.status == 0 else 0.0


@pytest.mark.parametrize("colour", ["#FF0000", "#FF00FF"])  # out of reach (Y 0) and within (Y ~24 %)
def test_bound_matches_highs_and_holds_for_the_designs_shares(colour):
    r = wb.design(target="colour:" + colour, size=16, spectral=16, band_um=(0.4, 0.7), levels=16,
                  height_range_um=2.0, iterations=10, refine_passes=2, seed=3)
    doc = r["design"]
    m = doc["mixture_bound"]
    prog = _programme(doc)
    target = doc["metrics"]["exact"]["target_uv"]
    assert m["y_at_target"] == pytest.approx(_max_y(prog, target), abs=1e-8)
    if not m["reachable_at_target"]:
        d = m["delta_uv_at_min_y"]
        assert d > 0.0
        # The recorded Δu′v′ is the edge: HiGHS finds Y below 5 % just inside it, at least 5 % just outside.
        assert _max_y(prog, target, d * (1 - 1e-3)) < m["min_y"] + 1e-8
        assert _max_y(prog, target, d * (1 + 1e-3) + 1e-6) >= m["min_y"] - 1e-8
    # The design's own level shares, finely mixed: a mixture, so within the bound at its chromaticity.
    K, nu, w = prog[0], prog[1], prog[2]
    shares = np.bincount(np.asarray(r["level"]).ravel(), minlength=K) / np.asarray(r["level"]).size
    R = np.abs(np.exp(-1j * np.outer(nu, np.arange(K))) @ shares) ** 2
    Xs = w @ R
    uv = (4 * Xs[0] / (Xs[0] + 15 * Xs[1] + 3 * Xs[2]), 9 * Xs[1] / (Xs[0] + 15 * Xs[1] + 3 * Xs[2]))
    assert Xs[1] <= _max_y(prog, uv) + 1e-8
    one = m["one_mixture"]
    assert one["y"] <= _max_y(prog, one["uv"]) + 1e-8
