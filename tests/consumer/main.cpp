// A consumer of the wavebrdf library (tests/consumer/CMakeLists.txt): renders a small slice of
// a small generated heightfield, writes and reads the heightfield back as EXR, and prints the
// version. Exits 0 when every value is finite and non-negative, the slice's peak is positive
// and the heightfield reads back; 1 otherwise, naming what failed.
#include <wavebrdf/brdf.h>
#include <wavebrdf/generate.h>
#include <wavebrdf/io.h>
#include <wavebrdf/version.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

int main(int argc, char** argv) {
    try {
        wavebrdf::SurfaceParams params;
        params.rows = 32;
        params.cols = 32;
        params.texel_um = 1.0;
        params.rms_height_um = 0.1;
        params.correlation_um = 3.0;
        params.seed = 7;
        const wavebrdf::Heightfield heightfield = wavebrdf::generate_heightfield(params);

        wavebrdf::Query query;
        query.sigma_p_um = 4.0;
        query.x_um = 16.0;
        query.y_um = 16.0;
        const int n = 24;
        const std::vector<double> slice = wavebrdf::render_slice<double>(heightfield, query, 0.5, n);
        double peak = 0.0;
        for (const double value : slice) {
            if (!std::isfinite(value) || value < 0.0) {
                std::fprintf(stderr, "consumer: a slice value is %g (expected finite and >= 0)\n", value);
                return 1;
            }
            peak = std::max(peak, value);
        }
        if (!(peak > 0.0)) {
            std::fprintf(stderr, "consumer: the slice is all zero\n");
            return 1;
        }

        // OpenEXR through the library (its private link dependency).
        const std::string path = (argc > 1 ? std::string(argv[1]) : std::string(".")) + "/consumer_heights.exr";
        wavebrdf::write_heightfield_exr(path, heightfield);
        const wavebrdf::Heightfield back = wavebrdf::read_heightfield_exr(path);
        if (back.rows() != heightfield.rows() || back.cols() != heightfield.cols() ||
            std::abs(back.value(5, 7) - heightfield.value(5, 7)) > 1e-3 * (1.0 + std::abs(heightfield.value(5, 7)))) {
            std::fprintf(stderr, "consumer: the heightfield did not read back\n");
            return 1;
        }
        std::printf("wavebrdf %s: %dx%d slice, peak %.6g 1/sr\n", wavebrdf::k_version, n, n, peak);
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "consumer: %s\n", e.what());
        return 1;
    }
}
