#include "wavebrdf/conditioning.h"

#include <fftw3.h>

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <queue>
#include <stdexcept>
#include <string>

#include "core/fftw_raii.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

constexpr int k_max_detrend_order = 10;

std::size_t at(int r, int c, int cols) {
    return static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c);
}

std::string number(double x) { return format_number(x, "%.6g"); }

std::size_t count_invalid(const MeasuredSurface& s) {
    std::size_t n = 0;
    for (const double z : s.heights_um) n += std::isfinite(z) ? 0 : 1;
    return n;
}

void check_shape(const MeasuredSurface& s) {
    if (s.rows < 2 || s.cols < 2 ||
        s.heights_um.size() != static_cast<std::size_t>(s.rows) * static_cast<std::size_t>(s.cols))
        throw std::invalid_argument("surface of " + std::to_string(s.rows) + "x" + std::to_string(s.cols) +
                                    " points with " + std::to_string(s.heights_um.size()) +
                                    " heights is invalid; expected at least 2x2 and rows x cols heights");
    if (!(std::isfinite(s.dx_um) && s.dx_um > 0.0 && std::isfinite(s.dy_um) && s.dy_um > 0.0))
        throw std::invalid_argument("surface spacing " + number(s.dx_um) + " x " + number(s.dy_um) +
                                    " um is invalid; expected finite and > 0");
}

void require_complete(const MeasuredSurface& s, const std::string& step) {
    const std::size_t bad = count_invalid(s);
    if (bad > 0)
        throw std::invalid_argument(std::to_string(bad) + " of " + std::to_string(s.heights_um.size()) +
                                    " points are not measured (NaN); " + step +
                                    " needs every point: expected --fill nearest, harmonic or mean");
}

// Legendre polynomial P_n(t), t in [−1, 1]: an orthogonal basis keeps the least-squares
// problem well conditioned up to order 10, where monomials of x and y are not.
double legendre(int n, double t) {
    double p0 = 1.0, p1 = t;
    if (n == 0) return p0;
    for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    return p1;
}

MeasuredSurface crop(const MeasuredSurface& s, const std::array<int, 4>& c) {
    const int r0 = c[0], c0 = c[1], rows = c[2], cols = c[3];
    if (r0 < 0 || c0 < 0 || rows < 2 || cols < 2 || static_cast<long long>(r0) + rows > s.rows ||
        static_cast<long long>(c0) + cols > s.cols)
        throw std::invalid_argument("crop " + std::to_string(r0) + "," + std::to_string(c0) + "," +
                                    std::to_string(rows) + "," + std::to_string(cols) +
                                    " is outside the surface's " + std::to_string(s.rows) + "x" +
                                    std::to_string(s.cols) + " points; expected R0,C0,ROWS,COLS with ROWS, COLS >= 2 "
                                    "inside the grid");
    MeasuredSurface out = s;
    out.rows = rows;
    out.cols = cols;
    out.heights_um.assign(static_cast<std::size_t>(rows) * cols, 0.0);
    for (int r = 0; r < rows; ++r)
        for (int q = 0; q < cols; ++q) out.heights_um[at(r, q, cols)] = s.heights_um[at(r0 + r, c0 + q, s.cols)];
    return out;
}

