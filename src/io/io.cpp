#include "wavebrdf/io.h"
#include "wavebrdf/input_files.h"

#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
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
#include <mutex>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <ImfTestFile.h>
#include <ImfThreading.h>
#include <ImfVecAttribute.h>
#include <png.h>

#include "core/srgb.h"
#include "io/surface_formats.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/threads.h"
#include "io/exr_source.h"
#include "io/exr_threads.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

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

[[noreturn]] void fail_file(const std::string& path, const std::string& what) {
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
    std::atomic<long> owner{0};  // the writing thread (its kernel id)
    char name[kTemporaryNameMax];
};
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<long>::is_always_lock_free &&
                  std::atomic<bool>::is_always_lock_free,
              "the signal handler needs lock-free atomics");
TemporarySlot g_temporary_slots[kTemporarySlots];

// Set once remove_temporary_files() has begun: the process is ending, and a write that has
// not yet moved its file into place removes its temporary and fails instead.
std::atomic<bool> g_removing{false};

long this_thread_id() { return static_cast<long>(::syscall(SYS_gettid)); }

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
                g_temporary_slots[k].owner.store(this_thread_id());
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

const char* file_kind(mode_t mode) {
    return S_ISDIR(mode)    ? "a directory"
           : S_ISLNK(mode)  ? "a symbolic link"
           : S_ISFIFO(mode) ? "a FIFO"
           : S_ISSOCK(mode) ? "a socket"
           : S_ISCHR(mode)  ? "a character device"
           : S_ISBLK(mode)  ? "a block device"
                            : "a special file";
}

// Throws when `path` exists and is not a regular file: renaming onto it would replace a device
// node, FIFO, socket or symbolic link with a regular file (or fail on a directory).
void refuse_non_regular(const std::string& path) {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return;  // absent (or unreachable: the write will say)
    if (S_ISREG(st.st_mode)) return;
    fail_file(path, std::string("is ") + file_kind(st.st_mode) + ", not a regular file; refusing to replace it");
}

// Throws when `path` is an OpenEXR file of several parts: InputFile would silently read part 0
// only. Refusing is simpler and safer than guessing which part holds the data.
void refuse_multi_part(const std::string& path) {
    if (!Imf::isMultiPartOpenExrFile(path.c_str())) return;
    int parts = 0;
    try {
        parts = Imf::MultiPartInputFile(path.c_str()).parts();
    } catch (const std::exception& e) {
        fail_file(path, std::string("cannot read OpenEXR header (") + e.what() + ")");
    }
    if (parts > 1)
        fail_file(path, "is a multi-part OpenEXR file (" + std::to_string(parts) +
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
                    fail_file(path, "declares more than " + std::to_string(k_max_exr_channels) +
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
                    fail_file(path, "declares a " + std::to_string(width) + "x" + std::to_string(height) +
                                   " image; the limit is " + std::to_string(k_max_exr_side) + " per side (" +
                                   std::to_string(k_max_exr_pixels) + " pixels)");
            } else {
                const long long tile_x = std::uint32_t(v[0]), tile_y = std::uint32_t(v[1]);
                if (tile_x > k_max_exr_side || tile_y > k_max_exr_side || tile_x * tile_y > k_max_exr_tile_pixels)
                    fail_file(path, "declares " + std::to_string(tile_x) + "x" + std::to_string(tile_y) +
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
            fail_file(path, "header attribute '" + name + "' (type '" + type + "') declares " + std::to_string(size) +
                           " bytes but only " + std::to_string(rest) +
                           " follow; expected an OpenEXR file that is not corrupt or truncated");
        in.seekg(size, std::ios::cur);
    }
}

using detail::ExrSource;

// Writes float channels interleaved in `data` (stride = channels.size()) as a ZIP EXR;
// `describe` adds header attributes.
void write_float_exr(const std::string& file, int rows, int cols, const std::vector<std::string>& channels,
                     const float* data, const std::function<void(Imf::Header&)>& describe = {}) {
    const std::size_t stride = channels.size();
    Imf::Header header(cols, rows);  // width = columns, height = rows
    // ZIP at deflate's fastest level: float slices shrink by about a fifth at any level, and the
    // default level took a third of a one-slice render's time. Lossless either way.
    header.zipCompressionLevel() = 1;
    if (describe) describe(header);
    for (const std::string& name : channels) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < stride; ++c)
        frame.insert(channels[c],
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(data + c)),
                                stride * sizeof(float), stride * sizeof(float) * static_cast<std::size_t>(cols)));
    Imf::OutputFile out(file.c_str(), header, detail::exr_threads());
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

