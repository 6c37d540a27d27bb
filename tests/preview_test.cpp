#include "wavebrdf/preview.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "png_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/threads.h"

namespace {

namespace fs = std::filesystem;
using wavebrdf::Preview8;
using wavebrdf::PreviewOptions;
using wavebrdf::PreviewScale;
using wavebrdf::RgbImage;

// A grey image (R = G = B = value) of one row.
RgbImage grey_row(const std::vector<float>& values) {
    RgbImage image{1, static_cast<int>(values.size()), {}};
    for (float v : values) image.data.insert(image.data.end(), {v, v, v});
    return image;
}

int at(const Preview8& p, int i, int j, int c) {
    return p.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(p.cols) + static_cast<std::size_t>(j)) * 3u +
                 static_cast<std::size_t>(c)];
}

fs::path scratch(const std::string& name) {
    const fs::path dir = fs::path(WAVEBRDF_TEST_TMP) / "preview" / std::to_string(::getpid());
    fs::create_directories(dir);
    return dir / name;
}

// The log scale: 1 + log10(v / peak) / decades, clamped; by hand for peak 100, 4 decades.
TEST(PreviewTest, LogLevelOfKnownValues) {
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(100.0, 100.0, 4.0), 1.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(10.0, 100.0, 4.0), 0.75);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(1.0, 100.0, 4.0), 0.5);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(0.01, 100.0, 4.0), 0.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(1e-9, 100.0, 4.0), 0.0);    // below the floor: clamped
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(1000.0, 100.0, 4.0), 1.0);  // above the peak: clamped
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(1.0, 100.0, 2.0), 0.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(0.0, 100.0, 4.0), 0.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(-1.0, 100.0, 4.0), 0.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(std::nan(""), 100.0, 4.0), 0.0);
    EXPECT_DOUBLE_EQ(wavebrdf::log_level(1.0, 0.0, 4.0), 0.0);
}

// A grey slice through the log preview: grey level round(255 · level), the peak white.
TEST(PreviewTest, LogPreviewGivesKnownGreyLevels) {
    PreviewOptions options;
    options.log_decades = 4.0;
    const Preview8 p = wavebrdf::make_slice_preview(
        grey_row({100.0f, 10.0f, 1.0f, 0.1f, 0.0f, std::numeric_limits<float>::infinity(), -5.0f}), options);
    ASSERT_EQ(p.rows, 1);
    ASSERT_EQ(p.cols, 7);
    const std::vector<int> expected = {255, 191, 128, 64, 0, 0, 0};  // 255·{1, .75, .5, .25, 0}, inf and <0 black
    for (int j = 0; j < 7; ++j)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(at(p, 0, j, c), expected[static_cast<std::size_t>(j)]) << j;
    EXPECT_EQ(p.bar_top, -1);
}

// Colour slices keep their hue: the largest channel carries the level of the luminance.
TEST(PreviewTest, LogPreviewKeepsHue) {
    RgbImage image{1, 2, {2.0f, 1.0f, 0.5f, 0.0f, 0.0f, 0.0f}};
    const Preview8 p = wavebrdf::make_slice_preview(image, PreviewOptions{});
    EXPECT_EQ(at(p, 0, 0, 0), 255);
    EXPECT_EQ(at(p, 0, 0, 1), 128);
    EXPECT_EQ(at(p, 0, 0, 2), 64);
    EXPECT_EQ(at(p, 0, 1, 0), 0);
}

// The published viridis table (matplotlib's _cm_listed.py, entries 0, 127, 128 and 255),
// typed here independently of src/io/viridis_table.inc.
TEST(PreviewTest, ViridisMatchesThePublishedTable) {
    const std::array<double, 3> first{0.267004, 0.004874, 0.329415}, e127{0.128729, 0.563265, 0.551229},
        e128{0.127568, 0.566949, 0.550556}, last{0.993248, 0.906157, 0.143936};
    for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_DOUBLE_EQ(wavebrdf::viridis(0.0)[c], first[c]);
        EXPECT_DOUBLE_EQ(wavebrdf::viridis(1.0)[c], last[c]);
        EXPECT_NEAR(wavebrdf::viridis(0.5)[c], 0.5 * (e127[c] + e128[c]), 1e-12);  // t = 127.5/255
        EXPECT_NEAR(wavebrdf::viridis(128.0 / 255.0)[c], e128[c], 1e-12);
        EXPECT_DOUBLE_EQ(wavebrdf::viridis(-3.0)[c], first[c]);
        EXPECT_DOUBLE_EQ(wavebrdf::viridis(7.0)[c], last[c]);
    }
}