// Least squares over the measured points; returns the rms of what was removed (µm).
double detrend(MeasuredSurface& s, int order) {
    std::vector<std::pair<int, int>> terms;
    for (int total = 0; total <= order; ++total)
        for (int a = total; a >= 0; --a) terms.emplace_back(a, total - a);
    const int n_terms = static_cast<int>(terms.size());
    const std::size_t valid = s.heights_um.size() - count_invalid(s);
    if (valid < static_cast<std::size_t>(n_terms))
        throw std::invalid_argument("detrend of order " + std::to_string(order) + " needs at least " +
                                    std::to_string(n_terms) + " measured points; the surface has " +
                                    std::to_string(valid));
    // Basis values per column and per row, once.
    std::vector<double> pu(static_cast<std::size_t>(s.cols) * (order + 1)), pv(static_cast<std::size_t>(s.rows) * (order + 1));
    for (int c = 0; c < s.cols; ++c)
        for (int k = 0; k <= order; ++k)
            pu[at(c, k, order + 1)] = legendre(k, s.cols > 1 ? 2.0 * c / (s.cols - 1) - 1.0 : 0.0);
    for (int r = 0; r < s.rows; ++r)
        for (int k = 0; k <= order; ++k)
            pv[at(r, k, order + 1)] = legendre(k, s.rows > 1 ? 2.0 * r / (s.rows - 1) - 1.0 : 0.0);
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(n_terms, n_terms);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_terms);
    Eigen::VectorXd phi(n_terms);
    for (int r = 0; r < s.rows; ++r)
        for (int c = 0; c < s.cols; ++c) {
            const double z = s.heights_um[at(r, c, s.cols)];
            if (!std::isfinite(z)) continue;
            for (int t = 0; t < n_terms; ++t)
                phi[t] = pu[at(c, terms[t].first, order + 1)] * pv[at(r, terms[t].second, order + 1)];
            normal.selfadjointView<Eigen::Lower>().rankUpdate(phi);
            rhs += z * phi;
        }
    normal.triangularView<Eigen::StrictlyUpper>() = normal.transpose();
    const Eigen::VectorXd coef = normal.colPivHouseholderQr().solve(rhs);
    double removed_sq = 0.0;
    for (int r = 0; r < s.rows; ++r)
        for (int c = 0; c < s.cols; ++c) {
            double form = 0.0;
            for (int t = 0; t < n_terms; ++t)
                form += coef[t] * pu[at(c, terms[t].first, order + 1)] * pv[at(r, terms[t].second, order + 1)];
            double& z = s.heights_um[at(r, c, s.cols)];
            if (std::isfinite(z)) {
                z -= form;
                removed_sq += form * form;
            }
        }
    return std::sqrt(removed_sq / static_cast<double>(valid));
}

// Each unmeasured point takes the value of its nearest measured point, found by a front that
// grows from the measured points in order of Euclidean distance (µm) and hands each point its
// neighbour's source: exact but for rare ties between sources at nearly equal distance.
void fill_nearest(MeasuredSurface& s) {
    const int rows = s.rows, cols = s.cols;
    const std::size_t n = s.heights_um.size();
    std::vector<double> dist(n, std::numeric_limits<double>::infinity());
    std::vector<std::size_t> source(n, n);
    using Item = std::pair<double, std::size_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> front;
    for (std::size_t k = 0; k < n; ++k)
        if (std::isfinite(s.heights_um[k])) {
            dist[k] = 0.0;
            source[k] = k;
            front.emplace(0.0, k);
        }
    while (!front.empty()) {
        const auto [d, k] = front.top();
        front.pop();
        if (d > dist[k]) continue;
        const int r = static_cast<int>(k / cols), c = static_cast<int>(k % cols);
        const int sr = static_cast<int>(source[k] / cols), sc = static_cast<int>(source[k] % cols);
        for (int dr = -1; dr <= 1; ++dr)
            for (int dc = -1; dc <= 1; ++dc) {
                const int nr = r + dr, nc = c + dc;
                if ((dr == 0 && dc == 0) || nr < 0 || nr >= rows || nc < 0 || nc >= cols) continue;
                const std::size_t m = at(nr, nc, cols);
                const double nd = std::hypot((nr - sr) * s.dy_um, (nc - sc) * s.dx_um);
                if (nd < dist[m]) {
                    dist[m] = nd;
                    source[m] = source[k];
                    front.emplace(nd, m);
                }
            }
    }
    std::vector<double> filled = s.heights_um;
    for (std::size_t k = 0; k < n; ++k)
        if (!std::isfinite(filled[k])) filled[k] = s.heights_um[source[k]];
    s.heights_um = std::move(filled);
}

