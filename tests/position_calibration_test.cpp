// Self-calibration of the footprint positions (calibration.h, src/recovery/recover_positions.h):
// observations rendered at true centres and given with stated ones 1 texel rms off; the
// refinement with settings.calibrate.positions finds the offsets (up to their mean, the
// unobservable shift) and better heights than without; its sums stay exact (threads, order).
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/recover.h"
#include "position_cases.h"

using namespace wavebrdf;
using test::OffCase;
using test::offset_rms;

namespace {

// The 5 × 5 positions of the shared case (position_cases.h): linear overlap 1 − 4.8/18 = 73 %.
OffCase shared_off_case(std::uint64_t seed, double rms_texels, int resolution = 40) {
    return test::off_case(seed, rms_texels, resolution, 5);
}

RecoverSettings quick_position_settings(bool positions) {
    RecoverSettings s;
    s.blurred.blur_widths = {12.0, 4.0};
    s.blurred.iterations = 15;
    s.field.iterations = 40;
    s.refine_iterations = 40;
    s.calibrate.positions = positions;
    s.position_outer_passes = 0;  // one recovery: stage 3's calibration alone (the loop: position_registration_test)
    return s;
}

// A short recovery with the positions calibrated through one pass of the position loop.
RecoverSettings one_pass_settings() {
    RecoverSettings s;
    s.blurred.blur_widths = {8.0};
    s.blurred.iterations = 4;
    s.field.iterations = 6;
    s.refine_iterations = 4;
    s.calibrate.positions = true;
    s.position_outer_passes = 1;
    return s;
}

}  // namespace

TEST(PositionCalibration, FindsOffsetsOfHalfATexelAndBetterHeights) {
    const OffCase c = shared_off_case(5111, 0.5);
    const Heightfield without = recover_heights(c.observations, 12, 12, 2.0, 1.0, quick_position_settings(false));
    Calibration calibration;
    calibration.position_offsets_um = {{9.0, 9.0}};  // replaced
    const Heightfield with = recover_heights(c.observations, 12, 12, 2.0, 1.0, quick_position_settings(true), {}, nullptr,
                                             serial_communicator(), &calibration);
    ASSERT_EQ(calibration.position_offsets_um.size(), c.observations.size());
    // Observations at one stated centre share one offset; the offsets have mean 0 (the gauge).
    const std::size_t half = c.observations.size() / 2;
    std::array<double, 2> mean{0.0, 0.0};
    for (std::size_t i = 0; i < half; ++i) {
        EXPECT_EQ(calibration.position_offsets_um[i], calibration.position_offsets_um[i + half]);
        mean = {mean[0] + calibration.position_offsets_um[i][0], mean[1] + calibration.position_offsets_um[i][1]};
    }
    EXPECT_NEAR(mean[0] / double(half), 0.0, 1e-9);
    EXPECT_NEAR(mean[1] / double(half), 0.0, 1e-9);
    const double before = offset_rms(std::vector<std::array<double, 2>>(c.errors.size(), {0.0, 0.0}), c.errors);
    const double after = offset_rms(calibration.position_offsets_um, c.errors);
    EXPECT_GT(before, 0.5);  // µm: about half a texel
    EXPECT_LT(after, 0.6 * before);
    const double rmse_without = height_rel_rmse(without, c.truth);
    const double rmse_with = height_rel_rmse(with, c.truth);
    EXPECT_LT(rmse_with, rmse_without) << "without " << rmse_without << " with " << rmse_with;
    // Without calibration nothing is reported.
    Calibration none;
    recover_heights(
        c.observations, 12, 12, 2.0, 1.0,
        [] {
            RecoverSettings s = quick_position_settings(false);
            s.blurred.iterations = 0;
            s.field.iterations = 1;
            s.refine_iterations = 1;
            return s;
        }(),
        {}, nullptr, serial_communicator(), &none);
    EXPECT_TRUE(none.position_offsets_um.empty());
}

// The joint refinement's sums are exact: one and two threads give the same heights and offsets
// bit for bit (as K ranks must, docs/scale.md), through one pass of the position loop as well
// (the registration's, the Newton step's and the rescue's decisions).
TEST(PositionCalibration, ExactSumsGiveTheSameBitsForAnyThreadCount) {
    const OffCase c = shared_off_case(5112, 1.0, 24);
    RecoverSettings s = one_pass_settings();
    const int threads = omp_get_max_threads();
    Calibration one_cal, two_cal;
    // The later pass's fields as short as the first's.
    const auto edit = test::edit_position_loop([](detail::PositionLoopSettings& p) { p.field_iterations = 6; });
    omp_set_num_threads(1);
    const Heightfield one = detail::recover_heights_edited(c.observations, 12, 12, 2.0, 1.0, s, edit, {}, nullptr,
                                                           serial_communicator(), &one_cal);
    omp_set_num_threads(2);
    const Heightfield two = detail::recover_heights_edited(c.observations, 12, 12, 2.0, 1.0, s, edit, {}, nullptr,
                                                           serial_communicator(), &two_cal);
    omp_set_num_threads(threads);
    EXPECT_EQ(one.values(), two.values());
    EXPECT_EQ(one_cal.position_offsets_um, two_cal.position_offsets_um);
}

