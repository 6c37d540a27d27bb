// `wavebrdf recover --spectral N` knobs of the smoothness continuation (docs/recovery.md, White
// light): --white-smoothness W1,W2,... (or none) and --white-smoothness-iterations N reach the
// pipeline, and bad values fail with one line before any work.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "cli_util.h"

using namespace wavebrdf::test;

namespace {

const std::string kWhite =
    "--size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --spectral 4 --resolution 16 --no-plots "
    "--quiet";

// The largest iteration number of the refine rows of metrics.csv (stage, iteration, ...): the
// continuation's weights × its iterations, then the refinement's.
int last_refine_iteration(const fs::path& metrics) {
    int last = -1;
    for (const std::string& line : lines_of(read_text(metrics)))
        if (line.rfind("refine,", 0) == 0) last = std::max(last, std::stoi(line.substr(7)));
    return last;
}

}  // namespace

TEST(WhiteLightCli, SmoothnessKnobsReachTheContinuationAndBadValuesFailWithOneLine) {
    const fs::path dir = fresh_dir("white_cli");
    // One weight × 3 iterations, then 1 refinement iteration: the refine rows end at iteration 4;
    // two weights: at 7.
    for (const auto& [weights, expected] : std::vector<std::pair<std::string, int>>{{"5", 4}, {"5,0.5", 7}}) {
        SCOPED_TRACE(weights);
        const std::string out = "run_" + std::to_string(expected);
        const CliResult r = run_cli(dir, "recover " + kWhite + " --white-smoothness " + weights +
                                             " --white-smoothness-iterations 3 --refine-iterations 1 --out " + out);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_EQ(last_refine_iteration(dir / out / "metrics.csv"), expected);
    }
    const std::string out = (dir / "bad").string();
    std::string many = "1";  // 65 weights, one more than allowed
    for (int i = 1; i < 65; ++i) many += ",1";
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
        {"--white-smoothness -1", {"--white-smoothness weight -1 is invalid", "0 to 1e12"}},
        {"--white-smoothness 1,x", {"--white-smoothness", "'1,x'"}},
        {"--white-smoothness 1e13", {"--white-smoothness weight 10000000000000 is invalid", "0 to 1e12"}},
        {"--white-smoothness " + many, {"65 weights", "at most 64"}},
        {"--white-smoothness-iterations 10000001", {"--white-smoothness-iterations 10000001", "0 to 10000000"}},
    };
    for (const auto& [args, needles] : cases) {
        SCOPED_TRACE(args);
        expect_one_line_naming(run_cli(dir, "recover " + kWhite + " " + args + " --out " + out), needles);
        EXPECT_FALSE(fs::exists(out) && !fs::is_empty(out)) << "wrote into " << out;
    }
}
