// roughness_plan.h: the expected slopes of a stated surface (checked against generated
// surfaces: an independent evaluation of the rule), the rough / smooth decision, and what
// prepare_recovery makes of it (the common case keeps the library's defaults).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>
#include <stdexcept>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf {
namespace {

// The rms |∇H| (central differences, as check_acquisition's rim warning and the renderer
// take them) and the fraction of texels with |∇H| > 0.5 of a generated surface.
struct MeasuredSlopes {
    double rms = 0.0;
    double beyond_rim = 0.0;
};

MeasuredSlopes measure(double range_um, double correlation_texels, double texel_um, std::uint64_t seed) {
    RecoveryOptions options;
    options.rows = options.cols = 64;
    options.texel_um = texel_um;
    options.height_range_um = range_um;
    options.correlation_texels = correlation_texels;
    options.seed = seed;
    const Heightfield h = generated_recovery_truth(options);
    MeasuredSlopes m;
    for (int i = 0; i < h.rows(); ++i)
        for (int j = 0; j < h.cols(); ++j) {
            const auto s = h.slope(i, j);
            const double s2 = s[0] * s[0] + s[1] * s[1];
            m.rms += s2;
            if (s2 > 0.25) m.beyond_rim += 1.0;
        }
    m.rms = std::sqrt(m.rms / (h.rows() * h.cols()));
    m.beyond_rim /= h.rows() * h.cols();
    return m;
}

// The rule rms |∇H| ≈ range / (3ℓ) against generated Gaussian surfaces of the study's kind, at
// correlations of 4 and 8 texels (central differences blur shorter ones) and several ranges:
// within 30 % (the peak-to-valley of a 64² tile is 5–7 σ_h), averaged over seeds.
TEST(RoughnessPlan, ExpectedSlopeMatchesGeneratedSurfaces) {
    for (double correlation_texels : {4.0, 8.0})
        for (double range_um : {2.0, 8.0}) {
            double measured = 0.0, rim = 0.0;
            const int seeds = 4;
            for (int s = 0; s < seeds; ++s) {
                const MeasuredSlopes m = measure(range_um, correlation_texels, 2.0, 6301 + s);
                measured += m.rms / seeds;
                rim += m.beyond_rim / seeds;
            }
            const RoughnessPlan plan = plan_for_roughness(range_um, 2.0 * correlation_texels, 2.0);
            EXPECT_NEAR(plan.rms_slope, measured, 0.3 * measured)
                << "range " << range_um << " um, correlation " << correlation_texels << " texels";
            // The fraction of texels lighting beyond the rim: the Rayleigh tail of the rule.
            EXPECT_NEAR(plan.rim_fraction, rim, 0.05 + 0.5 * rim)
                << "range " << range_um << " um, correlation " << correlation_texels << " texels";
        }
}

// The settings the recovery's schedule resolves for a stated surface (µm) on texels of 2 µm.
RecoverSettings scheduled_for(double range_um, double correlation_um, RecoverSettings s = {}) {
    s.surface.height_range_um = range_um;
    s.surface.correlation_um = correlation_um;
    return scheduled_settings(s, 2.0);
}

// The study's default surface (±1 µm, correlation 4 texels of 2 µm) is smooth: the recovery runs
// the schedule of an unstated surface (the library's defaults); the documented failures
// (±4 µm; correlation 2 texels) are rough and get the longer schedule.
TEST(RoughnessPlan, DefaultIsSmoothAndTheFailureLimitsAreRough) {
    const RoughnessPlan common = plan_for_roughness(2.0, 8.0, 2.0);
    EXPECT_FALSE(common.rough);
    EXPECT_TRUE(common.notes.empty());
    const RecoverSettings settings = scheduled_for(2.0, 8.0);
    const RecoverSettings defaults = scheduled_settings(RecoverSettings{}, 2.0);
    EXPECT_EQ(settings.field.iterations, defaults.field.iterations);
    EXPECT_EQ(settings.blurred.iterations, defaults.blurred.iterations);
    EXPECT_EQ(settings.blurred.blur_widths, defaults.blurred.blur_widths);
    EXPECT_EQ(settings.refine_iterations, defaults.refine_iterations);
    EXPECT_EQ(settings.refine_ladder_min_um, defaults.refine_ladder_min_um);
    EXPECT_EQ(common.refine_ladder_min_um, 0.0);
    // ±2 µm and correlation 3 texels recovered with the defaults (docs/recovery.md): smooth too.
    EXPECT_FALSE(plan_for_roughness(4.0, 8.0, 2.0).rough);
    EXPECT_FALSE(plan_for_roughness(2.0, 6.0, 2.0).rough);

    for (const RoughnessPlan& rough : {plan_for_roughness(8.0, 8.0, 2.0), plan_for_roughness(2.0, 4.0, 2.0)}) {
        EXPECT_TRUE(rough.rough);
        ASSERT_FALSE(rough.notes.empty());
    }
    // The longer field stage for the short correlation, and for steep slopes with their long
    // wavelengths (without them steep slopes gained nothing).
    const int library = FieldRetrievalSettings{}.iterations;
    EXPECT_GT(scheduled_for(2.0, 4.0).field.iterations, library);
    EXPECT_GT(scheduled_for(8.0, 8.0).field.iterations, library);
    // The rule is in µm, not texels, except for the correlation: the same surface on finer
    // texels (correlation 4 texels of 1 µm) is not "fine".
    EXPECT_FALSE(plan_for_roughness(1.0, 4.0, 1.0).rough);
}

// Steep surfaces get a ring of oblique lights (roughness_plan.h): a facet of slope s reflects
// light ω_i towards ω_o ≈ −ω_i − 2s, measured inside the rim 0.9. With the ring every slope up to
// 0.63 in any direction, and up to 0.85 along the lights' azimuths, reaches some slice (normal
// light alone: 0.45). Smooth and merely fine-correlated surfaces keep one light.
TEST(RoughnessPlan, SteepSurfacesGetObliqueLights) {
    EXPECT_TRUE(plan_for_roughness(2.0, 8.0, 2.0).oblique_omega_i.empty());
    EXPECT_TRUE(plan_for_roughness(2.0, 4.0, 2.0).oblique_omega_i.empty());  // rough, but not steep
    const RoughnessPlan steep = plan_for_roughness(8.0, 8.0, 2.0);
    ASSERT_EQ(steep.oblique_omega_i.size(), 4u);
    std::vector<std::array<double, 2>> lights{{{0.0, 0.0}}};
    for (const auto& w : steep.oblique_omega_i) {
        EXPECT_NEAR(std::hypot(w[0], w[1]), 0.8, 1e-12);
        lights.push_back(w);
    }
    const auto seen = [&](double sx, double sy) {
        for (const auto& w : lights)
            if (std::hypot(w[0] + 2.0 * sx, w[1] + 2.0 * sy) <= 0.9) return true;
        return false;
    };
    for (int a = 0; a < 360; ++a) {
        const double t = a * 3.14159265358979323846 / 180.0;
        EXPECT_TRUE(seen(0.63 * std::cos(t), 0.63 * std::sin(t))) << a << " deg";
    }
    EXPECT_TRUE(seen(0.85, 0.0));
    EXPECT_FALSE(seen(0.9, 0.0));
    EXPECT_FALSE(seen(0.7 * std::sqrt(0.5), 0.7 * std::sqrt(0.5)));
    // The acquisition gets them with a note; a smooth plan adds none.
    AcquisitionPlan acquisition;
    EXPECT_EQ(add_oblique_lights(plan_for_roughness(2.0, 8.0, 2.0), acquisition), 0);
    EXPECT_TRUE(acquisition.oblique_omega_i.empty());
    EXPECT_EQ(add_oblique_lights(steep, acquisition), 4);
    EXPECT_EQ(acquisition.oblique_omega_i, steep.oblique_omega_i);
    ASSERT_EQ(acquisition.notes.size(), 1u);
    EXPECT_NE(acquisition.notes[0].find("oblique lights"), std::string::npos);
    // GHS-type slices share one light direction in the field stage: none added, said so.
    AcquisitionPlan ghs;
    ghs.model = Model::GHS;
    EXPECT_EQ(add_oblique_lights(steep, ghs), 0);
    EXPECT_TRUE(ghs.oblique_omega_i.empty());
    ASSERT_EQ(ghs.notes.size(), 1u);
    EXPECT_NE(ghs.notes[0].find("no oblique lights for GHS"), std::string::npos);
}

// prepare_recovery observes a steep generated surface under every light, unless told not to.
TEST(RoughnessPlan, PrepareRecoveryObservesSteepSurfacesUnderObliqueLights) {
    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 6301;
    options.height_range_um = 8.0;
    const PreparedRecovery steep = prepare_recovery(options);
    std::vector<std::array<double, 2>> lights;
    for (const Observation& o : steep.observations)
        if (std::find(lights.begin(), lights.end(), o.query.omega_i) == lights.end()) lights.push_back(o.query.omega_i);
    EXPECT_EQ(lights.size(), 5u);
    options.oblique_lights = false;
    const PreparedRecovery one = prepare_recovery(options);
    EXPECT_EQ(steep.observations.size(), 5 * one.observations.size());
    for (const Observation& o : one.observations) EXPECT_EQ(o.query.omega_i, (std::array<double, 2>{{0.0, 0.0}}));
    // GHS keeps one light (its field stage refuses several) and says why.
    options.oblique_lights = true;
    options.model = Model::GHS;
    const PreparedRecovery ghs = prepare_recovery(options);
    EXPECT_EQ(ghs.observations.size(), one.observations.size());
    bool noted = false;
    for (const auto& n : ghs.notes) noted = noted || n.find("no oblique lights for GHS") != std::string::npos;
    EXPECT_TRUE(noted);
}

TEST(RoughnessPlan, RejectsBadValues) {
    EXPECT_THROW(plan_for_roughness(-1.0, 8.0, 2.0), std::domain_error);
    EXPECT_THROW(plan_for_roughness(2.0, 0.0, 2.0), std::domain_error);
    EXPECT_THROW(plan_for_roughness(2.0, 8.0, 0.0), std::domain_error);
    EXPECT_THROW(plan_for_roughness(std::nan(""), 8.0, 2.0), std::domain_error);
    EXPECT_THROW(expected_rms_slope(2.0, -1.0), std::domain_error);
    EXPECT_DOUBLE_EQ(expected_rms_slope(0.0, 1.0), 0.0);
}

// prepare_recovery applies the plan from the stated range and correlation: a small tile.
TEST(RoughnessPlan, PrepareRecoveryChoosesTheScheduleFromTheStatedSurface) {
    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 6301;
    const auto scheduled = [](const PreparedRecovery& r) { return scheduled_settings(r.pipeline, r.texel_um); };
    const PreparedRecovery smooth = prepare_recovery(options);
    // Smooth: the smooth schedule (fewer field iterations, longest wavelength only).
    const int library = FieldRetrievalSettings{}.iterations;
    EXPECT_LT(scheduled(smooth).field.iterations, library);
    EXPECT_EQ(scheduled(smooth).field_wavelengths, 1);
    EXPECT_EQ(scheduled(smooth).refine_ladder_wavelengths, 1);
    EXPECT_EQ(scheduled(smooth).blurred.iterations, RecoverSettings{}.blurred.iterations);
    options.correlation_texels = 2.0;
    const PreparedRecovery rough = prepare_recovery(options);
    EXPECT_GT(scheduled(rough).field.iterations, library);
    EXPECT_EQ(scheduled(rough).field_wavelengths, 0);
    bool noted = false;
    for (const auto& n : rough.notes) noted = noted || n.find("rough surface") != std::string::npos;
    EXPECT_TRUE(noted);
    // An explicit --field-iterations still wins.
    options.field_iterations = 7;
    EXPECT_EQ(scheduled(prepare_recovery(options)).field.iterations, 7);
}

// The long wavelengths of a rough plan (roughness_plan.h): ±4 µm at correlation 4 texels gets a
// ladder whose longest wavelength is at least 4× the blurred fit's expected rms error (a phase
// error within a quarter turn), each step at most 4× shorter, all above the visible 0.7 µm; the
// smooth default gets none and keeps field_lambda_min_um 0 (every wavelength's field).
TEST(RoughnessPlan, LongWavelengthsStartTheFieldWithinAQuarterWave) {
    const RoughnessPlan steep = plan_for_roughness(8.0, 8.0, 2.0);
    ASSERT_TRUE(steep.rough);
    ASSERT_FALSE(steep.long_lambdas_um.empty());
    EXPECT_NEAR(steep.blur_error_um, 0.17 * 8.0, 1e-12);  // measured 12–17 % of the range
    EXPECT_GE(steep.long_lambdas_um.front(), 4.0 * steep.blur_error_um);
    for (std::size_t k = 0; k < steep.long_lambdas_um.size(); ++k) {
        EXPECT_GT(steep.long_lambdas_um[k], 0.7);
        if (k > 0) {
            EXPECT_LT(steep.long_lambdas_um[k], steep.long_lambdas_um[k - 1]);
            EXPECT_LE(steep.long_lambdas_um[k - 1] / steep.long_lambdas_um[k], 4.0 + 0.1);
        }
    }
    // The shortest long wavelength is within a quarter wave of the next longer one's start:
    // with a field as good as the longest's start, 4× finer steps keep the phase within π.
    const RecoverSettings settings = scheduled_for(8.0, 8.0);
    EXPECT_EQ(settings.field_lambda_min_um, steep.long_lambdas_um.back());
    // ±4 µm at correlation 4 texels of 2 µm: 5.5 and 1.4 µm, and the refinement's ladder over
    // both (rungs 5.5, 1.4, then every slice; measured: docs/recovery.md, round 5).
    EXPECT_EQ(steep.long_lambdas_um, (std::vector<double>{5.5, 1.4}));
    EXPECT_EQ(steep.refine_ladder_min_um, 1.4);
    EXPECT_EQ(settings.refine_ladder_min_um, 1.4);

    const RoughnessPlan smooth = plan_for_roughness(2.0, 8.0, 2.0);
    EXPECT_TRUE(smooth.long_lambdas_um.empty());
    const RecoverSettings defaults = scheduled_for(2.0, 8.0);
    EXPECT_EQ(defaults.field_lambda_min_um, 0.0);
    EXPECT_EQ(smooth.refine_ladder_min_um, 0.0);
    EXPECT_EQ(defaults.refine_ladder_min_um, 0.0);
    AcquisitionPlan acquisition;
    acquisition.lambdas_um = {0.5, 0.55};
    EXPECT_EQ(add_long_wavelengths(smooth, acquisition), 0);
    EXPECT_EQ(acquisition.lambdas_um.size(), 2u);
    EXPECT_EQ(add_long_wavelengths(steep, acquisition), int(steep.long_lambdas_um.size()));
    EXPECT_EQ(acquisition.lambdas_um.back(), steep.long_lambdas_um.back());
    // A small range at a short correlation is rough, but its error is within the visible
    // wavelengths' quarter wave: no long wavelength.
    EXPECT_TRUE(plan_for_roughness(0.5, 4.0, 2.0).long_lambdas_um.empty());
}

// prepare_recovery adds the long wavelengths to the acquisition of a rough surface only (the
// smooth default's observations are the ladder's, as before), and recover_heights then runs
// the field stage at them only; a small tile of correlation 2 texels is recovered far better
// than from the visible ladder alone (the same tile, observations and refinement; a 12² tile,
// 16² slices).
TEST(RoughnessPlan, LongWavelengthsRecoverAFineTile) {
    RecoveryOptions options;
    options.rows = options.cols = 12;
    options.resolution = 16;
    options.seed = 7301;
    const PreparedRecovery smooth = prepare_recovery(options);
    for (const Observation& o : smooth.observations) EXPECT_LE(o.lambdas_um[0], 0.7);
    EXPECT_EQ(scheduled_settings(smooth.pipeline, smooth.texel_um).field_lambda_min_um, 0.0);

    options.correlation_texels = 2.0;
    const PreparedRecovery steep = prepare_recovery(options);
    double longest = 0.0;
    for (const Observation& o : steep.observations) longest = std::max(longest, o.lambdas_um[0]);
    EXPECT_GT(longest, 4.0 * 0.17 * steep.range_um - 1e-9);
    const double field_lambda_min_um = scheduled_settings(steep.pipeline, steep.texel_um).field_lambda_min_um;
    EXPECT_GT(field_lambda_min_um, 0.7);
    std::vector<std::string> fields;
    double final_long = -1.0;
    const Heightfield with_long = run_recovery(steep, [&](const StageMetrics& m) {
        if (m.stage.rfind("field:", 0) == 0 && std::find(fields.begin(), fields.end(), m.stage) == fields.end())
            fields.push_back(m.stage);
        return true;
    });
    final_long = height_rel_rmse(with_long, *steep.truth);
    for (const std::string& f : fields) EXPECT_GE(std::stod(f.substr(6)), field_lambda_min_um) << f;
    EXPECT_FALSE(fields.empty());

    // The visible ladder alone, the rest alike.
    std::vector<double> visible;
    for (const Observation& o : steep.observations)
        if (o.lambdas_um[0] <= 0.7 && std::find(visible.begin(), visible.end(), o.lambdas_um[0]) == visible.end())
            visible.push_back(o.lambdas_um[0]);
    options.lambdas_um = visible;
    const PreparedRecovery plain = prepare_recovery(options);
    const double final_visible = height_rel_rmse(run_recovery(plain), *plain.truth);
    std::printf("12x12 correlation 2 texels: final %.4f with the long wavelengths, %.4f without\n", final_long,
                final_visible);
    EXPECT_LT(final_long, 0.5 * final_visible);
}

// RecoverSettings::field_lambda_min_um: refused when negative (but −1, unset) or not finite; when no
// wavelength reaches it, every wavelength runs the field stage (an 8² smooth tile).
TEST(RoughnessPlan, FieldLambdaMinFallsBackToEveryWavelength) {
    RecoverSettings bad;
    bad.field_lambda_min_um = -2.0;  // −1 is unset: the schedule's
    EXPECT_THROW(recover_heights({}, 4, 4, 2.0, 1.0, bad), std::domain_error);
    bad.field_lambda_min_um = std::nan("");
    EXPECT_THROW(recover_heights({}, 4, 4, 2.0, 1.0, bad), std::domain_error);

    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 7302;
    options.lambdas_um = {0.5, 0.6};
    PreparedRecovery prepared = prepare_recovery(options);
    prepared.pipeline.field_lambda_min_um = 100.0;  // no wavelength reaches it
    prepared.pipeline.refine_iterations = 0;
    prepared.pipeline.model_check_iterations = 0;
    std::vector<std::string> fields;
    run_recovery(prepared, [&](const StageMetrics& m) {
        if (m.stage.rfind("field:", 0) == 0 && std::find(fields.begin(), fields.end(), m.stage) == fields.end())
            fields.push_back(m.stage);
        return true;
    });
    EXPECT_EQ(fields.size(), 2u);
    prepared.pipeline.field_lambda_min_um = 0.55;  // the longer one only
    fields.clear();
    run_recovery(prepared, [&](const StageMetrics& m) {
        if (m.stage.rfind("field:", 0) == 0 && std::find(fields.begin(), fields.end(), m.stage) == fields.end())
            fields.push_back(m.stage);
        return true;
    });
    ASSERT_EQ(fields.size(), 1u);
    EXPECT_EQ(fields[0], "field:0.6");
}

// RecoverSettings::refine_ladder_min_um: refused when negative or not finite; the rungs are the
// single-wavelength slices' wavelengths ≥ it, longest first, then the refinement on every
// slice; a rung's loss holds only the slices at wavelengths ≥ its own: with the 0.5 µm slices
// replaced by others (three times as bright), every step of the rungs at 1.2 and 0.6 µm is the
// same bit for bit, and the refinement on every slice is not (an 8² tile, 16² slices).
TEST(RoughnessPlan, RefineLadderAddsOneWavelengthPerRungLongestFirst) {
    RecoverSettings bad;
    bad.refine_ladder_min_um = -2.0;  // −1 is unset: the schedule's
    EXPECT_THROW(recover_heights({}, 4, 4, 2.0, 1.0, bad), std::domain_error);
    bad.refine_ladder_min_um = std::nan("");
    EXPECT_THROW(recover_heights({}, 4, 4, 2.0, 1.0, bad), std::domain_error);
    bad.refine_ladder_min_um = 1.0;
    bad.refine_ladder_iterations = -1;
    EXPECT_THROW(recover_heights({}, 4, 4, 2.0, 1.0, bad), std::invalid_argument);

    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 10301;
    options.lambdas_um = {0.5, 0.6, 1.2};
    PreparedRecovery prepared = prepare_recovery(options);
    prepared.pipeline.field_lambda_min_um = 0.55;  // the 0.5 µm slices enter the refinement only
    prepared.pipeline.refine_ladder_min_um = 0.55;
    prepared.pipeline.refine_ladder_iterations = 6;
    prepared.pipeline.refine_ladder_stall_window = 0;  // each rung runs its cap (no run-on)
    prepared.pipeline.refine_iterations = 6;
    prepared.pipeline.model_check_iterations = 0;
    const auto run = [](const PreparedRecovery& p) {
        std::vector<StageMetrics> steps;
        run_recovery(p, [&](const StageMetrics& m) {
            if (m.stage.rfind("refine", 0) == 0) steps.push_back(m);
            return true;
        });
        return steps;
    };
    const std::vector<StageMetrics> clean = run(prepared);
    std::vector<std::string> order;
    for (const StageMetrics& m : clean)
        if (order.empty() || order.back() != m.stage) order.push_back(m.stage);
    EXPECT_EQ(order, (std::vector<std::string>{"refine:1.2", "refine:0.6", "refine"}));

    PreparedRecovery other = prepared;
    int replaced = 0;
    for (Observation& o : other.observations)
        if (o.lambdas_um[0] < 0.55) {
            for (float& v : o.reference) v *= 3.0f;
            ++replaced;
        }
    ASSERT_GT(replaced, 0);
    const std::vector<StageMetrics> changed = run(other);
    ASSERT_EQ(changed.size(), clean.size());
    std::size_t rungs = 0, differ = 0;
    for (std::size_t k = 0; k < clean.size(); ++k) {
        ASSERT_EQ(changed[k].stage, clean[k].stage);
        if (clean[k].stage != "refine") {
            ++rungs;
            EXPECT_EQ(changed[k].loss, clean[k].loss) << clean[k].stage << " step " << clean[k].iteration;
            EXPECT_EQ(changed[k].height_rel_rmse, clean[k].height_rel_rmse) << clean[k].stage;
        } else if (changed[k].loss != clean[k].loss) {
            ++differ;
        }
    }
    EXPECT_GT(rungs, 0u);
    EXPECT_GT(differ, 0u);  // the 0.5 µm slices do enter the last round

    // Off (0, the default, and no count: the smooth schedule's refine_ladder_wavelengths 0) and
    // a minimum above every wavelength: the refinement as before.
    prepared.pipeline.refine_ladder_min_um = 0.0;
    prepared.pipeline.refine_ladder_wavelengths = 0;
    const std::vector<StageMetrics> off = run(prepared);
    prepared.pipeline.refine_ladder_min_um = 100.0;
    const std::vector<StageMetrics> above = run(prepared);
    ASSERT_EQ(off.size(), above.size());
    for (std::size_t k = 0; k < off.size(); ++k) {
        EXPECT_EQ(off[k].stage, "refine");
        EXPECT_EQ(above[k].loss, off[k].loss);
    }
}

// The smooth schedule (experiments/2026-11-23-recovery-speed.md): a smooth surface without
// self-calibration gets the field stage at its longest wavelength only, at most 25 field
// iterations, and the refinement first on that wavelength's slices; a rough surface or any
// calibration gets the longer schedule; a value the caller set is kept.
TEST(RoughnessPlan, SmoothScheduleOnlyForSmoothUncalibratedSurfaces) {
    const RoughnessPlan smooth = plan_for_roughness(2.0, 8.0, 2.0);
    ASSERT_FALSE(smooth.rough);
    const RecoverSettings settings = scheduled_for(2.0, 8.0);
    EXPECT_EQ(settings.field_wavelengths, 1);
    EXPECT_EQ(settings.refine_ladder_wavelengths, 1);
    EXPECT_EQ(settings.field.iterations, 25);
    EXPECT_EQ(settings.refine_ladder_iterations, 40);
    EXPECT_EQ(settings.refine_ladder_relative_tolerance, 1e-8);
    EXPECT_EQ(settings.refine_ladder_stall_window, 5);
    EXPECT_EQ(settings.refine_ladder_stall_tolerance, 0.01);
    EXPECT_EQ(settings.refine_iterations, 8);
    EXPECT_EQ(settings.outlier_repair_rounds, 3);  // a second trapped texel shows after the first's repair
    EXPECT_EQ(settings.field_lambda_min_um, 0.0);  // counted, not named
    EXPECT_EQ(settings.refine_ladder_min_um, 0.0);
    EXPECT_EQ(settings.height_range_um, 2.0);      // the stated range bounds the unwrapping
    // An unstated surface is smooth: the same schedule.
    const RecoverSettings unstated = scheduled_settings(RecoverSettings{}, 2.0);
    EXPECT_EQ(unstated.field.iterations, 25);
    EXPECT_EQ(unstated.refine_iterations, 8);
    EXPECT_EQ(unstated.refine_ladder_wavelengths, 1);
    EXPECT_EQ(unstated.height_range_um, 4.0);

    const auto longer = [&](const RecoverSettings& s, int field_iterations) {
        EXPECT_EQ(s.field_wavelengths, 0);
        EXPECT_EQ(s.refine_ladder_wavelengths, 0);
        EXPECT_EQ(s.refine_ladder_relative_tolerance, 0.0);
        EXPECT_EQ(s.field.iterations, field_iterations);
        EXPECT_EQ(s.refine_ladder_iterations, 40);
        EXPECT_EQ(s.refine_iterations, 40);
        EXPECT_EQ(s.refine_ladder_stall_window, 0);
        EXPECT_EQ(s.outlier_repair_rounds, 1);
    };
    RecoverSettings repair_off;
    repair_off.outlier_repair_rounds = 0;  // a caller's "off" stays off
    EXPECT_EQ(scheduled_for(2.0, 8.0, repair_off).outlier_repair_rounds, 0);
    RecoverSettings calibrated;
    calibrated.calibrate.sigma = true;
    longer(scheduled_for(2.0, 8.0, calibrated), FieldRetrievalSettings{}.iterations);
    const RecoverSettings rough = scheduled_for(8.0, 8.0);
    longer(rough, 200);
    EXPECT_EQ(rough.refine_ladder_min_um, 1.4);  // the rough plan's ladder instead
    // A stated refinement count is the whole refinement (no ladder before it); other values stay.
    RecoverSettings stated;
    stated.refine_iterations = 20;
    stated.field.iterations = 30;
    const RecoverSettings kept = scheduled_for(2.0, 8.0, stated);
    EXPECT_EQ(kept.refine_iterations, 20);
    EXPECT_EQ(kept.refine_ladder_wavelengths, 0);
    EXPECT_EQ(kept.field.iterations, 30);
    EXPECT_EQ(kept.field_wavelengths, 1);
    // Error bars: the refinement runs to the loss's minimum, after the same ladder.
    RecoverSettings bars;
    bars.error_bars = true;
    EXPECT_EQ(scheduled_for(2.0, 8.0, bars).refine_iterations, k_uncertainty_refine_iterations);
    EXPECT_EQ(scheduled_for(2.0, 8.0, bars).refine_ladder_wavelengths, 1);
    // Resolving twice changes nothing (make_schedule resolves what recover_heights resolved).
    const RecoverSettings twice = scheduled_settings(settings, 2.0);
    EXPECT_EQ(twice.field.iterations, settings.field.iterations);
    EXPECT_EQ(twice.refine_ladder_wavelengths, settings.refine_ladder_wavelengths);
    EXPECT_EQ(twice.refine_iterations, settings.refine_iterations);
}

}  // namespace
}  // namespace wavebrdf
