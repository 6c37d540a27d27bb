"""The recovery's option checks are the library's (recovery_run.h, check_recovery_options), made
once, before any file is read: `wavebrdf recover` and Python's recover() refuse the same options
with the same one-line message, each naming the option as its user spells it (--max-memory-gb,
max_memory_gb). The truth and observation files named here do not exist: a check that waited for
them would fail on the missing file instead."""
import re
import subprocess

import pytest

import wavebrdf as wb

CASES = [
    # (CLI arguments, recover() keywords, words the message must hold in Python's spelling)
    (["--truth", "missing.exr", "--observations", "missing.json"],
     dict(truth="missing.exr", observations="missing.json"), ["truth", "observations", "exclude each other"]),
    (["--observations", "missing.json", "--noise", "poisson:1000"],
     dict(observations="missing.json", noise="poisson:1000"), ["noise 'poisson:1000'", "not observations"]),
    (["--observations", "missing.json", "--simulator", "scalar"],
     dict(observations="missing.json", settings=wb.RecoverSettings(simulator="scalar")),
     ["simulator 'scalar'", "not observations"]),
    (["--observations", "missing.json", "--simulate-position-error-texels", "0.5"],
     dict(observations="missing.json", settings=wb.RecoverSettings(simulate_position_error_texels=0.5)),
     ["simulate_*", "not observations"]),
    (["--simulate-exposure", "0.0001,2"],
     dict(settings=wb.RecoverSettings(simulate_exposure=(0.0001, 2))), ["simulate_exposure min 0.0001"]),
    (["--max-memory-gb=-1"], dict(max_memory_gb=-1), ["max_memory_gb -1 is invalid"]),
    (["--white-smoothness=-1"], dict(settings=wb.RecoverSettings(white_smoothness=[-1.0])),
     ["white_smoothness weight -1 is invalid"]),
    (["--model", "Kirchhoff"], dict(model="Kirchhoff"), ["model Kirchhoff has no field stage"]),
    (["--overlap", "0.5"], dict(settings=wb.RecoverSettings(overlap=0.5)), ["overlap 0.5 is invalid; expected 0.6 to 0.95"]),
    (["--overlap", "0"], dict(settings=wb.RecoverSettings(overlap=0)), ["overlap 0 is invalid; expected 0.6 to 0.95"]),
    (["--overlap", "nan"], dict(settings=wb.RecoverSettings(overlap=float("nan"))), ["overlap nan is invalid"]),
]


def python_spelling(message):
    """A CLI message with its options spelled as Python's keywords: --simulate-* → simulate_*."""
    return re.sub(r"--([a-z][a-z-]*\*?)", lambda m: m.group(1).replace("-", "_"), message)


@pytest.mark.parametrize("args, kwargs, needles", CASES)
def test_cli_and_python_refuse_with_the_same_message(cli, tmp_path, args, kwargs, needles):
    run = subprocess.run([cli, "recover", "--size", "8", *args, "--quiet", "--out", str(tmp_path / "run")],
                         cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode != 0
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert not (tmp_path / "run" / "run.json").exists()
    with pytest.raises(ValueError) as info:
        wb.recover(size=8, quiet=True, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    for needle in needles:
        assert needle in message, message
    # The CLI's line is "…: <message>" in its own spelling; the same words in Python's.
    assert python_spelling(lines[0]).endswith(message), (lines[0], message)
    assert "--" in lines[0]
