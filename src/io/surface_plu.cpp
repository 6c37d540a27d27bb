// Sensofar PLU files (SensoSCAN): no magic number. A 500-byte little-endian header: the
// acquisition date as text (128 bytes), its time_t (4), a comment (256), the calibration (yres,
// xres, N_tall as uint32; dy_multip, µm per pixel along x and y, offsets x and y, µm per pixel
// along z, offset z as float32), the measurement configuration (type, algorithm, method,
// objective, area type as uint32), 40 bytes of scan settings, then restore, number of layers,
// version, hardware configuration, number of images (bytes), 3 reserved bytes and a uint32.
// Each layer: yres, xres (uint32), yres · xres float32 heights in µm (x fastest; 1000001 marks a
// point not measured), then its minimum and maximum.
#include <cctype>
#include <cmath>
#include <limits>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::surface_io {

namespace {
constexpr std::size_t k_plu_header = 500;
constexpr std::size_t k_calibration = 388;
constexpr std::size_t k_configuration = 428;
constexpr std::size_t k_layers = 489;
constexpr std::uint32_t k_topography = 3;
constexpr float k_not_measured = 1000001.0f;
}  // namespace

bool looks_like_plu(const std::string& d) {
    if (d.size() < k_plu_header + 8) return false;
    // The date: printable text, then only NUL bytes to 128.
    std::size_t i = 0;
    while (i < 128 && d[i] != '\0') {
        const auto c = static_cast<unsigned char>(d[i]);
        if (c < 0x20 || c > 0x7e) return false;
        ++i;
    }
    if (i < 8) return false;
    for (; i < 128; ++i)
        if (d[i] != '\0') return false;
    // The first layer's size repeats the calibration's.
    const Bytes b(d, "");
    return b.get<std::uint32_t>(k_calibration) == b.get<std::uint32_t>(k_plu_header) &&
           b.get<std::uint32_t>(k_calibration + 4) == b.get<std::uint32_t>(k_plu_header + 4);
}

MeasuredSurface read_plu(const Bytes& b) {
    b.need(0, k_plu_header + 8, "the PLU header");
    const std::uint32_t type = b.get<std::uint32_t>(k_configuration);
    if (type != k_topography)
        fail(b.name(), "is a Sensofar PLU measurement of type " + std::to_string(type) +
                           "; only topographies (type 3) are read");
    const int layers = static_cast<unsigned char>(b.data()[k_layers]);
    if (layers != 1) fail(b.name(), "holds " + std::to_string(layers) + " PLU layers; only single-layer files are read");
    const double dx = double(b.get<float>(k_calibration + 16));
    const double dy = double(b.get<float>(k_calibration + 20));
    const long long ny = b.get<std::uint32_t>(k_plu_header);
    const long long nx = b.get<std::uint32_t>(k_plu_header + 4);
    check_grid(b.name(), ny, nx, 4, b.size() - (k_plu_header + 8));
    MeasuredSurface s;
    s.rows = int(ny);
    s.cols = int(nx);
    s.dx_um = check_spacing(b.name(), dx, "x (um per pixel)");
    s.dy_um = check_spacing(b.name(), dy, "y (um per pixel)");
    s.format = "plu";
    const std::size_t n = std::size_t(nx) * std::size_t(ny);
    s.heights_um.resize(n);
    const char* data = b.data().data() + k_plu_header + 8;
    for (std::size_t i = 0; i < n; ++i) {
        const double h = sample_value(data + 4 * i, Sample::f32, false);
        s.heights_um[i] = h == double(k_not_measured) ? std::numeric_limits<double>::quiet_NaN() : h;
    }
    s.metadata.push_back({"date", b.text(0, 128)});
    const std::string comment = b.text(132, 256);
    if (!comment.empty()) s.metadata.push_back({"comment", comment});
    s.metadata.push_back({"instrument", "Sensofar (objective index " +
                                            std::to_string(b.get<std::uint32_t>(k_configuration + 12)) + ")"});
    return s;
}

}  // namespace wavebrdf::surface_io
