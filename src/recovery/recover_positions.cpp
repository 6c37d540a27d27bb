// Stage 3 of recover_heights with the footprint positions refined as well (recover_positions.h).

#include "recovery/recover_positions.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <omp.h>
#include <stdexcept>
#include <string>

#include "core/cholesky.h"
#include "core/exact_sum.h"
#include "core/parallel.h"
#include "recovery/calibration_detail.h"
#include "recovery/observation_loss.h"
#include "recovery/refinement.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::detail {

namespace {

// The position index a registration takes (one per observation, each naming a position of the
// offsets: 2 values per position) checked, with the function's name in the message.
void check_position_index(const char* function, const std::vector<Observation>& observations,
                          const std::vector<std::size_t>& index, const std::vector<double>& offsets_um) {
    const std::size_t positions = offsets_um.size() / 2;
    if (index.size() != observations.size() || offsets_um.size() % 2 != 0)
        throw std::invalid_argument(std::string(function) + ": " + std::to_string(index.size()) +
                                    " position indices for " + std::to_string(observations.size()) + " observations, " +
                                    std::to_string(offsets_um.size()) + " offsets; expected one each, 2 per position");
    for (std::size_t p : index)
        if (p >= positions)
            throw std::invalid_argument(std::string(function) + ": position " + std::to_string(p) + " outside the " +
                                        std::to_string(positions) + " positions' offsets given");
}

// The observations (and their position indices) of the positions flagged in `of`.
void observations_of(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                     const std::vector<char>& of, std::vector<Observation>& chosen,
                     std::vector<std::size_t>& chosen_index) {
    for (std::size_t i = 0; i < observations.size(); ++i)
        if (of[index[i]]) {
            chosen.push_back(observations[i]);
            chosen_index.push_back(index[i]);
        }
}

}  // namespace

std::vector<std::array<double, 2>> gather_positions(const std::vector<Observation>& observations,
                                                    std::vector<std::size_t>& index, const Communicator& comm) {
    std::vector<double> mine;
    mine.reserve(2 * observations.size());
    for (const Observation& o : observations) mine.insert(mine.end(), {o.query.x_um, o.query.y_um});
    const std::vector<double> all = all_gather(comm, mine);
    std::vector<std::array<double, 2>> positions;
    positions.reserve(all.size() / 2);
    for (std::size_t k = 0; 2 * k + 1 < all.size(); ++k) positions.push_back({all[2 * k], all[2 * k + 1]});
    std::sort(positions.begin(), positions.end());
    positions.erase(std::unique(positions.begin(), positions.end()), positions.end());
    index.resize(observations.size());
    for (std::size_t i = 0; i < observations.size(); ++i) {
        const std::array<double, 2> p{observations[i].query.x_um, observations[i].query.y_um};
        index[i] = std::size_t(std::lower_bound(positions.begin(), positions.end(), p) - positions.begin());
    }
    return positions;
}

std::vector<double> exposures_at(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                                 const Heightfield& heights, double sigma_scale,
                                 const std::vector<double>& offsets_um) {
    check_position_index("exposures_at", observations, index, offsets_um);
    std::vector<double> exposures(observations.size(), 1.0);
    RegionGuard guard;
#pragma omp parallel for schedule(dynamic)
    for (std::ptrdiff_t k = 0; k < std::ptrdiff_t(observations.size()); ++k)
        guard.run([&] {
            const Observation& o = observations[std::size_t(k)];
            const std::size_t p = index[std::size_t(k)];
            const std::array<double, 2> offset{offsets_um[2 * p], offsets_um[2 * p + 1]};
            SlicePlan<float> plan(heights, calibrated_query(o, sigma_scale, &offset), o.lambdas_um, o.resolution,
                                  o.channels(), {}, false);
            const double e = observation_exposure(plan.forward(), o);
            if (std::isfinite(e) && e > 0.0) exposures[std::size_t(k)] = e;
        });
    guard.rethrow();
    return exposures;
}