// The level a viridis pixel shows: the t on a fine grid whose colour is nearest.
double viridis_level(int r, int g, int b) {
    double best = 0.0, best_distance = 1e9;
    for (int k = 0; k <= 2550; ++k) {
        const std::array<double, 3> c = wavebrdf::viridis(k / 2550.0);
        const double d = std::hypot(c[0] * 255 - r, c[1] * 255 - g, c[2] * 255 - b);
        if (d < best_distance) best_distance = d, best = k / 2550.0;
    }
    return best;
}

// The bar: every column of it runs through the map from the top (1) to the bottom (0),
// monotone; the picture beside it is the preview without a bar; labels are drawn.
TEST(PreviewTest, ColourBarIsMonotoneInTheMap) {
    RgbImage image{64, 48, std::vector<float>(64 * 48 * 3)};
    for (std::size_t k = 0; k < image.data.size(); ++k) image.data[k] = float(std::pow(10.0, double(k % 97) / 20.0));
    for (const bool false_colour : {false, true}) {
        SCOPED_TRACE(false_colour ? "viridis" : "grey");
        PreviewOptions options;
        options.false_colour = false_colour;
        const Preview8 plain = wavebrdf::make_slice_preview(image, options);
        options.colour_bar = true;
        options.unit = "1/sr";
        const Preview8 p = wavebrdf::make_slice_preview(image, options);
        ASSERT_GE(p.rows, 64);
        ASSERT_GT(p.cols, 48);
        ASSERT_GE(p.bar_left, 48);
        ASSERT_GT(p.bar_bottom - p.bar_top, 20);
        for (int i = 0; i < 64; ++i)
            for (int j = 0; j < 48; ++j)
                for (int c = 0; c < 3; ++c) ASSERT_EQ(at(p, i, j, c), at(plain, i, j, c));
        for (int j = p.bar_left; j <= p.bar_right; ++j) {
            double previous = 2.0;
            for (int i = p.bar_top; i <= p.bar_bottom; ++i) {
                const double t = false_colour ? viridis_level(at(p, i, j, 0), at(p, i, j, 1), at(p, i, j, 2))
                                              : at(p, i, j, 0) / 255.0;
                EXPECT_LE(t, previous + 1e-9) << "row " << i << " column " << j;
                previous = t;
            }
            EXPECT_NEAR(false_colour
                            ? viridis_level(at(p, p.bar_top, j, 0), at(p, p.bar_top, j, 1), at(p, p.bar_top, j, 2))
                            : at(p, p.bar_top, j, 0) / 255.0,
                        1.0, 1e-3);
            EXPECT_NEAR(previous, 0.0, 1e-3);
        }
        // Tick labels right of the bar: white pixels there.
        int white = 0;
        for (int i = 0; i < p.rows; ++i)
            for (int j = p.bar_right + 1; j < p.cols; ++j) white += at(p, i, j, 0) == 255;
        EXPECT_GT(white, 20);
    }
}

// The 3×5 font: "1" is the glyph .#. / ##. / .#. / .#. / ###, scaled.
TEST(PreviewTest, FontDrawsDigits) {
    Preview8 p{10, 8, std::vector<std::uint8_t>(10 * 8 * 3, 0)};
    wavebrdf::draw_text(p, 0, 0, "1", 2, 255);
    const char* rows[5] = {".#.", "##.", ".#.", ".#.", "###"};
    for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 6; ++j) EXPECT_EQ(at(p, i, j, 1), rows[i / 2][j / 2] == '#' ? 255 : 0) << i << "," << j;
    EXPECT_EQ(wavebrdf::text_width("1e-3", 1), 15);
    wavebrdf::draw_text(p, 8, 6, "888", 3, 255);  // mostly outside: clipped, no crash
}

