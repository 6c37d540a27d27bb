#pragma once
// RenderOptions' choices as text, for the command line, run.json and Python (brdf.h has the
// options themselves): the path ("auto", "separable", "fft", "direct") and the tolerance's range.
#include <string>

#include "wavebrdf/brdf.h"

namespace wavebrdf {

// The range of RenderOptions::tolerance (relative to the slice's peak), as validate(options,
// model) checks it (slice_plan.h).
constexpr double k_min_render_tolerance = 1e-12;
constexpr double k_max_render_tolerance = 1e-2;

// "auto", "separable", "fft" or "direct" (exactly; lower case) → the path. Throws
// std::invalid_argument "NAME 'TEXT' is unknown; expected auto, separable, fft or direct"
// (`name` is the option the user gave, e.g. "--path" or "path"; TEXT cut to 80 bytes).
// Whether the path suits the model is checked later, by validate(options, model).
RenderPath parse_render_path(const std::string& text, const std::string& name = "path");

// The text parse_render_path reads: "auto", "separable", "fft" or "direct".
const char* to_string(RenderPath path);

// Throws std::domain_error "NAME X is out of range; expected 1e-12 to 1e-2 (an error bound
// relative to the slice peak)" unless k_min_render_tolerance ≤ tolerance ≤
// k_max_render_tolerance (NaN refused).
void validate_render_tolerance(double tolerance, const std::string& name = "tolerance");

}  // namespace wavebrdf
