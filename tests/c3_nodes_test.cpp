// GHS, RGHS and Kirchhoff on the separable path (Chebyshev nodes in C3, forward/c3_nodes.h)
// against the direct sum, the node-count bound, and the gradients: the engine's adjoint
// identity, finite differences, and the direct path's gradient.
#include <gtest/gtest.h>

#include <complex>
#include <random>

#include "forward/c3_nodes.h"
#include "forward/direct.h"
#include "forward/separable_engine.h"
#include "test_util.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/constants.h"

using namespace wavebrdf;
using test::make_query;
using test::random_heightfield;

namespace {

RenderOptions options_for(RenderPath path, double tolerance = 1e-6) {
    RenderOptions o;
    o.path = path;
    o.prune_tolerance = 0.0;
    o.tolerance = tolerance;
    return o;
}

double peak(const std::vector<double>& v) {
    double m = 0.0;
    for (double x : v) m = std::max(m, x);
    return m;
}

struct Surface {
    const char* name;
    Heightfield hf;
};

// White noise of ±amplitude texels (slopes up to about the amplitude).
Heightfield noise_heightfield(int size, double amplitude, std::uint64_t seed) {
    return Heightfield(size, size, test::uniform_vector(std::size_t(size) * size, -amplitude, amplitude, seed), 1.0,
                       1.0);
}

// Steep: slopes of order 1 (heights ±0.8 µm); rough: heights ±2 µm; smooth: a few nm.
std::vector<Surface> surfaces() {
    return {{"steep", noise_heightfield(24, 0.8, 11)},
            {"rough", random_heightfield(24, 24, 0.45, 12, 1.0, 1.0)},
            {"smooth", random_heightfield(24, 24, 0.01, 13, 1.0, 1.0)}};
}

double height_range(const FootprintKernels& k) {
    double lo = 1e300, hi = -1e300;
    for (double h : k.height_um) {
        lo = std::min(lo, h);
        hi = std::max(hi, h);
    }
    return hi - lo;
}

double max_slope(const FootprintKernels& k) {
    double m = 0.0;
    for (std::size_t i = 0; i < k.size(); ++i) m = std::max({m, std::abs(k.slope_x[i]), std::abs(k.slope_y[i])});
    return m;
}

// The nodes' slice of `hf` (double) and their count, with the given tolerance.
std::vector<double> node_slice(const FootprintKernels& k, const Query& q, double lambda, int n, double tolerance,
                               int* nodes = nullptr, double* bound = nullptr,
                               detail::ComplexMatrix<double>* field_out = nullptr) {
    const detail::SliceGrid grid(q, lambda, n);
    detail::SeparableEngine<double> engine(k, grid, lambda, n);
    detail::C3Nodes<double> layer(q, grid, lambda, n, tolerance);
    detail::ComplexMatrix<double> field;
    std::vector<double> slice = layer.forward(engine, k, field, nullptr);
    if (nodes) *nodes = layer.nodes();
    if (bound) *bound = layer.error_bound();
    if (field_out) *field_out = field;
    return slice;
}

}  // namespace

// The slices of every model match the direct sum (no pruning) to 1e-6 of the peak on both
// engine paths (separable products and the FFT engine, each with its C3 nodes), on steep, rough
// and smooth surfaces, normal and oblique light, several λ and resolutions.
TEST(C3Nodes, SeparableMatchesDirectSumWithinTolerance) {
    for (const Surface& s : surfaces())
        for (Model model : {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff})
            for (const auto& [wx, wy, lambda, n] : std::vector<std::tuple<double, double, double, int>>{
                     {0.0, 0.0, 0.5, 24}, {0.5, -0.5, 0.4, 17}, {-0.2, 0.65, 0.7, 32}}) {
                SCOPED_TRACE(std::string(s.name) + " " + to_string(model) + " light " + std::to_string(wx) + "," +
                             std::to_string(wy) + " lambda " + std::to_string(lambda) + " n " + std::to_string(n));
                const Query q = make_query(model, 12.0, 11.0, 3.5, wx, wy);
                const std::vector<double> direct = render_slice<double>(s.hf, q, lambda, n,
                                                                        options_for(RenderPath::Direct));
                const double p = peak(direct);
                ASSERT_GT(p, 0.0);
                for (RenderPath path : {RenderPath::Separable, RenderPath::Fft, RenderPath::Auto}) {
                    SCOPED_TRACE(path == RenderPath::Fft ? "fft" : path == RenderPath::Auto ? "auto" : "separable");
                    EXPECT_LE(test::max_abs_diff(direct, render_slice<double>(s.hf, q, lambda, n, options_for(path))),
                              1e-6 * p);
                }
            }
    // The steep surface is steep, the rough one rough.
    EXPECT_GT(max_slope(footprint_kernels(surfaces()[0].hf, 12.0, 11.0, 3.5)), 0.7);
    EXPECT_GT(height_range(footprint_kernels(surfaces()[1].hf, 12.0, 11.0, 3.5)), 3.0);
}

