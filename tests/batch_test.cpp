// Batches (batch.h): every item equals the single call it stands for (render_rgb,
// render_slice, the SlicePlan adjoint), in both precisions and for separable and direct models;
// the batch gradient against finite differences; empty, bad and hostile batches.
#include "wavebrdf/batch.h"

#include <gtest/gtest.h>
#include <omp.h>

#include "test_util.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;
using test::expect_throw_naming;
using test::make_query;
using test::max_abs;
using test::random_heightfield;
using test::uniform_vector;

namespace {

struct Case {
    Model model;
    RenderPath path;
};

std::vector<Case> cases() {
    return {{Model::OHS, RenderPath::Auto}, {Model::ROHS, RenderPath::Separable}, {Model::OHS, RenderPath::Direct},
            {Model::GHS, RenderPath::Auto}, {Model::Kirchhoff, RenderPath::Auto}, {Model::GHS, RenderPath::Fft}};
}

RenderOptions with_batch_path(RenderPath path) {
    RenderOptions o;
    o.path = path;
    return o;
}

const std::size_t k_values = 16 * 16 * 3;  // one item's values at n = 16, RGB

std::vector<double> item_values(const std::vector<double>& all, std::size_t b, std::size_t values) {
    return std::vector<double>(all.begin() + static_cast<std::ptrdiff_t>(b * values),
                               all.begin() + static_cast<std::ptrdiff_t>((b + 1) * values));
}

double max_abs_difference(const std::vector<double>& a, const std::vector<double>& b) {
    EXPECT_EQ(a.size(), b.size());
    double m = 0.0;
    for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
    return m;
}

// The product lights × positions × bands renders every item as render_rgb does, in order.
template <typename Float>
void expect_product_equals_single_calls() {
    const Heightfield hf = random_heightfield(20, 18, 0.3, 5, 0.8, 1.0);
    const int n = 16;
    const std::vector<std::array<double, 2>> lights{{0.0, 0.0}, {0.3, -0.2}};
    const std::vector<std::array<double, 2>> positions{{7.0, 9.5}, {3.0, 1.0}};
    const std::vector<std::vector<double>> bands{{0.5}, spectral_wavelengths_um(3)};
    for (const Case& c : cases()) {
        SCOPED_TRACE(to_string(c.model));
        const Query base = make_query(c.model, 0.0, 0.0, 4.0);
        const RenderOptions options = with_batch_path(c.path);
        const SliceBatch batch = batch_product(base, lights, positions, bands, n);
        ASSERT_EQ(batch.items.size(), 8u);
        const std::vector<Float> out = render_batch<Float>(hf, batch, options);
        ASSERT_EQ(out.size(), 8 * k_values);
        for (std::size_t l = 0; l < 2; ++l)
            for (std::size_t p = 0; p < 2; ++p)
                for (std::size_t w = 0; w < 2; ++w) {
                    const std::size_t b = (l * 2 + p) * 2 + w;
                    Query q = base;
                    q.omega_i = lights[l];
                    q.x_um = positions[p][0];
                    q.y_um = positions[p][1];
                    const std::vector<Float> single = render_rgb<Float>(hf, q, bands[w], n, options);
                    const std::vector<Float> item(out.begin() + static_cast<std::ptrdiff_t>(b * k_values),
                                                  out.begin() + static_cast<std::ptrdiff_t>((b + 1) * k_values));
                    EXPECT_EQ(item, single) << "item " << b;
                }
    }
}

// The summed gradient of a batch on one heightfield equals the sum of the items' SlicePlan
// adjoints, and the per-item slices equal render_batch's.
template <typename Float>
void expect_gradient_equals_single_calls(double tolerance) {
    const Heightfield hf = random_heightfield(20, 18, 0.3, 7, 0.8, 1.0);
    const int n = 16;
    for (const Case& c : cases()) {
        SCOPED_TRACE(to_string(c.model));
        const RenderOptions options = with_batch_path(c.path);
        const SliceBatch batch = batch_product(make_query(c.model, 0.0, 0.0, 4.0), {{0.0, 0.0}, {0.2, 0.25}},
                                               {{7.0, 9.5}, {12.0, 2.0}}, {{0.5}, {0.45, 0.6}}, n);
        const std::vector<double> weights = uniform_vector(batch.items.size() * k_values, -1.0, 1.0, 11);
        std::vector<double> gradient;
        std::vector<Float> slices;
        batch_gradient<Float>(hf, batch, weights, gradient, options, &slices);
        EXPECT_EQ(slices, render_batch<Float>(hf, batch, options));
        std::vector<double> expected;
        for (std::size_t b = 0; b < batch.items.size(); ++b) {
            const BatchItem& item = batch.items[b];
            SlicePlan<Float> plan(hf, item.query, batch.bands[item.band], n, 3, options);
            plan.forward();
            plan.adjoint(item_values(weights, b, k_values), expected);
        }
        EXPECT_LE(max_abs_difference(gradient, expected), tolerance * max_abs(expected));
    }
}

}  // namespace

