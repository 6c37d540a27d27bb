"""Progress of wavebrdf.invert and wavebrdf.recover (wavebrdf/_progress.py): a tqdm bar when
tqdm can be imported, else one line on stderr; nothing with quiet=True; with quiet=None only
where someone watches (stderr a terminal, or a Jupyter kernel). The user's callback still sees
every epoch and can stop the run; the display's line is ended however the run ends."""
import io
import os
import sys

import pytest

import wavebrdf as wb
from wavebrdf import _progress

SMALL = dict(size=8, resolution=16, epochs=3)  # 4 evaluated epochs (0 ... 3), well under a second


def no_tqdm(monkeypatch):
    """Makes `import tqdm` fail as if it were not installed."""
    for name in ("tqdm", "tqdm.auto", "tqdm.autonotebook", "tqdm.std"):
        monkeypatch.setitem(sys.modules, name, None)


def test_invert_shows_a_tqdm_bar_with_quiet_false(capsys):
    pytest.importorskip("tqdm")
    wb.invert(quiet=False, **SMALL)
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "invert" in captured.err and "4/4" in captured.err and "loss" in captured.err
    assert "100%|" in captured.err  # tqdm's bar, not the fallback line
    assert captured.err.endswith("\n")


def test_invert_shows_one_line_without_tqdm(capsys, monkeypatch):
    no_tqdm(monkeypatch)
    assert _progress._tqdm() is None
    wb.invert(quiet=False, **SMALL)
    err = capsys.readouterr().err
    assert "invert  4/4 100%" in err and "loss" in err
    assert "|" not in err
    assert err.endswith("\n") and err.count("\n") == 1  # one line, redrawn with '\r'


def test_quiet_true_shows_nothing(capsys):
    wb.invert(quiet=True, **SMALL)
    wb.recover(size=8, method="thesis", quiet=True, settings=wb.RecoverSettings(epochs=3))
    assert capsys.readouterr().err == ""


def test_quiet_none_shows_nothing_when_stderr_is_a_file(capsys, monkeypatch):
    # pytest's captured stderr is no terminal, and no Jupyter kernel is loaded.
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    wb.invert(**SMALL)
    assert capsys.readouterr().err == ""


def test_quiet_none_shows_progress_on_a_terminal_or_in_jupyter(monkeypatch):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    assert not _progress.shown(None)
    monkeypatch.setattr(sys, "stderr", Terminal())
    assert _progress.shown(None)
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    monkeypatch.setitem(sys.modules, "ipykernel", object())
    assert _progress.shown(None)
    assert not _progress.shown(True) and _progress.shown(False)


def test_quiet_must_be_a_bool_or_none():
    with pytest.raises(ValueError, match="quiet"):
        wb.invert(quiet=1, **SMALL)
    with pytest.raises(ValueError, match="quiet"):
        wb.recover(size=8, method="thesis", quiet="no", settings=wb.RecoverSettings(epochs=1))


def test_the_callback_still_sees_every_epoch_and_can_stop_the_run(capsys):
    seen = []

    def callback(metrics, estimate):
        seen.append(metrics["epoch"])
        assert estimate.shape == (8, 8)
        return metrics["epoch"] < 1

    result = wb.invert(quiet=False, callback=callback, **SMALL)
    assert seen == [0, 1] and result.stopped
    assert capsys.readouterr().err.endswith("\n")


def test_an_error_in_the_callback_is_raised_and_the_line_ended(capsys, monkeypatch):
    no_tqdm(monkeypatch)

    def callback(metrics, estimate):
        raise ArithmeticError("from the callback")

    with pytest.raises(ArithmeticError, match="from the callback"):
        wb.invert(quiet=False, callback=callback, **SMALL)
    err = capsys.readouterr().err
    assert "invert  1/4" in err and err.endswith("\n")


def test_recover_shows_a_bar_per_stage(capsys, monkeypatch):
    no_tqdm(monkeypatch)
    steps = []
    result = wb.recover(size=8, method="thesis", quiet=False, callback=lambda m: steps.append(m["stage"]),
                        settings=wb.RecoverSettings(epochs=5))
    err = capsys.readouterr().err
    assert steps and set(steps) == {"thesis"}
    assert "thesis  5/5 100%" in err and err.endswith("\n")
    assert result.estimate.shape == (8, 8)


def test_recover_with_tqdm(capsys):
    pytest.importorskip("tqdm")
    wb.recover(size=8, method="thesis", quiet=False, settings=wb.RecoverSettings(epochs=5))
    err = capsys.readouterr().err
    assert "thesis" in err and "5/5" in err and "100%|" in err


# A run with every iterating stage of the default pipeline and stated iteration counts.
PLANNED = dict(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, seed=3,
               settings=wb.RecoverSettings(field_iterations=7, refine_iterations=5))
PLANNED_CLI = ["--size", "8", "--texel-um", "2", "--sigma-p-um", "3", "--height-range-um", "0.1", "--seed", "3",
               "--field-iterations", "7", "--refine-iterations", "5"]


def cli_bar_totals(cli, tmp_path):
    """{stage: total} of the bars `wavebrdf recover` draws on a terminal (its stderr a pty)."""
    import pty
    import re
    import subprocess
    master, slave = pty.openpty()
    proc = subprocess.Popen([cli, "recover", *PLANNED_CLI, "--no-plots", "--out", str(tmp_path / "run")],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # the pty's other end closed
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    assert proc.wait() == 0
    text = b"".join(chunks).decode("utf-8", "replace")
    totals = {}
    for stage, total in re.findall(r"\r(\S+) \[[#.]+\] +\d+%  \d+/(\d+)", text):
        totals.setdefault(stage, set()).add(int(total))
    return totals


def test_progress_totals_are_the_runs_in_python_and_the_cli(cli, tmp_path, monkeypatch):
    # Python: what the display is given for each stage, and what the run reports with each step.
    no_tqdm(monkeypatch)
    shown = {}
    original = _progress.Display.update

    def update(self, stage, n, total, message=""):
        shown.setdefault(stage, set()).add(total)
        return original(self, stage, n, total, message)

    monkeypatch.setattr(_progress.Display, "update", update)
    steps = []
    wb.recover(quiet=False, callback=lambda m: steps.append(dict(m)), **PLANNED)
    reported = {}
    for m in steps:
        reported.setdefault(m["stage"], set()).add(m["total"])
        assert m["kind"] != "other", m["stage"]
    # Every stage has one kind and one total; the stated counts are the run's totals.
    assert all(len(t) == 1 for t in reported.values()), reported
    kinds = {m["stage"]: m["kind"] for m in steps}
    fields = [s for s in reported if kinds[s] == "field:"]
    assert fields and all(reported[s] == {7} for s in fields)
    assert reported["refine"] == {5} and reported["unwrap"] == {0} and reported["blur"] == {0}
    # The display shows exactly the iterating stages, with the run's totals.
    assert shown == {s: t for s, t in reported.items() if t != {0}}
    # The CLI's bars: the same totals (a stage reported once draws a bar of 1).
    bars = cli_bar_totals(cli, tmp_path)
    assert set(reported) <= set(bars)  # the CLI also draws the simulation's bar
    for stage, total in reported.items():
        assert bars[stage] == {max(total) or 1}, stage
