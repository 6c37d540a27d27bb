// Footprint positions from stitching per-footprint patches: stitch_positions.h.
#include "recovery/stitch_positions.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/catmull_rom.h"

namespace wavebrdf::detail {

namespace {

double window(const std::array<double, 2>& centre, double u, double v, double sigma) {
    const double du = u - centre[0], dv = v - centre[1];
    return std::exp(-(du * du + dv * dv) / (2 * sigma * sigma));
}

// The texels of a patch inside its window's 3σ: (u, v, height, P).
struct WindowPoint {
    double u, v, h, p;
};

std::vector<WindowPoint> window_points(const StitchPatch& patch, double sigma) {
    std::vector<WindowPoint> points;
    const double cut = std::exp(-4.5);
    for (int a = 0; a < patch.rows; ++a)
        for (int b = 0; b < patch.cols; ++b) {
            const double u = patch.origin_row + a + 0.5, v = patch.origin_col + b + 0.5;
            const double p = window(patch.centre, u, v, sigma);
            if (p >= cut) points.push_back({u, v, patch.heights_um[std::size_t(a) * patch.cols + b], p});
        }
    return points;
}

double window_energy(const StitchPatch& patch, double sigma) {
    double s = 0.0;
    for (int a = 0; a < patch.rows; ++a)
        for (int b = 0; b < patch.cols; ++b) {
            const double p = window(patch.centre, patch.origin_row + a + 0.5, patch.origin_col + b + 0.5, sigma);
            s += p * p;
        }
    return s;
}

struct PairCost {
    double misfit = 1e300;
    double overlap = 0.0;
};

PairCost pair_cost(const std::vector<WindowPoint>& a_points, double a_energy, const StitchPatch& b, double b_energy,
                   double sigma, double su, double sv, double min_overlap) {
    double sw = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (const WindowPoint& q : a_points) {
        const double u = q.u + su, v = q.v + sv;
        const double w = q.p * window(b.centre, u, v, sigma);
        if (w < 1e-12) continue;
        double hb = 0.0;
        if (!sample_patch(b, u, v, hb)) continue;
        sw += w;
        sa += w * q.h;
        sb += w * hb;
        saa += w * q.h * q.h;
        sbb += w * hb * hb;
        sab += w * q.h * hb;
    }
    PairCost c;
    c.overlap = sw / std::sqrt(a_energy * b_energy);
    if (c.overlap < min_overlap || sw <= 0) return c;
    const double ma = sa / sw, mb = sb / sw;
    const double va = std::max(0.0, saa / sw - ma * ma), vb = std::max(0.0, sbb / sw - mb * mb);
    const double cov = sab / sw - ma * mb;
    const double mis = std::max(0.0, va + vb - 2 * cov);
    const double scale = 0.5 * (va + vb);
    c.misfit = scale > 0 ? mis / scale : 1e300;
    return c;
}

}  // namespace

bool sample_patch(const StitchPatch& patch, double u, double v, double& value_um) {
    value_um = 0.0;
    const double r = u - patch.origin_row - 0.5, c = v - patch.origin_col - 0.5;
    const int i0 = int(std::floor(r)), j0 = int(std::floor(c));
    if (i0 - 1 < 0 || j0 - 1 < 0 || i0 + 2 >= patch.rows || j0 + 2 >= patch.cols) return false;
    value_um = catmull_rom_bicubic(r, c, [&](int i, int j) {
        return patch.heights_um[std::size_t(i) * std::size_t(patch.cols) + std::size_t(j)];
    });
    return true;
}

StitchPatch flip_patch(const StitchPatch& patch) {
    StitchPatch out = patch;
    const double lo_u = patch.origin_row + 1.5, hi_u = patch.origin_row + patch.rows - 2.5;
    const double lo_v = patch.origin_col + 1.5, hi_v = patch.origin_col + patch.cols - 2.5;
    for (int a = 0; a < patch.rows; ++a)
        for (int b = 0; b < patch.cols; ++b) {
            const double u = std::clamp(2 * patch.centre[0] - (patch.origin_row + a + 0.5), lo_u, hi_u - 1e-9);
            const double v = std::clamp(2 * patch.centre[1] - (patch.origin_col + b + 0.5), lo_v, hi_v - 1e-9);
            double h = 0.0;
            sample_patch(patch, u, v, h);
            out.heights_um[std::size_t(a) * patch.cols + b] = -h;
        }
    return out;
}

PairRegistration register_patch_pair(const StitchPatch& a, const StitchPatch& b, double sigma_texels,
                                     double min_overlap) {
    if (!(sigma_texels > 0) || !(min_overlap > 0 && min_overlap < 1))
        throw std::invalid_argument("register_patch_pair: sigma_texels must be > 0 and min_overlap in (0, 1)");
    const std::vector<WindowPoint> points = window_points(a, sigma_texels);
    const double ea = window_energy(a, sigma_texels), eb = window_energy(b, sigma_texels);
    const double reach = 2 * sigma_texels * std::sqrt(-std::log(min_overlap));
    const double bu = b.centre[0] - a.centre[0], bv = b.centre[1] - a.centre[1];
    PairRegistration best;
    const int n = int(std::floor(reach / 0.5));
    for (int i = -n; i <= n; ++i)
        for (int j = -n; j <= n; ++j) {
            if (std::hypot(0.5 * i, 0.5 * j) > reach) continue;
            const double su = bu + 0.5 * i, sv = bv + 0.5 * j;
            const PairCost c = pair_cost(points, ea, b, eb, sigma_texels, su, sv, min_overlap);
            if (c.misfit < best.misfit) best = {{su, sv}, c.misfit, c.overlap};
        }
    if (best.misfit >= 1e300) return best;
    for (double step = 0.25; step >= 1.0 / 64; step *= 0.5) {
        bool moved = true;
        while (moved) {
            moved = false;
            PairRegistration round = best;
            for (int i = -1; i <= 1; ++i)
                for (int j = -1; j <= 1; ++j) {
                    if (i == 0 && j == 0) continue;
                    const double su = best.shift[0] + step * i, sv = best.shift[1] + step * j;
                    const PairCost c = pair_cost(points, ea, b, eb, sigma_texels, su, sv, min_overlap);
                    if (c.misfit < round.misfit) round = {{su, sv}, c.misfit, c.overlap};
                }
            if (round.misfit < best.misfit) {
                best = round;
                moved = true;
            }
        }
    }
    return best;
}

std::vector<std::array<double, 2>> solve_stitch_offsets(int count, const std::vector<StitchPair>& pairs) {
    if (count <= 0) return {};
    const std::size_t n = std::size_t(count);
    // Normal equations: the weighted graph Laplacian, plus the gauge (Σ d = 0) as 11ᵀ and a
    // tiny ridge that pins patches without pairs to 0.
    std::vector<double> m(n * n, 0.0), rhs(2 * n, 0.0);
    double trace = 0.0;
    for (const StitchPair& p : pairs) {
        if (p.a < 0 || p.b < 0 || p.a >= count || p.b >= count || p.a == p.b)
            throw std::invalid_argument("solve_stitch_offsets: a pair names a patch out of range or itself");
        const std::size_t a = std::size_t(p.a), b = std::size_t(p.b);
        m[a * n + a] += p.weight;
        m[b * n + b] += p.weight;
        m[a * n + b] -= p.weight;
        m[b * n + a] -= p.weight;
        trace += 2 * p.weight;
        for (int c = 0; c < 2; ++c) {
            rhs[2 * a + c] += p.weight * p.shift[c];
            rhs[2 * b + c] -= p.weight * p.shift[c];
        }
    }
    const double gauge = trace > 0 ? trace / double(n) : 1.0;
    for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j < n; ++j) m[i * n + j] += gauge / double(n);
        m[i * n + i] += 1e-9 * gauge;
    }
    // Cholesky.
    for (std::size_t j = 0; j < n; ++j) {
        double d = m[j * n + j];
        for (std::size_t q = 0; q < j; ++q) d -= m[j * n + q] * m[j * n + q];
        d = std::sqrt(std::max(d, 1e-300));
        m[j * n + j] = d;
        for (std::size_t i = j + 1; i < n; ++i) {
            double s = m[i * n + j];
            for (std::size_t q = 0; q < j; ++q) s -= m[i * n + q] * m[j * n + q];
            m[i * n + j] = s / d;
        }
    }
    std::vector<std::array<double, 2>> d(n);
    for (int c = 0; c < 2; ++c) {
        std::vector<double> x(n);
        for (std::size_t i = 0; i < n; ++i) {
            double s = rhs[2 * i + c];
            for (std::size_t q = 0; q < i; ++q) s -= m[i * n + q] * x[q];
            x[i] = s / m[i * n + i];
        }
        for (std::size_t i = n; i-- > 0;) {
            double s = x[i];
            for (std::size_t q = i + 1; q < n; ++q) s -= m[q * n + i] * x[q];
            x[i] = s / m[i * n + i];
        }
        double mean = 0.0;
        for (double v : x) mean += v / double(n);
        for (std::size_t i = 0; i < n; ++i) d[i][c] = x[i] - mean;
    }
    return d;
}