// Laplace inpainting: on the unmeasured points Σ_neighbours w (z_p − z_n) = 0 with w = 1/dx²
// along x and 1/dy² along y; neighbours outside the grid are left out (no flux across the
// edge). Symmetric positive definite whenever each hole touches a measured point (always,
// with at least one measured point: holes are connected to the grid's measured part or to
// nothing, and a hole with no measured neighbour anywhere would be the whole grid). Conjugate
// gradients from the nearest fill.
void fill_harmonic(MeasuredSurface& s) {
    const int rows = s.rows, cols = s.cols;
    const std::size_t n = s.heights_um.size();
    std::vector<int> unknown(n, -1);
    int n_unknown = 0;
    for (std::size_t k = 0; k < n; ++k)
        if (!std::isfinite(s.heights_um[k])) unknown[k] = n_unknown++;
    if (n_unknown == 0) return;
    MeasuredSurface start = s;
    fill_nearest(start);
    const double wx = 1.0 / (s.dx_um * s.dx_um), wy = 1.0 / (s.dy_um * s.dy_um);
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<std::size_t>(n_unknown) * 5);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(n_unknown), x0(n_unknown);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int p = unknown[at(r, c, cols)];
            if (p < 0) continue;
            x0[p] = start.heights_um[at(r, c, cols)];
            double diag = 0.0;
            const int nbr[4][2] = {{r, c - 1}, {r, c + 1}, {r - 1, c}, {r + 1, c}};
            for (int e = 0; e < 4; ++e) {
                const int nr = nbr[e][0], nc = nbr[e][1];
                if (nr < 0 || nr >= rows || nc < 0 || nc >= cols) continue;
                const double w = e < 2 ? wx : wy;
                diag += w;
                const int q = unknown[at(nr, nc, cols)];
                if (q >= 0)
                    triplets.emplace_back(p, q, -w);
                else
                    b[p] += w * s.heights_um[at(nr, nc, cols)];
            }
            triplets.emplace_back(p, p, diag);
        }
    Eigen::SparseMatrix<double> a(n_unknown, n_unknown);
    a.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
    cg.setTolerance(1e-10);
    cg.setMaxIterations(std::max(1000, 20 * static_cast<int>(std::sqrt(static_cast<double>(n_unknown))) + 1000));
    cg.compute(a);
    const Eigen::VectorXd x = cg.solveWithGuess(b, x0);
    for (std::size_t k = 0; k < n; ++k)
        if (unknown[k] >= 0) s.heights_um[k] = x[unknown[k]];
}

MeasuredSurface resample(const MeasuredSurface& s, double w) {
    const double cols_d = std::floor((s.cols - 1) * s.dx_um / w + 1e-9) + 1.0;
    const double rows_d = std::floor((s.rows - 1) * s.dy_um / w + 1e-9) + 1.0;
    if (cols_d < 2 || rows_d < 2 || !(cols_d * rows_d <= static_cast<double>(k_max_surface_points)))
        throw std::invalid_argument("--resample-um " + number(w) + " gives " + number(rows_d) + "x" + number(cols_d) +
                                    " points over the surface's " + number((s.rows - 1) * s.dy_um) + " x " +
                                    number((s.cols - 1) * s.dx_um) + " um; expected at least 2x2 and at most " +
                                    std::to_string(k_max_surface_points) + " points");
    MeasuredSurface out = s;
    out.rows = static_cast<int>(rows_d);
    out.cols = static_cast<int>(cols_d);
    out.dx_um = out.dy_um = w;
    out.heights_um.assign(static_cast<std::size_t>(out.rows) * out.cols, 0.0);
#pragma omp parallel for schedule(static)
    for (int r = 0; r < out.rows; ++r) {
        const double fr = std::min(r * w / s.dy_um, s.rows - 1.0);
        const int r0 = std::min(static_cast<int>(fr), s.rows - 2);
        const double tr = fr - r0;
        for (int c = 0; c < out.cols; ++c) {
            const double fc = std::min(c * w / s.dx_um, s.cols - 1.0);
            const int c0 = std::min(static_cast<int>(fc), s.cols - 2);
            const double tc = fc - c0;
            out.heights_um[at(r, c, out.cols)] =
                (1 - tr) * ((1 - tc) * s.heights_um[at(r0, c0, s.cols)] + tc * s.heights_um[at(r0, c0 + 1, s.cols)]) +
                tr * ((1 - tc) * s.heights_um[at(r0 + 1, c0, s.cols)] + tc * s.heights_um[at(r0 + 1, c0 + 1, s.cols)]);
        }
    }
    return out;
}

