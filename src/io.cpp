#include "wavebrdf/io.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfTestFile.h>
#include <png.h>

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

// OpenEXR messages may span several lines; callers (the CLI) print exactly one.
std::string one_line(std::string text) {
    std::replace(text.begin(), text.end(), '\n', ' ');
    std::replace(text.begin(), text.end(), '\r', ' ');
    while (!text.empty() && text.back() == ' ') text.pop_back();
    return text;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
    throw std::runtime_error(path + ": " + one_line(what));
}

// A name beside the target, so the final rename stays on one filesystem and is atomic.
// The counter keeps two writes of the same path from one process apart.
std::string temporary_name(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    return path + ".tmp-" + std::to_string(static_cast<long long>(::getpid())) + "-" +
           std::to_string(counter.fetch_add(1));
}

void remove_quietly(const std::string& path) {
    std::error_code ignored;
    fs::remove(path, ignored);
}

// Runs `write` on a temporary file and renames it onto `path`; on any failure the temporary
// is removed and a std::runtime_error naming `path` is thrown, so no partial output remains.
void write_atomically(const std::string& path,
                      const std::function<void(const std::string&)>& write) {
    const std::string tmp = temporary_name(path);
    try {
        write(tmp);
    } catch (const std::exception& e) {
        remove_quietly(tmp);
        fail(path, std::string("cannot write file (") + e.what() + ")");
    } catch (...) {
        remove_quietly(tmp);
        fail(path, "cannot write file (unknown error)");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int err = errno;
        remove_quietly(tmp);
        fail(path,
             std::string("cannot move the finished file into place (") + std::strerror(err) + ")");
    }
}

void check_image(const RgbImage& image) {
    if (image.rows < 1 || image.cols < 1)
        throw std::invalid_argument("image size " + std::to_string(image.rows) + "x" +
                                    std::to_string(image.cols) +
                                    " is empty; expected at least 1x1");
    const std::size_t expected =
        static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols) * 3u;
    if (image.data.size() != expected)
        throw std::invalid_argument("image has " + std::to_string(image.data.size()) +
                                    " values; expected rows*cols*3 = " + std::to_string(expected));
}

// OpenEXR 3.1 allocates a header attribute of a type it stores as bytes (a string, an unknown
// type) at the size the file declares, up to 2 GB, before reading it, so a few hundred bytes
// can ask for gigabytes (found by fuzz/exr_fuzz.cpp). Walks the headers the way OpenEXR reads
// them (name, type, int32 size, value; fixed-size types and channel lists are read by their own
// layout, whatever their declared size; an empty name ends a header, and in a multi-part file an
// empty header ends the list) and refuses such an attribute larger than the rest of the file.
// Anything else malformed is left to OpenEXR, which reports it.
void check_attribute_sizes(const std::string& path) {
    std::error_code ec;
    const std::uintmax_t file_size = fs::file_size(path, ec);
    if (ec) return;
    std::ifstream in(path, std::ios::binary);
    char version[8];
    if (!in.read(version, sizeof version)) return;
    const bool multi_part = (static_cast<unsigned char>(version[5]) & 0x10u) != 0;  // bit 12
    const auto read_name = [&](std::string& name) {
        name.clear();
        for (char c; in.get(c);) {
            if (c == '\0') return true;
            if (name.size() >= 255) return false;  // longer than OpenEXR allows
            name += c;
        }
        return false;
    };
    // Bytes OpenEXR 3.1 reads for the fixed-size attribute types (ImfStandardAttributes.h).
    const auto fixed_size = [](const std::string& type) -> int {
        static const std::pair<const char*, int> sizes[] = {
            {"box2i", 16}, {"box2f", 16}, {"compression", 1}, {"deepImageState", 1},
            {"double", 8}, {"envmap", 1}, {"float", 4}, {"int", 4}, {"keycode", 28},
            {"lineOrder", 1}, {"m33f", 36}, {"m33d", 72}, {"m44f", 64}, {"m44d", 128},
            {"rational", 8}, {"tiledesc", 9}, {"timecode", 8}, {"v2i", 8}, {"v2f", 8},
            {"v2d", 16}, {"v3i", 12}, {"v3f", 12}, {"v3d", 24}, {"chromaticities", 32}};
        for (const auto& [name, size] : sizes)
            if (type == name) return size;
        return -1;
    };
    std::string name, type;
    for (bool header_empty = true;;) {
        if (!read_name(name)) return;
        if (name.empty()) {
            // End of a header; a multi-part file ends its list of headers with an empty one.
            if (!multi_part || header_empty) return;
            header_empty = true;
            continue;
        }
        header_empty = false;
        unsigned char size_bytes[4];
        if (!read_name(type) || !in.read(reinterpret_cast<char*>(size_bytes), 4)) return;
        const std::int32_t size = static_cast<std::int32_t>(
            std::uint32_t(size_bytes[0]) | std::uint32_t(size_bytes[1]) << 8 |
            std::uint32_t(size_bytes[2]) << 16 | std::uint32_t(size_bytes[3]) << 24);
        if (size < 0) return;  // OpenEXR refuses it itself
        if (type == "chlist") {
            // Channels (name, then 16 bytes) up to an empty name.
            std::string channel;
            while (read_name(channel) && !channel.empty()) in.seekg(16, std::ios::cur);
            if (!in) return;
            continue;
        }
        if (type == "preview") return;  // width × height × 4 bytes; left to the pixel checks
        const int fixed = fixed_size(type);
        if (fixed >= 0) {
            in.seekg(fixed, std::ios::cur);
            continue;
        }
        const std::streamoff at = in.tellg();
        if (at < 0) return;
        const std::uintmax_t rest = file_size - std::min<std::uintmax_t>(file_size, std::uintmax_t(at));
        if (std::uintmax_t(size) > rest)
            fail(path, "header attribute '" + name + "' (type '" + type + "') declares " +
                           std::to_string(size) + " bytes but only " + std::to_string(rest) +
                           " follow; expected an OpenEXR file that is not corrupt or truncated");
        in.seekg(size, std::ios::cur);
    }
}