namespace {

// Per position and candidate of the grid offset + step·(a, b), |a|, |b| ≤ half, the sum of its
// observations' losses (exact, every rank's), then per position its count marker (1 where it has
// an observation): positions · (candidates + 1) values.
std::vector<double> grid_losses(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                                const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                                int half, double step_texels, const std::vector<double>& offsets_um,
                                const Communicator& comm) {
    const std::size_t positions = offsets_um.size() / 2;
    const int side = 2 * half + 1;
    const std::size_t candidates = std::size_t(side) * side;
    const double texel_um = heights.texel_um();
    // Per position and candidate, the sum of its observations' losses (exact, every rank's), and
    // per position its count of observations (whether it has any).
    std::vector<double> losses;
    ExactParallelSum exact_sum(positions * (candidates + 1));
    std::vector<double> total{double(observations.size())};  // every rank's (integers: exact)
    comm.allreduce_sum(total);
    const double scale = total[0] > 0.0 ? 1.0 / total[0] : 1.0;
    std::vector<int> row0{0};
    exact_sum.run(observations.size(), comm, losses, [&](std::size_t i, ExactScratch& scratch) {
        const Observation& o = observations[i];
        const std::size_t p = index[i];
        std::vector<double>& out = scratch.vector();
        std::vector<int> columns(candidates + 1);
        for (std::size_t c = 0; c < candidates; ++c) {
            const std::array<double, 2> offset{
                offsets_um[2 * p] + texel_um * step_texels * (int(c / std::size_t(side)) - half),
                offsets_um[2 * p + 1] + texel_um * step_texels * (int(c % std::size_t(side)) - half)};
            out[p * candidates + c] = scale * observation_misfit(heights, o, settings.loss, sigma_scale, &offset,
                                                                 settings.calibrate_exposure, false);
            columns[c] = int(p * candidates + c);
        }
        out[positions * candidates + p] = 1.0;
        columns[candidates] = int(positions * candidates + p);
        scratch.take_box(row0, columns, 1);
        return 0.0;
    });
    return losses;
}

// One grid of register_positions (recover_positions.h): the best point of the grid, then the
// parabola. Returns nothing; offsets_um is updated.
void register_grid(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                   const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                   double radius_texels, double step_texels, bool parabola, std::vector<double>& offsets_um,
                   const Communicator& comm) {
    if (!(radius_texels >= 0.0) || !(step_texels > 0.0) || !(radius_texels / step_texels <= 16.0))
        throw std::invalid_argument("register_positions: radius " + std::to_string(radius_texels) + " / step " +
                                    std::to_string(step_texels) +
                                    " texels invalid; expected radius >= 0, step > 0, radius/step <= 16");
    check_position_index("register_positions", observations, index, offsets_um);
    const std::size_t positions = offsets_um.size() / 2;
    const int half = int(std::floor(radius_texels / step_texels + 1e-9));
    const int side = 2 * half + 1;
    const std::size_t candidates = std::size_t(side) * side;
    const double texel_um = heights.texel_um();
    const std::vector<double> losses = grid_losses(observations, index, heights, settings, sigma_scale, half,
                                                   step_texels, offsets_um, comm);
    for (std::size_t p = 0; p < positions; ++p) {
        if (losses[positions * candidates + p] == 0.0) continue;  // no observation here
        const double* l = &losses[p * candidates];
        std::size_t best = candidates / 2;  // no shift unless a smaller loss
        for (std::size_t c = 0; c < candidates; ++c)
            if (l[c] < l[best]) best = c;
        const int a = int(best / std::size_t(side)), b = int(best % std::size_t(side));
        // The parabola's vertex through (−1, 0, +1) steps about the best point, per coordinate.
        const auto vertex = [](double minus, double centre, double plus) {
            const double curvature = minus - 2.0 * centre + plus;
            if (!(curvature > 0.0)) return 0.0;
            return std::clamp(0.5 * (minus - plus) / curvature, -0.5, 0.5);
        };
        double sx = step_texels * (a - half), sy = step_texels * (b - half);
        if (parabola && a > 0 && a + 1 < side)
            sx += step_texels * vertex(l[std::size_t(a - 1) * side + b], l[best], l[std::size_t(a + 1) * side + b]);
        if (parabola && b > 0 && b + 1 < side)
            sy += step_texels * vertex(l[std::size_t(a) * side + b - 1], l[best], l[std::size_t(a) * side + b + 1]);
        offsets_um[2 * p] += texel_um * sx;
        offsets_um[2 * p + 1] += texel_um * sy;
    }
}

}  // namespace

