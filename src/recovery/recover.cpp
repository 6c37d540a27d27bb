// The recovery pipeline: field retrieval per wavelength → unwrapping → refinement in the full
// Gabor model (recover.h).
#include "wavebrdf/recover.h"

#include <algorithm>
#include <chrono>
#include <iterator>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include "wavebrdf/gabor.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/slice_plan.h"
#include "core/stall_rule.h"
#include "core/exact_sum.h"
#include "core/parallel.h"
#include "recovery/field_positions.h"
#include "recovery/field_tiles.h"
#include "recovery/field_proxy.h"
#include "recovery/outlier_repair.h"
#include "recovery/recover_positions.h"
#include "recovery/calibration_detail.h"
#include "recovery/coarse_correction.h"
#include "recovery/recover_field_model.h"
#include "recovery/white_light.h"
#include "recovery/sigma_search.h"

namespace wavebrdf {

double height_rel_rmse(const Heightfield& estimate, const Heightfield& truth) {
    if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols())
        throw std::invalid_argument("height_rel_rmse: estimate is " + std::to_string(estimate.rows()) + " x " +
                                    std::to_string(estimate.cols()) + " but truth is " + std::to_string(truth.rows()) +
                                    " x " + std::to_string(truth.cols()));
    const double n = double(truth.values().size());
    double mean_e = 0.0, mean_t = 0.0, lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j) {
            mean_e += estimate.height_um(i, j);
            const double t = truth.height_um(i, j);
            mean_t += t;
            lo = std::min(lo, t);
            hi = std::max(hi, t);
        }
    if (!(hi > lo)) throw std::domain_error("height_rel_rmse: the truth is flat; its height range is 0");
    mean_e /= n;
    mean_t /= n;
    double sum = 0.0;
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j) {
            const double d = (estimate.height_um(i, j) - mean_e) - (truth.height_um(i, j) - mean_t);
            sum += d * d;
        }
    return std::sqrt(sum / n) / (hi - lo);
}

int auto_refine(double texel_um, double lambda_min_um, double max_omega_i) {
    // The object grid must hold the slice's band and the field's: 1/d > 2(1 + |ω_i|)/λ.
    int q = int(std::floor(2.0 * texel_um * (1.0 + max_omega_i) / lambda_min_um)) + 1;
    if (q % 2 == 0) ++q;
    return std::max(q, 1);
}

