// The Schedule of recover_heights' stages (src/recovery/stages.h): which stages run, in which
// order, with which settings, for the run's conditions.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <typeinfo>
#include <vector>

#include "recovery/stages.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;
using namespace wavebrdf::detail;

namespace {

// The stages' types in order, by name.
std::vector<std::string> order(const Schedule& schedule) {
    std::vector<std::string> names;
    for (const auto& s : schedule.stages) {
        const Stage& stage = *s;
        if (dynamic_cast<const BlurredFitStage*>(&stage)) names.push_back("blurred");
        else if (dynamic_cast<const SigmaPresearchStage*>(&stage)) names.push_back("sigma-presearch");
        else if (dynamic_cast<const HeldExposuresStage*>(&stage)) names.push_back("held-exposures");
        else if (dynamic_cast<const FieldStage*>(&stage)) names.push_back("field");
        else if (dynamic_cast<const UnwrapStage*>(&stage)) names.push_back("unwrap");
        else if (dynamic_cast<const SigmaResearchStage*>(&stage)) names.push_back("sigma-research");
        else if (dynamic_cast<const ReleaseFieldsStage*>(&stage)) names.push_back("release");
        else if (dynamic_cast<const RefineStage*>(&stage)) names.push_back("refine");
        else if (dynamic_cast<const PositionLoopStage*>(&stage)) names.push_back("positions");
        else if (dynamic_cast<const ModelCheckStage*>(&stage)) names.push_back("model-check");
        else names.push_back(typeid(stage).name());
    }
    return names;
}

template <typename T>
const T* find(const Schedule& schedule) {
    for (const auto& s : schedule.stages)
        if (const T* t = dynamic_cast<const T*>(s.get())) return t;
    return nullptr;
}

// A context of the given wavelengths (no observations: make_schedule reads only the wavelengths
// and the run's conditions).
struct ScheduleFixture {
    std::vector<Observation> observations;
    std::map<double, std::vector<const Observation*>> by_lambda;
    Heightfield flat{4, 4, std::vector<double>(16, 0.0), 2.0, 1.0};
    std::function<bool(const StageMetrics&)> on_step;
    StageReporter reporter{on_step, nullptr, serial_communicator(), RecoverSettings{}};
    explicit ScheduleFixture(const std::vector<double>& lambdas) {
        for (double l : lambdas) by_lambda[l];
    }
    Schedule schedule(const RecoverSettings& settings, bool proxied = false) {
        FieldProxy proxy;
        proxy.proxied = proxied;
        const StageContext context{observations, by_lambda, 1.0,   flat, 4, 4, 2.0, 1.0, serial_communicator(), reporter,
                                   std::ref(reporter), by_lambda.empty(), proxy, 3, {}};
        return make_schedule(settings, context);
    }
};

}  // namespace

TEST(Schedule, DefaultsRunEveryStageInOrder) {
    ScheduleFixture f({0.45, 0.5, 0.6});
    const Schedule s = f.schedule(RecoverSettings{});
    EXPECT_EQ(order(s), (std::vector<std::string>{"blurred", "field", "unwrap", "release", "refine", "model-check"}));
    const FieldStage* field = find<FieldStage>(s);
    ASSERT_NE(field, nullptr);
    EXPECT_EQ(field->field.refine, 3);  // the context's object grid
    // The defaults are the smooth schedule's (scheduled_settings): the longest wavelength's field,
    // then the refinement's first rung on its slices.
    EXPECT_EQ(field->lambda_min_um, 0.6);
    EXPECT_EQ(field->field.iterations, scheduled_settings(RecoverSettings{}, 2.0).field.iterations);
    EXPECT_EQ(find<RefineStage>(s)->settings.ladder_min_um, 0.6);
    // With calibration the longer schedule: every wavelength's field.
    RecoverSettings calibrated;
    calibrated.calibrate.exposure = true;
    const Schedule c = f.schedule(calibrated);
    EXPECT_EQ(find<FieldStage>(c)->lambda_min_um, 0.0);
    EXPECT_EQ(find<RefineStage>(c)->settings.ladder_min_um, 0.0);
}

