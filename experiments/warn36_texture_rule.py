"""The texture check's rule (include/wavebrdf/texel_texture.h) on conditioned truths and estimates.

usage: python3 experiments/warn36_texture_rule.py WAVEBRDF SURFACES_DIR OUT_DIR
       python3 experiments/warn36_texture_rule.py --heights FILE.npy SIGMA_RELATIVE

The first form conditions every real-surface row of docs/surfaces.md with `WAVEBRDF convert`
(SURFACES_DIR: ../shared/real-surfaces) into OUT_DIR/*.npy, adds generated Gaussian surfaces of
correlation 0.5-4 texels, and prints the rule on each at the run's sigma (its error bars or the
planner's prediction, over the peak to valley, as docs/surfaces.md gives them) and at 0.5 % and 1 %:
the texels standing off their periodic 3 x 3 median by more than max(4 sigma, the rms height), their
share of the texel-scale power, and whether the run would be warned (>= 5 % of the texels and
2 sigma > 1 %). The estimate reproduces sur-2's texture, so a truth is a fair proxy for it. The
second form applies the rule to one heights file (a run's estimate_height.npy).
experiments/2026-11-30-texture-check.md.
"""
import os
import subprocess
import sys

import numpy as np

SIGMAS, FRACTION, FACTOR, TARGET = 4.0, 0.05, 2.0, 0.01

# name, file, conditioning, the run's sigma over the peak to valley (docs/surfaces.md: the check's
# bars where computed, else the planner's prediction), its error at the defaults
ROWS = [
    ("plu-1 64²", "SurfaceTopography__plu-1.plu", "--crop 200,300,64,64 --detrend plane --periodic smooth", 0.0088, "1.03 %"),
    ("plu-1 128²", "SurfaceTopography__plu-1.plu", "--crop 200,300,128,128 --detrend plane --periodic smooth", 0.00859, "1.004 %"),
    ("plu-1 256²", "SurfaceTopography__plu-1.plu", "--crop 200,300,256,256 --detrend plane --periodic smooth", 0.00885, "1.02 %"),
    ("sur-2 64²", "SurfaceTopography__sur-2.sur", "--fill harmonic --crop 200,250,64,64 --detrend plane --periodic smooth", 0.0091, "0.708 %"),
    ("sur-2 128²", "SurfaceTopography__sur-2.sur", "--fill harmonic --crop 200,250,128,128 --detrend plane --periodic smooth", 0.00965, "1.211 %"),
    ("sur-2 256²", "SurfaceTopography__sur-2.sur", "--fill harmonic --crop 200,250,256,256 --detrend plane --periodic smooth", 0.00171, "0.82 %"),
    ("sur-2 32² on the texture", "SurfaceTopography__sur-2.sur", "--fill harmonic --crop 264,314,32,32 --detrend plane --periodic smooth", 0.0095, "9.3 % (2 exp.)"),
    ("sur-2 32² off it", "SurfaceTopography__sur-2.sur", "--fill harmonic --crop 216,250,32,32 --detrend plane --periodic smooth", 0.0095, "0.78 % (2 exp.)"),
    ("x3p-2 64²", "SurfaceTopography__x3p-2.x3p", "--crop 100,40,102,251 --detrend plane --resample-um 0.5 --periodic smooth", 0.00187, "0.27 %"),
    ("x3p-2 128²", "SurfaceTopography__x3p-2.x3p", "--crop 100,40,204,499 --detrend plane --resample-um 0.5 --periodic smooth", 0.00217, "0.23 %"),
    ("x3p-2 256²", "SurfaceTopography__x3p-2.x3p", "--crop 100,0,261,641 --detrend plane --resample-um 0.32 --periodic smooth", 0.003, "0.31 %"),
    ("bullet land 32²", "x3ptools__sample-land.x3p", "--crop 96,300,32,32 --detrend plane --periodic smooth", 0.0001, "0.015 %"),
    ("bullet land 64²", "x3ptools__sample-land.x3p", "--crop 96,300,64,64 --detrend plane --periodic smooth", 0.0001, "0.009 %"),
    ("bullet land 128²", "x3ptools__sample-land.x3p", "--crop 32,300,128,128 --detrend plane --periodic smooth", 0.000055, "0.005 %"),
    ("bullet land 256²", "x3ptools__sample-land.x3p", "--crop 0,100,256,256 --fill harmonic --detrend plane --periodic smooth", 0.0001, "not run"),
]


def median3(a):
    """Median of each texel's periodic 3 x 3 neighbourhood."""
    return np.median(np.stack([np.roll(np.roll(a, i, 0), j, 1) for i in (-1, 0, 1) for j in (-1, 0, 1)]), axis=0)


def rule(heights, sigma_relative):
    """(fraction of texels, their share of the texel-scale power, warned) at sigma over the range."""
    t = heights - heights.mean()
    sigma = sigma_relative * (t.max() - t.min())
    d = t - median3(t)
    flagged = np.abs(d) > max(SIGMAS * sigma, np.sqrt(np.mean(t * t)))
    share = float(np.sum(d[flagged] ** 2) / max(np.sum(d * d), 1e-300))
    fraction = float(flagged.mean())
    return fraction, share, fraction >= FRACTION and FACTOR * sigma_relative > TARGET


def gaussian(n, correlation_texels, seed):
    """A periodic Gaussian-correlated surface (autocorrelation exp(-r²/l²), l in texels)."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(n)
    q2 = f[:, None] ** 2 + f[None, :] ** 2
    return np.real(np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * np.exp(-q2 * (np.pi * correlation_texels) ** 2 / 2)))


def line(name, heights, sigma_relative, error):
    cells = []
    for s in (sigma_relative, 0.005, 0.01):
        fraction, share, warned = rule(heights, s)
        cells.append("%.2f %% (%.0f %%)%s" % (100 * fraction, 100 * share, ", **warned**" if warned else ""))
    pv = heights.max() - heights.min()
    print("| %s | %.1f nm | %.3g %% | %s | %s | %s | %s |" % (name, 1e3 * pv, 100 * sigma_relative, *cells, error))


def main():
    if sys.argv[1] == "--heights":
        fraction, share, warned = rule(np.load(sys.argv[2]).astype(float), float(sys.argv[3]))
        print("texels %.4f, power share %.3f, warned %s" % (fraction, share, warned))
        return
    wavebrdf, surfaces, out = sys.argv[1:4]
    os.makedirs(out, exist_ok=True)
    print("| surface | peak to valley | the run's σ | at it: texels (power share) | at σ 0.5 % | at σ 1 % | error at the defaults |")
    print("|---|---|---|---|---|---|---|")
    for name, path, options, sigma, error in ROWS:
        npy = os.path.join(out, name.replace(" ", "_").replace("²", "") + ".npy")
        subprocess.run([wavebrdf, "convert", "--quiet", os.path.join(surfaces, path), npy, *options.split()], check=True)
        line(name, np.load(npy).astype(float), sigma, error)
    for n in (64, 128):
        for correlation in (0.5, 1, 2, 4):
            line("Gaussian %d², correlation %g texels" % (n, correlation), 1e-3 * gaussian(n, correlation, n), 0.009, "—")


if __name__ == "__main__":
    main()
