// BRDF tables (table.h): each entry is the light's slice bit for bit, the specular peak follows
// the light (ω_o = −ω_i), reciprocity of ROHS across entries, the file round trip, and hostile
// table files refused.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <gtest/gtest.h>

#include "cli_util.h"
#include "exr_util.h"
#include "test_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/table.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

namespace wavebrdf {
namespace {

using test::expect_throw_naming;
namespace fs = std::filesystem;

TableSpec small_spec(Model model = Model::OHS) {
    TableSpec spec;
    spec.query = test::make_query(model, 5.0, 7.0, 6.0);
    spec.lambdas_um = spectral_wavelengths_um(3);
    spec.spectral = true;
    spec.resolution = 16;
    spec.lights = {3, 4, 0.8};
    return spec;
}

std::size_t slice_values(const TableSpec& spec) {
    return std::size_t(spec.resolution) * std::size_t(spec.resolution) * 3;
}

const float* entry(const BrdfTable& t, int a, int b) {
    return t.values.data() + (std::size_t(a) * std::size_t(t.spec.lights.cols) + std::size_t(b)) * slice_values(t.spec);
}

bool same_bits(const float* a, const float* b, std::size_t count) { return std::memcmp(a, b, count * 4) == 0; }

TEST(Table, LightGridIsTheSliceConventionScaledByMaxSin) {
    std::vector<double> x, y;
    std::vector<unsigned char> rendered;
    light_grid_axes({4, 2, 0.5}, x, y, rendered);
    EXPECT_EQ(x, (std::vector<double>{-0.375, -0.125, 0.125, 0.375}));
    EXPECT_EQ(y, (std::vector<double>{-0.25, 0.25}));
    // Every light of this grid lies within max_sin except none; a 4x4 grid loses its corners.
    EXPECT_EQ(std::count(rendered.begin(), rendered.end(), 1), 8);
    light_grid_axes({4, 4, 0.5}, x, y, rendered);
    EXPECT_EQ(std::count(rendered.begin(), rendered.end(), 1), 12);
    EXPECT_EQ(rendered[0], 0);   // (−0.375, −0.375): |ω_i| = 0.53 > 0.5
    EXPECT_EQ(rendered[1], 1);   // (−0.375, −0.125)
    EXPECT_EQ(rendered[15], 0);  // (0.375, 0.375)
}

TEST(Table, EachEntryIsTheLightsSliceBitForBit) {
    const Heightfield hf = test::random_heightfield(48, 40, 0.3, 11);
    for (bool use_double : {false, true}) {
        TableSpec spec = small_spec();
        spec.double_precision = use_double;
        const BrdfTable t = render_brdf_table(hf, spec);
        ASSERT_EQ(t.values.size(), 3u * 4u * slice_values(spec));
        EXPECT_EQ(t.version, std::string(k_version));
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 4; ++b) {
                const bool inside = t.rendered[std::size_t(a) * 4 + std::size_t(b)] != 0;
                Query q = spec.query;
                q.omega_i = {light_grid_omega(a, 3, 0.8), light_grid_omega(b, 4, 0.8)};
                std::vector<float> alone;
                if (use_double) {
                    const std::vector<double> d = render_rgb<double>(hf, q, spec.lambdas_um, spec.resolution);
                    alone.assign(d.begin(), d.end());
                } else {
                    alone = render_rgb<float>(hf, q, spec.lambdas_um, spec.resolution);
                }
                if (inside) {
                    EXPECT_TRUE(same_bits(entry(t, a, b), alone.data(), alone.size()))
                        << "light " << a << "," << b << " double " << use_double;
                } else {
                    const float* e = entry(t, a, b);
                    EXPECT_TRUE(std::all_of(e, e + alone.size(), [](float v) { return v == 0.0f; }));
                }
            }
    }
}

// A flat mirror reflects each light into one lobe at ω_o = −ω_i (docs/conventions.md): the
// brightest pixel of every rendered entry lies within 1.5 pixel half-widths of −ω_i (the
// nearest pixel, or its neighbour where cos θ_o in OHS's f_r tilts the lobe).
TEST(Table, SpecularPeakOfAFlatMirrorMovesWithTheLight) {
    const Heightfield flat(64, 64, std::vector<double>(64 * 64, 0.0));
    TableSpec spec;
    // σ_p = 2 µm: a lobe of about λ/(2πσ_p) = 0.04 in ω_o, wider than a pixel (2/n = 0.05 apart),
    // so the brightest pixel is the one at the lobe (a much narrower lobe would fall between
    // pixels, below the window cut's sidelobes).
    spec.query = test::make_query(Model::OHS, 10.0, 20.0, 2.0);
    spec.lambdas_um = {0.5};
    spec.resolution = 40;
    spec.lights = {5, 6, 0.7};
    const BrdfTable t = render_brdf_table(flat, spec);
    const int n = spec.resolution;
    int checked = 0;
    for (int a = 0; a < 5; ++a)
        for (int b = 0; b < 6; ++b) {
            if (!t.rendered[std::size_t(a) * 6 + std::size_t(b)]) continue;
            const float* e = entry(t, a, b);
            int best = 0;
            for (int k = 1; k < n * n; ++k)
                if (e[3 * k] > e[3 * best]) best = k;
            const double ox = slice_omega(best / n, n), oy = slice_omega(best % n, n);
            EXPECT_NEAR(ox, -t.light_x[std::size_t(a)], 1.5 / n) << "light " << a << "," << b;
            EXPECT_NEAR(oy, -t.light_y[std::size_t(b)], 1.5 / n) << "light " << a << "," << b;
            ++checked;
        }
    EXPECT_GT(checked, 20);
}

// ROHS is reciprocal: f_r(ω_i, ω_o) = f_r(ω_o, ω_i). With 4 lights per axis at max_sin 0.5 and
// n = 8, light a sits exactly on slice pixel a + 2, so two entries of the table hold each pair.
TEST(Table, RohsEntriesAreReciprocal) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.2, 5);
    TableSpec spec;
    spec.query = test::make_query(Model::ROHS, 3.0, 4.0, 5.0);
    spec.lambdas_um = {0.6};
    spec.resolution = 8;
    spec.lights = {4, 4, 0.5};
    spec.double_precision = true;
    const BrdfTable t = render_brdf_table(hf, spec);
    const auto value = [&](int a, int b, int p, int q) {
        return double(entry(t, a, b)[(std::size_t(p) * 8 + std::size_t(q)) * 3]);
    };
    double peak = 0.0;
    for (float v : t.values) peak = std::max(peak, double(v));
    int pairs = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
            for (int a2 = 0; a2 < 4; ++a2)
                for (int b2 = 0; b2 < 4; ++b2) {
                    if (!t.rendered[std::size_t(a) * 4 + std::size_t(b)] ||
                        !t.rendered[std::size_t(a2) * 4 + std::size_t(b2)])
                        continue;
                    ASSERT_EQ(slice_omega(a2 + 2, 8), t.light_x[std::size_t(a2)]);
                    const double forward = value(a, b, a2 + 2, b2 + 2), backward = value(a2, b2, a + 2, b + 2);
                    EXPECT_NEAR(forward, backward, 1e-6 * peak + 1e-5 * std::abs(forward));
                    ++pairs;
                }
    EXPECT_EQ(pairs, 144);
    EXPECT_GT(peak, 0.0);
}

