#pragma once
// Helpers shared by the subcommands: distinct file names. (Sizes: wavebrdf::parse_size in
// wavebrdf/inversion_run.h; images of slices and atomic text files: wavebrdf/io.h.)
#include <CLI/CLI.hpp>
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

// The unit of every slice value the CLI reads or writes, for --help and the colour bar.
constexpr const char* k_slice_unit = "1/sr";
// The line each slice command's --help carries.
constexpr const char* k_slice_unit_help =
    "Slice values are the BRDF f_r in 1/sr (per steradian; spectral slices: its CIE 1931 mix to "
    "linear sRGB, also in 1/sr), pixel (i, j) at the projected outgoing direction "
    "((i+0.5)/n*2-1, (j+0.5)/n*2-1), 0 outside the unit disk.";

// The lines every command's --help ends with: where the model is described, and threads.
constexpr const char* k_common_help =
    "Model, units and conventions: docs/model.md. Threads: --threads N, else the environment "
    "variable OMP_NUM_THREADS, else all cores. Progress and summaries go to stderr (--quiet: none; "
    "warnings and errors still print); stdout is left for data.";

// Adds --threads N to `cmd`: OpenMP's thread count (omp_set_num_threads) for the command, set
// while the command line is parsed, before any work. N is an integer from 1 to 1024;
// otherwise the parse fails with one line naming the value.
void add_threads_option(CLI::App* cmd);

// The thread count of a --threads text: an integer from 1 to 1024 (surrounding blanks
// allowed); throws std::invalid_argument naming the text otherwise.
int parse_threads(const std::string& text);

// Throws std::invalid_argument when two of `files` ({option, path}; empty paths are skipped)
// name the same file, compared after std::filesystem::weakly_canonical (so `o.exr`, `./o.exr`
// and `dir/../o.exr` match): an output written over another output, or over an input, would
// silently lose it. The message names both options and the path.
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files);

}  // namespace wavebrdf::cli
