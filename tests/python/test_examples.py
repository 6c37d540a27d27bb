"""examples/: the Python version of the thesis's listing 4.1 runs end to end, and its loop (built
from render, Loss, gradient and Adam) follows the library's own inverse renderer."""
import importlib.util
import os
import re
import subprocess
import sys

import numpy as np

import wavebrdf as wb
from conftest import BUILD, ROOT

LISTING = os.path.join(ROOT, "examples", "listing_4_1.py")


def run_listing(*args):
    env = dict(os.environ, PYTHONPATH=os.path.join(BUILD, "python"))
    result = subprocess.run([sys.executable, LISTING, *args], capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_listing_4_1_runs_end_to_end():
    out = run_listing("--epochs", "100")
    final = re.search(r"final: loss (\S+) \((\S+)% of epoch 0\)", out)
    assert final, out
    assert float(final.group(2)) < 50.0  # the loss falls (the thesis's Fig. 5.3)
    assert "epoch    0" in out and "epoch  100" in out
    out = run_listing("--epochs", "5", "--stochastic", "--quiet")
    assert "final: loss" in out


def test_listing_4_1_follows_invert():
    spec = importlib.util.spec_from_file_location("listing_4_1", LISTING)
    listing = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(listing)
    mine = listing.main(["--epochs", "40", "--quiet"])
    theirs = wb.invert(epochs=40)  # the same defaults, looped in C++
    np.testing.assert_array_equal(mine["truth"].values, theirs.truth.values)
    np.testing.assert_allclose(mine["reference"], theirs.observations[0].reference, rtol=0,
                               atol=1e-12 * np.abs(mine["reference"]).max())
    np.testing.assert_allclose(mine["losses"], theirs.metrics["loss"], rtol=1e-9)
    np.testing.assert_allclose(mine["estimate"].values, theirs.estimate.values, rtol=0, atol=1e-9)
