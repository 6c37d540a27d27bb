// The slice plan (slice_plan.h) against the one-call functions it replaces (bit for bit) and
// against the slow direct sum; the spectral mix pair (spectrum.h).
#include "wavebrdf/slice_plan.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/denormals.h"
#include "test_util.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;
using test::make_query;
using test::random_heightfield;
using test::uniform_vector;

namespace {

RenderOptions with_plan_path(RenderPath path) {
    RenderOptions o;
    o.path = path;
    return o;
}

template <typename Float>
std::vector<Float> as(const std::vector<double>& v) {
    return std::vector<Float>(v.begin(), v.end());
}

struct PlanCase {
    Model model;
    RenderPath path;
    std::vector<double> lambdas;
};

std::vector<PlanCase> plan_cases() {
    return {{Model::OHS, RenderPath::Auto, {0.5}},
            {Model::OHS, RenderPath::Auto, spectral_wavelengths_um(4)},
            {Model::ROHS, RenderPath::Separable, {0.45, 0.61}},
            {Model::OHS, RenderPath::Direct, {0.55}},
            {Model::GHS, RenderPath::Auto, {0.5}},
            {Model::Kirchhoff, RenderPath::Auto, spectral_wavelengths_um(3)},
            {Model::OHS, RenderPath::Fft, {0.5, 0.6}},
            {Model::RGHS, RenderPath::Fft, {0.5}},
            {Model::Kirchhoff, RenderPath::Fft, {0.45}}};
}

// The plan, built on `first` and then given `second`'s heights, renders and differentiates
// `second` exactly as render_rgb / render_slice / slice_gradient do.
template <typename Float>
void expect_plan_matches_one_call_functions() {
    const Heightfield first = random_heightfield(20, 18, 0.3, 5, 0.8, 1.0);
    const Heightfield second = random_heightfield(20, 18, 0.3, 6, 0.8, 1.0);
    const int n = 20;
    const std::size_t pixels = static_cast<std::size_t>(n) * n;
    for (const PlanCase& c : plan_cases()) {
        SCOPED_TRACE(std::string(to_string(c.model)) + " lambdas " + std::to_string(c.lambdas.size()));
        const Query q = make_query(c.model, 7.0, 9.5, 4.0, 0.15, -0.1);
        const RenderOptions options = with_plan_path(c.path);
        SlicePlan<Float> plan(first, q, c.lambdas, n, 3, options);
        plan.set_heights(second.values());
        const std::vector<Float> rgb = plan.forward();
        EXPECT_EQ(rgb, render_rgb<Float>(second, q, c.lambdas, n, options));
        // Forward twice gives the same output; the per-wavelength slices are render_slice's.
        EXPECT_EQ(plan.forward(), rgb);
        for (std::size_t l = 0; l < c.lambdas.size(); ++l)
            EXPECT_EQ(plan.slice(l), render_slice<Float>(second, q, c.lambdas[l], n, options));

        // Adjoint: per wavelength through the spectral mix, as the old per-slice gradients.
        const std::vector<double> w = uniform_vector(3 * pixels, -1.0, 1.0, 3);
        std::vector<double> from_plan;
        plan.adjoint(w, from_plan, 0.5);
        const std::vector<double> mix = spectral_mix_weights(c.lambdas);
        std::vector<double> old;
        for (std::size_t l = 0; l < c.lambdas.size(); ++l) {
            std::vector<Float> wl;
            mix_spectral_to_rgb_adjoint<Float>(mix, l, w, wl, 0.5);
            slice_gradient<Float>(second, q, c.lambdas[l], n, wl, old, options);
        }
        EXPECT_EQ(from_plan, old);
    }
}

}  // namespace

