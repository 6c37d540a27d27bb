#include "wavebrdf/fabrication.h"

#include <array>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <png.h>

#include "test_util.h"

namespace fs = std::filesystem;

namespace wavebrdf {
namespace {

// A scratch directory removed at the end of the test.
struct ScratchDir {
    fs::path path;
    ScratchDir() {
        path = fs::temp_directory_path() /
               ("wavebrdf_fabrication_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(path);
        fs::create_directories(path);
    }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

// A grey PNG read with libpng's full API, untransformed except 1-bit pixels unpacked to one byte
// each and 16-bit pixels assembled from their big-endian bytes.
struct GreyPng {
    int rows = 0, cols = 0, bit_depth = 0, colour_type = -1;
    std::vector<std::uint32_t> pixels;
    std::map<std::string, std::string> texts;
    png_uint_32 pixels_per_metre = 0;
};

GreyPng read_grey_png(const std::string& path) {
    FILE* file = std::fopen(path.c_str(), "rb");
    if (file == nullptr) throw std::runtime_error("cannot open " + path);
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png_create_info_struct(png);
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, nullptr);
        std::fclose(file);
        throw std::runtime_error("libpng cannot read " + path);
    }
    png_init_io(png, file);
    png_read_png(png, info, PNG_TRANSFORM_PACKING, nullptr);
    GreyPng out;
    out.rows = static_cast<int>(png_get_image_height(png, info));
    out.cols = static_cast<int>(png_get_image_width(png, info));
    // The bit depth stored in the file's IHDR (png_read_png reports it after unpacking).
    {
        std::ifstream raw(path, std::ios::binary);
        char head[25] = {0};
        raw.read(head, sizeof head);
        out.bit_depth = static_cast<unsigned char>(head[24]);
    }
    out.colour_type = png_get_color_type(png, info);
    png_bytepp rows = png_get_rows(png, info);
    for (int i = 0; i < out.rows; ++i)
        for (int j = 0; j < out.cols; ++j)
            out.pixels.push_back(out.bit_depth == 16 ? (std::uint32_t(rows[i][2 * j]) << 8) | rows[i][2 * j + 1]
                                                     : rows[i][j]);
    png_textp texts = nullptr;
    const int n = png_get_text(png, info, &texts, nullptr);
    for (int k = 0; k < n; ++k) out.texts[texts[k].key] = std::string(texts[k].text, texts[k].text_length);
    int unit = 0;
    png_uint_32 py = 0;
    png_get_pHYs(png, info, &out.pixels_per_metre, &py, &unit);
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(file);
    return out;
}

TEST(FabricationTest, HeightsPngHoldsTheHeightsAndTheirScale) {
    ScratchDir dir;
    const int rows = 37, cols = 53;
    const double range_um = 1.7;
    std::vector<double> heights = test::uniform_vector(rows * cols, 0.0, range_um, 11);
    heights[0] = 0.0;
    heights[1] = range_um;
    const std::string path = (dir.path / "heights.png").string();
    write_heights_png16(path, heights, rows, cols, range_um, 0.5);
    const GreyPng png = read_grey_png(path);
    EXPECT_EQ(png.rows, rows);
    EXPECT_EQ(png.cols, cols);
    EXPECT_EQ(png.bit_depth, 16);
    EXPECT_EQ(png.colour_type, PNG_COLOR_TYPE_GRAY);
    EXPECT_EQ(png.pixels_per_metre, 2000000u);  // 0.5 µm texels
    ASSERT_EQ(png.texts.count("wavebrdf:height_range_um"), 1u);
    const double stored_range = std::stod(png.texts.at("wavebrdf:height_range_um"));
    EXPECT_EQ(stored_range, range_um);
    EXPECT_EQ(std::stod(png.texts.at("wavebrdf:texel_um")), 0.5);
    EXPECT_NE(png.texts.at("wavebrdf:units").find("65535"), std::string::npos);
    EXPECT_EQ(png.pixels[0], 0u);
    EXPECT_EQ(png.pixels[1], 65535u);
    // Read back with the stated mapping: within half a grey level.
    for (int k = 0; k < rows * cols; ++k)
        ASSERT_LE(std::abs(png.pixels[k] / 65535.0 * stored_range - heights[k]), 0.5 * range_um / 65535.0 + 1e-12)
            << "texel " << k;
    EXPECT_FALSE(fs::exists(path + ".tmp"));
}

TEST(FabricationTest, HeightsPngRefusesBadInputWithoutWriting) {
    ScratchDir dir;
    const std::string path = (dir.path / "h.png").string();
    std::vector<double> heights(6, 0.5);
    heights[4] = 2.5;
    test::expect_throw_naming<std::invalid_argument>([&] { write_heights_png16(path, heights, 2, 3, 2.0, 0.5); },
                                                     "texel (1, 1)");
    heights[4] = std::nan("");
    test::expect_throw_naming<std::invalid_argument>([&] { write_heights_png16(path, heights, 2, 3, 2.0, 0.5); },
                                                     "finite");
    heights[4] = 0.5;
    test::expect_throw_naming<std::invalid_argument>([&] { write_heights_png16(path, heights, 3, 3, 2.0, 0.5); },
                                                     "6 values for 3 x 3");
    test::expect_throw_naming<std::invalid_argument>([&] { write_heights_png16(path, heights, 2, 3, 0.0, 0.5); },
                                                     "height_range_um 0");
    test::expect_throw_naming<std::invalid_argument>([&] { write_heights_png16(path, heights, 2, 3, 2.0, -1.0); },
                                                     "texel_um -1");
    test::expect_throw_naming<std::invalid_argument>(
        [&] { write_heights_png16(path, heights, 1 << 20, 1 << 20, 2.0, 0.5); }, "exceed");
    EXPECT_TRUE(fs::is_empty(dir.path));
}

// Re-composes the relief from the masks as a fab would (sum of the etch depths of the masks
// exposing each texel, taken from masks.json) and compares with the levels asked for.
TEST(FabricationTest, MasksRecomposeTheLevels) {
    for (int levels : {2, 4, 8, 16, 3, 5, 256}) {
        SCOPED_TRACE("levels " + std::to_string(levels));
        ScratchDir dir;
        const int rows = 19, cols = 23;  // 437 texels: every one of 256 levels can appear
        const double range_um = 2.0, step_um = range_um / (levels - 1);
        std::mt19937 rng(static_cast<unsigned>(levels));
        std::uniform_int_distribution<int> pick(0, levels - 1);
        std::vector<int> level(rows * cols);
        for (int k = 0; k < rows * cols; ++k) level[k] = k < levels ? k : pick(rng);
        const std::string prefix = (dir.path / "masks").string();
        const std::vector<LevelMask> masks = write_level_masks(prefix, level, rows, cols, levels, range_um, 0.5);

        const bool power_of_two = (levels & (levels - 1)) == 0;
        const int expected_masks = power_of_two ? static_cast<int>(std::lround(std::log2(levels))) : levels - 1;
        EXPECT_EQ(static_cast<int>(masks.size()), expected_masks);
        EXPECT_EQ(level_mask_count(levels), expected_masks);

        std::ifstream in(prefix + ".json");
        const nlohmann::json doc = nlohmann::json::parse(in);
        EXPECT_EQ(doc.at("levels").get<int>(), levels);
        ASSERT_EQ(static_cast<int>(doc.at("masks").size()), expected_masks);
        std::vector<double> etched_um(rows * cols, 0.0);
        std::vector<std::uint32_t> previous;
        for (const nlohmann::json& entry : doc.at("masks")) {
            const std::string file = (dir.path / entry.at("file").get<std::string>()).string();
            const double depth_um = entry.at("depth_um").get<double>();
            const GreyPng png = read_grey_png(file);
            ASSERT_EQ(png.bit_depth, 1);
            ASSERT_EQ(png.rows, rows);
            ASSERT_EQ(png.cols, cols);
            for (int k = 0; k < rows * cols; ++k) {
                ASSERT_LE(png.pixels[k], 1u);
                if (png.pixels[k] != 0) etched_um[k] += depth_um;
            }
            // Cumulative masks (K − 1 of them) each expose a subset of the one before.
            if (!power_of_two && !previous.empty()) {
                for (int k = 0; k < rows * cols; ++k) ASSERT_LE(png.pixels[k], previous[k]);
            }
            previous = png.pixels;
        }
        for (int k = 0; k < rows * cols; ++k) {
            const double height_um = range_um - etched_um[k];
            ASSERT_NEAR(height_um, level[k] * step_um, 1e-9) << "texel " << k;
        }
    }
}

TEST(FabricationTest, MasksRefuseBadLevels) {
    ScratchDir dir;
    const std::string prefix = (dir.path / "masks").string();
    std::vector<int> level = {0, 1, 2, 4};
    test::expect_throw_naming<std::invalid_argument>(
        [&] { write_level_masks(prefix, level, 2, 2, 4, 2.0, 0.5); }, "level 4 at texel (1, 1)");
    test::expect_throw_naming<std::invalid_argument>([&] { write_level_masks(prefix, level, 2, 2, 1, 2.0, 0.5); },
                                                     "levels 1");
    test::expect_throw_naming<std::invalid_argument>([&] { write_level_masks(prefix, level, 2, 2, 257, 2.0, 0.5); },
                                                     "levels 257");
    EXPECT_TRUE(fs::is_empty(dir.path));
}

// --- STL -------------------------------------------------------------------------------------

struct Triangle {
    std::array<float, 3> normal;
    std::array<std::array<float, 3>, 3> v;
};

std::vector<Triangle> read_binary_stl(const std::string& path, std::string* header = nullptr) {
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.size() < 84) throw std::runtime_error("short STL");
    std::uint32_t n = 0;
    for (int k = 0; k < 4; ++k) n |= std::uint32_t(static_cast<unsigned char>(bytes[80 + k])) << (8 * k);
    if (bytes.size() != 84 + 50ull * n) throw std::runtime_error("STL size does not match its count");
    if (header) *header = std::string(bytes.data(), 80);
    std::vector<Triangle> out(n);
    for (std::uint32_t t = 0; t < n; ++t) {
        float f[12];
        std::memcpy(f, bytes.data() + 84 + 50ull * t, sizeof f);  // little-endian host
        out[t].normal = {f[0], f[1], f[2]};
        for (int a = 0; a < 3; ++a) out[t].v[a] = {f[3 + 3 * a], f[4 + 3 * a], f[5 + 3 * a]};
    }
    return out;
}

using Point = std::tuple<float, float, float>;

// Edges by their end points: the number of triangles using each undirected edge, and the
// directed count a → b minus b → a (zero for every edge of a consistently wound closed surface).
struct EdgeCensus {
    std::map<std::pair<Point, Point>, int> uses;
    std::map<std::pair<Point, Point>, int> balance;
};

EdgeCensus census(const std::vector<Triangle>& triangles) {
    EdgeCensus c;
    for (const Triangle& t : triangles)
        for (int a = 0; a < 3; ++a) {
            const Point p{t.v[a][0], t.v[a][1], t.v[a][2]};
            const Point q{t.v[(a + 1) % 3][0], t.v[(a + 1) % 3][1], t.v[(a + 1) % 3][2]};
            const auto key = p < q ? std::make_pair(p, q) : std::make_pair(q, p);
            ++c.uses[key];
            c.balance[key] += p < q ? 1 : -1;
        }
    return c;
}

// Is the point inside the texel relief solid (strictly)?
bool inside(const std::vector<double>& h, int rows, int cols, double w, double z_base, double x, double y, double z) {
    if (x <= 0 || y <= 0 || x >= rows * w || y >= cols * w) return false;
    const int i = static_cast<int>(x / w), j = static_cast<int>(y / w);
    return z > z_base && z < h[static_cast<std::size_t>(i * cols + j)];
}

// Checks the solid: closed (every edge used an even number of times, directions balanced;
// exactly twice where `manifold`), outward normals (a step out of each triangle along its normal
// leaves the relief, a step in enters it; the stored normal agrees with the winding), and the
// volume by the divergence theorem.
void check_solid(const std::vector<double>& h, int rows, int cols, double w, double base_um, bool manifold) {
    ScratchDir dir;
    const std::string path = (dir.path / "relief.stl").string();
    write_stl(path, h, rows, cols, w, base_um);
    std::string header;
    const std::vector<Triangle> triangles = read_binary_stl(path, &header);
    EXPECT_NE(header.rfind("solid", 0), 0u) << "a binary STL header must not begin with 'solid'";
    EXPECT_EQ(static_cast<long long>(triangles.size()), stl_triangle_count(h, rows, cols, base_um));

    const EdgeCensus edges = census(triangles);
    int four = 0;
    for (const auto& [edge, uses] : edges.uses) {
        ASSERT_TRUE(uses == 2 || (!manifold && uses == 4)) << "an edge used " << uses << " times";
        ASSERT_EQ(edges.balance.at(edge), 0) << "an edge not traversed once each way";
        four += uses == 4;
    }
    if (!manifold) {
        EXPECT_GT(four, 0);
    }

    double lowest = 0.0;
    for (double v : h) lowest = std::min(lowest, v);
    const double z_base = lowest - base_um;
    double volume = 0.0;
    const double eps = 1e-3 * std::min(w, base_um);
    for (const Triangle& t : triangles) {
        std::array<std::array<double, 3>, 3> p{};
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) p[r][k] = double(t.v[r][k]);
        const auto& [a, b, c] = p;
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        ASSERT_GT(len, 0.0) << "a degenerate triangle";
        for (int k = 0; k < 3; ++k) ASSERT_NEAR(double(t.normal[k]), n[k] / len, 1e-6);
        // Divergence theorem: V = Σ a · (b × c) / 6 over the outward-wound triangles.
        volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                   a[2] * (b[0] * c[1] - b[1] * c[0])) /
                  6.0;
        double centroid[3];
        for (int k = 0; k < 3; ++k) centroid[k] = (a[k] + b[k] + c[k]) / 3.0;
        auto at = [&](double s) {
            return inside(h, rows, cols, w, z_base, centroid[0] + s * n[0] / len, centroid[1] + s * n[1] / len,
                          centroid[2] + s * n[2] / len);
        };
        ASSERT_FALSE(at(eps)) << "normal points into the solid";
        ASSERT_TRUE(at(-eps)) << "the solid is not behind the triangle";
    }
    double expected = 0.0;
    for (double v : h) expected += w * w * (v - z_base);
    EXPECT_NEAR(volume, expected, 1e-5 * expected);
}

