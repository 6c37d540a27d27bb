// The outer loop of position self-calibration (experiments/2026-11-23-position-calibration.md;
// src/recovery/recover_positions.h): every position registered on its own at fixed
// heights by a grid search of its full-model loss (all its wavelengths) and a parabola, then the
// field stage and stage 3 again from the registered positions.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <map>
#include <string>
#include <random>

#include "core/catmull_rom.h"
#include "recovery/field_positions.h"
#include "recovery/recover_positions.h"
#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "position_cases.h"

using namespace wavebrdf;
using test::off_case;
using test::OffCase;
using test::offset_rms;

namespace {

// The 12² tile's pipeline in the loop's tests: two blur widths, short stages, no model check,
// the positions calibrated.
RecoverSettings tile_settings(int blurred_iterations, int iterations) {
    RecoverSettings s;
    s.blurred.blur_widths = {12.0, 4.0};
    s.blurred.iterations = blurred_iterations;
    s.field.iterations = iterations;
    s.refine_iterations = iterations;
    s.model_check_iterations = 0;
    s.calibrate.positions = true;
    return s;
}

}  // namespace

// At the true heights the grid search (±2 texels in halves) and the parabola find known offsets
// of up to ±1.7 texels, on and between the grid's points, to a quarter texel (measured: 0.2 texel
// at worst on this 12² tile of correlation 4 texels, where the loss is not a parabola); one and
// two threads give the same bits (the per-position sums are exact).
TEST(PositionRegistration, FindsKnownOffsetsAtTheTrueHeightsWithTheFullModel) {
    const OffCase c = off_case(5121, 0.0, 32, 3, {1.5, -1.0, 0.3, -1.7, 0.0, 0.8, -0.4, 1.2, -1.5});
    std::vector<std::size_t> index;
    const std::size_t count = detail::gather_positions(c.observations, index, serial_communicator()).size();
    ASSERT_EQ(count, 9u);
    detail::PositionFitSettings settings;
    const int threads = omp_get_max_threads();
    std::vector<std::vector<double>> found;
    for (int t : {1, 2}) {
        omp_set_num_threads(t);
        std::vector<double> offsets(2 * count, 0.0);
        const double moved = detail::register_positions(c.observations, index, c.truth, settings, 1.0, 2.0, 0.5,
                                                        offsets, serial_communicator());
        EXPECT_GT(moved, 0.5);
        found.push_back(offsets);
    }
    omp_set_num_threads(threads);
    EXPECT_EQ(found[0], found[1]);
    std::vector<std::array<double, 2>> per_observation(c.observations.size());
    for (std::size_t i = 0; i < index.size(); ++i)
        per_observation[i] = {found[0][2 * index[i]], found[0][2 * index[i] + 1]};
    for (std::size_t i = 0; i < index.size(); ++i)
        for (int k = 0; k < 2; ++k)
            EXPECT_NEAR(per_observation[i][std::size_t(k)], c.errors[i][std::size_t(k)], 0.5)  // µm: 0.25 texel
                << "observation " << i << " coordinate " << k;
    // Invalid grids are refused.
    std::vector<double> offsets(2 * count, 0.0);
    EXPECT_THROW(detail::register_positions(c.observations, index, c.truth, settings, 1.0, 2.0, 0.0, offsets,
                                            serial_communicator()),
                 std::invalid_argument);
    std::vector<double> short_offsets(2, 0.0);
    EXPECT_THROW(detail::register_positions(c.observations, index, c.truth, settings, 1.0, 2.0, 0.5, short_offsets,
                                            serial_communicator()),
                 std::invalid_argument);
}

