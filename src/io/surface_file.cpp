// Measured surfaces: recognising the format, NumPy and text matrices, heightfield EXRs, the
// conversions to and from the model's Heightfield, and the writers' dispatch.
#include "wavebrdf/surface_file.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "io/surface_formats.h"
#include "wavebrdf/io.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace surface_io {

std::size_t sample_size(Sample type) {
    switch (type) {
        case Sample::i8:
        case Sample::u8: return 1;
        case Sample::i16:
        case Sample::u16: return 2;
        case Sample::i32:
        case Sample::u32:
        case Sample::f32: return 4;
        case Sample::i64:
        case Sample::f64: return 8;
    }
    return 1;
}

namespace {
template <typename T>
T load(const char* p, bool big_endian) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, p, sizeof(T));
    if (big_endian)
        for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
}
}  // namespace

double sample_value(const char* p, Sample type, bool big_endian) {
    switch (type) {
        case Sample::i8: return double(static_cast<std::int8_t>(*p));
        case Sample::u8: return double(static_cast<std::uint8_t>(*p));
        case Sample::i16: return double(load<std::int16_t>(p, big_endian));
        case Sample::u16: return double(load<std::uint16_t>(p, big_endian));
        case Sample::i32: return double(load<std::int32_t>(p, big_endian));
        case Sample::u32: return double(load<std::uint32_t>(p, big_endian));
        case Sample::i64: return double(load<std::int64_t>(p, big_endian));
        case Sample::f32: return double(load<float>(p, big_endian));
        case Sample::f64: return load<double>(p, big_endian);
    }
    return 0.0;
}

void check_grid(const std::string& name, long long rows, long long cols, std::size_t bytes_per_point,
                std::size_t available) {
    if (rows < 1 || cols < 1 || rows > k_max_surface_side || cols > k_max_surface_side ||
        rows * cols > k_max_surface_points)
        fail(name, "declares " + std::to_string(cols) + " x " + std::to_string(rows) +
                       " points; expected 1 to " + std::to_string(k_max_surface_side) + " per side and at most " +
                       std::to_string(k_max_surface_points) + " in all");
    if (bytes_per_point > 0) {
        const unsigned long long need =
            static_cast<unsigned long long>(rows) * static_cast<unsigned long long>(cols) * bytes_per_point;
        if (need > available)
            fail(name, "is truncated: " + std::to_string(cols) + " x " + std::to_string(rows) + " points need " +
                           std::to_string(need) + " bytes of data, the file holds " + std::to_string(available));
    }
}

double check_spacing(const std::string& name, double spacing_um, const char* what) {
    if (!std::isfinite(spacing_um) || !(spacing_um > 0.0) || spacing_um > 1e9)
        fail(name, std::string("has spacing ") + what + " = " + format_shortest(spacing_um) +
                       " um; expected a finite spacing > 0 and at most 1e9 um");
    return spacing_um;
}

// ---------------------------------------------------------------------------------------------
// NumPy .npy (numpy.lib.format, versions 1.0, 2.0, 3.0): magic, version, header length, a
// Python dict literal {'descr': ..., 'fortran_order': ..., 'shape': (...)}, then the data.

namespace {

// The text after `'key':` in a npy header dict, or fails naming the key.
std::size_t npy_value(const Bytes& b, const std::string& header, const std::string& key) {
    const std::size_t k = header.find("'" + key + "'");
    if (k == std::string::npos) fail(b.name(), "is a .npy file whose header has no '" + key + "'");
    std::size_t p = header.find(':', k);
    if (p == std::string::npos) fail(b.name(), "is a .npy file with a malformed header at '" + key + "'");
    ++p;
    while (p < header.size() && header[p] == ' ') ++p;
    return p;
}

}  // namespace