TEST(Table, ValidatesItsSpec) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    TableSpec spec = small_spec();
    spec.lights.max_sin = 1.0;
    expect_throw_naming<std::domain_error>([&] { render_brdf_table(hf, spec); }, "max sin theta 1 is out of range");
    spec = small_spec();
    spec.lights.rows = 0;
    expect_throw_naming<std::domain_error>([&] { render_brdf_table(hf, spec); }, "light grid 0x4");
    spec = small_spec();
    spec.resolution = 64;
    spec.lights.cols = 257;  // 257 · 64 > 16384
    expect_throw_naming<std::domain_error>([&] { render_brdf_table(hf, spec); }, "16384 pixels per side");
    spec = small_spec();
    spec.lambdas_um.clear();
    expect_throw_naming<std::invalid_argument>([&] { render_brdf_table(hf, spec); }, "no wavelengths");
}

TEST(Table, RefusesATableBeyondTheMemoryLimitBeforeRendering) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    TableSpec spec = small_spec();
    spec.resolution = 512;
    spec.lights = {32, 32, 0.9};  // 32² · 512² · 3 floats, twice: 6.4 GB
    RenderOptions options;
    options.max_memory_gb = 1.0;
    EXPECT_GT(estimate_table_bytes(hf, spec, options), 6.4e9);
    expect_throw_naming<OutOfMemory>([&] { render_brdf_table(hf, spec, options); }, "table (32x32 lights");
}

