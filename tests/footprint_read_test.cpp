// read_heightfield_exr_footprint (io.h): `render` and `genbrdf` read only the rows of the
// heightfield their one footprint needs. Checked against a full read of the same file: the
// footprint's kernels (heights and slopes, so every row a slope reaches) and the rendered slices
// bit for bit, for footprints across the tile's seam, far away, and covering the whole tile; and
// the hostile files a full read refuses are refused too.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>

#include "wavebrdf/brdf.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/io.h"

namespace fs = std::filesystem;
using namespace wavebrdf;

namespace {

class FootprintReadTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        m_dir = fs::path(WAVEBRDF_TEST_TMP) / "footprint_read" /
                (std::string(info->name()) + "-" + std::to_string(::getpid()));
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override {
        std::error_code ignored;
        fs::remove_all(m_dir, ignored);
    }
    std::string file(const std::string& name) const { return (m_dir / name).string(); }
    fs::path m_dir;
};

// A rough, non-square field (every value different, floats exactly) with texel 0.5 µm and
// vertical scale 1.3: 96 rows (x, period 48 µm) × 80 columns (y, period 40 µm).
constexpr int k_rows = 96, k_cols = 80;
constexpr double k_texel_um = 0.5;

Heightfield rough_field() {
    std::vector<double> values(std::size_t(k_rows) * k_cols);
    std::uint32_t state = 12345u;
    for (double& v : values) {
        state = state * 1664525u + 1013904223u;
        v = double(float(double(state >> 8) / double(1u << 24) - 0.5));
    }
    return Heightfield(k_rows, k_cols, values, k_texel_um, 1.3);
}

// Rows of `hf` that hold anything but zeros.
int rows_read(const Heightfield& hf) {
    int count = 0;
    for (int i = 0; i < hf.rows(); ++i) {
        bool any = false;
        for (int j = 0; j < hf.cols(); ++j) any = any || hf.value(i, j) != 0.0;
        count += any ? 1 : 0;
    }
    return count;
}

void expect_same_kernels(const FootprintKernels& a, const FootprintKernels& b) {
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(a.row, b.row);
    EXPECT_EQ(a.col, b.col);
    EXPECT_EQ(a.dx_um, b.dx_um);
    EXPECT_EQ(a.dy_um, b.dy_um);
    EXPECT_EQ(a.weight, b.weight);
    EXPECT_EQ(a.height_um, b.height_um);
    EXPECT_EQ(a.slope_x, b.slope_x);
    EXPECT_EQ(a.slope_y, b.slope_y);
}

TEST_F(FootprintReadTest, KernelsAndSlicesAreBitIdenticalToAFullRead) {
    const std::string path = file("rough.exr");
    write_heightfield_exr(path, rough_field());
    const Heightfield full = read_heightfield_exr(path);
    const double period_x = k_rows * k_texel_um;
    struct Case {
        double x_um, y_um, sigma_p_um;
        bool partial;  // whether only some rows are read
    };
    const Case cases[] = {
        {24.0, 20.0, 2.0, true},                 // mid-tile
        {0.0, 0.0, 2.0, true},                   // on the seam: rows at both ends
        {0.1, 39.9, 2.0, true},                  // just after the seam
        {period_x - 0.05, 0.3, 2.0, true},       // just before it
        {-0.3, -7.0, 1.5, true},                 // negative: reduced to the end of the tile
        {period_x * 1e6 + 3.0, 5.0, 2.0, true},  // many periods away
        {47.0, 1.0, 7.0, true},                  // 91 of 96 rows, across the seam
        {12.0, 30.0, 8.0, false},                // covers every row: the whole file
        {0.0, 0.0, 100.0, false},                // far wider than the tile
    };
    for (const Case& c : cases) {
        SCOPED_TRACE("x " + std::to_string(c.x_um) + " um, y " + std::to_string(c.y_um) + " um, sigma_p " +
                     std::to_string(c.sigma_p_um) + " um");
        const HeightfieldFile read = read_heightfield_exr_footprint(path, c.x_um, c.sigma_p_um);
        const Heightfield& part = read.heightfield;
        ASSERT_EQ(part.rows(), k_rows);
        ASSERT_EQ(part.cols(), k_cols);
        EXPECT_EQ(part.texel_um(), full.texel_um());
        EXPECT_EQ(part.vscale(), full.vscale());
        EXPECT_EQ(read.attributes.texel_um, std::optional<double>(k_texel_um));
        if (c.partial)
            EXPECT_LT(rows_read(part), k_rows);
        else
            EXPECT_EQ(part.values(), full.values());
        expect_same_kernels(footprint_kernels(part, c.x_um, c.y_um, c.sigma_p_um),
                            footprint_kernels(full, c.x_um, c.y_um, c.sigma_p_um));
        Query q;
        q.x_um = c.x_um;
        q.y_um = c.y_um;
        q.sigma_p_um = c.sigma_p_um;
        q.omega_i = {0.3, -0.2};
        for (Model model : {Model::OHS, Model::GHS}) {
            q.model = model;
            EXPECT_EQ(render_rgb<double>(part, q, {0.5}, 12), render_rgb<double>(full, q, {0.5}, 12));
        }
    }
}

