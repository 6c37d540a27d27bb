#include "core/cholesky.h"

#include <cmath>

namespace wavebrdf::detail {

std::size_t cholesky_in_place(std::vector<double>& a, std::size_t n, bool parallel) {
    for (std::size_t j = 0; j < n; ++j) {
        double* lj = a.data() + j * n;
        double d = lj[j];
        for (std::size_t k = 0; k < j; ++k) d -= lj[k] * lj[k];
        if (!(d > 0.0) || !std::isfinite(d)) {
            lj[j] = d;
            return j;
        }
        const double ljj = std::sqrt(d);
        lj[j] = ljj;
#pragma omp parallel for schedule(static) if (parallel && n - j > 64)
        for (std::size_t i = j + 1; i < n; ++i) {
            double* li = a.data() + i * n;
            double s = li[j];
            for (std::size_t k = 0; k < j; ++k) s -= li[k] * lj[k];
            li[j] = s / ljj;
        }
    }
    return n;
}

void cholesky_solve(const std::vector<double>& l, std::size_t n, std::vector<double>& b) {
    for (std::size_t i = 0; i < n; ++i) {
        double s = b[i];
        for (std::size_t k = 0; k < i; ++k) s -= l[i * n + k] * b[k];
        b[i] = s / l[i * n + i];
    }
    for (std::size_t i = n; i-- > 0;) {
        double s = b[i];
        for (std::size_t k = i + 1; k < n; ++k) s -= l[k * n + i] * b[k];
        b[i] = s / l[i * n + i];
    }
}

}  // namespace wavebrdf::detail
