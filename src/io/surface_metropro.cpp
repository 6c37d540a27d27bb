// Zygo MetroPro .dat files: a big-endian header (formats 1–3, magic 0x881B036F, 0x881B0370,
// 0x881B0371; the header's size at byte 6), then the intensity data (2 bytes per bucket and
// point) and the phase data (int32 per point, x fastest). Offsets used: 52/54/56 intensity
// width, height, buckets; 68/70 phase width, height; 76 time stamp; 80 comment (82 bytes); 164
// intf_scale_factor, 168 wavelength (m), 176 obliquity_factor, 184 lateral_res (m per pixel)
// as float32; 218 phase_res; 232 sign.
#include <cmath>
#include <limits>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::surface_io {

MeasuredSurface read_metropro(const Bytes& b) {
    b.need(0, 834, "the MetroPro header");
    const std::uint32_t header_size = b.get<std::uint32_t>(6, true);
    if (header_size < 834 || header_size > b.size())
        fail(b.name(), "declares a MetroPro header of " + std::to_string(header_size) + " bytes; expected 834 to the file's size");
    const long long ac_width = b.get<std::uint16_t>(52, true), ac_height = b.get<std::uint16_t>(54, true);
    const long long buckets = b.get<std::uint16_t>(56, true);
    const long long nx = b.get<std::uint16_t>(68, true), ny = b.get<std::uint16_t>(70, true);
    const unsigned long long intensity = 2ULL * static_cast<unsigned long long>(buckets * ac_width * ac_height);
    if (intensity > b.size() - header_size)
        fail(b.name(), "declares " + std::to_string(intensity) + " bytes of MetroPro intensity data beyond its size");
    const std::size_t start = header_size + std::size_t(intensity);
    if (nx == 0 || ny == 0) fail(b.name(), "holds no MetroPro phase data (its size is 0)");
    check_grid(b.name(), ny, nx, 4, b.size() - start);
    const int phase_res = b.get<std::int16_t>(218, true);
    double resolution;
    switch (phase_res) {
        case 0: resolution = 4096.0; break;
        case 1: resolution = 32768.0; break;
        case 2: resolution = 131072.0; break;
        default: fail(b.name(), "has MetroPro phase_res " + std::to_string(phase_res) + "; expected 0, 1 or 2");
    }
    const double scale = double(b.get<float>(164, true)) * double(b.get<float>(176, true)) *
                         double(b.get<float>(168, true)) / resolution * (b.get<std::int16_t>(232, true) != 0 ? -1.0 : 1.0);
    if (!std::isfinite(scale) || scale == 0.0)
        fail(b.name(), "has a MetroPro height scale of " + format_shortest(scale) + " m per count; expected finite, non-zero");
    const double lateral = double(b.get<float>(184, true));
    if (!(lateral > 0.0))
        fail(b.name(), "has MetroPro lateral_res " + format_shortest(lateral) + "; a file without its spacing is not read");
    MeasuredSurface s;
    s.rows = int(ny);
    s.cols = int(nx);
    s.dx_um = s.dy_um = check_spacing(b.name(), lateral * 1e6, "lateral_res");
    s.format = "metropro";
    const std::size_t n = std::size_t(nx) * std::size_t(ny);
    s.heights_um.resize(n);
    const char* data = b.data().data() + start;
    for (std::size_t i = 0; i < n; ++i) {
        const double raw = sample_value(data + 4 * i, Sample::i32, true);
        s.heights_um[i] = raw >= 2147483640.0 ? std::numeric_limits<double>::quiet_NaN() : raw * scale * 1e6;
    }
    s.metadata.push_back({"instrument", "Zygo MetroPro"});
    const std::string comment = b.text(80, 82);
    if (!comment.empty()) s.metadata.push_back({"comment", comment});
    s.metadata.push_back({"time_stamp", std::to_string(b.get<std::int32_t>(76, true))});
    return s;
}

}  // namespace wavebrdf::surface_io