// End to end: positions 1 texel rms off; the outer loop (registration at the final heights,
// then the field stage and stage 3 again) leaves the offsets closer to the truth than one
// recovery does.
TEST(PositionRegistration, OuterLoopReducesTheOffsetsError) {
    const OffCase c = off_case(5122, 1.0, 32, 5);
    RecoverSettings s = tile_settings(15, 40);
    Calibration once, outer;
    s.position_outer_passes = 0;  // one recovery
    recover_heights(c.observations, 12, 12, 2.0, 1.0, s, {}, nullptr, serial_communicator(), &once);
    s.position_outer_passes = 2;
    std::vector<std::string> stages;
    recover_heights(
        c.observations, 12, 12, 2.0, 1.0, s,
        [&](const StageMetrics& m) {
            if (m.stage == "positions:register") stages.push_back(m.stage);
            return true;
        },
        nullptr, serial_communicator(), &outer);
    EXPECT_FALSE(stages.empty());
    const double before = offset_rms(std::vector<std::array<double, 2>>(c.errors.size(), {0.0, 0.0}), c.errors);
    const double after_once = offset_rms(once.position_offsets_um, c.errors);
    const double after_outer = offset_rms(outer.position_offsets_um, c.errors);
    std::printf("offsets error (um): before %.3f, one recovery %.3f, outer loop %.3f\n", before, after_once,
                after_outer);
    EXPECT_GT(before, 1.4);  // µm: about 0.7 texel or more
    // The loop's path depends on rounding (measured: 0.80 -> 0.24 µm in two passes), so this
    // checks only that it reduces the error.
    EXPECT_LT(after_outer, 0.8 * after_once) << "once " << after_once << " outer " << after_outer;
}

// calibrate.positions alone runs the position loop — the schedule's defaults: up to 40 passes,
// a Newton step after every registration, the field stage while the registration moves, stopped
// by the stall rule — and its offsets end closer to the truth than one recovery's. The loop's path
// depends on rounding (the same case stalls at 1.16 µm on one machine's vector units and reaches
// under half of one recovery's error on another's), so the claim is made over four cases.
TEST(PositionRegistration, CalibratePositionsRunsTheOuterLoopByDefault) {
    double once_sq = 0.0, loop_sq = 0.0;
    int halved = 0;
    for (std::uint64_t seed : {5124u, 5125u, 5126u, 5127u}) {
        const OffCase c = off_case(seed, 1.0, 32, 5);
        RecoverSettings s = tile_settings(15, 40);
        std::map<std::string, int> reported;
        Calibration by_default, once;
        recover_heights(
            c.observations, 12, 12, 2.0, 1.0, s,
            [&](const StageMetrics& m) {
                ++reported[m.stage];
                return true;
            },
            nullptr, serial_communicator(), &by_default);
        s.position_outer_passes = 0;
        recover_heights(c.observations, 12, 12, 2.0, 1.0, s, {}, nullptr, serial_communicator(), &once);
        const double before = offset_rms(std::vector<std::array<double, 2>>(c.errors.size(), {0.0, 0.0}), c.errors);
        const double after_once = offset_rms(once.position_offsets_um, c.errors);
        const double after_loop = offset_rms(by_default.position_offsets_um, c.errors);
        std::printf("seed %llu: offsets error (um): before %.3f, one recovery %.3f, default loop %.3f; %d passes, "
                    "%d stall checks\n", static_cast<unsigned long long>(seed), before, after_once, after_loop,
                    reported["positions:register"], reported["positions:stall"]);
        EXPECT_GE(reported["positions:register"], 2);
        EXPECT_LE(reported["positions:register"], 20);
        EXPECT_EQ(reported["positions:newton"], reported["positions:register"]);  // one Newton step a pass
        EXPECT_EQ(reported["positions:rescue"], reported["positions:register"]);  // the rescue looks every pass
        EXPECT_GT(before, 1.0);  // µm: about half a texel or more
        EXPECT_LE(after_loop, after_once * 1.0001) << "seed " << seed;  // the loop never ends worse
        once_sq += after_once * after_once;
        loop_sq += after_loop * after_loop;
        halved += after_loop < 0.5 * after_once;
    }
    EXPECT_LT(std::sqrt(loop_sq), 0.5 * std::sqrt(once_sq));
    EXPECT_GE(halved, 2);
}