// The linear preview is write_rgb_png's mapping, pixel for pixel (so --exposure and
// --reinhard keep their documented meaning).
TEST(PreviewTest, LinearPreviewIsWriteRgbPng) {
    RgbImage image{3, 4, {}};
    for (int k = 0; k < 36; ++k) image.data.push_back(float(std::pow(2.0, (k % 13) - 6.0) * (k % 5 == 0 ? -1 : 1)));
    for (const double exposure : {0.0, 1.5, -3.0})
        for (const bool reinhard : {false, true}) {
            const std::string path = scratch("linear.png").string();
            wavebrdf::write_rgb_png(path, image, exposure, reinhard);
            PreviewOptions options;
            options.scale = PreviewScale::Linear;
            options.exposure_stops = exposure;
            options.reinhard = reinhard;
            const Preview8 p = wavebrdf::make_slice_preview(image, options);
            const wavebrdf::test::DecodedPng png = wavebrdf::test::read_png_rgb(path);
            EXPECT_EQ(p.rgb, png.rgb) << exposure << " " << reinhard;
        }
}

// Written and decoded: the expected size and the same pixels.
TEST(PreviewTest, PngDecodesWithTheExpectedSize) {
    RgbImage image{20, 30, std::vector<float>(20 * 30 * 3, 0.5f)};
    image.data[0] = 50.0f;
    PreviewOptions options;
    options.colour_bar = true;
    options.false_colour = true;
    options.unit = "1/sr";
    const Preview8 p = wavebrdf::make_slice_preview(image, options);
    const std::string path = scratch("bar.png").string();
    wavebrdf::write_preview_png(path, p);
    const wavebrdf::test::DecodedPng png = wavebrdf::test::read_png_rgb(path);
    EXPECT_EQ(png.rows, p.rows);
    EXPECT_EQ(png.cols, p.cols);
    EXPECT_GT(png.cols, 30);
    EXPECT_EQ(png.rgb, p.rgb);
}

// Heights: min → 0, max → 1 as write_heightfield_png; a flat field mid grey.
TEST(PreviewTest, HeightfieldPreviewStretchesMinToMax) {
    const wavebrdf::Heightfield field(2, 3, {-1.0, 0.0, 1.0, 3.0, -1.0, 0.5}, 0.5, 2.0);
    Preview8 p = wavebrdf::make_heightfield_preview(field, false, false);
    ASSERT_EQ(p.rows, 2);
    ASSERT_EQ(p.cols, 3);
    const std::vector<int> grey = {0, 64, 128, 255, 0, 96};
    for (int k = 0; k < 6; ++k) EXPECT_EQ(at(p, k / 3, k % 3, 1), grey[static_cast<std::size_t>(k)]);
    p = wavebrdf::make_heightfield_preview(field, true, false);
    const std::array<double, 3> top = wavebrdf::viridis(1.0);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(at(p, 1, 0, c), std::lround(top[static_cast<std::size_t>(c)] * 255));
    p = wavebrdf::make_heightfield_preview(field, true, true);
    EXPECT_GT(p.cols, 3);
    EXPECT_GE(p.bar_top, 0);
    p = wavebrdf::make_heightfield_preview(wavebrdf::Heightfield(1, 2, {4.0, 4.0}), false, true);
    EXPECT_EQ(at(p, 0, 0, 0), 128);
}

TEST(PreviewTest, BadOptionsThrowNamingTheValue) {
    const RgbImage image = grey_row({1.0f});
    for (const double decades : {0.0, -1.0, 31.0, std::nan("")}) {
        PreviewOptions options;
        options.log_decades = decades;
        EXPECT_THROW(wavebrdf::make_slice_preview(image, options), std::domain_error) << decades;
    }
    PreviewOptions options;
    options.exposure_stops = std::numeric_limits<double>::infinity();
    try {
        wavebrdf::validate_preview_options(options);
        ADD_FAILURE() << "no exception";
    } catch (const std::domain_error& e) {
        EXPECT_NE(std::string(e.what()).find("exposure inf"), std::string::npos) << e.what();
    }
    EXPECT_THROW(wavebrdf::make_slice_preview(RgbImage{2, 2, std::vector<float>(5)}, PreviewOptions{}),
                 std::invalid_argument);
    EXPECT_THROW(wavebrdf::make_slice_preview(RgbImage{0, 2, {}}, PreviewOptions{}), std::invalid_argument);
}

TEST(ThreadsTest, SetThreadCountIsBounded) {
    const int before = wavebrdf::thread_count();
    EXPECT_THROW(wavebrdf::set_thread_count(0), std::domain_error);
    EXPECT_THROW(wavebrdf::set_thread_count(1025), std::domain_error);
    wavebrdf::set_thread_count(3);
    EXPECT_EQ(wavebrdf::thread_count(), 3);
    wavebrdf::set_thread_count(before);
    EXPECT_EQ(wavebrdf::thread_count(), before);
}

}  // namespace
