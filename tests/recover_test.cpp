// Recovery (recover.h): the field model against the renderer, its adjoint, phase retrieval,
// unwrapping, the blurred fit and an end-to-end recovery from flat.
#include "wavebrdf/recover.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <limits>
#include <map>
#include <malloc.h>
#include <random>
#include <tuple>
#include <thread>

#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/slice_plan.h"
#include "recovery/field_operator_detail.h"

namespace wavebrdf {
namespace {

using Complex = std::complex<double>;
using wavebrdf::k_pi;

// A heightfield whose central-difference slopes all vanish: period 2 along both axes
// (h[i+1] = h[i−1]), four free values. The Gabor model then has a_k = 0 for every kernel.
Heightfield zero_slope_heightfield(int rows, int cols, double texel_um, const std::array<double, 4>& values) {
    std::vector<double> v(std::size_t(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) v[std::size_t(i) * cols + j] = values[std::size_t((i % 2) * 2 + (j % 2))];
    return Heightfield(rows, cols, v, texel_um);
}

std::vector<Complex> random_complex(std::size_t size, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<Complex> v(size);
    for (auto& z : v) z = {g(rng), g(rng)};
    return v;
}

// The field model is the renderer's field at zero slope: with period-2 heights (every slope 0)
// amplitude_factor² |forward(e^{−i(4π/λ)H})|² is the slice, here against the direct sum.
TEST(FieldOperator, MatchesRenderSliceAtZeroSlope) {
    const Heightfield hf = zero_slope_heightfield(12, 10, 1.5, {0.0, 0.13, -0.07, 0.21});
    for (Model model : {Model::OHS, Model::ROHS}) {
        // Footprint across the periodic border, oblique light.
        const Query q = test::make_query(model, 1.1, 13.7, 2.5, 0.2, -0.1);
        const double lambda = 0.55;
        const int n = 40;
        RenderOptions direct;
        direct.path = RenderPath::Direct;
        direct.prune_tolerance = 0.0;
        const std::vector<double> slice = render_slice<double>(hf, q, lambda, n, direct);
        const FieldOperator op(hf.rows(), hf.cols(), hf.texel_um(), q, lambda, n);
        const std::vector<Complex> field = op.forward(test::object_of(hf, lambda));
        double peak = 0.0, worst = 0.0;
        for (std::size_t p = 0; p < slice.size(); ++p) {
            const double a = op.amplitude_factor()[p];
            peak = std::max(peak, slice[p]);
            worst = std::max(worst, std::abs(a * a * std::norm(field[p]) - slice[p]));
        }
        EXPECT_GT(peak, 0.0);
        EXPECT_LT(worst, 1e-10 * peak) << to_string(model);
    }
}

// On a refined object grid the operator is the renderer of the refined heightfield (texel w/q)
// at zero slope.
TEST(FieldOperator, RefinedGridMatchesRenderOfRefinedHeightfield) {
    const int q = 3;
    const Heightfield fine = zero_slope_heightfield(8 * q, 6 * q, 2.0 / q, {0.05, -0.1, 0.02, 0.17});
    const Query query = test::make_query(Model::OHS, 5.3, 2.2, 2.0);
    const double lambda = 0.5;
    const int n = 48;
    const std::vector<double> slice = render_slice<double>(fine, query, lambda, n);
    const FieldOperator op(8, 6, 2.0, query, lambda, n, q);
    const std::vector<Complex> field = op.forward(test::object_of(fine, lambda));
    double peak = 0.0, worst = 0.0;
    for (std::size_t p = 0; p < slice.size(); ++p) {
        const double a = op.amplitude_factor()[p];
        peak = std::max(peak, slice[p]);
        worst = std::max(worst, std::abs(a * a * std::norm(field[p]) - slice[p]));
    }
    EXPECT_LT(worst, 1e-10 * peak);
}

// ⟨A x, y⟩ = ⟨x, Aᴴ y⟩ for random complex x, y (footprint wrapping the border, oblique light).
TEST(FieldOperator, AdjointDotProductIdentity) {
    for (int refine : {1, 3}) {
        const Query q = test::make_query(Model::ROHS, 0.4, 9.1, 1.7, -0.15, 0.25);
        const FieldOperator op(7, 5, 2.0, q, 0.6, 24, refine);
        const auto x = random_complex(std::size_t(7 * refine) * (5 * refine), 3);
        const auto y = random_complex(24 * 24, 4);
        const auto ax = op.forward(x);
        const auto aty = op.adjoint(y);
        Complex lhs = 0.0, rhs = 0.0;
        for (std::size_t k = 0; k < y.size(); ++k) lhs += std::conj(y[k]) * ax[k];
        for (std::size_t k = 0; k < x.size(); ++k) rhs += std::conj(aty[k]) * x[k];
        EXPECT_GT(std::abs(lhs), 1e-3);
        EXPECT_NEAR(lhs.real(), rhs.real(), 1e-11 * std::abs(lhs)) << "refine " << refine;
        EXPECT_NEAR(lhs.imag(), rhs.imag(), 1e-11 * std::abs(lhs)) << "refine " << refine;
    }
}

// The flat fine grid is shared while held: an operator built after (and while holding)
// operators of other tiles (another size, the same size with another texel width) equals one
// built on its own on another thread.
TEST(FieldOperator, SameAfterOperatorsOfOtherTiles) {
    const Query q = test::make_query(Model::OHS, 0.4, 5.3, 4.1, 0.1, -0.05);
    const auto x = random_complex(std::size_t(7 * 3) * (5 * 3), 5);
    std::vector<Complex> fresh;
    std::thread([&] { fresh = FieldOperator(7, 5, 2.0, q, 0.6, 24, 3).forward(x); }).join();
    const FieldOperator other_size(9, 4, 2.0, q, 0.6, 24, 3);
    const FieldOperator other_texel(7, 5, 1.5, q, 0.6, 24, 3);
    const FieldOperator op(7, 5, 2.0, q, 0.6, 24, 3);
    const auto field = op.forward(x);
    ASSERT_EQ(field.size(), fresh.size());
    double peak = 0.0;
    for (const Complex& v : fresh) peak = std::max(peak, std::abs(v));
    EXPECT_GT(peak, 1e-3);
    for (std::size_t k = 0; k < field.size(); ++k) EXPECT_EQ(field[k], fresh[k]) << "pixel " << k;
}

// The operator (shared factor matrices, rows folded modulo q where q·du·d is an integer,
// per-footprint diagonal phases) against a direct sum of recover.h's formula over the object
// samples: I(u) = env(u) Σ_a P_a O_a e^{−i2π u·δ_a}, δ_a the minimal periodic image of
// x_a − μ, P_a = c(|δ_a|) d² within 3σ_p, env(u) = exp(−2π²(d/2)²|u|²). Footprint off the grid's
// origin and across the periodic border, oblique light; λ 0.5 folds (du·d = 1/9), 0.47 does not.
// Then the adjoint identity for the same operators.
TEST(FieldOperator, SharedFactorsMatchDirectSumAndAdjoint) {
    const int rows = 12, cols = 11, refine = 3, n = 24;
    const double texel = 2.0, d = texel / refine, sigma_p = 2.5;
    const Query q = test::make_query(Model::OHS, 7.3, 15.9, sigma_p, 0.3, -0.2);
    const int fr = rows * refine, fc = cols * refine;
    const auto object = random_complex(std::size_t(fr) * fc, 21);
    for (double lambda : {0.5, 0.47}) {
        const FieldOperator op(rows, cols, texel, q, lambda, n, refine);
        const std::vector<Complex> field = op.forward(object);
        const auto image = [](double x, double period) { return x - period * std::floor(x / period + 0.5); };
        std::vector<Complex> direct(std::size_t(n) * n, 0.0);
        const double env_gauss = 2.0 * k_pi * k_pi * (0.5 * d) * (0.5 * d);
        for (int p = 0; p < n; ++p)
            for (int s = 0; s < n; ++s) {
                const double ux = (q.omega_i[0] + slice_omega(p, n)) / lambda;
                const double uy = (q.omega_i[1] + slice_omega(s, n)) / lambda;
                Complex sum = 0.0;
                for (int a = 0; a < fr; ++a) {
                    const double dx = image((a + 0.5) * d - q.x_um, fr * d);
                    for (int b = 0; b < fc; ++b) {
                        const double dy = image((b + 0.5) * d - q.y_um, fc * d);
                        const double r2 = dx * dx + dy * dy;
                        if (r2 > 9.0 * sigma_p * sigma_p) continue;
                        const double weight = std::exp(-r2 / (2.0 * sigma_p * sigma_p)) / (std::sqrt(k_pi) * sigma_p) *
                                              d * d;
                        sum += weight * object[std::size_t(a) * fc + b] *
                               std::polar(1.0, -2.0 * k_pi * (ux * dx + uy * dy));
                    }
                }
                direct[std::size_t(p) * n + s] = std::exp(-env_gauss * (ux * ux + uy * uy)) * sum;
            }
        double peak = 0.0, worst = 0.0;
        for (std::size_t k = 0; k < direct.size(); ++k) {
            peak = std::max(peak, std::abs(direct[k]));
            worst = std::max(worst, std::abs(direct[k] - field[k]));
        }
        EXPECT_GT(peak, 1e-3);
        EXPECT_LT(worst, 1e-10 * peak) << "lambda " << lambda;

        const auto y = random_complex(std::size_t(n) * n, 22);
        const auto aty = op.adjoint(y);
        Complex lhs = 0.0, rhs = 0.0;
        for (std::size_t k = 0; k < y.size(); ++k) lhs += std::conj(y[k]) * field[k];
        for (std::size_t k = 0; k < object.size(); ++k) rhs += std::conj(aty[k]) * object[k];
        EXPECT_GT(std::abs(lhs), 1e-3);
        EXPECT_NEAR(lhs.real(), rhs.real(), 1e-11 * std::abs(lhs)) << "lambda " << lambda;
        EXPECT_NEAR(lhs.imag(), rhs.imag(), 1e-11 * std::abs(lhs)) << "lambda " << lambda;
    }
}

// The retrieval's single-precision products (field_operator_detail.h: three real products per
// complex one) against the double operator: |Ψ| on the box, and the adjoint identity of the
// float pair. λ 0.5 folds (du·d = 1/9), 0.47 does not; both product orders (a 12 × 11 tile with
// refine 3 at n = 24 and one with refine 9 at n = 48, the recovery's footprint).
TEST(FieldOperator, SinglePrecisionProductsMatchTheDoubleOperator) {
    struct Case {
        int rows, cols, refine, n;
        double texel, sigma_p;
    };
    for (const Case c : {Case{12, 11, 3, 24, 2.0, 2.5}, Case{12, 12, 9, 48, 2.0, 3.0}}) {
        const Query q = test::make_query(Model::OHS, 7.3, 15.9, c.sigma_p, 0.3, -0.2);
        const int fr = c.rows * c.refine, fc = c.cols * c.refine;
        const auto object = random_complex(std::size_t(fr) * fc, 23);
        for (double lambda : {0.5, 0.47}) {
            const FieldOperator op(c.rows, c.cols, c.texel, q, lambda, c.n, c.refine);
            const std::vector<Complex> field = op.forward(object);
            Eigen::MatrixXcf psi;
            wavebrdf::detail::field_forward_unphased(op, object.data(), psi);
            int a0 = 0, b0 = 0;
            (void)wavebrdf::detail::field_amplitude_box(op, a0, b0);
            double peak = 0.0, worst = 0.0;
            for (Eigen::Index a = 0; a < psi.rows(); ++a)
                for (Eigen::Index b = 0; b < psi.cols(); ++b) {
                    const double exact = std::abs(field[std::size_t(a0 + a) * c.n + std::size_t(b0 + b)]);
                    peak = std::max(peak, exact);
                    worst = std::max(worst, std::abs(exact - double(std::abs(psi(a, b)))));
                }
            EXPECT_GT(peak, 1e-3);
            EXPECT_LT(worst, 1e-5 * peak) << "lambda " << lambda << ", refine " << c.refine;

            // ⟨G, A x⟩ = ⟨Aᴴ G, x⟩ for the float pair.
            const auto gv = random_complex(std::size_t(psi.size()), 24);
            Eigen::MatrixXcf g(psi.rows(), psi.cols());
            for (Eigen::Index k = 0; k < g.size(); ++k) g(k) = std::complex<float>(gv[std::size_t(k)]);
            std::vector<Complex> atg(object.size(), 0.0);
            wavebrdf::detail::field_adjoint_unphased_add(op, g, atg.data());
            Complex lhs = 0.0, rhs = 0.0;
            for (Eigen::Index k = 0; k < g.size(); ++k) lhs += std::conj(Complex(g(k))) * Complex(psi(k));
            for (std::size_t k = 0; k < object.size(); ++k) rhs += std::conj(atg[k]) * object[k];
            EXPECT_GT(std::abs(lhs), 1e-3);
            EXPECT_NEAR(lhs.real(), rhs.real(), 1e-5 * std::abs(lhs)) << "lambda " << lambda;
            EXPECT_NEAR(lhs.imag(), rhs.imag(), 1e-5 * std::abs(lhs)) << "lambda " << lambda;
        }
    }
}

TEST(FieldOperator, RejectsBadArguments) {
    const Query q = test::make_query(Model::OHS, 0.0, 0.0, 2.0);
    EXPECT_THROW(FieldOperator(0, 4, 1.0, q, 0.5, 16), std::invalid_argument);
    EXPECT_THROW(FieldOperator(4, 4, -1.0, q, 0.5, 16), std::domain_error);
    EXPECT_THROW(FieldOperator(4, 4, 1.0, q, 0.5, 16, 0), std::invalid_argument);
    EXPECT_THROW(FieldOperator(4, 4, 1.0, test::make_query(Model::GHS, 0.0, 0.0, 2.0), 0.5, 16), std::invalid_argument);
    const FieldOperator op(4, 4, 1.0, q, 0.5, 16);
    EXPECT_THROW(op.forward(std::vector<Complex>(15)), std::invalid_argument);
    EXPECT_THROW(op.adjoint(std::vector<Complex>(17)), std::invalid_argument);
}

// Overlapping slices determine the object up to a global phase: from a start 0.6 rad (rms)
// away, the retrieval returns the object (which a single slice could not pin down).
TEST(RetrieveField, RecoversKnownObjectUpToGlobalPhase) {
    const int rows = 10, cols = 10;
    const double texel = 1.0, lambda = 0.5;
    const Heightfield hf = test::random_heightfield(rows, cols, 0.03, 5, texel);
    const std::vector<Complex> truth = test::object_of(hf, lambda);
    const auto observations = test::model_observations(truth, rows, cols, texel, lambda, 48, 2.0, 2.0, 11);
    std::mt19937_64 rng(2);
    std::normal_distribution<double> noise(0.0, 0.6);
    std::vector<Complex> start(truth.size());
    for (std::size_t k = 0; k < truth.size(); ++k) start[k] = truth[k] * std::polar(1.0, noise(rng));
    ASSERT_GT(test::distance_up_to_phase(truth, start), 0.4);
    FieldRetrievalSettings s;
    s.iterations = 300;
    const FieldRetrievalResult r = retrieve_field(observations, lambda, rows, cols, texel, start, s);
    EXPECT_LT(r.relative_loss, 1e-10);
    EXPECT_LT(test::distance_up_to_phase(truth, r.object), 1e-4);
}

// The stopping rule (stall_window / stall_tolerance): with noisy slices the loss has a floor;
// the retrieval stops once it stalls there, in fewer iterations than the full run, with the
// object as close to the truth as the full run gets (and far closer than the start).
TEST(RetrieveField, StallStopEndsEarlyWithTheFullRunsAccuracy) {
    const int rows = 10, cols = 10;
    const double texel = 1.0, lambda = 0.5;
    const Heightfield hf = test::random_heightfield(rows, cols, 0.03, 5, texel);
    const std::vector<Complex> truth = test::object_of(hf, lambda);
    auto observations = test::model_observations(truth, rows, cols, texel, lambda, 48, 2.0, 2.0, 11);
    std::mt19937_64 rng(7);
    std::normal_distribution<double> noise(0.0, 0.02);  // 2 % multiplicative noise: a floor
    for (Observation& o : observations)
        for (float& r : o.reference) r = float(double(r) * std::max(0.0, 1.0 + noise(rng)));
    std::normal_distribution<double> phase(0.0, 0.6);
    std::vector<Complex> start(truth.size());
    for (std::size_t k = 0; k < truth.size(); ++k) start[k] = truth[k] * std::polar(1.0, phase(rng));
    FieldRetrievalSettings full;
    full.iterations = 300;
    full.stall_window = 0;
    FieldRetrievalSettings stalled = full;
    stalled.stall_window = 5;
    stalled.stall_tolerance = 0.005;
    const FieldRetrievalResult a = retrieve_field(observations, lambda, rows, cols, texel, start, full);
    const FieldRetrievalResult b = retrieve_field(observations, lambda, rows, cols, texel, start, stalled);
    // The full run ends where its line search finds no descent any more (at the floor).
    EXPECT_LT(b.iterations, a.iterations);
    EXPECT_LT(b.relative_loss, 1.02 * a.relative_loss);
    const double d_full = test::distance_up_to_phase(truth, a.object),
                 d_stall = test::distance_up_to_phase(truth, b.object);
    EXPECT_LT(d_stall, 0.1 * test::distance_up_to_phase(truth, start));
    EXPECT_LT(d_stall, 1.5 * d_full + 1e-3);
    std::printf("stall: %d iterations (full %d), loss %.4g (%.4g), distance %.3g (%.3g)\n", b.iterations, a.iterations,
                b.relative_loss, a.relative_loss, d_stall, d_full);
    FieldRetrievalSettings bad;
    bad.stall_window = -1;
    EXPECT_THROW(retrieve_field(observations, lambda, rows, cols, texel, start, bad), std::domain_error);
}

TEST(RetrieveField, RejectsObservationsAtAnotherWavelength) {
    Observation o;
    o.query = test::make_query(Model::OHS, 1.0, 1.0, 1.0);
    o.lambdas_um = {0.6};
    o.resolution = 8;
    o.reference.assign(64, 1.0);
    EXPECT_THROW(retrieve_field({o}, 0.5, 4, 4, 1.0), std::invalid_argument);
    EXPECT_THROW(retrieve_field(std::vector<Observation>{}, 0.5, 4, 4, 1.0), std::invalid_argument);
    // The overload on pointers (no copies) checks the same, and refuses a null one.
    EXPECT_THROW(retrieve_field(std::vector<const Observation*>{&o}, 0.5, 4, 4, 1.0), std::invalid_argument);
    EXPECT_THROW(retrieve_field(std::vector<const Observation*>{nullptr}, 0.6, 4, 4, 1.0), std::invalid_argument);
}

// Heights spanning 2.4 µm (far beyond λ/2) from exact fields at three wavelengths, each with
// its own unknown global phase: per sample (synthetic wavelengths) and spatially.
TEST(UnwrapHeights, RecoversHeightsFromExactFieldsAtSeveralWavelengths) {
    const int rows = 64, cols = 56;
    SurfaceParams p;
    p.rows = rows;
    p.cols = cols;
    p.texel_um = 0.05;  // fine sampling: neighbours differ by less than π at 0.5 µm (checked)
    p.correlation_um = 1.2;
    p.rms_height_um = 0.55;
    p.seed = 3;
    const Heightfield hf = generate_heightfield(p);
    const std::vector<double> lambdas = {0.5, 0.55, 0.65};
    std::vector<std::vector<Complex>> fields;
    double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity(), mean = 0.0;
    for (double v : hf.values()) {
        lo = std::min(lo, v * p.texel_um);
        hi = std::max(hi, v * p.texel_um);
        mean += v * p.texel_um / double(rows * cols);
    }
    ASSERT_GT(hi - lo, 2.0);
    double steepest = 0.0;  // largest height step between neighbours, µm
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            steepest = std::max({steepest, std::abs(hf.height_um(i + 1, j) - hf.height_um(i, j)),
                                 std::abs(hf.height_um(i, j + 1) - hf.height_um(i, j))});
    ASSERT_LT(4.0 * k_pi / 0.5 * steepest, k_pi);
    for (std::size_t l = 0; l < lambdas.size(); ++l) {
        auto f = test::object_of(hf, lambdas[l]);
        for (auto& z : f) z *= std::polar(0.8, 1.0 + 2.0 * double(l));  // global phase and amplitude
        fields.push_back(f);
    }
    for (bool spatial : {false, true}) {
        const auto h = unwrap_heights(lambdas, fields, 3.0, spatial ? rows : 0, spatial ? cols : 0);
        double worst = 0.0;
        for (std::size_t k = 0; k < h.size(); ++k)
            worst = std::max(worst, std::abs(h[k] - (hf.values()[k] * p.texel_um - mean)));
        EXPECT_LT(worst, 1e-9) << (spatial ? "spatial" : "per sample");
    }
    // One wavelength alone cannot: per sample it only knows the heights modulo λ/2.
    const auto one = unwrap_heights({0.5}, {fields[0]}, 3.0);
    double worst = 0.0;
    for (std::size_t k = 0; k < one.size(); ++k)
        worst = std::max(worst, std::abs(one[k] - (hf.values()[k] * p.texel_um - mean)));
    EXPECT_GT(worst, 0.1);
}

// With a reference within a branch of the truth, each sample snaps to the truth.
TEST(UnwrapHeights, SnapsToTheBranchNearestAReference) {
    const std::vector<double> truth = {0.0, 0.9, -0.7, 1.3, -1.1, 0.2};
    std::vector<double> reference = truth;
    for (std::size_t k = 0; k < reference.size(); ++k) reference[k] += (k % 2 ? 0.05 : -0.04);
    std::vector<std::vector<Complex>> fields;
    for (double lambda : {0.5, 0.6}) {
        std::vector<Complex> f;
        for (double h : truth) f.push_back(std::polar(1.0, -4.0 * k_pi / lambda * h + 0.3));
        fields.push_back(f);
    }
    const auto h = unwrap_heights({0.5, 0.6}, fields, 3.0, 0, 0, &reference);
    double mean = 0.0;
    for (double v : truth) mean += v / double(truth.size());
    for (std::size_t k = 0; k < h.size(); ++k) EXPECT_NEAR(h[k], truth[k] - mean, 1e-12);
}

TEST(UnwrapHeights, RejectsBadArguments) {
    const std::vector<Complex> f(4, 1.0);
    EXPECT_THROW(unwrap_heights({0.5}, {}, 1.0), std::invalid_argument);
    EXPECT_THROW(unwrap_heights({0.5, 0.5}, {f, f}, 1.0), std::invalid_argument);
    EXPECT_THROW(unwrap_heights({0.5, 0.6}, {f, std::vector<Complex>(3)}, 1.0), std::invalid_argument);
    EXPECT_THROW(unwrap_heights({0.5}, {f}, 1.0, 3, 3), std::invalid_argument);
    EXPECT_THROW(unwrap_heights({0.5}, {f}, 0.0), std::domain_error);
    EXPECT_THROW(unwrap_heights({-0.5}, {f}, 1.0), std::domain_error);
}

// refined_heights blends the kernels' tangent planes: exact for a constant surface, and for a
// long-period sinusoid it follows H(x) between the texel centres.
TEST(RefinedHeights, FollowsTheSurfaceBetweenTexelCentres) {
    const int rows = 64, q = 5;
    const double w = 0.5, period = rows * w, amplitude = 0.3;
    std::vector<double> v(std::size_t(rows) * 2);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < 2; ++j)
            v[std::size_t(i) * 2 + j] = amplitude * std::sin(2.0 * k_pi * (i + 0.5) * w / period) / w;
    const Heightfield hf(rows, 2, v, w);
    const auto fine = refined_heights(hf, q);
    double worst = 0.0;
    for (int a = 0; a < rows * q; ++a) {
        const double x = (a + 0.5) * w / q;
        worst = std::max(worst, std::abs(fine[std::size_t(a) * 2 * q] - amplitude * std::sin(2.0 * k_pi * x / period)));
    }
    EXPECT_LT(worst, 2e-3 * amplitude);
    const auto flat = refined_heights(Heightfield(3, 3, std::vector<double>(9, 0.25), 2.0), 3);
    for (double h : flat) EXPECT_NEAR(h, 0.5, 1e-12);
    EXPECT_THROW(refined_heights(hf, 2), std::invalid_argument);
}

// refined_heights (its Gaussians from a table per place in the texel, the values from a
// periodically padded copy) against the blend written out with Heightfield's own accessors, on
// grids smaller than the kernels' reach (the padding wraps more than once) and with v ≠ 1.
TEST(RefinedHeights, MatchesTheBlendWrittenOut) {
    std::mt19937_64 rng(11511);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (const auto& [rows, cols, q, w, vscale] :
         {std::tuple{3, 5, 3, 2.0, 0.7}, std::tuple{9, 7, 5, 0.5, 1.3}, std::tuple{2, 2, 1, 1.0, 1.0}}) {
        std::vector<double> v(std::size_t(rows) * cols);
        for (double& x : v) x = u(rng);
        const Heightfield hf(rows, cols, v, w, vscale);
        const std::vector<double> fine = refined_heights(hf, q);
        ASSERT_EQ(fine.size(), std::size_t(rows) * q * cols * q);
        const double d = w / q, sigma = 0.5 * w;
        double worst = 0.0;
        for (int a = 0; a < rows * q; ++a)
            for (int b = 0; b < cols * q; ++b) {
                const double x = (a + 0.5) * d, y = (b + 0.5) * d;  // the sample's position
                const int i0 = a / q, j0 = b / q;
                double num = 0.0, den = 0.0;
                for (int i = i0 - 3; i <= i0 + 3; ++i)
                    for (int j = j0 - 3; j <= j0 + 3; ++j) {
                        const double dx = x - (i + 0.5) * w, dy = y - (j + 0.5) * w;
                        const double g = std::exp(-(dx * dx + dy * dy) / (2.0 * sigma * sigma));
                        num += g * (hf.height_um(i, j) + hf.slope(i, j)[0] * dx + hf.slope(i, j)[1] * dy);
                        den += g;
                    }
                worst = std::max(worst, std::abs(fine[std::size_t(a) * cols * q + b] - num / den));
            }
        EXPECT_LT(worst, 1e-12) << rows << "x" << cols << " refine " << q;
    }
}

using test::SmallCase;
using test::small_case;

// The refinement keeps one single-precision slice plan per observation across its iterations
// (set_heights, forward, adjoint, release per evaluation): every cycle gives exactly what a
// plan built fresh on those heights gives, so the cache changes the time, not the values.
TEST(RecoverHeights, RefinementPlanCycleMatchesFreshPlans) {
    const Heightfield first = test::random_heightfield(12, 12, 0.4, 31, 2.0);
    const Query q = test::make_query(Model::OHS, 11.0, 13.0, 3.0);
    const std::vector<double> lambdas{0.5};
    const int n = 24;
    SlicePlan<float> cached(first, q, lambdas, n, 1);
    for (unsigned seed : {32u, 33u, 34u}) {
        const Heightfield hf = test::random_heightfield(12, 12, 0.4, seed, 2.0);
        cached.set_heights(hf.values());
        const std::vector<float> slice = cached.forward();
        std::vector<double> weights(slice.size());
        for (std::size_t p = 0; p < slice.size(); ++p) weights[p] = std::sin(0.37 * double(p) + seed);
        std::vector<double> g_cached;
        cached.adjoint(weights, g_cached, 0.25);
        cached.release();

        SlicePlan<float> fresh(hf, q, lambdas, n, 1);
        EXPECT_EQ(slice, fresh.forward());
        std::vector<double> g_fresh;
        fresh.adjoint(weights, g_fresh, 0.25);
        EXPECT_EQ(g_cached, g_fresh);
    }
}

RecoverSettings quick_recover_settings() {
    RecoverSettings s;
    s.blurred.blur_widths = {12.0, 4.0};
    s.blurred.iterations = 15;
    s.field.iterations = 40;
    s.refine_iterations = 15;
    return s;
}

TEST(RecoverHeights, RecoversASmallSurfaceFromFlat) {
    const SmallCase c = small_case(21);
    std::map<std::string, double> last_rmse;
    const Heightfield estimate = recover_heights(
        c.observations, 12, 12, 2.0, 1.0, quick_recover_settings(),
        [&](const StageMetrics& m) {
            if (m.height_rel_rmse >= 0.0) last_rmse[m.stage] = m.height_rel_rmse;
            return true;
        },
        &c.truth);
    const double flat_rmse = height_rel_rmse(Heightfield(12, 12, std::vector<double>(144, 0.0), 2.0), c.truth);
    EXPECT_GT(flat_rmse, 0.15);
    // Each stage's own result: the blurred fit gets the shape, the fields the detail.
    ASSERT_TRUE(last_rmse.count("blur") && last_rmse.count("unwrap") && last_rmse.count("refine"));
    EXPECT_LT(last_rmse["blur"], 0.1);
    EXPECT_LT(last_rmse["unwrap"], 0.02);
    EXPECT_LT(height_rel_rmse(estimate, c.truth), 0.01);
    EXPECT_EQ(estimate.texel_um(), 2.0);
}

// The blurred fit alone, from flat, finds the surface's shape (the stage that makes the field
// retrieval converge); blurring less afterwards does not make it worse.
TEST(FitBlurred, FindsTheShapeFromFlat) {
    const SmallCase c = small_case(23);
    const Heightfield flat(12, 12, std::vector<double>(144, 0.0), 2.0);
    BlurredFitSettings s;
    s.blur_widths = {12.0};
    s.iterations = 30;
    int calls = 0;
    const Heightfield wide = fit_blurred(c.observations, flat, s, [&](int stage, int, double) {
        EXPECT_EQ(stage, 0);
        ++calls;
        return true;
    });
    EXPECT_GT(calls, 5);
    EXPECT_LT(height_rel_rmse(wide, c.truth), 0.4 * height_rel_rmse(flat, c.truth));
    s.blur_widths = {4.0};
    const Heightfield narrow = fit_blurred(c.observations, wide, s);
    EXPECT_LT(height_rel_rmse(narrow, c.truth), height_rel_rmse(wide, c.truth));
    s.blur_widths = {-1.0};
    EXPECT_THROW(fit_blurred(c.observations, flat, s), std::domain_error);
}

// BlurredFitSettings::width_iterations caps each width's stage on its own (0 skips the width), and
// the stall rule stops a width once its loss fell by less than stall_tolerance of its value over
// stall_window iterations (a tolerance of 1e6 is met at the first chance: window + 1 iterations);
// the stopped fit still finds the shape (the bound of FindsTheShapeFromFlat). Bad values refused.
TEST(FitBlurred, WidthIterationsAndTheStallRuleStopEachWidth) {
    const SmallCase c = small_case(23);
    const Heightfield flat(12, 12, std::vector<double>(144, 0.0), 2.0);
    BlurredFitSettings s;
    s.blur_widths = {12.0, 8.0, 4.0};
    s.iterations = 12;
    const auto per_stage = [&](const BlurredFitSettings& settings, Heightfield* out) {
        std::map<int, int> calls;
        *out = fit_blurred(c.observations, flat, settings, [&](int stage, int, double) {
            ++calls[stage];
            return true;
        });
        return calls;
    };
    Heightfield all = flat, capped = flat, stalled = flat;
    EXPECT_EQ(per_stage(s, &all), (std::map<int, int>{{0, 12}, {1, 12}, {2, 12}}));
    BlurredFitSettings c2 = s;
    c2.width_iterations = {12, 0, 5};
    EXPECT_EQ(per_stage(c2, &capped), (std::map<int, int>{{0, 12}, {2, 5}}));
    EXPECT_NE(all.values(), capped.values());
    BlurredFitSettings c3 = s;
    c3.stall_window = 3;
    c3.stall_tolerance = 1e6;
    EXPECT_EQ(per_stage(c3, &stalled), (std::map<int, int>{{0, 4}, {1, 4}, {2, 4}}));
    EXPECT_LT(height_rel_rmse(stalled, c.truth), 0.4 * height_rel_rmse(flat, c.truth));
    // A tolerance of 0 never stops a falling loss: the same bits as without the rule.
    BlurredFitSettings c4 = s;
    c4.stall_window = 3;
    Heightfield zero = flat;
    EXPECT_EQ(per_stage(c4, &zero), (std::map<int, int>{{0, 12}, {1, 12}, {2, 12}}));
    EXPECT_EQ(zero.values(), all.values());
    BlurredFitSettings bad = s;
    bad.width_iterations = {1, 2};
    EXPECT_THROW(fit_blurred(c.observations, flat, bad), std::invalid_argument);
    bad.width_iterations = {1, -1, 2};
    EXPECT_THROW(fit_blurred(c.observations, flat, bad), std::domain_error);
    bad = s;
    bad.stall_window = -1;
    EXPECT_THROW(fit_blurred(c.observations, flat, bad), std::domain_error);
    bad = s;
    bad.stall_tolerance = std::nan("");
    EXPECT_THROW(fit_blurred(c.observations, flat, bad), std::domain_error);
}

// The blurred fit and the refinement hold no more memory at their last iteration than at their
// third (only the L-BFGS history, 2·history vectors of rows·cols doubles, may still fill), and
// the refinement's plans, kept between iterations, stay light: under 16 KB per observation
// (a plan used to keep its per-pixel factors, phase tables and output: ~70 KB at 64² slices).
// Measured in a child on one thread, where every allocation is in glibc's main arena.
TEST(RecoverHeights, HeapDoesNotGrowWithIterations) {
#ifdef WAVEBRDF_ASAN
    GTEST_SKIP() << "AddressSanitizer replaces malloc: mallinfo2 does not see its heap; "
                    "the heap is checked in the plain build";
#endif
    const SmallCase c = small_case(21);
    RecoverSettings s = quick_recover_settings();
    s.blurred.blur_widths = {8.0};
    s.blurred.iterations = 10;
    s.field.iterations = 3;
    s.refine_iterations = 10;
    const double history_bytes = 2.0 * std::max(s.blurred.history, s.refine_history) * 144 * sizeof(double);
    const double observations = double(c.observations.size());
    const double measured = test::child_peak_memory_bytes([&] {
        std::map<std::string, std::vector<double>> heap;  // by stage, per report
        const auto in_use = [] { return double(mallinfo2().uordblks); };
        double before_refine = -1.0;
        recover_heights(c.observations, 12, 12, 2.0, 1.0, s, [&](const StageMetrics& m) {
            if (m.stage == "unwrap") before_refine = in_use();
            heap[m.stage].push_back(in_use());
            return true;
        });
        bool ok = before_refine > 0.0;
        for (const char* stage : {"blur:0", "refine"}) {
            const std::vector<double>& h = heap[stage];
            if (h.size() < 8) return false;
            if (h.back() > h[2] + history_bytes + 16384.0) {
                std::fprintf(stderr, "%s: heap %.0f at iteration 3, %.0f at the last\n", stage, h[2], h.back());
                ok = false;
            }
        }
        const double plans = heap["refine"].front() - before_refine;
        if (plans > 16384.0 * observations + history_bytes) {
            std::fprintf(stderr, "refinement plans: %.0f bytes for %.0f observations\n", plans, observations);
            ok = false;
        }
        return ok;
    });
    EXPECT_GT(measured, 0.0) << "the heap grew with the iterations, or the plans are heavy (see stderr)";
}

TEST(AutoRefine, SamplesTheSliceBandAndTheField) {
    // d = w/q < λ / (2(1 + |ω_i|)), q odd.
    EXPECT_EQ(auto_refine(2.0, 0.5), 9);        // 2·2/0.5 = 8 → 9
    EXPECT_EQ(auto_refine(1.0, 0.5), 5);        // 4 → 5
    EXPECT_EQ(auto_refine(0.2, 0.5), 1);        // 0.8 → 1
    EXPECT_EQ(auto_refine(2.0, 0.5, 0.3), 11);  // 10.4 → 11
    const Heightfield hf = test::random_heightfield(4, 5, 0.2, 9, 1.5);
    const auto object = object_from_heights(hf, 0.6, 3);
    const auto heights = refined_heights(hf, 3);
    ASSERT_EQ(object.size(), heights.size());
    for (std::size_t k = 0; k < object.size(); ++k)
        EXPECT_NEAR(std::arg(object[k] * std::polar(1.0, 4.0 * k_pi / 0.6 * heights[k])), 0.0, 1e-12);
}

// The stages sum over observations on all threads in a fixed order (ordered_parallel_sum):
// the same input gives the same heights, bit for bit, on every run.
TEST(RecoverHeights, IsReproducibleOnSeveralThreads) {
    const SmallCase c = small_case(23);
    const Heightfield a = recover_heights(c.observations, 12, 12, 2.0, 1.0, quick_recover_settings());
    const Heightfield b = recover_heights(c.observations, 12, 12, 2.0, 1.0, quick_recover_settings());
    EXPECT_EQ(a.values(), b.values());
}

TEST(RecoverHeights, StopsWhenTheCallbackSaysSo) {
    const SmallCase c = small_case(22);
    int calls = 0;
    recover_heights(c.observations, 12, 12, 2.0, 1.0, quick_recover_settings(), [&](const StageMetrics&) {
        ++calls;
        return false;
    });
    EXPECT_EQ(calls, 1);
}

// Recovers the 12² small case, counting the reports per stage name.
Heightfield recover_counting_stages(const SmallCase& c, const RecoverSettings& s, std::map<std::string, int>* stages) {
    return recover_heights(c.observations, 12, 12, 2.0, 1.0, s, [&](const StageMetrics& m) {
        ++(*stages)[m.stage];
        return true;
    });
}

// field_wavelengths / refine_ladder_wavelengths count the longest wavelengths: 1 runs the field
// stage at the longest wavelength only and the refinement first on its slices ("refine:0.6")
// then on every slice, the same bits as naming that wavelength in field_lambda_min_um /
// refine_ladder_min_um; negative counts other than −1 (unset: the schedule's) are refused.
TEST(RecoverHeights, FieldAndLadderWavelengthCountsTakeTheLongestWavelengths) {
    const SmallCase c = small_case(25);
    RecoverSettings s = quick_recover_settings();
    s.field_wavelengths = 0;  // every wavelength (the smooth schedule's default is the longest)
    s.refine_iterations = 3;
    s.refine_ladder_iterations = 4;
    s.refine_ladder_stall_window = 0;  // the rung runs its cap (no stall rule: no run-on)
    s.model_check_iterations = 0;
    std::map<std::string, int> all, counted, named;
    const Heightfield a = recover_counting_stages(c, s, &all);
    EXPECT_GT(all.count("field:0.5"), 0u);
    EXPECT_EQ(all.count("refine:0.6"), 0u);
    RecoverSettings one = s;
    one.field_wavelengths = 1;
    one.refine_ladder_wavelengths = 1;
    const Heightfield b = recover_counting_stages(c, one, &counted);
    EXPECT_GT(counted.count("field:0.6"), 0u);
    EXPECT_EQ(counted.count("field:0.5"), 0u);
    EXPECT_EQ(counted.at("refine:0.6"), one.refine_ladder_iterations);
    EXPECT_EQ(counted.count("refine:0.5"), 0u);
    EXPECT_GT(counted.count("refine"), 0u);
    EXPECT_NE(a.values(), b.values());
    RecoverSettings by_name = s;
    by_name.field_lambda_min_um = 0.6;
    by_name.refine_ladder_min_um = 0.6;
    const Heightfield d = recover_counting_stages(c, by_name, &named);
    EXPECT_EQ(b.values(), d.values());
    EXPECT_EQ(counted, named);
    RecoverSettings bad = s;
    bad.field_wavelengths = -2;
    EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, bad), std::invalid_argument);
    bad = s;
    bad.refine_ladder_wavelengths = -2;
    EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, bad), std::invalid_argument);
}