// The stall rule over passes: with a tolerance of 1 a pass stalls unless the lowest loss halved
// over the window. On stage 3's loss after each pass (stall_median false) with the field stage
// never rerun, the loop stops after its first pass with stall_passes = 1 (2 with
// stall_passes = 2; all 4 with the rule off). On the median position's loss at the start of a
// pass (the default, for the pass before's heights), the first pass is not judged (it follows the
// field stage's heights, a new start), so the loop stops at the start of the second pass with
// stall_passes = 1 (the third with 2); out-of-range loop settings are refused.
TEST(PositionRegistration, StallRuleStopsTheLoop) {
    const OffCase c = off_case(5125, 1.0, 24, 3);
    RecoverSettings s;
    s.blurred.blur_widths = {8.0};
    s.blurred.iterations = 4;
    s.field.iterations = 6;
    s.refine_iterations = 4;
    s.model_check_iterations = 0;
    s.calibrate.positions = true;
    s.position_outer_passes = 4;
    const auto loop = [](int stall_passes, bool median) {
        return test::edit_position_loop([=](detail::PositionLoopSettings& p) {
            p.tolerance_texels = 0.0;
            p.field_below_texels = 1e9;  // no field stage in later passes
            p.stall_tolerance = 1.0;
            p.stall_passes = stall_passes;
            p.stall_median = median;
        });
    };
    const auto passes = [&](int stall_passes, bool median) {
        int registered = 0, stall_reports = 0;
        detail::recover_heights_edited(
            c.observations, 12, 12, 2.0, 1.0, s, loop(stall_passes, median),
            [&](const StageMetrics& m) {
                registered += m.stage == "positions:register";
                stall_reports += m.stage == "positions:stall";
                return true;
            },
            nullptr, serial_communicator());
        EXPECT_EQ(stall_reports, stall_passes == 0 ? 0 : registered) << "stall_passes " << stall_passes;
        return registered;
    };
    EXPECT_EQ(passes(1, false), 1);
    EXPECT_EQ(passes(2, false), 2);
    EXPECT_EQ(passes(1, true), 2);
    EXPECT_EQ(passes(2, true), 3);
    EXPECT_EQ(passes(0, true), 4);
    const auto refused = [&](const std::function<void(detail::PositionLoopSettings&)>& change) {
        EXPECT_THROW(detail::recover_heights_edited(c.observations, 12, 12, 2.0, 1.0, s,
                                                    test::edit_position_loop(change), {}, nullptr,
                                                    serial_communicator()),
                     std::invalid_argument);
    };
    refused([](detail::PositionLoopSettings& p) { p.stall_passes = -1; });
    refused([](detail::PositionLoopSettings& p) { p.stall_tolerance = 1.5; });
    refused([](detail::PositionLoopSettings& p) { p.rescue_factor = 0.5; });
    refused([](detail::PositionLoopSettings& p) { p.rescue_step_texels = 0.01; });  // 4 / 0.02 > 16
    refused([](detail::PositionLoopSettings& p) { p.field_iterations = -1; });
    refused([](detail::PositionLoopSettings& p) { p.refine_iterations = -1; });
    refused([](detail::PositionLoopSettings& p) { p.tolerance_texels = std::nan(""); });
    // The user's settings are refused before the run.
    RecoverSettings bad = s;
    bad.position_outer_passes = 101;
    EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, bad), std::invalid_argument);
    bad = s;
    bad.position_rescue_radius_texels = 17.0;
    EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, bad), std::invalid_argument);
}

// The outer loop's later passes run the loop's field_iterations per field and refine_iterations
// in stage 3 (the first pass keeps field.iterations and refine_iterations).
TEST(PositionRegistration, OuterLoopLaterPassesRunTheirOwnIterationCounts) {
    const OffCase c = off_case(5123, 1.0, 32, 5);
    RecoverSettings s = tile_settings(10, 30);
    s.position_outer_passes = 1;
    int pass = 0;
    std::array<int, 2> field_max{0, 0}, refine_max{0, 0};
    detail::recover_heights_edited(
        c.observations, 12, 12, 2.0, 1.0, s,
        test::edit_position_loop([](detail::PositionLoopSettings& p) {
            p.tolerance_texels = 0.0;
            p.field_iterations = 10;
            p.refine_iterations = 4;
        }),
        [&](const StageMetrics& m) {
            if (m.stage == "positions:register") pass = 1;
            if (m.stage.rfind("field:", 0) == 0) field_max[pass] = std::max(field_max[pass], m.iteration);
            if (m.stage == "refine") refine_max[pass] = std::max(refine_max[pass], m.iteration);
            return true;
        },
        nullptr, serial_communicator());
    EXPECT_EQ(pass, 1);
    EXPECT_GT(field_max[0], 10);
    EXPECT_GT(refine_max[0], 4);
    EXPECT_GT(field_max[1], 0);
    EXPECT_LE(field_max[1], 10);
    EXPECT_GT(refine_max[1], 0);
    EXPECT_LE(refine_max[1], 4);
}

