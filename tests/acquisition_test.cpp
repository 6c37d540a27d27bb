// Tests of acquisition planning: the planned positions, resolution and wavelengths satisfy the
// rules they are planned by (measured independently here: nearest-neighbour distances on the
// periodic tile, the u spacing, synthetic wavelengths from the pairs), the ladder unwraps
// noisy single-wavelength phases into the right heights, and check_acquisition names each
// kind of too-coarse or too-sparse data.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/noise.h"

using namespace wavebrdf;

namespace {

using wavebrdf::k_pi;

double periodic_distance(const std::array<double, 2>& a, const std::array<double, 2>& b, double px, double py) {
    double dx = std::fmod(std::abs(a[0] - b[0]), px), dy = std::fmod(std::abs(a[1] - b[1]), py);
    dx = std::min(dx, px - dx);
    dy = std::min(dy, py - dy);
    return std::hypot(dx, dy);
}

bool mentions(const std::vector<std::string>& warnings, const std::string& text) {
    for (const auto& w : warnings)
        if (w.find(text) != std::string::npos) return true;
    return false;
}

std::vector<Observation> with_flat_references(std::vector<Observation> obs) {
    for (auto& o : obs) o.reference.assign(static_cast<std::size_t>(o.resolution) * o.resolution, 1.0);
    return obs;
}

}  // namespace

TEST(PlanTest, PositionsOverlapAsRequestedAndCoverTheTile) {
    for (double overlap : {0.6, 0.75, 0.9}) {
        PlanRequest r;
        r.rows = 48;
        r.cols = 40;
        r.texel_um = 1.5;
        r.overlap = overlap;
        r.jitter = 0.2;
        r.seed = 3;
        const AcquisitionPlan plan = plan_acquisition(r);
        const double px = r.rows * r.texel_um, py = r.cols * r.texel_um, d = 6.0 * plan.sigma_p_um;
        double worst = 0.0;
        for (std::size_t a = 0; a < plan.positions_um.size(); ++a) {
            double nearest = std::numeric_limits<double>::infinity();
            for (std::size_t b = 0; b < plan.positions_um.size(); ++b)
                if (a != b)
                    nearest = std::min(nearest, periodic_distance(plan.positions_um[a], plan.positions_um[b], px, py));
            worst = std::max(worst, nearest);
        }
        EXPECT_GE(1.0 - worst / d, overlap) << "overlap " << overlap;
        EXPECT_GE(plan.overlap, overlap);
        // Jittered: not all on one raster line.
        std::vector<double> xs;
        for (const auto& p : plan.positions_um) xs.push_back(std::fmod(p[0], plan.step_x_um));
        EXPECT_GT(*std::max_element(xs.begin(), xs.end()) - *std::min_element(xs.begin(), xs.end()),
                  0.01 * plan.step_x_um);
        EXPECT_TRUE(
            check_acquisition(with_flat_references(planned_observations(plan)), r.rows, r.cols, r.texel_um).empty());
    }
}

