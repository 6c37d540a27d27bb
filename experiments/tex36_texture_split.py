"""Split a recovery's height error by sur-2's texel-scale spike texture and by spatial frequency.

usage: PYTHONPATH=build/python python3 experiments/tex36_texture_split.py RUN_DIR [TAU_NM]

RUN_DIR is a `wavebrdf recover --truth ... --out RUN_DIR` directory (truth_height.npy,
estimate_height.npy, and uncertainty_height.npy where the run had --uncertainty).
The texture is located from the truth alone: spike texels lie more than TAU_NM (default 3 nm,
half the ~7.5 nm between the texture's two levels) off the median of their 3 x 3 neighbourhood;
the region is every texel within 2 texels of a spike. The same rule on the estimate locates the
texture without the truth. experiments/2026-11-30-real-scan-exposures.md.
"""
import os
import sys

import numpy as np


def median3(a):
    """Median of each texel's periodic 3 x 3 neighbourhood."""
    return np.median(np.stack([np.roll(np.roll(a, i, 0), j, 1) for i in (-1, 0, 1) for j in (-1, 0, 1)]), axis=0)


def dilate(mask, r):
    """Texels within r texels (Chebyshev, periodic) of a texel of mask."""
    out = np.zeros_like(mask)
    for i in range(-r, r + 1):
        for j in range(-r, r + 1):
            out |= np.roll(np.roll(mask, i, 0), j, 1)
    return out


def band_power(a, edges):
    """Power of a by radial band of spatial frequency (cycles per texel)."""
    q = np.hypot(np.fft.fftfreq(a.shape[0])[:, None], np.fft.fftfreq(a.shape[1])[None, :])
    p = np.abs(np.fft.fft2(a)) ** 2 / a.size ** 2
    return np.array([p[(q >= lo) & (q < hi)].sum() for lo, hi in zip(edges[:-1], edges[1:])])


def main():
    d = sys.argv[1]
    tau = float(sys.argv[2]) if len(sys.argv) > 2 else 3.0
    t = np.load(os.path.join(d, 'truth_height.npy')) * 1000.0  # nm
    e = np.load(os.path.join(d, 'estimate_height.npy')) * 1000.0
    t -= t.mean()
    e -= e.mean()
    err = e - t
    pv = t.max() - t.min()
    dev = t - median3(t)
    spikes = np.abs(dev) > tau
    region = dilate(spikes, 2)
    pct = lambda x: 100.0 * x / pv
    rms = lambda a: float(np.sqrt(np.mean(a ** 2)))
    total = np.sum(err ** 2)
    print('%s: peak to valley %.2f nm, error %.3f %% (%.3f nm rms); tau %.1f nm' % (d, pv, pct(rms(err)), rms(err), tau))
    sigma = None
    if os.path.exists(os.path.join(d, 'uncertainty_height.npy')):
        sigma = np.load(os.path.join(d, 'uncertainty_height.npy')) * 1000.0
    for name, m in [('spike texels', spikes), ('region', region), ('region, not spikes', region & ~spikes),
                    ('off the region', ~region), ('all', np.ones_like(spikes))]:
        line = '%-20s %5.1f %% of texels, %5.1f %% of err^2, rms error %.3f %%' % (
            name, 100.0 * m.mean(), 100.0 * np.sum(err[m] ** 2) / total, pct(rms(err[m])))
        if sigma is not None:
            line += ', rms sigma %.3f %%, rms err/sigma %.3f' % (pct(rms(sigma[m])), rms(err[m] / sigma[m]))
        print(line)
    # The error against the truth's texel-scale part: shrunk spikes would give a gain near -1.
    for name, m in [('region', region), ('off the region', ~region)]:
        g = np.sum(err[m] * dev[m]) / np.sum(dev[m] ** 2)
        rest = err[m] - g * dev[m]
        print('%-15s error = %.3f x (truth - median3) + rest; rest rms %.3f %%' % (name, g, pct(rms(rest))))
    # Without the truth: the same rule on the estimate.
    found = dilate(np.abs(e - median3(e)) > tau, 2)
    print('region from the estimate: %.1f %% of texels, %.1f %% of it in the truth\'s region, %.1f %% of err^2' % (
        100.0 * found.mean(), 100.0 * (found & region).sum() / max(found.sum(), 1), 100.0 * np.sum(err[found] ** 2) / total))
    edges = [0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.75]
    all_, inside, outside = band_power(err, edges), band_power(err * region, edges), band_power(err * ~region, edges)
    print('band (cycles/texel)  share of err^2: all, the region, off it')
    for k in range(len(edges) - 1):
        print('%4.2f-%4.2f            %5.1f %%  %5.1f %%  %5.1f %%' % (
            edges[k], edges[k + 1], 100 * all_[k] / all_.sum(), 100 * inside[k] / all_.sum(), 100 * outside[k] / all_.sum()))


if __name__ == '__main__':
    main()
