// The field stage on overlapping tiles (field_tiles.h).
#include "recovery/field_tiles.h"

#include <algorithm>
#include <map>
#include <utility>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/free_heap.h"
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

// Position of fine sample s of an axis of `extent` texels, in texels from the tile's centre.
double local_coordinate(std::size_t s, int extent, int refine) { return (double(s) + 0.5) / refine - 0.5 * extent; }

// Fine sample (origin·q + s) of a periodic axis of `size` fine samples.
std::size_t wrap_index(long long origin_fine, long long s, long long size) {
    return std::size_t((((origin_fine + s) % size) + size) % size);
}

// Along one axis, the samples two tiles share where both weigh > 0, as pairs (s_i, s_j) grouped
// by their offset s_j − s_i (one group per connected overlap: two tiles of a 2-tile axis meet twice).
std::map<long long, std::vector<std::pair<std::size_t, std::size_t>>> axis_overlaps(int origin_i, int extent_i,
                                                                                    const std::vector<double>& w_i,
                                                                                    int origin_j, int extent_j,
                                                                                    const std::vector<double>& w_j,
                                                                                    int refine, long long size) {
    std::map<long long, std::vector<std::pair<std::size_t, std::size_t>>> groups;
    const long long n_i = (long long)(extent_i)*refine, n_j = (long long)(extent_j)*refine;
    for (long long s = 0; s < n_i; ++s) {
        if (!(w_i[std::size_t(s)] > 0.0)) continue;
        const long long v = (long long)(wrap_index((long long)(origin_i)*refine, s, size));
        const long long t = (((v - (long long)(origin_j)*refine) % size) + size) % size;
        if (t < n_j && w_j[std::size_t(t)] > 0.0) groups[t - s].emplace_back(std::size_t(s), std::size_t(t));
    }
    return groups;
}

double wrap_phase(double x) { return x - 2.0 * k_pi * std::floor((x + k_pi) / (2.0 * k_pi)); }

// One equation of the alignment's least squares: Σ_k coefficient_k · unknown_k = rhs, weight.
struct Equation {
    std::vector<std::pair<std::size_t, double>> terms;
    double rhs = 0.0, weight = 0.0;
};

// Solves the normal equations (Σ w r rᵀ + ridge·I) x = Σ w r d by conjugate gradients with a
// Jacobi preconditioner (sparse: every equation touches two tiles), from x = 0.
std::vector<double> solve_least_squares(const std::vector<Equation>& equations, std::size_t unknowns) {
    std::vector<double> diagonal(unknowns, 0.0), rhs(unknowns, 0.0);
    for (const Equation& e : equations)
        for (const auto& [k, a] : e.terms) {
            diagonal[k] += e.weight * a * a;
            rhs[k] += e.weight * a * e.rhs;
        }
    double scale = 0.0;
    for (double d : diagonal) scale = std::max(scale, d);
    const double ridge = 1e-10 * std::max(scale, 1e-300);
    for (double& d : diagonal) d += ridge;
    const auto apply = [&](const std::vector<double>& x) {
        std::vector<double> y(unknowns, 0.0);
        for (const Equation& e : equations) {
            double r = 0.0;
            for (const auto& [k, a] : e.terms) r += a * x[k];
            for (const auto& [k, a] : e.terms) y[k] += e.weight * a * r;
        }
        for (std::size_t k = 0; k < unknowns; ++k) y[k] += ridge * x[k];
        return y;
    };
    const auto dot = [&](const std::vector<double>& a, const std::vector<double>& b) {
        double d = 0.0;
        for (std::size_t k = 0; k < unknowns; ++k) d += a[k] * b[k];
        return d;
    };
    std::vector<double> x(unknowns, 0.0), r = rhs, z(unknowns), p(unknowns);
    for (std::size_t k = 0; k < unknowns; ++k) z[k] = r[k] / diagonal[k];
    p = z;
    double rz = dot(r, z);
    const double stop = 1e-28 * std::max(dot(rhs, rhs), 1e-300);
    for (std::size_t it = 0; it < 10 * unknowns + 100 && dot(r, r) > stop; ++it) {
        const std::vector<double> ap = apply(p);
        const double pap = dot(p, ap);
        if (!(pap > 0.0)) break;
        const double alpha = rz / pap;
        for (std::size_t k = 0; k < unknowns; ++k) {
            x[k] += alpha * p[k];
            r[k] -= alpha * ap[k];
        }
        for (std::size_t k = 0; k < unknowns; ++k) z[k] = r[k] / diagonal[k];
        const double rz_next = dot(r, z);
        const double beta = rz_next / rz;
        rz = rz_next;
        for (std::size_t k = 0; k < unknowns; ++k) p[k] = z[k] + beta * p[k];
    }
    return x;
}

