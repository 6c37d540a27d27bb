// libFuzzer target: a design's iridescent target spec (`--target iridescent:SPEC.json`,
// parse_design_target) on arbitrary bytes: its size and nesting bounds, the JSON, the pairs'
// views and colours. Seeds: fuzz/corpus/iridescent_spec/.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/design_run.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("spec.json", data, size);
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::DesignTarget t = wavebrdf::parse_design_target("iridescent:" + path);
        if (t.pairs.empty() || t.pairs.size() > 16) std::abort();
        for (const auto& p : t.pairs)
            if (!(std::hypot(p.view[0], p.view[1]) < 1.0)) std::abort();
    });
    return 0;
}
