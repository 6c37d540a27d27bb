#!/usr/bin/env bash
# The Python package as a user installs it (docs/install.md): a fresh virtual environment on
# Debian's interpreter (--system-site-packages: NumPy, PyTorch, matplotlib, tqdm), `pip install
# --no-build-isolation --no-index` of this checkout (offline: setuptools drives the project's
# CMake, setup.py), then a smoke test run from a temporary directory outside the tree: import,
# the version equals the file VERSION, a slice is finite and non-negative, the torch helper's
# gradient, the stubs shipped, `python -m wavebrdf.report --help`, and tests/python's stub and
# progress tests on the installed package. The venv and the build are
# made in a temporary directory and removed; the checkout is left as it was (but for the
# ignored python/wavebrdf.egg-info). WAVEBRDF_PYTHON: the interpreter (default /usr/bin/python3).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
python="${WAVEBRDF_PYTHON:-/usr/bin/python3}"
work="$(mktemp -d "${TMPDIR:-/tmp}/wavebrdf-pip.XXXXXX")"
trap 'rm -rf "$work"' EXIT
start=$(date +%s)

echo "test_pip: venv in $work/venv ($python)"
"$python" -m venv --system-site-packages "$work/venv"
echo "test_pip: pip install --no-build-isolation $root"
# The CMake build in <checkout>/build-pip (ignored, kept): at build/'s depth, so ccache reuses
# the library build/ compiled (same flags, same batches) and only the extension's own sources
# compile anew (scripts/test.sh gives the two builds one cache even under CCACHE_DISABLE).
WAVEBRDF_PIP_BUILD_DIR="$work/build" WAVEBRDF_PIP_CMAKE_DIR="$root/build-pip" "$work/venv/bin/python" -m pip install --no-build-isolation --no-index \
    --disable-pip-version-check "$root"
installed=$(date +%s)

echo "test_pip: smoke test in $work/run"
mkdir "$work/run"
cd "$work/run"
"$work/venv/bin/python" - "$root/VERSION" "$work/venv" <<'PY'
import os
import sys

import numpy as np

import wavebrdf as wb

version_file, venv = sys.argv[1], sys.argv[2]
package = os.path.dirname(os.path.realpath(wb.__file__))
assert package.startswith(os.path.realpath(venv)), "wavebrdf imported from %s, not the venv" % package
with open(version_file, encoding="utf-8") as f:
    assert wb.__version__ == f.read().strip(), wb.__version__
for name in ("_core.pyi", "py.typed"):
    assert os.path.isfile(os.path.join(package, name)), name + " is not installed"

h = np.random.default_rng(1).standard_normal((16, 16)) * 0.3
# One wavelength: f_r itself (1/sr), never negative (a spectral slice's linear sRGB can be, out of gamut).
s = wb.render_slice(h, resolution=16, sigma_p_um=4.0, x_um=8.0, y_um=8.0, lambda_um=0.5)
assert s.shape == (16, 16, 3) and np.isfinite(s).all(), "slice not finite"
assert (s >= 0).all() and s.sum() > 0, "slice has f_r < 0 or is black: min %g, sum %g" % (s.min(), s.sum())

import torch
import wavebrdf.torch as wt

t = torch.tensor(h, requires_grad=True)
wt.render_slice(t, resolution=16, sigma_p_um=4.0, x_um=8.0, y_um=8.0, spectral=4).sum().backward()
assert t.grad is not None and torch.isfinite(t.grad).all() and t.grad.abs().sum() > 0, "bad gradient"

result = wb.invert(size=8, resolution=16, epochs=2, quiet=True)
assert result.epochs == 2 and np.isfinite(result.metrics["loss"]).all()

import wavebrdf.report, wavebrdf.report_invert, wavebrdf.report_recover  # noqa: E401,F401
print("test_pip: wavebrdf %s from %s: import, slice, torch gradient, invert ok" % (wb.__version__, package))
PY
"$work/venv/bin/python" -m wavebrdf.report --help >/dev/null
# The stubs against the installed extension, and its progress display (tests/python, run on
# the installed package: WAVEBRDF_TEST_INSTALLED=1).
WAVEBRDF_TEST_INSTALLED=1 "$work/venv/bin/python" -m pytest -q -p no:cacheprovider \
    "$root/tests/python/test_stubs.py" "$root/tests/python/test_progress.py"
end=$(date +%s)
echo "test_pip: passed (install $((installed - start)) s, smoke test $((end - installed)) s)"
