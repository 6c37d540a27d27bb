// x3p files (ISO 25178-72): the core's side. The reader and writer are in the x3p plugin
// (src/plugins/x3p/surface_x3p.cpp, src/plugins/x3p_api.h), loaded at the first x3p file, so
// that nothing else loads libzip, OpenSSL's libcrypto and pugixml.
#include <stdexcept>
#include <string>

#include "core/plugin.h"
#include "io/surface_formats.h"
#include "plugins/x3p_api.h"

namespace wavebrdf::surface_io {

namespace {

std::string surface_meta(const MeasuredSurface& surface, const std::string& key) { return surface.meta(key); }

const detail::X3pHost k_host = {check_grid, sample_size, sample_value, md5_hex, surface_meta};

// The plugin, loaded and attached on the first call.
const detail::X3pApi& x3p() {
    static const detail::X3pApi* const api = [] {
        using Entry = const detail::X3pApi* (*)();
        const auto entry = reinterpret_cast<Entry>(detail::plugin_symbol("x3p", "wavebrdf_x3p_api"));
        const detail::X3pApi* table = entry();
        if (table == nullptr || table->version != detail::k_x3p_api_version)
            throw std::runtime_error("wavebrdf: the x3p plugin libwavebrdf_x3p.so is of another version (interface " +
                                     std::to_string(table ? table->version : -1) + ", expected " +
                                     std::to_string(detail::k_x3p_api_version) + "); rebuild it");
        table->attach(&k_host);
        return table;
    }();
    return *api;
}

}  // namespace

MeasuredSurface read_x3p(const Bytes& bytes) { return x3p().read(bytes.data(), bytes.name()); }

std::string x3p_bytes(const MeasuredSurface& surface) { return x3p().bytes(surface); }

}  // namespace wavebrdf::surface_io