TEST(Table, FileRoundTripsWithAllAxes) {
    const fs::path dir = test::fresh_dir("table");
    const Heightfield hf = test::random_heightfield(48, 40, 0.3, 11, 0.5, 2.0);
    TableSpec spec = small_spec(Model::GHS);
    spec.query.x_um = 0.1;  // not exact in binary: the attribute must round-trip it exactly
    const BrdfTable t = render_brdf_table(hf, spec);
    const std::string path = (dir / "t.exr").string();
    write_brdf_table(path, t);
    const BrdfTable r = read_brdf_table(path);
    EXPECT_EQ(r.values, t.values);
    EXPECT_EQ(r.light_x, t.light_x);
    EXPECT_EQ(r.light_y, t.light_y);
    EXPECT_EQ(r.rendered, t.rendered);
    EXPECT_EQ(r.spec.lambdas_um, spec.lambdas_um);
    EXPECT_TRUE(r.spec.spectral);
    EXPECT_EQ(r.spec.query.model, Model::GHS);
    EXPECT_EQ(r.spec.query.x_um, 0.1);
    EXPECT_EQ(r.spec.query.y_um, 7.0);
    EXPECT_EQ(r.spec.query.sigma_p_um, 6.0);
    EXPECT_EQ(r.spec.resolution, 16);
    EXPECT_EQ(r.spec.lights.rows, 3);
    EXPECT_EQ(r.spec.lights.cols, 4);
    EXPECT_EQ(r.spec.lights.max_sin, 0.8);
    EXPECT_FALSE(r.spec.double_precision);
    EXPECT_EQ(r.heightfield_rows, 48);
    EXPECT_EQ(r.heightfield_cols, 40);
    EXPECT_EQ(r.texel_um, 0.5);
    EXPECT_EQ(r.vscale, 2.0);
    EXPECT_EQ(r.version, std::string(k_version));
    // The file is the mosaic any EXR viewer shows: tile (a, b) at rows a·n…, columns b·n….
    const RgbImage image = read_rgb_exr(path);
    ASSERT_EQ(image.rows, 3 * 16);
    ASSERT_EQ(image.cols, 4 * 16);
    const std::size_t p = 5, q = 9, a = 2, b = 1, c = 1;
    EXPECT_EQ(image.data[((a * 16 + p) * std::size_t(image.cols) + b * 16 + q) * 3 + c],
              entry(t, int(a), int(b))[(p * 16 + q) * 3 + c]);
}

