#pragma once
// Golden-section search for the minimum of a one-dimensional function on a bracket: the
// colour bound's dual (design/colour_bound.cpp) and the σ_p self-calibration
// (recovery/calibration.cpp, sigma_search.cpp) both search this way.
#include <functional>

namespace wavebrdf::detail {

// The x in [lo, hi] where f is smallest, by golden-section search with max(evaluations, 3) calls
// of f; *value (when given) receives f there. Exact for a convex f up to the final bracket's
// width, (hi − lo) · 0.618^(evaluations − 2); a plateau's minimiser stays inside the bracket.
double golden_section_minimum(const std::function<double(double)>& f, double lo, double hi, int evaluations,
                              double* value = nullptr);

}  // namespace wavebrdf::detail
