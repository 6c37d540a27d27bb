// The field stage on overlapping tiles (src/recovery/field_tiles.h).
#include "recovery/field_tiles.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <random>

#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;
using Complex = std::complex<double>;

namespace {}  // namespace

// Tiles retrieved on their own (observations moved to the tile's origin, the start cut to
// it), phase-aligned on the overlaps and blended, give the whole surface's object up to ONE
// global phase: a wrong shift, cut, weight or alignment leaves a tile off (the start is 0.6
// rad rms away, 120 iterations; each tile's retrieval returns its object up to a phase of its own).
TEST(FieldTiles, BlendOfTilesIsTheObjectUpToOneGlobalPhase) {
    const int rows = 28, cols = 28;
    const double texel = 1.0, lambda = 0.5;
    const Heightfield hf = test::random_heightfield(rows, cols, 0.03, 5, texel);
    const std::vector<Complex> truth = test::object_of(hf, lambda);
    const auto observations = test::model_observations(truth, rows, cols, texel, lambda, 48, 1.0, 2.0, 6501);
    std::vector<const Observation*> pointers;
    for (const Observation& o : observations) pointers.push_back(&o);
    std::mt19937_64 rng(6502);
    std::normal_distribution<double> noise(0.0, 0.6);
    std::vector<Complex> start(truth.size());
    for (std::size_t k = 0; k < truth.size(); ++k) start[k] = truth[k] * std::polar(1.0, noise(rng));
    ASSERT_GT(test::distance_up_to_phase(truth, start), 0.4);
    FieldRetrievalSettings s;
    s.iterations = 120;
    s.stall_window = 0;
    const detail::FieldTiling tiling{16, 14, 2};  // 2 × 2 tiles of 14 + 2·(4 + 2) texels
    ASSERT_TRUE(detail::field_tiles_apply(rows, cols, tiling));
    int calls = 0;
    const FieldRetrievalResult r = detail::retrieve_field_tiled(
        pointers, lambda, rows, cols, texel, start, s, tiling,
        [&](int, double) {
            ++calls;
            return true;
        },
        serial_communicator());
    ASSERT_EQ(r.object.size(), truth.size());
    EXPECT_GT(calls, 0);
    // 40× closer than the start (a tile shifted by a sample, or left at its own phase, is > 0.1
    // away; the tiles' edges converge more slowly than their cores).
    const double distance = test::distance_up_to_phase(truth, r.object);
    std::printf("tiles: loss %.3g, distance %.3g (start %.3g)\n", r.relative_loss, distance,
                test::distance_up_to_phase(truth, start));
    EXPECT_LT(r.relative_loss, 1e-4);
    EXPECT_LT(distance, 1e-2);
}

