#include "wavebrdf/io.h"

#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfRgbaFile.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>
#include <gtest/gtest.h>
#include <png.h>

#include "wavebrdf/version.h"
#include "exr_util.h"

namespace fs = std::filesystem;
using wavebrdf::Heightfield;
using wavebrdf::RgbImage;

namespace {

// A fresh directory per test, so leftovers from one test cannot satisfy another's checks.
class IoTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        m_dir = fs::path(WAVEBRDF_TEST_TMP) / "io" / (std::string(info->name()) + "-" + std::to_string(::getpid()));
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override {
        std::error_code ignored;
        fs::remove_all(m_dir, ignored);
    }
    std::string file(const std::string& name) const { return (m_dir / name).string(); }
    std::vector<std::string> listing() const {
        std::vector<std::string> names;
        for (const auto& entry : fs::directory_iterator(m_dir)) names.push_back(entry.path().filename().string());
        return names;
    }

    fs::path m_dir;
};

// Values exactly representable in both half and float: small multiples of 1/8.
Heightfield make_field(int rows, int cols) {
    std::vector<double> values(static_cast<std::size_t>(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) values[static_cast<std::size_t>(i) * cols + j] = 0.125 * (i * 17 - j * 5) - 3.0;
    return Heightfield(rows, cols, values);
}

// Expects `call` to throw exactly `Exception` with the path somewhere in its message.
template <typename Exception, typename Call>
void expect_io_error_naming(Call call, const std::string& path) {
    try {
        call();
        ADD_FAILURE() << "no exception for " << path;
    } catch (const Exception& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find(path), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << "message is not one line: " << message;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
    }
}

struct Png {
    int rows = 0;
    int cols = 0;
    std::vector<std::uint8_t> pixels;
};

Png read_png(const std::string& path, bool rgb) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (png_image_begin_read_from_file(&image, path.c_str()) == 0)
        throw std::runtime_error("cannot read " + path + ": " + image.message);
    image.format = rgb ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
    Png png;
    png.rows = static_cast<int>(image.height);
    png.cols = static_cast<int>(image.width);
    png.pixels.resize(PNG_IMAGE_SIZE(image));
    if (png_image_finish_read(&image, nullptr, png.pixels.data(), 0, nullptr) == 0)
        throw std::runtime_error("cannot decode " + path + ": " + image.message);
    return png;
}