// Copies table file `from` to `to` with its header changed by `edit`, and its pixels resized
// to rows × cols (zeros).
void rewrite(const std::string& from, const std::string& to, const std::function<void(Imf::Header&)>& edit,
             int rows = -1, int cols = -1) {
    Imf::Header header;
    {
        Imf::InputFile in(from.c_str());
        header = in.header();
    }
    edit(header);
    const Imath::Box2i dw = header.dataWindow();
    if (rows < 0) rows = dw.max.y - dw.min.y + 1;
    if (cols < 0) cols = dw.max.x - dw.min.x + 1;
    header.dataWindow() = header.displayWindow() = Imath::Box2i({0, 0}, {cols - 1, rows - 1});
    std::vector<float> pixels(std::size_t(rows) * std::size_t(cols) * 3, 0.0f);
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < 3; ++c)
        frame.insert(std::string(1, "RGB"[c]),
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(pixels.data() + c), 12, 12 * std::size_t(cols)));
    Imf::OutputFile out(to.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

TEST(Table, RefusesHostileTableFiles) {
    const fs::path dir = test::fresh_dir("table");
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    TableSpec spec = small_spec();
    spec.resolution = 4;
    const std::string good = (dir / "good.exr").string(), bad = (dir / "bad.exr").string();
    write_brdf_table(good, render_brdf_table(hf, spec));
    ASSERT_NO_THROW(read_brdf_table(good));
    const auto refused = [&](const std::function<void(Imf::Header&)>& edit, const std::string& text, int rows = -1,
                             int cols = -1) {
        rewrite(good, bad, edit, rows, cols);
        expect_throw_naming<std::runtime_error>([&] { read_brdf_table(bad); }, text);
    };
    // A tile count that disagrees with the mosaic: both sizes named.
    refused([](Imf::Header& h) { h.insert("wavebrdf:light_rows", Imf::IntAttribute(4)); },
            "mosaic is 12x16 pixels but the attributes declare 4x4 lights of 4x4 (16x16)");
    refused([](Imf::Header&) {}, "mosaic is 13x16 pixels", 13, 16);
    // Missing and mistyped attributes.
    refused([](Imf::Header& h) { h = wavebrdf::test::header_without(h, "wavebrdf:resolution"); },
            "has no int attribute wavebrdf:resolution");
    refused([](Imf::Header& h) { h.insert("wavebrdf:kind", Imf::StringAttribute("something else")); },
            "wavebrdf:kind is 'something else'");
    refused(
        [](Imf::Header& h) {
            h = wavebrdf::test::header_without(h, "wavebrdf:sigma_p_um");
            h.insert("wavebrdf:sigma_p_um", Imf::IntAttribute(3));
        },
        "has no double attribute wavebrdf:sigma_p_um");
    // Huge declared sizes are refused by their range, before anything is sized from them.
    refused([](Imf::Header& h) { h.insert("wavebrdf:resolution", Imf::IntAttribute(1 << 30)); },
            "wavebrdf:resolution = 1073741824 is out of range");
    refused([](Imf::Header& h) { h.insert("wavebrdf:light_cols", Imf::IntAttribute(16384)); },
            "attributes describe an invalid table: light grid 3x16384");
    // Values out of their ranges, malformed lists, axes that disagree with the grid.
    refused([](Imf::Header& h) { h.insert("wavebrdf:light_max_sin", Imf::DoubleAttribute(1.5)); },
            "max sin theta 1.5 is out of range");
    refused([](Imf::Header& h) { h.insert("wavebrdf:lambdas_um", Imf::StringAttribute("0.5,abc")); },
            "wavebrdf:lambdas_um has 'abc'");
    refused([](Imf::Header& h) { h.insert("wavebrdf:lambdas_um", Imf::StringAttribute("")); },
            "wavebrdf:lambdas_um has ''");
    refused([](Imf::Header& h) { h.insert("wavebrdf:light_x", Imf::StringAttribute("0,0,0")); },
            "disagree with the grid");
    refused([](Imf::Header& h) { h.insert("wavebrdf:light_x", Imf::StringAttribute("0,0,0,0,0,0")); },
            "lists more than 3 numbers");
    refused([](Imf::Header& h) { h.insert("wavebrdf:model", Imf::StringAttribute("Phong")); }, "Phong");
    // A plain RGB image is not a table.
    RgbImage plain;
    plain.rows = plain.cols = 4;
    plain.data.assign(48, 1.0f);
    write_rgb_exr(bad, plain);
    expect_throw_naming<std::runtime_error>([&] { read_brdf_table(bad); }, "has no string attribute wavebrdf:kind");
}

// Every convention attribute is required (docs/table.md says so), the surface it was rendered
// from is bounded (texel, vscale, size, footprint), and a table is not a heightfield.
TEST(Table, RequiresEveryConventionAndBoundsItsSurface) {
    const fs::path dir = test::fresh_dir("table");
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1, 2.0);
    TableSpec spec = small_spec();
    spec.resolution = 4;
    spec.query.sigma_p_um = 3.0;
    const std::string good = (dir / "good.exr").string(), bad = (dir / "bad.exr").string();
    write_brdf_table(good, render_brdf_table(hf, spec));
    ASSERT_NO_THROW(read_brdf_table(good));
    const auto refused = [&](const std::function<void(Imf::Header&)>& edit, const std::string& text) {
        rewrite(good, bad, edit);
        expect_throw_naming<std::runtime_error>([&] { read_brdf_table(bad); }, text);
    };
    for (const char* name : {"wavebrdf:unit", "wavebrdf:layout", "wavebrdf:omega_o", "wavebrdf:light_grid"}) {
        SCOPED_TRACE(name);
        refused([&](Imf::Header& h) { h = wavebrdf::test::header_without(h, name); },
                std::string("has no string attribute ") + name);
        refused([&](Imf::Header& h) { h.insert(name, Imf::StringAttribute("something else")); },
                std::string("attribute ") + name + " differs from this build's convention");
    }
    for (const auto& bad_texel : {std::pair<double, const char*>{0.0, "0"}, {-1.0, "-1"}, {20000.0, "20000"}}) {
        const double texel = bad_texel.first;  // C++17 lambdas cannot capture a structured binding
        refused([&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(texel)); },
                std::string("wavebrdf:texel_um = ") + bad_texel.second + " is out of range");
    }
    refused([](Imf::Header& h) { h.insert("wavebrdf:vscale", Imf::DoubleAttribute(20000.0)); },
            "wavebrdf:vscale = 20000 is out of range");
    refused([](Imf::Header& h) { h.insert("wavebrdf:heightfield_rows", Imf::IntAttribute(2147483647)); },
            "wavebrdf:heightfield_rows = 2147483647 is out of range");
    // sigma_p 500 um on a 32 um tile (16 texels of 2 um).
    refused([](Imf::Header& h) { h.insert("wavebrdf:sigma_p_um", Imf::DoubleAttribute(500.0)); },
            "wavebrdf:sigma_p_um = 500 um is more than 10 periods");
    // The table's R channel is f_r: the heightfield reader refuses it.
    expect_throw_naming<std::runtime_error>([&] { read_heightfield_exr(good); },
                                            "is a 'wavebrdf brdf table' file (attribute wavebrdf:kind), not a "
                                            "heightfield");
}