MeasuredSurface read_npy(const Bytes& b, std::optional<double> spacing_um) {
    b.need(0, 10, "the .npy preamble");
    const int major = static_cast<unsigned char>(b.data()[6]);
    std::size_t header_len = 0, start = 0;
    if (major == 1) {
        header_len = b.get<std::uint16_t>(8);
        start = 10;
    } else if (major == 2 || major == 3) {
        header_len = b.get<std::uint32_t>(8);
        start = 12;
    } else {
        fail(b.name(), "is a .npy file of format version " + std::to_string(major) + "; expected 1, 2 or 3");
    }
    if (header_len > 65536) fail(b.name(), "declares a .npy header of " + std::to_string(header_len) + " bytes; expected at most 65536");
    b.need(start, header_len, "the .npy header");
    const std::string header = b.data().substr(start, header_len);
    // descr: a quoted dtype string such as '<f8'.
    std::size_t p = npy_value(b, header, "descr");
    if (p >= header.size() || (header[p] != '\'' && header[p] != '"'))
        fail(b.name(), "is a .npy file of a structured dtype; expected a float32 or float64 array");
    const std::size_t q = header.find(header[p], p + 1);
    if (q == std::string::npos) fail(b.name(), "is a .npy file with a malformed 'descr'");
    const std::string descr = header.substr(p + 1, q - p - 1);
    Sample type;
    bool big = false;
    if (descr == "<f8" || descr == ">f8" || descr == "=f8") type = Sample::f64;
    else if (descr == "<f4" || descr == ">f4" || descr == "=f4") type = Sample::f32;
    else fail(b.name(), "is a .npy array of dtype '" + descr + "'; expected float32 or float64 ('<f4', '>f4', '<f8', '>f8')");
    big = descr[0] == '>';
    // fortran_order: True or False.
    p = npy_value(b, header, "fortran_order");
    bool fortran = false;
    if (header.compare(p, 4, "True") == 0) fortran = true;
    else if (header.compare(p, 5, "False") != 0) fail(b.name(), "is a .npy file with a malformed 'fortran_order'");
    // shape: a tuple of non-negative integers.
    p = npy_value(b, header, "shape");
    if (p >= header.size() || header[p] != '(') fail(b.name(), "is a .npy file with a malformed 'shape'");
    const std::size_t close = header.find(')', p);
    if (close == std::string::npos) fail(b.name(), "is a .npy file with a malformed 'shape'");
    std::vector<long long> shape;
    {
        const std::string tuple = header.substr(p + 1, close - p - 1);
        std::size_t i = 0;
        while (i < tuple.size()) {
            while (i < tuple.size() && (tuple[i] == ' ' || tuple[i] == ',')) ++i;
            if (i >= tuple.size()) break;
            if (!std::isdigit(static_cast<unsigned char>(tuple[i])))
                fail(b.name(), "is a .npy file with a malformed 'shape' (" + tuple + ")");
            long long v = 0;
            while (i < tuple.size() && std::isdigit(static_cast<unsigned char>(tuple[i]))) {
                v = v * 10 + (tuple[i] - '0');
                if (v > k_max_surface_points) fail(b.name(), "declares a .npy shape (" + tuple + ") beyond the bounds");
                ++i;
            }
            shape.push_back(v);
            if (shape.size() > 8) fail(b.name(), "declares a .npy array of more than 8 dimensions");
        }
    }
    if (shape.size() != 2)
        fail(b.name(), "holds a " + std::to_string(shape.size()) + "-D .npy array; expected a 2-D array of heights (rows along y)");
    if (!spacing_um) fail(b.name(), "is a .npy file, which states no spacing; give the spacing in um (--texel-um, spacing_um)");
    const double spacing = check_spacing(b.name(), *spacing_um, "given");
    const std::size_t data_start = start + header_len;
    const std::size_t size = sample_size(type);
    check_grid(b.name(), shape[0], shape[1], size, b.size() - data_start);
    MeasuredSurface s;
    s.rows = static_cast<int>(shape[0]);
    s.cols = static_cast<int>(shape[1]);
    s.dx_um = s.dy_um = spacing;
    s.format = "npy";
    s.heights_um.resize(static_cast<std::size_t>(s.rows) * static_cast<std::size_t>(s.cols));
    const char* data = b.data().data() + data_start;
    for (std::size_t r = 0; r < std::size_t(s.rows); ++r)
        for (std::size_t c = 0; c < std::size_t(s.cols); ++c) {
            const std::size_t k = fortran ? c * std::size_t(s.rows) + r : r * std::size_t(s.cols) + c;
            s.heights_um[r * std::size_t(s.cols) + c] = sample_value(data + k * size, type, big);
        }
    s.metadata.push_back({"npy_dtype", descr});
    if (fortran) s.metadata.push_back({"npy_order", "fortran"});
    return s;
}

