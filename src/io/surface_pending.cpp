// Formats recognised but not read: refused with their name.
#include "io/surface_formats.h"

namespace wavebrdf::surface_io {

MeasuredSurface read_datx(const Bytes& b) {
    fail(b.name(), "is an HDF5 file (Zygo datx?); this build does not read datx files; export the surface as x3p or SDF");
}

}  // namespace wavebrdf::surface_io