// Writes a single float channel `channel` with the given data window (x = column, y = row).
void write_exr_channel(const std::string& path, const char* channel, int rows, int cols, int x0, int y0,
                       const std::vector<float>& data) {
    Imf::Header header(Imath::Box2i({0, 0}, {x0 + cols + 2, y0 + rows + 2}),
                       Imath::Box2i({x0, y0}, {x0 + cols - 1, y0 + rows - 1}));
    header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    frame.insert(channel, Imf::Slice::Make(Imf::FLOAT, data.data(), header.dataWindow()));
    Imf::OutputFile out(path.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

TEST_F(IoTest, HeightfieldFloatExrRoundTripsNonSquare) {
    const Heightfield field = make_field(7, 13);
    const std::string path = file("field.exr");
    wavebrdf::write_heightfield_exr(path, field);
    const Heightfield back = wavebrdf::read_heightfield_exr(path, 2.5, 0.5);
    ASSERT_EQ(back.rows(), 7);
    ASSERT_EQ(back.cols(), 13);
    EXPECT_EQ(back.values(), field.values());
    EXPECT_EQ(back.texel_um(), 2.5);
    EXPECT_EQ(back.vscale(), 0.5);
    // Only the target remains: the temporary was renamed, not copied.
    EXPECT_EQ(listing(), std::vector<std::string>{"field.exr"});
}

// Issue 11: a heightfield written with any texel size reads back with that size (and its
// vertical scale), with no option given; the file says how it was made and by which version.
TEST_F(IoTest, HeightfieldAttributesRoundTripForSeveralTexelSizes) {
    const double texels[] = {0.37, 2.5, 0.5, 1e-4, 1e4, 1.0 / 3.0};
    const double vscales[] = {1.0, 0.0, -0.3, 1e-6, 1e4, 2.0 / 7.0};
    for (int k = 0; k < 6; ++k) {
        const std::string path = file("field" + std::to_string(k) + ".exr");
        const Heightfield field = make_field(5, 3).with_scale(texels[k], vscales[k]);
        wavebrdf::write_heightfield_exr(path, field, "made by test " + std::to_string(k));
        const Heightfield back = wavebrdf::read_heightfield_exr(path);
        EXPECT_EQ(back.texel_um(), texels[k]);
        EXPECT_EQ(back.vscale(), vscales[k]);
        EXPECT_EQ(back.values(), field.values());
        const wavebrdf::HeightfieldAttributes a = wavebrdf::read_heightfield_attributes(path);
        ASSERT_TRUE(a.texel_um && a.vscale);
        EXPECT_EQ(*a.texel_um, texels[k]);
        EXPECT_EQ(*a.vscale, vscales[k]);
        EXPECT_EQ(a.units, wavebrdf::k_heightfield_units);
        EXPECT_EQ(a.made_by, "made by test " + std::to_string(k));
        EXPECT_EQ(a.version, wavebrdf::k_version);
        // An explicit value still wins over the file's.
        EXPECT_EQ(wavebrdf::read_heightfield_exr(path, 0.25).texel_um(), 0.25);
        EXPECT_EQ(wavebrdf::read_heightfield_exr(path, 0.25).vscale(), vscales[k]);
        EXPECT_EQ(wavebrdf::read_heightfield_exr(path, std::nullopt, 3.0).texel_um(), texels[k]);
    }
}

// Files of genBrdf and of wavebrdf before 0.2 carry no attributes: the defaults (1, 1) apply,
// and the attributes say nothing (not "1").
TEST_F(IoTest, HeightfieldWithoutAttributesReadsWithDefaults) {
    const std::string path = file("plain.exr");
    write_exr_channel(path, "R", 4, 6, 0, 0, std::vector<float>(24, 0.5f));
    const wavebrdf::HeightfieldAttributes a = wavebrdf::read_heightfield_attributes(path);
    EXPECT_FALSE(a.texel_um.has_value());
    EXPECT_FALSE(a.vscale.has_value());
    EXPECT_EQ(a.units, "");
    EXPECT_EQ(a.made_by, "");
    EXPECT_EQ(a.version, "");
    const Heightfield h = wavebrdf::read_heightfield_exr(path);
    EXPECT_EQ(h.texel_um(), 1.0);
    EXPECT_EQ(h.vscale(), 1.0);
    EXPECT_EQ(wavebrdf::read_heightfield_exr(path, 0.37, 2.0).texel_um(), 0.37);
    // No file value: nothing to disagree with, no warning; the caller's default applies.
    const wavebrdf::HeightfieldScale s = wavebrdf::resolve_heightfield_scale(path, a, std::nullopt, 0.5, "--texel-um",
                                                                             "--vscale", 2.0, 1.0);
    EXPECT_EQ(s.texel_um, 2.0);
    EXPECT_EQ(s.vscale, 0.5);
    EXPECT_TRUE(s.warnings.empty());
}

// A given value that differs from the file's wins, with one warning line naming both.
TEST_F(IoTest, ResolveHeightfieldScaleWarnsNamingBothValues) {
    const std::string path = file("g.exr");
    wavebrdf::write_heightfield_exr(path, make_field(2, 2).with_scale(0.5, 1.0));
    const wavebrdf::HeightfieldAttributes a = wavebrdf::read_heightfield_attributes(path);
    const wavebrdf::HeightfieldScale agree = wavebrdf::resolve_heightfield_scale(path, a, 0.5, 1.0);
    EXPECT_EQ(agree.texel_um, 0.5);
    EXPECT_TRUE(agree.warnings.empty());
    const wavebrdf::HeightfieldScale none = wavebrdf::resolve_heightfield_scale(path, a, std::nullopt, std::nullopt);
    EXPECT_EQ(none.texel_um, 0.5);
    EXPECT_TRUE(none.warnings.empty());
    const wavebrdf::HeightfieldScale differ = wavebrdf::resolve_heightfield_scale(path, a, 1.0, 3.0);
    EXPECT_EQ(differ.texel_um, 1.0);
    EXPECT_EQ(differ.vscale, 3.0);
    ASSERT_EQ(differ.warnings.size(), 2u);
    EXPECT_EQ(differ.warnings[0], "--texel-um 1 disagrees with " + path + "'s texel_um 0.5; using 1");
    EXPECT_EQ(differ.warnings[1], "--vscale 3 disagrees with " + path + "'s vscale 1; using 3");
    // Out of range is an error naming the file, not a disagreement.
    expect_io_error_naming<std::domain_error>([&] { wavebrdf::resolve_heightfield_scale(path, a, 1e-300, 1.0); }, path);
    expect_io_error_naming<std::domain_error>([&] { wavebrdf::resolve_heightfield_scale(path, a, 0.5, 1e300); }, path);
}

// A hostile attribute (not finite, out of range, the wrong type, a huge string) is refused
// with an error naming the file and the attribute, by every reader of heightfields.
TEST_F(IoTest, HostileHeightfieldAttributesAreRefused) {
    const auto write_with = [&](const std::string& name, const std::function<void(Imf::Header&)>& add) {
        const std::string path = file(name);
        Imf::Header header(3, 2);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        add(header);
        std::vector<float> data(6, 0.0f);
        Imf::FrameBuffer frame;
        frame.insert("R",
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(data.data()), sizeof(float), 3 * sizeof(float)));
        Imf::OutputFile out(path.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(2);
        return path;
    };
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    struct Case {
        const char* attribute;
        std::function<void(Imf::Header&)> add;
    };
    const std::vector<Case> cases = {
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(nan)); }},
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(inf)); }},
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(-1.0)); }},
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(0.0)); }},
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::DoubleAttribute(1e300)); }},
        {"wavebrdf:texel_um", [&](Imf::Header& h) { h.insert("wavebrdf:texel_um", Imf::StringAttribute("0.5")); }},
        {"wavebrdf:vscale", [&](Imf::Header& h) { h.insert("wavebrdf:vscale", Imf::DoubleAttribute(nan)); }},
        {"wavebrdf:vscale", [&](Imf::Header& h) { h.insert("wavebrdf:vscale", Imf::DoubleAttribute(-1e9)); }},
        {"wavebrdf:vscale", [&](Imf::Header& h) { h.insert("wavebrdf:vscale", Imf::DoubleAttribute(1e-300)); }},
        {"wavebrdf:units",
         [&](Imf::Header& h) { h.insert("wavebrdf:units", Imf::StringAttribute(std::string(100000, 'x'))); }},
        {"wavebrdf:made_by", [&](Imf::Header& h) { h.insert("wavebrdf:made_by", Imf::DoubleAttribute(1.0)); }},
    };
    for (std::size_t k = 0; k < cases.size(); ++k) {
        const std::string path = write_with("hostile" + std::to_string(k) + ".exr", cases[k].add);
        for (const auto& read : {std::function<void()>([&] { wavebrdf::read_heightfield_exr(path); }),
                                 std::function<void()>([&] { wavebrdf::read_heightfield_attributes(path); }),
                                 std::function<void()>([&] { wavebrdf::read_heightfield_exr(path, 1.0, 1.0); })}) {
            expect_io_error_naming<std::runtime_error>(read, path);
            try {
                read();
            } catch (const std::runtime_error& e) {
                EXPECT_NE(std::string(e.what()).find(cases[k].attribute), std::string::npos) << e.what();
            }
        }
    }
}