// FlushDenormals (core/denormals.h, set by float plans): inside its scope a float product
// below FLT_MIN is 0 and a denormal operand counts as 0; afterwards gradual underflow is back.
TEST(SlicePlanTest, FlushDenormalsScopeFlushesAndRestores) {
    volatile float tiny = 1e-20f, denormal = 1e-40f, one = 1.0f;
    ASSERT_GT(tiny * tiny, 0.0f) << "gradual underflow is off before the scope";
    {
        const wavebrdf::detail::FlushDenormals flush;
#if defined(__SSE2__)
        EXPECT_EQ(tiny * tiny, 0.0f);
        EXPECT_EQ(denormal * one, 0.0f);
#endif
        EXPECT_EQ(tiny * one, 1e-20f);  // normal values are untouched
    }
    EXPECT_GT(tiny * tiny, 0.0f) << "the caller's mode was not put back";
    EXPECT_GT(denormal * one, 0.0f);
}

TEST(SlicePlanTest, MatchesOneCallFunctionsBitForBitDouble) { expect_plan_matches_one_call_functions<double>(); }
TEST(SlicePlanTest, MatchesOneCallFunctionsBitForBitFloat) { expect_plan_matches_one_call_functions<float>(); }

TEST(SlicePlanTest, OneChannelMatchesSliceAdjoint) {
    const Heightfield hf = random_heightfield(24, 24, 0.3, 9, 1.0, 1.0);
    const int n = 24;
    const Query q = make_query(Model::OHS, 12.0, 3.0, 5.0, 0.1, 0.2);
    SlicePlan<double> plan(hf, q, {0.5}, n, 1);
    const SliceAdjoint<double> old(hf, q, 0.5, n);
    EXPECT_EQ(plan.forward(), old.slice());
    const std::vector<double> w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 4);
    std::vector<double> a, b;
    plan.adjoint(w, a);
    old.backward(w, b);
    EXPECT_EQ(a, b);
    // Accumulates: a second adjoint doubles the gradient.
    plan.adjoint(w, a);
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], 2.0 * b[i], 1e-12 * test::max_abs(b));
}

// Both paths of the plan against the slow reference: the direct sum without pruning.
TEST(SlicePlanTest, AgreesWithTheDirectSum) {
    const Heightfield hf = random_heightfield(32, 32, 0.3, 11, 1.0, 1.0);
    const int n = 28;
    for (Model m : {Model::OHS, Model::ROHS, Model::GHS}) {
        SCOPED_TRACE(to_string(m));
        const Query q = make_query(m, 16.0, 16.0, 5.0, 0.2, 0.0);
        SlicePlan<double> plan(hf, q, {0.5}, n, 1);
        const std::vector<double> f = plan.forward();
        const std::vector<double> reference = render_slice_direct<double>(
            footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um), q, 0.5, n, 0.0);
        EXPECT_LT(test::max_abs_diff(f, reference), 1e-9 * test::max_abs(reference));
        const std::vector<double> w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 5);
        std::vector<double> g, g_direct;
        plan.adjoint(w, g);
        slice_gradient<double>(hf, q, 0.5, n, w, g_direct, with_plan_path(RenderPath::Direct));
        if (m != Model::GHS) {
            EXPECT_LT(test::max_abs_diff(g, g_direct), 1e-9 * test::max_abs(g_direct));
        }
    }
}

TEST(SlicePlanTest, MatchesReportsItsArguments) {
    const Heightfield hf = random_heightfield(16, 16, 0.3, 1, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 8.0, 8.0, 4.0);
    const SlicePlan<double> plan(hf, q, {0.5, 0.6}, 16, 3);
    EXPECT_TRUE(plan.matches(hf, q, {0.5, 0.6}, 16, 3, {}));
    EXPECT_FALSE(plan.matches(hf, q, {0.5}, 16, 3, {}));
    EXPECT_FALSE(plan.matches(hf, q, {0.5, 0.6}, 17, 3, {}));
    EXPECT_FALSE(plan.matches(hf.with_scale(2.0, 1.0), q, {0.5, 0.6}, 16, 3, {}));
    Query moved = q;
    moved.x_um = 9.0;
    EXPECT_FALSE(plan.matches(hf, moved, {0.5, 0.6}, 16, 3, {}));
    EXPECT_FALSE(plan.matches(hf, q, {0.5, 0.6}, 16, 3, with_plan_path(RenderPath::Direct)));
    EXPECT_EQ(plan.wavelengths(), 2u);
    EXPECT_EQ(plan.channels(), 3);
    EXPECT_EQ(plan.resolution(), 16);
    EXPECT_EQ(plan.kernels(), footprint_kernels(hf, 8.0, 8.0, 4.0).size());
}

