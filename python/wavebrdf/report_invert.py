"""Pictures of an inversion written by `wavebrdf invert --out DIR` (draw them with
`python3 -m wavebrdf.report DIR`, see wavebrdf.report).

make_report(DIR) writes DIR/report.png (like the thesis's Figure 5.1: truth, reference, and per
snapshot epoch the estimated slice, its squared error, the heightfield hypothesis and the
gradient); make_curves(DIR) writes DIR/curves.png (like Figure 5.3: every metric normalised by
its epoch-0 value, log scale).

DIR layout (see the C++ side): run.json, metrics.csv, reference.npy, truth_height.npy
(optional), snapshots/{height,slice,gradient}_EEEE.npy. Missing or unreadable optional files
leave an empty, labelled panel instead of failing; make_curves raises FileNotFoundError when
metrics.csv is missing.

Slice pixel (row i, column j) is ω_o = ((i+½)/n·2−1, (j+½)/n·2−1): rows run down (ω_o,x),
columns right (ω_o,y). Heightfield row i is the surface coordinate x, column j is y.
"""
import csv
import json
import math
import os
import textwrap
import re
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import LogNorm, Normalize  # noqa: E402

from .report import save_figure  # noqa: E402

DPI = 110
METRIC_LABELS = {
    "loss": "loss (objective)",
    "brdf_mse": "BRDF MSE",
    "cmsle_1": "CMSLE, ε = 1",
    "cmsle_0.001": "CMSLE, ε = 0.001",
    "rgb_mse": "RGB MSE",
    "rgb_gamma_mse": "RGB MSE, γ = 2.2",
    "height_mse": "height MSE (vs. truth)",
}
NOT_METRICS = ("epoch", "seconds")
SNAPSHOT_RE = re.compile(r"^(height|slice|gradient)_(\d+)\.npy$")


# ----------------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------------
def _warn(msg):
    print("wavebrdf.report: warning: " + msg, file=sys.stderr)


def _load_npy(path):
    """The array at `path`, or None when it is missing or unreadable (e.g. a torn write)."""
    if not os.path.isfile(path):
        return None
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as e:
        _warn("cannot read %s: %s" % (path, e))
        return None


def _load_run(d):
    path = os.path.join(d, "run.json")
    if not os.path.isfile(path):
        return {}
    try:
        with open(path, encoding="utf-8") as f:
            run = json.load(f)
        return run if isinstance(run, dict) else {}
    except (OSError, ValueError) as e:
        _warn("cannot read %s: %s" % (path, e))
        return {}


def _title(run, d):
    t = run.get("title")
    return str(t) if t else os.path.basename(os.path.normpath(os.path.abspath(d)))


def _snapshot_epochs(d):
    """Every epoch with at least one snapshot file (an interrupted run has only some of the
    run.json's snapshot_epochs; files are what counts)."""
    sdir = os.path.join(d, "snapshots")
    found = set()
    if os.path.isdir(sdir):
        for name in os.listdir(sdir):
            m = SNAPSHOT_RE.match(name)
            if m:
                found.add(int(m.group(2)))
    return sorted(found)


# The most snapshot rows one report draws: each row is ~260 px tall, so 300 snapshots made an
# image too large to save (77803 px). More are thinned to this many, first and last kept.
MAX_SNAPSHOT_ROWS = 12


def _drawn_epochs(epochs):
    """At most MAX_SNAPSHOT_ROWS of `epochs`, evenly spread, the first and the last kept."""
    if len(epochs) <= MAX_SNAPSHOT_ROWS:
        return epochs
    last = len(epochs) - 1
    picks = sorted({round(k * last / (MAX_SNAPSHOT_ROWS - 1)) for k in range(MAX_SNAPSHOT_ROWS)})
    return [epochs[i] for i in picks]


def _snapshot_path(d, kind, epoch):
    return os.path.join(d, "snapshots", "%s_%04d.npy" % (kind, epoch))


def read_metrics(d):
    """metrics.csv as (columns, {column: float array}); rows that do not parse are skipped
    (an interrupted run may leave a partial last line)."""
    path = os.path.join(d, "metrics.csv")
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows:
        return [], {}
    header = [h.strip() for h in rows[0]]
    data = []
    for r in rows[1:]:
        if len(r) != len(header):
            continue
        try:
            data.append([float(v) if v.strip() else math.nan for v in r])
        except ValueError:
            continue
    arr = np.array(data, dtype=float).reshape(len(data), len(header))
    return header, {h: arr[:, k] for k, h in enumerate(header)}


