// The cost model of the automatic path choice (forward/path_cost.h).
#include "forward/path_cost.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "forward/fft_engine.h"
#include "wavebrdf/constants.h"

namespace wavebrdf::detail {

namespace {

// Measured constants (path_cost.h, docs/fft_path.md).
constexpr double k_separable_flops_per_s = 85e9;
constexpr double k_factor_entry_s = 1e-9;
constexpr double k_spread_point_s = 1e-9;
constexpr double k_fft_point_log_s = 0.37e-9;
constexpr double k_grid_point_s = 1e-9;

// The grid size FftEngine would choose on one axis (its layout(), with every spectrum centre
// somewhere in ±b_max): M > max(hi, n − 1 − lo) over the kept kernels' spectra.
double axis_need(int n, double u0, double du, double b_max, double r) {
    const double c_hi = std::min((b_max - u0) / du, double(n - 1) + r);  // centre −b, in steps
    const double c_lo = std::max((-b_max - u0) / du, -r);
    const double hi = std::max(double(n - 1), c_hi + r), lo = std::min(0.0, c_lo - r);
    return std::max(hi, double(n - 1) - lo);
}

}  // namespace

FieldPathCost field_path_cost(const FieldPathInputs& in) {
    if (in.n < 1) throw std::invalid_argument("path cost: slice size " + std::to_string(in.n) + "; expected ≥ 1");
    if (!(in.lambda_um > 0.0) || !std::isfinite(in.lambda_um) || !(in.texel_um > 0.0) || !std::isfinite(in.texel_um))
        throw std::invalid_argument("path cost: wavelength " + std::to_string(in.lambda_um) + " µm, texel " +
                                    std::to_string(in.texel_um) + " µm; expected both > 0");
    if (!std::isfinite(in.max_slope) || !std::isfinite(in.shift_scale) || !(in.tolerance > 0.0) ||
        !std::isfinite(in.omega_ix) || !std::isfinite(in.omega_iy))
        throw std::invalid_argument("path cost: a non-finite slope, shift scale, light or tolerance");
    const double n = in.n, k = double(in.kernels), views = double(std::max<std::size_t>(in.views, 1));
    FieldPathCost cost;
    cost.separable_s = views * 8.0 * n * n * k / k_separable_flops_per_s + (1.0 + views) * n * k * k_factor_entry_s;

    // The FFT engine's grid: as FftEngine (t = tolerance / 4, R_x and R_u from it).
    const double sigma = in.texel_um / 2.0, log_t = std::log(4.0 / std::min(in.tolerance, 1e-2));
    const double radius_x = sigma * std::sqrt(2.0 * log_t);
    const double radius_u = std::sqrt(log_t / (2.0 * k_pi * k_pi * sigma * sigma));
    const double du = 2.0 / (n * in.lambda_um), r = radius_u / du;
    const double b_max = std::abs(in.shift_scale) * 2.0 / in.lambda_um * std::abs(in.max_slope);
    const double u0x = (in.omega_ix + slice_omega(0, in.n)) / in.lambda_um;
    const double u0y = (in.omega_iy + slice_omega(0, in.n)) / in.lambda_um;
    const double mx = double(
        good_fft_size(static_cast<long long>(std::min(1e9, axis_need(in.n, u0x, du, b_max, r))) + 1));
    const double my = double(
        good_fft_size(static_cast<long long>(std::min(1e9, axis_need(in.n, u0y, du, b_max, r))) + 1));
    const double period = 1.0 / du;
    const double span_x = std::floor(2.0 * radius_x * mx / period) + 1.0,
                 span_y = std::floor(2.0 * radius_x * my / period) + 1.0;
    const double points = mx * my;
    cost.fft_s = views * (k * span_x * span_y * k_spread_point_s +
                          points * std::log2(std::max(points, 2.0)) * k_fft_point_log_s + points * k_grid_point_s);
    cost.fft_grid = static_cast<int>(std::min(std::max(mx, my), 2e9));
    cost.fft_span = static_cast<int>(std::min(std::max(span_x, span_y), 2e9));
    return cost;
}

RenderPath choose_field_path(const FieldPathInputs& inputs) {
    const FieldPathCost cost = field_path_cost(inputs);
    return cost.fft_s < cost.separable_s ? RenderPath::Fft : RenderPath::Separable;
}

}  // namespace wavebrdf::detail
