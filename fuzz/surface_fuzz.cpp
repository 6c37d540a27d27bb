// libFuzzer target: one reader of measured surface files (include/wavebrdf/surface_file.h) on
// arbitrary bytes. Built once per format, WAVEBRDF_SURFACE_FORMAT naming it ("x3p", "sdf", ...):
// read_surface_as aims the bytes at that reader whatever they look like, and read_surface_bytes
// runs the detection on them too. Seeds: fuzz/corpus/surface_<format>/.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_util.h"
#include "wavebrdf/surface_file.h"

namespace {
void check(const wavebrdf::MeasuredSurface& s) {
    if (s.rows < 1 || s.cols < 1 || s.heights_um.size() != std::size_t(s.rows) * std::size_t(s.cols) ||
        !(s.dx_um > 0) || !(s.dy_um > 0) || !std::isfinite(s.dx_um) || !std::isfinite(s.dy_um))
        std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    wavebrdf::fuzz::expect_clean([&] { check(wavebrdf::read_surface_as(bytes, WAVEBRDF_SURFACE_FORMAT, "input", 1.0)); });
    wavebrdf::fuzz::expect_clean([&] {
        const std::string format = wavebrdf::detect_surface_format(bytes);
        if (format != "exr") check(wavebrdf::read_surface_bytes(bytes, "input", 1.0));
    });
    return 0;
}
