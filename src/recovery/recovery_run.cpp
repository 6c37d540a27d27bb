#include "wavebrdf/recovery_run.h"

#include "recovery/field_tiles.h"
#include "recovery/white_light.h"
#include "core/parallel.h"
#include "core/random.h"
#include "core/text.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "wavebrdf/constants.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/roughness_plan.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/texel_texture.h"

namespace wavebrdf {

RecoveryMethod parse_recovery_method(const std::string& text, const std::string& name) {
    if (text == "pipeline") return RecoveryMethod::Pipeline;
    if (text == "thesis") return RecoveryMethod::Thesis;
    throw std::invalid_argument(name + " '" + text + "' is unknown; expected pipeline or thesis");
}

const char* to_string(RecoveryMethod method) { return method == RecoveryMethod::Thesis ? "thesis" : "pipeline"; }

Loss recovery_loss(const RecoveryOptions& options) {
    if (options.loss) return *options.loss;
    // The thesis's method is the baseline as the thesis ran it: its own loss on any data.
    if (options.method == RecoveryMethod::Thesis) return Loss{LossKind::CMSLE, 1.0};
    return matched_loss(options.noise, Loss{LossKind::Amplitude, 1.0});
}

double estimate_recovery_bytes(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                               RecoveryMethod method, const RecoverSettings& settings) {
    const double texels = double(std::max(rows, 0)) * double(std::max(cols, 0));
    double references = 0.0, lambda_min = 0.0;
    // Per wavelength, the single-wavelength slices' pixels (the field stage works on one
    // wavelength at a time, the blurred fit on the longest).
    std::vector<std::pair<double, double>> pixels_per_lambda;
    for (const Observation& o : observations) {
        const double pixels = double(o.resolution) * double(o.resolution);
        references += pixels * double(o.lambdas_um.size() == 1 ? 1 : 3) * sizeof(float);  // Observation::reference
        // Weights, and the filled copy of the slices the whole-slice stages read
        // (observation_loss.h filled_observations).
        if (!o.weights.empty()) references += pixels * (1.0 + double(o.lambdas_um.size() == 1 ? 1 : 3)) * sizeof(float);
        for (double l : o.lambdas_um) lambda_min = lambda_min > 0.0 ? std::min(lambda_min, l) : l;
        if (o.lambdas_um.size() != 1) continue;
        auto it = std::find_if(pixels_per_lambda.begin(), pixels_per_lambda.end(),
                               [&](const auto& p) { return p.first == o.lambdas_um[0]; });
        if (it == pixels_per_lambda.end())
            pixels_per_lambda.push_back({o.lambdas_um[0], pixels});
        else
            it->second += pixels;
    }
    constexpr double base = 64e6;  // program, libraries, FFTW plans, per-thread slices
    if (method == RecoveryMethod::Thesis) return base + references + texels * 16.0 * sizeof(double);
    // Per slice pixel of one wavelength: the field stage's float √R and share of the √c1 maps
    // and factor matrices (shared by the footprints of a u grid: ~16 KB per 48² footprint, about
    // a double per pixel), and with position calibration a copy of that wavelength's references
    // (a float; without it the stage reads them where they are). The blurred fit's matrices
    // are shared per wavelength and width (small).
    const double per_pixel = sizeof(double) + (settings.calibrate.positions ? sizeof(float) : 0.0);
    double largest_stage = 0.0;
    for (const auto& p : pixels_per_lambda) largest_stage = std::max(largest_stage, per_pixel * p.second);
    int refine = settings.refine;
    if (refine <= 0 && lambda_min > 0.0 && texel_um > 0.0) refine = auto_refine(texel_um, lambda_min);
    const double samples = texels * double(std::max(refine, 1)) * double(std::max(refine, 1));
    // Object (complex) and its L-BFGS: x, gradient and `history` pairs of 2·samples floats, on
    // the whole surface or on one field tile (field_tiles.h: then also the fields of every
    // wavelength and their blend on the whole surface).
    double field_samples = samples, tiled_fields = 0.0;
    const detail::FieldTiling tiling{settings.field_tile_threshold, settings.field_tile_core};
    if (!settings.calibrate.positions && detail::field_tiles_apply(rows, cols, tiling) && texel_um > 0.0) {
        double sigma_max = 0.0;
        for (const Observation& o : observations) sigma_max = std::max(sigma_max, o.query.sigma_p_um);
        const double margin = std::ceil(3.0 * sigma_max / texel_um + 1.0) + tiling.ramp;
        const double tile_rows = std::min(double(rows), tiling.core + 1.0 + 2.0 * margin);
        const double tile_cols = std::min(double(cols), tiling.core + 1.0 + 2.0 * margin);
        field_samples = tile_rows * tile_cols * double(std::max(refine, 1)) * double(std::max(refine, 1));
        tiled_fields = samples * 2.0 * sizeof(double) * double(pixels_per_lambda.size() + 2);
        // The tiles' objects in complex float, kept until all are in for the joint alignment
        // (blend_field_tiles): the surface's samples times the tiles' overlap factor.
        const double core_rows = std::min(double(rows), double(tiling.core)),
                     core_cols = std::min(double(cols), double(tiling.core));
        tiled_fields += samples * 2.0 * sizeof(float) * (tile_rows * tile_cols) / (core_rows * core_cols);
    }
    // The pairs in float (LbfgsOptions::float_history: 2 · history vectors of 2·samples floats),
    // six vectors of 2·samples doubles besides (x, gradient, trial, directions).
    const double field_history =
        field_samples * 2.0 * (2.0 * settings.field.history * sizeof(float) + 6.0 * sizeof(double)) + tiled_fields;
    const double refine_history = texels * sizeof(double) * (2.0 * settings.refine_history + 8.0);
    // The model check (recover_field_model.h) on the whole surface's fine grid: one
    // wavelength's object (complex), the fine heights and gradient, the exact sum's
    // accumulator (16 bytes per value), and per thread a scratch and an object gradient
    // (complex); its operators share their factors (small).
    const double threads = double(std::max(1, omp_get_max_threads()));
    const double model_check = settings.model_check_iterations > 0
                                   ? samples * (2.0 * sizeof(double) + 2.0 * sizeof(double) + 16.0 +
                                                threads * 3.0 * sizeof(double)) +
                                         refine_history
                                   : 0.0;
    // The refinement keeps one plan per observation between iterations: its footprint's
    // kernels (two ints, seven doubles each, within 3σ_p) and ~2 KB of grids and bookkeeping;
    // the per-pixel factors are shared (slice_plan.h, release).
    double refine_plans = 0.0;
    for (const Observation& o : observations) {
        const double radius_texels = texel_um > 0.0 ? 3.0 * o.query.sigma_p_um / texel_um : 0.0;
        const double kernels = std::min(texels, k_pi * (radius_texels + 1.0) * (radius_texels + 1.0));
        refine_plans += 2048.0 + kernels * (2.0 * sizeof(int) + 7.0 * sizeof(double));
    }
    // The stages one after another (the fields are released before the refinement, its plans
    // before the model check): the largest of them on top of the references.
    const double field_stage = largest_stage + field_history;
    const double refinement = refine_history + refine_plans;
    return base + references + std::max({field_stage, refinement, model_check});
}

Heightfield generated_recovery_truth(const RecoveryOptions& options) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = options.rows;
    p.cols = options.cols;
    p.texel_um = options.texel_um;
    p.correlation_um = options.correlation_texels * options.texel_um;
    p.seed = options.seed;
    return with_height_range(generate_heightfield(p).with_scale(options.texel_um, options.vscale),
                             options.height_range_um);
}