# ----------------------------------------------------------------------------------------------
# Display helpers
# ----------------------------------------------------------------------------------------------
def _as_hwc(s):
    s = np.asarray(s, dtype=float)
    if s.ndim == 2:
        s = s[:, :, None]
    return np.nan_to_num(s, nan=0.0, posinf=0.0, neginf=0.0)


def tonemap_scale(reference):
    """The exposure that maps the reference's 99.9th percentile to 4."""
    if reference is None:
        return 1.0
    ref = _as_hwc(reference)
    p = float(np.percentile(ref, 99.9)) if ref.size else 0.0
    if not p > 0:
        p = float(ref.max()) if ref.size else 0.0
    return 4.0 / p if p > 0 else 1.0


def tonemap(s, scale):
    """Reinhard x/(1+x) after exposure, then gamma 1/2.2; an (h, w) image for one channel,
    (h, w, 3) for three, the channel mean otherwise."""
    x = np.clip(_as_hwc(s) * scale, 0.0, None)
    y = (x / (1.0 + x)) ** (1.0 / 2.2)
    if y.shape[2] == 3:
        return y
    return y.mean(axis=2) if y.shape[2] > 1 else y[:, :, 0]


def squared_error(est, ref):
    e, r = _as_hwc(est), _as_hwc(ref)
    if e.shape != r.shape:
        return None
    return ((e - r) ** 2).sum(axis=2)


def _missing(ax, what):
    ax.set_facecolor("#eeeeee")
    ax.set_box_aspect(1)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.text(0.5, 0.5, what, ha="center", va="center", transform=ax.transAxes, color="#777777",
            fontsize=9)


def _corner(ax, text):
    ax.text(0.03, 0.97, text, ha="left", va="top", transform=ax.transAxes, fontsize=7.5,
            color="white", bbox=dict(boxstyle="round,pad=0.2", fc="black", alpha=0.55, lw=0))


def _height_extent(h, texel_um):
    rows, cols = h.shape[:2]
    return [0.0, cols * texel_um, rows * texel_um, 0.0]


SLICE_EXTENT = [-1.0, 1.0, 1.0, -1.0]  # row i downward = ω_o,x from −1 to 1; columns = ω_o,y


# ----------------------------------------------------------------------------------------------
# Output
# ----------------------------------------------------------------------------------------------
def _save_atomic(fig, path):
    return save_figure(fig, path, DPI)


