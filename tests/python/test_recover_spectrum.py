"""A recovery with a known truth compares the estimate's power spectrum with the truth's
(recovery_directory.h: psd.csv and run.json "psd"; docs/recovery.md): the columns are the
radial PSDs NumPy computes from the run's own truth_height.npy and estimate_height.npy (an
independent periodogram), the summary follows from the columns, and the report draws them."""
import csv
import json
import os
import subprocess

import numpy as np
import pytest

import conftest


def radial_psd(heights_um, texel_um):
    """The periodic radial PSD as docs/surfaces.md defines it: C = dx dy / (N M) |FFT(z)|^2,
    bins of dq = the coarser step, bin k holds (k - 1/2, k + 1/2] dq, up to the smaller Nyquist."""
    z = heights_um - heights_um.mean()
    n, m = z.shape
    c = texel_um * texel_um / (n * m) * np.abs(np.fft.fft2(z)) ** 2
    qa = 2 * np.pi * np.fft.fftfreq(n, texel_um)
    qb = 2 * np.pi * np.fft.fftfreq(m, texel_um)
    q = np.hypot(qa[:, None], qb[None, :])
    dq = max(2 * np.pi / (n * texel_um), 2 * np.pi / (m * texel_um))
    q_max = min(2 * np.pi / (n * texel_um) * (n // 2), 2 * np.pi / (m * texel_um) * (m // 2))
    bins = max(1, int(np.floor(q_max / dq)))
    k = np.floor(q / dq + 0.5).astype(int)
    keep = (q > 0) & (k >= 1) & (k <= bins)
    out_q, out_c, out_n = [], [], []
    for b in range(1, bins + 1):
        sel = keep & (k == b)
        if sel.any():
            out_q.append(q[sel].mean())
            out_c.append(c[sel].mean())
            out_n.append(int(sel.sum()))
    return np.array(out_q), np.array(out_c), np.array(out_n)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    cli = os.path.join(conftest.BUILD, "bin", "wavebrdf")
    assert os.path.exists(cli), "%s is missing; build the wavebrdf_cli target" % cli
    out = tmp_path_factory.mktemp("spectrum") / "run"
    r = subprocess.run([cli, "recover", "--size", "16", "--texel-um", "2", "--height-range-um", "0.4", "--seed", "5",
                        "--no-plots", "--out", str(out)],
                       capture_output=True, text=True, check=True)
    return out, r.stderr


def read_columns(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_psd_columns_are_the_periodograms_of_truth_estimate_and_error(run_dir):
    out, _ = run_dir
    psd = read_columns(out / "psd.csv")
    truth = np.load(out / "truth_height.npy")
    estimate = np.load(out / "estimate_height.npy")
    texel = json.load(open(out / "run.json"))["texel_um"]
    for key, heights in (("truth_psd_um4", truth), ("estimate_psd_um4", estimate),
                         ("error_psd_um4", (estimate - estimate.mean()) - (truth - truth.mean()))):
        q, c, n = radial_psd(heights, texel)
        np.testing.assert_allclose(psd["q_per_um"], q, rtol=1e-9)
        np.testing.assert_array_equal(psd["count"], n)
        np.testing.assert_allclose(psd[key], c, rtol=1e-8, atol=1e-12 * c.max(), err_msg=key)


def test_psd_summary_follows_from_the_columns(run_dir):
    out, stderr = run_dir
    psd = read_columns(out / "psd.csv")
    summary = json.load(open(out / "run.json"))["psd"]
    # Bins where both spectra hold only the FFT's rounding (below 1e-12 of the truth's largest bin)
    # count as resolved, as the library states.
    rounding = 1e-12 * psd["truth_psd_um4"].max()
    ok = psd["error_psd_um4"] <= psd["truth_psd_um4"] + rounding
    first_bad = len(ok) if ok.all() else int(np.argmin(ok))
    assert summary["resolved_all"] == bool(ok.all())
    expected_q = psd["q_per_um"][first_bad - 1] if first_bad > 0 else 0.0
    assert summary["resolved_q_per_um"] == pytest.approx(expected_q, rel=1e-9)
    if expected_q > 0:
        assert summary["resolved_wavelength_um"] == pytest.approx(2 * np.pi / expected_q, rel=1e-9)
    ratio = np.sum(psd["error_psd_um4"] * psd["count"]) / np.sum(psd["truth_psd_um4"] * psd["count"])
    assert summary["error_power_ratio"] == pytest.approx(ratio, rel=1e-7)
    assert summary["bins"] == len(psd["q_per_um"])
    # The CLI's line says the same.
    line = [l for l in stderr.splitlines() if l.startswith("spectrum: ")]
    assert len(line) == 1 and "psd.csv" in line[0]
    # A recovery to better than 1 % leaves well under 1 % of the power in the error.
    assert ratio < 1e-3