// The planned slices sample every wavelength's u within 4× of the Nyquist spacing 1/(2D) (what
// check_acquisition accepts), at 48² where that suffices (also where Nyquist asks less), the
// smallest multiple of 8 that does where the footprint is wide.
TEST(PlanTest, ResolutionSamplesTheWindowAtEveryWavelength) {
    // σ_p (µm), texel (µm), at λ down to 0.4706 µm: the defaults (48² suffices, Nyquist 160²),
    // sur-2's 3.484 µm texels (σ_p 5.2 µm: 48² samples at 5.6×, so 72²), a wide footprint (σ_p
    // 12 µm: 160²) and a narrow one whose Nyquist size is below 48² (σ_p 0.5 µm: 32², kept at 48²).
    struct Case {
        double sigma_p_um, texel_um;
        int expected;
    };
    for (const Case c : {Case{0.0, 2.0, 48}, Case{0.0, 3.484, 72}, Case{12.0, 2.0, 160}, Case{0.5, 0.5, 48}}) {
        PlanRequest r;
        r.height_range_um = 2.0;
        r.texel_um = c.texel_um;
        r.sigma_p_um = c.sigma_p_um;
        const AcquisitionPlan plan = plan_acquisition(r);
        const double d = 6.0 * plan.sigma_p_um;
        const double shortest = *std::min_element(plan.lambdas_um.begin(), plan.lambdas_um.end());
        EXPECT_EQ(plan.resolution, c.expected) << "sigma_p " << plan.sigma_p_um;
        EXPECT_EQ(plan.resolution % 8, 0);
        for (double lambda : plan.lambdas_um)
            EXPECT_LE(2.0 / (plan.resolution * lambda), 4.0 * 0.5 / d) << "sigma_p " << plan.sigma_p_um << ", " << lambda;
        if (plan.resolution > 48) {
            EXPECT_GT(2.0 / ((plan.resolution - 8) * shortest), 4.0 * 0.5 / d) << "not larger than needed";
        }
        EXPECT_TRUE(check_acquisition(with_flat_references(planned_observations(plan)), r.rows, r.cols, r.texel_um)
                        .empty())
            << "sigma_p " << plan.sigma_p_um;
        const bool raised = std::any_of(plan.notes.begin(), plan.notes.end(), [](const std::string& n) {
            return n.find("raised from 48x48") != std::string::npos;
        });
        EXPECT_EQ(raised, plan.resolution > 48) << "sigma_p " << plan.sigma_p_um;
    }
}

TEST(PlanTest, WavelengthLadderSpansTheRangeInBoundedSteps) {
    for (double range : {0.1, 0.3, 1.0, 2.0, 5.0}) {
        std::vector<double> synthetic;
        const auto partners = plan_wavelengths(range, 0.55, 0.4, 0.7, 4.0, &synthetic);
        ASSERT_EQ(partners.size(), synthetic.size());
        if (range < 0.25 * 0.55) {
            EXPECT_TRUE(partners.empty()) << range;
            continue;
        }
        ASSERT_FALSE(partners.empty()) << range;
        for (std::size_t j = 0; j < partners.size(); ++j) {
            EXPECT_GE(partners[j], 0.4);
            EXPECT_LE(partners[j], 0.7);
            EXPECT_NEAR(0.55 * partners[j] / std::abs(0.55 - partners[j]), synthetic[j], 1e-9 * synthetic[j]);
            if (j > 0) {
                EXPECT_LE(synthetic[j - 1] / synthetic[j], 4.0 + 1e-9);
            }
        }
        EXPECT_GE(0.5 * synthetic.front(), range) << "the coarsest level spans the range";
        EXPECT_LE(synthetic.back() / 0.55, 4.0 + 1e-9) << "the finest level reaches lambda0";
    }
    EXPECT_THROW(plan_wavelengths(2.0, 0.55, 0.54, 0.56, 4.0), std::domain_error);
}

// The point of the ladder: wrapped phases at the planned wavelengths, with phase noise, give
// back the heights (to the single-wavelength precision, no wrong integer anywhere).
TEST(PlanTest, LadderUnwrapsNoisyPhasesIntoHeights) {
    // Step ratio 3 tolerates phase noise up to ~π/(4·3·√2) ≈ 0.19 rad at 4σ per level.
    const double range = 2.0, lambda0 = 0.55, noise_rad = 0.1;
    std::vector<double> synthetic;
    const auto partners = plan_wavelengths(range, lambda0, 0.4, 0.7, 3.0, &synthetic);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> height(-0.5 * range, 0.5 * range);
    std::normal_distribution<double> noise(0.0, noise_rad);
    const auto wrap = [](double phi) { return phi - 2.0 * k_pi * std::floor(phi / (2.0 * k_pi) + 0.5); };
    double worst = 0.0;
    for (int trial = 0; trial < 2000; ++trial) {
        const double h = height(rng);
        const auto phase = [&](double lambda) { return wrap(4.0 * k_pi * h / lambda + noise(rng)); };
        const double phi0 = phase(lambda0);
        // Coarsest level: the pair's phase difference determines h modulo Λ/2 ⊇ the range.
        double estimate = 0.0;
        for (std::size_t j = 0; j < partners.size(); ++j) {
            const double big = synthetic[j];
            const double sign = partners[j] < lambda0 ? 1.0 : -1.0;  // 4πh(1/λj − 1/λ0) = ±4πh/Λ
            const double diff = wrap(sign * (phase(partners[j]) - phi0));
            // h = Λ (diff + 2πm) / 4π with m nearest the previous estimate.
            const double base = big * diff / (4.0 * k_pi), period = 0.5 * big;
            estimate = j == 0 ? base : base + period * std::round((estimate - base) / period);
        }
        const double base = lambda0 * phi0 / (4.0 * k_pi), period = 0.5 * lambda0;
        estimate = partners.empty() ? base : base + period * std::round((estimate - base) / period);
        worst = std::max(worst, std::abs(estimate - h));
    }
    // Single-wavelength precision: λ0 · 5σ / 4π; a wrong integer would be ≥ λ0/2 = 0.275.
    EXPECT_LT(worst, lambda0 * 5.0 * noise_rad / (4.0 * k_pi));
}

