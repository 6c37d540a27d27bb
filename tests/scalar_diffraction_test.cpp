// The scalar-diffraction simulator (scalar_diffraction.h) against the Gabor model where the
// model is exact (planes), close to it for a gentle surface, Parseval, grid convergence.
#include "wavebrdf/scalar_diffraction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recovery_run.h"

using namespace wavebrdf;

namespace {

std::string sci(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3g", v);
    return text;
}

double relative_l2(const std::vector<double>& a, const std::vector<double>& b) {
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        num += (a[i] - b[i]) * (a[i] - b[i]);
        den += b[i] * b[i];
    }
    return std::sqrt(num / den);
}

Heightfield plane(int n, double texel_um, double sx, double sy) {
    std::vector<double> h(static_cast<std::size_t>(n) * n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) h[static_cast<std::size_t>(i) * n + j] = sx * i + sy * j;
    return Heightfield(n, n, h, texel_um);
}

Query centre_query(const Heightfield& hf, double sigma_p_um, std::array<double, 2> omega_i = {0.0, 0.0}) {
    Query q;
    q.x_um = hf.period_x_um() / 2 + 0.3;
    q.y_um = hf.period_y_um() / 2 - 0.7;
    q.sigma_p_um = sigma_p_um;
    q.omega_i = omega_i;
    return q;
}

}  // namespace

// A flat surface: the Gabor model is exact (one tangent plane), both give the same lobe.
TEST(ScalarDiffraction, FlatSurfaceEqualsTheGaborModel) {
    const Heightfield flat(24, 24, std::vector<double>(24 * 24, 0.3), 2.0);
    for (const std::array<double, 2> omega_i : {std::array<double, 2>{0.0, 0.0}, {0.2, -0.1}}) {
        for (Model model : {Model::OHS, Model::ROHS}) {
            Query q = centre_query(flat, 3.0, omega_i);
            q.model = model;
            const std::vector<double> gabor = render_slice<double>(flat, q, 0.5, 32);
            const std::vector<double> scalar = scalar_slice(flat, q, 0.5, 32);
            const double d = relative_l2(scalar, gabor);
            RecordProperty(std::string("flat_") + to_string(model) + (omega_i[0] != 0.0 ? "_oblique" : ""), sci(d));
            EXPECT_LT(d, 1e-6) << to_string(model) << " ω_i " << omega_i[0];
        }
    }
}

// A tilted plane (away from the seam): every kernel's tangent plane is the plane, so the Gabor
// model is exact again; the interpolant reproduces the plane (Keys is exact for degree ≤ 2).
TEST(ScalarDiffraction, TiltedPlaneEqualsTheGaborModel) {
    const Heightfield tilted = plane(32, 2.0, 0.05, -0.03);
    for (const std::array<double, 2> omega_i : {std::array<double, 2>{0.0, 0.0}, {-0.15, 0.25}}) {
        const Query q = centre_query(tilted, 3.0, omega_i);
        const std::vector<double> gabor = render_slice<double>(tilted, q, 0.6, 40);
        const std::vector<double> scalar = scalar_slice(tilted, q, 0.6, 40);
        const double d = relative_l2(scalar, gabor);
        RecordProperty(omega_i[0] != 0.0 ? "tilted_oblique" : "tilted", sci(d));
        EXPECT_LT(d, 1e-6) << "ω_i " << omega_i[0];
    }
}

// A gentle surface (heights ±0.025 µm, correlation 8 texels of 2 µm): the tangent-plane
// expansion is nearly exact. Measured distance 4.2e-3 (seed 5201; bound 1e-2); not zero, so the
// simulator does compute something else than the model.
TEST(ScalarDiffraction, GentleSurfaceIsCloseToTheGaborModel) {
    RecoveryOptions options;
    options.rows = options.cols = 24;
    options.height_range_um = 0.05;
    options.correlation_texels = 8.0;
    options.seed = 5201;
    const Heightfield gentle = generated_recovery_truth(options);
    const Query q = centre_query(gentle, 3.0);
    const std::vector<double> gabor = render_slice<double>(gentle, q, 0.5, 32);
    const std::vector<double> scalar = scalar_slice(gentle, q, 0.5, 32);
    const double d = relative_l2(scalar, gabor);
    RecordProperty("gentle", sci(d));
    EXPECT_LT(d, 1e-2);
    EXPECT_GT(d, 1e-6);
}

// Parseval: Σ |I|² Δu² over a slice that holds the whole spectrum, finely enough sampled
// (Δu ≤ 1/(2 · support)), equals ∫|W|² (closed form), whatever the heights.
TEST(ScalarDiffraction, ParsevalEnergyEqualsTheWindowsEnergy) {
    RecoveryOptions options;
    options.rows = options.cols = 12;
    options.texel_um = 1.0;
    options.height_range_um = 0.3;
    options.correlation_texels = 3.0;
    options.seed = 5202;
    const Heightfield rough = generated_recovery_truth(options);
    const double lambda = 0.5;
    const int n = 128;
    const double du = 2.0 / (n * lambda);
    for (ScalarWindow window : {ScalarWindow::Gabor, ScalarWindow::Gaussian}) {
        ScalarDiffractionSettings settings;
        settings.window = window;
        settings.tolerance = 1e-6;
        const Query q = centre_query(rough, 0.8);
        const std::vector<std::complex<double>> field = scalar_field(rough, q, lambda, n, settings);
        double energy = 0.0;
        for (const auto& v : field) energy += std::norm(v) * du * du;
        const double expected = scalar_window_energy(rough, q, window);
        RecordProperty(window == ScalarWindow::Gabor ? "parseval_gabor" : "parseval_gaussian",
                       sci(energy / expected - 1.0));
        EXPECT_NEAR(energy / expected, 1.0, 1e-5) << (window == ScalarWindow::Gabor ? "gabor" : "gaussian");
    }
    EXPECT_DOUBLE_EQ(scalar_window_energy(rough, centre_query(rough, 0.8), ScalarWindow::Gaussian), 1.0);
}

