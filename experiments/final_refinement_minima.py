"""Which minimum of the likelihood does a recovery end in? Starts without and with the truth.

usage: PYTHONPATH=build/python python3 experiments/final_refinement_minima.py RUN_DIR [ITERATIONS]
(imports experiments/tex36_basin.py: run it from experiments/ or with it on the path)

RUN_DIR: `wavebrdf recover --truth ... --save-observations RUN_DIR/obs.h5 --out RUN_DIR`. The run's
own loss (run.json) on its saved observations is minimised by L-BFGS (scipy, the library's
gradient, wavebrdf.observation_loss; ITERATIONS at most, default 300) from: the estimate; the
estimate with its band at >= 0.4 cycles per texel halved, zeroed and sign-flipped, and plus
random noise in that band (0.3 nm rms, 2 draws), none of them using the truth; the truth; and
truth + a (estimate - truth) for a = 0.5, 0.75. Prints each end's error and loss, and how far
the truth's minimum lies from the estimate's, by band of spatial frequency.
experiments/2026-11-30-final-refinement-stall.md.
"""
import sys

import numpy as np

from tex36_basin import load_run, minimise

BANDS = [(0.0, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 0.3), (0.3, 0.4), (0.4, 0.5), (0.5, 0.75)]
HIGH = 0.4  # cycles per texel
NOISE_UM = 0.0003  # the random starts' rms in the band: about the minima's distance on plu-1 128²
NOISE_DRAWS = 2


def main():
    d = sys.argv[1]
    iterations = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    _, texel, _, truth, estimate, pv, loss = load_run(d)
    rows, cols = truth.shape
    q = np.sqrt(np.fft.fftfreq(rows)[:, None] ** 2 + np.fft.fftfreq(cols)[None, :] ** 2)

    def percent(x):  # rms of x (mean removed), % of the truth's peak to valley
        return 100.0 * float(np.sqrt(np.mean((x - x.mean()) ** 2))) / pv

    spectrum = np.fft.fft2(estimate)
    starts = [('the estimate', estimate)]
    for name, k in [('halved', 0.5), ('zeroed', 0.0), ('sign-flipped', -1.0)]:
        starts.append(('the estimate, band >= %.1f %s' % (HIGH, name),
                       np.real(np.fft.ifft2(np.where(q >= HIGH, k * spectrum, spectrum)))))
    rng = np.random.default_rng(11)
    for k in range(NOISE_DRAWS):
        w = np.real(np.fft.ifft2(np.where(q >= HIGH, np.fft.fft2(rng.normal(size=truth.shape)), 0)))
        w *= NOISE_UM / texel / np.sqrt(np.mean(w ** 2))
        starts.append(('the estimate + band noise, draw %d' % k, estimate + w))
    starts.append(('the truth', truth))
    for a in (0.5, 0.75):
        starts.append(('truth + %.2f (estimate - truth)' % a, truth + a * (estimate - truth)))
    ends = {}
    for name, x0 in starts:
        r = minimise(loss, x0, iterations)
        x = r.x.reshape(truth.shape)
        ends[name] = x
        print('from %-36s (%.3f %%, loss %.8e): %3d iterations, loss %.8e, error %.3f %%' % (
            name, percent(x0 - truth), loss(x0.ravel())[0], r.nit, r.fun, percent(x - truth)), flush=True)
    apart = ends['the truth'] - ends['the estimate']
    power = np.abs(np.fft.fft2(apart - apart.mean())) ** 2
    print("the truth's minimum and the estimate's: %.3f %% rms apart; share of it by band:" % percent(apart))
    for lo, hi in BANDS:
        band = (q >= lo) & (q < hi) & (q > 0)
        print('  %.2f-%.2f cycles per texel (%5d modes): %.3f' % (lo, hi, band.sum(), power[band].sum() / power.sum()))


if __name__ == '__main__':
    main()
