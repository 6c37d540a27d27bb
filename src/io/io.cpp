#include "wavebrdf/io.h"

#include <sys/stat.h>
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
#include <ImfMultiPartInputFile.h>
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
// The pid keeps processes apart; the counter keeps two writes of one process (threads) apart.
std::string temporary_name(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    return path + ".tmp-" + std::to_string(static_cast<long long>(::getpid())) + "-" +
           std::to_string(counter.fetch_add(1));
}

void remove_quietly(const std::string& path) {
    std::error_code ignored;
    fs::remove(path, ignored);
}

// The temporary files of writes in progress, for remove_temporary_files() in a signal
// handler: fixed slots, no allocation, no locks. A slot is free (0), being changed (1), or
// holds the name of a temporary that may exist (2); the handler reads only slots in state 2.
constexpr int kTemporarySlots = 64;
constexpr std::size_t kTemporaryNameMax = 4096;
struct TemporarySlot {
    std::atomic<int> state{0};
    char name[kTemporaryNameMax];
};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs lock-free atomics");
TemporarySlot g_temporary_slots[kTemporarySlots];

// Lists `name` in a free slot for as long as it lives (none free, or a name too long: not
// listed, and the write goes on without that safety net).
class TemporaryRegistration {
public:
    explicit TemporaryRegistration(const std::string& name) {
        if (name.size() >= kTemporaryNameMax) return;
        for (int k = 0; k < kTemporarySlots; ++k) {
            int expected = 0;
            if (g_temporary_slots[k].state.compare_exchange_strong(expected, 1)) {
                std::memcpy(g_temporary_slots[k].name, name.c_str(), name.size() + 1);
                g_temporary_slots[k].state.store(2);
                m_slot = k;
                return;
            }
        }
    }
    // Call once the temporary is renamed or removed (a handler that unlinks the old name in
    // between finds nothing: the name is unique to this process and write).
    ~TemporaryRegistration() {
        if (m_slot >= 0) g_temporary_slots[m_slot].state.store(0);
    }
    TemporaryRegistration(const TemporaryRegistration&) = delete;
    TemporaryRegistration& operator=(const TemporaryRegistration&) = delete;

private:
    int m_slot = -1;
};

// Throws when `path` exists and is not a regular file: renaming onto it would replace a device
// node, FIFO, socket or symbolic link with a regular file (or fail on a directory).
void refuse_non_regular(const std::string& path) {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return;  // absent (or unreachable: the write will say)
    if (S_ISREG(st.st_mode)) return;
    const char* kind = S_ISDIR(st.st_mode)    ? "a directory"
                       : S_ISLNK(st.st_mode)  ? "a symbolic link"
                       : S_ISFIFO(st.st_mode) ? "a FIFO"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                                              : "a special file";
    fail(path, std::string("is ") + kind + ", not a regular file; refusing to replace it");
}

// Throws when `path` is an OpenEXR file of several parts: InputFile would silently read part 0
// only. Refusing is simpler and safer than guessing which part holds the data.
void refuse_multi_part(const std::string& path) {
    if (!Imf::isMultiPartOpenExrFile(path.c_str())) return;
    int parts = 0;
    try {
        parts = Imf::MultiPartInputFile(path.c_str()).parts();
    } catch (const std::exception& e) {
        fail(path, std::string("cannot read OpenEXR header (") + e.what() + ")");
    }
    if (parts > 1)
        fail(path, "is a multi-part OpenEXR file (" + std::to_string(parts) +
                       " parts); expected a single-part image (extract the part you want first)");
}

