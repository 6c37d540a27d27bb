// Entry points: validate, gather the footprint's kernels once, pick the path, and combine
// wavelengths into RGB.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "wavebrdf/brdf.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf {

long long work_units(int resolution) { return resolution; }

namespace {

void validate_options(const RenderOptions& options, Model model) {
    if (!(options.prune_tolerance >= 0.0 && options.prune_tolerance <= 1e-6))
        throw std::domain_error("prune tolerance " + std::to_string(options.prune_tolerance) +
                                " is out of range; expected 0 to 1e-6 of the slice peak");
    if (options.path == RenderPath::Separable && !is_separable(model))
        throw std::invalid_argument(std::string("the separable path needs OHS or ROHS; model is ") +
                                    to_string(model));
}

bool separable_path(const RenderOptions& options, Model model) {
    return options.path == RenderPath::Separable || (options.path == RenderPath::Auto && is_separable(model));
}

// Refuses, before any work, what estimate_render_bytes says cannot fit options.max_memory_gb.
void require_render_memory(const Heightfield& heightfield, const Query& query, int resolution,
                           const RenderOptions& options, std::size_t float_bytes, bool rgb) {
    const MemoryLimit limit = memory_limit(options.max_memory_gb);
    const double needed = estimate_render_bytes(heightfield, query, resolution, options, float_bytes, rgb);
    if (needed > limit.bytes)
        require_memory(needed, limit, "render (" + std::to_string(resolution) + "x" + std::to_string(resolution) +
                                          " slice, " + (float_bytes == 4 ? "float" : "double") + ")");
}

template <typename Float>
std::vector<Float> render_kernels(const FootprintKernels& kernels, const Query& query,
                                  double lambda_um, int resolution, const RenderOptions& options) {
    if (separable_path(options, query.model))
        return render_slice_separable<Float>(kernels, query, lambda_um, resolution, options.progress);
    return render_slice_direct<Float>(kernels, query, lambda_um, resolution,
                                      options.prune_tolerance, options.progress);
}

}  // namespace

double estimate_render_bytes(const Heightfield& heightfield, const Query& query, int resolution,
                             const RenderOptions& options, std::size_t float_bytes, bool rgb) {
    const double pixels = double(resolution) * double(resolution), n = double(resolution);
    // Kernels within 3σ_p of the centre: row, col and six doubles each.
    const double reach = 3.0 * query.sigma_p_um / heightfield.texel_um() + 1.0;
    const double kernels = std::min(double(heightfield.rows()) * double(heightfield.cols()), k_pi * reach * reach);
    double bytes = 32e6 + kernels * 56.0;
    bytes += pixels * double(float_bytes) * (rgb ? 4.0 : 1.0);  // the slice (and the RGB result)
    if (separable_path(options, query.model)) {
        // Field n² complex, its factor matrices (≤ 32 MiB) and the phase tables.
        bytes += pixels * 2.0 * double(float_bytes) + std::min(32.0 * (1 << 20), 4.0 * n * kernels * double(float_bytes));
        bytes += n * 2.0 * std::min(kernels, 2.0 * reach + 1.0) * 16.0;
    } else {
        bytes += pixels * (16.0 + 8.0 + 8.0);  // field, c1 and value in double
    }
    return bytes;
}

template <typename Float>
std::vector<Float> render_slice(const Heightfield& heightfield, const Query& query,
                                double lambda_um, int resolution, const RenderOptions& options) {
    validate(query);
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    validate_options(options, query.model);
    require_render_memory(heightfield, query, resolution, options, sizeof(Float), false);
    const FootprintKernels kernels =
        footprint_kernels(heightfield, query.x_um, query.y_um, query.sigma_p_um);
    return render_kernels<Float>(kernels, query, lambda_um, resolution, options);
}

template <typename Float>
std::vector<Float> render_rgb(const Heightfield& heightfield, const Query& query,
                              const std::vector<double>& lambdas_um, int resolution,
                              const RenderOptions& options) {
    validate(query);
    validate_resolution(resolution);
    validate_options(options, query.model);
    if (lambdas_um.empty())
        throw std::invalid_argument("no wavelengths given; expected at least one");
    for (double lambda : lambdas_um) validate_lambda(lambda);
    require_render_memory(heightfield, query, resolution, options, sizeof(Float), true);

    const FootprintKernels kernels =
        footprint_kernels(heightfield, query.x_um, query.y_um, query.sigma_p_um);
    const std::size_t pixels = static_cast<std::size_t>(resolution) * resolution;
    std::vector<Float> rgb(pixels * 3, Float(0));
    if (lambdas_um.size() == 1) {
        const std::vector<Float> slice =
            render_kernels<Float>(kernels, query, lambdas_um[0], resolution, options);
        for (std::size_t at = 0; at < pixels; ++at)
            rgb[3 * at] = rgb[3 * at + 1] = rgb[3 * at + 2] = slice[at];
        return rgb;
    }
    const std::vector<double> weights = spectral_to_srgb_weights(lambdas_um);
    const std::size_t count = lambdas_um.size();
    for (std::size_t l = 0; l < count; ++l) {
        const std::vector<Float> slice =
            render_kernels<Float>(kernels, query, lambdas_um[l], resolution, options);
        const Float wr = Float(weights[l]), wg = Float(weights[count + l]),
                    wb = Float(weights[2 * count + l]);
        for (std::size_t at = 0; at < pixels; ++at) {
            rgb[3 * at] += wr * slice[at];
            rgb[3 * at + 1] += wg * slice[at];
            rgb[3 * at + 2] += wb * slice[at];
        }
    }
    return rgb;
}

template std::vector<float> render_slice<float>(const Heightfield&, const Query&, double, int,
                                                const RenderOptions&);
template std::vector<double> render_slice<double>(const Heightfield&, const Query&, double, int,
                                                  const RenderOptions&);
template std::vector<float> render_rgb<float>(const Heightfield&, const Query&,
                                              const std::vector<double>&, int, const RenderOptions&);
template std::vector<double> render_rgb<double>(const Heightfield&, const Query&,
                                                const std::vector<double>&, int, const RenderOptions&);

}  // namespace wavebrdf
