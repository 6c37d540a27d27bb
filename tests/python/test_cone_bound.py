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
