"""Pictures of a run directory written by `wavebrdf invert`, `wavebrdf recover` or `wavebrdf design`
(`--out DIR`).

    python3 -m wavebrdf.report [--quiet] DIR

draws DIR/report.png (and, for an inversion, DIR/curves.png) and prints the paths it wrote. The
kind of run is read from DIR/metrics.csv (its first column: "epoch" for an inversion, "stage"
for a recovery) or, for a design, from DIR/design.json being there. The `wavebrdf` command runs
this after every run unless --no-plots; the pictures are drawn by wavebrdf.report_invert,
wavebrdf.report_recover and wavebrdf.report_design, which need NumPy and matplotlib (this module
itself needs neither, so it can say which one is missing).

Exit status: 0 drawn; 2 DIR, its metrics.csv or its kind missing or unknown, a design's file
unusable, a file in it that is not a regular file (a FIFO, a device) or larger than 1 GiB, or
contents the report cannot draw (missing or non-numeric columns, a truncated line, missing
keys) (one line on stderr); 3 NumPy is not installed; 4 matplotlib is not installed. With --quiet nothing is
printed on success, and a missing NumPy or matplotlib is reported by the exit status alone
(the `wavebrdf` command then prints its own warning).

Every PNG is written atomically (a temporary ".report.png.XXXX.tmp" beside it, renamed over
it), so a reader never sees half a picture.
"""
import argparse
import csv
import os
import stat
import sys
import tempfile

EXIT_USAGE = 2
EXIT_NO_NUMPY = 3
EXIT_NO_MATPLOTLIB = 4
# The largest file a report reads (metrics.csv of a long run is a few MB; a link to /dev/zero
# or a hostile file must not be read without end).
MAX_INPUT_BYTES = 1 << 30


def check_inputs(d):
    """Raises ValueError naming the first entry of the run directory `d` (or of its snapshots/)
    that is not a regular file or directory (a FIFO would block a read forever, a device never
    end one) or is larger than MAX_INPUT_BYTES."""
    for sub in ("", "snapshots"):
        folder = os.path.join(d, sub) if sub else d
        if not os.path.isdir(folder):
            continue
        for name in sorted(os.listdir(folder)):
            path = os.path.join(folder, name)
            try:
                st = os.stat(path)
            except OSError:
                continue  # a dangling link: the reader that wants it says it is missing
            if stat.S_ISDIR(st.st_mode):
                continue
            if not stat.S_ISREG(st.st_mode):
                kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a character device" if stat.S_ISCHR(st.st_mode)
                        else "a block device" if stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                        else "a special file")
                raise ValueError("%s is %s, not a regular file; expected the files of a run" % (path, kind))
            if st.st_size > MAX_INPUT_BYTES:
                raise ValueError("%s is %d bytes; expected at most %d" % (path, st.st_size, MAX_INPUT_BYTES))


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
        check_inputs(d)
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
    try:
        paths = draw(d)
    except ImportError:
        raise
    except Exception as e:  # a hostile or interrupted directory: one line, not a traceback
        if kind == "design" and type(e).__name__ == "ReportError":  # a design's file named by its reader
            print("wavebrdf.report: error: %s" % e, file=sys.stderr)
            return EXIT_USAGE
        text = " ".join(str(e).split()) or type(e).__name__
        print("wavebrdf.report: error: %s: cannot draw the report (%s: %s)" % (d, type(e).__name__, text[:300]),
              file=sys.stderr)
        return EXIT_USAGE
    for path in paths:
        if not args.quiet:
            print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