// An opened EXR file with the facts every reader needs; errors name the path.
struct ExrSource {
    explicit ExrSource(const std::string& path) : m_path(path) {
        std::error_code ec;
        if (!fs::exists(path, ec)) fail(path, "file does not exist");
        if (fs::is_directory(path, ec)) fail(path, "is a directory; expected an OpenEXR file");
        // isOpenExrFile checks the magic number, giving a clearer message than InputFile.
        if (!Imf::isOpenExrFile(path.c_str()))
            fail(path, "not an OpenEXR file (missing magic number or unreadable)");
        check_attribute_sizes(path);
        try {
            m_file = std::make_unique<Imf::InputFile>(path.c_str());
        } catch (const std::exception& e) {
            fail(path, std::string("cannot read OpenEXR header (") + e.what() + ")");
        }
        const Imath::Box2i dw = m_file->header().dataWindow();
        const long long width = static_cast<long long>(dw.max.x) - dw.min.x + 1;
        const long long height = static_cast<long long>(dw.max.y) - dw.min.y + 1;
        if (width < 1 || height < 1 || width > std::numeric_limits<int>::max() ||
            height > std::numeric_limits<int>::max())
            fail(path, "data window " + std::to_string(width) + "x" + std::to_string(height) +
                           " is invalid; expected a non-empty image");
        m_rows = static_cast<int>(height);
        m_cols = static_cast<int>(width);
    }

    bool has_channel(const char* name) const {
        return m_file->header().channels().findChannel(name) != nullptr;
    }

    // Reads channels[c] into data[k * stride + c] (float, whatever the stored type), row-major
    // from the data window's top-left corner, which Slice::Make maps to element 0.
    void read(const std::vector<std::string>& channels, std::vector<float>& data) const {
        const std::size_t stride = channels.size();
        const std::size_t count =
            static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols) * stride;
        const Imath::Box2i dw = m_file->header().dataWindow();
        try {
            data.assign(count, 0.0f);
            Imf::FrameBuffer frame;
            for (std::size_t c = 0; c < stride; ++c)
                frame.insert(
                    channels[c],
                    Imf::Slice::Make(Imf::FLOAT, data.data() + c, dw, stride * sizeof(float),
                                     stride * sizeof(float) * static_cast<std::size_t>(m_cols)));
            m_file->setFrameBuffer(frame);
            m_file->readPixels(dw.min.y, dw.max.y);
        } catch (const std::exception& e) {
            // A truncated file usually opens fine and only fails here.
            fail(m_path, std::string("cannot read OpenEXR pixels, file truncated or corrupt (") +
                             e.what() + ")");
        }
    }

    std::string m_path;
    std::unique_ptr<Imf::InputFile> m_file;
    int m_rows = 0;
    int m_cols = 0;
};

