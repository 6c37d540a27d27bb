#!/usr/bin/python3
"""The anti-mirror over a band, by exact scalar diffraction in NumPy (an evaluation that shares
nothing with the C++ engine but the definition: the orders of the texel relief's thin-element far
field, A = sum_l exp(-i k h_l (1 + cos theta_o)) FFT(mask_l)/N^2 x the texel's sinc, flux
|A|^2 sinc^2 cos theta_o, as fractions of the propagating orders' sum; normal light).

  am3_band.py profile DIR/heights.exr     where each wavelength's power goes, in rings of sin theta
                                           (and how much of it beyond 0.5 is an alias: an order
                                           outside the FFT's own band |m|, |n| <= N/2)
  am3_band.py crosstab DIR/heights.exr    per FFT bin: where its light lands at 0.41 and at 0.69 um,
                                           and which bins put light outside the annulus at 0.69 um
  am3_band.py response DIR/heights.exr STEP
                                           the power, per wavelength, of the FFT bins that fill rings 3-4
                                           at 0.41 um, beside a two-level grating of step 2 STEP
                                           (1 - cos(2 pi 2 STEP 2 / lambda), scaled to agree at 0.41 um)
  am3_band.py score DIR/heights.exr ...   the acceptance's metrics over 16 samples of 0.40-0.70 um
  am3_band.py facets N STEP CELLS SEED OUT.u8
                                           a geometric-optics relief: a jittered CELLS x CELLS grid of
                                           periodic Voronoi facets whose mirror-reflected offsets are
                                           area-uniform in the 16 bins (dealt evenly), heights wrapped
                                           onto 8 levels of STEP um; writes the levels (uint8, row-major)
                                           and prints its score
Needs the wavebrdf module (PYTHONPATH=build/python) to read heights.exr.
"""
import sys

import numpy as np

LAMBDAS = 0.40 + (np.arange(16) + 0.5) * 0.30 / 16  # --spectral 16 --band-um 0.40 0.70
EDGES = [0, 0.05, 0.1, 0.265, 0.361, 0.436, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0001]  # ring edges 0.1..0.5


def load(path):
    import wavebrdf as wb
    h = wb.Heightfield.read(path)
    return np.asarray(h.heights_um(), float).reshape(h.rows, h.cols), h.texel_um


