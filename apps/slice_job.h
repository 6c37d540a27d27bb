#pragma once
// The work shared by `render` and `genbrdf`: render an RGB slice with a progress bar and
// write it (EXR and/or PNG), failing before the long work when an output is unwritable; and
// the preview options the two share.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/preview.h"

namespace wavebrdf::cli {

struct SliceJob {
    std::vector<double> lambdas_um;  // one: monochrome; several: spectral → sRGB
    int resolution = 256;
    RenderOptions options;
    bool use_double = false;
    std::string out_exr;      // may be empty when png is given
    bool with_alpha = false;  // genBrdf's RGBA layout
    std::string png;
    PreviewOptions preview;  // checked before the render
    // Negative linear-sRGB values of a spectral slice (colours outside the sRGB gamut, model.md)
    // set to 0 in every output; false keeps them.
    bool clip_negative = false;
    bool quiet = false;
    // Recorded in the slice EXR's attributes (io.h SliceAttributes).
    std::string heightfield_file;  // "" when none
    std::string made_by;           // "wavebrdf render", "wavebrdf genbrdf"
};

// The preview options as given on a command line (add_preview_options fills them).
struct PreviewArgs {
    bool log = false;
    double log_decades = 5.0;  // a grating's orders (down to 3.3 decades) at a third of full scale, docs/cli.md
    double exposure = 0.0;
    bool reinhard = false;
    bool false_colour = false;
    bool colour_bar = false;  // given to be explicit: the bar is on unless --no-colour-bar
    bool no_colour_bar = false;
    bool no_axes = false;
    std::string window;             // --window x0,x1,y0,y1 (ω), "" for the whole slice
    std::string negative = "keep";  // --negative keep|clip (SliceJob::clip_negative)
    CLI::Option* log_decades_option = nullptr;
    CLI::Option* exposure_option = nullptr;
    CLI::Option* reinhard_option = nullptr;
};

// Adds --log, --log-decades, --exposure, --reinhard, --false-colour, --colour-bar,
// --no-colour-bar, --no-axes, --window and --negative to `cmd`; `args` must outlive the parse
// (keep it in the command's shared arguments).
void add_preview_options(CLI::App* cmd, PreviewArgs& args);

// The options for the library: the log scale unless --exposure or --reinhard asks for the linear
// one (they exclude --log and --log-decades); the bar labelled with the slice unit. Throws
// std::domain_error naming the flag for a bad --log-decades or --exposure.
PreviewOptions to_preview_options(const PreviewArgs& args);

// --negative: true for clip, false for keep; std::invalid_argument naming the value otherwise.
bool clip_negative_option(const PreviewArgs& args);

void run_slice_job(const Heightfield& heightfield, const Query& query, SliceJob job);

}  // namespace wavebrdf::cli
