// Slice previews people can read: ω axes with ticks, a zoom window in ω, table previews with
// grid lines and light labels, and `--negative keep|clip` for out-of-gamut spectral values.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli_util.h"
#include "png_util.h"
#include "test_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"
#include "wavebrdf/table.h"

namespace fs = std::filesystem;
using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

// The pixel rows (or columns) of an n-pixel axis whose centre ω = (i + ½)/n · 2 − 1 lies in
// [lo, hi], by testing every pixel.
std::vector<int> inside_indices(double lo, double hi, int n) {
    std::vector<int> kept;
    for (int i = 0; i < n; ++i) {
        const double centre = (i + 0.5) / n * 2.0 - 1.0;
        if (centre >= lo && centre <= hi) kept.push_back(i);
    }
    return kept;
}

std::vector<int> span(int first, int last) {
    std::vector<int> v;
    for (int i = first; i <= last; ++i) v.push_back(i);
    return v;
}

TEST(OmegaWindow, SelectsExactlyThePixelsWhoseCentreIsInside) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int n : {1, 2, 7, 32, 255, 256}) {
        for (int trial = 0; trial < 300; ++trial) {
            double a = u(rng), b = u(rng), c = u(rng), d = u(rng);
            if (trial % 3 == 0) {  // edges exactly on pixel centres: the closed window keeps them
                const int i = int(std::uniform_int_distribution<int>(0, n - 1)(rng));
                a = (i + 0.5) / n * 2.0 - 1.0;
                c = a;
            }
            OmegaWindow w{std::min(a, b), std::max(a, b), std::min(c, d), std::max(c, d)};
            if (!(w.x0 < w.x1) || !(w.y0 < w.y1)) continue;
            const std::vector<int> rows = inside_indices(w.x0, w.x1, n), cols = inside_indices(w.y0, w.y1, n);
            if (rows.empty() || cols.empty()) {
                EXPECT_THROW(window_pixels(w, n), std::invalid_argument);
                continue;
            }
            const PixelBox box = window_pixels(w, n);
            EXPECT_EQ(span(box.first_row, box.last_row), rows) << n << " " << w.x0 << " " << w.x1;
            EXPECT_EQ(span(box.first_col, box.last_col), cols) << n << " " << w.y0 << " " << w.y1;
        }
    }
}

TEST(OmegaWindow, ParsesFourBoundsAndNamesABadOne) {
    const OmegaWindow w = parse_omega_window(" -0.25, 0.5,-1 ,1", "--window");
    EXPECT_EQ(w.x0, -0.25);
    EXPECT_EQ(w.x1, 0.5);
    EXPECT_EQ(w.y0, -1.0);
    EXPECT_EQ(w.y1, 1.0);
    for (const char* bad : {"", "1,2,3", "0,0.1,0,0.1,0.2", "a,0.1,0,0.1", "nan,0.1,0,0.1", "0,,0,0.1"})
        expect_throw_naming<std::logic_error>([&] { parse_omega_window(bad, "--window"); }, "expected x0,x1,y0,y1");
    expect_throw_naming<std::logic_error>([&] { parse_omega_window("0,1.5,0,0.1", "--window"); },
                                          "x1 = 1.5 is outside [-1, 1]");
    expect_throw_naming<std::logic_error>([&] { parse_omega_window("0.2,0.1,0,0.1", "--window"); },
                                          "x0 0.2 is not below x1 0.1");
    expect_throw_naming<std::logic_error>([&] { parse_omega_window("0,0.1,0.3,0.3", "--window"); },
                                          "y0 0.3 is not below y1 0.3");
    // A window between two pixel centres.
    expect_throw_naming<std::logic_error>(
        [&] {
            window_pixels({0.01, 0.02, -1, 1}, 8);
        },
        "holds no pixel centre of the 8x8 slice");
}

// A slice with a distinct value per pixel (a ramp in both axes).
RgbImage ramp(int n) {
    RgbImage image;
    image.rows = image.cols = n;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            for (int c = 0; c < 3; ++c) image.data.push_back(float(1.0 + i * n + j + 0.25 * c));
    return image;
}