double register_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                          const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                          double radius_texels, double step_texels, std::vector<double>& offsets_um,
                          const Communicator& comm) {
    const std::vector<double> start = offsets_um;
    // Coarse to fine: ± radius in steps of 2·step, then ± step in steps of step about the best.
    if (radius_texels > step_texels && step_texels > 0.0) {
        register_grid(observations, index, heights, settings, sigma_scale, radius_texels, 2.0 * step_texels, false,
                      offsets_um, comm);
        register_grid(observations, index, heights, settings, sigma_scale, step_texels, step_texels, true, offsets_um,
                      comm);
    } else {
        register_grid(observations, index, heights, settings, sigma_scale, radius_texels, step_texels, true, offsets_um,
                      comm);
    }
    const double texel_um = heights.texel_um();
    double moved_sq = 0.0;
    for (std::size_t k = 0; k < start.size(); ++k) moved_sq += (offsets_um[k] - start[k]) * (offsets_um[k] - start[k]);
    return start.empty() ? 0.0 : std::sqrt(moved_sq / double(start.size())) / texel_um;
}

int rescue_lost_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                          const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                          double factor, double radius_texels, double step_texels, std::vector<double>& offsets_um,
                          const Communicator& comm, double* median_loss) {
    if (!(factor > 1.0) || !(radius_texels > 0.0))
        throw std::invalid_argument("rescue_lost_positions: factor " + std::to_string(factor) + " / radius " +
                                    std::to_string(radius_texels) + " invalid; expected factor > 1, radius > 0");
    check_position_index("rescue_lost_positions", observations, index, offsets_um);
    const std::size_t positions = offsets_um.size() / 2;
    const std::vector<double> losses = grid_losses(observations, index, heights, settings, sigma_scale, 0, 1.0,
                                                   offsets_um, comm);
    std::vector<double> seen;
    for (std::size_t p = 0; p < positions; ++p)
        if (losses[positions + p] != 0.0) seen.push_back(losses[p]);
    if (median_loss) *median_loss = 0.0;
    if (seen.empty()) return 0;
    std::nth_element(seen.begin(), seen.begin() + std::ptrdiff_t(seen.size() / 2), seen.end());
    const double median = seen[seen.size() / 2];
    if (median_loss) *median_loss = median;
    std::vector<char> lost(positions, 0);
    int count = 0;
    for (std::size_t p = 0; p < positions; ++p)
        if (losses[positions + p] != 0.0 && losses[p] > factor * median) {
            lost[p] = 1;
            ++count;
        }
    if (count == 0) return 0;
    // Only the lost positions' observations: the others have none and keep their offsets.
    std::vector<Observation> mine;
    std::vector<std::size_t> mine_index;
    observations_of(observations, index, lost, mine, mine_index);
    const std::vector<double> before = offsets_um;
    register_positions(mine, mine_index, heights, settings, sigma_scale, radius_texels, step_texels, offsets_um, comm);
    // A lost position whose offset lay more than half the radius from its stated
    // centre (either axis) before the search is searched about the stated centre as well, and
    // keeps the better of the two: the registration can carry a position far to the wrong side
    // of its centre, where a search about its offset no longer reaches the truth.
    const double half_radius_um = 0.5 * radius_texels * heights.texel_um();
    std::vector<double> centred = offsets_um;
    std::vector<char> far(positions, 0);
    bool any_far = false;
    for (std::size_t p = 0; p < positions; ++p)
        if (lost[p] && std::max(std::abs(before[2 * p]), std::abs(before[2 * p + 1])) > half_radius_um) {
            far[p] = 1;
            any_far = true;
            centred[2 * p] = centred[2 * p + 1] = 0.0;
        }
    if (!any_far) return count;  // (every rank: lost and the offsets are the same everywhere)
    std::vector<Observation> far_observations;
    std::vector<std::size_t> far_index;
    observations_of(mine, mine_index, far, far_observations, far_index);
    register_positions(far_observations, far_index, heights, settings, sigma_scale, radius_texels, step_texels,
                       centred, comm);
    const std::vector<double> at_offset =
        grid_losses(far_observations, far_index, heights, settings, sigma_scale, 0, 1.0, offsets_um, comm);
    const std::vector<double> at_centre =
        grid_losses(far_observations, far_index, heights, settings, sigma_scale, 0, 1.0, centred, comm);
    for (std::size_t p = 0; p < positions; ++p)
        if (far[p] && at_centre[p] < at_offset[p]) {
            offsets_um[2 * p] = centred[2 * p];
            offsets_um[2 * p + 1] = centred[2 * p + 1];
        }
    return count;
}

