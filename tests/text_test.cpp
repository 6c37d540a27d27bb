// text.h: format_shortest, the one number formatter of messages and option texts (library,
// CLI and bindings): typed values print as typed, every double reads back exactly.
#include "wavebrdf/text.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>

namespace wavebrdf {
namespace {

TEST(FormatShortest, TypedValuesPrintAsTyped) {
    EXPECT_EQ(format_shortest(0.01), "0.01");
    EXPECT_EQ(format_shortest(0.1), "0.1");
    EXPECT_EQ(format_shortest(1e4), "10000");
    EXPECT_EQ(format_shortest(1e300), "1e+300");
    EXPECT_EQ(format_shortest(-2.5), "-2.5");
    EXPECT_EQ(format_shortest(0.0), "0");
}

TEST(FormatShortest, EveryDoubleReadsBackExactly) {
    EXPECT_EQ(format_shortest(1.0 / 3.0), "0.3333333333333333");
    EXPECT_EQ(format_shortest(0.1 + 0.2), "0.30000000000000004");
    std::mt19937_64 rng(5);
    for (int i = 0; i < 2000; ++i) {
        double v;
        const std::uint64_t bits = rng();
        static_assert(sizeof v == sizeof bits, "64-bit double");
        std::memcpy(&v, &bits, sizeof v);
        if (!std::isfinite(v)) continue;
        EXPECT_EQ(std::strtod(format_shortest(v).c_str(), nullptr), v) << format_shortest(v);
    }
    EXPECT_EQ(std::strtod(format_shortest(std::numeric_limits<double>::denorm_min()).c_str(), nullptr),
              std::numeric_limits<double>::denorm_min());
}

TEST(FormatShortest, NonFiniteValuesAreNamed) {
    EXPECT_EQ(format_shortest(std::numeric_limits<double>::infinity()), "inf");
    EXPECT_EQ(format_shortest(-std::numeric_limits<double>::infinity()), "-inf");
    EXPECT_EQ(format_shortest(std::numeric_limits<double>::quiet_NaN()), "nan");
}

}  // namespace
}  // namespace wavebrdf