TEST(SlicePlanTest, BadInputThrows) {
    const Heightfield hf = random_heightfield(16, 16, 0.3, 1, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 8.0, 8.0, 4.0);
    test::expect_throw_naming<std::invalid_argument>(
        [&] {
            SlicePlan<double>(hf, q, {0.5, 0.6}, 16, 1);
        },
        "one output channel needs one wavelength");
    test::expect_throw_naming<std::invalid_argument>([&] { SlicePlan<double>(hf, q, {0.5}, 16, 2); }, "channels 2");
    test::expect_throw_naming<std::invalid_argument>([&] { SlicePlan<double>(hf, q, {}, 16, 3); }, "no wavelengths");
    test::expect_throw_naming<std::domain_error>([&] { SlicePlan<double>(hf, q, {0.5}, 0, 3); }, "resolution 0");
    // Every model has the separable and fft paths (c3_nodes_test).
    EXPECT_NO_THROW(
        SlicePlan<double>(hf, make_query(Model::GHS, 8, 8, 4), {0.5}, 16, 3, with_plan_path(RenderPath::Separable)));
    EXPECT_NO_THROW(SlicePlan<double>(hf, make_query(Model::GHS, 8, 8, 4), {0.5}, 16, 3, with_plan_path(RenderPath::Fft)));
    SlicePlan<double> plan(hf, q, {0.5}, 16, 3);
    std::vector<double> g;
    test::expect_throw_naming<std::logic_error>([&] { plan.adjoint(std::vector<double>(16 * 16 * 3), g); },
                                                "forward() first");
    test::expect_throw_naming<std::invalid_argument>([&] { plan.set_heights(std::vector<double>(3)); },
                                                     "heights have 3 values");
    std::vector<double> bad = hf.values();
    bad[7] = std::nan("");
    test::expect_throw_naming<std::domain_error>([&] { plan.set_heights(bad); }, "height value 7");
    test::expect_throw_naming<std::invalid_argument>([&] { plan.set_heights(hf.with_scale(2.0, 1.0)); }, "geometry");
    plan.forward();
    test::expect_throw_naming<std::invalid_argument>([&] { plan.adjoint(std::vector<double>(5), g); },
                                                     "weights have 5 entries");
    std::vector<double> wrong(7);
    test::expect_throw_naming<std::invalid_argument>([&] { plan.adjoint(std::vector<double>(16 * 16 * 3), wrong); },
                                                     "gradient has 7 entries");
    plan.release();
    test::expect_throw_naming<std::logic_error>([&] { plan.slice(0); }, "forward() first");
    SlicePlan<double> forward_only(hf, q, {0.5}, 16, 3, {}, false);
    forward_only.forward();
    test::expect_throw_naming<std::logic_error>([&] { forward_only.slice(0); }, "differentiable");
}