int newton_register_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                              const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                              double step_texels, double cap_texels, std::vector<double>& offsets_um,
                              const Communicator& comm) {
    if (!(step_texels > 0.0) || !(cap_texels > 0.0))
        throw std::invalid_argument("newton_register_positions: step " + std::to_string(step_texels) + " / cap " +
                                    std::to_string(cap_texels) + " texels invalid; expected step > 0, cap > 0");
    check_position_index("newton_register_positions", observations, index, offsets_um);
    const std::size_t positions = offsets_um.size() / 2;
    const double texel_um = heights.texel_um(), h = step_texels;
    // The 3 × 3 stencil: candidate (a + 1) · 3 + (b + 1) is the offset + step · (a, b).
    const std::vector<double> stencil = grid_losses(observations, index, heights, settings, sigma_scale, 1, step_texels,
                                                    offsets_um, comm);
    std::vector<double> step(2 * positions, 0.0), centre(positions, 0.0);
    std::vector<char> pending(positions, 0);
    for (std::size_t p = 0; p < positions; ++p) {
        if (stencil[positions * 9 + p] == 0.0) continue;  // no observation here
        const double* s = &stencil[p * 9];
        const auto at = [s](int a, int b) { return s[(a + 1) * 3 + (b + 1)]; };
        const double gx = (at(1, 0) - at(-1, 0)) / (2.0 * h), gy = (at(0, 1) - at(0, -1)) / (2.0 * h);
        const double hxx = (at(1, 0) - 2.0 * at(0, 0) + at(-1, 0)) / (h * h);
        const double hyy = (at(0, 1) - 2.0 * at(0, 0) + at(0, -1)) / (h * h);
        const double hxy = (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * h * h);
        const double det = hxx * hyy - hxy * hxy;
        if (!(hxx > 0.0) || !(det > 0.0)) continue;  // not a minimum's basin: no step
        double sx = -(hyy * gx - hxy * gy) / det, sy = -(hxx * gy - hxy * gx) / det;
        const double length = std::hypot(sx, sy);
        if (!(length > 0.0) || !std::isfinite(length)) continue;
        if (length > cap_texels) {
            sx *= cap_texels / length;
            sy *= cap_texels / length;
        }
        step[2 * p] = sx;
        step[2 * p + 1] = sy;
        centre[p] = at(0, 0);
        pending[p] = 1;
    }
    int moved = 0;
    for (int attempt = 0; attempt < 4; ++attempt) {  // the step, then halved at most 3 times
        if (std::find(pending.begin(), pending.end(), char(1)) == pending.end()) break;
        std::vector<double> trial = offsets_um;
        for (std::size_t p = 0; p < positions; ++p)
            if (pending[p]) {
                trial[2 * p] += texel_um * step[2 * p];
                trial[2 * p + 1] += texel_um * step[2 * p + 1];
            }
        const std::vector<double> losses = grid_losses(observations, index, heights, settings, sigma_scale, 0, 1.0,
                                                       trial, comm);
        for (std::size_t p = 0; p < positions; ++p) {
            if (!pending[p]) continue;
            if (losses[p] < centre[p]) {
                offsets_um[2 * p] = trial[2 * p];
                offsets_um[2 * p + 1] = trial[2 * p + 1];
                pending[p] = 0;
                ++moved;
            } else {
                step[2 * p] *= 0.5;
                step[2 * p + 1] *= 0.5;
            }
        }
    }
    return moved;
}

