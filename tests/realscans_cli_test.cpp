// `wavebrdf recover` from a measured file to an estimate in one command, and a recovery that
// did not converge saying so without the truth (convergence.h): the misfit against the photon
// noise floor, in the CLI's warning and run.json. The real scans are read from
// ../shared/real-surfaces/ (never committed); absent, the test skips, or fails where CI is set.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/io.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/texel_texture.h"

namespace wavebrdf::test {
namespace {

bool contains(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

nlohmann::json run_json(const fs::path& dir) { return nlohmann::json::parse(read_text(dir / "run.json")); }

// ../shared/real-surfaces/ beside the repository (or beside the worktree's parent), else "".
fs::path shared_surfaces() {
    for (const fs::path& p : {fs::path(WAVEBRDF_SOURCE_DIR) / ".." / "shared" / "real-surfaces",
                              fs::path(WAVEBRDF_SOURCE_DIR) / ".." / ".." / "shared" / "real-surfaces"})
        if (fs::is_directory(p)) return fs::canonical(p);
    return {};
}

// The study's 16² surface with photon noise, 48² slices (a few seconds).
const std::string kNoisy = "recover --size 16 --resolution 48 --noise poisson:1e4 --seed 4 --no-plots";

// A run stopped before its field and refinement stages (0 iterations each) is left several
// times the photon-noise floor off: it warns, on stderr and in run.json; the same run with the
// library's schedule sits on the floor and does not.
TEST(RealScansCli, ARecoveryThatDidNotConvergeSaysSoWithoutTheTruth) {
    const fs::path dir = fresh_dir("realscans");
    const CliResult stopped = run_cli(dir, kNoisy + " --field-iterations 0 --refine-iterations 0 --out stopped");
    ASSERT_EQ(stopped.exit_code, 0) << stopped.err;
    EXPECT_TRUE(contains(stopped.err, "wavebrdf: warning: the recovery did not converge: the slices' misfit is"))
        << stopped.err;
    const nlohmann::json bad = run_json(dir / "stopped");
    EXPECT_FALSE(bad["convergence"]["converged"].get<bool>());
    EXPECT_EQ(bad["convergence"]["floor"], "poisson");
    EXPECT_GT(bad["convergence"]["misfit_ratio"].get<double>(), 1.05);
    bool listed = false;
    for (const auto& w : bad["warnings"]) listed = listed || contains(w.get<std::string>(), "did not converge");
    EXPECT_TRUE(listed) << bad["warnings"].dump();

    const CliResult full = run_cli(dir, kNoisy + " --out full");
    ASSERT_EQ(full.exit_code, 0) << full.err;
    EXPECT_FALSE(contains(full.err, "did not converge")) << full.err;
    const nlohmann::json good = run_json(dir / "full");
    EXPECT_TRUE(good["convergence"]["converged"].get<bool>());
    // On the floor: a little below it (the estimate fits part of the noise), not above.
    EXPECT_NEAR(good["convergence"]["misfit_ratio"].get<double>(), 1.0, 0.05);
    // The misfit passed, so the error bars were computed for the check: within the target.
    EXPECT_FALSE(contains(full.err, "likely inaccurate")) << full.err;
    ASSERT_TRUE(good["convergence"].contains("predicted_error_relative")) << good["convergence"].dump();
    EXPECT_LT(good["convergence"]["predicted_error_relative"].get<double>(), 0.01);
    EXPECT_TRUE(contains(full.err, "convergence: the error bars predict an rms height error of")) << full.err;
    // The texture check (texel_texture.h) ran at the bars' σ: a smooth generated surface holds
    // no texel-scale spikes, so it counts few texels and does not warn.
    ASSERT_TRUE(good["convergence"].contains("texture")) << good["convergence"].dump();
    EXPECT_EQ(good["convergence"]["texture"]["sigma_source"], "error bars");
    EXPECT_LT(good["convergence"]["texture"]["fraction"].get<double>(), k_texture_fraction);
    EXPECT_FALSE(good["convergence"]["texture"]["warned"].get<bool>());
    EXPECT_TRUE(contains(full.err, "convergence: texture: ")) << full.err;
    // The stopped run's misfit said it already: no bars were computed for it.
    EXPECT_FALSE(bad["convergence"].contains("predicted_error_relative")) << bad["convergence"].dump();
    // The truth agrees with the verdicts: the stopped run is worse than the target, the full one meets it.
    const Heightfield truth = read_heightfield_exr((dir / "full" / "truth.exr").string(), 2.0);
    EXPECT_GT(height_rel_rmse(read_heightfield_exr((dir / "stopped" / "estimate.exr").string(), 2.0), truth), 0.01);
    EXPECT_LT(height_rel_rmse(read_heightfield_exr((dir / "full" / "estimate.exr").string(), 2.0), truth), 0.01);
}

// sur-2's binary texel texture in small (texel-scale spikes, texel_texture.h): a 32² tile of
// 3.484 µm texels, a smooth 3.4 nm rms surface whose texels on rows 8–20 are raised by 7.5 nm
// at random. The run's estimate keeps the texture, and the check says, without the truth,
// that it is likely inaccurate for it (about 9 CPU s; measured 1.9 % off, 12 % of the texels).
TEST(RealScansCli, ABinaryTexelTextureIsCalledLikelyInaccurateWithoutTheTruth) {
    const fs::path dir = fresh_dir("realscans");
    SurfaceParams p;
    p.rows = p.cols = 32;
    p.texel_um = 3.484;
    p.correlation_um = 4.0 * p.texel_um;
    p.rms_height_um = 0.0034;
    p.seed = 3;
    const Heightfield base = generate_heightfield(p);
    std::vector<double> v = base.values();
    std::mt19937_64 rng(20261130);
    std::bernoulli_distribution flip(0.5);
    for (int i = 8; i < 21; ++i)
        for (int j = 0; j < 32; ++j)
            if (flip(rng)) v[std::size_t(i) * 32 + j] += 0.0075 / p.texel_um;
    write_heightfield_exr((dir / "textured.exr").string(), base.with_values(v));
    const CliResult run = run_cli(dir, "recover --truth textured.exr --noise poisson:1e4 --seed 1 --no-plots --out run");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const nlohmann::json c = run_json(dir / "run")["convergence"];
    ASSERT_TRUE(c.contains("texture")) << c.dump();
    EXPECT_GE(c["texture"]["fraction"].get<double>(), k_texture_fraction) << c.dump();
    EXPECT_TRUE(c["texture"]["warned"].get<bool>()) << c.dump();
    EXPECT_FALSE(c["converged"].get<bool>());
    EXPECT_TRUE(contains(run.err, "off their 3x3 median by more than the estimate's rms height")) << run.err;
    EXPECT_TRUE(contains(run.err, "\"Spikes\"")) << run.err;
    // The truth agrees: the estimate misses the target.
    const Heightfield truth = read_heightfield_exr((dir / "run" / "truth.exr").string());
    EXPECT_GT(height_rel_rmse(read_heightfield_exr((dir / "run" / "estimate.exr").string()), truth), 0.01);
}

// Photon noise on nm heights: the recovery explains the slices as well as their noise allows
// (the misfit on the floor), yet 10⁴ photons per slice do not pin heights of a few nm to 1 % of
// their range. The error bars the check computes say so without the truth; the truth confirms
// the miss and that the bars' prediction is of its size. The same surface with a µm range meets
// the target, and the bars say that too.
TEST(RealScansCli, AFitOfThePhotonNoiseIsCalledLikelyInaccurateWithoutTheTruth) {
    const fs::path dir = fresh_dir("realscans");
    // One exposure per slice (the photon-aware planner off): the photon limit as it comes.
    const CliResult nm = run_cli(dir, kNoisy + " --height-range-um 0.02 --target-error 0 --out nm");
    ASSERT_EQ(nm.exit_code, 0) << nm.err;
    const nlohmann::json run = run_json(dir / "nm");
    // The misfit cannot tell: on the floor.
    EXPECT_LT(run["convergence"]["misfit_ratio"].get<double>(), k_misfit_ratio_limit);
    EXPECT_FALSE(contains(nm.err, "did not converge")) << nm.err;
    // The bars can.
    EXPECT_TRUE(contains(nm.err, "wavebrdf: warning: the recovery is likely inaccurate: the misfit is on the "
                                 "photon-noise floor, but the error bars predict an rms height error of"))
        << nm.err;
    EXPECT_FALSE(run["convergence"]["converged"].get<bool>());
    const double predicted = run["convergence"]["predicted_error_relative"].get<double>();
    EXPECT_GT(predicted, k_predicted_error_limit);
    bool listed = false;
    for (const auto& w : run["warnings"]) listed = listed || contains(w.get<std::string>(), "likely inaccurate");
    EXPECT_TRUE(listed) << run["warnings"].dump();
    // The truth: a miss, and of the predicted size. The bars are the curvature at the loss's
    // minimum; the schedule stops where the loss is flat, short of fitting every noise direction
    // they count, so they err on the safe side here (measured 2.1x the error; 1.1x at a 2 µm range).
    const Heightfield truth = read_heightfield_exr((dir / "nm" / "truth.exr").string(), 2.0);
    const double error = height_rel_rmse(read_heightfield_exr((dir / "nm" / "estimate.exr").string(), 2.0), truth);
    EXPECT_GT(error, 0.01);
    EXPECT_GT(predicted, 0.8 * error);
    EXPECT_LT(predicted, 3.0 * error);
}

// The check's own error bars turned off: the nm run above is then not warned, and says that its
// noise limit was not judged (run.json and the log); a mode it does not know is refused.
TEST(RealScansCli, TheChecksErrorBarsTurnedOffSayTheNoiseLimitIsNotJudged) {
    const fs::path dir = fresh_dir("realscans");
    const CliResult off = run_cli(dir, kNoisy + " --height-range-um 0.02 --target-error 0 --check-error-bars off --out off");
    ASSERT_EQ(off.exit_code, 0) << off.err;
    EXPECT_FALSE(contains(off.err, "likely inaccurate")) << off.err;
    EXPECT_TRUE(contains(off.err, "convergence: the noise limit is not judged: the check's error bars are off"))
        << off.err;
    const nlohmann::json run = run_json(dir / "off");
    EXPECT_EQ(run["convergence"]["error_bars"], "off");
    EXPECT_EQ(run["convergence"]["check_error_bars"], "off");
    EXPECT_TRUE(run["convergence"]["judged"].get<bool>());  // by the photon-noise floor
    EXPECT_FALSE(run["convergence"].contains("predicted_error_relative")) << run["convergence"].dump();

    const CliResult bad = run_cli(dir, kNoisy + " --check-error-bars sometimes --out bad");
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_TRUE(contains(bad.err, "'sometimes'")) << bad.err;
    EXPECT_FALSE(fs::exists(dir / "bad" / "run.json"));
}

// The amplitude loss states no noise level, so the misfit is not judged. The error bars, their
// noise estimated from the residuals, fail a run where even they exceed the target (nm heights
// under 10 % noise: the truth agrees), but do not pass one: 1 % noise on a 2 µm surface misses
// the target (the truth) while its bars, the curvature at the minimum it found, predict far
// less (docs/recovery.md), so such a run is reported as not judged.
TEST(RealScansCli, AnAmplitudeLossRunIsFailedByWideErrorBarsButNotPassedByNarrowOnes) {
    const fs::path dir = fresh_dir("realscans");
    const std::string amp = "recover --size 16 --resolution 48 --seed 4 --no-plots --loss amplitude "
                            "--check-error-bars always";
    const CliResult wide = run_cli(dir, amp + " --noise gaussian:0.1 --height-range-um 0.02 --out wide");
    ASSERT_EQ(wide.exit_code, 0) << wide.err;
    EXPECT_TRUE(contains(wide.err, "wavebrdf: warning: the recovery is likely inaccurate: the misfit is not judged "
                                   "(the loss states no noise level), but with the noise estimated from the residuals "
                                   "the error bars predict"))
        << wide.err;
    const nlohmann::json w = run_json(dir / "wide");
    EXPECT_EQ(w["convergence"]["floor"], "none");
    EXPECT_EQ(w["convergence"]["error_bars"], "computed");
    EXPECT_TRUE(w["convergence"]["judged"].get<bool>());
    EXPECT_FALSE(w["convergence"]["converged"].get<bool>());
    EXPECT_GT(w["convergence"]["predicted_error_relative"].get<double>(), k_predicted_error_limit);
    const Heightfield wide_truth = read_heightfield_exr((dir / "wide" / "truth.exr").string(), 2.0);
    EXPECT_GT(height_rel_rmse(read_heightfield_exr((dir / "wide" / "estimate.exr").string(), 2.0), wide_truth), 0.01);

    const CliResult narrow = run_cli(dir, amp + " --noise gaussian:0.01 --out narrow");
    ASSERT_EQ(narrow.exit_code, 0) << narrow.err;
    EXPECT_FALSE(contains(narrow.err, "wavebrdf: warning: the recovery")) << narrow.err;
    EXPECT_TRUE(contains(narrow.err, "a lower bound: without a noise level a wrong basin is not seen, so the run is "
                                     "not judged"))
        << narrow.err;
    const nlohmann::json n = run_json(dir / "narrow");
    EXPECT_FALSE(n["convergence"]["judged"].get<bool>());
    const double predicted = n["convergence"]["predicted_error_relative"].get<double>();
    EXPECT_LT(predicted, k_predicted_error_limit);
    // Narrow bars leave it unjudged whatever the truth says: this run ends in a wrong basin (3.8 %
    // off, bars 0.13 %) under GCC and in the right one under clang's sanitizer build, a difference
    // in rounding along the way, and the bars of the two look alike.
}

// The same statements on 8² runs, each line of the report checked against run.json: heights of
// 20 nm under 10 % noise under the amplitude loss (the misfit not judged, the error bars far over
// the target, texel-scale texture, and the estimate's error already at the truth's power in the
// longest band of the spectrum: psd.csv, run.json "psd"); and photon counts, whose misfit is
// judged against the photon-noise floor.
TEST(RealScansCli, AnAmplitudeLossRunIsNotJudgedAndItsSpectrumSaysWhereItFails) {
    const fs::path dir = fresh_dir("realscans");
    const CliResult wide = run_cli(dir, "recover --size 8 --no-plots --loss amplitude --check-error-bars always "
                                        "--resolution 48 --seed 4 --noise gaussian:0.1 --height-range-um 0.02 --out wide");
    ASSERT_EQ(wide.exit_code, 0) << wide.err;
    EXPECT_TRUE(contains(wide.err, "convergence: misfit not judged: loss amplitude states no noise level")) << wide.err;
    EXPECT_TRUE(contains(wide.err, "convergence: the error bars (the noise estimated from the residuals) predict"))
        << wide.err;
    EXPECT_TRUE(contains(wide.err, "convergence: texture: ")) << wide.err;
    EXPECT_TRUE(contains(wide.err, "wavebrdf: warning: the recovery is likely inaccurate")) << wide.err;
    EXPECT_TRUE(contains(wide.err, "spectrum: the error's power reaches the truth's already in the longest band"))
        << wide.err;
    const nlohmann::json w = run_json(dir / "wide");
    EXPECT_EQ(w["convergence"]["floor"], "none");
    EXPECT_TRUE(w["convergence"]["judged"].get<bool>());  // by the error bars
    EXPECT_FALSE(w["convergence"]["converged"].get<bool>());
    EXPECT_FALSE(w["psd"]["resolved_all"].get<bool>());
    EXPECT_EQ(w["psd"]["resolved_q_per_um"].get<double>(), 0.0);
    EXPECT_GT(w["psd"]["error_power_ratio"].get<double>(), 1.0);
    EXPECT_GT(w["convergence"]["predicted_error_relative"].get<double>(), k_predicted_error_limit);

    const CliResult photons = run_cli(dir, "recover --size 8 --no-plots --noise poisson:1e4 --seed 4 --out photons");
    ASSERT_EQ(photons.exit_code, 0) << photons.err;
    const nlohmann::json p = run_json(dir / "photons");
    EXPECT_EQ(p["convergence"]["floor"], "poisson");
    char line[128];
    std::snprintf(line, sizeof line, "convergence: misfit %.3g x the photon-noise floor",
                  p["convergence"]["misfit_ratio"].get<double>());
    EXPECT_TRUE(contains(photons.err, line)) << photons.err;
}

// A measured file straight into the recovery: the bullet land (x3p, striated, with unmeasured
// points elsewhere in the file), a 32² patch conditioned in the same command, planned for its
// measured roughness, with photon noise. It meets the target or warns.
TEST(RealScansCli, AMeasuredScanIsRecoveredInOneCommandAndMeetsTheTargetOrWarns) {
    const fs::path shared = shared_surfaces();
    if (shared.empty()) {
        if (std::getenv("CI")) FAIL() << "../shared/real-surfaces is absent (CI is set: the scans must be there)";
        GTEST_SKIP() << "../shared/real-surfaces is absent: the real scans cannot be read";
    }
    const fs::path dir = fresh_dir("realscans");
    const CliResult r = run_cli(dir, "recover --truth " + quote((shared / "x3ptools__sample-land.x3p").string()) +
                                         " --crop 96,300,32,32 --detrend plane --periodic smooth --noise poisson:1e4 "
                                         "--resolution 48 --no-plots --out land");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json run = run_json(dir / "land");
    bool measured = false;
    for (const auto& note : run["plan"])
        measured = measured || contains(note.get<std::string>(), "planned for the truth's measured roughness");
    EXPECT_TRUE(measured) << run["plan"].dump();
    EXPECT_EQ(run["size"], "32x32");
    EXPECT_DOUBLE_EQ(run["texel_um"].get<double>(), 2.58);
    const Heightfield truth = read_heightfield_exr((dir / "land" / "truth.exr").string(), 2.58);
    const Heightfield estimate = read_heightfield_exr((dir / "land" / "estimate.exr").string(), 2.58);
    const double error = height_rel_rmse(estimate, truth);
    const bool warned = contains(r.err, "wavebrdf: warning: the recovery did not converge");
    EXPECT_TRUE(error <= 0.01 || warned) << "height_rel_rmse " << error << " without a warning:\n" << r.err;
    EXPECT_EQ(warned, !run["convergence"]["converged"].get<bool>());
}

// Bad measured files: one line naming the file, nothing written.
TEST(RealScansCli, BadMeasuredTruthFailsWithOneLine) {
    const fs::path dir = fresh_dir("realscans");
    {
        std::ofstream f(dir / "broken.x3p", std::ios::binary);
        f << "PK\x03\x04 not really a zip archive";
    }
    {
        std::ofstream f(dir / "ragged.txt");
        f << "1 2 3\n4 5\n";
    }
    for (const std::string& file : std::vector<std::string>{"broken.x3p", "ragged.txt", "missing.sdf"}) {
        const CliResult r = run_cli(dir, "recover --truth " + file + " --texel-um 1 --fill harmonic --out run_" + file);
        expect_one_line_naming(r, {file});
        EXPECT_FALSE(fs::exists(dir / ("run_" + file) / "estimate.exr")) << file;
    }
    const fs::path shared = shared_surfaces();
    if (shared.empty()) return;
    // Unmeasured points without --fill: refused with their count and the way out.
    const CliResult holes = run_cli(dir, "recover --truth " + quote((shared / "x3ptools__sample-land.x3p").string()) +
                                             " --crop 0,0,64,64 --quiet --out holes");
    expect_one_line_naming(holes, {"not measured", "--fill"});
}

}  // namespace
}  // namespace wavebrdf::test