// refine_ladder_relative_tolerance stops a ladder rung once loss / loss(flat) is below it (the
// rung starts near the answer, so 0.999 stops it after its first iteration), and the refinement
// on every slice still runs its iterations; 0 runs the rung to its cap. Out of range: refused.
TEST(RecoverHeights, LadderRelativeToleranceStopsTheRungEarly) {
    const SmallCase c = small_case(25);
    RecoverSettings s = quick_recover_settings();
    s.refine_iterations = 3;
    s.refine_ladder_iterations = 6;
    s.refine_ladder_stall_window = 0;  // the rung runs its cap (no stall rule: no run-on)
    s.model_check_iterations = 0;
    s.field_wavelengths = 1;
    s.refine_ladder_wavelengths = 1;
    std::map<std::string, int> full, early;
    const Heightfield a = recover_counting_stages(c, s, &full);
    EXPECT_EQ(full.at("refine:0.6"), 6);
    EXPECT_EQ(full.at("refine"), 3);
    RecoverSettings stop = s;
    stop.refine_ladder_relative_tolerance = 0.999;
    const Heightfield b = recover_counting_stages(c, stop, &early);
    EXPECT_EQ(early.at("refine:0.6"), 1);
    EXPECT_EQ(early.at("refine"), 3);
    EXPECT_NE(a.values(), b.values());
    for (double bad : {-1e-9, 1.0, std::nan("")}) {
        RecoverSettings r = s;
        r.refine_ladder_relative_tolerance = bad;
        EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, r), std::domain_error);
    }
}