void check_image(const RgbImage& image) {
    if (image.rows < 1 || image.cols < 1)
        throw std::invalid_argument("image size " + std::to_string(image.rows) + "x" + std::to_string(image.cols) +
                                    " is empty; expected at least 1x1");
    const std::size_t expected = static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols) * 3u;
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
// It also refuses, from the same walk, a data window wider or taller than k_max_exr_side, more
// than k_max_exr_channels channels and tiles above k_max_exr_tile_pixels: OpenEXR sizes its
// line-offset tables and buffers from them when it opens the file (fuzz/regressions/exr/).
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
            {"box2i", 16},   {"box2f", 16},    {"compression", 1}, {"deepImageState", 1},
            {"double", 8},   {"envmap", 1},    {"float", 4},       {"int", 4},
            {"keycode", 28}, {"lineOrder", 1}, {"m33f", 36},       {"m33d", 72},
            {"m44f", 64},    {"m44d", 128},    {"rational", 8},    {"tiledesc", 9},
            {"timecode", 8}, {"v2i", 8},       {"v2f", 8},         {"v2d", 16},
            {"v3i", 12},     {"v3f", 12},      {"v3d", 24},        {"chromaticities", 32}};
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
            std::uint32_t(size_bytes[0]) | std::uint32_t(size_bytes[1]) << 8 | std::uint32_t(size_bytes[2]) << 16 |
            std::uint32_t(size_bytes[3]) << 24);
        if (size < 0) return;  // OpenEXR refuses it itself
        if (type == "chlist") {
            // Channels (name, then 16 bytes) up to an empty name.
            std::string channel;
            int channels = 0;
            while (read_name(channel) && !channel.empty()) {
                in.seekg(16, std::ios::cur);
                if (++channels > k_max_exr_channels)
                    fail(path, "declares more than " + std::to_string(k_max_exr_channels) +
                                   " channels; expected an image (R, G, B, A or Y)");
            }
            if (!in) return;
            continue;
        }
        // The data window and the tile size decide what OpenEXR allocates when it opens the
        // file (line-offset tables, compressor and tile buffers): bounded here, before it does.
        if ((type == "box2i" && name == "dataWindow") || (type == "tiledesc" && name == "tiles")) {
            unsigned char bytes[16] = {};
            const int count = type == "box2i" ? 16 : 8;
            if (!in.read(reinterpret_cast<char*>(bytes), count)) return;
            if (type == "tiledesc") in.seekg(1, std::ios::cur);  // level and rounding modes
            long long v[4] = {};
            for (int k = 0; k < count / 4; ++k)
                v[k] = static_cast<std::int32_t>(std::uint32_t(bytes[4 * k]) | std::uint32_t(bytes[4 * k + 1]) << 8 |
                                                 std::uint32_t(bytes[4 * k + 2]) << 16 |
                                                 std::uint32_t(bytes[4 * k + 3]) << 24);
            if (type == "box2i") {
                const long long width = v[2] - v[0] + 1, height = v[3] - v[1] + 1;
                if (width > k_max_exr_side || height > k_max_exr_side)
                    // No pixel count: sides up to 2^32 each would overflow it (found by the fuzzer).
                    fail(path, "declares a " + std::to_string(width) + "x" + std::to_string(height) +
                                   " image; the limit is " + std::to_string(k_max_exr_side) + " per side (" +
                                   std::to_string(k_max_exr_pixels) + " pixels)");
            } else {
                const long long tile_x = std::uint32_t(v[0]), tile_y = std::uint32_t(v[1]);
                if (tile_x > k_max_exr_side || tile_y > k_max_exr_side || tile_x * tile_y > k_max_exr_tile_pixels)
                    fail(path, "declares " + std::to_string(tile_x) + "x" + std::to_string(tile_y) +
                                   " tiles; the limit is " + std::to_string(k_max_exr_tile_pixels) +
                                   " pixels per tile");
            }
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
            fail(path, "header attribute '" + name + "' (type '" + type + "') declares " + std::to_string(size) +
                           " bytes but only " + std::to_string(rest) +
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
        if (!Imf::isOpenExrFile(path.c_str())) fail(path, "not an OpenEXR file (missing magic number or unreadable)");
        check_attribute_sizes(path);  // first: opening the file is what allocates
        refuse_multi_part(path);
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
        // Before any pixel is allocated: a small file may declare a huge image.
        if (width * height > k_max_exr_pixels)
            fail(path, "declares a " + std::to_string(width) + "x" + std::to_string(height) + " image (" +
                           std::to_string(width * height) + " pixels); the limit is " +
                           std::to_string(k_max_exr_pixels) + " pixels (16384x16384)");
        m_rows = static_cast<int>(height);
        m_cols = static_cast<int>(width);
    }

    bool has_channel(const char* name) const { return m_file->header().channels().findChannel(name) != nullptr; }

    // Reads channels[c] into data[k * stride + c] (float, whatever the stored type), row-major
    // from the data window's top-left corner, which Slice::Make maps to element 0.
    void read(const std::vector<std::string>& channels, std::vector<float>& data) const {
        const std::size_t stride = channels.size();
        const std::size_t count = static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols) * stride;
        const Imath::Box2i dw = m_file->header().dataWindow();
        try {
            data.assign(count, 0.0f);
            Imf::FrameBuffer frame;
            for (std::size_t c = 0; c < stride; ++c)
                frame.insert(channels[c], Imf::Slice::Make(Imf::FLOAT, data.data() + c, dw, stride * sizeof(float),
                                                           stride * sizeof(float) * static_cast<std::size_t>(m_cols)));
            m_file->setFrameBuffer(frame);
            m_file->readPixels(dw.min.y, dw.max.y);
        } catch (const std::exception& e) {
            // A truncated file usually opens fine and only fails here.
            fail(m_path, std::string("cannot read OpenEXR pixels, file truncated or corrupt (") + e.what() + ")");
        }
    }

    std::string m_path;
    std::unique_ptr<Imf::InputFile> m_file;
    int m_rows = 0;
    int m_cols = 0;
};

