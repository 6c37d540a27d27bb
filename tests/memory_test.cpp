// memory.h: out-of-memory errors that name what was allocated, limits, and the estimates that
// render and recover check before any work (brdf.h, recovery_run.h), against measured peaks.
#include <gtest/gtest.h>

#include <cstdio>
#include <new>
#include <string>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {
namespace {

TEST(Memory, AllocatingNamesWhatFailed) {
    try {
        allocating("the 1024x1024 slice's factor matrices", 64.0 * (1 << 20), []() -> int { throw std::bad_alloc(); });
        FAIL() << "expected OutOfMemory";
    } catch (const OutOfMemory& e) {
        EXPECT_EQ(std::string(e.what()), "out of memory allocating the 1024x1024 slice's factor matrices (64 MiB)");
    }
}

TEST(Memory, RequireMemoryRefusesAboveTheLimitWithBothNumbers) {
    const MemoryLimit limit = memory_limit(23.4);
    EXPECT_NO_THROW(require_memory(23.3e9, limit, "recover"));
    try {
        require_memory(101e9, limit, "recover");
        FAIL() << "expected OutOfMemory";
    } catch (const OutOfMemory& e) {
        EXPECT_EQ(std::string(e.what()),
                  "recover needs about 101 GB; the limit is 23.4 GB (max-memory-gb); raise it with --max-memory-gb");
    }
    EXPECT_THROW(memory_limit(-1.0), std::invalid_argument);
    EXPECT_GT(memory_limit(0.0).bytes, 1e8) << "the default is the physical memory";
    EXPECT_EQ(memory_limit(0.0).source, "physical memory");
}

// A render refused before any work, with both numbers.
TEST(Memory, RenderRefusesWhatCannotFit) {
    const Heightfield hf = test::random_heightfield(64, 64, 0.4, 3);
    Query q;
    q.sigma_p_um = 10.0;
    RenderOptions o;
    o.max_memory_gb = 0.05;
    try {
        render_rgb<double>(hf, q, {0.5}, 4096, o);
        FAIL() << "expected OutOfMemory";
    } catch (const OutOfMemory& e) {
        EXPECT_NE(std::string(e.what()).find("render (4096x4096 slice, double) needs about "), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("the limit is 50 MB (max-memory-gb)"), std::string::npos) << e.what();
    }
    EXPECT_THROW(render_slice<float>(hf, q, 0.5, 4096, o), OutOfMemory);
    o.max_memory_gb = 0.0;  // the physical memory: fits
    EXPECT_EQ(render_slice<float>(hf, q, 0.5, 16, o).size(), 256u);
}

// The render estimate against the peak resident memory of the render in a child process:
// within a factor of two either way, for each path.
TEST(Memory, RenderEstimateIsWithinAFactorOfTwoOfTheMeasuredPeak) {
#ifdef WAVEBRDF_ASAN
    GTEST_SKIP() << "AddressSanitizer's shadow memory and quarantine inflate the resident size; "
                    "the estimate is checked in the plain build";
#endif
    const Heightfield hf = test::random_heightfield(64, 64, 0.4, 3);
    for (Model model : {Model::OHS, Model::GHS}) {
        Query q;
        q.sigma_p_um = model == Model::OHS ? 10.0 : 1.0;
        q.model = model;
        const int n = model == Model::OHS ? 3072 : 1024;
        const double estimate = estimate_render_bytes(hf, q, n, RenderOptions{}, sizeof(double), true);
        const double measured = test::child_peak_memory_bytes(
            [&] { return render_rgb<double>(hf, q, {0.5}, n).size() == std::size_t(n) * n * 3; });
        ASSERT_GT(measured, 0.0) << "the render failed in the child";
        test::expect_estimate_within_factor_of_two(
            estimate, measured,
            "render " + std::string(to_string(model)) + " " + std::to_string(n) + "x" + std::to_string(n));
    }
}

// The CLI: recover --size 1000 (which used to grow until the machine ran out) and a render
// over --max-memory-gb are refused in one line naming the estimate and the limit.
TEST(Memory, CliRefusesRunsThatCannotFit) {
    const test::fs::path dir = test::fresh_dir("memory");
    // The default limit (physical memory) refuses it on any machine with less than ~260 GB.
    if (double(physical_memory_bytes()) < 200e9) {
        test::expect_one_line_naming(test::run_cli(dir, "recover --size 1000 --resolution 160 --out run --quiet"),
                                     {"recover (1000x1000 heights, 492075 observations of 160x160) needs about",
                                      "(physical memory); raise it with --max-memory-gb"});
        EXPECT_FALSE(test::fs::exists(dir / "run")) << "refused before writing anything";
    }
    test::expect_one_line_naming(test::run_cli(dir, "recover --size 1000 --max-memory-gb 3 --out run --quiet"),
                                 {"the limit is 3 GB (max-memory-gb)"});
    write_heightfield_exr((dir / "h.exr").string(), test::random_heightfield(32, 32, 0.4, 3));
    test::expect_one_line_naming(
        test::run_cli(dir, "render --heightfield h.exr --resolution 4096 --max-memory-gb 0.05 --out s.exr --quiet"),
        {"render (4096x4096 slice, float) needs about", "the limit is 50 MB (max-memory-gb)"});
    EXPECT_FALSE(test::fs::exists(dir / "s.exr"));
    test::expect_one_line_naming(test::run_cli(dir, "genbrdf -i h.exr -o g.exr -r 4096 --max-memory-gb 0.05 --quiet"),
                                 {"render (4096x4096 slice, float) needs about"});
    test::expect_one_line_naming(test::run_cli(dir, "render --heightfield h.exr --max-memory-gb -1 --out s.exr"),
                                 {"max-memory-gb", "-1"});
}

}  // namespace
}  // namespace wavebrdf