// Writes float channels interleaved in `data` (stride = channels.size()) as a ZIP EXR.
void write_float_exr(const std::string& file, int rows, int cols,
                     const std::vector<std::string>& channels, const float* data) {
    const std::size_t stride = channels.size();
    Imf::Header header(cols, rows);  // width = columns, height = rows
    for (const std::string& name : channels)
        header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < stride; ++c)
        frame.insert(channels[c],
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(data + c)),
                                stride * sizeof(float),
                                stride * sizeof(float) * static_cast<std::size_t>(cols)));
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

// Writes 8-bit pixels (1 or 3 channels) with libpng's simplified API, which reports errors
// through its return value instead of longjmp, so no C++ frame is skipped.
void write_png8(const std::string& file, int rows, int cols, bool rgb,
                const std::vector<std::uint8_t>& pixels) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(cols);
    image.height = static_cast<png_uint_32>(rows);
    image.format = rgb ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
    if (png_image_write_to_file(&image, file.c_str(), 0, pixels.data(), 0, nullptr) == 0) {
        const std::string message = image.message;
        png_image_free(&image);
        throw std::runtime_error("libpng: " + message);
    }
}

// sRGB transfer curve (IEC 61966-2-1) on a linear value already clamped to [0, 1].
double srgb_encode(double x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}

}  // namespace

Heightfield read_heightfield_exr(const std::string& path, double texel_um, double vscale) {
    ExrSource source(path);
    // A single-channel luminance file is as good a heightfield as an R channel.
    const char* channel = source.has_channel("R") ? "R" : source.has_channel("Y") ? "Y" : nullptr;
    if (channel == nullptr) fail(path, "has no R or Y channel; expected a heightfield in R");
    std::vector<float> pixels;
    source.read({channel}, pixels);
    std::vector<double> values(pixels.begin(), pixels.end());
    try {
        return Heightfield(source.m_rows, source.m_cols, std::move(values), texel_um, vscale);
    } catch (const std::domain_error& e) {
        throw std::domain_error(path + ": " + e.what());
    }
}

void write_heightfield_exr(const std::string& path, const Heightfield& heightfield) {
    const std::vector<double>& values = heightfield.values();
    const std::vector<float> data(values.begin(), values.end());
    write_atomically(path, [&](const std::string& tmp) {
        write_float_exr(tmp, heightfield.rows(), heightfield.cols(), {"R"}, data.data());
    });
}

void write_heightfield_png(const std::string& path, const Heightfield& heightfield) {
    const std::vector<double>& values = heightfield.values();
    const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
    const double min = *lo;
    const double range = *hi - *lo;
    std::vector<std::uint8_t> pixels(values.size());
    for (std::size_t k = 0; k < values.size(); ++k) {
        // A flat field has no range to stretch; mid grey says "constant" rather than "lowest".
        const double t = range > 0.0 ? (values[k] - min) / range : 128.0 / 255.0;
        pixels[k] = static_cast<std::uint8_t>(std::lround(std::clamp(t, 0.0, 1.0) * 255.0));
    }
    write_atomically(path, [&](const std::string& tmp) {
        write_png8(tmp, heightfield.rows(), heightfield.cols(), false, pixels);
    });
}

void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha) {
    check_image(image);
    if (!with_alpha) {
        write_atomically(path, [&](const std::string& tmp) {
            write_float_exr(tmp, image.rows, image.cols, {"R", "G", "B"}, image.data.data());
        });
        return;
    }
    const std::size_t count =
        static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols);
    std::vector<float> rgba(count * 4u, 1.0f);
    for (std::size_t k = 0; k < count; ++k)
        for (std::size_t c = 0; c < 3; ++c) rgba[k * 4u + c] = image.data[k * 3u + c];
    write_atomically(path, [&](const std::string& tmp) {
        write_float_exr(tmp, image.rows, image.cols, {"R", "G", "B", "A"}, rgba.data());
    });
}

