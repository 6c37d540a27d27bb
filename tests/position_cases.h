#pragma once
// The position-error test cases shared by the position calibration tests: a small tile seen at
// stated footprint centres that are off from the true ones, and the rms of found − true offsets.
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "recover_util.h"
#include "recovery/stages.h"
#include "test_util.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::test {

// An edit for detail::recover_heights_edited: the position loop's own settings (stages.h,
// PositionLoopSettings; make_schedule's constants) changed by `change`.
inline std::function<void(detail::Schedule&)> edit_position_loop(
    std::function<void(detail::PositionLoopSettings&)> change) {
    return [change](detail::Schedule& schedule) {
        detail::edit_stages<detail::PositionLoopStage>(schedule,
                                                       [&](detail::PositionLoopStage& s) { change(s.settings); });
    };
}

struct OffCase {
    Heightfield truth;
    std::vector<Observation> observations;      // stated centres
    std::vector<std::array<double, 2>> errors;  // per observation: true − stated, µm (mean 0)
};

// A 12² tile of 2 µm texels (max |H| 0.5 µm), per_side² positions σ_p 3 µm at two
// wavelengths, each position's true centre off by a Gaussian of `rms_texels` per coordinate
// (mean removed), or by `fixed_texels` per coordinate when given (cycled over the positions).
inline OffCase off_case(std::uint64_t seed, double rms_texels, int resolution, int per_side,
                        const std::vector<double>& fixed_texels = {}) {
    const Heightfield surface = peak_scaled_surface(12, 8.0, 0.5, seed);
    OffCase c{surface, {}, {}};
    std::mt19937_64 rng(seed + 7);
    std::uniform_real_distribution<double> jitter(-0.2, 0.2);
    std::normal_distribution<double> normal(0.0, rms_texels * surface.texel_um());
    const double step = 24.0 / per_side;
    std::vector<std::array<double, 2>> stated, error;
    std::size_t next = 0;
    for (int a = 0; a < per_side; ++a)
        for (int b = 0; b < per_side; ++b) {
            stated.push_back({(a + 0.5 + jitter(rng)) * step, (b + 0.5 + jitter(rng)) * step});
            if (fixed_texels.empty()) {
                error.push_back({normal(rng), normal(rng)});
            } else {
                const double ex = fixed_texels[next++ % fixed_texels.size()] * surface.texel_um();
                const double ey = fixed_texels[next++ % fixed_texels.size()] * surface.texel_um();
                error.push_back({ex, ey});
            }
        }
    std::array<double, 2> mean{0.0, 0.0};
    for (const auto& e : error) mean = {mean[0] + e[0] / double(error.size()), mean[1] + e[1] / double(error.size())};
    if (fixed_texels.empty())
        for (auto& e : error) e = {e[0] - mean[0], e[1] - mean[1]};
    for (double lambda : {0.5, 0.6})
        for (std::size_t k = 0; k < stated.size(); ++k) {
            Observation o;
            o.query = test::make_query(Model::OHS, stated[k][0] + error[k][0], stated[k][1] + error[k][1], 3.0);
            o.lambdas_um.assign(1, lambda);
            o.resolution = resolution;
            o.reference = to_reference(render_observation(c.truth, o));
            o.query.x_um = stated[k][0];
            o.query.y_um = stated[k][1];
            c.observations.push_back(std::move(o));
            c.errors.push_back(error[k]);
        }
    return c;
}

// rms over observations and coordinates of (found − true), both with their means removed, µm.
inline double offset_rms(const std::vector<std::array<double, 2>>& found,
                         const std::vector<std::array<double, 2>>& truth) {
    std::array<double, 2> mf{0, 0}, mt{0, 0};
    const double n = double(truth.size());
    for (std::size_t i = 0; i < truth.size(); ++i)
        for (int c = 0; c < 2; ++c) {
            mf[c] += found[i][c] / n;
            mt[c] += truth[i][c] / n;
        }
    double sum = 0.0;
    for (std::size_t i = 0; i < truth.size(); ++i)
        for (int c = 0; c < 2; ++c) {
            const double d = (found[i][c] - mf[c]) - (truth[i][c] - mt[c]);
            sum += d * d;
        }
    return std::sqrt(sum / (2.0 * n));
}

}  // namespace wavebrdf::test
