// libFuzzer target: read_observations_json on arbitrary bytes. The JSON part is what is
// fuzzed; a reference named "ref.exr" resolves to a valid 4x4 RGB EXR written beside the input
// at start-up, so the image branch (size check, channel selection) is reached too.
// Seeds: fuzz/corpus/observations_json/.
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    wavebrdf::RgbImage image;
    image.rows = 4;
    image.cols = 4;
    image.data.assign(4 * 4 * 3, 0.25f);
    wavebrdf::write_rgb_exr(wavebrdf::fuzz::scratch_dir() + "/ref.exr", image);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("observations.json", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        const auto observations = wavebrdf::read_observations_json(path);
        // Documented: at least one, each validated.
        if (observations.empty()) std::abort();
        for (std::size_t i = 0; i < observations.size(); ++i) wavebrdf::validate(observations[i], i);
    });
    return 0;
}