// The window's picture is the preview of exactly the pixels inside it (cut out here by
// testing every pixel), each scaled up to a k × k block, k = 256 / the longer side (≤ 16).
TEST(SlicePreview, WindowShowsThePixelsInsideItScaledUp) {
    const int n = 64;
    const RgbImage image = ramp(n);
    PreviewOptions o;
    o.has_window = true;
    o.window = {-0.3, 0.1, 0.2, 0.9};
    const Preview8 p = make_slice_preview(image, o);
    const std::vector<int> rows = inside_indices(-0.3, 0.1, n), cols = inside_indices(0.2, 0.9, n);
    RgbImage crop;
    crop.rows = int(rows.size());
    crop.cols = int(cols.size());
    for (int i : rows)
        for (int j : cols)
            for (int c = 0; c < 3; ++c) crop.data.push_back(image.data[(std::size_t(i) * n + std::size_t(j)) * 3 + c]);
    const Preview8 expected = make_slice_preview(crop, PreviewOptions{});
    const int k = std::clamp(256 / std::max(crop.rows, crop.cols), 1, 16);
    EXPECT_EQ(p.magnify, k);
    ASSERT_EQ(p.rows, crop.rows * k);
    ASSERT_EQ(p.cols, crop.cols * k);
    for (int i = 0; i < p.rows; ++i)
        for (int j = 0; j < p.cols; ++j)
            for (int c = 0; c < 3; ++c)
                ASSERT_EQ(p.rgb[(std::size_t(i) * std::size_t(p.cols) + std::size_t(j)) * 3 + c],
                          expected.rgb[(std::size_t(i / k) * std::size_t(crop.cols) + std::size_t(j / k)) * 3 + c])
                    << i << "," << j;
}

bool lit(const Preview8& p, int i, int j) {
    const std::uint8_t* px = &p.rgb[(std::size_t(i) * std::size_t(p.cols) + std::size_t(j)) * 3];
    return px[0] != 0 || px[1] != 0 || px[2] != 0;
}

// Axes: the picture sits inside a frame; the ticks left of it are at the rows of ω_x = −1, −0.5,
// 0, 0.5, 1 (a 1-2-5 step over [−1, 1]) and nowhere between; those below at ω_y's columns.
TEST(SlicePreview, AxesTickTheOmegaValuesAtTheirPixels) {
    const int n = 64;
    PreviewOptions o;
    o.axes = true;
    const Preview8 p = make_slice_preview(ramp(n), o);
    ASSERT_GT(p.image_top, 0);
    ASSERT_GT(p.image_left, 0);
    ASSERT_EQ(p.image_rows, n);
    ASSERT_EQ(p.image_cols, n);
    // The frame, one pixel outside the picture.
    for (int j = p.image_left - 1; j <= p.image_left + n; ++j) {
        EXPECT_TRUE(lit(p, p.image_top - 1, j));
        EXPECT_TRUE(lit(p, p.image_top + n, j));
    }
    const int tick_col = p.image_left - 2, tick_row = p.image_top + n + 1;
    std::vector<int> tick_rows, tick_cols;
    for (int i = p.image_top; i < p.image_top + n; ++i)
        if (lit(p, i, tick_col)) tick_rows.push_back(i - p.image_top);
    for (int j = p.image_left; j < p.image_left + n; ++j)
        if (lit(p, tick_row, j)) tick_cols.push_back(j - p.image_left);
    // ω = −1, −0.5, 0, 0.5, 1 at rows floor((ω + 1)/2 · n), the last one clamped to n − 1.
    EXPECT_EQ(tick_rows, (std::vector<int>{0, 16, 32, 48, 63}));
    EXPECT_EQ(tick_cols, (std::vector<int>{0, 16, 32, 48, 63}));

    // A window's axes tick its own range: ω_x in [0.1, 0.3] of a 256² slice by steps of 0.05.
    o.has_window = true;
    o.window = {0.1, 0.3, -0.5, 0.5};
    const Preview8 w = make_slice_preview(ramp(256), o);
    std::vector<int> window_rows;
    for (int i = w.image_top; i < w.image_top + w.image_rows; ++i)
        if (lit(w, i, w.image_left - 2)) window_rows.push_back((i - w.image_top) / w.magnify);
    // Rows 141…165 of the slice have their centres in [0.1, 0.3]; the picture spans their edges,
    // ω 0.1016 to 0.2969, so the ticks are 0.15, 0.2 and 0.25 (a step of 0.05), each at the
    // row its value falls in.
    const std::vector<int> rows = inside_indices(0.1, 0.3, 256);
    ASSERT_EQ(rows.front(), 141);
    ASSERT_EQ(rows.back(), 165);
    std::vector<int> expected;
    for (double v : {0.1, 0.15, 0.2, 0.25, 0.3}) {
        const double edge0 = double(rows.front()) / 256 * 2 - 1, edge1 = double(rows.back() + 1) / 256 * 2 - 1;
        if (v < edge0 - 1e-12 || v > edge1 + 1e-12) continue;
        expected.push_back(
            std::clamp(int(std::floor((v - edge0) / (edge1 - edge0) * double(rows.size()))), 0, int(rows.size()) - 1));
    }
    EXPECT_EQ(expected.size(), 3u);
    EXPECT_EQ(window_rows, expected);
}

