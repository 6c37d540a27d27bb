// The anti-mirror's level-step survey (src/design/level_step.h): which steps it designs, that each
// of its scores is the design a run fixed on that step makes, and that the design starts on the
// best of them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <nlohmann/json.hpp>
#include <string>

#include "design_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

// 16² on its own (no continuation, no anneal: the survey's tile is the run's), 8 wavelengths.
DesignOptions band_anti_mirror() {
    DesignOptions o = test::small_design("anti-mirror", 8, 20, 5);
    o.band_um = {0.4, 0.7};
    o.continuation = "off";
    o.anneal_sweeps = 0;
    return o;
}

// The least worst mirror power over the band's phases that any shares of K levels Δ apart reach,
// by a projected-gradient descent on the simplex (independent of the run's active set): an upper
// bound on the darkest mirror order, enough to show that a surveyed step can be kept dark.
double darkest_mirror_power(double step_um, int levels, double lambda_lo, double lambda_hi) {
    std::vector<double> theta;
    for (int d = 0; d <= 64; ++d) theta.push_back(4.0 * k_pi * step_um / (lambda_lo + (lambda_hi - lambda_lo) * d / 64.0));
    const auto K = static_cast<std::size_t>(levels);
    std::vector<double> a(K, 1.0 / levels);
    for (int it = 0; it < 4000; ++it) {
        std::vector<double> g(K, 0.0);
        for (double th : theta) {
            std::complex<double> p(0.0, 0.0);
            for (std::size_t l = 0; l < K; ++l) p += a[l] * std::polar(1.0, -th * static_cast<double>(l));
            for (std::size_t l = 0; l < K; ++l) g[l] += 2.0 * std::real(std::conj(p) * std::polar(1.0, -th * static_cast<double>(l)));
        }
        // Step, then project onto the simplex (sort-based).
        std::vector<double> y(K);
        for (std::size_t l = 0; l < K; ++l) y[l] = a[l] - 0.1 * g[l] / static_cast<double>(theta.size());
        std::vector<double> s = y;
        std::sort(s.rbegin(), s.rend());
        double cum = 0.0, tau = 0.0;
        for (std::size_t k = 0; k < K; ++k) {
            cum += s[k];
            const double t = (cum - 1.0) / static_cast<double>(k + 1);
            if (s[k] - t > 0.0) tau = t;
        }
        for (std::size_t l = 0; l < K; ++l) a[l] = std::max(0.0, y[l] - tau);
    }
    double worst = 0.0;
    for (int d = 0; d <= 256; ++d) {
        const double th = 4.0 * k_pi * step_um / (lambda_lo + (lambda_hi - lambda_lo) * d / 256.0);
        std::complex<double> p(0.0, 0.0);
        for (std::size_t l = 0; l < K; ++l) p += a[l] * std::polar(1.0, -th * static_cast<double>(l));
        worst = std::max(worst, std::norm(p));
    }
    return worst;
}

TEST(DesignStepSurvey, SurveysTheRulesStepAndStepsTheMirrorCanBeDarkOn) {
    const DesignOptions o = band_anti_mirror();
    const PreparedDesign p = prepare_design(o);
    ASSERT_GE(p.step_survey_um.size(), 3u);
    EXPECT_EQ(p.step_survey_size, 16);  // the run's tile (no continuation here)
    DesignOptions continued = o;
    continued.continuation = "auto";  // 8² first on a 16² tile: the survey designs that tile
    EXPECT_EQ(prepare_design(continued).step_survey_size, 8);
    const double rule = p.levels_um[1];
    EXPECT_NE(std::find(p.step_survey_um.begin(), p.step_survey_um.end(), rule), p.step_survey_um.end());
    EXPECT_TRUE(std::is_sorted(p.step_survey_um.rbegin(), p.step_survey_um.rend()));
    // The sampled wavelengths' extremes, as the run samples the band.
    const double lo = *std::min_element(p.lambdas_um.begin(), p.lambdas_um.end());
    const double hi = *std::max_element(p.lambdas_um.begin(), p.lambdas_um.end());
    for (double step : p.step_survey_um) {
        EXPECT_GT(step, 0.0);
        EXPECT_LE(step * (o.levels - 1), o.height_range_um * (1 + 1e-12));
        // Kept dark within the loop's aim by some shares (0.95 of the cone's limit; the
        // descent's shares are no better than the optimum, so a small margin).
        EXPECT_LE(darkest_mirror_power(step, o.levels, lo, hi), 1.2 * 0.95 * o.cone_limit) << "step " << step;
    }
    // A step on which no shares keep the mirror dark is not surveyed: near H/(K−1) = 0.286 µm,
    // 2Δ is a wavelength of the band (0.571 µm), which makes every relief a mirror there.
    EXPECT_LT(p.step_survey_um.front(), 0.2);
    EXPECT_GT(darkest_mirror_power(0.28, o.levels, lo, hi), 0.1);
}

