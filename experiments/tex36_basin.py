"""Is a recovery's estimate the likelihood's minimum next to the truth, or another basin?

usage: PYTHONPATH=build/python python3 experiments/tex36_basin.py RUN_DIR [ITERATIONS [RESTARTS]]

RUN_DIR: `wavebrdf recover --truth ... --save-observations RUN_DIR/obs.h5 --out RUN_DIR`. The
run's own loss (run.json) on its saved observations is minimised by L-BFGS (scipy, the library's
gradient, wavebrdf.observation_loss) from the truth, from the estimate, and from the estimate
plus 1 nm rms white noise (RESTARTS draws, default 2: without the truth, are the minima unique?).
experiments/2026-11-30-real-scan-exposures.md.
"""
import json
import os
import sys

import numpy as np
from scipy.optimize import minimize

import wavebrdf as wb


def load_run(d):
    """A recovery directory with saved observations: (run.json, texel µm, observations, truth and
    estimate in texel units, the truth's peak to valley, the run's loss with its gradient)."""
    run = json.load(open(os.path.join(d, 'run.json')))
    texel = run['texel_um']
    observations = wb.read_observations(os.path.join(d, 'obs.h5'))
    truth = np.load(os.path.join(d, 'truth_height.npy')) / texel  # texel units
    estimate = np.load(os.path.join(d, 'estimate_height.npy')) / texel

    def loss(x):
        value, grad = wb.observation_loss(wb.Heightfield(x.reshape(truth.shape), texel_um=texel), observations,
                                          run['loss'])
        return value, np.asarray(grad, dtype=float).ravel()

    return run, texel, observations, truth, estimate, truth.max() - truth.min(), loss


def minimise(loss, x0, iterations):
    """L-BFGS from x0 to the loss's minimum (scipy's result)."""
    return minimize(loss, x0.ravel(), jac=True, method='L-BFGS-B',
                    options={'maxiter': iterations, 'gtol': 1e-14, 'ftol': 1e-15})


def main():
    d = sys.argv[1]
    iterations = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    restarts = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    run, texel, observations, truth, estimate, pv, loss = load_run(d)

    def nm(x):
        e = x.reshape(truth.shape) - truth
        return 1000.0 * texel * float(np.sqrt(np.mean((e - e.mean()) ** 2)))

    rng = np.random.default_rng(7)
    starts = [('the truth', truth), ('the estimate', estimate)]
    starts += [('the estimate + 1 nm noise', estimate + rng.normal(0.0, 0.001 / texel, truth.shape)) for _ in range(restarts)]
    minima = []
    for name, x0 in starts:
        r = minimise(loss, x0, iterations)
        x = r.x.reshape(truth.shape)
        minima.append(x - x.mean())
        print('from %-26s (%.3f nm, loss %.8e): %3d iterations, loss %.8e, error %.3f nm (%.3f %%)' % (
            name, nm(x0.ravel()), loss(x0.ravel())[0], r.nit, r.fun, nm(r.x), 100.0 * nm(r.x) / (1000.0 * texel * pv)),
              flush=True)
    for a in range(1, len(minima)):
        for b in range(a + 1, len(minima)):
            print('minima %d and %d (no truth): %.3f nm rms apart' % (
                a, b, 1000.0 * texel * np.sqrt(np.mean((minima[a] - minima[b]) ** 2))))


if __name__ == '__main__':
    main()
