#pragma once
// The pictures of a run directory (report.png; curves.png for an inversion), drawn by the
// Python package: `python3 -m wavebrdf.report DIR`, started without a shell.
#include <string>

#include "wavebrdf/run_directory.h"

namespace wavebrdf::cli {

// Draws the report of the run of `kind` in `dir` with `PYTHON -m wavebrdf.report --quiet DIR`
// (DIR made absolute, one argument whatever its characters). PYTHON is $WAVEBRDF_PYTHON when
// set, else /usr/bin/python3 (the interpreter with Debian's NumPy and matplotlib), else the
// first python3 on PATH. The package is looked up next to the executable, <bin>/../python (the
// build tree's build/python, whatever the source tree), then where `cmake --install` puts it
// (<prefix>/lib/wavebrdf/python from <prefix>/bin/wavebrdf; docs/install.md), the first found
// put first on the child's PYTHONPATH; when neither holds it, wherever the interpreter finds
// wavebrdf on its own path (a pip-installed package). Returns true
// when the report was drawn; otherwise prints one line, "wavebrdf: warning: report.png not
// drawn: WHY (the run's data are in DIR)", WHY naming what is missing (the interpreter, numpy,
// matplotlib) or the plotter's exit status, and returns false. Never throws: the run's data
// are written already, so the command still succeeds.
bool draw_report(RunKind kind, const std::string& dir);

}  // namespace wavebrdf::cli
