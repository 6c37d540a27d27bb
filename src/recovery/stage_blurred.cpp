// Stage 0, the blurred fit, and σ_p's search at its heights (stages.h).
#include <algorithm>
#include <cmath>

#include "recovery/sigma_search.h"
#include "recovery/stages.h"

namespace wavebrdf::detail {

namespace {

// The observations the blurred fit sees. It sees the slope distribution, nearly the same at
// every wavelength: the longest `wavelengths` (smoothest) suffice. It needs the slope
// distribution everywhere, not the overlap that pins phases down: positions closer than
// 2 σ_p to one already taken are left out (greedy, periodic distance), which buys more
// iterations for the same time. The choice is made on every rank's positions (x, y, σ_p
// per observation, in rank order, the one-process order when each rank holds a block of
// positions), and each rank keeps those of its own observations that were taken.
// White light: the RGB observations, one group.
std::vector<const Observation*> blurred_fit_set(const StageContext& context, int wavelengths) {
    constexpr double spacing_sigma = 2.0;
    const Communicator& comm = context.comm;
    const double period_x = context.rows * context.texel_um, period_y = context.cols * context.texel_um;
    const auto periodic = [](double d, double period) { return d - period * std::floor(d / period + 0.5); };
    std::map<double, std::vector<const Observation*>> white_group;
    if (context.white)
        for (const Observation& o : context.field_observations()) white_group[0.0].push_back(&o);
    const auto& groups = context.white ? white_group : context.by_lambda;
    std::vector<const Observation*> set;
    int taken = 0;
    for (auto it = groups.rbegin(); it != groups.rend(); ++it, ++taken) {
        if (wavelengths > 0 && taken >= wavelengths) break;
        std::vector<double> mine;
        for (const Observation* o : it->second)
            mine.insert(mine.end(), {o->query.x_um, o->query.y_um, o->query.sigma_p_um});
        std::vector<std::size_t> counts;
        const std::vector<double> all = all_gather(comm, mine, &counts);
        std::size_t first_mine = 0;
        for (int r = 0; r < comm.rank(); ++r) first_mine += counts[std::size_t(r)] / 3;
        std::vector<std::size_t> chosen;  // indices of observations in `all`
        for (std::size_t k = 0; 3 * k + 2 < all.size(); ++k) {
            bool close = false;
            for (std::size_t c = 0; c < chosen.size() && !close; ++c) {
                const std::size_t j = chosen[c];
                const double dx = periodic(all[3 * k] - all[3 * j], period_x);
                const double dy = periodic(all[3 * k + 1] - all[3 * j + 1], period_y);
                const double spacing = spacing_sigma * std::min(all[3 * k + 2], all[3 * j + 2]);
                close = dx * dx + dy * dy < spacing * spacing;
            }
            if (!close) chosen.push_back(k);
        }
        for (std::size_t k : chosen)
            if (k >= first_mine && k < first_mine + it->second.size()) set.push_back(it->second[k - first_mine]);
    }
    return set;
}

}  // namespace

bool BlurredFitStage::run(const StageContext& context, RecoveryState& state) const {
    std::vector<const Observation*> set = blurred_fit_set(context, wavelengths);
    // GHS/RGHS: on the separable proxy (its renders cost a fraction of the GHS ones).
    std::vector<Observation> proxies;
    if (context.proxy.proxied) {
        proxies.reserve(set.size());
        for (const Observation* o : set) {
            proxies.push_back(*o);
            proxies.back().query.model = field_proxy_model(o->query.model);
        }
        for (std::size_t k = 0; k < set.size(); ++k) set[k] = &proxies[k];
    }
    state.estimate = fit_blurred(
        set, state.estimate, fit,
        [&](int stage, int it, double loss) {
            return context.report({StageKind::BlurredFit, std::to_string(stage)}, it, loss, nullptr);
        },
        context.comm);
    const double proxy_scale = context.proxy.height_scale;
    if (proxy_scale != 1.0) {
        std::vector<double> h = state.estimate.values();
        for (double& v : h) v /= proxy_scale;
        state.estimate = context.flat.with_values(std::move(h));
    }
    std::vector<Observation>().swap(proxies);
    return !context.stopped() && context.report(StageKind::BlurredResult, 0, 0.0, &state.estimate);
}

bool SigmaPresearchStage::run(const StageContext& context, RecoveryState& state) const {
    state.sigma_scale = presearch_sigma_scale(context.observations, context.observations_total, state.estimate, loss,
                                              calibrate_exposure, context.comm);
    state.calibration.sigma_p_scale = state.calibration.sigma_p_scale_fields = state.sigma_scale;
    return true;
}

}  // namespace wavebrdf::detail