// A corrupted attribute, as a fuzzer would make it: the file's texel_um bytes overwritten with
// those of NaN. Refused by name, not read as NaN (which the Heightfield would refuse less clearly).
TEST_F(IoTest, CorruptedTexelAttributeBytesAreRefused) {
    const std::string path = file("corrupt.exr");
    wavebrdf::write_heightfield_exr(path, make_field(3, 3).with_scale(0.37, 1.0));
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    double value = 0.37;
    const std::string needle(reinterpret_cast<const char*>(&value), sizeof value);  // little-endian, as EXR
    const std::size_t at = bytes.find(needle);
    ASSERT_NE(at, std::string::npos);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::memcpy(&bytes[at], &nan, sizeof nan);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
    try {
        wavebrdf::read_heightfield_exr(path);
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("wavebrdf:texel_um"), std::string::npos) << e.what();
    }
}

// Slices carry the query that rendered them, the heightfield, the unit and the version.
TEST_F(IoTest, SliceAttributesRoundTrip) {
    RgbImage image{4, 4, std::vector<float>(48, 0.25f)};
    wavebrdf::SliceAttributes a;
    a.query.x_um = -12.5;
    a.query.y_um = 3.0e6;
    a.query.sigma_p_um = 0.37;
    a.query.omega_i = {0.3, -0.2};
    a.query.model = wavebrdf::Model::RGHS;
    a.lambdas_um = {0.4, 0.55, 1.0 / 3.0};
    a.resolution = 4;
    a.channels = 3;
    a.heightfield_rows = 64;
    a.heightfield_cols = 32;
    a.texel_um = 0.37;
    a.vscale = -2.5;
    a.heightfield_file = "dir/g.exr";
    a.made_by = "test";
    for (bool alpha : {false, true}) {
        const std::string path = file(alpha ? "rgba.exr" : "rgb.exr");
        wavebrdf::write_slice_exr(path, image, a, alpha);
        const wavebrdf::SliceFile back = wavebrdf::read_slice_exr(path);
        EXPECT_EQ(back.image.data, image.data);
        ASSERT_TRUE(back.attributes.has_value());
        const wavebrdf::SliceAttributes& b = *back.attributes;
        EXPECT_EQ(b.query.x_um, a.query.x_um);
        EXPECT_EQ(b.query.y_um, a.query.y_um);
        EXPECT_EQ(b.query.sigma_p_um, a.query.sigma_p_um);
        EXPECT_EQ(b.query.omega_i, a.query.omega_i);
        EXPECT_EQ(b.query.model, a.query.model);
        EXPECT_EQ(b.lambdas_um, a.lambdas_um);  // exactly: shortest round-trip text
        EXPECT_EQ(b.resolution, 4);
        EXPECT_EQ(b.channels, 3);
        EXPECT_EQ(b.heightfield_rows, 64);
        EXPECT_EQ(b.heightfield_cols, 32);
        EXPECT_EQ(b.texel_um, 0.37);
        EXPECT_EQ(b.vscale, -2.5);
        EXPECT_EQ(b.heightfield_file, "dir/g.exr");
        EXPECT_EQ(b.unit, wavebrdf::k_slice_unit);
        EXPECT_EQ(b.made_by, "test");
        EXPECT_EQ(b.version, wavebrdf::k_version);
    }
    // No heightfield known (observations given as a list): none stored, none read.
    a.heightfield_rows = a.heightfield_cols = 0;
    wavebrdf::write_slice_exr(file("observed.exr"), image, a);
    const wavebrdf::SliceFile observed = wavebrdf::read_slice_exr(file("observed.exr"));
    ASSERT_TRUE(observed.attributes.has_value());
    EXPECT_EQ(observed.attributes->heightfield_rows, 0);
    EXPECT_EQ(observed.attributes->lambdas_um, a.lambdas_um);
    // A plain RGB EXR says nothing.
    wavebrdf::write_rgb_exr(file("plain.exr"), image);
    EXPECT_FALSE(wavebrdf::read_slice_exr(file("plain.exr")).attributes.has_value());
}

