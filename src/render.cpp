// Entry points: validate, gather the footprint's kernels once, pick the path, and combine
// wavelengths into RGB.
#include <stdexcept>
#include <string>

#include "wavebrdf/brdf.h"
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

template <typename Float>
std::vector<Float> render_kernels(const FootprintKernels& kernels, const Query& query,
                                  double lambda_um, int resolution, const RenderOptions& options) {
    const bool separable = options.path == RenderPath::Separable ||
                           (options.path == RenderPath::Auto && is_separable(query.model));
    if (separable)
        return render_slice_separable<Float>(kernels, query, lambda_um, resolution, options.progress);
    return render_slice_direct<Float>(kernels, query, lambda_um, resolution,
                                      options.prune_tolerance, options.progress);
}

}  // namespace

template <typename Float>
std::vector<Float> render_slice(const Heightfield& heightfield, const Query& query,
                                double lambda_um, int resolution, const RenderOptions& options) {
    validate(query);
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    validate_options(options, query.model);
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
