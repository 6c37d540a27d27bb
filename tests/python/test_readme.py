"""README.md kept honest: its examples run as written, in a fresh directory, in the order given.

Every ```sh block's `build/bin/wavebrdf ...` command runs in an empty temporary directory whose
`build` is this build (so the README's relative paths hold), each after the ones before it, and
must exit 0 and make the outputs it names (--out, -o, --png). A file a command reads (--truth,
--heightfield, -i, --observations, --resume) must have been made by an earlier command: that is
how the E3 example's missing truth.exr would have been caught.

Long commands (`invert`, `recover`: minutes each) are not skipped: they run with their options
and values exactly as written, plus a few options that only cut their cost (fewer epochs, a
smaller surface, small slices, few iterations, one wavelength, no plots; SHRINK below). So
their option names and values are checked by the real parser and the real run, and their
outputs must exist for the commands after them; only the size of the run differs. The Python
block runs the same way: as written, with `wb.recover` calls given the same cost cuts. The
`bash scripts/...` commands of the opening block (a build and the whole test suite) are checked
to exist and to parse (`bash -n`), not run. Any other command fails the test: teach it here.
Takes about 20 s on 2 cores. Also: no tracked file cites a file outside the repository."""
import os
import re
import shlex
import subprocess

import numpy as np
import pytest

import wavebrdf as wb
from conftest import BUILD, ROOT

README = os.path.join(ROOT, "README.md")

# Options that name a file a command reads, and ones that name the files it writes.
INPUTS = {"--truth", "--heightfield", "-i", "--observations", "--resume"}
OUTPUTS = {"--out", "-o", "--png"}
# Cost cuts for the long subcommands: option → value, replacing the README's value where it gives
# one (numbers only ever lowered) and added where it does not. Flags (value None) are added.
SHRINK = {
    "invert": {"--epochs": "3", "--no-plots": None},
    "recover": {
        "--size": "8",
        "--epochs": "3",
        "--resolution": "16",
        "--field-iterations": "2",
        "--refine-iterations": "2",
        "--lambdas-um": "0.5",
        "--no-plots": None,
    },
}
RECOVER_SHRINK = dict(size=8, resolution=16, lambdas_um=[0.5])
RECOVER_SETTINGS_SHRINK = dict(epochs=3, field_iterations=2, refine_iterations=2)  # wb.RecoverSettings


def code_blocks(language):
    text = open(README, encoding="utf-8").read()
    return re.findall(r"^```" + language + r"\n(.*?)^```", text, flags=re.S | re.M)


def commands(block):
    """The commands of a shell block: continuation lines joined, comments dropped."""
    joined = re.sub(r"\\\n", " ", block)
    return [argv for argv in (shlex.split(line, comments=True) for line in joined.splitlines()) if argv]


def shrink(argv):
    """argv of a long subcommand with SHRINK's cost cuts applied (argv[1] is the subcommand)."""
    cuts = SHRINK[argv[1]]
    out, i, seen = [], 0, set()
    while i < len(argv):
        token = argv[i]
        out.append(token)
        if token in cuts and cuts[token] is not None and i + 1 < len(argv):
            value = argv[i + 1]
            if re.fullmatch(r"[0-9.]+", value):  # a number: lowered, never raised
                value = str(min(float(value), float(cuts[token]))).rstrip("0").rstrip(".")
            else:
                value = cuts[token]
            out.append(value)
            seen.add(token)
            i += 2
            continue
        seen.add(token)
        i += 1
    for option, value in cuts.items():
        if option not in seen:
            out += [option] if value is None else [option, value]
    return out


def option_values(argv, names):
    return [argv[i + 1] for i in range(len(argv) - 1) if argv[i] in names]


@pytest.fixture
def fresh_dir(tmp_path):
    """An empty directory whose build/ is this build, as a fresh clone's root after the build."""
    os.symlink(BUILD, tmp_path / "build")
    return tmp_path


def test_readme_has_the_examples_this_test_runs():
    shell = [argv for block in code_blocks("sh") for argv in commands(block)]
    assert ["bash", "scripts/demo.sh"] in shell and ["bash", "scripts/test.sh"] in shell
    subcommands = {argv[1] for argv in shell if argv[0] == "build/bin/wavebrdf"}
    assert {"heightfield", "render", "genbrdf", "invert", "recover"} <= subcommands
    assert len(code_blocks("python")) == 1