// A surface whose tolerance would need more than k_max_c3_nodes nodes (heights ±6 µm, steep)
// is rendered by the direct sum: the separable path still matches it.
TEST(C3Nodes, TooManyNodesFallsBackToDirectSum) {
    const Heightfield hf = random_heightfield(24, 24, 1.2, 11, 1.0, 1.0);
    const Query q = make_query(Model::GHS, 12.0, 11.0, 3.5);
    const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
    int nodes = -1;
    EXPECT_TRUE(node_slice(k, q, 0.5, 24, 1e-6, &nodes).empty());
    EXPECT_EQ(nodes, 0);
    const std::vector<double> direct = render_slice<double>(hf, q, 0.5, 24, options_for(RenderPath::Direct));
    EXPECT_EQ(render_slice<double>(hf, q, 0.5, 24, options_for(RenderPath::Separable)), direct);
    EXPECT_EQ(render_slice_separable<double>(k, q, 0.5, 24), direct);
    std::vector<double> g_sep, g_dir;
    const std::vector<double> w = test::uniform_vector(24 * 24, -1.0, 1.0, 3);
    slice_gradient<double>(hf, q, 0.5, 24, w, g_sep, options_for(RenderPath::Separable));
    slice_gradient<double>(hf, q, 0.5, 24, w, g_dir, options_for(RenderPath::Direct));
    EXPECT_EQ(g_sep, g_dir);
}

// The a-priori bound holds: | |I_nodes| − |I_direct| | ≤ error_bound() at every pixel (the
// fields differ by the per-pixel phase of H̄), for few nodes (a loose tolerance) and many.
TEST(C3Nodes, ErrorBoundHoldsAndLooserToleranceTakesFewerNodes) {
    const Heightfield hf = random_heightfield(24, 24, 0.15, 12, 1.0, 1.0);
    for (Model model : {Model::GHS, Model::Kirchhoff}) {
        const Query q = make_query(model, 12.0, 11.0, 3.5, 0.3, 0.4);
        const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
        const int n = 24;
        const double lambda = 0.5;
        const detail::DirectField direct = detail::direct_field(k, q, lambda, n, 0.0, nullptr);
        const double p = peak(direct.value);
        int previous = 0;
        for (double tolerance : {1e-2, 1e-4, 1e-6, 1e-8}) {
            SCOPED_TRACE(std::string(to_string(model)) + " tolerance " + std::to_string(tolerance));
            int nodes = 0;
            double bound = 0.0;
            detail::ComplexMatrix<double> field;
            const std::vector<double> slice = node_slice(k, q, lambda, n, tolerance, &nodes, &bound, &field);
            ASSERT_FALSE(slice.empty());
            EXPECT_LE(test::max_abs_diff(slice, direct.value), tolerance * p);
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j)
                    EXPECT_LE(std::abs(std::abs(field(i, j)) - std::abs(direct.field[std::size_t(i) * n + j])),
                              bound + 1e-12 * std::sqrt(p));
            EXPECT_GE(nodes, previous);
            previous = nodes;
            std::printf("%s tolerance %g: %d nodes, bound %.3g\n", to_string(model), tolerance, nodes, bound);
        }
        int loose = 0, tight = 0;
        node_slice(k, q, lambda, n, 1e-2, &loose);
        node_slice(k, q, lambda, n, 1e-8, &tight);
        EXPECT_LT(loose, tight);
    }
}

