// End-to-end tests of `wavebrdf recover`: bad input fails with one line and writes nothing,
// a small study recovers its truth and writes every promised output, simulated observations
// saved with --save-observations read back through --observations, and the thesis's method
// runs on the same data.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/photon_plan.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

// A small problem that runs in seconds: 8×8 texels of 2 µm, heights within 0.1 µm (one
// wavelength suffices), σ_p = 3 µm.
const std::string kSmallRecover = "--size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --no-plots --quiet";

// The last height_rel_rmse of metrics.csv.
double final_height_error(const fs::path& metrics) {
    const auto lines = lines_of(read_text(metrics));
    EXPECT_GE(lines.size(), 2u);
    if (lines.size() < 2) return std::numeric_limits<double>::quiet_NaN();
    // The fifth column (height_rel_rmse; the sixth is the plane-removed one).
    std::string last = lines.back();
    for (int column = 0; column < 4; ++column) last = last.substr(last.find(',') + 1);
    return std::stod(last.substr(0, last.find(',')));
}

}  // namespace

TEST(RecoverCliTest, BadInputFailsWithOneLineAndWritesNothing) {
    const fs::path dir = fresh_dir("recover");
    const std::string out = (dir / "out").string();
    struct Case {
        std::string args;
        std::vector<std::string> needles;
    };
    const std::vector<Case> cases = {
        // Used to fail only after simulating the observations and writing run.json.
        {"--size 8 --model Kirchhoff --out " + out, {"Kirchhoff", "OHS, ROHS, GHS or RGHS"}},
        {"--truth a.exr --observations o.json --out " + out, {"--truth", "--observations"}},
        {"--method adam --out " + out, {"--method", "adam"}},
        {"--noise poisson:-3 --out " + out, {"poisson:-3"}},
        {"--noise loud --out " + out, {"'loud'"}},
        {"--overlap 0.3 --out " + out, {"overlap", "0.3"}},
        {"--jitter 0.9 --out " + out, {"jitter", "0.9"}},
        {"--size 0 --out " + out, {"--size", "'0'"}},
        {"--lambdas-um 0.5,x --out " + out, {"--lambdas-um", "0.5,x"}},
        {"--loss cmsle:0 --out " + out, {"cmsle:0"}},
        {"--truth missing.exr --out " + out, {"missing.exr"}},
        {"--observations missing.json --size 8 --out " + out, {"missing.json"}},
        // Issue 9: counts are bounded (2147483647 overflowed the progress total), before work.
        {"--method thesis --epochs 2147483647 --out " + out, {"epochs 2147483647", "0 to 10000000"}},
        {"--field-iterations 2147483647 --out " + out, {"--field-iterations 2147483647", "0 to 10000000"}},
        {"--refine-iterations 10000001 --out " + out, {"--refine-iterations 10000001", "0 to 10000000"}},
        // Self-calibration and simulated acquisition errors (calibration.h).
        {"--calibrate exposure,focus --out " + out, {"--calibrate", "'focus'", "positions, exposure, sigma"}},
        {"--simulate-exposure 2,1 --out " + out, {"--simulate-exposure", "2", "at most the max"}},
        {"--simulate-exposure 0.5 --out " + out, {"--simulate-exposure", "MIN,MAX"}},
        {"--simulate-sigma-factor 10 --out " + out, {"--simulate-sigma-factor", "10", "[0.25, 4]"}},
        {"--simulate-position-error-texels -1 --out " + out, {"--simulate-position-error-texels", "-1"}},
        {"--calibrate positions --position-passes 101 --out " + out, {"--position-passes", "101", "0 to 100"}},
        {"--overlap 0 --out " + out, {"--overlap", "0", "0.6 to 0.95"}},
        {"--calibrate positions --overlap 0.96 --out " + out, {"--overlap", "0.96", "0.6 to 0.95"}},
        {"--position-uncertainty-um -2 --out " + out, {"--position-uncertainty-um", "-2", "0 to 1e6"}},
        {"--observations o.json --simulate-sigma-factor 1.2 --size 8 --out " + out, {"--simulate-", "--truth"}},
        // A plan needs a truth to plan for, and renders nothing to save.
        {"--observations o.json --size 8 --plan-only --out " + out, {"--plan-only", "--observations", "nothing to plan"}},
        {"--size 8 --plan-only --save-observations --out " + out, {"--plan-only", "--save-observations"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.args);
        expect_one_line_naming(run_cli(dir, "recover " + c.args + " --quiet"), c.needles);
        EXPECT_FALSE(fs::exists(out) && !fs::is_empty(out)) << "wrote into " << out;
    }
}

TEST(RecoverCliTest, SmallStudyRecoversTheTruthAndWritesEveryOutput) {
    const fs::path dir = fresh_dir("recover");
    const CliResult r = run_cli(dir, "recover " + kSmallRecover + " --save-observations --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const char* name :
         {"estimate.exr", "estimate.png", "truth.exr", "metrics.csv", "run.json", "estimate_height.npy",
          "truth_height.npy", "reference.npy", "final.npy", "observations.json"})
        EXPECT_TRUE(fs::exists(dir / "run" / name)) << name;
    EXPECT_EQ(lines_of(read_text(dir / "run" / "metrics.csv"))[0],
              "stage,iteration,loss,seconds,height_rel_rmse,height_rel_rmse_plane_removed");
    // The estimate, read back from its file, against the truth (an evaluation independent of
    // the metrics the run reports).
    const Heightfield truth = read_heightfield_exr((dir / "run" / "truth.exr").string(), 2.0);
    const Heightfield estimate = read_heightfield_exr((dir / "run" / "estimate.exr").string(), 2.0);
    EXPECT_LT(height_rel_rmse(estimate, truth), 0.01);
    EXPECT_NEAR(final_height_error(dir / "run" / "metrics.csv"), height_rel_rmse(estimate, truth), 1e-5);

    // The saved observations give the same recovery through --observations.
    const CliResult again = run_cli(dir, "recover --observations run/observations.json " + kSmallRecover + " --out again");
    ASSERT_EQ(again.exit_code, 0) << again.err;
    const Heightfield from_files = read_heightfield_exr((dir / "again" / "estimate.exr").string(), 2.0);
    EXPECT_LT(height_rel_rmse(from_files, truth), 0.01);
    EXPECT_FALSE(fs::exists(dir / "again" / "truth.exr"));
}

// Slices rendered with unknown exposures, recovered with --calibrate exposure: calibration.json
// holds what was refined, one exposure per observation near the true one, and the errors.
TEST(RecoverCliTest, CalibratedStudyWritesCalibrationJson) {
    const fs::path dir = fresh_dir("recover");
    const CliResult r = run_cli(dir, "recover " + kSmallRecover + " --simulate-exposure 0.5,2 --calibrate exposure --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json run = nlohmann::json::parse(read_text(dir / "run" / "run.json"));
    EXPECT_EQ(run.at("calibrate"), "exposure");
    const nlohmann::json c = nlohmann::json::parse(read_text(dir / "run" / "calibration.json"));
    EXPECT_EQ(c.at("refined"), "exposure");
    const auto& found = c.at("exposures");
    const auto& truth = c.at("truth").at("exposures");
    ASSERT_EQ(found.size(), run.at("observations").get<std::size_t>());
    ASSERT_EQ(truth.size(), found.size());
    for (std::size_t i = 0; i < found.size(); ++i)
        EXPECT_NEAR(found[i].get<double>() / truth[i].get<double>(), 1.0, 0.02) << i;
    EXPECT_LT(c.at("errors").at("exposure_rel_rms").get<double>(), 0.01);
    EXPECT_TRUE(temporaries_under(dir / "run").empty());
}

// The report plotter is started without a shell: a hostile --out runs nothing (it used to
// run `touch PWNED` through std::system), and an ordinary name with a quote gets its report.
TEST(RecoverCliTest, HostileOutNamesRunNoShellAndGetTheirReport) {
    const fs::path dir = fresh_dir("recover");
    const bool can_plot = python_can_plot();
    for (const std::string name : {"x'; touch PWNED; echo '", "bob's run $(touch PWNED2)"}) {
        SCOPED_TRACE(name);
        const CliResult r = run_cli(dir,
                                    "recover --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 "
                                    "--method thesis --epochs 2 --quiet --out " +
                                        quote(name));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_TRUE(fs::exists(dir / name / "estimate.exr"));
        if (can_plot) {
            EXPECT_TRUE(fs::exists(dir / name / "report.png")) << r.err;
            // The only line: two epochs of the thesis's method do not converge, and say so.
            EXPECT_EQ(lines_of(r.err).size(), 1u) << r.err;
            EXPECT_EQ(r.err.rfind("wavebrdf: warning: the recovery did not converge", 0), 0u)
                << "no warning but the convergence one when the report is drawn: " << r.err;
        }
    }
    for (const auto& entry : fs::recursive_directory_iterator(dir))
        EXPECT_TRUE(entry.path().filename() != "PWNED" && entry.path().filename() != "PWNED2") << entry.path();
}

TEST(RecoverCliTest, ThesisMethodRunsOnTheSameData) {
    const fs::path dir = fresh_dir("recover");
    const CliResult r = run_cli(dir, "recover " + kSmallRecover + " --method thesis --epochs 40 --out thesis");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto lines = lines_of(read_text(dir / "thesis" / "metrics.csv"));
    ASSERT_EQ(lines.size(), 1u + 4u) << "a row every 10 epochs";
    EXPECT_EQ(lines[1].rfind("thesis,10,", 0), 0u) << lines[1];
    EXPECT_TRUE(std::isfinite(final_height_error(dir / "thesis" / "metrics.csv")));
}

// A flat truth (8×8, and 1×1) has no relative height error: the run still writes its
// estimate, with nan in the metrics and "undefined: the truth is flat" in run.json (it used to
// fail in the metric after the recovery, writing no estimate).
TEST(RecoverCliTest, FlatTruthReportsTheMetricAsUndefinedAndWritesTheEstimate) {
    const fs::path dir = fresh_dir("recover");
    write_heightfield_exr((dir / "flat.exr").string(), Heightfield(8, 8, std::vector<double>(64, 0.25), 2.0));
    write_heightfield_exr((dir / "one.exr").string(), Heightfield(1, 1, std::vector<double>(1, 0.0), 2.0));
    for (const std::string name : {"flat", "one"}) {
        SCOPED_TRACE(name);
        const CliResult r = run_cli(dir, "recover --truth " + name +
                                             ".exr --texel-um 2 --sigma-p-um 3 "
                                             "--field-iterations 3 --refine-iterations 2 --no-plots --quiet --out " +
                                             name);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.err.find("undefined: the truth is flat"), std::string::npos) << r.err;
        EXPECT_TRUE(fs::exists(dir / name / "estimate.exr"));
        EXPECT_TRUE(std::isnan(final_height_error(dir / name / "metrics.csv")));
        EXPECT_EQ(nlohmann::json::parse(read_text(dir / name / "run.json")).at("height_rel_rmse"),
                  "undefined: the truth is flat");
    }
}

// Issue 11: a --truth file's texel width applies without --texel-um (recover's default is 2);
// a given one that differs wins, with one warning line naming both values.
TEST(RecoverCliTest, TruthFilesTexelWidthAppliesUnlessGiven) {
    const fs::path dir = fresh_dir("recover");
    write_heightfield_exr((dir / "flat.exr").string(), Heightfield(8, 8, std::vector<double>(64, 0.25), 0.5));
    const std::string common = " --sigma-p-um 1 --field-iterations 3 --refine-iterations 2 --no-plots --quiet --out ";
    const CliResult from_file = run_cli(dir, "recover --truth flat.exr" + common + "file");
    ASSERT_EQ(from_file.exit_code, 0) << from_file.err;
    EXPECT_EQ(from_file.err.find("disagrees"), std::string::npos) << from_file.err;
    const nlohmann::json run = nlohmann::json::parse(read_text(dir / "file" / "run.json"));
    EXPECT_EQ(run.at("texel_um"), 0.5);
    EXPECT_EQ(read_heightfield_exr((dir / "file" / "estimate.exr").string()).texel_um(), 0.5);
    const CliResult given = run_cli(dir, "recover --truth flat.exr --texel-um 2" + common + "given");
    ASSERT_EQ(given.exit_code, 0) << given.err;
    const std::string warning = "wavebrdf: warning: --texel-um 2 disagrees with flat.exr's texel_um 0.5; using 2\n";
    EXPECT_NE(given.err.find(warning), std::string::npos) << given.err;
    EXPECT_EQ(given.err.find("disagrees"), given.err.rfind("disagrees")) << "one warning line: " << given.err;
    EXPECT_EQ(nlohmann::json::parse(read_text(dir / "given" / "run.json")).at("texel_um"), 2.0);
}

// A new run into a non-empty --out is refused; --force replaces a directory of recover's own
// outputs and nothing else.
TEST(RecoverCliTest, OutMustBeNewOrEmptyUnlessForced) {
    const fs::path dir = fresh_dir("recover");
    const std::string fast = kSmallRecover + " --field-iterations 3 --refine-iterations 2";
    const CliResult first = run_cli(dir, "recover " + fast + " --save-observations --out run");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    const std::string metrics_before = read_text(dir / "run" / "metrics.csv");
    expect_one_line_naming(run_cli(dir, "recover " + fast + " --loss mse --out run"), {"--out run", "--force"});
    EXPECT_EQ(read_text(dir / "run" / "metrics.csv"), metrics_before) << "the refused run changed the directory";

    const CliResult forced = run_cli(dir, "recover " + fast + " --loss mse --force --out run");
    ASSERT_EQ(forced.exit_code, 0) << forced.err;
    EXPECT_FALSE(fs::exists(dir / "run" / "observations.json")) << "the old run's observations survived --force";
    EXPECT_FALSE(fs::exists(dir / "run" / "observations"));

    std::ofstream(dir / "run" / "notes.txt") << "mine";
    expect_one_line_naming(run_cli(dir, "recover " + fast + " --force --out run"), {"--out run", "notes.txt"});
    EXPECT_EQ(read_text(dir / "run" / "notes.txt"), "mine");
    EXPECT_TRUE(fs::exists(dir / "run" / "estimate.exr")) << "--force deleted files though a foreign one was there";
}

// The smooth schedule's single-texel trap (experiments/2026-11-23-recovery-speed.md): on this seed the
// 0.667 µm ladder rung left texel (5, 5) 0.218 µm off (0.357 % overall, every other texel within
// 0.022 µm); the outlier repair after the refinement puts it back. ~6 s of CPU.
TEST(RecoverCliTest, SmoothScheduleLeavesNoSingleTexelOutlier) {
    const fs::path dir = fresh_dir("recover");
    const CliResult r = run_cli(dir, "recover --size 32 --resolution 48 --seed 4 --no-plots --quiet --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Heightfield truth = read_heightfield_exr((dir / "run" / "truth.exr").string(), 2.0);
    const Heightfield estimate = read_heightfield_exr((dir / "run" / "estimate.exr").string(), 2.0);
    double mean_e = 0.0, mean_t = 0.0;
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j) {
            mean_e += estimate.height_um(i, j) / double(truth.values().size());
            mean_t += truth.height_um(i, j) / double(truth.values().size());
        }
    double worst_um = 0.0;
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j)
            worst_um = std::max(worst_um,
                                std::abs((estimate.height_um(i, j) - mean_e) - (truth.height_um(i, j) - mean_t)));
    EXPECT_LT(worst_um, 0.05);                            // 0.218 without the repair
    EXPECT_LT(height_rel_rmse(estimate, truth), 0.0005);  // 0.357 % without it
    // Whether the trap occurs depends on the build's float rounding: the Release build lands in it
    // (and the repair reports repair:outliers), the sanitizer build (other optimisation) does not.
    // So the outcome is asserted here; the repair itself is OutlierRepair.*'s.
}