// A file that says it is a slice must say all of it, and say it in range.
TEST_F(IoTest, HostileSliceAttributesAreRefused) {
    RgbImage image{2, 2, std::vector<float>(12, 1.0f)};
    wavebrdf::SliceAttributes a;
    a.lambdas_um = {0.5};
    a.resolution = 2;
    a.channels = 1;
    const std::string good = file("good.exr");
    wavebrdf::write_slice_exr(good, image, a);
    ASSERT_TRUE(wavebrdf::read_slice_exr(good).attributes.has_value());
    // Rewrites the file's header with one attribute replaced (or removed: `value` null).
    const auto rewrite = [&](const std::string& name, const std::string& attribute, const Imf::Attribute* value) {
        Imf::InputFile in(good.c_str());
        // Without the attribute first: insert cannot change an attribute's type.
        Imf::Header header = wavebrdf::test::header_without(in.header(), attribute);
        if (value != nullptr) header.insert(attribute, *value);
        std::vector<float> data(12, 1.0f);
        Imf::FrameBuffer frame;
        for (int c = 0; c < 3; ++c)
            frame.insert(std::string(1, "RGB"[c]), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(data.data() + c),
                                                              3 * sizeof(float), 6 * sizeof(float)));
        const std::string path = file(name);
        Imf::OutputFile out(path.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(2);
        return path;
    };
    const Imf::StringAttribute bad_lambdas("0.5,abc"), bad_model("Phong"), many(std::string(5000, '1'));
    const Imf::DoubleAttribute negative_sigma(-1.0), nan_x(std::numeric_limits<double>::quiet_NaN());
    const Imf::IntAttribute big_resolution(1 << 30), two_channels(2);
    const Imf::V2dAttribute outside({0.9, 0.9});
    const std::vector<std::pair<std::string, const Imf::Attribute*>> cases = {{"wavebrdf:lambdas_um", &bad_lambdas},
                                                                              {"wavebrdf:model", &bad_model},
                                                                              {"wavebrdf:unit", &many},
                                                                              {"wavebrdf:sigma_p_um", &negative_sigma},
                                                                              {"wavebrdf:x_um", &nan_x},
                                                                              {"wavebrdf:resolution", &big_resolution},
                                                                              {"wavebrdf:channels", &two_channels},
                                                                              {"wavebrdf:omega_i", &outside},
                                                                              {"wavebrdf:model", nullptr},
                                                                              {"wavebrdf:resolution", nullptr},
                                                                              {"wavebrdf:lambdas_um", &negative_sigma}};
    for (std::size_t k = 0; k < cases.size(); ++k) {
        const std::string path = rewrite("bad" + std::to_string(k) + ".exr", cases[k].first, cases[k].second);
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_slice_exr(path); }, path);
        try {
            wavebrdf::read_slice_exr(path);
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find(cases[k].first), std::string::npos) << e.what();
        }
    }
}

TEST_F(IoTest, ReadsHalfExrWrittenWithRgbaApi) {
    const int rows = 5, cols = 3;
    std::vector<Imf::Rgba> pixels(rows * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            pixels[i * cols + j] = Imf::Rgba(half(0.25f * static_cast<float>(i) - 0.5f * static_cast<float>(j)),
                                             half(1.0f), half(2.0f), half(1.0f));
    const std::string path = file("half.exr");
    {
        Imf::RgbaOutputFile out(path.c_str(), cols, rows, Imf::WRITE_RGBA);
        out.setFrameBuffer(pixels.data(), 1, cols);
        out.writePixels(rows);
    }
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), rows);
    ASSERT_EQ(field.cols(), cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) EXPECT_EQ(field.value(i, j), 0.25 * i - 0.5 * j) << i << "," << j;

    const RgbImage image = wavebrdf::read_rgb_exr(path);
    ASSERT_EQ(image.rows, rows);
    ASSERT_EQ(image.cols, cols);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 0], 0.25f - 1.0f);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 1], 1.0f);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 2], 2.0f);
}

TEST_F(IoTest, HonoursDataWindowOffset) {
    const int rows = 4, cols = 6;
    std::vector<float> data(rows * cols);
    for (int k = 0; k < rows * cols; ++k) data[k] = static_cast<float>(k);
    const std::string path = file("offset.exr");
    write_exr_channel(path, "R", rows, cols, 3, 5, data);
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), rows);
    ASSERT_EQ(field.cols(), cols);
    EXPECT_EQ(field.value(0, 0), 0.0);
    EXPECT_EQ(field.value(2, 5), 2.0 * cols + 5);
    EXPECT_EQ(field.value(3, 1), 3.0 * cols + 1);
}

TEST_F(IoTest, AcceptsLuminanceOnlyExr) {
    const std::vector<float> data = {1.5f, -2.0f, 0.0f, 4.0f, 8.0f, -0.25f};
    const std::string path = file("y.exr");
    write_exr_channel(path, "Y", 2, 3, 0, 0, data);
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), 2);
    ASSERT_EQ(field.cols(), 3);
    EXPECT_EQ(field.value(1, 2), -0.25);
    const RgbImage image = wavebrdf::read_rgb_exr(path);
    EXPECT_EQ(image.data[(1 * 3 + 0) * 3 + 2], 4.0f);
}

TEST_F(IoTest, RgbExrRoundTripsWithAndWithoutAlpha) {
    RgbImage image{2, 3, {}};
    for (int k = 0; k < 2 * 3 * 3; ++k) image.data.push_back(0.1f * static_cast<float>(k) - 0.7f);
    for (bool alpha : {false, true}) {
        const std::string path = file(alpha ? "rgba.exr" : "rgb.exr");
        wavebrdf::write_rgb_exr(path, image, alpha);
        const RgbImage back = wavebrdf::read_rgb_exr(path);
        EXPECT_EQ(back.rows, 2);
        EXPECT_EQ(back.cols, 3);
        EXPECT_EQ(back.data, image.data);
        Imf::InputFile in(path.c_str());
        const Imf::ChannelList& channels = in.header().channels();
        EXPECT_EQ(channels.findChannel("A") != nullptr, alpha);
        ASSERT_NE(channels.findChannel("G"), nullptr);
        EXPECT_EQ(channels.findChannel("G")->type, Imf::FLOAT);
        if (alpha) {
            std::vector<float> a(6, 0.0f);
            Imf::FrameBuffer frame;
            frame.insert("A", Imf::Slice::Make(Imf::FLOAT, a.data(), in.header().dataWindow()));
            in.setFrameBuffer(frame);
            in.readPixels(0, 1);
            EXPECT_EQ(a, std::vector<float>(6, 1.0f));
        }
    }
}

TEST_F(IoTest, MissingFileThrowsNamingPath) {
    const std::string path = file("absent.exr");
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
}

