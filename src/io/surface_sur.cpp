// Digital Surf SUR files (MountainsMap): a 512-byte little-endian header per object, a comment
// and a private zone of the sizes it gives, then the points as int16 or int32 counts, x fastest.
// Offsets used: 12 format, 14 object count, 18 object type, 50 instrument name
// (30 bytes), 86 special-points flag, 98 bits per point (16 or 32), 100 zmin, 108 x and y point
// counts, 116 their product, 120 x and y spacing and z per count (float32), 180 / 196 / 212 the
// units of those three (16 bytes each), 306 seconds … 316 year (uint16), 334 comment size, 336
// private zone size, 474 z offset (float32, z unit): height = count · z scale + z offset. With special points, zmin − 2 marks a point not measured.
#include <cmath>
#include <limits>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::surface_io {

namespace {

constexpr std::size_t k_sur_header = 512;

// µm per unit of a SUR unit name ("mm", "µm" in Latin-1 or UTF-8, "um", "nm", "m", "A").
std::optional<double> sur_unit(const std::string& unit) {
    if (unit == "m") return 1e6;
    if (unit == "cm") return 1e4;
    if (unit == "mm") return 1e3;
    if (unit == "um" || unit == "\xb5m" || unit == "\xc2\xb5m" || unit == "\xce\xbcm") return 1.0;
    if (unit == "nm") return 1e-3;
    if (unit == "A" || unit == "\xc5") return 1e-4;
    if (unit == "pm") return 1e-6;
    return std::nullopt;
}

}  // namespace

MeasuredSurface read_sur(const Bytes& b) {
    if (b.data().compare(0, 12, "DSCOMPRESSED") == 0)
        fail(b.name(), "is a compressed Digital Surf file (DSCOMPRESSED); only uncompressed SUR files are read");
    b.need(0, k_sur_header, "the SUR header");
    const int objects = b.get<std::uint16_t>(14);
    if (objects != 1)
        fail(b.name(), "holds " + std::to_string(objects) + " SUR objects; only single-object files are read");
    // The object type is not checked: MountainsMap writes 2 for a surface, Gwyddion 1; the grid
    // is read as it is declared (a profile is a grid of one row).
    const int bits = b.get<std::uint16_t>(98);
    if (bits != 16 && bits != 32) fail(b.name(), "has " + std::to_string(bits) + "-bit SUR points; expected 16 or 32");
    const std::int32_t zmin = b.get<std::int32_t>(100);
    const long long nx = b.get<std::int32_t>(108);
    const long long ny = b.get<std::int32_t>(112);
    const long long count = b.get<std::uint32_t>(116);
    if (count != nx * ny)
        fail(b.name(), "declares " + std::to_string(count) + " SUR points for " + std::to_string(nx) + " x " +
                           std::to_string(ny));
    const auto unit = [&](std::size_t offset, const char* what) {
        const std::string name = b.text(offset, 16);
        const auto factor = sur_unit(name);
        if (!factor) fail(b.name(), std::string("has SUR ") + what + " unit '" + name + "'; expected m, mm, um, nm or A");
        return *factor;
    };
    const double dx = double(b.get<float>(120)) * unit(180, "x");
    const double dy = double(b.get<float>(124)) * unit(196, "y");
    const double z_unit = unit(212, "z");
    const double dz = double(b.get<float>(128)) * z_unit;
    // The z offset (Gwyddion writes counts from 0 and the minimum here; MountainsMap writes 0).
    const double z_offset = double(b.get<float>(474)) * z_unit;
    if (!std::isfinite(z_offset)) fail(b.name(), "has a SUR z offset that is not finite");
    if (!std::isfinite(dz) || dz == 0.0) fail(b.name(), "has SUR z scale " + format_shortest(dz) + "; expected finite, non-zero");
    const std::size_t start = k_sur_header + b.get<std::uint16_t>(334) + b.get<std::uint16_t>(336);
    const std::size_t size = std::size_t(bits / 8);
    b.need(start, 0, "the SUR data");
    check_grid(b.name(), ny, nx, size, b.size() - start);
    MeasuredSurface s;
    s.rows = int(ny);
    s.cols = int(nx);
    s.dx_um = check_spacing(b.name(), dx, "x");
    s.dy_um = check_spacing(b.name(), dy, "y");
    s.format = "sur";
    const bool special = b.get<std::uint16_t>(86) != 0;
    const double marker = double(zmin) - 2.0;
    const std::size_t n = std::size_t(nx) * std::size_t(ny);
    s.heights_um.resize(n);
    const Sample sample = bits == 16 ? Sample::i16 : Sample::i32;
    const char* data = b.data().data() + start;
    for (std::size_t i = 0; i < n; ++i) {
        const double raw = sample_value(data + i * size, sample, false);
        s.heights_um[i] = special && raw == marker ? std::numeric_limits<double>::quiet_NaN() : raw * dz + z_offset;
    }
    const std::string instrument = b.text(50, 30);
    if (!instrument.empty()) s.metadata.push_back({"instrument", instrument});
    const std::string object = b.text(20, 30);
    if (!object.empty()) s.metadata.push_back({"object", object});
    const int year = b.get<std::uint16_t>(316);
    if (year > 0) {
        char date[32];
        std::snprintf(date, sizeof date, "%04d-%02d-%02dT%02d:%02d:%02d", year, b.get<std::uint16_t>(314) % 100,
                      b.get<std::uint16_t>(312) % 100, b.get<std::uint16_t>(310) % 100, b.get<std::uint16_t>(308) % 100,
                      b.get<std::uint16_t>(306) % 100);
        s.metadata.push_back({"date", date});
    }
    const std::size_t comment_size = b.get<std::uint16_t>(334);
    if (comment_size > 0) s.metadata.push_back({"comment", b.text(k_sur_header, comment_size)});
    return s;
}

}  // namespace wavebrdf::surface_io
