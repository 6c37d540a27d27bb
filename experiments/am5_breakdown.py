#!/usr/bin/python3
"""Where each wavelength's power goes for an anti-mirror relief, by exact scalar diffraction in
NumPy (am3_band.orders: the orders of exp(-i k h (1 + cos theta_o)) on the texel relief, x sinc^2
x cos theta_o, as fractions of the propagating orders' sum; normal light, 16 samples 0.40-0.70 um).

Columns (% of the propagating power): cone (r <= 0.05), inner (0.05-0.1), region split into the
FFT's own band (|m|, |n| <= N/2: 'main') and aliases (orders outside it, a copy of a bin through the
texel's sinc), beyond 0.5 split the same way; 'env' is the region fraction this relief's bin
powers would give if every copy of a bin carried the main order's amplitude (the obliquity phase
ignored): the sinc^2 x cos envelope's share of the loss.
Usage: am5_breakdown.py HEIGHTS.exr [...]   (needs PYTHONPATH=build/python for wavebrdf)"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import am3_band as am  # noqa: E402


def breakdown(h, texel, lam):
    o = am.orders(h, texel, lam)
    r, P, main = o["r"], o["P"], o["main"]
    reg = (r >= 0.1) & (r <= 0.5)
    return dict(cone=P[r <= 0.05].sum(), inner=P[(r > 0.05) & (r < 0.1)].sum(),
                reg_main=P[reg & main].sum(), reg_alias=P[reg & ~main].sum(),
                beyond_main=P[(r > 0.5) & main].sum(), beyond_alias=P[(r > 0.5) & ~main].sum(),
                kirchhoff=o["kirchhoff"])


def envelope_fraction(h, texel, lam):
    """Region fraction if each order carried its bin's main-order amplitude (no obliquity phase
    difference between a bin's copies): sum_bins |c|^2 a(bin) / sum_bins |c|^2 t(bin)."""
    o = am.orders(h, texel, lam)
    N = h.shape[0]
    env = np.sinc(o["m"] / N) ** 2 * np.sinc(o["n"] / N) ** 2 * np.sqrt(1 - o["r"] ** 2)
    # |c|^2 of each order's bin taken from its main order (the copy inside the FFT's band)
    c2 = np.zeros(N * N)
    mm = o["main"]
    c2[o["bin"][mm]] = o["P"][mm] / env[mm]
    w = c2[o["bin"]] * env
    reg = (o["r"] >= 0.1) & (o["r"] <= 0.5)
    return w[reg].sum() / w.sum()


def main():
    for path in sys.argv[1:]:
        h, texel = am.load(path)
        print(f"{path}  ({h.shape[0]}^2, {len(np.unique(np.round(h, 9)))} heights)")
        print("lambda   cone  inner  reg_main reg_alias  beyond_main beyond_alias | region  env   kirchhoff")
        rows = []
        for lam in am.LAMBDAS:
            b = breakdown(h, texel, lam)
            e = envelope_fraction(h, texel, lam)
            rows.append([b[k] for k in ("cone", "inner", "reg_main", "reg_alias", "beyond_main", "beyond_alias")]
                        + [b["reg_main"] + b["reg_alias"], e, b["kirchhoff"]])
            x = rows[-1]
            print(f"{lam:.4f} {100 * x[0]:5.2f} {100 * x[1]:5.2f} {100 * x[2]:8.1f} {100 * x[3]:8.1f} "
                  f"{100 * x[4]:10.1f} {100 * x[5]:11.1f}   | {100 * x[6]:5.1f} {100 * x[7]:5.1f}  {x[8]:.3f}")
        m = np.mean(rows, 0)
        print(f"mean   {100 * m[0]:5.2f} {100 * m[1]:5.2f} {100 * m[2]:8.1f} {100 * m[3]:8.1f} "
              f"{100 * m[4]:10.1f} {100 * m[5]:11.1f}   | {100 * m[6]:5.1f} {100 * m[7]:5.1f}  {m[8]:.3f}")


if __name__ == "__main__":
    main()