// The CLI: `wavebrdf table` entries equal `wavebrdf render` with that light, bit for bit.
TEST(TableCli, EntryEqualsRenderOfThatLight) {
    const fs::path dir = test::fresh_dir("table_cli");
    ASSERT_EQ(test::run_cli(dir, "heightfield --size 48 --out h.exr --no-png --quiet").exit_code, 0);
    const std::string common =
        "--heightfield h.exr --texel-um 0.5 --x-um 3 --sigma-p-um 4 --spectral 3 "
        "--resolution 12 --quiet";
    const test::CliResult r = test::run_cli(
        dir, "table " + common + " --lights 3x5 --max-light-sin 0.85 --out t.exr --png t.png");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "t.png"));
    const BrdfTable t = read_brdf_table((dir / "t.exr").string());
    EXPECT_EQ(t.texel_um, 0.5);
    for (const auto& [a, b] : std::vector<std::pair<int, int>>{{0, 2}, {1, 0}, {2, 3}}) {
        ASSERT_TRUE(t.rendered[std::size_t(a) * 5 + std::size_t(b)]);
        const test::CliResult s = test::run_cli(dir, "render " + common + " --light-x " +
                                                         format_shortest(t.light_x[std::size_t(a)]) + " --light-y " +
                                                         format_shortest(t.light_y[std::size_t(b)]) + " --out s.exr");
        ASSERT_EQ(s.exit_code, 0) << s.err;
        const RgbImage slice = read_rgb_exr((dir / "s.exr").string());
        EXPECT_TRUE(same_bits(entry(t, a, b), slice.data.data(), slice.data.size())) << "light " << a << "," << b;
    }
}

TEST(TableCli, UsesTheHeightfieldFilesTexelSizeUnlessGiven) {
    const fs::path dir = test::fresh_dir("table_cli_texel");
    ASSERT_EQ(test::run_cli(dir, "heightfield --size 32 --texel-um 0.5 --out h.exr --no-png --quiet").exit_code, 0);
    const std::string common = "table --heightfield h.exr --sigma-p-um 3 --resolution 8 --lights 2x2 --quiet";
    const test::CliResult from_file = test::run_cli(dir, common + " --out a.exr");
    ASSERT_EQ(from_file.exit_code, 0) << from_file.err;
    EXPECT_EQ(from_file.err, "");
    EXPECT_EQ(read_brdf_table((dir / "a.exr").string()).texel_um, 0.5);
    const test::CliResult given = test::run_cli(dir, common + " --texel-um 1 --out b.exr");
    ASSERT_EQ(given.exit_code, 0) << given.err;
    EXPECT_EQ(read_brdf_table((dir / "b.exr").string()).texel_um, 1.0);
    EXPECT_NE(given.err.find("--texel-um 1 disagrees with"), std::string::npos) << given.err;
}

TEST(TableCli, ErrorsAreOneLine) {
    const fs::path dir = test::fresh_dir("table_cli");
    ASSERT_EQ(test::run_cli(dir, "heightfield --size 16 --out h.exr --no-png --quiet").exit_code, 0);
    test::expect_one_line_naming(test::run_cli(dir, "table --heightfield h.exr --lights 3y4 --out t.exr"),
                                 {"--lights", "3y4"});
    test::expect_one_line_naming(test::run_cli(dir, "table --heightfield h.exr --max-light-sin 1 --out t.exr"),
                                 {"max sin theta 1"});
    test::expect_one_line_naming(
        test::run_cli(dir, "table --heightfield h.exr --lights 300x2 --resolution 64 --out t.exr"),
        {"light grid 300x2", "16384"});
    test::expect_one_line_naming(
        test::run_cli(dir, "table --heightfield h.exr --resolution 512 --max-memory-gb 0.01 --out t.exr"),
        {"table (32x32 lights", "max-memory-gb"});
    test::expect_one_line_naming(test::run_cli(dir, "table --heightfield h.exr --out h.exr"), {"--out"});
    EXPECT_FALSE(fs::exists(dir / "t.exr"));
    EXPECT_TRUE(test::temporaries_under(dir).empty());
}

}  // namespace
}  // namespace wavebrdf