TEST_F(IoTest, TextFileThrowsNamingPath) {
    const std::string path = file("notes.exr");
    std::ofstream(path) << "this is not an image\n";
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

TEST_F(IoTest, TruncatedExrThrowsNamingPath) {
    // Big and noisy enough that half the file cuts through pixel data, not just the header.
    const int rows = 64, cols = 48;
    std::vector<double> values(rows * cols);
    for (std::size_t k = 0; k < values.size(); ++k)
        values[k] = std::sin(0.37 * static_cast<double>(k)) * 1e3 + static_cast<double>(k);
    const std::string path = file("cut.exr");
    wavebrdf::write_heightfield_exr(path, Heightfield(rows, cols, values));
    const auto size = fs::file_size(path);
    fs::resize_file(path, size / 2);
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

// Issue 9: a 1.6 MB file declaring 20000² pixels took 4.7 GB and failed with std::bad_alloc.
// The header alone (no pixels written) declares the size; the reader must refuse it before
// allocating, naming the file, the declared size and the limit.
TEST_F(IoTest, HugeDeclaredSizeIsRefusedBeforeAllocating) {
    const std::string path = file("huge.exr");
    {
        Imf::Header header(20000, 20000);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        Imf::OutputFile out(path.c_str(), header);  // closed without pixels: header + offsets
    }
    ASSERT_LT(fs::file_size(path), 1u << 20);
    for (const auto& read : {std::function<void()>([&] { wavebrdf::read_heightfield_exr(path); }),
                             std::function<void()>([&] { wavebrdf::read_rgb_exr(path); })}) {
        try {
            read();
            ADD_FAILURE() << "no exception for " << path;
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("20000x20000"), std::string::npos) << message;
            EXPECT_NE(message.find(std::to_string(wavebrdf::k_max_exr_pixels)), std::string::npos) << message;
        } catch (const std::exception& e) {
            ADD_FAILURE() << "wrong exception type: " << e.what();
        }
    }
}

// Found by fuzz/exr_fuzz.cpp: OpenEXR 3.1 allocates a header attribute at its declared size
// (here 2 GB, from a 357-byte file) before reading it. The reader refuses it first, naming it.
TEST_F(IoTest, ExrAttributeLargerThanTheFileIsRefusedBeforeAllocating) {
    const std::string path = file("huge_attribute.exr");
    wavebrdf::write_heightfield_exr(path, make_field(4, 4));
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    // pixelAspectRatio becomes an attribute OpenEXR does not know, "qixelAspectRatio" of type
    // "xloat", declaring 2^31 - 1 bytes.
    const std::string attribute("pixelAspectRatio\0float\0", 23);
    const std::size_t at = bytes.find(attribute);
    ASSERT_NE(at, std::string::npos);
    bytes[at] = 'q';
    bytes[at + 17] = 'x';
    bytes.replace(at + attribute.size(), 4, std::string("\xff\xff\xff\x7f", 4));
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << bytes;
    }
    for (const auto& read : {+[](const std::string& p) { wavebrdf::read_heightfield_exr(p); },
                             +[](const std::string& p) { wavebrdf::read_rgb_exr(p); }}) {
        try {
            read(path);
            ADD_FAILURE() << "no exception";
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("'qixelAspectRatio' (type 'xloat') declares 2147483647 bytes"), std::string::npos)
                << message;
        }
    }
}

TEST_F(IoTest, ExrWithoutRedOrLuminanceThrowsNamingPath) {
    const std::string path = file("green.exr");
    write_exr_channel(path, "G", 2, 2, 0, 0, {1.0f, 2.0f, 3.0f, 4.0f});
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
    expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
}

TEST_F(IoTest, NonFiniteValueThrowsDomainErrorNamingPath) {
    const std::string path = file("nan.exr");
    write_exr_channel(path, "R", 2, 2, 0, 0, {1.0f, std::numeric_limits<float>::quiet_NaN(), 3.0f, 4.0f});
    expect_io_error_naming<std::domain_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

TEST_F(IoTest, FailedWritesLeaveNoFileBehind) {
    const Heightfield field = make_field(3, 4);
    const RgbImage image{1, 2, {0.f, 0.5f, 1.f, 2.f, 3.f, 4.f}};
    // A missing directory, and a "directory" that is a regular file (fails even for root).
    std::ofstream(file("plain")) << "x";
    for (const std::string& dir : {file("missing"), file("plain")}) {
        const std::string path = dir + "/out";
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::write_heightfield_exr(path + ".exr", field); },
                                                path + ".exr");
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::write_heightfield_png(path + ".png", field); },
                                                path + ".png");
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::write_rgb_exr(path + ".exr", image, true); },
                                                path + ".exr");
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::write_rgb_png(path + ".png", image); }, path + ".png");
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::check_writable(path + ".exr"); }, path + ".exr");
    }
    EXPECT_FALSE(fs::exists(file("missing")));
    EXPECT_EQ(listing(), std::vector<std::string>{"plain"});
}

TEST_F(IoTest, RenameOntoDirectoryFailsAndRemovesTemporary) {
    // The temporary is written fine; only the final rename fails, which must clean up too.
    fs::create_directory(file("taken.exr"));
    fs::create_directory(file("taken.exr") + "/inside");
    expect_io_error_naming<std::runtime_error>(
        [&] { wavebrdf::write_heightfield_exr(file("taken.exr"), make_field(2, 2)); }, file("taken.exr"));
    EXPECT_EQ(listing(), std::vector<std::string>{"taken.exr"});
}

TEST_F(IoTest, CheckWritableLeavesNothing) {
    wavebrdf::check_writable(file("later.exr"));
    EXPECT_TRUE(listing().empty());
}

// ---------------------------------------------------------------------------------------------
// Atomic writes replace only regular files, never mix, and leave no temporary behind.