// Moisan's periodic-plus-smooth decomposition (L. Moisan, "Periodic plus smooth image
// decomposition", J. Math. Imaging Vis. 39, 2011, eq. 7 and Theorem 1): the smooth component s
// solves Δ_per s = v, v holding the jumps across the tile's edges (v = 0 inside), and
// ŝ(q, r) = v̂(q, r) / (2 cos(2πq/N) + 2 cos(2πr/M) − 4), ŝ(0, 0) = 0. Returns the periodic
// component u − s, whose mean is u's.
void periodic_smooth(MeasuredSurface& s) {
    const int rows = s.rows, cols = s.cols;
    const std::size_t n = s.heights_um.size();
    detail::FftwBuffer<fftw_complex> data = detail::fftw_buffer<fftw_complex>(n);
    detail::FftwPlan forward, inverse;
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        forward.reset(fftw_plan_dft_2d(rows, cols, data.get(), data.get(), FFTW_FORWARD, FFTW_ESTIMATE));
        inverse.reset(fftw_plan_dft_2d(rows, cols, data.get(), data.get(), FFTW_BACKWARD, FFTW_ESTIMATE));
    }
    if (!forward || !inverse) throw std::runtime_error("FFTW could not plan the periodic decomposition");
    const std::vector<double>& u = s.heights_um;
    std::vector<double> v(n, 0.0);
    for (int c = 0; c < cols; ++c) {
        const double jump = u[at(rows - 1, c, cols)] - u[at(0, c, cols)];
        v[at(0, c, cols)] += jump;
        v[at(rows - 1, c, cols)] -= jump;
    }
    for (int r = 0; r < rows; ++r) {
        const double jump = u[at(r, cols - 1, cols)] - u[at(r, 0, cols)];
        v[at(r, 0, cols)] += jump;
        v[at(r, cols - 1, cols)] -= jump;
    }
    for (std::size_t k = 0; k < n; ++k) {
        data[k][0] = v[k];
        data[k][1] = 0.0;
    }
    fftw_execute(forward.get());
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const double denom = 2.0 * std::cos(2.0 * k_pi * r / rows) + 2.0 * std::cos(2.0 * k_pi * c / cols) - 4.0;
            fftw_complex& z = data[at(r, c, cols)];
            if (r == 0 && c == 0) {
                z[0] = z[1] = 0.0;
            } else {
                z[0] /= denom;
                z[1] /= denom;
            }
        }
    fftw_execute(inverse.get());
    for (std::size_t k = 0; k < n; ++k) s.heights_um[k] -= data[k][0] / static_cast<double>(n);
}

MeasuredSurface mirror_tile(const MeasuredSurface& s) {
    if (2LL * s.rows * 2LL * s.cols > k_max_surface_points)
        throw std::invalid_argument("--periodic mirror doubles the " + std::to_string(s.rows) + "x" +
                                    std::to_string(s.cols) + " points each way, over " +
                                    std::to_string(k_max_surface_points) + "; expected a smaller surface (crop it)");
    MeasuredSurface out = s;
    out.rows = 2 * s.rows;
    out.cols = 2 * s.cols;
    out.heights_um.assign(static_cast<std::size_t>(out.rows) * out.cols, 0.0);
    for (int r = 0; r < out.rows; ++r)
        for (int c = 0; c < out.cols; ++c) {
            const int sr = r < s.rows ? r : out.rows - 1 - r;
            const int sc = c < s.cols ? c : out.cols - 1 - c;
            out.heights_um[at(r, c, out.cols)] = s.heights_um[at(sr, sc, s.cols)];
        }
    return out;
}

void record(MeasuredSurface& s, ConditioningReport& report, const std::string& step) {
    s.metadata.emplace_back("conditioning", step);
    report.steps.push_back(step);
}

}  // namespace