namespace {

// Registers the candidate pairs of `patches` (canonical orientations) and solves, leaving out
// pairs above max_misfit and, in 3 rounds, those whose residual exceeds outlier_texels.
StitchResult solve_oriented(const std::vector<StitchPatch>& patches, const std::vector<std::array<int, 2>>& candidates,
                            const StitchSettings& s) {
    StitchResult r;
    std::vector<StitchPair> pairs;
    for (const auto& [a, b] : candidates) {
        const PairRegistration reg = register_patch_pair(patches[a], patches[b], s.sigma_texels, s.search_overlap);
        if (reg.misfit > s.max_misfit || reg.overlap < s.min_overlap) continue;
        pairs.push_back({a, b, reg.shift, reg.overlap, reg.misfit});
    }
    r.pairs_tried = int(candidates.size());
    // Start: a spanning tree of the pairs in order of misfit (Kruskal), the offsets along it.
    const std::vector<StitchPair> all = pairs;
    {
        const int n = int(patches.size());
        std::vector<int> order(all.size());
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return all[x].misfit < all[y].misfit; });
        std::vector<int> parent(n);
        std::iota(parent.begin(), parent.end(), 0);
        const auto find = [&](int x) {
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            return x;
        };
        std::vector<std::vector<std::pair<int, std::array<double, 2>>>> tree(n);
        for (int k : order) {
            const StitchPair& p = all[k];
            const int ra = find(p.a), rb = find(p.b);
            if (ra == rb) continue;
            parent[rb] = ra;
            tree[p.a].push_back({p.b, {-p.shift[0], -p.shift[1]}});  // d_b = d_a − shift
            tree[p.b].push_back({p.a, p.shift});
        }
        r.offsets_texels.assign(n, {0.0, 0.0});
        std::vector<int> seen(n, 0);
        for (int start = 0; start < n; ++start) {
            if (seen[start]) continue;
            std::vector<int> stack{start};
            seen[start] = 1;
            while (!stack.empty()) {
                const int x = stack.back();
                stack.pop_back();
                for (const auto& [y, step] : tree[x])
                    if (!seen[y]) {
                        seen[y] = 1;
                        r.offsets_texels[y] = {r.offsets_texels[x][0] + step[0], r.offsets_texels[x][1] + step[1]};
                        stack.push_back(y);
                    }
            }
        }
    }
    for (double threshold = 2.0;; threshold = std::max(0.5 * threshold, s.outlier_texels)) {
        for (int repeat = 0; repeat < 2; ++repeat) {
            std::vector<StitchPair> kept;
            for (const StitchPair& p : all) {
                const double du = r.offsets_texels[p.a][0] - r.offsets_texels[p.b][0] - p.shift[0];
                const double dv = r.offsets_texels[p.a][1] - r.offsets_texels[p.b][1] - p.shift[1];
                if (std::hypot(du, dv) <= threshold) kept.push_back(p);
            }
            pairs = std::move(kept);
            r.offsets_texels = solve_stitch_offsets(int(patches.size()), pairs);
        }
        if (threshold <= s.outlier_texels) break;
    }
    double s2 = 0.0;
    for (const StitchPair& p : pairs) {
        const double du = r.offsets_texels[p.a][0] - r.offsets_texels[p.b][0] - p.shift[0];
        const double dv = r.offsets_texels[p.a][1] - r.offsets_texels[p.b][1] - p.shift[1];
        s2 += du * du + dv * dv;
    }
    {  // patches held by fewer than min_pairs pairs: unresolved, at the stated centre
        const int n = int(patches.size());
        std::vector<int> degree(n, 0);
        for (const StitchPair& p : pairs) {
            ++degree[p.a];
            ++degree[p.b];
        }
        r.resolved.assign(n, 0);
        std::array<double, 2> mean{0, 0};
        int count = 0;
        for (int i = 0; i < n; ++i)
            if (degree[i] >= s.min_pairs) {
                r.resolved[i] = 1;
                ++count;
                mean = {mean[0] + r.offsets_texels[i][0], mean[1] + r.offsets_texels[i][1]};
            }
        for (int i = 0; i < n; ++i)
            r.offsets_texels[i] = r.resolved[i] ? std::array<double, 2>{r.offsets_texels[i][0] - mean[0] / count,
                                                                        r.offsets_texels[i][1] - mean[1] / count}
                                                : std::array<double, 2>{0.0, 0.0};
        r.unresolved = n - count;
    }
    r.pairs_used = int(pairs.size());
    r.pairs = pairs;
    r.residual_rms_texels = pairs.empty() ? 0.0 : std::sqrt(s2 / (2.0 * double(pairs.size())));
    return r;
}

}  // namespace

