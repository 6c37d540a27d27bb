"""Is the average of several likelihood minima closer to the truth than one of them?

usage: PYTHONPATH=build/python python3 experiments/minima_ensemble.py RUN_DIR METHOD [K [ITERATIONS]]
(imports experiments/tex36_basin.py: run it from experiments/ or with it on the path)

RUN_DIR: `wavebrdf recover --truth ... --save-observations RUN_DIR/obs.h5 --out RUN_DIR`. K minima
(default 8) of the run's own loss on its saved observations, each reached by L-BFGS (scipy, the
library's gradient; ITERATIONS at most, default 120) from a start that does not use the truth:
  band      the estimate with its band at >= 0.4 cycles per texel given random phases (each
            mode keeps the estimate's own amplitude there);
  small     the estimate plus white noise of a quarter of the estimate's rms in that band;
  bootstrap the estimate, minimised on the observations resampled with replacement;
  half      the estimate, minimised on a random half of the observations (K/2 splits, both halves).
For K = 2, 4, 8 (the first K minima) it prints the mean's error and loss (on all observations),
and the error and loss after 20 more iterations of L-BFGS on all observations from the mean;
beside them the single references: the estimate itself and the estimate run to its end.
Saves the minima to RUN_DIR/ensemble_METHOD.npz. experiments/2026-11-30-minima-ensemble.md.
"""
import os
import sys
import time

import numpy as np

import wavebrdf as wb
from tex36_basin import load_run, minimise

HIGH = 0.4  # cycles per texel
POLISH = 20  # iterations on all observations from the mean of the minima


def main():
    d, method = sys.argv[1], sys.argv[2]
    k_max = int(sys.argv[3]) if len(sys.argv) > 3 else 8
    iterations = int(sys.argv[4]) if len(sys.argv) > 4 else 120
    run, texel, observations, truth, estimate, pv, loss = load_run(d)
    rows, cols = truth.shape
    q = np.sqrt(np.fft.fftfreq(rows)[:, None] ** 2 + np.fft.fftfreq(cols)[None, :] ** 2)
    high = q >= HIGH

    def percent(x):  # rms of x (mean removed), % of the truth's peak to valley
        return 100.0 * float(np.sqrt(np.mean((x - x.mean()) ** 2))) / pv

    def high_percent(x):  # the part of percent(x) above HIGH
        return 100.0 * float(np.sqrt(np.mean(np.real(np.fft.ifft2(np.where(high, np.fft.fft2(x), 0))) ** 2))) / pv

    def subset_loss(chosen):
        def f(x):
            value, grad = wb.observation_loss(wb.Heightfield(x.reshape(truth.shape), texel_um=texel), chosen,
                                              run['loss'])
            return value, np.asarray(grad, dtype=float).ravel()
        return f

    def report(name, x, t0=None):
        extra = '' if t0 is None else ', %.1f CPU s' % (time.process_time() - t0)
        print('%-34s error %.4f %% (above %.1f: %.4f %%), loss %.8e%s' % (
            name, percent(x - truth), HIGH, high_percent(x - truth), loss(x.ravel())[0], extra), flush=True)

    report('the estimate', estimate)
    t0 = time.process_time()
    end = minimise(loss, estimate, iterations).x.reshape(truth.shape)
    report('the estimate run to its end', end, t0)

    rng = np.random.default_rng(36)
    spectrum = np.fft.fft2(estimate)
    n = len(observations)
    minima = []
    halves = None
    for k in range(k_max):
        t0 = time.process_time()
        f, x0 = loss, estimate
        if method == 'band':
            phase = np.fft.fft2(rng.normal(size=truth.shape))
            x0 = np.real(np.fft.ifft2(np.where(high, np.abs(spectrum) * phase / np.abs(phase), spectrum)))
        elif method == 'small':
            x0 = estimate + rng.normal(0.0, 0.25 * high_percent(estimate) * pv / 100.0, truth.shape)
        elif method == 'bootstrap':
            f = subset_loss([observations[i] for i in rng.integers(0, n, n)])
        elif method == 'half':
            if k % 2 == 0:
                halves = np.array_split(rng.permutation(n), 2)
            f = subset_loss([observations[i] for i in halves[k % 2]])
        else:
            raise SystemExit('unknown method %r: expected band, small, bootstrap or half' % method)
        r = minimise(f, x0, iterations)
        minima.append(r.x.reshape(truth.shape))
        report('%s minimum %d (%d it.)' % (method, k, r.nit), minima[-1], t0)
    np.savez(os.path.join(d, 'ensemble_%s.npz' % method), minima=np.array(minima), end=end)

    e = [m - truth for m in minima]
    for k in (2, 4, 8):
        if k > k_max:
            break
        mean = np.mean(minima[:k], axis=0)
        report('%s: mean of %d' % (method, k), mean)
        t0 = time.process_time()
        polished = minimise(loss, mean, POLISH).x.reshape(truth.shape)
        report('%s: mean of %d + %d it.' % (method, k, POLISH), polished, t0)
    he = [np.real(np.fft.ifft2(np.where(high, np.fft.fft2(x), 0))).ravel() for x in e]
    c = np.corrcoef(np.array(he))
    print('mean correlation of the minima\'s errors above %.1f: %.3f' % (HIGH, c[np.triu_indices(len(e), 1)].mean()))
    centred = np.array([(x - x.mean()).ravel() for x in e])
    gram = centred @ centred.T / centred.shape[1]
    shared = gram[np.triu_indices(len(e), 1)].mean()  # the error all minima share: the mean's as K grows
    print('the mean of K minima as K grows: %.4f %% (from the pairwise products of their errors)' % (
        100.0 * np.sqrt(max(shared, 0.0)) / pv))


if __name__ == '__main__':
    main()
