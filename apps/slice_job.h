#pragma once
// The work shared by `render` and `genbrdf`: render an RGB slice with a progress bar and
// write it (EXR and/or PNG), failing before the long work when an output is unwritable.
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"

namespace wavebrdf::cli {

struct SliceJob {
    std::vector<double> lambdas_um;  // one: monochrome; several: spectral → sRGB
    int resolution = 256;
    RenderOptions options;
    bool use_double = false;
    std::string out_exr;      // may be empty when png is given
    bool with_alpha = false;  // genBrdf's RGBA layout
    std::string png;
    double exposure = 0.0;
    bool tonemap = false;
    bool quiet = false;
    // Recorded in the slice EXR's attributes (io.h SliceAttributes).
    std::string heightfield_file;  // "" when none
    std::string made_by;           // "wavebrdf render", "wavebrdf genbrdf"
};

void run_slice_job(const Heightfield& heightfield, const Query& query, SliceJob job);

}  // namespace wavebrdf::cli
