// The optional parts that carry heavy libraries (MPI: libwavebrdf_mpi.so, HDF5:
// libwavebrdf_hdf5.so) are shared libraries loaded on first use, so that a command which needs
// neither starts without loading them (the dynamic loader's work is most of a short command's
// time). Where they are looked for, in order: the folder $WAVEBRDF_PLUGIN_DIR; the build tree's
// lib/wavebrdf (compiled in); beside the program or module that holds this library and its
// ../lib/wavebrdf (a relocated install); the install prefix's lib/wavebrdf (compiled in).
#pragma once

#include <string>

namespace wavebrdf::detail {

// The plugin `name` ("mpi", "hdf5") loaded once (later calls return the same handle), and its
// symbol `symbol`; throws std::runtime_error naming the plugin, where it was looked for and why
// it did not load.
void* plugin_symbol(const char* name, const char* symbol);

// Whether a library whose file name contains `fragment` (e.g. "libmpi") is loaded in this process.
bool library_loaded(const char* fragment);

}  // namespace wavebrdf::detail