// Grid convergence: the converged slice changes by less than the tolerance when the fine
// spacing is halved once more.
TEST(ScalarDiffraction, HalvingTheSpacingChangesLessThanTheTolerance) {
    RecoveryOptions options;
    options.rows = options.cols = 16;
    options.height_range_um = 2.0;  // the recovery's default truth: ±1 µm, correlation 4 texels
    options.seed = 5203;
    const Heightfield truth = generated_recovery_truth(options);
    const Query q = centre_query(truth, 3.0, {0.1, 0.05});
    ScalarDiffractionSettings settings;
    settings.tolerance = 1e-4;
    ScalarDiffractionInfo info;
    const std::vector<double> converged = scalar_slice(truth, q, 0.5, 32, settings, &info);
    EXPECT_LE(info.relative_change, settings.tolerance);
    EXPECT_GE(info.samples_per_texel, 4);
    ScalarDiffractionSettings fixed = settings;
    fixed.tolerance = 0.0;
    fixed.min_samples_per_texel = 2 * info.samples_per_texel;
    const std::vector<double> finer = scalar_slice(truth, q, 0.5, 32, fixed);
    RecordProperty("m", info.samples_per_texel);
    RecordProperty("change_halved", sci(relative_l2(converged, finer)));
    EXPECT_LT(relative_l2(converged, finer), settings.tolerance);
    // And the coarsest grid is visibly wrong (the check has teeth).
    fixed.min_samples_per_texel = 1;
    EXPECT_GT(relative_l2(scalar_slice(truth, q, 0.5, 32, fixed), finer), 10 * settings.tolerance);
}

TEST(ScalarDiffraction, RefusesBadArguments) {
    const Heightfield flat(8, 8, std::vector<double>(64, 0.0), 1.0);
    Query q = centre_query(flat, 1.0);
    q.model = Model::GHS;
    EXPECT_THROW(scalar_slice(flat, q, 0.5, 16), std::invalid_argument);
    q.model = Model::OHS;
    ScalarDiffractionSettings s;
    s.tolerance = 0.5;
    EXPECT_THROW(scalar_slice(flat, q, 0.5, 16, s), std::domain_error);
    s = {};
    s.max_grid_side = 10;
    EXPECT_THROW(scalar_slice(flat, q, 0.5, 16, s), std::bad_alloc);
    EXPECT_THROW(scalar_slice(flat, q, -1.0, 16), std::domain_error);
    EXPECT_THROW(parse_simulator("exact"), std::invalid_argument);
    EXPECT_EQ(parse_simulator("scalar"), Simulator::Scalar);
}

// Simulated observations: the same noise draws per index as simulate_observations, slices
// from scalar_slice.
TEST(ScalarDiffraction, SimulatedObservationsAreScalarSlicesWithTheSameNoise) {
    PlanRequest request;
    request.rows = request.cols = 12;
    request.texel_um = 2.0;
    request.height_range_um = 0.4;
    request.resolution = 16;
    request.lambdas_um = {0.5};
    const AcquisitionPlan plan = plan_acquisition(request);
    const Heightfield flat(12, 12, std::vector<double>(144, 0.0), 2.0);
    const std::vector<std::size_t> indices{0, 2};
    Noise noise;
    noise.kind = NoiseKind::Gaussian;
    noise.level = 0.01;
    const std::vector<Observation> scalar = simulate_scalar_observations(flat, plan, noise, 7, indices);
    const std::vector<Observation> gabor = simulate_observations(flat, plan, noise, 7, indices);
    ASSERT_EQ(scalar.size(), 2u);
    for (std::size_t k = 0; k < 2; ++k)
        EXPECT_LT(relative_l2(to_doubles(scalar[k].reference), to_doubles(gabor[k].reference)), 1e-6);
    EXPECT_THROW(simulate_scalar_observations(flat, plan, noise, 7, {99}), std::invalid_argument);
    // A share of one observation (an MPI rank's) gets the same bits as in a larger share.
    RecoveryOptions options;
    options.rows = options.cols = 12;
    options.height_range_um = 0.4;
    options.seed = 5206;
    const Heightfield rough = generated_recovery_truth(options);
    const std::vector<Observation> all = simulate_scalar_observations(rough, plan, noise, 7, {0, 1, 2});
    const std::vector<Observation> one = simulate_scalar_observations(rough, plan, noise, 7, {2});
    EXPECT_EQ(one[0].reference, all[2].reference);
}