def make_report(d):
    """Writes d/report.png (Figure 5.1 style) and returns its path."""
    run = _load_run(d)
    texel_um = float(run.get("texel_um") or 1.0)
    hunit = "µm" if run.get("texel_um") else "texels"
    truth = _load_npy(os.path.join(d, "truth_height.npy"))
    reference = _load_npy(os.path.join(d, "reference.npy"))
    epochs = _drawn_epochs(_snapshot_epochs(d))
    snaps = [{k: _load_npy(_snapshot_path(d, k, e)) for k in ("slice", "height", "gradient")}
             for e in epochs]
    scale = tonemap_scale(reference)

    # Shared colour limits.
    heights = [s["height"] for s in snaps if s["height"] is not None]
    if truth is not None:
        hmax = float(np.nanmax(np.abs(truth))) if truth.size else 0.0
    else:
        hmax = max([float(np.nanmax(np.abs(h))) for h in heights if h.size] or [0.0])
    hmax = hmax if hmax > 0 and math.isfinite(hmax) else 1.0
    hnorm = Normalize(-hmax, hmax)
    errors = [squared_error(s["slice"], reference) if s["slice"] is not None and reference is not None
              else None for s in snaps]
    emax = max([float(e.max()) for e in errors if e is not None and e.size] or [0.0])
    if not (emax > 0 and math.isfinite(emax)):
        emax = 1.0
    positive = np.concatenate([e[e > 0].ravel() for e in errors if e is not None] or [np.zeros(0)])
    emin = max(float(np.percentile(positive, 1)) if positive.size else 0.0, emax * 1e-6)
    if not emin < emax:
        emin = emax * 1e-6
    enorm = LogNorm(emin, emax, clip=True)
    ecmap = plt.get_cmap("magma").copy()

    ncols = max(len(epochs), 2)
    nrows = 5 if epochs else 1
    panel = 2.35
    fig = plt.figure(figsize=(1.0 + panel * ncols + 1.3, 0.5 + nrows * (panel + 0.25)),
                     layout="constrained")
    fig.get_layout_engine().set(h_pad=0.04, w_pad=0.04, hspace=0.02, wspace=0.02)
    gs = fig.add_gridspec(nrows, ncols)
    axes = [[fig.add_subplot(gs[r, c]) for c in range(ncols)] for r in range(nrows)]
    fig.suptitle(_title(run, d), fontsize=13, fontweight="bold")

    def label_axes(ax, row_label, kind, first):
        if first:
            if kind == "slice":
                ax.set_xticks([-1, -0.5, 0, 0.5, 1])
                ax.set_yticks([-1, -0.5, 0, 0.5, 1])
                ax.set_ylabel("%s\nω$_{o,x}$" % row_label)
                ax.set_xlabel("ω$_{o,y}$", labelpad=1)
            else:
                ax.set_ylabel("%s\nx (%s)" % (row_label, hunit))
                ax.set_xlabel("y (%s)" % hunit, labelpad=1)
            ax.tick_params(labelsize=7.5)
        else:
            ax.set_xticks([])
            ax.set_yticks([])

    def show_height(ax, h, first, row_label):
        im = ax.imshow(np.nan_to_num(h), cmap="RdBu_r", norm=hnorm, extent=_height_extent(h, texel_um),
                       interpolation="nearest")
        label_axes(ax, row_label, "height", first)
        return im

    def show_slice(ax, s, first, row_label):
        img = tonemap(s, scale)
        kw = dict(cmap="gray", vmin=0.0, vmax=1.0) if img.ndim == 2 else {}
        ax.imshow(img, extent=SLICE_EXTENT, interpolation="nearest", **kw)
        label_axes(ax, row_label, "slice", first)

    # Top row: (a) truth, (b) reference, then a short run summary.
    top = axes[0]
    ta, tb = top[0], top[1]
    if truth is not None:
        truth_im = show_height(ta, truth, True, "")
        ta.set_ylabel("x (%s)" % hunit)
    else:
        truth_im = None
        _missing(ta, "no ground truth known")
    ta.set_title("(a) ground-truth heightfield", fontsize=10)
    if reference is not None:
        show_slice(tb, reference, False, "")
        tb.set_xlabel("ω$_{o,y}$", labelpad=1)
        tb.set_xticks([-1, 0, 1])
        tb.tick_params(labelsize=7.5)
    else:
        _missing(tb, "reference.npy missing")
    tb.set_title("(b) reference slice", fontsize=10)
    for ax in top[2:]:
        ax.axis("off")
    info = []
    n = run.get("resolution")
    ch = run.get("channels")
    if n:
        info.append("slice %s×%s, %s" % (n, n, {1: "mono", 3: "linear sRGB"}.get(ch, "%s ch" % ch)))
    if heights or truth is not None:
        h0 = truth if truth is not None else heights[0]
        info.append("heightfield %d×%d texels" % h0.shape[:2])
    if run.get("texel_um"):
        info.append("texel %g µm" % texel_um)
    info.append("tonemap: Reinhard, p99.9 of ref → 4, γ 1/2.2")
    if epochs:
        info.append("snapshots: epochs %s" % ", ".join(str(e) for e in epochs))
    else:
        info.append("no snapshots found")
    if ncols > 2:
        t = top[2].text(0.0, 0.9, "\n".join(info), transform=top[2].transAxes, va="top", ha="left",
                        fontsize=9, linespacing=1.6)
        t.set_in_layout(False)
    elif not epochs:
        fig.supxlabel("no snapshots found", fontsize=10, color="#777777")

    row_labels = ["(c) estimated slice", "(d) squared error", "(e) heightfield", "(f) gradient"]
    last_e = last_h = last_g = None
    for c in range(ncols if epochs else 0):
        col = [axes[r][c] for r in range(1, 5)]
        if c >= len(epochs):
            for ax in col:
                ax.axis("off")
            continue
        s, e, first = snaps[c], epochs[c], c == 0
        col[0].set_title("epoch %d" % e, fontsize=10, fontweight="bold")
        # (c) estimate
        if s["slice"] is not None:
            show_slice(col[0], s["slice"], first, row_labels[0])
        else:
            _missing(col[0], "slice missing")
            if first:
                col[0].set_ylabel(row_labels[0])
        # (d) squared error
        err = errors[c]
        if err is not None:
            last_e = col[1].imshow(np.clip(err, emin, emax), cmap=ecmap, norm=enorm, extent=SLICE_EXTENT,
                                   interpolation="nearest")
            label_axes(col[1], row_labels[1], "slice", first)
            _corner(col[1], "mean %.2e" % float(err.mean()))
        else:
            _missing(col[1], "slice missing" if s["slice"] is None else
                     ("no reference" if reference is None else "shape mismatch"))
            if first:
                col[1].set_ylabel(row_labels[1])
        # (e) heightfield hypothesis
        h = s["height"]
        if h is not None:
            last_h = show_height(col[2], h, first, row_labels[2])
            if truth is not None and truth.shape == h.shape:
                _corner(col[2], "rms err %.3g %s" % (float(np.sqrt(np.mean((h - truth) ** 2))), hunit))
            else:
                _corner(col[2], "rms %.3g %s" % (float(np.sqrt(np.mean(h ** 2))), hunit))
        else:
            _missing(col[2], "heightfield missing")
            if first:
                col[2].set_ylabel(row_labels[2])
        # (f) gradient, each normalised by its own max |g|
        g = s["gradient"]
        if g is not None:
            g = np.nan_to_num(np.asarray(g, dtype=float))
            gmax = float(np.abs(g).max()) if g.size else 0.0
            last_g = col[3].imshow(g / gmax if gmax > 0 else g, cmap="PuOr_r", vmin=-1.0, vmax=1.0,
                                   extent=_height_extent(g, texel_um), interpolation="nearest")
            label_axes(col[3], row_labels[3], "height", first)
            _corner(col[3], "max |g| %.2e" % gmax)
        else:
            _missing(col[3], "gradient missing")
            if first:
                col[3].set_ylabel(row_labels[3])

    def row_colorbar(im, row, label, **kw):
        if im is None:
            return
        cb = fig.colorbar(im, ax=axes[row], shrink=0.9, pad=0.01, aspect=15, **kw)
        cb.set_label(label, fontsize=8)
        cb.ax.tick_params(labelsize=7)

    row_colorbar(truth_im, 0, "(a) height (%s)" % hunit, extend="both")
    row_colorbar(last_e, 2, "Σ$_{ch}$ (est − ref)²")
    row_colorbar(last_h, 3, "height (%s)" % hunit, extend="both")
    row_colorbar(last_g, 4, "∂loss/∂h ÷ max |∂loss/∂h|")
    return _save_atomic(fig, os.path.join(d, "report.png"))


