// Stages 1 and 2, the field retrieval and the unwrapping, with the steps around them: held
// exposures and σ_p's search at the unwrapped heights (stages.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>

#include "recovery/field_positions.h"
#include "recovery/recover_positions.h"
#include "recovery/sigma_search.h"
#include "recovery/stages.h"

namespace wavebrdf::detail {

namespace {

// Heights × the proxy's scale (the field stage's heights are s·H).
std::vector<double> scaled(const StageContext& context, std::vector<double> h) {
    const double s = context.proxy.height_scale;
    if (s != 1.0)
        for (double& v : h) v *= s;
    return h;
}

// The field stage's start at one wavelength: the object of the current heights.
std::vector<std::complex<double>> start_object(const StageContext& context, const Heightfield& estimate,
                                               double lambda_um) {
    if (context.proxy.height_scale == 1.0) return object_from_heights(estimate, lambda_um, context.refine);
    return object_from_heights(estimate.with_values(scaled(context, estimate.values())), lambda_um, context.refine);
}

}  // namespace

bool FieldStage::run(const StageContext& context, RecoveryState& state) const {
    return retrieve(context, state, field);
}

void FieldStage::unwrap(const StageContext& context, RecoveryState& state) const {
    // Heights on the refined grid from the fields so far (spatially unwrapped), then at the texel
    // centres (refine is odd: texel (i, j) is sample (i·q + q/2, j·q + q/2)).
    const int q = context.refine, rows = context.rows, cols = context.cols, obj_cols = cols * q;
    const double to_texel = 1.0 / (context.vscale * context.texel_um * context.proxy.height_scale);
    const std::vector<double> fine_um =
        unwrap_heights(state.fields.lambdas_um, state.fields.objects, height_range_um, rows * q, obj_cols);
    std::vector<double> h(std::size_t(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            h[std::size_t(i) * cols + j] = fine_um[std::size_t(i * q + q / 2) * obj_cols + (j * q + q / 2)] * to_texel;
    state.estimate = context.flat.with_values(h);
}

bool FieldStage::retrieve(const StageContext& context, RecoveryState& state,
                          const FieldRetrievalSettings& settings) const {
    // Longest wavelength first: its phases are the least wrapped, so it converges from the
    // blurred fit most surely; each next field starts from the heights of all fields before it.
    const auto& by_lambda = context.by_lambda;
    // Every rank holds every wavelength's key (maybe empty), so all ranks skip the same ones.
    const auto end = by_lambda.rend();
    FieldRetrievalSettings field_settings = settings;
    for (auto it = by_lambda.rbegin(); it != end && it->first >= lambda_min_um; ++it) {
            const double lambda = it->first;
            const StageId name(StageKind::Field, stage_part(lambda));
            // This wavelength's observations where they are (pointers: no copy of the references);
            // with σ_p calibration copies at σ_p · s while its field runs (one wavelength's at a
            // time); with position calibration the offsets are applied and corrected inside
            // (field_positions.h).
            std::vector<Observation> group;
            std::vector<const Observation*> used = it->second;
            const bool held = !state.field_exposures.empty();
            if (state.sigma_scale != 1.0 || context.proxy.proxied || held) {
                group.reserve(it->second.size());
                for (const Observation* o : it->second) {
                    group.push_back(*o);
                    group.back().query.sigma_p_um *= state.sigma_scale;
                    group.back().query.model = field_proxy_model(o->query.model);
                    if (held) {
                        const double e = state.field_exposures[std::size_t(o - context.field_observations().data())];
                        for (float& v : group.back().reference) v = float(double(v) / e);
                    }
                }
                for (std::size_t k = 0; k < group.size(); ++k) used[k] = &group[k];
            }
            field_settings.calibrate_exposure = !held && calibrate_exposure;
            const auto on_iteration = [&](int iteration, double loss) {
                return context.report(name, iteration, loss, nullptr);
            };
            FieldRetrievalResult r = [&] {
                const std::vector<std::complex<double>> start = start_object(context, state.estimate, lambda);
                if (!positions && field_tiles_apply(context.rows, context.cols, tiling))
                    return retrieve_field_tiled(used, lambda, context.rows, context.cols, context.texel_um, start,
                                                field_settings, tiling, on_iteration, context.comm);
                if (!positions)
                    return retrieve_field(used, lambda, context.rows, context.cols, context.texel_um, start,
                                          field_settings, on_iteration, context.comm);
                std::vector<std::size_t> index;
                for (const Observation* o : it->second)
                    index.push_back(context.position_of[std::size_t(o - context.field_observations().data())]);
                return retrieve_field_with_positions(used, index, lambda, context.rows, context.cols,
                                                     context.texel_um, start, field_settings, on_iteration,
                                                     state.offsets_um, context.comm);
            }();
            if (context.stopped()) return false;
            if (std::isfinite(r.relative_loss) && r.relative_loss > 0.0)
                state.field_floor = std::min(state.field_floor, r.relative_loss);
            std::vector<Observation>().swap(group);
            FieldSet& fields = state.fields;
            const auto at = std::find(fields.lambdas_um.begin(), fields.lambdas_um.end(), lambda);
            if (at == fields.lambdas_um.end()) {
                fields.lambdas_um.push_back(lambda);
                fields.objects.push_back(std::move(r.object));
            } else {
                fields.objects[std::size_t(at - fields.lambdas_um.begin())] = std::move(r.object);
            }
            const bool last = std::next(it) == end || std::next(it)->first < lambda_min_um;
            if (!last) {
                unwrap(context, state);
                if (!context.report(name, r.iterations, r.relative_loss, &state.estimate)) return false;
            }
        }
    return true;
}

bool UnwrapStage::run(const StageContext& context, RecoveryState& state) const {
    field->unwrap(context, state);
    return context.report(StageKind::Unwrap, pass, 0.0, &state.estimate);
}

bool HeldExposuresStage::run(const StageContext& context, RecoveryState& state) const {
    state.field_exposures =
        exposures_at(context.observations, context.position_of, state.estimate, state.sigma_scale, state.offsets_um);
    return context.report(StageKind::ExposuresHeld, 0, 0.0, &state.estimate);
}

bool SigmaResearchStage::run(const StageContext& context, RecoveryState& state) const {
    // σ_p searched again at the unwrapped heights (sigma_search.h: ≈ 0.4–1 % off, where the
    // blurred fit's bias the first search towards 1); when it moved, the field stage runs again
    // at the new σ_p from the unwrapped heights (every field anew) and is unwrapped again. With
    // exposure calibration there was no first search (the energy ratio pulls it off at the
    // blurred heights): this is then the only one, over the first search's whole range, and
    // its answer is kept only where its loss is below the stated σ_p's (guarded_sigma_scale).
    const double s = presearched
                         ? research_sigma_scale(context.observations, context.observations_total, state.estimate,
                                                state.sigma_scale, loss, calibrate_exposure, context.comm)
                         : guarded_sigma_scale(context.observations, context.observations_total, state.estimate, loss,
                                               calibrate_exposure, context.comm);
    const bool moved = sigma_scale_moved(state.sigma_scale, s);
    if (!context.report({StageKind::SigmaSearch, "unwrapped"}, moved ? 1 : 0, s, &state.estimate)) return false;
    if (!moved) return true;
    state.sigma_scale = s;
    state.calibration.sigma_p_scale = state.calibration.sigma_p_scale_fields = s;
    state.fields = FieldSet{};
    if (hold_exposures)  // at the unwrapped heights and the new σ_p
        state.field_exposures =
            exposures_at(context.observations, context.position_of, state.estimate, state.sigma_scale, state.offsets_um);
    if (!field->run(context, state)) return false;
    field->unwrap(context, state);
    return context.report(StageKind::Unwrap, 1, 0.0, &state.estimate);
}

}  // namespace wavebrdf::detail
