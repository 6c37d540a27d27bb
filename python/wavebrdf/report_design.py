"""Pictures of a surface design written by `wavebrdf design --out DIR` (draw them with
`python3 -m wavebrdf.report DIR`, see wavebrdf.report).

make_report(DIR) writes DIR/report.png: the target beside the achieved far field (linear and
log), the colour swatches target / achieved when the target is a colour (with a line on the
brightness trade when its blocks ran), the height map with
its level histogram, the loss curve, the metrics under the design model, under exact scalar
diffraction and under each fabrication error, and, when design.json has `warnings` (a limit the
exported relief still breaks, ...), a panel along the bottom that lists them.

DIR layout (docs/design.md): design.json (required: target, constraints, levels_um, metrics
{model, exact, ...}, fabrication_errors [{error, metrics}], notes), heights.exr (µm = value ·
texel_um · vscale), target.exr and far_field.exr (linear RGB pictures over the window about the
mirror direction), metrics.csv (iteration, loss, phase, ...). Everything but design.json is
optional: a missing file leaves its panel saying so. A file that is there but unreadable raises
ReportError naming it (the report's command prints one line and exits 2).
"""
import csv
import json
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .report import save_figure  # noqa: E402


class ReportError(ValueError):
    """A run directory file that is there but cannot be used; the message names it."""


def read_design_json(directory):
    """design.json as a dict; ReportError when it is missing, not JSON or not an object."""
    path = os.path.join(directory, "design.json")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except FileNotFoundError:
        raise ReportError("missing %s (design.json is written last: did the run finish?)" % path) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ReportError("%s: cannot be read as JSON (%s)" % (path, e)) from None
    if not isinstance(doc, dict):
        raise ReportError("%s: expected a JSON object, found %s" % (path, type(doc).__name__))
    return doc


def read_loss_curve(directory):
    """metrics.csv as {column: float array} (None when absent); ReportError when malformed."""
    path = os.path.join(directory, "metrics.csv")
    if not os.path.exists(path):
        return None
    columns = {}
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            if not reader.fieldnames or "iteration" not in reader.fieldnames or "loss" not in reader.fieldnames:
                raise ReportError("%s: expected the columns iteration,loss,...; found %s" % (path, reader.fieldnames))
            names = list(reader.fieldnames)
            for name in names:
                columns[name] = []
            for line, row in enumerate(reader, start=2):
                for name in names:
                    value = row.get(name)
                    if name == "phase":
                        columns[name].append(value or "")
                        continue
                    try:
                        columns[name].append(float(value))
                    except (TypeError, ValueError):
                        raise ReportError("%s: line %d: %s = %r is not a number" % (path, line, name, value)) from None
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise ReportError("%s: cannot be read (%s)" % (path, e)) from None
    return {k: (np.array(v) if k != "phase" else v) for k, v in columns.items()}


def _read_exr(directory, name, reader):
    path = os.path.join(directory, name)
    if not os.path.exists(path):
        return None
    try:
        return reader(path)
    except (RuntimeError, ValueError, OSError) as e:
        raise ReportError("%s: cannot be read (%s)" % (path, str(e).splitlines()[0] if str(e) else e)) from None


def read_picture(directory, name):
    """An RGB EXR of the run as a float array (n, n, 3), None when absent."""
    from . import _core

    return _read_exr(directory, name, lambda p: np.asarray(_core.read_slice(p)[0], dtype=np.float64))


def read_heights_um(directory):
    """heights.exr in µm (values · texel_um · vscale), None when absent."""
    from . import _core

    def read(path):
        hf = _core.Heightfield.from_exr(path)
        return np.array(hf.values, dtype=np.float64) * hf.texel_um * hf.vscale

    return _read_exr(directory, "heights.exr", read)


def _get(doc, *keys, default=None):
    """doc[k0][k1]... or default when any level is absent or not a dict."""
    for k in keys:
        if not isinstance(doc, dict) or k not in doc:
            return default
        doc = doc[k]
    return doc


