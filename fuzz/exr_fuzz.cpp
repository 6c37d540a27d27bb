// libFuzzer target: the OpenEXR readers (read_heightfield_exr, read_rgb_exr, and the readers of
// wavebrdf's attributes, read_heightfield_attributes and read_slice_exr) on arbitrary bytes.
// Seeds: fuzz/corpus/exr/.
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("input.exr", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::Heightfield h = wavebrdf::read_heightfield_exr(path);
        if (h.rows() < 1 || h.cols() < 1 ||
            h.values().size() != static_cast<std::size_t>(h.rows()) * static_cast<std::size_t>(h.cols()))
            std::abort();
    });
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::RgbImage image = wavebrdf::read_rgb_exr(path);
        if (image.rows < 1 || image.cols < 1 ||
            image.data.size() != static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols) * 3u)
            std::abort();
    });
    wavebrdf::fuzz::expect_clean([&] { wavebrdf::read_heightfield_attributes(path); });
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::SliceFile slice = wavebrdf::read_slice_exr(path);
        if (slice.attributes && (slice.attributes->lambdas_um.empty() || slice.attributes->resolution < 1))
            std::abort();
    });
    return 0;
}