TEST(Schedule, WavelengthCountsBecomeWavelengths) {
    ScheduleFixture f({0.45, 0.5, 0.6});
    RecoverSettings settings;
    settings.field_wavelengths = 1;
    settings.refine_ladder_wavelengths = 2;
    const Schedule s = f.schedule(settings);
    EXPECT_EQ(find<FieldStage>(s)->lambda_min_um, 0.6);  // the longest
    EXPECT_EQ(find<RefineStage>(s)->settings.ladder_min_um, 0.5);  // the second longest
}

TEST(Schedule, WhiteLightHasNoFieldStageAndNoModelCheck) {
    ScheduleFixture f({});
    const Schedule s = f.schedule(RecoverSettings{});
    EXPECT_EQ(order(s), (std::vector<std::string>{"blurred", "release", "refine"}));
    EXPECT_EQ(find<BlurredFitStage>(s)->fit.blur_widths, RecoverSettings{}.white_blurred.blur_widths);
}

TEST(Schedule, ProxiedSlicesSkipTheModelCheck) {
    ScheduleFixture f({0.5});
    EXPECT_EQ(find<ModelCheckStage>(f.schedule(RecoverSettings{}, true)), nullptr);
}

TEST(Schedule, CalibrationAddsItsStagesAndResolvesTheLoopsDefaults) {
    ScheduleFixture f({0.5, 0.6});
    RecoverSettings settings;
    settings.calibrate.sigma = true;
    EXPECT_EQ(order(f.schedule(settings)),
              (std::vector<std::string>{"blurred", "sigma-presearch", "field", "unwrap", "sigma-research", "release",
                                        "refine", "model-check"}));
    settings.calibrate.positions = true;
    settings.calibrate.exposure = true;  // no presearch with exposures; the exposures held
    const Schedule s = f.schedule(settings);
    EXPECT_EQ(order(s), (std::vector<std::string>{"blurred", "held-exposures", "field", "unwrap", "sigma-research",
                                                  "release", "positions", "model-check"}));
    const PositionLoopStage* loop = find<PositionLoopStage>(s);
    ASSERT_NE(loop, nullptr);
    EXPECT_EQ(loop->settings.passes, 40);  // position_outer_passes −1: the library's default
    EXPECT_EQ(loop->settings.stall_tolerance, 0.02);
    EXPECT_TRUE(loop->settings.hold_exposures);
    EXPECT_TRUE(loop->field.positions);
    EXPECT_TRUE(find<FieldStage>(s)->calibrate_exposure);
    // Stage 3's settings as the plain refinement's, the rescue's as the run's.
    EXPECT_EQ(loop->settings.fit.iterations, scheduled_settings(settings, 2.0).refine_iterations);
    EXPECT_EQ(loop->settings.fit.history, settings.refine_history);
    EXPECT_TRUE(loop->settings.fit.calibrate_exposure);
    EXPECT_TRUE(loop->settings.fit.calibrate_sigma);
    EXPECT_EQ(loop->settings.rescue_radius_texels, 4.0);
    EXPECT_EQ(loop->settings.rescue_step_texels, 0.125);
    EXPECT_NO_THROW(check_position_loop(loop->settings));
    settings.position_outer_passes = 3;
    settings.position_rescue_radius_texels = 12.0;
    settings.refine_loss = Loss{LossKind::Poisson, 1.0};
    const Schedule given = f.schedule(settings);  // held: the stages live as long as their schedule
    const PositionLoopStage* set = find<PositionLoopStage>(given);
    EXPECT_EQ(set->settings.passes, 3);
    EXPECT_EQ(set->settings.fit.loss.kind, LossKind::Poisson);
    // The rescue's grid keeps its number of points: radius / step as at the default.
    EXPECT_EQ(set->settings.rescue_radius_texels, 12.0);
    EXPECT_EQ(set->settings.rescue_step_texels, 0.375);
    EXPECT_NO_THROW(check_position_loop(set->settings));
}

TEST(Schedule, NoRefinementNoModelCheck) {
    ScheduleFixture f({0.5});
    RecoverSettings settings;
    settings.refine_iterations = 0;
    settings.blurred.blur_widths.clear();
    EXPECT_EQ(order(f.schedule(settings)), (std::vector<std::string>{"field", "unwrap", "release"}));
}
