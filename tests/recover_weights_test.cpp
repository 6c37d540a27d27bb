// The recovery with per-pixel weights (src/recovery/observation_loss.h): the observation
// objective's gradient with weights against central differences (exposure calibration on and
// off); garbage at pixels of weight 0 changing nothing in any stage that reads the
// observations' misfit (objective, σ search, exposures, position grids, convergence, error
// bars); a recovery from slices with corrupted pixels that are masked reaching the accuracy of
// the clean slices, and missing it when the same pixels are not masked; the CLI reading
// weighted observations and saving them with their weights.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include "cli_util.h"
#include "position_cases.h"
#include "recover_util.h"
#include "recovery/observation_loss.h"
#include "recovery/recover_positions.h"
#include "recovery/refinement.h"
#include "recovery/sigma_search.h"
#include "test_util.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

using WeightsCase = test::SmallCase;
using test::small_case;

// `fraction` of each slice's pixels (chosen at random) set to garbage: bright hot pixels of up
// to 20 × the slice's largest value, and dead ones at 0. With `mask` they get weight 0 (and one
// of them NaN, which only a weight of 0 allows); the others weigh 1.
std::vector<Observation> corrupted(std::vector<Observation> observations, double fraction, bool mask,
                                   std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (Observation& o : observations) {
        const std::size_t pixels = std::size_t(o.resolution) * std::size_t(o.resolution);
        const int channels = o.channels();
        float peak = 0.0f;
        for (float v : o.reference) peak = std::max(peak, v);
        if (mask) o.weights.assign(pixels, 1.0f);
        bool nan_placed = false;
        for (std::size_t p = 0; p < pixels; ++p) {
            if (!(u(rng) < fraction)) continue;
            const float garbage = u(rng) < 0.5 ? 0.0f : float(20.0 * u(rng)) * peak;
            for (int k = 0; k < channels; ++k) o.reference[p * std::size_t(channels) + std::size_t(k)] = garbage;
            if (mask) {
                o.weights[p] = 0.0f;
                if (!nan_placed) {
                    o.reference[p * std::size_t(channels)] = std::numeric_limits<float>::quiet_NaN();
                    nan_placed = true;
                }
            }
        }
    }
    return observations;
}

// Non-binary weights in (0, 2] with about a tenth of the pixels at 0, those holding garbage.
std::vector<Observation> weighted(std::vector<Observation> observations, std::uint64_t seed, float garbage) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (Observation& o : observations) {
        const std::size_t pixels = std::size_t(o.resolution) * std::size_t(o.resolution);
        o.weights.resize(pixels);
        for (std::size_t p = 0; p < pixels; ++p) {
            o.weights[p] = u(rng) < 0.1 ? 0.0f : float(0.1 + 1.9 * u(rng));
            if (o.weights[p] == 0.0f)
                for (int k = 0; k < o.channels(); ++k) o.reference[p * std::size_t(o.channels()) + std::size_t(k)] = garbage;
        }
    }
    return observations;
}

Heightfield perturbed(const Heightfield& truth) {
    std::vector<double> h = truth.values();
    for (std::size_t k = 0; k < h.size(); ++k) h[k] *= 0.9 + 0.02 * double(k % 7);
    return truth.with_values(h);
}

}  // namespace

