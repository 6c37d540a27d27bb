// The anti-mirror's annealed last stage (src/design/anneal.h, DesignOptions::anneal_sweeps): the
// incremental evaluation against the library's exact one, the anneal against exhaustive search
// on a tiny tile, the design run with it against the exported relief's exact diffraction, the
// same relief with one and two threads, and the refusals.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "design/anneal.h"
#include "design/continuation.h"
#include "design/engine.h"
#include "design/relief.h"
#include "design/target.h"
#include "design_util.h"
#include "wavebrdf/design.h"

namespace wavebrdf {
namespace {

using detail::Fractions;

// OpenMP's thread count set for a scope.
struct AnnealTestThreads {
    int before = omp_get_max_threads();
    explicit AnnealTestThreads(int n) { omp_set_num_threads(n); }
    ~AnnealTestThreads() { omp_set_num_threads(before); }
    AnnealTestThreads(const AnnealTestThreads&) = delete;
    AnnealTestThreads& operator=(const AnnealTestThreads&) = delete;
};

// The anti-mirror target (default cone and annulus) on an N² tile of 0.5 µm texels at these
// wavelengths, normal light.
struct Problem {
    int size = 0;
    std::vector<detail::OrderSet> sets;
    std::unique_ptr<detail::Target> target;
    Problem(int n, const std::vector<double>& lambdas) : size(n) {
        for (double l : lambdas) sets.push_back(detail::make_order_set(n, 0.5, {0.0, 0.0}, l));
        target = detail::make_anti_mirror({});
        target->assign(sets);
    }
    // The library's exact fractions of a relief (level_flux: the level masks' FFTs).
    Fractions exact(const std::vector<int>& level, int levels, double step_um) const {
        detail::LevelRelief r;
        r.levels = levels;
        r.heights.step_um = step_um;
        r.level = level;
        return detail::group_fractions(*target, detail::level_flux(r, size, sets, 1.0));
    }
};

std::vector<int> random_relief(int n, int levels, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> pick(0, levels - 1);
    std::vector<int> level(static_cast<std::size_t>(n) * n);
    for (int& l : level) l = pick(rng);
    return level;
}

// The region's mean fraction, the cone's worst and the uniformity's worst of exact fractions.
struct Measures {
    double region = 0.0, cone = 0.0, u = 0.0;
};
Measures measures(const Fractions& f) {
    Measures m;
    for (const auto& g : f) {
        double region = 0.0, var = 0.0;
        for (int q = 1; q <= 16; ++q) region += g[static_cast<std::size_t>(q)];
        const double mean = region / 16.0;
        for (int q = 1; q <= 16; ++q) var += (g[static_cast<std::size_t>(q)] - mean) * (g[static_cast<std::size_t>(q)] - mean);
        m.region += region / static_cast<double>(f.size());
        m.cone = std::max(m.cone, g[0]);
        m.u = std::max(m.u, mean > 0.0 ? std::sqrt(var / 16.0) / mean : 0.0);
    }
    return m;
}

TEST(DesignAnneal, IncrementalFractionsEqualAFreshExactEvaluationAfterManyMoves) {
    // 16² at four wavelengths on 8 levels: hot sweeps (most texels move) and a greedy pass, the
    // totals only ever updated move by move, then compared with the library's FFT evaluation.
    const Problem p(16, {0.41, 0.5, 0.6, 0.69});
    const double step = 0.165;
    detail::ReliefAnnealer an(p.sets, *p.target, 16, 8, step, detail::anneal_aims(0.002, 0.25), 0.05);
    an.set_relief(random_relief(16, 8, 3));
    std::mt19937_64 rng(5);
    long moves = 0;
    for (int k = 0; k < 6; ++k) {
        moves += an.heat_sweep(k < 3 ? 1e-2 : 1e-4, rng, {});
        an.update_multipliers();
    }
    moves += an.greedy_pass();
    EXPECT_GT(moves, 500);
    const Fractions incremental = an.fractions();
    const Fractions exact = p.exact(an.level(), 8, step);
    double worst = 0.0;
    for (std::size_t w = 0; w < exact.size(); ++w)
        for (std::size_t q = 0; q < exact[w].size(); ++q) worst = std::max(worst, std::abs(incremental[w][q] - exact[w][q]));
    EXPECT_LT(worst, 1e-12);
    // The score reads the same fractions.
    const Measures m = measures(exact);
    const detail::AnnealScore s = an.score();
    EXPECT_NEAR(s.region, m.region, 1e-12);
    EXPECT_NEAR(s.cone_worst, m.cone, 1e-12);
    EXPECT_NEAR(s.uniformity_worst, m.u, 1e-10);
}

TEST(DesignAnneal, ATinyTileEndsOnTheExhaustiveOptimum) {
    // A 3² tile on 3 levels at two wavelengths: all 3^9 reliefs scored by the library, the best
    // region with the cone within its aim (the uniformity aim left loose: the 3² tile's orders
    // leave half the bins empty) against the anneal's relief kept.
    const std::vector<double> lambdas{0.45, 0.6};
    const Problem p(3, lambdas);
    const int K = 3;
    const double step = 0.16;
    // One thread: 3^9 evaluations of a few orders each, where the threads' meetings would cost more.
    const AnnealTestThreads one(1);
    std::vector<Measures> all;
    std::vector<int> level(9, 0);
    for (int code = 0; code < 19683; ++code) {
        for (int t = 0, c = code; t < 9; ++t, c /= 3) level[static_cast<std::size_t>(t)] = c % 3;
        all.push_back(measures(p.exact(level, K, step)));
    }
    // The cone's aim halfway between the darkest cone any relief reaches and the cone of the
    // relief of the highest region, so that it binds.
    const Measures top = *std::max_element(all.begin(), all.end(), [](const Measures& x, const Measures& y) { return x.region < y.region; });
    double darkest = 1.0;
    for (const Measures& m : all) darkest = std::min(darkest, m.cone);
    ASSERT_GT(top.cone, darkest + 1e-3);
    const detail::AnnealAims aims{0.5 * (darkest + top.cone), 10.0};
    double best = -1.0;
    for (const Measures& m : all)
        if (m.cone <= aims.cone && m.u <= aims.uniformity) best = std::max(best, m.region);
    ASSERT_GT(best, 0.0);
    ASSERT_LT(best, top.region - 1e-3) << "the cone's aim must bind for the test to mean something";
    detail::AnnealSchedule schedule;
    schedule.sweeps = 300;
    schedule.t_start = 0.05;
    schedule.t_end = 1e-5;
    const detail::AnnealOutcome a =
        detail::anneal_relief(p.sets, *p.target, 3, K, step, aims, schedule, std::vector<int>(9, 0));
    EXPECT_TRUE(a.kept.within_aims);
    EXPECT_NEAR(a.kept.region, best, 1e-12);
    const Measures m = measures(p.exact(a.level, K, step));
    EXPECT_NEAR(m.region, best, 1e-12);
    EXPECT_LE(m.cone, aims.cone);
    EXPECT_FALSE(a.start.within_aims);  // the flat start is a mirror
}

TEST(DesignAnneal, TheSameSeedGivesTheSameReliefWithOneAndTwoThreads) {
    // 32² at 8 wavelengths on 8 levels: a trial's pass is long enough to be shared by the threads.
    std::vector<double> lambdas;
    for (int k = 0; k < 8; ++k) lambdas.push_back(0.4 + (k + 0.5) * 0.3 / 8);
    const Problem p(32, lambdas);
    detail::AnnealSchedule schedule;
    schedule.sweeps = 2;
    schedule.greedy_passes = 0;
    const std::vector<int> start = random_relief(32, 8, 11);
    std::vector<detail::AnnealOutcome> runs;
    for (int n : {1, 2}) {
        const AnnealTestThreads use(n);
        runs.push_back(detail::anneal_relief(p.sets, *p.target, 32, 8, 0.1675, detail::anneal_aims(0.002, 0.25),
                                             schedule, start));
    }
    EXPECT_GT(runs[0].moves, 100);
    EXPECT_EQ(runs[0].level, runs[1].level);
    EXPECT_EQ(runs[0].moves, runs[1].moves);
    EXPECT_EQ(runs[0].kept.region, runs[1].kept.region);
    EXPECT_EQ(runs[0].kept.objective, runs[1].kept.objective);
}

// A 32² anti-mirror at 4 wavelengths (auto: its 16² tile first), a short loop and anneal.
DesignOptions small_annealed(int sweeps) {
    DesignOptions o = test::small_design("anti-mirror", 8, 10, 3);
    o.size = 32;
    o.spectral = 4;
    o.band_um = {0.41, 0.69};
    o.anneal_sweeps = sweeps;
    return o;
}

TEST(DesignAnneal, TheAnnealedRunIsItsTileRepeatedOnTheLevelsAndScoresAsTheExportsExactDiffraction) {
    const DesignOptions o = small_annealed(60);
    const PreparedDesign p = prepare_design(o);
    EXPECT_EQ(p.anneal_sweeps, 60);
    EXPECT_EQ(p.anneal_size, 16);
    const DesignResult r = run_design(p);
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_TRUE(j.contains("anneal"));
    const auto& a = j["anneal"];
    EXPECT_EQ(a["tile"].get<int>(), 16);
    EXPECT_EQ(a["sweeps_run"].get<int>(), 60);
    EXPECT_GT(a["moves"].get<long>(), 0);
    // The run's tile is the annealed 16² relief repeated, on the designed levels.
    ASSERT_EQ(r.level.size(), 1024u);
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x)
            EXPECT_EQ(r.level[static_cast<std::size_t>(y * 32 + x)], r.level[static_cast<std::size_t>((y % 16) * 32 + x % 16)]);
    const double step = r.levels_um[1];
    EXPECT_NEAR(step, a["level_step_um"].get<double>(), 1e-12);
    for (std::size_t t = 0; t < r.heights_um.size(); ++t)
        EXPECT_EQ(r.heights_um[t], r.levels_um[static_cast<std::size_t>(r.level[t])]);
    EXPECT_LE(r.levels_um.back(), o.height_range_um + 1e-12);
    // design.json's exact metrics are the exported heights' exact diffraction (exact_orders, an
    // independent direct sum), and equal the anneal's own score of its tile.
    const auto orders = exact_orders(r.heights_um, 32, o.texel_um, o.omega_i, r.lambdas_um);
    const auto& m = j["metrics"]["exact"];
    double region_mean = 0.0;
    for (std::size_t w = 0; w < orders.size(); ++w) {
        double total = 0.0, cone = 0.0, region = 0.0;
        for (std::size_t k = 0; k < orders[w].power.size(); ++k) {
            const double rr = std::hypot(orders[w].omega_x[k], orders[w].omega_y[k]);
            total += orders[w].power[k];
            if (rr <= 0.05) cone += orders[w].power[k];
            if (rr >= 0.1 && rr <= 0.5) region += orders[w].power[k];
        }
        EXPECT_NEAR(m["specular_fraction"][w].get<double>(), cone / total, 1e-9);
        EXPECT_NEAR(m["region_fraction"][w].get<double>(), region / total, 1e-9);
        region_mean += region / total / static_cast<double>(orders.size());
    }
    EXPECT_NEAR(a["after"]["region_fraction_mean"].get<double>(), region_mean, 1e-9);
    // The anneal keeps the loop's tile unless it finds better within the aims.
    if (a["before"]["within_aims"].get<bool>()) {
        EXPECT_TRUE(a["after"]["within_aims"].get<bool>());
        EXPECT_GE(a["after"]["region_fraction_mean"].get<double>(), a["before"]["region_fraction_mean"].get<double>());
    }
    // Within the aims, the limits are met on the exported relief.
    ASSERT_TRUE(a["after"]["within_aims"].get<bool>());
    EXPECT_TRUE(j["warnings"].empty());
    EXPECT_LE(m["specular_fraction_worst"].get<double>(), o.cone_limit);
    EXPECT_LE(m["uniformity_worst"].get<double>(), o.uniformity_limit);
    // The curve holds the sweeps; the 32² tile ran no loop.
    int sweeps = 0;
    for (const DesignStep& s : r.curve) sweeps += s.phase == "anneal 16x16";
    EXPECT_EQ(sweeps, 60);
    EXPECT_EQ(j["continuation"]["schedule"][1]["iterations"].get<int>(), 0);
    // 0: the continuation as before (no anneal block, the 32² tile designed by the loop).
    const DesignResult plain = run_design(prepare_design(small_annealed(0)));
    EXPECT_FALSE(nlohmann::json::parse(plain.metrics_json).contains("anneal"));
}

TEST(DesignAnneal, BadValuesAndKindsItDoesNotApplyToAreRefusedAndTheDefaultSaysWhyItSkips) {
    const auto refused = [](DesignOptions o, const std::vector<std::string>& needles) {
        try {
            (void)prepare_design(o);
            ADD_FAILURE() << "not refused";
        } catch (const std::exception& e) {
            const std::string what = e.what();
            for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << what;
            EXPECT_EQ(what.find('\n'), std::string::npos);
        }
    };
    refused(small_annealed(-1), {"--anneal-sweeps", "-1"});
    refused(small_annealed(100001), {"--anneal-sweeps", "100001"});
    DesignOptions colour = test::small_design("colour:#00FF00", 8, 10, 3);
    colour.anneal_sweeps = 5;
    refused(colour, {"--anneal-sweeps 5", "colour:#00FF00"});
    DesignOptions errors = small_annealed(5);
    errors.errors.scale = 0.05;
    refused(errors, {"--anneal-sweeps 5", "--fabrication-error"});
    DesignOptions grey = small_annealed(5);
    grey.levels = 0;
    grey.min_feature_um = 1.0;
    refused(grey, {"--anneal-sweeps 5", "--min-feature-um"});
    // The acceptance tile alone: 400 sweeps of 256² cost about 4096 times the 32² tile's.
    DesignOptions large = small_annealed(400);
    large.size = 256;
    large.spectral = 16;
    large.band_um = {0.4, 0.7};
    large.continuation = "off";
    refused(large, {"--anneal-sweeps 400", "256x256", "CPU-s"});
    // The default skips where it does not apply, and says so.
    const auto note_of = [](const PreparedDesign& p, const std::string& needle) {
        for (const auto& n : p.notes)
            if (n.find(needle) != std::string::npos) return true;
        return false;
    };
    large.anneal_sweeps.reset();
    const PreparedDesign pl = prepare_design(large);
    EXPECT_EQ(pl.anneal_sweeps, 0);
    EXPECT_TRUE(note_of(pl, "not annealed"));
    errors.anneal_sweeps.reset();
    const PreparedDesign pe = prepare_design(errors);
    EXPECT_EQ(pe.anneal_sweeps, 0);
    EXPECT_TRUE(note_of(pe, "--fabrication-error"));
    DesignOptions dflt = small_annealed(5);
    dflt.anneal_sweeps.reset();
    const PreparedDesign pd = prepare_design(dflt);
    EXPECT_EQ(pd.anneal_sweeps, detail::k_anneal_default_sweeps);
    EXPECT_TRUE(note_of(pd, "annealed last stage"));
    colour.anneal_sweeps.reset();
    EXPECT_EQ(prepare_design(colour).anneal_sweeps, 0);
    colour.anneal_sweeps = 0;
    EXPECT_EQ(prepare_design(colour).anneal_sweeps, 0);
}

}  // namespace
}  // namespace wavebrdf
