// Error bars under MPI (uncertainty.h): `wavebrdf recover --uncertainty` on K ranks writes the
// one-process uncertainty map bit for bit (every sum over observations exact and allreduced).
// Compiled only when the library is built with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

TEST(MpiUncertainty, ShardedErrorBarsAreTheOneProcessMap) {
    const fs::path dir = fresh_dir("mpi_uncertainty");
    const auto args = [](const std::string& out) {
        return std::vector<std::string>{"recover",     "--size",
                                        "12",          "--seed",
                                        "5305",        "--lambdas-um",
                                        "0.6",         "--height-range-um",
                                        "0.2",         "--field-iterations",
                                        "10",          "--refine-iterations",
                                        "5",           "--noise",
                                        "poisson:1e4", "--uncertainty",
                                        "--no-plots",  "--quiet",
                                        "--out",       out};
    };
    const CliResult one = run_cli_on_ranks(dir, 1, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "uncertainty_height.npy");
    ASSERT_EQ(reference.size(), 144u);
    for (double s : reference) EXPECT_GT(s, 0.0);
    EXPECT_NE(read_text(dir / "one" / "uncertainty.json").find("coverage_2sigma"), std::string::npos);
    const CliResult two = run_cli_on_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    EXPECT_EQ(read_npy(dir / "two" / "uncertainty_height.npy"), reference);
    EXPECT_EQ(read_npy(dir / "two" / "estimate_height.npy"), read_npy(dir / "one" / "estimate_height.npy"));
}

}  // namespace
}  // namespace wavebrdf::test

#endif  // WAVEBRDF_HAS_MPI