TEST(FabricationTest, FlatReliefIsABoxWithTheCountedTriangles) {
    const int rows = 5, cols = 7;
    const std::vector<double> h(rows * cols, 0.75);
    // 2 per top texel, 1 per bottom fan segment, 2 per side wall segment (2 (rows + cols) each).
    EXPECT_EQ(stl_triangle_count(h, rows, cols, 1.0), 2 * rows * cols + 2 * (rows + cols) + 2 * 2 * (rows + cols));
    check_solid(h, rows, cols, 0.5, 1.0, true);
}

TEST(FabricationTest, RaisedTexelAddsFourWalls) {
    std::vector<double> h(9, 0.0);
    h[4] = 1.0;
    // 18 tops, 12 bottom, 24 side walls, 4 walls of 2 around the raised texel.
    EXPECT_EQ(stl_triangle_count(h, 3, 3, 0.5), 62);
    check_solid(h, 3, 3, 0.5, 0.5, true);
}

TEST(FabricationTest, StepsMeetingAtACornerSplitTheWalls) {
    // Three heights around the centre corner: the wall from 0 to 2 is split at 1 there.
    const std::vector<double> h = {0.0, 1.0, 2.0, 2.0};
    check_solid(h, 2, 2, 1.0, 0.25, true);
}

TEST(FabricationTest, SaddleEdgeIsSharedByFourTriangles) {
    const std::vector<double> h = {1.0, 0.0, 0.0, 1.0};
    check_solid(h, 2, 2, 1.0, 0.5, false);
}

