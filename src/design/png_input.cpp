#include "design/png_input.h"

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "wavebrdf/input_files.h"

namespace wavebrdf::detail {

void begin_png_read(png_image& image, const std::string& path, const std::string& what) {
    try {
        check_readable_file(path);
    } catch (const std::runtime_error& e) {
        throw std::invalid_argument(what + ": " + e.what());
    }
    image = png_image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path.c_str()))
        throw std::invalid_argument(what + " cannot be read: " + image.message);
    std::error_code ec;
    const auto file_bytes = std::filesystem::file_size(path, ec);
    const double least = double(image.height) * (1.0 + std::ceil(double(image.width) / 8.0));
    if (!ec && least > 1032.0 * double(file_bytes)) {
        png_image_free(&image);
        throw std::invalid_argument(what + " declares " + std::to_string(image.width) + " x " +
                                    std::to_string(image.height) + " pixels, more than its " +
                                    std::to_string(file_bytes) + " bytes can hold; expected a complete PNG file");
    }
}

}  // namespace wavebrdf::detail
