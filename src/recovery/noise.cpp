#include "wavebrdf/noise.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <stdexcept>

#include "core/random.h"
#include "core/text.h"
#include "wavebrdf/observation.h"

namespace wavebrdf {

Noise parse_noise(const std::string& text) {
    const auto bad = [&]() {
        return std::invalid_argument("unknown noise '" + text +
                                     "'; expected 'none', 'poisson:N' (N photons per slice, e.g. poisson:1e4) "
                                     "or 'gaussian:REL' (sigma relative to the slice's peak, e.g. gaussian:0.01)");
    };
    if (text == "none") return {};
    const std::size_t colon = text.find(':');
    if (colon == std::string::npos) throw bad();
    const std::string name = text.substr(0, colon);
    if (name != "poisson" && name != "gaussian") throw bad();
    const double level = detail::parse_number_from(text, colon + 1, bad);
    if (name == "poisson") {
        if (!(std::isfinite(level) && level > 0.0 && level <= 1e18))
            throw std::domain_error("noise '" + text + "': photons per slice must be more than 0 and at most 1e18");
        return {NoiseKind::Poisson, level};
    }
    // Bounded where it is read, not when the noisy slices turn out infinite midway through a run.
    if (!(std::isfinite(level) && level >= 0.0 && level <= 100.0))
        throw std::domain_error("noise '" + text + "': the relative sigma must be 0 to 100 (times the slice's peak)");
    return {NoiseKind::Gaussian, level};
}

std::string to_string(const Noise& noise) {
    switch (noise.kind) {
        case NoiseKind::None: return "none";
        case NoiseKind::Poisson: return "poisson:" + detail::format_shortest(noise.level);
        case NoiseKind::Gaussian: return "gaussian:" + detail::format_shortest(noise.level);
    }
    throw std::invalid_argument("to_string: invalid NoiseKind");
}

std::vector<double> add_noise(const std::vector<double>& slice, const Noise& noise, std::uint64_t seed) {
    std::vector<double> out = slice;
    std::mt19937_64 rng(detail::derive_seed(seed, 0));
    switch (noise.kind) {
        case NoiseKind::None: break;
        case NoiseKind::Poisson: {
            double total = 0.0;
            for (double v : slice) total += std::max(v, 0.0);
            if (!(total > 0.0)) break;
            const double counts_per_unit = noise.level / total;
            for (double& v : out) v = detail::poisson_sample(std::max(v, 0.0) * counts_per_unit, rng) / counts_per_unit;
            break;
        }
        case NoiseKind::Gaussian: {
            double peak = 0.0;
            for (double v : slice) peak = std::max(peak, v);
            std::vector<double> z(slice.size());
            detail::fill_standard_normal(z.data(), z.size(), rng);
            for (std::size_t i = 0; i < out.size(); ++i) out[i] = std::max(0.0, out[i] + noise.level * peak * z[i]);
            break;
        }
    }
    return out;
}

void add_noise(std::vector<Observation>& observations, const Noise& noise, std::uint64_t seed) {
    for (std::size_t i = 0; i < observations.size(); ++i)
        observations[i].reference = to_reference(
            add_noise(to_doubles(observations[i].reference), noise, detail::derive_seed(seed, 1 + i)));
}

Loss matched_loss(const Noise& noise, const Loss& fallback) {
    switch (noise.kind) {
        case NoiseKind::None: return fallback;
        case NoiseKind::Poisson: return {LossKind::Poisson, 1.0, noise.level};
        case NoiseKind::Gaussian: return {LossKind::MSE, 1.0};
    }
    return fallback;
}

}  // namespace wavebrdf