namespace {

// RecoverSettings::position_outer_passes = −1 (the default): outer passes of position
// self-calibration. Converging runs still gain after 12 passes, a cluster the rescue brings back
// late needs 20, and 3 texels rms with the footprint sized for it converges in 12–19 passes, the
// slowest seed's last passes doing the most (3.1 % → 0.36 % → 0.04 %): so the cap is 40, and
// converged or stalled runs end earlier by the stall rule
// (experiments/2026-11-23-position-calibration.md).
constexpr int k_position_outer_passes = 40;
// RecoverSettings::position_outer_stall_tolerance = −1 (the default): the stall rule's relative
// loss decrease: converging runs lower stage 3's loss by ≥ 14 % a pass to their 12th, a stalled
// one by ≤ 1 %; 0.1 stopped a run whose lost cluster the rescue brought back later, 0.05 nearly
// did.
constexpr double k_position_outer_stall_tolerance = 0.02;
// White light's defect repair: texels farther than this many robust deviations from their
// neighbours' median are flagged, and connected regions of them up to k_white_repair_region_texels
// are shifted by whole wraps or filled (white_light.h, repair_defect_regions).
constexpr double k_white_repair_threshold = 3.0;
constexpr int k_white_repair_region_texels = 64;

// recover_heights' stages, after its checks: `by_lambda` holds this rank's single-wavelength
// separable observations, with an entry (maybe empty) for every rank's wavelengths;
// `observations_total` counts all ranks' observations.
Heightfield recover_stages(const std::vector<Observation>& observations,
                           const std::map<double, std::vector<const Observation*>>& by_lambda,
                           double observations_total, const Heightfield& flat, int rows, int cols, double texel_um,
                           double vscale, const RecoverSettings& settings_in,
                           const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                           const Communicator& comm, Calibration* calibration) {
    RecoverSettings settings = settings_in;
    // field_wavelengths / refine_ladder_wavelengths as wavelengths (every rank holds every
    // wavelength's key, so all ranks agree): the n-th longest.
    const auto nth_longest = [&](int n) {
        double l = 0.0;
        for (auto it = by_lambda.rbegin(); it != by_lambda.rend() && n > 0; ++it, --n) l = it->first;
        return l;
    };
    if (settings.field_lambda_min_um == 0.0 && settings.field_wavelengths > 0)
        settings.field_lambda_min_um = nth_longest(settings.field_wavelengths);
    if (settings.refine_ladder_min_um == 0.0 && settings.refine_ladder_wavelengths > 0)
        settings.refine_ladder_min_um = nth_longest(settings.refine_ladder_wavelengths);
    const auto start = std::chrono::steady_clock::now();
    const auto seconds = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    bool stopped = false;
    double last_refine_loss = 0.0;  // stage 3's last reported loss (the position loop's stall rule)
    const auto report = [&](const std::string& stage, int iteration, double loss, const Heightfield* hf) {
        if (stage == "refine") last_refine_loss = loss;
        bool go_on = true;
        if (on_step) {
            StageMetrics m;
            m.stage = stage;
            m.iteration = iteration;
            m.loss = loss;
            m.seconds = seconds();
            if (truth && hf) {
                m.height_rel_rmse = height_rel_rmse(*hf, *truth);
                m.height_rel_rmse_plane_removed = height_rel_rmse_plane_removed(*hf, *truth);
            }
            go_on = on_step(m);
        }
        go_on = !comm.any(!go_on);  // one rank's stop stops all, at the same step
        if (!go_on) stopped = true;
        return go_on;
    };

    // Stage 0: the surface's shape from blurred slices, from flat.
    // (Pointers, not copies: the references are most of the memory a run holds.)
    std::vector<const Observation*> blur_set;
    // The blurred fit sees the slope distribution, nearly the same at every wavelength: the
    // longest ones (smoothest) suffice.
    // It needs the slope distribution everywhere, not the overlap that pins phases down: positions
    // closer than blur_spacing_sigma · σ_p to one already taken are left out (greedy, periodic
    // distance), which buys more iterations for the same time.
    // The choice is made on every rank's positions (x, y, σ_p per observation, in rank order,
    // the one-process order when each rank holds a block of positions), and each rank keeps
    // those of its own observations that were taken.
    const double period_x = rows * texel_um, period_y = cols * texel_um;
    const auto periodic = [](double d, double period) { return d - period * std::floor(d / period + 0.5); };
    // White light (no single-wavelength observation on any rank): the RGB observations, one
    // group, feed the blurred fit, and the refinement follows it (no field stage).
    const bool white = by_lambda.empty();
    std::map<double, std::vector<const Observation*>> blur_groups;
    if (white)
        for (const Observation& o : observations) blur_groups[0.0].push_back(&o);
    const auto& groups = white ? blur_groups : by_lambda;
    int taken = 0;
    for (auto it = groups.rbegin(); it != groups.rend(); ++it, ++taken) {
        if (settings.blur_wavelengths > 0 && taken >= settings.blur_wavelengths) break;
        std::vector<double> mine;
        for (const Observation* o : it->second)
            mine.insert(mine.end(), {o->query.x_um, o->query.y_um, o->query.sigma_p_um});
        std::vector<std::size_t> counts;
        const std::vector<double> all = all_gather(comm, mine, &counts);
        std::size_t first_mine = 0;
        for (int r = 0; r < comm.rank(); ++r) first_mine += counts[std::size_t(r)] / 3;
        std::vector<std::size_t> chosen;  // indices of observations in `all`
        for (std::size_t k = 0; 3 * k + 2 < all.size(); ++k) {
            bool close = false;
            for (std::size_t c = 0; c < chosen.size() && !close; ++c) {
                const std::size_t j = chosen[c];
                const double dx = periodic(all[3 * k] - all[3 * j], period_x);
                const double dy = periodic(all[3 * k + 1] - all[3 * j + 1], period_y);
                const double spacing = settings.blur_spacing_sigma * std::min(all[3 * k + 2], all[3 * j + 2]);
                close = dx * dx + dy * dy < spacing * spacing;
            }
            if (!close) chosen.push_back(k);
        }
        for (std::size_t k : chosen)
            if (k >= first_mine && k < first_mine + it->second.size()) blur_set.push_back(it->second[k - first_mine]);
    }
    // GHS/RGHS slices: the field stage (and the blurred fit, whose GHS renders cost many times
    // the separable ones) run on the separable proxy for the heights s·H (field_proxy.h), s =
    // cos θ_i; 1 for OHS/ROHS. The refinement runs the full model.
    const detail::FieldProxy proxy = detail::common_field_proxy(by_lambda, comm);
    const double proxy_scale = proxy.height_scale;
    std::vector<Observation> blur_proxies;
    if (proxy.proxied) {
        blur_proxies.reserve(blur_set.size());
        for (const Observation* o : blur_set) {
            blur_proxies.push_back(*o);
            blur_proxies.back().query.model = detail::field_proxy_model(o->query.model);
        }
        for (std::size_t k = 0; k < blur_set.size(); ++k) blur_set[k] = &blur_proxies[k];
    }
    Heightfield estimate = flat;
    const BlurredFitSettings& blur_settings = white ? settings.white_blurred : settings.blurred;
    // Self-calibration of positions (recover_positions.h): one offset per gathered position,
    // corrected by the field stage.
    std::vector<std::size_t> position_of;
    std::vector<double> offsets_um;
    if (settings.calibrate.positions)
        offsets_um.assign(2 * detail::gather_positions(observations, position_of, comm).size(), 0.0);
    const auto position_index = [&](const Observation* o) { return position_of[std::size_t(o - observations.data())]; };
    if (!blur_settings.blur_widths.empty() && blur_settings.iterations > 0) {
        BlurredFitSettings blurred = blur_settings;
        blurred.calibrate_exposure = blurred.calibrate_exposure || settings.calibrate.exposure;
        estimate = fit_blurred(
            blur_set, flat, blurred,
            [&](int stage, int it, double loss) { return report("blur:" + std::to_string(stage), it, loss, nullptr); },
            comm);
        if (proxy_scale != 1.0) {
            std::vector<double> h = estimate.values();
            for (double& v : h) v /= proxy_scale;
            estimate = flat.with_values(std::move(h));
        }
        std::vector<Observation>().swap(blur_proxies);
        if (stopped || !report("blur", 0, 0.0, &estimate)) return estimate;
    }
    // σ_p self-calibration before the field stage (sigma_search.h): the scale where the full
    // model's loss at the blurred heights is smallest; the field stage, the position
    // registration and the refinement (which starts its σ rounds there) see σ_p · sigma_scale.
    // Not with exposure calibration as well: the energy ratio then absorbs σ_p's energy and the
    // search at the blurred heights can run off (measured: 1.68 for a true 1.0 on an 8² tile of
    // 0.1 µm range, where the refinement from there stayed at 1.45).
    double sigma_scale = 1.0;
    const bool presearched = settings.calibrate.sigma && settings.sigma_presearch && !settings.calibrate.exposure;
    if (presearched) {
        sigma_scale = detail::presearch_sigma_scale(observations, observations_total, estimate, settings.refine_loss,
                                                    settings.calibrate.exposure, comm);
        if (calibration) calibration->sigma_p_scale = calibration->sigma_p_scale_fields = sigma_scale;
    }

    // Stage 1: the field at every wavelength on the refined grid, from the blurred fit.
    double max_omega_i = 0.0;
    for (const auto& [lambda, group] : by_lambda)
        for (const Observation* o : group)
            max_omega_i = std::max(max_omega_i, std::hypot(o->query.omega_i[0], o->query.omega_i[1]));
    for (double w : all_gather(comm, {max_omega_i})) max_omega_i = std::max(max_omega_i, w);  // every rank's
    const int q = settings.refine > 0 ? settings.refine
                : white        ? 1
                               : auto_refine(texel_um, by_lambda.begin()->first, max_omega_i);
    if (q % 2 == 0 || q > 63)
        throw std::invalid_argument("recover_heights: refine " + std::to_string(q) +
                                    " is invalid; expected an odd value up to 63 (texel centres must be samples)");
    FieldRetrievalSettings field_settings = settings.field;
    field_settings.refine = q;
    field_settings.calibrate_exposure = field_settings.calibrate_exposure || settings.calibrate.exposure;
    const int obj_cols = cols * q;
    const double to_texel = 1.0 / (vscale * texel_um * proxy_scale);
    const auto scaled = [&](std::vector<double> h) {
        if (proxy_scale != 1.0)
            for (double& v : h) v *= proxy_scale;
        return h;
    };
    const auto proxy_start = [&](double lambda) {
        if (proxy_scale == 1.0) return object_from_heights(estimate, lambda, q);
        return object_from_heights(estimate.with_values(scaled(estimate.values())), lambda, q);
    };
    std::vector<double> lambdas;
    std::vector<std::vector<std::complex<double>>> fields;
    // Stage 2 (after each field when cascading): heights on the refined grid from the fields so
    // far (spatially unwrapped, or each sample on the branch nearest the current estimate), then
    // at the texel centres (refine is odd: texel (i, j) is sample (i·q + q/2, j·q + q/2)).
    const auto unwrap_fields = [&] {
        const std::vector<double> reference = scaled(refined_heights(estimate, q));
        const std::vector<double> fine_um = unwrap_heights(lambdas, fields, settings.height_range_um, rows * q,
                                                           obj_cols,
                                                           settings.unwrap_from_blurred ? &reference : nullptr);
        std::vector<double> h(std::size_t(rows) * cols);
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j)
                h[std::size_t(i) * cols + j] = fine_um[std::size_t(i * q + q / 2) * obj_cols + (j * q + q / 2)] *
                                               to_texel;
        estimate = flat.with_values(h);
    };
    // Longest wavelength first: its phases are the least wrapped, so it converges from the
    // blurred fit most surely; cascading, each next field starts from all fields before it.
    // Later passes start every field again from the heights of all of them: the heights are a
    // projection onto pure-phase, smooth objects, which removes the local defects (phase
    // vortices) a retrieval from a poor start can stall in.
    const int passes = settings.cascade ? std::max(1, settings.field_passes) : 1;
    // Every rank holds every wavelength's key (maybe empty), so all ranks skip the same ones.
    const double field_min_um =
        !by_lambda.empty() && by_lambda.rbegin()->first >= settings.field_lambda_min_um ? settings.field_lambda_min_um
                                                                                        : 0.0;
    const auto field_end = by_lambda.rend();
    // The smallest final loss of the field retrievals (the model check's shortcut; 0: none).
    double field_floor = std::numeric_limits<double>::infinity();
    // With positions and exposures both calibrated (field_exposures_held): each observation's
    // exposure, held fixed through the field stage (recover_positions.h, exposures_at); its
    // references are divided by it and the stage's own exposure calibration is off.
    std::vector<double> field_exposures;
    const bool hold_exposures = settings.calibrate.positions && settings.calibrate.exposure &&
                                settings.field_exposures_held && !white;
    const auto field_stage = [&]() -> bool {  // false: stopped
    for (int pass = 0; pass < passes; ++pass)
        for (auto it = by_lambda.rbegin(); it != field_end && it->first >= field_min_um; ++it) {
            const double lambda = it->first;
            char name[48];
            std::snprintf(name, sizeof name, "field:%g", lambda);
            // This wavelength's observations where they are (pointers: no copy of the references);
            // with σ_p calibration copies at σ_p · s while its field runs (one wavelength's at a
            // time); with position calibration the offsets are applied and corrected inside
            // (field_positions.h).
            std::vector<Observation> group;
            std::vector<const Observation*> used = it->second;
            const bool held = !field_exposures.empty();
            if (sigma_scale != 1.0 || proxy.proxied || held) {
                group.reserve(it->second.size());
                for (const Observation* o : it->second) {
                    group.push_back(*o);
                    group.back().query.sigma_p_um *= sigma_scale;
                    group.back().query.model = detail::field_proxy_model(o->query.model);
                    if (held) {
                        const double e = field_exposures[std::size_t(o - observations.data())];
                        for (float& v : group.back().reference) v = float(double(v) / e);
                    }
                }
                for (std::size_t k = 0; k < group.size(); ++k) used[k] = &group[k];
            }
            field_settings.calibrate_exposure =
                !held && (settings.field.calibrate_exposure || settings.calibrate.exposure);
            const auto on_iteration = [&](int iteration, double loss) { return report(name, iteration, loss, nullptr); };
            FieldRetrievalResult r = [&] {
                const detail::FieldTiling tiling{settings.field_tile_threshold, settings.field_tile_core,
                                                 settings.field_tile_ramp};
                if (!settings.calibrate.positions && detail::field_tiles_apply(rows, cols, tiling))
                    return detail::retrieve_field_tiled(used, lambda, rows, cols, texel_um, proxy_start(lambda),
                                                        field_settings,
                                                        tiling, on_iteration, comm);
                if (!settings.calibrate.positions)
                    return retrieve_field(used, lambda, rows, cols, texel_um, proxy_start(lambda),
                                          field_settings, on_iteration, comm);
                std::vector<std::size_t> index;
                for (const Observation* o : it->second) index.push_back(position_index(o));
                return detail::retrieve_field_with_positions(used, index, lambda, rows, cols, texel_um,
                                                             proxy_start(lambda), field_settings, on_iteration,
                                                             offsets_um, comm);
            }();
            if (stopped) return false;
            if (std::isfinite(r.relative_loss) && r.relative_loss > 0.0)
                field_floor = std::min(field_floor, r.relative_loss);
            std::vector<Observation>().swap(group);
            const auto at = std::find(lambdas.begin(), lambdas.end(), lambda);
            if (at == lambdas.end()) {
                lambdas.push_back(lambda);
                fields.push_back(std::move(r.object));
            } else {
                fields[std::size_t(at - lambdas.begin())] = std::move(r.object);
            }
            const bool last =
                pass + 1 == passes && (std::next(it) == field_end || std::next(it)->first < field_min_um);
            if (settings.cascade && !last) {
                unwrap_fields();
                if (!report(name, r.iterations, r.relative_loss, &estimate)) return false;
            }
        }
    return true;
    };
    if (hold_exposures) {
        field_exposures = detail::exposures_at(observations, position_of, estimate, sigma_scale, offsets_um);
        if (!report("exposures:held", 0, 0.0, &estimate)) return estimate;
    }
    if (!field_stage()) return estimate;
    if (!white) {
        unwrap_fields();
        if (!report("unwrap", 0, 0.0, &estimate)) return estimate;
    }
    // σ_p searched again at the unwrapped heights (sigma_search.h: ≈ 0.4–1 % off, where the
    // blurred fit's bias the first search towards 1); when it moved, the field stage runs again
    // at the new σ_p from the unwrapped heights (every field anew) and is unwrapped again. With
    // exposure calibration there was no first search (the energy ratio pulls it off at the
    // blurred heights): this is then the only one, over the first search's whole range, and
    // its answer is kept only where its loss is below the stated σ_p's (guarded_sigma_scale).
    const bool researched = !white && settings.calibrate.sigma &&
                            (presearched || settings.calibrate.exposure);
    if (researched) {
        const double s =
            presearched ? detail::research_sigma_scale(observations, observations_total, estimate, sigma_scale,
                                                       settings.refine_loss, settings.calibrate.exposure, comm)
                        : detail::guarded_sigma_scale(observations, observations_total, estimate, settings.refine_loss,
                                                      settings.calibrate.exposure, comm);
        const bool moved = detail::sigma_scale_moved(sigma_scale, s);
        if (!report("sigma:unwrapped", moved ? 1 : 0, s, &estimate)) return estimate;
        if (moved) {
            sigma_scale = s;
            if (calibration) calibration->sigma_p_scale = calibration->sigma_p_scale_fields = sigma_scale;
            lambdas.clear();
            fields.clear();
            if (hold_exposures)  // at the unwrapped heights and the new σ_p
                field_exposures = detail::exposures_at(observations, position_of, estimate, sigma_scale, offsets_um);
            if (!field_stage()) return estimate;
            unwrap_fields();
            if (!report("unwrap", 1, 0.0, &estimate)) return estimate;
        }
    }