std::string npy_bytes(const MeasuredSurface& s) {
    std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" + std::to_string(s.rows) + ", " +
                         std::to_string(s.cols) + "), }";
    // Version 1.0: the preamble and header padded with spaces to a multiple of 64, ending in '\n'.
    const std::size_t total = 10 + header.size() + 1;
    header.append((64 - total % 64) % 64, ' ');
    header += '\n';
    std::string out("\x93NUMPY\x01\x00", 8);
    const auto len = static_cast<std::uint16_t>(header.size());
    out += static_cast<char>(len & 0xff);
    out += static_cast<char>(len >> 8);
    out += header;
    const std::size_t at = out.size();
    out.resize(at + s.heights_um.size() * 8);
    for (std::size_t i = 0; i < s.heights_um.size(); ++i) {
        const double v = s.heights_um[i];
        unsigned char bytes[8];
        std::memcpy(bytes, &v, 8);
        // The file is little-endian whatever the machine.
        const std::uint16_t probe = 1;
        unsigned char first;
        std::memcpy(&first, &probe, 1);
        if (first == 0)
            for (int k = 0; k < 4; ++k) std::swap(bytes[k], bytes[7 - k]);
        std::memcpy(&out[at + i * 8], bytes, 8);
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Plain text matrices: one line per row (along y), numbers separated by blanks, commas or
// semicolons; '#' starts a comment line. Gwyddion's "ASCII data matrix" export header
// ("# Width: 12.5 µm", "# Value units: m") gives the spacing and the height unit.

namespace {

// Meters per unit for the length units a text header may name ("m", "mm", "µm"/"um", "nm", "Å").
std::optional<double> unit_in_um(std::string unit) {
    unit.erase(0, std::min(unit.size(), unit.find_first_not_of(" \t")));
    while (!unit.empty() && std::isspace(static_cast<unsigned char>(unit.back()))) unit.pop_back();
    if (unit == "m") return 1e6;
    if (unit == "mm") return 1e3;
    if (unit == "um" || unit == "\xc2\xb5m" || unit == "\xce\xbcm") return 1.0;
    if (unit == "nm") return 1e-3;
    if (unit == "pm") return 1e-6;
    if (unit == "A" || unit == "\xc3\x85" || unit == "\xe2\x84\xab") return 1e-4;
    return std::nullopt;
}

bool is_blank_line(const std::string& line) {
    return std::all_of(line.begin(), line.end(), [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; });
}

}  // namespace

bool looks_like_text(const std::string& bytes) {
    // Printable ASCII, UTF-8 (in comments) and whitespace only in the first 4 KiB, and a first
    // data line that starts with a number.
    const std::size_t n = std::min<std::size_t>(bytes.size(), 4096);
    if (n == 0) return false;
    for (std::size_t i = 0; i < n; ++i) {
        const auto c = static_cast<unsigned char>(bytes[i]);
        if (c < 0x20 && c != '\n' && c != '\r' && c != '\t') return false;
        if (c == 0x7f) return false;
    }
    std::istringstream in(bytes.substr(0, n));
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#' || is_blank_line(line)) continue;
        std::size_t i = line.find_first_not_of(" \t");
        const char c = line[i];
        return std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.' || c == 'n' ||
               c == 'N' || c == 'i' || c == 'I';
    }
    return false;
}

MeasuredSurface read_text(const Bytes& b, std::optional<double> spacing_um) {
    MeasuredSurface s;
    s.format = "text";
    double width_um = 0, height_um_extent = 0, value_scale = 1.0;
    std::vector<double>& v = s.heights_um;
    long long cols = -1, rows = 0;
    const std::string& d = b.data();
    std::size_t pos = 0;
    long long line_no = 0;
    while (pos < d.size()) {
        std::size_t end = d.find('\n', pos);
        if (end == std::string::npos) end = d.size();
        std::string line = d.substr(pos, end - pos);
        pos = end + 1;
        ++line_no;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty() || is_blank_line(line)) continue;
        if (line[0] == '#') {
            // Gwyddion's header lines: "# Width: 12.5 µm", "# Height: ...", "# Value units: m".
            const auto field = [&](const char* key) -> std::optional<std::string> {
                const std::string k = std::string("# ") + key + ":";
                if (line.compare(0, k.size(), k) != 0) return std::nullopt;
                std::string rest = line.substr(k.size());
                rest.erase(0, rest.find_first_not_of(' '));
                return rest;
            };
            if (auto w = field("Width"); w || (w = field("Height"))) {
                const bool is_width = line.compare(0, 8, "# Width:") == 0;
                char* stop = nullptr;
                const double value = std::strtod(w->c_str(), &stop);
                const auto unit = unit_in_um(stop);
                if (!unit || !std::isfinite(value) || !(value > 0))
                    fail(b.name(), "line " + std::to_string(line_no) + ": cannot read '" + line + "'; expected a length in m, mm, um or nm");
                (is_width ? width_um : height_um_extent) = value * *unit;
            } else if (auto u = field("Value units")) {
                const auto unit = unit_in_um(*u);
                if (!unit) fail(b.name(), "line " + std::to_string(line_no) + ": value units '" + *u + "' are not a length; expected m, mm, um or nm");
                value_scale = *unit;
            }
            s.metadata.push_back({"comment", line.substr(1)});
            continue;
        }
        long long count = 0;
        const char* p = line.c_str();
        while (*p) {
            while (*p == ' ' || *p == '\t' || *p == ',' || *p == ';') ++p;
            if (!*p) break;
            char* stop = nullptr;
            const double x = std::strtod(p, &stop);
            if (stop == p)
                fail(b.name(), "line " + std::to_string(line_no) + ": '" + std::string(p).substr(0, 20) +
                                   "' is not a number; expected a matrix of numbers (NaN for missing points)");
            if (static_cast<long long>(v.size()) >= k_max_surface_points)
                fail(b.name(), "holds more than " + std::to_string(k_max_surface_points) + " numbers");
            v.push_back(x);
            ++count;
            p = stop;
        }
        if (cols < 0) cols = count;
        else if (count != cols)
            fail(b.name(), "line " + std::to_string(line_no) + " has " + std::to_string(count) + " numbers, the first row " +
                               std::to_string(cols) + "; expected a rectangular matrix");
        ++rows;
    }
    if (rows == 0) fail(b.name(), "holds no numbers; expected a matrix of heights");
    check_grid(b.name(), rows, cols);
    s.rows = static_cast<int>(rows);
    s.cols = static_cast<int>(cols);
    if (width_um > 0) {
        s.dx_um = check_spacing(b.name(), width_um / double(cols), "dx");
        s.dy_um = height_um_extent > 0 ? check_spacing(b.name(), height_um_extent / double(rows), "dy") : s.dx_um;
    } else {
        if (!spacing_um)
            fail(b.name(), "is a text matrix that states no spacing; give the spacing in um (--texel-um, spacing_um)");
        s.dx_um = s.dy_um = check_spacing(b.name(), *spacing_um, "given");
    }
    if (value_scale != 1.0)
        for (double& x : v) x *= value_scale;
    return s;
}