// Throws std::invalid_argument for a core outside 8 … 4096 texels or a ramp outside 1 … core / 2.
void validate_tiling(const FieldTiling& tiling) {
    if (tiling.core < 8 || tiling.core > 4096)
        throw std::invalid_argument("field tile core " + std::to_string(tiling.core) +
                                    " texels is invalid; expected 8 to 4096");
    if (tiling.ramp < 1 || 2 * tiling.ramp > tiling.core)
        throw std::invalid_argument("field tile ramp " + std::to_string(tiling.ramp) +
                                    " texels is invalid; expected 1 to half the core (" + std::to_string(tiling.core) +
                                    ")");
}

}  // namespace

bool field_tiles_apply(int rows, int cols, const FieldTiling& tiling) {
    return tiling.threshold > 0 && (rows > tiling.threshold || cols > tiling.threshold);
}

FieldTileLayout field_tile_layout(int rows, int cols, int refine, int reach, const FieldTiling& tiling) {
    validate_tiling(tiling);
    if (rows < 1 || cols < 1 || refine < 1 || reach < 0)
        throw std::invalid_argument("field_tile_layout: surface " + std::to_string(rows) + " x " +
                                    std::to_string(cols) + ", refine " + std::to_string(refine) + ", reach " +
                                    std::to_string(reach) + "; expected >= 1 x 1, refine >= 1, reach >= 0");
    const AxisTiles tx = axis_tiles(rows, reach, tiling), ty = axis_tiles(cols, reach, tiling);
    FieldTileLayout layout;
    layout.rows = rows;
    layout.cols = cols;
    layout.refine = refine;
    layout.reach = reach;
    layout.ramp = tiling.ramp;
    layout.cut_x = tx.cut;
    layout.cut_y = ty.cut;
    layout.origin_x = tx.origin;
    layout.extent_x = tx.extent;
    layout.origin_y = ty.origin;
    layout.extent_y = ty.extent;
    return layout;
}

// File-local like the AxisTiles it holds (a class outside the anonymous namespace holding one
// draws GCC's -Wsubobject-linkage once the file is compiled in a unity batch).
namespace {

// The tiles' objects, their blend weights and per-tile phases a + b·x + c·y (x, y in texels
// from the tile's centre), for aligning the tiles' arbitrary phases and blending them.
template <typename T>
class TileBlend {
public:
    TileBlend(const FieldTileLayout& layout, std::vector<std::vector<std::complex<T>>>& objects)
        : objects(objects),
          q(layout.refine),
          nx(layout.origin_x.size()),
          ny(layout.origin_y.size()),
          tiles(nx * ny),
          fine_rows((long long)(layout.rows) * q),
          fine_cols((long long)(layout.cols) * q),
          phase(3 * tiles, 0.0) {
        if (objects.size() != tiles)
            throw std::invalid_argument("blend_field_tiles: " + std::to_string(objects.size()) +
                                        " tile objects; expected " + std::to_string(tiles));
        ax.cut = layout.cut_x;
        ax.origin = layout.origin_x;
        ax.extent = layout.extent_x;
        ay.cut = layout.cut_y;
        ay.origin = layout.origin_y;
        ay.extent = layout.extent_y;
        wx.resize(nx);
        wy.resize(ny);
        for (std::size_t k = 0; k < nx; ++k) wx[k] = axis_weights(ax, ax.extent[k], q, layout.reach, layout.ramp);
        for (std::size_t k = 0; k < ny; ++k) wy[k] = axis_weights(ay, ay.extent[k], q, layout.reach, layout.ramp);
        for (std::size_t t = 0; t < tiles; ++t) {
            const auto [kx, ky] = tile_of(t);
            if (!objects[t].empty() && objects[t].size() != wx[kx].size() * wy[ky].size())
                throw std::invalid_argument("blend_field_tiles: tile " + std::to_string(t) + " has " +
                                            std::to_string(objects[t].size()) + " values; expected " +
                                            std::to_string(wx[kx].size() * wy[ky].size()));
        }
    }

