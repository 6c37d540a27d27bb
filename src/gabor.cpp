#include "wavebrdf/gabor.h"

#include <cmath>

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
    const int reach = static_cast<int>(std::ceil(radius_um / texel_um)) + 1;
    if (2 * reach + 1 >= count) {
        for (int i = 0; i < count; ++i)
            if (std::abs(periodic_offset(i, centre_um, texel_um, count)) <= radius_um) out.push_back(i);
        return out;
    }
    const int centre = static_cast<int>(std::floor(centre_um / texel_um));
    for (int di = -reach; di <= reach; ++di) {
        int i = (centre + di) % count;
        if (i < 0) i += count;
        if (std::abs(periodic_offset(i, centre_um, texel_um, count)) <= radius_um) out.push_back(i);
    }
    return out;
}

}  // namespace

double window_weight(double distance_sq_um2, double sigma_p_um) {
    static const double inv_sqrt_pi = 1.0 / std::sqrt(std::acos(-1.0));
    return inv_sqrt_pi / sigma_p_um * std::exp(-distance_sq_um2 / (2.0 * sigma_p_um * sigma_p_um));
}

FootprintKernels footprint_kernels(const Heightfield& hf, double x_um, double y_um,
                                   double sigma_p_um) {
    const double w = hf.texel_um();
    const double radius = 3.0 * sigma_p_um;
    const std::vector<int> rows = indices_within(x_um, radius, w, hf.rows());
    const std::vector<int> cols = indices_within(y_um, radius, w, hf.cols());

    FootprintKernels k;
    k.sigma_um = 0.5 * w;
    const std::size_t reserve = rows.size() * cols.size();
    for (auto* v : {&k.dx_um, &k.dy_um, &k.weight, &k.height_um, &k.slope_x, &k.slope_y})
        v->reserve(reserve);
    k.row.reserve(reserve);
    k.col.reserve(reserve);
    for (int i : rows) {
        const double dx = periodic_offset(i, x_um, w, hf.rows());
        for (int j : cols) {
            const double dy = periodic_offset(j, y_um, w, hf.cols());
            const double d2 = dx * dx + dy * dy;
            // The model's cut: the reference drops kernels farther than 3σ_p.
            if (d2 > radius * radius) continue;
            const auto s = hf.slope(i, j);
            k.row.push_back(i);
            k.col.push_back(j);
            k.dx_um.push_back(dx);
            k.dy_um.push_back(dy);
            k.weight.push_back(window_weight(d2, sigma_p_um) * w * w);
            k.height_um.push_back(hf.height_um(i, j));
            k.slope_x.push_back(s[0]);
            k.slope_y.push_back(s[1]);
        }
    }
    return k;
}

}  // namespace wavebrdf
