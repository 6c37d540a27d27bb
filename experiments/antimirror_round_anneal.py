#!/usr/bin/python3
"""Round the Gram relaxation's 32^2 point at step 0.11 um (Gerchberg-Saxton as antimirror_rounding.py),
then let the design run's annealed last stage (400 sweeps) take it; against random starts on the same
step and schedule. Scores: design.json's exact metrics (32^2 equals its tiling to 256^2).

Usage, from the repository root with PYTHONPATH=build/python:
    experiments/antimirror_round_anneal.py MEAN.json [gs,gw,random] [SEEDS]
MEAN.json: antimirror_gram_bound.py --solve-size 32 --check-size 32 --steps 0.11 --no-every --json.
(experiments/2026-12-02-antimirror-step-survey.md, its last section.)"""
import json, sys, time, warnings
import numpy as np
sys.path.insert(0, "experiments")
import antimirror_gram_bound as gb
import antimirror_rounding as ar
import wavebrdf as wb

N, STEP = 32, 0.11
K = gb.LEVELS
f, _ = gb.grid_bins(N)
pbar = np.array(json.load(open(sys.argv[1]))[0]["pbar"])
G, s, fr, _ = gb.relaxed_point(("mean", pbar), np.arange(K) * STEP, gb.LAMBDAS, f)
print(f"relaxed point: band mean {100 * fr[:, 1:5].sum(1).mean():.2f} %", flush=True)
V, Gb = ar.bin_targets(G, s, f, N)
counts = np.floor(s * N * N).astype(int)
while counts.sum() < N * N:
    counts[np.argmax(s * N * N - counts)] += 1
slots = np.repeat(np.arange(K), counts)

def run(start, sweeps):
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = wb.design("anti-mirror", spectral=16, band_um=(0.40, 0.70), size=N, start=start, iterations=0,
                      refine_passes=0, continuation="off", anneal_sweeps=sweeps, level_step_um=STEP)
    e = r["metrics"]["exact"]
    return (f"mean {100 * e['region_fraction_mean']:.2f} %, worst {100 * e['region_fraction_worst']:.2f} %, "
            f"cone <= {100 * e['specular_fraction_worst']:.3f} %, u <= {e['uniformity_worst']:.3f}, "
            f"step {r['levels_um'][1]:.4f}, {time.process_time() - t0:.0f} CPU-s")

kinds = sys.argv[2].split(",") if len(sys.argv) > 2 else ["gs", "random"]
for seed in range(int(sys.argv[3]) if len(sys.argv) > 3 else 2):
    rng = np.random.default_rng(seed)
    for kind in kinds:
        if kind == "gs":
            lv = ar.round_gs(V, slots, s, rng, 50)
        elif kind == "gw":
            lv = ar.round_gw(Gb, slots, rng)
        else:
            lv = rng.integers(0, K, (N, N))
        print(f"seed {seed} {kind}: as rounded {run(lv * STEP, 0)}", flush=True)
        print(f"seed {seed} {kind}: annealed 400 {run(lv * STEP, 400)}", flush=True)