// refine_ladder_stall_window / _tolerance stop a ladder rung once its loss fell by less than the
// tolerance (a fraction of its value) over the window, for the outlier repair; where nothing is
// repaired (rounds 0 here) the rung then runs on to its cap without the rule: a tolerance of 1e6
// stops it at the first chance (window + 1 iterations), so the rung reports all its iterations but
// restarts L-BFGS there (other heights); a tolerance of 0 never stops a falling loss (the same bits
// as off). The refinement on every slice still runs its iterations. Out of range: refused.
TEST(RecoverHeights, LadderStallRuleStopsTheRung) {
    const SmallCase c = small_case(25);
    RecoverSettings s = quick_recover_settings();
    s.refine_iterations = 3;
    s.refine_ladder_iterations = 8;
    s.model_check_iterations = 0;
    s.field_wavelengths = 1;
    s.refine_ladder_wavelengths = 1;
    s.outlier_repair_rounds = 0;  // the rung's count alone
    s.refine_ladder_stall_window = 0;          // off (the smooth schedule's is 5)
    s.refine_ladder_relative_tolerance = 0.0;  // off (the smooth schedule's is 1e-8)
    std::map<std::string, int> full, stalled, never;
    const Heightfield a = recover_counting_stages(c, s, &full);
    EXPECT_EQ(full.at("refine:0.6"), 8);
    RecoverSettings stall = s;
    stall.refine_ladder_stall_window = 2;
    stall.refine_ladder_stall_tolerance = 1e6;
    std::vector<int> iterations;
    const Heightfield b = recover_heights(c.observations, 12, 12, 2.0, 1.0, stall, [&](const StageMetrics& m) {
        if (m.stage == "refine:0.6") iterations.push_back(m.iteration);
        ++stalled[m.stage];
        return true;
    });
    EXPECT_EQ(iterations, (std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8}));  // 3 stalled, then 5 more
    EXPECT_EQ(stalled.at("refine"), 3);
    EXPECT_NE(a.values(), b.values());
    stall.refine_ladder_stall_tolerance = 0.0;
    const Heightfield d = recover_counting_stages(c, stall, &never);
    EXPECT_EQ(never, full);
    EXPECT_EQ(d.values(), a.values());
    for (const auto& [window, tolerance] :
         std::vector<std::pair<int, double>>{{-2, 0.01}, {5, -0.1}, {5, std::nan("")}}) {
        RecoverSettings r = s;
        r.refine_ladder_stall_window = window;
        r.refine_ladder_stall_tolerance = tolerance;
        EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, r), std::invalid_argument);
    }
}