TEST(PlanTest, CheckNamesSparseAndCoarseData) {
    PlanRequest r;
    r.height_range_um = 1.0;
    const AcquisitionPlan plan = plan_acquisition(r);
    auto obs = with_flat_references(planned_observations(plan));
    EXPECT_TRUE(check_acquisition(obs, r.rows, r.cols, r.texel_um).empty());

    // One position only.
    const std::vector<Observation> single(obs.begin(), obs.begin() + 1);
    EXPECT_TRUE(mentions(check_acquisition(single, r.rows, r.cols, r.texel_um), "one footprint position"));

    // Every other raster column dropped: neighbours too far apart.
    std::vector<Observation> sparse;
    for (const auto& o : obs)
        if (static_cast<int>(std::floor(o.query.x_um / plan.step_x_um)) % 3 == 0 &&
            static_cast<int>(std::floor(o.query.y_um / plan.step_y_um)) % 3 == 0)
            sparse.push_back(o);
    ASSERT_GE(sparse.size(), 2u);
    EXPECT_TRUE(mentions(check_acquisition(sparse, r.rows, r.cols, r.texel_um), "overlap by only"));

    // Slices 4× coarser than Nyquist's are accepted, 5× coarser are not.
    const auto with_resolution = [&](int n) {
        auto coarse = obs;
        for (auto& o : coarse) {
            o.resolution = n;
            o.reference.assign(static_cast<std::size_t>(n) * n, 1.0);
        }
        return coarse;
    };
    const double shortest = *std::min_element(plan.lambdas_um.begin(), plan.lambdas_um.end());
    const int nyquist = static_cast<int>(std::ceil(4.0 * 6.0 * plan.sigma_p_um / shortest / 8.0)) * 8;
    ASSERT_EQ(nyquist % 4, 0);
    EXPECT_TRUE(check_acquisition(with_resolution(nyquist / 4), r.rows, r.cols, r.texel_um).empty());
    EXPECT_TRUE(mentions(check_acquisition(with_resolution(nyquist / 5), r.rows, r.cols, r.texel_um),
                         "expected at least " + std::to_string(nyquist / 4) + " pixels"));

    // Steep slopes reflect light off the slice.
    const Heightfield steep = test::random_heightfield(r.rows, r.cols, 2.0, 3, r.texel_um, 1.0);
    EXPECT_TRUE(mentions(check_acquisition(obs, r.rows, r.cols, r.texel_um, &steep), "slopes up to"));
}

