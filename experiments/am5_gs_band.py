#!/usr/bin/python3
"""Multi-wavelength Gerchberg-Saxton for the anti-mirror over 0.40-0.70 um on 8 levels of STEP um,
scored by exact scalar diffraction (am3_band.score). Each iteration, per wavelength: the field
exp(-i k h (1 + c0)) (c0 a representative cos theta_o inside the region), its FFT's amplitudes
replaced by the target (the bins whose main copy lands in that wavelength's region, amplitude^2 per
ring RING_WEIGHTS, equal within a ring), back; each texel then takes the level whose phasors are
nearest the 16 back-propagated fields together (weights: those fields' own amplitudes).
Usage: am5_gs_band.py N STEP_UM [ITERS [SEED [W1,W2,W3,W4 [OUT.npy]]]]"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import am3_band as am  # noqa: E402


def targets(N, texel, lams, ring_w):
    f = np.fft.fftfreq(N, d=texel)
    fx, fy = np.meshgrid(f, f, indexing="ij")
    out = []
    for lam in lams:
        r2 = (lam * fx) ** 2 + (lam * fy) ** 2
        ring = np.clip(np.floor(4 * (r2 - 0.01) / 0.24).astype(int), 0, 3)
        inreg = (r2 >= 0.01) & (r2 <= 0.25)
        a2 = np.zeros((N, N))
        for q in range(4):
            sel = inreg & (ring == q)
            a2[sel] = ring_w[q] / max(sel.sum(), 1)
        out.append(np.sqrt(a2 / a2.sum()))
    return np.array(out)


def main():
    N, step = int(sys.argv[1]), float(sys.argv[2])
    iters = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    ring_w = np.array([float(x) for x in sys.argv[5].split(",")]) if len(sys.argv) > 5 else np.full(4, 0.25)
    out = sys.argv[6] if len(sys.argv) > 6 else None
    texel = 0.5
    lams = am.LAMBDAS
    c0 = np.sqrt(1 - 0.3 ** 2)
    T = targets(N, texel, lams, ring_w)
    lv = np.exp(-2j * np.pi / lams[:, None] * np.arange(8)[None, :] * step * (1 + c0))  # (L, 8)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, 8, (N, N))
    for it in range(iters):
        acc = np.zeros((N, N, 8))
        for w in range(len(lams)):
            u = lv[w][idx]
            U = np.fft.fft2(u) / N
            v = np.fft.ifft2(T[w] * np.exp(1j * np.angle(U))) * N
            acc += np.real(np.conj(lv[w])[None, None, :] * v[..., None])
        idx = acc.argmax(-1)
    h = idx * step
    reg, uni, cone = am.score(h, texel)
    print(f"N {N} step {step} iters {iters} seed {seed} rings {ring_w}: region mean {100 * reg.mean():.1f} % "
          f"(worst {100 * reg.min():.1f}), uniformity worst {uni.max():.3f}, cone worst {100 * cone.max():.3f} %")
    print("  region % per wavelength: " + " ".join(f"{100 * x:.0f}" for x in reg))
    print("  uniformity per wavelength: " + " ".join(f"{x:.2f}" for x in uni))
    if out:
        np.save(out, h)


if __name__ == "__main__":
    main()