// The file type bits of `path` itself (a link is not followed); 0 when it does not exist.
mode_t file_type(const std::string& path) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0 ? (st.st_mode & S_IFMT) : 0;
}

// Every writer on `path`, each expected to refuse with the path and "not a regular file".
void expect_every_writer_refuses(const std::string& path) {
    const Heightfield field = make_field(2, 3);
    const RgbImage image{1, 2, {0.f, 0.5f, 1.f, 2.f, 3.f, 4.f}};
    const std::vector<std::function<void()>> writers = {
        [&] { wavebrdf::write_text_atomically(path, "text\n"); },
        [&] { wavebrdf::write_file_atomically(path, [](const std::string& tmp) { std::ofstream(tmp) << "x"; }); },
        [&] { wavebrdf::write_heightfield_exr(path, field); },
        [&] { wavebrdf::write_heightfield_png(path, field); },
        [&] { wavebrdf::write_rgb_exr(path, image, true); },
        [&] { wavebrdf::write_rgb_png(path, image); },
        [&] {
            wavebrdf::write_npy(path, {2}, {1.0, 2.0});
        },
        [&] { wavebrdf::check_writable(path); },
    };
    for (std::size_t k = 0; k < writers.size(); ++k) {
        SCOPED_TRACE("writer " + std::to_string(k));
        try {
            writers[k]();
            ADD_FAILURE() << "no exception for " << path;
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("not a regular file; refusing to replace it"), std::string::npos) << message;
        }
    }
}

TEST_F(IoTest, WritersRefuseFifoSymlinkDirectoryAndSocket) {
    std::ofstream(file("target.txt")) << "keep me\n";
    ASSERT_EQ(::mkfifo(file("fifo").c_str(), 0644), 0);
    fs::create_symlink(file("target.txt"), file("link"));
    fs::create_symlink(file("missing.txt"), file("dangling"));
    fs::create_directory(file("dir"));
    const int sock = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    const std::string socket_path = file("sock");
    const bool have_socket = sock >= 0 && socket_path.size() < sizeof address.sun_path;
    if (have_socket) {
        std::memcpy(address.sun_path, socket_path.c_str(), socket_path.size() + 1);
        ASSERT_EQ(::bind(sock, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
    }
    for (const char* name : {"fifo", "link", "dangling", "dir", "sock"}) {
        SCOPED_TRACE(name);
        if (std::string(name) == "sock" && !have_socket) continue;
        const mode_t before = file_type(file(name));
        expect_every_writer_refuses(file(name));
        EXPECT_EQ(file_type(file(name)), before) << "the target was replaced";
    }
    if (sock >= 0) ::close(sock);
    EXPECT_EQ(fs::read_symlink(file("link")), fs::path(file("target.txt")));
    std::ifstream in(file("target.txt"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, "keep me\n") << "wrote through the link";
    EXPECT_FALSE(fs::exists(file("missing.txt"))) << "created the dangling link's target";
    EXPECT_TRUE(fs::is_empty(file("dir")));
    for (const std::string& name : listing()) EXPECT_EQ(name.find(".tmp"), std::string::npos) << name;
}

// A character device like /dev/null, made here (root only) so that a broken writer could only
// replace a node of this test's own directory, never the machine's /dev/null.
TEST_F(IoTest, WritersRefuseACharacterDevice) {
    const std::string node = file("null");
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0)
        GTEST_SKIP() << "cannot create a device node here (not root?)";
    ASSERT_EQ(file_type(node), static_cast<mode_t>(S_IFCHR));
    expect_every_writer_refuses(node);
    EXPECT_EQ(file_type(node), static_cast<mode_t>(S_IFCHR)) << "the device node was replaced";
    EXPECT_EQ(listing(), std::vector<std::string>{"null"});
}

TEST_F(IoTest, WriteTextReplacesARegularFile) {
    const std::string path = file("run.json");
    std::ofstream(path) << "old contents, longer than the new\n";
    wavebrdf::write_text_atomically(path, "new\n");
    std::ifstream in(path);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, "new\n");
    EXPECT_EQ(listing(), std::vector<std::string>{"run.json"});
}

// Threads of one process and two processes write the same path at once: every read sees one
// writer's whole file (the last rename wins), and no temporary is left. (With one fixed
// `<path>.tmp` name, two writers wrote into one temporary and mixed their contents.)
TEST_F(IoTest, ConcurrentWritersNeverMixAndLeaveNoTemporary) {
    const std::string path = file("metrics.csv");
    const std::size_t size = 1 << 18;
    auto writer = [&](char letter, int count) {
        const std::string text(size, letter);
        for (int k = 0; k < count; ++k) wavebrdf::write_text_atomically(path, text);
    };
    // Every complete read is one letter, `size` times.
    auto uniform = [&](const std::string& text) {
        return text.size() == size && text.find_first_not_of(text[0]) == std::string::npos;
    };
    auto read_all = [&] {
        std::ifstream in(path, std::ios::binary);
        return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    writer('z', 1);

    std::atomic<bool> done{false};
    std::atomic<int> mixed{0};
    std::thread reader([&] {
        while (!done.load())
            if (!uniform(read_all())) ++mixed;
    });
    {
        std::vector<std::thread> threads;
        for (char letter : {'a', 'b', 'c'}) threads.emplace_back(writer, letter, 20);
        for (std::thread& t : threads) t.join();
    }
    // Two processes (forked children write 'p' and 'q').
    std::vector<pid_t> children;
    for (char letter : {'p', 'q'}) {
        const pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            try {
                writer(letter, 20);
            } catch (...) {
                std::_Exit(1);
            }
            std::_Exit(0);
        }
        children.push_back(pid);
    }
    for (pid_t pid : children) {
        int status = 0;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child " << pid << " failed";
    }
    done.store(true);
    reader.join();
    EXPECT_EQ(mixed.load(), 0) << "a read saw a mixed or partial file";
    EXPECT_TRUE(uniform(read_all()));
    EXPECT_EQ(listing(), std::vector<std::string>{"metrics.csv"});
}

// A write that fails part way, or whose directory disappears before the rename, leaves no
// temporary and (where it still exists) the old file unchanged.
TEST_F(IoTest, FailedWriteLeavesNoTemporary) {
    const std::string path = file("checkpoint.json");
    std::ofstream(path) << "old\n";
    EXPECT_THROW(wavebrdf::write_file_atomically(path,
                                                 [](const std::string& tmp) {
                                                     std::ofstream(tmp) << "half";
                                                     throw std::runtime_error("disk full");
                                                 }),
                 std::runtime_error);
    EXPECT_EQ(listing(), std::vector<std::string>{"checkpoint.json"});

    const fs::path sub = m_dir / "sub";
    fs::create_directory(sub);
    const std::string inside = (sub / "metrics.csv").string();
    expect_io_error_naming<std::runtime_error>(
        [&] {
            wavebrdf::write_file_atomically(inside, [&](const std::string& tmp) {
                std::ofstream(tmp) << "data";
                fs::remove_all(sub);  // the run directory removed while the file is written
            });
        },
        inside);
    EXPECT_FALSE(fs::exists(sub));

    // A directory without write permission (root may write anyway: skipped then).
    fs::create_directory(sub);
    fs::permissions(sub, fs::perms::owner_read | fs::perms::owner_exec);
    if (::geteuid() != 0) {
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::write_text_atomically(inside, "x"); }, inside);
        EXPECT_TRUE(fs::is_empty(sub));
    }
    fs::permissions(sub, fs::perms::owner_all);
    std::vector<std::string> names = listing();
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"checkpoint.json", "sub"}));
    EXPECT_TRUE(fs::is_empty(sub));
    std::ifstream in(path);
    EXPECT_EQ(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()), "old\n");
}