def linear_to_srgb(rgb):
    """Linear sRGB (any scale) to display sRGB in [0, 1], normalised so the largest channel is 1:
    a swatch shows chromaticity and relative brightness of the channels, not absolute level."""
    c = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, None)
    top = c.max()
    if not top > 0:
        return np.zeros(3)
    c = c / top
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def _picture_axes(ax, picture, title, extent, log=False, rgb_ok=True):
    """A far-field picture: RGB when it has colour, else its luminance with a colour bar."""
    if picture is None:
        ax.text(0.5, 0.5, title + "\n(not in the run)", ha="center", va="center", fontsize=8)
        ax.axis("off")
        return
    grey = np.allclose(picture[..., 0], picture[..., 1]) and np.allclose(picture[..., 0], picture[..., 2])
    lum = picture[..., 0] if grey else picture @ np.array([0.2126, 0.7152, 0.0722])
    kw = {"interpolation": "nearest", "origin": "upper"}
    if extent is not None:
        kw["extent"] = (-extent, extent, extent, -extent)  # columns: Δω_y, rows: Δω_x
    if log:
        top = float(lum.max())
        floor = top * 1e-6 if top > 0 else 1.0
        im = ax.imshow(np.log10(np.clip(lum, floor, None)), cmap="magma", **kw)
        plt.colorbar(im, ax=ax, fraction=0.046, pad=0.04).set_label("log10", fontsize=7)
    elif not grey and rgb_ok:
        top = float(np.quantile(picture, 0.999)) or float(picture.max()) or 1.0
        ax.imshow(np.clip(picture / top, 0.0, 1.0) ** (1 / 2.2), **kw)
    else:
        im = ax.imshow(lum, cmap="viridis", vmin=0.0, **kw)
        plt.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    ax.set_title(title, fontsize=9)
    if extent is not None:
        ax.set_xlabel("Δω_y", fontsize=7)
        ax.set_ylabel("Δω_x", fontsize=7)
        ax.tick_params(labelsize=6)
    else:
        ax.set_xticks([])
        ax.set_yticks([])


def _format_value(v):
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, (int, float)):
        if isinstance(v, float) and not math.isfinite(v):
            return str(v)
        return "%.4g" % v
    if isinstance(v, list):
        if v and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            if len(v) <= 3:
                return "[" + ", ".join("%.3g" % x for x in v) + "]"
            return "[%.3g … %.3g] (%d)" % (min(v), max(v), len(v))
        return "[%d items]" % len(v)
    if isinstance(v, dict):
        return "{…}"
    return str(v)


# The scalar metrics worth a row, most telling first; others follow in file order.
_PREFERRED = ("specular_fraction_worst", "specular_fraction_mean", "region_fraction_mean", "region_fraction_worst",
              "uniformity_worst", "uniformity_mean", "correlation", "efficiency", "delta_uv", "luminous_efficiency",
              "luminous_efficiency_share_of_reflected", "relative_l2")


def metrics_rows(doc):
    """(names, columns): one column per evaluation (model, exact, each fabrication error) of the
    scalar metrics of design.json; absent ones are blank. Lists of per-wavelength values are
    shown by their range."""
    columns = []
    metrics = _get(doc, "metrics", default={}) or {}
    for key, label in (("model", "design model"), ("exact", "exact scalar")):
        if isinstance(metrics.get(key), dict):
            columns.append((label, metrics[key]))
    for entry in _get(doc, "fabrication_errors", default=[]) or []:
        if isinstance(entry, dict) and isinstance(entry.get("metrics"), dict):
            columns.append((str(entry.get("error", "error")), entry["metrics"]))
    names = []
    for _, m in columns:
        for k, v in m.items():
            if k not in names and (isinstance(v, (int, float)) or isinstance(v, list)):
                names.append(k)
    order = {k: i for i, k in enumerate(names)}
    names.sort(key=lambda k: (_PREFERRED.index(k) if k in _PREFERRED else len(_PREFERRED), order[k]))
    return names, columns


