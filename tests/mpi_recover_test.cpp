// `mpiexec -n K wavebrdf recover …` (docs/scale.md): the observations sharded over K ranks, the
// sums over observations exact (src/core/exact_sum.h). Compared with the one-process run of the
// same arguments: the same heights bit for bit for K = 2 and 3 and for one process on one or two
// threads (docs/scale.md, "Equality with one process"), rank 0 alone writing and printing.
// Compiled only when the library is built with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

// `wavebrdf args` on `ranks` ranks (0: without mpiexec) in `dir`, `threads` threads each.
CliResult run_ranks(const fs::path& dir, int ranks, const std::vector<std::string>& args, int threads = 1) {
    return run_cli_on_ranks(dir, ranks, args, threads);
}

// A small recovery: 12², one wavelength, few iterations (a few seconds on 2 cores).
std::vector<std::string> recover_args(const std::string& out) {
    return {"recover", "--size",
            "12",      "--seed",
            "3",       "--lambdas-um",
            "0.6",     "--height-range-um",
            "0.2",     "--field-iterations",
            "10",      "--refine-iterations",
            "5",       "--no-plots",
            "--quiet", "--out",
            out};
}

double max_relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
    double diff = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        diff = std::max(diff, std::abs(a[i] - b[i]));
        scale = std::max(scale, std::abs(a[i]));
    }
    return diff / scale;
}

TEST(MpiRecover, ShardedRunsAreReproducibleAndMatchTheOneProcessRun) {
    const fs::path dir = fresh_dir("mpi_recover");
    const CliResult one = run_ranks(dir, 0, recover_args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "estimate_height.npy");
    ASSERT_EQ(reference.size(), 144u);
    // One process on two threads: the same bits (the sums do not depend on the thread count).
    const CliResult two_threads = run_ranks(dir, 0, recover_args("one_t2"), 2);
    ASSERT_EQ(two_threads.exit_code, 0) << two_threads.err;
    EXPECT_EQ(read_npy(dir / "one_t2" / "estimate_height.npy"), reference) << "1 process, 2 threads";
    for (int ranks : {2, 3}) {
        const std::string a = "k" + std::to_string(ranks) + "a", b = "k" + std::to_string(ranks) + "b";
        const CliResult first = run_ranks(dir, ranks, recover_args(a));
        ASSERT_EQ(first.exit_code, 0) << first.err;
        const CliResult second = run_ranks(dir, ranks, recover_args(b));
        ASSERT_EQ(second.exit_code, 0) << second.err;
        const std::vector<double> x = read_npy(dir / a / "estimate_height.npy");
        const std::vector<double> y = read_npy(dir / b / "estimate_height.npy");
        ASSERT_EQ(x.size(), reference.size());
        // The same bits for the same number of ranks, and the one-process heights bit for bit
        // (exact sums: the split over ranks changes no sum; the bound is 1e-9).
        EXPECT_EQ(x, y) << ranks << " ranks";
        EXPECT_EQ(x, reference) << ranks << " ranks; max relative difference " << max_relative_difference(reference, x);
        // Only rank 0 wrote: the run's files once, no other file beside them.
        EXPECT_NE(read_text(dir / a / "run.json").find("\"observations\": 25"), std::string::npos)
            << "run.json counts every rank's observations";
        EXPECT_TRUE(temporaries_under(dir / a).empty());
        // --quiet: no rank prints, but for rank 0's warning that 10 + 5 iterations did not converge.
        for (const std::string& line : lines_of(first.err))
            EXPECT_EQ(line.rfind("wavebrdf: warning: the recovery did not converge", 0), 0u) << first.err;
        EXPECT_LE(lines_of(first.err).size(), 1u) << first.err;
    }
}

TEST(MpiRecover, SavedObservationsAreEveryRanksGatheredOnRankZero) {
    const fs::path dir = fresh_dir("mpi_recover");
    std::vector<std::string> one = recover_args("one"), two = recover_args("two");
    for (auto* args : {&one, &two}) {
        args->push_back("--save-observations");
        // No iterations: only the observations matter here.
        for (std::size_t i = 0; i + 1 < args->size(); ++i)
            if ((*args)[i] == "--field-iterations" || (*args)[i] == "--refine-iterations") (*args)[i + 1] = "0";
    }
    ASSERT_EQ(run_ranks(dir, 0, one).exit_code, 0);
    const CliResult r = run_ranks(dir, 2, two);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // The same observations (their noise-free references: rendered per observation, the same
    // bits whichever rank rendered them) in the same order.
    EXPECT_EQ(read_text(dir / "one" / "observations.json"), read_text(dir / "two" / "observations.json"));
    for (const auto& entry : fs::directory_iterator(dir / "one" / "observations"))
        EXPECT_EQ(read_text(entry.path()), read_text(dir / "two" / "observations" / entry.path().filename()))
            << entry.path().filename();
}