// The bound's factor shrinks with the node count and grows with α and β.
TEST(C3Nodes, ChebyshevFactorIsMonotone) {
    for (int m = 2; m < 20; ++m) {
        EXPECT_LT(detail::chebyshev_error_factor(m + 1, 1.0, 0.5), detail::chebyshev_error_factor(m, 1.0, 0.5));
        EXPECT_LT(detail::chebyshev_error_factor(m, 1.0, 0.5), detail::chebyshev_error_factor(m, 2.0, 0.5));
        EXPECT_LT(detail::chebyshev_error_factor(m, 1.0, 0.5), detail::chebyshev_error_factor(m, 1.0, 1.5));
    }
    EXPECT_EQ(detail::chebyshev_node_count(1.0, 0.5, 1.0, 0.0), detail::k_max_c3_nodes + 1);
    const int m = detail::chebyshev_node_count(1.0, 0.5, 1.0, 1e-6);
    EXPECT_LE(detail::chebyshev_error_factor(m, 1.0, 0.5), 1e-6);
    EXPECT_GT(detail::chebyshev_error_factor(m - 1, 1.0, 0.5), 1e-6);
}

// A smooth surface under normal light needs few nodes.
TEST(C3Nodes, SmoothSurfaceNeedsFewNodes) {
    const Heightfield hf = random_heightfield(32, 32, 0.01, 21, 1.0, 1.0);
    for (Model model : {Model::GHS, Model::RGHS, Model::Kirchhoff}) {
        const Query q = make_query(model, 16.0, 16.0, 5.0);
        const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
        int nodes = 0;
        node_slice(k, q, 0.5, 32, 1e-6, &nodes);
        EXPECT_LE(nodes, 8) << to_string(model);
        std::printf("%s smooth: %d nodes\n", to_string(model), nodes);
    }
}

// The engine's adjoint: Σ B_v F_v = Σ G_vk w_vk (F is linear in the weights), and its shift
// gradient against a central difference in one kernel's slope.
TEST(C3Nodes, SeparableEngineAdjointIdentityAndShiftGradient) {
    const Heightfield hf = random_heightfield(20, 20, 0.4, 31, 1.0, 1.0);
    const Query q = make_query(Model::GHS, 10.0, 10.0, 3.0, 0.2, -0.3);
    FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
    const int n = 16;
    const double lambda = 0.55, shift_scale = 0.8;
    const detail::SliceGrid grid(q, lambda, n);
    std::mt19937_64 rng(5);
    std::normal_distribution<double> gauss;
    detail::KernelWeights w(2, std::vector<std::complex<double>>(k.size()));
    for (auto& v : w)
        for (auto& x : v) x = {gauss(rng), gauss(rng)};
    std::vector<detail::ComplexMatrix<double>> b(2, detail::ComplexMatrix<double>(n, n));
    for (auto& m : b)
        for (int i = 0; i < n * n; ++i) m.data()[i] = {gauss(rng), gauss(rng)};
    for (bool keep : {false, true}) {
        detail::SeparableEngine<double> engine(k, grid, lambda, n);
        engine.keep_factors(keep);
        std::vector<detail::ComplexMatrix<double>> f;
        engine.forward(w, shift_scale, f);
        detail::FieldGradient g;
        engine.adjoint(w, shift_scale, b, g);
        std::complex<double> lhs = 0.0, rhs = 0.0;
        for (int v = 0; v < 2; ++v) {
            for (int i = 0; i < n * n; ++i) lhs += b[v].data()[i] * f[v].data()[i];
            for (std::size_t i = 0; i < k.size(); ++i) rhs += g.weight[v][i] * w[v][i];
        }
        EXPECT_NEAR(std::abs(lhs - rhs), 0.0, 1e-12 * std::abs(lhs));
        // L = 2 Re Σ B F; ∂L/∂b_kx · shift_scale·2/λ = ∂L/∂s_kx.
        auto loss = [&](detail::SeparableEngine<double>& e) {
            std::vector<detail::ComplexMatrix<double>> fields;
            e.forward(w, shift_scale, fields);
            double l = 0.0;
            for (int v = 0; v < 2; ++v)
                for (int i = 0; i < n * n; ++i) l += 2.0 * std::real(b[v].data()[i] * fields[v].data()[i]);
            return l;
        };
        for (std::size_t idx : {std::size_t(3), k.size() / 2}) {
            const double h = 1e-6, sx = k.slope_x[idx], sy = k.slope_y[idx];
            k.slope_x[idx] = sx + h;
            const double lp = loss(engine);
            k.slope_x[idx] = sx - h;
            const double lm = loss(engine);
            k.slope_x[idx] = sx;
            k.slope_y[idx] = sy + h;
            const double lpy = loss(engine);
            k.slope_y[idx] = sy - h;
            const double lmy = loss(engine);
            k.slope_y[idx] = sy;
            const double scale = shift_scale * 2.0 / lambda;
            EXPECT_NEAR((lp - lm) / (2 * h), g.shift_x[idx] * scale, 1e-6 * (1.0 + std::abs(g.shift_x[idx] * scale)));
            EXPECT_NEAR((lpy - lmy) / (2 * h), g.shift_y[idx] * scale, 1e-6 * (1.0 + std::abs(g.shift_y[idx] * scale)));
        }
    }
}