// The loop's gauge helper: a displacement that is affine (or bilinear on the nodes) is removed
// to rounding; white noise keeps most of its rms (its smooth projection is small); bad input
// throws.
TEST(PositionRegistration, SmoothDisplacementRemovesAffineAndNodeFieldsAndKeepsNoise) {
    std::vector<std::array<double, 2>> centres;
    for (int i = 0; i < 13; ++i)
        for (int j = 0; j < 13; ++j) centres.push_back({3.05 * i + 1.0, 3.05 * j - 2.0});
    const std::size_t n = centres.size();
    std::vector<double> affine(2 * n), bilinear(2 * n), noise(2 * n);
    std::mt19937 rng(7);
    std::normal_distribution<double> g(0.0, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
        const double x = centres[i][0], y = centres[i][1];
        affine[2 * i] = 0.3 + 0.01 * x - 0.02 * y;
        affine[2 * i + 1] = -0.1 + 0.015 * x + 0.005 * y;
        // Bilinear between the 3 × 3 nodes at x, y ∈ {1, 19.3, 37.6} and {−2, 16.3, 34.6}:
        // one hat function per coordinate.
        const double hx = std::max(0.0, 1.0 - std::abs(x - 19.3) / 18.3);
        const double hy = std::max(0.0, 1.0 - std::abs(y - 16.3) / 18.3);
        bilinear[2 * i] = 0.5 * hx * hy;
        bilinear[2 * i + 1] = -0.25 * hx * hy;
        noise[2 * i] = g(rng);
        noise[2 * i + 1] = g(rng);
    }
    const auto rms = [](const std::vector<double>& v) {
        double s = 0.0;
        for (double x : v) s += x * x;
        return std::sqrt(s / double(v.size()));
    };
    std::vector<double> a = affine;
    const std::vector<double> removed = wavebrdf::detail::remove_smooth_displacement(centres, a, 1);
    EXPECT_LT(rms(a), 1e-9 * rms(affine));
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(removed[i], affine[i], 1e-9);
    std::vector<double> a6 = affine;
    wavebrdf::detail::remove_smooth_displacement(centres, a6, 6);
    EXPECT_LT(rms(a6), 1e-6 * rms(affine));
    std::vector<double> b = bilinear, b1 = bilinear;
    wavebrdf::detail::remove_smooth_displacement(centres, b, 3);
    EXPECT_LT(rms(b), 1e-6 * rms(bilinear));
    wavebrdf::detail::remove_smooth_displacement(centres, b1, 1);  // an affine fit cannot
    EXPECT_GT(rms(b1), 0.3 * rms(bilinear));
    std::vector<double> w = noise;
    wavebrdf::detail::remove_smooth_displacement(centres, w, 6);
    EXPECT_GT(rms(w), 0.75 * rms(noise));  // 36 of 169 degrees of freedom per coordinate: ≈ 0.89
    EXPECT_LT(rms(w), rms(noise));
    std::vector<double> bad(3);
    EXPECT_THROW(wavebrdf::detail::remove_smooth_displacement(centres, bad, 1), std::invalid_argument);
    EXPECT_THROW(wavebrdf::detail::remove_smooth_displacement(centres, noise, 0), std::invalid_argument);
}

// The rescue's cases: a 12² tile at 9 positions on a 3 × 3 raster, every position at its
// stated centre but those `fixed` (x, y texels per position) puts elsewhere, with the position
// index of each observation and each position's true offset (µm, 2 per position).
// `lost` is the position whose true x offset is lost_x_texels.
struct RescueCase {
    OffCase c;
    std::vector<std::size_t> index;
    std::vector<double> truth;
    std::size_t lost;
};

