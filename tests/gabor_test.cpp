// GaborRepresentation (gabor.h): its inverse transform and rendering from it (brdf.h).
#include "wavebrdf/gabor.h"

#include <gtest/gtest.h>

#include <tuple>

#include "surface/footprint_offsets.h"
#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;

TEST(GaborRepresentationTest, HeightsFromKernelsInvertsTheKernelHeights) {
    const Heightfield hf = test::random_heightfield(12, 10, 0.3, 3, 0.8, 1.7);
    const GaborRepresentation rep(hf, 4.0, 4.0, 1.0);
    ASSERT_GT(rep.kernels.size(), 0u);
    const std::vector<double> values = rep.heights_from_kernels(rep.kernels.height_um,
                                                                std::vector<double>(hf.values().size(), -9.0));
    for (std::size_t k = 0; k < rep.kernels.size(); ++k)
        EXPECT_NEAR(values[hf.index(rep.kernels.row[k], rep.kernels.col[k])],
                    hf.value(rep.kernels.row[k], rep.kernels.col[k]), 1e-12);
    EXPECT_EQ(std::count(values.begin(), values.end(), -9.0),
              static_cast<long>(hf.values().size() - rep.kernels.size()));
    test::expect_throw_naming<std::invalid_argument>(
        [&] { rep.heights_from_kernels({1.0}, std::vector<double>(hf.values().size())); }, "kernel heights have 1");
    const GaborRepresentation flat(hf.with_scale(0.8, 0.0), 4.0, 4.0, 1.0);
    test::expect_throw_naming<std::domain_error>(
        [&] { flat.heights_from_kernels(flat.kernels.height_um, std::vector<double>(hf.values().size())); },
        "vscale = 0");
}

// footprint_offsets lists footprint_kernels' texels and offsets, the same values in the same
// order, for centres inside and across the tile's edges (the periodic images), and throws as it.
TEST(GaborRepresentationTest, FootprintOffsetsAreTheKernelsPositions) {
    const Heightfield hf = test::random_heightfield(12, 10, 0.3, 5, 0.8, 1.7);
    for (const auto& [x, y, sigma] : {std::tuple{4.0, 4.0, 1.0}, std::tuple{0.1, 7.9, 0.7}, std::tuple{-3.3, 25.0, 1.4},
                                      std::tuple{9.5, 0.0, 2.5}}) {
        const FootprintKernels k = footprint_kernels(hf, x, y, sigma);
        const detail::FootprintOffsets o = detail::footprint_offsets(hf, x, y, sigma);
        ASSERT_GT(k.size(), 0u);
        EXPECT_EQ(o.size(), k.size());
        EXPECT_EQ(o.row, k.row);
        EXPECT_EQ(o.col, k.col);
        EXPECT_EQ(o.dx_um, k.dx_um);
        EXPECT_EQ(o.dy_um, k.dy_um);
        EXPECT_EQ(o.sigma_um, k.sigma_um);
    }
    EXPECT_THROW(detail::footprint_offsets(hf, 0.0, 0.0, 0.0), std::domain_error);
}

// Rendering from the representation is render_rgb of the heightfield, for every path the
// options ask for (the Python binding used to ignore RenderOptions::path).
TEST(GaborRepresentationTest, RenderHonoursThePathBitForBit) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.3, 4, 1.0, 1.0);
    const Query q = test::make_query(Model::OHS, 8.0, 6.0, 3.0, 0.1, 0.0);
    const GaborRepresentation rep(hf, q.x_um, q.y_um, q.sigma_p_um);
    for (RenderPath path : {RenderPath::Auto, RenderPath::Separable, RenderPath::Direct}) {
        RenderOptions o;
        o.path = path;
        o.prune_tolerance = 0.0;
        for (const auto& lambdas : {std::vector<double>{0.5}, spectral_wavelengths_um(3)})
            EXPECT_EQ(render_rgb<double>(rep, q, lambdas, 16, o), render_rgb<double>(hf, q, lambdas, 16, o));
    }
    RenderOptions direct;
    direct.path = RenderPath::Direct;
    direct.prune_tolerance = 0.0;
    EXPECT_NE(render_rgb<double>(rep, q, {0.5}, 16, direct), render_rgb<double>(rep, q, {0.5}, 16));
    Query moved = q;
    moved.x_um += 1.0;
    test::expect_throw_naming<std::invalid_argument>([&] { render_rgb<double>(rep, moved, {0.5}, 16); },
                                                     "differs from the GaborRep");
}
