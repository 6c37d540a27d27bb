#pragma once
// A minimal PNG decoder for the tests (libpng's simplified API): any PNG as 8-bit RGB.
#include <png.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace wavebrdf::test {

struct DecodedPng {
    int rows = 0;
    int cols = 0;
    std::vector<std::uint8_t> rgb;  // rgb[(i * cols + j) * 3 + c]
};

// Decodes `path` to 8-bit RGB (a grey file is expanded to R = G = B); throws
// std::runtime_error when it is not a readable PNG.
inline DecodedPng read_png_rgb(const std::string& path) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (png_image_begin_read_from_file(&image, path.c_str()) == 0)
        throw std::runtime_error("cannot read " + path + ": " + image.message);
    image.format = PNG_FORMAT_RGB;
    DecodedPng png;
    png.rows = static_cast<int>(image.height);
    png.cols = static_cast<int>(image.width);
    png.rgb.resize(PNG_IMAGE_SIZE(image));
    if (png_image_finish_read(&image, nullptr, png.rgb.data(), 0, nullptr) == 0)
        throw std::runtime_error("cannot decode " + path + ": " + image.message);
    return png;
}

}  // namespace wavebrdf::test
