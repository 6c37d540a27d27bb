"""Progress of wavebrdf.invert and wavebrdf.recover (wavebrdf/_progress.py): a tqdm bar when
tqdm can be imported, else one line on stderr; nothing with quiet=True; with quiet=None only
where someone watches (stderr a terminal, or a Jupyter kernel). The user's callback still sees
every epoch and can stop the run; the display's line is ended however the run ends."""
import io
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
    wb.recover(size=8, method="thesis", epochs=3, quiet=True)
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
        wb.recover(size=8, method="thesis", epochs=1, quiet="no")


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
    result = wb.recover(size=8, method="thesis", epochs=5, quiet=False, callback=lambda m: steps.append(m["stage"]))
    err = capsys.readouterr().err
    assert steps and set(steps) == {"thesis"}
    assert "thesis  5/5 100%" in err and err.endswith("\n")
    assert result.estimate.shape == (8, 8)


def test_recover_with_tqdm(capsys):
    pytest.importorskip("tqdm")
    wb.recover(size=8, method="thesis", epochs=5, quiet=False)
    err = capsys.readouterr().err
    assert "thesis" in err and "5/5" in err and "100%|" in err
