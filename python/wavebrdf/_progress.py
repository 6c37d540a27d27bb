"""Progress of the long runs wavebrdf.invert and wavebrdf.recover, shown while they run: a tqdm
bar when tqdm is installed (``tqdm.auto``: a widget in a Jupyter notebook where ipywidgets is
installed, text otherwise), else one line on stderr redrawn in place, one per stage.

Their ``quiet`` argument: None (the default) shows progress where someone is watching: stderr
is a terminal, or the code runs in a Jupyter kernel (whose stderr is no terminal but shows
tqdm's bars and redrawn lines); a script whose stderr goes to a file or a pipe stays silent,
as the command line's bars do. False always shows it, True never.

The extension calls wrap_invert / wrap_recover once the run is set up: they return the callback
to run with (the user's, wrapped, or the user's itself when nothing is shown) and the display,
whose close() the extension calls however the run ends (Ctrl-C included).
"""
import sys
import time

__all__ = ["shown", "Display", "wrap_invert", "wrap_recover"]


def shown(quiet):
    """Whether progress is shown for `quiet` (None, True or False; see the module's text)."""
    if quiet is not None:
        return not quiet
    try:
        if sys.stderr is not None and sys.stderr.isatty():
            return True
    except (AttributeError, ValueError):  # a replaced or closed stderr
        pass
    return "ipykernel" in sys.modules


def _tqdm():
    """tqdm's class (tqdm.auto), or None when tqdm is not installed."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm


class _Line:
    """The fallback without tqdm: `stage  12/80  15%  0:03  message` on one stderr line, redrawn
    ('\\r') at most every 0.1 s, finished with a newline by close()."""

    def __init__(self, stage, total, stream):
        self.stage, self.total, self.stream = stage, total, stream
        self.n, self.message, self.width = 0, "", 0
        self.start = self.last = time.monotonic()
        self.draw()

    def update(self, n, message):
        self.n, self.message = n, message
        now = time.monotonic()
        if now - self.last >= 0.1:
            self.last = now
            self.draw()

    def draw(self, end=""):
        seconds = int(time.monotonic() - self.start)
        count = "%d/%d %3d%%" % (self.n, self.total, 100 * min(self.n, self.total) // max(self.total, 1))
        text = "%s  %s  %d:%02d  %s" % (self.stage, count, seconds // 60, seconds % 60, self.message)
        self.stream.write("\r" + text.ljust(self.width) + end)
        self.stream.flush()
        self.width = len(text)

    def close(self):
        self.draw("\n")


class Display:
    """One bar per stage of a run (a new stage closes the bar of the one before)."""

    def __init__(self, use_tqdm=True):
        self.tqdm = _tqdm() if use_tqdm else None
        self.stage, self.bar = None, None

    def update(self, stage, n, total, message=""):
        """Stage `stage` has done `n` of `total` steps; `message` is shown after the count."""
        if stage != self.stage:
            self.close()
            self.stage = stage
            if self.tqdm is not None:
                self.bar = self.tqdm(total=total, desc=stage, file=sys.stderr, leave=True, dynamic_ncols=True)
            else:
                self.bar = _Line(stage, total, sys.stderr)
        if self.tqdm is not None:
            self.bar.set_postfix_str(message, refresh=False)
            self.bar.update(max(0, n - self.bar.n))
        else:
            self.bar.update(n, message)

    def close(self):
        if self.bar is not None:
            bar, self.bar, self.stage = self.bar, None, None
            bar.close()


def wrap_invert(callback, quiet, total_epochs):
    """(callback to run invert with, Display or None): epochs 0 ... total_epochs - 1 counted."""
    if not shown(quiet):
        return callback, None
    display = Display()

    def on_epoch(metrics, estimate):
        display.update("invert", int(metrics["epoch"]) + 1, total_epochs, "loss %.4g" % metrics["loss"])
        return None if callback is None else callback(metrics, estimate)

    return on_epoch, display


def wrap_recover(callback, quiet):
    """(callback to run recover with, Display or None). Each step's metrics carry its stage's
    planned iterations ('total', the run's: recover.h, StageKind); steps of a stage reported once
    (total 0: a stage's result) are not drawn."""
    if not shown(quiet):
        return callback, None
    display = Display()

    def on_step(metrics):
        total = metrics["total"]
        if total > 0:
            message = "loss %.3g" % metrics["loss"]
            if metrics["height_rel_rmse"] == metrics["height_rel_rmse"]:  # not NaN
                message += " height err %.2f%%" % (100.0 * metrics["height_rel_rmse"])
            display.update(metrics["stage"], int(metrics["iteration"]), max(int(total), 1), message)
        return None if callback is None else callback(metrics)

    return on_step, display