RescueCase rescue_case(std::uint64_t seed, const std::vector<double>& fixed, double lost_x_texels) {
    RescueCase r{off_case(seed, 0.0, 32, 3, fixed), {}, {}, 0};
    const std::size_t count = detail::gather_positions(r.c.observations, r.index, serial_communicator()).size();
    r.truth.assign(2 * count, 0.0);
    for (std::size_t i = 0; i < r.index.size(); ++i)
        for (int k = 0; k < 2; ++k) r.truth[2 * r.index[i] + std::size_t(k)] = r.c.errors[i][std::size_t(k)];
    r.lost = count;
    for (std::size_t p = 0; p < count; ++p)
        if (std::abs(r.truth[2 * p] - lost_x_texels * r.c.truth.texel_um()) < 1e-9) r.lost = p;
    return r;
}

// (experiments/2026-11-23-position-calibration.md): the outer loop's stall on seeds
// 11201/11202 was held by one or two positions trapped 2.7–5 texels from the truth, beyond the
// registration's ± 2 texels, whose loss was 100–700 × the median. rescue_lost_positions searches
// only the positions above factor × the median over ± radius: here, at the true heights, one
// position 3.5 / −3 texels off (beyond ± 2 + the half-texel grid and parabola: register_positions
// leaves it > 0.5 texel away) is found to a quarter texel; the others (0.2 texel off, losses
// far below the lost one's) are not searched and keep their offsets' bits.
TEST(PositionRegistration, RescueFindsAPositionBeyondTheRegistrationRadius) {
    std::vector<double> fixed(18, 0.0);
    fixed[8] = 3.5;
    fixed[9] = -3.0;
    const RescueCase r = rescue_case(5125, fixed, 3.5);
    const OffCase& c = r.c;
    const std::vector<std::size_t>& index = r.index;
    const std::vector<double>& truth = r.truth;
    const std::size_t lost = r.lost;
    const std::size_t count = truth.size() / 2;
    ASSERT_EQ(count, 9u);
    ASSERT_LT(lost, count);
    const double texel_um = c.truth.texel_um();
    // Start: every position 0.2 texel (x) off its truth, the lost one at its stated centre.
    std::vector<double> start(2 * count, 0.0);
    for (std::size_t p = 0; p < count; ++p)
        if (p != lost) {
            start[2 * p] = truth[2 * p] + 0.2 * texel_um;
            start[2 * p + 1] = truth[2 * p + 1];
        }
    const auto lost_error = [&](const std::vector<double>& o) {
        return std::hypot(o[2 * lost] - truth[2 * lost], o[2 * lost + 1] - truth[2 * lost + 1]) / texel_um;
    };
    detail::PositionFitSettings settings;
    std::vector<double> registered = start;
    detail::register_positions(c.observations, index, c.truth, settings, 1.0, 2.0, 0.5, registered,
                               serial_communicator());
    EXPECT_GT(lost_error(registered), 0.5);  // beyond the ordinary registration's reach
    std::vector<double> rescued = start;
    double median = -1.0;
    const int searched = detail::rescue_lost_positions(c.observations, index, c.truth, settings, 1.0, 20.0, 6.0, 0.5,
                                                       rescued, serial_communicator(), &median);
    // The median it reports (the loop's stall rule reads it) is the median position's loss at the
    // start offsets: each position's observations rendered in double at their shifted centres.
    std::vector<double> position_loss(count, 0.0);
    for (std::size_t i = 0; i < c.observations.size(); ++i) {
        Observation o = c.observations[i];
        o.query.x_um += start[2 * index[i]];
        o.query.y_um += start[2 * index[i] + 1];
        const std::vector<double> reference = to_doubles(o.reference);
        position_loss[index[i]] += loss_value(settings.loss, render_observation(c.truth, o), reference,
                                              o.channels(), nullptr) /
                                   double(c.observations.size());
    }
    std::vector<double> sorted = position_loss;
    std::sort(sorted.begin(), sorted.end());
    std::printf("median position loss %.6g (direct %.6g; lowest %.3g, lost one %.3g)\n", median, sorted[count / 2],
                sorted[0], position_loss[lost]);
    EXPECT_NEAR(median, sorted[count / 2], 1e-3 * sorted[count / 2]);
    EXPECT_GT(position_loss[lost], 20.0 * median);  // the one the rescue searched
    std::printf("lost position: %.3f texel after register_positions, %.3f after the rescue (%d searched)\n",
                lost_error(registered), lost_error(rescued), searched);
    EXPECT_EQ(searched, 1);
    EXPECT_LT(lost_error(rescued), 0.25);
    for (std::size_t p = 0; p < count; ++p)
        if (p != lost) {
            EXPECT_EQ(rescued[2 * p], start[2 * p]) << "position " << p;
            EXPECT_EQ(rescued[2 * p + 1], start[2 * p + 1]) << "position " << p;
        }
    EXPECT_THROW(detail::rescue_lost_positions(c.observations, index, c.truth, settings, 1.0, 1.0, 6.0, 0.5, rescued,
                                               serial_communicator()),
                 std::invalid_argument);
    EXPECT_THROW(detail::rescue_lost_positions(c.observations, index, c.truth, settings, 1.0, 20.0, 0.0, 0.5, rescued,
                                               serial_communicator()),
                 std::invalid_argument);
}

