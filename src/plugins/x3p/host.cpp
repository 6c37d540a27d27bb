// The core functions surface_x3p.cpp calls, defined in the plugin as calls into the core's table
// (src/plugins/x3p_api.h). Hidden like everything in the plugin: they bind here, never to the
// core's definitions of the same names. Also the plugin's table.
#include "plugins/x3p_api.h"

namespace wavebrdf {

namespace {
const detail::X3pHost* g_host = nullptr;
}  // namespace

std::string MeasuredSurface::meta(const std::string& key) const { return g_host->meta(*this, key); }

namespace surface_io {

void check_grid(const std::string& name, long long rows, long long cols, std::size_t bytes_per_point,
                std::size_t available) {
    g_host->check_grid(name, rows, cols, bytes_per_point, available);
}
std::size_t sample_size(Sample type) { return g_host->sample_size(type); }
double sample_value(const char* p, Sample type, bool big_endian) { return g_host->sample_value(p, type, big_endian); }
std::string md5_hex(const std::string& data) { return g_host->md5_hex(data); }

}  // namespace surface_io

namespace {

void attach(const detail::X3pHost* host) { g_host = host; }
MeasuredSurface read(const std::string& data, const std::string& name) {
    return surface_io::read_x3p(surface_io::Bytes(data, name));
}
std::string bytes(const MeasuredSurface& surface) { return surface_io::x3p_bytes(surface); }

const detail::X3pApi k_api = {detail::k_x3p_api_version, attach, read, bytes};

}  // namespace

}  // namespace wavebrdf

extern "C" __attribute__((visibility("default"))) const wavebrdf::detail::X3pApi* wavebrdf_x3p_api() {
    return &wavebrdf::k_api;
}
