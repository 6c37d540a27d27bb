// ExactVector::allreduce across MPI ranks (core/exact_sum.h, Communicator::allreduce_words192):
// the probe (mpi_exact_sum_probe.cpp) under `mpiexec -n 3`. Compiled only with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

TEST(MpiExactSum, RanksGetTheExactTotalEvenWhereTwoRanksTogetherLeaveTheRangeAndRefuseARealOverflowAlike) {
    const fs::path dir = fresh_dir("mpi_exact_sum");
    const CliResult r = spawn_in(dir,
                                 // --timeout: before the 192-bit sums, rank 0 refused the partial sum alone and the
                                 // others waited for its broadcast for ever.
                                 {WAVEBRDF_MPIEXEC, "-q", "--timeout", "120", "-n", "3", "--oversubscribe", "--bind-to",
                                  "none", WAVEBRDF_EXACT_SUM_PROBE},
                                 mpi_environment(1));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.out);
    ASSERT_EQ(lines.size(), 3u) << r.out;
    std::vector<bool> seen(3, false);
    for (const std::string& line : lines) {
        int rank = -1;
        double small = 0.0, big = 0.0;
        char refused[16] = {};
        ASSERT_EQ(std::sscanf(line.c_str(), "rank %d %lf %lf %15s", &rank, &small, &big, refused), 4)
            << "the BIG sum was refused (two ranks' partial sum left the 128-bit range): " << line;
        ASSERT_TRUE(rank >= 0 && rank < 3) << line;
        seen[std::size_t(rank)] = true;
        EXPECT_EQ(small, 6.0 / 1024.0) << line;               // (1 + 2 + 3) · 2^-10, exactly
        EXPECT_EQ(big, 0.75 * 0x1p55) << line;                // (+1 + 1 − 1) · 0.75 · 2^32 · 2^23, exactly
        EXPECT_EQ(std::string(refused), "overflow") << line;  // 3 · 0.75 · 2^127 does not fit
    }
    EXPECT_EQ(seen, std::vector<bool>(3, true));
}

}  // namespace
}  // namespace wavebrdf::test

#endif
