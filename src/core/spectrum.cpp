#include "wavebrdf/spectrum.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>
#include <string>

#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

struct CmfRow {
    double nm, x, y, z;
};

constexpr CmfRow k_cie1931[] = {
#include "cie1931_table.inc"
};
constexpr int k_cie_rows = static_cast<int>(sizeof(k_cie1931) / sizeof(k_cie1931[0]));
constexpr double k_cie_first_nm = 360.0;
constexpr double k_cie_last_nm = 830.0;
constexpr double k_cie_step_nm = 5.0;
static_assert(k_cie_rows == 95, "CIE 1931 table must have 95 rows (360..830 nm at 5 nm)");

// Rec. 709 primaries and the D65 white point as CIE xy chromaticities (ITU-R BT.709-6).
constexpr double k_primaries_xy[3][2] = {{0.64, 0.33}, {0.30, 0.60}, {0.15, 0.06}};
constexpr double k_d65_xy[2] = {0.3127, 0.3290};

// Bradford cone-response matrix (Lam 1985; as used in CIECAT97s / ICC v4).
const Eigen::Matrix3d& bradford() {
    static const Eigen::Matrix3d m = (Eigen::Matrix3d() << 0.8951, 0.2664, -0.1614,  //
                                      -0.7502, 1.7135, 0.0367,                       //
                                      0.0389, -0.0685, 1.0296)
                                         .finished();
    return m;
}

// XYZ with Y = 1 of the colour with chromaticity (x, y).
Eigen::Vector3d xyz_from_xy(double x, double y) { return {x / y, 1.0, (1.0 - x - y) / y}; }

Eigen::Matrix3d xyz_to_srgb_matrix() {
    // Columns: the primaries' XYZ (Y = 1), scaled so that D65 (Y = 1) becomes RGB (1, 1, 1).
    Eigen::Matrix3d primaries;
    for (int c = 0; c < 3; ++c) primaries.col(c) = xyz_from_xy(k_primaries_xy[c][0], k_primaries_xy[c][1]);
    const Eigen::Vector3d white = xyz_from_xy(k_d65_xy[0], k_d65_xy[1]);
    const Eigen::Vector3d scale = primaries.partialPivLu().solve(white);
    const Eigen::Matrix3d rgb_to_xyz = primaries * scale.asDiagonal();
    return rgb_to_xyz.inverse();
}

// Δλ per sample by the midpoint rule: each distinct wavelength gets half the distance to each
// neighbour, the end ones the full distance to their only neighbour (so an equally spaced
// grid gets equal Δλ); equal wavelengths share their Δλ. A single wavelength gets 1.
std::vector<double> wavelength_widths(const std::vector<double>& lambdas) {
    const std::size_t n = lambdas.size();
    std::vector<double> widths(n, 1.0);
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return lambdas[a] < lambdas[b]; });
    // Groups of equal wavelengths, in increasing order: [group_start[g], group_start[g + 1]).
    std::vector<std::size_t> group_start;
    for (std::size_t i = 0; i < n; ++i)
        if (i == 0 || lambdas[order[i]] != lambdas[order[i - 1]]) group_start.push_back(i);
    const std::size_t groups = group_start.size();
    group_start.push_back(n);
    if (groups == 1) return std::vector<double>(n, 1.0 / static_cast<double>(n));
    auto value = [&](std::size_t g) { return lambdas[order[group_start[g]]]; };
    for (std::size_t g = 0; g < groups; ++g) {
        double width;
        if (g == 0)
            width = value(1) - value(0);
        else if (g + 1 == groups)
            width = value(g) - value(g - 1);
        else
            width = 0.5 * (value(g + 1) - value(g - 1));
        const std::size_t members = group_start[g + 1] - group_start[g];
        for (std::size_t i = group_start[g]; i < group_start[g + 1]; ++i)
            widths[order[i]] = width / static_cast<double>(members);
    }
    return widths;
}

}  // namespace

std::array<double, 3> cie1931_xyz(double lambda_um) {
    const double nm = lambda_um * 1000.0;
    if (!(nm >= k_cie_first_nm && nm <= k_cie_last_nm)) return {0.0, 0.0, 0.0};
    // Linear interpolation between the two table rows around nm.
    const double pos = (nm - k_cie_first_nm) / k_cie_step_nm;
    const int i = std::min(static_cast<int>(pos), k_cie_rows - 2);
    const double t = pos - static_cast<double>(i);
    const CmfRow& a = k_cie1931[i];
    const CmfRow& b = k_cie1931[i + 1];
    return {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
}

std::vector<double> spectral_wavelengths_um(int count) {
    if (count < 1 || count > k_max_spectral_samples)
        throw std::invalid_argument("spectral sample count " + std::to_string(count) +
                                    " is out of range; expected 1 to " + std::to_string(k_max_spectral_samples));
    std::vector<double> lambdas(static_cast<std::size_t>(count));
    const double step = 0.47 / static_cast<double>(count);
    for (int k = 0; k < count; ++k) lambdas[static_cast<std::size_t>(k)] = 0.36 + (static_cast<double>(k) + 0.5) * step;
    return lambdas;
}

std::array<double, 9> xyz_to_linear_srgb() {
    const Eigen::Matrix3d m = xyz_to_srgb_matrix();
    std::array<double, 9> out{};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(3 * r + c)] = m(r, c);
    return out;
}

