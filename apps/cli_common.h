#pragma once
// Helpers shared by the subcommands: distinct file names. (Sizes: wavebrdf::parse_size in
// wavebrdf/inversion_run.h; images of slices and atomic text files: wavebrdf/io.h.)
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

}  // namespace wavebrdf::cli