// The table preview: grid lines between and around the tiles, each tile's pixels the
// Reinhard/sRGB mapping of its values at the exposure, labels above and left of the tiles.
TEST(TablePreview, GridLinesSeparateTheTilesAndLabelsNameTheLights) {
    const int n = 16, rows = 2, cols = 3;  // 16: every label ("-0.6" is 15 pixels wide) fits its tile
    RgbImage mosaic;
    mosaic.rows = rows * n;
    mosaic.cols = cols * n;
    const std::vector<double> values = uniform_vector(std::size_t(mosaic.rows * mosaic.cols * 3), 0.0, 4.0, 3);
    mosaic.data.assign(values.begin(), values.end());
    const double exposure = -1.0;
    const Preview8 p = make_table_preview(mosaic, n, {-0.5, 0.5}, {-0.6, 0.0, 0.6}, exposure);
    const int top = p.image_top - 1, left = p.image_left - 1;
    ASSERT_GT(top, 0);
    ASSERT_GT(left, 0);
    for (int a = 0; a <= rows; ++a)
        for (int j = left; j < p.cols; ++j) EXPECT_TRUE(lit(p, top + a * (n + 1), j)) << "row line " << a;
    for (int b = 0; b <= cols; ++b)
        for (int i = top; i < p.rows; ++i) EXPECT_TRUE(lit(p, i, left + b * (n + 1))) << "column line " << b;
    for (int i = 0; i < mosaic.rows; ++i)
        for (int j = 0; j < mosaic.cols; ++j)
            for (int c = 0; c < 3; ++c) {
                double x = values[(std::size_t(i) * std::size_t(mosaic.cols) + std::size_t(j)) * 3 + c];
                x = double(float(x)) * std::exp2(exposure);
                x = x / (1.0 + x);
                const double srgb = x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
                const int row = top + 1 + i + i / n, col = left + 1 + j + j / n;
                EXPECT_EQ(p.rgb[(std::size_t(row) * std::size_t(p.cols) + std::size_t(col)) * 3 + c],
                          std::lround(srgb * 255.0));
            }
    // Something is written above every column of tiles and left of every row.
    for (int b = 0; b < cols; ++b) {
        bool any = false;
        for (int i = 0; i < top; ++i)
            for (int j = left + 1 + b * (n + 1); j < left + 1 + b * (n + 1) + n; ++j) any = any || lit(p, i, j);
        EXPECT_TRUE(any) << "column " << b;
    }
    for (int a = 0; a < rows; ++a) {
        bool any = false;
        for (int i = top + 1 + a * (n + 1); i < top + 1 + a * (n + 1) + n; ++i)
            for (int j = 0; j < left; ++j) any = any || lit(p, i, j);
        EXPECT_TRUE(any) << "row " << a;
    }
    EXPECT_THROW(make_table_preview(mosaic, n, {0.0}, {-0.6, 0.0, 0.6}, 0.0), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// The command line

class PreviewCliTest : public ::testing::Test {
protected:
    void SetUp() override {
        m_dir = fresh_dir("preview_cli");
        ASSERT_EQ(run_cli(m_dir, "heightfield --size 64 --rms-height-um 0.15 --out h.exr --no-png --quiet").exit_code,
                  0);
    }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(m_dir);
    }
    fs::path path(const std::string& name) const { return m_dir / name; }
    CliResult render(const std::string& args) const {
        return run_cli(m_dir, "render --heightfield h.exr --resolution 32 --sigma-p-um 6 --quiet " + args);
    }
    fs::path m_dir;
};

TEST_F(PreviewCliTest, AxesAndBarByDefaultAndTheirOptions) {
    ASSERT_EQ(render("--out a.exr --png a.png").exit_code, 0);
    const DecodedPng png = read_png_rgb(path("a.png").string());
    PreviewOptions o;
    o.axes = o.colour_bar = true;
    o.unit = "1/sr";
    const Preview8 expected = make_slice_preview(read_rgb_exr(path("a.exr").string()), o);
    EXPECT_EQ(png.rows, expected.rows);
    EXPECT_EQ(png.cols, expected.cols);
    EXPECT_GT(png.cols, 32 + 20);
    ASSERT_EQ(render("--out b.exr --png b.png --no-axes --no-colour-bar").exit_code, 0);
    const DecodedPng plain = read_png_rgb(path("b.png").string());
    EXPECT_EQ(plain.rows, 32);
    EXPECT_EQ(plain.cols, 32);
    EXPECT_EQ(plain.rgb, make_slice_preview(read_rgb_exr(path("b.exr").string()), PreviewOptions{}).rgb);
    ASSERT_EQ(render("--out w.exr --png w.png --window -0.25,0.25,-0.25,0.25 --no-colour-bar").exit_code, 0);
    const DecodedPng window = read_png_rgb(path("w.png").string());
    PreviewOptions zoom;
    zoom.axes = zoom.has_window = true;
    zoom.window = {-0.25, 0.25, -0.25, 0.25};
    const Preview8 zoomed = make_slice_preview(read_rgb_exr(path("w.exr").string()), zoom);
    EXPECT_EQ(zoomed.image_rows, 8 * 16) << "the 8x8 pixels of the window, scaled up 16 times";
    EXPECT_EQ(window.rows, zoomed.rows);
    EXPECT_EQ(window.rgb, zoomed.rgb);
}

TEST_F(PreviewCliTest, BadWindowIsOneLineAndWritesNothing) {
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
        {"0,1", {"--window '0,1'", "expected x0,x1,y0,y1"}},
        {"0,0.5,0,2", {"--window", "y1 = 2", "[-1, 1]"}},
        {"0.5,0,0,0.5", {"--window", "x0 0.5 is not below x1 0"}},
        {"0.01,0.02,0,0.5", {"--window", "no pixel centre", "32x32"}},
    };
    for (const auto& [window, needles] : cases) {
        const CliResult r = render("--out o.exr --png o.png --window " + window);
        expect_one_line_naming(r, needles);
        EXPECT_FALSE(fs::exists(path("o.exr"))) << window;
        EXPECT_FALSE(fs::exists(path("o.png"))) << window;
    }
    expect_one_line_naming(render("--out o.exr --negative drop"), {"--negative 'drop'", "keep or clip"});
    EXPECT_FALSE(fs::exists(path("o.exr")));
}