TEST(BatchTest, ProductEqualsSingleCallsDouble) { expect_product_equals_single_calls<double>(); }
TEST(BatchTest, ProductEqualsSingleCallsFloat) { expect_product_equals_single_calls<float>(); }
TEST(BatchTest, GradientEqualsSingleCallsDouble) { expect_gradient_equals_single_calls<double>(1e-12); }
TEST(BatchTest, GradientEqualsSingleCallsFloat) { expect_gradient_equals_single_calls<float>(1e-5); }

TEST(BatchTest, OneChannelEqualsRenderSlice) {
    const Heightfield hf = random_heightfield(16, 16, 0.3, 3);
    const Query base = make_query(Model::GHS, 0.0, 0.0, 3.0);
    const SliceBatch batch = batch_product(base, {{0.1, 0.0}}, {{4.0, 5.0}}, {{0.5}, {0.7}}, 12, 1);
    const std::vector<double> out = render_batch<double>(hf, batch);
    ASSERT_EQ(out.size(), 2u * 144u);
    for (std::size_t w = 0; w < 2; ++w) {
        Query q = base;
        q.omega_i = {0.1, 0.0};
        q.x_um = 4.0;
        q.y_um = 5.0;
        EXPECT_EQ(item_values(out, w, 144), render_slice<double>(hf, q, batch.bands[w][0], 12));
    }
}

// A batch of heightfields of one shape (Python's leading axes): each item reads its own, the
// plan is reused across them, and each gets its own gradient.
TEST(BatchTest, BatchOfHeightfieldsGetsOneGradientEach) {
    std::vector<Heightfield> hfs;
    for (std::uint64_t s = 0; s < 5; ++s) hfs.push_back(random_heightfield(18, 18, 0.3, 20 + s, 0.9, 1.0));
    const int n = 16;
    for (const Case& c : cases()) {
        SCOPED_TRACE(to_string(c.model));
        const RenderOptions options = with_batch_path(c.path);
        const Query q = make_query(c.model, 6.0, 8.0, 4.0, 0.1, 0.2);
        const std::vector<double> lambdas = spectral_wavelengths_um(2);
        const SliceBatch batch = batch_per_heightfield(q, lambdas, n, hfs.size());
        const std::vector<double> out = render_batch<double>(hfs, batch, options);
        const std::vector<double> weights = uniform_vector(hfs.size() * k_values, -1.0, 1.0, 3);
        std::vector<std::vector<double>> gradients;
        batch_gradient<double>(hfs, batch, weights, gradients, options);
        ASSERT_EQ(gradients.size(), hfs.size());
        for (std::size_t b = 0; b < hfs.size(); ++b) {
            EXPECT_EQ(item_values(out, b, k_values), render_rgb<double>(hfs[b], q, lambdas, n, options));
            SlicePlan<double> plan(hfs[b], q, lambdas, n, 3, options);
            plan.forward();
            std::vector<double> expected;
            plan.adjoint(item_values(weights, b, k_values), expected);
            EXPECT_LE(max_abs_difference(gradients[b], expected), 1e-12 * max_abs(expected)) << "heightfield " << b;
        }
        // Gradients accumulate (adjoint.h's rule): a second call doubles them.
        std::vector<std::vector<double>> twice = gradients;
        batch_gradient<double>(hfs, batch, weights, twice, options);
        for (std::size_t b = 0; b < hfs.size(); ++b)
            for (std::size_t c2 = 0; c2 < twice[b].size(); ++c2)
                EXPECT_NEAR(twice[b][c2], 2.0 * gradients[b][c2], 1e-12 * max_abs(gradients[b]));
    }
}

