"""The anti-mirror's Gram bound (experiments/antimirror_gram_bound.py) against independent evaluations:
its weights give the library's exact metrics of a designed relief; weak duality holds at real reliefs'
own Gram matrices for any multipliers (a sign or scale slip in the certificate breaks it); the bound on
the cone's flux equals its known optimum (1, a flat relief); the certified bounds lie above what a
designed relief achieves (region fraction, propagating flux); the relaxation's own optimum, read
back from the solver, keeps its constraints and its objective equals the certified bound."""
import os
import sys

import numpy as np
import pytest

pytest.importorskip("cvxopt")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "experiments"))
import antimirror_gram_bound as gb  # noqa: E402

import wavebrdf as wb  # noqa: E402

LAMS = 0.40 + (np.arange(4) + 0.5) * 0.30 / 4  # the design's --spectral 4 samples of 0.40-0.70 um


@pytest.fixture(scope="module")
def designed():
    r = wb.design(target="anti-mirror", size=16, spectral=4, band_um=(0.4, 0.7), levels=8, height_range_um=2.0,
                  iterations=60, refine_passes=10, seed=3)
    levels = np.asarray(r["level"]).reshape(16, 16)
    step = r["levels_um"][1] - r["levels_um"][0]
    return r, levels, step


def test_the_weights_give_the_librarys_exact_metrics_of_a_designed_relief(designed):
    r, levels, step = designed
    assert np.allclose(r["lambdas_um"], LAMS)
    got = gb.relief_metrics(levels, step, LAMS)
    exact = r["metrics"]["exact"]
    assert got["region"] == pytest.approx(exact["region_fraction"], abs=1e-12)
    assert got["cone"] == pytest.approx(exact["specular_fraction"], abs=1e-12)
    u = [np.std(np.repeat(x / 4, 4)) / np.mean(x / 4) for x in got["rings"]]  # ring means' spread <= the 16 bins'
    assert np.all(np.array(u) <= np.array(exact["uniformity"]) + 1e-12)


@pytest.mark.parametrize("kind", [("power", 1), ("mean", np.full(4, 1.3)), ("every", 0.8)])
def test_weak_duality_at_real_reliefs_for_any_multipliers(kind):
    rng = np.random.default_rng(5)
    K = gb.LEVELS
    fc, _ = gb.grid_bins(16)
    _, A, lead, sums = gb.problem(fc[:2], np.arange(K) * 0.16, LAMS, kind)
    for trial in range(3):
        S = rng.normal(size=(K - 1, K - 1))
        B = gb.basis_perp_ones(K)
        Y = B @ (S @ S.T / 10 + 20.0 * np.eye(K - 1)) @ B.T  # above every V(b) on the complement of 1: t finite
        z = gb.project_cones(np.abs(rng.normal(size=len(A))), lead, sums)
        bound, _, _ = gb.certify(Y, z, kind, np.arange(K) * 0.16, LAMS, fc)
        assert np.isfinite(bound)
        for N in (8, 16):
            for _ in range(2):
                levels = rng.integers(0, K if trial else 3, (N, N))
                val = gb.lagrangian(levels, 0.16, Y, z, kind, LAMS)
                assert val <= bound + 1e-12, (kind, N, val, bound)


def test_the_cone_bound_equals_its_known_optimum():
    # An 8-texel tile at 0.5 um puts its first orders at lam / 4 um > 0.05: the cone holds the mirror
    # order alone, whose flux |sum_k s_k w_k|^2 is at most 1, reached by a flat relief.
    f, _ = gb.grid_bins(8)
    b, solver, _, _ = gb.certified(("cone", 0), np.arange(gb.LEVELS) * 0.16, LAMS, f, f)
    flat = gb.relief_metrics(np.zeros((8, 8), int), 0.16, LAMS)
    assert flat["P"][0] == pytest.approx(1.0, abs=1e-12)
    assert 1.0 - 1e-9 <= b <= 1.0 + 1e-5


def test_the_certified_bounds_lie_above_a_designed_relief(designed):
    r, levels, step = designed
    f, _ = gb.grid_bins(16)
    h = np.arange(gb.LEVELS) * step
    pbar = np.array([gb.certified(("power", w), h, LAMS, f, f)[0] for w in range(len(LAMS))])
    got = gb.relief_metrics(levels, step, LAMS)
    assert np.all(got["P"] <= pbar)
    ex = r["metrics"]["exact"]
    assert max(ex["uniformity"]) <= gb.UNIFORMITY and max(ex["specular_fraction"]) <= gb.CONE_LIMIT
    bm, *_ = gb.certified(("mean", pbar), h, LAMS, f, f)
    j = 1.0 - np.mean((got["cone"] + got["other"]) * got["P"] / pbar)
    assert j >= ex["region_fraction_mean"] - 1e-12
    assert ex["region_fraction_mean"] <= 1.0 + bm  # the limits hold: the relief is a point of the relaxation


def test_the_relaxations_own_optimum_keeps_its_constraints_and_reaches_its_bound():
    f, _ = gb.grid_bins(16)
    h = np.arange(gb.LEVELS) * 0.165
    pbar = np.array([gb.certified(("power", w), h, LAMS, f, f)[0] for w in range(len(LAMS))])
    bm, *_ = gb.certified(("mean", pbar), h, LAMS, f, f)
    G, s, fr, parseval = gb.relaxed_point(("mean", pbar), h, LAMS, f)
    assert parseval < 1e-7 and s.sum() == pytest.approx(1.0, abs=1e-7)
    assert np.linalg.eigvalsh(G).min() > -1e-7
    assert np.abs(G[1:].sum(2)).max() < 1e-7  # each bin's Gram matrix is orthogonal to 1
    assert fr[:, 0].max() <= gb.CONE_LIMIT + 1e-6
    rings = fr[:, 1:5]
    assert (rings.std(1) / rings.mean(1)).max() <= gb.UNIFORMITY + 1e-5
    # the programme's objective at its optimum equals the certified bound (strong duality)
    P = np.array([np.einsum("cnij,nij->", gb.class_weights(f, lam, h), G) for lam in LAMS])
    phi = -np.mean((fr[:, 0] + fr[:, 5]) * P / pbar)
    assert phi == pytest.approx(bm, abs=1e-5)