// A process killed by a signal in the middle of a write: its handler calls
// remove_temporary_files(), and the temporary is gone.
extern "C" void remove_temporaries_and_exit(int) {
    wavebrdf::remove_temporary_files();
    ::_exit(3);
}

TEST_F(IoTest, SignalHandlerRemovesTheTemporaryOfAWriteInProgress) {
    const std::string path = file("estimate.exr");
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ::close(ready[0]);
        ::signal(SIGTERM, remove_temporaries_and_exit);
        ::alarm(60);  // never outlive a broken test
        try {
            wavebrdf::write_file_atomically(path, [&](const std::string& tmp) {
                std::ofstream(tmp) << "half-written";
                const char byte = 1;
                if (::write(ready[1], &byte, 1) != 1) std::_Exit(1);
                for (;;) ::pause();  // "still writing" until the signal comes
            });
        } catch (...) {}
        std::_Exit(2);
    }
    ::close(ready[1]);
    char byte = 0;
    ASSERT_EQ(::read(ready[0], &byte, 1), 1);
    ::close(ready[0]);
    bool temporary_seen = false;
    for (const std::string& name : listing()) temporary_seen |= name.rfind("estimate.exr.tmp-", 0) == 0;
    EXPECT_TRUE(temporary_seen) << "the child's temporary should exist while it writes";
    ASSERT_EQ(::kill(pid, SIGTERM), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 3);
    EXPECT_TRUE(listing().empty()) << "left: " << (listing().empty() ? "" : listing()[0]);
}

// A signal handled on one thread while another thread writes: the writer creates its temporary
// only after the handler began (unlinking then would not stop it), so remove_temporary_files()
// must wait for it; the write then removes its temporary and fails instead of moving the file
// into place, and a write begun afterwards fails at once. In a child process: the removal is
// for good.
TEST_F(IoTest, RemovalWaitsForAWriteOnAnotherThread) {
    const std::string path = file("checkpoint.json");
    const std::string later = file("later.json");
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ::alarm(60);  // never outlive a broken test
        std::atomic<bool> registered{false};
        std::atomic<int> outcome{0};  // 1: the write threw, 2: it returned
        std::thread writer([&] {
            try {
                wavebrdf::write_file_atomically(path, [&](const std::string& tmp) {
                    registered = true;
                    std::this_thread::sleep_for(std::chrono::milliseconds(200));
                    std::ofstream(tmp) << "{}";
                });
                outcome = 2;
            } catch (const std::runtime_error&) {
                outcome = 1;
            }
        });
        while (!registered) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        wavebrdf::remove_temporary_files();
        const bool waited = outcome != 0;
        writer.join();
        bool later_refused = false;
        try {
            wavebrdf::write_text_atomically(later, "{}");
        } catch (const std::runtime_error&) {
            later_refused = true;
        }
        std::_Exit((waited ? 0 : 1) | (outcome == 1 ? 0 : 2) | (later_refused ? 0 : 4));
    }
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status)) << status;
    const int code = WEXITSTATUS(status);
    EXPECT_EQ(code & 1, 0) << "the removal returned before the other thread's write ended";
    EXPECT_EQ(code & 2, 0) << "the write moved its file into place after the removal";
    EXPECT_EQ(code & 4, 0) << "a write begun after the removal went ahead";
    EXPECT_TRUE(listing().empty()) << "left: " << (listing().empty() ? "" : listing()[0]);
}