// ---------------------------------------------------------------------------------------------
// MD5 (RFC 1321).

std::string md5_hex(const std::string& data) {
    static const std::uint32_t k[64] = {
        0xd76aa478, 0xe8c7b756, 0x242070db, 0xc1bdceee, 0xf57c0faf, 0x4787c62a, 0xa8304613, 0xfd469501,
        0x698098d8, 0x8b44f7af, 0xffff5bb1, 0x895cd7be, 0x6b901122, 0xfd987193, 0xa679438e, 0x49b40821,
        0xf61e2562, 0xc040b340, 0x265e5a51, 0xe9b6c7aa, 0xd62f105d, 0x02441453, 0xd8a1e681, 0xe7d3fbc8,
        0x21e1cde6, 0xc33707d6, 0xf4d50d87, 0x455a14ed, 0xa9e3e905, 0xfcefa3f8, 0x676f02d9, 0x8d2a4c8a,
        0xfffa3942, 0x8771f681, 0x6d9d6122, 0xfde5380c, 0xa4beea44, 0x4bdecfa9, 0xf6bb4b60, 0xbebfbc70,
        0x289b7ec6, 0xeaa127fa, 0xd4ef3085, 0x04881d05, 0xd9d4d039, 0xe6db99e5, 0x1fa27cf8, 0xc4ac5665,
        0xf4292244, 0x432aff97, 0xab9423a7, 0xfc93a039, 0x655b59c3, 0x8f0ccc92, 0xffeff47d, 0x85845dd1,
        0x6fa87e4f, 0xfe2ce6e0, 0xa3014314, 0x4e0811a1, 0xf7537e82, 0xbd3af235, 0x2ad7d2bb, 0xeb86d391};
    static const int r[64] = {7, 12, 17, 22, 7, 12, 17, 22, 7, 12, 17, 22, 7, 12, 17, 22, 5, 9,  14, 20, 5, 9,
                              14, 20, 5, 9,  14, 20, 5, 9,  14, 20, 4, 11, 16, 23, 4, 11, 16, 23, 4, 11, 16, 23,
                              4, 11, 16, 23, 6, 10, 15, 21, 6, 10, 15, 21, 6, 10, 15, 21, 6, 10, 15, 21};
    std::uint32_t h[4] = {0x67452301, 0xefcdab89, 0x98badcfe, 0x10325476};
    const std::uint64_t bits = static_cast<std::uint64_t>(data.size()) * 8;
    const auto block = [&](const unsigned char* p) {
        std::uint32_t w[16];
        for (int i = 0; i < 16; ++i)
            w[i] = std::uint32_t(p[4 * i]) | std::uint32_t(p[4 * i + 1]) << 8 | std::uint32_t(p[4 * i + 2]) << 16 |
                   std::uint32_t(p[4 * i + 3]) << 24;
        std::uint32_t a = h[0], b = h[1], c = h[2], d = h[3];
        for (int i = 0; i < 64; ++i) {
            std::uint32_t f;
            int g;
            if (i < 16) f = (b & c) | (~b & d), g = i;
            else if (i < 32) f = (d & b) | (~d & c), g = (5 * i + 1) % 16;
            else if (i < 48) f = b ^ c ^ d, g = (3 * i + 5) % 16;
            else f = c ^ (b | ~d), g = (7 * i) % 16;
            const std::uint32_t t = d;
            d = c;
            c = b;
            const std::uint32_t x = a + f + k[i] + w[g];
            b = b + ((x << r[i]) | (x >> (32 - r[i])));
            a = t;
        }
        h[0] += a, h[1] += b, h[2] += c, h[3] += d;
    };
    const auto* p = reinterpret_cast<const unsigned char*>(data.data());
    std::size_t n = data.size();
    for (; n >= 64; n -= 64, p += 64) block(p);
    unsigned char tail[128] = {};
    std::memcpy(tail, p, n);
    tail[n] = 0x80;
    const std::size_t len = n < 56 ? 64 : 128;
    for (int i = 0; i < 8; ++i) tail[len - 8 + std::size_t(i)] = static_cast<unsigned char>(bits >> (8 * i));
    block(tail);
    if (len == 128) block(tail + 64);
    static const char* hex = "0123456789abcdef";
    std::string out;
    for (std::uint32_t v : h)
        for (int i = 0; i < 4; ++i) {
            const unsigned byte = (v >> (8 * i)) & 0xff;
            out += hex[byte >> 4];
            out += hex[byte & 15];
        }
    return out;
}

}  // namespace surface_io