    // The fields (every wavelength's object on the fine grid, 16 bytes per sample) are the
    // unwrapping's input only: released before stage 3 (the position loop's field stages below
    // start from empty ones again).
    lambdas.clear();
    std::vector<std::vector<std::complex<double>>>().swap(fields);

    // Stage 3: the full model (with the positions refined as well: recover_positions.h).
    Heightfield unwrapped = estimate;
    std::vector<std::array<double, 2>> refined_offsets;  // per observation (positions calibrated)
    double refined_sigma_scale = 1.0;
    if (settings.refine_iterations > 0 && settings.calibrate.positions) {
        std::vector<std::array<double, 2>> offsets;
        std::vector<double> exposures;
        std::vector<double> position_offsets;  // per gathered position (2 each, µm)
        estimate = detail::refine_heights_and_positions(observations, observations_total, flat, estimate, settings,
                                                        report, comm, offsets, offsets_um, &exposures, &sigma_scale,
                                                        &position_offsets);
        if (stopped) return estimate;
        // The outer loop: every
        // position registered on its own at the final heights (a grid search of its full-model
        // loss, then Newton steps), then the field stage (from the final heights, while the
        // registration moves) and stage 3 again at the registered positions, until the
        // registration moves the offsets by less than position_outer_tolerance_texels rms or
        // stage 3's loss stalls.
        const int outer_passes = settings.position_outer_passes >= 0 ? settings.position_outer_passes
                                                                      : k_position_outer_passes;
        // Later passes warm-start from the pass before (its heights, hence its objects) and may
        // run fewer iterations (position_outer_field_iterations, position_outer_refine_iterations).
        RecoverSettings later = settings;
        if (settings.position_outer_refine_iterations > 0)
            later.refine_iterations = settings.position_outer_refine_iterations;
        // The smooth part of each registration's update removed (positions and heights
        // can trade a smooth warp; recover_positions.h).
        const int smooth_nodes = settings.position_outer_smooth_nodes;
        std::vector<std::array<double, 2>> centres;
        if (outer_passes > 0 && smooth_nodes > 0) {
            std::vector<std::size_t> unused;
            centres = detail::gather_positions(observations, unused, comm);
        }
        // The stall rule on stage 3's loss: the lowest stage-3 loss of the passes without the field stage
        // (and of the first recovery), and how many such passes in a row lowered it by less than
        // the tolerance.
        const double stall_tolerance = settings.position_outer_stall_tolerance >= 0.0
                                           ? settings.position_outer_stall_tolerance
                                           : k_position_outer_stall_tolerance;
        double best_loss = last_refine_loss;
        int stalled = 0;
        // The rule on the median position's loss (position_outer_stall_median), judged at the
        // start of each pass for the heights of the pass before (a pass after the field stage's
        // heights, a new start, resets the count as the rule on stage 3's loss does).
        double best_median = 0.0;
        bool after_field = true;  // the first recovery ran the field stage
        for (int outer = 0; outer < outer_passes; ++outer) {
            const std::vector<double> before = position_offsets;
            double moved = detail::register_positions(observations, position_of, estimate, settings, sigma_scale,
                                                      settings.position_register_radius_texels, 0.5, position_offsets,
                                                      comm);
            // Newton steps on each position's offset after the grid and parabola
            // (recover_positions.h); moved counts them.
            for (int n = 0; n < settings.position_register_newton_steps; ++n) {
                const int stepped = detail::newton_register_positions(
                    observations, position_of, estimate, settings, sigma_scale, settings.position_newton_step_texels,
                    settings.position_newton_cap_texels, position_offsets, comm);
                double s2 = 0.0;
                for (std::size_t i = 0; i < before.size(); ++i)
                    s2 += (position_offsets[i] - before[i]) * (position_offsets[i] - before[i]);
                moved = before.empty() ? 0.0 : std::sqrt(s2 / double(before.size())) / estimate.texel_um();
                if (!report("positions:newton", stepped, moved, &estimate)) return estimate;
            }
            if (smooth_nodes > 0) {
                std::vector<double> update(position_offsets.size());
                for (std::size_t i = 0; i < update.size(); ++i) update[i] = position_offsets[i] - before[i];
                detail::remove_smooth_displacement(centres, update, smooth_nodes);
                double s2 = 0.0;
                for (std::size_t i = 0; i < update.size(); ++i) {
                    position_offsets[i] = before[i] + update[i];
                    s2 += update[i] * update[i];
                }
                moved = update.empty() ? 0.0 : std::sqrt(s2 / double(update.size())) / estimate.texel_um();
            }
            if (!report("positions:register", outer + 1, moved, &estimate)) return estimate;
            // The lost positions searched wide.
            int rescued = 0;
            bool median_judged = false;  // the median position's stall rule judged this pass
            if (settings.position_rescue_factor > 0.0) {
                const std::vector<double> kept = position_offsets;
                double median = 0.0;
                rescued = detail::rescue_lost_positions(
                    observations, position_of, estimate, settings, sigma_scale, settings.position_rescue_factor,
                    settings.position_rescue_radius_texels, settings.position_rescue_step_texels, position_offsets,
                    comm, &median);
                double s2 = 0.0;
                for (std::size_t i = 0; i < kept.size(); ++i)
                    s2 += (position_offsets[i] - kept[i]) * (position_offsets[i] - kept[i]);
                const double jump = kept.empty() ? 0.0 : std::sqrt(s2 / double(kept.size())) / estimate.texel_um();
                if (!report("positions:rescue", rescued, jump, &estimate)) return estimate;
                if (jump > 0.0) moved = std::max(moved, settings.position_outer_tolerance_texels);
                // The stall rule on the median position's loss at the heights of the pass
                // before (stage 3's loss is dominated by positions lost for good). A stalled loop
                // ends here, with the pass before's heights and offsets.
                if (settings.position_outer_stall_median && settings.position_outer_stall_passes > 0) {
                    median_judged = true;
                    stalled = after_field ? 0 : median > (1.0 - stall_tolerance) * best_median ? stalled + 1 : 0;
                    best_median = after_field && outer == 0 ? median : std::min(best_median, median);
                    if (!report("positions:stall", stalled, median, &estimate)) return estimate;
                    if (stalled >= settings.position_outer_stall_passes) break;
                }
            }
            if (moved < settings.position_outer_tolerance_texels) break;
            offsets_um = position_offsets;
            const bool field_pass = !white && settings.position_outer_fields &&
                                    !(settings.position_outer_field_below_texels > 0.0 &&
                                      moved < settings.position_outer_field_below_texels);
            if (field_pass) {
                lambdas.clear();
                fields.clear();
                if (settings.position_outer_field_iterations > 0)
                    field_settings.iterations = settings.position_outer_field_iterations;
                if (hold_exposures)  // stage 3's, at the heights and offsets it ended with
                    field_exposures = exposures.size() == observations.size()
                                          ? exposures
                                          : detail::exposures_at(observations, position_of, estimate, sigma_scale,
                                                                 offsets_um);
                if (!field_stage()) return estimate;
                unwrap_fields();
                if (!report("unwrap", outer + 1, 0.0, &estimate)) return estimate;
                unwrapped = estimate;
            }
            estimate = detail::refine_heights_and_positions(
                observations, observations_total, flat, estimate, later, report, comm, offsets, offsets_um, &exposures,
                &sigma_scale, &position_offsets);
            if (stopped) return estimate;
            // The stall rule on stage 3's loss: a pass of registration and stage 3 alone that lowered stage
            // 3's loss by less than the tolerance (relative to the lowest so far) counts; the
            // loop stops after position_outer_stall_passes of them in a row. A pass with the
            // field stage resets the count (its heights are a new start).
            after_field = field_pass;
            if (field_pass) {
                stalled = 0;
            } else if (settings.position_outer_stall_passes > 0 && !median_judged) {
                stalled = last_refine_loss > (1.0 - stall_tolerance) * best_loss ? stalled + 1 : 0;
                if (!report("positions:stall", stalled, last_refine_loss, &estimate)) return estimate;
                if (stalled >= settings.position_outer_stall_passes) break;
            }
            best_loss = std::min(best_loss, last_refine_loss);
        }
        refined_offsets = offsets;
        refined_sigma_scale = sigma_scale;
        if (calibration) {
            calibration->position_offsets_um = std::move(offsets);
            calibration->exposures = std::move(exposures);
            calibration->sigma_p_scale = sigma_scale;
        }
    } else if (settings.refine_iterations > 0) {
        std::vector<double> h = estimate.values();
        // observation_loss's mean, split over the observations on all threads (each slice alone
        // is too small for the renderer to split). Each observation keeps its slice plan for
        // every iteration (built on the first call, on the thread that owns it): only the
        // heights change (slice_plan.h), so rebuilding the tables each time was wasted work.
        // A plan keeps only its height-independent tables between calls (release below).
        std::vector<std::unique_ptr<SlicePlan<float>>> plans(observations.size());
        // Every rank's observations summed exactly (core/exact_sum.h): each plan's gradient
        // goes in over its box (the texels its adjoint writes), so the sums are the same for any
        // thread count and split over ranks.
        std::vector<std::vector<int>> box_rows(observations.size()), box_cols(observations.size());
        detail::ExactParallelSum exact_sum(h.size());
        // Self-calibration (calibration_detail.h): each observation's exposure as the ratio of
        // its energies at every evaluation (with its gradient), one σ_p scale for all (plans
        // rebuilt).
        const bool calibrate_exposure = settings.calibrate.exposure;
        std::vector<double> exposures(observations.size(), 1.0);
        // The wavelength ladder's rung (refine_ladder_min_um): the observations in the loss (empty: all).
        std::vector<char> active;
        double smooth_weight = 0.0;  // white light: the smoothness continuation's weight (white_light.h)
        const auto data_objective = [&](const std::vector<double>& x, std::vector<double>& g) {
            const double scale = 1.0 / observations_total;  // all ranks' observations
            return exact_sum.run(observations.size(), comm, g, [&](std::size_t i, detail::ExactScratch& scratch) {
                if (!active.empty() && !active[i]) return 0.0;
                const Observation& o = observations[i];
                // Built on the flat surface's geometry (no copy of the heights per
                // observation), then given the heights like every later call.
                if (!plans[i]) {
                    Query query = o.query;
                    query.sigma_p_um *= sigma_scale;
                    plans[i] = std::make_unique<SlicePlan<float>>(flat, query, o.lambdas_um, o.resolution,
                                                                  o.channels());
                    plans[i]->gradient_box(box_rows[i], box_cols[i]);
                }
                plans[i]->set_heights(x);
                SlicePlan<float>& plan = *plans[i];
                const std::vector<float>& f = plan.forward();
                std::vector<double> d_estimate;
                double exposure = 1.0;
                const std::size_t values = std::min(f.size(), o.reference.size());
                if (calibrate_exposure) {
                    exposure = detail::slice_exposure(f.data(), o.reference.data(), values);
                    exposures[i] = exposure;
                }
                std::vector<double> model(f.begin(), f.end());
                if (calibrate_exposure)
                    for (double& m : model) m *= exposure;
                const double v = loss_value(settings.refine_loss, model, o.reference, o.channels(), &d_estimate);
                if (calibrate_exposure) detail::exposure_gradient(exposure, f.data(), values, d_estimate);
                plan.adjoint(d_estimate, scratch.vector(), scale);
                scratch.take_box(box_rows[i], box_cols[i], std::size_t(cols));
                plan.release();
                return scale * v;
            });
        };
        const auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
            const double value = data_objective(x, g);
            return smooth_weight > 0.0 ? value + detail::add_smoothness_penalty(x, rows, cols, smooth_weight, g)
                                       : value;
        };
        LbfgsOptions lo;
        lo.history = settings.refine_history;
        lo.max_iterations = settings.refine_iterations;
        lo.gradient_tolerance = 0.0;
        // observation_loss's mean over all ranks' observations (summed exactly, as above).
        std::vector<double> no_gradient;
        detail::ExactParallelSum exact_reference(0);
        const double reference_loss = exact_reference.run(observations.size(), comm, no_gradient,
                                                          [&](std::size_t i, detail::ExactScratch&) {
                                                              return observation_loss(flat, {observations[i]},
                                                                                      settings.refine_loss, nullptr);
                                                          }) /
                                      observations_total;
        bool go_on = true;
        int done = 0;  // refinement iterations so far (the metrics' count across rounds)
        // The coarse space (coarse_correction.h): none when off or the surface is too small.
        const detail::CoarseBasis coarse(rows, cols,
                                         settings.refine_coarse_spacing > 0.0 ? settings.refine_coarse_spacing
                                                                              : double(std::max(rows, cols)),
                                         settings.refine_coarse_weight > 0.0 ? settings.refine_coarse_weight : 1.0);
        const bool coarse_on = settings.refine_coarse_spacing > 0.0 && coarse.size() > 0;
        const auto refine_heights = [&](int iterations, const std::string& stage = "refine",
                                        double relative_tolerance = 0.0, int stall_window = 0,
                                        double stall_tolerance = 0.0) {
            // loss / loss(flat) below which the round stops.
            const double stop_below =
                std::max(detail::k_refine_relative_tolerance, relative_tolerance) * reference_loss;
            LbfgsOptions round = lo;
            round.max_iterations = iterations;
            const int before = done;
            // The stall rule (stall_window > 0): the loss fell by less than stall_tolerance of its
            // value over the last stall_window iterations (the values are every rank's: all agree).
            detail::StallRule stall(stall_window, stall_tolerance);
            bool stalled = false;
            const auto go_on_at = [&](double value) {
                if (stall.stalled_at(value) && value > stop_below) stalled = true;
                return !stalled && value > stop_below;
            };
            if (coarse_on && settings.refine_coarse_weight > 0.0) {
                // L-BFGS on z = (x, c), h = x + B c.
                std::vector<double> z(h.size() + coarse.size(), 0.0);
                std::copy(h.begin(), h.end(), z.begin());
                lbfgs_minimize(detail::coarse_objective(objective, coarse), z, round, [&](int it, double value) {
                    done = before + it;
                    h = detail::coarse_heights(z, coarse);
                    const Heightfield current = flat.with_values(h);
                    if (!report(stage, done, value, &current)) return go_on = false;
                    return go_on_at(value);
                });
                h = detail::coarse_heights(z, coarse);
            } else {
                lbfgs_minimize(objective, h, round, [&](int it, double value) {
                    done = before + it;
                    const Heightfield current = flat.with_values(h);
                    if (!report(stage, done, value, &current)) return go_on = false;
                    return go_on_at(value);
                });
            }
            if (coarse_on && settings.refine_coarse_iterations > 0 && go_on && !stopped) {
                // L-BFGS on c alone, h fixed: the smooth directions by themselves.
                const std::vector<double> h0 = h;
                std::vector<double> c(coarse.size(), 0.0);
                LbfgsOptions co = lo;
                co.max_iterations = settings.refine_coarse_iterations;
                lbfgs_minimize(detail::coarse_only_objective(objective, coarse, h0), c, co,
                               [&](int it, double value) {
                                   h = h0;
                                   coarse.apply(c.data(), h);
                                   const Heightfield current = flat.with_values(h);
                                   return go_on = report("refine:coarse", it, value, &current);
                               });
                h = h0;
                coarse.apply(c.data(), h);
            }
            return stalled;  // stopped by the stall rule
        };
        // Single-texel outliers (outlier_repair.h): each flagged texel judged on the slices that see
        // it (its gradient box) among `within` (a ladder rung's; empty: every slice), through the
        // objective with the `active` mask (a local loss, collective); `active` is `within` after.
        const auto repair_outliers = [&](const std::vector<char>& within) {
            detail::OutlierRepairCounts counts;
            std::vector<double> wraps;  // λ/2 of every rank's wavelengths, value units
            for (const auto& entry : by_lambda) wraps.push_back(0.5 * entry.first / std::abs(vscale * texel_um));
            if (wraps.empty()) return counts;
            std::vector<double> no_g;
            const auto local_loss = [&](const std::vector<double>& x, std::size_t texel) {
                const int r = int(texel / std::size_t(cols)), c = int(texel % std::size_t(cols));
                active.assign(observations.size(), 0);
                for (std::size_t i = 0; i < observations.size(); ++i)
                    active[i] = (within.empty() || within[i]) &&
                                (!plans[i] || (std::binary_search(box_rows[i].begin(), box_rows[i].end(), r) &&
                                               std::binary_search(box_cols[i].begin(), box_cols[i].end(), c)));
                return objective(x, no_g);
            };
            const double min_residual = 0.25 * *std::min_element(wraps.begin(), wraps.end());
            counts = detail::repair_outlier_texels(h, rows, cols, settings.outlier_repair_threshold, min_residual,
                                                   std::max(16, rows * cols / 256), wraps, local_loss);
            active = within;
            if (counts.flagged > 0) {
                const Heightfield current = flat.with_values(h);
                if (!report("repair:outliers", counts.kept, double(counts.flagged), &current)) go_on = false;
            }
            return counts;
        };
        // The wavelength ladder (rough surfaces): a round on the slices at wavelengths ≥ each rung,
        // longest first, each from the last ("refine:λ" in the metrics), then every observation.
        if (!white && !settings.calibrate.sigma && settings.refine_ladder_min_um > 0.0 &&
            settings.refine_ladder_iterations > 0) {
            for (auto it = by_lambda.rbegin();
                 it != by_lambda.rend() && it->first >= settings.refine_ladder_min_um && go_on && !stopped; ++it) {
                active.assign(observations.size(), 0);
                for (std::size_t i = 0; i < observations.size(); ++i) {
                    const std::vector<double>& l = observations[i].lambdas_um;
                    active[i] = !l.empty() && *std::min_element(l.begin(), l.end()) >= it->first;
                }
                char name[48];
                std::snprintf(name, sizeof name, "refine:%g", it->first);
                done = 0;
                int rung_start = 0;  // `done` where the last round of the rung began
                const auto rung = [&](int iterations, int stall_window) {
                    rung_start = done;
                    return refine_heights(iterations, name, settings.refine_ladder_relative_tolerance, stall_window,
                                          settings.refine_ladder_stall_tolerance);
                };
                bool stalled = rung(settings.refine_ladder_iterations, settings.refine_ladder_stall_window);
                // The outlier repair on the rung's slices, then the rung again where a texel was kept.
                for (int round = 0; go_on && !stopped &&
                                    round < settings.outlier_repair_rounds;
                     ++round) {
                    const std::vector<char> within = active;
                    if (repair_outliers(within).kept == 0 || !go_on || stopped) break;
                    stalled = rung(settings.refine_ladder_iterations, settings.refine_ladder_stall_window);
                }
                // A stall that no repair answered: the rung runs on to its cap, without the rule (the
                // stall was the loss's own pace, not a trapped texel).
                const int left = settings.refine_ladder_iterations - (done - rung_start);
                if (stalled && left > 0 && go_on && !stopped) rung(left, 0);
            }
            active.clear();
            done = 0;
            if (stopped) return flat.with_values(h);
        }
        if (settings.calibrate.sigma) {
            // σ_p: a golden-section search on log s at fixed heights, alternated with L-BFGS
            // on the heights (rounds of refine_iterations / 6, the last one the rest).
            std::vector<double> no_g;
            sigma_scale = detail::refine_sigma_scale(
                [&](double s) {
                    sigma_scale = s;
                    for (auto& p : plans) p.reset();
                    return objective(h, no_g);
                },
                [&](int round, double s, double value) {
                    sigma_scale = s;
                    for (auto& p : plans) p.reset();
                    const Heightfield current = flat.with_values(h);
                    if (!report("calibrate:sigma", round, value, &current)) return go_on = false;
                    refine_heights(round + 1 < detail::k_sigma_rounds
                                       ? std::max(1, settings.refine_iterations / (2 * detail::k_sigma_rounds))
                                       : std::max(1, settings.refine_iterations - done));
                    return go_on;
                },
                sigma_scale);
            for (auto& p : plans) p.reset();
        } else {
            // White light: the smoothness continuation (white_light.h), then the loss alone.
            for (std::size_t k = 0; white && k < settings.white_smoothness.size() && go_on && !stopped; ++k) {
                smooth_weight = settings.white_smoothness[k];
                if (settings.white_smoothness_iterations > 0) refine_heights(settings.white_smoothness_iterations);
            }
            smooth_weight = 0.0;
            refine_heights(settings.refine_iterations);
        }
        // Single-texel outliers after stage 3 (every slice), then stage 3's last iterations again.
        for (int round = 0; !white && go_on && !stopped && round < settings.outlier_repair_rounds; ++round) {
            const detail::OutlierRepairCounts counts = repair_outliers({});
            if (counts.flagged == 0 || counts.kept == 0 || !go_on || stopped) break;
            refine_heights(settings.outlier_repair_iterations > 0 ? settings.outlier_repair_iterations
                                                                  : settings.refine_iterations,
                           "refine", settings.refine_ladder_relative_tolerance);
        }
        // White light: isolated texels (or connected regions) left a wrap from their neighbours,
        // repaired where the loss agrees, then refined again (white_light.h). The wrap: half the
        // shortest mean wavelength of any rank's observations, in value units (every rank agrees).
        const auto white_wrap_height = [&]() {
            std::vector<double> mine;
            for (const Observation& o : observations)
                if (!o.lambdas_um.empty()) mine.push_back(white_light_lambda_um(o.lambdas_um));
            const std::vector<double> all = all_gather(comm, mine);
            if (all.empty()) return 0.0;
            return 0.5 * *std::min_element(all.begin(), all.end()) / std::abs(vscale * texel_um);
        };
        for (int round = 0; white && go_on && !stopped && round < settings.white_repair_rounds; ++round) {
            std::vector<double> no_g;
            const auto loss_of = [&](const std::vector<double>& x) { return objective(x, no_g); };
            const int budget = std::max(16, rows * cols / 64);
            const int kept =
                detail::repair_defect_regions(h, rows, cols, white_wrap_height(), k_white_repair_threshold, budget,
                                              k_white_repair_region_texels, loss_of);
            const Heightfield current = flat.with_values(h);
            if (!report("repair", kept, 0.0, &current)) break;
            if (kept == 0) break;
            refine_heights(settings.refine_iterations);
        }
        estimate = flat.with_values(h);
        if (stopped) return estimate;
        // The exposures at the final heights (collective: on every rank, whatever it asked).
        if (calibrate_exposure) {
            std::vector<double> g;
            objective(h, g);
        }
        if (calibration) {
            if (calibrate_exposure) calibration->exposures = exposures;
            calibration->sigma_p_scale = sigma_scale;
        }
        refined_sigma_scale = sigma_scale;
    }
    // The model check (recover_field_model.h): the field model's refinement of the unwrapped
    // heights against stage 3's, the one whose model fits the slices better kept (not for
    // white light: no single-wavelength slice, no field model, no unwrapped heights).
    // (Nor for GHS/RGHS slices: the field model is their separable proxy's, not theirs.)
    if (!white && !proxy.proxied && settings.refine_iterations > 0 && settings.model_check_iterations > 0) {
        std::vector<const Observation*> separable;
        std::vector<std::size_t> index;
        for (const auto& entry : by_lambda)
            for (const Observation* o : entry.second) {
                separable.push_back(o);
                index.push_back(std::size_t(o - observations.data()));
            }
        estimate = detail::check_model(separable, index, refined_offsets, refined_sigma_scale, unwrapped, estimate, q,
                                       settings, report, comm, std::isfinite(field_floor) ? field_floor : 0.0);
    }
    return estimate;
}

}  // namespace

