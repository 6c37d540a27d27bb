// The spatially varying design (design_plate.h): the plate is the palette's tiles laid out as the
// picture, and each region of the exported plate, taken alone, shows its palette colour under a
// direct Kirchhoff integral over that region (finite size, continuous directions: not the
// periodic orders the tiles were designed with).
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <map>
#include <nlohmann/json.hpp>

#include "cli_util.h"
#include "design_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {
namespace {

using namespace wavebrdf::test;
using C = std::complex<double>;

PlateOptions small_test_plate() {
    PlateOptions o = test::small_plate(32, 8, 16, 40, 10);
    o.design.height_range_um = 2.0;
    o.picture = picture(2, 2, {{{0, 255, 0}}, {{255, 0, 255}}, {{255, 0, 255}}, {{0, 255, 0}}});
    o.plate_pixel_um = 64.0;  // 4 periods of 16 um
    return o;
}

// The light reflected into the cone |ω_o − centre| ≤ cone (normal light) by the R × R block of texels at
// (r0, c0) of the plate alone, per wavelength, as a fraction of the light incident on the block:
// the Kirchhoff far field of the block,
//   A(ω) = w² sinc(w f_x) sinc(w f_y) Σ_t e^{−i k h_t (1 + cos θ_o)} e^{−2πi f·x_t},  f = ω/λ,
// integrated by the midpoint rule on a grid of spacing `step` over the cone:
//   ∫ |A|² cos θ_o / (λ² S) d²ω  (S = (R w)²; Parseval: a flat block puts all of it near ω = 0).
// The sum over texels is grouped by the block's distinct heights and separated along rows and
// columns (exact algebra, no FFT, no periodicity).
std::vector<double> block_cone_flux(const std::vector<double>& h, int cols, int r0, int c0, int R, double w,
                                    const std::vector<double>& lambdas, double cone, double step,
                                    std::array<double, 2> centre = {0.0, 0.0}) {
    std::map<double, int> level_of;
    for (int i = 0; i < R; ++i)
        for (int j = 0; j < R; ++j) level_of.emplace(h[static_cast<std::size_t>((r0 + i) * cols + c0 + j)], 0);
    std::vector<double> heights;
    for (auto& [value, index] : level_of) {
        index = static_cast<int>(heights.size());
        heights.push_back(value);
    }
    const int K = static_cast<int>(heights.size());
    const int G = static_cast<int>(std::ceil(2.0 * cone / step));
    std::vector<double> grid(static_cast<std::size_t>(G)), gridx(grid.size()), gridy(grid.size());
    for (int g = 0; g < G; ++g) {
        grid[static_cast<std::size_t>(g)] = -cone + (g + 0.5) * (2.0 * cone / G);
        gridx[static_cast<std::size_t>(g)] = centre[0] + grid[static_cast<std::size_t>(g)];
        gridy[static_cast<std::size_t>(g)] = centre[1] + grid[static_cast<std::size_t>(g)];
    }
    const double cell = (2.0 * cone / G) * (2.0 * cone / G);
    auto sinc = [](double x) { return x == 0.0 ? 1.0 : std::sin(k_pi * x) / (k_pi * x); };
    std::vector<double> out;
    for (double lambda : lambdas) {
        const double k = 2.0 * k_pi / lambda;
        // T[ℓ][i][gy] = Σ_j [level(i, j) = ℓ] e^{−2πi f_y y_j}
        std::vector<C> T(static_cast<std::size_t>(K) * R * G, C(0.0, 0.0));
        for (int i = 0; i < R; ++i)
            for (int j = 0; j < R; ++j) {
                const int l = level_of[h[static_cast<std::size_t>((r0 + i) * cols + c0 + j)]];
                for (int gy = 0; gy < G; ++gy)
                    T[(static_cast<std::size_t>(l) * R + i) * G + gy] +=
                        std::polar(1.0, -2.0 * k_pi * gridy[static_cast<std::size_t>(gy)] / lambda * (j + 0.5) * w);
            }
        double flux = 0.0;
#pragma omp parallel for reduction(+ : flux) schedule(static)
        for (int gx = 0; gx < G; ++gx) {
            const double wx = gridx[static_cast<std::size_t>(gx)];
            std::vector<C> ex(static_cast<std::size_t>(R));
            for (int i = 0; i < R; ++i) ex[static_cast<std::size_t>(i)] = std::polar(1.0, -2.0 * k_pi * wx / lambda * (i + 0.5) * w);
            for (int gy = 0; gy < G; ++gy) {
                const double wy = gridy[static_cast<std::size_t>(gy)];
                const double gxo = grid[static_cast<std::size_t>(gx)], gyo = grid[static_cast<std::size_t>(gy)];
                if (gxo * gxo + gyo * gyo > cone * cone) continue;
                const double cos_o = std::sqrt(1.0 - wx * wx - wy * wy);
                C a(0.0, 0.0);
                for (int l = 0; l < K; ++l) {
                    C m(0.0, 0.0);
                    for (int i = 0; i < R; ++i) m += ex[static_cast<std::size_t>(i)] * T[(static_cast<std::size_t>(l) * R + i) * G + gy];
                    a += std::polar(1.0, -k * heights[static_cast<std::size_t>(l)] * (1.0 + cos_o)) * m;
                }
                a *= w * w * sinc(w * wx / lambda) * sinc(w * wy / lambda);
                flux += std::norm(a) * cos_o * cell;
            }
        }
        const double S = (R * w) * (R * w);
        out.push_back(flux / (lambda * lambda * S));
    }
    return out;
}

TEST(DesignPlate, EachRegionShowsItsPaletteColourUnderADirectIntegralOverTheRegion) {
    const fs::path dir = fresh_dir("design_plate");
    const PlateOptions o = small_test_plate();
    const PreparedPlate p = prepare_plate(o);
    EXPECT_EQ(p.pixel_texels, 128);
    EXPECT_EQ(p.rows, 256);
    EXPECT_EQ(p.assignment, (std::vector<int>{0, 1, 1, 0}));
    const PlateResult r = run_plate(p);
    write_plate_directory((dir / "run").string(), r, false);
    for (const char* name : {"design.json", "heights.exr", "heights.png", "masks.json", "plate.png", "plate.exr"})
        EXPECT_TRUE(fs::is_regular_file(dir / "run" / name)) << name;
    const nlohmann::json j = nlohmann::json::parse(read_text(dir / "run" / "design.json"));
    const std::vector<double> lambdas = j["light"]["lambdas_um"].get<std::vector<double>>();
    // The exported relief, read back.
    const Heightfield hf = read_heightfield_exr((dir / "run" / "heights.exr").string());
    ASSERT_EQ(hf.rows(), 256);
    const std::vector<double> h = heights_um(hf);
    // The region's cone flux per unit incident power, as the plate's colours count it.
    std::vector<std::array<double, 2>> target_uv;
    for (const auto& e : o.palette) target_uv.push_back(xyz_to_uv(linear_srgb_to_xyz(e.linear_rgb)));
    for (int pr = 0; pr < 2; ++pr)
        for (int pc = 0; pc < 2; ++pc) {
            const int entry = p.assignment[static_cast<std::size_t>(pr * 2 + pc)];
            std::vector<double> flux = block_cone_flux(h, 256, pr * 128, pc * 128, 128, 0.5, lambdas, 0.1, 0.0015);
            const auto uv = xyz_to_uv(reflectance_xyz(lambdas, flux));
            const auto& view = j["entries"][static_cast<std::size_t>(entry)]["views"][0];
            const double design_delta = view["delta_uv"].get<double>();
            const double own = std::hypot(uv[0] - target_uv[static_cast<std::size_t>(entry)][0], uv[1] - target_uv[static_cast<std::size_t>(entry)][1]);
            const double other = std::hypot(uv[0] - target_uv[static_cast<std::size_t>(1 - entry)][0], uv[1] - target_uv[static_cast<std::size_t>(1 - entry)][1]);
            const auto tile_uv = view["uv"].get<std::vector<double>>();
            // The region alone spreads each order by about λ / 64 µm, against a cone of 0.1.
            EXPECT_LT(std::hypot(uv[0] - tile_uv[0], uv[1] - tile_uv[1]), 0.01);
            EXPECT_LT(own, design_delta + 0.01);
            EXPECT_GT(other, 0.1);
        }
}

TEST(DesignPlate, EachDirectionRegionSendsItsHighlightToItsOwnDirection) {
    // Two highlight directions on a 1 x 2 picture (dark: the first, light: the second); each
    // region of the exported plate, integrated alone over both view cones, puts far more of the
    // light into its own entry's cone than into the other's, as its tile's exact orders say.
    const fs::path dir = fresh_dir("design_plate");
    PlateOptions o = small_test_plate();
    o.palette = parse_palette("dir:0.2,0;dir:0,-0.2");
    o.picture = picture(1, 2, {{{0, 0, 0}}, {{255, 255, 255}}});
    const PreparedPlate p = prepare_plate(o);
    ASSERT_EQ(p.assignment, (std::vector<int>{0, 1}));
    const PlateResult r = run_plate(p);
    write_plate_directory((dir / "run").string(), r, false);
    const nlohmann::json j = nlohmann::json::parse(read_text(dir / "run" / "design.json"));
    const std::vector<double> lambdas = j["light"]["lambdas_um"].get<std::vector<double>>();
    const std::vector<double> h = heights_um(read_heightfield_exr((dir / "run" / "heights.exr").string()));
    ASSERT_EQ(h.size(), 128u * 256u);
    for (int e = 0; e < 2; ++e) {
        const auto& views = j["entries"][static_cast<std::size_t>(e)]["views"];
        // The cone flux per unit incident power, as the plate counts it.
        double into[2];
        for (int v = 0; v < 2; ++v) {
            const std::array<double, 2> centre = o.palette[static_cast<std::size_t>(v)].omega;
            std::vector<double> flux = block_cone_flux(h, 256, 0, e * 128, 128, 0.5, lambdas, 0.1, 0.0015, centre);
            into[v] = reflectance_xyz(lambdas, flux)[1];
            // The tile's exact Y into that cone against the region's, which its finite size spreads.
            EXPECT_NEAR(into[v], views[static_cast<std::size_t>(v)]["luminous_efficiency"].get<double>(), 0.05) << e << v;
        }
        EXPECT_GT(into[e], 0.3) << e;
        EXPECT_GT(into[e], 5.0 * into[1 - e]) << e;
    }
}

// Writes an 8-bit sRGB picture as PNG (through the linear writer: decode, then its encode).
void write_picture(const fs::path& path, const PlatePicture& p) {
    RgbImage im;
    im.rows = p.rows;
    im.cols = p.cols;
    for (std::uint8_t v : p.srgb8) im.data.push_back(static_cast<float>(srgb_decode(v / 255.0)));
    write_rgb_png(path.string(), im);
}

TEST(DesignPlate, ThePlateIsTheEntriesTilesLaidOutAsThePicture) {
    PlateOptions o = small_test_plate();
    o.design.size = 8;
    o.design.iterations = 0;
    o.design.refine_passes = 0;
    o.plate_pixel_um = 8.0;  // two periods of 4 um: 16 texels a pixel
    // Colours map to the nearest entry in CIELUV: dark and bluish greens to green, pinks and
    // purples to magenta.
    o.picture = picture(2, 3, {{{0, 100, 0}}, {{255, 150, 255}}, {{20, 255, 60}}, {{200, 0, 200}}, {{0, 255, 0}}, {{120, 0, 90}}});
    const PreparedPlate p = prepare_plate(o);
    ASSERT_EQ(p.assignment, (std::vector<int>{0, 1, 0, 1, 0, 1}));
    EXPECT_EQ(p.pixels_per_entry, (std::vector<long long>{3, 3}));
    const PlateResult r = run_plate(p);
    ASSERT_EQ(r.rows, 32);
    ASSERT_EQ(r.cols, 48);
    for (int I = 0; I < r.rows; ++I)
        for (int J = 0; J < r.cols; ++J) {
            const int e = p.assignment[static_cast<std::size_t>((I / 16) * 3 + J / 16)];
            ASSERT_EQ(r.heights_um[static_cast<std::size_t>(I * r.cols + J)],
                      r.tiles[static_cast<std::size_t>(e)].heights_um[static_cast<std::size_t>((I % 8) * 8 + J % 8)])
                << I << "," << J;
        }
    // The two tiles differ (two designs), and the levels are shared.
    EXPECT_NE(r.tiles[0].heights_um, r.tiles[1].heights_um);
    EXPECT_EQ(r.tiles[0].levels_um, r.tiles[1].levels_um);
    ASSERT_EQ(r.appearance.size(), 1u);

    // Directions map by luminance, darkest to the first entry; one panel per direction.
    o.palette = parse_palette("dir:0.2,0 dir:-0.2,0");
    o.picture = picture(1, 4, {{{0, 0, 0}}, {{128, 128, 128}}, {{200, 200, 200}}, {{255, 255, 255}}});
    const PreparedPlate q = prepare_plate(o);
    EXPECT_EQ(q.assignment, (std::vector<int>{0, 0, 1, 1}));
    const PlateResult rq = run_plate(q);
    EXPECT_EQ(rq.appearance.size(), 2u);
}

TEST(DesignPlate, AnEntrysWarningsReachThePlatesDesignJsonNamingTheEntry) {
    // A grayscale blue (1 µm features, 16² texels) ends dim after the brightness trade; magenta
    // reaches Y 5 %.
    PlateOptions o = test::small_plate(16, 8, 0, 80, 20);
    o.design.min_feature_um = 1.0;
    o.design.view_cone = 0.05;
    o.design.height_range_um = 2.0;
    o.design.seed = 5;
    o.palette = parse_palette("#0000FF;#FF00FF");
    o.picture = picture(2, 2, {{{0, 0, 255}}, {{255, 0, 255}}, {{255, 0, 255}}, {{0, 0, 255}}});
    const PlateResult r = run_plate(prepare_plate(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_EQ(j["entries"].size(), 2u);
    std::vector<std::string> expected;
    for (std::size_t e = 0; e < 2; ++e) {
        const auto tile = nlohmann::json::parse(r.tiles[e].metrics_json);
        const auto& entry = j["entries"][e];
        EXPECT_EQ(entry["warnings"], tile["warnings"]) << e;
        EXPECT_EQ(entry["brightness_trade"], tile["brightness_trade"]) << e;
        EXPECT_EQ(entry["optimal_colour_bound"], tile["optimal_colour_bound"]) << e;
        for (const auto& w : tile["warnings"])
            expected.push_back("palette entry " + o.palette[e].text + ": " + w.get<std::string>());
        // A warned entry is the dim one by the plate's own scoring (its tile's exact orders into
        // the view cone, computed apart from the trade's warning).
        const double y = entry["views"][0]["luminous_efficiency"].get<double>();
        if (tile["warnings"].empty()) {
            EXPECT_GE(y, 0.05) << o.palette[e].text;
        } else {
            EXPECT_LT(y, 0.05) << o.palette[e].text;
        }
    }
    ASSERT_FALSE(expected.empty()) << "the test needs a dim entry: " << j["entries"].dump();
    EXPECT_EQ(j["warnings"].get<std::vector<std::string>>(), expected);
}

TEST(DesignPlate, BadInputIsRefusedBeforeAnyWork) {
    EXPECT_THROW(parse_palette("#FF0000"), std::invalid_argument);
    EXPECT_THROW(parse_palette("#FF0000;dir:0.1,0"), std::invalid_argument);
    EXPECT_THROW(parse_palette("#GG0000,#00FF00"), std::invalid_argument);
    EXPECT_THROW(parse_palette("dir:0.9,0.9;dir:0,0"), std::invalid_argument);
    EXPECT_THROW(parse_palette("#000000;#FFFFFF"), std::invalid_argument);
    EXPECT_THROW(parse_palette("#FF0000;#ff0000"), std::invalid_argument);
    EXPECT_EQ(parse_palette("#FF0000,#00FF00 #0000FF").size(), 3u);
    try {
        parse_palette("#FF0000;#12345");
        FAIL();
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("#12345"), std::string::npos) << e.what();
    }
    PlateOptions o = small_test_plate();
    o.plate_pixel_um = 50.0;  // not a multiple of 16 um
    EXPECT_THROW(prepare_plate(o), std::domain_error);
    o = small_test_plate();
    o.picture = picture(200, 1, std::vector<std::array<int, 3>>(200, {{0, 255, 0}}));  // 200 x 128 texels a side
    EXPECT_THROW(prepare_plate(o), std::domain_error);
    o = small_test_plate();
    o.design.max_memory_gb = 1e-6;
    EXPECT_THROW(prepare_plate(o), OutOfMemory);
    o = small_test_plate();
    o.design.spectral = 0;
    EXPECT_THROW(prepare_plate(o), std::invalid_argument);
    o = small_test_plate();
    o.palette = parse_palette("dir:0.95,0;dir:0,0");  // the cone reaches outside the visible disk
    EXPECT_THROW(prepare_plate(o), std::domain_error);

    const fs::path dir = fresh_dir("design_plate");
    EXPECT_THROW(read_plate_picture((dir / "missing.png").string()), std::invalid_argument);
    write_picture(dir / "big.png", picture(10, 10, std::vector<std::array<int, 3>>(100, {{1, 2, 3}})));
    EXPECT_THROW(read_plate_picture((dir / "big.png").string(), 99), std::invalid_argument);
    const PlatePicture back = read_plate_picture((dir / "big.png").string(), 100);
    EXPECT_EQ(back.srgb8[0], 1);
    EXPECT_EQ(back.srgb8[2], 3);
}

TEST(DesignPlate, CliWritesThePlateAndRefusesBadInputWithOneLine) {
    const fs::path dir = fresh_dir("design_plate");
    write_picture(dir / "pic.png", picture(2, 2, {{{0, 255, 0}}, {{255, 0, 255}}, {{255, 0, 255}}, {{0, 255, 0}}}));
    const std::string base = "design --target image:pic.png --size 8 --spectral 3 --iterations 2 --refine-passes 1 --quiet ";
    const CliResult r = run_cli(dir, base + "--palette '#00FF00;#FF00FF' --plate-pixel-um 8 --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const char* name : {"design.json", "heights.exr", "heights.x3p", "heights.png", "heights.stl", "masks.json", "plate.png", "plate.exr"})
        EXPECT_TRUE(fs::is_regular_file(dir / "run" / name)) << name;
    const nlohmann::json j = nlohmann::json::parse(read_text(dir / "run" / "design.json"));
    EXPECT_EQ(j["target"]["kind"], "image");
    EXPECT_EQ(j["plate"]["rows"], 32);
    EXPECT_EQ(read_heightfield_exr((dir / "run" / "heights.exr").string()).cols(), 32);
    expect_one_line_naming(run_cli(dir, base + "--palette '#00FF00' --out a"), {"--palette"});
    expect_one_line_naming(run_cli(dir, base + "--palette '#00FF00;#XYZ' --out a"), {"#XYZ"});
    expect_one_line_naming(run_cli(dir, base + "--palette '#00FF00;#FF00FF' --plate-pixel-um 5 --out a"), {"--plate-pixel-um"});
    expect_one_line_naming(run_cli(dir, "design --target image:nope.png --palette '#00FF00;#FF00FF' --spectral 3 --out a"),
                           {"nope.png"});
    expect_one_line_naming(run_cli(dir, "design --target colour:#00FF00 --palette '#00FF00;#FF00FF' --spectral 3 --out a"),
                           {"--palette"});
    EXPECT_FALSE(fs::exists(dir / "a"));
}

}  // namespace
}  // namespace wavebrdf