// The plan-only path without photon noise (no pilot), small enough for the sanitizer pass: run.json
// alone, marked plan_only, one footprint centre per planned slice, each distinct and on the surface.
TEST(RecoverCliTest, PlanOnlyWithoutPhotonNoiseWritesTheSlicesPositionsAlone) {
    const fs::path dir = fresh_dir("recover");
    const CliResult plan = run_cli(dir, "recover --size 16 --resolution 48 --height-range-um 0.02 --seed 4 --no-plots "
                                        "--threads 1 --plan-only --out plan");
    ASSERT_EQ(plan.exit_code, 0) << plan.err;
    EXPECT_NE(plan.err.find("49 positions on a 7x7 raster"), std::string::npos) << plan.err;
    std::vector<std::string> written;
    for (const auto& e : fs::directory_iterator(dir / "plan")) written.push_back(e.path().filename().string());
    EXPECT_EQ(written, std::vector<std::string>{"run.json"});
    const auto p = nlohmann::json::parse(read_text(dir / "plan" / "run.json"));
    EXPECT_TRUE(p.at("plan_only").get<bool>());
    EXPECT_FALSE(p.contains("photon_plan"));
    const auto& positions = p.at("positions_um");
    ASSERT_EQ(positions.size(), 49u);
    EXPECT_EQ(p.at("observations").get<std::size_t>(), positions.size());
    const double side_um = 16 * p.at("texel_um").get<double>();
    std::set<std::pair<double, double>> distinct;
    for (const auto& c : positions) {
        const double x = c[0].get<double>(), y = c[1].get<double>();
        EXPECT_TRUE(x >= 0.0 && x <= side_um && y >= 0.0 && y <= side_um) << x << ", " << y;
        distinct.insert({x, y});
    }
    EXPECT_EQ(distinct.size(), positions.size());
}