double seam_slope_ratio(const MeasuredSurface& s) {
    check_shape(s);
    require_complete(s, "the seam ratio");
    const int rows = s.rows, cols = s.cols;
    const std::vector<double>& z = s.heights_um;
    double seam = 0.0, inside = 0.0;
    std::size_t n_seam = 0, n_inside = 0;
    for (int r = 0; r < rows; ++r) {
        for (int c = 0; c + 1 < cols; ++c) {
            const double d = (z[at(r, c + 1, cols)] - z[at(r, c, cols)]) / s.dx_um;
            inside += d * d;
            ++n_inside;
        }
        const double d = (z[at(r, 0, cols)] - z[at(r, cols - 1, cols)]) / s.dx_um;
        seam += d * d;
        ++n_seam;
    }
    for (int c = 0; c < cols; ++c) {
        for (int r = 0; r + 1 < rows; ++r) {
            const double d = (z[at(r + 1, c, cols)] - z[at(r, c, cols)]) / s.dy_um;
            inside += d * d;
            ++n_inside;
        }
        const double d = (z[at(0, c, cols)] - z[at(rows - 1, c, cols)]) / s.dy_um;
        seam += d * d;
        ++n_seam;
    }
    const double rms_seam = std::sqrt(seam / static_cast<double>(n_seam));
    const double rms_inside = std::sqrt(inside / static_cast<double>(n_inside));
    if (rms_inside > 0.0) return rms_seam / rms_inside;
    return rms_seam > 0.0 ? std::numeric_limits<double>::infinity() : 1.0;
}

MeasuredSurface condition(const MeasuredSurface& input, const ConditioningOptions& o, ConditioningReport* report_out) {
    check_shape(input);
    ConditioningReport report;
    MeasuredSurface s = input;
    if (o.detrend_order < -1 || o.detrend_order > k_max_detrend_order)
        throw std::invalid_argument("detrend order " + std::to_string(o.detrend_order) +
                                    " is invalid; expected -1 (none) to 10");
    if (o.resample_um && !(std::isfinite(*o.resample_um) && *o.resample_um > 0.0))
        throw std::invalid_argument("--resample-um " + number(*o.resample_um) + " is invalid; expected finite and > 0");

    if (o.crop) {
        s = crop(s, *o.crop);
        const auto& c = *o.crop;
        record(s, report,
               "crop rows " + std::to_string(c[0]) + ".." + std::to_string(c[0] + c[2] - 1) + ", columns " +
                   std::to_string(c[1]) + ".." + std::to_string(c[1] + c[3] - 1) + " (" + std::to_string(c[2]) + "x" +
                   std::to_string(c[3]) + " points)");
    }
    if (o.detrend_order >= 0) {
        const double removed = detrend(s, o.detrend_order);
        const std::string what = o.detrend_order == 0   ? "the mean"
                                 : o.detrend_order == 1 ? "a plane"
                                                        : "a polynomial of order " + std::to_string(o.detrend_order);
        record(s, report,
               "detrend: " + what + " removed, least squares over the measured points (Legendre basis in x, y); "
                                    "rms of the removed form " +
                   number(removed) + " um");
    }
    const std::size_t invalid = count_invalid(s);
    if (invalid > 0 && o.fill != FillMethod::Refuse) {
        if (invalid == s.heights_um.size())
            throw std::invalid_argument("every point of the surface is unmeasured (NaN); there is nothing to fill from");
        switch (o.fill) {
            case FillMethod::Nearest: fill_nearest(s); break;
            case FillMethod::Harmonic: fill_harmonic(s); break;
            case FillMethod::Mean: {
                double sum = 0.0;
                for (const double z : s.heights_um)
                    if (std::isfinite(z)) sum += z;
                const double mean = sum / static_cast<double>(s.heights_um.size() - invalid);
                for (double& z : s.heights_um)
                    if (!std::isfinite(z)) z = mean;
                break;
            }
            case FillMethod::Refuse: break;
        }
        record(s, report,
               "fill: " + std::to_string(invalid) + " unmeasured points (" +
                   number(100.0 * static_cast<double>(invalid) / static_cast<double>(s.heights_um.size())) +
                   " %) filled by " + to_string(o.fill));
    }
    if (o.resample_um) {
        require_complete(s, "--resample-um");
        const int rows = s.rows, cols = s.cols;
        const double dx = s.dx_um, dy = s.dy_um;
        s = resample(s, *o.resample_um);
        record(s, report,
               "resample: " + std::to_string(rows) + "x" + std::to_string(cols) + " points at " + number(dx) +
                   " x " + number(dy) + " um (x, y) to " + std::to_string(s.rows) + "x" + std::to_string(s.cols) +
                   " at " + number(*o.resample_um) + " um, bilinear interpolation");
    }
    if (o.periodic != PeriodicMethod::None) {
        require_complete(s, "--periodic");
        report.seam_ratio_before = seam_slope_ratio(s);
        if (o.periodic == PeriodicMethod::Smooth)
            periodic_smooth(s);
        else
            s = mirror_tile(s);
        report.seam_ratio_after = seam_slope_ratio(s);
        record(s, report,
               std::string("periodic: ") +
                   (o.periodic == PeriodicMethod::Smooth
                        ? "periodic-plus-smooth decomposition (Moisan 2011), the periodic component kept"
                        : "mirror tiling (the surface and its reflections, " + std::to_string(s.rows) + "x" +
                              std::to_string(s.cols) + " points)") +
                   "; seam slope ratio " + number(report.seam_ratio_before) + " before, " +
                   number(report.seam_ratio_after) + " after");
    }
    if (report_out) *report_out = std::move(report);
    return s;
}

