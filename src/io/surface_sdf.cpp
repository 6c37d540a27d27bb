// ISO 25178-71 surface data files (SDF), ASCII ("aISO-1.0") and binary ("bISO-1.0"), and their
// predecessor of the same layout from the BCR project ("aBCR-1.0", "bBCR-1.0"). A header of
// ManufacID, dates, NumPoints (along x), NumProfiles (along y), Xscale, Yscale, Zscale (m per
// unit), Zresolution, Compression, DataType, CheckType; then NumProfiles profiles of NumPoints
// values, x fastest. Binary: an 81-byte little-endian header, DataType 0–7 = uint8, uint16,
// uint32, float32, int8, int16, int32, float64. ASCII: "Key = value" lines ended by a line "*",
// the values in text ("BAD" for a point not measured), then "*" and an optional trailer.
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <limits>
#include <map>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::surface_io {

namespace {

constexpr std::size_t k_binary_header = 81;

Sample sdf_type(const std::string& name, int data_type) {
    switch (data_type) {
        case 0: return Sample::u8;
        case 1: return Sample::u16;
        case 2: return Sample::u32;
        case 3: return Sample::f32;
        case 4: return Sample::i8;
        case 5: return Sample::i16;
        case 6: return Sample::i32;
        case 7: return Sample::f64;
        default:
            fail(name, "has SDF DataType " + std::to_string(data_type) + "; expected 0 to 7");
    }
}

// The value integer types reserve for a point not measured (as Gwyddion reads them).
std::optional<double> invalid_marker(int data_type) {
    switch (data_type) {
        case 1: return 65535.0;
        case 2: return 4294967295.0;
        case 5: return -32768.0;
        case 6: return -2147483648.0;
        default: return std::nullopt;
    }
}

struct Header {
    std::string manufacturer, created, modified;
    long long points = 0, profiles = 0;
    double xscale = 0, yscale = 0, zscale = 0, zresolution = 0;
    int compression = 0, data_type = 7, check_type = 0;
};

MeasuredSurface surface_of(const Bytes& b, const Header& h) {
    if (h.compression != 0)
        fail(b.name(), "is a compressed SDF file (Compression " + std::to_string(h.compression) + "); expected 0");
    check_grid(b.name(), h.profiles, h.points);
    if (!std::isfinite(h.zscale) || h.zscale == 0.0)
        fail(b.name(), "has Zscale " + format_shortest(h.zscale) + "; expected a finite, non-zero scale");
    MeasuredSurface s;
    s.rows = int(h.profiles);
    s.cols = int(h.points);
    s.dx_um = check_spacing(b.name(), h.xscale * 1e6, "Xscale");
    s.dy_um = check_spacing(b.name(), h.yscale * 1e6, "Yscale");
    s.format = "sdf";
    if (!h.manufacturer.empty()) s.metadata.push_back({"instrument", h.manufacturer});
    if (!h.created.empty()) s.metadata.push_back({"date", h.created});
    if (!h.modified.empty()) s.metadata.push_back({"modified", h.modified});
    return s;
}

std::string trimmed(const std::string& s) {
    const std::size_t a = s.find_first_not_of(" \t\r\n");
    if (a == std::string::npos) return "";
    return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
}

MeasuredSurface read_binary(const Bytes& b) {
    b.need(0, k_binary_header, "the SDF header");
    Header h;
    h.manufacturer = b.text(8, 10);
    h.created = b.text(18, 12);
    h.modified = b.text(30, 12);
    h.points = b.get<std::uint16_t>(42);
    h.profiles = b.get<std::uint16_t>(44);
    h.xscale = b.get<double>(46);
    h.yscale = b.get<double>(54);
    h.zscale = b.get<double>(62);
    h.zresolution = b.get<double>(70);
    h.compression = static_cast<unsigned char>(b.data()[78]);
    h.data_type = static_cast<unsigned char>(b.data()[79]);
    h.check_type = static_cast<unsigned char>(b.data()[80]);
    const Sample type = sdf_type(b.name(), h.data_type);
    MeasuredSurface s = surface_of(b, h);
    const std::size_t size = sample_size(type);
    check_grid(b.name(), h.profiles, h.points, size, b.size() - k_binary_header);
    const std::size_t n = std::size_t(s.rows) * std::size_t(s.cols);
    const std::optional<double> bad = invalid_marker(h.data_type);
    s.heights_um.resize(n);
    const char* data = b.data().data() + k_binary_header;
    for (std::size_t i = 0; i < n; ++i) {
        const double raw = sample_value(data + i * size, type, false);
        s.heights_um[i] = bad && raw == *bad ? std::numeric_limits<double>::quiet_NaN() : raw * h.zscale * 1e6;
    }
    return s;
}

MeasuredSurface read_ascii(const Bytes& b) {
    const std::string& d = b.data();
    // The header: "Key = value" lines after the magic, up to a line holding only "*".
    std::size_t pos = d.find('\n');
    if (pos == std::string::npos) fail(b.name(), "is an SDF file with no header lines");
    ++pos;
    std::map<std::string, std::string> fields;
    bool ended = false;
    while (pos < d.size()) {
        std::size_t end = d.find('\n', pos);
        if (end == std::string::npos) end = d.size();
        const std::string line = trimmed(d.substr(pos, end - pos));
        pos = end + 1;
        if (line == "*") {
            ended = true;
            break;
        }
        if (line.empty()) continue;
        const std::size_t eq = line.find('=');
        if (eq == std::string::npos) fail(b.name(), "has the SDF header line '" + line.substr(0, 40) + "'; expected Key = value");
        if (fields.size() > 64) fail(b.name(), "has more than 64 SDF header fields");
        fields[trimmed(line.substr(0, eq))] = trimmed(line.substr(eq + 1));
    }
    if (!ended) fail(b.name(), "is an SDF file whose header does not end with a line '*'");
    const auto number = [&](const char* key, std::optional<double> fallback) {
        const auto it = fields.find(key);
        if (it == fields.end()) {
            if (fallback) return *fallback;
            fail(b.name(), std::string("is an SDF file without ") + key);
        }
        char* stop = nullptr;
        const double v = std::strtod(it->second.c_str(), &stop);
        if (stop == it->second.c_str() || !std::isfinite(v))
            fail(b.name(), std::string("has SDF ") + key + " '" + it->second + "'; expected a number");
        return v;
    };
    const auto count = [&](const char* key) {
        const double v = number(key, std::nullopt);
        if (v != std::floor(v) || v < 1 || v > double(k_max_surface_side))
            fail(b.name(), std::string("has SDF ") + key + " " + format_shortest(v) + "; expected 1 to " +
                               std::to_string(k_max_surface_side));
        return static_cast<long long>(v);
    };
    Header h;
    h.manufacturer = fields["ManufacID"];
    h.created = fields["CreateDate"];
    h.modified = fields["ModDate"];
    h.points = count("NumPoints");
    h.profiles = count("NumProfiles");
    h.xscale = number("Xscale", std::nullopt);
    h.yscale = number("Yscale", std::nullopt);
    h.zscale = number("Zscale", std::nullopt);
    // Small codes: bounded before the conversion to int.
    const auto code = [&](const char* key, double fallback) {
        const double v = number(key, fallback);
        if (!(v >= 0 && v <= 255) || v != std::floor(v))
            fail(b.name(), std::string("has SDF ") + key + " " + format_shortest(v) + "; expected a code 0 to 255");
        return int(v);
    };
    h.compression = code("Compression", 0.0);
    h.data_type = code("DataType", 7.0);
    sdf_type(b.name(), h.data_type);
    MeasuredSurface s = surface_of(b, h);
    const std::size_t n = std::size_t(s.rows) * std::size_t(s.cols);
    // At least two bytes per value ("0 "): a file too short for its declared points fails here,
    // before anything is allocated.
    if (n > (d.size() - std::min(pos, d.size())) / 2 + 1)
        fail(b.name(), "is truncated: " + std::to_string(h.points) + " x " + std::to_string(h.profiles) +
                           " points cannot fit in its " + std::to_string(d.size() - pos) + " bytes of data");
    const std::optional<double> bad = invalid_marker(h.data_type);
    s.heights_um.reserve(n);
    const char* p = d.c_str() + pos;
    const char* end = d.c_str() + d.size();
    while (s.heights_um.size() < n) {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n' || *p == ',')) ++p;
        if (p >= end || *p == '*')
            fail(b.name(), "is truncated: its data ends after " + std::to_string(s.heights_um.size()) + " of " +
                               std::to_string(n) + " values");
        if (end - p >= 3 && std::strncmp(p, "BAD", 3) == 0) {
            s.heights_um.push_back(std::numeric_limits<double>::quiet_NaN());
            p += 3;
            continue;
        }
        char* stop = nullptr;
        const double raw = std::strtod(p, &stop);
        if (stop == p)
            fail(b.name(), "has '" + std::string(p, std::size_t(std::min<std::ptrdiff_t>(end - p, 16))) +
                               "' among its SDF values; expected a number or BAD");
        p = stop;
        s.heights_um.push_back(bad && raw == *bad ? std::numeric_limits<double>::quiet_NaN() : raw * h.zscale * 1e6);
    }
    return s;
}

}  // namespace