TEST(DesignStepSurvey, EachScoreIsTheFixedStepsDesignAndTheRunStartsOnTheBest) {
    const DesignOptions o = band_anti_mirror();
    const PreparedDesign p = prepare_design(o);
    int reported = 0;
    const DesignResult r = run_design(p, [&](const DesignStep& s) {
        reported += s.phase == "step survey";
        return true;
    });
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_TRUE(j.contains("step_survey"));
    const auto& steps = j["step_survey"]["steps"];
    ASSERT_EQ(steps.size(), p.step_survey_um.size());
    // Every loop's steps (a repair block may add passes to a loop's budget).
    EXPECT_GE(reported, static_cast<int>(steps.size()) * (o.iterations + o.refine_passes));
    double best = -1e300, best_step = 0.0;
    for (const auto& s : steps) {
        const double score = s["score"].get<double>();
        const double cone = s["specular_fraction_worst"].get<double>(), u = s["uniformity_worst"].get<double>();
        EXPECT_NEAR(score, s["region_fraction_mean"].get<double>() - std::max(0.0, cone / o.cone_limit - 1.0) -
                               std::max(0.0, u / o.uniformity_limit - 1.0), 1e-15);
        if (score > best) {
            best = score;
            best_step = s["step_um"].get<double>();
        }
    }
    EXPECT_EQ(j["step_survey"]["chosen_um"].get<double>(), best_step);
    // The design keeps that step: its levels and its exported heights are on it.
    EXPECT_EQ(j["level_step"]["start_um"].get<double>(), best_step);
    EXPECT_EQ(j["level_step"]["final_um"].get<double>(), best_step);
    for (std::size_t k = 0; k < r.levels_um.size(); ++k) EXPECT_NEAR(r.levels_um[k], static_cast<double>(k) * best_step, 1e-15);
    for (std::size_t t = 0; t < r.level.size(); ++t)
        EXPECT_EQ(r.heights_um[t], r.levels_um[static_cast<std::size_t>(r.level[t])]);
    // The scores differ between steps: the choice is a real one.
    double lowest = 1e300;
    for (const auto& s : steps) lowest = std::min(lowest, s["score"].get<double>());
    EXPECT_GT(best - lowest, 1e-3);
    // Two of the surveyed steps, designed alone on that fixed step, score exactly as surveyed.
    for (std::size_t k : {std::size_t{0}, steps.size() - 1}) {
        DesignOptions f = o;
        f.level_step_um = steps[k]["step_um"].get<double>();
        f.continuation = "off";
        f.anneal_sweeps = 0;
        const PreparedDesign pf = prepare_design(f);
        EXPECT_TRUE(pf.step_survey_um.empty());  // a fixed step is not surveyed
        const auto jf = nlohmann::json::parse(run_design(pf).metrics_json);
        EXPECT_EQ(jf["metrics"]["exact"]["region_fraction_mean"].get<double>(),
                  steps[k]["region_fraction_mean"].get<double>());
    }
}

