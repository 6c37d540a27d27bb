"""Pictures of a heightfield recovery written by `wavebrdf recover --out DIR` (draw them with
`python3 -m wavebrdf.report DIR`, see wavebrdf.report).

make_report(DIR) writes DIR/report.png: the true heights (when known), the estimate, their
difference after removing each one's mean (the mean height is invisible to every slice), one
observation beside the estimate's slice for it, and the convergence of every stage (its loss,
normalised to the stage's first value, and height_rel_rmse when the truth is known), and with
error bars (``--uncertainty``) the map of σ per texel and, with the truth, the distribution of
error / σ against the standard normal, and with the truth the radial power spectra of the truth,
the estimate and the error (psd.csv) with the band the estimate resolves (the error's power below
the truth's).

DIR layout (recovery_directory.h): run.json, metrics.csv, estimate_height.npy,
truth_height.npy (optional), reference.npy, final.npy, uncertainty_height.npy and
uncertainty.json (optional), psd.csv (with a truth).
"""
import csv
import json
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .report import save_figure  # noqa: E402


def read_metrics(path):
    """Rows of metrics.csv grouped by stage, in file order: {stage: {column: array}}."""
    stages = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            s = stages.setdefault(row["stage"], {"iteration": [], "loss": [], "seconds": [], "height_rel_rmse": []})
            for key in s:
                s[key].append(float(row[key]))
    return {name: {k: np.array(v) for k, v in cols.items()} for name, cols in stages.items()}


def tonemap(slice_rgb):
    """Reinhard with an exposure that puts the 99.9th percentile near 4, as the CLI's PNGs."""
    v = np.clip(slice_rgb, 0.0, None)
    top = np.quantile(v, 0.999)
    scale = 4.0 / top if top > 0 else 1.0
    x = v * scale
    return np.clip((x / (1.0 + x)) ** (1.0 / 2.2), 0.0, 1.0)