using namespace surface_io;

// ---------------------------------------------------------------------------------------------

std::size_t MeasuredSurface::invalid_count() const {
    return static_cast<std::size_t>(
        std::count_if(heights_um.begin(), heights_um.end(), [](double h) { return std::isnan(h); }));
}

std::string MeasuredSurface::meta(const std::string& key) const {
    for (const auto& [k, v] : metadata)
        if (k == key) return v;
    return "";
}

namespace {

const char k_exr_magic[4] = {0x76, 0x2f, 0x31, 0x01};

bool starts_with(const std::string& bytes, const char* prefix, std::size_t n) {
    return bytes.size() >= n && std::memcmp(bytes.data(), prefix, n) == 0;
}

// The whole file, refused over k_max_surface_file_bytes.
std::string read_whole(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) fail(path, "does not exist");
    if (std::filesystem::is_directory(path, ec)) fail(path, "is a directory; expected a surface file");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, std::string("cannot be opened: ") + std::strerror(errno));
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0) fail(path, "cannot be read (not a seekable file)");
    if (size > k_max_surface_file_bytes)
        fail(path, "is " + std::to_string(size) + " bytes; expected at most " + std::to_string(k_max_surface_file_bytes));
    in.seekg(0);
    std::string bytes(static_cast<std::size_t>(size), '\0');
    if (size > 0 && !in.read(&bytes[0], size)) fail(path, "cannot be read");
    return bytes;
}