// --- wavebrdf header attributes (docs/conventions.md, "Files") --------------------------------

const std::string k_prefix = "wavebrdf:";

void put_string(Imf::Header& header, const std::string& name, const std::string& value) {
    header.insert(k_prefix + name, Imf::StringAttribute(value.substr(0, k_max_attribute_chars)));
}
void put_double(Imf::Header& header, const std::string& name, double value) {
    header.insert(k_prefix + name, Imf::DoubleAttribute(value));
}
void put_int(Imf::Header& header, const std::string& name, int value) {
    header.insert(k_prefix + name, Imf::IntAttribute(value));
}

// One attribute of a file, read with the checks every value from a file needs: the expected
// type, a bounded length, finite numbers. Errors name the file and the attribute.
class AttributeReader {
public:
    AttributeReader(const std::string& path, const Imf::Header& header) : m_path(path), m_header(header) {}

    bool has(const std::string& name) const { return m_header.find(k_prefix + name) != m_header.end(); }

    [[noreturn]] void bad(const std::string& name, const std::string& what) const {
        fail_file(m_path, "attribute '" + k_prefix + name + "' " + what);
    }

    template <typename Attribute>
    const Attribute* typed(const std::string& name, const char* type) const {
        const auto it = m_header.find(k_prefix + name);
        if (it == m_header.end()) return nullptr;
        const auto* a = dynamic_cast<const Attribute*>(&it.attribute());
        if (a == nullptr) bad(name, std::string("has type '") + it.attribute().typeName() + "'; expected " + type);
        return a;
    }

    std::optional<std::string> string(const std::string& name) const {
        const auto* a = typed<Imf::StringAttribute>(name, "string");
        if (a == nullptr) return std::nullopt;
        const std::string& v = a->value();
        if (v.size() > k_max_attribute_chars)
            bad(name, "is " + std::to_string(v.size()) + " bytes long; expected at most " +
                          std::to_string(k_max_attribute_chars));
        return v;
    }

    // A finite double within [lo, hi] (or 0 when zero_ok).
    std::optional<double> number(const std::string& name, double lo, double hi, bool zero_ok = false,
                                 bool signed_ok = false) const {
        const auto* a = typed<Imf::DoubleAttribute>(name, "double");
        if (a == nullptr) return std::nullopt;
        const double v = a->value();
        const double m = signed_ok ? std::abs(v) : v;
        if (!std::isfinite(v) || !((zero_ok && v == 0.0) || (m >= lo && m <= hi)))
            bad(name, "is " + format_shortest(v) + "; expected a finite value " + (zero_ok ? "0 or " : "") +
                          (signed_ok ? "of magnitude " : "") + format_shortest(lo) + " to " + format_shortest(hi));
        return v;
    }

    std::optional<int> integer(const std::string& name, int lo, int hi) const {
        const auto* a = typed<Imf::IntAttribute>(name, "int");
        if (a == nullptr) return std::nullopt;
        const int v = a->value();
        if (v < lo || v > hi)
            bad(name, "is " + std::to_string(v) + "; expected " + std::to_string(lo) + " to " + std::to_string(hi));
        return v;
    }

    // For a file that must carry `name`.
    template <typename T>
    T required(const std::string& name, std::optional<T> value) const {
        if (!value) bad(name, "is missing; a wavebrdf slice file carries every slice attribute");
        return *value;
    }

private:
    std::string m_path;
    const Imf::Header& m_header;
};