// L(h) = Σ W · slices(h) by central differences, for a separable and a direct model.
TEST(BatchTest, GradientMatchesFiniteDifferences) {
    const Heightfield hf = random_heightfield(14, 14, 0.2, 9, 1.0, 1.0);
    const int n = 12;
    for (const Model model : {Model::OHS, Model::Kirchhoff}) {
        SCOPED_TRACE(to_string(model));
        const SliceBatch batch = batch_product(make_query(model, 0.0, 0.0, 3.0), {{0.0, 0.0}, {0.3, 0.1}},
                                               {{5.0, 6.0}, {9.0, 2.0}}, {{0.5}, {0.45, 0.62}}, n);
        const std::vector<double> weights = uniform_vector(batch.items.size() * n * n * 3, 0.0, 1.0, 4);
        std::vector<double> gradient;
        batch_gradient<double>(hf, batch, weights, gradient);
        const auto loss = [&](const std::vector<double>& values) {
            const std::vector<double> out = render_batch<double>(Heightfield(14, 14, values, 1.0, 1.0), batch);
            double sum = 0.0;
            for (std::size_t i = 0; i < out.size(); ++i) sum += weights[i] * out[i];
            return sum;
        };
        const double eps = 1e-5;
        for (const std::size_t cell : {std::size_t(0), std::size_t(31), std::size_t(77), std::size_t(150)}) {
            std::vector<double> plus = hf.values(), minus = hf.values();
            plus[cell] += eps;
            minus[cell] -= eps;
            const double fd = (loss(plus) - loss(minus)) / (2.0 * eps);
            EXPECT_NEAR(gradient[cell], fd, 1e-5 * std::max(1.0, max_abs(gradient))) << "cell " << cell;
        }
    }
}

TEST(BatchTest, EmptyBatchRendersNothing) {
    const Heightfield hf = random_heightfield(8, 8, 0.3, 1);
    const SliceBatch batch = batch_product(make_query(Model::OHS, 0, 0, 2.0), {}, {{1.0, 1.0}}, {{0.5}}, 16);
    EXPECT_TRUE(batch.items.empty());
    EXPECT_TRUE(render_batch<float>(hf, batch).empty());
    std::vector<double> gradient;
    std::vector<float> slices{1.0f};
    batch_gradient<float>(hf, batch, {}, gradient, {}, &slices);
    EXPECT_EQ(gradient, std::vector<double>(64, 0.0));
    EXPECT_TRUE(slices.empty());
}

// Called inside a parallel region (a caller's own threads), a batch runs on that thread.
TEST(BatchTest, InsideAParallelRegionEachThreadRendersItsOwnBatch) {
    const Heightfield hf = random_heightfield(16, 16, 0.3, 2);
    const SliceBatch batch = batch_product(make_query(Model::OHS, 0, 0, 3.0), {{0.0, 0.0}, {0.2, 0.1}, {-0.3, 0.0}},
                                           {{4.0, 4.0}}, {{0.5}}, 16);
    const std::vector<double> expected = render_batch<double>(hf, batch);
    std::vector<std::vector<double>> got(4);
#pragma omp parallel for num_threads(2)
    for (int t = 0; t < 4; ++t) got[static_cast<std::size_t>(t)] = render_batch<double>(hf, batch);
    for (const auto& g : got) EXPECT_EQ(g, expected);
}