void finish(MeasuredSurface& s, const std::string& name) {
    check_grid(name, s.rows, s.cols);
    check_spacing(name, s.dx_um, "dx");
    check_spacing(name, s.dy_um, "dy");
    if (s.heights_um.size() != std::size_t(s.rows) * std::size_t(s.cols))
        fail(name, "holds " + std::to_string(s.heights_um.size()) + " heights for " + std::to_string(s.cols) + " x " +
                       std::to_string(s.rows) + " points");
    // Infinities are no measurement either.
    for (double& h : s.heights_um)
        if (!std::isfinite(h)) h = std::numeric_limits<double>::quiet_NaN();
}

MeasuredSurface read_exr_surface(const std::string& path) {
    HeightfieldFile file = read_heightfield_exr_file(path);
    MeasuredSurface s = from_heightfield(file.heightfield, "exr");
    if (!file.attributes.made_by.empty()) s.metadata.push_back({"made_by", file.attributes.made_by});
    return s;
}

std::atomic<unsigned> g_bytes_temp_counter{0};

}  // namespace

std::string detect_surface_format(const std::string& bytes) {
    if (starts_with(bytes, k_exr_magic, 4)) return "exr";
    if (starts_with(bytes, "\x93NUMPY", 6)) return "npy";
    if (starts_with(bytes, "PK\x03\x04", 4)) return "x3p";
    if (starts_with(bytes, "\x89HDF\r\n\x1a\n", 8)) return "datx";
    // SDF: "aISO-1.0" / "bISO-1.0", and the BCR predecessors ("aBCR-1.0"; Gwyddion writes "aBCR-0.0").
    if (bytes.size() >= 8 && (bytes[0] == 'a' || bytes[0] == 'b') &&
        (bytes.compare(1, 4, "ISO-") == 0 || bytes.compare(1, 4, "BCR-") == 0) &&
        std::isdigit(static_cast<unsigned char>(bytes[5])) && bytes[6] == '.' &&
        std::isdigit(static_cast<unsigned char>(bytes[7])))
        return "sdf";
    if (starts_with(bytes, "AliconaImaging", 14)) return "al3d";
    if (starts_with(bytes, "DIGITAL SURF", 12) || starts_with(bytes, "DSCOMPRESSED", 12)) return "sur";
    if (bytes.size() >= 4) {
        const auto b = [&](int i) { return static_cast<unsigned char>(bytes[std::size_t(i)]); };
        const std::uint32_t magic = std::uint32_t(b(0)) << 24 | std::uint32_t(b(1)) << 16 | std::uint32_t(b(2)) << 8 | b(3);
        if (magic == 0x881B036Fu || magic == 0x881B0370u || magic == 0x881B0371u) return "metropro";
    }
    if (looks_like_plu(bytes)) return "plu";
    if (looks_like_text(bytes)) return "text";
    return "";
}

bool is_exr_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[4] = {};
    return in.read(magic, 4) && std::memcmp(magic, k_exr_magic, 4) == 0;
}

MeasuredSurface read_surface_bytes(const std::string& data, const std::string& name, std::optional<double> spacing_um) {
    return read_surface_as(data, detect_surface_format(data), name, spacing_um);
}

