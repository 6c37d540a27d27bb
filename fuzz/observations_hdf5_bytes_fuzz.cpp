// libFuzzer target: the HDF5 observation reader (read_observation_index and
// read_observations_file of a .h5 path) on arbitrary bytes: structure, chunk layout, storage
// that points outside the file, filters and declared sizes are all checked before a read
// (observation_hdf5.cpp). Seeds: fuzz/corpus/observations_hdf5_bytes/ (files written by
// write_observations_file). Mostly HDF5's own parser at work (fuzz/README.md): scripts/fuzz.sh
// replays its inputs unless it is named; observations_hdf5_fuzz fuzzes our reader by recipe.
#include <cstdint>
#include <cstdlib>

#include "fuzz_util.h"
#include "wavebrdf/observation_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = wavebrdf::fuzz::write_input("observations.h5", data, size);
    // 0.25 GB: a small file may not make the reader allocate more than this.
    wavebrdf::fuzz::expect_clean([&] { wavebrdf::read_observation_index(path, 0.25); });
    wavebrdf::fuzz::expect_clean([&] {
        const auto observations = wavebrdf::read_observations_file(path, 0, 1, 0.25);
        // Documented: at least one, each validated.
        if (observations.empty()) std::abort();
        for (std::size_t i = 0; i < observations.size(); ++i) wavebrdf::validate(observations[i], i);
    });
    return 0;
}