// (experiments/2026-11-23-position-calibration.md): at 0.8 overlap the loop ends with
// single positions lost 6–7 texels from the truth, carried to the far side of their stated centre
// (truths 2.3–3.4 texels off): a search about the offset no longer reaches them. Here one position
// is 2.5 texels (x) off its stated centre and starts at −3.5: a search of ± 4 about the offset
// alone left it lost (0.5 texel or more); the rescue also searches about the stated centre and
// finds it to a quarter texel, and the others keep their offsets' bits.
TEST(PositionRegistration, RescueSearchesAboutTheStatedCentreToo) {
    std::vector<double> fixed(18, 0.0);
    fixed[8] = 2.5;
    const RescueCase r = rescue_case(5127, fixed, 2.5);
    ASSERT_EQ(r.truth.size(), 18u);
    ASSERT_LT(r.lost, 9u);
    const double texel_um = r.c.truth.texel_um();
    std::vector<double> start = r.truth;  // (y: the truth)
    for (std::size_t p = 0; p < 9; ++p)  // the lost one on the far side of its stated centre
        start[2 * p] = p == r.lost ? -3.5 * texel_um : r.truth[2 * p] + 0.2 * texel_um;
    const auto lost_error = [&](const std::vector<double>& o) {
        return std::hypot(o[2 * r.lost] - r.truth[2 * r.lost], o[2 * r.lost + 1] - r.truth[2 * r.lost + 1]) /
               texel_um;
    };
    detail::PositionFitSettings settings;
    std::vector<double> both = start;
    const int searched_both = detail::rescue_lost_positions(r.c.observations, r.index, r.c.truth, settings, 1.0, 20.0, 4.0,
                                                            0.5, both, serial_communicator());
    std::printf("lost position: %.3f texel at the start, %.3f after the rescue (%d searched)\n", lost_error(start),
                lost_error(both), searched_both);
    EXPECT_EQ(searched_both, 1);
    EXPECT_GT(lost_error(start), 0.5);
    EXPECT_LT(lost_error(both), 0.25);
    for (std::size_t p = 0; p < 9; ++p)
        if (p != r.lost) {
            EXPECT_EQ(both[2 * p], start[2 * p]) << "position " << p;
            EXPECT_EQ(both[2 * p + 1], start[2 * p + 1]) << "position " << p;
        }
}