def image(ax, data, title, cmap="viridis", vmin=None, vmax=None, unit="µm"):
    im = ax.imshow(data, cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    if unit:
        plt.colorbar(im, ax=ax, fraction=0.046, pad=0.04).set_label(unit, fontsize=8)


def make_report(directory):
    """Writes directory/report.png and returns its path."""
    with open(os.path.join(directory, "run.json")) as f:
        run = json.load(f)
    stages = read_metrics(os.path.join(directory, "metrics.csv"))
    estimate = np.load(os.path.join(directory, "estimate_height.npy"))
    truth_path = os.path.join(directory, "truth_height.npy")
    truth = np.load(truth_path) if os.path.exists(truth_path) else None
    reference = np.load(os.path.join(directory, "reference.npy"))
    final = np.load(os.path.join(directory, "final.npy"))

    sigma_path = os.path.join(directory, "uncertainty_height.npy")
    sigma = np.load(sigma_path) if os.path.exists(sigma_path) else None
    psd_path = os.path.join(directory, "psd.csv")
    psd = read_psd(psd_path) if os.path.exists(psd_path) else None
    columns = 4 + (sigma is not None) + (psd is not None)
    fig, axes = plt.subplots(2, columns, figsize=(4 * columns, 7.6))
    title = "wavebrdf recover ({method}): {size} heights, {observations} observations, noise {noise}, loss {loss}".format(**run)
    calibration_path = os.path.join(directory, "calibration.json")
    if os.path.exists(calibration_path):  # self-calibration (calibration.h)
        with open(calibration_path) as f:
            cal = json.load(f)
        parts = ["calibrated: " + cal.get("refined", "none")]
        if cal.get("refined", "none") != "none":
            parts.append("sigma_p scale {:.4f}".format(cal.get("sigma_p_scale", 1.0)))
        errors = cal.get("errors", {})
        if "exposure_rel_rms" in errors:
            parts.append("exposure error rms {:.2%}".format(errors["exposure_rel_rms"]))
        if "position_rms_um" in errors:
            parts.append("position error rms {:.3g} um".format(errors["position_rms_um"]))
        if "truth" in cal:
            parts.append("true sigma_p scale {:.4f}".format(cal["truth"].get("sigma_p_scale", 1.0)))
        title += "\n" + ", ".join(parts)
    fig.suptitle(title, fontsize=11)

    est = estimate - estimate.mean()
    if truth is not None:
        tru = truth - truth.mean()
        lo, hi = float(min(tru.min(), est.min())), float(max(tru.max(), est.max()))
        image(axes[0, 0], tru, "truth (mean removed)", vmin=lo, vmax=hi)
        image(axes[0, 1], est, "estimate (mean removed)", vmin=lo, vmax=hi)
        err = est - tru
        bound = float(np.abs(err).max()) or 1.0
        rel = np.sqrt(np.mean(err**2)) / (truth.max() - truth.min())
        image(axes[0, 2], err, "estimate − truth: rel. RMSE {:.2%}".format(rel), cmap="RdBu_r", vmin=-bound, vmax=bound)
    else:
        image(axes[0, 0], est, "estimate (mean removed)")
        axes[0, 1].axis("off")
        axes[0, 2].axis("off")

    # Slices: mono slices are (n, n, 1).
    def rgb(s):
        return np.repeat(s, 3, axis=2) if s.shape[2] == 1 else s

    image(axes[0, 3], tonemap(rgb(reference)), "observation 0", unit=None)
    image(axes[1, 3], tonemap(rgb(final)), "estimate's slice for it", unit=None)

    # Convergence: each stage's loss relative to its first value, one after another.
    ax = axes[1, 0]
    offset = 0
    for name, s in stages.items():
        if not (s["loss"] > 0).any():
            continue  # stages without a loss of their own (the summary rows "blur", "unwrap")
        it = s["iteration"] + offset
        loss = s["loss"] / s["loss"][0] if s["loss"][0] > 0 else s["loss"]
        ax.semilogy(it, np.clip(loss, 1e-16, None), label=name)
        offset = it[-1] if len(it) else offset
    ax.set_xlabel("iteration (stages one after another)")
    ax.set_ylabel("loss / stage's first")
    ax.set_title("loss per stage", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[1, 1]
    if truth is not None:
        for name, s in stages.items():
            ok = s["height_rel_rmse"] >= 0
            if ok.any():
                # Markers: several stages report a single value (the end of the blurred fit,
                # the unwrapped heights).
                ax.semilogy(s["seconds"][ok], s["height_rel_rmse"][ok], "o-", ms=3, label=name)
        ax.axhline(0.01, color="k", ls="--", lw=0.8, label="1 %")
        ax.set_xlabel("seconds")
        ax.set_ylabel("height_rel_rmse")
        ax.set_title("height error", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    else:
        ax.axis("off")

    ax = axes[1, 2]
    ax.axis("off")
    lines = ["plan:"] + ["  " + n for n in run.get("plan", [])]
    if run.get("warnings"):
        lines += ["warnings:"] + ["  " + w for w in run["warnings"]]
    ax.text(0.0, 1.0, "\n".join(_wrap(l, 60) for l in lines), va="top", ha="left", fontsize=7, family="monospace")

    if sigma is not None:
        summary = {}
        summary_path = os.path.join(directory, "uncertainty.json")
        if os.path.exists(summary_path):
            with open(summary_path) as f:
                summary = json.load(f)
        image(axes[0, 4], sigma, "uncertainty σ: median {:.3g} µm".format(float(np.median(sigma))), cmap="magma",
              vmin=0.0)
        ax = axes[1, 4]
        if truth is not None:
            z = ((est - tru) / np.where(sigma > 0, sigma, np.nan)).ravel()
            z = z[np.isfinite(z)]
            ax.hist(np.clip(z, -5, 5), bins=41, range=(-5, 5), density=True, alpha=0.7, label="error / σ")
            x = np.linspace(-5, 5, 201)
            ax.plot(x, np.exp(-0.5 * x**2) / np.sqrt(2 * np.pi), "k-", lw=1, label="N(0, 1)")
            inside = summary.get("coverage_2sigma", float(np.mean(np.abs(z) <= 2)))
            ax.set_title("error / σ: {:.1%} within ±2σ".format(inside), fontsize=9)
            ax.set_xlabel("(estimate − truth) / σ")
            ax.legend(fontsize=7)
        else:
            ax.hist(sigma.ravel(), bins=40)
            ax.set_title("σ per texel", fontsize=9)
            ax.set_xlabel("µm")

    if psd is not None:
        q = psd["q_per_um"]
        summary = run.get("psd", {})
        ax = axes[0, columns - 1]
        for key, label in (("truth_psd_um4", "truth"), ("estimate_psd_um4", "estimate"),
                           ("error_psd_um4", "estimate − truth")):
            ax.loglog(q, np.clip(psd[key], 1e-300, None), label=label)
        resolved = summary.get("resolved_q_per_um", 0.0)
        if resolved > 0 and not summary.get("resolved_all", False):
            ax.axvline(resolved, color="k", ls="--", lw=0.8, label="resolved to {:.3g} µm".format(2 * np.pi / resolved))
        ax.set_xlabel("q (rad/µm)")
        ax.set_ylabel("radial PSD (µm⁴)")
        ax.set_title("power spectra", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        ax = axes[1, columns - 1]
        ok = psd["truth_psd_um4"] > 0
        ax.loglog(q[ok], np.clip(psd["error_psd_um4"][ok] / psd["truth_psd_um4"][ok], 1e-300, None), "o-", ms=2)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_xlabel("q (rad/µm)")
        ax.set_ylabel("error PSD / truth PSD")
        ax.set_title("error's share of the power: {:.3g}".format(summary.get("error_power_ratio", float("nan"))),
                     fontsize=9)
        ax.grid(True, which="both", alpha=0.3)

    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save_figure(fig, os.path.join(directory, "report.png"), 110)


def read_psd(path):
    """psd.csv (recovery_directory.h) as {column: float64 array}."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    names = ("q_per_um", "truth_psd_um4", "estimate_psd_um4", "error_psd_um4", "count")
    return {n: np.array([float(r[n]) for r in rows]) for n in names}


def _wrap(text, width):
    words, lines, line = text.split(" "), [], ""
    for w in words:
        if len(line) + len(w) + 1 > width and line:
            lines.append(line)
            line = "    " + w
        else:
            line = (line + " " + w) if line else w
    lines.append(line)
    return "\n".join(lines)

