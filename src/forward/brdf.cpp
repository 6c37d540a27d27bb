// Entry points: validate, check the memory, and render through a forward-only SlicePlan
// (slice_plan.h), which gathers the kernels once, picks the path and mixes wavelengths to RGB.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "wavebrdf/brdf.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/spectrum.h"
#include "core/text.h"

namespace wavebrdf {

long long work_units(int resolution) { return resolution; }

namespace {

// Auto: the separable engine for every model.
bool separable_path(const RenderOptions& options, Model) { return options.path != RenderPath::Direct; }

// Refuses, before any work, what estimate_render_bytes says cannot fit options.max_memory_gb.
void require_render_memory(const Heightfield& heightfield, const Query& query, int resolution,
                           const RenderOptions& options, std::size_t float_bytes, bool rgb) {
    const MemoryLimit limit = memory_limit(options.max_memory_gb);
    const double needed = estimate_render_bytes(heightfield, query, resolution, options, float_bytes, rgb);
    if (needed > limit.bytes)
        require_memory(needed, limit,
                       "render (" + std::to_string(resolution) + "x" + std::to_string(resolution) + " slice, " +
                           (float_bytes == 4 ? "float" : "double") + ")");
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
        // The field I and the engine's fields n² complex (Kirchhoff: three), the per-pixel c1
        // and S, the factor matrices (≤ 32 MiB) and the phase tables.
        const double fields = query.model == Model::Kirchhoff ? 4.0 : (is_separable(query.model) ? 1.0 : 2.0);
        bytes += pixels * (fields * 2.0 * double(float_bytes) + 16.0) +
                 std::min(32.0 * (1 << 20), 6.0 * n * kernels * double(float_bytes));
        bytes += n * 2.0 * std::min(kernels, 2.0 * reach + 1.0) * 16.0;
    } else {
        bytes += pixels * (16.0 + 8.0 + 8.0);  // field, c1 and value in double
    }
    return bytes;
}

template <typename Float>
std::vector<Float> render_slice(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                const RenderOptions& options) {
    validate(query);
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    validate(options, query.model);
    require_render_memory(heightfield, query, resolution, options, sizeof(Float), false);
    SlicePlan<Float> plan(heightfield, query, {lambda_um}, resolution, 1, options, false);
    return plan.forward();
}

namespace {

// The checks render_rgb makes of its arguments, from a heightfield or a Gabor representation.
void validate_rgb_arguments(const Query& query, const std::vector<double>& lambdas_um, int resolution,
                            const RenderOptions& options) {
    validate(query);
    validate_resolution(resolution);
    validate(options, query.model);
    if (lambdas_um.empty()) throw std::invalid_argument("no wavelengths given; expected at least one");
    for (double lambda : lambdas_um) validate_lambda(lambda);
}

}  // namespace

template <typename Float>
std::vector<Float> render_rgb(const Heightfield& heightfield, const Query& query, const std::vector<double>& lambdas_um,
                              int resolution, const RenderOptions& options) {
    validate_rgb_arguments(query, lambdas_um, resolution, options);
    require_render_memory(heightfield, query, resolution, options, sizeof(Float), true);
    SlicePlan<Float> plan(heightfield, query, lambdas_um, resolution, 3, options, false);
    return plan.forward();
}

template <typename Float>
std::vector<Float> render_rgb(const GaborRepresentation& rep, const Query& query, const std::vector<double>& lambdas_um,
                              int resolution, const RenderOptions& options) {
    validate_rgb_arguments(query, lambdas_um, resolution, options);
    if (query.x_um != rep.x_um || query.y_um != rep.y_um || query.sigma_p_um != rep.sigma_p_um)
        throw std::invalid_argument(
            "query footprint (" + detail::format_shortest(query.x_um) + ", " + detail::format_shortest(query.y_um) +
            ", sigma_p " + detail::format_shortest(query.sigma_p_um) + ") differs from the GaborRep's (" +
            detail::format_shortest(rep.x_um) + ", " + detail::format_shortest(rep.y_um) + ", sigma_p " +
            detail::format_shortest(rep.sigma_p_um) + "); expected the query the GaborRep was made for");
    const std::vector<double> mix = spectral_mix_weights(lambdas_um);
    const std::size_t pixels = static_cast<std::size_t>(resolution) * static_cast<std::size_t>(resolution);
    std::vector<Float> rgb(3 * pixels, Float(0));
    for (std::size_t l = 0; l < lambdas_um.size(); ++l) {
        const std::vector<Float> slice = separable_path(options, query.model)
                                             ? render_slice_separable<Float>(rep.kernels, query, lambdas_um[l],
                                                                             resolution, options.progress,
                                                                             options.tolerance)
                                             : render_slice_direct<Float>(rep.kernels, query, lambdas_um[l], resolution,
                                                                          options.prune_tolerance, options.progress);
        mix_spectral_to_rgb<Float>(mix, l, slice, rgb);
    }
    return rgb;
}

template std::vector<float> render_rgb<float>(const GaborRepresentation&, const Query&, const std::vector<double>&, int,
                                              const RenderOptions&);
template std::vector<double> render_rgb<double>(const GaborRepresentation&, const Query&, const std::vector<double>&,
                                                int, const RenderOptions&);
template std::vector<float> render_slice<float>(const Heightfield&, const Query&, double, int, const RenderOptions&);
template std::vector<double> render_slice<double>(const Heightfield&, const Query&, double, int, const RenderOptions&);
template std::vector<float> render_rgb<float>(const Heightfield&, const Query&, const std::vector<double>&, int,
                                              const RenderOptions&);
template std::vector<double> render_rgb<double>(const Heightfield&, const Query&, const std::vector<double>&, int,
                                                const RenderOptions&);

}  // namespace wavebrdf