    // Aligns every tile's phase and tilt to its neighbours' on all overlaps at once.
    void align_jointly() {
        const std::vector<Region> regions = overlapping_regions();
        std::vector<std::vector<std::size_t>> regions_of(tiles);
        for (std::size_t g = 0; g < regions.size(); ++g) {
            regions_of[regions[g].i].push_back(g);
            regions_of[regions[g].j].push_back(g);
        }
        for (int pass = 0; pass < 2; ++pass) {
            // The phases: synchronised by the complex averages (raster order, then sweeps).
            std::vector<Stats> stats(regions.size());
            for (std::size_t g = 0; g < regions.size(); ++g) stats[g] = statistics(regions[g], false);
            std::vector<std::complex<double>> z(tiles, 0.0);
            const auto sweep = [&](bool first) {
                for (std::size_t t = 0; t < tiles; ++t) {
                    std::complex<double> sum = 0.0;
                    for (std::size_t g : regions_of[t]) {
                        // z_i O_i ≈ z_j O_j: z_i ∝ z_j conj m, z_j ∝ z_i m.
                        if (regions[g].i == t && (!first || regions[g].j < t))
                            sum += z[regions[g].j] * std::conj(stats[g].m);
                        else if (regions[g].j == t && (!first || regions[g].i < t))
                            sum += z[regions[g].i] * stats[g].m;
                    }
                    z[t] = std::abs(sum) > 0.0 ? sum / std::abs(sum) : (first ? 1.0 : z[t]);
                }
            };
            sweep(true);
            for (int s = 0; s < 20; ++s) sweep(false);
            for (std::size_t t = 0; t < tiles; ++t) {
                std::fill(phase.begin() + 3 * t, phase.begin() + 3 * t + 3, 0.0);
                phase[3 * t] = std::arg(z[t]);
                if (!objects[t].empty()) rotate(t);
            }
            // Then a phase and a tilt per tile by least squares on every overlap (φ_j − φ_i = the
            // phase difference O_i conj O_j: at the centroid and its slopes along cut axes).
            std::vector<Equation> equations;
            double largest = 0.0;
            for (std::size_t g = 0; g < regions.size(); ++g) {
                const Stats st = statistics(regions[g], true);
                if (!(st.weight > 0.0) || std::abs(st.m) == 0.0) continue;
                const std::size_t i = regions[g].i, j = regions[g].j;
                largest = std::max(largest, st.weight);
                Equation e;
                e.terms = {{3 * j, 1.0}, {3 * i, -1.0}};
                if (ax.cut) {
                    e.terms.push_back({3 * j + 1, st.xj});
                    e.terms.push_back({3 * i + 1, -st.xi});
                }
                if (ay.cut) {
                    e.terms.push_back({3 * j + 2, st.yj});
                    e.terms.push_back({3 * i + 2, -st.yi});
                }
                e.rhs = wrap_phase(std::arg(st.m) + st.e);
                e.weight = st.weight;
                equations.push_back(e);
                if (ax.cut && st.sxx > 0.0)
                    equations.push_back(Equation{{{3 * j + 1, 1.0}, {3 * i + 1, -1.0}}, st.gx, st.sxx});
                if (ay.cut && st.syy > 0.0)
                    equations.push_back(Equation{{{3 * j + 2, 1.0}, {3 * i + 2, -1.0}}, st.gy, st.syy});
            }
            if (equations.empty()) break;
            Equation gauge;  // Σ a = 0 (one global phase)
            for (std::size_t t = 0; t < tiles; ++t)
                if (!objects[t].empty()) gauge.terms.push_back({3 * t, 1.0});
            gauge.weight = largest;
            equations.push_back(gauge);
            phase = solve_least_squares(equations, 3 * tiles);
            for (std::size_t t = 0; t < tiles; ++t)
                if (!objects[t].empty()) rotate(t);
        }
    }