MeasuredSurface read_surface_as(const std::string& data, const std::string& format, const std::string& name,
                                std::optional<double> spacing_um) {
    const Bytes bytes(data, name);
    MeasuredSurface s;
    if (format == "npy") s = read_npy(bytes, spacing_um);
    else if (format == "text") s = read_text(bytes, spacing_um);
    else if (format == "x3p") s = read_x3p(bytes);
    else if (format == "sdf") s = read_sdf(bytes);
    else if (format == "datx") s = read_datx(bytes);
    else if (format == "metropro") s = read_metropro(bytes);
    else if (format == "sur") s = read_sur(bytes);
    else if (format == "plu") s = read_plu(bytes);
    else if (format == "al3d") s = read_al3d(bytes);
    else if (format == "exr") {
        // OpenEXR reads files: through a private temporary one.
        const std::string tmp = (std::filesystem::temp_directory_path() /
                                 ("wavebrdf-surface-" + std::to_string(::getpid()) + "-" +
                                  std::to_string(g_bytes_temp_counter++) + ".exr"))
                                    .string();
        {
            std::ofstream out(tmp, std::ios::binary);
            out.write(data.data(), static_cast<std::streamsize>(data.size()));
            if (!out) fail(name, "cannot be staged in " + tmp);
        }
        try {
            s = read_exr_surface(tmp);
        } catch (const std::exception& e) {
            std::remove(tmp.c_str());
            std::string what = e.what();
            if (what.compare(0, tmp.size(), tmp) == 0) what = name + what.substr(tmp.size());
            throw std::runtime_error(what);
        }
        std::remove(tmp.c_str());
    } else if (!format.empty())
        throw std::invalid_argument("surface format '" + format +
                                    "' is unknown; expected x3p, sdf, datx, metropro, sur, plu, al3d, npy, text or exr");
    else
        fail(name, "is of no known surface format; expected x3p, sdf, datx, MetroPro .dat, sur, plu, al3d, npy, "
                   "a text matrix or a heightfield EXR");
    finish(s, name);
    return s;
}

MeasuredSurface read_surface(const std::string& path, std::optional<double> spacing_um) {
    if (spacing_um && (!std::isfinite(*spacing_um) || !(*spacing_um > 0)))
        throw std::domain_error("spacing " + format_shortest(*spacing_um) + " um is invalid; expected finite and > 0");
    if (is_exr_file(path)) {
        MeasuredSurface s = read_exr_surface(path);
        finish(s, path);
        return s;
    }
    return read_surface_bytes(read_whole(path), path, spacing_um);
}

// ---------------------------------------------------------------------------------------------

Heightfield to_heightfield(const MeasuredSurface& s, const std::string& name, std::optional<double> texel_um,
                           std::optional<double> vscale) {
    const std::string convert = "; run `wavebrdf convert " + (name.empty() ? std::string("IN") : name) +
                                " OUT.exr --resample-um W --fill METHOD` first";
    if (!(s.dx_um > 0) || !(s.dy_um > 0) || std::abs(s.dx_um - s.dy_um) > 1e-6 * std::max(s.dx_um, s.dy_um))
        throw std::invalid_argument(name + ": spacing dx " + format_shortest(s.dx_um) + " um, dy " +
                                    format_shortest(s.dy_um) + " um is not square; the model needs square texels" +
                                    convert);
    if (const std::size_t bad = s.invalid_count(); bad > 0)
        throw std::invalid_argument(name + ": " + std::to_string(bad) + " of " + std::to_string(s.heights_um.size()) +
                                    " points are not measured (NaN); the model needs every height" + convert);
    const double w = texel_um.value_or(s.dx_um);
    const double v = vscale.value_or(1.0);
    const double to_texels = v != 0.0 ? 1.0 / (v * w) : 0.0;
    // Transposed: the heightfield's row index runs along x, the surface's columns do.
    const std::size_t rows = std::size_t(s.rows), cols = std::size_t(s.cols);
    std::vector<double> values(rows * cols);
    for (std::size_t r = 0; r < rows; ++r)
        for (std::size_t c = 0; c < cols; ++c) values[c * rows + r] = s.heights_um[r * cols + c] * to_texels;
    try {
        return Heightfield(s.cols, s.rows, std::move(values), w, v);
    } catch (const std::exception& e) {
        throw std::domain_error(name + ": " + e.what());
    }
}

MeasuredSurface from_heightfield(const Heightfield& hf, const std::string& format) {
    MeasuredSurface s;
    s.rows = hf.cols();
    s.cols = hf.rows();
    s.dx_um = s.dy_um = hf.texel_um();
    s.format = format;
    const double scale = hf.vscale() * hf.texel_um();
    const std::size_t rows = std::size_t(s.rows), cols = std::size_t(s.cols);
    s.heights_um.resize(rows * cols);
    const std::vector<double>& v = hf.values();
    for (std::size_t r = 0; r < rows; ++r)
        for (std::size_t c = 0; c < cols; ++c) s.heights_um[r * cols + c] = v[c * rows + r] * scale;
    s.metadata.push_back({"texel_um", format_shortest(hf.texel_um())});
    s.metadata.push_back({"vscale", format_shortest(hf.vscale())});
    return s;
}


