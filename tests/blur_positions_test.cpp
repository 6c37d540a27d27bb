// Position registration against the blurred fit (src/recovery/blur_positions.h): at the true
// heights, the grid search of each position's blurred loss finds known offsets (chosen on its
// grid) exactly, with wrong stated centres and any number of threads alike.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "recovery/blur_positions.h"
#include "test_util.h"
#include "wavebrdf/slice_plan.h"

using namespace wavebrdf;

namespace {

constexpr int kSize = 12;
constexpr double kTexel = 2.0, kLambda = 0.5, kSigma = 3.0;

// Observations at a 3 × 3 raster of stated centres (step 8 µm) whose slices were rendered at
// stated + error (errors in whole half texels, up to ±1.5 texels).
std::vector<Observation> shifted_observations(const Heightfield& truth, std::vector<double>& errors_um) {
    std::mt19937_64 rng(6101);
    std::uniform_int_distribution<int> half_texels(-3, 3);
    std::vector<Observation> out;
    errors_um.clear();
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            const double ex = 0.5 * kTexel * half_texels(rng), ey = 0.5 * kTexel * half_texels(rng);
            errors_um.insert(errors_um.end(), {ex, ey});
            Observation o;
            o.query = test::make_query(Model::OHS, 4.0 + 8.0 * a + ex, 4.0 + 8.0 * b + ey, kSigma);
            o.lambdas_um = {kLambda};
            o.resolution = 32;
            SlicePlan<double> plan(truth, o.query, o.lambdas_um, o.resolution, 1, {}, false);
            o.reference = to_reference(plan.forward());
            o.query.x_um -= ex;
            o.query.y_um -= ey;
            out.push_back(std::move(o));
        }
    return out;
}

}  // namespace

TEST(BlurPositions, RegistrationFindsKnownOffsetsAtTheTrueHeights) {
    const Heightfield truth = test::random_heightfield(kSize, kSize, 0.15, 6102, kTexel);
    std::vector<double> errors_um;
    const std::vector<Observation> observations = shifted_observations(truth, errors_um);
    std::vector<const Observation*> group;
    std::vector<std::size_t> position;
    for (std::size_t i = 0; i < observations.size(); ++i) {
        group.push_back(&observations[i]);
        position.push_back(i);
    }
    double error_rms = 0.0;
    for (double e : errors_um) error_rms += e * e;
    ASSERT_GT(error_rms, 0.0);
    const int before = omp_get_max_threads();
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        std::vector<double> offsets_um(errors_um.size(), 0.0);
        const double moved = detail::register_positions_blurred(group, position, truth, 2.0, 2.0, 0.5, offsets_um,
                                                                serial_communicator());
        EXPECT_GT(moved, 0.0);
        for (std::size_t k = 0; k < errors_um.size(); ++k)
            EXPECT_NEAR(offsets_um[k], errors_um[k], 1e-9)
                << "position " << k / 2 << " coordinate " << k % 2 << " threads " << threads;
    }
    omp_set_num_threads(before);
}

TEST(BlurPositions, RejectsAnInvalidGrid) {
    const Heightfield truth = test::random_heightfield(kSize, kSize, 0.15, 6102, kTexel);
    std::vector<double> errors_um;
    const std::vector<Observation> observations = shifted_observations(truth, errors_um);
    std::vector<const Observation*> group{&observations[0]};
    std::vector<std::size_t> position{0};
    std::vector<double> offsets_um(2, 0.0);
    EXPECT_THROW(
        detail::register_positions_blurred(group, position, truth, 2.0, 2.0, 0.0, offsets_um, serial_communicator()),
        std::invalid_argument);
    EXPECT_THROW(
        detail::register_positions_blurred(group, position, truth, 2.0, 20.0, 0.5, offsets_um, serial_communicator()),
        std::invalid_argument);
    std::vector<std::size_t> outside{5};
    EXPECT_THROW(
        detail::register_positions_blurred(group, outside, truth, 2.0, 2.0, 0.5, offsets_um, serial_communicator()),
        std::invalid_argument);
}
