#!/usr/bin/env python3
"""The height error of a recover run directory split by spatial frequency (experiments/2026-11-24-field-tiles-and-coarse-space.md,
"Where the 512² error is"): estimate_height.npy − truth_height.npy, each mean removed, 2-D FFT,
the share of the error power below 1.5 cycles per surface, at 1.5–3, 3–6 and above 6, and the
error's rms relative to the truth's height range (height_rel_rmse: all of it, with the best-fit
plane removed, and with only the periods below ~size/16 kept, i.e. the detail).

    /usr/bin/python3 experiments/error_spectrum.py RUN_DIR [RUN_DIR ...]
"""
import os
import sys

import numpy as np


def split(run_dir):
    e = np.load(os.path.join(run_dir, "estimate_height.npy")).astype(np.float64)
    t = np.load(os.path.join(run_dir, "truth_height.npy")).astype(np.float64)
    if e.shape != t.shape:
        raise SystemExit(f"{run_dir}: estimate {e.shape} and truth {t.shape} differ")
    span = float(t.max() - t.min())
    d = (e - e.mean()) - (t - t.mean())
    rows, cols = d.shape
    # Best-fit plane (with the mean) removed, least squares.
    yy, xx = np.mgrid[0:rows, 0:cols]
    a = np.stack([np.ones(d.size), xx.ravel(), yy.ravel()], axis=1)
    coef, *_ = np.linalg.lstsq(a, d.ravel(), rcond=None)
    d_plane = d - (a @ coef).reshape(d.shape)
    power = np.abs(np.fft.fft2(d)) ** 2
    fy = np.fft.fftfreq(rows) * rows  # cycles per surface
    fx = np.fft.fftfreq(cols) * cols
    f = np.hypot(fy[:, None], fx[None, :])
    total = power[f > 0].sum()
    bands = [(0, 1.5), (1.5, 3), (3, 6), (6, np.inf)]
    shares = [power[(f > 0) & (f >= lo) & (f < hi)].sum() / total for lo, hi in bands]
    # The detail: periods under size/16 (|f| ≥ 16 cycles per surface on the longer side).
    detail = np.real(np.fft.ifft2(np.where(f >= max(rows, cols) / 16.0, np.fft.fft2(d), 0)))
    rel = lambda v: float(np.sqrt(np.mean(v ** 2)) / span)
    return rel(d), rel(d_plane), rel(detail), shares


def main(argv):
    if len(argv) < 2:
        raise SystemExit(__doc__)
    print("run | height_rel_rmse | plane removed | detail (|f| ≥ N/16) | power <1.5 | 1.5–3 | 3–6 | >6")
    for run_dir in argv[1:]:
        whole, plane, detail, shares = split(run_dir)
        print(f"{run_dir} | {100 * whole:.4f} % | {100 * plane:.4f} % | {100 * detail:.4f} % | " +
              " | ".join(f"{100 * s:.1f} %" for s in shares))


if __name__ == "__main__":
    main(sys.argv)
