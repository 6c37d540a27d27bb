// The recovery's sums over observations are exact (src/core/exact_sum.h): the heights do not
// depend on the thread count (nor, tests/mpi_recover_test.cpp, on the number of ranks), and
// every stage hands over a box that holds everything an observation writes.
#include <gtest/gtest.h>
#include <omp.h>

#include <array>
#include <cmath>
#include <vector>

#include "core/exact_sum.h"
#include "test_util.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf {
namespace {

// A 10² tile of 2 µm texels, footprints σ_p = 3 µm (3σ_p = 4.5 texels: most wrap around the
// tile's edges), 4 × 4 positions at one wavelength and 2 × 2 at another, 32² slices.
std::vector<Observation> small_observations(const Heightfield& truth) {
    std::vector<Observation> observations;
    for (double lambda : {0.5, 0.6}) {
        const int per_side = lambda == 0.5 ? 4 : 2;
        for (int a = 0; a < per_side; ++a)
            for (int b = 0; b < per_side; ++b) {
                Observation o;
                const double step = 20.0 / per_side;
                o.query = test::make_query(Model::OHS, (a + 0.3) * step, (b + 0.6) * step, 3.0);
                o.lambdas_um = {lambda};
                o.resolution = 32;
                o.reference = to_reference(render_observation(truth, o));
                observations.push_back(std::move(o));
            }
    }
    return observations;
}

RecoverSettings tiny_settings() {
    RecoverSettings s;
    s.blurred.blur_widths = {8.0};
    s.blurred.iterations = 6;
    s.field.iterations = 8;
    s.refine_iterations = 4;
    return s;
}

struct ScratchCheck {
    ScratchCheck() { detail::exact_scratch_check() = true; }
    ~ScratchCheck() { detail::exact_scratch_check() = false; }
};

TEST(ExactRecover, OneThreadAndTwoThreadsGiveTheSameHeightsBitForBit) {
    const Heightfield truth = test::random_heightfield(10, 10, 0.15, 41, 2.0);
    const std::vector<Observation> observations = small_observations(truth);
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const Heightfield one = recover_heights(observations, 10, 10, 2.0, 1.0, tiny_settings());
    omp_set_num_threads(2);
    const Heightfield two = recover_heights(observations, 10, 10, 2.0, 1.0, tiny_settings());
    omp_set_num_threads(threads);
    EXPECT_EQ(one.values(), two.values());
    // Observations in another order: the same sums, so the same heights.
    std::vector<Observation> reversed(observations.rbegin(), observations.rend());
    const Heightfield back = recover_heights(reversed, 10, 10, 2.0, 1.0, tiny_settings());
    EXPECT_EQ(one.values(), back.values());
}

// With the scratch check on, an observation that wrote outside the box it handed over throws
// std::logic_error: every stage's box (field operators' rows × columns, slice plans'
// gradient_box) holds what it writes, footprints wrapping around the tile included.
TEST(ExactRecover, EveryStagesBoxHoldsWhatItsObservationWrites) {
    const Heightfield truth = test::random_heightfield(10, 10, 0.15, 42, 2.0);
    const std::vector<Observation> observations = small_observations(truth);
    const ScratchCheck check;
    EXPECT_NO_THROW(recover_heights(observations, 10, 10, 2.0, 1.0, tiny_settings()));
}

TEST(ExactRecover, GradientBoxHoldsTheAdjointsValues) {
    const Heightfield hf = test::random_heightfield(20, 24, 0.3, 43, 2.0);
    for (const auto& [x, y] : std::vector<std::array<double, 2>>{{{1.0, 47.0}}, {{20.0, 24.0}}, {{39.5, 0.5}}}) {
        SlicePlan<double> plan(hf, test::make_query(Model::OHS, x, y, 3.0), {0.5}, 24, 1);
        const std::vector<double>& slice = plan.forward();
        std::vector<double> weights(slice.size(), 1.0), gradient;
        plan.adjoint(weights, gradient);
        std::vector<int> rows, cols;
        plan.gradient_box(rows, cols);
        std::vector<char> inside(gradient.size(), 0);
        for (int r : rows)
            for (int c : cols) inside[std::size_t(r) * 24 + std::size_t(c)] = 1;
        std::size_t written = 0;
        for (std::size_t k = 0; k < gradient.size(); ++k) {
            if (gradient[k] != 0.0) ++written;
            EXPECT_TRUE(gradient[k] == 0.0 || inside[k])
                << "value " << k << " outside the box at (" << x << ", " << y << ")";
        }
        EXPECT_GT(written, 0u);
        EXPECT_LT(rows.size() * cols.size(), gradient.size()) << "the box is smaller than the tile";
    }
}

}  // namespace
}  // namespace wavebrdf
