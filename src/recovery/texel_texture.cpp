#include "wavebrdf/texel_texture.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "wavebrdf/text.h"

namespace wavebrdf {

TexelTexture texel_texture(const Heightfield& estimate, double sigma_um) {
    if (!(std::isfinite(sigma_um) && sigma_um > 0.0))
        throw std::invalid_argument("texel_texture: sigma " + std::to_string(sigma_um) +
                                    " um is invalid; expected a finite value > 0");
    TexelTexture t;
    const int rows = estimate.rows(), cols = estimate.cols();
    const double texels = double(rows) * double(cols);
    double mean = 0.0, square = 0.0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) mean += estimate.height_um(i, j);
    mean /= texels;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) square += (estimate.height_um(i, j) - mean) * (estimate.height_um(i, j) - mean);
    t.rms_height_um = std::sqrt(square / texels);
    t.threshold_um = std::max(k_texture_sigmas * sigma_um, t.rms_height_um);
    double total = 0.0, flagged = 0.0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            std::array<double, 9> window;
            std::size_t k = 0;
            for (int di = -1; di <= 1; ++di)
                for (int dj = -1; dj <= 1; ++dj) window[k++] = estimate.height_um(i + di, j + dj);
            std::nth_element(window.begin(), window.begin() + 4, window.end());
            const double d = estimate.height_um(i, j) - window[4];
            total += d * d;
            if (std::abs(d) > t.threshold_um) {
                ++t.texels;
                flagged += d * d;
            }
        }
    t.fraction = double(t.texels) / texels;
    t.power_share = total > 0.0 ? flagged / total : 0.0;
    return t;
}

void add_texel_texture(ConvergenceCheck& check, const Heightfield& estimate, double sigma_relative,
                       double range_um, const std::string& source) {
    if (!(std::isfinite(sigma_relative) && sigma_relative > 0.0) || !(range_um > 0.0)) return;
    const TexelTexture t = texel_texture(estimate, sigma_relative * range_um);
    check.texture_sigma_relative = sigma_relative;
    check.texture_sigma_source = source;
    check.texture_texels = t.texels;
    check.texture_fraction = t.fraction;
    check.texture_power_share = t.power_share;
    const double likely = k_texture_error_factor * sigma_relative;
    check.texture_warned = t.fraction >= k_texture_fraction && likely > k_predicted_error_limit;
    if (!check.texture_warned) return;
    check.converged = false;
    check.reasons.push_back(
        std::string(check.misfit_failed ? "" : "the misfit is on the photon-noise floor, but ") +
        format_number(100.0 * t.fraction, "%.3g") + " % of the texels (" + std::to_string(t.texels) +
        ") stand off their 3x3 median by more than the estimate's rms height and " +
        format_number(k_texture_sigmas, "%.0f") + " sigma (" + format_number(1e3 * t.threshold_um, "%.3g") +
        " nm; sigma from the " + source + "), holding " + format_number(100.0 * t.power_share, "%.3g") +
        " % of the estimate's texel-scale power: texel-scale spikes, pits or a binary texture, on which the "
        "recovery's error has been measured at about " +
        format_number(k_texture_error_factor, "%.0f") + "x its error bars (here " +
        format_number(100.0 * likely, "%.3g") + " % of the height range, against the target " +
        format_number(100.0 * k_predicted_error_limit, "%.0f") +
        " %) and it ends in a local minimum there (docs/surfaces.md, \"Spikes\"; more exposures narrow it slowly)");
}

}  // namespace wavebrdf