// The objective with weights (some 0, the others between 0.1 and 2) against central differences
// of its value, at heights off the truth, with the exposure's closed form and without it.
TEST(RecoverWeights, ObjectiveGradientWithWeightsMatchesFiniteDifferences) {
    const WeightsCase c = small_case(41);
    std::vector<Observation> obs = weighted(c.observations, 7, 0.0f);
    obs.resize(12);  // a few slices keep the differences quick
    for (std::size_t i = 0; i < obs.size(); ++i)  // exposures that differ per slice
        for (float& v : obs[i].reference) v *= float(0.7 + 0.05 * double(i));
    const Heightfield flat = c.truth.with_values(std::vector<double>(c.truth.values().size(), 0.0));
    const std::vector<double> x = perturbed(c.truth).values();
    for (const Loss& loss : {Loss{LossKind::Amplitude, 1.0}, parse_loss("poisson:1e5")})
        for (bool exposure : {false, true}) {
            detail::ObservationObjective objective(obs, double(obs.size()), flat, loss, exposure, 1.0,
                                                   serial_communicator());
            std::vector<double> g, unused;
            objective(x, g);
            double largest = 0.0;
            for (double v : g) largest = std::max(largest, std::abs(v));
            ASSERT_GT(largest, 0.0);
            // Texels; the slices are float. The Poisson deviance is strongly curved where the model's
            // counts are small: its central differences at 1e-2, 3e-3 and 1e-3 came out -68.5, -67.6
            // and -65.1 against the adjoint's -63.1 at one texel (clang's rounding), so its step is
            // smaller; the amplitude loss's float rounding needs the larger one.
            const double step = loss.kind == LossKind::Amplitude ? 1e-3 : 3e-4;
            for (std::size_t k : {std::size_t(13), std::size_t(50), std::size_t(77), std::size_t(130)}) {
                std::vector<double> plus = x, minus = x;
                plus[k] += step;
                minus[k] -= step;
                const double fd = (objective(plus, unused) - objective(minus, unused)) / (2.0 * step);
                EXPECT_NEAR(g[k], fd, 0.02 * std::abs(fd) + 1e-3 * largest)
                    << to_string(loss) << " exposure " << exposure << " texel " << k;
            }
        }
}

// The exposure's chain rule with weights on its own: the model's gradient against differences
// of slice_misfit in each value of the slice (weights in (0, 2], a tenth 0).
TEST(RecoverWeights, ExposureChainRuleWithWeightsMatchesFiniteDifferences) {
    const WeightsCase c = small_case(43);
    const Observation o = weighted({c.observations[3]}, 11, 5.0f)[0];
    const std::vector<double> model = render_observation(perturbed(c.truth), o);
    std::vector<float> f(model.begin(), model.end());
    const Loss loss{LossKind::Amplitude, 1.0};
    std::vector<double> d;
    double exposure = 0.0;
    detail::slice_misfit(loss, f, o, true, &d, &exposure);
    EXPECT_GT(exposure, 0.0);
    double largest = 0.0;
    for (double v : d) largest = std::max(largest, std::abs(v));
    // The brightest values of weight > 0 (most of a slice is dark), every third of the 36.
    std::vector<std::size_t> order(f.size());
    for (std::size_t k = 0; k < f.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return f[a] > f[b]; });
    int checked = 0;
    for (std::size_t j = 0, seen = 0; j < order.size() && seen < 36; ++j) {
        const std::size_t k = order[j];
        if (o.weights[k] == 0.0f || seen++ % 3 != 0) continue;
        const float h = 1e-2f * f[k];
        std::vector<float> plus = f, minus = f;
        plus[k] += h;
        minus[k] -= h;
        const double fd = (detail::slice_misfit(loss, plus, o, true) - detail::slice_misfit(loss, minus, o, true)) /
                          (double(plus[k]) - double(minus[k]));
        EXPECT_NEAR(d[k], fd, 0.01 * std::abs(fd) + 1e-4 * largest) << "value " << k << " weight "
                                                                    << o.weights[k];
        ++checked;
    }
    EXPECT_GE(checked, 6);
}