// The single-precision engine (three real products on planar operands) against the double one
// (Eigen's complex products) on the same kernels: fields, weight gradients and shift gradients
// within float rounding, and its own adjoint identity, with the factors kept and not, and for a
// footprint large enough that the adjoint works in chunks of kernels.
TEST(C3Nodes, FloatSeparableEngineMatchesTheDoubleEngineAndItsAdjointIdentity) {
    for (double sigma : {3.0, 7.0}) {
        SCOPED_TRACE(sigma);
        const Heightfield hf = random_heightfield(48, 48, 0.4, 32, 1.0, 1.0);
        const Query q = make_query(Model::GHS, 24.0, 24.0, sigma, 0.2, -0.3);
        const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
        if (sigma > 5.0) {
            ASSERT_GT(k.size(), 512u);  // the adjoint's chunk (separable_engine.cpp)
        }
        const int n = 20;
        const double lambda = 0.55, shift_scale = 0.8;
        const detail::SliceGrid grid(q, lambda, n);
        std::mt19937_64 rng(6);
        std::normal_distribution<double> gauss;
        detail::KernelWeights w(2, std::vector<std::complex<double>>(k.size()));
        for (auto& v : w)
            for (auto& x : v) x = {gauss(rng), gauss(rng)};
        std::vector<detail::ComplexMatrix<double>> bd(2, detail::ComplexMatrix<double>(n, n));
        std::vector<detail::ComplexMatrix<float>> bf(2);
        for (int v = 0; v < 2; ++v) {
            for (int i = 0; i < n * n; ++i) bd[v].data()[i] = {gauss(rng), gauss(rng)};
            bf[v] = bd[v].cast<std::complex<float>>();
        }
        for (bool keep : {false, true}) {
            SCOPED_TRACE(keep);
            detail::SeparableEngine<double> ed(k, grid, lambda, n);
            detail::SeparableEngine<float> ef(k, grid, lambda, n);
            ed.keep_factors(keep);
            ef.keep_factors(keep);
            std::vector<detail::ComplexMatrix<double>> fd;
            std::vector<detail::ComplexMatrix<float>> ff;
            ed.forward(w, shift_scale, fd);
            ef.forward(w, shift_scale, ff);
            detail::FieldGradient gd, gf;
            ed.adjoint(w, shift_scale, bd, gd);
            ef.adjoint(w, shift_scale, bf, gf);
            std::complex<double> lhs = 0.0, rhs = 0.0;
            for (int v = 0; v < 2; ++v) {
                const double scale = fd[v].cwiseAbs().maxCoeff();
                ASSERT_GT(scale, 0.0);
                EXPECT_LE((fd[v] - ff[v].cast<std::complex<double>>()).cwiseAbs().maxCoeff(), 1e-5 * scale);
                for (int i = 0; i < n * n; ++i)
                    lhs += std::complex<double>(bf[v].data()[i]) * std::complex<double>(ff[v].data()[i]);
                double gscale = 0.0, gdiff = 0.0;
                for (std::size_t i = 0; i < k.size(); ++i) {
                    rhs += gf.weight[v][i] * w[v][i];
                    gscale = std::max(gscale, std::abs(gd.weight[v][i]));
                    gdiff = std::max(gdiff, std::abs(gd.weight[v][i] - gf.weight[v][i]));
                }
                EXPECT_LE(gdiff, 1e-5 * gscale);
            }
            // Float rounding of Σ|B||F| terms: a relative 1e-5 of the sum of magnitudes.
            double magnitude = 0.0;
            for (int v = 0; v < 2; ++v)
                for (int i = 0; i < n * n; ++i)
                    magnitude += double(std::abs(bf[v].data()[i])) * double(std::abs(ff[v].data()[i]));
            EXPECT_LE(std::abs(lhs - rhs), 1e-5 * magnitude);
            double sx = 0.0, sy = 0.0, dx = 0.0, dy = 0.0;
            for (std::size_t i = 0; i < k.size(); ++i) {
                sx = std::max(sx, std::abs(gd.shift_x[i]));
                sy = std::max(sy, std::abs(gd.shift_y[i]));
                dx = std::max(dx, std::abs(gd.shift_x[i] - gf.shift_x[i]));
                dy = std::max(dy, std::abs(gd.shift_y[i] - gf.shift_y[i]));
            }
            ASSERT_GT(sx, 0.0);
            ASSERT_GT(sy, 0.0);
            EXPECT_LE(dx, 1e-5 * sx);
            EXPECT_LE(dy, 1e-5 * sy);
        }
    }
}