def test_readme_shell_examples_run_as_written(fresh_dir, cli):
    env = dict(os.environ, WAVEBRDF_PYTHON="/usr/bin/python3")
    for block in code_blocks("sh"):
        for argv in commands(block):
            if argv[0] == "bash" and len(argv) >= 2 and argv[1].startswith("scripts/"):
                script = os.path.join(ROOT, argv[1])
                assert os.path.isfile(script), "README runs %s, which does not exist" % argv[1]
                check = subprocess.run(["bash", "-n", script], capture_output=True, text=True)
                assert check.returncode == 0, "%s does not parse: %s" % (argv[1], check.stderr)
                continue
            launcher = []
            if argv[0] == "mpiexec":  # mpiexec -n K build/bin/wavebrdf …: K ranks (docs/scale.md)
                assert argv[1] == "-n" and argv[2].isdigit(), "README: mpiexec without -n K: %s" % argv
                # As root and with more ranks than cores, as CI runs it.
                launcher = ["mpiexec", "-n", argv[2], "--oversubscribe", "--bind-to", "none"]
                argv = argv[3:]
            assert argv[0] == "build/bin/wavebrdf", "README command this test does not know: %s" % argv
            for path in option_values(argv, INPUTS):
                assert (fresh_dir / path).exists(), "README: `%s` reads %s, which no earlier example makes" % (
                    shlex.join(argv),
                    path,
                )
            run = launcher + (shrink(argv) if argv[1] in SHRINK else argv)
            run_env = dict(env, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1")
            result = subprocess.run(run, cwd=fresh_dir, capture_output=True, text=True,
                                    env=run_env if launcher else env, timeout=300)
            assert result.returncode == 0, "README: `%s` failed (ran as `%s`):\n%s" % (
                shlex.join(argv),
                shlex.join(run),
                result.stderr[-2000:],
            )
            for path in option_values(argv, OUTPUTS):
                assert (fresh_dir / path).exists(), "README: `%s` did not write %s" % (shlex.join(argv), path)
            if argv[1] in SHRINK:  # a run directory: its estimate and metrics
                out = option_values(argv, {"--out"})[0]
                assert (fresh_dir / out / "estimate.exr").exists() and (fresh_dir / out / "metrics.csv").exists()
            if "--save-observations" in argv:  # into --out, or to the FILE it names
                named = [v for v in option_values(argv, {"--save-observations"}) if not v.startswith("-")]
                saved = fresh_dir / named[0] if named else fresh_dir / option_values(argv, {"--out"})[0] / "observations.json"
                assert saved.exists(), "README: `%s` did not write %s" % (shlex.join(argv), saved)


def test_readme_python_example_runs_as_written(fresh_dir, monkeypatch):
    (code,) = code_blocks("python")
    real_recover = wb.recover
    calls = []

    def recover(*args, **kwargs):  # the same call, its cost cut (RECOVER_SHRINK)
        calls.append(dict(kwargs))
        for key, value in RECOVER_SHRINK.items():
            kwargs[key] = min(kwargs[key], value) if isinstance(kwargs.get(key), (int, float)) else value
        settings = kwargs.get("settings") or wb.RecoverSettings()
        for key, value in RECOVER_SETTINGS_SHRINK.items():
            current = getattr(settings, key)
            setattr(settings, key, min(current, value) if isinstance(current, (int, float)) else value)
        kwargs["settings"] = settings
        return real_recover(*args, **kwargs)

    monkeypatch.setattr(wb, "recover", recover)
    monkeypatch.chdir(fresh_dir)
    namespace = {}
    exec(compile(code, "README.md (python block)", "exec"), namespace)
    assert len(calls) == 3
    # What the example computes: a fitted loss below the start's, a torch gradient, a result.
    assert namespace["loss"] < wb.Loss("cmsle:1").value_and_gradient(
        wb.render_slice(np.zeros((16, 16)), **namespace["opts"]), namespace["reference"]
    )[0]
    assert namespace["h"].grad is not None and namespace["h"].grad.shape == (16, 16)
    assert namespace["r2"].estimate.shape == namespace["r"].estimate.shape
    r3 = namespace["r3"]  # self-calibration and error bars: one exposure per observation, a sigma map
    assert len(r3.calibration["exposures"]) == len(r3.observations)
    assert r3.uncertainty.shape == r3.estimate.shape and r3.median_sigma_um > 0


def test_repository_cites_no_file_outside_it():
    """Code, docs, scripts and tests cite docs/model.md or a paper's title, never the specification,
    notes or thesis files the project was developed from (outside the repository)."""
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True)
    if listed.returncode != 0:
        pytest.skip("not a git checkout")
    # The measured scans beside the repository (../shared/real-surfaces, ../shared/format-examples)
    # are data the surface tests read, not sources the project was developed from: they may be named.
    outside = re.compile("|".join([r"MODEL" + r"\.md", r"\.\./shared(?!/(real-surfaces|format-examples)\b)",
                                   r"/work" + "/", r"\bseeds" + "/"]))
    found = []
    for name in listed.stdout.decode().split("\0"):
        path = os.path.join(ROOT, name)
        if not name or not os.path.isfile(path):
            continue
        with open(path, "rb") as f:
            data = f.read()
        if b"\0" in data[:8192]:
            continue  # binary
        for number, line in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
            if outside.search(line):
                found.append("%s:%d: %s" % (name, number, line.strip()))
    assert not found, "citations of files outside the repository:\n" + "\n".join(found)
