#pragma once
// The benchmarks' shared input: the 1024² isotropic surface of bench/results (texel 1 µm, rms
// height 0.05 µm, correlation 4 µm, seed 1), the same one bench/speed.sh writes to an EXR.
#include "wavebrdf/generate.h"

namespace wavebrdf::bench {

inline const Heightfield& surface() {
    static const Heightfield hf = [] {
        SurfaceParams p;
        p.type = SurfaceType::Isotropic;
        p.rows = p.cols = 1024;
        p.rms_height_um = 0.05;
        p.correlation_um = 4.0;
        p.seed = 1;
        return generate_heightfield(p);
    }();
    return hf;
}

}  // namespace wavebrdf::bench