StitchResult stitch_positions(const std::vector<StitchPatch>& patches, const StitchSettings& s,
                              const std::vector<int>* known_twins) {
    const int n = int(patches.size());
    std::vector<std::array<int, 2>> candidates;
    for (int a = 0; a < n; ++a)
        for (int b = a + 1; b < n; ++b)
            if (std::hypot(patches[a].centre[0] - patches[b].centre[0], patches[a].centre[1] - patches[b].centre[1]) <=
                s.max_distance_texels)
                candidates.push_back({a, b});
    if (known_twins) {
        if (known_twins->size() != patches.size())
            throw std::invalid_argument("stitch_positions: known_twins must have one flag per patch");
        std::vector<StitchPatch> oriented;
        for (int i = 0; i < n; ++i) oriented.push_back((*known_twins)[i] ? flip_patch(patches[i]) : patches[i]);
        StitchResult r = solve_oriented(oriented, candidates, s);
        r.twin = *known_twins;
        return r;
    }
    // Relative orientations: each pair as it is and with b flipped.
    std::vector<StitchPatch> flipped;
    flipped.reserve(patches.size());
    for (const StitchPatch& p : patches) flipped.push_back(flip_patch(p));
    struct Relation {
        double misfit;
        int a, b, flip;
    };
    std::vector<Relation> relations;
    std::vector<double> candidate_misfits;
    for (const auto& [a, b] : candidates) {
        const PairRegistration same = register_patch_pair(patches[a], patches[b], s.sigma_texels, s.search_overlap);
        const PairRegistration other = register_patch_pair(patches[a], flipped[b], s.sigma_texels, s.search_overlap);
        const bool flip = other.misfit < same.misfit;
        const PairRegistration& better = flip ? other : same;
        if (better.overlap >= s.min_overlap) candidate_misfits.push_back(better.misfit);
        if (better.misfit <= s.max_misfit && better.overlap >= s.min_overlap)
            relations.push_back({better.misfit, a, b, flip ? 1 : 0});
    }
    std::stable_sort(relations.begin(), relations.end(),
                     [](const Relation& x, const Relation& y) { return x.misfit < y.misfit; });
    // Union-find with parity (the parity to the parent: 1 when the orientations differ).
    std::vector<int> parent(n), parity(n, 0);
    std::iota(parent.begin(), parent.end(), 0);
    const auto find = [&](int x, int& par) {
        par = 0;
        while (parent[x] != x) {
            par ^= parity[x];
            x = parent[x];
        }
        return x;
    };
    for (const Relation& rel : relations) {
        int pa = 0, pb = 0;
        const int ra = find(rel.a, pa), rb = find(rel.b, pb);
        if (ra == rb) continue;  // consistent or not, the better pairs decided first
        parent[rb] = ra;
        parity[rb] = pa ^ pb ^ rel.flip;
    }
    std::vector<int> orientation(n, 0);
    for (int i = 0; i < n; ++i) find(i, orientation[i]);
    StitchResult best;
    double best_rms = INFINITY;
    for (int global = 0; global < 2; ++global) {
        std::vector<StitchPatch> oriented;
        oriented.reserve(patches.size());
        for (int i = 0; i < n; ++i) oriented.push_back((orientation[i] ^ global) ? flipped[i] : patches[i]);
        StitchResult r = solve_oriented(oriented, candidates, s);
        double s2 = 0.0;
        for (const auto& d : r.offsets_texels) s2 += d[0] * d[0] + d[1] * d[1];
        const double rms = n > 0 ? std::sqrt(s2 / (2.0 * n)) : 0.0;
        if (rms < best_rms) {
            best_rms = rms;
            best = std::move(r);
            best.candidate_misfits = candidate_misfits;
            best.twin.assign(n, 0);
            for (int i = 0; i < n; ++i) best.twin[i] = orientation[i] ^ global;
        }
    }
    return best;
}

}  // namespace wavebrdf::detail
