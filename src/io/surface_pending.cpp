// Formats recognised but not read yet: refused with their name.
#include "io/surface_formats.h"

namespace wavebrdf::surface_io {

namespace {
[[noreturn]] void pending(const Bytes& b, const char* format) {
    fail(b.name(), std::string("is a ") + format + " file; this build does not read " + format + " files yet");
}
}  // namespace

MeasuredSurface read_x3p(const Bytes& b) { pending(b, "x3p"); }
MeasuredSurface read_sdf(const Bytes& b) { pending(b, "SDF"); }
MeasuredSurface read_datx(const Bytes& b) { pending(b, "Zygo datx"); }
MeasuredSurface read_metropro(const Bytes& b) { pending(b, "MetroPro"); }
MeasuredSurface read_sur(const Bytes& b) { pending(b, "Digital Surf sur"); }
MeasuredSurface read_plu(const Bytes& b) { pending(b, "Sensofar plu"); }
MeasuredSurface read_al3d(const Bytes& b) { pending(b, "Alicona al3d"); }
bool looks_like_plu(const std::string&) { return false; }
std::string x3p_bytes(const MeasuredSurface&) { throw std::invalid_argument("writing x3p is not available yet"); }
std::string sdf_bytes(const MeasuredSurface&) { throw std::invalid_argument("writing SDF is not available yet"); }

}  // namespace wavebrdf::surface_io
