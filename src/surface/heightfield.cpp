#include "wavebrdf/heightfield.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/text.h"

namespace wavebrdf {

Heightfield::Heightfield(int rows, int cols, std::vector<double> values, double texel_um, double vscale)
    : m_rows(rows), m_cols(cols), m_values(std::move(values)), m_texel_um(texel_um), m_vscale(vscale) {
    if (rows < 1 || cols < 1)
        throw std::invalid_argument("heightfield size " + std::to_string(rows) + "x" + std::to_string(cols) +
                                    " is empty; expected at least 1x1");
    if (m_values.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
        throw std::invalid_argument(
            "heightfield has " + std::to_string(m_values.size()) +
            " values; expected rows*cols = " + std::to_string(static_cast<long long>(rows) * cols));
    if (!std::isfinite(texel_um) || texel_um <= 0.0)
        throw std::domain_error("texel width " + std::to_string(texel_um) +
                                " um is invalid; expected a finite value > 0");
    if (texel_um < k_min_texel_um || texel_um > k_max_texel_um)
        throw std::domain_error("texel width " + detail::format_shortest(texel_um) + " um is out of range; expected " +
                                detail::format_shortest(k_min_texel_um) + " to " +
                                detail::format_shortest(k_max_texel_um) + " um");
    if (!std::isfinite(vscale))
        throw std::domain_error("vertical scale " + std::to_string(vscale) + " is invalid; expected a finite value");
    if (vscale != 0.0 && (std::abs(vscale) < k_min_vscale || std::abs(vscale) > k_max_vscale))
        throw std::domain_error("vertical scale " + detail::format_shortest(vscale) +
                                " is out of range; expected 0 or " + detail::format_shortest(k_min_vscale) +
                                " <= |vscale| <= " + detail::format_shortest(k_max_vscale));
    for (std::size_t k = 0; k < m_values.size(); ++k)
        if (!std::isfinite(m_values[k]))
            throw std::domain_error("heightfield value at row " + std::to_string(k / static_cast<std::size_t>(cols)) +
                                    ", column " + std::to_string(k % static_cast<std::size_t>(cols)) +
                                    " is not finite; expected finite heights");
}

Heightfield Heightfield::with_values(std::vector<double> values) const {
    return Heightfield(m_rows, m_cols, std::move(values), m_texel_um, m_vscale);
}

Heightfield Heightfield::with_scale(double texel_um, double vscale) const {
    return Heightfield(m_rows, m_cols, m_values, texel_um, vscale);
}

std::vector<double> heights_um(const Heightfield& heightfield) {
    std::vector<double> v = heightfield.values();
    for (double& x : v) x *= heightfield.vscale() * heightfield.texel_um();
    return v;
}

}  // namespace wavebrdf
