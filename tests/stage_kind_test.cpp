// recover.h's StageKind: every step a recovery reports has a kind and its planned total, which
// the front ends' progress bars show instead of reading the names.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "wavebrdf/recovery_run.h"

namespace wavebrdf {
namespace {

TEST(StageKind, EveryKindsNameIsItsOwn) {
    for (int k = 0; k + 1 < k_stage_kinds; ++k) {
        const std::string name = stage_kind_name(StageKind(k));
        // A prefix kind ("field:") names steps with a suffix ("field:0.7").
        const std::string step = name.back() == ':' ? name + "0.7" : name;
        EXPECT_EQ(int(stage_kind(step)), k) << step;
        if (name.back() == ':') {
            EXPECT_EQ(stage_kind(name), StageKind::Other) << name;
        }
    }
    EXPECT_EQ(stage_kind("refine:coarse"), StageKind::RefineCoarse);
    EXPECT_EQ(stage_kind("refine:field"), StageKind::ModelRefine);
    EXPECT_EQ(stage_kind("refine:0.55"), StageKind::RefineRung);
    EXPECT_EQ(stage_kind("refined"), StageKind::Other);
    EXPECT_EQ(stage_kind(""), StageKind::Other);
    EXPECT_STREQ(stage_kind_name(StageKind::Other), "other");
}

// Runs `options` and checks every step: a kind (not Other) that is its name's, and the total the
// run planned for that kind (the iterating kinds ≥ 1, the others 0). Returns the kinds seen.
std::set<StageKind> check_steps(const RecoveryOptions& options) {
    const PreparedRecovery prepared = prepare_recovery(options);
    const RecoverSettings resolved = scheduled_settings(prepared.pipeline, prepared.texel_um);
    std::set<StageKind> seen;
    run_recovery(prepared, [&](const StageMetrics& m) {
        seen.insert(m.kind);
        EXPECT_NE(m.kind, StageKind::Other) << "a step of no kind: " << m.stage;
        EXPECT_EQ(m.kind, stage_kind(m.stage)) << m.stage;
        const int planned = m.kind == StageKind::Thesis ? prepared.thesis.epochs : planned_iterations(resolved, m.kind);
        EXPECT_EQ(m.total, planned) << m.stage;
        if (m.kind == StageKind::Thesis || m.kind == StageKind::Field || m.kind == StageKind::Refine ||
            m.kind == StageKind::BlurredFit) {
            EXPECT_GE(m.total, 1) << m.stage;
        }
        return true;
    });
    return seen;
}

TEST(StageKind, EveryStepOfTheDefaultRunHasAKindAndItsTotal) {
    RecoveryOptions options;
    options.rows = options.cols = 12;
    options.resolution = 16;
    options.seed = 3;
    options.field_iterations = 7;
    const std::set<StageKind> seen = check_steps(options);
    for (StageKind k : {StageKind::BlurredFit, StageKind::BlurredResult, StageKind::Field, StageKind::Unwrap,
                        StageKind::Refine, StageKind::ModelMisfit, StageKind::ModelSelect})
        EXPECT_TRUE(seen.count(k)) << stage_kind_name(k);
}

TEST(StageKind, EveryStepOfACalibratedRunHasAKindAndItsTotal) {
    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 3;
    options.calibrate = parse_calibration("all");
    options.position_passes = 1;
    options.errors.position_rms_texels = 0.3;
    options.errors.exposure_min = 0.9;
    options.errors.exposure_max = 1.1;
    options.errors.seed = 3;
    // Short stages: the kinds and totals are the question here, not the accuracy.
    options.field_iterations = 5;
    options.refine_iterations = 3;
    const std::set<StageKind> seen = check_steps(options);
    for (StageKind k : {StageKind::Positions, StageKind::CalibrateSigma})
        EXPECT_TRUE(seen.count(k)) << stage_kind_name(k);
}

TEST(StageKind, EveryStepOfWhiteLightAndTheThesisHasAKindAndItsTotal) {
    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.resolution = 16;
    options.seed = 3;
    options.spectral = 3;
    options.refine_iterations = 4;
    options.white_smoothness_iterations = 2;
    EXPECT_TRUE(check_steps(options).count(StageKind::Refine));
    RecoveryOptions thesis;
    thesis.rows = thesis.cols = 8;
    thesis.resolution = 16;
    thesis.method = RecoveryMethod::Thesis;
    thesis.epochs = 6;
    EXPECT_EQ(check_steps(thesis), std::set<StageKind>{StageKind::Thesis});
}

}  // namespace
}  // namespace wavebrdf
