#pragma once
// Helpers shared by the subcommands: distinct file names. (Sizes: wavebrdf::parse_size in
// wavebrdf/inversion_run.h; images of slices and atomic text files: wavebrdf/io.h.)
#include <CLI/CLI.hpp>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

// The unit of every slice value, short, for the colour bar's label (io.h k_slice_unit says it in full).
constexpr const char* k_slice_unit_label = "1/sr";
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

// "; did you mean X?" for the first word of a CLI11 parse error `message` ("The following
// arguments were not expected: --sigma-p 3") that is near a name `app` knows: an option of the
// subcommand being parsed (a prefix of exactly one, or at most a third of its letters edited);
// with no subcommand parsed, the first word of `args` (the command line after the program)
// that is not an option, near a subcommand ("rendr" → render). "" when none is near.
std::string did_you_mean(const CLI::App& app, const std::string& message, const std::vector<std::string>& args);

// A CLI11 check for a --seed text: an integer from 0 to 2^64 - 1 (CLI11's own conversion
// saturates a larger one to 2^64 - 1 without a word). Returns "" or the reason.
std::string seed_error(const std::string& text);

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

// The rendering path and its error bound as given on a command line (add_render_path_options
// fills them; apply_render_path_options checks them into RenderOptions).
struct RenderPathArgs {
    std::string path = "auto";
    double tolerance = 1e-6;  // RenderOptions' default
};

// Adds --path auto|separable|fft|direct and --tolerance X to `cmd`; `args` must outlive the parse.
void add_render_path_options(CLI::App* cmd, RenderPathArgs& args);

// Sets options.path and options.tolerance from `args`. Throws std::invalid_argument
// "--path 'X' is unknown; expected auto, separable, fft or direct" or std::domain_error
// "--tolerance X is out of range; expected 1e-12 to 1e-2 ..." (whether the path suits the model
// is the library's check, when it renders).
void apply_render_path_options(const RenderPathArgs& args, RenderOptions& options);

// The options invert and recover share in shape. --size NxM (for the generated truth or with
// --observations), --texel-um and --vscale (with --truth: the file's if it says); returns the
// --texel-um and --vscale options (count() > 0 when given). The variables must outlive the parse.
std::pair<CLI::Option*, CLI::Option*> add_grid_options(CLI::App* cmd, std::string& size, double& texel_um,
                                                       double& vscale);
// --light-x, --light-y: the projected light direction.
void add_light_options(CLI::App* cmd, double& light_x, double& light_y);
// --max-memory-gb: the limit on the estimated peak memory (0: the physical memory).
void add_memory_option(CLI::App* cmd, double& max_memory_gb);

// `value` when `given`, else std::nullopt (for the options above).
inline std::optional<double> if_given(bool given, double value) {
    return given ? std::optional<double>(value) : std::nullopt;
}

// Runs a command on the ranks mpiexec started (world_communicator(); one rank without it,
// docs/scale.md): with one rank, `command(world)` as it is. With several, every rank runs it
// inside one agreement (run_agreed), so a failure is printed once, by rank 0 ("wavebrdf: error:
// rank R: …" when rank R failed alone), and every rank ends with ExitStatus{1}; an ExitStatus a
// rank's command throws (e.g. 130 after a stop) is its own exit, after the others finished. A
// failure of one rank amid the command's collective work must end every rank inside the
// library (run_or_abort), since the others never reach the agreement.
void run_on_world(const std::function<void(const Communicator& world)>& command);

}  // namespace wavebrdf::cli
