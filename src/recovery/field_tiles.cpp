// The field stage on overlapping tiles (field_tiles.h).
#include "recovery/field_tiles.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "wavebrdf/memory.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

namespace {

constexpr double k_pi = 3.14159265358979323846;

// The tiles along one axis of n texels: origins (texels, maybe negative: periodic) and extents.
struct AxisTiles {
    bool cut = false;
    int margin = 0;  // texels
    std::vector<int> origin, extent;
};

AxisTiles axis_tiles(int n, int reach, const FieldTiling& tiling) {
    AxisTiles a;
    const int margin = reach + tiling.ramp;
    const int count = (n + tiling.core - 1) / tiling.core;
    if (n <= tiling.threshold || count < 2 || n / count + 2 * margin >= n) {
        a.origin = {0};
        a.extent = {n};
        return a;
    }
    a.cut = true;
    a.margin = margin;
    for (int k = 0; k < count; ++k) {
        const int begin = int((long long)(k)*n / count), end = int((long long)(k + 1) * n / count);
        a.origin.push_back(begin - margin);
        a.extent.push_back(end - begin + 2 * margin);
    }
    return a;
}

// x reduced to [0, period).
double reduce(double x, double period) {
    double r = std::fmod(x, period);
    if (r < 0.0) r += period;
    return r;
}

// Feathering weight of each of a tile's fine samples along one axis (extent·refine values).
std::vector<double> axis_weights(const AxisTiles& a, int extent, int refine, int reach, int ramp) {
    std::vector<double> w(std::size_t(extent) * refine, 1.0);
    if (!a.cut) return w;
    for (std::size_t s = 0; s < w.size(); ++s) {
        // Distance from the nearer edge, in texels (a sample's centre).
        const double x = (double(s) + 0.5) / refine;
        const double e = std::min(x, double(extent) - x);
        const double t = std::clamp((e - reach) / (2.0 * ramp), 0.0, 1.0);
        const double v = std::sin(0.5 * k_pi * t);
        w[s] = v * v;
    }
    return w;
}

}  // namespace

bool field_tiles_apply(int rows, int cols, const FieldTiling& tiling) {
    return tiling.threshold > 0 && (rows > tiling.threshold || cols > tiling.threshold);
}

