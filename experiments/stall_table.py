#!/usr/bin/env python3
"""Round 10 (experiments/2026-11-23-position-calibration.md): the stall table from
recover_study ... stall_diag=1 save=PREFIX (PREFIX_positions.csv). Usage: stall_table.py PREFIX"""
import sys

import numpy as np

d = np.genfromtxt(sys.argv[1] + "_positions.csv", delimiter=",", names=True)
ef = d["err_found"]
n = len(ef)


def rms(v):
    return float(np.sqrt(np.mean(np.square(v)))) if len(v) else float("nan")


print(f"positions {n}: offset error rms (per coordinate) {rms(ef) / np.sqrt(2):.4f} texel, "
      f"registered {rms(d['err_reg']) / np.sqrt(2):.4f}, Newton point {rms(d['newton_err']) / np.sqrt(2):.4f}")
print("(a) by distance of the stated centre to the border (texels)")
print("| edge distance | positions | error rms (texel, per coord) | max |")
for lo, hi in [(0, 2), (2, 4), (4, 8), (8, 100)]:
    m = (d["edge_texels"] >= lo) & (d["edge_texels"] < hi)
    if m.any():
        print(f"| [{lo}, {hi}) | {m.sum()} | {rms(ef[m]) / np.sqrt(2):.4f} | {ef[m].max():.3f} |")
print("(b) by the Hessian's smaller eigenvalue (quartiles) and condition")
q = np.quantile(d["lmin"], [0, 0.25, 0.5, 0.75, 1])
print("| lmin quartile | lmin range | cond median | error rms | registered error rms |")
for k in range(4):
    m = (d["lmin"] >= q[k]) & (d["lmin"] <= q[k + 1])
    cond = d["lmax"][m] / np.maximum(d["lmin"][m], 1e-300)
    print(f"| {k + 1} | {q[k]:.3g}–{q[k + 1]:.3g} | {np.median(cond):.2f} | {rms(ef[m]) / np.sqrt(2):.4f} | "
          f"{rms(d['err_reg'][m]) / np.sqrt(2):.4f} |")
print(f"corr(error, 1/sqrt(lmin)) = {np.corrcoef(ef, 1 / np.sqrt(np.maximum(d['lmin'], 1e-30)))[0, 1]:.3f}; "
      f"corr(error, edge) = {np.corrcoef(ef, d['edge_texels'])[0, 1]:.3f}; negative lmin: {(d['lmin'] <= 0).sum()}")
print("(c) loss at the found, true, registered offsets")
for name, a, b in [("final heights: true − found", "lf_true", "lf_found"),
                   ("final heights: registered − found", "lf_reg", "lf_found"),
                   ("true heights: true − found", "lt_true", "lt_found")]:
    diff = d[a] - d[b]
    print(f"| {name} | sum {diff.sum():.4e} (rel. {diff.sum() / d[b].sum():+.3%}) | lower at {(diff < 0).sum()}/{n} |")
print(f"sums: final heights found {d['lf_found'].sum():.5e} true {d['lf_true'].sum():.5e} "
      f"registered {d['lf_reg'].sum():.5e}; true heights found {d['lt_found'].sum():.5e} true {d['lt_true'].sum():.5e}")
# Large-error positions: which class do they belong to?
order = np.argsort(-ef)[:10]
print("worst 10: p edge err_found err_reg lmin cond lf_true-lf_found (rel)")
for p in order:
    print(f"  {int(d['p'][p])} {d['edge_texels'][p]:.1f} {ef[p]:.3f} {d['err_reg'][p]:.3f} {d['lmin'][p]:.3g} "
          f"{d['lmax'][p] / max(d['lmin'][p], 1e-300):.2f} {(d['lf_true'][p] - d['lf_found'][p]) / d['lf_found'][p]:+.3%}")
# Share of the squared error held by the worst 10 %.
s = np.sort(ef ** 2)[::-1]
print(f"worst 10% of positions hold {s[: max(1, n // 10)].sum() / s.sum():.1%} of the squared error")
