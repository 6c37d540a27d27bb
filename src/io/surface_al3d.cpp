// Alicona AL3D files: the magic "AliconaImaging\0\r\n", then 52-byte tags (a 20-byte key, a
// 30-byte value, "\r\n"): Version, TagCount, then TagCount more (Cols, Rows, PixelSizeXMeter,
// PixelSizeYMeter, DepthImageOffset, InvalidPixelValue, ...), a 256-byte comment. The depth
// image at DepthImageOffset: Rows rows of float32 heights in metres (little-endian), each row
// padded to a multiple of 8 bytes; NaN or InvalidPixelValue marks a point not measured.
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::surface_io {

namespace {
constexpr std::size_t k_magic = 17;
constexpr std::size_t k_tag = 52;
}  // namespace

MeasuredSurface read_al3d(const Bytes& b) {
    b.need(0, k_magic, "the AL3D magic");
    if (b.data().compare(0, k_magic, std::string("AliconaImaging\0\r\n", k_magic)) != 0)
        fail(b.name(), "does not start with AL3D's magic 'AliconaImaging'");
    std::map<std::string, std::string> tags;
    std::size_t at = k_magic;
    const auto read_tag = [&]() {
        b.need(at, k_tag, "an AL3D tag");
        if (b.data().compare(at + 50, 2, "\r\n") != 0) fail(b.name(), "has an AL3D tag not ended by CR LF at byte " + std::to_string(at));
        std::pair<std::string, std::string> tag{b.text(at, 20), b.text(at + 20, 30)};
        at += k_tag;
        return tag;
    };
    const auto version = read_tag();
    if (version.first != "Version") fail(b.name(), "has '" + version.first + "' as its first AL3D tag; expected Version");
    const auto count = read_tag();
    if (count.first != "TagCount") fail(b.name(), "has '" + count.first + "' as its second AL3D tag; expected TagCount");
    const long n_tags = std::strtol(count.second.c_str(), nullptr, 10);
    if (n_tags < 0 || n_tags > 4096) fail(b.name(), "declares " + count.second + " AL3D tags; expected 0 to 4096");
    for (long i = 0; i < n_tags; ++i) {
        auto [k, v] = read_tag();
        tags[k] = v;
    }
    const auto number = [&](const char* key) {
        const auto it = tags.find(key);
        if (it == tags.end()) fail(b.name(), std::string("has no AL3D tag ") + key);
        char* stop = nullptr;
        const double v = std::strtod(it->second.c_str(), &stop);
        if (stop == it->second.c_str()) fail(b.name(), std::string("has AL3D ") + key + " '" + it->second + "'; expected a number");
        return v;
    };
    const double cols = number("Cols"), rows = number("Rows"), offset = number("DepthImageOffset");
    // Bounded before any conversion to an integer (a double beyond its range would be undefined).
    if (cols != std::floor(cols) || rows != std::floor(rows) || offset != std::floor(offset) || offset < 0 ||
        offset > double(b.size()) || !(cols >= 1 && cols <= double(k_max_surface_side)) ||
        !(rows >= 1 && rows <= double(k_max_surface_side)))
        fail(b.name(), "has AL3D Cols " + format_shortest(cols) + ", Rows " + format_shortest(rows) +
                           ", DepthImageOffset " + format_shortest(offset) + "; expected counts within the file");
    if (offset == 0) fail(b.name(), "has no AL3D depth image (DepthImageOffset 0)");
    check_grid(b.name(), (long long)rows, (long long)cols);
    const std::size_t nx = std::size_t(cols), ny = std::size_t(rows);
    const std::size_t stride = (nx * 4 + 7) / 8 * 8;
    const std::size_t start = std::size_t(offset);
    // Every row but the last needs its padding; check the whole block before allocating.
    b.need(start, (ny - 1) * stride + nx * 4, "the AL3D depth image");
    const double invalid = tags.count("InvalidPixelValue") ? number("InvalidPixelValue") : std::nan("");
    MeasuredSurface s;
    s.rows = int(ny);
    s.cols = int(nx);
    s.dx_um = check_spacing(b.name(), number("PixelSizeXMeter") * 1e6, "PixelSizeXMeter");
    s.dy_um = check_spacing(b.name(), number("PixelSizeYMeter") * 1e6, "PixelSizeYMeter");
    s.format = "al3d";
    s.heights_um.resize(nx * ny);
    for (std::size_t r = 0; r < ny; ++r)
        for (std::size_t c = 0; c < nx; ++c) {
            const double z = sample_value(b.data().data() + start + r * stride + c * 4, Sample::f32, false);
            // The marker is stored in float32 and written in the tag in decimal: matched to 1.5e-7.
            const bool bad = std::isnan(z) || (!std::isnan(invalid) && std::abs(z - invalid) <= 1.5e-7 * std::abs(invalid));
            s.heights_um[r * nx + c] = bad ? std::numeric_limits<double>::quiet_NaN() : z * 1e6;
        }
    s.metadata.push_back({"instrument", "Alicona (AL3D version " + version.second + ")"});
    for (const char* key : {"Magnification", "WorkingDistance", "Voltage"})
        if (tags.count(key)) s.metadata.push_back({key, tags[key]});
    return s;
}

}  // namespace wavebrdf::surface_io