FieldRetrievalResult retrieve_field_tiled(const std::vector<const Observation*>& observations, double lambda_um,
                                          int rows, int cols, double texel_um,
                                          const std::vector<std::complex<double>>& initial,
                                          const FieldRetrievalSettings& settings, const FieldTiling& tiling,
                                          const std::function<bool(int, double)>& on_iteration,
                                          const Communicator& comm) {
    if (tiling.core < 8 || tiling.core > 4096)
        throw std::invalid_argument("field tile core " + std::to_string(tiling.core) +
                                    " texels is invalid; expected 8 to 4096");
    if (tiling.ramp < 1 || 2 * tiling.ramp > tiling.core)
        throw std::invalid_argument("field tile ramp " + std::to_string(tiling.ramp) +
                                    " texels is invalid; expected 1 to half the core (" + std::to_string(tiling.core) +
                                    ")");
    if (rows < 1 || cols < 1 || !(texel_um > 0.0))
        throw std::invalid_argument("retrieve_field_tiled: surface " + std::to_string(rows) + " x " +
                                    std::to_string(cols) + " of texel " + std::to_string(texel_um) +
                                    " um; expected >= 1 x 1 and a texel > 0");
    const int q = settings.refine;
    const std::size_t fine_rows = std::size_t(rows) * q, fine_cols = std::size_t(cols) * q;
    if (initial.size() != fine_rows * fine_cols)
        throw std::invalid_argument("retrieve_field_tiled: initial object has " + std::to_string(initial.size()) +
                                    " values; expected " + std::to_string(fine_rows * fine_cols));
    for (const Observation* o : observations)
        if (!o) throw std::invalid_argument("retrieve_field_tiled: null observation");
    // The footprint's reach (3σ_p cut plus a texel), the widest of every rank's.
    double sigma_max = 0.0;
    for (const Observation* o : observations) sigma_max = std::max(sigma_max, o->query.sigma_p_um);
    for (double s : all_gather(comm, {sigma_max})) sigma_max = std::max(sigma_max, s);
    const double reach_um = 3.0 * sigma_max + texel_um;
    const int reach = int(std::ceil(reach_um / texel_um));
    const AxisTiles tx = axis_tiles(rows, reach, tiling), ty = axis_tiles(cols, reach, tiling);
    const std::size_t tiles = tx.origin.size() * ty.origin.size();

    // Which tiles each observation fits in (its footprint inside, away from the edges).
    const double period_x = rows * texel_um, period_y = cols * texel_um;
    const auto fits = [&](const AxisTiles& a, std::size_t k, double x, double period, double sigma) {
        if (!a.cut) return true;
        const double local = reduce(x - a.origin[k] * texel_um, period);
        const double r = 3.0 * sigma + texel_um;
        return local >= r && local <= a.extent[k] * texel_um - r;
    };
    std::vector<double> counts(tiles, 0.0);
    for (std::size_t kx = 0; kx < tx.origin.size(); ++kx)
        for (std::size_t ky = 0; ky < ty.origin.size(); ++ky)
            for (const Observation* o : observations)
                if (fits(tx, kx, o->query.x_um, period_x, o->query.sigma_p_um) &&
                    fits(ty, ky, o->query.y_um, period_y, o->query.sigma_p_um))
                    counts[kx * ty.origin.size() + ky] += 1.0;
    comm.allreduce_sum(counts);
    double total = 0.0;
    for (double c : counts) total += c;
    if (total == 0.0) throw std::invalid_argument("retrieve_field_tiled: no observation fits any tile");

    // The blend Σ_t w_t O_t; the weights are separable, so is their sum.
    std::vector<std::complex<double>> blend = allocating(
        "the field tiles' blend", double(fine_rows * fine_cols) * 16.0,
        [&] { return std::vector<std::complex<double>>(fine_rows * fine_cols, 0.0); });
    std::vector<double> sum_x(fine_rows, 0.0), sum_y(fine_cols, 0.0);
    const auto add_sums = [&](const AxisTiles& a, std::size_t size, std::vector<double>& sum) {
        for (std::size_t k = 0; k < a.origin.size(); ++k) {
            const std::vector<double> w = axis_weights(a, a.extent[k], q, reach, tiling.ramp);
            for (std::size_t s = 0; s < w.size(); ++s) {
                const long long v = (long long)(a.origin[k]) * q + (long long)(s);
                sum[std::size_t(((v % (long long)(size)) + (long long)(size)) % (long long)(size))] += w[s];
            }
        }
    };
    add_sums(tx, fine_rows, sum_x);
    add_sums(ty, fine_cols, sum_y);
    FieldRetrievalResult result;
    double loss_sum = 0.0, loss_weight = 0.0;
    bool go_on = true;
    for (std::size_t kx = 0; kx < tx.origin.size() && go_on; ++kx)
        for (std::size_t ky = 0; ky < ty.origin.size() && go_on; ++ky) {
            const double count = counts[kx * ty.origin.size() + ky];
            if (count == 0.0) continue;  // no observation anywhere: the tile stays out of the blend
            const int ex = tx.extent[kx], ey = ty.extent[ky];
            const std::size_t tr = std::size_t(ex) * q, tc = std::size_t(ey) * q;
            // Fine sample s of the tile is the surface's (origin·q + s) mod (rows·q).
            const auto surface_index = [&](std::size_t s, int origin, std::size_t size) {
                const long long v = (long long)(origin)*q + (long long)(s);
                return std::size_t(((v % (long long)(size)) + (long long)(size)) % (long long)(size));
            };
            std::vector<std::size_t> map_r(tr), map_c(tc);
            for (std::size_t s = 0; s < tr; ++s) map_r[s] = surface_index(s, tx.origin[kx], fine_rows);
            for (std::size_t s = 0; s < tc; ++s) map_c[s] = surface_index(s, ty.origin[ky], fine_cols);
            // This rank's observations of the tile, moved to its origin (copies: one tile's).
            std::vector<Observation> mine;
            for (const Observation* o : observations)
                if (fits(tx, kx, o->query.x_um, period_x, o->query.sigma_p_um) &&
                    fits(ty, ky, o->query.y_um, period_y, o->query.sigma_p_um)) {
                    mine.push_back(*o);
                    Query& query = mine.back().query;
                    if (tx.cut) query.x_um = reduce(query.x_um - tx.origin[kx] * texel_um, period_x);
                    if (ty.cut) query.y_um = reduce(query.y_um - ty.origin[ky] * texel_um, period_y);
                }
            std::vector<const Observation*> used(mine.size());
            for (std::size_t i = 0; i < mine.size(); ++i) used[i] = &mine[i];
            std::vector<std::complex<double>> start(tr * tc);
            for (std::size_t r = 0; r < tr; ++r)
                for (std::size_t c = 0; c < tc; ++c) start[r * tc + c] = initial[map_r[r] * fine_cols + map_c[c]];
            FieldRetrievalResult t = retrieve_field(
                used, lambda_um, ex, ey, texel_um, start, settings,
                [&](int iteration, double loss) {
                    if (on_iteration && !on_iteration(iteration, loss)) go_on = false;
                    return go_on;
                },
                comm);
            std::vector<Observation>().swap(mine);
            std::vector<std::complex<double>>().swap(start);
            result.iterations += t.iterations;
            loss_sum += count * t.relative_loss;
            loss_weight += count;
            const std::vector<double> wx = axis_weights(tx, ex, q, reach, tiling.ramp);
            const std::vector<double> wy = axis_weights(ty, ey, q, reach, tiling.ramp);
            // The tile's phase: arg Σ w · blend · conj(O_t) on what the tiles before it hold.
            std::complex<double> overlap = 0.0;
            for (std::size_t r = 0; r < tr; ++r)
                for (std::size_t c = 0; c < tc; ++c) {
                    const double w = wx[r] * wy[c];
                    if (w > 0.0)
                        overlap += w * blend[map_r[r] * fine_cols + map_c[c]] * std::conj(t.object[r * tc + c]);
                }
            const std::complex<double> turn = std::abs(overlap) > 0.0 ? overlap / std::abs(overlap) : 1.0;
            for (std::size_t r = 0; r < tr; ++r)
                for (std::size_t c = 0; c < tc; ++c)
                    blend[map_r[r] * fine_cols + map_c[c]] += wx[r] * wy[c] * turn * t.object[r * tc + c];
        }
    for (std::size_t r = 0; r < fine_rows; ++r)
        for (std::size_t c = 0; c < fine_cols; ++c) {
            const double w = sum_x[r] * sum_y[c];
            blend[r * fine_cols + c] = w > 0.0 ? blend[r * fine_cols + c] / w : 0.0;
        }
    result.object = std::move(blend);
    result.relative_loss = loss_weight > 0.0 ? loss_sum / loss_weight : 0.0;
    return result;
}

}  // namespace wavebrdf::detail
