// libFuzzer target: inversion_options_from_json, which reads the options of `wavebrdf invert
// --resume DIR` from run.json's "args" object, on arbitrary bytes. What it accepts must also
// round-trip: the options written back (inversion_options_to_json) read as the same options,
// so a resumed run continues the run that was started. Seeds: fuzz/corpus/run_json/.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_util.h"
#include "wavebrdf/inversion_run.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    wavebrdf::fuzz::expect_clean([&] {
        const wavebrdf::InversionOptions options = wavebrdf::inversion_options_from_json(text, "run.json");
        // run.json holds only options that came from a command line, which it can always store.
        const std::string written = wavebrdf::inversion_options_to_json(options);
        const std::string again = wavebrdf::inversion_options_to_json(
            wavebrdf::inversion_options_from_json(written, "run.json (written back)"));
        if (again != written) {
            std::fprintf(stderr, "fuzz: run.json does not round-trip:\n%s\n---\n%s\n", written.c_str(), again.c_str());
            std::abort();
        }
    });
    return 0;
}