// A rung with a stall rule that reaches its cap while its loss still falls by more than the
// rule's tolerance over its window runs on under the rule, up to 4 × its cap in all
// (stage_refine.cpp; sur-2's texel-scale texture left 1.36 % at the smooth schedule's cap of
// 40, experiments/2026-11-30-refinement-budget.md): here a cap of 6 is reached while the loss
// still falls, and the rung goes on to heights closer to the truth than its 6th iteration's.
// Without the rule (window 0) it stops at its cap.
TEST(RecoverHeights, LadderRungStillFallingAtItsCapRunsOn) {
    const SmallCase c = small_case(25);
    RecoverSettings s = quick_recover_settings();
    s.refine_iterations = 3;
    s.refine_ladder_iterations = 6;
    s.model_check_iterations = 0;
    s.field_wavelengths = 1;
    s.refine_ladder_wavelengths = 1;
    s.outlier_repair_rounds = 0;
    s.refine_ladder_relative_tolerance = 0.0;  // the rung's own stop: the stall rule alone
    const auto rung = [&](const RecoverSettings& r) {
        std::vector<double> errors;
        recover_heights(
            c.observations, 12, 12, 2.0, 1.0, r,
            [&](const StageMetrics& m) {
                if (m.stage == "refine:0.6") errors.push_back(m.height_rel_rmse);
                return true;
            },
            &c.truth);
        return errors;
    };
    RecoverSettings capped = s;
    capped.refine_ladder_stall_window = 0;
    const std::vector<double> at_cap = rung(capped);
    ASSERT_EQ(at_cap.size(), 6u);
    s.refine_ladder_stall_window = 5;
    s.refine_ladder_stall_tolerance = 0.01;
    const std::vector<double> on = rung(s);
    EXPECT_GT(on.size(), 6u);
    EXPECT_LE(on.size(), 24u);
    ASSERT_GE(on.size(), 6u);
    for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(on[i], at_cap[i]);  // the same first round
    EXPECT_LT(on.back(), 0.5 * at_cap.back());
    std::printf("rung: %zu iterations, height_rel_rmse %.3g at the cap of 6, %.3g at its end\n", on.size(),
                at_cap.back(), on.back());
}