// A facet of slope s reflects light ω_i towards ω_o ≈ −ω_i − 2s: on a sinusoid whose slopes
// along x span ±0.6, normal light sees |s| ≤ 0.45 (|ω_o| ≤ 0.9), a light at +0.8 sees
// s ∈ [−0.85, 0.05] and one at −0.8 s ∈ [−0.05, 0.85].
TEST(PlanTest, ObliqueLightsBringSteepFacetsBackOntoTheSlice) {
    PlanRequest r;
    r.height_range_um = 1.0;
    AcquisitionPlan plan = plan_acquisition(r);
    const double pi = 3.14159265358979323846, amplitude = 0.6 / std::sin(2.0 * pi / r.rows);
    std::vector<double> values;
    for (int i = 0; i < r.rows; ++i)
        for (int j = 0; j < r.cols; ++j) values.push_back(amplitude * std::sin(2.0 * pi * i / r.rows));
    const Heightfield tilted(r.rows, r.cols, values, r.texel_um, 1.0);
    const auto check = [&](const AcquisitionPlan& p) {
        return check_acquisition(with_flat_references(planned_observations(p)), r.rows, r.cols, r.texel_um, &tilted);
    };
    EXPECT_TRUE(mentions(check(plan), "reflect the light beyond the slice's rim"));
    // Only a light on the slope's side brings it back: +0.8 sends it to |ω_o| = 2.0.
    plan.oblique_omega_i = {{{0.8, 0.0}}};
    EXPECT_TRUE(mentions(check(plan), "each of the 2 lights"));
    plan.oblique_omega_i = {{{0.8, 0.0}}, {{-0.8, 0.0}}};
    EXPECT_FALSE(mentions(check(plan), "slice's rim"));
    // Every position under every light, at every wavelength.
    EXPECT_EQ(planned_observations(plan).size(), plan.positions_um.size() * 3 * plan.lambdas_um.size());
    EXPECT_EQ(observations_per_position(plan), 3 * plan.lambdas_um.size());
}

// check_acquisition finds nearest centres on a grid of cells (linear in the positions); the
// worst nearest-neighbour distance and the count of uncovered texels it reports must be the
// all-pairs search's, here on scattered, clustered and repeated centres, some outside the period.
TEST(PlanTest, CheckMatchesTheAllPairsSearchOnScatteredCentres) {
    PlanRequest r;
    r.height_range_um = 1.0;
    const AcquisitionPlan plan = plan_acquisition(r);
    const double px = r.rows * r.texel_um, py = r.cols * r.texel_um, sigma_p = plan.sigma_p_um;
    std::mt19937 rng(17);
    int sparse_trials = 0;
    for (int trial = 0; trial < 4; ++trial) {
        auto obs = with_flat_references(planned_observations(plan));
        std::uniform_real_distribution<double> anywhere(-0.3 * px, 1.3 * px), near(-2.0 * sigma_p, 2.0 * sigma_p);
        const int count = 5 + 15 * trial;
        obs.resize(static_cast<std::size_t>(count));
        for (int k = 0; k < count; ++k) {
            // A third of the centres scattered, the rest in clusters around one of them; one repeated.
            const bool scattered = trial % 2 == 0 || k % 3 == 0;
            obs[k].query.x_um = scattered ? anywhere(rng) : obs[k - k % 3].query.x_um + near(rng);
            obs[k].query.y_um = scattered ? anywhere(rng) : obs[k - k % 3].query.y_um + near(rng);
        }
        obs.push_back(obs.front());

        std::vector<std::array<double, 2>> centres;
        for (const auto& o : obs) centres.push_back({{o.query.x_um, o.query.y_um}});
        std::sort(centres.begin(), centres.end());
        centres.erase(std::unique(centres.begin(), centres.end()), centres.end());
        double worst = 0.0;
        for (std::size_t a = 0; a < centres.size(); ++a) {
            double nearest = 1e300;
            for (std::size_t b = 0; b < centres.size(); ++b)
                if (a != b) nearest = std::min(nearest, periodic_distance(centres[a], centres[b], px, py));
            worst = std::max(worst, nearest);
        }
        int uncovered = 0;
        for (int i = 0; i < r.rows; ++i)
            for (int j = 0; j < r.cols; ++j) {
                double nearest = 1e300;
                for (const auto& c : centres)
                    nearest = std::min(
                        nearest, periodic_distance({{(i + 0.5) * r.texel_um, (j + 0.5) * r.texel_um}}, c, px, py));
                uncovered += nearest > 2.0 * sigma_p;
            }
        ASSERT_GT(uncovered, 0);
        char apart[64];
        std::snprintf(apart, sizeof apart, "centres up to %.2f um apart", worst);
        const auto warnings = check_acquisition(obs, r.rows, r.cols, r.texel_um);
        // The overlap warning names the worst distance when the overlap 1 − worst / 6σ_p is
        // below 60 %, and is absent otherwise.
        const bool sparse = 1.0 - worst / (6.0 * sigma_p) < 0.6;
        sparse_trials += sparse;
        EXPECT_EQ(mentions(warnings, apart), sparse) << "trial " << trial << ": " << apart;
        EXPECT_EQ(mentions(warnings, "overlap by only"), sparse) << "trial " << trial;
        EXPECT_TRUE(
            mentions(warnings, std::to_string(uncovered) + " of " + std::to_string(r.rows * r.cols) + " texels"))
            << "trial " << trial << ": expected " << uncovered << " uncovered texels";
    }
    EXPECT_GE(sparse_trials, 2) << "the scattered trials must reach the overlap warning";
}

