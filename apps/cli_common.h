#pragma once
// Helpers shared by the subcommands: option texts, atomic text files, images of slices.
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

// "N" or "NxM" → rows, cols (1 … 16384 each). Throws std::invalid_argument naming `option`
// and the text.
void parse_size(const std::string& option, const std::string& text, int& rows, int& cols);

// Writes `text` to `path` through a temporary file and a rename: never a half-written file.
void write_text_atomically(const std::string& path, const std::string& text);

// Heights in µm (v · w · h), row-major.
std::vector<double> heights_um(const Heightfield& heightfield);

// An n × n slice of `channels` (1 or 3) values per pixel as an RGB image (mono → grey).
RgbImage to_image(const std::vector<double>& slice, int n, int channels);

// Exposure (in stops) that maps the 99.9th percentile of `slice` to about 4 before Reinhard.
double auto_exposure(const std::vector<double>& slice);

}  // namespace wavebrdf::cli