// build_planar_factors writes the float engine's planar factors directly: the same bits as
// build_factors<float> followed by PlanarFactors::assign, on a chunk that starts inside the
// footprint, and an independent evaluation of the formula agrees to float rounding (the test
// fails if an entry took another kernel's slope or phase).
TEST(C3Nodes, PlanarFactorsAreBuildFactorsInPlanarFormBitForBit) {
    const Heightfield hf = random_heightfield(24, 24, 0.4, 17, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 12.0, 12.0, 2.0, 0.15, -0.25);
    const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
    ASSERT_GT(k.size(), 20u);
    const int n = 24;
    const double lambda = 0.5, shift_scale = 0.9;
    const detail::SliceGrid grid(q, lambda, n);
    const detail::PhaseTables phases(k, grid);
    const Eigen::Index k0 = 5, count = Eigen::Index(k.size()) - 7;
    detail::ComplexMatrix<float> xs(n, count), ys(n, count);
    detail::build_factors<float>(k, grid, phases, lambda, shift_scale, k0, count, xs, ys);
    detail::PlanarFactors want_x, want_y, px, py;
    want_x.resize(n, count);
    want_y.resize(n, count);
    want_x.assign(xs, count);
    want_y.assign(ys, count);
    px.resize(n, count + 3);  // wider than needed: only columns [0, count) are written
    py.resize(n, count + 3);
    detail::build_planar_factors(k, grid, phases, lambda, shift_scale, k0, count, px, py);
    const double gauss = 2.0 * k_pi * k_pi * k.sigma_um * k.sigma_um;
    double worst = 0.0;
    for (Eigen::Index c = 0; c < count; ++c)
        for (Eigen::Index p = 0; p < n; ++p) {
            for (auto [got, want] : {std::pair{&px, &want_x}, std::pair{&py, &want_y}}) {
                ASSERT_EQ(got->re(p, c), want->re(p, c)) << p << ", " << c;
                ASSERT_EQ(got->im(p, c), want->im(p, c)) << p << ", " << c;
                ASSERT_EQ(got->sum(p, c), want->sum(p, c)) << p << ", " << c;
            }
            // The formula (separable_engine.h), term by term in double.
            const std::size_t idx = std::size_t(k0 + c);
            const double b = shift_scale * 2.0 / lambda * k.slope_x[idx];
            const double u = grid.ux[std::size_t(p)];
            const std::complex<double> x = std::exp(-gauss * (u + b) * (u + b)) *
                                           std::polar(1.0, -2.0 * k_pi * u * k.dx_um[idx]);
            worst = std::max(worst, std::abs(std::complex<double>(double(px.re(p, c)), double(px.im(p, c))) - x));
        }
    EXPECT_LE(worst, 1e-6);
}