TEST(PlanTest, BadRequestsNameTheField) {
    const auto expect_naming = [](PlanRequest r, const std::string& name) {
        try {
            plan_acquisition(r);
            ADD_FAILURE() << "no exception for " << name;
        } catch (const std::exception& e) {
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        }
    };
    PlanRequest r;
    r.overlap = 0.5;
    expect_naming(r, "overlap");
    r = {};
    r.jitter = 0.5;
    expect_naming(r, "jitter");
    r = {};
    r.texel_um = -1.0;
    expect_naming(r, "texel_um");
    r = {};
    r.rows = 0;
    expect_naming(r, "size");
    r = {};
    r.lambda_um = 0.8;
    expect_naming(r, "lambda0");
    r = {};
    r.height_range_um = std::numeric_limits<double>::quiet_NaN();
    expect_naming(r, "height range");
    r = {};
    r.position_uncertainty_um = -1.0;
    expect_naming(r, "position_uncertainty_um");
    r.position_uncertainty_um = std::numeric_limits<double>::quiet_NaN();
    expect_naming(r, "position_uncertainty_um");
}

// A stage whose positions are uncertain by more than the default footprint gets a footprint of
// that width (the position loop's reach, docs/recovery.md round 15); a smaller uncertainty, or a
// given σ_p, leaves σ_p as it was.
TEST(PlanTest, FootprintGrowsWithThePositionUncertainty) {
    PlanRequest r;
    r.texel_um = 2.0;
    r.height_range_um = 2.0;
    r.overlap = 0.8;
    const AcquisitionPlan nominal = plan_acquisition(r);
    EXPECT_EQ(nominal.sigma_p_um, 3.0);  // 1.5 texels
    r.position_uncertainty_um = 2.0;     // below 1.5 texels: unchanged
    EXPECT_EQ(plan_acquisition(r).sigma_p_um, 3.0);
    r.position_uncertainty_um = 6.0;
    const AcquisitionPlan wide = plan_acquisition(r);
    EXPECT_EQ(wide.sigma_p_um, k_footprint_per_position_uncertainty * 6.0);
    // The raster follows the wider window (its step scales with D) and keeps the overlap.
    EXPECT_LT(wide.positions_um.size(), nominal.positions_um.size());
    EXPECT_GE(wide.overlap, 0.8 - 1e-12);
    bool noted = false;
    for (const auto& n : wide.notes) noted |= n.find("uncertain by 6 um") != std::string::npos;
    EXPECT_TRUE(noted);
    r.sigma_p_um = 4.0;  // given: kept
    EXPECT_EQ(plan_acquisition(r).sigma_p_um, 4.0);
}