FillMethod parse_fill_method(const std::string& text, const std::string& option) {
    if (text == "none") return FillMethod::Refuse;
    if (text == "nearest") return FillMethod::Nearest;
    if (text == "harmonic") return FillMethod::Harmonic;
    if (text == "mean") return FillMethod::Mean;
    throw std::invalid_argument(option + " '" + text + "' is unknown; expected none, nearest, harmonic or mean");
}

int parse_detrend(const std::string& text, const std::string& option) {
    if (text == "none") return -1;
    if (text == "mean") return 0;
    if (text == "plane") return 1;
    if (text.rfind("poly:", 0) == 0) {
        const std::string n = text.substr(5);
        if (!n.empty() && n.size() <= 2 && std::all_of(n.begin(), n.end(), [](char ch) { return ch >= '0' && ch <= '9'; })) {
            const int order = std::stoi(n);
            if (order <= k_max_detrend_order) return order;
        }
    }
    throw std::invalid_argument(option + " '" + text + "' is unknown; expected none, mean, plane or poly:N (N = 0 to 10)");
}

std::array<int, 4> parse_crop(const std::string& text, const std::string& option) {
    std::array<int, 4> out{};
    std::size_t pos = 0;
    for (int k = 0; k < 4; ++k) {
        const std::size_t end = k < 3 ? text.find(',', pos) : text.size();
        const std::string item = end == std::string::npos ? "" : text.substr(pos, end - pos);
        if (item.empty() || item.size() > 9 ||
            !std::all_of(item.begin(), item.end(), [](char ch) { return ch >= '0' && ch <= '9'; }))
            throw std::invalid_argument(option + " '" + text +
                                        "' is invalid; expected R0,C0,ROWS,COLS (four non-negative integers)");
        out[static_cast<std::size_t>(k)] = std::stoi(item);
        pos = end + 1;
    }
    return out;
}

PeriodicMethod parse_periodic_method(const std::string& text, const std::string& option) {
    if (text == "none") return PeriodicMethod::None;
    if (text == "smooth") return PeriodicMethod::Smooth;
    if (text == "mirror") return PeriodicMethod::Mirror;
    throw std::invalid_argument(option + " '" + text + "' is unknown; expected none, smooth or mirror");
}

const char* to_string(FillMethod m) {
    switch (m) {
        case FillMethod::Refuse: return "none";
        case FillMethod::Nearest: return "nearest";
        case FillMethod::Harmonic: return "harmonic";
        case FillMethod::Mean: return "mean";
    }
    return "none";
}

const char* to_string(PeriodicMethod m) {
    switch (m) {
        case PeriodicMethod::None: return "none";
        case PeriodicMethod::Smooth: return "smooth";
        case PeriodicMethod::Mirror: return "mirror";
    }
    return "none";
}

}  // namespace wavebrdf