// A multi-part EXR: the reader used to read part 0 silently; it refuses and says why.
void write_multi_part_exr(const std::string& path, int parts) {
    const int rows = 2, cols = 3;
    std::vector<float> values(static_cast<std::size_t>(rows * cols), 0.5f);
    std::vector<Imf::Header> headers;
    for (int p = 0; p < parts; ++p) {
        Imf::Header header(cols, rows);
        header.setName("part" + std::to_string(p));
        header.setType(Imf::SCANLINEIMAGE);
        for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        headers.push_back(header);
    }
    Imf::MultiPartOutputFile out(path.c_str(), headers.data(), parts);
    for (int p = 0; p < parts; ++p) {
        Imf::OutputPart part(out, p);
        Imf::FrameBuffer frame;
        for (const char* c : {"R", "G", "B"})
            frame.insert(c, Imf::Slice::Make(Imf::FLOAT, values.data(), headers[p].dataWindow()));
        part.setFrameBuffer(frame);
        part.writePixels(rows);
    }
}

TEST_F(IoTest, MultiPartExrIsRefused) {
    const std::string path = file("parts.exr");
    write_multi_part_exr(path, 2);
    for (int reader = 0; reader < 2; ++reader) {
        try {
            if (reader == 0)
                wavebrdf::read_heightfield_exr(path);
            else
                wavebrdf::read_rgb_exr(path);
            ADD_FAILURE() << "a multi-part file was read";
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("multi-part"), std::string::npos) << message;
            EXPECT_NE(message.find("2 parts"), std::string::npos) << message;
        }
    }
    // One part written through the multi-part API is an ordinary image.
    write_multi_part_exr(file("one.exr"), 1);
    EXPECT_EQ(wavebrdf::read_rgb_exr(file("one.exr")).cols, 3);
}

TEST_F(IoTest, RgbPngHasSizeAndSrgbValues) {
    // 0.5 linear → sRGB 0.7354 → 188; 0.001 is on the linear segment → 0.01292 → 3.
    RgbImage image{2, 3, std::vector<float>(18, 0.0f)};
    auto px = [&](int i, int j, int c) -> float& { return image.data[(i * 3 + j) * 3 + c]; };
    px(0, 0, 0) = 0.5f;
    px(0, 0, 1) = 0.001f;
    px(0, 0, 2) = 7.0f;  // clamps to white
    px(1, 2, 0) = std::numeric_limits<float>::quiet_NaN();
    px(1, 2, 1) = std::numeric_limits<float>::infinity();
    px(1, 2, 2) = -3.0f;
    px(0, 1, 0) = 0.25f;  // exposure +1 → 0.5 → 188; with Reinhard 1/3 → 0.6125 → 156
    const std::string path = file("img.png");
    wavebrdf::write_rgb_png(path, image);
    Png png = read_png(path, true);
    ASSERT_EQ(png.rows, 2);
    ASSERT_EQ(png.cols, 3);
    auto at = [&](int i, int j, int c) { return static_cast<int>(png.pixels[(i * 3 + j) * 3 + c]); };
    EXPECT_EQ(at(0, 0, 0), 188);
    EXPECT_EQ(at(0, 0, 1), 3);
    EXPECT_EQ(at(0, 0, 2), 255);
    EXPECT_EQ(at(1, 2, 0), 0);
    EXPECT_EQ(at(1, 2, 1), 0);
    EXPECT_EQ(at(1, 2, 2), 0);
    EXPECT_EQ(at(0, 1, 0), 137);  // 0.25 → 0.5371 → 137

    wavebrdf::write_rgb_png(path, image, 1.0);
    png = read_png(path, true);
    EXPECT_EQ(at(0, 1, 0), 188);
    wavebrdf::write_rgb_png(path, image, 1.0, true);
    png = read_png(path, true);
    EXPECT_EQ(at(0, 1, 0), 156);
    EXPECT_EQ(listing(), std::vector<std::string>{"img.png"});
}

TEST_F(IoTest, HeightfieldPngStretchesMinToMax) {
    const Heightfield field(2, 3, {-1.0, 0.0, 1.0, 3.0, -1.0, 0.5});
    const std::string path = file("h.png");
    wavebrdf::write_heightfield_png(path, field);
    Png png = read_png(path, false);
    ASSERT_EQ(png.rows, 2);
    ASSERT_EQ(png.cols, 3);
    EXPECT_EQ(png.pixels, (std::vector<std::uint8_t>{0, 64, 128, 255, 0, 96}));

    wavebrdf::write_heightfield_png(path, Heightfield(1, 2, {4.0, 4.0}));
    png = read_png(path, false);
    EXPECT_EQ(png.pixels, (std::vector<std::uint8_t>{128, 128}));
}

TEST_F(IoTest, InvalidImageArgumentsThrow) {
    const std::string path = file("bad.png");
    EXPECT_THROW(wavebrdf::write_rgb_png(path, RgbImage{2, 2, std::vector<float>(5)}), std::invalid_argument);
    EXPECT_THROW(wavebrdf::write_rgb_exr(file("bad.exr"), RgbImage{0, 2, {}}), std::invalid_argument);
    EXPECT_THROW(wavebrdf::write_rgb_png(path, RgbImage{1, 1, {0.f, 0.f, 0.f}}, std::nan("")), std::domain_error);
    EXPECT_TRUE(listing().empty());
}

// Found by fuzz/exr_fuzz.cpp: OpenEXR sizes line-offset tables, compressor and tile buffers from
// the header when it opens a file (up to 1.2 GB from 133 bytes). Each saved input is refused
// before it is opened, with a runtime_error naming the file.
TEST_F(IoTest, FuzzerFoundExrHeadersAreRefusedBeforeOpening) {
    const fs::path dir = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "regressions" / "exr";
    int seen = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string path = entry.path().string();
        ++seen;
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
        expect_io_error_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
    }
    EXPECT_GE(seen, 5);
}

}  // namespace