TEST(PlanTest, GivenWavelengthsAndResolutionReplaceThePlannedOnes) {
    PlanRequest r;
    r.height_range_um = 2.0;
    r.lambdas_um = {0.5, 0.55, 0.65};
    r.resolution = 48;
    const AcquisitionPlan plan = plan_acquisition(r);
    EXPECT_EQ(plan.lambdas_um, r.lambdas_um);
    EXPECT_EQ(plan.resolution, 48);
    ASSERT_EQ(plan.synthetic_um.size(), 3u);
    EXPECT_NEAR(plan.synthetic_um.front(), 0.5 * 0.55 / 0.05, 1e-9);  // the coarsest pair
    bool coarse_noted = false;
    for (const auto& n : plan.notes) coarse_noted |= n.find("coarser than") != std::string::npos;
    EXPECT_TRUE(coarse_noted) << "48 pixels are below the Nyquist rule for sigma_p = 4 um";
    r.resolution = -5;
    EXPECT_THROW(plan_acquisition(r), std::domain_error);
    r.resolution = 0;
    r.lambdas_um = {0.5, -1.0};
    EXPECT_THROW(plan_acquisition(r), std::domain_error);
}

// Not only each window's nearest neighbour: the raster neighbours along x and along y overlap
// by the requested amount too, also at the largest jitter (which moves them across the axis).
TEST(PlanTest, RasterNeighboursOverlapAtTheLargestJitter) {
    PlanRequest r;
    r.rows = r.cols = 40;
    r.texel_um = 2.0;
    r.overlap = 0.6;
    r.jitter = 0.3;
    for (std::uint64_t seed : {1, 2, 3}) {
        r.seed = seed;
        const AcquisitionPlan plan = plan_acquisition(r);
        const double px = r.rows * r.texel_um, py = r.cols * r.texel_um, d = 6.0 * plan.sigma_p_um;
        const int nx = static_cast<int>(std::lround(px / plan.step_x_um)),
                  ny = static_cast<int>(std::lround(py / plan.step_y_um));
        ASSERT_EQ(std::size_t(nx) * ny, plan.positions_um.size());
        double worst = 0.0;
        for (int i = 0; i < nx; ++i)
            for (int j = 0; j < ny; ++j) {
                const auto& p = plan.positions_um[std::size_t(i) * ny + j];
                worst = std::max(worst,
                                 periodic_distance(p, plan.positions_um[std::size_t((i + 1) % nx) * ny + j], px, py));
                worst = std::max(worst,
                                 periodic_distance(p, plan.positions_um[std::size_t(i) * ny + (j + 1) % ny], px, py));
            }
        EXPECT_GE(1.0 - worst / d, r.overlap) << "seed " << seed;
    }
}

// simulate_observations renders one observation per thread: every slice's noise has its own
// seed, so the slices do not depend on the thread count, and the subset form (any order of
// indices) gives each planned observation the same bits as the whole.
TEST(SimulateTest, SlicesDoNotDependOnTheThreadCountOrTheSubsetOrder) {
    PlanRequest r;
    r.rows = r.cols = 16;
    r.texel_um = 1.0;
    r.resolution = 24;
    r.seed = 5;
    const AcquisitionPlan plan = plan_acquisition(r);
    const Heightfield truth = test::random_heightfield(16, 16, 0.3, 11);
    const Noise noise{NoiseKind::Poisson, 1e4};
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const std::vector<Observation> one = simulate_observations(truth, plan, noise, 7);
    omp_set_num_threads(2);
    const std::vector<Observation> two = simulate_observations(truth, plan, noise, 7);
    std::vector<std::size_t> reversed(one.size());
    for (std::size_t i = 0; i < reversed.size(); ++i) reversed[i] = reversed.size() - 1 - i;
    const std::vector<Observation> subset = simulate_observations(truth, plan, noise, 7, reversed);
    omp_set_num_threads(before);
    ASSERT_GT(one.size(), 8u);
    ASSERT_EQ(two.size(), one.size());
    ASSERT_EQ(subset.size(), one.size());
    for (std::size_t i = 0; i < one.size(); ++i) {
        EXPECT_EQ(one[i].reference, two[i].reference) << "observation " << i;
        EXPECT_EQ(one[i].reference, subset[reversed.size() - 1 - i].reference) << "observation " << i;
        EXPECT_EQ(one[i].query.x_um, subset[reversed.size() - 1 - i].query.x_um);
    }
    // The noise differs from slice to slice (each its own seed): two slices of one position at
    // different wavelengths, or two positions, are not equal.
    EXPECT_NE(one[0].reference, one[1].reference);
}