std::vector<double> spectral_to_srgb_weights(const std::vector<double>& lambdas_um) {
    if (lambdas_um.empty()) throw std::invalid_argument("spectral wavelength list is empty; expected at least one");
    for (std::size_t k = 0; k < lambdas_um.size(); ++k)
        if (!std::isfinite(lambdas_um[k]) || lambdas_um[k] <= 0.0)
            throw std::domain_error("wavelength " + std::to_string(k) + " is " + format_shortest(lambdas_um[k]) +
                                    " um; expected a finite value > 0");
    const std::size_t n = lambdas_um.size();
    const std::vector<double> widths = wavelength_widths(lambdas_um);

    // Riemann sum of the colour-matching functions at the sampled wavelengths.
    Eigen::Matrix3Xd xyz(3, static_cast<Eigen::Index>(n));
    for (std::size_t k = 0; k < n; ++k) {
        const std::array<double, 3> cmf = cie1931_xyz(lambdas_um[k]);
        for (int c = 0; c < 3; ++c) xyz(c, static_cast<Eigen::Index>(k)) = cmf[static_cast<std::size_t>(c)] * widths[k];
    }
    // Normalise so that a constant spectrum 1 has Y = 1.
    const double y_sum = xyz.row(1).sum();
    if (!(y_sum > 0.0))
        throw std::domain_error("sampled white has Y = " + format_shortest(y_sum) +
                                "; expected > 0 (are the wavelengths within 0.36-0.83 um?)");
    xyz /= y_sum;

    // Bradford adaptation of the sampled white (≈ equal energy) to D65, so that a constant
    // spectrum stays achromatic in sRGB.
    const Eigen::Vector3d white = xyz.rowwise().sum();
    const Eigen::Vector3d d65 = xyz_from_xy(k_d65_xy[0], k_d65_xy[1]);
    const Eigen::Matrix3d& m = bradford();
    const Eigen::Vector3d cone_white = m * white;
    const Eigen::Vector3d cone_d65 = m * d65;
    for (int c = 0; c < 3; ++c)
        if (!(std::abs(cone_white(c)) > 1e-12 * std::abs(cone_d65(c))))
            throw std::domain_error("sampled white XYZ (" + format_shortest(white(0)) + ", " +
                                    format_shortest(white(1)) + ", " + format_shortest(white(2)) +
                                    ") has a zero Bradford cone response; expected a white "
                                    "that can be adapted to D65");
    const Eigen::Matrix3d adapt = m.inverse() * cone_d65.cwiseQuotient(cone_white).asDiagonal() * m;

    const Eigen::Matrix3Xd rgb = xyz_to_srgb_matrix() * adapt * xyz;
    std::vector<double> weights(3 * n);
    for (int c = 0; c < 3; ++c)
        for (std::size_t k = 0; k < n; ++k)
            weights[static_cast<std::size_t>(c) * n + k] = rgb(c, static_cast<Eigen::Index>(k));
    return weights;
}

std::vector<double> spectral_mix_weights(const std::vector<double>& lambdas_um) {
    if (lambdas_um.size() == 1) return {1.0, 1.0, 1.0};
    return spectral_to_srgb_weights(lambdas_um);
}

namespace {

std::size_t check_mix(const std::vector<double>& mix, std::size_t wavelength, std::size_t rgb_size,
                      std::size_t pixels) {
    const std::size_t count = mix.size() / 3;
    if (count == 0 || mix.size() != 3 * count)
        throw std::invalid_argument("spectral mix has " + std::to_string(mix.size()) +
                                    " entries; expected 3 x the number of wavelengths");
    if (wavelength >= count)
        throw std::invalid_argument("wavelength index " + std::to_string(wavelength) +
                                    " is out of range; expected below " + std::to_string(count));
    if (rgb_size != 3 * pixels)
        throw std::invalid_argument("RGB values have " + std::to_string(rgb_size) + " entries; expected 3 x " +
                                    std::to_string(pixels) + " pixels");
    return count;
}

}  // namespace

template <typename Float>
void mix_spectral_to_rgb(const std::vector<double>& mix, std::size_t wavelength, const std::vector<Float>& slice,
                         std::vector<Float>& rgb) {
    const std::size_t pixels = slice.size();
    const std::size_t count = check_mix(mix, wavelength, rgb.size(), pixels);
    const Float wr = Float(mix[wavelength]), wg = Float(mix[count + wavelength]),
                wb = Float(mix[2 * count + wavelength]);
    for (std::size_t at = 0; at < pixels; ++at) {
        rgb[3 * at] += wr * slice[at];
        rgb[3 * at + 1] += wg * slice[at];
        rgb[3 * at + 2] += wb * slice[at];
    }
}

template <typename Float>
void mix_spectral_to_rgb_adjoint(const std::vector<double>& mix, std::size_t wavelength,
                                 const std::vector<double>& rgb_weights, std::vector<Float>& weights, double scale) {
    const std::size_t pixels = rgb_weights.size() / 3;
    const std::size_t count = check_mix(mix, wavelength, rgb_weights.size(), pixels);
    const double wr = mix[wavelength], wg = mix[count + wavelength], wb = mix[2 * count + wavelength];
    weights.resize(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
        double sum = 0.0;
        sum += wr * rgb_weights[3 * p];
        sum += wg * rgb_weights[3 * p + 1];
        sum += wb * rgb_weights[3 * p + 2];
        weights[p] = Float(scale * sum);
    }
}

template void mix_spectral_to_rgb<float>(const std::vector<double>&, std::size_t, const std::vector<float>&,
                                         std::vector<float>&);
template void mix_spectral_to_rgb<double>(const std::vector<double>&, std::size_t, const std::vector<double>&,
                                          std::vector<double>&);
template void mix_spectral_to_rgb_adjoint<float>(const std::vector<double>&, std::size_t, const std::vector<double>&,
                                                 std::vector<float>&, double);
template void mix_spectral_to_rgb_adjoint<double>(const std::vector<double>&, std::size_t, const std::vector<double>&,
                                                  std::vector<double>&, double);

}  // namespace wavebrdf