TEST(FabricationTest, RandomMultiLevelReliefIsClosedWithOutwardNormals) {
    const int rows = 24, cols = 17;
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> pick(0, 7);
    std::vector<double> h(rows * cols);
    for (double& v : h) v = pick(rng) * (2.0 / 7.0);
    check_solid(h, rows, cols, 0.5, 2.0, false);
    // A ramp has no saddle: every edge is shared by exactly two triangles.
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) h[i * cols + j] = 0.1 * (i + 2 * j);
    check_solid(h, rows, cols, 0.5, 0.3, true);
}

TEST(FabricationTest, StlRefusesBadInput) {
    ScratchDir dir;
    const std::string path = (dir.path / "r.stl").string();
    std::vector<double> h(4, 0.0);
    test::expect_throw_naming<std::invalid_argument>([&] { write_stl(path, h, 2, 2, 0.5, 0.0); }, "base_um 0");
    h[3] = std::numeric_limits<double>::infinity();
    test::expect_throw_naming<std::invalid_argument>([&] { write_stl(path, h, 2, 2, 0.5, 1.0); }, "texel (1, 1)");
    EXPECT_TRUE(fs::is_empty(dir.path));
}

TEST(FabricationTest, ExportsWriteEveryFileAndCheckTheLevels) {
    ScratchDir dir;
    const int rows = 8, cols = 8, levels = 4;
    const double range_um = 1.5, step_um = range_um / 3;
    std::vector<double> h(rows * cols);
    for (int k = 0; k < rows * cols; ++k) h[k] = (k % levels) * step_um;
    const FabricationFiles files = write_fabrication_exports(dir.path.string(), h, rows, cols, 0.5, range_um, levels);
    EXPECT_TRUE(fs::exists(files.heights_png));
    EXPECT_TRUE(fs::exists(files.heights_stl));
    EXPECT_EQ(files.masks.size(), 2u);
    EXPECT_EQ(fs::path(files.masks_json).filename(), "masks.json");
    EXPECT_EQ(fs::path(files.masks[0].path).filename(), "masks_01.png");
    for (const auto& entry : fs::directory_iterator(dir.path))
        EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();

    ScratchDir grey;
    const FabricationFiles grey_files = write_fabrication_exports(grey.path.string(), h, rows, cols, 0.5, range_um, 0);
    EXPECT_TRUE(grey_files.masks.empty());
    EXPECT_FALSE(fs::exists(grey.path / "masks.json"));
    EXPECT_EQ(grey_files.stl_triangles, stl_triangle_count(h, rows, cols, range_um));
    EXPECT_EQ(fs::file_size(grey_files.heights_stl), 84u + 50u * std::uintmax_t(grey_files.stl_triangles));

    ScratchDir small;  // an STL over the size limit is skipped, and the note says so
    const FabricationFiles skipped =
        write_fabrication_exports(small.path.string(), h, rows, cols, 0.5, range_um, 0, 1000.0);
    EXPECT_EQ(skipped.heights_stl, "");
    EXPECT_NE(skipped.note.find("triangles"), std::string::npos);
    EXPECT_FALSE(fs::exists(small.path / "heights.stl"));
    EXPECT_TRUE(fs::exists(small.path / "heights.png"));

    h[9] += 0.1 * step_um;
    ScratchDir off;
    test::expect_throw_naming<std::invalid_argument>(
        [&] { write_fabrication_exports(off.path.string(), h, rows, cols, 0.5, range_um, levels); },
        "texel (1, 1)");
    EXPECT_TRUE(fs::is_empty(off.path));
}

}  // namespace
}  // namespace wavebrdf
