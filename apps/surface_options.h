#pragma once
// What the commands that take a measured surface share: the conditioning options (convert,
// stats, recover --truth) and reading a surface file into a heightfield through them.
#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <vector>

#include "wavebrdf/conditioning.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf::cli {

// The conditioning options as typed (add_conditioning_options fills them).
struct ConditioningArgs {
    double resample_um = 0.0;
    std::string fill = "none", detrend = "none", crop, periodic = "none";
    CLI::Option* resample_option = nullptr;  // count() > 0 when --resample-um was given
};

// Adds --resample-um W, --fill METHOD, --detrend plane|poly:N, --crop R0,C0,ROWS,COLS and
// --periodic METHOD to `cmd` (in an option group "Conditioning"); `args` must outlive the parse.
void add_conditioning_options(CLI::App* cmd, ConditioningArgs& args);

// The options given, checked (each parser's one-line error names the option).
ConditioningOptions to_conditioning_options(const ConditioningArgs& args);

// Whether any conditioning option was given.
bool any_conditioning(const ConditioningArgs& args);

// `surface` conditioned by `args`; each step printed as "conditioning: <step>" on stderr
// unless `quiet`.
MeasuredSurface condition_and_report(const MeasuredSurface& surface, const ConditioningArgs& args, bool quiet);

// The heightfield of the surface file at `path` (read_surface, with spacing_um for a file that
// states none), conditioned by `args` (reported as above, each step also appended to `steps`),
// on square texels of its (conditioned) spacing with vertical scale `vscale` (default 1):
// to_heightfield's errors (non-square spacing, unmeasured points) name what to add.
Heightfield read_conditioned_heightfield(const std::string& path, const ConditioningArgs& args,
                                         std::optional<double> spacing_um, std::optional<double> vscale, bool quiet,
                                         std::vector<std::string>& steps);

}  // namespace wavebrdf::cli