// A spectral slice's linear sRGB has negative values (colours outside the sRGB gamut); keep
// writes them, clip writes max(value, 0) of the same slice.
TEST_F(PreviewCliTest, NegativeSrgbValuesAreKeptOrClipped) {
    ASSERT_EQ(render("--spectral 8 --out keep.exr").exit_code, 0);
    ASSERT_EQ(render("--spectral 8 --out clip.exr --negative clip").exit_code, 0);
    const RgbImage keep = read_rgb_exr(path("keep.exr").string()), clip = read_rgb_exr(path("clip.exr").string());
    ASSERT_EQ(keep.data.size(), clip.data.size());
    std::size_t negative = 0;
    for (std::size_t i = 0; i < keep.data.size(); ++i) {
        negative += keep.data[i] < 0.0f;
        EXPECT_EQ(clip.data[i], std::max(keep.data[i], 0.0f));
    }
    EXPECT_GT(negative, 0u);
}

TEST(TableCliPreview, HasGridLinesAroundEveryLight) {
    const fs::path dir = fresh_dir("table_preview_cli");
    ASSERT_EQ(run_cli(dir, "heightfield --size 48 --out h.exr --no-png --quiet").exit_code, 0);
    const CliResult r = run_cli(dir,
                                "table --heightfield h.exr --sigma-p-um 4 --lambda-um 0.5 --resolution 12 --lights "
                                "2x3 --max-light-sin 0.85 --out t.exr --png t.png --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const DecodedPng png = read_png_rgb((dir / "t.png").string());
    const BrdfTable t = read_brdf_table((dir / "t.exr").string());
    RgbImage mosaic;
    mosaic.rows = 2 * 12;
    mosaic.cols = 3 * 12;
    mosaic.data = table_mosaic(t);
    const Preview8 expected = make_table_preview(
        mosaic, 12, t.light_x, t.light_y, auto_exposure(std::vector<double>(mosaic.data.begin(), mosaic.data.end())));
    EXPECT_EQ(png.rows, expected.rows);
    EXPECT_EQ(png.cols, expected.cols);
    EXPECT_EQ(png.rgb, expected.rgb);
    fs::remove_all(dir);
}

}  // namespace