// Self-calibration under MPI: exposures and the σ_p scale refined from slices rendered with
// acquisition errors (drawn per observation: the same whatever the split) give the one-process
// heights and calibration.json bit for bit (the exposures are per slice, every sum exact).
TEST(MpiRecover, CalibratedRunsOnTwoRanksEqualOneProcess) {
    const fs::path dir = fresh_dir("mpi_recover");
    const auto args = [](const std::string& out) {
        std::vector<std::string> a = recover_args(out);
        a.insert(a.end() - 2,
                 {"--calibrate", "exposure,sigma", "--simulate-exposure", "0.5,2", "--simulate-sigma-factor", "1.1"});
        return a;
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const CliResult two = run_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    EXPECT_EQ(read_npy(dir / "one" / "estimate_height.npy"), read_npy(dir / "two" / "estimate_height.npy"));
    const std::string calibration = read_text(dir / "one" / "calibration.json");
    EXPECT_NE(calibration.find("\"refined\": \"exposure,sigma\""), std::string::npos) << calibration;
    EXPECT_NE(calibration.find("\"exposure_rel_rms\""), std::string::npos) << calibration;
    EXPECT_EQ(calibration, read_text(dir / "two" / "calibration.json"));
}

// One process and two ranks on recover_args plus `extra` (inserted before "--out DIR"): both
// succeed and give the same heights and calibration.json (asserted here); rank 0's metrics.csv
// and calibration.json for the caller's checks.
struct OneAndTwoRanks {
    std::string metrics, calibration;
};
OneAndTwoRanks calibrated_on_one_and_two_ranks(const std::string& name, const std::vector<std::string>& extra) {
    const fs::path dir = fresh_dir(name);
    const auto args = [&](const std::string& out) {
        std::vector<std::string> a = recover_args(out);
        a.insert(a.end() - 2, extra.begin(), extra.end());
        return a;
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    EXPECT_EQ(one.exit_code, 0) << one.err;
    const CliResult two = run_ranks(dir, 2, args("two"));
    EXPECT_EQ(two.exit_code, 0) << two.err;
    if (one.exit_code != 0 || two.exit_code != 0) return {};  // (reported above)
    EXPECT_EQ(read_npy(dir / "one" / "estimate_height.npy"), read_npy(dir / "two" / "estimate_height.npy"));
    OneAndTwoRanks r{read_text(dir / "one" / "metrics.csv"), read_text(dir / "one" / "calibration.json")};
    EXPECT_EQ(r.calibration, read_text(dir / "two" / "calibration.json"));
    return r;
}

// Position self-calibration under MPI (field_positions.h, recover_positions.h): the position
// correction inside the field stage, the joint refinement and the position loop (on by default:
// the registration, its Newton step and the rescue decide from exact collective sums; here 1
// passes) sum every position's terms exactly over the ranks, so two ranks give the one-process
// heights and offsets bit for bit.
TEST(MpiRecover, PositionCalibratedRunsOnTwoRanksEqualOneProcess) {
    const OneAndTwoRanks r = calibrated_on_one_and_two_ranks(
        "mpi_recover_positions",
        {"--calibrate", "positions", "--simulate-position-error-texels", "0.5", "--position-passes", "1"});
    if (r.metrics.empty()) return;  // a run failed (reported)
    // The loop ran (its per-pass lines in the metrics), the same on both.
    EXPECT_NE(r.metrics.find("positions:newton"), std::string::npos) << r.metrics.substr(0, 400);
    EXPECT_NE(r.metrics.find("positions:register"), std::string::npos);
    const std::string& calibration = r.calibration;
    EXPECT_NE(calibration.find("\"position_offsets_um\""), std::string::npos) << calibration;
    // The simulated offsets are mean-free (a common offset is an unobservable shift of the
    // surface), as the refined ones (the gauge).
    const nlohmann::json j = nlohmann::json::parse(calibration);
    for (const char* which : {"truth", "estimate"}) {
        const nlohmann::json& offsets = std::string(which) == "truth" ? j["truth"]["position_offsets_um"]
                                                                      : j["position_offsets_um"];
        ASSERT_TRUE(offsets.is_array()) << which;
        double mean[2] = {0.0, 0.0}, rms = 0.0;
        for (const auto& o : offsets)
            for (int c = 0; c < 2; ++c) {
                mean[c] += o[std::size_t(c)].get<double>() / double(offsets.size());
                rms += std::pow(o[std::size_t(c)].get<double>(), 2) / double(2 * offsets.size());
            }
        EXPECT_GT(std::sqrt(rms), 0.1) << which;
        EXPECT_NEAR(mean[0], 0.0, 1e-9) << which;
        EXPECT_NEAR(mean[1], 0.0, 1e-9) << which;
    }
}

// Positions, exposures and σ_p calibrated together (docs/recovery.md, "Self-calibration: all at
// once"): the field stage's held exposures are each rank's own slices' (exposures_at, local),
// the rest exact collective sums, so two ranks give the one-process heights and calibration.json
// bit for bit, through the first recovery and one pass of the position loop.
TEST(MpiRecover, AllCalibratedRunsOnTwoRanksEqualOneProcess) {
    const OneAndTwoRanks r = calibrated_on_one_and_two_ranks(
        "mpi_recover_all", {"--calibrate", "all", "--simulate-position-error-texels", "0.5", "--simulate-exposure",
                            "0.5,2", "--simulate-sigma-factor", "1.2", "--position-passes", "1"});
    if (r.metrics.empty()) return;  // a run failed (reported)
    EXPECT_NE(r.metrics.find("exposures:held"), std::string::npos) << r.metrics.substr(0, 400);
    EXPECT_NE(r.metrics.find("positions:register"), std::string::npos);
    EXPECT_NE(r.calibration.find("\"exposures\""), std::string::npos) << r.calibration;
}

// White light under MPI (docs/recovery.md, White light): RGB slices only, the blurred fit on
// the RGB channels, the smoothness continuation, the spectral refinement and the defect repair
// (which decides on the collective loss) on two ranks give the one-process heights bit for bit.
TEST(MpiRecover, WhiteLightRunsOnTwoRanksEqualOneProcess) {
    const fs::path dir = fresh_dir("mpi_recover_white");
    const auto args = [](const std::string& out) {
        return std::vector<std::string>{
            "recover", "--size",       "12", "--texel-um",          "2", "--sigma-p-um", "3",    "--spectral",
            "4",       "--resolution", "24", "--refine-iterations", "8", "--seed",       "6211", "--no-plots",
            "--quiet", "--out",        out};
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "estimate_height.npy");
    ASSERT_EQ(reference.size(), 144u);
    // The white path ran: blurred fit and repair stages, no field stage (no laser slice).
    const std::string metrics = read_text(dir / "one" / "metrics.csv");
    EXPECT_NE(metrics.find("repair,"), std::string::npos) << "the white-light repair stage ran";
    EXPECT_EQ(metrics.find("unwrap,"), std::string::npos) << "no field stage without a laser slice";
    const CliResult two = run_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    const std::vector<double> x = read_npy(dir / "two" / "estimate_height.npy");
    ASSERT_EQ(x.size(), reference.size());
    EXPECT_EQ(x, reference) << "max relative difference " << max_relative_difference(reference, x);
}

// The field stage on tiles (docs/scale.md, "One machine: the field stage on tiles") under MPI:
// every rank runs every tile with its share of the tile's observations, so 2 ranks give the
// one-process heights bit for bit. The smallest run that cuts: 32 rows (3 cores of ~11 texels
// plus margins of 10: reach 6 + ramp 4), 8 columns (not cut: one periodic tile across), 24²
// slices. The tiled run must differ from the whole-surface run (else no tile was cut).
TEST(MpiRecover, TiledFieldStageOnTwoRanksEqualsOneProcess) {
    const fs::path dir = fresh_dir("mpi_recover_tiles");
    const auto args = [](const std::string& out, const std::string& threshold) {
        return std::vector<std::string>{"recover", "--size",
                                        "32x8",    "--seed",
                                        "3",       "--lambdas-um",
                                        "0.6",     "--height-range-um",
                                        "0.2",     "--resolution",
                                        "24",      "--field-iterations",
                                        "6",       "--refine-iterations",
                                        "3",       "--field-tile-threshold",
                                        threshold, "--field-tile-core",
                                        "12",      "--no-plots",
                                        "--quiet", "--out",
                                        out};
    };
    const CliResult one = run_ranks(dir, 0, args("one", "16"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "estimate_height.npy");
    ASSERT_EQ(reference.size(), 256u);
    // Three tiles of 6 iterations each: 18 field rows (the whole surface: 6).
    const std::string metrics = read_text(dir / "one" / "metrics.csv");
    std::size_t field_rows = 0;
    for (std::size_t at = metrics.find("\nfield:"); at != std::string::npos; at = metrics.find("\nfield:", at + 1))
        ++field_rows;
    EXPECT_EQ(field_rows, 18u) << "the field stage ran on 3 tiles";
    const CliResult whole = run_ranks(dir, 0, args("whole", "0"));
    ASSERT_EQ(whole.exit_code, 0) << whole.err;
    EXPECT_NE(read_npy(dir / "whole" / "estimate_height.npy"), reference) << "the tiles changed nothing";
    const CliResult two = run_ranks(dir, 2, args("two", "16"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    const std::vector<double> x = read_npy(dir / "two" / "estimate_height.npy");
    ASSERT_EQ(x.size(), reference.size());
    EXPECT_EQ(x, reference) << "max relative difference " << max_relative_difference(reference, x);
}

// GHS slices under MPI (field_proxy.h): the blurred fit and the field stage through the
// separable proxy, the refinement on GHS itself; two ranks give the one-process heights bit for
// bit.
TEST(MpiRecover, GhsRunsOnTwoRanksEqualOneProcess) {
    const fs::path dir = fresh_dir("mpi_recover_ghs");
    const auto args = [](const std::string& out) {
        std::vector<std::string> a = recover_args(out);
        a.insert(a.end() - 2, {"--model", "GHS"});
        return a;
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "estimate_height.npy");
    ASSERT_EQ(reference.size(), 144u);
    EXPECT_NE(read_text(dir / "one" / "metrics.csv").find("unwrap,"), std::string::npos)
        << "the field stage ran (through the proxy)";
    const CliResult two = run_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    const std::vector<double> x = read_npy(dir / "two" / "estimate_height.npy");
    ASSERT_EQ(x.size(), reference.size());
    EXPECT_EQ(x, reference) << "max relative difference " << max_relative_difference(reference, x);
}

// σ_p alone calibrated under MPI: the search before the field stage, the second search at the
// unwrapped heights with the field stage run again (sigma_search.h), and the refinement's σ
// rounds give the one-process heights and calibration.json bit for bit on two ranks.
TEST(MpiRecover, SigmaSearchedTwiceOnTwoRanksEqualsOneProcess) {
    const fs::path dir = fresh_dir("mpi_recover_sigma");
    const auto args = [](const std::string& out) {
        std::vector<std::string> a = recover_args(out);
        a.insert(a.end() - 2, {"--calibrate", "sigma", "--simulate-sigma-factor", "1.3"});
        return a;
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    EXPECT_NE(read_text(dir / "one" / "metrics.csv").find("sigma:unwrapped,"), std::string::npos)
        << "the second search ran";
    const CliResult two = run_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    EXPECT_EQ(read_npy(dir / "one" / "estimate_height.npy"), read_npy(dir / "two" / "estimate_height.npy"));
    EXPECT_EQ(read_text(dir / "one" / "calibration.json"), read_text(dir / "two" / "calibration.json"));
}

TEST(MpiRecover, ABadOptionFailsWithOneLineNotOnePerRank) {
    const fs::path dir = fresh_dir("mpi_recover");
    const CliResult bad = run_ranks(dir, 2, {"recover", "--size", "12", "--no-such-option", "--out", "x"});
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_EQ(lines_of(bad.err).size(), 1u) << bad.err;
    // An error the command raises (every rank alike): printed once too.
    const CliResult noise = run_ranks(dir, 2, {"recover", "--size", "12", "--noise", "loud", "--out", "y"});
    EXPECT_NE(noise.exit_code, 0);
    ASSERT_EQ(lines_of(noise.err).size(), 1u) << noise.err;
    EXPECT_NE(noise.err.find("loud"), std::string::npos) << noise.err;
    // The thesis's method runs on one process: refused, once.
    const CliResult thesis = run_ranks(dir, 2, {"recover", "--size", "12", "--method", "thesis", "--out", "z"});
    EXPECT_NE(thesis.exit_code, 0);
    ASSERT_EQ(lines_of(thesis.err).size(), 1u) << thesis.err;
    EXPECT_NE(thesis.err.find("one process"), std::string::npos) << thesis.err;
}

}  // namespace
}  // namespace wavebrdf::test

#endif  // WAVEBRDF_HAS_MPI