// No observation is refused; RGB slices alone are taken (white light: white_light_test.cpp),
// where they used to be refused for want of a single-wavelength slice.
TEST(RecoverHeights, RejectsNoObservationsButTakesRgbOnesAlone) {
    Observation o;
    o.query = test::make_query(Model::OHS, 1.0, 1.0, 1.0);
    o.lambdas_um = {0.45, 0.55, 0.65};
    o.resolution = 8;
    o.reference.assign(8 * 8 * 3, 1.0);
    RecoverSettings s;
    s.white_blurred.blur_widths = {4.0};
    s.white_blurred.iterations = 2;
    s.refine_iterations = 2;
    EXPECT_NO_THROW(recover_heights({o}, 4, 4, 1.0, 1.0, s));
    EXPECT_THROW(recover_heights({}, 4, 4, 1.0, 1.0), std::invalid_argument);
}

TEST(HeightRelRmse, IsTheRmsAfterRemovingMeansOverTheRange) {
    const Heightfield truth(1, 4, {0.0, 1.0, 2.0, 3.0}, 0.5, 2.0);     // heights 0, 1, 2, 3 µm
    const Heightfield estimate(1, 4, {5.0, 6.5, 7.0, 7.5}, 1.0, 1.0);  // minus mean: −1.5, 0, 0.5, 1
    // Truth minus its mean: −1.5, −0.5, 0.5, 1.5. Differences 0, 0.5, 0, −0.5 → rms √(0.5/4);
    // range 3.
    EXPECT_NEAR(height_rel_rmse(estimate, truth), std::sqrt(0.5 / 4.0) / 3.0, 1e-15);
    EXPECT_NEAR(height_rel_rmse(truth, truth), 0.0, 1e-15);
    EXPECT_THROW(height_rel_rmse(Heightfield(1, 3, {0, 0, 0}), truth), std::invalid_argument);
    EXPECT_THROW(height_rel_rmse(truth, Heightfield(1, 4, {1, 1, 1, 1})), std::domain_error);
}

}  // namespace
}  // namespace wavebrdf