HeightfieldAttributes heightfield_attributes(const std::string& path, const Imf::Header& header) {
    const AttributeReader r(path, header);
    HeightfieldAttributes a;
    a.texel_um = r.number("texel_um", k_min_texel_um, k_max_texel_um);
    a.vscale = r.number("vscale", k_min_vscale, k_max_vscale, true, true);
    a.units = r.string("units").value_or("");
    a.made_by = r.string("made_by").value_or("");
    a.version = r.string("version").value_or("");
    return a;
}

std::string join_numbers(const std::vector<double>& values) {
    std::string text;
    for (double v : values) text += (text.empty() ? "" : ",") + format_shortest(v);
    return text;
}

}  // namespace

HeightfieldAttributes read_heightfield_attributes(const std::string& path) {
    // Measured topographies (x3p, sdf, npy, ...) are heightfields too (surface_file.h).
    if (surface_io::is_measured_surface_file(path)) return surface_io::measured_attributes(path);
    const ExrSource source(path);
    return heightfield_attributes(path, source.m_file->header());
}

namespace {

// The heightfield channel of `source`: R, else a single luminance channel Y. A file that says
// it is something else (a BRDF table's wavebrdf:kind) is refused: its R channel is f_r, not heights.
const char* height_channel(const ExrSource& source) {
    const auto* kind = source.m_file->header().findTypedAttribute<Imf::StringAttribute>("wavebrdf:kind");
    if (kind != nullptr && kind->value() == "wavebrdf brdf table")
        fail_file(source.m_path, "is a '" + one_line(kind->value().substr(0, 64)) +
                                "' file (attribute wavebrdf:kind), not a heightfield; expected a heightfield EXR "
                                "(heights in R)");
    const char* channel = source.has_channel("R") ? "R" : source.has_channel("Y") ? "Y" : nullptr;
    if (channel == nullptr) fail_file(source.m_path, "has no R or Y channel; expected a heightfield in R");
    return channel;
}

// Rows per readPixels call: a multiple of every OpenEXR chunk height (1, 16, 32, 256 lines),
// so no chunk is decompressed twice; the float buffer is at most 256 × 16384 values (16 MiB).
constexpr int k_rows_per_read = 256;

// Appends rows first_row … last_row of `channel` to `values` as double, read block by block
// through one small float buffer (no full-size float copy, no zero-fill of `values`).
void append_rows(const ExrSource& source, const char* channel, int first_row, int last_row, std::vector<double>& values,
                 std::vector<float>& buffer) {
    const std::size_t cols = static_cast<std::size_t>(source.m_cols);
    for (int row = first_row; row <= last_row; row += k_rows_per_read) {
        const int last = std::min(last_row, row + k_rows_per_read - 1);
        const std::size_t count = static_cast<std::size_t>(last - row + 1) * cols;
        if (buffer.size() < count) buffer.resize(count);
        source.read_rows(channel, row, last, buffer.data());
        values.insert(values.end(), buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(count));
    }
}

// Reads the rows i of the file that rows_needed(i, rows, texel_um) asks for (others are 0) into a Heightfield.
template <typename RowsNeeded>
HeightfieldFile read_heightfield_rows(const std::string& path, std::optional<double> texel_um,
                                      std::optional<double> vscale, const RowsNeeded& rows_needed) {
    if (surface_io::is_measured_surface_file(path)) return surface_io::read_measured_heightfield(path, texel_um, vscale);
    ExrSource source(path);
    HeightfieldAttributes attributes = heightfield_attributes(path, source.m_file->header());
    const char* channel = height_channel(source);
    const double texel = texel_um.value_or(attributes.texel_um.value_or(1.0));
    const double scale = vscale.value_or(attributes.vscale.value_or(1.0));
    std::vector<double> values;
    values.reserve(static_cast<std::size_t>(source.m_rows) * static_cast<std::size_t>(source.m_cols));
    std::vector<float> buffer;
    // Runs of needed rows are read, runs of others filled with 0, in row order.
    for (int row = 0; row < source.m_rows;) {
        const bool needed = rows_needed(row, source.m_rows, texel);
        int end = row + 1;
        while (end < source.m_rows && rows_needed(end, source.m_rows, texel) == needed) ++end;
        if (needed)
            append_rows(source, channel, row, end - 1, values, buffer);
        else
            values.insert(values.end(), static_cast<std::size_t>(end - row) * std::size_t(source.m_cols), 0.0);
        row = end;
    }
    try {
        Heightfield heightfield(source.m_rows, source.m_cols, std::move(values), texel, scale);
        return {std::move(heightfield), std::move(attributes)};
    } catch (const std::domain_error& e) {
        throw std::domain_error(path + ": " + e.what());
    }
}

}  // namespace