// The separable and FFT paths' gradients (tight tolerance) equal the direct path's, and match
// central differences of their own slices.
TEST(C3Nodes, GradientMatchesDirectPathAndFiniteDifferences) {
    const Heightfield hf = random_heightfield(20, 20, 0.5, 41, 1.0, 1.0);
    const int n = 18;
    const double lambda = 0.5;
    const std::vector<double> weights = test::uniform_vector(std::size_t(n) * n, -1.0, 1.0, 7);
    for (Model model : {Model::GHS, Model::RGHS, Model::Kirchhoff})
        for (RenderPath path : {RenderPath::Separable, RenderPath::Fft}) {
            SCOPED_TRACE(std::string(to_string(model)) + (path == RenderPath::Fft ? " fft" : " separable"));
            const Query q = make_query(model, 10.0, 9.0, 3.0, 0.4, -0.3);
            const RenderOptions separable = options_for(path, 1e-10);
            std::vector<double> g_sep, g_dir;
            slice_gradient<double>(hf, q, lambda, n, weights, g_sep, separable);
            slice_gradient<double>(hf, q, lambda, n, weights, g_dir, options_for(RenderPath::Direct));
            EXPECT_LE(test::max_abs_diff(g_sep, g_dir), 1e-6 * test::max_abs(g_dir));
            auto loss = [&](const Heightfield& h) {
                const std::vector<double> s = render_slice<double>(h, q, lambda, n, separable);
                double l = 0.0;
                for (std::size_t i = 0; i < s.size(); ++i) l += weights[i] * s[i];
                return l;
            };
            for (std::size_t cell : {std::size_t(9 * 20 + 9), std::size_t(11 * 20 + 8)}) {
                std::vector<double> plus = hf.values(), minus = hf.values();
                const double h = 1e-5;
                plus[cell] += h;
                minus[cell] -= h;
                const double fd = (loss(Heightfield(20, 20, plus, 1.0, 1.0)) -
                                   loss(Heightfield(20, 20, minus, 1.0, 1.0))) /
                                  (2 * h);
                EXPECT_NEAR(fd, g_sep[cell], 1e-5 * test::max_abs(g_sep));
            }
        }
}

// The separable float path stays within float rounding of the double one for GHS-type models.
TEST(C3Nodes, FloatPathAgreesWithDouble) {
    const Heightfield hf = random_heightfield(24, 24, 0.5, 51, 1.0, 1.0);
    const Query q = make_query(Model::Kirchhoff, 12.0, 12.0, 4.0, 0.3, 0.1);
    const std::vector<double> d = render_slice<double>(hf, q, 0.5, 24, options_for(RenderPath::Separable));
    const std::vector<float> f = render_slice<float>(hf, q, 0.5, 24, options_for(RenderPath::Separable));
    EXPECT_LE(test::max_abs_diff(d, std::vector<double>(f.begin(), f.end())), 1e-4 * peak(d));
}

