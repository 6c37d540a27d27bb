// How far the Gabor model's slices are from the scalar-diffraction simulator's
// (scalar_diffraction.h) for the recovery's default study: the generated truth (±1 µm,
// correlation 4 texels, texel 2 µm, 32²), the planner's acquisition at the given resolution.
// Prints per seed the relative L2 distance over all slices, sqrt(Σ|s − g|² / Σ|s|²), the
// median and largest per-slice distance, the amplitude distance sqrt(Σ(√s − √g)² / Σ s) (what
// the recovery's amplitude loss sees), and the fine grids used.
//   scalar_distance [resolution=48] [seeds...=5201 5202 5203] (environment: none)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/scalar_diffraction.h"

using namespace wavebrdf;

int main(int argc, char** argv) {
    const int resolution = argc > 1 ? std::atoi(argv[1]) : 48;
    std::vector<unsigned long> seeds;
    for (int a = 2; a < argc; ++a) seeds.push_back(std::strtoul(argv[a], nullptr, 10));
    if (seeds.empty()) seeds = {5201, 5202, 5203};
    std::printf("seed,resolution,observations,relative_l2_all,median_slice,max_slice,amplitude_l2_all,m_min,m_max\n");
    for (unsigned long seed : seeds) {
        RecoveryOptions options;
        options.seed = seed;
        options.resolution = resolution;
        const Heightfield truth = generated_recovery_truth(options);
        PlanRequest request;
        request.rows = truth.rows();
        request.cols = truth.cols();
        request.texel_um = truth.texel_um();
        request.height_range_um = options.height_range_um;
        request.resolution = resolution;
        request.seed = seed;
        const AcquisitionPlan plan = plan_acquisition(request);
        const std::vector<Observation> planned = planned_observations(plan);
        double num = 0.0, den = 0.0, anum = 0.0, aden = 0.0;
        std::vector<double> per_slice(planned.size());
        int m_min = 1 << 30, m_max = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : num, den, anum, aden) reduction(min : m_min) reduction(max : m_max)
        for (std::size_t k = 0; k < planned.size(); ++k) {
            const Observation& o = planned[k];
            ScalarDiffractionInfo info;
            const std::vector<double> s = scalar_slice(truth, o.query, o.lambdas_um[0], o.resolution, {}, &info);
            const std::vector<double> g = render_slice<double>(truth, o.query, o.lambdas_um[0], o.resolution);
            double n1 = 0.0, d1 = 0.0;
            for (std::size_t i = 0; i < s.size(); ++i) {
                n1 += (s[i] - g[i]) * (s[i] - g[i]);
                d1 += s[i] * s[i];
                anum += (std::sqrt(s[i]) - std::sqrt(g[i])) * (std::sqrt(s[i]) - std::sqrt(g[i]));
                aden += s[i];
            }
            num += n1;
            den += d1;
            per_slice[k] = std::sqrt(n1 / d1);
            m_min = std::min(m_min, info.samples_per_texel);
            m_max = std::max(m_max, info.samples_per_texel);
        }
        std::vector<double> sorted = per_slice;
        std::sort(sorted.begin(), sorted.end());
        std::printf("%lu,%d,%zu,%.5f,%.5f,%.5f,%.5f,%d,%d\n", seed, resolution, planned.size(), std::sqrt(num / den),
                    sorted[sorted.size() / 2], sorted.back(), std::sqrt(anum / aden), m_min, m_max);
        std::fflush(stdout);
    }
    return 0;
}
