// The field stage on overlapping tiles (src/recovery/field_tiles.h).
#include "recovery/field_tiles.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <random>

#include "test_util.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;
using Complex = std::complex<double>;

namespace {

std::vector<Complex> object_of(const Heightfield& hf, double lambda_um) {
    std::vector<Complex> o(hf.values().size());
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j)
            o[hf.index(i, j)] = std::polar(1.0, -4.0 * k_pi / lambda_um * hf.height_um(i, j));
    return o;
}

// RMS of a − e^{iφ}b over RMS of a, for the best single phase φ.
double distance_up_to_phase(const std::vector<Complex>& a, const std::vector<Complex>& b) {
    Complex overlap = 0.0;
    double norm = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        overlap += std::conj(b[k]) * a[k];
        norm += std::norm(a[k]);
    }
    const Complex phase = std::polar(1.0, std::arg(overlap));
    double d = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) d += std::norm(a[k] - phase * b[k]);
    return std::sqrt(d / norm);
}

// Slices made by the field model of the whole (periodic) surface from a known object, on a
// jittered raster of positions.
std::vector<Observation> model_observations(const std::vector<Complex>& object, int rows, int cols, double texel_um,
                                            double lambda_um, int n, double sigma_p_um, double step_um) {
    std::vector<Observation> out;
    std::mt19937_64 rng(6501);
    std::uniform_real_distribution<double> jitter(-0.15, 0.15);
    for (double x = 0.5 * step_um; x < rows * texel_um; x += step_um)
        for (double y = 0.5 * step_um; y < cols * texel_um; y += step_um) {
            Observation o;
            o.query = test::make_query(Model::OHS, x + jitter(rng) * step_um, y + jitter(rng) * step_um, sigma_p_um);
            o.lambdas_um.assign(1, lambda_um);
            o.resolution = n;
            const FieldOperator op(rows, cols, texel_um, o.query, lambda_um, n);
            const auto field = op.forward(object);
            o.reference.resize(field.size());
            for (std::size_t p = 0; p < field.size(); ++p)
                o.reference[p] = std::pow(op.amplitude_factor()[p], 2) * std::norm(field[p]);
            out.push_back(std::move(o));
        }
    return out;
}

}  // namespace

// Tiles retrieved on their own (observations moved to the tile's origin, the start cut to
// it), phase-aligned on the overlaps and blended, give the whole surface's object up to ONE
// global phase: a wrong shift, cut, weight or alignment leaves a tile off (the start is 0.6
// rad rms away, 120 iterations; each tile's retrieval returns its object up to a phase of its own).
TEST(FieldTiles, BlendOfTilesIsTheObjectUpToOneGlobalPhase) {
    const int rows = 28, cols = 28;
    const double texel = 1.0, lambda = 0.5;
    const Heightfield hf = test::random_heightfield(rows, cols, 0.03, 5, texel);
    const std::vector<Complex> truth = object_of(hf, lambda);
    const auto observations = model_observations(truth, rows, cols, texel, lambda, 48, 1.0, 2.0);
    std::vector<const Observation*> pointers;
    for (const Observation& o : observations) pointers.push_back(&o);
    std::mt19937_64 rng(6502);
    std::normal_distribution<double> noise(0.0, 0.6);
    std::vector<Complex> start(truth.size());
    for (std::size_t k = 0; k < truth.size(); ++k) start[k] = truth[k] * std::polar(1.0, noise(rng));
    ASSERT_GT(distance_up_to_phase(truth, start), 0.4);
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
    const double distance = distance_up_to_phase(truth, r.object);
    std::printf("tiles: loss %.3g, distance %.3g (start %.3g)\n", r.relative_loss, distance,
                distance_up_to_phase(truth, start));
    EXPECT_LT(r.relative_loss, 1e-4);
    EXPECT_LT(distance, 1e-2);
}

// Surfaces within the threshold are not tiled (recover_heights keeps its whole-surface field
// stage, bit for bit); bad settings name themselves.
TEST(FieldTiles, ThresholdAndBadSettings) {
    const RecoverSettings defaults;
    const detail::FieldTiling tiling{defaults.field_tile_threshold, defaults.field_tile_core, defaults.field_tile_ramp};
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
