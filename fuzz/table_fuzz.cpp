// libFuzzer target: the BRDF table reader (read_brdf_table) on arbitrary bytes: its EXR header
// walk, every required attribute, the bounds of the surface it names and the mosaic's size.
// Seeds: fuzz/corpus/table/ (tables written by write_brdf_table).
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/table.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("table.exr", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::BrdfTable t = wavebrdf::read_brdf_table(path);
        const std::size_t n = std::size_t(t.spec.resolution);
        if (t.values.size() != std::size_t(t.spec.lights.rows) * std::size_t(t.spec.lights.cols) * n * n * 3u)
            std::abort();
    });
    return 0;
}
