#!/usr/bin/python3
"""Where a design's power goes at each wavelength: cone, inside the annulus's hole, the annulus,
beyond it; and how much of it is carried by aliases (orders outside the first Brillouin zone)."""
import argparse, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(__file__))
from am_png import read_heights_png
from antimirror_bound import orders

ap = argparse.ArgumentParser()
ap.add_argument("run")
ap.add_argument("--lambdas", type=float, nargs="*")
a = ap.parse_args()
j = json.load(open(os.path.join(a.run, "design.json")))
v, t = read_heights_png(os.path.join(a.run, "heights.png"))
levels = np.array(j["levels_um"])
K = len(levels)
idx = np.rint(v / 65535 * (K - 1)).astype(int)
N = v.shape[0]
texel = j["constraints"]["texel_um"]
for lam in (a.lambdas or j["light"]["lambdas_um"]):
    o = orders(N, texel, lam)
    A = np.zeros(len(o["m"]), complex)
    for l in range(K):
        F = np.fft.fft2((idx == l).astype(float)) / N**2
        A += np.exp(-1j * o["k"] * levels[l] * o["q"]) * F.ravel()[o["bin"]]
    flux = o["env"] * np.abs(A) ** 2
    tot = flux.sum()
    r = np.hypot(o["m"], o["n"]) * lam / (N * texel)
    alias = (np.abs(o["m"]) >= N // 2) | (np.abs(o["n"]) >= N // 2)
    def frac(mask): return 100 * flux[mask].sum() / tot
    print(f"λ {lam:.3f}: cone {frac(r <= 0.05):.2f}  hole {frac((r > 0.05) & (r < 0.1)):.2f}  "
          f"region {frac((r >= 0.1) & (r <= 0.5)):.2f} (alias {frac((r >= 0.1) & (r <= 0.5) & alias):.2f})  "
          f"0.5-0.6 {frac((r > 0.5) & (r <= 0.6)):.2f}  0.6-1 {frac(r > 0.6):.2f} (alias {frac((r > 0.5) & alias):.2f})  "
          f"kirchhoff total {tot:.3f}")