TEST(BatchTest, BadBatchesAreRefusedNamingTheValue) {
    const Heightfield hf = random_heightfield(8, 8, 0.3, 1);
    const Query q = make_query(Model::OHS, 0, 0, 2.0);
    SliceBatch batch = batch_product(q, {{0.0, 0.0}, {0.2, 0.0}}, {{1.0, 1.0}}, {{0.5}}, 16);
    SliceBatch bad = batch;
    bad.items[1].band = 3;
    expect_throw_naming<std::invalid_argument>([&] { render_batch<float>(hf, bad); }, "batch item 1 has band 3");
    bad = batch;
    bad.items[1].heightfield = 1;
    expect_throw_naming<std::invalid_argument>([&] { render_batch<float>(hf, bad); }, "reads heightfield 1");
    bad = batch;
    bad.items[1].query.omega_i = {1.0, 0.5};
    expect_throw_naming<std::domain_error>([&] { render_batch<float>(hf, bad); }, "batch item 1");
    bad = batch;
    bad.channels = 1;
    bad.bands = {{0.5, 0.6}};
    expect_throw_naming<std::invalid_argument>([&] { render_batch<float>(hf, bad); }, "one output channel");
    bad = batch;
    bad.bands = {{}};
    expect_throw_naming<std::invalid_argument>([&] { render_batch<float>(hf, bad); }, "batch band 0 has 0");
    bad = batch;
    bad.resolution = 0;
    EXPECT_THROW(render_batch<float>(hf, bad), std::domain_error);
    // Heightfields of different shapes, and weights of the wrong size.
    const std::vector<Heightfield> mixed{hf, random_heightfield(8, 9, 0.3, 2)};
    expect_throw_naming<std::invalid_argument>(
        [&] { render_batch<float>(mixed, batch_per_heightfield(q, {0.5}, 8, 2)); }, "heightfield 1 is 8x9");
    EXPECT_THROW(render_batch<float>(std::vector<Heightfield>{}, batch), std::invalid_argument);
    std::vector<double> gradient;
    expect_throw_naming<std::invalid_argument>(
        [&] { batch_gradient<float>(hf, batch, std::vector<double>(10, 0.0), gradient); }, "batch weights have 10");
    std::vector<double> wrong(5, 0.0);
    EXPECT_THROW(batch_gradient<float>(hf, batch, std::vector<double>(2 * 16 * 16 * 3, 0.0), wrong),
                 std::invalid_argument);
}

// B · n² · channels far beyond the limit: refused by the estimate before anything is allocated.
TEST(BatchTest, HostileSizesAreRefusedBeforeAllocating) {
    const Heightfield hf = random_heightfield(8, 8, 0.3, 1);
    SliceBatch batch = batch_product(make_query(Model::OHS, 0, 0, 2.0), {{0.0, 0.0}}, {{1.0, 1.0}}, {{0.5}}, 8192);
    batch.items.resize(100000, batch.items[0]);  // 100000 × 8192² × 3 floats: 8e13 bytes
    RenderOptions options;
    options.max_memory_gb = 1.0;
    expect_throw_naming<OutOfMemory>([&] { render_batch<float>(hf, batch, options); }, "batch render (100000 slices");
    std::vector<double> gradient;
    expect_throw_naming<OutOfMemory>([&] { batch_gradient<float>(hf, batch, {}, gradient, options); },
                                     "batch gradient");
    // The physical memory is the default limit.
    expect_throw_naming<OutOfMemory>([&] { render_batch<double>(hf, batch); }, "needs about");
    EXPECT_GT(estimate_batch_bytes(hf, batch, 1, {}, 4, false, 2), 8e13);
}
