// libFuzzer target: Inversion::load_checkpoint (checkpoint.json of `wavebrdf invert`) on
// arbitrary bytes. The inversion it loads into is the run that wrote the seed
// fuzz/corpus/checkpoint/invert_4x4.json:
//   wavebrdf invert --observations fuzz/corpus/observations_json/inline_mono.json --size 4
//                   --epochs 3 --no-plots --quiet --out DIR
// (defaults otherwise), so the seed passes the fingerprint check and the fuzzer starts from the
// fields behind it. A fresh Inversion per input: a rejected checkpoint may leave one half-loaded.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/observation.h"

namespace {

// The run's observations: the seed fuzz/corpus/observations_json/inline_mono.json.
std::vector<wavebrdf::Observation>& observations() {
    static std::vector<wavebrdf::Observation> list = wavebrdf::read_observations_json(
        std::string(WAVEBRDF_SOURCE_DIR) + "/fuzz/corpus/observations_json/inline_mono.json");
    return list;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    observations();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("checkpoint.json", data, size);
    wavebrdf::Inversion inversion(observations(), wavebrdf::Heightfield(4, 4, std::vector<double>(16, 0.0)),
                                  wavebrdf::InversionSettings{});
    wavebrdf::fuzz::expect_clean([&] {
        inversion.load_checkpoint(path);
        if (std::getenv("WAVEBRDF_FUZZ_VERBOSE") != nullptr)
            std::fprintf(stderr, "fuzz: checkpoint loaded, epoch %d\n", inversion.epoch());
    });
    return 0;
}
