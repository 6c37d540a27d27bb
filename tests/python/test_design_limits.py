"""The anti-mirror's limits: a limit no relief can keep (16 bins exactly even) is reported by the
CLI on stderr, by wb.design as a UserWarning, and in design.json's warnings, each naming the
option; the exact uniformity of the exported relief, recomputed here from the diffraction orders of the heights, is above it.
A limit the design keeps gives no warning."""
import json
import subprocess
import warnings

import numpy as np
import pytest

import wavebrdf as wb

ARGS = dict(size=16, spectral=3, band_um=(0.45, 0.65), levels=4, height_range_um=1.0, iterations=8,
            refine_passes=4, seed=7)


def uniformity_worst(heights, lambdas, texel_um=0.5, r1=0.1, r2=0.5):
    """std/mean of the 16 equal-area bins (4 rings x the half-open quadrants), worst wavelength,
    from the periodic tile's diffraction orders under normal light summed directly here:
    a_mn = sinc(m/N) sinc(n/N) sum_t exp(-i k h_t (1 + cos theta_o) - 2 pi i (m i_t + n j_t)/N) / N^2,
    flux ~ cos theta_o |a_mn|^2."""
    n = heights.shape[0]
    period = n * texel_um
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    worst = 0.0
    for lam in lambdas:
        k = 2 * np.pi / lam
        reach = int(period / lam) + 1
        bins = np.zeros(16)
        for m in range(-reach, reach + 1):
            for q in range(-reach, reach + 1):
                x, y = lam * m / period, lam * q / period
                rr = x * x + y * y
                if rr >= 1 or not (r1 * r1 <= rr <= r2 * r2):
                    continue
                cos_o = np.sqrt(1 - rr)
                a = np.exp(-1j * k * heights * (1 + cos_o) - 2j * np.pi * (m * i + q * j) / n).sum() / n ** 2
                flux = np.sinc(m / n) ** 2 * np.sinc(q / n) ** 2 * cos_o * abs(a) ** 2
                ring = min(3, max(0, int(4 * (rr - r1 * r1) / (r2 * r2 - r1 * r1))))
                quad = 0 if (x > 0 and y >= 0) else 1 if (x <= 0 and y > 0) else 2 if (x < 0 and y <= 0) else 3
                bins[ring * 4 + quad] += flux
        worst = max(worst, bins.std() / bins.mean())
    return worst


def test_a_limit_no_relief_keeps_is_a_warning_everywhere(cli, tmp_path):
    # The loop on the tile alone, with its repair blocks (no annealed last stage, which ends on a
    # relief it scores and does not repair).
    with pytest.warns(UserWarning, match="--uniformity-limit"):
        r = wb.design(uniformity_limit=0.001, anneal_sweeps=0, **ARGS)
    doc = r["design"]
    assert any("--uniformity-limit" in w for w in doc["warnings"])
    assert doc["constraint_loop"]["limits_met"] is False
    assert doc["constraint_loop"]["repair_blocks"] == 4
    u = uniformity_worst(r["heights_um"], r["lambdas_um"])
    assert u == pytest.approx(doc["metrics"]["exact"]["uniformity_worst"], rel=1e-9)
    assert u > 0.001
    out = tmp_path / "run"
    p = subprocess.run([cli, "design", "--out", str(out), "--size", "16", "--spectral", "3", "--band-um", "0.45,0.65",
                        "--levels", "4", "--height-range-um", "1", "--iterations", "8", "--refine-passes", "4",
                        "--seed", "7", "--uniformity-limit", "0.001", "--anneal-sweeps", "0", "--quiet", "--no-plots"],
                       capture_output=True, text=True, check=True)
    assert "design: warning: the region's uniformity" in p.stderr
    assert json.loads((out / "design.json").read_text())["warnings"] == doc["warnings"]


def test_a_kept_limit_gives_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = wb.design(uniformity_limit=3.0, cone_limit=0.5, **ARGS)
    assert r["design"]["warnings"] == []
    assert r["design"]["constraint_loop"]["limits_met"] is True
    assert uniformity_worst(r["heights_um"], r["lambdas_um"]) <= 3.0
