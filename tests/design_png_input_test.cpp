// A PNG picture (a pattern target's image, a plate's picture) is a file like any other: a small
// file that declares a huge picture is refused from its header, before the pixels it declares are
// allocated, and complete pictures still read.
#include <gtest/gtest.h>
#include <png.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

// CRC-32 of PNG chunks (ISO 3309), bit by bit.
std::uint32_t crc32(const unsigned char* data, std::size_t n) {
    std::uint32_t c = 0xffffffffU;
    for (std::size_t i = 0; i < n; ++i) {
        c ^= data[i];
        for (int k = 0; k < 8; ++k) c = (c & 1U) ? 0xedb88320U ^ (c >> 1) : c >> 1;
    }
    return c ^ 0xffffffffU;
}

void put32(std::string& bytes, std::size_t at, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) bytes[at + std::size_t(k)] = char((v >> (24 - 8 * k)) & 0xffU);
}

// An RGB picture written by libpng (rows × cols, every pixel `rgb`).
std::string png_bytes(const std::string& path, int rows, int cols, std::uint8_t value) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = png_uint_32(cols);
    image.height = png_uint_32(rows);
    image.format = PNG_FORMAT_RGB;
    const std::vector<std::uint8_t> pixels(std::size_t(rows) * std::size_t(cols) * 3, value);
    if (png_image_write_to_file(&image, path.c_str(), 0, pixels.data(), 0, nullptr) == 0)
        throw std::runtime_error("libpng cannot write " + path);
    return test::read_text(path);
}

// The same file with IHDR declaring another size (its CRC made right again).
void declare_size(const std::string& path, std::string bytes, std::uint32_t width, std::uint32_t height) {
    ASSERT_EQ(bytes.substr(12, 4), "IHDR");
    put32(bytes, 16, width);
    put32(bytes, 20, height);
    put32(bytes, 29, crc32(reinterpret_cast<const unsigned char*>(bytes.data()) + 12, 17));
    std::ofstream(path, std::ios::binary) << bytes;
}

template <typename Read>
std::string message_of(Read&& read) {
    try {
        read();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "(no exception)";
}

TEST(DesignPngInput, ADeclaredSizeTheFileCannotHoldIsRefusedBeforeAllocating) {
    const auto dir = test::fresh_dir("design_png");
    const std::string small = (dir / "small.png").string(), huge = (dir / "huge.png").string();
    const std::string bytes = png_bytes(small, 2, 2, 200);
    ASSERT_LT(bytes.size(), 200u);

    // A plate's picture may have 16384² pixels: 805 MB of RGB that this file of under 200 bytes
    // declares without holding.
    declare_size(huge, bytes, 16384, 16384);
    std::string m = message_of([&] { read_plate_picture(huge); });
    EXPECT_NE(m.find("huge.png' declares 16384 x 16384 pixels, more than its " + std::to_string(bytes.size()) +
                     " bytes can hold"),
              std::string::npos)
        << m;
    // A pattern image is at most 1024²: still more than the file can hold.
    declare_size(huge, bytes, 1024, 1024);
    m = message_of([&] { parse_design_target("pattern:" + huge); });
    EXPECT_NE(m.find("pattern image '" + huge + "' declares 1024 x 1024 pixels"), std::string::npos) << m;

    // Complete pictures read, large ones of one colour (libpng compresses them the most) too.
    EXPECT_EQ(read_plate_picture(small).rows, 2);
    const std::string flat = (dir / "flat.png").string();
    png_bytes(flat, 2048, 2048, 0);
    const PlatePicture p = read_plate_picture(flat);
    EXPECT_EQ(p.rows, 2048);
    EXPECT_EQ(p.cols, 2048);
    png_bytes(flat, 1024, 1024, 0);
    m = message_of([&] { parse_design_target("pattern:" + flat); });
    EXPECT_NE(m.find("pattern image is uniform"), std::string::npos) << "a flat image is read, then refused: " << m;
}

}  // namespace
}  // namespace wavebrdf
