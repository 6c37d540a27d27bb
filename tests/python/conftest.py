"""pytest set-up for tests/python: the module and the CLI come from one build directory,
build/ by default (what scripts/setup.sh builds) or $WAVEBRDF_BUILD_DIR (relative to the
repository root, or absolute); with WAVEBRDF_TEST_INSTALLED=1 the module is the installed one."""
import os
import sys

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BUILD = os.path.join(ROOT, os.environ.get("WAVEBRDF_BUILD_DIR", "build"))
# WAVEBRDF_TEST_INSTALLED=1: the tests import the installed package (pip install, docs/install.md)
# instead of the build's; those that start the CLI or a child interpreter still use BUILD.
INSTALLED = os.environ.get("WAVEBRDF_TEST_INSTALLED") == "1"
if not INSTALLED:
    sys.path.insert(0, os.path.join(BUILD, "python"))


@pytest.fixture
def cli():
    """The `wavebrdf` executable of the same build as the module."""
    path = os.path.join(BUILD, "bin", "wavebrdf")
    assert os.path.exists(path), "%s is missing; build the wavebrdf_cli target" % path
    return path


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def random_heightfield_exr(tmp_path, rng):
    """random_heightfield_exr(n): the path of an n × n heightfield EXR (heights N(0, 0.2) in texel
    widths, 1 µm texels) in tmp_path."""
    def make(n):
        import wavebrdf as wb

        path = str(tmp_path / "h.exr")
        wb.Heightfield(rng.normal(0.0, 0.2, (n, n)), texel_um=1.0).save_exr(path)
        return path

    return make