Heightfield refine_heights_and_positions(const std::vector<Observation>& observations, double observations_total,
                                         const Heightfield& flat, const Heightfield& estimate,
                                         const PositionFitSettings& settings, const StageReport& report,
                                         const Communicator& comm, std::vector<std::array<double, 2>>& offsets_um,
                                         const std::vector<double>& initial_offsets_um,
                                         std::vector<double>* exposures_out, double* sigma_scale,
                                         std::vector<double>* position_offsets_out, double* last_loss) {
    std::vector<std::size_t> index;
    const std::vector<std::array<double, 2>> positions = gather_positions(observations, index, comm);
    const std::size_t cells = estimate.values().size(), count = positions.size();
    const double texel_um = flat.texel_um();
    std::vector<double> x = estimate.values();
    x.resize(cells + 2 * count, 0.0);
    if (initial_offsets_um.size() == 2 * count)
        for (std::size_t k = 0; k < 2 * count; ++k) x[cells + k] = initial_offsets_um[k] / texel_um;

    ObservationObjective objective(observations, observations_total, flat, settings.loss,
                                   settings.calibrate_exposure, sigma_scale ? *sigma_scale : 1.0, comm, &index, count);
    RefinementRounds rounds(std::ref(objective), flat, settings.history,
                            mean_observation_loss(observations, observations_total, flat, settings.loss, comm),
                            report);
    if (settings.calibrate_sigma && sigma_scale)
        *sigma_scale = calibrate_sigma_rounds(objective, rounds, x, settings.iterations, report);
    else
        rounds.run(x, settings.iterations);
    if (last_loss && rounds.reported()) *last_loss = rounds.last_loss();
    if (settings.calibrate_exposure) {  // the exposures at the final heights (collective)
        std::vector<double> g;
        objective(x, g);
        if (exposures_out) *exposures_out = objective.exposures();
    }
    const std::vector<double> off = objective.offsets_um(x);
    if (position_offsets_out) *position_offsets_out = off;
    offsets_um.resize(observations.size());
    for (std::size_t i = 0; i < observations.size(); ++i) offsets_um[i] = {off[2 * index[i]], off[2 * index[i] + 1]};
    return flat.with_values(std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(cells)));
}

namespace {

// The smooth basis at the bounding-box coordinates t (each in [0, 1] inside the box): nodes = 1:
// (1, t0 − ½, t1 − ½); nodes = k ≥ 2: bilinear hats on k × k nodes (t clamped to the box).
void smooth_basis(const double t_in[2], int nodes, double* b) {
    if (nodes == 1) {
        b[0] = 1.0;
        b[1] = t_in[0] - 0.5;
        b[2] = t_in[1] - 0.5;
        return;
    }
    std::fill(b, b + nodes * nodes, 0.0);
    int k[2];
    double f[2];
    for (int d = 0; d < 2; ++d) {
        const double u = std::clamp(t_in[d], 0.0, 1.0) * (nodes - 1);
        k[d] = std::min(nodes - 2, std::max(0, int(std::floor(u))));
        f[d] = u - k[d];
    }
    for (int a = 0; a < 2; ++a)
        for (int c = 0; c < 2; ++c) b[(k[0] + a) * nodes + (k[1] + c)] += (a ? f[0] : 1 - f[0]) * (c ? f[1] : 1 - f[1]);
}

}  // namespace

