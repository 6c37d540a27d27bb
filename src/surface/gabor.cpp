#include "wavebrdf/gabor.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "surface/footprint_offsets.h"
#include "wavebrdf/constants.h"

namespace wavebrdf {

namespace {

// Offset of texel centre `index` from `centre_um` on a circle of `count` texels, wrapped to
// the nearest image in [−P/2, P/2).
double periodic_offset(int index, double centre_um, double texel_um, int count) {
    const double period = count * texel_um;
    double d = (index + 0.5) * texel_um - centre_um;
    d -= period * std::floor(d / period + 0.5);
    return d;
}

// Texel indices along one axis within `radius_um` of `centre_um`, each once.
std::vector<int> indices_within(double centre_um, double radius_um, double texel_um, int count) {
    std::vector<int> out;
    // In double: a footprint many tiles wide must not overflow the texel count.
    const double reach_texels = std::ceil(radius_um / texel_um) + 1.0;
    if (2.0 * reach_texels + 1.0 >= static_cast<double>(count)) {
        for (int i = 0; i < count; ++i)
            if (std::abs(periodic_offset(i, centre_um, texel_um, count)) <= radius_um) out.push_back(i);
        return out;
    }
    const int reach = static_cast<int>(reach_texels);
    // centre_um is within one period (footprint_kernels reduced it), so this fits an int.
    const int centre = static_cast<int>(std::floor(centre_um / texel_um));
    for (int di = -reach; di <= reach; ++di) {
        int i = (centre + di) % count;
        if (i < 0) i += count;
        if (std::abs(periodic_offset(i, centre_um, texel_um, count)) <= radius_um) out.push_back(i);
    }
    return out;
}

// x modulo `period`, in [0, period): std::fmod is exact, so no precision is lost and no
// integer conversion overflows however far from the origin the footprint was placed.
double reduce_periodic(double x, double period) {
    double r = std::fmod(x, period);
    if (r < 0.0) r += period;
    return r < period ? r : 0.0;  // r + period can round up to period for a tiny negative r
}

}  // namespace

double window_weight(double distance_sq_um2, double sigma_p_um) {
    static const double inv_sqrt_pi = 1.0 / std::sqrt(k_pi);
    return inv_sqrt_pi / sigma_p_um * std::exp(-distance_sq_um2 / (2.0 * sigma_p_um * sigma_p_um));
}

void validate_footprint(double sigma_p_um, double period_x_um, double period_y_um) {
    const double longest = std::max(period_x_um, period_y_um);
    const double limit = k_max_sigma_p_periods * longest;
    if (!(sigma_p_um > 0.0) || !(sigma_p_um <= limit)) {
        std::ostringstream out;
        out.precision(10);
        out << "sigma_p " << sigma_p_um << " um is too large for the tile (" << period_x_um << " x " << period_y_um
            << " um); expected 0 < sigma_p <= " << k_max_sigma_p_periods << " x the longer tile period = " << limit
            << " um (the window is cut to one periodic tile: a wider one only fades the slice)";
        throw std::domain_error(out.str());
    }
}

namespace {

// The footprint's walker: visit(i, j, dx, dy, d2) for each texel within 3σ_p of the centre, in
// the order footprint_kernels lists them, after reserve(candidates).
template <typename Reserve, typename Visit>
void for_each_footprint_texel(const Heightfield& hf, double x_in_um, double y_in_um, double sigma_p_um,
                              Reserve&& reserve, Visit&& visit) {
    validate_footprint(sigma_p_um, hf.period_x_um(), hf.period_y_um());
    const double x_um = reduce_periodic(x_in_um, hf.period_x_um());
    const double y_um = reduce_periodic(y_in_um, hf.period_y_um());
    const double w = hf.texel_um();
    const double radius = 3.0 * sigma_p_um;
    const std::vector<int> rows = indices_within(x_um, radius, w, hf.rows());
    const std::vector<int> cols = indices_within(y_um, radius, w, hf.cols());
    reserve(rows.size() * cols.size());
    for (int i : rows) {
        const double dx = periodic_offset(i, x_um, w, hf.rows());
        for (int j : cols) {
            const double dy = periodic_offset(j, y_um, w, hf.cols());
            const double d2 = dx * dx + dy * dy;
            // The model's cut: the reference drops kernels farther than 3σ_p.
            if (d2 > radius * radius) continue;
            visit(i, j, dx, dy, d2);
        }
    }
}

}  // namespace

FootprintKernels footprint_kernels(const Heightfield& hf, double x_in_um, double y_in_um, double sigma_p_um) {
    const double w = hf.texel_um();
    FootprintKernels k;
    k.sigma_um = 0.5 * w;
    for_each_footprint_texel(
        hf, x_in_um, y_in_um, sigma_p_um,
        [&](std::size_t reserve) {
            for (auto* v : {&k.dx_um, &k.dy_um, &k.weight, &k.height_um, &k.slope_x, &k.slope_y}) v->reserve(reserve);
            k.row.reserve(reserve);
            k.col.reserve(reserve);
        },
        [&](int i, int j, double dx, double dy, double d2) {
            const auto s = hf.slope(i, j);
            k.row.push_back(i);
            k.col.push_back(j);
            k.dx_um.push_back(dx);
            k.dy_um.push_back(dy);
            k.weight.push_back(window_weight(d2, sigma_p_um) * w * w);
            k.height_um.push_back(hf.height_um(i, j));
            k.slope_x.push_back(s[0]);
            k.slope_y.push_back(s[1]);
        });
    return k;
}

detail::FootprintOffsets detail::footprint_offsets(const Heightfield& hf, double x_um, double y_um, double sigma_p_um) {
    detail::FootprintOffsets k;
    k.sigma_um = 0.5 * hf.texel_um();
    for_each_footprint_texel(
        hf, x_um, y_um, sigma_p_um,
        [&](std::size_t reserve) {
            for (auto* v : {&k.dx_um, &k.dy_um}) v->reserve(reserve);
            k.row.reserve(reserve);
            k.col.reserve(reserve);
        },
        [&](int i, int j, double dx, double dy, double) {
            k.row.push_back(i);
            k.col.push_back(j);
            k.dx_um.push_back(dx);
            k.dy_um.push_back(dy);
        });
    return k;
}

GaborRepresentation::GaborRepresentation(const Heightfield& hf, double x, double y, double sigma_p)
    : kernels(footprint_kernels(hf, x, y, sigma_p)),
      rows(hf.rows()),
      cols(hf.cols()),
      texel_um(hf.texel_um()),
      vscale(hf.vscale()),
      x_um(x),
      y_um(y),
      sigma_p_um(sigma_p) {}

std::vector<double> GaborRepresentation::heights_from_kernels(const std::vector<double>& height_um,
                                                              std::vector<double> fill) const {
    if (height_um.size() != kernels.size())
        throw std::invalid_argument("kernel heights have " + std::to_string(height_um.size()) +
                                    " values; expected one per kernel (" + std::to_string(kernels.size()) + ")");
    const std::size_t cells = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
    if (fill.size() != cells)
        throw std::invalid_argument("fill has " + std::to_string(fill.size()) +
                                    " values; expected rows*cols = " + std::to_string(cells));
    if (vscale == 0.0)
        throw std::domain_error(
            "GaborRep has vscale = 0: kernel heights H = v * w * h are all 0 and the heights "
            "cannot be recovered; expected vscale != 0");
    const double scale = 1.0 / (vscale * texel_um);
    for (std::size_t k = 0; k < kernels.size(); ++k)
        fill[static_cast<std::size_t>(kernels.row[k]) * static_cast<std::size_t>(cols) +
             static_cast<std::size_t>(kernels.col[k])] = height_um[k] * scale;
    return fill;
}

}  // namespace wavebrdf
