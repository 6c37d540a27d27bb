// The x3p plugin's interface (libwavebrdf_x3p.so, src/plugins/x3p/): the ISO 25178-72 reader
// and writer, which need libzip (and through it OpenSSL's libcrypto) and pugixml, loaded at the
// first x3p file (src/core/plugin.h) so that nothing else loads those libraries. The plugin links
// no part of the core library: the core's helpers it calls come through X3pHost, handed over once
// after loading (src/plugins/x3p/host.cpp defines the functions of surface_formats.h it uses as
// calls into that table). Both sides are compiled from this tree by one compiler.
#pragma once

#include <cstddef>
#include <string>

#include "io/surface_formats.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf::detail {

constexpr int k_x3p_api_version = 1;

struct X3pHost {
    void (*check_grid)(const std::string& name, long long rows, long long cols, std::size_t bytes_per_point,
                       std::size_t available);
    std::size_t (*sample_size)(surface_io::Sample type);
    double (*sample_value)(const char* p, surface_io::Sample type, bool big_endian);
    std::string (*md5_hex)(const std::string& data);
    std::string (*meta)(const MeasuredSurface& surface, const std::string& key);
};

struct X3pApi {
    int version;
    // Called once, before any other entry; `host` lives as long as the process.
    void (*attach)(const X3pHost* host);
    // surface_io::read_x3p of the file's bytes `data` named `name`.
    MeasuredSurface (*read)(const std::string& data, const std::string& name);
    // surface_io::x3p_bytes.
    std::string (*bytes)(const MeasuredSurface& surface);
};

}  // namespace wavebrdf::detail

// The one symbol the plugin exports.
extern "C" const wavebrdf::detail::X3pApi* wavebrdf_x3p_api();