    // The blend Σ_t w_t O_t (raster alignment: each tile turned by arg Σ w · blend · conj(O_t) on
    // what the tiles before it hold); the weights are separable, so is their sum.
    std::vector<std::complex<double>> blend(FieldTileAlignment alignment) {
        std::vector<std::complex<double>> blend = allocating(
            "the field tiles' blend", double(fine_rows * fine_cols) * 16.0,
            [&] { return std::vector<std::complex<double>>(std::size_t(fine_rows * fine_cols), 0.0); });
        std::vector<double> sum_x(std::size_t(fine_rows), 0.0), sum_y(std::size_t(fine_cols), 0.0);
        for (std::size_t k = 0; k < nx; ++k)
            for (std::size_t s = 0; s < wx[k].size(); ++s)
                sum_x[wrap_index((long long)(ax.origin[k]) * q, (long long)(s), fine_rows)] += wx[k][s];
        for (std::size_t k = 0; k < ny; ++k)
            for (std::size_t s = 0; s < wy[k].size(); ++s)
                sum_y[wrap_index((long long)(ay.origin[k]) * q, (long long)(s), fine_cols)] += wy[k][s];
        for (std::size_t t = 0; t < tiles; ++t) {
            if (objects[t].empty()) continue;
            const auto [kx, ky] = tile_of(t);
            const std::size_t tr = wx[kx].size(), tc = wy[ky].size();
            std::vector<std::size_t> map_r(tr), map_c(tc);
            for (std::size_t s = 0; s < tr; ++s)
                map_r[s] = wrap_index((long long)(ax.origin[kx]) * q, (long long)(s), fine_rows);
            for (std::size_t s = 0; s < tc; ++s)
                map_c[s] = wrap_index((long long)(ay.origin[ky]) * q, (long long)(s), fine_cols);
            std::complex<double> turn = 1.0;
            if (alignment == FieldTileAlignment::raster) {
                std::complex<double> overlap = 0.0;
                for (std::size_t r = 0; r < tr; ++r)
                    for (std::size_t c = 0; c < tc; ++c) {
                        const double w = wx[kx][r] * wy[ky][c];
                        if (w > 0.0)
                            overlap += w * blend[map_r[r] * std::size_t(fine_cols) + map_c[c]] *
                                       std::conj(at(t, r * tc + c));
                    }
                if (std::abs(overlap) > 0.0) turn = overlap / std::abs(overlap);
                for (std::complex<T>& v : objects[t]) v = std::complex<T>(std::complex<double>(v) * turn);
            }
            for (std::size_t r = 0; r < tr; ++r)
                for (std::size_t c = 0; c < tc; ++c)
                    blend[map_r[r] * std::size_t(fine_cols) + map_c[c]] += wx[kx][r] * wy[ky][c] * at(t, r * tc + c);
        }
        for (std::size_t r = 0; r < std::size_t(fine_rows); ++r)
            for (std::size_t c = 0; c < std::size_t(fine_cols); ++c) {
                const double w = sum_x[r] * sum_y[c];
                std::complex<double>& v = blend[r * std::size_t(fine_cols) + c];
                v = w > 0.0 ? v / w : 0.0;
            }
        return blend;
    }

private:
    struct Region {
        std::size_t i, j;
        std::vector<std::pair<std::size_t, std::size_t>> xs, ys;
    };