MeasuredSurface read_sdf(const Bytes& b) {
    b.need(0, 8, "the SDF magic");
    return b.data()[0] == 'b' ? read_binary(b) : read_ascii(b);
}

std::string sdf_bytes(const MeasuredSurface& s) {
    if (s.cols > 65535 || s.rows > 65535)
        throw std::invalid_argument("an SDF file holds at most 65535 x 65535 points; the surface has " +
                                    std::to_string(s.cols) + " x " + std::to_string(s.rows));
    std::string out(k_binary_header, '\0');
    const auto put_text = [&](std::size_t at, std::size_t width, const std::string& text) {
        std::memcpy(&out[at], text.data(), std::min(width, text.size()));
    };
    const auto put = [&](std::size_t at, auto value) {
        // The layout is little-endian whatever the machine.
        unsigned char bytes[sizeof(value)];
        std::memcpy(bytes, &value, sizeof(value));
        const std::uint16_t probe = 1;
        unsigned char first;
        std::memcpy(&first, &probe, 1);
        if (first == 0)
            for (std::size_t k = 0; k < sizeof(value) / 2; ++k) std::swap(bytes[k], bytes[sizeof(value) - 1 - k]);
        std::memcpy(&out[at], bytes, sizeof(value));
    };
    put_text(0, 8, "bISO-1.0");
    put_text(8, 10, "wavebrdf");
    // DDMMYYYYHHMM, as the standard's dates are written.
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char date[16];
    std::strftime(date, sizeof date, "%d%m%Y%H%M", &tm);
    put_text(18, 12, date);
    put_text(30, 12, date);
    put(42, static_cast<std::uint16_t>(s.cols));
    put(44, static_cast<std::uint16_t>(s.rows));
    put(46, s.dx_um * 1e-6);
    put(54, s.dy_um * 1e-6);
    put(62, 1e-6);  // Zscale: the values are in µm
    put(70, 0.0);   // Zresolution: not stated
    out[78] = 0;    // Compression: none
    out[79] = 7;    // DataType: float64 (NaN for a point not measured)
    out[80] = 0;    // CheckType: none
    const std::size_t at = out.size();
    out.resize(at + s.heights_um.size() * 8);
    for (std::size_t i = 0; i < s.heights_um.size(); ++i) put(at + i * 8, s.heights_um[i]);
    return out;
}

}  // namespace wavebrdf::surface_io
