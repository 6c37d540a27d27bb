#include "wavebrdf/lobe.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/constants.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/model.h"
#include "wavebrdf/version.h"

namespace wavebrdf {
namespace {


std::string shortest(double value) {
    std::ostringstream out;
    out.precision(10);
    out << value;
    return out.str();
}

void check_alpha(double alpha, const char* name) {
    if (!(alpha >= 1e-3 && alpha <= 4.0))
        throw std::invalid_argument(std::string(name) + " " + shortest(alpha) + " is outside 0.001 ... 4");
}

}  // namespace

LobeDistribution parse_lobe_distribution(const std::string& text) {
    if (text == "ggx" || text == "GGX") return LobeDistribution::ggx;
    if (text == "beckmann" || text == "Beckmann") return LobeDistribution::beckmann;
    throw std::invalid_argument("distribution '" + text + "' is unknown; expected ggx or beckmann");
}

const char* to_string(LobeDistribution distribution) {
    return distribution == LobeDistribution::ggx ? "ggx" : "beckmann";
}

void validate(const Lobe& lobe) {
    check_alpha(lobe.alpha_x, "alpha_x");
    check_alpha(lobe.alpha_y, "alpha_y");
    if (!(lobe.fresnel_f0 >= 0.0 && lobe.fresnel_f0 <= 1.0))
        throw std::invalid_argument("fresnel_f0 " + shortest(lobe.fresnel_f0) + " is outside 0 ... 1");
}

double lobe_distribution(const Lobe& lobe, double hx, double hy, double hz) {
    if (!(hz > 0.0)) return 0.0;
    const double ax = lobe.alpha_x, ay = lobe.alpha_y;
    // tan²θ_h stretched by the roughness, times cos²θ_h: the slope (x/z, y/z) scaled per axis.
    const double t = hx * hx / (ax * ax) + hy * hy / (ay * ay);
    const double z2 = hz * hz;
    if (lobe.distribution == LobeDistribution::ggx) {
        // Walter 2007 eq. 33, anisotropic: 1 / (π α_x α_y (t + cos²θ)²).
        const double s = t + z2;
        return 1.0 / (k_pi * ax * ay * s * s);
    }
    // Walter 2007 eq. 25, anisotropic: exp(−tan²θ stretched) / (π α_x α_y cos⁴θ).
    return std::exp(-t / z2) / (k_pi * ax * ay * z2 * z2);
}

double lobe_lambda(const Lobe& lobe, double x, double y, double z) {
    if (!(z > 0.0)) return 0.0;
    // α(φ) tan θ = sqrt(x² α_x² + y² α_y²) / z; a = 1 / (α(φ) tan θ).
    const double alpha_tan = std::sqrt(x * x * lobe.alpha_x * lobe.alpha_x + y * y * lobe.alpha_y * lobe.alpha_y) / z;
    if (alpha_tan == 0.0) return 0.0;
    if (lobe.distribution == LobeDistribution::ggx) return 0.5 * (std::sqrt(1.0 + alpha_tan * alpha_tan) - 1.0);
    const double a = 1.0 / alpha_tan;
    return 0.5 * (std::erf(a) - 1.0) + std::exp(-a * a) / (2.0 * a * std::sqrt(k_pi));
}

double lobe_brdf(const Lobe& lobe, double omega_i_x, double omega_i_y, double omega_o_x, double omega_o_y) {
    const double si = omega_i_x * omega_i_x + omega_i_y * omega_i_y;
    const double so = omega_o_x * omega_o_x + omega_o_y * omega_o_y;
    if (!(si < 1.0) || !(so < 1.0)) return 0.0;
    const double iz = std::sqrt(1.0 - si), oz = std::sqrt(1.0 - so);
    double hx = omega_i_x + omega_o_x, hy = omega_i_y + omega_o_y, hz = iz + oz;
    const double norm = std::sqrt(hx * hx + hy * hy + hz * hz);
    hx /= norm;
    hy /= norm;
    hz /= norm;
    const double cos_d = omega_i_x * hx + omega_i_y * hy + iz * hz;  // ω_i · h = ω_o · h
    const double f0 = lobe.fresnel_f0;
    const double fresnel = f0 >= 1.0 ? 1.0 : f0 + (1.0 - f0) * std::pow(1.0 - cos_d, 5.0);
    // Height-correlated Smith masking-shadowing: symmetric in ω_i and ω_o, so f_r is reciprocal.
    const double g2 = 1.0 / (1.0 + lobe_lambda(lobe, omega_i_x, omega_i_y, iz) +
                             lobe_lambda(lobe, omega_o_x, omega_o_y, oz));
    return fresnel * lobe_distribution(lobe, hx, hy, hz) * g2 / (4.0 * iz * oz);
}

std::string lobe_description(const Lobe& lobe) {
    return std::string("analytic lobe: ") + to_string(lobe.distribution) + " alpha_x " + shortest(lobe.alpha_x) +
           " alpha_y " + shortest(lobe.alpha_y) + " fresnel_f0 " + shortest(lobe.fresnel_f0) +
           " (Cook-Torrance, height-correlated Smith G2, Schlick F; f_r sampled at the pixel centres)";
}

double estimate_lobe_table_bytes(const LobeTableSpec& spec) {
    const double values = 3.0 * spec.lights.rows * spec.lights.cols * double(spec.resolution) * spec.resolution;
    return 2.0 * 4.0 * values;
}

BrdfTable lobe_table(const LobeTableSpec& spec, double max_memory_gb) {
    validate(spec.lobe);
    BrdfTable table;
    TableSpec& s = table.spec;
    s.query.model = Model::Kirchhoff;
    s.query.x_um = 0.0;
    s.query.y_um = 0.0;
    s.query.sigma_p_um = 1.0;
    s.lambdas_um = {spec.lambda_um};
    s.spectral = false;
    s.resolution = spec.resolution;
    s.lights = spec.lights;
    s.double_precision = true;
    validate(s);  // sizes, wavelength and light grid, before anything is allocated
    require_memory(estimate_lobe_table_bytes(spec), memory_limit(max_memory_gb), "lobe table");
    table.heightfield_rows = 1;
    table.heightfield_cols = 1;
    table.texel_um = 1.0;
    table.vscale = 1.0;
    table.version = k_version;
    table.source = lobe_description(spec.lobe);
    light_grid_axes(s.lights, table.light_x, table.light_y, table.rendered);
    const long long rows = s.lights.rows, cols = s.lights.cols, n = s.resolution;
    table.values.assign(static_cast<std::size_t>(rows * cols * n * n * 3), 0.0f);
#pragma omp parallel for schedule(dynamic)
    for (long long light = 0; light < rows * cols; ++light) {
        if (!table.rendered[static_cast<std::size_t>(light)]) continue;
        const double ix = table.light_x[static_cast<std::size_t>(light / cols)];
        const double iy = table.light_y[static_cast<std::size_t>(light % cols)];
        float* slice = table.values.data() + static_cast<std::size_t>(light * n * n * 3);
        for (int p = 0; p < n; ++p)
            for (const DiskPixel& pixel : DiskRow(p, static_cast<int>(n))) {
                const double f = lobe_brdf(spec.lobe, ix, iy, pixel.ox, pixel.oy);
                // cos θ_o → 0 at the rim: non-finite values are stored as 0, as slices store them.
                const float v = std::isfinite(f) ? static_cast<float>(f) : 0.0f;
                float* out = slice + (static_cast<std::size_t>(p) * static_cast<std::size_t>(n) +
                                      static_cast<std::size_t>(pixel.q)) * 3;
                out[0] = out[1] = out[2] = v;
            }
    }
    return table;
}

}  // namespace wavebrdf
