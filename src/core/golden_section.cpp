#include "core/golden_section.h"

#include <algorithm>
#include <cmath>

namespace wavebrdf::detail {

double golden_section_minimum(const std::function<double(double)>& f, double lo, double hi, int evaluations,
                              double* value) {
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    double f1 = f(x1), f2 = f(x2);
    for (int k = 2; k < std::max(evaluations, 3); ++k) {
        if (f1 <= f2) {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    const bool first = f1 <= f2;
    if (value) *value = first ? f1 : f2;
    return first ? x1 : x2;
}

}  // namespace wavebrdf::detail
