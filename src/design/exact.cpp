// The exact scalar far field of a texel relief (design.h): the K-level FFT identity and a slow
// direct evaluation of the Kirchhoff integral that shares nothing with it but the definition.
#include <algorithm>
#include <cmath>

#include "wavebrdf/constants.h"
#include <stdexcept>
#include <string>

#include "design/engine.h"
#include "design/relief.h"
#include "wavebrdf/design.h"
#include "wavebrdf/spectrum.h"
#include "core/srgb.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {



void check_relief(const std::vector<double>& heights_um, int size) {
    if (size < 1 || size > 8192)
        throw std::invalid_argument("tile size " + std::to_string(size) + " is out of range; expected 1 to 8192");
    if (heights_um.size() != static_cast<std::size_t>(size) * static_cast<std::size_t>(size))
        throw std::invalid_argument("relief has " + std::to_string(heights_um.size()) + " heights; expected " +
                                    std::to_string(size) + "^2");
    for (double h : heights_um)
        if (!std::isfinite(h)) throw std::domain_error("relief height " + format_shortest(h) + " is not finite");
}

OrderPowers normalised(const detail::OrderSet& orders, const std::vector<double>& flux) {
    OrderPowers p;
    p.lambda_um = orders.lambda_um;
    p.m = orders.m;
    p.n = orders.n;
    p.omega_x.resize(orders.size());
    p.omega_y.resize(orders.size());
    double total = 0.0;
    for (double f : flux) total += f;
    p.kirchhoff_total = total;
    p.power.resize(flux.size());
    for (std::size_t o = 0; o < flux.size(); ++o) p.power[o] = total > 0.0 ? flux[o] / total : 0.0;
    return p;
}

}  // namespace

namespace detail {

LevelRelief to_level_relief(const std::vector<double>& heights_um, int max_levels) {
    LevelRelief r;
    std::vector<double> distinct = heights_um;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    const double lo = distinct.front(), hi = distinct.back();
    r.heights.base_um = lo;
    if (distinct.size() == 1) {
        r.levels = 1;
        r.heights.step_um = 0.0;
        r.level.assign(heights_um.size(), 0);
        return r;
    }
    // Equally spaced already (every relief of --levels)? The smallest gap is the step.
    double step = hi - lo;
    for (std::size_t i = 1; i < distinct.size(); ++i) step = std::min(step, distinct[i] - distinct[i - 1]);
    const double span = (hi - lo) / step;
    bool on_grid = span < max_levels - 0.5;
    if (on_grid)
        for (double d : distinct) {
            const double x = (d - lo) / step;
            if (std::abs(x - std::round(x)) > 1e-6) {
                on_grid = false;
                break;
            }
        }
    if (!on_grid) {
        step = (hi - lo) / (max_levels - 1);
        r.quantised = true;
    }
    r.heights.step_um = step;
    r.levels = static_cast<int>(std::lround((hi - lo) / step)) + 1;
    r.level.resize(heights_um.size());
    for (std::size_t t = 0; t < heights_um.size(); ++t)
        r.level[t] = static_cast<int>(std::lround((heights_um[t] - lo) / step));
    return r;
}

double start_step_um(const std::vector<double>& heights_um) {
    if (heights_um.empty()) return 0.0;
    std::vector<double> d(heights_um);
    std::sort(d.begin(), d.end());
    const double top = d.back();
    double gap = 0.0;
    for (std::size_t i = 1; i < d.size(); ++i)
        if (d[i] - d[i - 1] > 1e-6 * std::max(top, 1e-12) && (gap == 0.0 || d[i] - d[i - 1] < gap)) gap = d[i] - d[i - 1];
    if (gap == 0.0 && top > 0.0) gap = top;  // one height, not 0: level 1
    return gap > 0.0 ? top / std::round(top / gap) : 0.0;
}

std::vector<std::vector<double>> level_flux(const LevelRelief& relief, int size,
                                            const std::vector<OrderSet>& order_sets, double height_scale) {
    const std::size_t n2 = static_cast<std::size_t>(size) * static_cast<std::size_t>(size);
    std::vector<double> masks(n2 * static_cast<std::size_t>(relief.levels), 0.0);
    for (std::size_t t = 0; t < n2; ++t) masks[static_cast<std::size_t>(relief.level[t]) * n2 + t] = 1.0;
    LevelSpectra spectra(size, relief.levels);
    spectra.forward(masks);
    const LevelHeights heights{relief.heights.base_um * height_scale, relief.heights.step_um * height_scale};
    std::vector<std::vector<double>> flux(order_sets.size());
    std::vector<Complex> amplitude;
    for (std::size_t w = 0; w < order_sets.size(); ++w) order_flux(order_sets[w], spectra, heights, amplitude, flux[w]);
    return flux;
}

}  // namespace detail

std::vector<OrderPowers> exact_orders(const std::vector<double>& heights_um, int size, double texel_um,
                                      const std::array<double, 2>& omega_i, const std::vector<double>& lambdas_um,
                                      bool* quantised) {
    check_relief(heights_um, size);
    if (lambdas_um.empty()) throw std::invalid_argument("no wavelengths; expected at least one");
    std::vector<detail::OrderSet> sets;
    for (double lambda : lambdas_um) sets.push_back(detail::make_order_set(size, texel_um, omega_i, lambda));
    const detail::LevelRelief relief = detail::to_level_relief(heights_um, detail::k_exact_max_levels);
    if (quantised) *quantised = relief.quantised;
    const auto flux = detail::level_flux(relief, size, sets, 1.0);
    std::vector<OrderPowers> out;
    for (std::size_t w = 0; w < sets.size(); ++w) {
        OrderPowers p = normalised(sets[w], flux[w]);
        for (std::size_t o = 0; o < p.m.size(); ++o) {
            p.omega_x[o] = -omega_i[0] + sets[w].dx(o);
            p.omega_y[o] = -omega_i[1] + sets[w].dy(o);
        }
        out.push_back(std::move(p));
    }
    return out;
}