// A first-order prediction well within the target (8² of 2 µm heights at 1e4 photons) runs no
// pilot, and the plan says why, in the log and in run.json; the reason is the pilot's own rule
// (prediction × k_photon_pilot_band below the target). Small enough for the sanitizer pass.
TEST(RecoverCliTest, APlanWellWithinTheTargetSaysWhyNoPilotRan) {
    const fs::path dir = fresh_dir("recover");
    const CliResult plan = run_cli(dir, "recover --size 8 --resolution 16 --noise poisson:1e4 --seed 4 --no-plots "
                                        "--threads 1 --plan-only --out plan");
    ASSERT_EQ(plan.exit_code, 0) << plan.err;
    const std::string why = "the first-order prediction is below the target / 1.5";
    EXPECT_NE(plan.err.find("no pilot: " + why), std::string::npos) << plan.err;
    const auto p = nlohmann::json::parse(read_text(dir / "plan" / "run.json")).at("photon_plan");
    EXPECT_EQ(p.at("exposures").get<int>(), 1);
    EXPECT_LT(p.at("predicted_error").get<double>() * k_photon_pilot_band, p.at("target_error").get<double>());
    const auto& pilot = p.at("pilot");
    EXPECT_FALSE(pilot.at("ran").get<bool>());
    EXPECT_EQ(pilot.at("why_not"), why);
    EXPECT_EQ(pilot.at("first_order_exposures").get<int>(), 1);
    EXPECT_FALSE(pilot.contains("ratio") || pilot.contains("errors_um")) << pilot.dump();
}