// Where the survey's tile is the run's first (a continuation's first tile, the annealed tile), the
// run starts from the best step's tile as surveyed: that tile is not designed again.
TEST(DesignStepSurvey, TheBestStepsTileIsTheRunsFirstTile) {
    DesignOptions o = band_anti_mirror();
    o.continuation = "auto";  // 8² first, then the 16² tile
    o.anneal_sweeps = 6;      // the anneal takes the 8² tile
    const PreparedDesign p = prepare_design(o);
    ASSERT_EQ(p.step_survey_size, 8);
    ASSERT_EQ(p.anneal_size, 8);
    ASSERT_TRUE(p.step_survey_first_tile);
    long long reported = 0, first_tile_loops = 0;
    const DesignResult r = run_design(p, [&](const DesignStep& s) {
        ++reported;
        // A loop on the 8² tile after the survey would report "relaxed 8x8" or "refine 8x8".
        first_tile_loops += s.phase.find("8x8") != std::string::npos && s.phase.rfind("anneal", 0) != 0;
        return true;
    });
    EXPECT_EQ(first_tile_loops, 0);  // the survey's tile is annealed, not designed again
    const long long budget = o.iterations + o.refine_passes;
    EXPECT_EQ(design_step_count(p), static_cast<long long>(p.step_survey_um.size()) * budget + 6);
    EXPECT_GE(reported, design_step_count(p));  // a repair block may add passes to a loop
    const auto j = nlohmann::json::parse(r.metrics_json);
    // The first stage is the chosen step's surveyed tile: the same exact metrics, and the anneal
    // starts from them.
    const double chosen = j["step_survey"]["chosen_um"].get<double>();
    nlohmann::json surveyed;
    for (const auto& s : j["step_survey"]["steps"])
        if (s["step_um"].get<double>() == chosen) surveyed = s;
    ASSERT_FALSE(surveyed.is_null());
    const auto& first = j["continuation"]["schedule"][0];
    EXPECT_TRUE(first.contains("designed_by"));
    EXPECT_EQ(first["size"].get<int>(), 8);
    EXPECT_EQ(first["iterations"].get<int>(), o.iterations);
    EXPECT_EQ(first["level_step_um"].get<double>(), chosen);
    for (const char* key : {"region_fraction_mean", "specular_fraction_worst", "uniformity_worst"}) {
        EXPECT_EQ(first["exact"][key].get<double>(), surveyed[key].get<double>()) << key;
        EXPECT_NEAR(j["anneal"]["before"][key].get<double>(), surveyed[key].get<double>(), 1e-10) << key;
    }
    // The survey's tile's steps are the curve's first (an 8x8 tile's).
    ASSERT_FALSE(r.curve.empty());
    EXPECT_NE(r.curve.front().phase.find("8x8"), std::string::npos);

    // Without the anneal the continuation goes on from that tile: only the 16² tile's loop runs.
    o.anneal_sweeps = 0;
    const PreparedDesign q = prepare_design(o);
    ASSERT_TRUE(q.step_survey_first_tile);
    long long loops = 0, reported_q = 0;
    const DesignResult rq = run_design(q, [&](const DesignStep& s) {
        ++reported_q;
        loops += s.phase != "step survey";
        EXPECT_EQ(s.phase.find("8x8"), std::string::npos) << s.phase;
        return true;
    });
    EXPECT_GE(loops, budget);
    EXPECT_EQ(design_step_count(q), static_cast<long long>(q.step_survey_um.size() + 1) * budget);
    EXPECT_GE(reported_q, design_step_count(q));
    const auto jq = nlohmann::json::parse(rq.metrics_json);
    EXPECT_TRUE(jq["continuation"]["schedule"][0].contains("designed_by"));
    EXPECT_EQ(jq["continuation"]["schedule"].size(), 2u);

    // A fabrication error designs the first tile under it, as the survey does not: no reuse.
    o.errors.scale = 0.05;
    EXPECT_FALSE(prepare_design(o).step_survey_first_tile);
    // Nor where the survey's tile is the run's own (no continuation, no anneal).
    EXPECT_FALSE(prepare_design(band_anti_mirror()).step_survey_first_tile);
}

TEST(DesignStepSurvey, NotWhereTheStepIsGivenOrTheDesignHasNoBudget) {
    DesignOptions o = band_anti_mirror();
    o.level_step_um = 0.12;
    EXPECT_TRUE(prepare_design(o).step_survey_um.empty());
    o = band_anti_mirror();
    o.iterations = 0;
    o.refine_passes = 0;
    EXPECT_TRUE(prepare_design(o).step_survey_um.empty());
    o = band_anti_mirror();
    o.start_heights_um.assign(256, 0.0);
    for (std::size_t t = 0; t < 256; t += 2) o.start_heights_um[t] = 0.13;
    EXPECT_TRUE(prepare_design(o).step_survey_um.empty());
    o = test::small_design("colour:#80a0c0", 8, 10, 5);
    EXPECT_TRUE(prepare_design(o).step_survey_um.empty());
}

}  // namespace
}  // namespace wavebrdf