RgbImage read_rgb_exr(const std::string& path) {
    ExrSource source(path);
    RgbImage image;
    image.rows = source.m_rows;
    image.cols = source.m_cols;
    if (source.has_channel("R") && source.has_channel("G") && source.has_channel("B")) {
        source.read({"R", "G", "B"}, image.data);
        return image;
    }
    // A luminance-only file is grey: replicate Y so callers always get three channels.
    if (!source.has_channel("Y"))
        fail(path, "has no R, G, B channels (nor Y); expected an RGB image");
    std::vector<float> grey;
    source.read({"Y"}, grey);
    image.data.resize(grey.size() * 3u);
    for (std::size_t k = 0; k < grey.size(); ++k)
        for (std::size_t c = 0; c < 3; ++c) image.data[k * 3u + c] = grey[k];
    return image;
}

void write_rgb_png(const std::string& path, const RgbImage& image, double exposure, bool tonemap) {
    check_image(image);
    if (!std::isfinite(exposure))
        throw std::domain_error("exposure " + std::to_string(exposure) +
                                " is invalid; expected a finite number of stops");
    const double scale = std::exp2(exposure);
    std::vector<std::uint8_t> pixels(image.data.size());
    for (std::size_t k = 0; k < image.data.size(); ++k) {
        const double value = static_cast<double>(image.data[k]);
        // NaN/inf carry no brightness to show; black marks them instead of poisoning the clamp.
        double x = std::isfinite(value) ? std::max(value * scale, 0.0) : 0.0;
        // x/(1+x) would give inf/inf = NaN for an overflowed product; its limit is 1.
        if (tonemap) x = std::isinf(x) ? 1.0 : x / (1.0 + x);
        x = std::min(x, 1.0);
        pixels[k] = static_cast<std::uint8_t>(std::lround(srgb_encode(x) * 255.0));
    }
    write_atomically(path, [&](const std::string& tmp) {
        write_png8(tmp, image.rows, image.cols, true, pixels);
    });
}

void write_npy(const std::string& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data) {
    std::size_t count = 1;
    for (std::size_t d : shape) count *= d;
    if (count != data.size())
        throw std::invalid_argument(path + ": npy shape holds " + std::to_string(count) + " values but " +
                                    std::to_string(data.size()) + " were given");
    // NPY format 1.0: magic, version, little-endian header length, a Python dict literal padded
    // with spaces to a multiple of 64 bytes and ending in a newline, then the raw data.
    std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (";
    for (std::size_t d : shape) dict += std::to_string(d) + ", ";
    dict += "), }";
    const std::size_t preamble = 10;
    std::size_t total = preamble + dict.size() + 1;
    dict.append((64 - total % 64) % 64, ' ');
    dict += '\n';
    write_atomically(path, [&](const std::string& tmp) {
        std::FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f) throw std::runtime_error("cannot create the file");
        const unsigned short length = static_cast<unsigned short>(dict.size());
        const unsigned char head[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0,
                                        static_cast<unsigned char>(length & 0xff),
                                        static_cast<unsigned char>(length >> 8)};
        bool ok = std::fwrite(head, 1, 10, f) == 10 &&
                  std::fwrite(dict.data(), 1, dict.size(), f) == dict.size() &&
                  std::fwrite(data.data(), sizeof(double), data.size(), f) == data.size();
        ok = (std::fclose(f) == 0) && ok;
        if (!ok) throw std::runtime_error("write failed");
    });
}

void check_writable(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) fail(path, "is a directory; expected a file path");
    const std::string tmp = temporary_name(path);
    std::FILE* file = std::fopen(tmp.c_str(), "wb");
    if (file == nullptr) {
        const int err = errno;
        fail(path, std::string("cannot create a file here (") + std::strerror(err) + ")");
    }
    std::fclose(file);
    remove_quietly(tmp);
}

}  // namespace wavebrdf