    // A region's statistics: m = Σ ω O_i conj O_j, ω = the four weights' product; the
    // weights' sum and centroids (each tile's frame); the weighted linear fit of the residual
    // phase arg(O_i conj O_j conj m̂) = e + g_x (x − x̄) + g_y (y − ȳ).
    struct Stats {
        std::complex<double> m = 0.0;
        double weight = 0.0, xi = 0.0, yi = 0.0, xj = 0.0, yj = 0.0, e = 0.0, gx = 0.0, gy = 0.0, sxx = 0.0, syy = 0.0;
    };

    // Sample k of tile t in double (the sums and the blend are in double whatever T).
    std::complex<double> at(std::size_t t, std::size_t k) const { return std::complex<double>(objects[t][k]); }
    std::pair<std::size_t, std::size_t> tile_of(std::size_t t) const { return {t / ny, t % ny}; }

    // Turns tile t by its phase.
    void rotate(std::size_t t) {
        const auto [kx, ky] = tile_of(t);
        const std::size_t tc = wy[ky].size();
        for (std::size_t r = 0; r < wx[kx].size(); ++r)
            for (std::size_t c = 0; c < tc; ++c)
                objects[t][r * tc + c] = std::complex<T>(
                    at(t, r * tc + c) *
                    std::polar(1.0, phase[3 * t] + phase[3 * t + 1] * local_coordinate(r, ax.extent[kx], q) +
                                        phase[3 * t + 2] * local_coordinate(c, ay.extent[ky], q)));
    }

    // Every overlap of two tiles, as a product of the axes' connected overlaps.
    std::vector<Region> overlapping_regions() const {
        std::vector<Region> regions;
        for (std::size_t i = 0; i < tiles; ++i)
            for (std::size_t j = i + 1; j < tiles; ++j) {
                if (objects[i].empty() || objects[j].empty()) continue;
                const auto [xi, yi] = tile_of(i);
                const auto [xj, yj] = tile_of(j);
                // Only neighbours (periodic) overlap: the cores are wider than the margins.
                const auto near = [](std::size_t a, std::size_t b, std::size_t n) {
                    const std::size_t d = a > b ? a - b : b - a;
                    return d <= 1 || d + 1 == n;
                };
                if (!near(xi, xj, nx) || !near(yi, yj, ny)) continue;
                const auto gx = axis_overlaps(ax.origin[xi], ax.extent[xi], wx[xi], ax.origin[xj], ax.extent[xj],
                                              wx[xj], q, fine_rows);
                if (gx.empty()) continue;
                const auto gy = axis_overlaps(ay.origin[yi], ay.extent[yi], wy[yi], ay.origin[yj], ay.extent[yj],
                                              wy[yj], q, fine_cols);
                for (const auto& [dx, xs] : gx)
                    for (const auto& [dy, ys] : gy) regions.push_back(Region{i, j, xs, ys});
            }
        return regions;
    }

    Stats statistics(const Region& g, bool fit) const {
        Stats st;
        const auto [kxi, kyi] = tile_of(g.i);
        const auto [kxj, kyj] = tile_of(g.j);
        const std::size_t tci = wy[kyi].size(), tcj = wy[kyj].size();
        for (const auto& [ri, rj] : g.xs)
            for (const auto& [ci, cj] : g.ys) {
                const double w = wx[kxi][ri] * wx[kxj][rj] * wy[kyi][ci] * wy[kyj][cj];
                st.m += w * at(g.i, ri * tci + ci) * std::conj(at(g.j, rj * tcj + cj));
                st.weight += w;
                st.xi += w * local_coordinate(ri, ax.extent[kxi], q);
                st.yi += w * local_coordinate(ci, ay.extent[kyi], q);
                st.xj += w * local_coordinate(rj, ax.extent[kxj], q);
                st.yj += w * local_coordinate(cj, ay.extent[kyj], q);
            }
        if (!(st.weight > 0.0)) return st;
        st.xi /= st.weight;
        st.yi /= st.weight;
        st.xj /= st.weight;
        st.yj /= st.weight;
        if (!fit || std::abs(st.m) == 0.0) return st;
        const std::complex<double> unit = std::conj(st.m) / std::abs(st.m);
        double se = 0.0, sx = 0.0, sy = 0.0;
        for (const auto& [ri, rj] : g.xs)
            for (const auto& [ci, cj] : g.ys) {
                const double w = wx[kxi][ri] * wx[kxj][rj] * wy[kyi][ci] * wy[kyj][cj];
                const double rho = std::arg(at(g.i, ri * tci + ci) * std::conj(at(g.j, rj * tcj + cj)) * unit);
                const double x = local_coordinate(ri, ax.extent[kxi], q) - st.xi;
                const double y = local_coordinate(ci, ay.extent[kyi], q) - st.yi;
                se += w * rho;
                sx += w * rho * x;
                sy += w * rho * y;
                st.sxx += w * x * x;
                st.syy += w * y * y;
            }
        st.e = se / st.weight;
        st.gx = st.sxx > 0.0 ? sx / st.sxx : 0.0;
        st.gy = st.syy > 0.0 ? sy / st.syy : 0.0;
        return st;
    }

