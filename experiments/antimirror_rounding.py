#!/usr/bin/python3
"""Anti-mirror reliefs from the level masks' Gram relaxation (experiments/antimirror_gram_bound.py):
its optimum of the band-mean programme on an N^2 tile, rounded to 8-level reliefs and polished by the
library's design loop started from them (wb.design(start=...)), then tiled to the acceptance tile
and polished there. Scores are design.json's exact-scalar-diffraction metrics.

Rounding (--rounding gs, the default): each bin's Gram matrix is nearly rank one, so its leading
eigenvector v(b) (scaled by the root of its eigenvalue) stands for the masks' spectrum up to a phase.
Gerchberg-Saxton: masks = inverse DFT of v(b) e^{i phi(b)} (random phases to begin), texels
assigned to levels with the relaxed shares' counts maximising the masks' sum (an assignment problem),
then each bin's phase from the assigned masks' spectra projected on v(b); repeated.
--rounding gw: one Gaussian draw per bin with the Gram matrix as covariance, assigned the same way.

Usage: antimirror_rounding.py --pbar-json MEAN.json [--size 32] [--step 0.165] [--seeds 0,1]
           [--polish 1000:300] [--tile 256] [--tile-polish 200:60] [--rounding gs|gw]
MEAN.json: antimirror_gram_bound.py --json output of a band-mean run (its pbar).
"""
import argparse
import json
import sys
import time
import warnings

import numpy as np
from scipy.optimize import linear_sum_assignment

import antimirror_gram_bound as gb

K = gb.LEVELS


def bin_targets(G, s, f, N):
    """Per bin of the N^2 grid: each orbit's Gram matrix shared by its bins, as (N, N, K) leading
    eigenvectors scaled by their eigenvalues' roots and (N, N, K, K) Gram matrices; bin 0 the shares."""
    reps = {tuple(k): i for i, k in enumerate(np.rint(f * N * gb.TEXEL).astype(int))}
    orbit = np.zeros((N, N), int)
    for m in range(N):
        for n in range(N):
            a, b = min(m, N - m), min(n, N - n)
            orbit[m, n] = reps[(max(a, b), min(a, b))]
    count = np.bincount(orbit.ravel(), minlength=len(G))
    Gb = G[orbit] / count[orbit][..., None, None]
    w, U = np.linalg.eigh(Gb)
    V = U[..., -1] * np.sqrt(np.clip(w[..., -1], 0.0, None))[..., None]
    V[0, 0] = s
    return V, Gb


def partition(chi, slots):
    """Texels to levels, each level's count fixed (slots), maximising the sum of chi_level(x)."""
    rows, cols = linear_sum_assignment(-chi.reshape(-1, K)[:, slots])
    lv = np.empty(len(rows), int)
    lv[rows] = slots[cols]
    return lv.reshape(chi.shape[:2])


def masks_spectra(lv):
    N = lv.shape[0]
    return np.stack([np.fft.fft2((lv == k).astype(float)) / N ** 2 for k in range(K)], -1)


def round_gs(V, slots, s, rng, iterations):
    N = V.shape[0]
    F = V * np.exp(2j * np.pi * rng.random((N, N)))[..., None]
    for _ in range(iterations):
        lv = partition(np.real(np.fft.ifft2(F, axes=(0, 1))) * N * N, slots)
        c = np.einsum("mnk,mnk->mn", V, masks_spectra(lv))
        F = V * np.exp(1j * np.angle(c))[..., None]
        F[0, 0] = s
    return lv


def round_gw(Gb, slots, rng):
    N = Gb.shape[0]
    w, U = np.linalg.eigh(Gb)
    z = rng.normal(size=(N, N, K)) + 1j * rng.normal(size=(N, N, K))
    Z = np.einsum("mnij,mnj->mni", U, np.sqrt(np.clip(w, 0.0, None)) * z)
    Z[0, 0] = 0.0
    return partition(np.real(np.fft.ifft2(Z, axes=(0, 1))) * N * N, slots)


def design(wb, start, size, schedule):
    it, rp = (int(v) for v in schedule.split(":"))
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = wb.design("anti-mirror", spectral=16, band_um=(0.40, 0.70), size=size, start=start, iterations=it,
                      refine_passes=rp)
    e = r["metrics"]["exact"]
    return r, (f"mean {100 * e['region_fraction_mean']:.2f} %, worst {100 * e['region_fraction_worst']:.2f} %, "
               f"cone <= {100 * e['specular_fraction_worst']:.3f} %, uniformity <= {e['uniformity_worst']:.3f}, "
               f"limits {'met' if r['design']['constraint_loop']['limits_met'] else 'BROKEN'}, "
               f"step {r['levels_um'][1]:.4f} um, {time.process_time() - t0:.1f} CPU-s")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pbar-json", required=True)
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--step", type=float, default=0.165)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--rounding", choices=("gs", "gw"), default="gs")
    ap.add_argument("--gs-iterations", type=int, default=50)
    ap.add_argument("--polish", default="1000:300", help="iterations:refine_passes on the relaxation's tile")
    ap.add_argument("--tile", type=int, default=256)
    ap.add_argument("--tile-polish", default="200:60", help="iterations:refine_passes on the tiled relief")
    a = ap.parse_args()
    import wavebrdf as wb
    N = a.size
    t0 = time.process_time()
    f, _ = gb.grid_bins(N)
    pbar = np.array(json.load(open(a.pbar_json))[0]["pbar"])
    G, s, fr, _ = gb.relaxed_point(("mean", pbar), np.arange(K) * a.step, gb.LAMBDAS, f)
    print(f"relaxed point {N}^2: band mean {100 * fr[:, 1:5].sum(1).mean():.2f} %, shares {np.round(s, 3)}, "
          f"{time.process_time() - t0:.0f} CPU-s", flush=True)
    V, Gb = bin_targets(G, s, f, N)
    counts = np.floor(s * N * N).astype(int)
    while counts.sum() < N * N:
        counts[np.argmax(s * N * N - counts)] += 1
    slots = np.repeat(np.arange(K), counts)
    for seed in (int(v) for v in a.seeds.split(",")):
        rng = np.random.default_rng(seed)
        t0 = time.process_time()
        lv = round_gs(V, slots, s, rng, a.gs_iterations) if a.rounding == "gs" else round_gw(Gb, slots, rng)
        cpu = time.process_time() - t0
        _, line = design(wb, lv * a.step, N, "0:0")
        print(f"seed {seed} {a.rounding} rounded ({cpu:.1f} CPU-s): {line}", flush=True)
        r, line = design(wb, lv * a.step, N, a.polish)
        print(f"  polished {a.polish} on {N}^2: {line}", flush=True)
        if a.tile > N:
            start = np.tile(r["heights_um"], (a.tile // N, a.tile // N))
            _, line = design(wb, start, a.tile, "0:0")
            print(f"  tiled to {a.tile}^2: {line}", flush=True)
            _, line = design(wb, start, a.tile, a.tile_polish)
            print(f"  polished {a.tile_polish} on {a.tile}^2: {line}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
