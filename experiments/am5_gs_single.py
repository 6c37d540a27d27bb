#!/usr/bin/python3
"""A single-wavelength anti-mirror by Gerchberg-Saxton on the FFT bins, quantised to 8 levels, scored
by exact scalar diffraction (am3_band.orders): is the design loop's result at one wavelength the
loop's limit or the relief's? The target spectrum: the region's bins (main copy's sin theta in
0.1-0.5), amplitude^2 per ring RING_WEIGHTS (tilted to the inner rings, as the envelope LP's
optimum is), bins whose copies put less than EMIN of their envelope weight into the region left dark.
Usage: am5_gs_single.py N LAMBDA STEP_UM [EMIN [ITERS [SEED [W1,W2,W3,W4]]]]"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import am3_band as am  # noqa: E402
import am5_envelope_lp as lp  # noqa: E402


def score1(h, texel, lam):
    o = am.orders(h, texel, lam)
    rr = o["r"] ** 2
    a, b = 0.01, 0.25
    inr = (rr >= a) & (rr <= b)
    ring = np.clip((4 * (rr - a) / (b - a)).astype(int), 0, 3)
    dx, dy = o["dx"], o["dy"]
    quad = np.full(dx.shape, 3)
    quad[(dx > 0) & (dy >= 0)] = 0
    quad[(dx <= 0) & (dy > 0)] = 1
    quad[(dx < 0) & (dy <= 0)] = 2
    bins = np.bincount((ring * 4 + quad)[inr], weights=o["P"][inr], minlength=16)
    return bins.sum(), bins.std() / bins.mean(), o["P"][rr <= 0.0025].sum(), o["kirchhoff"]


def main():
    N, lam, step = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    emin = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    iters = int(sys.argv[5]) if len(sys.argv) > 5 else 300
    seed = int(sys.argv[6]) if len(sys.argv) > 6 else 1
    texel = 0.5
    ring_w = np.array([float(x) for x in sys.argv[7].split(",")]) if len(sys.argv) > 7 else np.array([0.30, 0.28, 0.24, 0.18])
    V = lp.bin_vectors(N, texel, lam).reshape(7, N, N)
    eff = V[1:5].sum(0) / np.where(V[6] > 0, V[6], np.inf)
    f = np.fft.fftfreq(N, d=texel)
    fx, fy = np.meshgrid(f, f, indexing="ij")
    r2 = (lam * fx) ** 2 + (lam * fy) ** 2
    edges = np.linspace(0.01, 0.25, 5)
    ring = np.clip(np.floor(4 * (r2 - 0.01) / 0.24).astype(int), 0, 3)
    inreg = (r2 >= edges[0]) & (r2 <= edges[-1]) & (eff >= emin)
    amp2 = np.zeros((N, N))
    for q in range(4):
        sel = inreg & (ring == q)
        amp2[sel] = ring_w[q] / max(sel.sum(), 1)
    target = np.sqrt(amp2 / amp2.sum())
    c0 = np.sqrt(1 - 0.3 ** 2)  # a representative obliquity inside the region
    phases = -2 * np.pi / lam * np.arange(8) * step * (1 + c0)
    lv = np.exp(1j * phases)
    rng = np.random.default_rng(seed)
    u = np.exp(2j * np.pi * rng.random((N, N)))
    for it in range(iters):
        U = np.fft.fft2(u) / N
        U = target * np.exp(1j * np.angle(U))
        v = np.fft.ifft2(U) * N
        if it < iters // 2:
            u = np.exp(1j * np.angle(v))
        else:  # nearest of the 8 level phasors
            idx = np.abs(v[..., None] / np.maximum(np.abs(v[..., None]), 1e-12) - lv).argmin(-1)
            u = lv[idx]
    h = np.arange(8)[idx] * step
    reg, uni, cone, kt = score1(h, texel, lam)
    o = am.orders(h, texel, lam)
    rr = o["r"] ** 2
    print("  ring shares", [round(float(o["P"][(rr >= edges[q]) & (rr < edges[q + 1])].sum()), 3) for q in range(4)])
    print(f"N {N} lambda {lam} step {step} emin {emin}: region {100 * reg:.1f} %  uniformity {uni:.3f}  "
          f"cone {100 * cone:.3f} %  kirchhoff {kt:.3f}  levels used {np.bincount(idx.ravel(), minlength=8)}")


if __name__ == "__main__":
    main()
