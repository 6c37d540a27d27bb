// libFuzzer target: the design's PNG readers on arbitrary bytes: a pattern target's image
// (`--target pattern:IMAGE.png`, grey, at most 1024²) and a plate's picture (`--target
// image:PICTURE.png`, read_plate_picture, RGB). libpng parses; ours bounds the declared size by
// what the file can hold before allocating. Seeds: fuzz/corpus/png_picture/.
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("picture.png", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::DesignTarget t = wavebrdf::parse_design_target("pattern:" + path);
        if (t.image.size() != std::size_t(t.image_rows) * std::size_t(t.image_cols)) std::abort();
    });
    // A plate's picture: at most 2^22 pixels here (12 MB of RGB), far under the fuzzer's
    // allocation limit; the CLI's bound is larger and only its size check differs.
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::PlatePicture p = wavebrdf::read_plate_picture(path, 1LL << 22);
        if (p.srgb8.size() != std::size_t(p.rows) * std::size_t(p.cols) * 3u) std::abort();
    });
    return 0;
}