namespace surface_io {

namespace {
// The first bytes of a file, enough to recognise every format (PLU's header is the longest).
std::string file_head(const std::string& path, std::size_t count) {
    std::ifstream in(path, std::ios::binary);
    std::string head(count, '\0');
    in.read(&head[0], static_cast<std::streamsize>(count));
    head.resize(static_cast<std::size_t>(std::max<std::streamsize>(in.gcount(), 0)));
    return head;
}

std::string lower_extension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}
}  // namespace

bool is_measured_surface_file(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) return false;
    const std::string head = file_head(path, 8192);
    const std::string format = detect_surface_format(head);
    if (format == "exr") return false;
    if (format != "" && format != "text") return true;
    return lower_extension(path) != ".exr";
}

HeightfieldAttributes measured_attributes(const std::string& path) {
    HeightfieldAttributes a;
    const std::string format = detect_surface_format(file_head(path, 8192));
    MeasuredSurface s;
    if (format == "npy" || format == "text") {
        // Their spacing is the caller's (a text file may state one; read it then).
        a.units = "a measured surface (" + format + ", heights in um)";
        if (measured_surface_needs_spacing(path)) return a;
        s = read_surface(path);
    } else {
        s = read_surface(path);
    }
    if (std::abs(s.dx_um - s.dy_um) <= 1e-6 * std::max(s.dx_um, s.dy_um) &&
        s.dx_um >= k_min_texel_um && s.dx_um <= k_max_texel_um)
        a.texel_um = s.dx_um;
    a.units = "measured surface (" + s.format + "): heights in um";
    a.made_by = s.meta("instrument");
    return a;
}

bool measured_surface_needs_spacing(const std::string& path) {
    if (!is_measured_surface_file(path)) return false;
    const std::string format = detect_surface_format(file_head(path, 8192));
    if (format == "npy") return true;
    if (format != "text") return false;
    // A text file may state its spacing (Gwyddion's header).
    try {
        read_surface(path);
        return false;
    } catch (const std::runtime_error&) {
        return true;
    }
}

HeightfieldFile read_measured_heightfield(const std::string& path, std::optional<double> texel_um,
                                          std::optional<double> vscale) {
    MeasuredSurface s = read_surface(path, texel_um);
    HeightfieldAttributes a;
    if (s.format != "npy" && s.format != "text") a.texel_um = s.dx_um;
    a.units = "measured surface (" + s.format + "): heights in um";
    a.made_by = s.meta("instrument");
    Heightfield hf = to_heightfield(s, path, texel_um, vscale);
    return {std::move(hf), std::move(a)};
}

}  // namespace surface_io

void write_surface(const std::string& path, const MeasuredSurface& s) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext != ".x3p" && ext != ".sdf" && ext != ".npy" && ext != ".exr")
        throw std::invalid_argument(path + ": cannot write surfaces as '" + ext +
                                    "'; expected the extension .x3p, .sdf, .npy or .exr");
    if (s.rows < 1 || s.cols < 1 || s.rows > k_max_surface_side || s.cols > k_max_surface_side ||
        s.heights_um.size() != std::size_t(s.rows) * std::size_t(s.cols))
        throw std::invalid_argument(path + ": the surface is " + std::to_string(s.cols) + " x " +
                                    std::to_string(s.rows) + " points with " + std::to_string(s.heights_um.size()) +
                                    " heights; expected matching, non-empty sizes");
    if (!std::isfinite(s.dx_um) || !(s.dx_um > 0) || !std::isfinite(s.dy_um) || !(s.dy_um > 0))
        throw std::invalid_argument(path + ": spacing dx " + format_shortest(s.dx_um) + " um, dy " +
                                    format_shortest(s.dy_um) + " um; expected finite and > 0");
    if (ext == ".exr") {
        const Heightfield hf = to_heightfield(s, path);
        std::string made_by = s.meta("made_by");
        if (made_by.empty()) made_by = "measured surface (" + s.format + ")";
        write_heightfield_exr(path, hf, made_by);
        return;
    }
    const std::string bytes = ext == ".npy" ? npy_bytes(s) : ext == ".x3p" ? x3p_bytes(s) : sdf_bytes(s);
    write_file_atomically(path, [&](const std::string& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        out.close();
        if (!out) throw std::runtime_error("cannot write " + tmp);
    });
}

}  // namespace wavebrdf