HeightfieldFile read_heightfield_exr_file(const std::string& path, std::optional<double> texel_um,
                                          std::optional<double> vscale) {
    return read_heightfield_rows(path, texel_um, vscale, [](int, int, double) { return true; });
}

HeightfieldFile read_heightfield_exr_footprint(const std::string& path, double x_um, double sigma_p_um,
                                               std::optional<double> texel_um, std::optional<double> vscale) {
    if (!std::isfinite(x_um) || !std::isfinite(sigma_p_um) || !(sigma_p_um > 0.0))
        throw std::domain_error("footprint x " + format_shortest(x_um) + " um, sigma_p " + format_shortest(sigma_p_um) +
                                " um is invalid; expected finite x and sigma_p > 0");
    // Kernels lie within 3σ_p of the centre (gabor.cpp footprint_kernels), their slopes one row
    // further; 3 rows more absorb any rounding of the centre. In rows of texels, with the centre
    // reduced to one period as the kernels' is; distances are periodic, across the tile's seam.
    return read_heightfield_rows(path, texel_um, vscale, [&](int row, int rows, double texel) {
        const double reach = std::ceil(3.0 * sigma_p_um / texel) + 3.0;
        if (2.0 * reach + 1.0 >= double(rows)) return true;  // the footprint covers every row
        const double period = double(rows) * texel;
        double x = std::fmod(x_um, period);
        if (x < 0.0) x += period;
        double d = std::abs((double(row) + 0.5) - x / texel);
        d = std::min(d, double(rows) - d);
        return d <= reach;
    });
}
Heightfield read_heightfield_exr(const std::string& path, std::optional<double> texel_um,
                                 std::optional<double> vscale) {
    return read_heightfield_exr_file(path, texel_um, vscale).heightfield;
}

HeightfieldScale resolve_heightfield_scale(const std::string& path, const HeightfieldAttributes& file,
                                           std::optional<double> texel_um, std::optional<double> vscale,
                                           const std::string& texel_option, const std::string& vscale_option,
                                           double default_texel_um, double default_vscale) {
    HeightfieldScale scale;
    if (!texel_um && surface_io::measured_surface_needs_spacing(path))
        throw std::runtime_error(path + ": " + file.units + " states no spacing; give the texel width (" +
                                 texel_option + ")");
    const auto pick = [&](std::optional<double> given, std::optional<double> in_file, double fallback,
                          const std::string& option, const char* attribute) {
        if (given && in_file && *given != *in_file)
            scale.warnings.push_back(option + " " + format_shortest(*given) + " disagrees with " + path + "'s " +
                                     attribute + " " + format_shortest(*in_file) + "; using " +
                                     format_shortest(*given));
        return given ? *given : in_file ? *in_file : fallback;
    };
    scale.texel_um = pick(texel_um, file.texel_um, default_texel_um, texel_option, "texel_um");
    scale.vscale = pick(vscale, file.vscale, default_vscale, vscale_option, "vscale");
    // A given value out of range is an error, not a disagreement: checked as the Heightfield
    // read with it would, before any warning is shown.
    try {
        Heightfield(1, 1, {0.0}, scale.texel_um, scale.vscale);
    } catch (const std::domain_error& e) {
        throw std::domain_error(path + ": " + e.what());
    }
    return scale;
}

