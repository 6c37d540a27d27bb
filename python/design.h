#pragma once
// Surface design (design_run.h) for Python, and what design() and design_plate() share.
#include <array>
#include <cstdint>
#include <string>

#include "common.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/run_directory.h"

namespace wavebrdf::python {

void bind_design(py::module_& m);

// The options design() and design_plate() take alike, set on `o` as the CLI sets them: the view
// and its cone, the tile and its levels, the fabrication errors, the seed, the schedule and the
// memory limit. ValueError (the library's) for a bad fabrication_error.
void set_common_design_options(DesignOptions& o, const py::object& view, double view_cone, int size, double texel_um,
                               double height_range_um, int levels, double level_step_um,
                               const std::string& fabrication_error, std::uint64_t seed, int iterations,
                               int refine_passes, double max_memory_gb);

// design.json's warnings (a limit the exported relief breaks, a dim colour; `info` its parsed
// dict) as Python UserWarnings, each "design: …".
void warn_design_warnings(const py::object& info);

// Runs `run()` without the GIL (Ctrl-C interrupts it): with `out` a path, its run directory is
// checked first (new or empty, or a design's with force) and `write(dir, result)` fills it after.
template <typename Run, typename Write>
auto run_design_into(const py::object& out, bool force, Run run, Write write) {
    const std::string dir = out.is_none() ? std::string()
                                          : py::module_::import("os").attr("fspath")(out).cast<std::string>();
    InterruptibleRelease release;
    if (!dir.empty()) check_run_directory(RunKind::Design, dir, force, "out");
    auto result = run();
    if (!dir.empty()) write(dir, result);
    return result;
}

}  // namespace wavebrdf::python