std::vector<OrderPowers> direct_orders(const std::vector<double>& heights_um, int size, double texel_um,
                                       const std::array<double, 2>& omega_i, const std::vector<double>& lambdas_um,
                                       int samples) {
    check_relief(heights_um, size);
    if (size > 64) throw std::invalid_argument("direct_orders: tile size " + std::to_string(size) + " > 64");
    if (samples < 1 || samples > 64) throw std::invalid_argument("direct_orders: samples out of range 1 to 64");
    std::vector<OrderPowers> out;
    const double cos_i = std::sqrt(1.0 - omega_i[0] * omega_i[0] - omega_i[1] * omega_i[1]);
    const double period = size * texel_um;
    for (double lambda : lambdas_um) {
        const double k = 2.0 * k_pi / lambda;
        const int reach = static_cast<int>(std::ceil(2.0 * period / lambda)) + 1;
        OrderPowers p;
        p.lambda_um = lambda;
        std::vector<double> flux;
        for (int m = -reach; m <= reach; ++m)
            for (int n = -reach; n <= reach; ++n) {
                const double ox = -omega_i[0] + lambda * m / period, oy = -omega_i[1] + lambda * n / period;
                const double r2 = ox * ox + oy * oy;
                if (!(r2 < 1.0)) continue;
                const double cos_o = std::sqrt(1.0 - r2);
                // (1/L²) ∫ e^{−i k h(x)(cos θ_i + cos θ_o)} e^{−2πi (m x + n y)/L} dx over one period,
                // by the midpoint rule on samples² points per texel.
                std::complex<double> a(0.0, 0.0);
                for (int i = 0; i < size; ++i)
                    for (int j = 0; j < size; ++j) {
                        const double h = heights_um[static_cast<std::size_t>(i) * size + j];
                        const double height_phase = -k * h * (cos_i + cos_o);
                        for (int si = 0; si < samples; ++si)
                            for (int sj = 0; sj < samples; ++sj) {
                                const double x = (i + (si + 0.5) / samples) * texel_um;
                                const double y = (j + (sj + 0.5) / samples) * texel_um;
                                a += std::polar(1.0, height_phase - 2.0 * k_pi * (m * x + n * y) / period);
                            }
                    }
                a /= static_cast<double>(size) * size * samples * samples;
                p.m.push_back(m);
                p.n.push_back(n);
                p.omega_x.push_back(ox);
                p.omega_y.push_back(oy);
                flux.push_back(std::norm(a) * cos_o / cos_i);
            }
        double total = 0.0;
        for (double f : flux) total += f;
        p.kirchhoff_total = total;
        for (double f : flux) p.power.push_back(total > 0.0 ? f / total : 0.0);
        out.push_back(std::move(p));
    }
    return out;
}

std::array<double, 2> xyz_to_uv(const std::array<double, 3>& xyz) {
    const double d = xyz[0] + 15.0 * xyz[1] + 3.0 * xyz[2];
    if (!(d > 0.0)) return {0.0, 0.0};
    return {4.0 * xyz[0] / d, 9.0 * xyz[1] / d};
}

std::array<double, 3> linear_srgb_to_xyz(const std::array<double, 3>& rgb) {
    // The inverse of xyz_to_linear_srgb (spectrum.h), by Cramer's rule.
    const std::array<double, 9> a = xyz_to_linear_srgb();
    const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                       a[2] * (a[3] * a[7] - a[4] * a[6]);
    const std::array<double, 9> inv{(a[4] * a[8] - a[5] * a[7]) / det, (a[2] * a[7] - a[1] * a[8]) / det,
                                    (a[1] * a[5] - a[2] * a[4]) / det, (a[5] * a[6] - a[3] * a[8]) / det,
                                    (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
                                    (a[3] * a[7] - a[4] * a[6]) / det, (a[1] * a[6] - a[0] * a[7]) / det,
                                    (a[0] * a[4] - a[1] * a[3]) / det};
    return {inv[0] * rgb[0] + inv[1] * rgb[1] + inv[2] * rgb[2], inv[3] * rgb[0] + inv[4] * rgb[1] + inv[5] * rgb[2],
            inv[6] * rgb[0] + inv[7] * rgb[1] + inv[8] * rgb[2]};
}

double srgb_decode(double encoded) { return detail::srgb_decode(encoded); }

std::array<double, 3> reflectance_xyz(const std::vector<double>& lambdas_um, const std::vector<double>& reflectance) {
    if (reflectance.size() != lambdas_um.size())
        throw std::invalid_argument("reflectance_xyz: one reflectance per wavelength expected");
    const std::vector<double> mix = spectral_mix_weights(lambdas_um);
    const std::size_t count = lambdas_um.size();
    std::array<double, 3> rgb{0.0, 0.0, 0.0};
    for (int c = 0; c < 3; ++c)
        for (std::size_t l = 0; l < count; ++l) rgb[static_cast<std::size_t>(c)] += mix[c * count + l] * reflectance[l];
    return linear_srgb_to_xyz(rgb);
}

}  // namespace wavebrdf