// The mix pair is a forward / adjoint pair: Σ W · mix(f) = Σ_l adjoint_l(W) · f_l.
// A plan reads only its footprint's texels and their neighbours: a NaN elsewhere is not
// checked (set_heights costs the footprint, not rows·cols) and cannot change the slice or the
// gradient; a NaN the footprint reads is refused. Plans released between cycles (their phase
// tables dropped, the per-pixel factors shared with a second plan) give the same bits as a
// plan that never released.
TEST(SlicePlanTest, ReadsOnlyItsFootprintAndReleasesWithoutChangingResults) {
    const Heightfield hf = random_heightfield(32, 32, 0.3, 21, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 8.0, 8.0, 1.0);  // kernels within 3 texels of (8, 8)
    SlicePlan<float> kept(hf, q, {0.5}, 24, 1), released(hf, q, {0.5}, 24, 1);
    const SlicePlan<float> other(hf, make_query(Model::OHS, 20.0, 20.0, 1.0), {0.5}, 24, 1);
    std::vector<double> far = hf.values();
    far[std::size_t(25) * 32 + 25] = std::nan("");
    for (int cycle = 0; cycle < 2; ++cycle) {
        kept.set_heights(hf.values());
        released.set_heights(far);
        const std::vector<float> a = kept.forward();
        const std::vector<float> b = released.forward();
        EXPECT_EQ(a, b);
        std::vector<double> weights(a.size());
        for (std::size_t p = 0; p < a.size(); ++p) weights[p] = std::cos(0.11 * double(p));
        std::vector<double> ga, gb;
        kept.adjoint(weights, ga);
        released.adjoint(weights, gb);
        EXPECT_EQ(ga, gb);
        released.release();
        EXPECT_TRUE(std::isnan(far[std::size_t(25) * 32 + 25]));
    }
    std::vector<double> near = hf.values();
    near[std::size_t(9) * 32 + 8] = std::nan("");
    test::expect_throw_naming<std::domain_error>([&] { released.set_heights(near); },
                                                 "height value " + std::to_string(9 * 32 + 8));
}

TEST(SpectralMixTest, AdjointIsTheTransposeOfTheMix) {
    const std::vector<double> lambdas = spectral_wavelengths_um(5);
    const std::vector<double> mix = spectral_mix_weights(lambdas);
    ASSERT_EQ(mix, spectral_to_srgb_weights(lambdas));
    const std::size_t pixels = 30;
    std::vector<double> rgb(3 * pixels, 0.0);
    std::vector<std::vector<double>> slices;
    for (std::size_t l = 0; l < lambdas.size(); ++l) {
        slices.push_back(uniform_vector(pixels, 0.0, 2.0, 20 + l));
        mix_spectral_to_rgb<double>(mix, l, slices.back(), rgb);
    }
    const std::vector<double> w = uniform_vector(3 * pixels, -1.0, 1.0, 7);
    double lhs = 0.0, rhs = 0.0;
    for (std::size_t i = 0; i < rgb.size(); ++i) lhs += w[i] * rgb[i];
    for (std::size_t l = 0; l < lambdas.size(); ++l) {
        std::vector<double> wl;
        mix_spectral_to_rgb_adjoint<double>(mix, l, w, wl, 2.0);
        for (std::size_t p = 0; p < pixels; ++p) rhs += wl[p] * slices[l][p];
    }
    EXPECT_NEAR(rhs, 2.0 * lhs, 1e-12 * std::abs(lhs));
}

TEST(SpectralMixTest, OneWavelengthIsGreyAndSizesAreChecked) {
    EXPECT_EQ(spectral_mix_weights({0.5}), (std::vector<double>{1.0, 1.0, 1.0}));
    const std::vector<float> slice{1.0f, 2.0f};
    std::vector<float> rgb(6, 0.0f);
    mix_spectral_to_rgb<float>({1.0, 1.0, 1.0}, 0, slice, rgb);
    EXPECT_EQ(rgb, (std::vector<float>{1, 1, 1, 2, 2, 2}));
    std::vector<float> short_rgb(5);
    test::expect_throw_naming<std::invalid_argument>(
        [&] {
            mix_spectral_to_rgb<float>({1.0, 1.0, 1.0}, 0, slice, short_rgb);
        },
        "RGB values have 5");
    test::expect_throw_naming<std::invalid_argument>(
        [&] {
            mix_spectral_to_rgb<float>({1.0, 1.0, 1.0}, 1, slice, rgb);
        },
        "wavelength index 1");
}
