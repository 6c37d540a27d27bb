#pragma once
// Helpers shared by the subcommands: option texts, distinct file names, images of slices.
// (Atomic text files: wavebrdf::write_text_atomically in wavebrdf/io.h.)
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

// "N" or "NxM" → rows, cols (1 … 16384 each). Throws std::invalid_argument naming `option`
// and the text.
void parse_size(const std::string& option, const std::string& text, int& rows, int& cols);

// Throws std::invalid_argument when two of `files` ({option, path}; empty paths are skipped)
// name the same file, compared after std::filesystem::weakly_canonical (so `o.exr`, `./o.exr`
// and `dir/../o.exr` match): an output written over another output, or over an input, would
// silently lose it. The message names both options and the path.
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files);

// (Heights in µm: wavebrdf::heights_um in heightfield.h; slices as images: wavebrdf::to_image
// in io.h.)

// Exposure (in stops) that maps the 99.9th percentile of `slice` to about 4 before Reinhard.
double auto_exposure(const std::vector<double>& slice);

}  // namespace wavebrdf::cli