// Whatever the pixels of weight 0 hold (garbage, NaN), every stage that reads the misfit gives
// the same bits as with the clean values there; with weight 1 the garbage would show.
TEST(RecoverWeights, PixelsOfWeightZeroChangeNothingInAnyStage) {
    const test::OffCase oc = test::off_case(5113, 0.5, 24, 3);
    std::vector<Observation> clean = oc.observations, dirty = oc.observations;
    for (std::size_t i = 0; i < clean.size(); ++i) {
        const std::size_t pixels = std::size_t(clean[i].resolution) * std::size_t(clean[i].resolution);
        clean[i].weights.assign(pixels, 1.0f);
        for (std::size_t p = i % 5; p < pixels; p += 7) clean[i].weights[p] = 0.0f;
        dirty[i].weights = clean[i].weights;
        for (std::size_t p = 0; p < pixels; ++p)
            if (dirty[i].weights[p] == 0.0f) dirty[i].reference[p] = p % 2 ? 1e4f : std::nanf("");
    }
    const Heightfield flat = oc.truth.with_values(std::vector<double>(oc.truth.values().size(), 0.0));
    const Heightfield at = perturbed(oc.truth);
    const Communicator& comm = serial_communicator();
    const double total = double(clean.size());
    for (const Loss& loss : {Loss{LossKind::Amplitude, 1.0}, parse_loss("poisson:1e4")}) {
        for (bool exposure : {false, true}) {
            detail::ObservationObjective a(clean, total, flat, loss, exposure, 1.1, comm);
            detail::ObservationObjective b(dirty, total, flat, loss, exposure, 1.1, comm);
            std::vector<double> ga, gb;
            EXPECT_EQ(a(at.values(), ga), b(at.values(), gb));
            EXPECT_EQ(ga, gb);
            EXPECT_EQ(detail::scaled_sigma_loss(clean, total, at, 0.9, loss, exposure, comm),
                      detail::scaled_sigma_loss(dirty, total, at, 0.9, loss, exposure, comm));
        }
        EXPECT_EQ(detail::mean_observation_loss(clean, total, at, loss, comm),
                  detail::mean_observation_loss(dirty, total, at, loss, comm));
    }
    std::vector<std::size_t> index;
    const std::size_t positions = detail::gather_positions(clean, index, comm).size();
    const std::vector<double> offsets(2 * positions, 0.3);
    EXPECT_EQ(detail::exposures_at(clean, index, at, 1.0, offsets), detail::exposures_at(dirty, index, at, 1.0, offsets));
    detail::PositionFitSettings s;
    s.calibrate_exposure = true;
    std::vector<double> oa = offsets, ob = offsets;
    detail::register_positions(clean, index, at, s, 1.0, 1.0, 0.5, oa, comm);
    detail::register_positions(dirty, index, at, s, 1.0, 1.0, 0.5, ob, comm);
    EXPECT_EQ(oa, ob);
    const ConvergenceCheck ca = check_convergence(clean, at, 1e4, false), cb = check_convergence(dirty, at, 1e4, false);
    EXPECT_EQ(ca.deviance, cb.deviance);
    EXPECT_EQ(ca.expected_deviance, cb.expected_deviance);
    EXPECT_EQ(ca.relative_misfit, cb.relative_misfit);
    const HeightUncertainty ua = height_uncertainty(clean, at, parse_loss("poisson:1e4"));
    const HeightUncertainty ub = height_uncertainty(dirty, at, parse_loss("poisson:1e4"));
    EXPECT_EQ(ua.sigma_um, ub.sigma_um);
    // The same garbage at weight 1 changes the objective and the convergence check.
    std::vector<Observation> counted = dirty;
    for (Observation& o : counted) {
        for (float& v : o.reference)
            if (std::isnan(v)) v = 1e4f;
        o.weights.clear();
    }
    detail::ObservationObjective a(clean, total, flat, Loss{LossKind::Amplitude, 1.0}, false, 1.0, comm);
    detail::ObservationObjective b(counted, total, flat, Loss{LossKind::Amplitude, 1.0}, false, 1.0, comm);
    std::vector<double> ga, gb;
    EXPECT_GT(b(at.values(), gb), 2.0 * a(at.values(), ga));
    EXPECT_GT(check_convergence(counted, at, 1e4, false).deviance, 2.0 * ca.deviance);
}

