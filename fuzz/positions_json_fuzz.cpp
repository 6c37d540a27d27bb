// libFuzzer target: read_positions_json (`wavebrdf invert --positions FILE.json`) on arbitrary
// bytes. Seeds: fuzz/corpus/positions_json/.
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/invert.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("positions.json", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        if (wavebrdf::read_positions_json(path).empty()) std::abort();  // documented non-empty
    });
    return 0;
}
