// Zygo datx files: the core's side. The reader is in the HDF5 plugin
// (src/plugins/hdf5/surface_datx.cpp, src/plugins/hdf5_api.h), loaded at the first datx file, so
// that nothing else loads HDF5; a build without HDF5 recognises the file and says so.
#include <stdexcept>
#include <string>

#include "core/plugin.h"
#include "io/surface_formats.h"
#include "plugins/hdf5_api.h"

namespace wavebrdf::surface_io {

#ifdef WAVEBRDF_HAS_HDF5

MeasuredSurface read_datx(const Bytes& bytes) {
    // The plugin's table; read_datx needs no host (hdf5_api.h), so nothing is attached here.
    static const detail::Hdf5Api* const api = [] {
        using Entry = const detail::Hdf5Api* (*)();
        const auto entry = reinterpret_cast<Entry>(detail::plugin_symbol("hdf5", "wavebrdf_hdf5_api"));
        const detail::Hdf5Api* table = entry();
        if (table == nullptr || table->version != detail::k_hdf5_api_version)
            throw std::runtime_error(
                "wavebrdf: the HDF5 plugin libwavebrdf_hdf5.so is of another version "
                "(interface " +
                std::to_string(table ? table->version : -1) + ", expected " +
                std::to_string(detail::k_hdf5_api_version) + "); rebuild it");
        return table;
    }();
    return api->read_datx(bytes.data(), bytes.name());
}

#else

MeasuredSurface read_datx(const Bytes& b) {
    fail(b.name(),
         "is an HDF5 file (Zygo datx?); this build has no HDF5 (rebuild with libhdf5-dev installed); "
         "export the surface as x3p or SDF");
}

#endif

}  // namespace wavebrdf::surface_io
