#pragma once
// Helpers shared by the subcommands: distinct file names. (Sizes: wavebrdf::parse_size in
// wavebrdf/inversion_run.h; images of slices and atomic text files: wavebrdf/io.h.)
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

// Throws std::invalid_argument when two of `files` ({option, path}; empty paths are skipped)
// name the same file, compared after std::filesystem::weakly_canonical (so `o.exr`, `./o.exr`
// and `dir/../o.exr` match): an output written over another output, or over an input, would
// silently lose it. The message names both options and the path.
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files);

// The texel width (µm) and vertical scale for the heightfield file at `path`: the user's
// value where the option was given (CLI11's count() > 0), else the file's attribute, else the
// default. Prints one line "wavebrdf: warning: <option> X disagrees with <path>'s <attribute>
// Y; using X" on stderr for each given value that differs from the file's.
HeightfieldScale resolve_scale_with_warnings(const std::string& path, std::optional<double> texel_um,
                                             std::optional<double> vscale, const std::string& texel_option,
                                             const std::string& vscale_option, double default_texel_um = 1.0,
                                             double default_vscale = 1.0);

// `value` when `given`, else std::nullopt (for the options above).
inline std::optional<double> if_given(bool given, double value) {
    return given ? std::optional<double>(value) : std::nullopt;
}

}  // namespace wavebrdf::cli