// (experiments/2026-11-23-position-calibration.md): with the rescue of lost positions, the outer
// loop was still held by the registration's precision (the half-texel grid and a parabola per
// coordinate, without the cross term), not by the heights. newton_register_positions takes one
// Newton step per position on its 2 × 2 Hessian (central differences ± 0.25 texel): here, at the
// true heights, every position starts 0.3 / −0.2 texel off its truth; the grid and parabola
// leave x 0.2 texel off (the fine grid's best at its edge, where there is no parabola: rms 0.161
// texel measured), the Newton step after them takes 8 of the 9 positions to ≤ 0.012 texel (rms
// 0.085, held by one corner position whose step was not taken). No position moves away; one and
// two threads give the same bits; invalid steps throw.
TEST(PositionRegistration, NewtonStepLandsCloserThanTheGridAndParabola) {
    const OffCase c = off_case(5121, 0.0, 32, 3, {1.5, -1.0, 0.3, -1.7, 0.0, 0.8, -0.4, 1.2, -1.5});
    std::vector<std::size_t> index;
    const std::size_t count = detail::gather_positions(c.observations, index, serial_communicator()).size();
    ASSERT_EQ(count, 9u);
    const double texel_um = c.truth.texel_um();
    std::vector<double> truth(2 * count, 0.0);
    for (std::size_t i = 0; i < index.size(); ++i)
        for (int k = 0; k < 2; ++k) truth[2 * index[i] + std::size_t(k)] = c.errors[i][std::size_t(k)];
    std::vector<double> start = truth;
    for (std::size_t p = 0; p < count; ++p) {
        start[2 * p] += 0.3 * texel_um;
        start[2 * p + 1] -= 0.2 * texel_um;
    }
    const auto rms_error = [&](const std::vector<double>& o) {
        double s2 = 0.0;
        for (std::size_t k = 0; k < o.size(); ++k) s2 += (o[k] - truth[k]) * (o[k] - truth[k]);
        return std::sqrt(s2 / double(o.size())) / texel_um;
    };
    detail::PositionFitSettings settings;
    std::vector<double> grid = start;
    detail::register_positions(c.observations, index, c.truth, settings, 1.0, 2.0, 0.5, grid, serial_communicator());
    const int threads = omp_get_max_threads();
    std::vector<std::vector<double>> newton;
    int moved = 0;
    for (int t : {1, 2}) {
        omp_set_num_threads(t);
        std::vector<double> o = grid;
        moved = detail::newton_register_positions(c.observations, index, c.truth, settings, 1.0, 0.25, 0.5, o,
                                                  serial_communicator());
        newton.push_back(o);
    }
    omp_set_num_threads(threads);
    EXPECT_EQ(newton[0], newton[1]);
    std::printf("offsets' error (rms, texels): start %.4f, grid + parabola %.4f, + Newton %.4f (%d moved)\n",
                rms_error(start), rms_error(grid), rms_error(newton[0]), moved);
    // Per position: the grid's fine step (± 0.5 about the coarse best, no parabola at its edge)
    // leaves x 0.2 texel off; the Newton step takes the typical position to ≈ 0.005 texel.
    const auto errors = [&](const std::vector<double>& o) {
        std::vector<double> e(count);
        for (std::size_t p = 0; p < count; ++p)
            e[p] = std::hypot(o[2 * p] - truth[2 * p], o[2 * p + 1] - truth[2 * p + 1]) / texel_um;
        return e;
    };
    const std::vector<double> eg = errors(grid), en = errors(newton[0]);
    int closer = 0;
    for (std::size_t p = 0; p < count; ++p) {
        std::printf("position %zu: grid + parabola %.4f texel, + Newton %.4f\n", p, eg[p], en[p]);
        EXPECT_LE(en[p], eg[p] + 1e-12) << "position " << p;
        closer += en[p] < 0.25 * eg[p];
    }
    EXPECT_GE(moved, 8);
    EXPECT_GE(closer, 8);  // measured: 8 of 9 (one corner position's step was not taken)
    std::vector<double> sg = eg, sn = en;
    std::nth_element(sg.begin(), sg.begin() + 4, sg.end());
    std::nth_element(sn.begin(), sn.begin() + 4, sn.end());
    EXPECT_LT(sn[4], 0.1 * sg[4]);  // the median position
    EXPECT_LT(rms_error(newton[0]), 0.6 * rms_error(grid));
    // A second step does not go back (each step only where the loss falls).
    std::vector<double> twice = newton[0];
    detail::newton_register_positions(c.observations, index, c.truth, settings, 1.0, 0.25, 0.5, twice,
                                      serial_communicator());
    std::printf("two Newton steps: %.4f\n", rms_error(twice));
    EXPECT_LT(rms_error(twice), 0.6 * rms_error(grid));
    EXPECT_THROW(detail::newton_register_positions(c.observations, index, c.truth, settings, 1.0, 0.0, 0.5, twice,
                                                   serial_communicator()),
                 std::invalid_argument);
    EXPECT_THROW(detail::newton_register_positions(c.observations, index, c.truth, settings, 1.0, 0.25, 0.0, twice,
                                                   serial_communicator()),
                 std::invalid_argument);
}