def _numbers(v):
    """v as a list of numbers (a number is a list of one); None when it is neither."""
    v = v if isinstance(v, list) else [v]
    ok = v and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
    return v if ok else None


def brightness_trade_text(doc):
    """The report's line on design.json's brightness_trade (colour: one view cone, iridescent:
    values per pair), or None when no block ran: blocks, the Δu′v′ tolerance used within the
    ceiling, and the loop's Y before and after."""
    t = _get(doc, "brightness_trade")
    if not isinstance(t, dict) or not isinstance(t.get("blocks"), int) or t["blocks"] <= 0:
        return None
    tol, before, after = (_numbers(t.get(k)) for k in ("tolerance_used", "model_y_before", "model_y_after"))
    ceiling = t.get("ceiling")
    if tol is None or before is None or after is None or not isinstance(ceiling, (int, float)):
        return None
    per_pair = isinstance(t.get("tolerance_used"), list)
    join = "/".join
    return "brightness trade%s: %d block%s, Δu′v′ tolerance %s (ceiling %.3g): loop's Y %s%% → %s%%" % (
        " per pair" if per_pair else "", t["blocks"], "" if t["blocks"] == 1 else "s",
        join("%.3g" % x for x in tol), ceiling, join("%.1f" % (100 * y) for y in before),
        join("%.1f" % (100 * y) for y in after))


def warnings_lines(doc):
    """design.json's `warnings`, each as the text the report's warnings panel shows (wrapped to
    the panel's width); [] when the run has none. A value that is not a list of strings is shown
    as it is, so that a warning is never dropped for its form."""
    w = _get(doc, "warnings", default=[])
    if w in (None, []):
        return []
    items = w if isinstance(w, list) else [w]
    return [_wrap(x if isinstance(x, str) else json.dumps(x), 180) for x in items]


def survey_points(doc):
    """The anti-mirror's level-step survey (design.json step_survey) as (step µm, region band mean,
    limits met) triples, in the file's order; [] where the run has none."""
    points = []
    for entry in _get(doc, "step_survey", "steps", default=[]) or []:
        step, region = _get(entry, "step_um"), _get(entry, "region_fraction_mean")
        if isinstance(step, (int, float)) and isinstance(region, (int, float)):
            points.append((float(step), float(region), _get(entry, "limits_met") is True))
    return points


def _step_survey_axes(ax, doc):
    """Region band mean against the surveyed level steps; the chosen start and the final step marked."""
    points = survey_points(doc)
    steps = np.array([p[0] for p in points])
    region = 100 * np.array([p[1] for p in points])
    met = np.array([p[2] for p in points])
    order = np.argsort(steps)
    ax.plot(steps[order], region[order], "-", color="0.7", lw=1)
    ax.plot(steps[met], region[met], "o", color="tab:blue", ms=4, label="limits met")
    if (~met).any():
        ax.plot(steps[~met], region[~met], "x", color="tab:red", ms=5, label="a limit broken")
    chosen = _get(doc, "step_survey", "chosen_um")
    if isinstance(chosen, (int, float)):
        ax.axvline(chosen, color="tab:green", lw=1, ls="--", label="start %.4g µm" % chosen)
    final = _get(doc, "level_step", "final_um")
    if isinstance(final, (int, float)):
        ax.axvline(final, color="tab:purple", lw=1, ls=":", label="final %.4g µm" % final)
    size = _get(doc, "step_survey", "size", default="?")
    budget = "%s:%s" % (_get(doc, "step_survey", "iterations", default="?"),
                        _get(doc, "step_survey", "refine_passes", default="?"))
    ax.set_title("level-step survey: %s² tile at %s each" % (size, budget), fontsize=9)
    ax.set_xlabel("level step (µm)")
    ax.set_ylabel("region, band mean (%)")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)