// The convergence check's statistics over the weighted pixels: with 0/1 weights they are the
// check of the same slices with the masked pixels' reference replaced by the estimate's own
// slice there (a pixel that fits exactly adds nothing to the amplitude misfit or deviance), an
// independent evaluation by the unweighted code.
TEST(RecoverWeights, ConvergenceCountsOnlyWeightedPixels) {
    const WeightsCase c = small_case(47);
    const Heightfield at = perturbed(c.truth);
    std::vector<Observation> masked = c.observations, filled = c.observations;
    masked.resize(8);
    filled.resize(8);
    for (std::size_t i = 0; i < masked.size(); ++i) {
        const std::vector<double> own = render_observation(at, masked[i]);
        const std::size_t pixels = own.size();
        masked[i].weights.assign(pixels, 1.0f);
        for (std::size_t p = 3 * i; p < pixels; p += 11) {
            masked[i].weights[p] = 0.0f;
            masked[i].reference[p] = -7.0f;
            filled[i].reference[p] = float(own[p]);
        }
    }
    const ConvergenceCheck m = check_convergence(masked, at, 0.0, true);
    const ConvergenceCheck f = check_convergence(filled, at, 0.0, true);
    // Σ R differs by the masked pixels' own slice values; the amplitude misfit's sum does not.
    double masked_energy = 0.0;
    for (std::size_t i = 0; i < masked.size(); ++i)
        for (std::size_t p = 0; p < masked[i].reference.size(); ++p)
            if (masked[i].weights[p] != 0.0f) masked_energy += std::max(double(masked[i].reference[p]), 0.0);
    double filled_energy = 0.0;
    for (const Observation& o : filled)
        for (float r : o.reference) filled_energy += std::max(double(r), 0.0);
    EXPECT_NEAR(m.relative_misfit * masked_energy, f.relative_misfit * filled_energy,
                1e-9 * f.relative_misfit * filled_energy);
    EXPECT_GT(m.relative_misfit, 0.0);
}

// Slices with 3 % of their pixels corrupted (hot and dead pixels): masked, the default
// recovery reaches the accuracy of the clean slices; unmasked, it does not.
TEST(RecoverWeights, MaskedCorruptedPixelsRecoverAsWellAsCleanSlices) {
    const WeightsCase c = small_case(45);
    const auto run = [&](const std::vector<Observation>& obs) {
        return height_rel_rmse(recover_heights(obs, 12, 12, 2.0, 1.0, RecoverSettings{}), c.truth);
    };
    const double clean = run(c.observations);
    const double masked = run(corrupted(c.observations, 0.03, true, 3));
    const double unmasked = run(corrupted(c.observations, 0.03, false, 3));
    std::printf("height_rel_rmse: clean %.3g, corrupted and masked %.3g, corrupted unmasked %.3g\n", clean, masked,
                unmasked);
    EXPECT_LT(clean, 1e-3);
    EXPECT_LT(masked, std::max(2.0 * clean, 1e-3));
    EXPECT_GT(unmasked, 10.0 * std::max(masked, 1e-4));
}

// The CLI: weighted observations from JSON (weights in EXR files beside it) are recovered, and
// --save-observations writes them with their weights.
TEST(RecoverWeights, CliRecoversWeightedObservationsAndSavesTheirWeights) {
    const fs::path dir = test::fresh_dir("recover_weights");
    const WeightsCase c = small_case(45);
    const std::vector<Observation> obs = corrupted(c.observations, 0.03, true, 5);
    write_observations_json((dir / "o.json").string(), obs, ReferenceStorage::Exr);
    const test::CliResult r = test::run_cli(
        dir, "recover --observations o.json --size 12 --texel-um 2 --no-plots --quiet --out run "
             "--save-observations saved.json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::vector<double> um = test::read_npy(dir / "run" / "estimate_height.npy");
    ASSERT_EQ(um.size(), 144u);
    std::vector<double> values(um.size());
    for (std::size_t k = 0; k < um.size(); ++k) values[k] = um[k] / 2.0;  // texel units (vscale 1)
    EXPECT_LT(height_rel_rmse(Heightfield(12, 12, values, 2.0), c.truth), 1e-3);
    const std::vector<Observation> saved = read_observations_json((dir / "saved.json").string());
    ASSERT_EQ(saved.size(), obs.size());
    for (std::size_t i = 0; i < obs.size(); ++i) EXPECT_EQ(saved[i].weights, obs[i].weights) << "observation " << i;
}

}  // namespace wavebrdf
