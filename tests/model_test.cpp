// model.h: the models' names, and the slice pixels inside the unit disk (disk_row), against the plain loop over all
// pixels that the renderers, their adjoints and the planner used to write each.
#include "wavebrdf/model.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

namespace wavebrdf {
namespace {

// Every model's name parses back to it, in any case, and only those names parse.
TEST(ModelNames, EveryModelRoundTripsThroughItsName) {
    for (Model m : {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff})
        EXPECT_EQ(parse_model(to_string(m)), m) << to_string(m);
    EXPECT_STREQ(to_string(Model::Kirchhoff), "Kirchhoff");
    EXPECT_EQ(parse_model("ohs"), Model::OHS);
    EXPECT_EQ(parse_model("rGhS"), Model::RGHS);
    EXPECT_EQ(parse_model("KIRCHHOFF"), Model::Kirchhoff);
    for (const char* bad : {"", "oh", "Wave", "OHS ", "Kirchof"})
        EXPECT_THROW(parse_model(bad), std::invalid_argument) << bad;
}

TEST(DiskRow, VisitsExactlyThePixelsInsideTheDiskInColumnOrder) {
    for (int n : {1, 2, 3, 7, 16, 33, 128}) {
        int total = 0;
        for (int p = 0; p < n; ++p) {
            std::vector<DiskPixel> expected;
            const double ox = slice_omega(p, n);
            for (int q = 0; q < n; ++q) {
                const double oy = slice_omega(q, n);
                if (ox * ox + oy * oy > 1.0) continue;
                expected.push_back({q, ox, oy});
            }
            std::vector<DiskPixel> visited;
            for (const auto [q, px, py] : disk_row(p, n)) visited.push_back({q, px, py});
            ASSERT_EQ(visited.size(), expected.size()) << "n " << n << " row " << p;
            for (std::size_t i = 0; i < visited.size(); ++i) {
                EXPECT_EQ(visited[i].q, expected[i].q) << "n " << n << " row " << p;
                EXPECT_EQ(visited[i].ox, expected[i].ox);
                EXPECT_EQ(visited[i].oy, expected[i].oy);
            }
            total += int(visited.size());
        }
        // The disk covers π/4 of the square: every pixel for n ≤ 2, about 79% for large n.
        if (n <= 2) {
            EXPECT_EQ(total, n * n);
        }
        if (n >= 33) {
            EXPECT_GT(total, int(0.75 * n * n));
            EXPECT_LT(total, int(0.82 * n * n));
        }
    }
}

TEST(DiskRow, CornerRowsOfALargeSliceSkipTheirOutsideColumns) {
    // Row 0 of a 64 x 64 slice: |ω_o,x| = 63/64, so only columns with |ω_o,y| ≤ ~0.175 remain.
    int count = 0, first = -1;
    for (const auto [q, ox, oy] : disk_row(0, 64)) {
        if (first < 0) first = q;
        EXPECT_LE(ox * ox + oy * oy, 1.0);
        ++count;
    }
    EXPECT_GT(first, 20);
    EXPECT_LT(count, 14);
    EXPECT_GT(count, 0);
}

}  // namespace
}  // namespace wavebrdf