def make_report(directory):
    """Writes directory/report.png and returns its path. Raises ReportError for an unusable file."""
    doc = read_design_json(directory)
    curve = read_loss_curve(directory)
    heights = read_heights_um(directory)
    target = read_picture(directory, "target.exr")
    achieved = read_picture(directory, "far_field.exr")

    kind = _get(doc, "target", "kind", default="?")
    constraints = _get(doc, "constraints", default={}) or {}
    levels_um = _get(doc, "levels_um", default=None)
    extent = _get(doc, "picture_extent", default=None)
    if not isinstance(extent, (int, float)):
        extent = _get(doc, "target", "window", default=None)
        extent = extent if isinstance(extent, (int, float)) else None

    # The warnings panel: a band along the bottom, one line of text per wrapped line.
    warnings = warnings_lines(doc)
    band = 0.0
    if warnings:
        band = 0.25 + 0.2 * sum(w.count("\n") + 1 for w in warnings)  # inches
    fig, axes = plt.subplots(2, 4, figsize=(19, 9 + band))
    title = "wavebrdf design: target %s" % _get(doc, "target", "text", default=kind)
    parts = []
    if "size" in constraints:
        parts.append("%s² texels of %s µm" % (constraints["size"], _format_value(constraints.get("texel_um", "?"))))
    if "height_range_um" in constraints:
        parts.append("heights 0…%s µm" % _format_value(constraints["height_range_um"]))
    levels = constraints.get("levels")
    parts.append("%s levels" % levels if levels else "grayscale")
    total = _get(doc, "timings_s", "total")
    if isinstance(total, (int, float)):
        parts.append("%.1f s" % total)
    fig.suptitle(title + "\n" + ", ".join(parts), fontsize=11)

    _picture_axes(axes[0, 0], target, "target", extent)
    _picture_axes(axes[0, 1], achieved, "achieved far field (exact scalar), linear", extent)
    _picture_axes(axes[0, 2], achieved, "achieved far field, log10 (1e-6 of peak floor)", extent, log=True)

    # Colour swatches: the target's colour beside what each evaluation reaches.
    ax = axes[0, 3]
    swatches = []
    target_rgb = _get(doc, "target", "linear_rgb")
    if isinstance(target_rgb, list) and len(target_rgb) == 3:
        swatches.append(("target", target_rgb))
    for key, label in (("model", "model"), ("exact", "exact")):
        rgb = _get(doc, "metrics", key, "linear_srgb")
        if isinstance(rgb, list) and len(rgb) == 3 and all(isinstance(x, (int, float)) for x in rgb):
            swatches.append((label, rgb))
    # An iridescent target: each pair's target colour above what exact scalar diffraction reaches.
    pairs = _get(doc, "target", "pairs")
    reached = _get(doc, "metrics", "exact", "pairs")
    if isinstance(pairs, list) and pairs and isinstance(reached, list) and len(reached) == len(pairs):
        for k, (p, m) in enumerate(zip(pairs, reached)):
            for row, rgb in ((1, _get(p, "linear_rgb")), (0, _get(m, "linear_srgb"))):
                if isinstance(rgb, list) and len(rgb) == 3 and all(isinstance(x, (int, float)) for x in rgb):
                    ax.add_patch(plt.Rectangle((k, row * 1.1), 0.9, 1, color=linear_to_srgb(rgb)))
            view = _get(p, "view", default=["?", "?"])
            du, y = _get(m, "delta_uv"), _get(m, "luminous_efficiency")
            label = "view (%s, %s)" % tuple(_format_value(v) for v in view)
            if isinstance(du, (int, float)) and isinstance(y, (int, float)):
                label += "\nΔu′v′ %.3f\nY %.1f%%" % (du, 100 * y)
            bounds = _get(doc, "optimal_colour_bound")
            if isinstance(bounds, list) and k < len(bounds) and isinstance(_get(bounds[k], "y_at_target"), (int, float)):
                label += "\n(≤ %.1f%%)" % (100 * bounds[k]["y_at_target"])
            ax.text(k + 0.45, -0.08, label, ha="center", va="top", fontsize=7)
        ax.set_xlim(-0.1, len(pairs))
        ax.set_ylim(-0.6, 2.15)
        trade = brightness_trade_text(doc)
        ax.set_title("pairs: target (top), exact (bottom)" + ("\n" + _wrap(trade, 40) if trade else ""), fontsize=9)
        ax.axis("off")
    elif len(swatches) >= 1 and target_rgb is not None:
        for k, (label, rgb) in enumerate(swatches):
            ax.add_patch(plt.Rectangle((k, 0), 0.9, 1, color=linear_to_srgb(rgb)))
            ax.text(k + 0.45, -0.08, label, ha="center", va="top", fontsize=8)
        ax.set_xlim(-0.1, len(swatches))
        ax.set_ylim(-0.3, 1.05)
        du = _get(doc, "metrics", "exact", "delta_uv")
        y = _get(doc, "metrics", "exact", "luminous_efficiency")
        sub = []
        if isinstance(du, (int, float)):
            sub.append("Δu′v′ %.3f" % du)
        if isinstance(y, (int, float)):
            sub.append("Y %.1f%% of incident" % (100 * y))
        lines = [", ".join(sub)] if sub else []
        share = _get(doc, "metrics", "exact", "luminous_efficiency_share_of_reflected")
        if isinstance(share, (int, float)):
            lines.append("(%.1f%% of the reflected light)" % (100 * share))
        bound = _get(doc, "optimal_colour_bound", "y_at_target")
        if isinstance(bound, (int, float)):
            lines.append("any surface: Y ≤ %.1f%%" % (100 * bound))
        mix = _get(doc, "mixture_bound", "y_at_target")
        min_y = _get(doc, "mixture_bound", "min_y")
        if isinstance(mix, (int, float)) and isinstance(min_y, (int, float)):
            if mix < min_y:
                text = "out of reach for this view: level mixtures' bound Y %.1f%% < %.0f%%" % (100 * mix, 100 * min_y)
                if _get(doc, "mixture_bound", "design_check", "absolute", "within") is False:
                    text += "\n(this relief exceeds it: not a bound for it)"
                best = _get(doc, "view_survey", "best")
                view = _get(best, "view") if isinstance(best, dict) else None
                if isinstance(view, list) and len(view) == 2 and all(isinstance(v, (int, float)) for v in view):
                    text += "\nview (%.2g, %.2g) reaches Δu′v′ %.3f at Y %.1f%%" % (
                        view[0], view[1], _get(best, "delta_uv", default=float("nan")),
                        100 * _get(best, "luminous_efficiency", default=float("nan")))
                lines.append(text)
            else:
                lines.append("level mixtures: Y ≤ %.1f%%" % (100 * mix))
        trade = brightness_trade_text(doc)
        if trade:
            lines.append(_wrap(trade, 40))
        ax.set_title("colour (each swatch at full brightness)" + ("\n" + "\n".join(lines) if lines else ""), fontsize=9)
        ax.axis("off")
    elif survey_points(doc):
        _step_survey_axes(ax, doc)
    else:
        ax.axis("off")
        notes = _get(doc, "notes", default=[]) or []
        text = "\n".join(_wrap(str(n), 48) for n in notes) if notes else "no colour target"
        ax.text(0.0, 1.0, "notes:\n" + text if notes else text, va="top", ha="left", fontsize=7,
                family="monospace")

    # Height map and its level histogram.
    ax = axes[1, 0]
    if heights is not None:
        im = ax.imshow(heights, cmap="viridis", interpolation="nearest")
        plt.colorbar(im, ax=ax, fraction=0.046, pad=0.04).set_label("µm", fontsize=8)
        ax.set_title("heights (%d×%d), %.3g…%.3g µm" % (heights.shape[0], heights.shape[1], heights.min(),
                                                        heights.max()), fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        ax = axes[1, 1]
        if isinstance(levels_um, list) and levels_um and all(isinstance(v, (int, float)) for v in levels_um):
            lv = np.asarray(levels_um, dtype=np.float64)
            nearest = np.abs(heights.ravel()[:, None] - lv[None, :]).argmin(axis=1)
            counts = np.bincount(nearest, minlength=len(lv)) / heights.size
            width = 0.8 * (np.min(np.diff(np.sort(lv))) if len(lv) > 1 else 1.0)
            ax.bar(lv, counts, width=width, color="tab:blue")
            ax.set_title("level histogram: %d levels, %d used" % (len(lv), int((counts > 0).sum())), fontsize=9)
        else:
            ax.hist(heights.ravel(), bins=64, color="tab:blue", weights=np.full(heights.size, 1.0 / heights.size))
            ax.set_title("height histogram", fontsize=9)
        ax.set_xlabel("height (µm)")
        ax.set_ylabel("fraction of texels")
        ax.grid(True, alpha=0.3)
    else:
        for a in (axes[1, 0], axes[1, 1]):
            a.axis("off")
        axes[1, 0].text(0.5, 0.5, "heights.exr\n(not in the run)", ha="center", va="center", fontsize=8)

    # Loss curve, one line per phase.
    ax = axes[1, 2]
    if curve is not None and len(curve["iteration"]):
        it, loss = curve["iteration"], curve["loss"]
        phases = curve.get("phase") or [""] * len(it)
        positive = bool((loss > 0).all())
        for phase in dict.fromkeys(phases):
            sel = np.array([p == phase for p in phases])
            (ax.semilogy if positive else ax.plot)(it[sel], loss[sel], ".-", ms=2, lw=1, label=phase or "loss")
        ax.set_xlabel("iteration")
        ax.set_ylabel("loss")
        ax.set_title("loss", fontsize=9)
        if any(phases):
            ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    else:
        ax.axis("off")
        ax.text(0.5, 0.5, "metrics.csv\n(%s)" % ("empty" if curve is not None else "not in the run"), ha="center",
                va="center", fontsize=8)

    # Metrics table: rows are metrics, columns the evaluations.
    ax = axes[1, 3]
    ax.axis("off")
    names, columns = metrics_rows(doc)
    if names and columns:
        cells = [[_format_value(m.get(n, "")) if n in m else "" for _, m in columns] for n in names[:18]]
        table = ax.table(cellText=cells, rowLabels=names[:18], colLabels=[c for c, _ in columns], loc="upper right",
                         cellLoc="center")
        table.auto_set_font_size(False)
        table.set_fontsize(6.5)
        table.scale(1.0, 1.15)
        ax.set_title("metrics (model, exact scalar diffraction, fabrication errors)", fontsize=9)
    else:
        ax.text(0.5, 0.5, "no metrics in design.json", ha="center", va="center", fontsize=8)

    # The panels keep their 9 inches and the title its space; the warnings take the band below.
    bottom = band / (9 + band)
    fig.tight_layout(rect=(0, bottom, 1, 1 - 0.06 * 9 / (9 + band)))
    if warnings:
        ax = fig.add_axes((0.01, 0.1 * bottom, 0.98, 0.85 * bottom))
        ax.axis("off")
        ax.add_patch(plt.Rectangle((0, 0), 1, 1, transform=ax.transAxes, facecolor="#fff1e0", edgecolor="#c05000",
                                   lw=1.5))
        ax.text(0.005, 0.5, "\n".join("warning: " + w for w in warnings), transform=ax.transAxes, va="center",
                ha="left", fontsize=10, color="#802000")
    return save_figure(fig, os.path.join(directory, "report.png"), 100)


def _wrap(text, width):
    words, lines, line = text.split(" "), [], ""
    for w in words:
        if len(line) + len(w) + 1 > width and line:
            lines.append(line)
            line = "  " + w
        else:
            line = (line + " " + w) if line else w
    lines.append(line)
    return "\n".join(lines)