TEST_F(FootprintReadTest, GivenScaleDecidesTheRowsAndIsUsed) {
    // A given texel width other than the file's moves the footprint's rows: a footprint at 10 um
    // is at row 20 of 0.5 um texels but at row 5 of 2 um ones.
    const std::string path = file("rough.exr");
    write_heightfield_exr(path, rough_field());
    const Heightfield full = read_heightfield_exr(path, 2.0, 0.7);
    const Heightfield part = read_heightfield_exr_footprint(path, 10.0, 3.0, 2.0, 0.7).heightfield;
    EXPECT_EQ(part.texel_um(), 2.0);
    EXPECT_EQ(part.vscale(), 0.7);
    EXPECT_LT(rows_read(part), k_rows);
    expect_same_kernels(footprint_kernels(part, 10.0, 4.0, 3.0), footprint_kernels(full, 10.0, 4.0, 3.0));
}

TEST_F(FootprintReadTest, HostileFilesAreRefused) {
    const auto expect_refused = [](const std::string& path, const auto& call, bool domain = false) {
        try {
            call();
            ADD_FAILURE() << "no exception for " << path;
        } catch (const std::domain_error& e) {
            EXPECT_TRUE(domain) << e.what();
            EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        } catch (const std::runtime_error& e) {
            EXPECT_FALSE(domain) << e.what();
            EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
        }
    };
    // The fuzzer's headers, refused before OpenEXR opens them.
    const fs::path dir = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "regressions" / "exr";
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string path = entry.path().string();
        expect_refused(path, [&] { read_heightfield_exr_footprint(path, 0.0, 1.0); });
    }
    // A header declaring 20000² pixels (no pixels follow).
    const std::string huge = file("huge.exr");
    {
        Imf::Header header(20000, 20000);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        Imf::OutputFile out(huge.c_str(), header);
    }
    expect_refused(huge, [&] { read_heightfield_exr_footprint(huge, 0.0, 1.0); });
    expect_refused(file("missing.exr"), [&] { read_heightfield_exr_footprint(file("missing.exr"), 0.0, 1.0); });

    // Cut where the footprint's rows are (the last rows, reached across the seam from x = 0).
    const std::string cut = file("cut.exr");
    write_heightfield_exr(cut, rough_field());
    fs::resize_file(cut, fs::file_size(cut) * 3 / 4);
    expect_refused(cut, [&] { read_heightfield_exr_footprint(cut, 0.0, 2.0); });

    // A non-finite value in a row the footprint reads.
    std::vector<double> values = rough_field().values();
    const std::string nan = file("nan.exr");
    {
        std::vector<float> pixels(values.begin(), values.end());
        pixels[std::size_t(k_rows - 2) * k_cols + 7] = std::numeric_limits<float>::quiet_NaN();
        Imf::Header header(k_cols, k_rows);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        Imf::FrameBuffer frame;
        frame.insert(
            "R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(pixels.data()), sizeof(float), sizeof(float) * k_cols));
        Imf::OutputFile out(nan.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(k_rows);
    }
    expect_refused(
        nan, [&] { read_heightfield_exr_footprint(nan, 0.0, 1.0); }, true);

    // A footprint that is no footprint.
    const std::string good = file("good.exr");
    write_heightfield_exr(good, rough_field());
    for (const auto& [x, sigma] : {std::pair{std::nan(""), 1.0}, std::pair{0.0, 0.0}, std::pair{0.0, -1.0},
                                   std::pair{std::numeric_limits<double>::infinity(), 1.0}})
        EXPECT_THROW(read_heightfield_exr_footprint(good, x, sigma), std::domain_error);
}

}  // namespace