def make_curves(d):
    """Writes d/curves.png (Figure 5.3 style) and returns its path. Raises FileNotFoundError
    when d/metrics.csv is missing."""
    run = _load_run(d)
    header, cols = read_metrics(d)
    fig, ax = plt.subplots(figsize=(8.0, 5.2), layout="constrained")
    # The curves figure is narrower than the report: wrap long titles instead of cutting them.
    ax.set_title("\n".join(textwrap.wrap(_title(run, d), 70)), fontsize=11, fontweight="bold")
    ax.set_xlabel("epoch")
    ax.set_ylabel("metric / metric at epoch 0")
    ax.set_yscale("log")
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)
    plotted = 0
    if "epoch" in cols and len(cols["epoch"]):
        epoch = cols["epoch"]
        order = np.argsort(epoch, kind="stable")
        epoch = epoch[order]
        base_row = np.flatnonzero(epoch == 0)
        base_row = int(base_row[0]) if base_row.size else 0
        names = [h for h in header if h not in NOT_METRICS]
        styles = ["-", "--", "-.", ":"]
        for k, name in enumerate(names):
            v = cols[name][order]
            base = v[base_row]
            if not (math.isfinite(base) and base != 0):
                continue
            rel = v / base
            ok = np.isfinite(rel) & (rel > 0)
            if not ok.any():
                continue
            label = "%s  (epoch 0: %.3g)" % (METRIC_LABELS.get(name, name), base)
            marker = "o" if ok.sum() <= 20 else None
            if name == "loss":
                # Thick and translucent underneath: the objective usually coincides with one of
                # the metrics (CMSLE ε = 1 by default), which stays visible on top of it.
                ax.plot(epoch[ok], rel[ok], "-", color="0.25", lw=5, alpha=0.35, label=label,
                        marker=marker, ms=6, zorder=1)
            else:
                ax.plot(epoch[ok], rel[ok], styles[k % len(styles)], lw=1.6, label=label,
                        marker=marker, ms=3, zorder=2)
            plotted += 1
        if len(epoch) > 1 and epoch[-1] > epoch[0]:
            ax.set_xlim(epoch[0], epoch[-1])
    if plotted:
        ax.legend(fontsize=9, loc="best", framealpha=0.9)
    else:
        ax.text(0.5, 0.5, "no metrics to plot yet", ha="center", va="center", transform=ax.transAxes,
                color="#777777")
        ax.set_yscale("linear")
    return _save_atomic(fig, os.path.join(d, "curves.png"))

