// The field stage for GHS-type observations (field_proxy.h).
#include "recovery/field_proxy.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "wavebrdf/text.h"

namespace wavebrdf::detail {

bool has_field_stage(Model model) { return model != Model::Kirchhoff; }

Model field_proxy_model(Model model) {
    switch (model) {
        case Model::OHS:
        case Model::GHS: return Model::OHS;
        case Model::ROHS:
        case Model::RGHS: return Model::ROHS;
        case Model::Kirchhoff: break;
    }
    throw std::invalid_argument(std::string("model ") + to_string(model) +
                                " has no field stage; expected OHS, ROHS, GHS or RGHS");
}

double field_height_scale(const Query& query) {
    if (is_separable(query.model)) return 1.0;
    field_proxy_model(query.model);  // refuses Kirchhoff
    const double wx = query.omega_i[0], wy = query.omega_i[1];
    return std::sqrt(std::max(0.0, 1.0 - wx * wx - wy * wy));
}

FieldProxy common_field_proxy(const std::map<double, std::vector<const Observation*>>& by_lambda,
                              const Communicator& comm) {
    double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity(), proxied = 0.0;
    for (const auto& entry : by_lambda)
        for (const Observation* o : entry.second) {
            const double s = field_height_scale(o->query);
            lo = std::min(lo, s);
            hi = std::max(hi, s);
            if (!is_separable(o->query.model)) proxied = 1.0;
        }
    // Every rank's (a rank may hold none: ±inf, ignored by min/max).
    const std::vector<double> all = all_gather(comm, {lo, hi, proxied});
    for (std::size_t k = 0; k + 2 < all.size(); k += 3) {
        lo = std::min(lo, all[k]);
        hi = std::max(hi, all[k + 1]);
        proxied = std::max(proxied, all[k + 2]);
    }
    FieldProxy proxy;
    proxy.proxied = proxied > 0.0;
    if (!(lo <= hi)) return proxy;
    if (hi - lo > 1e-12)
        throw std::invalid_argument("field stage: observations need height scales " + format_shortest(lo) + " and " +
                                    format_shortest(hi) +
                                    " (cos theta_i of GHS slices under different light, or GHS with oblique OHS); "
                                    "expected one light direction for all GHS/RGHS slices");
    proxy.height_scale = lo;
    return proxy;
}

}  // namespace wavebrdf::detail