// --plan-only plans as the run does (the same photon plan and pilot, the same slices) and writes
// run.json alone. 16² of 20 nm at 1e5 photons: the first-order plan asks 3 exposures and the pilot
// runs (one 16² tile, 4 draws), so a plan that skipped or changed it would differ from the run's.
TEST(RecoverCliTest, PlanOnlyPlansAsTheRunAndWritesRunJsonAlone) {
    const fs::path dir = fresh_dir("recover");
    const std::string args =
        "recover --size 16 --resolution 48 --noise poisson:1e5 --height-range-um 0.02 --seed 4 --no-plots --threads 1";
    const CliResult plan = run_cli(dir, args + " --plan-only --out plan");
    ASSERT_EQ(plan.exit_code, 0) << plan.err;
    EXPECT_NE(plan.err.find("plan: photon-limited"), std::string::npos) << plan.err;
    std::vector<std::string> written;
    for (const auto& e : fs::directory_iterator(dir / "plan")) written.push_back(e.path().filename().string());
    EXPECT_EQ(written, std::vector<std::string>{"run.json"});
    const CliResult full = run_cli(dir, args + " --quiet --save-observations --out full");
    ASSERT_EQ(full.exit_code, 0) << full.err;
    const auto p = nlohmann::json::parse(read_text(dir / "plan" / "run.json"));
    const auto f = nlohmann::json::parse(read_text(dir / "full" / "run.json"));
    EXPECT_TRUE(p.at("plan_only").get<bool>());
    EXPECT_FALSE(p.contains("convergence") || p.contains("finished"));
    for (const char* key : {"plan", "noise", "loss", "observations", "wavelengths_um", "sigma_p_um", "resolution", "size"})
        EXPECT_EQ(p.at(key), f.at(key)) << key;
    const auto& pp = p.at("photon_plan");
    const auto& fp = f.at("photon_plan");
    EXPECT_EQ(pp.at("exposures").get<int>(), 3);
    for (const char* key : {"exposures", "capped", "predicted_error", "predicted_error_one_exposure", "predicted_bias_um"})
        EXPECT_EQ(pp.at(key), fp.at(key)) << key;
    ASSERT_TRUE(pp.at("pilot").at("ran").get<bool>());
    for (const char* key : {"errors_um", "predicted_um", "ratio", "ratio_sd", "upper_ratio", "exposures"})
        EXPECT_EQ(pp.at("pilot").at(key), fp.at("pilot").at(key)) << key;
    // The footprint centres: the run's slices' positions (one light, one wavelength: one slice each).
    const auto slices = nlohmann::json::parse(read_text(dir / "full" / "observations.json")).at("observations");
    const auto& positions = p.at("positions_um");
    ASSERT_EQ(positions.size(), slices.size());
    for (std::size_t k = 0; k < slices.size(); ++k) {
        EXPECT_EQ(positions[k][0].get<double>(), slices[k].at("x_um").get<double>()) << k;
        EXPECT_EQ(positions[k][1].get<double>(), slices[k].at("y_um").get<double>()) << k;
    }
}
