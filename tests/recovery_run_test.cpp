// recovery_run.h: the memory estimate of a recovery and the limit prepare_recovery enforces.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "test_util.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/recovery_run.h"

namespace wavebrdf {
namespace {

// `recover --size 1000` planned 492075 observations of 160x160 (the planner's Nyquist size then)
// and grew until the machine ran out; it is now refused before any work, with the estimate and
// the limit in the message.
TEST(RecoveryRun, RefusesAPlanThatCannotFitBeforeSimulating) {
    RecoveryOptions options;
    options.rows = options.cols = 1000;
    options.resolution = 160;
    options.max_memory_gb = 8.0;
    try {
        prepare_recovery(options);
        FAIL() << "expected OutOfMemory";
    } catch (const OutOfMemory& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("recover (1000x1000 heights, 492075 observations of 160x160) needs about "),
                  std::string::npos)
            << what;
        EXPECT_NE(what.find("; the limit is 8 GB (max-memory-gb); raise it with --max-memory-gb"), std::string::npos)
            << what;
    }
    // The default limit is the physical memory; 1000x1000 needs hundreds of GB.
    options.max_memory_gb = 0.0;
    if (double(physical_memory_bytes()) < 200e9) {
        EXPECT_THROW(prepare_recovery(options), OutOfMemory);
    }
    options.max_memory_gb = -2.0;
    EXPECT_THROW(prepare_recovery(options), std::invalid_argument);
}

// The estimate against the peak resident memory of a real (shortened: one iteration per
// stage, the same allocations) recovery in a child process, for a 24x24 heightfield (300
// slices of 160x160): within a factor of two either way.
TEST(RecoveryRun, EstimateIsWithinAFactorOfTwoOfTheMeasuredPeak) {
#ifdef WAVEBRDF_ASAN
    GTEST_SKIP() << "AddressSanitizer's shadow memory and quarantine inflate the resident size; "
                    "the estimate is checked in the plain build";
#endif
    RecoveryOptions options;
    options.rows = options.cols = 24;
    options.resolution = 160;
    PlanRequest request;
    request.rows = request.cols = 24;
    request.resolution = options.resolution;
    request.texel_um = options.texel_um;
    request.height_range_um = options.height_range_um;
    request.seed = options.seed;
    const std::vector<Observation> planned = planned_observations(plan_acquisition(request));
    const double estimate = estimate_recovery_bytes(planned, 24, 24, options.texel_um, RecoveryMethod::Pipeline);

    const double measured = test::child_peak_memory_bytes([&] {
        PreparedRecovery r = prepare_recovery(options);
        r.pipeline.blurred.iterations = 1;
        // Enough field iterations to fill the L-BFGS history, which the estimate counts whole
        // (its pairs are allocated as they come: one iteration held one pair).
        r.pipeline.field.iterations = r.pipeline.field.history + 1;
        r.pipeline.refine_iterations = 1;
        run_recovery(r);
        return true;
    });
    ASSERT_GT(measured, 0.0) << "the recovery failed in the child";
    test::expect_estimate_within_factor_of_two(estimate, measured, "recover 24x24");
}

// The convergence check's own error bars are held to the run's memory limit, as the recovery
// is (require_memory): a 16² photon-noise run of nm heights, whose misfit sits on the floor so
// that the check needs bars, computes them under the physical memory; with a limit below their
// predicted peak it skips them (auto) or has none (always), the note the refusal's message; with
// a limit above it computes them again. The run's CPU time is given as large: only memory decides.
TEST(RecoveryRun, TheChecksErrorBarsAreHeldToTheMemoryLimit) {
    RecoveryOptions options;
    options.rows = options.cols = 16;
    options.resolution = 48;
    options.noise = parse_noise("poisson:1e4");
    options.seed = 4;
    options.height_range_um = 0.02;
    PreparedRecovery r = prepare_recovery(options);
    const Heightfield estimate = run_recovery(r);
    const ModelCheckMisfits none;
    const double run_seconds = 1e6;
    const ConvergenceCheck free = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
    ASSERT_EQ(free.floor, "poisson");
    EXPECT_EQ(free.error_bars, "computed") << free.error_bars_note;
    EXPECT_GT(free.predicted_error_relative, 0.0);
    const double needed = free.error_bars_predicted_bytes;
    EXPECT_GT(needed, 64e6);  // the program's base and what the run holds, then the bars
    if (physical_memory_bytes() > 0) {
        EXPECT_EQ(free.memory_limit_bytes, double(physical_memory_bytes()));
    }

    r.max_memory_gb = 0.9 * needed / 1e9;
    const ConvergenceCheck tight = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
    EXPECT_EQ(tight.error_bars, "skipped");
    EXPECT_LT(tight.predicted_error_relative, 0.0);
    EXPECT_NE(tight.error_bars_note.find("computing the check's error bars (16x16 heights, "), std::string::npos)
        << tight.error_bars_note;
    EXPECT_NE(tight.error_bars_note.find("(max-memory-gb); raise it with --max-memory-gb"), std::string::npos)
        << tight.error_bars_note;
    EXPECT_DOUBLE_EQ(tight.memory_limit_bytes, r.max_memory_gb * 1e9);

    r.check_error_bars = CheckErrorBars::Always;
    const ConvergenceCheck always = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
    EXPECT_EQ(always.error_bars, "unavailable");
    EXPECT_EQ(always.error_bars_note, tight.error_bars_note);

    r.check_error_bars = CheckErrorBars::Auto;
    r.max_memory_gb = 1.1 * needed / 1e9;
    const ConvergenceCheck roomy = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
    EXPECT_EQ(roomy.error_bars, "computed") << roomy.error_bars_note;
    EXPECT_DOUBLE_EQ(roomy.predicted_error_relative, free.predicted_error_relative);
}

// Where the check's bars are left out (here by the memory rule), G's diagonal still judges the noise limit:
// a 16² photon-noise run of nm heights (0.005 µm range: the misfit on the floor, the slices'
// 10⁴ photons too few for the heights) warns with the bars skipped, the bound alone beyond the
// target, and the exact bars, computed after, predict at least as much; a run of µm heights
// (0.3 µm, converged) gets a bound within the target and no warning.
TEST(RecoveryRun, SkippedErrorBarsLeaveTheirLowerBoundToJudge) {
    for (const double range_um : {0.005, 0.3}) {
        RecoveryOptions options;
        options.rows = options.cols = 16;
        options.resolution = 48;
        options.noise = parse_noise("poisson:1e4");
        options.seed = 4;
        options.height_range_um = range_um;
        options.target_error = 0.0;  // one exposure per slice: the photon limit as it comes
        PreparedRecovery r = prepare_recovery(options);
        const Heightfield estimate = run_recovery(r);
        const ModelCheckMisfits none;
        r.check_error_bars = CheckErrorBars::Always;
        const ConvergenceCheck bars = judge_recovery(r, estimate, none, nullptr, false, 1e6).convergence;
        ASSERT_EQ(bars.floor, "poisson");
        ASSERT_EQ(bars.error_bars, "computed") << bars.error_bars_note;
        EXPECT_LT(bars.error_lower_bound_relative, 0.0);  // bars computed: no bound asked
        r.check_error_bars = CheckErrorBars::Auto;
        // Bars left out by the memory rule, whose predictions are counts of bytes (the cost
        // rule's are timings: a bound predicted at 0.9 x the bars' time under one build is
        // over it under another): a limit just below the bars' need, and just below the other
        // solve's too where that one fits under the first limit. G's diagonal needs far less.
        const double run_seconds = 1e6;
        r.max_memory_gb = (1.0 - 1e-6) * bars.error_bars_predicted_bytes / 1e9;
        ConvergenceCheck skipped = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
        if (skipped.error_bars == "computed") {
            r.max_memory_gb = (1.0 - 1e-6) * skipped.error_bars_predicted_bytes / 1e9;
            skipped = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
        }
        r.max_memory_gb = 0.0;
        EXPECT_EQ(skipped.error_bars, "skipped") << skipped.error_bars_note;
        EXPECT_LT(skipped.predicted_error_relative, 0.0);
        ASSERT_GE(skipped.error_lower_bound_relative, 0.0) << "the bound was not computed";
        EXPECT_GE(skipped.error_lower_bound_seconds, 0.0);
        std::printf("range %.3g um: bars predict %.3g %%, the bound %.3g %%, true %s\n", range_um,
                    100.0 * bars.predicted_error_relative, 100.0 * skipped.error_lower_bound_relative,
                    skipped.converged ? "converged" : skipped.warning().c_str());
        EXPECT_LE(skipped.error_lower_bound_relative, bars.predicted_error_relative * (1.0 + 1e-6));
        if (range_um < 0.01) {
            EXPECT_TRUE(bars.misfit_ratio < k_misfit_ratio_limit) << bars.misfit_ratio;
            EXPECT_FALSE(skipped.converged);
            EXPECT_FALSE(skipped.misfit_failed);
            EXPECT_GT(skipped.error_lower_bound_relative, k_predicted_error_limit);
            EXPECT_NE(skipped.warning().find("the recovery is likely inaccurate: the misfit is on the photon-noise "
                                             "floor, but the slices' Fisher information bounds"),
                      std::string::npos)
                << skipped.warning();
        } else {
            EXPECT_TRUE(skipped.converged) << skipped.warning();
            EXPECT_TRUE(bars.converged) << bars.warning();
            EXPECT_LT(skipped.error_lower_bound_relative, k_predicted_error_limit);
        }
        // Off: neither the bars nor the bound.
        r.check_error_bars = CheckErrorBars::Off;
        const ConvergenceCheck off = judge_recovery(r, estimate, none, nullptr, false, run_seconds).convergence;
        EXPECT_LT(off.error_lower_bound_relative, 0.0);
        EXPECT_TRUE(off.converged);
    }
}

// The memory half of the rule on its own: a need within the limit fits, one above it or one
// that is not a number does not; an infinite limit (an unknown physical memory) takes any
// finite need.
TEST(RecoveryRun, TheChecksErrorBarsFitRule) {
    EXPECT_TRUE(check_error_bars_fit(1e9, 2e9));
    EXPECT_TRUE(check_error_bars_fit(2e9, 2e9));
    EXPECT_FALSE(check_error_bars_fit(2.1e9, 2e9));
    EXPECT_FALSE(check_error_bars_fit(std::nan(""), 2e9));
    EXPECT_FALSE(check_error_bars_fit(-1.0, 2e9));
    EXPECT_FALSE(check_error_bars_fit(HUGE_VAL, HUGE_VAL));
    EXPECT_TRUE(check_error_bars_fit(1e15, HUGE_VAL));
}

// The references are held in float (Observation::reference): one more observation adds its
// pixels × channels × 4 bytes to the estimate's reference term (the thesis method's estimate is
// the base, the references and a per-texel term only).
TEST(RecoveryRun, EstimateCountsTheReferencesInFloat) {
    Observation mono;
    mono.lambdas_um = {0.5};
    mono.resolution = 40;
    Observation rgb = mono;
    rgb.lambdas_um = {0.45, 0.55, 0.65};
    const std::vector<Observation> one{mono}, two{mono, mono}, with_rgb{mono, rgb};
    const double a = estimate_recovery_bytes(one, 16, 16, 2.0, RecoveryMethod::Thesis);
    EXPECT_EQ(estimate_recovery_bytes(two, 16, 16, 2.0, RecoveryMethod::Thesis) - a, 40.0 * 40.0 * 4.0);
    EXPECT_EQ(estimate_recovery_bytes(with_rgb, 16, 16, 2.0, RecoveryMethod::Thesis) - a, 40.0 * 40.0 * 3.0 * 4.0);
}

// The planner's overlap (RecoveryOptions::overlap unset): 0.6, and k_position_calibration_overlap
// (0.7) where the positions are calibrated (experiments/2026-11-23-position-calibration.md); a stated overlap is kept with or without calibration.
TEST(RecoveryRun, CalibratedPositionsArePlannedWithMoreOverlap) {
    const auto planned = [](const char* calibrate, std::optional<double> overlap) {
        RecoveryOptions options;
        options.rows = options.cols = 16;
        options.resolution = 16;
        options.calibrate = parse_calibration(calibrate);
        options.overlap = overlap;
        const PreparedRecovery r = prepare_recovery(options);
        std::set<std::pair<double, double>> positions;
        for (const Observation& o : r.observations) positions.insert({o.query.x_um, o.query.y_um});
        std::string note;
        for (const std::string& n : r.notes)
            if (n.find("overlap by at least") != std::string::npos) note = n;
        return std::make_pair(positions.size(), note);
    };
    const auto plain = planned("none", std::nullopt);
    const auto calibrated = planned("positions", std::nullopt);
    EXPECT_NE(plain.second.find("at least 6"), std::string::npos) << plain.second;            // 60 % and up
    EXPECT_NE(calibrated.second.find("at least 8"), std::string::npos) << calibrated.second;  // 80 % and up
    EXPECT_GT(calibrated.first, plain.first);
    EXPECT_EQ(planned("all", std::nullopt).first, calibrated.first);
    EXPECT_EQ(planned("positions", 0.6).first, plain.first);  // stated: kept
    EXPECT_EQ(planned("none", 0.8).first, calibrated.first);
    EXPECT_EQ(planned("exposure,sigma", std::nullopt).first, plain.first);  // not without positions
}

// The simulated position error is the stage's stated uncertainty unless one is given: the
// planner sizes the footprint for it (PlanRequest::position_uncertainty_um), and the position
// loop's rescue reaches k × it (k_rescue_radius_per_position_uncertainty) where that is farther
// than its default (its grid keeps its number of points: schedule_test.cpp).
TEST(RecoveryRun, SimulatedPositionErrorSizesTheFootprintAndTheRescue) {
    const RecoverSettings defaults;
    struct Planned {
        double sigma_p_um, rescue_radius_texels;
    };
    const auto planned = [](double error_texels, std::optional<double> uncertainty_um,
                            const char* calibrate = "positions") {
        RecoveryOptions options;
        options.rows = options.cols = 16;
        options.resolution = 16;
        options.calibrate = parse_calibration(calibrate);
        options.errors.position_rms_texels = error_texels;
        options.position_uncertainty_um = uncertainty_um;
        const PreparedRecovery r = prepare_recovery(options);
        return Planned{r.observations.front().query.sigma_p_um, r.pipeline.position_rescue_radius_texels};
    };
    EXPECT_EQ(planned(0.0, std::nullopt).sigma_p_um, 3.0);  // 1.5 texels of 2 um
    EXPECT_EQ(planned(1.0, std::nullopt).sigma_p_um, 3.0);  // 2 um: within the default footprint
    EXPECT_EQ(planned(1.0, std::nullopt).rescue_radius_texels, defaults.position_rescue_radius_texels);
    const Planned three = planned(3.0, std::nullopt);  // 6 um rms per coordinate
    EXPECT_EQ(three.sigma_p_um, 6.0);
    EXPECT_EQ(three.rescue_radius_texels, k_rescue_radius_per_position_uncertainty * 3.0);
    EXPECT_EQ(planned(10.0, std::nullopt).rescue_radius_texels, 16.0);  // the rescue's bound
    EXPECT_EQ(planned(3.0, 0.0).sigma_p_um, 3.0);                      // stated: kept
    EXPECT_EQ(planned(3.0, 0.0).rescue_radius_texels, defaults.position_rescue_radius_texels);
    EXPECT_EQ(planned(0.0, 5.0).sigma_p_um, 5.0);
    // Without position calibration only the footprint follows.
    EXPECT_EQ(planned(3.0, std::nullopt, "none").rescue_radius_texels, defaults.position_rescue_radius_texels);
}

// recover_heights with default settings runs the schedule that `wavebrdf recover` and Python's
// recover() run (prepare_recovery, run_recovery) for the default, smooth surface: the same
// stages, iterations and losses, and the same heights to the bit. (The front ends once
// overwrote the settings with a smooth schedule the library did not know.)
TEST(RecoveryRun, LibraryDefaultsRunTheFrontEndsSchedule) {
    RecoveryOptions options;
    options.rows = options.cols = 12;
    options.resolution = 16;
    options.seed = 3;
    const PreparedRecovery prepared = prepare_recovery(options);
    std::vector<StageMetrics> front, library;
    const Heightfield a = run_recovery(prepared, [&](const StageMetrics& m) {
        front.push_back(m);
        return true;
    });
    const Heightfield b = recover_heights(prepared.observations, prepared.rows, prepared.cols, prepared.texel_um,
                                          prepared.vscale, RecoverSettings{}, [&](const StageMetrics& m) {
                                              library.push_back(m);
                                              return true;
                                          });
    ASSERT_EQ(front.size(), library.size());
    for (std::size_t k = 0; k < front.size(); ++k) {
        EXPECT_EQ(front[k].stage, library[k].stage) << k;
        EXPECT_EQ(front[k].iteration, library[k].iteration) << k;
        EXPECT_EQ(front[k].loss, library[k].loss) << front[k].stage << " " << front[k].iteration;
    }
    ASSERT_EQ(a.values().size(), b.values().size());
    for (std::size_t k = 0; k < a.values().size(); ++k) EXPECT_EQ(a.values()[k], b.values()[k]) << k;
    // The front ends' progress totals (each step's) are the schedule's.
    const RecoverSettings s = scheduled_settings(RecoverSettings{}, prepared.texel_um);
    for (const StageMetrics& m : front) {
        EXPECT_EQ(m.kind, stage_kind(m.stage)) << m.stage;
        if (m.stage == "refine") {
            EXPECT_EQ(m.total, s.refine_iterations);
        }
        if (m.kind == StageKind::Field) {
            EXPECT_EQ(m.total, s.field.iterations) << m.stage;
        }
        if (m.stage == "unwrap") {
            EXPECT_EQ(m.total, 0);
        }
    }
}

// Error bars need the minimum: with them the smooth schedule's 8 last iterations become
// k_uncertainty_refine_iterations (the ±2σ coverage fell to 85–93 % with 8); a stated count wins.
TEST(RecoveryRun, ErrorBarsRefineToTheMinimum) {
    const auto refine_of = [](bool uncertainty, int stated) {
        RecoveryOptions options;
        options.rows = options.cols = 16;
        options.resolution = 16;
        options.noise = parse_noise("poisson:1e4");
        options.uncertainty = uncertainty;
        options.refine_iterations = stated;
        const PreparedRecovery r = prepare_recovery(options);
        return scheduled_settings(r.pipeline, r.texel_um).refine_iterations;
    };
    EXPECT_LT(refine_of(false, -1), k_uncertainty_refine_iterations);  // the smooth schedule's
    EXPECT_EQ(refine_of(true, -1), k_uncertainty_refine_iterations);
    EXPECT_EQ(refine_of(true, 5), 5);
}

}  // namespace
}  // namespace wavebrdf