def orders(h, texel, lam):
    N = h.shape[0]
    L = N * texel
    lv, idx = np.unique(np.round(h, 9), return_inverse=True)
    idx = idx.reshape(h.shape)
    F = np.stack([np.fft.fft2((idx == l).astype(float)) / N**2 for l in range(len(lv))], -1)
    M = int(np.floor(L / lam))
    m, n = np.meshgrid(np.arange(-M, M + 1), np.arange(-M, M + 1), indexing="ij")
    m, n = m.ravel(), n.ravel()
    dx, dy = lam * m / L, lam * n / L
    rr = dx * dx + dy * dy
    keep = rr < 1.0
    m, n, dx, dy, rr = m[keep], n[keep], dx[keep], dy[keep], rr[keep]
    cos_o = np.sqrt(1 - rr)
    env = np.sinc(m / N) ** 2 * np.sinc(n / N) ** 2 * cos_o
    A = (F[m % N, n % N] * np.exp(-1j * 2 * np.pi / lam * (1 + cos_o)[:, None] * lv[None, :])).sum(1)
    P = env * np.abs(A) ** 2
    main = (np.abs(m) <= N // 2) & (np.abs(n) <= N // 2)
    return dict(m=m, n=n, dx=dx, dy=dy, r=np.sqrt(rr), P=P / P.sum(), main=main, kirchhoff=P.sum(),
                bin=(m % N) * N + (n % N))


def score(h, texel, lams=LAMBDAS):
    reg, uni, cone = [], [], []
    a, b = 0.01, 0.25
    for lam in lams:
        o = orders(h, texel, lam)
        rr = o["r"] ** 2
        inr = (rr >= a) & (rr <= b)
        ring = np.clip((4 * (rr - a) / (b - a)).astype(int), 0, 3)
        dx, dy = o["dx"], o["dy"]
        quad = np.full(dx.shape, 3)
        quad[(dx > 0) & (dy >= 0)] = 0
        quad[(dx <= 0) & (dy > 0)] = 1
        quad[(dx < 0) & (dy <= 0)] = 2
        bins = np.bincount((ring * 4 + quad)[inr], weights=o["P"][inr], minlength=16)
        reg.append(bins.sum())
        uni.append(bins.std() / bins.mean())
        cone.append(o["P"][rr <= 0.0025].sum())
    return np.array(reg), np.array(uni), np.array(cone)


def print_score(name, h, texel):
    reg, uni, cone = score(h, texel)
    print(f"{name}: region mean {100 * reg.mean():.1f} % (worst {100 * reg.min():.1f} %), uniformity worst "
          f"{uni.max():.3f}, cone worst {100 * cone.max():.3f} %")
    print("  region % per wavelength: " + " ".join(f"{100 * x:.0f}" for x in reg))
    print("  uniformity per wavelength: " + " ".join(f"{x:.2f}" for x in uni))


def profile(path):
    h, texel = load(path)
    print("lambda  " + " ".join(f"{a:.3f}-{b:.3f}" for a, b in zip(EDGES[:-1], EDGES[1:]))
          + " | region  alias>0.5  kirchhoff")
    for lam in LAMBDAS:
        o = orders(h, texel, lam)
        cells = [((o["r"] >= a) & (o["r"] < b)) for a, b in zip(EDGES[:-1], EDGES[1:])]
        p = [o["P"][c].sum() for c in cells]
        region = sum(p[2:6])
        alias = o["P"][(o["r"] >= 0.5) & ~o["main"]].sum()
        print(f"{lam:.4f} " + " ".join(f"{100 * x:11.1f}" for x in p)
              + f" | {100 * region:5.1f}  {100 * alias:5.1f}  {o['kirchhoff']:.3f}")


def crosstab(path, short=LAMBDAS[0], long=LAMBDAS[-1]):
    h, texel = load(path)
    N = h.shape[0]

    def group(r):  # 0 inside 0.1, 1..4 the rings, 5 beyond 0.5
        a, b = 0.01, 0.25
        return np.where(r < 0.1, 0, np.where(r > 0.5, 5, 1 + np.clip((4 * (r * r - a) / (b - a)).astype(int), 0, 3)))

    def per_bin(lam):
        o = orders(h, texel, lam)
        P = np.bincount(o["bin"], weights=o["P"], minlength=N * N)
        g = np.full(N * N, 5)
        g[o["bin"][o["main"]]] = group(o["r"][o["main"]])
        out = np.bincount(o["bin"], weights=o["P"] * (o["r"] > 0.5), minlength=N * N)
        return P, g, out

    Ps, gs, _ = per_bin(short)
    Pl, _, outl = per_bin(long)
    names = ["inside 0.1", "ring 1", "ring 2", "ring 3", "ring 4", "beyond 0.5"]
    print(f"power beyond 0.5 at {long:.3f} um: {100 * outl.sum():.1f} %, by where the same FFT bins' main order "
          f"lands at {short:.3f} um:")
    for g in range(6):
        s = gs == g
        print(f"  {names[g]:10s}: {100 * outl[s].sum():5.1f} % beyond 0.5 at {long:.3f}; these bins carry "
              f"{100 * Ps[s].sum():5.1f} % of the power at {short:.3f} and {100 * Pl[s].sum():5.1f} % at {long:.3f}")
    f = np.hypot(np.fft.fftfreq(N)[:, None], np.fft.fftfreq(N)[None, :]).ravel() / texel
    lo_ok, hi_ok = 0.1 / short, 0.5 / long
    for lo, hi in [(0, lo_ok), (lo_ok, hi_ok), (hi_ok, 1.0), (1.0, 1.5)]:
        s = (f >= lo) & (f < hi)
        print(f"  bins with |f| in [{lo:.3f}, {hi:.3f}) per um: {100 * Ps[s].sum():5.1f} % of the power at "
              f"{short:.3f}, {100 * Pl[s].sum():5.1f} % at {long:.3f}")


def response(path, step):
    h, texel = load(path)
    N = h.shape[0]
    f = np.hypot(np.fft.fftfreq(N)[:, None], np.fft.fftfreq(N)[None, :]).ravel() / texel
    sel = (f * LAMBDAS[0] >= 0.361) & (f * LAMBDAS[0] < 0.5)  # rings 3-4 at the short end
    power = []
    for lam in LAMBDAS:
        o = orders(h, texel, lam)
        power.append(np.bincount(o["bin"], weights=o["P"], minlength=N * N)[sel].sum())
    power = np.array(power)
    pair = 1 - np.cos(2 * np.pi * 2 * step * 2 / LAMBDAS)
    pair *= power[0] / pair[0]
    print(f"{path}: power % of the bins with 0.361 <= 0.409 |f| < 0.5, per wavelength " +
          " ".join(f"{x:.3f}" for x in LAMBDAS))
    print("  design:       " + " ".join(f"{100 * x:5.1f}" for x in power))
    print("  2-step grating: " + " ".join(f"{100 * x:5.1f}" for x in pair))


def facets(N, step, cells, seed, K=8, texel=0.5, r1=0.1, r2=0.5):
    rng = np.random.default_rng(seed)
    L = N * texel
    size = L / cells
    nb = cells * cells
    c = (np.stack(np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij"), -1).reshape(-1, 2)
         + rng.uniform(0.25, 0.75, (nb, 2))) * size
    binid = rng.permutation(np.arange(nb) % 16)
    ring, quad = binid // 4, binid % 4
    a, b = r1 * r1, r2 * r2
    s = np.sqrt(a + (ring + rng.uniform(0, 1, nb)) * (b - a) / 4)
    phi = (quad + rng.uniform(0, 1, nb)) * np.pi / 2
    tilt = np.tan(np.arcsin(s) / 2)  # the mirror about a normal tilted by t sends light to 2t
    g = -tilt[:, None] * np.stack([np.cos(phi), np.sin(phi)], 1)
    x = (np.arange(N) + 0.5) * texel
    X, Y = np.meshgrid(x, x, indexing="ij")
    best = np.full((N, N), np.inf)
    h = np.zeros((N, N))
    for i in range(nb):
        ddx = (X - c[i, 0] + L / 2) % L - L / 2
        ddy = (Y - c[i, 1] + L / 2) % L - L / 2
        d = ddx**2 + ddy**2
        sel = d < best
        best[sel] = d[sel]
        h[sel] = (g[i, 0] * ddx + g[i, 1] * ddy)[sel] + rng.uniform(0, K * step)
    return (np.floor(np.mod(h, K * step) / step).astype(int) % K).astype(np.uint8)


def main():
    cmd = sys.argv[1]
    if cmd == "profile":
        profile(sys.argv[2])
    elif cmd == "crosstab":
        crosstab(sys.argv[2])
    elif cmd == "response":
        response(sys.argv[2], float(sys.argv[3]))
    elif cmd == "score":
        for p in sys.argv[2:]:
            print_score(p, *load(p))
    elif cmd == "facets":
        N, step, cells, seed, out = int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
        lv = facets(N, step, cells, seed)
        lv.tofile(out)
        print_score(f"facets {N}^2, step {step} um, {cells}x{cells} cells, seed {seed}", lv * step, 0.5)
    else:
        sys.exit(f"unknown command '{cmd}'; expected profile, crosstab, response, score or facets")


if __name__ == "__main__":
    main()
