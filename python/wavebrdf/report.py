"""Pictures of a run directory written by `wavebrdf invert`, `wavebrdf recover` or `wavebrdf design`
(`--out DIR`).

    python3 -m wavebrdf.report [--quiet] DIR

draws DIR/report.png (and, for an inversion, DIR/curves.png) and prints the paths it wrote. The
kind of run is read from DIR/metrics.csv (its first column: "epoch" for an inversion, "stage"
for a recovery) or, for a design, from DIR/design.json being there. The `wavebrdf` command runs
this after every run unless --no-plots; the pictures are drawn by wavebrdf.report_invert,
wavebrdf.report_recover and wavebrdf.report_design, which need NumPy and matplotlib (this module
itself needs neither, so it can say which one is missing).

Exit status: 0 drawn; 2 DIR, its metrics.csv or its kind missing or unknown, or a design's file
unusable (one line on stderr); 3 NumPy is not installed; 4 matplotlib is not installed. With --quiet nothing is
printed on success, and a missing NumPy or matplotlib is reported by the exit status alone
(the `wavebrdf` command then prints its own warning).

Every PNG is written atomically (a temporary ".report.png.XXXX.tmp" beside it, renamed over
it), so a reader never sees half a picture.
"""
import argparse
import csv
import os
import sys
import tempfile

EXIT_USAGE = 2
EXIT_NO_NUMPY = 3
EXIT_NO_MATPLOTLIB = 4


def run_kind(d):
    """'invert', 'recover' or 'design': the command that wrote the run directory `d`: 'design'
    when it holds design.json, else from the first column of its metrics.csv ('epoch' or
    'stage'; 'iteration' is a design whose design.json is missing). Raises FileNotFoundError
    when metrics.csv is missing and ValueError when its header is none of these."""
    if os.path.exists(os.path.join(d, "design.json")):
        return "design"
    path = os.path.join(d, "metrics.csv")
    with open(path, newline="", encoding="utf-8") as f:
        header = next(csv.reader(f), [])
    first = header[0].strip() if header else ""
    if first == "epoch":
        return "invert"
    if first == "stage":
        return "recover"
    if first == "iteration":
        return "design"
    raise ValueError("%s: first column %r is unknown; expected 'epoch' (wavebrdf invert), 'stage' "
                     "(wavebrdf recover) or 'iteration' (wavebrdf design)" % (path, first))


def save_figure(fig, path, dpi):
    """Writes the matplotlib figure `fig` to `path` as a PNG atomically (a temporary file in the
    same directory, renamed over `path`; removed on failure), closes the figure and returns
    `path`."""
    import matplotlib.pyplot as plt

    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=d)
    try:
        with os.fdopen(fd, "wb") as f:
            fig.savefig(f, format="png", dpi=dpi, pil_kwargs={"compress_level": 3})
        # mkstemp makes the file 0600; give it the permissions of any other output.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    finally:
        plt.close(fig)
    return path


def draw(d):
    """Draws the pictures of the run directory `d` (report.png; curves.png too for an
    inversion) and returns the paths written. Raises as run_kind does; ImportError when NumPy
    or matplotlib is missing."""
    kind = run_kind(d)
    if kind == "invert":
        from . import report_invert

        return [report_invert.make_report(d), report_invert.make_curves(d)]
    if kind == "design":
        from . import report_design

        return [report_design.make_report(d)]
    from . import report_recover

    return [report_recover.make_report(d)]


def _missing_dependency():
    """(exit status, name) of NumPy or matplotlib when it cannot be imported, else None."""
    for status, name in ((EXIT_NO_NUMPY, "numpy"), (EXIT_NO_MATPLOTLIB, "matplotlib")):
        try:
            __import__(name)
        except ImportError:
            return status, name
    return None


def main(argv=None):
    p = argparse.ArgumentParser(prog="python3 -m wavebrdf.report",
                                description="Pictures of a `wavebrdf invert`, `recover` or `design` run directory.")
    p.add_argument("dir", help="the run's output directory (--out)")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing on success; a missing numpy or matplotlib only by the exit status")
    try:
        args = p.parse_args(sys.argv[1:] if argv is None else argv)
    except SystemExit as e:  # usage errors: argparse has printed the message
        return e.code if isinstance(e.code, int) else EXIT_USAGE
    d = args.dir
    if not os.path.isdir(d):
        print("wavebrdf.report: error: no such directory: %s" % d, file=sys.stderr)
        return EXIT_USAGE
    try:
        kind = run_kind(d)
    except (OSError, ValueError) as e:
        print("wavebrdf.report: error: %s" % (
            "missing %s" % os.path.join(d, "metrics.csv") if isinstance(e, FileNotFoundError) else e), file=sys.stderr)
        return EXIT_USAGE
    missing = _missing_dependency()
    if missing:
        if not args.quiet:
            print("wavebrdf.report: error: %s is not installed for %s" % (missing[1], sys.executable), file=sys.stderr)
        return missing[0]
    if kind == "design":
        from .report_design import ReportError

        try:
            paths = draw(d)
        except ReportError as e:  # a file of the run that is there but unusable, named
            print("wavebrdf.report: error: %s" % e, file=sys.stderr)
            return EXIT_USAGE
    else:
        paths = draw(d)
    for path in paths:
        if not args.quiet:
            print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