// Tiles that each come back with a phase offset AND a tilt of their own (the ambiguity and the
// slow direction of a tile's retrieval) blend to the object up to ONE global phase when the
// phases and tilts are fitted on all overlaps at once: on 3 × 3 tiles (rings along both axes)
// and on 4 tiles in a row (cut along x only; tilts only along x). The first version's raster
// alignment (one phase per tile, tile after tile) leaves the tilts in and fails the bound.
TEST(FieldTiles, JointAlignmentRemovesPerTilePhaseAndTilt) {
    struct Case {
        int rows, cols;
        detail::FieldTiling tiling;
    };
    for (const Case& k : {Case{36, 36, {16, 12, 2}}, Case{48, 16, {16, 12, 2}}}) {
        const int q = 2, reach = 4;
        const detail::FieldTileLayout layout = detail::field_tile_layout(k.rows, k.cols, q, reach, k.tiling);
        const std::size_t nx = layout.origin_x.size(), ny = layout.origin_y.size();
        ASSERT_EQ(nx, k.rows == 36 ? 3u : 4u);
        ASSERT_EQ(ny, k.rows == 36 ? 3u : 1u);
        // A smooth object on the fine grid (phase up to a few radians).
        const Heightfield hf = test::random_heightfield(k.rows * q, k.cols * q, 0.15, 6, 1.0);
        const std::vector<Complex> truth = test::object_of(hf, 0.5);
        const std::size_t fine_cols = std::size_t(k.cols) * q, fine_rows = std::size_t(k.rows) * q;
        std::mt19937_64 rng(6503);
        std::uniform_real_distribution<double> offset(0.0, 2.0 * k_pi);
        std::normal_distribution<double> tilt(0.0, 0.04);  // rad per texel
        std::vector<std::vector<Complex>> objects(nx * ny);
        for (std::size_t kx = 0; kx < nx; ++kx)
            for (std::size_t ky = 0; ky < ny; ++ky) {
                const int ex = layout.extent_x[kx], ey = layout.extent_y[ky];
                const double a = offset(rng), b = layout.cut_x ? tilt(rng) : 0.0, c = layout.cut_y ? tilt(rng) : 0.0;
                std::vector<Complex>& o = objects[kx * ny + ky];
                o.resize(std::size_t(ex) * q * ey * q);
                for (int r = 0; r < ex * q; ++r)
                    for (int cc = 0; cc < ey * q; ++cc) {
                        const std::size_t sr = std::size_t(
                            ((layout.origin_x[kx] * q + r) % int(fine_rows) + int(fine_rows)) % int(fine_rows));
                        const std::size_t sc = std::size_t(
                            ((layout.origin_y[ky] * q + cc) % int(fine_cols) + int(fine_cols)) % int(fine_cols));
                        const double x = (r + 0.5) / q - 0.5 * ex, y = (cc + 0.5) / q - 0.5 * ey;
                        o[std::size_t(r) * ey * q + cc] = truth[sr * fine_cols + sc] *
                                                          std::polar(1.0, a + b * x + c * y);
                    }
            }
        std::vector<std::vector<Complex>> raster = objects;
        const std::vector<Complex> joint = detail::blend_field_tiles(layout, objects);
        const std::vector<Complex> old = detail::blend_field_tiles(layout, raster, detail::FieldTileAlignment::raster);
        const double d_joint = test::distance_up_to_phase(truth, joint),
                     d_raster = test::distance_up_to_phase(truth, old);
        std::printf("%d x %d: joint %.3g, raster %.3g\n", k.rows, k.cols, d_joint, d_raster);
        EXPECT_LT(d_joint, 1e-6);
        EXPECT_GT(d_raster, 0.05);
    }
}

// Surfaces within the threshold are not tiled (recover_heights keeps its whole-surface field
// stage, bit for bit); bad settings name themselves.
TEST(FieldTiles, ThresholdAndBadSettings) {
    const RecoverSettings defaults;
    const detail::FieldTiling tiling{defaults.field_tile_threshold, defaults.field_tile_core};
    EXPECT_FALSE(detail::field_tiles_apply(64, 64, tiling));
    EXPECT_TRUE(detail::field_tiles_apply(128, 64, tiling));
    EXPECT_FALSE(detail::field_tiles_apply(1024, 1024, detail::FieldTiling{0, 48, 4}));
    Observation o;
    o.query = test::make_query(Model::OHS, 10.0, 10.0, 1.0);
    o.lambdas_um.assign(1, 0.5);
    o.resolution = 8;
    o.reference.assign(64, 1.0);
    const std::vector<const Observation*> one{&o};
    const std::vector<Complex> start(40 * 40, 1.0);
    const FieldRetrievalSettings s;
    EXPECT_THROW(detail::retrieve_field_tiled(one, 0.5, 40, 40, 1.0, start, s, detail::FieldTiling{16, 4, 2}, {},
                                              serial_communicator()),
                 std::invalid_argument);
    EXPECT_THROW(detail::retrieve_field_tiled(one, 0.5, 40, 40, 1.0, start, s, detail::FieldTiling{16, 16, 9}, {},
                                              serial_communicator()),
                 std::invalid_argument);
    EXPECT_THROW(detail::retrieve_field_tiled(one, 0.5, 40, 40, 1.0, std::vector<Complex>(10), s,
                                              detail::FieldTiling{16, 16, 2}, {}, serial_communicator()),
                 std::invalid_argument);
}