// The pointwise bound (Hermite's formula): interpolating f(t) = Σ w e^{iαt} e^{−β(t + t0)²} (|f| on
// E_ρ at most Σ w exp(α ε + β ε²), the cells' model) in m second-kind Chebyshev points, computed
// here independently, errs at every t by at most chebyshev_node_factor(m, t) × the Hermite
// bound, and by at most the uniform bound; the factor vanishes at the nodes.
TEST(C3Nodes, PointwiseBoundHoldsForAnIndependentInterpolant) {
    const std::vector<std::tuple<double, double, double, double>> terms = {
        {1.0, 3.0, 0.4, 0.3}, {0.5, 1.0, 0.1, -1.2}, {0.25, 5.0, 1.5, 0.0}};
    detail::C3BoundCells cells;
    for (const auto& [w, a, b, t0] : terms) {
        cells.weight.push_back(w);
        cells.alpha.push_back(a);
        cells.beta.push_back(b);
    }
    auto f = [&](double t) {
        std::complex<double> sum = 0.0;
        for (const auto& [w, a, b, t0] : terms) sum += w * std::polar(std::exp(-b * (t + t0) * (t + t0)), a * t);
        return sum;
    };
    for (int m : {3, 5, 7, 9, 12, 15}) {
        SCOPED_TRACE("nodes " + std::to_string(m));
        std::vector<double> x(static_cast<std::size_t>(m)), bary(static_cast<std::size_t>(m));
        std::vector<std::complex<double>> fx(static_cast<std::size_t>(m));
        for (int j = 0; j < m; ++j) {
            x[std::size_t(j)] = std::cos(k_pi * j / (m - 1));
            bary[std::size_t(j)] = (j % 2 ? -1.0 : 1.0) * (j == 0 || j == m - 1 ? 0.5 : 1.0);
            fx[std::size_t(j)] = f(x[std::size_t(j)]);
            EXPECT_LT(detail::chebyshev_node_factor(m, x[std::size_t(j)]), 1e-12);
        }
        const double uniform = detail::chebyshev_error_bound(m, cells);
        const double hermite = detail::chebyshev_hermite_bound(m, cells);
        double worst_ratio = 0.0;
        for (int i = 1; i < 2000; ++i) {
            const double t = -1.0 + 2.0 * i / 2000.0 + 1e-7;
            std::complex<double> num = 0.0;
            double den = 0.0;
            for (int j = 0; j < m; ++j) {
                const double c = bary[std::size_t(j)] / (t - x[std::size_t(j)]);
                num += c * fx[std::size_t(j)];
                den += c;
            }
            const double err = std::abs(num / den - f(t));
            EXPECT_LE(err, uniform * (1.0 + 1e-9) + 1e-13);
            const double pointwise = detail::chebyshev_node_factor(m, t) * hermite;
            EXPECT_LE(err, pointwise * (1.0 + 1e-9) + 1e-13) << "t " << t;
            worst_ratio = std::max(worst_ratio, err / std::max(pointwise, 1e-300));
        }
        std::printf("%d nodes: uniform %.3g, Hermite %.3g, worst error / pointwise bound %.3g\n", m, uniform, hermite,
                    worst_ratio);
    }
}

// Normal light puts the specular peak at S = 1, a node, where the pointwise bound vanishes;
// the per-pixel check must still hold the slice to the tolerance there and everywhere else,
// from loose tolerances (few nodes, large errors between the nodes) to tight ones.
TEST(C3Nodes, NormalLightPointwiseBoundKeepsTheTolerance) {
    const Heightfield hf = random_heightfield(32, 32, 0.04, 17, 1.0, 1.0);
    for (Model model : {Model::GHS, Model::RGHS, Model::Kirchhoff}) {
        const Query q = make_query(model, 16.0, 16.0, 5.0);
        const FootprintKernels k = footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um);
        const int n = 32;
        const double lambda = 0.5;
        const std::vector<double> direct = detail::direct_field(k, q, lambda, n, 0.0, nullptr).value;
        const double p = peak(direct);
        ASSERT_GT(p, 0.0);
        for (double tolerance : {1e-2, 1e-3, 1e-4, 1e-6, 1e-8}) {
            SCOPED_TRACE(std::string(to_string(model)) + " tolerance " + std::to_string(tolerance));
            int nodes = 0;
            const std::vector<double> slice = node_slice(k, q, lambda, n, tolerance, &nodes);
            ASSERT_FALSE(slice.empty());
            EXPECT_LE(test::max_abs_diff(slice, direct), tolerance * p);
            std::printf("%s normal light, tolerance %g: %d nodes, error / peak %.3g\n", to_string(model), tolerance,
                        nodes, test::max_abs_diff(slice, direct) / p);
        }
    }
}
