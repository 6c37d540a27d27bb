// The refinement's coarse space (coarse_correction.h).
#include "recovery/coarse_correction.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace wavebrdf::detail {

namespace {

// The centred uniform cubic B-spline (support |u| < 2, integral 1, Σ_a β(u − a) = 1).
double cubic_bspline(double u) {
    const double a = std::abs(u);
    if (a >= 2.0) return 0.0;
    if (a >= 1.0) {
        const double t = 2.0 - a;
        return t * t * t / 6.0;
    }
    return (4.0 - 6.0 * a * a + 3.0 * a * a * a) / 6.0;
}

double mean_of(const std::vector<double>& v) {
    double s = 0.0;
    for (double a : v) s += a;
    return v.empty() ? 0.0 : s / double(v.size());
}

}  // namespace

CoarseBasis::Axis CoarseBasis::make_axis(int texels, int nodes) {
    Axis axis;
    axis.node.resize(std::size_t(texels) * 4);
    axis.weight.resize(std::size_t(texels) * 4);
    for (int i = 0; i < texels; ++i) {
        const double u = double(i) * double(nodes) / double(texels);  // in node units
        const int a0 = int(std::floor(u));
        for (int k = 0; k < 4; ++k) {
            const int a = a0 - 1 + k;  // the nodes a0 − 1 … a0 + 2 reach u
            const std::size_t at = std::size_t(i) * 4 + std::size_t(k);
            axis.node[at] = ((a % nodes) + nodes) % nodes;  // periodic
            axis.weight[at] = cubic_bspline(u - double(a));
        }
    }
    return axis;
}

CoarseBasis::CoarseBasis(int rows, int cols, double spacing_texels, double weight)
    : m_rows(rows), m_cols(cols), m_weight(weight) {
    if (rows < 1 || cols < 1)
        throw std::invalid_argument("coarse basis: surface " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    "; expected >= 1 x 1");
    if (!(std::isfinite(spacing_texels) && spacing_texels >= 1.0))
        throw std::invalid_argument("coarse basis: spacing " + std::to_string(spacing_texels) +
                                    " texels; expected finite and >= 1");
    if (!(std::isfinite(weight) && weight > 0.0))
        throw std::invalid_argument("coarse basis: weight " + std::to_string(weight) + "; expected finite and > 0");
    for (double s = spacing_texels;; s *= 2.0) {
        const int mr = int(std::lround(double(rows) / s)), mc = int(std::lround(double(cols) / s));
        if (mr < 4 || mc < 4) break;
        Level level;
        level.m_rows = mr;
        level.m_cols = mc;
        level.m_row_axis = make_axis(rows, mr);
        level.m_col_axis = make_axis(cols, mc);
        level.m_offset = m_size;
        m_size += std::size_t(mr) * std::size_t(mc);
        m_levels.push_back(std::move(level));
    }
}

void CoarseBasis::apply(const double* c, std::vector<double>& h) const {
    if (m_levels.empty()) return;
    const std::size_t n = std::size_t(m_rows) * std::size_t(m_cols);
    std::vector<double> add(n, 0.0);
    for (const Level& level : m_levels) {
        const double* cl = c + level.m_offset;
        // T = C B_colsᵀ (nodes_rows × cols), then add += B_rows T.
        std::vector<double> t(std::size_t(level.m_rows) * std::size_t(m_cols), 0.0);
        for (int a = 0; a < level.m_rows; ++a)
            for (int j = 0; j < m_cols; ++j) {
                double s = 0.0;
                for (int k = 0; k < 4; ++k) {
                    const std::size_t at = std::size_t(j) * 4 + std::size_t(k);
                    s += level.m_col_axis.weight[at] *
                         cl[std::size_t(a) * std::size_t(level.m_cols) + std::size_t(level.m_col_axis.node[at])];
                }
                t[std::size_t(a) * std::size_t(m_cols) + std::size_t(j)] = s;
            }
        for (int i = 0; i < m_rows; ++i)
            for (int k = 0; k < 4; ++k) {
                const std::size_t at = std::size_t(i) * 4 + std::size_t(k);
                const double w = level.m_row_axis.weight[at];
                const double* row = &t[std::size_t(level.m_row_axis.node[at]) * std::size_t(m_cols)];
                double* out = &add[std::size_t(i) * std::size_t(m_cols)];
                for (int j = 0; j < m_cols; ++j) out[j] += w * row[j];
            }
    }
    const double mean = mean_of(add);  // P: the piston stays where the heights put it
    for (std::size_t k = 0; k < n; ++k) h[k] += m_weight * (add[k] - mean);
}

void CoarseBasis::adjoint(const std::vector<double>& g, double* gc) const {
    for (std::size_t k = 0; k < m_size; ++k) gc[k] = 0.0;
    if (m_levels.empty()) return;
    const double mean = mean_of(g);
    for (const Level& level : m_levels) {
        double* cl = gc + level.m_offset;
        // U = B_rowsᵀ P g (nodes_rows × cols), then C = U B_cols.
        std::vector<double> u(std::size_t(level.m_rows) * std::size_t(m_cols), 0.0);
        for (int i = 0; i < m_rows; ++i)
            for (int k = 0; k < 4; ++k) {
                const std::size_t at = std::size_t(i) * 4 + std::size_t(k);
                const double w = level.m_row_axis.weight[at];
                double* row = &u[std::size_t(level.m_row_axis.node[at]) * std::size_t(m_cols)];
                const double* in = &g[std::size_t(i) * std::size_t(m_cols)];
                for (int j = 0; j < m_cols; ++j) row[j] += w * (in[j] - mean);
            }
        for (int a = 0; a < level.m_rows; ++a)
            for (int j = 0; j < m_cols; ++j) {
                const double v = m_weight * u[std::size_t(a) * std::size_t(m_cols) + std::size_t(j)];
                for (int k = 0; k < 4; ++k) {
                    const std::size_t at = std::size_t(j) * 4 + std::size_t(k);
                    cl[std::size_t(a) * std::size_t(level.m_cols) + std::size_t(level.m_col_axis.node[at])] +=
                        level.m_col_axis.weight[at] * v;
                }
            }
    }
}

std::vector<double> coarse_heights(const std::vector<double>& z, const CoarseBasis& basis) {
    const std::size_t n = z.size() - basis.size();
    std::vector<double> h(z.begin(), z.begin() + std::ptrdiff_t(n));
    basis.apply(z.data() + n, h);
    return h;
}

Objective coarse_objective(const Objective& objective, const CoarseBasis& basis) {
    return [objective, &basis](const std::vector<double>& z, std::vector<double>& gz) {
        const std::size_t n = z.size() - basis.size();
        const std::vector<double> h = coarse_heights(z, basis);
        std::vector<double> g(n, 0.0);
        const double f = objective(h, g);
        gz.assign(z.size(), 0.0);
        std::copy(g.begin(), g.end(), gz.begin());
        basis.adjoint(g, gz.data() + n);
        return f;
    };
}

Objective coarse_only_objective(const Objective& objective, const CoarseBasis& basis, const std::vector<double>& h0) {
    return [objective, &basis, &h0](const std::vector<double>& c, std::vector<double>& gc) {
        std::vector<double> h = h0;
        basis.apply(c.data(), h);
        std::vector<double> g(h.size(), 0.0);
        const double f = objective(h, g);
        gc.assign(c.size(), 0.0);
        basis.adjoint(g, gc.data());
        return f;
    };
}

}  // namespace wavebrdf::detail