    std::vector<std::vector<std::complex<T>>>& objects;
    const int q;
    const std::size_t nx, ny, tiles;
    const long long fine_rows, fine_cols;
    AxisTiles ax, ay;
    std::vector<std::vector<double>> wx, wy;
    std::vector<double> phase;
};

}  // namespace

template <typename T>
std::vector<std::complex<double>> blend_field_tiles(const FieldTileLayout& layout,
                                                    std::vector<std::vector<std::complex<T>>>& objects,
                                                    FieldTileAlignment alignment) {
    TileBlend<T> tiles(layout, objects);
    if (alignment == FieldTileAlignment::joint) tiles.align_jointly();
    return tiles.blend(alignment);
}

template std::vector<std::complex<double>> blend_field_tiles(const FieldTileLayout&,
                                                             std::vector<std::vector<std::complex<double>>>&,
                                                             FieldTileAlignment);
template std::vector<std::complex<double>> blend_field_tiles(const FieldTileLayout&,
                                                             std::vector<std::vector<std::complex<float>>>&,
                                                             FieldTileAlignment);

FieldRetrievalResult retrieve_field_tiled(const std::vector<const Observation*>& observations, double lambda_um,
                                          int rows, int cols, double texel_um,
                                          const std::vector<std::complex<double>>& initial,
                                          const FieldRetrievalSettings& settings, const FieldTiling& tiling,
                                          const std::function<bool(int, double)>& on_iteration,
                                          const Communicator& comm) {
    validate_tiling(tiling);
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
    const FieldTileLayout layout = field_tile_layout(rows, cols, q, reach, tiling);
    AxisTiles tx, ty;
    tx.cut = layout.cut_x;
    tx.origin = layout.origin_x;
    tx.extent = layout.extent_x;
    ty.cut = layout.cut_y;
    ty.origin = layout.origin_y;
    ty.extent = layout.extent_y;
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

    // Every tile's object (each in its own frame, 2.2× the surface's samples at 128²), kept in
    // complex float (half the memory; the rounding, 6e-8 relative, is ~1e-9 µm of height) and
    // aligned and blended in double once all are in (blend_field_tiles).
    double tile_samples = 0.0;
    for (int ex : tx.extent)
        for (int ey : ty.extent) tile_samples += double(ex) * q * double(ey) * q;
    std::vector<std::vector<std::complex<float>>> objects = allocating(
        "the field tiles' objects", tile_samples * 8.0,
        [&] { return std::vector<std::vector<std::complex<float>>>(tiles); });
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
            objects[kx * ty.origin.size() + ky].assign(t.object.begin(), t.object.end());
            std::vector<std::complex<double>>().swap(t.object);
            release_free_heap();  // the tile's retrieval is gone: its pages back before the next
        }
    result.object = blend_field_tiles(layout, objects, FieldTileAlignment::joint);
    std::vector<std::vector<std::complex<float>>>().swap(objects);
    release_free_heap();
    result.relative_loss = loss_weight > 0.0 ? loss_sum / loss_weight : 0.0;
    return result;
}

}  // namespace wavebrdf::detail