void write_heightfield_exr(const std::string& path, const Heightfield& heightfield, const std::string& made_by) {
    const std::vector<double>& values = heightfield.values();
    const std::vector<float> data(values.begin(), values.end());
    const auto describe = [&](Imf::Header& header) {
        put_string(header, "kind", "heightfield");
        put_double(header, "texel_um", heightfield.texel_um());
        put_double(header, "vscale", heightfield.vscale());
        put_string(header, "units", k_heightfield_units);
        put_string(header, "made_by", made_by);
        put_string(header, "version", k_version);
    };
    write_file_atomically(path, [&](const std::string& tmp) {
        write_float_exr(tmp, heightfield.rows(), heightfield.cols(), {"R"}, data.data(), describe);
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

namespace {

void write_rgb_exr_described(const std::string& path, const RgbImage& image, bool with_alpha,
                             const std::function<void(Imf::Header&)>& describe) {
    check_image(image);
    if (!with_alpha) {
        write_file_atomically(path, [&](const std::string& tmp) {
            write_float_exr(tmp, image.rows, image.cols, {"R", "G", "B"}, image.data.data(), describe);
        });
        return;
    }
    const std::size_t count = static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols);
    std::vector<float> rgba(count * 4u, 1.0f);
    for (std::size_t k = 0; k < count; ++k)
        for (std::size_t c = 0; c < 3; ++c) rgba[k * 4u + c] = image.data[k * 3u + c];
    write_file_atomically(path, [&](const std::string& tmp) {
        write_float_exr(tmp, image.rows, image.cols, {"R", "G", "B", "A"}, rgba.data(), describe);
    });
}

}  // namespace

void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha) {
    write_rgb_exr_described(path, image, with_alpha, {});
}

void write_slice_exr(const std::string& path, const RgbImage& image, const SliceAttributes& a, bool with_alpha) {
    const auto describe = [&](Imf::Header& header) {
        put_string(header, "kind", "slice");
        put_double(header, "x_um", a.query.x_um);
        put_double(header, "y_um", a.query.y_um);
        put_double(header, "sigma_p_um", a.query.sigma_p_um);
        header.insert(k_prefix + "omega_i", Imf::V2dAttribute(Imath::V2d(a.query.omega_i[0], a.query.omega_i[1])));
        put_string(header, "model", to_string(a.query.model));
        put_string(header, "lambdas_um", join_numbers(a.lambdas_um));
        put_int(header, "resolution", a.resolution);
        put_int(header, "channels", a.channels);
        if (a.heightfield_rows > 0) {  // 0: no heightfield known (measured or listed observations)
            put_double(header, "heightfield_texel_um", a.texel_um);
            put_double(header, "heightfield_vscale", a.vscale);
            header.insert(k_prefix + "heightfield_size",
                          Imf::V2iAttribute(Imath::V2i(a.heightfield_rows, a.heightfield_cols)));
            put_string(header, "heightfield_file", a.heightfield_file);
        }
        put_string(header, "unit", a.unit);
        put_string(header, "made_by", a.made_by);
        put_string(header, "version", k_version);
    };
    write_rgb_exr_described(path, image, with_alpha, describe);
}

SliceFile read_slice_exr(const std::string& path) {
    SliceFile file;
    file.image = read_rgb_exr(path);
    ExrSource source(path);  // the header again (read_rgb_exr keeps none): cheap, no pixels
    const AttributeReader r(path, source.m_file->header());
    const std::optional<std::string> kind = r.string("kind");
    if (!kind || *kind != "slice") return file;
    SliceAttributes a;
    a.query.x_um = r.required("x_um", r.number("x_um", 0.0, std::numeric_limits<double>::max(), true, true));
    a.query.y_um = r.required("y_um", r.number("y_um", 0.0, std::numeric_limits<double>::max(), true, true));
    a.query.sigma_p_um = r.required("sigma_p_um", r.number("sigma_p_um", k_min_sigma_p_um, k_max_sigma_p_um));
    const auto* omega = r.typed<Imf::V2dAttribute>("omega_i", "v2d");
    if (omega == nullptr) r.bad("omega_i", "is missing; a wavebrdf slice file carries every slice attribute");
    a.query.omega_i = {omega->value().x, omega->value().y};
    const std::string model = r.required("model", r.string("model"));
    try {
        a.query.model = parse_model(model);
    } catch (const std::exception& e) {
        r.bad("model", std::string("is invalid (") + e.what() + ")");
    }
    try {
        validate(a.query);  // x, y and sigma_p are checked above: what is left is the light
    } catch (const std::exception& e) {
        r.bad("omega_i", std::string("is invalid (") + e.what() + ")");
    }
    const std::string lambdas = r.required("lambdas_um", r.string("lambdas_um"));
    try {
        std::size_t at = 0;
        while (at <= lambdas.size()) {
            const std::size_t comma = std::min(lambdas.find(',', at), lambdas.size());
            const std::string item = lambdas.substr(at, comma - at);
            std::size_t used = 0;
            const double l = std::stod(item, &used);
            if (used != item.size()) throw std::invalid_argument(item);
            validate_lambda(l);
            a.lambdas_um.push_back(l);
            if (a.lambdas_um.size() > std::size_t(k_max_spectral_samples)) throw std::invalid_argument("too many");
            at = comma + 1;
        }
    } catch (const std::exception&) {
        r.bad("lambdas_um", "is '" + lambdas.substr(0, 80) + "'; expected 1 to " +
                                std::to_string(k_max_spectral_samples) + " wavelengths in um, comma-separated");
    }
    a.resolution = r.required("resolution", r.integer("resolution", 1, 8192));
    a.channels = r.required("channels", r.integer("channels", 1, 3));
    if (a.channels == 2) r.bad("channels", "is 2; expected 1 or 3");
    if (const auto* size = r.typed<Imf::V2iAttribute>("heightfield_size", "v2i")) {
        a.heightfield_rows = size->value().x;
        a.heightfield_cols = size->value().y;
        if (a.heightfield_rows < 1 || a.heightfield_cols < 1 || a.heightfield_rows > k_max_exr_side ||
            a.heightfield_cols > k_max_exr_side)
            r.bad("heightfield_size", "is " + std::to_string(a.heightfield_rows) + "x" +
                                          std::to_string(a.heightfield_cols) + "; expected 1 to 16384 per side");
        a.texel_um = r.required("heightfield_texel_um",
                                r.number("heightfield_texel_um", k_min_texel_um, k_max_texel_um));
        a.vscale = r.required("heightfield_vscale",
                              r.number("heightfield_vscale", k_min_vscale, k_max_vscale, true, true));
    }
    a.heightfield_file = r.string("heightfield_file").value_or("");
    a.unit = r.required("unit", r.string("unit"));
    a.made_by = r.string("made_by").value_or("");
    a.version = r.required("version", r.string("version"));
    file.attributes = std::move(a);
    return file;
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
    if (!source.has_channel("Y")) fail_file(path, "has no R, G, B channels (nor Y); expected an RGB image");
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
        pixels[k] = static_cast<std::uint8_t>(std::lround(detail::srgb_encode(x) * 255.0));
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
    // Checked after registering and again before the rename, while still registered: either
    // remove_temporary_files() waits for this write, or this write sees it and cleans up.
    if (g_removing.load()) fail_file(path, "not written: the process is being stopped");
    try {
        write(tmp);
    } catch (const std::exception& e) {
        remove_quietly(tmp);
        fail_file(path, std::string("cannot write file (") + e.what() + ")");
    } catch (...) {
        remove_quietly(tmp);
        fail_file(path, "cannot write file (unknown error)");
    }
    if (g_removing.load()) {
        remove_quietly(tmp);
        fail_file(path, "not written: the process is being stopped");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int err = errno;
        remove_quietly(tmp);
        fail_file(path, std::string("cannot move the finished file into place (") + std::strerror(err) + ")");
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
    // Another thread may be writing while this one handles a signal; unlinking its temporary
    // now would not stop it from creating the file afterwards (the process dies only when the
    // handler returns). So this thread's own temporaries go at once (its write never resumes),
    // and the others' writers, seeing g_removing, remove theirs and release the slot; after
    // kWaitMs (a writer blocked on this thread, say) the rest are unlinked regardless.
    g_removing.store(true);
    constexpr int kWaitMs = 5000;
    const long self = this_thread_id();
    for (int waited = 0;; ++waited) {
        bool others = false;
        for (TemporarySlot& slot : g_temporary_slots) {
            if (slot.state.load() != 2) continue;
            if (slot.owner.load() == self || waited >= kWaitMs)
                ::unlink(slot.name);
            else
                others = true;
        }
        if (!others) return;
        const struct timespec millisecond = {0, 1000000};
        ::nanosleep(&millisecond, nullptr);
    }
}

void check_readable_file(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return;  // absent: the reader says so
    if (S_ISREG(st.st_mode)) return;
    fail_file(path, std::string("is ") + file_kind(st.st_mode) + ", not a regular file; expected a regular file to read");
}

void check_writable(const std::string& path) {
    refuse_non_regular(path);
    const std::string tmp = temporary_name(path);
    const TemporaryRegistration registration(tmp);
    std::FILE* file = std::fopen(tmp.c_str(), "wb");
    if (file == nullptr) {
        const int err = errno;
        fail_file(path, std::string("cannot create a file here (") + std::strerror(err) + ")");
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

namespace detail {

int exr_threads() {
    static std::mutex mutex;
    static int pool = 0;
    const int threads = std::max(1, thread_count());
    std::lock_guard<std::mutex> lock(mutex);
    if (pool != threads) {
        Imf::setGlobalThreadCount(threads);
        pool = threads;
    }
    return threads;
}

}  // namespace detail

namespace detail {

double exr_expansion_limit(int compression) {
    switch (static_cast<Imf::Compression>(compression)) {
        case Imf::NO_COMPRESSION: return 1.0;
        case Imf::RLE_COMPRESSION: return 64.0;
        case Imf::ZIPS_COMPRESSION:
        case Imf::ZIP_COMPRESSION: return 1032.0;
        case Imf::PXR24_COMPRESSION: return 1376.0;
        case Imf::B44_COMPRESSION:
        case Imf::B44A_COMPRESSION: return 11.0;
        default: return 0.0;
    }
}

ExrSource::ExrSource(const std::string& path) : m_path(path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) fail_file(path, "file does not exist");
    if (fs::is_directory(path, ec)) fail_file(path, "is a directory; expected an OpenEXR file");
    check_readable_file(path);
    // isOpenExrFile checks the magic number, giving a clearer message than InputFile.
    if (!Imf::isOpenExrFile(path.c_str())) fail_file(path, "not an OpenEXR file (missing magic number or unreadable)");
    check_attribute_sizes(path);  // first: opening the file is what allocates
    refuse_multi_part(path);
    try {
        m_file = std::make_unique<Imf::InputFile>(path.c_str(), detail::exr_threads());
    } catch (const std::exception& e) {
        fail_file(path, std::string("cannot read OpenEXR header (") + e.what() + ")");
    }
    const Imath::Box2i dw = m_file->header().dataWindow();
    const long long width = static_cast<long long>(dw.max.x) - dw.min.x + 1;
    const long long height = static_cast<long long>(dw.max.y) - dw.min.y + 1;
    if (width < 1 || height < 1 || width > std::numeric_limits<int>::max() ||
        height > std::numeric_limits<int>::max())
        fail_file(path, "data window " + std::to_string(width) + "x" + std::to_string(height) +
                       " is invalid; expected a non-empty image");
    // Before any pixel is allocated: a small file may declare a huge image.
    if (width * height > k_max_exr_pixels)
        fail_file(path, "declares a " + std::to_string(width) + "x" + std::to_string(height) + " image (" +
                       std::to_string(width * height) + " pixels); the limit is " + std::to_string(k_max_exr_pixels) +
                       " pixels (16384x16384)");
    // ... and no more pixel data than the file can hold: each stored byte expands to at most
    // exr_expansion_limit bytes, so a truncated or forged file that declares more is refused
    // here instead of allocating its declared size (a 3 MB table asked for 6.3 GB).
    const double limit = exr_expansion_limit(int(m_file->header().compression()));
    const std::uintmax_t file_size = fs::file_size(path, ec);
    if (limit > 0.0 && !ec) {
        double declared = 0.0;
        for (auto c = m_file->header().channels().begin(); c != m_file->header().channels().end(); ++c) {
            const Imf::Channel& channel = c.channel();
            const double bytes = channel.type == Imf::HALF ? 2.0 : 4.0;
            const double xs = std::max(channel.xSampling, 1), ys = std::max(channel.ySampling, 1);
            declared += bytes * std::floor(double(width) / xs) * std::floor(double(height) / ys);
        }
        if (declared > limit * double(file_size))
            fail_file(path, "declares a " + std::to_string(width) + "x" + std::to_string(height) + " image of " +
                           format_shortest(declared) + " bytes, more than its " + std::to_string(file_size) +
                           " bytes can hold (at most " + format_shortest(limit) +
                           " times their size with its compression); expected an OpenEXR file that is not "
                           "truncated or corrupt");
    }
    m_rows = static_cast<int>(height);
    m_cols = static_cast<int>(width);
}

bool ExrSource::has_channel(const char* name) const {
    return m_file->header().channels().findChannel(name) != nullptr;
}

void ExrSource::read(const std::vector<std::string>& channels, std::vector<float>& data) const {
    const std::size_t stride = channels.size();
    const std::size_t count = static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols) * stride;
    try {
        data.assign(count, 0.0f);
    } catch (const std::bad_alloc&) {
        throw OutOfMemory("out of memory allocating the " + std::to_string(m_rows) + "x" + std::to_string(m_cols) +
                          " pixels of " + m_path + " (" + format_shortest(4.0 * double(count)) + " bytes)");
    }
    read_rows(channels, 0, m_rows - 1, data.data());
}

void ExrSource::read_rows(const char* channel, int first_row, int last_row, float* out) const {
    read_rows(std::vector<std::string>{channel}, first_row, last_row, out);
}

void ExrSource::read_rows(const std::vector<std::string>& channels, int first_row, int last_row, float* out) const {
    const Imath::Box2i dw = m_file->header().dataWindow();
    const Imath::Box2i rows(Imath::V2i(dw.min.x, dw.min.y + first_row), Imath::V2i(dw.max.x, dw.min.y + last_row));
    const std::size_t stride = channels.size();
    try {
        Imf::FrameBuffer frame;
        for (std::size_t c = 0; c < stride; ++c)
            frame.insert(channels[c], Imf::Slice::Make(Imf::FLOAT, out + c, rows, stride * sizeof(float),
                                                       stride * sizeof(float) * static_cast<std::size_t>(m_cols)));
        m_file->setFrameBuffer(frame);
        m_file->readPixels(rows.min.y, rows.max.y);
    } catch (const std::exception& e) {
        // A truncated file usually opens fine and only fails here.
        fail_file(m_path, std::string("cannot read OpenEXR pixels, file truncated or corrupt (") + e.what() + ")");
    }
}

}  // namespace detail

void check_output_format(const std::string& option, const std::string& path,
                         const std::vector<std::string>& extensions) {
    if (path.empty()) return;
    // A path that exists and is not a regular file (a FIFO, a device) is the writer's to refuse,
    // with its own message; its name says nothing of a format.
    std::error_code ec;
    const auto status = std::filesystem::symlink_status(path, ec);
    if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) return;
    const auto lower = [](std::string s) {
        std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
        return s;
    };
    const std::string name = lower(std::filesystem::path(path).filename().string());
    std::string known;
    for (const std::string& e : extensions) {
        if (name.size() > e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) return;
        known += (known.empty() ? "" : ", ") + e;
    }
    throw std::invalid_argument(option + " " + path + ": the name's extension is not a format this output writes; " +
                                "expected a name ending in " + known);
}

}  // namespace wavebrdf