Heightfield recover_heights(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                            double vscale, const RecoverSettings& settings,
                            const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                            const Communicator& comm, Calibration* calibration) {
    if (calibration) *calibration = Calibration{};
    // Checks of what every rank is given alike first, then of each rank's share, agreed.
    const Heightfield flat(rows, cols, std::vector<double>(std::size_t(rows) * std::size_t(cols), 0.0), texel_um,
                           vscale);
    if (truth && (truth->rows() != rows || truth->cols() != cols))
        throw std::invalid_argument("recover_heights: truth is " + std::to_string(truth->rows()) + " x " +
                                    std::to_string(truth->cols()) + "; expected " + std::to_string(rows) + " x " +
                                    std::to_string(cols));
    if (vscale == 0.0) throw std::domain_error("recover_heights: vscale 0 maps every height to 0; expected != 0");
    validate_iterations(settings.blurred.iterations, "recover_heights: blur iterations");
    validate_iterations(settings.field.iterations, "recover_heights: field iterations");
    validate_iterations(settings.refine_iterations, "recover_heights: refine iterations");
    if (settings.position_outer_passes < -1 || settings.position_outer_passes > 100)
        throw std::invalid_argument("recover_heights: position outer passes " +
                                    std::to_string(settings.position_outer_passes) +
                                    " is invalid; expected 0 ... 100 (-1: the default)");
    if (!(settings.position_register_radius_texels >= 0.0 && settings.position_register_radius_texels <= 8.0))
        throw std::domain_error("recover_heights: position register radius " +
                                std::to_string(settings.position_register_radius_texels) +
                                " texels is invalid; expected 0 ... 8");
    if (settings.position_outer_field_iterations < 0 || settings.position_outer_refine_iterations < 0)
        throw std::invalid_argument("recover_heights: position outer iterations " +
                                    std::to_string(settings.position_outer_field_iterations) + ", " +
                                    std::to_string(settings.position_outer_refine_iterations) +
                                    " (field, refinement) must be >= 0 (0: the first pass's)");
    if (!(settings.position_outer_tolerance_texels >= 0.0 && std::isfinite(settings.position_outer_tolerance_texels)))
        throw std::domain_error("recover_heights: position outer tolerance " +
                                std::to_string(settings.position_outer_tolerance_texels) +
                                " texels is invalid; expected a finite value >= 0");
    if (settings.position_register_newton_steps < 0 || settings.position_register_newton_steps > 10 ||
        !(settings.position_newton_step_texels > 0.0 && settings.position_newton_step_texels <= 2.0) ||
        !(settings.position_newton_cap_texels > 0.0 && settings.position_newton_cap_texels <= 4.0))
        throw std::invalid_argument("recover_heights: position Newton steps " +
                                    std::to_string(settings.position_register_newton_steps) + " / stencil " +
                                    std::to_string(settings.position_newton_step_texels) + " / cap " +
                                    std::to_string(settings.position_newton_cap_texels) +
                                    " texels is invalid; expected 0 ... 10 / > 0 ... 2 / > 0 ... 4");
    if (settings.position_outer_smooth_nodes < 0 || settings.position_outer_smooth_nodes > 16)
        throw std::invalid_argument("recover_heights: position outer smooth nodes " +
                                    std::to_string(settings.position_outer_smooth_nodes) +
                                    " is invalid; expected 0 (off), 1 (affine) or 2 ... 16");
    if (!(settings.position_rescue_factor == 0.0 ||
          (settings.position_rescue_factor > 1.0 && settings.position_rescue_factor <= 1e6)) ||
        !(settings.position_rescue_radius_texels > 0.0 && settings.position_rescue_radius_texels <= 16.0) ||
        !(settings.position_rescue_step_texels > 0.0 &&
          settings.position_rescue_radius_texels / (2.0 * settings.position_rescue_step_texels) <= 16.0))
        throw std::invalid_argument("recover_heights: position rescue factor " +
                                    std::to_string(settings.position_rescue_factor) + " / radius " +
                                    std::to_string(settings.position_rescue_radius_texels) + " / step " +
                                    std::to_string(settings.position_rescue_step_texels) +
                                    " texels is invalid; expected 0 (off) or > 1 ... 1e6 / > 0 ... 16 / > 0 with "
                                    "radius / (2 step) <= 16");
    if (!(settings.position_outer_field_below_texels >= 0.0 && std::isfinite(settings.position_outer_field_below_texels)))
        throw std::domain_error("recover_heights: position outer field-below " +
                                std::to_string(settings.position_outer_field_below_texels) +
                                " texels is invalid; expected a finite value >= 0");
    if (settings.position_outer_stall_passes < 0 || settings.position_outer_stall_passes > 100 ||
        !(settings.position_outer_stall_tolerance == -1.0 ||
          (settings.position_outer_stall_tolerance >= 0.0 && settings.position_outer_stall_tolerance <= 1.0)))
        throw std::invalid_argument("recover_heights: position outer stall passes " +
                                    std::to_string(settings.position_outer_stall_passes) + " / tolerance " +
                                    std::to_string(settings.position_outer_stall_tolerance) +
                                    " is invalid; expected 0 ... 100 / 0 ... 1 (-1: the default)");
    validate_iterations(settings.refine_coarse_iterations, "recover_heights: refine coarse iterations");
    if (!(std::isfinite(settings.refine_coarse_spacing) &&
          (settings.refine_coarse_spacing == 0.0 || settings.refine_coarse_spacing >= 1.0)))
        throw std::domain_error("recover_heights: refine_coarse_spacing " +
                                std::to_string(settings.refine_coarse_spacing) + "; expected 0 (off) or >= 1 texel");
    if (!(std::isfinite(settings.refine_coarse_weight) && settings.refine_coarse_weight >= 0.0))
        throw std::domain_error("recover_heights: refine_coarse_weight " +
                                std::to_string(settings.refine_coarse_weight) + "; expected finite and >= 0");
    if (!(std::isfinite(settings.field_lambda_min_um) && settings.field_lambda_min_um >= 0.0))
        throw std::domain_error("recover_heights: field_lambda_min_um " + std::to_string(settings.field_lambda_min_um) +
                                " is invalid; expected a finite wavelength >= 0 um (0: every wavelength)");
    if (settings.field_wavelengths < 0)
        throw std::invalid_argument("recover_heights: field_wavelengths " + std::to_string(settings.field_wavelengths) +
                                    " is invalid; expected >= 0 (0: every wavelength)");
    if (settings.refine_ladder_wavelengths < 0)
        throw std::invalid_argument("recover_heights: refine_ladder_wavelengths " +
                                    std::to_string(settings.refine_ladder_wavelengths) +
                                    " is invalid; expected >= 0 (0: no ladder)");
    if (!(std::isfinite(settings.refine_ladder_min_um) && settings.refine_ladder_min_um >= 0.0))
        throw std::domain_error("recover_heights: refine_ladder_min_um " +
                                std::to_string(settings.refine_ladder_min_um) +
                                " is invalid; expected a finite wavelength >= 0 um (0: no ladder)");
    validate_iterations(settings.refine_ladder_iterations, "recover_heights: refine ladder iterations");
    if (!(std::isfinite(settings.refine_ladder_relative_tolerance) && settings.refine_ladder_relative_tolerance >= 0.0 &&
          settings.refine_ladder_relative_tolerance < 1.0))
        throw std::domain_error("recover_heights: refine_ladder_relative_tolerance " +
                                std::to_string(settings.refine_ladder_relative_tolerance) +
                                " is invalid; expected 0 (off) to below 1");
    if (settings.refine_ladder_stall_window < 0 ||
        !(std::isfinite(settings.refine_ladder_stall_tolerance) && settings.refine_ladder_stall_tolerance >= 0.0))
        throw std::invalid_argument("recover_heights: refine ladder stall window " +
                                    std::to_string(settings.refine_ladder_stall_window) + " / tolerance " +
                                    std::to_string(settings.refine_ladder_stall_tolerance) +
                                    " is invalid; expected >= 0 (0: off) / a finite value >= 0");
    validate_iterations(settings.outlier_repair_iterations, "recover_heights: outlier repair iterations");
    if (settings.outlier_repair_rounds < 0 || settings.outlier_repair_rounds > 100 ||
        !(settings.outlier_repair_threshold > 0.0 && std::isfinite(settings.outlier_repair_threshold)))
        throw std::invalid_argument("recover_heights: outlier repair rounds " +
                                    std::to_string(settings.outlier_repair_rounds) + " / threshold " +
                                    std::to_string(settings.outlier_repair_threshold) +
                                    " is invalid; expected 0 ... 100 / a finite value > 0");
    validate_iterations(settings.white_smoothness_iterations, "recover_heights: white smoothness iterations");
    for (double w : settings.white_smoothness)
        if (!(w >= 0.0 && w <= 1e12))
            throw std::domain_error("recover_heights: white smoothness weight " + std::to_string(w) +
                                    " is invalid; expected a finite value >= 0");
    detail::skip_field_refinement(0.0, 0.0, settings.model_check_skip_ratio);  // throws when out of [0, 1]
    // Single-wavelength separable observations, grouped by wavelength, feed the field stage.
    // (Pointers, not copies: the references are most of the memory a run holds.)
    std::map<double, std::vector<const Observation*>> by_lambda;
    run_agreed(comm, [&] {
        for (std::size_t i = 0; i < observations.size(); ++i) {
            validate(observations[i], i);
            // Its stages fit whole slices; silently fitting masked pixels would be a wrong answer.
            if (!observations[i].weights.empty())
                throw std::invalid_argument("observation " + std::to_string(i) +
                                            " has per-pixel weights, which recover does not use; expected "
                                            "observations without weights (invert uses them)");
        }
        // Here, not only in the renderer: the stages render inside parallel regions.
        for (const Observation& o : observations)
            validate_footprint(o.query.sigma_p_um, flat.period_x_um(), flat.period_y_um());
        for (const Observation& o : observations)
            if (o.lambdas_um.size() == 1 && detail::has_field_stage(o.query.model))
                by_lambda[o.lambdas_um[0]].push_back(&o);
    });
    // Every rank runs every rank's wavelengths (its share of one may be empty).
    std::vector<double> lambdas_here;
    for (const auto& entry : by_lambda) lambdas_here.push_back(entry.first);
    for (double lambda : all_gather(comm, lambdas_here)) by_lambda[lambda];
    std::vector<double> total{double(observations.size())};
    comm.allreduce_sum(total);
    if (total[0] == 0.0) throw std::invalid_argument("recover_heights: no observations given");
    // From here on the ranks meet in collective calls: one rank's failure ends them all.
    return run_or_abort(comm, [&] {
        return recover_stages(observations, by_lambda, total[0], flat, rows, cols, texel_um, vscale, settings, on_step,
                              truth, comm, calibration);
    });
}

}  // namespace wavebrdf