namespace {

// The observations without their references.
std::vector<Observation> metadata_of(const std::vector<Observation>& observations) {
    std::vector<Observation> out;
    out.reserve(observations.size());
    for (const Observation& o : observations) {
        Observation m;
        m.query = o.query;
        m.lambdas_um = o.lambdas_um;
        m.resolution = o.resolution;
        out.push_back(std::move(m));
    }
    return out;
}

// Throws std::invalid_argument when the footprint centres of `observations` span a full tile
// period or more along x or y (max − min ≥ rows · texel_um, or cols · texel_um): positions that
// far apart were made on a larger surface than the rows × cols one asked for (a --size that
// disagrees with the observations ran to a 100 times worse loss with exit 0).
void check_observation_extent(const std::vector<Observation>& observations, int rows, int cols, double texel_um) {
    const std::string option = "--size";
    if (observations.empty() || !(texel_um > 0.0)) return;
    double lo[2] = {observations[0].query.x_um, observations[0].query.y_um}, hi[2] = {lo[0], lo[1]};
    for (const Observation& o : observations) {
        const double p[2] = {o.query.x_um, o.query.y_um};
        for (int a = 0; a < 2; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    const double period[2] = {rows * texel_um, cols * texel_um};
    const char* axis[2] = {"x", "y"};
    for (int a = 0; a < 2; ++a)
        if (hi[a] - lo[a] >= period[a] * (1.0 - 1e-12))
            throw std::invalid_argument(
                "the observations' footprint centres span " + detail::format_shortest(hi[a] - lo[a]) + " um along " +
                axis[a] + " (" + detail::format_shortest(lo[a]) + " to " + detail::format_shortest(hi[a]) +
                " um), a full period or more of the " + std::to_string(rows) + "x" + std::to_string(cols) +
                " surface asked for (" + option + ", texel " + detail::format_shortest(texel_um) + " um: period " +
                detail::format_shortest(period[a]) +
                " um); expected the size of the surface the observations were made of");
}

// Throws std::invalid_argument when the footprints of `observations` leave a band of texel rows
// or columns of the rows × cols tile that none of them reaches: the renderer reads the texels
// within 3σ_p of a footprint's centre only (gabor.h), so heights there are not observed at all —
// a --size larger than the surface the observations were made of. Per axis: the centres reduced
// modulo the period, sorted; between neighbours (and across the wrap) the part farther than 3σ_p
// (the largest σ_p of the set) from both. A band wider than one texel holds a texel's centre.
void check_observation_coverage(const std::vector<Observation>& observations, int rows, int cols, double texel_um) {
    if (observations.empty() || !(texel_um > 0.0)) return;
    double radius = 0.0;
    for (const Observation& o : observations) radius = std::max(radius, 3.0 * o.query.sigma_p_um);
    const double period[2] = {rows * texel_um, cols * texel_um};
    const char* axis[2] = {"x", "y"};
    const char* lines[2] = {"rows", "columns"};
    for (int a = 0; a < 2; ++a) {
        if (!(2.0 * radius < period[a])) continue;  // one footprint reaches across the whole period
        std::vector<double> centres;
        centres.reserve(observations.size());
        for (const Observation& o : observations) {
            double c = std::fmod(a == 0 ? o.query.x_um : o.query.y_um, period[a]);
            if (c < 0.0) c += period[a];
            centres.push_back(c);
        }
        std::sort(centres.begin(), centres.end());
        double widest = 0.0, from = 0.0;
        for (std::size_t k = 0; k < centres.size(); ++k) {
            const double next = k + 1 < centres.size() ? centres[k + 1] : centres.front() + period[a];
            const double band = (next - centres[k]) - 2.0 * radius;
            if (band > widest) {
                widest = band;
                from = std::fmod(centres[k] + radius, period[a]);
            }
        }
        if (widest > texel_um * (1.0 + 1e-12))
            throw std::invalid_argument(
                "no observation's footprint (3 sigma_p = " + detail::format_shortest(radius) +
                " um about its centre) reaches the texel " + lines[a] + " from " + axis[a] + " = " +
                detail::format_shortest(from) + " to " + detail::format_shortest(from + widest) + " um of the " +
                std::to_string(rows) + "x" + std::to_string(cols) + " surface asked for (--size, texel " +
                detail::format_shortest(texel_um) + " um: period " + detail::format_shortest(period[a]) +
                " um), a band " + detail::format_shortest(widest) +
                " um wide whose heights they cannot tell; expected the size of the surface the observations were "
                "made of");
    }
}

// The most laser wavelengths a recovery takes (RecoveryOptions::lambdas_um): a plan's ladder
// has a handful; 300 ran past 100 s before any check.
constexpr std::size_t k_max_laser_wavelengths = 64;

// The stage's position uncertainty, µm rms per coordinate: stated, else the simulated error's.
double position_uncertainty_um(const RecoveryOptions& options, double texel_um) {
    return options.position_uncertainty_um.value_or(options.errors.position_rms_texels * texel_um);
}

}  // namespace

void check_recovery_options(const RecoveryOptions& options, const RecoveryInputs& given) {
    const auto name = [&](const std::string& key) { return option_name(options.names, key); };
    const std::string truth = name("truth"), observations = name("observations");
    if (given.truth && given.observations)
        throw std::invalid_argument(truth + " and " + observations +
                                    " exclude each other; expected one of them (or neither)");
    if (options.plan_only && given.observations)
        throw std::invalid_argument(name("plan_only") + " plans the acquisition of a truth; with " + observations +
                                    " there is nothing to plan; expected " + truth + " or the generated truth");
    if (options.noise.kind != NoiseKind::None && given.observations)
        throw std::invalid_argument(name("noise") + " '" + to_string(options.noise) +
                                    "' simulates noise on rendered observations; it needs " + truth +
                                    " (or the generated default), not " + observations);
    if (options.simulator != Simulator::Gabor && given.observations)
        throw std::invalid_argument(name("simulator") + " '" + to_string(options.simulator) +
                                    "' simulates observations of a truth; it needs " + truth +
                                    " (or the generated default), not " + observations);
    if (options.plan_from_truth && !given.truth)
        throw std::invalid_argument(name("plan_from_truth") +
                                    " plans for a given truth's measured roughness; expected " + truth + " (not " +
                                    observations + " or the generated default)");
    if (options.plan_from_truth && given.correlation)
        throw std::invalid_argument(name("plan_from_truth") + " and " + name("correlation_texels") +
                                    " exclude each other; expected one of them (the measured roughness, or the "
                                    "stated correlation length)");
    if (options.overlap && !(*options.overlap >= 0.6 && *options.overlap <= 0.95))
        throw std::invalid_argument(name("overlap") + " " + detail::format_shortest(*options.overlap) +
                                    " is invalid; expected 0.6 to 0.95 (unset: the planner's, 0.6, or 0.8 with the "
                                    "positions calibrated)");
    if (!(std::isfinite(options.target_error) && options.target_error >= 0.0 && options.target_error <= 1.0))
        throw std::invalid_argument(name("target_error") + " " + detail::format_shortest(options.target_error) +
                                    " is invalid; expected 0 (no photon planning) to 1 (a fraction of the peak to "
                                    "valley)");
    if (options.max_exposures < 1 || options.max_exposures > 10000)
        throw std::invalid_argument(name("max_exposures") + " " + std::to_string(options.max_exposures) +
                                    " is invalid; expected 1 to 10000 exposures per slice");
    if (!std::isfinite(options.max_memory_gb) || options.max_memory_gb < 0.0)
        throw std::invalid_argument(name("max_memory_gb") + " " + detail::format_shortest(options.max_memory_gb) +
                                    " is invalid; expected a limit in GB > 0, or 0 for the physical memory");
    // The sentinels first: -1 is "the library's default"; another negative or a NaN is a
    // mistake (an option given as -5 or nan).
    {
        const std::pair<const char*, long long> counts[] = {
            {"field_iterations", options.field_iterations},
            {"refine_iterations", options.refine_iterations},
            {"refine_coarse_iterations", options.refine_coarse_iterations},
            {"white_smoothness_iterations", options.white_smoothness_iterations},
            {"position_passes", options.position_passes},
            {"field_tile_threshold", options.field_tile_threshold},
            {"field_tile_core", options.field_tile_core}};
        for (const auto& [key, value] : counts)
            if (value < -1)
                throw std::invalid_argument(name(key) + " " + std::to_string(value) +
                                            " is invalid; expected 0 or more (unset: the default)");
        const std::pair<const char*, double> weights[] = {{"refine_coarse_spacing", options.refine_coarse_spacing},
                                                          {"refine_coarse_weight", options.refine_coarse_weight}};
        for (const auto& [key, value] : weights)
            if (std::isnan(value) || (value < 0.0 && value != -1.0) || std::isinf(value))
                throw std::invalid_argument(name(key) + " " + detail::format_shortest(value) +
                                            " is invalid; expected a finite value >= 0 (unset: the default)");
        if (options.lambdas_um.size() > k_max_laser_wavelengths)
            throw std::invalid_argument(name("lambdas_um") + " lists " + std::to_string(options.lambdas_um.size()) +
                                        " wavelengths; expected at most " + std::to_string(k_max_laser_wavelengths));
    }
    // Counts first, before the observations are planned and rendered (negative iteration counts: the library's default).
    validate_iterations(options.epochs, name("epochs"));
    if (options.field_iterations >= 0) validate_iterations(options.field_iterations, name("field_iterations"));
    if (options.refine_iterations >= 0) validate_iterations(options.refine_iterations, name("refine_iterations"));
    if (options.refine_coarse_iterations >= 0)
        validate_iterations(options.refine_coarse_iterations, name("refine_coarse_iterations"));
    if (options.position_passes > 100)
        throw std::invalid_argument(name("position_passes") + " " + std::to_string(options.position_passes) +
                                    " is invalid; expected 0 to 100 (0: off)");
    if (options.field_tile_threshold > 1000000)
        throw std::invalid_argument(name("field_tile_threshold") + " " + std::to_string(options.field_tile_threshold) +
                                    " texels is invalid; expected 0 to 1000000");
    if (options.white_smoothness) detail::check_white_smoothness(*options.white_smoothness, name("white_smoothness"));
    if (options.white_smoothness_iterations >= 0)
        validate_iterations(options.white_smoothness_iterations, name("white_smoothness_iterations"));
    if (options.field_tile_core >= 0 && (options.field_tile_core < 8 || options.field_tile_core > 4096))
        throw std::invalid_argument(name("field_tile_core") + " " + std::to_string(options.field_tile_core) +
                                    " texels is invalid; expected 8 to 4096");
    if (options.position_uncertainty_um &&
        !(*options.position_uncertainty_um >= 0.0 && *options.position_uncertainty_um <= 1e6))
        throw std::invalid_argument(name("position_uncertainty_um") + " " +
                                    detail::format_shortest(*options.position_uncertainty_um) +
                                    " is invalid; expected 0 to 1e6 (um rms per coordinate)");
    if (options.spectral != 0 &&
        (options.spectral < 2 || options.spectral > k_max_spectral_samples || !options.lambdas_um.empty()))
        throw std::invalid_argument(name("spectral") + " " + std::to_string(options.spectral) +
                                    " is invalid; expected 2 ... " + std::to_string(k_max_spectral_samples) +
                                    " wavelengths, without given wavelengths (0: laser slices)");
    check_acquisition_errors(options.errors, options.names == OptionStyle::Cli ? "--simulate-" : "simulate_");
    if (options.errors.any() && given.observations)
        throw std::invalid_argument((options.names == OptionStyle::Cli ? "--simulate-*" : "simulate_*") +
                                    std::string(" render the observations with acquisition errors; they need ") +
                                    truth + " (or the generated default), not " + observations);
    // The pipeline's field retrieval needs single-wavelength separable slices: checked here,
    // before the observations are simulated, not after.
    if (options.method == RecoveryMethod::Pipeline && !given.observations && options.spectral == 0 &&
        options.model == Model::Kirchhoff)
        throw std::invalid_argument(name("model") + " " + to_string(options.model) +
                                    " has no field stage; the pipeline expects OHS, ROHS, GHS or RGHS "
                                    "(or the thesis's method)");
}

namespace {

// check_recovery_options with what prepare_recovery was given, and what needs the ranks.
// Returns the memory limit the run is held to.
MemoryLimit checked_options(const RecoveryOptions& options, const Heightfield* truth,
                            const std::vector<Observation>& observations, const Communicator& comm) {
    RecoveryInputs given;
    given.truth = truth != nullptr;
    given.observations = !observations.empty();
    check_recovery_options(options, given);
    const MemoryLimit limit = memory_limit(options.max_memory_gb);
    if (comm.size() > 1 && options.method == RecoveryMethod::Thesis)
        throw std::invalid_argument(
            "method thesis runs on one process (Adam draws one observation at a time); "
            "expected the pipeline under MPI (" +
            std::to_string(comm.size()) + " ranks)");
    return limit;
}

// Given observations: this rank's share (under MPI `catalogue` gets every observation's
// metadata), checked against the grid's extent and the memory limit.
void take_given_observations(PreparedRecovery& r, const RecoveryOptions& options, std::vector<Observation> observations,
                             const MemoryLimit& limit, const Communicator& comm, std::vector<Observation>& catalogue) {
    r.total_observations = observations.size();
    r.share = observation_share(footprint_centres(observations), comm.rank(), comm.size());
    if (comm.size() > 1) {
        catalogue = metadata_of(observations);
        for (std::size_t k = 0; k < r.share.size(); ++k) r.observations.push_back(std::move(observations[r.share[k]]));
        observations.clear();
        observations.shrink_to_fit();
    } else {
        r.observations = std::move(observations);
    }
    r.rows = options.rows;
    r.cols = options.cols;
    check_observation_extent(comm.size() > 1 ? catalogue : r.observations, r.rows, r.cols, r.texel_um);
    check_observation_coverage(comm.size() > 1 ? catalogue : r.observations, r.rows, r.cols, r.texel_um);
    require_memory(estimate_recovery_bytes(r.observations, r.rows, r.cols, r.texel_um, options.method), limit,
                   "recover (" + std::to_string(r.rows) + "x" + std::to_string(r.cols) + " heights, " +
                       std::to_string(r.observations.size()) + " given observations)");
}

// The planned acquisition of a truth (r.truth, its grid and range set), with the surface's
// measured roughness where options.plan_from_truth asks for it.
struct TruthAcquisition {
    AcquisitionPlan plan;
    std::optional<RoughnessPlan> measured;
    std::optional<MeasuredRoughness> measured_roughness;
};

TruthAcquisition plan_truth_acquisition(const PreparedRecovery& r, const RecoveryOptions& options,
                                        bool truth_given, const MeasuredRoughness* given_roughness = nullptr) {
    PlanRequest request;
    request.rows = r.rows;
    request.cols = r.cols;
    request.texel_um = r.texel_um;
    request.height_range_um = r.range_um;
    request.sigma_p_um = options.sigma_p_um;
    request.position_uncertainty_um = position_uncertainty_um(options, r.texel_um);
    if (options.overlap)
        request.overlap = *options.overlap;
    else if (options.calibrate.positions)
        request.overlap = k_position_calibration_overlap;  // else the planner's default
    request.jitter = options.jitter;
    request.omega_i = options.omega_i;
    request.model = options.model;
    request.seed = options.seed;
    request.lambdas_um = options.lambdas_um;
    request.resolution = options.resolution;
    std::vector<double> white;
    if (options.spectral != 0) {
        white = spectral_wavelengths_um(options.spectral);
        request.lambdas_um = {*std::min_element(white.begin(), white.end())};  // sizes the slices
    }
    TruthAcquisition a{plan_acquisition(request), std::nullopt, std::nullopt};
    // Rough surfaces (roughness_plan.h): long wavelengths for the field stage's start.
    // Steep ones: oblique lights, so that their steep facets reflect into a slice.
    if (options.plan_from_truth && truth_given && r.range_um > 0.0) {
        a.measured_roughness = given_roughness ? *given_roughness : measure_roughness(*r.truth);
        a.measured = plan_for_measured_roughness(*a.measured_roughness, r.texel_um);
    }
    if (options.method == RecoveryMethod::Pipeline && white.empty() && options.correlation_texels > 0.0 &&
        r.range_um > 0.0) {
        const RoughnessPlan rough =
            a.measured ? *a.measured : plan_for_roughness(r.range_um, options.correlation_texels * r.texel_um, r.texel_um);
        if (options.lambdas_um.empty()) add_long_wavelengths(rough, a.plan);
        if (options.oblique_lights) add_oblique_lights(rough, a.plan);
    }
    if (!white.empty()) {
        a.plan.white_lambdas_um = white;
        a.plan.notes.push_back("white light: one RGB slice per position, " + std::to_string(white.size()) +
                               " wavelengths");
    }
    return a;
}

// With acquisition errors: the true (perturbed) acquisition the observations are rendered for;
// `offsets` gets each position's offset (µm).
AcquisitionPlan perturbed_plan(const AcquisitionPlan& plan, const AcquisitionErrors& e, double texel_um,
                               std::vector<std::array<double, 2>>& offsets) {
    AcquisitionPlan true_plan = plan;
    offsets.assign(plan.positions_um.size(), {});
    if (!e.any()) return true_plan;
    true_plan.sigma_p_um *= e.sigma_p_factor;
    for (std::size_t p = 0; p < offsets.size(); ++p) offsets[p] = simulated_position_offset_um(e, p, texel_um);
    // Mean-free: a common offset of every position is a shift of the whole surface, which
    // no slice sees (the recovery's gauge puts the surface where the stated positions do),
    // so height_rel_rmse would measure that shift rather than the recovery.
    std::array<double, 2> mean{{0.0, 0.0}};
    for (const auto& o : offsets)
        for (int c = 0; c < 2; ++c) mean[std::size_t(c)] += o[std::size_t(c)] / double(offsets.size());
    for (std::size_t p = 0; p < offsets.size(); ++p) {
        for (int c = 0; c < 2; ++c) offsets[p][std::size_t(c)] -= mean[std::size_t(c)];
        true_plan.positions_um[p][0] += offsets[p][0];
        true_plan.positions_um[p][1] += offsets[p][1];
    }
    return true_plan;
}

// The plan's notes and its slices' count as r's; returns every planned slice, not rendered.
std::vector<Observation> adopt_plan(PreparedRecovery& r, const AcquisitionPlan& plan) {
    r.notes = plan.notes;
    std::vector<Observation> planned = planned_observations(plan);
    r.total_observations = planned.size();
    return planned;
}

// This rank's share of the plan's observations rendered from r.truth (with acquisition errors:
// for the true acquisition, handed over with the nominal one, and r.true_calibration set).
// Under MPI `catalogue` gets every planned observation.
void simulate_planned_observations(PreparedRecovery& r, const RecoveryOptions& options, const AcquisitionPlan& plan,
                                   const MemoryLimit& limit, bool show_progress, const Communicator& comm,
                                   std::vector<Observation>& catalogue) {
    const std::vector<Observation> planned = adopt_plan(r, plan);
    r.share = observation_share(footprint_centres(planned), comm.rank(), comm.size());
    std::vector<Observation> mine;
    for (std::size_t i : r.share) mine.push_back(planned[i]);
    require_memory(estimate_recovery_bytes(mine, r.rows, r.cols, r.texel_um, options.method), limit,
                   "recover (" + std::to_string(r.rows) + "x" + std::to_string(r.cols) + " heights, " +
                       std::to_string(mine.size()) + " observations of " + std::to_string(plan.resolution) + "x" +
                       std::to_string(plan.resolution) + ")");
    Progress progress("simulate", static_cast<long long>(r.share.size()), show_progress && comm.is_root());
    const AcquisitionErrors& e = options.errors;
    std::vector<std::array<double, 2>> offsets;
    const AcquisitionPlan true_plan = perturbed_plan(plan, e, r.texel_um, offsets);
    if (options.simulator == Simulator::Scalar)
        r.observations =
            simulate_scalar_observations(*r.truth, true_plan, options.noise, options.seed, r.share, {}, &progress);
    else
        r.observations = comm.size() > 1 || e.any()
                             ? simulate_observations(*r.truth, true_plan, options.noise, options.seed, r.share,
                                                     &progress)
                             : simulate_observations(*r.truth, plan, options.noise, options.seed, &progress);
    if (e.any()) {
        Calibration t;
        t.sigma_p_scale = e.sigma_p_factor;
        const std::size_t per_position = std::max<std::size_t>(observations_per_position(plan), 1);
        for (std::size_t k = 0; k < r.share.size(); ++k) {
            Observation& o = r.observations[k];
            const double exposure = simulated_exposure(e, r.share[k]);
            for (float& v : o.reference) v = float(double(v) * exposure);
            o.query = planned[r.share[k]].query;  // the stated acquisition
            t.exposures.push_back(exposure);
            t.position_offsets_um.push_back(offsets[r.share[k] / per_position]);
        }
        r.true_calibration = std::move(t);
    }
    progress.finish();
    if (comm.size() > 1) catalogue = std::move(planned);
}

// The pipeline's inputs as the caller stated them: loss, calibration, the surface (the
// schedule, recover.h's scheduled_settings, takes the smooth or the rough-surface plan from
// it) and the counts the caller set; the rest stays unset for the schedule.
void state_pipeline_settings(PreparedRecovery& r, const RecoveryOptions& options,
                             const std::optional<RoughnessPlan>& measured,
                             const std::optional<MeasuredRoughness>& measured_roughness) {
    r.pipeline.refine_loss = r.loss;
    r.pipeline.calibrate = options.calibrate;
    // The position loop's rescue reaches as far as the stated uncertainty: ± k × it about a lost
    // position's offset and stated centre (the schedule keeps its grid's number of points).
    const double rescue_radius_texels = std::min(
        k_rescue_radius_per_position_uncertainty * position_uncertainty_um(options, r.texel_um) / r.texel_um, 16.0);
    if (options.calibrate.positions && rescue_radius_texels > r.pipeline.position_rescue_radius_texels)
        r.pipeline.position_rescue_radius_texels = rescue_radius_texels;
    r.pipeline.surface.height_range_um = r.range_um;
    r.pipeline.surface.correlation_um = options.correlation_texels * r.texel_um;
    r.pipeline.surface.measured = measured_roughness;
    if (options.method == RecoveryMethod::Pipeline && r.range_um > 0.0 && options.correlation_texels > 0.0) {
        const RoughnessPlan rough =
            measured ? *measured : plan_for_roughness(r.range_um, options.correlation_texels * r.texel_um, r.texel_um);
        r.notes.insert(r.notes.end(), rough.notes.begin(), rough.notes.end());
    }
    if (options.field_iterations >= 0) r.pipeline.field.iterations = options.field_iterations;
    if (options.refine_iterations >= 0) r.pipeline.refine_iterations = options.refine_iterations;
    if (options.position_passes >= 0) r.pipeline.position_outer_passes = options.position_passes;
    if (options.field_tile_threshold >= 0) r.pipeline.field_tile_threshold = options.field_tile_threshold;
    if (options.field_tile_core >= 0) r.pipeline.field_tile_core = options.field_tile_core;
    if (options.refine_coarse_spacing >= 0.0) r.pipeline.refine_coarse_spacing = options.refine_coarse_spacing;
    if (options.refine_coarse_weight >= 0.0) r.pipeline.refine_coarse_weight = options.refine_coarse_weight;
    if (options.refine_coarse_iterations >= 0) r.pipeline.refine_coarse_iterations = options.refine_coarse_iterations;
    if (options.white_smoothness) r.pipeline.white_smoothness = *options.white_smoothness;
    if (options.white_smoothness_iterations >= 0)
        r.pipeline.white_smoothness_iterations = options.white_smoothness_iterations;
    r.pipeline.error_bars = options.uncertainty;
}

// `truth` as the run's truth, with the grid, texel and vertical scale it carries.
void set_truth(PreparedRecovery& r, Heightfield truth) {
    r.rows = truth.rows();
    r.cols = truth.cols();
    r.texel_um = truth.texel_um();
    r.vscale = truth.vscale();
    r.truth = std::move(truth);
}

// A recovery of `tile` as the pilot's truth, planned for the full tile's range `range_um` (the same
// wavelengths and bounds as the full run).
PreparedRecovery pilot_tile_run(const Heightfield& tile, double range_um) {
    PreparedRecovery p;
    set_truth(p, tile);
    p.range_um = range_um;
    return p;
}

// One draw of the photon plan's pilot (photon_plan.h): the recovery of `tile` (planned as `a`,
// the full run's roughness and schedule) from its Poisson slices of `photons` simulated with
// `seed`; its rms height error in µm (means removed). One process (rank 0 draws).
double photon_pilot_error_um(const Heightfield& tile, double range_um, const RecoveryOptions& options,
                             const TruthAcquisition& a, double photons, std::uint64_t seed, const MemoryLimit& limit) {
    PreparedRecovery p = pilot_tile_run(tile, range_um);
    RecoveryOptions o = options;
    o.noise.level = photons;
    o.seed = seed;
    p.noise = o.noise;
    p.loss = recovery_loss(o);
    std::vector<Observation> catalogue;
    simulate_planned_observations(p, o, a.plan, limit, false, serial_communicator(), catalogue);
    state_pipeline_settings(p, o, a.measured, a.measured_roughness);
    const Heightfield estimate = recover_heights(p.observations, p.rows, p.cols, p.texel_um, p.vscale, p.pipeline);
    const HeightStats stats = height_stats(tile);
    return height_rel_rmse(estimate, tile) * (stats.max_um - stats.min_um);
}

// The pilot's ratio from its draws' errors² x and their tiles' predicted errors² y: ρ = √(Σx / Σy)
// (measured_rms_um and predicted_rms_um their rms), its standard error by the delta method on the
// ratio of means: se(R) = √(Σ(x − R y)² / (n (n − 1))) / ȳ, se(ρ) = se(R) / (2ρ).
void ratio_of_draws(const std::vector<double>& x, const std::vector<double>& y, PhotonPilot& pilot) {
    const double n = double(x.size());
    double sx = 0.0, sy = 0.0;
    for (std::size_t d = 0; d < x.size(); ++d) {
        sx += x[d];
        sy += y[d];
    }
    const double ratio2 = sx / sy;
    double spread = 0.0;
    for (std::size_t d = 0; d < x.size(); ++d) spread += (x[d] - ratio2 * y[d]) * (x[d] - ratio2 * y[d]);
    pilot.measured_rms_um = std::sqrt(sx / n);
    pilot.predicted_rms_um = std::sqrt(sy / n);
    pilot.ratio = std::sqrt(ratio2);
    pilot.ratio_sd = n > 1.0 ? std::sqrt(spread / (n * (n - 1.0))) / (sy / n) / (2.0 * pilot.ratio) : 0.0;
}

// A pilot tile (photon_plan.h): the size² cut at row0, col0 of r.truth, its acquisition planned
// as the full run's (the full tile's range and measured roughness) and its first-order
// prediction with `exposures` by the full tile's plan (its variance spectrum, the tile's heights).
struct PilotTile {
    PreparedRecovery run;
    TruthAcquisition a;
    double predicted_um = 0.0;
};

PilotTile pilot_tile(const PreparedRecovery& r, const RecoveryOptions& options, const TruthAcquisition& full,
                     bool truth_given, int row0, int col0, int size, int exposures) {
    PilotTile t;
    t.run = pilot_tile_run(photon_proxy_tile_at(*r.truth, row0, col0, size, size), r.range_um);
    t.a = plan_truth_acquisition(t.run, options, truth_given,
                                 full.measured_roughness ? &*full.measured_roughness : nullptr);
    t.predicted_um = photon_plan_rms_um(*t.run.truth, *r.photon_plan, exposures);
    return t;
}

// The radical inverse of d in `base` (0 … 1): the Halton sequence that spreads the draws' tiles.
double radical_inverse(int d, int base) {
    double x = 0.0, f = 1.0 / base;
    for (; d > 0; d /= base, f /= base) x += f * (d % base);
    return x;
}

// The photon plan's pilot (photon_plan.h): the recovery itself on square tiles of side
// photon_pilot_tile_texels of r.truth at the first-order plan's exposures, draw d on the cell (Halton(d, 2), Halton(d, 3)) of the
// tile's grid of such cells (so the draws spread over the surface), until the decision is made,
// against the first-order prediction for the same tiles; or why not.
PhotonPilot run_photon_pilot(const PreparedRecovery& r, const RecoveryOptions& options, const TruthAcquisition& full,
                             bool truth_given, const MemoryLimit& limit, const Communicator& comm) {
    const PhotonPlan& plan = *r.photon_plan;
    PhotonPilot pilot;
    pilot.first_order_exposures = plan.exposures;
    if (plan.capped) {
        pilot.why_not = "the first-order plan is already capped";
        return pilot;
    }
    if (plan.rms_um * k_photon_pilot_band < options.target_error * plan.range_um) {
        pilot.why_not = "the first-order prediction is below the target / " + format_number(k_photon_pilot_band, "%.3g");
        return pilot;
    }
    if (!comm.is_root()) return pilot;  // rank 0 draws; share_photon_pilot hands its result on
    const double cpu_before = process_cpu_seconds();
    pilot.exposures = plan.exposures;
    // The full tile's first-order prediction by exposures (memoised: the bias is a sum over its
    // spectrum) and the exposures a ratio asks for.
    std::vector<double> full_rms(std::size_t(options.max_exposures) + 1, -1.0);
    const auto exposures_at = [&](double ratio) {
        return exposures_for_target(
            [&](int k) {
                double& v = full_rms[std::size_t(k)];
                if (v < 0.0) v = photon_plan_rms_um(*r.truth, plan, k);
                return std::max(1.0, ratio) * v;
            },
            options.target_error * plan.range_um, options.max_exposures);
    };
    const int n = photon_pilot_tile_texels(r.rows, r.cols);
    const int grid_rows = std::max(1, r.rows / n), grid_cols = std::max(1, r.cols / n);
    std::vector<std::optional<PilotTile>> tiles(std::size_t(grid_rows) * std::size_t(grid_cols));
    std::vector<double> x, y;  // each draw's error² and its tile's predicted error²
    const int max_draws = photon_pilot_max_draws(n, n);
    for (int d = 0; d < max_draws; ++d) {
        const int gr = std::min(grid_rows - 1, int(radical_inverse(d, 2) * grid_rows));
        const int gc = std::min(grid_cols - 1, int(radical_inverse(d, 3) * grid_cols));
        std::optional<PilotTile>& t = tiles[std::size_t(gr) * std::size_t(grid_cols) + std::size_t(gc)];
        if (!t)
            t = pilot_tile(r, options, full, truth_given, gr * (r.rows / grid_rows) + (r.rows / grid_rows - n) / 2,
                           gc * (r.cols / grid_cols) + (r.cols / grid_cols - n) / 2, n, plan.exposures);
        const double e = photon_pilot_error_um(*t->run.truth, r.range_um, options, t->a,
                                               options.noise.level * plan.exposures,
                                               detail::derive_seed(options.seed, 0x9170 + std::uint64_t(d)), limit);
        pilot.errors_um.push_back(e);
        pilot.predicted_um.push_back(t->predicted_um);
        pilot.rows = t->run.rows;
        pilot.cols = t->run.cols;
        x.push_back(e * e);
        y.push_back(t->predicted_um * t->predicted_um);
        ratio_of_draws(x, y, pilot);
        set_photon_pilot_spread(pilot, r.rows, r.cols);
        // U (photon_plan.h) lies within ρ + z s_N ± z se: stop when both ends ask the same exposures.
        const double centre = pilot.ratio + k_photon_pilot_z * pilot.run_sd;
        const double half = k_photon_pilot_z * pilot.ratio_sd;
        if (d + 1 >= k_photon_pilot_min_draws && exposures_at(centre - half) == exposures_at(centre + half)) break;
    }
    for (const auto& t : tiles) pilot.tiles += t ? 1 : 0;
    pilot.ran = true;
    pilot.cpu_seconds = process_cpu_seconds() - cpu_before;
    return pilot;
}

// Rank 0's pilot on every rank (the same exposures everywhere). Collective.
void share_photon_pilot(PhotonPilot& pilot, const Communicator& comm) {
    if (comm.size() == 1 || !pilot.why_not.empty()) return;  // why_not: the same on every rank
    double head[12] = {double(pilot.ran),        double(pilot.rows),          double(pilot.cols),
                       double(pilot.exposures),  double(pilot.errors_um.size()), pilot.measured_rms_um,
                       pilot.predicted_rms_um,   pilot.ratio,                 pilot.ratio_sd,
                       pilot.cpu_seconds,        double(pilot.first_order_exposures), double(pilot.tiles)};
    comm.broadcast(head, 12);
    pilot.ran = head[0] != 0.0;
    pilot.rows = int(head[1]);
    pilot.cols = int(head[2]);
    pilot.exposures = int(head[3]);
    pilot.errors_um.resize(std::size_t(head[4]));
    pilot.measured_rms_um = head[5];
    pilot.predicted_rms_um = head[6];
    pilot.ratio = head[7];
    pilot.ratio_sd = head[8];
    pilot.cpu_seconds = head[9];
    pilot.tiles = int(head[11]);
    pilot.predicted_um.resize(pilot.errors_um.size());
    if (pilot.errors_um.empty()) return;
    comm.broadcast(pilot.errors_um.data(), pilot.errors_um.size());
    comm.broadcast(pilot.predicted_um.data(), pilot.predicted_um.size());
}

// The photon-aware plan (photon_plan.h) of a truth's acquisition, into r.photon_plan: with
// Poisson noise, the loss matched to it (a loss of one's own states its own photons), laser
// slices (the white-light slices' channels share their photons) and a target; the first-order
// plan, then its pilot. True when it asks for more than one exposure per slice.
bool plan_photons(PreparedRecovery& r, const RecoveryOptions& options, const TruthAcquisition& a, bool truth_given,
                  const MemoryLimit& limit, const Communicator& comm) {
    const AcquisitionPlan& plan = a.plan;
    if (options.noise.kind != NoiseKind::Poisson || options.target_error <= 0.0 || options.loss ||
        options.method != RecoveryMethod::Pipeline || !plan.white_lambdas_um.empty() || !(r.range_um > 0.0))
        return false;
    PhotonPlanSettings settings;
    settings.target = options.target_error;
    settings.max_exposures = options.max_exposures;
    r.photon_plan = plan_exposures(*r.truth, plan, options.noise.level, r.range_um, settings);
    PhotonPilot pilot = run_photon_pilot(r, options, a, truth_given, limit, comm);
    share_photon_pilot(pilot, comm);
    apply_photon_pilot(*r.photon_plan, *r.truth, settings, std::move(pilot));
    return r.photon_plan->exposures > 1;
}

}  // namespace

PreparedRecovery prepare_recovery(const RecoveryOptions& options, const Heightfield* truth,
                                  std::vector<Observation> observations, bool show_progress, const Communicator& comm) {
    const MemoryLimit limit = checked_options(options, truth, observations, comm);
    PreparedRecovery r;
    r.ranks = comm.size();
    r.method = options.method;
    r.noise = options.noise;
    r.loss = recovery_loss(options);
    r.range_um = options.height_range_um;
    r.texel_um = options.texel_um;
    r.vscale = options.vscale;
    // Every observation's metadata (check_acquisition needs them all), and this rank's share.
    std::vector<Observation> catalogue;
    std::optional<RoughnessPlan> measured;  // options.plan_from_truth: the truth's measured roughness
    std::optional<MeasuredRoughness> measured_roughness;
    if (!observations.empty()) {
        take_given_observations(r, options, std::move(observations), limit, comm, catalogue);
    } else {
        set_truth(r, truth != nullptr ? *truth : generated_recovery_truth(options));
        const HeightStats stats = height_stats(*r.truth);
        r.range_um = stats.max_um - stats.min_um;
        TruthAcquisition a = plan_truth_acquisition(r, options, truth != nullptr);
        // Photon-limited: k exposures of N photons per slice, summed, are one slice of k·N.
        RecoveryOptions exposed = options;
        if (plan_photons(r, options, a, truth != nullptr, limit, comm)) {
            exposed.noise.level *= double(r.photon_plan->exposures);
            r.noise = exposed.noise;
            r.loss = recovery_loss(exposed);
        }
        measured = std::move(a.measured);
        measured_roughness = std::move(a.measured_roughness);
        if (options.plan_only) {  // the slices as planned, nothing rendered
            r.plan_only = true;
            r.observations = adopt_plan(r, a.plan);
        } else {
            simulate_planned_observations(r, exposed, a.plan, limit, show_progress, comm, catalogue);
        }
        if (r.photon_plan) r.notes.push_back(r.photon_plan->note);
    }
    if (r.truth) {
        const HeightStats stats = height_stats(*r.truth);
        if (!(stats.max_um > stats.min_um)) r.metric_note = "undefined: the truth is flat";
    }
    r.warnings = check_acquisition(comm.size() > 1 ? catalogue : r.observations, r.rows, r.cols, r.texel_um,
                                   r.truth ? &*r.truth : nullptr);
    if (comm.size() > 1) r.catalogue = std::move(catalogue);
    if (!r.metric_note.empty())
        r.warnings.push_back("height_rel_rmse is " + r.metric_note + " (its height range is 0); the metrics give nan");
    state_pipeline_settings(r, options, measured, measured_roughness);
    r.uncertainty = options.uncertainty;
    r.check_error_bars = options.check_error_bars;
    r.max_memory_gb = options.max_memory_gb;
    r.memory_hint = options.names == OptionStyle::Cli ? "--max-memory-gb" : "max_memory_gb=";
    r.thesis.epochs = options.epochs;
    r.thesis.loss = r.loss;
    r.thesis.seed = options.seed;
    return r;
}

Heightfield run_recovery(const PreparedRecovery& r, const std::function<bool(const StageMetrics&)>& on_step,
                         const Communicator& comm, Calibration* calibration) {
    if (calibration) *calibration = Calibration{};
    if (r.plan_only)
        throw std::invalid_argument("run_recovery: the recovery was prepared as a plan only (its slices are not "
                                    "rendered); expected one prepared without plan_only");
    if (comm.size() != r.ranks)
        throw std::invalid_argument("run_recovery: the recovery was prepared for " + std::to_string(r.ranks) +
                                    " ranks but runs on " + std::to_string(comm.size()) +
                                    "; expected the communicator given to prepare_recovery");
    // A flat truth has no relative height error (its range is 0): the recovery runs without it.
    const Heightfield* truth = r.truth && r.metric_note.empty() ? &*r.truth : nullptr;
    if (r.method == RecoveryMethod::Pipeline)
        return recover_heights(r.observations, r.rows, r.cols, r.texel_um, r.vscale, r.pipeline, on_step, truth, comm,
                               calibration);
    return recover_heights_thesis(r.observations, r.rows, r.cols, r.texel_um, r.vscale, r.thesis, on_step, truth);
}

std::optional<UncertaintyReport> recovery_error_bars(const PreparedRecovery& r, const Heightfield& estimate,
                                                     const Communicator& comm, std::string* why_not,
                                                     const UncertaintySettings& settings) {
    const auto start = std::chrono::steady_clock::now();
    std::string why;
    HeightUncertainty map = run_or_abort(comm, [&] {
        try {
            return height_uncertainty(r.observations, estimate, r.loss, settings, comm);
        } catch (const std::domain_error& e) {
            why = e.what();
        } catch (const std::invalid_argument& e) {
            why = e.what();
        }
        return HeightUncertainty{};
    });
    if (why_not) *why_not = why;
    if (!why.empty()) return std::nullopt;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const Heightfield* truth = r.truth && r.metric_note.empty() ? &*r.truth : nullptr;
    return uncertainty_report(std::move(map), seconds, estimate, truth);
}

void judge_noise_limit(ConvergenceCheck& check, const PreparedRecovery& r, const Heightfield& estimate,
                       const std::vector<double>* sigma_um, double run_seconds, const Communicator& comm) {
    if (sigma_um) {
        check.error_bars = "given";
        add_predicted_error(check, *sigma_um, r.range_um);
        return;
    }
    if (!needs_error_bars(check)) return;
    if (r.check_error_bars == CheckErrorBars::Off) {
        check.error_bars = "off";
        check.error_bars_note = "the check's error bars are off";
        return;
    }
    // The cheaper solve that fits the memory limit (rank 0's predictions and time: one decision
    // on every rank).
    UncertaintySettings settings;
    UncertaintySettings probed = settings;
    probed.dense_max_texels = 0;
    const double pass = std::max(check.pass_seconds, 0.0);
    const int threads = std::max(1, omp_get_max_threads());
    const UncertaintyCost exact_cost = predicted_uncertainty_cost(r.observations, estimate, pass, settings, threads);
    const UncertaintyCost probed_cost = predicted_uncertainty_cost(r.observations, estimate, pass, probed, threads);
    // What the run holds meanwhile: the program's base, the observations' references and
    // weights (floats) and the estimate's heights.
    double held = 64e6 + 3.0 * sizeof(double) * double(estimate.values().size());
    for (const Observation& o : r.observations)
        held += sizeof(float) * double(o.reference.size() + o.weights.size());
    double costs[7] = {exact_cost.seconds,    held + exact_cost.bytes, probed_cost.seconds, held + probed_cost.bytes,
                       run_seconds,           exact_cost.diagonal_seconds, held + exact_cost.diagonal_bytes};
    comm.broadcast(costs, 7);
    const MemoryLimit limit = memory_limit(r.max_memory_gb);
    const bool exact_fits = check_error_bars_fit(costs[1], limit.bytes);
    const bool probed_fits = check_error_bars_fit(costs[3], limit.bytes);
    const bool take_probed = exact_fits == probed_fits ? costs[2] < costs[0] : probed_fits;
    if (take_probed) settings = probed;
    const double predicted = take_probed ? costs[2] : costs[0], needed = take_probed ? costs[3] : costs[1];
    const double seconds = costs[4];
    check.error_bars_predicted_seconds = predicted;
    check.run_seconds = seconds;
    check.error_bars_predicted_bytes = needed;
    if (std::isfinite(limit.bytes)) check.memory_limit_bytes = limit.bytes;
    // Bars left out for their cost or memory: G's diagonal alone still bounds what they would
    // predict from below (fisher_rms_error_lower_bound_um), at the cost of their forwards only
    // (no products between texels, no solve). Where the slices' photons are too few for the
    // heights (nm surfaces at 10⁴ photons per slice: the misfit on the floor, the bars costlier
    // than the short run) the bound alone exceeds the target, so the run warns without the bars;
    // within the target it passes nothing. Held to the same cost and memory rules as the bars;
    // photon counts only (their Fisher information is absolute, nothing estimated).
    const auto bound_instead = [&] {
        if (check.floor != "poisson" || !check_error_bars_fit(costs[6], limit.bytes) ||
            (r.check_error_bars == CheckErrorBars::Auto &&
             !check_error_bars_affordable(CheckErrorBars::Auto, costs[5], seconds)))
            return;
        const double cpu_before = process_cpu_seconds();
        std::vector<double> diagonal;
        std::string why;
        run_or_abort(comm, [&] {
            try {
                diagonal = GaussNewtonOperator(r.observations, estimate, r.loss, UncertaintySettings{}.step_um, comm)
                               .diagonal();
            } catch (const std::domain_error& e) {
                why = e.what();
            } catch (const std::invalid_argument& e) {
                why = e.what();
            }
            return 0;
        });
        double cpu = process_cpu_seconds() - cpu_before;
        comm.broadcast(&cpu, 1);
        if (!why.empty()) return;
        check.error_lower_bound_seconds = cpu;
        add_error_lower_bound(check, fisher_rms_error_lower_bound_um(diagonal), r.range_um);
    };
    if (!check_error_bars_fit(needed, limit.bytes)) {
        check.error_bars = r.check_error_bars == CheckErrorBars::Always ? "unavailable" : "skipped";
        try {
            require_memory(needed, limit,
                           "computing the check's error bars (" + std::to_string(estimate.rows()) + "x" +
                               std::to_string(estimate.cols()) + " heights, " +
                               std::to_string(r.observations.size()) + " observations)",
                           r.memory_hint);
            check.error_bars_note = "the check's error bars' memory is not known";  // a need that is not finite
        } catch (const OutOfMemory& e) {
            check.error_bars_note = e.what();
        }
        bound_instead();
        return;
    }
    if (!check_error_bars_affordable(r.check_error_bars, predicted, seconds)) {
        check.error_bars = "skipped";
        char note[256];
        std::snprintf(note, sizeof note,
                      "the error bars would take about %.3g CPU s, more than %.3g x the recovery's %.3g CPU s",
                      predicted, k_check_error_bars_budget, seconds);
        check.error_bars_note = note;
        bound_instead();
        return;
    }
    std::string why_not;
    const double cpu_before = process_cpu_seconds();
    std::optional<UncertaintyReport> bars = recovery_error_bars(r, estimate, comm, &why_not, settings);
    double bars_cpu = process_cpu_seconds() - cpu_before;
    comm.broadcast(&bars_cpu, 1);
    if (!bars) {
        check.error_bars = "unavailable";
        check.error_bars_note = "no error bars: " + why_not;
        return;
    }
    check.error_bars = "computed";
    check.error_bars_seconds = bars_cpu;
    add_predicted_error(check, bars->map.sigma_um, r.range_um);
}

// The texture check (texel_texture.h) at the run's predicted per-texel rms error: the error
// bars' where computed, else the photon plan's without its bias (the plan's range is the
// truth's, the run's), else the Fisher diagonal's lower bound; none of them: not judged. The
// same heights and numbers on every rank.
void judge_texture(ConvergenceCheck& check, const PreparedRecovery& r, const Heightfield& estimate) {
    if (check.predicted_error_relative > 0.0) {
        add_texel_texture(check, estimate, check.predicted_error_relative, r.range_um, "error bars");
        return;
    }
    if (r.photon_plan && r.photon_plan->range_um > 0.0) {
        const PhotonPlan& p = *r.photon_plan;
        const double noise_um = std::sqrt(std::max(p.rms_um * p.rms_um - p.bias_um * p.bias_um, 0.0));
        add_texel_texture(check, estimate, noise_um / p.range_um, r.range_um, "photon plan");
        return;
    }
    if (check.error_lower_bound_relative > 0.0)
        add_texel_texture(check, estimate, check.error_lower_bound_relative, r.range_um, "error lower bound");
}

void ModelCheckMisfits::record(const StageMetrics& m) {
    if (m.kind == StageKind::ModelMisfit && m.stage == "misfit:gabor") gabor = m.loss;
    if (m.kind == StageKind::ModelMisfit && m.stage == "misfit:field") field = m.loss;
    if (m.kind == StageKind::ModelSelect) selected = m.stage.substr(std::string(stage_kind_name(m.kind)).size());
}

RecoveryJudgement judge_recovery(const PreparedRecovery& r, const Heightfield& estimate,
                                 const ModelCheckMisfits& misfits, const Calibration* calibration, bool stopped,
                                 double run_seconds, const Communicator& comm) {
    RecoveryJudgement j;
    if (r.uncertainty && !stopped) j.error_bars = recovery_error_bars(r, estimate, comm, &j.no_error_bars);
    j.convergence = run_or_abort(comm, [&] {
        const double photons = r.noise.kind == NoiseKind::Poisson ? r.noise.level
                               : r.loss.kind == LossKind::Poisson ? r.loss.photons
                                                                  : 0.0;
        return check_convergence(r.observations, estimate, photons, r.truth && r.noise.kind == NoiseKind::None,
                                 r.pipeline.calibrate.any() ? calibration : nullptr, comm);
    });
    add_model_check(j.convergence, misfits.gabor, misfits.field, misfits.selected);
    if (j.error_bars) add_error_bars(j.convergence, j.error_bars->median_sigma_um, r.range_um);
    if (!stopped) {
        judge_noise_limit(j.convergence, r, estimate, j.error_bars ? &j.error_bars->map.sigma_um : nullptr,
                          run_seconds, comm);
        judge_texture(j.convergence, r, estimate);
    }
    return j;
}

}  // namespace wavebrdf