std::array<double, 2> SmoothDisplacement::at(double x_um, double y_um) const {
    if (nodes < 1) return {0.0, 0.0};
    const int m = nodes == 1 ? 3 : nodes * nodes;
    std::vector<double> b(static_cast<std::size_t>(m), 0.0);
    const double p[2] = {x_um, y_um};
    double t[2];
    for (int d = 0; d < 2; ++d) t[d] = hi_um[d] > lo_um[d] ? (p[d] - lo_um[d]) / (hi_um[d] - lo_um[d]) : 0.0;
    smooth_basis(t, nodes, b.data());
    std::array<double, 2> v{0.0, 0.0};
    for (int d = 0; d < 2; ++d)
        for (int q = 0; q < m; ++q)
            v[std::size_t(d)] += b[std::size_t(q)] * coefficients[std::size_t(d)][std::size_t(q)];
    return v;
}

SmoothDisplacement fit_smooth_displacement(const std::vector<std::array<double, 2>>& centres_um,
                                           const std::vector<double>& values, int nodes) {
    if (nodes < 1)
        throw std::invalid_argument("remove_smooth_displacement: nodes must be >= 1, got " + std::to_string(nodes));
    const std::size_t n = centres_um.size();
    if (values.size() != 2 * n)
        throw std::invalid_argument("remove_smooth_displacement: values must hold 2 per centre, got " +
                                    std::to_string(values.size()) + " for " + std::to_string(n));
    SmoothDisplacement fit;
    if (n == 0) return fit;
    fit.nodes = nodes;
    double* lo = fit.lo_um.data();
    double* hi = fit.hi_um.data();
    lo[0] = hi[0] = centres_um[0][0];
    lo[1] = hi[1] = centres_um[0][1];
    for (const auto& c : centres_um)
        for (int d = 0; d < 2; ++d) {
            lo[d] = std::min(lo[d], c[d]);
            hi[d] = std::max(hi[d], c[d]);
        }
    // Basis values per position (m functions).
    const int m = nodes == 1 ? 3 : nodes * nodes;
    std::vector<double> basis(n * std::size_t(m), 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        double t[2];
        for (int d = 0; d < 2; ++d) t[d] = hi[d] > lo[d] ? (centres_um[i][d] - lo[d]) / (hi[d] - lo[d]) : 0.0;
        smooth_basis(t, nodes, &basis[i * std::size_t(m)]);
    }
    // Normal equations (a tiny ridge keeps nodes without positions at 0), Cholesky.
    std::vector<double> a(std::size_t(m) * m, 0.0);
    for (std::size_t i = 0; i < n; ++i)
        for (int p = 0; p < m; ++p)
            for (int q = 0; q < m; ++q) a[p * m + q] += basis[i * m + p] * basis[i * m + q];
    double trace = 0.0;
    for (int p = 0; p < m; ++p) trace += a[p * m + p];
    for (int p = 0; p < m; ++p) a[p * m + p] += 1e-10 * trace / m;
    detail::cholesky_in_place(a, std::size_t(m), false);  // positive definite by the ridge
    for (int d = 0; d < 2; ++d) {
        std::vector<double> r(m, 0.0);
        for (std::size_t i = 0; i < n; ++i)
            for (int p = 0; p < m; ++p) r[p] += basis[i * m + p] * values[2 * i + d];
        detail::cholesky_solve(a, std::size_t(m), r);
        fit.coefficients[std::size_t(d)] = r;
    }
    return fit;
}

std::vector<double> remove_smooth_displacement(const std::vector<std::array<double, 2>>& centres_um,
                                               std::vector<double>& values, int nodes) {
    const SmoothDisplacement fit = fit_smooth_displacement(centres_um, values, nodes);
    const std::size_t n = centres_um.size();
    std::vector<double> removed(2 * n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        const std::array<double, 2> s = fit.at(centres_um[i][0], centres_um[i][1]);
        for (int d = 0; d < 2; ++d) {
            removed[2 * i + std::size_t(d)] = s[std::size_t(d)];
            values[2 * i + std::size_t(d)] -= s[std::size_t(d)];
        }
    }
    return removed;
}

}  // namespace wavebrdf::detail