// Writes float channels interleaved in `data` (stride = channels.size()) as a ZIP EXR.
void write_float_exr(const std::string& file, int rows, int cols, const std::vector<std::string>& channels,
                     const float* data) {
    const std::size_t stride = channels.size();
    Imf::Header header(cols, rows);  // width = columns, height = rows
    for (const std::string& name : channels) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < stride; ++c)
        frame.insert(channels[c],
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(data + c)),
                                stride * sizeof(float), stride * sizeof(float) * static_cast<std::size_t>(cols)));
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

// Writes 8-bit pixels (1 or 3 channels) with libpng's simplified API, which reports errors
// through its return value instead of longjmp, so no C++ frame is skipped.
void write_png8(const std::string& file, int rows, int cols, bool rgb, const std::vector<std::uint8_t>& pixels) {
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
double srgb_encode(double x) { return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055; }

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
    write_file_atomically(path, [&](const std::string& tmp) {
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
    write_file_atomically(
        path, [&](const std::string& tmp) { write_png8(tmp, heightfield.rows(), heightfield.cols(), false, pixels); });
}

RgbImage to_image(const std::vector<double>& slice, int n, int channels) {
    RgbImage image;
    image.rows = image.cols = n;
    image.data.resize(static_cast<std::size_t>(n) * n * 3);
    for (std::size_t p = 0; p < static_cast<std::size_t>(n) * n; ++p)
        for (int c = 0; c < 3; ++c) image.data[3 * p + c] = float(slice[p * channels + (channels == 3 ? c : 0)]);
    return image;
}

void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha) {
    check_image(image);
    if (!with_alpha) {
        write_file_atomically(path, [&](const std::string& tmp) {
            write_float_exr(tmp, image.rows, image.cols, {"R", "G", "B"}, image.data.data());
        });
        return;
    }
    const std::size_t count = static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols);
    std::vector<float> rgba(count * 4u, 1.0f);
    for (std::size_t k = 0; k < count; ++k)
        for (std::size_t c = 0; c < 3; ++c) rgba[k * 4u + c] = image.data[k * 3u + c];
    write_file_atomically(path, [&](const std::string& tmp) {
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
    if (!source.has_channel("Y")) fail(path, "has no R, G, B channels (nor Y); expected an RGB image");
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
    write_file_atomically(path, [&](const std::string& tmp) { write_png8(tmp, image.rows, image.cols, true, pixels); });
}

void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const std::vector<double>& data) {
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
    write_file_atomically(path, [&](const std::string& tmp) {
        std::FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f) throw std::runtime_error("cannot create the file");
        const unsigned short length = static_cast<unsigned short>(dict.size());
        const unsigned char head[10] = {0x93,
                                        'N',
                                        'U',
                                        'M',
                                        'P',
                                        'Y',
                                        1,
                                        0,
                                        static_cast<unsigned char>(length & 0xff),
                                        static_cast<unsigned char>(length >> 8)};
        bool ok = std::fwrite(head, 1, 10, f) == 10 && std::fwrite(dict.data(), 1, dict.size(), f) == dict.size() &&
                  std::fwrite(data.data(), sizeof(double), data.size(), f) == data.size();
        ok = (std::fclose(f) == 0) && ok;
        if (!ok) throw std::runtime_error("write failed");
    });
}

void write_file_atomically(const std::string& path,
                           const std::function<void(const std::string& temporary_path)>& write) {
    refuse_non_regular(path);
    const std::string tmp = temporary_name(path);
    const TemporaryRegistration registration(tmp);
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
        fail(path, std::string("cannot move the finished file into place (") + std::strerror(err) + ")");
    }
}

void write_text_atomically(const std::string& path, const std::string& text) {
    write_file_atomically(path, [&](const std::string& tmp) {
        std::FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f) {
            const int err = errno;
            throw std::runtime_error(std::string("cannot create the file: ") + std::strerror(err));
        }
        bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
        ok = (std::fclose(f) == 0) && ok;
        if (!ok) throw std::runtime_error("write failed (disk full?)");
    });
}

void remove_temporary_files() noexcept {
    for (TemporarySlot& slot : g_temporary_slots)
        if (slot.state.load() == 2) ::unlink(slot.name);
}

void check_writable(const std::string& path) {
    refuse_non_regular(path);
    const std::string tmp = temporary_name(path);
    const TemporaryRegistration registration(tmp);
    std::FILE* file = std::fopen(tmp.c_str(), "wb");
    if (file == nullptr) {
        const int err = errno;
        fail(path, std::string("cannot create a file here (") + std::strerror(err) + ")");
    }
    std::fclose(file);
    remove_quietly(tmp);
}

double auto_exposure(const std::vector<double>& slice) {
    std::vector<double> v(slice.begin(), slice.end());
    if (v.empty()) return 0.0;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(0.999 * double(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k] > 0 ? -std::log2(v[k]) + 2.0 : 0.0;
}

}  // namespace wavebrdf
